//! The hand-written IES (ANSI/IESNA LM-63-2002) and EULUMDAT files in
//! tests/data load and give their tabulated values.

use super::{data, root, temp_dir};
use footlight_fixture::{Beam, FixtureState, Patch, photometric};
use glam::Vec3;

fn dir(c_deg: f32, g_deg: f32) -> Vec3 {
    let (c, g) = (c_deg.to_radians(), g_deg.to_radians());
    Vec3::new(g.sin() * c.cos(), g.sin() * c.sin(), -g.cos())
}

#[test]
fn ies_file_matches_its_table() {
    let t = photometric::load(&data().join("flood.ies")).unwrap_or_else(|e| panic!("{e}"));
    // Multiplier 1.5 × ballast 1.0: the peak is 1000 × 1.5 cd.
    assert_eq!(t.peak_cd(), 1500.0);
    // Stored planes C0, C90, C180 (bilateral about C0-C180) → C270 mirrors C90.
    assert_eq!(t.c_angles(), &[0.0, 90.0, 180.0, 270.0, 360.0]);
    let cases = [
        (0.0, 0.0, 1.0),
        (0.0, 10.0, 0.9),
        (90.0, 10.0, 0.7),
        (270.0, 10.0, 0.7),
        (180.0, 20.0, 0.4),
        (0.0, 30.0, 0.2),
        (90.0, 30.0, 0.05),
        (45.0, 20.0, 0.45), // between C0 (0.6) and C90 (0.3)
        (90.0, 15.0, 0.5),  // between γ10 (0.7) and γ20 (0.3)
        (0.0, 40.0, 0.0),
        (0.0, 60.0, 0.0),
    ];
    for (c, g, want) in cases {
        assert!((t.at(c, g) - want).abs() < 1e-5, "C{c} γ{g}: {} vs {want}", t.at(c, g));
    }
    assert_eq!(t.cutoff_deg(), 40.0);
    // As a beam: C90 is local +Y.
    let beam = Beam::Measured(footlight_fixture::MeasuredBeam::new(std::sync::Arc::new(t)));
    assert!((beam.pattern(dir(90.0, 10.0)) - 0.7).abs() < 1e-4);
    assert!((beam.pattern(dir(0.0, 10.0)) - 0.9).abs() < 1e-4);
    assert_eq!(beam.pattern(dir(0.0, 45.0)), 0.0);
    assert!(!beam.is_symmetric());
}

#[test]
fn eulumdat_file_matches_its_table() {
    let t = photometric::load(&data().join("narrow.ldt")).unwrap_or_else(|e| panic!("{e}"));
    // cd/klm × 25000 lm / 1000 × conversion factor 1,0 (decimal comma).
    assert_eq!(t.peak_cd(), 10_000.0);
    assert_eq!(t.c_angles(), &[0.0, 90.0, 180.0, 270.0, 360.0], "Isym 4 mirrors C0-C90");
    let cases = [
        (0.0, 10.0, 0.75),
        (180.0, 10.0, 0.75),
        (90.0, 10.0, 0.5),
        (270.0, 10.0, 0.5),
        (90.0, 20.0, 0.1),
        (0.0, 20.0, 0.25),
        (0.0, 30.0, 0.0),
    ];
    for (c, g, want) in cases {
        assert!((t.at(c, g) - want).abs() < 1e-5, "C{c} γ{g}: {} vs {want}", t.at(c, g));
    }
}

#[test]
fn broken_photometric_files_name_file_and_line() {
    let d = temp_dir("photometry");
    let ldt = std::fs::read_to_string(data().join("narrow.ldt")).unwrap();
    let mut lines: Vec<&str> = ldt.lines().collect();
    lines[52] = "lots"; // line 53: the third intensity of C0
    let bad = d.join("bad.ldt");
    std::fs::write(&bad, lines.join("\n")).unwrap();
    let e = photometric::load(&bad).unwrap_err().to_string();
    assert!(e.contains("bad.ldt:53:") && e.contains("not a number"), "{e}");
    std::fs::write(&bad, lines[..40].join("\n")).unwrap();
    let e = photometric::load(&bad).unwrap_err().to_string();
    assert!(e.contains("bad.ldt:") && e.contains("ends before"), "{e}");
    let ies = std::fs::read_to_string(data().join("flood.ies")).unwrap().replace("1 2 0.2", "2 2 0.2");
    let bad = d.join("bad.ies");
    std::fs::write(&bad, ies).unwrap();
    let e = photometric::load(&bad).unwrap_err().to_string();
    assert!(e.contains("bad.ies:9:") && e.contains("type C"), "{e}");
    let e = photometric::load(&d.join("x.txt")).unwrap_err().to_string();
    assert!(e.contains("x.txt:0:"), "{e}");
}

#[test]
fn a_fixture_type_can_use_measured_photometry() {
    let text = format!(
        "fixtures = \"{}\"\n[[fixture]]\nid = 1\ntype = \"measured-flood\"\nuniverse = 1\naddress = 1\n\
         position = [0, 5, 0]\naim = [0, 0, 0]\n[look]\n1 = {{ dimmer = 255 }}\n",
        data().join("fixtures").display()
    );
    let patch = Patch::parse(&root().join("patch/x.toml"), &text).unwrap_or_else(|e| panic!("{e}"));
    let f = &patch.fixtures[0];
    assert_eq!(f.intensity_of(&f.look), 1500.0);
    assert!(matches!(f.light.beam, Beam::Measured(_)));
    let k = f.k();
    assert!(k.is_finite() && k.min_element() > 0.0);
    assert_eq!(f.k_of(&FixtureState { v: 0.0, ..f.look }), Vec3::ZERO);
}
