//! MVR and GDTF onto Footlight's fixture model: the patch an MVR becomes.

use super::{gdtf, mvr};
use footlight_fixture::fixture_type::{Attribute, Optics};
use footlight_fixture::{FixtureModel, Universes};
use footlight_mvr::gdtf::Gdtf;
use footlight_mvr::{check_patch, fixture_type, load_mvr};
use glam::Vec3;

#[test]
fn spot_gdtf_maps_onto_a_fixture_type() {
    let (ty, warnings) = fixture_type(&Gdtf::open(&gdtf("Spot")).unwrap()).unwrap();
    let m = &ty.modes[ty.mode("Standard").unwrap()];
    assert_eq!(m.footprint, 27);
    let pan = m.channel(Attribute::Pan).unwrap();
    assert_eq!((pan.offset, pan.fine, pan.range), (0, Some(1), [-270.0, 270.0]));
    assert_eq!(ty.movement.map(|mv| (mv.pan, mv.tilt)), Some((540.0, 270.0)));
    // Zoom 10..40° beam angle with field/beam 20/15 → field 13.3..53.3°.
    let Optics::Spot(o) = &ty.optics else { panic!() };
    assert!((o.zoom[0] - 40.0 / 3.0).abs() < 1e-4 && (o.zoom[1] - 160.0 / 3.0).abs() < 1e-4, "{:?}", o.zoom);
    // Î = flux / ∫f dω at the narrowest field: the pattern carries all 20,000 lm.
    let state = ty.rest_state(&Default::default());
    let lm = ty.intensity(&state) * ty.beam(&state).solid_angle();
    assert!((lm - 20_000.0).abs() < 1.0, "{lm}");
    assert_eq!(ty.mix_names, ["colorsub_c", "colorsub_m", "colorsub_y"]);
    assert_eq!(m.channels.iter().filter(|c| c.attribute == Attribute::Other).count(), 15);
    assert_eq!(warnings.len(), 1, "one warning per type: {warnings:?}");
    assert!(warnings[0].message.contains("Shutter1") && warnings[0].message.contains("Gobo1"));
    // The 24-bit dimmer of Basic reads coarse and fine and still holds three slots.
    let b = &ty.modes[ty.mode("Basic").unwrap()];
    assert_eq!((b.footprint, b.channel(Attribute::Dimmer).unwrap().fine), (8, Some(3)));
    // The Fresnel's DMX profile is the square law.
    let (fr, _) = fixture_type(&Gdtf::open(&gdtf("Fresnel")).unwrap()).unwrap();
    let d = fr.modes[0].channel(Attribute::Dimmer).unwrap();
    assert_eq!(d.curve, footlight_photometry::DimmerCurve::SquareLaw);
    assert!(fixture_type(&Gdtf::open(&gdtf("Hazer")).unwrap()).unwrap_err().message.contains("not a light"));
}

#[test]
fn features_mvr_becomes_a_patch_with_warnings() {
    let import = load_mvr(&mvr("features")).unwrap();
    let p = &import.patch;
    // 9 MVR fixtures; the hazer is not a light.
    assert_eq!(p.fixtures.len(), 8);
    let ghosts: Vec<_> = import.warnings.iter().filter(|w| w.message.contains("Footlight@Missing.gdtf")).collect();
    assert_eq!(ghosts.len(), 1, "{:?}", import.warnings);
    assert!(ghosts[0].message.contains("Ghost 1 (id 701)") && ghosts[0].message.contains("Ghost 2 (id 702)"));
    let ghost = p.fixtures.iter().find(|f| f.id == 701).unwrap();
    assert!(matches!(ghost.model, FixtureModel::Builtin(_)) && ghost.k() == Vec3::ZERO);
    assert!(import.warnings.iter().any(|w| w.message.contains("Hazer 1") && w.message.contains("not a light")));
    assert!(import.warnings.iter().any(|w| w.message.contains("break 2")));
    // Spot 1 hangs at MVR (−2000, 2000, 6800) + 500 mm layer: its lens 0.75 m below, beam straight down.
    let spot = p.fixtures.iter().find(|f| f.id == 101).unwrap();
    assert!((spot.light.position - Vec3::new(-2.0, 7.3 - 0.75, -2.0)).length() < 1e-4, "{}", spot.light.position);
    assert!((spot.light.axis() - Vec3::NEG_Y).length() < 1e-3, "{}", spot.light.axis());
    assert_eq!(spot.dmx, Some((1, 1)));
    // The blinder is rotated 90° about MVR X: its beam points along MVR +Y (upstage, stage −Z).
    let blinder = p.fixtures.iter().find(|f| f.id == 401).unwrap();
    assert!((blinder.light.axis() - Vec3::NEG_Z).length() < 1e-3, "{}", blinder.light.axis());
    // DMX reaches the fixtures through their GDTF channels: the spot's 16-bit dimmer at 5/6.
    let mut u = Universes::new();
    u.set_slot(1, 5, 255);
    u.set_slot(1, 6, 255);
    let s = spot.decode_universes(&u);
    assert_eq!(s.v, 1.0);
    assert!(spot.k_of(&s).min_element() > 0.0);
    let (_, warnings) = check_patch(&mvr("features")).unwrap();
    assert_eq!(warnings.len(), import.warnings.len());
}

#[test]
fn show150_imports_every_fixture() {
    let import = load_mvr(&mvr("show150")).unwrap();
    // 150 fixtures, 2 of them hazers (not lights).
    assert_eq!(import.patch.fixtures.len(), 148);
    let universes: std::collections::BTreeSet<u16> =
        import.patch.fixtures.iter().filter_map(|f| f.dmx.map(|d| d.0)).collect();
    // Packed in file order, 512 slots per universe (tools/gen_gdtf_mvr.py, SHOW).
    assert_eq!(universes.into_iter().collect::<Vec<_>>(), [1, 2, 3, 4, 5]);
    // One unsupported-attribute warning per type, not per fixture.
    let per_type = import.warnings.iter().filter(|w| w.message.contains("not modelled")).count();
    assert!(per_type <= 6, "{:?}", import.warnings);
}

#[test]
fn overlapping_addresses_are_errors() {
    let e = check_patch(&mvr("bad-dotdot")).unwrap_err();
    assert!(e[0].message.contains("refused"));
}

#[test]
fn toml_patch_takes_gdtf_types_by_path() {
    let path = super::root().join("tests/data/gdtf-patch.toml");
    let (p, warnings) = check_patch(&path).unwrap();
    assert_eq!(p.fixtures.len(), 3);
    let typed = |id: u32| match &p.fixtures.iter().find(|f| f.id == id).unwrap().model {
        FixtureModel::Typed(t) => t.clone(),
        _ => panic!("fixture {id} is not typed"),
    };
    // The same type as the GDTF reader gives on its own, parsed once for both spots.
    let (direct, _) = fixture_type(&Gdtf::open(&gdtf("Spot")).unwrap()).unwrap();
    let (a, c) = (typed(1), typed(3));
    assert!(std::sync::Arc::ptr_eq(&a.fixture_type, &c.fixture_type));
    assert_eq!(a.fixture_type.modes.len(), direct.modes.len());
    assert_eq!(a.fixture_type.modes[a.mode].name, "Standard");
    assert_eq!(a.fixture_type.modes[a.mode].footprint, 27);
    assert_eq!(c.fixture_type.modes[c.mode].name, "Basic");
    assert_eq!(typed(2).fixture_type.modes[typed(2).mode].footprint, 7);
    // The [look] reaches the GDTF channels by attribute name: the 16-bit dimmer at full.
    let spot = p.fixtures.iter().find(|f| f.id == 1).unwrap();
    assert_eq!(spot.look.v, 1.0);
    assert_eq!(p.look_universes.get(1).unwrap()[4..6], [255, 255]);
    // The moving head hangs (no aim): at pan/tilt 0 its beam points straight down.
    assert!((spot.light.axis() - Vec3::NEG_Y).length() < 1e-4, "{}", spot.light.axis());
    // One warning per GDTF type for attributes not modelled, not one per fixture.
    let spot_warnings = warnings.iter().filter(|w| w.path.to_string_lossy().contains("Footlight@Spot")).count();
    assert!(spot_warnings <= 1, "{warnings:?}");
    // The plain TOML loader has no GDTF reader and says so with the line.
    let e = footlight_fixture::Patch::load(&path).unwrap_err();
    assert!(e.line == 12 && e.message.contains("GDTF"), "{e}");
}
