//! Fixture bodies from the GDTF model (issue 14 item 5): the drawn
//! silhouettes of `tests/data/mvr/bodies.mvr` (a glb head on a moving head,
//! a 3ds can, a primitives-only par; tools/gen_gdtf_mvr.py) against the
//! projection of the dimensions written in the generator, posed here by
//! hand from the GDTF rules (pan about the Axis' Z, tilt about X, GDTF Z up
//! → stage Y up).

use footlight::render::bodies::{Body, BodyLayer, body_models};
use footlight::scene::{Camera, SceneBuilder};
use glam::{Mat3, Vec3};
use std::path::Path;

const W: u32 = 400;
const H: u32 = 250;

/// GDTF fixture frame → stage for an unrotated MVR fixture: (X, Y, Z) → (X, Z, −Y).
fn gdtf_to_stage(p: Vec3) -> Vec3 {
    Vec3::new(p.x, p.z, -p.y)
}

/// Pinhole projection of a stage point to continuous pixel coordinates.
fn project(cam: &Camera, p: Vec3) -> (f32, f32) {
    let rel = cam.basis.transpose() * (p - cam.position);
    let t = (cam.yfov * 0.5).tan();
    let aspect = W as f32 / H as f32;
    let x = (rel.x / (-rel.z * t * aspect) + 1.0) * 0.5 * W as f32;
    let y = (1.0 - rel.y / (-rel.z * t)) * 0.5 * H as f32;
    (x, y)
}

/// Outline samples of a box `lo..hi` (its corners) in GDTF coordinates.
fn box_points(lo: Vec3, hi: Vec3) -> Vec<Vec3> {
    (0..8).map(|i| Vec3::new([lo.x, hi.x][i & 1], [lo.y, hi.y][(i >> 1) & 1], [lo.z, hi.z][(i >> 2) & 1])).collect()
}

/// Outline samples of a cylinder along Z (rims, 720 points each).
fn cylinder_points(r: f32, z0: f32, z1: f32) -> Vec<Vec3> {
    (0..720)
        .flat_map(|k| {
            let a = k as f32 / 720.0 * std::f32::consts::TAU;
            [Vec3::new(r * a.cos(), r * a.sin(), z0), Vec3::new(r * a.cos(), r * a.sin(), z1)]
        })
        .collect()
}

/// The pixel-centre extent (x0, y0, x1, y1 inclusive) the points' hull should cover.
fn expected_extent(cam: &Camera, stage_points: &[Vec3]) -> (f32, f32, f32, f32) {
    let mut e = (f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY);
    for &p in stage_points {
        let (x, y) = project(cam, p);
        e = (e.0.min(x), e.1.min(y), e.2.max(x), e.3.max(y));
    }
    // Pixel centres at i + 0.5 inside [min, max].
    ((e.0 - 0.5).ceil(), (e.1 - 0.5).ceil(), (e.2 - 0.5).floor(), (e.3 - 0.5).floor())
}

fn drawn_extent(layer: &BodyLayer, body: u32) -> (f32, f32, f32, f32) {
    let mut e = (f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY);
    for (i, h) in layer.hits.iter().enumerate() {
        if h.is_some_and(|h| h.body == body) {
            let (x, y) = ((i as u32 % W) as f32, (i as u32 / W) as f32);
            e = (e.0.min(x), e.1.min(y), e.2.max(x), e.3.max(y));
        }
    }
    e
}

fn close(a: (f32, f32, f32, f32), b: (f32, f32, f32, f32)) -> bool {
    [(a.0, b.0), (a.1, b.1), (a.2, b.2), (a.3, b.3)].iter().all(|(x, y)| (x - y).abs() <= 1.0)
}

#[test]
fn glb_3ds_and_primitive_bodies_span_their_model_dimensions_at_any_pan_tilt() {
    let path = Path::new("tests/data/mvr/bodies.mvr");
    let import = footlight_mvr::load_mvr(path).expect("bodies.mvr loads");
    let fixtures = &import.patch.fixtures;
    let names: Vec<String> = fixtures.iter().map(|f| f.name.clone()).collect();
    let ids: Vec<u32> = fixtures.iter().map(|f| f.id).collect();
    let (models, warnings) = body_models(path, &names, &ids);
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(models.len(), 3);
    assert!(models.iter().all(|m| !m.is_estimated()), "every body from its GDTF model");
    let scene = SceneBuilder::new().build(); // nothing hides a body
    let cam = Camera::look_at(Vec3::new(0.0, 3.0, 9.0), Vec3::new(0.0, 4.0, 0.0), 35f32.to_radians());
    let (pan, tilt) = (90.0f32, 60.0f32);
    let bodies: Vec<Body> = models
        .iter()
        .map(|m| {
            let f = &fixtures[m.driver];
            let mut state = f.look;
            state.pan = pan;
            state.tilt = tilt;
            m.pose(&f.light_of(&state), pan, tilt)
        })
        .collect();
    let layer = BodyLayer::build(&scene, &cam, W, H, &bodies);

    // Head glb at stage (-2, 4, 0): Foot cube 0.4 x 0.4 x 0.2; the Lantern
    // (0, 0, -0.3) under pan (Z) and tilt (X); its glb box scaled to
    // X [0, 0.3], Y [-0.2, 0], Z [0, 0.5]; the lens disc r 0.08 at z -0.1.
    let at = Vec3::new(-2.0, 4.0, 0.0);
    let (rz, rx) = (Mat3::from_rotation_z(pan.to_radians()), Mat3::from_rotation_x(tilt.to_radians()));
    let head = |p: Vec3| at + gdtf_to_stage(rz * (rx * p + Vec3::new(0.0, 0.0, -0.3)));
    let mut pts: Vec<Vec3> = box_points(Vec3::new(-0.2, -0.2, -0.1), Vec3::new(0.2, 0.2, 0.1))
        .into_iter()
        .map(|p| at + gdtf_to_stage(p))
        .collect();
    pts.extend(box_points(Vec3::new(0.0, -0.2, 0.0), Vec3::new(0.3, 0.0, 0.5)).into_iter().map(head));
    pts.extend(cylinder_points(0.08, -0.101, -0.099).into_iter().map(head));
    let (want, got) = (expected_extent(&cam, &pts), drawn_extent(&layer, 0));
    assert!(close(want, got), "glb head: drawn {got:?}, projected {want:?}");
    // The lens faces where the light points: the posed disc's normal is the light's axis.
    let light = fixtures[models[0].driver].light_of(&{
        let mut s = fixtures[models[0].driver].look;
        s.pan = pan;
        s.tilt = tilt;
        s
    });
    let lens_axis = gdtf_to_stage(rz * rx * Vec3::NEG_Z);
    assert!((lens_axis - light.axis()).length() < 1e-4, "{lens_axis} vs {}", light.axis());

    // Can 3ds at (0, 4, 0): X, Y ±0.125, Z [0, 0.4]; lens r 0.1 at the origin.
    let at = Vec3::new(0.0, 4.0, 0.0);
    let mut pts: Vec<Vec3> = box_points(Vec3::new(-0.125, -0.125, 0.0), Vec3::new(0.125, 0.125, 0.4));
    pts.extend(cylinder_points(0.1, -0.001, 0.001));
    let pts: Vec<Vec3> = pts.into_iter().map(|p| at + gdtf_to_stage(p)).collect();
    let (want, got) = (expected_extent(&cam, &pts), drawn_extent(&layer, 1));
    assert!(close(want, got), "3ds can: drawn {got:?}, projected {want:?}");

    // Par (primitives) at (2, 4, 0): cylinder r 0.15, Z ±0.2; lens cylinder r 0.12 at z -0.2, 0.01 high.
    let at = Vec3::new(2.0, 4.0, 0.0);
    let mut pts = cylinder_points(0.15, -0.2, 0.2);
    pts.extend(cylinder_points(0.12, -0.205, -0.195));
    let pts: Vec<Vec3> = pts.into_iter().map(|p| at + gdtf_to_stage(p)).collect();
    let (want, got) = (expected_extent(&cam, &pts), drawn_extent(&layer, 2));
    assert!(close(want, got), "primitive par: drawn {got:?}, projected {want:?}");

    // Pan/tilt move the glb head: at rest the drawn extent differs.
    let rest: Vec<Body> = models.iter().map(|m| m.pose(&fixtures[m.driver].light, 0.0, 0.0)).collect();
    let rest_layer = BodyLayer::build(&scene, &cam, W, H, &rest);
    assert_ne!(drawn_extent(&rest_layer, 0), got_extent_of(&layer, 0));
    assert_eq!(drawn_extent(&rest_layer, 1), drawn_extent(&layer, 1), "a fixed can does not move");
}

fn got_extent_of(layer: &BodyLayer, body: u32) -> (f32, f32, f32, f32) {
    drawn_extent(layer, body)
}

/// 200×125 live picture of `bodies.mvr` over a floor: the three bodies 4 m up, seen from the front.
const LW: u32 = 200;
const LH: u32 = 125;

fn live_camera() -> Camera {
    Camera::look_at(Vec3::new(0.0, 3.0, 9.0), Vec3::new(0.0, 3.6, 0.0), 40f32.to_radians())
}

/// The DMX crate's merged frame of one universe (what the daemon's clock reads).
fn merged(universe: u16, slots: [u8; 512]) -> footlight_dmx::Universes {
    let mut u = footlight_dmx::Universes::default();
    u.update(&footlight_dmx::UniverseFrame { universe, slots, at: tokio::time::Instant::now(), stale: false });
    u
}

/// Waits (real time: the tracer runs on its own threads) until the tracer is idle.
fn wait_idle(tracer: &footlight::live::Tracer) {
    let t = std::time::Instant::now();
    while !tracer.idle() {
        assert!(t.elapsed() < std::time::Duration::from_secs(120), "tracer never idle");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

/// A DMX pan of the glb head through the daemon's frame clock (paused
/// time): the moved body shows in the next frame made, the picture changes
/// only inside the body's old and new rectangles (projected here from a
/// layer cast afresh at each pose), the stream's body tiles change only
/// there, a dimmer change afterwards re-sends no body tile but changes the
/// lens glow, and the tracer rebuilds the panned light only.
#[tokio::test(start_paused = true)]
async fn a_dmx_pan_moves_one_body_in_the_next_frame_and_rebuilds_only_its_light() {
    use footlight::live::{FrameClock, Show, Tracer, TracerSettings, bodies::LiveBodies};
    use footlight::render::composite::Compositor;
    use footlight::render::{Display, RecursionLimits, Sampling, View};
    use std::sync::Arc;
    let path = crate::common::root().join("tests/data/mvr/bodies.mvr");
    let import = footlight_mvr::load_mvr(&path).expect("bodies.mvr loads");
    let patch = import.patch;
    let show = Show::new(patch.clone()).unwrap();
    let names: Vec<String> = patch.fixtures.iter().map(|f| f.name.clone()).collect();
    let (models, warnings) = body_models(&path, &names, &show.fixture_ids());
    assert!(warnings.is_empty(), "{warnings:?}");
    let mut b = SceneBuilder::new();
    let m = crate::common::lambert(&mut b, 0.5);
    crate::common::floor(&mut b, 12.0, 0.0, m);
    let scene = Arc::new(b.build());
    let cam = live_camera();
    let view = View::build(&scene, cam, LW, LH, Sampling::One, RecursionLimits::default());
    let mut settings = TracerSettings { threads: 1, ..TracerSettings::default() };
    settings.build.photons = None;
    settings.build.refine_passes = 0;
    let lights = footlight::live::Decode::len(&show);
    assert_eq!(lights, 3);
    let tracer = Arc::new(Tracer::new(scene.clone(), Arc::new(view), lights, settings));
    let mut clock = FrameClock::new(
        Arc::new(Show::new(patch.clone()).unwrap()),
        tracer.clone(),
        Compositor::new(LW, LH, Display::neutral(2000.0)),
    )
    .with_bodies(Some(LiveBodies::new(body_models(&path, &names, &show.fixture_ids()).0, scene.clone())));

    // Universe of the head (fixture 1: pan 1-2, tilt 3-4, dimmer 5), all lamps at full.
    let universe = show.universes()[0];
    let mut slots = *patch.look_universes.get(universe).expect("look frame");
    for a in [5, 11, 21] {
        slots[a - 1] = 255;
    }
    let fixture_universes = |slots: [u8; 512]| {
        let mut u = footlight::fixture::Universes::new();
        for (a, v) in slots.iter().enumerate() {
            u.set_slot(universe, a as u16 + 1, *v);
        }
        u
    };
    clock.tick(&fixture_universes(slots));
    let t = tracer.clone();
    tokio::task::spawn_blocking(move || wait_idle(&t)).await.unwrap();
    let generations = |t: &Tracer| (0..3).map(|i| t.published(i).generation).collect::<Vec<_>>();
    let (g0, builds0) = (generations(&tracer), tracer.builds());

    let (in_tx, in_rx) = tokio::sync::watch::channel(merged(universe, slots));
    let first = Arc::new(clock.tick(&fixture_universes(slots)));
    let (out_tx, mut out_rx) = tokio::sync::watch::channel(first);
    let (_stop_tx, stop) = footlight::live::daemon::stop_signal();
    tokio::spawn(footlight::live::run_clock(clock, 50.0, in_rx, out_tx, Default::default(), stop));
    tokio::time::sleep(std::time::Duration::from_millis(60)).await;
    let before = out_rx.borrow_and_update().clone();

    // Pan 12.5°, tilt -83.8° (16-bit: -180..180 and -90..90): the head at
    // (-2, 4, 0) m turns its lens to the camera (axis (0.216, -0.971,
    // -0.108) in GDTF coordinates), with the tracer held so no buffer changes.
    tracer.set_paused(true);
    let mut panned = slots;
    let (pan, tilt) = (12.5f32, -83.8f32);
    let p = ((pan + 180.0) / 360.0 * 65535.0).round() as u16;
    let q = ((tilt + 90.0) / 180.0 * 65535.0).round() as u16;
    panned[..4].copy_from_slice(&[(p >> 8) as u8, p as u8, (q >> 8) as u8, q as u8]);
    // The first frame made after the packet shows the pan (presented a tick
    // after it was made: within two frame periods).
    let period = std::time::Duration::from_millis(20);
    let next = crate::common::first_frame_where(&mut out_rx, &in_tx, merged(universe, panned), period, &before, |f| {
        f.rgb != before.rgb
    })
    .await;

    // The head's body at each pose, cast afresh.
    let layer_at = |slots: [u8; 512]| {
        let inputs = footlight::live::Decode::decode(&show, &fixture_universes(slots));
        let bodies: Vec<Body> = models
            .iter()
            .map(|m| m.pose(&inputs[m.driver].light, inputs[m.driver].state.pan, inputs[m.driver].state.tilt))
            .collect();
        BodyLayer::build(&scene, &cam, LW, LH, &bodies)
    };
    let (old, new) = (layer_at(slots), layer_at(panned));
    let (ro, rn) = (old.rect(0).unwrap(), new.rect(0).unwrap());
    let inside = |i: usize, r: (u32, u32, u32, u32)| {
        let (x, y) = (i as u32 % LW, i as u32 / LW);
        x >= r.0 && x < r.2 && y >= r.1 && y < r.3
    };
    let mut changed = 0;
    for i in 0..(LW * LH) as usize {
        if before.rgb[3 * i..3 * i + 3] != next.rgb[3 * i..3 * i + 3] {
            changed += 1;
            assert!(
                inside(i, ro) || inside(i, rn),
                "pixel {i} changed outside the head's old {ro:?} and new {rn:?} rectangles"
            );
        }
    }
    let is_head = |l: &BodyLayer, i: usize| l.hits[i].is_some_and(|h| h.body == 0);
    let moved: Vec<usize> = (0..(LW * LH) as usize).filter(|&i| is_head(&old, i) != is_head(&new, i)).collect();
    assert!(moved.len() > 10, "the head's silhouette moves: {} pixels", moved.len());
    let shown = moved.iter().filter(|&&i| before.rgb[3 * i..3 * i + 3] != next.rgb[3 * i..3 * i + 3]).count();
    assert!(
        shown * 10 >= moved.len() * 9,
        "{shown} of {} moved silhouette pixels changed ({changed} changed)",
        moved.len()
    );
    // The stream's tiles: changed only where the head was or is.
    let (tb, tn) = (before.bodies.as_ref().unwrap(), next.bodies.as_ref().unwrap());
    let tiles_x = tn.tiles_x() as u32;
    let touched: Vec<usize> = (0..tn.tiles.len()).filter(|&i| tn.tiles[i].revision != tb.tiles[i].revision).collect();
    assert!(!touched.is_empty());
    for &i in &touched {
        let (x0, y0) = (i as u32 % tiles_x * 16, i as u32 / tiles_x * 16);
        let overlaps = |r: (u32, u32, u32, u32)| x0 < r.2 && r.0 < x0 + 16 && y0 < r.3 && r.1 < y0 + 16;
        assert!(overlaps(ro) || overlaps(rn), "tile {i} changed away from the head");
    }
    // The tiles carry what the server drew: base + k · glow through the display is the picture.
    let inputs = footlight::live::Decode::decode(&show, &fixture_universes(panned));
    let k: Vec<Vec3> = inputs.iter().map(|i| i.k).collect();
    for (t, tile) in tn.tiles.iter().enumerate() {
        for (j, p) in tile.pixels.iter().enumerate() {
            let (x, y) = (t as u32 % tiles_x * 16 + j as u32 % 16, t as u32 / tiles_x * 16 + j as u32 / 16);
            let Some(p) = p else { continue };
            let i = (y * LW + x) as usize;
            let want = next.display.to_srgb8(&[p.radiance(&k)]);
            assert_eq!(&next.rgb[3 * i..3 * i + 3], &want[..], "pixel ({x}, {y})");
        }
    }

    // A dimmer change: the same tiles (no body bytes), but the lens glow follows k.
    let mut dark = panned;
    dark[4] = 0;
    // The first frame made after the packet (nothing else changes: the
    // tracer is held) is the first that differs.
    let last = out_rx.borrow_and_update().clone();
    let dimmed = crate::common::first_frame_where(&mut out_rx, &in_tx, merged(universe, dark), period, &last, |f| {
        f.rgb != last.rgb
    })
    .await;
    assert!(Arc::ptr_eq(dimmed.bodies.as_ref().unwrap(), tn), "a dimmer change sends no body tile");
    let lens: Vec<usize> =
        (0..(LW * LH) as usize).filter(|&i| new.hits[i].is_some_and(|h| h.body == 0 && h.lens)).collect();
    let glow_changed = lens.iter().filter(|&&i| dimmed.rgb[3 * i..3 * i + 3] != next.rgb[3 * i..3 * i + 3]).count();
    assert!(!lens.is_empty() && glow_changed == lens.len(), "{glow_changed} of {} lens pixels", lens.len());

    eprintln!(
        "silhouette {} px moved, {shown} shown, {changed} changed, {} tiles, {} lens px",
        moved.len(),
        touched.len(),
        lens.len()
    );
    // Only the panned light is rebuilt.
    tracer.set_paused(false);
    let (t, first) = (tracer.clone(), g0[0]);
    let g = tokio::task::spawn_blocking(move || {
        let t0 = std::time::Instant::now();
        while t.published(0).generation == first || !t.idle() {
            assert!(t0.elapsed() < std::time::Duration::from_secs(120), "the panned light was never rebuilt");
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        (0..3).map(|i| t.published(i).generation).collect::<Vec<_>>()
    })
    .await
    .unwrap();
    assert!(g[0] > g0[0]);
    assert_eq!((g[1], g[2]), (g0[1], g0[2]), "no other light rebuilt");
    assert!(tracer.builds() > builds0);
    for i in 1..3 {
        assert!(tracer.report(i).unwrap().pending_ms.is_none(), "light {i} has no request");
    }
}
