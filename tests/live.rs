//! The live daemon: frame numbers under paused time, staged rebuilds of a
//! moved light, the geometry cache, the HTTP preview on loopback, and the
//! status's per-light patch fields (fixture, cell, address, mode, position)
//! against a TOML patch and an MVR file read by the tests themselves.

use crate::common::*;
use footlight::fixture::{DmxSlots, FixtureState, Universes};
use footlight::live::{Daemon, DaemonConfig, Decode, DmxSource, FrameClock, LightInput, Tracer, TracerSettings};
use footlight::output::{Frame, Stage};
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
    // The desk pulls the fader to 0 between two frames. Frames are presented
    // on the tick one period after they are made (`run_clock`): the frame in
    // the making when the packet came may still show the fader up, and the
    // one made at the next tick shows it, presented a tick later.
    let next =
        first_frame_where(&mut out_rx, &in_tx, merged(0, 128), period, &before, |f| centre_brightness(f, 20) == 0)
            .await;
    assert_eq!(next.update.changed_lights, 1);
    // And back up: again within two ticks, and the picture is what it was.
    let back =
        first_frame_where(&mut out_rx, &in_tx, merged(255, 128), period, &next, |f| centre_brightness(f, 20) > 100)
            .await;
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

/// A daemon serving `patch` over a floor on loopback (CPU compositor, no
/// photons), fed DMX through a channel; stopped when dropped.
pub(crate) struct ShowDaemon {
    /// The preview's address.
    pub(crate) http: std::net::SocketAddr,
    /// The merged DMX the daemon reads (held: the input stays open).
    _dmx: watch::Sender<footlight_dmx::Universes>,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl ShowDaemon {
    /// Starts the daemon at `width`×`height` with `dmx` as the first levels.
    pub(crate) fn start(patch: footlight::Patch, width: u32, height: u32, dmx: footlight_dmx::Universes) -> Self {
        Self::start_with_import(patch, width, height, dmx, footlight::output::ImportStatus::default())
    }

    /// [`ShowDaemon::start`], the status's `import` given.
    pub(crate) fn start_with_import(
        patch: footlight::Patch,
        width: u32,
        height: u32,
        dmx: footlight_dmx::Universes,
        import: footlight::output::ImportStatus,
    ) -> Self {
        let (dmx_tx, dmx_rx) = watch::channel(dmx);
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let (addr_tx, addr_rx) = std::sync::mpsc::channel();
        let thread = std::thread::spawn(move || {
            let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
            rt.block_on(async move {
                let mut b = SceneBuilder::new();
                let m = lambert(&mut b, 0.5);
                floor(&mut b, 12.0, 0.0, m);
                let camera = Camera::look_at(Vec3::new(0.0, 5.0, 14.0), Vec3::new(0.0, 1.0, 0.0), 50f32.to_radians());
                let listener = footlight::live::bind_http("127.0.0.1:0".parse().unwrap()).await.unwrap();
                addr_tx.send(listener.local_addr().unwrap()).unwrap();
                let config = DaemonConfig {
                    width,
                    height,
                    fps: 20.0,
                    tracer: no_photons(),
                    compositor: footlight::gpu::CompositorChoice::Cpu,
                    ..DaemonConfig::default()
                };
                let show = Arc::new(footlight::live::Show::new(patch).unwrap());
                Daemon::new(Arc::new(b.build()), show, camera, config)
                    .input(DmxSource::Channel(dmx_rx))
                    .import_status(import)
                    .serve(listener)
                    .run(async {
                        let _ = stop_rx.await;
                    })
                    .await
                    .unwrap();
            })
        });
        let http = addr_rx.recv_timeout(Duration::from_secs(120)).unwrap();
        Self { http, _dmx: dmx_tx, stop: Some(stop_tx), thread: Some(thread) }
    }

    /// `GET /api/status`, parsed.
    pub(crate) fn status(&self) -> serde_json::Value {
        serde_json::from_slice(&http_get(self.http, "/api/status").1).unwrap()
    }
}

impl Drop for ShowDaemon {
    fn drop(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Issue 36 item 3: `/api/status` lists what the import said: one summary
/// per fixture type (a GDTF the archive lacks: not modelled, with its
/// fixtures) and each warning once, as `footlight check` prints them.
#[test]
fn status_lists_the_import_summary() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mvr/features.mvr");
    let checked = footlight_mvr::check_report(&path).unwrap();
    let import = footlight::output::ImportStatus::of(&checked);
    let said: Vec<String> = checked.warnings.iter().map(ToString::to_string).collect();
    let d = ShowDaemon::start_with_import(checked.patch, 40, 25, Default::default(), import);
    let status = d.status();
    let types = status["import"]["types"].as_array().unwrap();
    // features.mvr names 7 GDTF files: Spot, Wash, Bar8, Blinder, Fresnel, Hazer and a missing one.
    assert_eq!(types.len(), 7, "{status}");
    let missing = types.iter().find(|t| t["file"] == "Footlight@Missing.gdtf").unwrap();
    assert_eq!((missing["status"].as_str(), missing["fixtures"].as_u64()), (Some("not"), Some(2)), "{missing}");
    let bar = types.iter().find(|t| t["file"] == "Footlight@Bar8.gdtf").unwrap();
    assert_eq!((bar["fixtures"].as_u64(), bar["cells"].as_u64()), (Some(1), Some(8)), "{bar}");
    let warnings: Vec<String> =
        status["import"]["warnings"].as_array().unwrap().iter().filter_map(|w| w.as_str().map(String::from)).collect();
    assert_eq!(warnings, said, "the status says what `footlight check` says");
    assert!(
        warnings.iter().any(|w| w.contains("Footlight@Missing.gdtf") && w.contains("(2 fixtures)")),
        "{warnings:?}"
    );
}

/// One fixture as read from its patch file by the tests (not by Footlight).
#[derive(Debug)]
struct FileFixture {
    id: u64,
    name: String,
    /// Lights it makes: its cells (1 for a one-light fixture).
    cells: usize,
    universe: Option<u64>,
    address: Option<u64>,
    mode: Option<String>,
    /// Metres, stage axes.
    position: [f64; 3],
}

/// Checks `/api/status`'s per-light patch fields against the fixtures read
/// from the file: each fixture's lights are consecutive, under its id and
/// name, numbered 1.. when it has cells, with its address, mode and
/// position (within `tolerance` metres).
fn assert_status_patch(status: &serde_json::Value, expected: &[FileFixture], tolerance: f64) {
    let lights = status["lights"].as_array().unwrap();
    assert_eq!(lights.len(), expected.iter().map(|f| f.cells).sum::<usize>(), "one light per cell");
    let mut next = lights.iter();
    for f in expected {
        for n in 1..=f.cells {
            let l = next.next().unwrap();
            let what = format!("{} light {n}: {l}", f.name);
            assert_eq!(l["fixture"].as_u64(), Some(f.id), "{what}");
            assert_eq!(l["fixture_name"].as_str(), Some(f.name.as_str()), "{what}");
            if f.cells > 1 {
                assert_eq!(l["cell"].as_u64(), Some(n as u64), "{what}");
                assert!(l["name"].as_str().unwrap().starts_with(&format!("{} / ", f.name)), "{what}");
            } else {
                assert!(l["cell"].is_null(), "{what}");
                assert_eq!(l["name"].as_str(), Some(f.name.as_str()), "{what}");
            }
            assert_eq!(l["universe"].as_u64(), f.universe, "{what}");
            assert_eq!(l["address"].as_u64(), f.address, "{what}");
            let desk = f.universe.zip(f.address).map(|(u, a)| format!("{u}.{a}"));
            assert_eq!(l["dmx_address"].as_str(), desk.as_deref(), "{what}");
            assert_eq!(l["mode"].as_str(), f.mode.as_deref(), "{what}");
            let p: Vec<f64> = l["position"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
            assert!(p.iter().zip(f.position).all(|(a, b)| (a - b).abs() <= tolerance), "{what}: want {:?}", f.position);
        }
    }
}

/// Issue 36 item 6: the status gives each light's fixture, DMX address
/// (universe.address as a desk writes it), mode and position, for a TOML
/// patch: a library type with a mode, a built-in spot (no mode) and an
/// unaddressed spot, read back from the file with a plain TOML parser.
#[test]
fn status_gives_each_lights_address_mode_and_position_from_a_toml_patch() {
    let dir = std::env::temp_dir().join(format!("footlight-status-patch-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("rig.toml");
    let text = format!(
        r#"fixtures = "{fixtures}"
gels = "{gels}"

[[fixture]]
id = 12
name = "Castor on 2.17"
type = "strand-castor"
mode = "1ch"
universe = 2
address = 17
position = [-5.5, 5.25, 7.0]
aim = [0.0, 0.0, 0.0]

[[fixture]]
id = 3
name = "Spot on 3.512"
type = "spot"
universe = 3
address = 512
position = [1.5, 6.0, -3.125]
aim = [0.0, 0.0, 0.0]
beam_angle = 20.0
field_angle = 30.0
intensity = 1000.0

[[fixture]]
id = 40
name = "Spot with no address"
type = "spot"
position = [0.0, 7.5, 2.0]
aim = [0.0, 0.0, 0.0]
beam_angle = 20.0
field_angle = 30.0
intensity = 1000.0
"#,
        fixtures = root().join("patch/fixtures").display(),
        gels = root().join("patch/gels.toml").display(),
    );
    std::fs::write(&path, &text).unwrap();
    let patch = footlight::Patch::load(&path).unwrap();
    // The file, read with a plain TOML parser.
    let file: toml::Table = text.parse().unwrap();
    let expected: Vec<FileFixture> = file["fixture"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| FileFixture {
            id: f["id"].as_integer().unwrap() as u64,
            name: f["name"].as_str().unwrap().to_string(),
            cells: 1,
            universe: f.get("universe").map(|v| v.as_integer().unwrap() as u64),
            address: f.get("address").map(|v| v.as_integer().unwrap() as u64),
            mode: f.get("mode").map(|v| v.as_str().unwrap().to_string()),
            position: [0, 1, 2].map(|i| f["position"][i].as_float().unwrap()),
        })
        .collect();
    let daemon = ShowDaemon::start(patch, 16, 10, footlight_dmx::Universes::default());
    assert_status_patch(&daemon.status(), &expected, 1e-9);
    drop(daemon);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The named member of a zip archive (stored or deflated), found through
/// the central directory: the tests' own reader of an MVR file.
fn zip_member(zip: &[u8], name: &str) -> Vec<u8> {
    use std::io::Read;
    let u16_at = |o: usize| usize::from(u16::from_le_bytes([zip[o], zip[o + 1]]));
    let u32_at = |o: usize| u32::from_le_bytes(zip[o..o + 4].try_into().unwrap()) as usize;
    let end = (0..zip.len() - 21).rev().find(|&o| u32_at(o) == 0x0605_4b50).expect("end of central directory");
    let mut o = u32_at(end + 16);
    for _ in 0..u16_at(end + 10) {
        assert_eq!(u32_at(o), 0x0201_4b50, "central directory entry");
        let (method, size, local) = (u16_at(o + 10), u32_at(o + 20), u32_at(o + 42));
        let (n, extra, comment) = (u16_at(o + 28), u16_at(o + 30), u16_at(o + 32));
        if &zip[o + 46..o + 46 + n] == name.as_bytes() {
            let data = local + 30 + u16_at(local + 26) + u16_at(local + 28);
            let raw = &zip[data..data + size];
            let mut out = Vec::new();
            match method {
                0 => out.extend_from_slice(raw),
                8 => {
                    flate2::read::DeflateDecoder::new(raw).read_to_end(&mut out).unwrap();
                }
                m => panic!("zip method {m}"),
            }
            return out;
        }
        o += 46 + n + extra + comment;
    }
    panic!("{name} is not in the archive")
}

/// The fixtures of an MVR scene description, read with string searches: id,
/// name, GDTF mode, absolute DMX address (→ universe.address, 512 slots a
/// universe) and the matrix's offset (mm, Z up → metres, stage Y up, +Z
/// toward the audience: (x, z, −y) / 1000). `cells` gives the lights per
/// GDTF file.
fn mvr_fixtures(xml: &str, cells: &dyn Fn(&str) -> usize) -> Vec<FileFixture> {
    let between = |s: &str, open: &str, close: &str| -> Option<String> {
        let start = s.find(open)? + open.len();
        Some(s[start..start + s[start..].find(close)?].to_string())
    };
    xml.split("<Fixture ")
        .skip(1)
        .map(|chunk| {
            let body = &chunk[..chunk.find("</Fixture>").unwrap()];
            let absolute: u64 = between(body, "<Address break=\"0\">", "<").unwrap().trim().parse().unwrap();
            let matrix = between(body, "<Matrix>", "<").unwrap();
            let offset: Vec<f64> = matrix
                .rsplit('{')
                .next()
                .unwrap()
                .trim_end_matches('}')
                .split(',')
                .map(|v| v.parse().unwrap())
                .collect();
            FileFixture {
                id: between(body, "<FixtureID>", "<").unwrap().parse().unwrap(),
                name: between(body, "name=\"", "\"").unwrap(),
                cells: cells(&between(body, "<GDTFSpec>", "<").unwrap()),
                universe: Some((absolute - 1) / 512 + 1),
                address: Some((absolute - 1) % 512 + 1),
                mode: between(body, "<GDTFMode>", "<"),
                position: [offset[0] / 1000.0, offset[2] / 1000.0, -offset[1] / 1000.0],
            }
        })
        .collect()
}

/// Issue 36 item 6 on the 150-fixture MVR show: every light carries its
/// fixture's id, name, address, GDTF mode and position as the MVR file
/// gives them, and the 24 pixel bars' cells are numbered 1-8 under their bar.
#[test]
fn status_gives_each_mvr_fixtures_cells_address_mode_and_position() {
    let path = root().join("tests/data/mvr/show150.mvr");
    let xml = String::from_utf8(zip_member(&std::fs::read(&path).unwrap(), "GeneralSceneDescription.xml")).unwrap();
    // tools/gen_gdtf_mvr.py: the bar has eight RGB pixels, the blinder two
    // lamps, the hazer no beam (it is not a light).
    let cells = |spec: &str| match spec {
        "Footlight@Bar8.gdtf" => 8,
        "Footlight@Blinder.gdtf" => 2,
        "Footlight@Hazer.gdtf" => 0,
        _ => 1,
    };
    let expected: Vec<FileFixture> = mvr_fixtures(&xml, &cells).into_iter().filter(|f| f.cells > 0).collect();
    assert_eq!((expected.len(), expected.iter().map(|f| f.cells).sum::<usize>()), (148, 336));
    let patch = footlight_mvr::load_mvr(&path).unwrap().patch;
    let daemon = ShowDaemon::start(patch, 16, 10, footlight_dmx::Universes::default());
    // Positions in the status are to the millimetre; the file's to 1/1000 mm.
    assert_status_patch(&daemon.status(), &expected, 0.0005 + 1e-6);
}

/// Universe 1: slot i+1 = dimmer of light i, a row of `0` spots 1 m apart.
struct RowDecoder(usize);

impl Decode for RowDecoder {
    fn len(&self) -> usize {
        self.0
    }
    fn decode(&self, u: &dyn DmxSlots) -> Vec<LightInput> {
        let slots = u.slots(1).copied().unwrap_or([0; 512]);
        (0..self.0)
            .map(|i| {
                let v = f32::from(slots[i]) / 255.0;
                let x = i as f32 - (self.0 as f32 - 1.0) / 2.0;
                let light = spot_at(x, 20.0);
                let state = FixtureState { v, pan: x, ..FixtureState::default() };
                LightInput { light, k: Vec3::splat(1000.0 * v), k_full: Vec3::splat(1000.0), state }
            })
            .collect()
    }
    fn slots_of(&self, index: usize, u: &dyn DmxSlots) -> Vec<u8> {
        u.slots(1).map(|s| vec![s[index]]).unwrap_or_default()
    }
}

/// Issue 38 (done means), through the daemon in paused time: with every
/// other light of a row dark, no dark light leaves `queued` before every
/// lit one is `ready` (dark lights are built in idle time), and the dark
/// ones are built after; with a memory budget that holds the lit lights
/// and half a buffer more, the dark lights' buffers are evicted, the lit
/// lights stay ready and the memory used ends within the budget.
#[tokio::test(start_paused = true)]
async fn the_daemon_builds_lit_lights_first_and_holds_its_memory_budget() {
    use footlight::output::DaemonStatus;
    const N: usize = 8;
    let lit = |i: usize| i % 2 == 1;
    async fn run(budget: Option<u64>, lit: impl Fn(usize) -> bool) -> DaemonStatus {
        let (scene, cam) = small_stage();
        let mut slots = [0u8; 512];
        for (i, s) in slots.iter_mut().enumerate().take(N) {
            *s = if lit(i) { 255 } else { 0 };
        }
        let mut dmx = footlight_dmx::Universes::default();
        dmx.update(&footlight_dmx::UniverseFrame { universe: 1, slots, at: tokio::time::Instant::now(), stale: false });
        let (_dmx_tx, dmx_rx) = watch::channel(dmx);
        let mut tracer = TracerSettings { settle: Duration::ZERO, ..no_photons() };
        if let Some(b) = budget {
            tracer.memory = b;
        }
        let config = DaemonConfig {
            width: 48,
            height: 32,
            fps: 30.0,
            tracer,
            compositor: footlight::gpu::CompositorChoice::Cpu,
            ..DaemonConfig::default()
        };
        let (running_tx, running_rx) = std::sync::mpsc::channel();
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let daemon = tokio::spawn(
            Daemon::with_decoder(scene, Arc::new(RowDecoder(N)), cam, config)
                .input(DmxSource::Channel(dmx_rx))
                .on_running(running_tx)
                .run(async {
                    let _ = stop_rx.await;
                }),
        );
        let handle = loop {
            if let Ok(h) = running_rx.try_recv() {
                break h;
            }
            tokio::task::yield_now().await;
        };
        let started = Instant::now();
        let mut last_frame = 0;
        let end = loop {
            let s = (handle.status)();
            assert!(s.frame >= last_frame, "frame numbers go forward");
            last_frame = s.frame;
            let stages: Vec<Stage> =
                s.lights.iter().map(|l| l.build.as_ref().map_or(Stage::Queued, |b| b.stage)).collect();
            let lit_ready = (0..N).filter(|&i| lit(i)).all(|i| stages[i] == Stage::Ready);
            let dark_started = (0..N).filter(|&i| !lit(i)).any(|i| stages[i] != Stage::Queued);
            assert!(!dark_started || lit_ready || budget.is_some(), "a dark light was built first: {stages:?}");
            let dark_done = match budget {
                None => (0..N).all(|i| stages[i] == Stage::Ready),
                Some(_) => {
                    s.memory.evicted_lights >= 1
                        && s.lights.iter().all(|l| l.build.as_ref().is_some_and(|b| b.pending_ms.is_none()))
                }
            };
            if lit_ready && dark_done {
                break s;
            }
            assert!(started.elapsed() < Duration::from_secs(120), "not built: {stages:?} {:?}", s.memory);
            // Real time for the tracer's threads (the daemon's clock is paused).
            tokio::task::spawn_blocking(|| std::thread::sleep(Duration::from_millis(5))).await.unwrap();
        };
        stop_tx.send(()).unwrap();
        daemon.await.unwrap().unwrap();
        end
    }
    // Without a budget: lit first, then every dark light.
    let all = run(None, lit).await;
    assert!(!all.memory.over_budget && all.memory.evicted_lights == 0, "{:?}", all.memory);
    let per_light = all.memory.buffers_bytes / N as u64;
    assert!(per_light > 0 && all.memory.lit_bytes > 0, "{:?}", all.memory);
    // A budget for the lit lights (their buffers) and half a buffer more.
    let budget = all.memory.lit_bytes + per_light / 2;
    let held = run(Some(budget), lit).await;
    assert!(held.memory.used_bytes <= budget, "{:?}", held.memory);
    assert!(!held.memory.over_budget, "{:?}", held.memory);
    for (i, l) in held.lights.iter().enumerate() {
        let stage = l.build.as_ref().map(|b| b.stage);
        if lit(i) {
            assert_eq!(stage, Some(Stage::Ready), "lit light {i} kept");
        }
    }
    assert!(held.memory.evicted_lights >= 1, "{:?}", held.memory);
}
