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
    // Shutter, colour wheel, CTO, gobo, prism, blades and shaper are all modelled: no warning.
    assert_eq!(m.channels.iter().filter(|c| c.attribute == Attribute::Other).count(), 0);
    assert!(warnings.is_empty(), "{warnings:?}");
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
    // 9 MVR fixtures; the hazer is not a light; the pixel bar is 8 lights (its cells), the blinder 2 (its lamps).
    assert_eq!(p.fixtures.len(), 16);
    let ghosts: Vec<_> = import.warnings.iter().filter(|w| w.message.contains("Footlight@Missing.gdtf")).collect();
    assert_eq!(ghosts.len(), 1, "{:?}", import.warnings);
    assert!(ghosts[0].message.contains("Ghost 1 (id 701)") && ghosts[0].message.contains("Ghost 2 (id 702)"));
    let ghost = p.fixtures.iter().find(|f| f.id == 701).unwrap();
    assert!(matches!(ghost.model, FixtureModel::Builtin(_)) && ghost.k() == Vec3::ZERO);
    assert!(import.warnings.iter().any(|w| w.message.contains("Hazer 1") && w.message.contains("not a light")));
    // Its DMX break 2 is decoded now: no warning about it.
    assert!(!import.warnings.iter().any(|w| w.message.contains("break")), "{:?}", import.warnings);
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
    // Shutter slot 7 at 0 is "Closed" (DMX 0-31): black until it opens.
    let s = spot.decode_universes(&u);
    assert_eq!((s.v, s.shutter), (1.0, 0.0));
    assert_eq!(spot.k_of(&s), Vec3::ZERO);
    u.set_slot(1, 7, 40);
    let s = spot.decode_universes(&u);
    assert_eq!((s.v, s.shutter, s.strobe), (1.0, 1.0, 0.0));
    assert!(spot.k_of(&s).min_element() > 0.0);
    let (_, warnings) = check_patch(&mvr("features")).unwrap();
    assert_eq!(warnings.len(), import.warnings.len());
}

#[test]
fn show150_imports_every_fixture() {
    let import = load_mvr(&mvr("show150")).unwrap();
    // 150 fixtures, 2 of them hazers (not lights), 24 pixel bars of 8 cells each, 20 blinders of 2 lamps.
    assert_eq!(import.patch.fixtures.len(), 148 - 24 + 24 * 8 - 20 + 20 * 2);
    assert_eq!(import.patch.fixtures.iter().filter(|f| f.name.starts_with("Bar8 ")).count(), 24 * 8);
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

/// The Spot's Standard mode at address 1 with the dimmer full and the given extra slots.
fn spot_state(extra: &[(u16, u8)]) -> (footlight_fixture::Fixture, footlight_fixture::FixtureState) {
    let import = load_mvr(&mvr("features")).unwrap();
    let spot = import.patch.fixtures.into_iter().find(|f| f.id == 101).unwrap();
    let mut u = Universes::new();
    for (a, v) in [(5, 255), (6, 255), (7, 40)].iter().chain(extra) {
        u.set_slot(1, *a, *v);
    }
    let s = spot.decode_universes(&u);
    (spot, s)
}

#[test]
fn colour_wheel_slots_filter_k_by_their_xyy() {
    let (spot, open) = spot_state(&[]);
    assert_eq!(open.wheel, 0.0);
    // Slot 8 at DMX 10 is the channel set "Red" (WheelSlotIndex 2): CIE (0.64, 0.33) at
    // Y 21.26 % is the sRGB red primary at its own luminance, so c_F = (1, 0, 0).
    let (_, red) = spot_state(&[(8, 12)]);
    assert_eq!(red.wheel, 1.0);
    let (k0, k1) = (spot.k_of(&open), spot.k_of(&red));
    assert!((k1.x / k0.x - 1.0).abs() < 2e-3 && k1.y.abs() < 2e-3 * k0.y && k1.z.abs() < 2e-3 * k0.z, "{k0} {k1}");
    // Green (0.30, 0.60, 71.52 %) and blue (0.15, 0.06, 7.22 %) are the other primaries.
    let (_, green) = spot_state(&[(8, 20)]);
    let k2 = spot.k_of(&green);
    assert!((k2.y / k0.y - 1.0).abs() < 2e-3 && k2.x.abs() < 2e-3 * k0.x, "{k2}");
    let (_, blue) = spot_state(&[(8, 39)]);
    let k3 = spot.k_of(&blue);
    assert!((k3.z / k0.z - 1.0).abs() < 2e-3 && k3.y.abs() < 2e-3 * k0.y, "{k3}");
    // A wheel change is composite-only.
    assert_eq!(footlight_fixture::classify(&open, &red), footlight_fixture::Change::Composite);
}

#[test]
fn shutter_and_strobe_follow_the_channel_functions() {
    // DMX 0-31 closed, 32-63 open, 64-255 strobe 1..25 Hz (tools/gen_gdtf_mvr.py, spot()).
    let (spot, closed) = spot_state(&[(7, 10)]);
    assert_eq!((closed.shutter, spot.k_of(&closed)), (0.0, Vec3::ZERO));
    let (_, open) = spot_state(&[]);
    let (_, strobe) = spot_state(&[(7, 160)]);
    let hz = 1.0 + 24.0 * (160.0 - 64.0) / (255.0 - 64.0);
    assert!((strobe.strobe - hz).abs() < 1e-4, "{}", strobe.strobe);
    let (_, fastest) = spot_state(&[(7, 255)]);
    assert_eq!(fastest.strobe, 25.0);
    // The strobe is a time factor on k_i: open at t = 0 (stills), closed in the second half period.
    let k = spot.k_of(&open);
    assert_eq!(spot.k_of(&strobe), k);
    assert_eq!(spot.k_at(&strobe, 0.0), k);
    assert_eq!(spot.k_at(&strobe, 0.25 / f64::from(hz)), k);
    assert_eq!(spot.k_at(&strobe, 0.75 / f64::from(hz)), Vec3::ZERO);
    // Neither the shutter nor the strobe moves the beam; k_full ignores the shutter.
    assert_eq!(footlight_fixture::classify(&open, &strobe), footlight_fixture::Change::Composite);
    assert_eq!(spot.k_full_of(&closed), spot.k_full_of(&open));
}

#[test]
fn cto_turns_the_lamp_warmer_and_costs_its_transmittance() {
    let (spot, open) = spot_state(&[]);
    assert_eq!(open.cto, 7000.0, "CTO at DMX 0 is the lamp's own 7000 K");
    let (_, full) = spot_state(&[(18, 255)]);
    assert_eq!(full.cto, 3200.0);
    // Reference: τ(λ) = B(λ, 3200)/B(λ, 7000) scaled to peak 1 over 380-780 nm, luminous
    // transmittance ∫τ B₇₀₀₀ ȳ / ∫B₇₀₀₀ ȳ, integrated here at 1 nm with Planck's law.
    let planck = |nm: f64, t: f64| {
        let l = nm * 1e-9;
        1.0 / (l.powi(5) * ((1.438_776_877e-2 / (l * t)).exp() - 1.0))
    };
    let nms: Vec<f64> = (380..=780).map(f64::from).collect();
    let peak = nms.iter().map(|&nm| planck(nm, 3200.0) / planck(nm, 7000.0)).fold(0.0, f64::max);
    let ybar = |nm: f64| f64::from(footlight_photometry::cie::cmf(nm as f32).y);
    let num: f64 = nms.iter().map(|&nm| planck(nm, 3200.0) / peak * ybar(nm)).sum();
    let den: f64 = nms.iter().map(|&nm| planck(nm, 7000.0) * ybar(nm)).sum();
    let tau = num / den;
    assert!(tau > 0.3 && tau < 0.9, "{tau}");
    let (k0, k1) = (spot.k_of(&open), spot.k_of(&full));
    let lum = |k: Vec3| f64::from(k.dot(Vec3::new(0.2126, 0.7152, 0.0722)));
    assert!((lum(k1) / lum(k0) - tau).abs() < 5e-3, "{} vs {tau}", lum(k1) / lum(k0));
    // Warmer: red over blue rises, and matches a 3200 K lamp's colour.
    assert!(k1.x / k1.z > 1.5 * k0.x / k0.z);
    let c3200 = footlight_photometry::colour(&footlight_photometry::Lamp::Discharge { cct: 3200.0 }, 1.0, None);
    let (a, b) = (k1 / k1.x, c3200 / c3200.x);
    assert!((a - b).abs().max_element() < 1e-3, "{a} {b}");
}

/// The split-mode bar reads its master dimmer from break 1 (universe 1 slot
/// 201) and its cells from break 2 (universe 2 from slot 1), merges them
/// latest-takes-precedence on both universes, and its defaults land on both.
#[test]
fn split_bar_decodes_dmx_break_two() {
    use footlight_fixture::fixture_type::Attribute;
    let import = load_mvr(&mvr("features")).unwrap();
    let p = &import.patch;
    let cells: Vec<_> = p.fixtures.iter().filter(|f| f.id == 301).collect();
    assert_eq!(cells.len(), 8);
    assert_eq!(cells[0].breaks(), [(2, 1)]);
    assert_eq!(cells[0].universes(), [1, 2]);
    // Cell 5's R, G, B: break 2 slots 13, 14, 15; its dimmer: the bar's, 1.201.
    let FixtureModel::Typed(t) = &cells[4].model else { panic!() };
    let m = &t.fixture_type.modes[t.mode];
    let at: Vec<_> = m.channels.iter().map(|c| (c.attribute, cells[4].slot_address(c.offset))).collect();
    assert_eq!(
        at,
        [
            (Attribute::Dimmer, Some((1, 201))),
            (Attribute::Mix(0), Some((2, 13))),
            (Attribute::Mix(1), Some((2, 14))),
            (Attribute::Mix(2), Some((2, 15)))
        ]
    );
    let mut u = Universes::new();
    u.set_slot(1, 201, 255);
    for (slot, v) in [(13, 10), (14, 200), (15, 40)] {
        u.set_slot(2, slot, v);
    }
    let s = cells[4].decode_universes(&u);
    assert_eq!((s.v, s.mix[0], s.mix[1], s.mix[2]), (1.0, 10.0 / 255.0, 200.0 / 255.0, 40.0 / 255.0));
    // Only universe 1 arrived: the cells' colour reads 0 (dark), not the default look.
    let mut only1 = Universes::new();
    only1.set_slot(1, 201, 255);
    assert_eq!(cells[4].k_of(&cells[4].decode_universes(&only1)), Vec3::ZERO);
    // LTP: the colour slots on universe 2, not universe 1 (the dimmer stays HTP).
    let ltp = p.ltp_addresses();
    assert_eq!(ltp.get(&2).map(|v| v.len()), Some(24));
    assert!(!ltp.get(&1).is_some_and(|v| v.contains(&201)));
}

/// A multi-lamp blinder (two plain `<Beam>`s, no references) is two lights:
/// in mode 2ch each lamp has its own dimmer (slots 301 and 302), 240 mm apart.
#[test]
fn blinder_lamps_are_lights_with_their_own_dimmers() {
    let import = load_mvr(&mvr("features")).unwrap();
    let lamps: Vec<_> = import.patch.fixtures.iter().filter(|f| f.id == 401).collect();
    assert_eq!(lamps.len(), 2);
    assert_eq!((lamps[0].name.as_str(), lamps[1].name.as_str()), ("Blinder 1 / Cell1", "Blinder 1 / Cell2"));
    assert!(((lamps[1].light.position - lamps[0].light.position).length() - 0.24).abs() < 1e-4);
    let mut u = Universes::new();
    u.set_slot(1, 302, 255);
    let k: Vec<Vec3> = lamps.iter().map(|f| f.k_of(&f.decode_universes(&u))).collect();
    assert_eq!(k[0], Vec3::ZERO);
    assert!(k[1].min_element() > 0.0, "{}", k[1]);
}
