//! Issue 35: nesting and counts are bounded before the recursion or the
//! allocation they would drive. A deep GDTF geometry tree or MVR group
//! nesting is refused naming the file and the limit (it used to overflow
//! the stack and abort the process); the deepest files allowed parse on a
//! 2 MiB thread stack (a tokio blocking thread's, where `footlight run`
//! loads its patch) in this debug build; symbol fan-out stops at its
//! budget; a GDTF model with NaN dimensions is warned about.

use super::{gdtf, temp_dir, zip_of};
use footlight_mvr::archive::{Archive, Limits};
use footlight_mvr::gdtf::{Gdtf, MAX_XML_DEPTH as GDTF_DEPTH};
use footlight_mvr::mvr::{MAX_SYMBOL_INSTANCES, MAX_XML_DEPTH as MVR_DEPTH, Mvr};
use footlight_mvr::{check_patch, fixture_type};
use std::path::Path;

/// Runs `f` on a thread with a 2 MiB stack (tokio's blocking threads and
/// Rust's spawned threads get that much).
fn on_2mib_stack<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> T {
    std::thread::Builder::new().stack_size(2 << 20).spawn(f).unwrap().join().unwrap()
}

/// The Spot's `description.xml` with a chain of `<Geometry>` elements inside
/// its beam, so that the document nests `depth` elements deep (the beam is
/// at level 7: GDTF, FixtureType, Geometries, Foot, Arm, Lantern, Lens).
fn spot_nested(depth: usize) -> String {
    let a = Archive::open(&gdtf("Spot")).unwrap();
    let xml = String::from_utf8(a.get("description.xml").unwrap().to_vec()).unwrap();
    let links = depth.saturating_sub(7);
    let mut chain = String::with_capacity(links * 64);
    for i in 0..links {
        chain.push_str(&format!("<Geometry Name=\"D{i}\" Position=\"{{1,0,0,0}}{{0,1,0,0}}{{0,0,1,0}}{{0,0,0,1}}\">"));
    }
    chain.push_str(&"</Geometry>".repeat(links));
    let at = xml.find("<FilterShaper").expect("the Spot's beam holds a FilterShaper");
    let mut s = xml;
    s.insert_str(at, &chain);
    s
}

/// The Spot GDTF archive nested `depth` elements deep.
fn deep_gdtf(depth: usize) -> Vec<u8> {
    zip_of(&[("description.xml", spot_nested(depth).as_bytes())])
}

/// A `GeneralSceneDescription.xml` hanging `Deep.gdtf` (mode Standard) at
/// 1.1 inside `groups` nested group objects: it nests `8 + 2 · groups`
/// elements deep (Scene, Layers, Layer, ChildList; two per group; Fixture,
/// Addresses, Address).
fn scene_xml(groups: usize) -> String {
    let mut s = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<GeneralSceneDescription verMajor=\"1\" verMinor=\"6\">\
         <Scene><Layers><Layer name=\"Rig\" uuid=\"L1\"><ChildList>",
    );
    for i in 0..groups {
        s.push_str(&format!("<GroupObject name=\"G{i}\" uuid=\"g{i}\"><ChildList>"));
    }
    s.push_str(
        "<Fixture name=\"Deep 1\" uuid=\"F1\"><GDTFSpec>Deep.gdtf</GDTFSpec><GDTFMode>Standard</GDTFMode>\
         <Addresses><Address break=\"0\">1</Address></Addresses><FixtureID>1</FixtureID></Fixture>",
    );
    s.push_str(&"</ChildList></GroupObject>".repeat(groups));
    s.push_str("</ChildList></Layer></Layers></Scene></GeneralSceneDescription>");
    s
}

/// An MVR of [`scene_xml`]`(groups)` with `gdtf` as `Deep.gdtf`.
fn mvr_with(gdtf: &[u8], groups: usize) -> Vec<u8> {
    zip_of(&[("GeneralSceneDescription.xml", scene_xml(groups).as_bytes()), ("Deep.gdtf", gdtf)])
}

/// Writes `bytes` to `dir/name` and returns the path.
fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn a_10000_deep_gdtf_is_refused_naming_the_file_and_the_limit() {
    // Issue 35 item 1: this used to overflow the stack inside the `gdtf` crate.
    let dir = temp_dir("deep-gdtf");
    let gdtf_path = write(&dir, "Deep.gdtf", &deep_gdtf(10_000));
    let toml = dir.join("deep.toml");
    std::fs::write(
        &toml,
        "[[fixture]]\nid = 1\ntype = \"Deep.gdtf\"\nmode = \"Standard\"\nuniverse = 1\naddress = 1\nposition = [0, 5, 0]\n",
    )
    .unwrap();
    let mvr_path = write(&dir, "show.mvr", &mvr_with(&std::fs::read(&gdtf_path).unwrap(), 0));
    let (g, t, m) = on_2mib_stack(move || {
        let g = Gdtf::open(&gdtf_path).map(|_| ()).unwrap_err();
        let t = check_patch(&toml).map(|_| ()).unwrap_err();
        let m = check_patch(&mvr_path).map(|_| ()).unwrap_err();
        (g, t, m)
    });
    let want = format!("nested 10000 deep (limit {GDTF_DEPTH}; <Geometry> here is the first past it)");
    assert!(g.path.ends_with("Deep.gdtf/description.xml") && g.line == 2 && g.message.contains(&want), "{g}");
    // A TOML patch naming it as a type: its error first, then the patch line.
    assert!(t[0].to_string().contains("Deep.gdtf/description.xml:2:") && t[0].message.contains(&want), "{t:?}");
    assert!(t.iter().any(|e| e.path.ends_with("deep.toml") && e.line == 3), "{t:?}");
    // Inside an MVR: the fixture's error names the entry and the limit.
    let m = m.iter().map(ToString::to_string).collect::<Vec<_>>().join("\n");
    assert!(m.contains("fixture \"Deep 1\" (id 1)") && m.contains("show.mvr/Deep.gdtf/description.xml:2:"), "{m}");
    assert!(m.contains(&want), "{m}");
}

#[test]
fn a_10000_deep_mvr_is_refused_naming_the_file_and_the_limit() {
    // Issue 35 item 2: serde's ChildList recursion used to overflow the stack.
    let dir = temp_dir("deep-mvr");
    let path = write(&dir, "deep.mvr", &mvr_with(&deep_gdtf(10), 10_000));
    let e = on_2mib_stack(move || check_patch(&path).map(|_| ()).unwrap_err());
    assert_eq!(e.len(), 1, "{e:?}");
    assert!(e[0].path.ends_with("deep.mvr/GeneralSceneDescription.xml") && e[0].line == 2, "{}", e[0]);
    let want = format!("nested 20008 deep (limit {MVR_DEPTH}; <ChildList> here is the first past it)");
    assert!(e[0].message.contains(&want), "{}", e[0]);
}

#[test]
fn the_deepest_files_allowed_load_on_a_2mib_stack() {
    // At the limits the recursive readers survive a 2 MiB stack in this
    // debug build (measured: ~250 GDTF levels, ~600 MVR levels); one level
    // more is refused. Through `check_patch`, the path of `run --patch`.
    let dir = temp_dir("deepest");
    let groups = (MVR_DEPTH - 8) / 2;
    assert_eq!(8 + 2 * groups, MVR_DEPTH, "the scene nests exactly to the limit");
    let scene_at = write(&dir, "scene-at.mvr", &mvr_with(&deep_gdtf(10), groups));
    let gdtf_at = write(&dir, "gdtf-at.mvr", &mvr_with(&deep_gdtf(GDTF_DEPTH), 0));
    let scene_over = write(&dir, "scene-over.mvr", &{
        let xml = scene_xml(groups).replace("</Address>", "<x/></Address>");
        zip_of(&[("GeneralSceneDescription.xml", xml.as_bytes()), ("Deep.gdtf", &deep_gdtf(10))])
    });
    let gdtf_over = write(&dir, "gdtf-over.mvr", &mvr_with(&deep_gdtf(GDTF_DEPTH + 1), 0));
    let results = on_2mib_stack(move || {
        let text = |r: Result<(_, Vec<footlight_fixture::PatchError>), Vec<footlight_fixture::PatchError>>| {
            let all = |e: &[footlight_fixture::PatchError]| e.iter().map(ToString::to_string).collect::<Vec<_>>();
            r.map(|(_, w)| all(&w).join("\n")).map_err(|e| all(&e).join("\n"))
        };
        [&scene_at, &gdtf_at, &scene_over, &gdtf_over].map(|p| text(check_patch(p)))
    });
    let [scene_at, gdtf_at, scene_over, gdtf_over] = results;
    // At the limits: parsed. Groups past 32 are then skipped with a warning;
    // the GDTF's 57-deep geometry chain is past the mode walk's own depth
    // (32), an error of its own, not a crash.
    let scene_at = scene_at.unwrap();
    assert!(scene_at.contains("groups nested deeper than 32"), "{scene_at}");
    let gdtf_at = gdtf_at.unwrap_err();
    assert!(gdtf_at.contains("geometry tree is deeper than 32") && !gdtf_at.contains("nested"), "{gdtf_at}");
    let scene_over = scene_over.unwrap_err();
    assert!(scene_over.contains(&format!("nested {} deep (limit {MVR_DEPTH}", MVR_DEPTH + 1)), "{scene_over}");
    let gdtf_over = gdtf_over.unwrap_err();
    assert!(gdtf_over.contains(&format!("nested {} deep (limit {GDTF_DEPTH}", GDTF_DEPTH + 1)), "{gdtf_over}");
    // The deepest nesting serde recurses hardest on (Fixture inside Fixture's
    // ChildList) also parses at the MVR limit.
    let mut xml = String::from("<GeneralSceneDescription><Scene><Layers><Layer name=\"L\"><ChildList>");
    let links = (MVR_DEPTH - 6) / 2;
    for i in 0..links {
        xml.push_str(&format!("<Fixture name=\"F{i}\" uuid=\"f{i}\"><ChildList>"));
    }
    xml.push_str("<Fixture name=\"leaf\"/>");
    xml.push_str(&"</ChildList></Fixture>".repeat(links));
    xml.push_str("</ChildList></Layer></Layers></Scene></GeneralSceneDescription>");
    assert_eq!(5 + 2 * links + 1, MVR_DEPTH);
    let zip = zip_of(&[("GeneralSceneDescription.xml", xml.as_bytes())]);
    let m = on_2mib_stack(move || {
        Archive::from_bytes(Path::new("fixtures.mvr"), zip, Limits::default()).and_then(Mvr::from_archive)
    })
    .unwrap();
    assert_eq!(m.scene.fixtures.len(), 33, "nesting past 32 is skipped with a warning");
    assert!(m.warnings.iter().any(|w| w.message.contains("nested deeper than 32")), "{:?}", m.warnings);
}

#[test]
fn symbol_fan_out_stops_at_its_budget() {
    // Issue 35 item 5: each Symdef holds two Symbols of the next, 40 deep
    // (2^40 instances through the 32-deep symbol limit; it used to expand
    // them all). The walk stops at the budget, with one warning.
    let levels = 40;
    let mut aux = String::new();
    for i in 0..levels {
        let body = if i + 1 == levels {
            "<Geometry3D fileName=\"leaf.glb\"/>".to_string()
        } else {
            format!("<Symbol symdef=\"S{0}\"/><Symbol symdef=\"S{0}\"/>", i + 1)
        };
        aux.push_str(&format!("<Symdef name=\"S{i}\" uuid=\"S{i}\"><ChildList>{body}</ChildList></Symdef>"));
    }
    let xml = format!(
        "<GeneralSceneDescription><Scene><AUXData>{aux}</AUXData><Layers><Layer name=\"L\"><ChildList>\
         <SceneObject name=\"Bomb\" uuid=\"o1\"><Geometries><Symbol symdef=\"S0\"/></Geometries></SceneObject>\
         <SceneObject name=\"After\" uuid=\"o2\"><Geometries><Geometry3D fileName=\"after.glb\"/></Geometries></SceneObject>\
         </ChildList></Layer></Layers></Scene></GeneralSceneDescription>"
    );
    let zip = zip_of(&[("GeneralSceneDescription.xml", xml.as_bytes())]);
    let t = std::time::Instant::now();
    let m = Archive::from_bytes(Path::new("bomb.mvr"), zip, Limits::default()).and_then(Mvr::from_archive).unwrap();
    let bomb = &m.scene.objects[0];
    assert!(bomb.geometries.len() <= MAX_SYMBOL_INSTANCES, "{}", bomb.geometries.len());
    let warned: Vec<_> = m.warnings.iter().filter(|w| w.message.contains("symbol instances")).collect();
    assert_eq!(warned.len(), 1, "{:?}", m.warnings);
    assert!(warned[0].message.contains(&format!("{MAX_SYMBOL_INSTANCES}")), "{}", warned[0]);
    // The objects after it are still read: their own Geometry3D are not
    // symbol instances (the file's size bounds them).
    assert_eq!(m.scene.objects.len(), 2);
    assert_eq!(m.scene.objects[1].geometries.len(), 1);
    assert!(t.elapsed().as_secs() < 20, "bounded work: {:?}", t.elapsed());
}

#[test]
fn nan_model_dimensions_are_warned_about_and_never_drawn_as_nan() {
    // Issue 35 item 6 (nit): the warning names the file and the model.
    let a = Archive::open(&gdtf("Spot")).unwrap();
    let xml = String::from_utf8(a.get("description.xml").unwrap().to_vec()).unwrap();
    let bad = xml.replace(
        "<Model Name=\"Head\" Length=\"0.25\" Width=\"0.25\" Height=\"0.4\"",
        "<Model Name=\"Head\" Length=\"NaN\" Width=\"inf\" Height=\"-0.4\"",
    );
    assert_ne!(bad, xml, "the Spot has the Head model");
    let gdtf = zip_of(&[("description.xml", bad.as_bytes())]);
    let g = Gdtf::from_bytes(Path::new("nan.gdtf"), gdtf.clone()).unwrap();
    let (_, warnings) = fixture_type(&g).unwrap();
    let w: Vec<_> = warnings.iter().filter(|w| w.message.contains("model \"Head\"")).collect();
    assert_eq!(w.len(), 1, "{warnings:?}");
    assert!(w[0].path.ends_with("nan.gdtf/description.xml"), "{}", w[0]);
    for what in ["Length NaN", "Width inf", "Height -0.4"] {
        assert!(w[0].message.contains(what), "{}", w[0]);
    }
    // The bodies: finite everywhere, at any pan and tilt.
    let dir = temp_dir("nan-model");
    let path = write(&dir, "nan.mvr", &mvr_with(&gdtf, 0));
    let (bodies, warnings) = footlight_mvr::body::fixture_bodies(&path).unwrap();
    assert_eq!(bodies.len(), 1);
    assert!(warnings.iter().any(|w| w.contains("model \"Head\"") && w.contains("nan.mvr/Deep.gdtf")), "{warnings:?}");
    let head = bodies[0].parts.iter().find(|p| p.model == "Head").unwrap();
    assert!(head.dimensions.is_finite() && head.dimensions.min_element() >= 0.0, "{}", head.dimensions);
    assert!(head.estimated, "a size the file does not give is marked estimated");
    for m in bodies[0].pose(30.0, f32::NAN) {
        assert!(m.is_finite(), "{m}");
    }
}
