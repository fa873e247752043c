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
    // The error-vs-time curves are drawn by default, as SVG (no fonts needed).
    let svg = std::fs::read_to_string(dir.join("curve-1.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("<polyline") && svg.contains(r#"fill="red""#));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
    let lin = json["linearity_max_rel_error"].as_f64().unwrap();
    assert!(lin < 1e-5, "composite vs eq. 1: {lin}");
    let mse = json["mse_vs_nine"].as_array().unwrap();
    let sum = |i: usize| mse[i][1].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).sum::<f64>();
    assert!(sum(1) < sum(0), "adaptive AA is closer to 9× than one sample");
    assert!(json["ratios"].as_array().unwrap().iter().all(|r| r["ours"].as_f64().unwrap().is_finite()));
    // Issue 14: the 150-fixture MVR imported (336 lights: two hazers are none, 24
    // pixel bars are 8 cells each, 20 blinders 2 lamps each), and 50 strobing
    // fixtures flip some lights each frame (never none, never more than all).
    assert_eq!(json["mvr"]["fixtures"].as_u64(), Some(148 - 24 + 24 * 8 - 20 + 20 * 2));
    // The pixel-bar rig: 24 bars × 8 cells; one fader recomposites fewer tiles than all of them.
    let px = &json["mvr"]["pixels"];
    assert_eq!((px["bars"].as_u64(), px["cells"].as_u64()), (Some(24), Some(192)));
    let (one, all) = (px["one_fader_tiles"].as_f64().unwrap(), px["all_faders_tiles"].as_f64().unwrap());
    assert!(one > 0.0 && one < all, "one fader {one} tiles, all faders {all}");
    assert!(json["mvr"]["import_ms"].as_f64().unwrap().is_finite());
    let flips = json["mvr"]["strobe_changed_per_frame"].as_f64().unwrap();
    assert!(flips > 0.0 && flips <= 50.0, "{flips}");
    assert!(md.contains("MVR import, show150.mvr"));
}

/// What the README and docs/live.md promise: after SIGTERM, `footlight run`
/// exits within a second under any load.
const SIGTERM_EXIT: std::time::Duration = std::time::Duration::from_secs(1);

/// Sends SIGTERM to `child` and waits for its exit, asserting the
/// documented [`SIGTERM_EXIT`] from the signal to the exit (start-up may
/// take as long as it takes; the shutdown may not).
fn sigterm_exit(child: &mut std::process::Child) -> std::process::ExitStatus {
    let stopped = Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap();
    assert!(stopped.success());
    let t = std::time::Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let took = t.elapsed();
            assert!(took < SIGTERM_EXIT, "footlight took {took:.2?} to exit after SIGTERM (documented: < 1 s)");
            return status;
        }
        if t.elapsed() >= SIGTERM_EXIT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("footlight did not exit within {SIGTERM_EXIT:?} of SIGTERM (documented: < 1 s)");
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

/// `footlight run` as a user starts it: the binary's own wiring, real UDP on
/// loopback, the typed status over HTTP, `[[input]]` routes applied, and a
/// clean exit (code 0) on SIGTERM.
#[test]
fn the_binarys_run_routes_artnet_and_stops_cleanly_on_sigterm() {
    use std::io::BufRead;
    let dir = temp_dir("run");
    let root = root();
    let patch = dir.join("routed.toml");
    let replay_patch = std::fs::read_to_string(root.join("tests/replays/replay-patch.toml")).unwrap();
    let replay_patch = replay_patch
        .replace("fixtures = \"fixtures\"", &format!("fixtures = {:?}", root.join("tests/replays/fixtures")))
        .replace("gels = \"../../patch/gels.toml\"", &format!("gels = {:?}", root.join("patch/gels.toml")));
    // The desk sends on Art-Net Port-Address 5; Port-Address 0 (the default
    // source of patch universe 1) is blocked.
    let routes = "\n[[input]]\nprotocol = \"artnet\"\nuniverse = 5\npatch_universe = 1\n\n[[input]]\nprotocol = \"artnet\"\nuniverse = 0\nblock = true\n";
    std::fs::write(&patch, format!("{replay_patch}{routes}")).unwrap();
    let mut child = footlight()
        .args(["run", "--artnet", "127.0.0.1:0", "--sacn", "off", "--http", "127.0.0.1:0"])
        .args(["--width", "64", "--height", "40", "--photons", "0", "--compositor", "cpu", "--patch"])
        .arg(&patch)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let (lines_tx, lines) = std::sync::mpsc::channel();
    let stdout = child.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = lines_tx.send(line);
        }
    });
    let (mut http, mut artnet) = (None, None);
    while http.is_none() || artnet.is_none() {
        let line = lines.recv_timeout(std::time::Duration::from_secs(120)).expect("startup lines");
        if let Some(url) = line.strip_prefix("Footlight preview: http://") {
            http = Some(url.trim_end_matches('/').parse::<std::net::SocketAddr>().unwrap());
        }
        if let Some(rest) = line.strip_prefix("listening for DMX: Art-Net ") {
            assert!(!rest.contains("Some("), "no Debug text in user messages: {line}");
            artnet = Some(rest.split(',').next().unwrap().parse::<std::net::SocketAddr>().unwrap());
        }
    }
    let (http, artnet) = (http.unwrap(), artnet.unwrap());
    let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let status = || -> serde_json::Value { serde_json::from_slice(&http_get(http, "/api/status").1).unwrap() };
    let mut slots = [0u8; 512];
    slots[0] = 77;
    let mut blocked = [0u8; 512];
    blocked[0] = 200;
    let t = std::time::Instant::now();
    let seen = loop {
        // Both arrive; only the routed one may reach the profile's dimmer.
        sock.send_to(&art_dmx(0, 0, &blocked), artnet).unwrap();
        sock.send_to(&art_dmx(5, 0, &slots), artnet).unwrap();
        std::thread::sleep(std::time::Duration::from_millis(50));
        let s = status();
        if s["lights"][0]["dmx"][0] == 77 {
            break s;
        }
        assert!(t.elapsed() < std::time::Duration::from_secs(60), "routed DMX never arrived: {s}");
    };
    assert_eq!(seen["lights"][0]["fixture"], 1, "fixture ids as in the patch: {seen}");
    // DMX on a universe nothing takes is counted and warned about, naming it.
    for _ in 0..3 {
        sock.send_to(&art_dmx(9, 0, &slots), artnet).unwrap();
    }
    let t = std::time::Instant::now();
    let warned = loop {
        let s = status();
        let w = s["warnings"].to_string();
        // The warning may show after the first of the 3 packets: wait for
        // all 3 to be counted too (the status is read while they arrive).
        let counted = s["input"]["unpatched"]
            .as_array()
            .is_some_and(|u| u.iter().any(|u| u["input"]["universe"] == 9 && u["packets"] == 3));
        if w.contains("Port-Address 9") && counted {
            break s;
        }
        assert!(t.elapsed() < std::time::Duration::from_secs(30), "no unpatched warning: {s}");
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    let unpatched = warned["input"]["unpatched"].as_array().unwrap();
    assert!(unpatched.iter().any(|u| u["input"]["universe"] == 9 && u["packets"] == 3), "{warned}");
    let blocked = unpatched.iter().find(|u| u["input"]["universe"] == 0).expect("the blocked Port-Address 0 is listed");
    assert_eq!(blocked["blocked"], true);
    assert!(
        !warned["warnings"].to_string().contains("Port-Address 0 "),
        "a blocked input is not warned about: {warned}"
    );
    assert_eq!(seen["input"]["kind"], "network");
    assert!(seen["frame"].as_u64().unwrap() > 0);
    // A tablet that dropped off Wi-Fi mid-request must not hold shutdown.
    let mut half_sent = std::net::TcpStream::connect(http).unwrap();
    std::io::Write::write_all(&mut half_sent, b"GET / HTTP/1.1\r\n").unwrap();
    let code = sigterm_exit(&mut child);
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    assert!(code.success(), "exit {code:?}: {stderr}");
    assert!(!stderr.contains('\u{1b}'), "no ANSI codes when stderr is not a terminal: {stderr}");
    assert!(!stderr.contains("ERROR") && !stderr.contains("error:"), "a healthy run logs no error: {stderr}");
}

/// Reads an RGB(A) OpenEXR file with the `exr` crate: (width, height, pixels row-major from the top).
fn read_exr(path: &std::path::Path) -> (usize, usize, Vec<[f32; 3]>) {
    use exr::prelude::*;
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution, _| {
            (resolution.width(), resolution.height(), vec![[0f32; 3]; resolution.width() * resolution.height()])
        },
        |(w, _, px), pos, (r, g, b, _a): (f32, f32, f32, f32)| px[pos.y() * *w + pos.x()] = [r, g, b],
    )
    .unwrap();
    image.layer_data.channel_data.pixels
}

/// Reads a little-endian RGB Portable Float Map written bottom row first.
fn read_pfm(path: &std::path::Path) -> (usize, usize, Vec<[f32; 3]>) {
    let bytes = std::fs::read(path).unwrap();
    let mut lines = 0;
    let mut at = 0;
    while lines < 3 {
        if bytes[at] == b'\n' {
            lines += 1;
        }
        at += 1;
    }
    let header = String::from_utf8_lossy(&bytes[..at]).to_string();
    let mut parts = header.split_whitespace();
    assert_eq!(parts.next(), Some("PF"));
    let w: usize = parts.next().unwrap().parse().unwrap();
    let h: usize = parts.next().unwrap().parse().unwrap();
    assert!(parts.next().unwrap().parse::<f32>().unwrap() < 0.0, "little-endian");
    let floats: Vec<f32> = bytes[at..].chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    assert_eq!(floats.len(), w * h * 3);
    let mut px = vec![[0f32; 3]; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = ((h - 1 - y) * w + x) * 3;
            px[y * w + x] = [floats[i], floats[i + 1], floats[i + 2]];
        }
    }
    (w, h, px)
}

#[test]
fn exr_round_trip_equals_the_composite_buffer() {
    // Issue 13.7, library side: what write_exr stores reads back bit-exact.
    use footlight::render::display::{balanced, write_exr, write_pfm};
    use glam::Vec3;
    let dir = temp_dir("exr-lib");
    let (w, h) = (7u32, 5u32);
    let mut rng = Rng(42);
    // HDR values far above display white and tiny ones: nothing is clipped or quantised.
    let linear: Vec<Vec3> =
        (0..w * h).map(|_| Vec3::new(rng.next_f32() * 5000.0, rng.next_f32() * 1e-3, rng.next_f32() * 300.0)).collect();
    let gains = Vec3::new(0.8, 1.0, 1.7);
    let stored = balanced(&linear, gains);
    write_exr(&dir.join("a.exr"), w, h, &stored).unwrap();
    write_pfm(&dir.join("a.pfm"), w, h, &stored).unwrap();
    for (name, (rw, rh, px)) in [("exr", read_exr(&dir.join("a.exr"))), ("pfm", read_pfm(&dir.join("a.pfm")))] {
        assert_eq!((rw, rh), (w as usize, h as usize), "{name}");
        for (i, (a, b)) in px.iter().zip(&stored).enumerate() {
            assert_eq!(*a, b.to_array(), "{name} pixel {i}");
        }
    }
}

#[test]
fn render_writes_linear_exr_and_pfm() {
    // Issue 13.7 through the binary: the same render as EXR and PFM, linear
    // and unclipped, with and without white balance.
    let dir = temp_dir("exr-cli");
    let run = |out: &std::path::Path, wb: &str| {
        let o = footlight()
            .args(["render", "--width", "48", "--height", "30", "--photons", "0", "--white-balance", wb, "--out"])
            .arg(out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    run(&dir.join("n.exr"), "none");
    run(&dir.join("n.pfm"), "none");
    run(&dir.join("t.exr"), "tungsten");
    let (w, h, none) = read_exr(&dir.join("n.exr"));
    assert_eq!((w, h), (48, 30));
    assert_eq!(read_pfm(&dir.join("n.pfm")).2, none, "EXR and PFM hold the same linear values");
    // No exposure and no clipping: at --white-lux 10 a PNG would clip most of
    // the stage to white (white = 10/π cd/m²); the EXR values stay the same.
    let peak = none.iter().flatten().fold(0f32, |m, &v| m.max(v));
    assert!(peak > 10.0 / std::f32::consts::PI, "peak {peak} cd/m²");
    let o = footlight()
        .args(["render", "--width", "48", "--height", "30", "--photons", "0", "--white-balance", "none"])
        .args(["--white-lux", "10", "--out"])
        .arg(dir.join("bright.exr"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(read_exr(&dir.join("bright.exr")).2, none);
    // Tungsten balance = none × the 3200 K gains, pixel by pixel.
    let gains = footlight_photometry::WhiteBalance::default().gains.to_array();
    let (_, _, tungsten) = read_exr(&dir.join("t.exr"));
    for (a, b) in tungsten.iter().zip(&none) {
        for c in 0..3 {
            assert!((a[c] - b[c] * gains[c]).abs() <= 1e-6 * b[c].abs().max(1.0), "{a:?} vs {b:?}");
        }
    }
    let o = footlight().args(["render", "--white-balance", "blue", "--out"]).arg(dir.join("x.exr")).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--white-balance"));
    let o = footlight().args(["render", "--out"]).arg(dir.join("x.tiff")).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains(".exr"));
}

/// Every numeric flag is checked when the command line is parsed: a bad
/// value is refused at once with a message naming the flag and its range,
/// never a panic, a dead task or a silent substitute (issue 12, item 6).
#[test]
fn bad_flag_values_are_refused_at_parse_time_naming_the_flag() {
    let dir = temp_dir("flags");
    let out = dir.join("never.png");
    let out = out.to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (&["render", "--dmx", "tests/replays/cue-fades.pcapng", "--at", "1e30", "--out", out], "--at"),
        (&["render", "--dmx", "tests/replays/cue-fades.pcapng", "--at", "1e19", "--out", out], "--at"),
        (&["render", "--at=-1", "--out", out], "--at"),
        (&["render", "--photons", "1000000000000", "--out", out], "--photons"),
        (&["render", "--photons=-5", "--out", out], "--photons"),
        (&["render", "--white-lux", "0", "--out", out], "--white-lux"),
        (&["render", "--white-lux=-1", "--out", out], "--white-lux"),
        (&["render", "--white-lux", "nan", "--out", out], "--white-lux"),
        (&["render", "--aa-threshold", "inf", "--out", out], "--aa-threshold"),
        (&["render", "--width", "0", "--out", out], "--width"),
        (&["render", "--depth", "1000", "--out", out], "--depth"),
        (&["render", "--estimate", "1", "--out", out], "--estimate"),
        (&["run", "--fps", "nan"], "--fps"),
        (&["run", "--fps", "0"], "--fps"),
        (&["run", "--fps", "1000"], "--fps"),
        (&["run", "--white-lux", "nan"], "--white-lux"),
        (&["replay", "tests/replays/cue-fades.pcapng", "--speed", "1e-300"], "--speed"),
        (&["replay", "tests/replays/cue-fades.pcapng", "--speed", "0"], "--speed"),
        (&["replay", "tests/replays/cue-fades.pcapng", "--speed=-1"], "--speed"),
        (&["replay", "tests/replays/cue-fades.pcapng", "--speed", "nan"], "--speed"),
    ];
    for (args, flag) in cases {
        let o = footlight().args(*args).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?} must be a usage error: {err}");
        assert!(err.contains(flag), "{args:?}: the message names {flag}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    assert!(!dir.join("never.png").exists());
    // The photon message gives the memory it would need.
    let o = footlight().args(["render", "--photons", "1000000000000", "--out", out]).output().unwrap();
    assert!(String::from_utf8_lossy(&o.stderr).contains("GB"), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `render --dmx` of a recording with no DMX for the patch says which
/// universes it holds instead of rendering the default look.
#[test]
fn render_of_a_recording_without_patched_dmx_names_its_universes() {
    let dir = temp_dir("unpatched");
    let patch = dir.join("far.toml");
    let text = std::fs::read_to_string(root().join("tests/replays/replay-patch.toml")).unwrap();
    let text = text
        .replace("fixtures = \"fixtures\"", &format!("fixtures = {:?}", root().join("tests/replays/fixtures")))
        .replace("gels = \"../../patch/gels.toml\"", &format!("gels = {:?}", root().join("patch/gels.toml")))
        .replace("universe = 1", "universe = 7");
    std::fs::write(&patch, text).unwrap();
    let o = footlight()
        .args(["render", "--width", "32", "--height", "20", "--dmx", "tests/replays/cue-fades.pcapng", "--patch"])
        .arg(&patch)
        .arg("--out")
        .arg(dir.join("x.png"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(err.contains("sACN universe 1"), "names what the recording holds: {err}");
    assert!(!dir.join("x.png").exists());
}

#[test]
fn check_and_render_a_toml_patch_with_gdtf_types() {
    let o = footlight().args(["check", "tests/data/gdtf-patch.toml"]).output().unwrap();
    let (out, err) = (String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "{err}");
    assert!(out.contains("ok, 3 fixtures on universes 1, 2"), "{out}");
    let dir = temp_dir("gdtf-patch");
    let png = dir.join("gdtf.png");
    let o = footlight()
        .args(["render", "--width", "64", "--height", "40", "--patch", "tests/data/gdtf-patch.toml", "--out"])
        .arg(&png)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(&png).unwrap().to_rgb8();
    assert!(img.pixels().any(|p| p.0.iter().any(|&c| c > 40)), "the GDTF fixtures light the stage");
}

#[test]
fn render_refine_blends_progressive_passes_into_the_still() {
    // Issue 13.4 through the binary: `--refine N` runs N progressive passes
    // after the photon-map estimate. Both estimate the same light, so the
    // refined still differs from the unrefined one only in the indirect
    // term's noise: same total to a few percent, not the same pixels.
    let dir = temp_dir("refine");
    let run = |out: &std::path::Path, refine: &str| {
        footlight()
            .args(["render", "--width", "40", "--height", "25", "--photons", "4000", "--white-balance", "none"])
            .args(["--refine", refine, "--out"])
            .arg(out)
            .output()
            .unwrap()
    };
    for (name, n) in [("r0.pfm", "0"), ("r3.pfm", "3")] {
        let o = run(&dir.join(name), n);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let (_, _, plain) = read_pfm(&dir.join("r0.pfm"));
    let (_, _, refined) = read_pfm(&dir.join("r3.pfm"));
    assert!(refined.iter().flatten().all(|v| v.is_finite()));
    assert_ne!(plain, refined, "--refine 3 changed nothing");
    let total = |img: &[[f32; 3]]| img.iter().map(|p| f64::from(p[0] + p[1] + p[2])).sum::<f64>();
    let (a, b) = (total(&plain), total(&refined));
    assert!((a - b).abs() < 0.03 * a, "total {a} unrefined vs {b} refined");
    // Refinement without photons, or a fraction of a pass, is a clear error.
    let o = footlight().args(["render", "--photons", "0", "--refine", "2", "--out"]).arg(dir.join("x.pfm")).output();
    let o = o.unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--refine"));
    let o = run(&dir.join("y.pfm"), "1.5");
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--refine"));
}

/// `footlight bench --converge-only --quick` (issue 34, item 3): the
/// renderer's picture stage by stage and the path tracer's by samples per
/// pixel, each against an independent converged path-traced reference.
/// The figures are measured, not timed here: the path tracer's error falls
/// as 1/samples (unbiased: 256 spp at most 1/64 of 1 spp's, with slack for
/// the stratified edges), and ours is within the same bound of the
/// reference as a 256-spp path tracer (a wrong indirect term, e.g. 10 %
/// too dark, would be 1e-2 off).
#[test]
fn converge_bench_section_races_the_path_tracer() {
    let dir = temp_dir("converge");
    let o = footlight().args(["bench", "--converge-only", "--quick", "--out"]).arg(&dir).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
    let errors = |key: &str| -> Vec<f64> {
        json[key].as_array().unwrap().iter().map(|p| p["rel_mse"].as_f64().unwrap()).collect()
    };
    let (ours, path) = (errors("ours"), errors("path"));
    assert!(ours.len() >= 3 && path.len() >= 2, "{ours:?} {path:?}");
    assert!(ours.iter().chain(&path).all(|e| e.is_finite() && *e >= 0.0));
    assert!(path.last().unwrap() * 32.0 < path[0], "path tracer error {path:?}");
    assert!(*ours.last().unwrap() < 5e-3, "our refined picture {ours:?}");
    assert!(json["direct"]["rel_mse"].as_f64().unwrap() < 5e-3);
    let noise = json["reference_noise"].as_f64().unwrap();
    assert!(noise > 0.0 && noise < path[0] / 100.0, "reference noise {noise}");
    let svg = std::fs::read_to_string(dir.join("error-time.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.matches("<polyline").count() == 2);
    assert!(std::fs::read_to_string(dir.join("report.md")).unwrap().contains("| refinement pass 8 |"));
    // Edge supersampling takes the direct term to the direct-only
    // reference's own noise (6e-5 at 64 spp; 5e-4 at the Whitted stage).
    let refined = errors("direct_refined");
    assert!(refined.len() >= 4 && *refined.last().unwrap() < 2e-4, "direct term by edge batch {refined:?}");
    // The indirect term by region against the path tracer's (issue 34
    // item 4), as it stands: the floor and walls away from edges within
    // 1 % (1.0006 measured), wall corners within 5 % after refinement
    // (they fell to 0.976 before SPPM's gathers were boundary-corrected);
    // the whole picture ~1 % and the boxes' faces ~9 % dark (the targets,
    // 0.5 % and 5 %, are not met: docs/rendering.md); the open edges within
    // 10 % (0.80 before they were cuts, 1.04 after).
    let region = |name: &str| -> f64 {
        let r = json["indirect_by_region"].as_array().unwrap().iter().find(|r| r["name"] == name).unwrap();
        r["refined"].as_f64().unwrap()
    };
    let rest = region("the rest of the floor and walls");
    assert!((rest - 1.0).abs() <= 0.01, "indirect away from edges {rest}");
    let corners = region("within 0.15 m of a wall corner");
    assert!((corners - 1.0).abs() <= 0.05, "wall corners' indirect {corners}");
    let open = region("within 0.3 m of an open edge");
    assert!((open - 1.0).abs() <= 0.1, "indirect at open edges {open}");
    let whole = region("whole picture");
    assert!((whole - 1.0).abs() <= 0.035, "whole picture's indirect {whole}");
    let faces = region("box faces (vertical)");
    assert!(faces > 0.85 && faces < 1.05, "box faces' indirect {faces}");
}

/// `footlight bench --pixels-only --quick`: the pixel-bar rig of the
/// 150-fixture MVR alone, its 24 bars × 8 cells built and composited.
#[test]
fn pixel_bar_bench_section_runs_alone() {
    let o = footlight().args(["bench", "--pixels-only", "--quick"]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("pixel bars: 24 bars × 8 cells = 192 lights"), "{out}");
    assert!(out.contains("all faders moving") && out.contains("one fader"), "{out}");
    // Through the live tracer: each bar's cells in one direct and one Whitted pass.
    assert!(out.contains("through the live tracer") && out.contains("(48 batched passes;"), "{out}");
}

/// A picture size that cannot fit in memory is refused when the command line
/// is parsed (exit 2, like every flag error), naming both flags and the
/// memory, instead of aborting on a failed allocation (issue 35).
#[test]
fn a_picture_too_big_for_the_machine_is_refused_at_parse_time() {
    let o =
        footlight().args(["run", "--width", "16384", "--height", "16384", "--http", "127.0.0.1:0"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    match footlight::memory::picture_too_big(16384, 16384, footlight::memory::available()) {
        Some(_) => {
            assert_eq!(o.status.code(), Some(2), "{err}");
            assert!(err.contains("--width 16384 --height 16384") && err.contains("GB"), "{err}");
            assert!(!err.contains("memory allocation"), "{err}");
        }
        // A machine with over 67 GB free would run it: this test then only
        // checks that the flags parsed (the message is checked in src/memory.rs).
        None => eprintln!("this machine fits a 16384×16384 picture; refusal not exercised"),
    }
    let o =
        footlight().args(["render", "--width", "16384", "--height", "16384", "--out", "/nonexistent/x.png"]).output();
    let o = o.unwrap();
    if footlight::memory::picture_too_big(16384, 16384, footlight::memory::available()).is_some() {
        assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    }
}

/// `render` builds only what its look lights: the default patch is the
/// paper's rig plus four dark fixtures, so its still is the paper rig's,
/// pixel for pixel, and the log says the dark ones were not built.
#[test]
fn render_of_the_default_patch_builds_only_its_lit_lights() {
    let dir = temp_dir("lit-only");
    let size = ["--width", "64", "--height", "40", "--photons", "2000"];
    let a = dir.join("default.png");
    let o = footlight().arg("render").args(size).arg("--out").arg(&a).output().unwrap();
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{log}");
    assert!(log.contains("6 of 10 lights are lit; the dark ones are not built"), "{log}");
    let b = dir.join("paper.png");
    let o = footlight().arg("render").args(size).args(["--patch", "patch/paper-rig.toml", "--out"]).arg(&b).output();
    assert!(o.unwrap().status.success());
    let (a, b) = (image::open(&a).unwrap().to_rgb8(), image::open(&b).unwrap().to_rgb8());
    assert_eq!(a.as_raw(), b.as_raw(), "dark fixtures add exactly nothing");
    assert!(a.pixels().any(|p| p.0.iter().any(|&c| c > 40)), "the look lights the stage");
}

/// `replay --loop` plays the recording again each time it ends, until
/// SIGTERM; without `--replay` the flag is refused.
#[test]
fn replay_loop_plays_the_recording_again_until_stopped() {
    use std::io::BufRead;
    let mut child = footlight()
        .args(["replay", "tests/replays/colour-chase.pcapng", "--loop", "--speed", "1000"])
        .args(["--http", "127.0.0.1:0", "--width", "32", "--height", "20", "--photons", "0", "--compositor", "cpu"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Read the log to its end (a pipe left unread would stall the daemon's logging).
    let stderr = std::io::BufReader::new(child.stderr.take().unwrap());
    let (tx, lines) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in stderr.lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let mut passes = 0;
    while passes < 3 {
        let line = lines.recv_timeout(std::time::Duration::from_secs(120)).expect("the replay's log");
        assert!(!line.contains("ERROR"), "{line}");
        assert!(!line.contains("holding the last look"), "a looped replay does not stop: {line}");
        if line.contains("replay pass") && line.contains("finished") {
            passes += 1;
        }
    }
    assert_eq!(passes, 3, "the recording played three times");
    assert!(sigterm_exit(&mut child).success());
    let o = footlight().args(["run", "--loop", "--http", "127.0.0.1:0", "--artnet", "off", "--sacn", "off"]).output();
    let o = o.unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--loop"), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A zip archive of `entries`, stored (not compressed): the GDTF and MVR
/// files the tests below build (this crate has no zip writer; `flate2`
/// gives the CRC-32).
fn stored_zip(entries: &[(&str, &[u8])]) -> Vec<u8> {
    // The fields shared by a local header (after its signature and version)
    // and a central-directory entry: flags, method 0, 1980-01-01, CRC, sizes, name length.
    let common = |crc: u32, size: u32, name: &str| {
        let mut h = Vec::new();
        for v in [0u16, 0, 0, 0x21] {
            h.extend(v.to_le_bytes());
        }
        for v in [crc, size, size] {
            h.extend(v.to_le_bytes());
        }
        h.extend((name.len() as u16).to_le_bytes());
        h
    };
    let (mut out, mut central) = (Vec::new(), Vec::new());
    for (name, data) in entries {
        let mut crc = flate2::Crc::new();
        crc.update(data);
        let (crc, size, offset) = (crc.sum(), data.len() as u32, out.len() as u32);
        out.extend(0x0403_4b50u32.to_le_bytes());
        out.extend(20u16.to_le_bytes());
        out.extend(common(crc, size, name));
        out.extend(0u16.to_le_bytes()); // extra field length
        out.extend(name.as_bytes());
        out.extend(*data);
        central.extend(0x0201_4b50u32.to_le_bytes());
        central.extend([20u8, 0, 20, 0]); // made by, needed
        central.extend(common(crc, size, name));
        central.extend([0u8; 12]); // extra and comment lengths, disk, internal and external attributes
        central.extend(offset.to_le_bytes());
        central.extend(name.as_bytes());
    }
    let (at, len, n) = (out.len() as u32, central.len() as u32, entries.len() as u16);
    out.extend(central);
    out.extend(0x0605_4b50u32.to_le_bytes());
    out.extend([0u8; 4]); // disk numbers
    out.extend(n.to_le_bytes());
    out.extend(n.to_le_bytes());
    out.extend(len.to_le_bytes());
    out.extend(at.to_le_bytes());
    out.extend(0u16.to_le_bytes()); // comment length
    out
}

/// A GDTF whose `description.xml` nests `depth` elements deep: a chain of
/// `<Geometry>` under `GDTF/FixtureType/Geometries`.
fn deep_gdtf(depth: usize) -> Vec<u8> {
    let links = depth - 3;
    let mut xml = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<GDTF DataVersion=\"1.2\"><FixtureType Name=\"Deep\" \
         ShortName=\"Deep\" FixtureTypeID=\"D0000000-0000-0000-0000-000000000000\"><Geometries>",
    );
    for i in 0..links {
        xml.push_str(&format!("<Geometry Name=\"G{i}\">"));
    }
    xml.push_str(&"</Geometry>".repeat(links));
    xml.push_str(
        "</Geometries><DMXModes><DMXMode Name=\"Standard\" Geometry=\"G0\"><DMXChannels/></DMXMode></DMXModes>\
         </FixtureType></GDTF>",
    );
    stored_zip(&[("description.xml", xml.as_bytes())])
}

/// An MVR hanging `Deep.gdtf` (mode Standard, at 1.1) inside `groups`
/// nested group objects; its scene nests `8 + 2 · groups` elements deep.
fn deep_mvr(gdtf: &[u8], groups: usize) -> Vec<u8> {
    let mut xml = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<GeneralSceneDescription verMajor=\"1\" verMinor=\"6\">\
         <Scene><Layers><Layer name=\"Rig\" uuid=\"L1\"><ChildList>",
    );
    for i in 0..groups {
        xml.push_str(&format!("<GroupObject name=\"G{i}\" uuid=\"g{i}\"><ChildList>"));
    }
    xml.push_str(
        "<Fixture name=\"Deep 1\" uuid=\"F1\"><GDTFSpec>Deep.gdtf</GDTFSpec><GDTFMode>Standard</GDTFMode>\
         <Addresses><Address break=\"0\">1</Address></Addresses><FixtureID>1</FixtureID></Fixture>",
    );
    xml.push_str(&"</ChildList></GroupObject>".repeat(groups));
    xml.push_str("</ChildList></Layer></Layers></Scene></GeneralSceneDescription>");
    stored_zip(&[("GeneralSceneDescription.xml", xml.as_bytes()), ("Deep.gdtf", gdtf)])
}

/// Runs `footlight` with `args` to its exit (at most `limit`; killed and
/// failed past it): exit code and stderr.
fn exit_of(args: &[&std::ffi::OsStr], limit: std::time::Duration) -> (Option<i32>, String) {
    let child = footlight()
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let pid = child.id();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait_with_output());
    });
    match rx.recv_timeout(limit) {
        Ok(o) => {
            let o = o.unwrap();
            (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
        }
        Err(_) => {
            let _ = Command::new("kill").args(["-KILL", &pid.to_string()]).status();
            panic!("footlight {args:?} did not exit within {limit:?}");
        }
    }
}

/// Issue 35 items 1 and 2: a GDTF (in a TOML patch, in an MVR) or an MVR
/// nested 10,000 deep used to overflow the stack and abort (exit 134):
/// `check` and `render` on the main thread, `run` on its loading thread.
/// Now each stops with exit code 1 and an error naming the file, the line
/// and the limit; `run` stops at start instead of serving without a patch.
#[test]
fn files_nested_10000_deep_exit_1_naming_the_file_and_the_limit() {
    let dir = temp_dir("deep");
    std::fs::write(dir.join("Deep.gdtf"), deep_gdtf(10_000)).unwrap();
    let toml = dir.join("deep-gdtf.toml");
    std::fs::write(
        &toml,
        "[[fixture]]\nid = 1\ntype = \"Deep.gdtf\"\nmode = \"Standard\"\nuniverse = 1\naddress = 1\nposition = [0, 5, 0]\n",
    )
    .unwrap();
    let in_mvr = dir.join("deep-gdtf.mvr");
    std::fs::write(&in_mvr, deep_mvr(&deep_gdtf(10_000), 0)).unwrap();
    let groups = dir.join("deep-groups.mvr");
    std::fs::write(&groups, deep_mvr(&deep_gdtf(10), 10_000)).unwrap();
    // Where (file:line) and what; the column depends on the names' lengths.
    let gdtf_error = "elements nested 10000 deep (limit 64; <Geometry> here is the first past it)";
    let cases = [
        (&toml, format!("{}:2: column ", dir.join("Deep.gdtf/description.xml").display()), gdtf_error),
        (
            &in_mvr,
            format!("fixture \"Deep 1\" (id 1): {}:2: column ", in_mvr.join("Deep.gdtf/description.xml").display()),
            gdtf_error,
        ),
        (
            &groups,
            format!("{}:2: column ", groups.join("GeneralSceneDescription.xml").display()),
            "elements nested 20008 deep (limit 128; <ChildList> here is the first past it)",
        ),
    ];
    let minute = std::time::Duration::from_secs(60);
    for (patch, at, what) in &cases {
        let (code, err) = exit_of(&["check".as_ref(), patch.as_os_str()], minute);
        assert_eq!(code, Some(1), "check {}: {err}", patch.display());
        assert!(
            err.contains(at.as_str()) && err.contains(what),
            "check {}: want {at:?}…{what:?} in\n{err}",
            patch.display()
        );
        let run = ["run", "--artnet", "off", "--sacn", "off", "--http", "127.0.0.1:0", "--photons", "0", "--patch"];
        let mut args: Vec<&std::ffi::OsStr> = run.iter().map(|a| a.as_ref()).collect();
        args.push(patch.as_os_str());
        let (code, err) = exit_of(&args, 3 * minute);
        assert_eq!(code, Some(1), "run --patch {}: {err}", patch.display());
        assert!(err.contains(at.as_str()) && err.contains(what), "run --patch {}: {err}", patch.display());
    }
    let png = dir.join("x.png");
    let (code, err) = exit_of(
        &["render".as_ref(), "--patch".as_ref(), in_mvr.as_os_str(), "--out".as_ref(), png.as_os_str()],
        3 * minute,
    );
    assert_eq!(code, Some(1), "render: {err}");
    assert!(err.contains(&cases[1].1) && err.contains(gdtf_error) && !png.exists(), "render: {err}");
}

/// `check` lists every fixture with its type, mode and DMX addresses, counts
/// fixtures and their cells apart, names the universes actually patched, and
/// warns about fixtures a desk cannot reach (issue 37).
#[test]
fn check_lists_fixtures_with_their_addresses_and_warns_about_unaddressed_ones() {
    let o = footlight().args(["check", "patch/default.toml"]).output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(out.lines().count(), 11, "one line per fixture and the summary: {out}");
    assert!(out.contains("    9  Moving spot stage right  [Generic moving spot (standard)]  DMX 1/21-33"), "{out}");
    assert!(out.contains("    7  LED PAR RGBW stage right  [Generic LED PAR RGBW (6ch)]  DMX 1/7-12"), "{out}");
    assert!(out.trim_end().ends_with("patch/default.toml: ok, 10 fixtures on universe 1"), "{out}");

    let o = footlight().args(["check", "patch/builtin-spots.toml"]).output().unwrap();
    let (out, err) = (String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "{err}");
    assert!(out.trim_end().ends_with("ok, 6 fixtures, none patched"), "no universe list made up: {out}");
    assert!(err.contains("6 fixture(s) have no universe and address (id 1, 2, 3, 4, 5, 6)"), "{err}");

    // An MVR pixel show: fixtures and cells counted apart, cells folded; past 40
    // fixtures in runs of one type and mode (`--list`: each fixture).
    let o = footlight().args(["check", "tests/data/mvr/show150.mvr"]).output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success());
    let summary = out.lines().last().unwrap();
    assert!(summary.ends_with("ok, 148 fixtures (336 lights: cells counted) on universes 1-5"), "{summary}");
    assert!(out.lines().any(|l| l.contains(" 8 cells] × 24  DMX ")), "the 24 pixel bars in one run: {out}");
    let o = footlight().args(["check", "--list", "tests/data/mvr/show150.mvr"]).output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.lines().filter(|l| l.contains(" cells]  DMX ")).count() == 24 + 20, "bars and blinders, each: {out}");
}

/// A festival-scale show (tools/gen_gdtf_mvr.py --festival: 231 fixtures,
/// 3,687 lights on 34 universes, a 204,450-triangle venue) checks on one
/// screen (issue 36 item 3): each warning once with its line and the
/// fixtures it concerns, the fixtures in runs, and one summary line per
/// fixture type (modelled, partly and why, or not) before the verdict.
#[test]
fn check_of_a_festival_show_fits_one_screen_with_a_line_per_fixture_type() {
    let known: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string("tests/data/mvr/festival.json").unwrap()).unwrap();
    let o = footlight().args(["check", "tests/data/mvr/festival.mvr"]).output().unwrap();
    let (out, err) = (String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "{err}");
    let lines = out.lines().count() + err.lines().count();
    assert!(lines < 60, "{lines} lines:\n{err}{out}");
    assert!(err.lines().all(|l| l.starts_with("warning: ") || l.starts_with("note: ")), "{err}");
    // The summary: one line per GDTF the show names, after "fixture types:", then the verdict.
    let types = known["types"].as_object().unwrap();
    let block: Vec<&str> =
        out.lines().skip_while(|l| *l != "fixture types:").skip(1).take_while(|l| l.starts_with("  ")).collect();
    assert_eq!(block.len(), types.len(), "{out}");
    for (file, t) in types {
        let cells = t["fixtures"].as_u64().unwrap() * t["cells_per_fixture"].as_u64().unwrap();
        let line = block.iter().find(|l| l.contains(&format!("({} fixtures", t["fixtures"]))).unwrap();
        if t["cells_per_fixture"].as_u64().unwrap() > 1 {
            assert!(block.iter().any(|l| l.contains(&format!(", {cells} cells): "))), "{file}: {out}");
        }
        assert!([": modelled", ": partly — ", ": not modelled — "].iter().any(|s| line.contains(s)), "{line}");
    }
    let missing = block.iter().find(|l| l.contains("Floor Wash 7")).unwrap();
    assert!(missing.contains("(3 fixtures): not modelled — the GDTF is not in the archive"), "{missing}");
    assert!(
        err.contains("Floor Wash 7.gdtf\" is named but not in the archive") && err.contains("(3 fixtures)"),
        "{err}"
    );
    let last = out.lines().last().unwrap();
    assert!(last.ends_with("ok, 231 fixtures (3687 lights: cells counted) on universes 1-34, 3 not patched"), "{last}");
    assert!(out.contains(&format!("scene of 2 object(s), {} triangles", known["triangles_total"])), "{out}");
    // Both extension-less GDTFSpecs resolve, each with a one-line note.
    assert_eq!(err.lines().filter(|l| l.starts_with("note: ") && l.contains("GDTFSpec")).count(), 2, "{err}");
}

/// `render` (like `run`) says what the import said once, summarised: a line
/// per fixture type (the missing GDTF among them, no longer silent) and each
/// missing body model file once with its count, not once per cell (issue 36 item 3).
#[test]
fn render_sums_up_the_import_once() {
    let dir = temp_dir("festival-render");
    let o = footlight()
        .args(["render", "--patch", "tests/data/mvr/festival.mvr", "--width", "40", "--height", "25"])
        .args(["--photons", "0", "--bodies", "--out"])
        .arg(dir.join("f.png"))
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{log}");
    assert_eq!(log.lines().filter(|l| l.contains("fixture type ")).count(), 7, "{log}");
    assert!(
        log.lines().any(|l| l.contains("WARN") && l.contains("Floor Wash 7.gdtf (3 fixtures): not modelled")),
        "{log}"
    );
    // The pixel bar's two model files, 96 bodies and 96 × 16 pixels: two lines.
    let models: Vec<&str> = log.lines().filter(|l| l.contains("is in neither models/gltf nor models/3ds")).collect();
    assert_eq!(models.len(), 2, "{log}");
    assert!(models.iter().any(|l| l.contains("\"px16_pixel\"") && l.contains("(1536 parts of 96 fixtures)")), "{log}");
    assert!(log.lines().count() < 60, "{} lines:\n{log}", log.lines().count());
}

/// An MVR whose venue has no camera opens on the "frame the rig" view, from
/// above the deck (issue 36 item 6), not on a seat level with the deck.
#[test]
fn an_mvr_without_a_camera_is_framed_from_a_designers_height() {
    let dir = temp_dir("mvr-frame");
    let o = footlight()
        .args(["render", "--patch", "tests/data/mvr/venue.mvr", "--width", "40", "--height", "25", "--photons", "0"])
        .arg("--out")
        .arg(dir.join("venue.png"))
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{log}");
    let at = log.split("framing the rig from (").nth(1).expect("the framed camera is logged");
    let xyz: Vec<f32> = at.split(')').next().unwrap().split(", ").map(|v| v.parse().unwrap()).collect();
    assert!(xyz.iter().all(|v| v.is_finite()) && xyz[1] > 2.0 && xyz[1] < 10.0, "eye {xyz:?}: above the deck");
}

/// Issue 36 item 6: haze on an MVR show. A TOML patch that names the show
/// (`show = "…"`) keeps its rig and venue and adds `[haze]`, `[[view]]` and
/// a `[look]` whose fixture ids set every cell; through the binary the
/// hazed still has light in the air where the plain show has none, and a
/// `[[fixture]]` of its own is refused with its line.
#[test]
fn a_toml_patch_adds_haze_views_and_a_look_to_an_mvr_show() {
    let dir = temp_dir("show-overlay");
    let show = root().join("tests/data/mvr/show150.mvr");
    let base = footlight_mvr::load_patch(&show).unwrap();
    // A blinder (two cells, a dimmer each) and a Fresnel, by fixture id.
    let overlay = format!(
        "show = {show:?}\n\
         [haze]\nscattering = 0.08\ng = 0.7\ndensity = 100\nmultiple = false\n\
         [[view]]\nname = \"balcony\"\nposition = [0.0, 6.0, 16.0]\ntarget = [0.0, 1.0, 0.0]\n\
         [look]\n\"1109\" = {{ dimmer = 255 }}\n\"1129\" = {{ dimmer = 255 }}\n"
    );
    let path = dir.join("hazy.toml");
    std::fs::write(&path, &overlay).unwrap();
    let patch = footlight_mvr::load_patch(&path).unwrap();
    assert_eq!(patch.fixtures.len(), base.fixtures.len(), "the show's rig, every cell");
    assert!(patch.haze.is_some() && base.haze.is_none());
    assert_eq!(patch.views.iter().map(|v| v.name.as_str()).collect::<Vec<_>>(), ["balcony"]);
    let lit: Vec<(u32, Option<u32>)> =
        patch.fixtures.iter().filter(|f| f.look.v > 0.0).map(|f| (f.id, f.cell.as_ref().map(|c| c.number))).collect();
    let blinder_cells = base.fixtures.iter().filter(|f| f.id == 1109).count();
    assert_eq!(blinder_cells, 2);
    assert_eq!(lit.iter().filter(|l| l.0 == 1109).count(), blinder_cells, "every cell of 1109: {lit:?}");
    assert_eq!(lit.iter().filter(|l| l.0 == 1129).count(), 1, "{lit:?}");
    assert_eq!(lit.len(), blinder_cells + 1, "nothing else lit: {lit:?}");
    let check = footlight().arg("check").arg(&path).output().unwrap();
    assert!(check.status.success(), "{}", String::from_utf8_lossy(&check.stderr));

    // The same look without haze, as a second overlay; both rendered.
    let clear = dir.join("clear.toml");
    std::fs::write(&clear, overlay.replace("scattering = 0.08", "scattering = 0.0")).unwrap();
    let render = |patch: &std::path::Path, name: &str| {
        let out = dir.join(name);
        let o = footlight()
            .args(["render", "--width", "80", "--height", "50", "--photons", "0", "--out"])
            .arg(&out)
            .arg("--patch")
            .arg(patch)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        read_pfm(&out).2
    };
    let (hazy, plain) = (render(&path, "hazy.pfm"), render(&clear, "clear.pfm"));
    let air = hazy.iter().zip(&plain).filter(|(h, p)| p.iter().sum::<f32>() == 0.0 && h.iter().sum::<f32>() > 0.0);
    assert!(air.count() > 20, "the beams show in the haze where the clear picture is black");

    // A fixture of its own is refused with its line.
    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        format!("show = {show:?}\n\n[[fixture]]\nid = 1\ntype = \"spot\"\nposition = [0.0, 5.0, 0.0]\n"),
    )
    .unwrap();
    let o = footlight().arg("check").arg(&bad).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("bad.toml:3") && err.contains("re-patch them in the MVR"), "{err}");
}

/// Issue 33 item 4: no path of the build checkout in the binary. Run from a
/// directory that is not the checkout, `render` finds the bundled stage and
/// patch where `FOOTLIGHT_DATA` says; with nothing there it exits 1 naming
/// the file and where it looked; without the variable it looks beside the
/// executable (a checkout's `target/`), else says the same.
#[test]
fn the_binary_finds_bundled_files_at_run_time_not_through_the_build_checkout() {
    let dir = temp_dir("elsewhere");
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let render = |data: Option<&std::path::Path>, out: &str| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_footlight"));
        c.current_dir(&dir).args(["render", "--width", "40", "--height", "25", "--photons", "0", "--out", out]);
        match data {
            Some(d) => c.env("FOOTLIGHT_DATA", d),
            None => c.env_remove("FOOTLIGHT_DATA"),
        };
        let o = c.output().unwrap();
        (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
    };
    let (code, err) = render(Some(&root()), "found.png");
    assert_eq!(code, Some(0), "{err}");
    assert!(dir.join("found.png").exists());
    let (code, err) = render(Some(&empty), "missing.png");
    assert_eq!(code, Some(1), "{err}");
    let named = format!("{}: not found in the working directory", footlight::DEFAULT_PATCH);
    assert!(err.contains(&named) && err.contains("FOOTLIGHT_DATA"), "names the file and the remedy: {err}");
    assert!(!err.contains("panicked") && !dir.join("missing.png").exists(), "{err}");
    let (code, err) = render(None, "beside.png");
    assert!(code == Some(0) || (code == Some(1) && err.contains("not found in")), "{code:?}: {err}");
}

/// No library or binary code reads the build checkout's path
/// (`env!("CARGO_MANIFEST_DIR")`); test modules (after `#[cfg(test)]`) may.
#[test]
fn no_code_outside_tests_names_the_build_checkout() {
    fn walk(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
        for e in std::fs::read_dir(dir).unwrap().map(Result::unwrap) {
            let p = e.path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    let mut files = Vec::new();
    walk(&root().join("src"), &mut files);
    let needle = concat!("env!(\"CARGO_", "MANIFEST_DIR\")");
    let offenders: Vec<String> = files
        .iter()
        .filter(|p| {
            let text = std::fs::read_to_string(p).unwrap();
            let code = text.split("#[cfg(test)]").next().unwrap_or_default();
            code.contains(needle)
        })
        .map(|p| p.display().to_string())
        .collect();
    assert!(files.len() > 20 && offenders.is_empty(), "the build checkout's path in: {offenders:?}");
}
