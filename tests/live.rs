//! The live daemon: frame numbers under paused time, staged rebuilds of a
//! moved light, the geometry cache, and the HTTP preview on loopback.

use crate::common::*;
use footlight::fixture::{DmxSlots, FixtureState, Universes};
use footlight::live::{
    Daemon, DaemonConfig, Decode, DmxSource, Frame, FrameClock, LightInput, Stage, Tracer, TracerSettings,
};
use footlight::render::composite::Compositor;
use footlight::render::{Display, RecursionLimits, Sampling, View};
use footlight::scene::{Camera, Scene, SceneBuilder};
use glam::Vec3;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::watch;

/// Universe 1: slot 1 = dimmer (0-255), slot 2 = light x position (0-255 → −2..2 m),
/// decoded as a fixture whose "pan" is the position (the change rule's geometry).
struct TestDecoder;

impl Decode for TestDecoder {
    fn len(&self) -> usize {
        1
    }
    fn decode(&self, u: &dyn DmxSlots) -> Vec<LightInput> {
        let slots = u.slots(1).copied().unwrap_or([0; 512]);
        let v = slots[0] as f32 / 255.0;
        let x = -2.0 + 4.0 * slots[1] as f32 / 255.0;
        let light = footlight::Light::aimed(
            Vec3::new(x, 2.0, 0.0),
            Vec3::new(x, 0.0, 0.0),
            footlight::Beam::Spot(footlight::fixture::SpotBeam::from_beam_field(30.0, 40.0)),
        );
        let state = FixtureState { v, pan: x, ..FixtureState::default() };
        vec![LightInput { light, k: Vec3::splat(1000.0 * v), k_full: Vec3::splat(1000.0), state }]
    }
    fn slots_of(&self, _index: usize, u: &dyn DmxSlots) -> Vec<u8> {
        u.slots(1).map(|s| s[..2].to_vec()).unwrap_or_default()
    }
}

fn small_stage() -> (Arc<Scene>, Camera) {
    let mut b = SceneBuilder::new();
    let m = lambert(&mut b, 0.8);
    floor(&mut b, 10.0, 0.0, m);
    (Arc::new(b.build()), Camera::look_at(Vec3::new(0.0, 6.0, 0.01), Vec3::ZERO, 70f32.to_radians()))
}

fn tracer(scene: &Arc<Scene>, camera: Camera, w: u32, h: u32) -> Arc<Tracer> {
    let view = View::build(scene, camera, w, h, Sampling::Adaptive, RecursionLimits::default());
    let settings = no_photons();
    Arc::new(Tracer::new(scene.clone(), Arc::new(view), 1, settings))
}

fn no_photons() -> TracerSettings {
    let mut settings = TracerSettings { threads: 1, ..TracerSettings::default() };
    settings.build.photons = None;
    settings
}

fn wait_for(tracer: &Tracer, what: impl Fn(Stage) -> bool) {
    let t = Instant::now();
    while !what(tracer.published(0).stage) {
        assert!(t.elapsed() < Duration::from_secs(60), "tracer stuck at {:?}", tracer.published(0).stage);
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn universes(dimmer: u8, x: u8) -> Universes {
    let mut u = Universes::new();
    u.set_slot(1, 1, dimmer);
    u.set_slot(1, 2, x);
    u
}

/// The same levels as the DMX crate's merged frames (what the daemon reads).
fn merged(dimmer: u8, x: u8) -> footlight_dmx::Universes {
    let mut slots = [0u8; 512];
    slots[0] = dimmer;
    slots[1] = x;
    let mut u = footlight_dmx::Universes::default();
    u.update(&footlight_dmx::UniverseFrame { universe: 1, slots, at: tokio::time::Instant::now(), stale: false });
    u
}

fn centre_brightness(f: &Frame, x: u32) -> u8 {
    let i = ((f.height / 2 * f.width + x) * 3) as usize;
    f.rgb[i]
}

#[tokio::test(start_paused = true)]
async fn dimmer_packet_shows_in_the_next_frame() {
    let (scene, cam) = small_stage();
    let tracer = tracer(&scene, cam, 40, 40);
    let mut clock =
        FrameClock::new(Arc::new(TestDecoder), tracer.clone(), Compositor::new(40, 40, Display::neutral(1000.0)));
    clock.tick(&universes(255, 128)); // requests the first build
    let t = tracer.clone();
    tokio::task::spawn_blocking(move || wait_for(&t, |s| s == Stage::Ready)).await.unwrap();

    let (in_tx, in_rx) = watch::channel(merged(255, 128));
    let first = Arc::new(clock.tick(&universes(255, 128)));
    let (out_tx, mut out_rx) = watch::channel(first);
    let (_stop_tx, stop) = footlight::live::daemon::stop_signal();
    tokio::spawn(footlight::live::run_clock(clock, 50.0, in_rx, out_tx, Default::default(), stop));
    let period = Duration::from_millis(20);
    // Let the clock settle on a frame at full.
    tokio::time::sleep(period * 3).await;
    let before = out_rx.borrow_and_update().clone();
    assert!(centre_brightness(&before, 20) > 100, "lit at full: {}", centre_brightness(&before, 20));
    // The desk pulls the fader to 0 between two frames.
    in_tx.send(merged(0, 128)).unwrap();
    out_rx.changed().await.unwrap();
    let next = out_rx.borrow_and_update().clone();
    assert_eq!(next.number, before.number + 1, "the change must land in the very next frame");
    assert_eq!(centre_brightness(&next, 20), 0);
    assert_eq!(next.update.changed_lights, 1);
    // And back up: again frame n+1, and the picture is what it was.
    in_tx.send(merged(255, 128)).unwrap();
    out_rx.changed().await.unwrap();
    let back = out_rx.borrow_and_update().clone();
    assert_eq!(back.number, next.number + 1);
    assert_eq!(back.rgb, before.rgb);
}

#[test]
fn moved_light_shows_its_direct_stage_then_converges_and_presets_come_from_cache() {
    let (scene, cam) = small_stage();
    let (w, h) = (64, 64);
    let tracer = tracer(&scene, cam, w, h);
    let mut clock =
        FrameClock::new(Arc::new(TestDecoder), tracer.clone(), Compositor::new(w, h, Display::neutral(1000.0)));
    clock.tick(&universes(255, 40)); // light at the left
    wait_for(&tracer, |s| s == Stage::Ready);
    let left = clock.tick(&universes(255, 40));
    // x = −1.37 m and +1.37 m on the floor (slots 40 and 215) at pixel columns ≈ 0.34 w and 0.66 w.
    let lx = (w as f32 * 0.34) as u32;
    let rx = (w as f32 * 0.66) as u32;
    assert!(centre_brightness(&left, lx) > centre_brightness(&left, rx));

    // Pan to the right: the first frame after the packet still shows the old
    // buffer (the clock never waits), then the direct stage arrives.
    let t0 = Instant::now();
    let generation = tracer.published(0).generation;
    clock.tick(&universes(255, 215));
    while tracer.published(0).generation == generation {
        assert!(t0.elapsed() < Duration::from_secs(60), "no stage published");
        std::thread::sleep(Duration::from_millis(1));
    }
    let frame = clock.tick(&universes(255, 215));
    assert!(centre_brightness(&frame, rx) > centre_brightness(&frame, lx), "moved light visible after the first stage");
    wait_for(&tracer, |s| s == Stage::Ready);
    // Two stages were published: direct light first, then the full Whitted buffer.
    assert_eq!(tracer.published(0).generation, generation + 2);
    let report = tracer.report(0).unwrap();
    assert!(report.first_stage_ms.is_some() && report.direct_updates == 2, "{report:?}");

    // Back to the left preset: served from the geometry cache within the
    // request itself (Ready before any worker could have built it), and the
    // very next frame is the converged picture from before.
    let generation = tracer.published(0).generation;
    clock.tick(&universes(255, 40));
    let recalled_state = tracer.published(0);
    assert_eq!(recalled_state.stage, Stage::Ready, "preset recalled from the cache");
    assert_eq!(recalled_state.generation, generation + 1, "one publish: the cached buffer, no build stages");
    let recalled = clock.tick(&universes(255, 40));
    assert_eq!(recalled.rgb, left.rgb);
}

#[test]
fn preview_serves_page_status_and_frames_on_loopback_and_refuses_a_taken_port() {
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
    let (scene, cam) = small_stage();
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let (addr_tx, addr_rx) = std::sync::mpsc::channel();
    let daemon = std::thread::spawn(move || {
        rt.block_on(async move {
            let listener = footlight::live::bind_http("127.0.0.1:0".parse().unwrap()).await.unwrap();
            let addr = listener.local_addr().unwrap();
            // A second daemon on the same port is refused with a clear error.
            let err = footlight::live::bind_http(addr).await.unwrap_err().to_string();
            assert!(err.contains("another footlight"), "{err}");
            addr_tx.send(addr).unwrap();
            let (_tx, inputs) = watch::channel(merged(255, 128));
            let config = DaemonConfig {
                width: 48,
                height: 32,
                fps: 30.0,
                display: Display::neutral(1000.0),
                tracer: no_photons(),
                compositor: footlight::gpu::CompositorChoice::Cpu,
                ..DaemonConfig::default()
            };
            Daemon::with_decoder(scene, Arc::new(TestDecoder), cam, config)
                .input(DmxSource::Channel(inputs))
                .serve(listener)
                .run(async {
                    let _ = stop_rx.await;
                })
                .await
                .unwrap();
        })
    });
    let addr = addr_rx.recv_timeout(Duration::from_secs(60)).unwrap();
    let (head, page) = http_get(addr, "/");
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    assert!(String::from_utf8_lossy(&page).contains("/api/frame.png"));
    // Wait until the light is built and the picture lit.
    let t = Instant::now();
    loop {
        let (_, body) = http_get(addr, "/api/status");
        let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
        if v["lights"][0]["stage"] == "ready" {
            assert_eq!(v["lights"][0]["dmx"], serde_json::json!([255, 128]));
            assert!(v["frame"].as_u64().unwrap() > 0);
            break;
        }
        assert!(t.elapsed() < Duration::from_secs(60), "never ready: {v}");
        std::thread::sleep(Duration::from_millis(50));
    }
    std::thread::sleep(Duration::from_millis(100));
    let (head, png) = http_get(addr, "/api/frame.png");
    assert!(head.contains("image/png"), "{head}");
    let img = image::load_from_memory(&png).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (48, 32));
    assert!(img.get_pixel(24, 16).0[0] > 100, "lit centre");
    stop_tx.send(()).unwrap();
    daemon.join().unwrap();
    // After shutdown the port is free again.
    std::net::TcpListener::bind(addr).expect("port released on shutdown");
}

fn spot_at(x: f32, beam_deg: f32) -> footlight::Light {
    footlight::Light::aimed(
        Vec3::new(x, 2.0, 0.0),
        Vec3::new(x, 0.0, 0.0),
        footlight::Beam::Spot(footlight::fixture::SpotBeam::from_beam_field(beam_deg, beam_deg * 1.3)),
    )
}

/// The footprint-culled direct stage equals the whole-frame one pixel for
/// pixel, and a narrow beam evaluates a small fraction of the frame's
/// directly seen vertices (the counter, not a time).
#[test]
fn direct_stage_costs_the_beams_footprint_and_equals_the_whole_frame_stage() {
    use footlight::render::footprint::{DirectQuality, primary_direct};
    let (scene, cam) = small_stage();
    let view = View::build(&scene, cam, 160, 160, Sampling::Adaptive, RecursionLimits::default());
    let frame_vertices = view.shading.vertices().iter().filter(|v| v.depth == 0).count();
    for (beam, max_share) in [(5.0, 0.05), (18.0, 0.2), (40.0, 0.6)] {
        let light = spot_at(0.3, beam);
        let (culled, stats) = primary_direct(&scene, &view, view.tile_bounds(), &light, DirectQuality::Full);
        let whole = view.render_primary_direct(&scene, &light);
        assert_eq!(culled.to_dense(), whole, "{beam}°: culling must not change a pixel");
        assert!(whole.iter().any(|p| p.max_element() > 0.0), "{beam}°: the beam lights the floor");
        let share = stats.vertices as f64 / frame_vertices as f64;
        assert!(share < max_share, "{beam}°: evaluated {} of {frame_vertices} vertices ({share:.3})", stats.vertices);
    }
    // Moving quality shades a quarter of the pixels and repeats them.
    let light = spot_at(0.3, 40.0);
    let (_, full) = primary_direct(&scene, &view, view.tile_bounds(), &light, DirectQuality::Full);
    let (moving, fast) = primary_direct(&scene, &view, view.tile_bounds(), &light, DirectQuality::Moving);
    assert!(fast.vertices * 3 < full.vertices, "{} vs {}", fast.vertices, full.vertices);
    assert_eq!(moving.get(10, 10), moving.get(11, 11));
}

/// A light that keeps moving only ever shows direct stages (no Whitted,
/// photon or refinement work on a stale position); once it stops it
/// settles to `ready`, and its final buffer equals a build of that position
/// from scratch (moving quality leaves no trace).
#[test]
fn a_moving_light_never_starts_its_later_stages_and_settles_to_the_same_buffer() {
    use footlight::render::{BuildSettings, Cancel, LightBuild};
    let (scene, cam) = small_stage();
    let view = Arc::new(View::build(&scene, cam, 48, 48, Sampling::Adaptive, RecursionLimits::default()));
    let mut build = BuildSettings { refine_passes: 0, ..BuildSettings::default() };
    build.photons = Some(footlight::render::photon::PhotonSettings { stored: 2_000, ..Default::default() });
    // A long settle time: a stalled test thread can never make the light look still.
    let settings = TracerSettings { threads: 1, build, settle: Duration::from_secs(2), ..TracerSettings::default() };
    let tracer = Tracer::new(scene.clone(), view.clone(), 1, settings);
    let mut last = spot_at(-1.0, 30.0);
    for step in 0..25 {
        last = spot_at(-1.0 + 0.08 * step as f32, 30.0);
        tracer.request(0, last.clone(), 1.0);
        std::thread::sleep(Duration::from_millis(20));
        let stage = tracer.published(0).stage;
        assert!(matches!(stage, Stage::Queued | Stage::Direct), "step {step}: {stage:?} while moving");
        assert!(tracer.report(0).unwrap().moving);
    }
    wait_for(&tracer, |s| s == Stage::Ready);
    let report = tracer.report(0).unwrap();
    assert!(!report.moving && report.pending_ms.is_none(), "{report:?}");
    assert!(report.direct_updates >= 2, "{report:?}");
    let mut fresh = LightBuild::new(last, 0, build, Cancel::never());
    let expected = fresh.photons(&scene, &view).unwrap();
    assert_eq!(*tracer.published(0).buffer, expected);
    tracer.shutdown(Duration::from_secs(30));
}

/// One light at full, strobing at 10 Hz (shutter_at: open 0-50 ms of each 100 ms).
struct StrobeDecoder;

impl Decode for StrobeDecoder {
    fn len(&self) -> usize {
        1
    }
    fn decode(&self, _u: &dyn DmxSlots) -> Vec<LightInput> {
        let light = footlight::Light::aimed(
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::ZERO,
            footlight::Beam::Spot(footlight::fixture::SpotBeam::from_beam_field(30.0, 40.0)),
        );
        let state = FixtureState { v: 1.0, strobe: 10.0, ..FixtureState::default() };
        vec![LightInput { light, k: Vec3::splat(1000.0), k_full: Vec3::splat(1000.0), state }]
    }
}

#[test]
fn strobe_is_a_composite_on_the_frame_clock_not_a_rebuild() {
    let (scene, cam) = small_stage();
    let tracer = tracer(&scene, cam, 40, 40);
    let mut clock =
        FrameClock::new(Arc::new(StrobeDecoder), tracer.clone(), Compositor::new(40, 40, Display::neutral(1000.0)));
    clock.tick_at(&Universes::new(), 0.0);
    wait_for(&tracer, |s| s == Stage::Ready);
    let generation = tracer.published(0).generation;
    let lit = clock.tick_at(&Universes::new(), 0.01);
    assert!(centre_brightness(&lit, 20) > 100 && lit.intensity[0] > 0.0);
    let dark = clock.tick_at(&Universes::new(), 0.07);
    assert_eq!((centre_brightness(&dark, 20), dark.intensity[0]), (0, 0.0));
    assert_eq!(dark.update.changed_lights, 1);
    let again = clock.tick_at(&Universes::new(), 0.12);
    assert_eq!(again.rgb, lit.rgb);
    // The state never changed, so the tracer was never asked for a rebuild.
    assert_eq!(tracer.published(0).generation, generation);
}
