//! The `footlight` binary as a user runs it: renders, error messages that
//! name file and line, and the quick benchmark report.

use crate::common::*;
use std::process::Command;

fn footlight() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_footlight"));
    c.current_dir(root());
    c
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("footlight-test-{}-{name}", std::process::id()));
    // Fresh every run: a leftover from an earlier run with the same pid must not count as the user's file.
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn render_writes_a_png_of_the_requested_size() {
    let dir = temp_dir("render");
    let out = dir.join("still.png");
    let o = footlight().args(["render", "--width", "120", "--height", "75", "--out"]).arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(&out).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (120, 75));
    assert!(img.pixels().any(|p| p.0.iter().any(|&c| c > 40)), "the default look lights the stage");
    // An existing file is never replaced without --force.
    let before = std::fs::read(&out).unwrap();
    let o = footlight().args(["render", "--width", "40", "--height", "25", "--out"]).arg(&out).output().unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("already exists"));
    assert_eq!(std::fs::read(&out).unwrap(), before, "the user's file is untouched");
    let o =
        footlight().args(["render", "--width", "40", "--height", "25", "--force", "--out"]).arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(image::open(&out).unwrap().to_rgb8().dimensions(), (40, 25));
}

#[test]
fn broken_patch_and_scene_name_file_and_line() {
    let dir = temp_dir("broken");
    let patch = dir.join("bad.toml");
    std::fs::write(
        &patch,
        "[[fixture]]\nid = 1\ntype = \"spot\"\nposition = [0, 5, 5]\naim = [0, 0, 0]\nintensity = -3\n",
    )
    .unwrap();
    let o = footlight().args(["render", "--out"]).arg(dir.join("x.png")).arg("--patch").arg(&patch).output().unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bad.toml:6:") && err.contains("intensity"), "{err}");

    let scene = dir.join("bad.glb");
    std::fs::write(&scene, b"glTF\x02\0\0\0garbage").unwrap();
    let o = footlight().args(["render", "--out"]).arg(dir.join("x.png")).arg("--scene").arg(&scene).output().unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bad.glb"), "{err}");
    assert!(!dir.join("x.png").exists(), "no output on error");
}

/// Minimal base64 (RFC 4648) for a data-URI buffer in a test glTF.
fn base64(data: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in data.chunks(3) {
        let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
        for i in 0..4 {
            if i <= c.len() {
                s.push(T[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

#[test]
fn gltf_with_nan_and_degenerate_triangles_renders_finite() {
    // Three triangles: a good floor piece, one with a NaN vertex, one with zero area.
    let verts: [[f32; 3]; 9] = [
        [-5.0, 0.0, 5.0],
        [5.0, 0.0, 5.0],
        [0.0, 0.0, -5.0],
        [0.0, 1.0, 0.0],
        [f32::NAN, 1.0, 0.0],
        [1.0, 1.0, 1.0],
        [0.0, 2.0, 0.0],
        [1.0, 2.0, 0.0],
        [2.0, 2.0, 0.0],
    ];
    let bytes: Vec<u8> = verts.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":9,"type":"VEC3","min":[-5,0,-5],"max":[5,2,5]}}],
        "bufferViews":[{{"buffer":0,"byteLength":{n}}}],
        "buffers":[{{"byteLength":{n},"uri":"data:application/octet-stream;base64,{b64}"}}]}}"#,
        n = bytes.len(),
        b64 = base64(&bytes)
    );
    let dir = temp_dir("nan");
    let scene_path = dir.join("nan.gltf");
    std::fs::write(&scene_path, json).unwrap();
    let scene = footlight::scene::load(&scene_path).expect("loads, dropping bad triangles");
    assert_eq!(scene.triangle_count(), 1);
    assert_eq!((scene.report.non_finite, scene.report.degenerate), (1, 1));
    let patch = dir.join("p.toml");
    std::fs::write(&patch, "[camera]\nposition = [0, 4, 6]\nlook_at = [0, 0, 0]\n[[fixture]]\nid = 1\ntype = \"spot\"\nposition = [0, 3, 0]\naim = [0, 0, 0]\nbeam_angle = 60\nintensity = 1000\n").unwrap();
    let out = dir.join("nan.png");
    let o = footlight()
        .args(["render", "--width", "64", "--height", "40", "--out"])
        .arg(&out)
        .arg("--scene")
        .arg(&scene_path)
        .arg("--patch")
        .arg(&patch)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("dropped 1 triangle(s) with NaN/Inf vertices and 1 with zero area")
    );
}

#[test]
fn quick_bench_writes_a_consistent_report() {
    let dir = temp_dir("bench");
    let o = footlight().args(["bench", "--quick", "--out"]).arg(&dir).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    assert!(md.contains("illumination: adaptive AA / 1 sample"));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
    let lin = json["linearity_max_rel_error"].as_f64().unwrap();
    assert!(lin < 1e-5, "composite vs eq. 1: {lin}");
    let mse = json["mse_vs_nine"].as_array().unwrap();
    let sum = |i: usize| mse[i][1].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).sum::<f64>();
    assert!(sum(1) < sum(0), "adaptive AA is closer to 9× than one sample");
    assert!(json["ratios"].as_array().unwrap().iter().all(|r| r["ours"].as_f64().unwrap().is_finite()));
}
