//! The spot's gate on stage (issue 14): framing-shutter cuts on a floor
//! against their pin-hole projection, the gobo/shutter golden image through
//! the binary, and spinning gobos rebuilt at a bounded rate by the live
//! decoder.

use crate::common::*;
use footlight::fixture::beam::{Blade, Gate, ShapedBeam};
use footlight::fixture::state::{Change, SPIN_UPDATE_HZ, classify};
use footlight::fixture::{Beam, Light, SpotBeam};
use footlight::live::{Decode, FrameClock, Show, Tracer, TracerSettings};
use footlight::output::Stage;
use footlight::render::composite::Compositor;
use footlight::render::view::Sampling;
use footlight::render::{Display, RecursionLimits, View};
use footlight::scene::{Camera, SceneBuilder};
use glam::{Vec2, Vec3};
use std::path::PathBuf;
use std::process::Command;
use std::sync::Arc;
use std::time::{Duration, Instant};

#[test]
fn blade_cut_on_the_floor_is_exactly_dark_beyond_its_projected_line() {
    let mut b = SceneBuilder::new();
    let m = lambert(&mut b, 1.0);
    floor(&mut b, 20.0, 0.0, m);
    let scene = b.build();
    let h = 3.0;
    let pos = Vec3::new(0.0, h, 0.0);
    let spot = SpotBeam::from_beam_field(20.0, 30.0);
    // Blade 1 straight in to 0.3 of the diameter, blade 2 tilted (A 0.2, B 0.6), shaper turned 10°.
    let mut gate = Gate { shaper_rot: 10.0, ..Gate::default() };
    gate.blades[0] = Blade { a: 0.3, b: 0.3, rot: 0.0 };
    gate.blades[1] = Blade { a: 0.2, b: 0.6, rot: 0.0 };
    let light = Light::aimed(pos, Vec3::ZERO, Beam::Shaped(Box::new(ShapedBeam::new(spot.clone(), gate))));
    let cam = Camera::look_at(Vec3::new(0.0, 5.0, 0.01), Vec3::ZERO, 50f32.to_radians());
    let (w, hgt) = (96, 96);
    let v = view(&scene, cam, w, hgt, Sampling::One, 0);
    let (buf, _) = v.render_light(&scene, &light, None);
    // The edges' end points in the gate (module doc of beam::gate), turned by the shaper,
    // projected through the pin hole onto the floor: a blade's floor line.
    let t = spot.outer.tan();
    let turn = Vec2::from_angle(10f32.to_radians());
    let floor_of = |g: Vec2| {
        let g = turn.rotate(g);
        let d = light.rotation * Vec3::new(g.x * t, g.y * t, -1.0);
        pos + d * (h / -d.y)
    };
    // Blade 1 (home +y): ends (−1, 0.4) and (1, 0.4); blade 2 (home +x): (0.6, 1) and (−0.2, −1).
    let lines = [
        (floor_of(Vec2::new(-1.0, 0.4)), floor_of(Vec2::new(1.0, 0.4)), floor_of(Vec2::new(0.0, 1.0))),
        (floor_of(Vec2::new(0.6, 1.0)), floor_of(Vec2::new(-0.2, -1.0)), floor_of(Vec2::new(1.0, 0.0))),
    ];
    // Signed side of floor point p relative to line a→b, positive on the blade's home side.
    let side = |(a, b, home): (Vec3, Vec3, Vec3), p: Vec3| {
        let cross = |u: Vec3, v: Vec3| u.x * v.z - u.z * v.x;
        let s = cross(b - a, p - a);
        if cross(b - a, home - a) > 0.0 { s } else { -s }
    };
    let (mut dark, mut lit) = (0, 0);
    for y in 0..hgt {
        for x in 0..w {
            let s = v.gbuffer.samples[(y * w + x) as usize][footlight::render::gbuffer::CENTRE_SAMPLE];
            let p = v.gbuffer.position(&scene, &s).unwrap();
            let got = buf.get(x, y).x;
            let cut = lines.iter().map(|l| side(*l, p)).fold(f32::MIN, f32::max);
            if cut > 1e-3 {
                assert_eq!(got, 0.0, "({x},{y}) at {p}: beyond a blade line");
                dark += 1;
            } else if cut < -1e-3 {
                // Unchanged: the open spot's closed form, 1 − smoothstep over the penumbra.
                let d = pos - p;
                let theta = (d.y / d.length()).acos();
                let u = ((theta - spot.inner) / (spot.outer - spot.inner)).clamp(0.0, 1.0);
                let pattern = if theta <= spot.inner { 1.0 } else { 1.0 - u * u * (3.0 - 2.0 * u) };
                let expected = pattern / std::f32::consts::PI * (d.y / d.length()) / d.length_squared();
                assert!((got - expected).abs() <= 0.01 * expected + 1e-6, "({x},{y}): {got} vs {expected}");
                if expected > 1e-3 {
                    lit += 1;
                }
            }
        }
    }
    // Both regions are well covered: the cut removes a real part of the pool.
    let inside_cone = |p: Vec3| (pos - p).normalize().y > spot.outer.cos();
    assert!(inside_cone(floor_of(Vec2::new(0.0, 0.8))), "blade 1's cut is inside the cone");
    assert!(dark > 300 && lit > 300, "dark {dark}, lit {lit}");
}

/// Runs `footlight render` with `args` (plus size, no photons) and compares
/// with tests/golden/`name`.png (bless with FOOTLIGHT_BLESS=1); returns the
/// number of clearly lit pixels.
fn render_matches_golden(name: &str, args: &[&str]) -> usize {
    let dir = root().join("target/golden");
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join(format!("{name}.{}.png", std::process::id()));
    let o = Command::new(env!("CARGO_BIN_EXE_footlight"))
        .current_dir(root())
        .arg("render")
        .args(args)
        // The goldens were made under the 3200 K balance, the default before
        // `--white-balance auto` (which balances these 7000 K spots for 7000 K).
        .args(["--photons", "0", "--width", "480", "--height", "300", "--white-balance", "tungsten"])
        .args(["--force", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let actual = image::open(&out).unwrap().to_rgb8();
    let _ = std::fs::remove_file(&out);
    let golden_path: PathBuf = root().join(format!("tests/golden/{name}.png"));
    let lit = actual.pixels().filter(|p| p.0.iter().any(|&c| c > 60)).count();
    if std::env::var_os("FOOTLIGHT_BLESS").is_some() {
        actual.save(&golden_path).unwrap();
        blessed(&golden_path);
        return lit;
    }
    let golden = image::open(&golden_path).expect("golden image (bless with FOOTLIGHT_BLESS=1)").to_rgb8();
    assert_eq!(golden.dimensions(), actual.dimensions());
    let diffs: Vec<u8> = golden.as_raw().iter().zip(actual.as_raw()).map(|(a, b)| a.abs_diff(*b)).collect();
    let mean = diffs.iter().map(|&d| f64::from(d)).sum::<f64>() / diffs.len() as f64;
    let large = diffs.iter().filter(|&&d| d > 8).count() as f64 / diffs.len() as f64;
    if mean > 0.5 || large > 0.001 {
        let actual_path = dir.join(format!("{name}.actual.png"));
        actual.save(&actual_path).unwrap();
        panic!(
            "{name} render differs from golden: mean |Δ| {mean:.3}/255, {:.3} % off by > 8; see {}",
            large * 100.0,
            actual_path.display()
        );
    }
    lit
}

/// Gobos and shutter cuts on the floor, seen from above: five GDTF spots in
/// a TOML patch with a camera (tests/data/gate-patch.toml: ring, bars
/// turned, two blades, ring through a 3-facet prism, frosted bars with a blade).
#[test]
fn gobos_and_shutter_cuts_on_the_floor_match_the_golden_image() {
    let lit = render_matches_golden("gate", &["--patch", "tests/data/gate-patch.toml"]);
    assert!(lit > 2000, "{lit} lit pixels");
}

/// The same gates from an MVR (tests/data/mvr/gate.mvr: the spots turned
/// upstage onto the cyclorama), set by `--set` as a desk would, seen from
/// the stage's own camera.
#[test]
fn gobos_and_shutter_cuts_from_an_mvr_match_the_golden_image() {
    let mut set: Vec<String> = Vec::new();
    for k in 0..5u16 {
        let a = 1 + 30 * k;
        // 16-bit dimmer full, shutter open.
        set.extend([format!("1/{}=255", a + 4), format!("1/{}=255", a + 5), format!("1/{}=40", a + 6)]);
    }
    // 1 ring; 2 bars at 59.5°; 3 blades 1 and 2 (tilted); 4 ring + prism; 5 bars, frost, blade 3.
    for s in ["1/9=10", "1/39=20", "1/40=21", "1/77=100", "1/78=100", "1/79=60", "1/80=160"] {
        set.push(s.into());
    }
    for s in ["1/99=10", "1/101=128", "1/129=20", "1/136=255", "1/141=90", "1/142=90"] {
        set.push(s.into());
    }
    let set = set.join(",");
    let lit = render_matches_golden("gate-mvr", &["--patch", "tests/data/mvr/gate.mvr", "--set", &set]);
    assert!(lit > 300, "{lit} lit pixels");
}

#[test]
fn a_spinning_gobo_is_rebuilt_at_a_bounded_rate() {
    let mut patch = footlight_mvr::load_patch(&root().join("tests/data/gate-patch.toml")).unwrap();
    // Fixture 1: ring gobo; gobo1pos 255 = continuous rotation at 360 °/s.
    let mut u = patch.look_universes.clone();
    u.set_slot(1, 10, 255);
    patch.fixtures.truncate(1);
    let show = Show::new(patch).unwrap();
    let mut last = show.decode_at(&u, 0.0);
    assert!(last[0].state.gobo_spin > 300.0, "{}", last[0].state.gobo_spin);
    let mut rebuilds = 0;
    let seconds = 2.0;
    let frames = (60.0 * seconds) as usize;
    for f in 1..=frames {
        let now = show.decode_at(&u, f as f64 / 60.0);
        if classify(&last[0].state, &now[0].state) == Change::Geometry {
            rebuilds += 1;
            assert_ne!(now[0].light, last[0].light, "the turned gobo is a new beam");
        }
        last = now;
    }
    // 60 Hz frames, rebuilt at most SPIN_UPDATE_HZ times a second, and it does turn.
    assert!(
        rebuilds as f64 <= SPIN_UPDATE_HZ * seconds + 1.0 && rebuilds as f64 >= SPIN_UPDATE_HZ * seconds - 1.0,
        "{rebuilds}"
    );
    // Without the time, the state is still (decode ignores the clock).
    assert_eq!(classify(&show.decode(&u)[0].state, &show.decode(&u)[0].state), Change::Unchanged);
}

/// A rotation with nothing in the beam to turn (an open gobo slot, no
/// prism in) does not change the beam: the light is never rebuilt for it
/// (issue 38: the festival show's profiles, prism out with its rotation
/// channel at 128, were rebuilt 15 times a second and never converged).
/// The same spin with the ring gobo in turns the beam (the test above).
#[test]
fn a_rotation_with_nothing_in_the_beam_is_no_rebuild() {
    let mut patch = footlight_mvr::load_patch(&root().join("tests/data/gate-patch.toml")).unwrap();
    let mut u = patch.look_universes.clone();
    // Fixture 1: gobo wheel on its open slot, gobo1pos 255 = rotation at 360 °/s.
    u.set_slot(1, 9, 0);
    u.set_slot(1, 10, 255);
    patch.fixtures.truncate(1);
    let show = Show::new(patch).unwrap();
    let first = show.decode_at(&u, 0.0);
    assert!(first[0].state.gobo_spin > 300.0, "{}", first[0].state.gobo_spin);
    for f in 1..=120 {
        let now = show.decode_at(&u, f as f64 / 60.0);
        assert_eq!(classify(&first[0].state, &now[0].state), Change::Unchanged, "frame {f}");
        assert_eq!(now[0].light, first[0].light);
    }
    // With the ring in, the same rotation turns the beam within a clock step.
    u.set_slot(1, 9, 10);
    let ring = (show.decode_at(&u, 0.0), show.decode_at(&u, 1.5 / SPIN_UPDATE_HZ));
    assert_eq!(classify(&ring.0[0].state, &ring.1[0].state), Change::Geometry);
}

#[test]
fn the_frame_clock_rebuilds_a_spinning_gobo_only_when_its_angle_steps() {
    let mut patch = footlight_mvr::load_patch(&root().join("tests/data/gate-patch.toml")).unwrap();
    let mut u = patch.look_universes.clone();
    u.set_slot(1, 10, 255); // fixture 1's ring gobo turning at 360 °/s
    patch.fixtures.truncate(1);
    let mut b = SceneBuilder::new();
    let m = lambert(&mut b, 0.8);
    floor(&mut b, 10.0, 0.0, m);
    let scene = Arc::new(b.build());
    let cam = Camera::look_at(Vec3::new(-4.4, 6.0, 2.0), Vec3::new(-4.4, 0.0, 0.2), 50f32.to_radians());
    let view = View::build(&scene, cam, 32, 32, Sampling::One, RecursionLimits::default());
    let mut settings = TracerSettings { threads: 1, ..TracerSettings::default() };
    settings.build.photons = None;
    let tracer = Arc::new(Tracer::new(scene.clone(), Arc::new(view), 1, settings));
    let mut clock = FrameClock::new(
        Arc::new(Show::new(patch).unwrap()),
        tracer.clone(),
        Compositor::new(32, 32, Display::neutral(1000.0)),
    );
    // Waits until the light has published past generation `after` and is Ready.
    let ready_after = |tracer: &Tracer, after: u64| {
        let t = Instant::now();
        loop {
            let p = tracer.published(0);
            if p.stage == Stage::Ready && p.generation > after {
                return p.generation;
            }
            assert!(t.elapsed() < Duration::from_secs(60), "tracer stuck at {:?}", p.stage);
            std::thread::sleep(Duration::from_millis(5));
        }
    };
    let step = 1.0 / SPIN_UPDATE_HZ;
    clock.tick_at(&u, 0.1 * step);
    let g0 = ready_after(&tracer, 0);
    // Later frames within the same clock step: no request (nothing pending, nothing new published).
    for f in [0.3, 0.6, 0.9] {
        clock.tick_at(&u, f * step);
        let report = tracer.report(0).unwrap();
        assert!(report.pending_ms.is_none(), "no rebuild requested within a step");
        assert_eq!((tracer.published(0).stage, tracer.published(0).generation), (Stage::Ready, g0));
    }
    // The next step turns the gobo by 360°/15 = 24°: the light is rebuilt.
    clock.tick_at(&u, 1.1 * step);
    assert!(ready_after(&tracer, g0) > g0, "a stepped spin is a rebuild");
}

/// `tests/data/textures/checker.jpg`: a baseline JPEG of flat 8×8 blocks,
/// encoded by `tools/gen_gdtf_mvr.py` without any JPEG library (its
/// `JPEG_BLOCKS`): block values row by row.
const JPEG_BLOCKS: [[u8; 3]; 2] = [[255, 0, 128], [64, 200, 10]];

fn checker_jpeg() -> Vec<u8> {
    std::fs::read(root().join("tests/data/textures/checker.jpg")).expect("checker.jpg (tools/gen_gdtf_mvr.py)")
}

/// A JPEG wheel slot image as a gobo: the gate decoder (`footlight_mvr::gate::decode`,
/// what a GDTF's `wheels/<MediaFileName>.jpg` goes through) reads every
/// block's transmission v/255 at the block's texel centres.
#[test]
fn jpeg_wheel_image_decodes_to_its_blocks() {
    let gobo = footlight_mvr::gate::decode("checker", &checker_jpeg()).expect("JPEG gobo decodes");
    assert_eq!(gobo.size(), (24, 16));
    for (by, row) in JPEG_BLOCKS.iter().enumerate() {
        for (bx, &v) in row.iter().enumerate() {
            for (dx, dy) in [(1, 1), (3, 4), (6, 6)] {
                let (x, y) = (bx * 8 + dx, by * 8 + dy);
                let p = Vec2::new((x as f32 + 0.5) / 24.0 * 2.0 - 1.0, 1.0 - (y as f32 + 0.5) / 16.0 * 2.0);
                let t = gobo.sample(p);
                assert!((t - f32::from(v) / 255.0).abs() <= 1.01 / 255.0, "texel ({x},{y}): {t} vs {v}/255");
            }
        }
    }
}

/// A JPEG base-colour texture through the glTF importer (glTF 2.0 allows
/// PNG and JPEG images): a plane whose material's texture is checker.jpg
/// reads every block as its sRGB value made linear.
#[test]
fn jpeg_base_colour_texture_loads_through_gltf() {
    use footlight::scene::texture::srgb_to_linear;
    let d = std::env::temp_dir().join(format!("footlight-jpeg-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    std::fs::write(d.join("checker.jpg"), checker_jpeg()).unwrap();
    let plane = crate::common::textured_plane_gltf(&d, "plane.gltf", "checker.jpg", 1.0);
    let scene = footlight::scene::load(&plane).expect("textured plane loads");
    let texture = scene.materials.iter().find_map(|m| m.base_texture.clone()).expect("the JPEG texture is used");
    assert_eq!(texture.size(), (24, 16));
    for (by, row) in JPEG_BLOCKS.iter().enumerate() {
        for (bx, &v) in row.iter().enumerate() {
            let (x, y) = (bx * 8 + 3, by * 8 + 4);
            let got = texture.sample(Vec2::new((x as f32 + 0.5) / 24.0, (y as f32 + 0.5) / 16.0));
            let lin = |b: f32| srgb_to_linear(b.clamp(0.0, 255.0) / 255.0);
            let (lo, hi) = (lin(f32::from(v) - 1.0), lin(f32::from(v) + 1.0));
            for c in got.to_array() {
                assert!(c >= lo - 1e-6 && c <= hi + 1e-6, "block ({bx},{by}): {got} vs sRGB {v}");
            }
        }
    }
    std::fs::remove_dir_all(&d).ok();
}
