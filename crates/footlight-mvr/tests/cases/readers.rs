//! Known answers written by `tools/gen_gdtf_mvr.py`, and the refused archives.

use super::{gdtf, mvr};
use footlight_mvr::gdtf::{Gdtf, GeometryKind, LampType};
use footlight_mvr::mvr::{Mvr, ObjectKind, stage_pose};
use glam::DVec3;

#[test]
fn spot_mode_channels_and_geometry() {
    let g = Gdtf::open(&gdtf("Spot")).unwrap();
    assert_eq!(g.data_version, "1.2");
    assert_eq!(g.mode_names(), ["Standard", "Basic", "Extended"]);
    let l = g.layout("Standard").unwrap();
    assert_eq!(l.footprints.get(&1), Some(&27));
    let pan = l.channels.iter().find(|c| c.attribute == "Pan").unwrap();
    assert_eq!((pan.offsets.as_slice(), pan.default, pan.geometry.as_str()), (&[1u16, 2][..], 32768, "Arm"));
    assert_eq!((pan.functions[0].physical_from, pan.functions[0].physical_to), (-270.0, 270.0));
    // The shutter's three functions split 0..255 at 32 and 64; strobe 1..25 Hz.
    let sh = l.channels.iter().find(|c| c.attribute == "Shutter1").unwrap();
    let ranges: Vec<_> = sh.functions.iter().map(|f| (f.dmx_from, f.dmx_to)).collect();
    assert_eq!(ranges, [(0, 31), (32, 63), (64, 255)]);
    assert_eq!((sh.functions[2].attribute.as_str(), sh.functions[2].physical_to), ("Shutter1Strobe", 25.0));
    // Colour wheel sets carry their slot indices.
    let cw = l.channels.iter().find(|c| c.attribute == "Color1").unwrap();
    let f = &cw.functions[0];
    assert_eq!(f.wheel.as_deref(), Some("Color1"));
    let slots: Vec<_> = f.sets.iter().map(|s| (s.dmx_from, s.dmx_to, s.wheel_slot)).collect();
    assert_eq!(slots[1], (10, 19, Some(2)));
    assert_eq!(slots[4], (40, 255, Some(5)));
    assert_eq!(g.wheel_slots("Gobo1"), Some(3));
    // The gobo images are in the archive and are PNGs.
    assert!(g.wheel_image("gobo_ring").unwrap().starts_with(b"\x89PNG"));
    // Basic: a 24-bit dimmer on three slots.
    let b = g.layout("Basic").unwrap();
    assert_eq!(b.channels.iter().find(|c| c.attribute == "Dimmer").unwrap().bytes(), 3);
    // The tree is walked by reference: Foot > Arm (axis) > Lantern (axis) > Lens (beam) > filters,
    // names that are not Base/Yoke/Head.
    let arm = &l.root.children[0];
    assert_eq!((arm.name.as_str(), &arm.kind), ("Arm", &GeometryKind::Axis));
    let lens = &arm.children[0].children[0];
    let GeometryKind::Beam(beam) = &lens.kind else { panic!("{:?}", lens.kind) };
    assert_eq!(
        (beam.beam_angle, beam.field_angle, beam.flux_lm, beam.lamp_type),
        (15.0, 20.0, 20000.0, LampType::Discharge)
    );
    // Positions compose down the tree: −0.15 − 0.35 − 0.25 m.
    assert!((lens.to_fixture.w_axis.z + 0.75).abs() < 1e-12, "{}", lens.to_fixture);
    assert_eq!(lens.children.len(), 3);
}

#[test]
fn pixel_bar_references_and_breaks() {
    let g = Gdtf::open(&gdtf("Bar8")).unwrap();
    let l = g.layout("25ch").unwrap();
    assert_eq!(l.footprints.get(&1), Some(&25));
    assert_eq!(l.root.children.len(), 8);
    // Cell k (0-based): red at 2 + 3k, 125 mm apart from −0.4375 m.
    for (k, cell) in l.root.children.iter().enumerate() {
        let red = l.channels.iter().find(|c| c.geometry == cell.name && c.attribute == "ColorAdd_R").unwrap();
        assert_eq!(red.offsets, [2 + 3 * k as u16]);
        assert!((cell.to_fixture.w_axis.x - (-0.4375 + 0.125 * k as f64)).abs() < 1e-12);
        assert!(matches!(cell.children[0].kind, GeometryKind::Beam(_)));
    }
    let split = g.layout("Split").unwrap();
    assert_eq!(split.footprints.iter().map(|(b, n)| (*b, *n)).collect::<Vec<_>>(), [(1, 1), (2, 24)]);
    let w = Gdtf::open(&gdtf("Wash")).unwrap().layout("8ch").unwrap();
    assert_eq!(w.relations.len(), 4);
    assert_eq!(w.relations[0].kind, "Multiply");
    assert_eq!(
        w.channels.iter().find(|c| c.attribute == "ColorAdd_G").unwrap().functions[0].emitter.as_deref(),
        Some("Green")
    );
}

#[test]
fn mvr_scene_layers_groups_symbols_and_axes() {
    let m = Mvr::open(&mvr("features")).unwrap();
    assert_eq!(m.scene.version, "1.6");
    assert_eq!(m.scene.layers.len(), 2);
    assert_eq!(m.scene.fixtures.len(), 9);
    let spot = m.scene.fixtures.iter().find(|f| f.name == "Spot 1").unwrap();
    assert_eq!(spot.groups, ["Spots"]);
    assert_eq!(spot.class.as_deref(), Some("Lighting"));
    assert_eq!(spot.gobo.as_ref().map(|g| (g.0.as_str(), g.1)), Some(("gobo_ring", 15.0)));
    assert!(spot.focus.is_some() && m.scene.focus_points.contains_key(spot.focus.as_deref().unwrap()));
    // MVR (−2000, 2000, 6800) mm in the Rig layer raised 500 mm: stage (−2, 7.3, −2) m.
    let (p, _) = stage_pose(spot.world);
    assert!((p - DVec3::new(-2.0, 7.3, -2.0)).length() < 1e-9, "{p}");
    let bar = m.scene.fixtures.iter().find(|f| f.name == "Bar split").unwrap();
    assert_eq!(bar.addresses.len(), 2);
    assert_eq!((bar.addresses[1].dmx_break, bar.addresses[1].universe, bar.addresses[1].address), (1, 2, 1));
    let hazer = m.scene.fixtures.iter().find(|f| f.name == "Hazer 1").unwrap();
    assert_eq!((hazer.addresses[0].universe, hazer.addresses[0].address), (3, 1), "universe.address form");
    // Three truss pieces instance one symdef.
    let truss: Vec<_> = m.scene.objects.iter().filter(|o| o.kind == ObjectKind::Truss).collect();
    assert_eq!(truss.len(), 3);
    assert!(truss.iter().all(|t| t.geometries.len() == 1 && t.geometries[0].0 == "truss_2m.glb"));
    assert_eq!(truss[1].geometries[0].1.w_axis.x, -1000.0);
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
}

#[test]
fn refused_archives_say_why() {
    let cases = [
        ("bad-dotdot", "`..` path"),
        ("bad-absolute", "absolute path"),
        ("bad-ratio", "more than 100:1"),
        ("bad-huge", "more than 1073741824 bytes"),
    ];
    for (stem, why) in cases {
        let e = Mvr::open(&mvr(stem)).unwrap_err().to_string();
        assert!(e.contains(stem) && e.contains("refused") && e.contains(why), "{stem}: {e}");
    }
    let e = Mvr::open(&mvr("bad-xml")).unwrap_err();
    assert!(e.path.ends_with("bad-xml.mvr/GeneralSceneDescription.xml"), "{e}");
    assert_eq!(e.line, 2, "{e}");
    assert!(e.message.contains("column") && e.message.contains("GDTFMod"), "{e}");
}
