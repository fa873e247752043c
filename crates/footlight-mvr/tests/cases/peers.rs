//! The Rust readers against pygdtf 1.4.5 and pymvr 1.0.7 (installed by
//! `.ci/run`) on the same generated files: fixture count, addresses, mode
//! channel counts and offsets per break, geometry tree, beam angles, wheel
//! slot counts, gobo slot image names, prism facets, the gate channels
//! (gobo, prism, blades, shaper, frost) as Footlight maps them, and the
//! emitters' and filters' spectral measurements.

use super::{gdtf, mvr, root};
use footlight_fixture::fixture_type::Attribute;
use footlight_mvr::gdtf::{Gdtf, GeometryKind, GeometryNode};
use footlight_mvr::mvr::Mvr;
use serde_json::Value;
use std::process::Command;

const TYPES: [&str; 9] = ["Spot", "Wash", "Bar8", "Blinder", "Fresnel", "Hazer", "Fan4", "SpectralLed", "CmySpot"];

pub(super) fn peers_available() -> bool {
    match Command::new("python3").args(["-c", "import pygdtf, pymvr"]).output() {
        Ok(o) if o.status.success() => true,
        _ => {
            assert!(
                std::env::var_os("FOOTLIGHT_REQUIRE_PEERS").is_none(),
                "FOOTLIGHT_REQUIRE_PEERS is set but python3 cannot import pygdtf and pymvr"
            );
            eprintln!("skipped: python3 with pygdtf and pymvr is missing (.ci/run installs them with pip)");
            false
        }
    }
}

fn dump(paths: &[std::path::PathBuf]) -> Value {
    let script = root().join("crates/footlight-mvr/tests/peers/dump.py");
    let out = Command::new("timeout").arg("120").arg("python3").arg(script).args(paths).output().expect("run python3");
    assert!(out.status.success(), "dump.py failed:\n{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("dump.py prints JSON")
}

/// (name, kind) tree as pygdtf names the kinds.
fn tree(n: &GeometryNode) -> Value {
    let kind = match &n.kind {
        GeometryKind::Generic => "Geometry",
        GeometryKind::Axis => "GeometryAxis",
        GeometryKind::Beam(_) => "GeometryBeam",
        GeometryKind::FilterBeam => "GeometryFilterBeam",
        GeometryKind::FilterColor => "GeometryFilterColor",
        GeometryKind::FilterGobo => "GeometryFilterGobo",
        GeometryKind::FilterShaper => "GeometryFilterShaper",
        GeometryKind::Reference(_) => "GeometryReference",
        GeometryKind::Other(k) => k,
    };
    // pygdtf keeps the referenced geometry's own name inside a reference.
    let name = n.template.clone();
    serde_json::json!({"name": name, "kind": kind, "children": n.children.iter().map(tree).collect::<Vec<_>>()})
}

fn strip_kind(v: &Value) -> Value {
    // Only names and nesting are compared with pygdtf's class names mapped above.
    v.clone()
}

#[test]
fn gdtf_agrees_with_pygdtf() {
    if !peers_available() {
        return;
    }
    let paths: Vec<_> = TYPES.iter().map(|t| gdtf(t)).collect();
    let peer = dump(&paths);
    for (t, p) in TYPES.iter().zip(&paths) {
        let theirs = &peer["gdtf"][p.to_str().unwrap()];
        let g = Gdtf::open(p).unwrap();
        assert_eq!(theirs["name"], g.name(), "{t}");
        for w in &g.ft.wheels {
            let name = w.name.as_deref().unwrap();
            assert_eq!(theirs["wheels"][name], w.slots.len(), "{t} wheel {name}");
        }
        assert_eq!(theirs["wheels"].as_object().unwrap().len(), g.ft.wheels.len(), "{t}");
        gate_agrees(t, &g, theirs);
        measurements_agree(t, &g, theirs);
        let modes = theirs["modes"].as_object().unwrap();
        assert_eq!(modes.len(), g.mode_names().len(), "{t}");
        for (mode, m) in modes {
            let layout = g.layout(mode).unwrap();
            // Channels per break, sorted by coarse offset as pygdtf lists them.
            let mut ours: Vec<Vec<Value>> = Vec::new();
            for c in layout.channels.iter().filter(|c| !c.offsets.is_empty()) {
                let b = usize::from(c.dmx_break) - 1;
                while ours.len() <= b {
                    ours.push(Vec::new());
                }
                ours[b].push(serde_json::json!([c.offsets, c.attribute]));
            }
            for b in &mut ours {
                b.sort_by_key(|v| v[0][0].as_u64());
            }
            assert_eq!(Value::from(ours), m["breaks"], "{t} {mode}: channels per break");
            assert_eq!(strip_kind(&tree(&layout.root)), m["tree"], "{t} {mode}: geometry tree");
            // Relations (Multiply virtual dimmers, the Fan4's Override master): name, master, follower, type.
            let relations: Vec<Value> =
                layout.relations.iter().map(|r| serde_json::json!([r.name, r.master, r.follower, r.kind])).collect();
            assert_eq!(Value::from(relations), m["relations"], "{t} {mode}: relations");
            let mut beams = Vec::new();
            collect_beams(&layout.root, &mut beams);
            let theirs_beams = m["beams"].as_array().unwrap();
            assert_eq!(beams.len(), theirs_beams.len(), "{t} {mode}: beams");
            for ((name, beam, field, flux), b) in beams.iter().zip(theirs_beams) {
                assert_eq!(b[0], *name, "{t} {mode}");
                assert!((b[1].as_f64().unwrap() - beam).abs() < 1e-9, "{t} {mode} {name}: beam angle");
                assert!((b[2].as_f64().unwrap() - field).abs() < 1e-9, "{t} {mode} {name}: field angle");
                assert!((b[3].as_f64().unwrap() - flux).abs() < 1e-6, "{t} {mode} {name}: flux");
            }
        }
    }
}

/// The emitters' and filters' measurements that colour is computed from
/// (Physical, LuminousIntensity, every WaveLength/Energy point) against
/// pygdtf's reading (which reads a missing LuminousIntensity as 0).
fn measurements_agree(t: &str, g: &Gdtf, theirs: &Value) {
    use gdtf::physical_descriptions::Measurement;
    let ours = |name: Option<&str>, ms: &[Measurement]| -> (String, Value) {
        let v: Vec<Value> = ms
            .iter()
            .map(|m| {
                let pts: Vec<Value> = m.points.iter().map(|p| serde_json::json!([p.wave_length, p.energy])).collect();
                serde_json::json!([m.physical, m.luminous_intensity.unwrap_or(0.0), pts])
            })
            .collect();
        (name.unwrap_or_default().to_string(), Value::from(v))
    };
    let pd = &g.ft.physical_descriptions;
    let emitters: serde_json::Map<String, Value> =
        pd.emitters.iter().map(|e| ours(e.name.as_deref(), &e.measurements)).collect();
    let filters: serde_json::Map<String, Value> =
        pd.filters.iter().map(|f| ours(f.name.as_deref(), &f.measurements)).collect();
    assert_eq!(Value::from(emitters), theirs["emitters"], "{t}: emitter measurements");
    assert_eq!(Value::from(filters), theirs["filters"], "{t}: filter measurements");
}

/// The gate as Footlight maps it against pygdtf's reading: gobo slot image
/// names (slot count and order), prism facet counts and angles, and the
/// gobo/prism/blade/shaper/frost channels of every mode (offset, attribute).
fn gate_agrees(t: &str, g: &Gdtf, theirs: &Value) {
    let Ok((ty, _)) = footlight_mvr::fixture_type(g) else { return };
    let slots = |wheel: &str| theirs["wheel_slots"][wheel].as_array().cloned().unwrap_or_default();
    let gobo = slots("Gobo1");
    assert_eq!(ty.gate.gobo_wheel.len(), gobo.len(), "{t}: gobo slots");
    for (ours, their) in ty.gate.gobo_wheel.iter().zip(&gobo) {
        let name = ours.as_ref().map(|i| i.name.clone()).unwrap_or_default();
        assert_eq!(Value::from(name), their["media"], "{t}: gobo slot {}", their["name"]);
    }
    let prism = slots("Prism1");
    assert_eq!(ty.gate.prism_wheel.len(), prism.len(), "{t}: prism slots");
    for (ours, their) in ty.gate.prism_wheel.iter().zip(&prism) {
        let angles = their["facets"].as_array().unwrap();
        assert_eq!(ours.len(), angles.len(), "{t}: facets of {}", their["name"]);
        for (f, a) in ours.iter().zip(angles) {
            assert!(
                (f64::from(f.rotation) - a.as_f64().unwrap()).abs() < 1e-5,
                "{t}: facet angle {} vs {a}",
                f.rotation
            );
        }
    }
    if t == "Spot" {
        assert_eq!((gobo.len(), prism.len()), (3, 2), "the generator's Spot has both wheels");
    }
    let gate_attr = |a: &str| ["Gobo1", "Prism1", "Blade", "ShaperRot", "Frost1"].iter().any(|p| a.starts_with(p));
    for (mode, m) in theirs["modes"].as_object().unwrap() {
        let mut their_gate: Vec<(u64, String)> = m["breaks"][0]
            .as_array()
            .map(|b| {
                b.iter()
                    .filter(|c| gate_attr(c[1].as_str().unwrap()))
                    .map(|c| (c[0][0].as_u64().unwrap(), c[1].as_str().unwrap().to_ascii_lowercase()))
                    .collect()
            })
            .unwrap_or_default();
        their_gate.sort();
        let md = &ty.modes[ty.mode(mode).unwrap()];
        let mut ours: Vec<(u64, String)> = md
            .channels
            .iter()
            .filter(|c| matches!(c.attribute, Attribute::Gobo | Attribute::Prism | Attribute::Gate))
            .map(|c| (u64::from(c.offset) + 1, c.name.clone()))
            .collect();
        ours.sort();
        assert_eq!(ours, their_gate, "{t} {mode}: gate channels (gobo, prism, blades, shaper, frost)");
        if t == "Spot" && mode == "Extended" {
            assert_eq!(ours.iter().filter(|c| c.1.starts_with("blade")).count(), 12, "8 insertions + 4 rotations");
        }
    }
}

fn collect_beams(n: &GeometryNode, out: &mut Vec<(String, f64, f64, f64)>) {
    if let GeometryKind::Beam(b) = &n.kind {
        out.push((n.template.clone(), b.beam_angle, b.field_angle, b.flux_lm));
    }
    n.children.iter().for_each(|c| collect_beams(c, out));
}

#[test]
fn mvr_agrees_with_pymvr() {
    if !peers_available() {
        return;
    }
    let paths = [mvr("features"), mvr("show150")];
    let peer = dump(&paths);
    for p in &paths {
        let theirs = peer["mvr"][p.to_str().unwrap()].as_array().unwrap();
        let m = Mvr::open(p).unwrap();
        assert_eq!(theirs.len(), m.scene.fixtures.len(), "{}: fixture count", p.display());
        // pymvr lists a child list's fixtures before its groups; so does the Rust reader.
        for (t, f) in theirs.iter().zip(&m.scene.fixtures) {
            assert_eq!(t["name"], f.name);
            assert_eq!(t["spec"], f.gdtf_spec, "{}", f.name);
            assert_eq!(t["mode"], f.gdtf_mode, "{}", f.name);
            let ours: Vec<Value> =
                f.addresses.iter().map(|a| serde_json::json!([a.dmx_break, a.universe, a.address])).collect();
            assert_eq!(t["addresses"], Value::from(ours), "{}: addresses", f.name);
            assert_eq!(t["fixture_id"], f.fixture_id, "{}", f.name);
            assert_eq!(t["unit_number"].as_u64(), f.unit_number.map(u64::from), "{}", f.name);
        }
    }
}

/// Pixel cells: every emitting GeometryReference pygdtf finds in a mode is
/// one light of ours, with the same name, beam position and DMX slots
/// (the referenced Pixel's R, G, B at offsets 1-3, shifted by the
/// reference's `Break`, on that break).
#[test]
fn pixel_cells_agree_with_pygdtf() {
    if !peers_available() {
        return;
    }
    let path = gdtf("Bar8");
    let peer = dump(std::slice::from_ref(&path));
    let g = Gdtf::open(&path).unwrap();
    let (ty, _) = footlight_mvr::fixture_type(&g).unwrap();
    for mode in ["25ch", "Split"] {
        let theirs = peer["gdtf"][path.to_str().unwrap()]["modes"][mode]["cells"].as_array().unwrap().clone();
        let ours = footlight_mvr::show::cells(&g, &ty, mode).unwrap();
        assert_eq!(ours.len(), theirs.len(), "{mode}: cell count");
        assert_eq!(ours.len(), 8, "{mode}");
        for (c, t) in ours.iter().zip(&theirs) {
            assert_eq!(t[0], c.name.as_str(), "{mode}");
            for (axis, x) in c.offset.to_array().iter().enumerate() {
                assert!(
                    (t[1][axis].as_f64().unwrap() - f64::from(*x)).abs() < 1e-6,
                    "{mode} {}: offset {axis}",
                    c.name
                );
            }
            let (brk, off) = (t[2][0][0].as_u64().unwrap() as u16, t[2][0][1].as_u64().unwrap() as u16);
            let m = &c.fixture_type.modes[0];
            let mut mix: Vec<u16> = m
                .channels
                .iter()
                .filter(|ch| matches!(ch.attribute, footlight_fixture::Attribute::Mix(_)))
                .map(|ch| ch.offset)
                .collect();
            mix.sort_unstable();
            let first = (brk - 1) * footlight_fixture::patch::BREAK_STRIDE + off - 1;
            assert_eq!(mix, [first, first + 1, first + 2], "{mode} {}: its R, G, B slots", c.name);
            // The bar's master dimmer (on the bar, outside every cell) is in every cell, on break 1 slot 1.
            let d = m.channel(footlight_fixture::Attribute::Dimmer).unwrap();
            assert_eq!(d.offset, 0, "{mode} {}", c.name);
            assert_eq!(m.channels.len(), 4, "{mode} {}: master dimmer + R, G, B", c.name);
        }
    }
}
