//! LED colour of GDTF types without `<Emitter>`s (issue 36 item 1), as real
//! pixel bars ship: `Footlight@PixelBar16.gdtf` (16 RGBW cells, colours only
//! in its attribute definitions' `Color`) and `Footlight@LedRyWw.gdtf` (R/G/B
//! with a `Color`, RY and WW without: GDTF Annex B's nominal colours).
//! Expected colours are computed here from the xyY the generator wrote
//! (`tools/gen_gdtf_mvr.py`, `LED_COLOURS`) by the textbook path: xyY → XYZ
//! → linear sRGB with IEC 61966-2-1's matrix; and against pygdtf's reading
//! of the same attribute colours.

use super::{gdtf, mvr, root};
use footlight_fixture::FixtureModel;
use footlight_mvr::fixture_type;
use footlight_mvr::gdtf::Gdtf;
use footlight_photometry::lamp::Chroma;
use footlight_photometry::{Lamp, Response};
use glam::{DVec3, Vec2};
use std::process::Command;

/// (attribute, x, y, Y) as `LED_COLOURS` in the generator writes them.
const BAR: [(&str, f64, f64, f64); 4] = [
    ("ColorAdd_R", 0.62, 0.335, 20.0),
    ("ColorAdd_G", 0.31, 0.585, 70.0),
    ("ColorAdd_B", 0.158, 0.075, 8.0),
    ("ColorAdd_W", 0.322, 0.3318, 100.0),
];

/// xyY → XYZ.
fn xyz(x: f64, y: f64, lum: f64) -> DVec3 {
    DVec3::new(x / y * lum, lum, (1.0 - x - y) / y * lum)
}

/// XYZ → linear sRGB, IEC 61966-2-1:1999 (the standard's printed inverse).
fn srgb(v: DVec3) -> DVec3 {
    DVec3::new(
        3.2406 * v.x - 1.5372 * v.y - 0.4986 * v.z,
        -0.9689 * v.x + 1.8758 * v.y + 0.0415 * v.z,
        0.0557 * v.x - 0.2040 * v.y + 1.0570 * v.z,
    )
}

fn led(ty: &footlight_fixture::FixtureType) -> Vec<footlight_photometry::Emitter> {
    match &ty.lamp {
        Lamp::Led { emitters } => emitters.clone(),
        other => panic!("{}: an LED lamp, not {other:?}", ty.name),
    }
}

/// The lamp with only the emitters in `on` at full.
fn only(emitters: &[footlight_photometry::Emitter], on: &[usize]) -> Lamp {
    let mut e = emitters.to_vec();
    for (i, x) in e.iter_mut().enumerate() {
        x.level = if on.contains(&i) { 1.0 } else { 0.0 };
    }
    Lamp::Led { emitters: e }
}

#[test]
fn each_primary_mixes_from_its_attribute_colour() {
    let g = Gdtf::open(&gdtf("PixelBar16")).unwrap();
    assert!(g.ft.physical_descriptions.emitters.is_empty(), "the file defines no emitters");
    let (ty, warnings) = fixture_type(&g).unwrap();
    assert_eq!(ty.mix_names, ["coloradd_r", "coloradd_g", "coloradd_b", "coloradd_w"]);
    let emitters = led(&ty);
    let total: f64 = BAR.iter().map(|p| p.3).sum();
    for (i, (name, x, y, lum)) in BAR.iter().enumerate() {
        assert_eq!(emitters[i].chroma(), Chroma::Xy(Vec2::new(*x as f32, *y as f32)), "{name}");
        assert!((f64::from(emitters[i].share) - lum).abs() < 1e-4, "{name}: share {}", emitters[i].share);
        // Alone at full: Y = its share of the lamp's full white (Î is measured at full white).
        let want = srgb(xyz(*x, *y, lum / total));
        let lamp = only(&emitters, &[i]);
        let got = lamp.colour(1.0).as_dvec3();
        assert!((got - want).abs().max_element() < 2e-4 * want.max_element(), "{name}: {got} vs {want}");
        let got_xyz = lamp.xyz_through(1.0, Response::open()).as_dvec3();
        assert!((got_xyz - xyz(*x, *y, lum / total)).abs().max_element() < 1e-5, "{name}: {got_xyz}");
    }
    // All four at full: the additive sum, luminance 1 (the lamp's own white).
    let all: DVec3 = BAR.iter().map(|(_, x, y, l)| xyz(*x, *y, l / total)).sum();
    let got = only(&emitters, &[0, 1, 2, 3]).colour(1.0).as_dvec3();
    assert!((got - srgb(all)).abs().max_element() < 2e-4, "{got} vs {}", srgb(all));
    assert!((all.y - 1.0).abs() < 1e-12);
    // One note for the type, nothing per channel or cell.
    let notes: Vec<String> = warnings.iter().map(|w| w.to_string()).filter(|w| w.contains("ColorAdd")).collect();
    assert_eq!(notes.len(), 1, "{notes:#?}");
    assert!(
        notes[0].contains("PixelBar16: no emitters; ColorAdd_R/G/B/W mixed from the attribute definitions' colours"),
        "{}",
        notes[0]
    );
    assert!(!notes[0].contains("estimated"), "{}", notes[0]);
}

#[test]
fn ry_and_ww_without_a_colour_take_gdtf_annex_b() {
    let g = Gdtf::open(&gdtf("LedRyWw")).unwrap();
    let (ty, warnings) = fixture_type(&g).unwrap();
    assert_eq!(ty.mix_names, ["coloradd_r", "coloradd_g", "coloradd_b", "coloradd_ry", "coloradd_ww"]);
    let e = led(&ty);
    // DIN SPEC 15800:2022 Annex B: ColorAdd_RY 0.477,0.460,57.0; ColorAdd_WW 0.319,0.340,99.3.
    assert_eq!(e[3].chroma(), Chroma::Xy(Vec2::new(0.477, 0.460)));
    assert_eq!(e[3].share, 57.0);
    assert_eq!(e[4].chroma(), Chroma::Xy(Vec2::new(0.319, 0.340)));
    assert_eq!(e[4].share, 99.3);
    assert_eq!(e[0].share, 20.0, "the file's own Y where it gives one");
    let amber = only(&e, &[3]).colour(1.0);
    assert!(amber.x > amber.y && amber.y > 2.0 * amber.z, "amber: {amber}");
    let note: Vec<String> = warnings.iter().map(|w| w.to_string()).filter(|w| w.contains("ColorAdd")).collect();
    assert_eq!(note.len(), 1, "{note:#?}");
    assert!(
        note[0].contains(
            "LedRyWw: no emitters; ColorAdd_R/G/B mixed from the attribute definitions' colours \
             (estimated primaries for ColorAdd_RY/WW: GDTF Annex B's nominal colours)"
        ),
        "{}",
        note[0]
    );
}

/// The MVR of two bars (16 cells each) and the can: one note per type,
/// whatever the number of cells, and a cell's RGBW at full decodes to the
/// bar's white.
#[test]
fn an_mvr_of_pixel_bars_says_it_once_per_type_and_mixes_every_cell() {
    let import = footlight_mvr::load_mvr(&mvr("led-bars")).unwrap();
    let text: Vec<String> = import.warnings.iter().map(|w| w.to_string()).collect();
    let about = |t: &str| text.iter().filter(|w| w.contains(&format!("{t}: no emitters"))).count();
    assert_eq!((about("PixelBar16"), about("LedRyWw")), (1, 1), "{text:#?}");
    assert!(!text.iter().any(|w| w.contains("decoded but not mixed")), "{text:#?}");
    let cells: Vec<_> = import.patch.fixtures.iter().filter(|f| f.name.starts_with("Bar 1 /")).collect();
    assert_eq!(cells.len(), 16);
    let total: f64 = BAR.iter().map(|p| p.3).sum();
    let white = srgb(BAR.iter().map(|(_, x, y, l)| xyz(*x, *y, l / total)).sum());
    for f in cells {
        let FixtureModel::Typed(t) = &f.model else { panic!() };
        let all = f.decode_with(&|_| 255);
        let rgb = f.k_of(&all).as_dvec3() / f64::from(t.fixture_type.intensity(&all));
        assert!((rgb - white).abs().max_element() < 3e-4, "{}: {rgb} vs {white}", f.name);
        let dark = f.decode_with(&|o| if o == 0 { 255 } else { 0 });
        assert_eq!(f.k_of(&dark), glam::Vec3::ZERO, "{}: colour channels at 0", f.name);
    }
}

/// pygdtf reads the same attribute colours (x, y, Y) that Footlight mixes.
#[test]
fn pygdtf_reads_the_same_attribute_colours() {
    if !pygdtf_available() {
        return;
    }
    let script = root().join("crates/footlight-mvr/tests/peers/attribute_colours.py");
    let files = [gdtf("PixelBar16"), gdtf("LedRyWw")];
    let out = Command::new("timeout").arg("120").arg("python3").arg(script).args(&files).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let peer: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for f in &files {
        let theirs = &peer[f.to_str().unwrap()];
        let (ty, _) = fixture_type(&Gdtf::open(f).unwrap()).unwrap();
        for (name, e) in ty.mix_names.iter().zip(led(&ty)) {
            let attr = theirs.as_object().unwrap().keys().find(|k| k.eq_ignore_ascii_case(name)).unwrap();
            let Chroma::Xy(xy) = e.chroma() else { panic!() };
            match theirs[attr].as_array() {
                Some(c) => {
                    let c: Vec<f64> = c.iter().map(|v| v.as_f64().unwrap()).collect();
                    assert!((f64::from(xy.x) - c[0]).abs() < 1e-6 && (f64::from(xy.y) - c[1]).abs() < 1e-6, "{name}");
                    assert!((f64::from(e.share) - c[2]).abs() < 1e-4, "{name}: Y");
                }
                // No Color in the file (pygdtf: None): Footlight took Annex B's.
                None => {
                    let [x, y, lum] = footlight_mvr::colour::nominal(attr).unwrap();
                    assert_eq!((xy, e.share), (Vec2::new(x, y), lum), "{name}");
                }
            }
        }
    }
}

/// pygdtf is installed by `.ci/run`; with `FOOTLIGHT_REQUIRE_PEERS` set (CI)
/// a missing pygdtf fails, otherwise the test says loudly that it skipped.
fn pygdtf_available() -> bool {
    match Command::new("python3").args(["-c", "import pygdtf"]).output() {
        Ok(o) if o.status.success() => true,
        other => {
            let why = match other {
                Ok(o) => String::from_utf8_lossy(&o.stderr).trim().to_string(),
                Err(e) => e.to_string(),
            };
            assert!(
                std::env::var_os("FOOTLIGHT_REQUIRE_PEERS").is_none(),
                "FOOTLIGHT_REQUIRE_PEERS is set but python3 cannot import pygdtf: {why}"
            );
            eprintln!("SKIPPED: python3 cannot import pygdtf ({why}); .ci/run installs pygdtf 1.4.5");
            false
        }
    }
}
