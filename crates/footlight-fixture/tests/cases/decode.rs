//! DMX frames → real units, and real units → geometry.

use super::{gels, library_type, root};
use footlight_fixture::{Change, FixtureState, Patch, Universes, classify};
use footlight_photometry::DimmerCurve;
use glam::Vec3;
use std::path::Path;

/// A patch with one of each library type, written to a temporary folder that sees patch/fixtures and patch/gels.toml.
fn rig() -> Patch {
    let text = format!(
        r#"
fixtures = "{root}/patch/fixtures"
gels = "{root}/patch/gels.toml"

[[fixture]]
id = 10
type = "generic-moving-spot"
mode = "standard"
universe = 2
address = 101
position = [0.0, 7.0, 0.0]

[[fixture]]
id = 11
type = "generic-led-par-rgbw"
mode = "6ch"
universe = 2
address = 201
position = [2.0, 6.0, 2.0]
aim = [2.0, 0.0, 0.0]

[[fixture]]
id = 12
type = "strand-castor"
mode = "scroller"
universe = 2
address = 301
position = [-4.0, 5.0, 6.0]
aim = [0.0, 1.0, 0.0]
frames = ["open", "L201", "L136"]
"#,
        root = root().display()
    );
    Patch::parse(Path::new("/nonexistent/rig.toml"), &text).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn a_hand_built_universe_decodes_to_real_units() {
    let patch = rig();
    let mut u = Universes::new();
    let f = u.frame_mut(2);
    // Moving spot at 101: pan 0x8000+? , tilt full, CMY, zoom, focus, iris, shutter, dimmer 16-bit.
    f[100..113].copy_from_slice(&[0xC0, 0x00, 0xFF, 0xFF, 255, 0, 51, 0, 255, 255, 255, 0x80, 0x00]);
    // LED PAR at 201: dimmer 0xFFFF, R 255, G 0, B 102, W 0.
    f[200..206].copy_from_slice(&[0xFF, 0xFF, 255, 0, 102, 0]);
    // Castor at 301: dimmer 255, scroller on frame 1 (L201) exactly = DMX 128 for 3 frames.
    f[300..302].copy_from_slice(&[255, 128]);
    let states = patch.decode(&u);

    let head = states[0];
    // Pan 0xC000 of 540°: (49152 / 65535 − 0.5) · 540.
    assert!((head.pan - (49152.0 / 65535.0 - 0.5) * 540.0).abs() < 1e-3, "pan {}", head.pan);
    assert!((head.tilt - 135.0).abs() < 1e-4, "tilt {}", head.tilt);
    assert_eq!(&head.mix[..3], &[1.0, 0.0, 0.2]);
    assert_eq!(head.zoom, 12.0, "zoom DMX 0 = the first field angle");
    assert_eq!((head.focus, head.iris), (1.0, 0.2), "focus full, iris full = iris_min");
    assert!((head.v - DimmerCurve::Linear.from_dmx16(0x8000)).abs() < 1e-7);

    let par = states[1];
    assert_eq!(par.v, 1.0);
    assert_eq!(&par.mix[..4], &[1.0, 0.0, 0.4, 0.0]);

    let castor = states[2];
    assert_eq!(castor.v, 1.0);
    assert_eq!(castor.frame, 1.0, "DMX 128 is frame 1 of 3 (frames at 0, 128, 255)");
    // Frame 1 is L201: k is LEE 201 on 3200 K tungsten, the same as a fixed L201.
    let lib = gels();
    let l201 = lib.get(lib.find("L201").unwrap());
    let want = footlight_photometry::colour(&footlight_photometry::Lamp::tungsten(), 1.0, l201);
    let k = patch.fixtures[2].k_of(&castor);
    let i_hat = patch.fixtures[2].intensity_of(&castor);
    assert!((k / i_hat - want).abs().max_element() < 1e-5, "{k} vs {want}");
    // Half way between frames 1 and 2 mixes L201 and L136.
    let half = FixtureState { frame: 1.5, ..castor };
    let kh = patch.fixtures[2].k_of(&half);
    assert!(kh != k && kh.is_finite());

    // Every non-dimmer slot merges LTP: the head's 101-111 (its dimmer is 112/113), the PAR's colours, the scroller.
    let ltp = patch.ltp_addresses();
    let want: Vec<u16> = (101..=111).chain(203..=206).chain([302]).collect();
    assert_eq!(ltp.get(&2), Some(&want));
    // Universes without a frame keep the default look; no universe at all too.
    let none = patch.decode(&Universes::new());
    assert_eq!(none[0], patch.fixtures[0].look);
}

#[test]
fn sixteen_bit_pan_and_tilt_ends_and_fine_steps() {
    let ty = library_type("generic-moving-spot");
    let mode = &ty.modes[ty.mode("standard").unwrap()];
    let manual = Default::default();
    let at = |pan: u16, tilt: u16| {
        let slots = [(pan >> 8) as u8, pan as u8, (tilt >> 8) as u8, tilt as u8];
        ty.decode(mode, &manual, &|o| slots.get(usize::from(o)).copied().unwrap_or(0))
    };
    assert_eq!(at(0, 0).pan, -270.0);
    assert_eq!(at(0, 0).tilt, -135.0);
    assert_eq!(at(65535, 65535).pan, 270.0);
    assert_eq!(at(65535, 65535).tilt, 135.0);
    assert!(at(32768, 32768).pan.abs() < 540.0 / 65535.0, "DMX centre is 0 deg");
    // One fine step moves the beam by range / 65535.
    for (coarse, fine) in [(0u16, 0u16), (128, 17), (255, 254)] {
        let v = coarse << 8 | fine;
        let (a, b) = (at(v, v), at(v + 1, v + 1));
        assert!(((b.pan - a.pan) - 540.0 / 65535.0).abs() < 1e-4, "pan step at {v}: {}", b.pan - a.pan);
        assert!(((b.tilt - a.tilt) - 270.0 / 65535.0).abs() < 1e-4, "tilt step at {v}");
        // The beam direction turns by the same angle (tilt about the yoke axis).
        let patch_light = |s: &FixtureState| {
            footlight_fixture::light::head_rotation(glam::Quat::IDENTITY, s.pan, s.tilt) * Vec3::NEG_Z
        };
        let chord = (patch_light(&a) - patch_light(&FixtureState { tilt: b.tilt, ..a })).length();
        let turn = (2.0 * (chord / 2.0).asin()).to_degrees();
        assert!((turn - 270.0 / 65535.0).abs() < 2e-3, "beam turn {turn}");
    }
}

#[test]
fn a_hanging_head_points_where_documented() {
    let patch = rig();
    let head = &patch.fixtures[0];
    let rest = FixtureState { v: 1.0, ..head.look };
    assert!(head.look.pan.abs() < 0.01 && head.look.tilt.abs() < 0.01, "defaults centre pan and tilt");
    let axis = |pan: f32, tilt: f32| head.light_of(&FixtureState { pan, tilt, ..rest }).axis();
    assert!((axis(0.0, 0.0) - Vec3::NEG_Y).length() < 1e-5, "pan 0 tilt 0: straight down");
    assert!((axis(0.0, 90.0) - Vec3::NEG_Z).length() < 1e-5, "tilt +90: toward body −Z (upstage when hung square)");
    assert!((axis(90.0, 90.0) - Vec3::NEG_X).length() < 1e-5);
    assert_eq!(head.light_of(&rest).position, Vec3::new(0.0, 7.0, 0.0));
    // A geometry change is classified as such and moves the light.
    let moved = FixtureState { tilt: 10.0, ..rest };
    assert_eq!(classify(&rest, &moved), Change::Geometry);
    assert_eq!(classify(&rest, &FixtureState { v: 0.3, ..rest }), Change::Composite);
    assert_eq!(classify(&rest, &rest), Change::Unchanged);
}

#[test]
fn dmx_changes_classify_by_attribute() {
    let patch = rig();
    let head = &patch.fixtures[0];
    let base = [0x80u8, 0, 0x80, 0, 0, 0, 0, 0, 0, 0, 255, 0x80, 0];
    let state = |edit: &dyn Fn(&mut [u8; 13])| {
        let mut s = base;
        edit(&mut s);
        head.decode_with(&|o| s[usize::from(o)])
    };
    let a = state(&|_| {});
    type Edit = fn(&mut [u8; 13]);
    let cases: [(&str, Edit, Change); 10] = [
        ("nothing", |_| {}, Change::Unchanged),
        ("shutter (not modelled)", |s| s[10] = 0, Change::Unchanged),
        ("dimmer fine", |s| s[12] = 1, Change::Composite),
        ("cyan", |s| s[4] = 9, Change::Composite),
        ("pan fine", |s| s[1] = 1, Change::Geometry),
        ("tilt", |s| s[2] = 0, Change::Geometry),
        ("zoom", |s| s[7] = 200, Change::Geometry),
        ("focus", |s| s[8] = 3, Change::Geometry),
        ("iris", |s| s[9] = 3, Change::Geometry),
        (
            "dimmer and pan",
            |s| {
                s[11] = 0;
                s[0] = 0
            },
            Change::Geometry,
        ),
    ];
    for (name, edit, want) in cases {
        assert_eq!(classify(&a, &state(&edit)), want, "{name}");
    }
}
