//! Shared helpers: small scenes built in code, a seeded RNG, image metrics.

#![allow(dead_code)]

pub mod browser;

use footlight::fixture::{Beam, Light, SpotBeam};
use footlight::render::RecursionLimits;
use footlight::render::view::{Sampling, View};
use footlight::scene::{Camera, Material, Scene, SceneBuilder};
use glam::Vec3;
use std::path::PathBuf;

/// Repository root (for bundled scenes and patches).
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Says, when `FOOTLIGHT_BLESS` rewrote a golden image, what the policy of
/// `tests/golden/README.md` asks for: a note in the commit and a row in its
/// table saying what changed and why (issue 33 item 6).
pub fn blessed(path: &std::path::Path) {
    eprintln!(
        "FOOTLIGHT_BLESS: rewrote {}. A golden is re-blessed only with a note: say in the commit what \
         changed and why, and add a row (with RMS and % of values off by > 8 against the previous \
         golden) to tests/golden/README.md",
        path.display()
    );
}

/// The bundled stage, loaded once per test that needs it.
pub fn stage() -> Scene {
    footlight::scene::load(&root().join(footlight::DEFAULT_SCENE)).expect("bundled stage loads")
}

/// The paper's rig (six lights; the goldens' and the paper figures' rig).
pub fn paper_patch() -> footlight::Patch {
    footlight::Patch::load(&root().join(footlight::PAPER_PATCH)).expect("paper rig loads")
}

/// Adds an axis-aligned horizontal square at height `y`, facing +Y.
pub fn floor(b: &mut SceneBuilder, half: f32, y: f32, material: u32) {
    let (a, c) = (-half, half);
    b.add_quad(Vec3::new(a, y, c), Vec3::new(c, y, c), Vec3::new(c, y, a), Vec3::new(a, y, a), material);
}

/// Adds a closed axis-aligned box (outward-facing).
pub fn cube(b: &mut SceneBuilder, min: Vec3, max: Vec3, material: u32) {
    let p = |x: bool, y: bool, z: bool| {
        Vec3::new(if x { max.x } else { min.x }, if y { max.y } else { min.y }, if z { max.z } else { min.z })
    };
    // Each face counter-clockwise seen from outside.
    b.add_quad(p(false, false, true), p(true, false, true), p(true, true, true), p(false, true, true), material); // +Z
    b.add_quad(p(true, false, false), p(false, false, false), p(false, true, false), p(true, true, false), material); // -Z
    b.add_quad(p(true, false, true), p(true, false, false), p(true, true, false), p(true, true, true), material); // +X
    b.add_quad(p(false, false, false), p(false, false, true), p(false, true, true), p(false, true, false), material); // -X
    b.add_quad(p(false, true, true), p(true, true, true), p(true, true, false), p(false, true, false), material); // +Y
    b.add_quad(p(false, false, false), p(true, false, false), p(true, false, true), p(false, false, true), material); // -Y
}

/// A 1 cd omnidirectional point light.
pub fn omni(position: Vec3) -> Light {
    Light::aimed(position, position + Vec3::NEG_Y, Beam::Spot(SpotBeam::from_beam_field(360.0, 360.0)))
}

/// A view with the given sampling and depth.
pub fn view(scene: &Scene, camera: Camera, w: u32, h: u32, sampling: Sampling, depth: u32) -> View {
    View::build(scene, camera, w, h, sampling, RecursionLimits { max_depth: depth, min_weight: 0.0 })
}

/// A Lambert material index.
pub fn lambert(b: &mut SceneBuilder, rho: f32) -> u32 {
    b.add_material(Material::lambert("lambert", Vec3::splat(rho)))
}

/// SplitMix64: a seeded, dependency-free RNG for test inputs.
pub struct Rng(pub u64);

impl Rng {
    /// Next value in [0, 1).
    pub fn next_f32(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// Asserts every value is finite and non-negative.
pub fn assert_finite(img: &[Vec3], what: &str) {
    for (i, v) in img.iter().enumerate() {
        assert!(v.is_finite() && v.min_element() >= 0.0, "{what}: pixel {i} = {v}");
    }
}

/// Minimal HTTP/1.1 GET over loopback (no client dependency needed).
pub fn http_get(addr: std::net::SocketAddr, path: &str) -> (String, Vec<u8>) {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(std::time::Duration::from_secs(30))).unwrap();
    write!(s, "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n").unwrap();
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).unwrap();
    let split = raw.windows(4).position(|w| w == b"\r\n\r\n").expect("header end") + 4;
    let head = String::from_utf8_lossy(&raw[..split]).to_string();
    let mut body = raw[split..].to_vec();
    if head.to_ascii_lowercase().contains("transfer-encoding: chunked") {
        let mut out = Vec::new();
        let mut b = &body[..];
        loop {
            let e = b.windows(2).position(|w| w == b"\r\n").unwrap();
            let n = usize::from_str_radix(std::str::from_utf8(&b[..e]).unwrap().trim(), 16).unwrap();
            if n == 0 {
                break;
            }
            out.extend_from_slice(&b[e + 2..e + 2 + n]);
            b = &b[e + 2 + n + 2..];
        }
        body = out;
    }
    (head, body)
}

/// The daemon's picture (`/api/frame.png`, RGB8) of a frame begun after
/// this call: two past the frame `/api/status` reports now (the next one
/// may be under way already), read until two reads agree (the PNG of a
/// picture that did not change keeps the number of the frame that first
/// showed it, and a read can get an encoding still under way of an older
/// picture). A loaded machine can lag the frame clock by more than any
/// fixed sleep, and an older frame shows an older build or display.
pub fn png_after_now(addr: std::net::SocketAddr) -> image::RgbImage {
    use std::time::{Duration, Instant};
    let frame = || -> u64 {
        let status: serde_json::Value = serde_json::from_slice(&http_get(addr, "/api/status").1).unwrap();
        status["frame"].as_u64().expect("status has the frame number")
    };
    let after = frame();
    let t = Instant::now();
    while frame() < after + 2 {
        assert!(t.elapsed() < Duration::from_secs(30), "no frame after {after}");
        std::thread::sleep(Duration::from_millis(10));
    }
    let read = || image::load_from_memory(&http_get(addr, "/api/frame.png").1).unwrap().to_rgb8();
    let mut last = read();
    loop {
        let now = read();
        if now == last {
            return now;
        }
        assert!(t.elapsed() < Duration::from_secs(30), "the picture never settled");
        last = now;
    }
}

/// An ArtDmx packet (Art-Net 4, protocol 14) for 15-bit `port_address`
/// carrying all 512 `slots`, built from the spec's field table.
pub fn art_dmx(port_address: u16, sequence: u8, slots: &[u8; 512]) -> Vec<u8> {
    let mut p = b"Art-Net\0".to_vec();
    p.extend_from_slice(&0x5000u16.to_le_bytes()); // OpCode, little-endian
    p.extend_from_slice(&14u16.to_be_bytes()); // ProtVer, big-endian
    p.extend_from_slice(&[sequence, 0, (port_address & 0xFF) as u8, (port_address >> 8) as u8 & 0x7F]);
    p.extend_from_slice(&512u16.to_be_bytes()); // Length, big-endian
    p.extend_from_slice(slots);
    p
}

/// Writes `dir/plane.bin` and `dir/<name>`: a glTF 2 m plane at y = 0 (uv
/// (0, 0) at (−1, 0, −1), u along +x, v along +z) whose matte material has
/// base-colour factor `factor` and the texture `image` (a file beside it,
/// NEAREST sampling). Returns the glTF's path.
pub fn textured_plane_gltf(dir: &std::path::Path, name: &str, image: &str, factor: f32) -> PathBuf {
    let pos: [[f32; 3]; 4] = [[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]];
    let uv: [[f32; 2]; 4] = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let idx: [u16; 6] = [0, 2, 1, 0, 3, 2];
    let mut bin: Vec<u8> = pos.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
    bin.extend(uv.iter().flatten().flat_map(|f| f.to_le_bytes()));
    bin.extend(idx.iter().flat_map(|i| i.to_le_bytes()));
    std::fs::write(dir.join("plane.bin"), &bin).unwrap();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}},"indices":2,"material":0}}]}}],
        "materials":[{{"pbrMetallicRoughness":{{"baseColorFactor":[{factor},{factor},{factor},1],"metallicFactor":0,"roughnessFactor":1,
            "baseColorTexture":{{"index":0}}}}}}],
        "textures":[{{"source":0,"sampler":0}}],"samplers":[{{"magFilter":9728,"minFilter":9728}}],
        "images":[{{"uri":"{image}"}}],
        "accessors":[
          {{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,0,-1],"max":[1,0,1]}},
          {{"bufferView":1,"componentType":5126,"count":4,"type":"VEC2"}},
          {{"bufferView":2,"componentType":5123,"count":6,"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":32}},
          {{"buffer":0,"byteOffset":80,"byteLength":12}}],
        "buffers":[{{"byteLength":92,"uri":"plane.bin"}}]}}"#
    );
    let path = dir.join(name);
    std::fs::write(&path, json).unwrap();
    path
}

/// The lights built together in one Whitted pass
/// ([`footlight::render::build::together::whitted_together`]) equal each
/// built alone with `LightBuild::whitted`: the same pixels re-shaded, every
/// pixel within 1e-6 of the light's peak.
pub fn assert_together_equals_alone(
    scene: &Scene,
    v: &View,
    lights: &[Light],
    settings: footlight::render::build::BuildSettings,
) {
    use footlight::render::build::together::whitted_together;
    use footlight::render::build::{Cancel, LightBuild};
    use footlight::render::footprint::TileBounds;
    let aa = footlight::render::AaParams::new(settings.aa_threshold);
    let bounds = TileBounds::paths(v);
    let (together, _) = whitted_together(scene, v, &bounds, lights, Some(aa), &|| false).unwrap();
    for (i, l) in lights.iter().enumerate() {
        let mut alone_build = LightBuild::new(l.clone(), i, settings, Cancel::never());
        let alone = alone_build.whitted(scene, v).unwrap().to_dense();
        let (buf, reshaded) = &together[i];
        assert_eq!(*reshaded, alone_build.reshaded(), "light {i}: same pixels re-shaded");
        let peak = alone.iter().map(|p| p.max_element()).fold(0.0f32, f32::max);
        assert!(peak > 0.0);
        for (p, (x, y)) in alone.iter().zip(&buf.to_dense()).enumerate() {
            assert!((*x - *y).abs().max_element() <= 1e-6 * peak, "light {i} pixel {p}: alone {x}, together {y}");
        }
    }
}

/// Relative MSE Σ(x − r)²/Σ r² of `img`'s green channel against a
/// per-pixel f64 `reference`, over the pixels `which` selects (0 where the
/// reference is black there).
pub fn green_rel_mse(img: &[Vec3], reference: &[f64], which: impl Fn(usize) -> bool) -> f64 {
    let (mut err, mut norm) = (0.0, 0.0);
    for (i, (v, r)) in img.iter().zip(reference).enumerate() {
        if which(i) {
            err += (f64::from(v.y) - r).powi(2);
            norm += r * r;
        }
    }
    if norm > 0.0 { err / norm } else { 0.0 }
}

/// Sends `input` and waits for the first frame where `shows` holds: it must
/// come within two frame periods of the packet (made at the next tick,
/// presented at the one after), and every frame from `before` on is
/// numbered in sequence (none skipped, none sent twice).
pub async fn first_frame_where(
    out_rx: &mut tokio::sync::watch::Receiver<std::sync::Arc<footlight::output::Frame>>,
    in_tx: &tokio::sync::watch::Sender<footlight_dmx::Universes>,
    input: footlight_dmx::Universes,
    period: std::time::Duration,
    before: &footlight::output::Frame,
    shows: impl Fn(&footlight::output::Frame) -> bool,
) -> std::sync::Arc<footlight::output::Frame> {
    in_tx.send(input).unwrap();
    let sent = tokio::time::Instant::now();
    let mut number = before.number;
    loop {
        out_rx.changed().await.unwrap();
        let frame = out_rx.borrow_and_update().clone();
        assert_eq!(frame.number, number + 1, "frames are presented in sequence");
        number = frame.number;
        if shows(&frame) {
            assert!(sent.elapsed() <= period * 2, "shown {:?} after the packet", sent.elapsed());
            return frame;
        }
        assert!(sent.elapsed() < period * 2, "not shown within two frame periods of the packet");
    }
}
