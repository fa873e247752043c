//! The Spot's gate from its GDTF channels (issue 14): gobo wheel images,
//! prism facets, blades, frost, spins, and what each DMX change costs.

use super::{gdtf, mvr};
use footlight_fixture::fixture_type::{Action, Attribute, GateTarget};
use footlight_fixture::state::{Change, classify};
use footlight_fixture::{Beam, FixtureState, Universes};
use footlight_mvr::gdtf::Gdtf;
use footlight_mvr::{fixture_type, load_mvr};

#[test]
fn gobo_and_prism_wheels_are_read_with_their_images_and_facets() {
    let (ty, warnings) = fixture_type(&Gdtf::open(&gdtf("Spot")).unwrap()).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    // Gobo1: Open (no image), Ring and Bars (64×64 PNGs in wheels/).
    let g = &ty.gate.gobo_wheel;
    assert_eq!(g.len(), 3);
    assert!(g[0].is_none());
    let ring = g[1].as_ref().unwrap();
    assert_eq!((ring.name.as_str(), ring.size()), ("gobo_ring", (64, 64)));
    // The ring's centre is opaque, its band (r 0.5..0.9 of the half size) passes.
    assert_eq!(ring.sample(glam::Vec2::ZERO), 0.0);
    assert_eq!(ring.sample(glam::Vec2::new(0.7, 0.0)), 1.0);
    assert_eq!(g[2].as_ref().unwrap().name, "gobo_bars");
    // Prism1: Open (no facets) and a 3-facet prism at 0°, 120°, 240°.
    let p = &ty.gate.prism_wheel;
    assert_eq!(p.iter().map(Vec::len).collect::<Vec<_>>(), [0, 3]);
    for (k, f) in p[1].iter().enumerate() {
        let want = (k as f32 * 120.0).to_radians();
        let d = (f.rotation - want + 1.0).rem_euclid(std::f32::consts::TAU) - 1.0;
        assert!(d.abs() < 1e-4, "facet {k}: {}", f.rotation);
    }
    // Channel mapping of the Extended mode.
    let m = &ty.modes[ty.mode("Extended").unwrap()];
    assert_eq!(m.footprint, 29);
    let gobo = m.channels.iter().find(|c| c.offset == 8).unwrap();
    assert_eq!(gobo.attribute, Attribute::Gobo);
    let actions: Vec<_> = gobo.functions.iter().map(|f| (f.from, f.action)).collect();
    assert_eq!(
        actions,
        [
            (0, Action::Slot(0)),
            (10, Action::Slot(1)),
            (20, Action::Slot(2)),
            (128, Action::Gate(GateTarget::GoboWheelSpin))
        ]
    );
    let gate = |name: &str| m.channel_named(name).unwrap().attribute;
    for n in ["gobo1pos", "prism1pos", "frost1", "blade1a", "blade4b", "blade3rot", "shaperrot"] {
        assert_eq!(gate(n), Attribute::Gate, "{n}");
    }
    assert_eq!(gate("prism1"), Attribute::Prism);
}

/// The first gate spot of gate.mvr (Extended mode at 1.1), dimmer full, shutter open, plus `extra` slots.
fn gate_spot(extra: &[(u16, u8)]) -> (footlight_fixture::Fixture, FixtureState) {
    let import = load_mvr(&mvr("gate")).unwrap();
    assert_eq!(import.patch.fixtures.len(), 5);
    assert!(import.warnings.is_empty(), "{:?}", import.warnings);
    // From the MVR's power-up defaults (blade and shaper rotation centred).
    let mut u: Universes = import.patch.look_universes.clone();
    let f = import.patch.fixtures.into_iter().find(|f| f.id == 2000).unwrap();
    for (a, v) in [(5, 255), (6, 255), (7, 40)].iter().chain(extra) {
        u.set_slot(1, *a, *v);
    }
    let s = f.decode_universes(&u);
    (f, s)
}

#[test]
fn gate_channels_decode_to_real_units() {
    let (_, rest) = gate_spot(&[]);
    assert_eq!((rest.gobo, rest.prism, rest.frost), (0.0, 0.0, 0.0));
    // Rotations default to DMX 128 of −45..45°: 0.18°.
    assert!(rest.blades.iter().all(|b| b[0] == 0.0 && b[1] == 0.0 && (b[2] - 0.176).abs() < 1e-3), "{:?}", rest.blades);
    assert!((rest.shaper_rot - 0.176).abs() < 1e-3);
    // Gobo slot sets: DMX 10-19 is Ring (slot 1), 20-127 Bars (slot 2).
    assert_eq!(gate_spot(&[(9, 12)]).1.gobo, 1.0);
    assert_eq!(gate_spot(&[(9, 20)]).1.gobo, 2.0);
    // Gobo1Pos 0..127 → 0..360°; Gobo1PosRotate 128..255 → −360..360 °/s.
    let s = gate_spot(&[(10, 127)]).1;
    assert_eq!(s.gobo_angle, 360.0);
    let s = gate_spot(&[(10, 255)]).1;
    assert_eq!(s.gobo_spin, 360.0);
    // Wheel spin on the gobo channel: 128 → −120 °/s.
    assert_eq!(gate_spot(&[(9, 128)]).1.gobo_wheel_spin, -120.0);
    // Prism in (128 = 3-facet), frost full, blade 2 A/B, blade 1 rotation (−45..45°), shaper.
    let s = gate_spot(&[(11, 128), (16, 255), (19, 51), (20, 255), (25, 0), (29, 255)]).1;
    assert_eq!((s.prism, s.frost), (1.0, 1.0));
    assert_eq!((s.blades[1][0], s.blades[1][1]), (0.2, 1.0));
    assert_eq!((s.blades[0][2], s.shaper_rot), (-45.0, 45.0));
}

#[test]
fn gate_changes_are_geometry_and_strobe_stays_composite() {
    let (f, rest) = gate_spot(&[]);
    assert!(matches!(f.light_of(&rest).beam, Beam::Spot(_)), "an open gate is the plain spot");
    for extra in [&[(9u16, 12u8)][..], &[(10, 30)], &[(10, 200)], &[(9, 200)], &[(11, 128)], &[(12, 40)], &[(16, 99)]]
        .iter()
        .chain([&[(17u16, 80u8)][..], &[(26, 0)], &[(29, 0)]].iter())
    {
        let (_, s) = gate_spot(extra);
        assert_eq!(classify(&rest, &s), Change::Geometry, "{extra:?}");
    }
    // Strobe (64..255 on the shutter) and dimmer: composite only, even with a gobo in.
    let (_, gobo) = gate_spot(&[(9, 12)]);
    let (_, strobe) = gate_spot(&[(9, 12), (7, 200)]);
    assert!(strobe.strobe > 0.0);
    assert_eq!(classify(&gobo, &strobe), Change::Composite);
    let (_, dim) = gate_spot(&[(9, 12), (5, 100)]);
    assert_eq!(classify(&gobo, &dim), Change::Composite);
    // The ring gobo in the beam: a shaped beam passing less light at the same Î.
    let open = f.light_of(&rest).beam.solid_angle();
    let ringed = f.light_of(&gobo).beam;
    assert!(matches!(ringed, Beam::Shaped(_)));
    assert!(
        ringed.solid_angle() < 0.8 * open && ringed.solid_angle() > 0.2 * open,
        "{} of {open}",
        ringed.solid_angle()
    );
    assert_eq!(f.k_of(&gobo), f.k_of(&rest), "a gobo does not change k_i");
    // A spinning gobo steps on the frame clock (bounded rebuild rate).
    let (_, spin) = gate_spot(&[(9, 12), (10, 255)]);
    let (a, b) = (spin.at_time(1.0, 3), spin.at_time(1.01, 3));
    assert_eq!(classify(&a, &b), Change::Unchanged);
    assert_eq!(classify(&a, &spin.at_time(1.5, 3)), Change::Geometry);
}
