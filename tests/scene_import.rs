//! Hostile and broken glTF files (issue 12 items 2, 3 and 10): each is
//! rejected with an error naming the file and the element, or loaded with
//! the documented warning, and none panics or allocates without bound.
//! Every file is built here as JSON.

use footlight::scene::{ImportLimits, SceneError, load, load_with};
use std::path::{Path, PathBuf};

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("footlight-import-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// One triangle's positions (x, y, z) as little-endian f32.
fn tri_bytes() -> Vec<u8> {
    [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]].iter().flatten().flat_map(|f| f.to_le_bytes()).collect()
}

fn data_uri(bytes: &[u8]) -> String {
    format!("data:application/octet-stream;base64,{}", base64::encode(bytes))
}

/// A one-mesh glTF: `nodes`, `accessors`, `views`, `buffers` and `extra`
/// top-level members are spliced in as JSON.
fn gltf(nodes: &str, accessors: &str, views: &str, buffers: &str, extra: &str) -> String {
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":{nodes},
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
        "accessors":{accessors},"bufferViews":{views},"buffers":{buffers}{extra}}}"#
    )
}

const POS: &str = r#"{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,0,1]}"#;

/// The one-triangle scene with its buffer given by `buffer` (JSON).
fn triangle_with_buffer(buffer: &str) -> String {
    gltf(r#"[{"mesh":0}]"#, &format!("[{POS}]"), r#"[{"buffer":0,"byteLength":36}]"#, &format!("[{buffer}]"), "")
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn error(path: &Path) -> String {
    match load(path) {
        Ok(s) => panic!("{} loaded ({} triangles)", path.display(), s.triangle_count()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn a_good_triangle_loads() {
    let d = dir("good");
    let p = write(
        &d,
        "good.gltf",
        &triangle_with_buffer(&format!(r#"{{"byteLength":36,"uri":"{}"}}"#, data_uri(&tri_bytes()))),
    );
    let s = load(&p).unwrap();
    assert_eq!(s.triangle_count(), 1);
    assert_eq!(s.positions[0][1], glam::Vec3::X);
}

#[test]
fn node_cycles_and_shared_subtrees_are_rejected() {
    let d = dir("cycle");
    let buffer = format!(r#"{{"byteLength":36,"uri":"{}"}}"#, data_uri(&tri_bytes()));
    let accessors = format!("[{POS}]");
    let views = r#"[{"buffer":0,"byteLength":36}]"#;
    // Node 0 is its own child.
    let p = write(
        &d,
        "self.gltf",
        &gltf(r#"[{"mesh":0,"children":[0],"name":"loop"}]"#, &accessors, views, &format!("[{buffer}]"), ""),
    );
    let e = error(&p);
    assert!(e.contains("self.gltf") && e.contains("node 0 \"loop\"") && e.contains("cycle"), "{e}");
    // 0 → 1 → 2 → 0.
    let p = write(
        &d,
        "ring.gltf",
        &gltf(
            r#"[{"children":[1]},{"children":[2]},{"mesh":0,"children":[0]}]"#,
            &accessors,
            views,
            &format!("[{buffer}]"),
            "",
        ),
    );
    let e = error(&p);
    assert!(e.contains("ring.gltf") && e.contains("node 0") && e.contains("cycle"), "{e}");
    // 2^40 instances: 41 nodes, each listing the next one twice.
    let nodes: Vec<String> = (0..40)
        .map(|k| format!(r#"{{"children":[{},{}]}}"#, k + 1, k + 1))
        .chain([r#"{"mesh":0}"#.to_string()])
        .collect();
    let p =
        write(&d, "bomb.gltf", &gltf(&format!("[{}]", nodes.join(",")), &accessors, views, &format!("[{buffer}]"), ""));
    let e = error(&p);
    assert!(e.contains("bomb.gltf") && e.contains("node 39 lists node 40 twice"), "{e}");
}

#[test]
fn triangle_budget_is_checked_before_reading() {
    let d = dir("budget");
    let buffer = format!(r#"{{"byteLength":36,"uri":"{}"}}"#, data_uri(&tri_bytes()));
    // 500 nodes instancing the one-triangle mesh side by side: legal glTF, 500 triangles.
    let nodes: Vec<String> = std::iter::once(format!(
        r#"{{"children":[{}]}}"#,
        (1..=500).map(|i| i.to_string()).collect::<Vec<_>>().join(",")
    ))
    .chain((0..500).map(|k| format!(r#"{{"mesh":0,"translation":[{},0,{}]}}"#, k % 25, k / 25)))
    .collect();
    let p = write(
        &d,
        "crowd.gltf",
        &gltf(
            &format!("[{}]", nodes.join(",")),
            &format!("[{POS}]"),
            r#"[{"buffer":0,"byteLength":36}]"#,
            &format!("[{buffer}]"),
            "",
        ),
    );
    assert_eq!(load(&p).unwrap().triangle_count(), 500);
    match load_with(&p, &ImportLimits { max_triangles: 499 }) {
        Err(e @ SceneError::Budget { triangles: 500, limit: 499, .. }) => {
            assert!(e.to_string().contains("crowd.gltf"), "{e}");
        }
        other => panic!("expected the budget error, got {:?}", other.map(|s| s.triangle_count())),
    }
    match load_with(&p, &ImportLimits { max_triangles: 500 }) {
        Ok(s) => assert_eq!(s.triangle_count(), 500),
        Err(e) => panic!("{e}"),
    }
    assert_eq!(ImportLimits::default().max_triangles, 20_000_000);
    // Few triangles but many vertices per instance: 1 indexed triangle over 12 vertices, 500 times.
    let mut b = Vec::new();
    for k in 0..12 {
        b.extend([k as f32, 0.0, (k % 2) as f32].iter().flat_map(|f| f.to_le_bytes()));
    }
    b.extend([0u16, 1, 2].iter().flat_map(|i| i.to_le_bytes()));
    let json = gltf(
        &format!("[{}]", nodes.join(",")),
        r#"[{"bufferView":0,"componentType":5126,"count":12,"type":"VEC3","min":[0,0,0],"max":[11,0,1]},
            {"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}]"#,
        r#"[{"buffer":0,"byteLength":144},{"buffer":0,"byteOffset":144,"byteLength":6}]"#,
        &format!(r#"[{{"byteLength":150,"uri":"{}"}}]"#, data_uri(&b)),
        "",
    )
    .replace(r#""POSITION":0}"#, r#""POSITION":0},"indices":1"#);
    let p = write(&d, "spread.gltf", &json);
    match load_with(&p, &ImportLimits { max_triangles: 1000 }) {
        Err(SceneError::VertexBudget { vertices: 6000, limit: 3000, .. }) => {}
        other => panic!("expected the vertex budget error, got {:?}", other.map(|s| s.triangle_count())),
    }
}

#[test]
fn buffer_uris_stay_inside_the_scene_folder() {
    let top = dir("uris");
    let d = top.join("scene");
    std::fs::create_dir_all(&d).unwrap();
    std::fs::write(top.join("outside.bin"), tri_bytes()).unwrap();
    let uri = |u: &str| triangle_with_buffer(&format!(r#"{{"byteLength":36,"uri":"{u}"}}"#));
    for (name, u, why) in [
        ("devzero.gltf", "../../../../../../../../dev/zero", "outside the scene folder"),
        ("fileuri.gltf", "file:///dev/zero", "only data: URIs and paths relative"),
        ("passwd.gltf", "/etc/passwd", "absolute paths are not allowed"),
        ("outside.gltf", "../outside.bin", "outside the scene folder"),
        ("escaped.gltf", "%2E%2E/outside.bin", "outside the scene folder"),
        ("http.gltf", "http://example.com/x.bin", "only data: URIs"),
        ("missing.gltf", "nothere.bin", "cannot open"),
    ] {
        let p = write(&d, name, &uri(u));
        let e = error(&p);
        assert!(e.contains(name) && e.contains("buffer 0") && e.contains(why), "{u}: {e}");
    }
    // A symlink inside the folder that points at a device or outside it.
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink("/dev/zero", d.join("zero.bin")).unwrap();
        std::os::unix::fs::symlink(top.join("outside.bin"), d.join("link.bin")).unwrap();
        for link in ["zero.bin", "link.bin"] {
            let p = write(&d, "link.gltf", &uri(link));
            let e = error(&p);
            assert!(e.contains("outside the scene folder"), "{link}: {e}");
        }
        // A FIFO inside the folder is not a regular file (and is never opened for a blocking read).
        let fifo = d.join("fifo.bin");
        if std::process::Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success()) {
            let p = write(&d, "fifo.gltf", &uri("fifo.bin"));
            let e = error(&p);
            assert!(e.contains("not a regular file"), "{e}");
        }
    }
    // Inside the folder: read exactly byteLength bytes of a longer file; a shorter file is an error.
    let mut long = tri_bytes();
    long.extend([0xFFu8; 100]);
    std::fs::write(d.join("long.bin"), &long).unwrap();
    std::fs::create_dir_all(d.join("sub")).unwrap();
    std::fs::write(d.join("sub/short.bin"), &tri_bytes()[..20]).unwrap();
    let s = load(&write(&d, "long.gltf", &uri("long.bin"))).unwrap();
    assert_eq!(s.triangle_count(), 1);
    let e = error(&write(&d, "short.gltf", &uri("sub/short.bin")));
    assert!(e.contains("byteLength is 36") && e.contains("only 20 bytes"), "{e}");
    // A data URI shorter than byteLength too.
    let p = write(
        &d,
        "shortdata.gltf",
        &triangle_with_buffer(&format!(r#"{{"byteLength":36,"uri":"{}"}}"#, data_uri(&tri_bytes()[..24]))),
    );
    let e = error(&p);
    assert!(e.contains("only 24 bytes"), "{e}");
}

#[test]
fn accessors_are_bound_checked_before_use() {
    let d = dir("accessors");
    let bytes = tri_bytes();
    let buffer = |b: &[u8]| format!(r#"[{{"byteLength":{},"uri":"{}"}}]"#, b.len(), data_uri(b));
    let node = r#"[{"mesh":0}]"#;
    let view36 = r#"[{"buffer":0,"byteLength":36}]"#;

    // A count of 4e9 names the accessor and the bound (not "no POSITION").
    let huge = r#"[{"bufferView":0,"componentType":5126,"count":4000000000,"type":"VEC3","min":[0,0,0],"max":[1,0,1],"name":"big"}]"#;
    let e = error(&write(&d, "huge.gltf", &gltf(node, huge, view36, &buffer(&bytes), "")));
    assert!(
        e.contains("huge.gltf")
            && e.contains("accessor 0 \"big\"")
            && e.contains("count 4000000000")
            && e.contains("bufferView 0 has 36"),
        "{e}"
    );
    assert!(!e.contains("no POSITION"), "{e}");

    // A view past its buffer.
    let e = error(&write(
        &d,
        "view.gltf",
        &gltf(node, &format!("[{POS}]"), r#"[{"buffer":0,"byteOffset":8,"byteLength":36}]"#, &buffer(&bytes), ""),
    ));
    assert!(e.contains("bufferView 0") && e.contains("run past the 36 bytes of buffer 0"), "{e}");

    // A POSITION accessor index past the accessors: no validator panic.
    let bad_index =
        gltf(node, &format!("[{POS}]"), view36, &buffer(&bytes), "").replace(r#""POSITION":0"#, r#""POSITION":7"#);
    let e = error(&write(&d, "index.gltf", &bad_index));
    assert!(e.contains("index.gltf") && e.contains("accessor 7") && !e.contains("panicked"), "{e}");

    // Wrong type.
    let vec2 = POS.replace("VEC3", "VEC2");
    let e = error(&write(&d, "vec2.gltf", &gltf(node, &format!("[{vec2}]"), view36, &buffer(&bytes), "")));
    assert!(e.contains("accessor 0") && e.contains("VEC3 of FLOAT"), "{e}");

    // A stride shorter than the element.
    let e = error(&write(
        &d,
        "stride.gltf",
        &gltf(node, &format!("[{POS}]"), r#"[{"buffer":0,"byteLength":36,"byteStride":4}]"#, &buffer(&bytes), ""),
    ));
    assert!(e.contains("byteStride 4") && e.contains("12-byte element"), "{e}");

    // Indices: an index accessor past its view, and an index value past the vertices.
    let mut with_idx = bytes.clone();
    with_idx.extend([0u16, 1, 7].iter().flat_map(|i| i.to_le_bytes()));
    let views = r#"[{"buffer":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}]"#;
    let idx =
        |count: u32| format!(r#"[{POS},{{"bufferView":1,"componentType":5123,"count":{count},"type":"SCALAR"}}]"#);
    let indexed = |count: u32| {
        gltf(node, &idx(count), views, &buffer(&with_idx), "")
            .replace(r#""POSITION":0}"#, r#""POSITION":0},"indices":1"#)
    };
    let e = error(&write(&d, "idxview.gltf", &indexed(6)));
    assert!(e.contains("accessor 1") && e.contains("count 6") && e.contains("bufferView 1 has 6"), "{e}");
    let e = error(&write(&d, "idxvalue.gltf", &indexed(3)));
    assert!(e.contains("idxvalue.gltf") && e.contains("index 7 past the 3 vertices"), "{e}");

    // Sparse: one value replaced (checked against the closed result), and an index out of range.
    let mut sparse = bytes.clone();
    sparse.extend(2u16.to_le_bytes());
    sparse.extend([0.0f32, 0.0, 2.0].iter().flat_map(|f| f.to_le_bytes()));
    let views = r#"[{"buffer":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":2},{"buffer":0,"byteOffset":38,"byteLength":12}]"#;
    let sp = |i: u32| {
        let mut b = sparse.clone();
        b[36..38].copy_from_slice(&(i as u16).to_le_bytes());
        let acc = r#"[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,0,2],
            "sparse":{"count":1,"indices":{"bufferView":1,"componentType":5123},"values":{"bufferView":2}}}]"#;
        gltf(node, acc, views, &buffer(&b), "")
    };
    let s = load(&write(&d, "sparse.gltf", &sp(2))).unwrap();
    assert_eq!(s.positions[0][2], glam::Vec3::new(0.0, 0.0, 2.0));
    let e = error(&write(&d, "sparsebad.gltf", &sp(3)));
    assert!(e.contains("sparse index 3 past the 3 elements"), "{e}");
}

#[test]
fn cameras_materials_and_normals_are_checked() {
    let d = dir("values");
    let bytes = tri_bytes();
    let buffer = format!(r#"[{{"byteLength":36,"uri":"{}"}}]"#, data_uri(&bytes));
    let view = r#"[{"buffer":0,"byteLength":36}]"#;
    let with_camera = |yfov: &str| {
        gltf(
            r#"[{"mesh":0,"children":[1]},{"camera":0}]"#,
            &format!("[{POS}]"),
            view,
            &buffer,
            &format!(
                r#","cameras":[{{"type":"perspective","name":"front","perspective":{{"yfov":{yfov},"znear":0.1}}}}]"#
            ),
        )
    };
    assert!(load(&write(&d, "cam.gltf", &with_camera("0.7"))).unwrap().camera.is_some());
    for yfov in ["0", "-1", "3.2"] {
        let e = error(&write(&d, "cam.gltf", &with_camera(yfov)));
        assert!(e.contains("cam.gltf") && e.contains("camera 0 \"front\"") && e.contains("yfov"), "{yfov}: {e}");
    }
    // Factors: out of range is clamped (with a warning), non-finite is an error.
    let with_material = |roughness: &str| {
        gltf(
            r#"[{"mesh":0}]"#,
            &format!("[{POS}]"),
            view,
            &buffer,
            &format!(r#","materials":[{{"name":"floor","pbrMetallicRoughness":{{"roughnessFactor":{roughness}}}}}]"#),
        )
        .replace(r#""POSITION":0}"#, r#""POSITION":0},"material":0"#)
    };
    let s = load(&write(&d, "mat.gltf", &with_material("1.5"))).unwrap();
    assert_eq!(s.material_of[0], 1);
    assert_eq!(
        format!("{:?}", s.materials[1]),
        format!("{:?}", footlight::scene::Material::from_pbr("floor", glam::Vec3::ONE, 1.0, 1.0, 0.0, 1.5)),
        "roughness 1.5 clamps to 1"
    );
    let e = error(&write(&d, "mat.gltf", &with_material("1e39")));
    assert!(e.contains("material 0 \"floor\"") && e.contains("roughnessFactor is inf"), "{e}");
    // A NaN normal (bit pattern in the buffer) is replaced by the face normal and counted.
    let mut b = bytes.clone();
    b.extend([[f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0]].iter().flatten().flat_map(|f| f.to_le_bytes()));
    let json = gltf(
        r#"[{"mesh":0}]"#,
        &format!(r#"[{POS},{{"bufferView":1,"componentType":5126,"count":3,"type":"VEC3"}}]"#),
        r#"[{"buffer":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":36}]"#,
        &format!(r#"[{{"byteLength":72,"uri":"{}"}}]"#, data_uri(&b)),
        "",
    )
    .replace(r#""POSITION":0}"#, r#""POSITION":0,"NORMAL":1}"#);
    let s = load(&write(&d, "normals.gltf", &json)).unwrap();
    assert_eq!(s.report.non_finite_normals, 1);
    assert!(s.normals[0].iter().all(|n| n.is_finite() && (n.length() - 1.0).abs() < 1e-5));
}

#[test]
fn the_scene_file_must_be_a_regular_file() {
    let e = error(Path::new("/dev/null"));
    assert!(e.contains("/dev/null") && e.contains("not a regular file"), "{e}");
    let d = dir("nofile");
    let e = error(&d.join("absent.glb"));
    assert!(e.contains("absent.glb") && e.contains("cannot open"), "{e}");
}

/// Issue 35 item 5: glTF nests its node tree by `children` indices, not by
/// JSON nesting, so a file of a few hundred kilobytes can be 10,000 nodes
/// deep. The walk is iterative (`walk_nodes`: an explicit stack), so the
/// chain loads on a 2 MiB thread stack (the daemon's loading thread) and
/// every transform along it is applied.
#[test]
fn a_10000_deep_node_chain_loads_on_a_2mib_stack() {
    let d = dir("deep-chain");
    let depth = 10_000;
    let mut nodes: Vec<String> =
        (0..depth - 1).map(|k| format!(r#"{{"children":[{}],"translation":[0,0.001,0]}}"#, k + 1)).collect();
    nodes.push(r#"{"mesh":0,"translation":[0,0.001,0]}"#.to_string());
    let buffer = format!(r#"{{"byteLength":36,"uri":"{}"}}"#, data_uri(&tri_bytes()));
    let text = gltf(
        &format!("[{}]", nodes.join(",")),
        &format!("[{POS}]"),
        r#"[{"buffer":0,"byteLength":36}]"#,
        &format!("[{buffer}]"),
        "",
    );
    let p = write(&d, "chain.gltf", &text);
    let s = std::thread::Builder::new().stack_size(2 << 20).spawn(move || load(&p)).unwrap().join().unwrap().unwrap();
    assert_eq!(s.triangle_count(), 1);
    // 10,000 steps of 1 mm up: the triangle sits at y = 10 m (f32 sums).
    let y = s.positions[0][0].y;
    assert!((y - 10.0).abs() < 1e-2, "{y}");
}

// --- The MVR's geometry as the scene (issue 14 item 4) -------------------------

fn venue() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mvr/venue.mvr")
}

/// First hit of a ray straight down from `(x, 20, z)`: the height of the top surface there.
fn top_at(scene: &footlight::scene::Scene, x: f32, z: f32) -> Option<f32> {
    use glam::Vec3;
    scene.accel.intersect(Vec3::new(x, 20.0, z), Vec3::NEG_Y, f32::INFINITY).map(|h| 20.0 - h.t)
}

#[test]
fn mvr_geometry_is_converted_once_from_millimetres_and_z_up() {
    // venue.mvr (tools/gen_gdtf_mvr.py): GLB floor 10 m x 8 m at y = 0; a GLB
    // truss 2 x 0.3 x 0.3 m instanced 3x by a Symdef at MVR (-2500 + 2500k,
    // 2000, 6000) mm; a 3DS 1000 mm cube (z 0..1000 mm, MVR frame) at MVR
    // (2000, 0, 0) mm inside a GroupObject; a Support whose model is missing.
    let loaded = footlight::scene::load_mvr_scene(&venue()).expect("venue.mvr loads");
    let s = &loaded.scene;
    // 2 floor + 3 x 12 truss + 12 cube + 2 panel + 2 sign (cube.3ds) + 12 stand-in.
    assert_eq!(s.triangle_count(), 2 + 36 + 16 + 12, "{:?}", loaded.warnings);
    assert_eq!(loaded.objects, 6);
    // The 3DS cube: mm -> m, MVR x stays x, MVR z (up) -> stage y: it stands on
    // the floor (y 0..1 m) centred on x = 2 m, z = 0.
    let top = top_at(s, 2.0, 0.0).expect("the cube");
    assert!((top - 1.0).abs() < 1e-5, "cube top at {top}");
    assert!((top_at(s, 2.45, 0.45).unwrap() - 1.0).abs() < 1e-5);
    assert!(top_at(s, 2.55, 0.0).unwrap().abs() < 1e-5, "beside the cube: the floor");
    assert!(top_at(s, 1.45, 0.0).unwrap().abs() < 1e-5);
    // Its bottom sits on y = 0 (a ray up from under the floor meets it there).
    let up = s.accel.intersect(glam::Vec3::new(2.0, -1.0, 0.3), glam::Vec3::Y, f32::INFINITY).unwrap();
    assert!((up.t - 1.0).abs() < 1e-5, "{}", up.t);
    // GLB floor (metres, Y up: passes through unchanged) spans x ±5, z ±4.
    assert!(top_at(s, -4.9, 3.9).unwrap().abs() < 1e-5);
    assert!(top_at(s, 5.1, 0.0).is_none());
    // Trusses: MVR y = 2000 mm upstage -> stage z = -2, MVR z = 6000 mm -> y = 6;
    // the box's top is 0.15 m above its centre line.
    for x in [-2.5, 0.0, 2.5] {
        let t = top_at(s, x + 0.9, -2.0).expect("a truss");
        assert!((t - 6.15).abs() < 1e-5, "truss at x {x}: top {t}");
    }
    assert!(top_at(s, 0.0, -1.8).unwrap().abs() < 1e-5, "trusses are 0.3 m deep");
    // The missing hoist model: a warning naming it, and a 0.5 m stand-in cube
    // standing at MVR (-4000, 2000, 6000) mm -> (-4, 6..6.5, -2).
    assert!(
        loaded.warnings.iter().any(|w| w.contains("chain_hoist.glb") && w.contains("Hoist 1")),
        "{:?}",
        loaded.warnings
    );
    assert!((top_at(s, -4.0, -2.0).unwrap() - 6.5).abs() < 1e-5);
    // And cube.3ds's sign names a texture map the archive lacks (its own test below).
    assert_eq!(loaded.warnings.len(), 2, "{:?}", loaded.warnings);
    // The floor's base-colour texture comes from the GLB's binary chunk inside
    // the archive: factor 0.5 × a NEAREST 2×2 checker, sRGB 255 where x and z
    // share a sign, 64 elsewhere.
    let albedo = |x: f32, z: f32| {
        let h = s.accel.intersect(glam::Vec3::new(x, 0.5, z), glam::Vec3::NEG_Y, f32::INFINITY).unwrap();
        s.diffuse_at(&s.surface(&h))
    };
    for (x, z, byte) in [(-3.0, -3.0, 255), (3.0, 3.0, 255), (3.0, -3.0, 64), (-3.0, 3.0, 64)] {
        let want = 0.5 * srgb_byte(byte);
        let got = albedo(x, z);
        assert!((got - glam::Vec3::splat(want)).abs().max_element() < 1e-6, "floor at ({x}, {z}): {got} vs {want}");
    }
}

#[test]
fn mvr_scene_budget_counts_every_instance() {
    let limits = ImportLimits { max_triangles: 20 };
    let err = match footlight::scene::mvr_scene::load_mvr_scene_with(&venue(), &limits) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("66 triangles loaded under a budget of 20"),
    };
    assert!(err.contains("venue.mvr/") && err.contains("limit of"), "{err}");
}

// --- Base-colour textures (issue 14 item 4, also for plain glTF scenes) --------

/// sRGB byte → linear (IEC 61966-2-1), written out here independently of the importer.
fn srgb_byte(b: u8) -> f32 {
    let c = f64::from(b) / 255.0;
    (if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }) as f32
}

#[test]
fn a_textured_plane_shades_each_texel_as_its_albedo() {
    use crate::common::{omni, view};
    use footlight::render::view::Sampling;
    use glam::Vec3;
    // A 2 m plane at y = 0: uv (0, 0) at (-1, 0, -1), u along +x, v along +z;
    // a 2×2 checker PNG beside the file, NEAREST sampling, factor 0.8.
    let d = dir("texture");
    let texels: [[u8; 3]; 4] = [[255, 0, 0], [0, 200, 0], [30, 60, 255], [128, 128, 128]];
    let mut img = image::RgbImage::new(2, 2);
    for (i, t) in texels.iter().enumerate() {
        img.put_pixel(i as u32 % 2, i as u32 / 2, image::Rgb(*t));
    }
    img.save(d.join("checker.png")).unwrap();
    let scene = load(&crate::common::textured_plane_gltf(&d, "textured.gltf", "checker.png", 0.8))
        .expect("textured plane loads");
    assert!(scene.materials[1].base_texture.is_some());
    let light_pos = Vec3::new(0.2, 2.0, 0.1);
    let cam = footlight::scene::Camera::look_at(Vec3::new(0.0, 4.0, 0.01), Vec3::ZERO, 40f32.to_radians());
    let (w, h) = (48, 48);
    let v = view(&scene, cam, w, h, Sampling::One, 0);
    let (buf, _) = v.render_light(&scene, &omni(light_pos), None);
    let mut seen = [0usize; 4];
    for y in 0..h {
        for x in 0..w {
            let s = v.gbuffer.samples[(y * w + x) as usize][footlight::render::gbuffer::CENTRE_SAMPLE];
            let Some(p) = v.gbuffer.position(&scene, &s) else { continue };
            // Skip pixels on a texel edge (x = 0 or z = 0) and off the plane.
            if p.x.abs() < 0.02 || p.z.abs() < 0.02 || p.x.abs() > 0.98 || p.z.abs() > 0.98 {
                continue;
            }
            let texel = usize::from(p.x > 0.0) + 2 * usize::from(p.z > 0.0);
            let rho = Vec3::from_array(texels[texel].map(srgb_byte)) * 0.8;
            assert_lambert_under_1cd(buf.get(x, y), rho, light_pos, p, &format!("({x},{y}) texel {texel}"));
            seen[texel] += 1;
        }
    }
    assert!(seen.iter().all(|&n| n > 20), "every texel checked: {seen:?}");
}

#[test]
fn footlight_check_reports_the_mvr_scene() {
    let run = |file: &str| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_footlight"))
            .arg("check")
            .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mvr").join(file))
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (String::from_utf8_lossy(&o.stdout).into_owned(), String::from_utf8_lossy(&o.stderr).into_owned())
    };
    let (out, err) = run("venue.mvr");
    assert!(out.contains("scene of 6 object(s), 66 triangles"), "{out}");
    assert!(err.contains("\"Hoist 1\"") && err.contains("chain_hoist.glb"), "{err}");
    // A rig without scene objects is lit on the bundled stage.
    let (out, _) = run("show150.mvr");
    assert!(out.contains("no scene objects; shows use the bundled stage"), "{out}");
}

#[test]
fn mangled_3ds_files_never_panic() {
    use footlight::scene::mvr_scene::{Materials3ds, add_3ds, materials_3ds, parse_3ds};
    let archive = footlight_mvr::archive::Archive::open(&venue()).unwrap();
    let cube = archive.get("cube.3ds").expect("cube.3ds in venue.mvr").to_vec();
    let label = Path::new("venue.mvr/cube.3ds");
    let limits = ImportLimits::default();
    // The intact file: 12 cube + 2 panel + 2 sign triangles.
    let mut b = footlight::scene::SceneBuilder::new();
    add_3ds(
        label,
        &parse_3ds(label, &cube).unwrap(),
        glam::DMat4::IDENTITY,
        &Materials3ds::uniform(0),
        &mut b,
        &limits,
    )
    .unwrap();
    assert_eq!(b.triangle_count(), 16);
    // Seeded mutations (bytes overwritten, truncations): an error or a
    // scene, never a panic; an index past the vertices is reported.
    let mut rng = crate::common::Rng(0x3D5);
    let (mut errors, mut loaded) = (0, 0);
    for _ in 0..3000 {
        let mut bytes = cube.clone();
        for _ in 0..1 + (rng.next_f32() * 4.0) as usize {
            let i = (rng.next_f32() * bytes.len() as f32) as usize % bytes.len();
            bytes[i] = (rng.next_f32() * 256.0) as u8;
        }
        if rng.next_f32() < 0.2 {
            bytes.truncate((rng.next_f32() * bytes.len() as f32) as usize);
        }
        let mut b = footlight::scene::SceneBuilder::new();
        match parse_3ds(label, &bytes) {
            Err(e) => {
                assert!(e.contains("cube.3ds"), "{e}");
                errors += 1;
            }
            // The material chunks of the same bytes: materials (or grey and a
            // warning naming the file), never a panic, and the faces placed.
            Ok(m) => match add_3ds(
                label,
                &m,
                glam::DMat4::IDENTITY,
                &{
                    let mut warnings = Vec::new();
                    let mats = materials_3ds(label, "cube.3ds", &bytes, &m, &archive, 0, &mut b, &mut warnings);
                    assert!(warnings.iter().all(|w| w.contains("cube.3ds")), "{warnings:?}");
                    mats
                },
                &mut b,
                &limits,
            ) {
                Ok(()) => loaded += 1,
                Err(e) => {
                    assert!(e.to_string().contains("cube.3ds"), "{e}");
                    errors += 1;
                }
            },
        }
    }
    assert!(errors > 100 && loaded > 100, "errors {errors}, loaded {loaded}");
}

/// venue.mvr's cube.3ds materials, as tools/gen_gdtf_mvr.py writes them
/// (COLOR_24 bytes, gamma-corrected: sRGB-encoded).
const CUBE_PAINT: [u8; 3] = [200, 60, 20];
const PANEL_COLOUR: [u8; 3] = [90, 90, 200];
const SIGN_COLOUR: [u8; 3] = [30, 160, 90];
/// PANEL.PNG: 8×8 texels in 4×4 blocks, block (bx, by) from the top-left.
const PANEL_BLOCKS: [[u8; 3]; 4] = [[255, 0, 0], [0, 200, 0], [30, 60, 255], [128, 128, 128]];

#[test]
fn three_ds_materials_give_their_colours_and_the_missing_map_a_warning() {
    use glam::Vec3;
    let loaded = footlight::scene::load_mvr_scene(&venue()).expect("venue.mvr loads");
    let s = &loaded.scene;
    let hit_down = |x: f32, z: f32| s.accel.intersect(Vec3::new(x, 20.0, z), Vec3::NEG_Y, f32::INFINITY).unwrap();
    let rgb = |b: [u8; 3]| Vec3::from_array(b.map(srgb_byte));
    // The cube (its MSH_MAT_GROUP nested in the face array, as real files
    // have it): "Cube paint", sRGB → linear of its COLOR_24 bytes.
    let h = hit_down(2.0, 0.0);
    let m = &s.materials[s.material_of[h.triangle as usize] as usize];
    assert!(m.name.contains("Cube paint"), "{}", m.name);
    let got = s.diffuse_at(&s.surface(&h));
    assert!((got - rgb(CUBE_PAINT)).abs().max_element() < 1e-6, "cube {got} vs {}", rgb(CUBE_PAINT));
    assert!(m.base_texture.is_none());
    // The sign's map sign.png is not in the archive: one warning naming it
    // and the material, and its own colour.
    let h = hit_down(0.5, 0.0);
    assert!((20.0 - h.t - 0.5).abs() < 1e-5, "the sign at y 0.5: {}", 20.0 - h.t);
    let got = s.diffuse_at(&s.surface(&h));
    assert!((got - rgb(SIGN_COLOUR)).abs().max_element() < 1e-6, "sign {got} vs {}", rgb(SIGN_COLOUR));
    let missing: Vec<_> = loaded.warnings.iter().filter(|w| w.contains("sign.png")).collect();
    assert_eq!(missing.len(), 1, "{:?}", loaded.warnings);
    assert!(missing[0].contains("\"Sign\"") && missing[0].contains("cube.3ds"), "{}", missing[0]);
    // The panel's map PANEL.PNG is found (as panel.png, at the archive root):
    // it replaces the colour PANEL_COLOUR.
    let h = hit_down(3.25, -0.25);
    let m = &s.materials[s.material_of[h.triangle as usize] as usize];
    assert!(m.name.contains("Panel print") && m.base_texture.is_some(), "{}", m.name);
    assert_ne!(s.diffuse_at(&s.surface(&h)), rgb(PANEL_COLOUR));
}

#[test]
fn a_textured_3ds_face_shades_each_texel_as_its_albedo() {
    use crate::common::{omni, view};
    use footlight::render::view::Sampling;
    use glam::Vec3;
    // cube.3ds's panel: 1 m square facing up at y = 0.5, x 3..4, z -0.5..0.5;
    // 3DS UVs u = x - 3, v = 0.5 - z (v up from the image's bottom), so the
    // image's top-left block lies at x < 3.5, z < 0.
    let loaded = footlight::scene::load_mvr_scene(&venue()).expect("venue.mvr loads");
    let scene = &loaded.scene;
    let light_pos = Vec3::new(3.6, 2.5, 0.1);
    let cam =
        footlight::scene::Camera::look_at(Vec3::new(3.5, 3.0, 0.01), Vec3::new(3.5, 0.5, 0.0), 30f32.to_radians());
    let (w, h) = (48, 48);
    let v = view(scene, cam, w, h, Sampling::One, 0);
    let (buf, _) = v.render_light(scene, &omni(light_pos), None);
    let mut seen = [0usize; 4];
    for y in 0..h {
        for x in 0..w {
            let s = v.gbuffer.samples[(y * w + x) as usize][footlight::render::gbuffer::CENTRE_SAMPLE];
            let Some(p) = v.gbuffer.position(scene, &s) else { continue };
            let (u, t) = (p.x - 3.0, p.z + 0.5);
            // On the panel, away from block edges (bilinear is exact there:
            // a texel is 0.125 m) and from its rim (the texture repeats).
            if (p.y - 0.5).abs() > 1e-3 || !(0.07..0.93).contains(&u) || !(0.07..0.93).contains(&t) {
                continue;
            }
            if (u - 0.5).abs() < 0.07 || (t - 0.5).abs() < 0.07 {
                continue;
            }
            let block = usize::from(u > 0.5) + 2 * usize::from(t > 0.5);
            let rho = Vec3::from_array(PANEL_BLOCKS[block].map(srgb_byte));
            assert_lambert_under_1cd(buf.get(x, y), rho, light_pos, p, &format!("({x},{y}) block {block}"));
            seen[block] += 1;
        }
    }
    assert!(seen.iter().all(|&n| n > 20), "every block checked: {seen:?}");
}

#[test]
fn mvr_model_placement_agrees_with_pymvr() {
    // pymvr (PyPI, installed by .ci/run) reads the same files; a Python
    // script composes layer, group, object, symbol and Geometry3D matrices.
    if !std::process::Command::new("python3").args(["-c", "import pymvr"]).output().is_ok_and(|o| o.status.success()) {
        assert!(
            std::env::var_os("FOOTLIGHT_REQUIRE_PEERS").is_none(),
            "FOOTLIGHT_REQUIRE_PEERS is set but python3 cannot import pymvr"
        );
        eprintln!("skipped: python3 with pymvr is missing (.ci/run installs it with pip)");
        return;
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("crates/footlight-mvr/tests/peers/geometry.py");
    for file in ["venue.mvr", "features.mvr"] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mvr").join(file);
        let o = std::process::Command::new("python3").arg(&script).arg(&path).output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let peer: Vec<(String, String, Vec<f64>)> = serde_json::from_slice(&o.stdout).unwrap();
        let mvr = footlight_mvr::mvr::Mvr::open(&path).unwrap();
        let mut ours: Vec<(String, String, Vec<f64>)> = mvr
            .scene
            .objects
            .iter()
            .flat_map(|obj| {
                obj.geometries
                    .iter()
                    .map(|(f, m)| (obj.name.clone(), f.clone(), m.transpose().to_cols_array().to_vec()))
            })
            .collect();
        let mut peer = peer;
        let key = |a: &(String, String, Vec<f64>), b: &(String, String, Vec<f64>)| (&a.0, &a.1).cmp(&(&b.0, &b.1));
        ours.sort_by(key);
        peer.sort_by(key);
        assert_eq!(ours.len(), peer.len(), "{file}: models placed");
        assert!(ours.len() >= 4, "{file}");
        for (a, b) in ours.iter().zip(&peer) {
            assert_eq!((&a.0, &a.1), (&b.0, &b.1), "{file}");
            for (x, y) in a.2.iter().zip(&b.2) {
                assert!((x - y).abs() < 1e-6, "{file}: {} {}: {:?} vs pymvr {:?}", a.0, a.1, a.2, b.2);
            }
        }
    }
}

#[test]
fn photon_bounces_take_their_albedo_from_the_texture() {
    // A closed 4 m box, white factor × a texture of linear 0.5 everywhere:
    // each bounce keeps ρ = 0.5 of the power, so the stored indirect power
    // is Φ ρ/(1−ρ) (closed form). Were the texture ignored, ρ would be 1.
    use footlight::render::photon::{PhotonSettings, trace_photons};
    use footlight::scene::{Material, SceneBuilder, Texture};
    use glam::Vec3;
    let half = Texture::from_linear("half", 2, 2, vec![Vec3::splat(0.5); 4]).unwrap();
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material {
        base_texture: Some(std::sync::Arc::new(half)),
        ..Material::lambert("textured white", Vec3::ONE)
    });
    crate::common::cube(&mut b, Vec3::splat(-2.0), Vec3::splat(2.0), m);
    let scene = b.build();
    let light = crate::common::omni(Vec3::new(0.3, -0.2, 0.1));
    let maps = trace_photons(&scene, &light, &PhotonSettings { stored: 50_000, seed: 7, ..PhotonSettings::default() });
    let total: Vec3 = maps.global.photons.iter().map(|p| p.power).sum();
    let expected = maps.flux * 0.5 / (1.0 - 0.5);
    assert!((total.x - expected).abs() < 0.04 * expected, "stored indirect power {} vs {expected}", total.x);
}

#[test]
fn render_bodies_draws_the_rig_over_the_still() {
    // features.mvr on the bundled stage, all lights dark: the only change
    // --bodies makes is body pixels, each the work-lit housing
    // ρ_body/π · E_work (lenses glow with k_i = 0).
    let dir = dir("bodies");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let render = |name: &str, bodies: bool| {
        let out = dir.join(name);
        let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_footlight"));
        c.args(["render", "--width", "160", "--height", "100", "--photons", "0", "--white-balance", "none"])
            .arg("--patch")
            .arg(root.join("tests/data/mvr/features.mvr"))
            .arg("--scene")
            .arg(root.join("scenes/stage.glb"))
            .arg("--out")
            .arg(&out);
        if bodies {
            c.arg("--bodies");
        }
        let o = c.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let bytes = std::fs::read(&out).unwrap();
        let header_end = bytes.iter().enumerate().filter(|(_, b)| **b == b'\n').nth(2).unwrap().0 + 1;
        bytes[header_end..].chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect::<Vec<f32>>()
    };
    let plain = render("plain.pfm", false);
    let with = render("bodies.pfm", true);
    assert_eq!(plain.len(), with.len());
    let housing =
        footlight::render::bodies::BODY_ALBEDO / std::f32::consts::PI * footlight::render::bodies::WORK_LIGHT_LUX;
    let mut changed = 0;
    for (a, b) in plain.iter().zip(&with) {
        if a != b {
            assert!((b - housing).abs() < 1e-5, "a body pixel is {b}, the housing {housing}");
            changed += 1;
        }
    }
    assert!(changed >= 3 * 4, "{changed} channel values changed");
}

/// `got` is a Lambert surface of albedo `rho` at `p` (normal +y) under a
/// 1 cd point light at `light`: ρ/π · E with E = cos θ / d², within 1e-4.
fn assert_lambert_under_1cd(got: glam::Vec3, rho: glam::Vec3, light: glam::Vec3, p: glam::Vec3, what: &str) {
    let d = light - p;
    let e = d.y / d.length() / d.length_squared();
    let expected = rho / std::f32::consts::PI * e;
    assert!(
        (got - expected).abs().max_element() <= 1e-4 * expected.max_element(),
        "{what} at {p}: got {got}, expected {expected}"
    );
}

// --- Files a model inside an MVR references resolve inside the archive (issue 36 item 4) ---

/// A zip (deflated) of `entries`: a small MVR made here.
fn mvr_zip(entries: &[(&str, &[u8])]) -> Vec<u8> {
    use std::io::Write;
    let mut buf = std::io::Cursor::new(Vec::new());
    let mut w = zip::ZipWriter::new(&mut buf);
    for (name, data) in entries {
        w.start_file(*name, zip::write::SimpleFileOptions::default()).unwrap();
        w.write_all(data).unwrap();
    }
    w.finish().unwrap();
    buf.into_inner()
}

/// A scene description with one SceneObject whose Geometry3D is `file`, at the origin.
fn one_object_gsd(file: &str) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<GeneralSceneDescription verMajor="1" verMinor="6"><Scene><Layers><Layer name="Venue" uuid="L1"><ChildList>
<SceneObject name="Quad" uuid="O1"><Matrix>{{1,0,0}}{{0,1,0}}{{0,0,1}}{{0,0,0}}</Matrix>
<Geometries><Geometry3D fileName="{file}"/></Geometries></SceneObject>
</ChildList></Layer></Layers></Scene></GeneralSceneDescription>"#
    )
}

/// A 1 m textured quad at y = 0 (u along x, v along z) as glTF JSON whose
/// buffer is the file `buffer_uri` (`byte_length` declared) and whose
/// base-colour image is the file `image_uri`; and that buffer's bytes.
fn quad_gltf(buffer_uri: &str, byte_length: usize, image_uri: &str) -> (String, Vec<u8>) {
    let pos: [[f32; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 0.0, 1.0]];
    let uv: [[f32; 2]; 4] = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let idx: [u16; 6] = [0, 3, 2, 0, 2, 1];
    let mut bin: Vec<u8> = pos.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
    bin.extend(uv.iter().flatten().flat_map(|f| f.to_le_bytes()));
    bin.extend(idx.iter().flat_map(|i| i.to_le_bytes()));
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}},"indices":2,"material":0}}]}}],
        "materials":[{{"pbrMetallicRoughness":{{"baseColorTexture":{{"index":0}},"metallicFactor":0}}}}],
        "textures":[{{"source":0}}],"images":[{{"uri":"{image_uri}"}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[0,0,0],"max":[1,0,1]}},
          {{"bufferView":1,"componentType":5126,"count":4,"type":"VEC2"}},
          {{"bufferView":2,"componentType":5123,"count":6,"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":32}},
          {{"buffer":0,"byteOffset":80,"byteLength":12}}],
        "buffers":[{{"uri":"{buffer_uri}","byteLength":{byte_length}}}]}}"#
    );
    (json, bin)
}

/// A 2 × 1 PNG: red on the left, blue on the right (sRGB 255: linear 1).
fn red_blue_png() -> Vec<u8> {
    let img = image::RgbImage::from_raw(2, 1, vec![255, 0, 0, 0, 0, 255]).unwrap();
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

#[test]
fn a_gltf_inside_an_mvr_reads_its_buffer_and_texture_from_the_archive() {
    let d = dir("mvr-files");
    let png = red_blue_png();
    // models/quad.gltf reads models/quad.bin and models/maps/red-blue.png: paths from its own folder.
    let load = |name: &str, buffer_uri: &str, byte_length: Option<usize>, image_uri: &str| {
        let (json, bin) = quad_gltf(buffer_uri, byte_length.unwrap_or(92), image_uri);
        let gsd = one_object_gsd("models/quad.gltf");
        let zip = mvr_zip(&[
            ("GeneralSceneDescription.xml", gsd.as_bytes()),
            ("models/quad.gltf", json.as_bytes()),
            ("models/quad.bin", &bin),
            ("models/maps/red-blue.png", &png),
            ("secret.bin", &bin),
        ]);
        let path = d.join(name);
        std::fs::write(&path, zip).unwrap();
        footlight::scene::load_mvr_scene(&path).expect("the MVR loads (a bad model is a stand-in)")
    };
    let good = load("good.mvr", "quad.bin", None, "maps/red-blue.png");
    assert!(good.warnings.is_empty(), "{:?}", good.warnings);
    assert_eq!(good.scene.triangle_count(), 2);
    let tex = good.scene.materials.iter().find_map(|m| m.base_texture.clone()).expect("a textured material");
    let (left, right) = (tex.sample(glam::Vec2::new(0.25, 0.5)), tex.sample(glam::Vec2::new(0.75, 0.5)));
    assert!((left - glam::Vec3::X).length() < 1e-5 && (right - glam::Vec3::Z).length() < 1e-5, "{left} {right}");
    // `./` and a percent-escaped name are the same file.
    let escaped = load("escaped.mvr", "./quad%2Ebin", None, "maps/red%2Dblue.png");
    assert!(escaped.warnings.is_empty() && escaped.scene.triangle_count() == 2, "{:?}", escaped.warnings);
    // Confined to the archive: no `..`, no absolute path, no scheme; a missing
    // file or a short one is an error; each is a stand-in cube with one warning.
    let refused = [
        ("dotdot.mvr", "../secret.bin", None, "`..`"),
        ("absolute.mvr", "/secret.bin", None, "absolute"),
        ("drive.mvr", "C:\\\\secret.bin", None, "absolute"),
        ("scheme.mvr", "file:///etc/passwd", None, "only data: URIs and paths relative"),
        ("missing.mvr", "nothing.bin", None, "\"models/nothing.bin\" is not in the archive"),
        (
            "short.mvr",
            "quad.bin",
            Some(200),
            "byteLength is 200, but \"models/quad.bin\" in the archive has only 92 bytes",
        ),
    ];
    for (name, uri, len, why) in refused {
        let s = load(name, uri, len, "maps/red-blue.png");
        assert_eq!(s.warnings.len(), 1, "{name}: {:?}", s.warnings);
        assert!(s.warnings[0].contains(why) && s.warnings[0].contains("stand-in"), "{name}: {}", s.warnings[0]);
        assert_eq!(s.scene.triangle_count(), 12, "{name}: the stand-in cube");
    }
    // An image that is not in the archive leaves the constant factor, with a warning; the mesh loads.
    let no_image = load("no-image.mvr", "quad.bin", None, "maps/none.png");
    assert_eq!(no_image.scene.triangle_count(), 2, "{:?}", no_image.warnings);
}

#[test]
fn the_festival_venue_reads_its_texture_and_buffer_files_from_the_archive() {
    // tests/data/mvr/festival.mvr (tools/gen_gdtf_mvr.py --festival): festival_ground.glb samples
    // textures/grass.png and festival_stage.gltf reads festival_stage.bin, both files of the archive.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let known: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("tests/data/mvr/festival.json")).unwrap()).unwrap();
    let loaded = footlight::scene::load_mvr_scene(&root.join("tests/data/mvr/festival.mvr")).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    assert_eq!(loaded.scene.triangle_count() as u64, known["triangles_total"].as_u64().unwrap());
    assert!(known["triangles_total"].as_u64().unwrap() >= 200_000);
    assert!(loaded.scene.camera.is_none(), "a camera-less venue");
    let grass = loaded.scene.materials.iter().find_map(|m| m.base_texture.clone()).expect("the ground's texture");
    // textures/grass.png's texels are green (sRGB (v/2, 60 + v, v/3), v in 40..64).
    let texel = grass.sample(glam::Vec2::new(0.3, 0.7));
    assert!(texel.y > 2.0 * texel.x && texel.y > 2.0 * texel.z, "{texel}");
}
