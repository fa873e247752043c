//! The Rust readers against pygdtf 1.4.5 and pymvr 1.0.7 (installed by
//! `.ci/run`) on the same generated files: fixture count, addresses, mode
//! channel counts and offsets per break, geometry tree, beam angles, wheel
//! slot counts.

use super::{gdtf, mvr, root};
use footlight_mvr::gdtf::{Gdtf, GeometryKind, GeometryNode};
use footlight_mvr::mvr::Mvr;
use serde_json::Value;
use std::process::Command;

const TYPES: [&str; 6] = ["Spot", "Wash", "Bar8", "Blinder", "Fresnel", "Hazer"];

fn peers_available() -> bool {
    match Command::new("python3").args(["-c", "import pygdtf, pymvr"]).output() {
        Ok(o) if o.status.success() => true,
        _ => {
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
