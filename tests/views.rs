//! Walking the stage (issue 16): photon maps survive a camera move, cached
//! views come back with their buffers, an orbit through a recorded camera
//! path with DMX arriving ends on the picture `footlight render` makes, the
//! write policy of the camera routes, and a drag in headless Chromium.
//!
//! References: a light build from scratch over the same view (it traces its
//! own photons with the same seed), `render_still` (what `footlight render`
//! runs), and the moving preview function evaluated by the test itself.

use crate::common::*;
use footlight::fixture::{DmxSlots, FixtureState};
use footlight::gpu::CompositorChoice;
use footlight::live::views::{Phase, Pose, Views, preview};
use footlight::live::{Daemon, DaemonConfig, Decode, DmxSource, LightInput, Stage, Tracer, TracerSettings};
use footlight::render::build::{BuildSettings, Cancel, LightBuild};
use footlight::render::display::check_finite;
use footlight::render::photon::PhotonSettings;
use footlight::render::still::{LightJob, render_still};
use footlight::render::{Display, RecursionLimits, RenderSettings, Sampling, View};
use footlight::scene::{Camera, Scene, SceneBuilder};
use glam::Vec3;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::watch;

const W: u32 = 48;
const H: u32 = 32;

/// Universe 1: slot 1 dimmer, slot 2 the spot's x (0-255 → −2..2 m).
struct OneSpot;

fn spot(x: f32) -> footlight::Light {
    footlight::Light::aimed(
        Vec3::new(x, 3.0, 0.5),
        Vec3::new(x, 0.0, 0.0),
        footlight::Beam::Spot(footlight::fixture::SpotBeam::from_beam_field(40.0, 60.0)),
    )
}

fn spot_x(slot: u8) -> f32 {
    -2.0 + 4.0 * f32::from(slot) / 255.0
}

impl Decode for OneSpot {
    fn len(&self) -> usize {
        1
    }
    fn decode(&self, u: &dyn DmxSlots) -> Vec<LightInput> {
        let slots = u.slots(1).copied().unwrap_or([0; 512]);
        let v = f32::from(slots[0]) / 255.0;
        let x = spot_x(slots[1]);
        let state = FixtureState { v, pan: x, ..FixtureState::default() };
        vec![LightInput { light: spot(x), k: Vec3::splat(1000.0 * v), k_full: Vec3::splat(1000.0), state }]
    }
}

fn scene() -> Arc<Scene> {
    let mut b = SceneBuilder::new();
    let m = lambert(&mut b, 0.8);
    floor(&mut b, 10.0, 0.0, m);
    cube(&mut b, Vec3::new(-0.6, 0.0, -0.6), Vec3::new(0.6, 1.2, 0.6), m);
    Arc::new(b.build())
}

fn start_camera() -> Camera {
    Camera::look_at(Vec3::new(0.0, 5.0, 6.0), Vec3::ZERO, 60f32.to_radians())
}

fn photons() -> PhotonSettings {
    PhotonSettings { stored: 3000, ..PhotonSettings::default() }
}

fn tracer_settings() -> TracerSettings {
    TracerSettings {
        threads: 2,
        build: BuildSettings { photons: Some(photons()), refine_passes: 0, ..BuildSettings::default() },
        ..TracerSettings::default()
    }
}

fn view(scene: &Scene, camera: Camera) -> Arc<View> {
    Arc::new(View::build(scene, camera, W, H, Sampling::Adaptive, RecursionLimits::default()))
}

fn wait_ready(tracer: &Tracer) {
    let t = Instant::now();
    while tracer.published(0).stage != Stage::Ready {
        assert!(t.elapsed() < Duration::from_secs(60), "tracer stuck at {:?}", tracer.published(0).stage);
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The light built from scratch over `view`, as `footlight render` builds it.
fn fresh(scene: &Scene, view: &View, light: footlight::Light) -> Vec<Vec3> {
    let mut build = LightBuild::new(light, 0, tracer_settings().build, Cancel::never());
    let buffer = build.photons(scene, view).expect("finite");
    assert!(build.traced_photons());
    buffer.to_dense()
}

#[test]
fn photon_maps_survive_a_camera_move_and_a_cached_view_comes_back_with_its_buffers() {
    let scene = scene();
    let other = Camera::look_at(Vec3::new(5.0, 4.0, 2.0), Vec3::ZERO, 50f32.to_radians());
    let (va, vb) = (view(&scene, start_camera()), view(&scene, other));
    let tracer = Tracer::new(scene.clone(), va.clone(), 1, tracer_settings());
    tracer.request(0, spot(0.0), 1.0);
    wait_ready(&tracer);
    assert_eq!(tracer.photon_traces(), 1);
    let in_a = tracer.published(0).buffer;

    // Camera move: the light is rebuilt for the new view from its maps.
    let (kept_a, restored) = tracer.set_view(vb.clone(), &[]);
    assert_eq!(restored, 0);
    let kept = kept_a[0].as_ref().expect("view A kept its light");
    assert!(Arc::ptr_eq(&kept.buffer, &in_a) && kept.light == spot(0.0) && kept.stage == Stage::Ready);
    wait_ready(&tracer);
    assert_eq!(tracer.photon_traces(), 1, "a camera move must not re-trace photons");
    let in_b = tracer.published(0).buffer.to_dense();
    // Reused maps give exactly the buffer of a build that traces its own.
    assert_eq!(in_b, fresh(&scene, &vb, spot(0.0)), "view B from reused maps == from scratch");
    assert_ne!(in_b, in_a.to_dense(), "the views differ");

    // Back to A with what it kept: published at once, the same buffer.
    let (kept_b, restored) = tracer.set_view(va.clone(), &kept_a);
    assert_eq!(restored, 1, "cache hit: the light did not move");
    let p = tracer.published(0);
    assert!(Arc::ptr_eq(&p.buffer, &in_a), "the cached buffer itself is shown");
    assert_eq!(p.stage, Stage::Ready);
    assert!(tracer.idle());

    // The light moves while B is away: B rebuilds it on return (its maps
    // were traced once, for the new position, while A was shown).
    let before = tracer.published(0).generation;
    tracer.request(0, spot(1.0), 1.0);
    let t = Instant::now();
    while tracer.published(0).generation == before || !tracer.idle() || tracer.published(0).stage != Stage::Ready {
        assert!(t.elapsed() < Duration::from_secs(60), "the moved light was never rebuilt");
        std::thread::sleep(Duration::from_millis(5));
    }
    assert_eq!(tracer.photon_traces(), 2, "a moved light traces its new maps once");
    let (_, restored) = tracer.set_view(vb.clone(), &kept_b);
    assert_eq!(restored, 0, "the light moved while view B was away");
    wait_ready(&tracer);
    assert_eq!(tracer.photon_traces(), 2);
    assert_eq!(tracer.published(0).buffer.to_dense(), fresh(&scene, &vb, spot(1.0)));

    // A kept buffer that never finished shows at once and is built again.
    let partial = Arc::new(footlight::render::LightBuffer::from_dense(W, H, &vec![Vec3::splat(0.5); (W * H) as usize]));
    let unfinished = footlight::live::Kept { light: spot(1.0), buffer: partial.clone(), stage: Stage::Direct };
    let g0 = tracer.published(0).generation;
    let (_, restored) = tracer.set_view(va.clone(), &[Some(unfinished)]);
    assert_eq!(restored, 1);
    let p = tracer.published(0);
    // Either the kept buffer is on screen, or the rebuild already replaced it.
    assert!(p.generation > g0 + 1 || Arc::ptr_eq(&p.buffer, &partial), "shown until rebuilt");
    wait_ready(&tracer);
    assert_eq!(tracer.published(0).buffer.to_dense(), fresh(&scene, &va, spot(1.0)));
    assert_eq!(tracer.photon_traces(), 2);
    assert!(tracer.shutdown(Duration::from_secs(5)));
}

/// The DMX crate's merged frame for dimmer and x (what the daemon reads).
fn merged(dimmer: u8, x: u8) -> footlight_dmx::Universes {
    let mut slots = [0u8; 512];
    slots[0] = dimmer;
    slots[1] = x;
    let mut u = footlight_dmx::Universes::default();
    u.update(&footlight_dmx::UniverseFrame { universe: 1, slots, at: tokio::time::Instant::now(), stale: false });
    u
}

/// Waits in real time without letting paused tokio time run ahead (a
/// blocking task holds the clock's auto-advance).
async fn pause_real(ms: u64) {
    tokio::task::spawn_blocking(move || std::thread::sleep(Duration::from_millis(ms))).await.unwrap();
}

fn camera_path() -> Vec<(u64, Pose)> {
    let text = std::fs::read_to_string(root().join("tests/data/camera_path.json")).unwrap();
    let doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    doc["path"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let t = p["t_ms"].as_u64().unwrap();
            let mut pose = p.clone();
            pose.as_object_mut().unwrap().remove("t_ms");
            (t, serde_json::from_value(pose).unwrap())
        })
        .collect()
}

#[tokio::test(start_paused = true)]
async fn orbit_through_a_recorded_camera_path_with_dmx_ends_on_the_render_and_returns_from_the_cache() {
    let scene = scene();
    let display = Display::neutral(1000.0);
    let config = DaemonConfig {
        width: W,
        height: H,
        fps: 50.0,
        display,
        compositor: CompositorChoice::Cpu,
        tracer: tracer_settings(),
        ..DaemonConfig::default()
    };
    let period = Duration::from_millis(20);
    let (dmx_tx, dmx_rx) = watch::channel(merged(255, 128));
    let (run_tx, run_rx) = std::sync::mpsc::channel();
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let daemon = Daemon::with_decoder(scene.clone(), Arc::new(OneSpot), start_camera(), config)
        .input(DmxSource::Channel(dmx_rx))
        .on_running(run_tx);
    let task = tokio::spawn(daemon.run(async move {
        let _ = stop_rx.await;
    }));
    let handle = loop {
        if let Ok(h) = run_rx.try_recv() {
            break h;
        }
        pause_real(5).await;
    };
    let status = || (handle.status)();
    let settled = || {
        let s = status();
        s.view.phase == Phase::Still
            && s.lights.iter().all(|l| l.build.as_ref().is_some_and(|b| b.stage == Stage::Ready))
    };
    let wait_settled = || async {
        let t = Instant::now();
        while !settled() {
            assert!(t.elapsed() < Duration::from_secs(60), "never settled: {:?}", status().view);
            // Virtual time runs (the settle timer), then real time (the builds).
            tokio::time::sleep(Duration::from_millis(10)).await;
            pause_real(5).await;
        }
        // Two ticks: the frame after the last publish.
        tokio::time::sleep(period * 2).await;
    };
    wait_settled().await;
    let mut frames = handle.frames.clone();
    let at_start = frames.borrow_and_update().rgb.clone();
    let x = spot_x(128);

    // The orbit: a camera write every 40 ms with a new dimmer level each time.
    let t0 = tokio::time::Instant::now();
    let path = camera_path();
    assert_eq!(path.len(), 12);
    for (i, (t_ms, pose)) in path.iter().enumerate() {
        tokio::time::sleep_until(t0 + Duration::from_millis(*t_ms)).await;
        let camera = pose.camera().unwrap();
        handle.views.move_to_pose(*pose).unwrap();
        let dimmer = 255 - 10 * i as u8;
        dmx_tx.send(merged(dimmer, 128)).unwrap();
        frames.borrow_and_update();
        // A tick that read the DMX just before the send may publish once;
        // the frame after it must show the new level: at most one tick behind.
        let k = Vec3::splat(1000.0 * f32::from(dimmer) / 255.0);
        let mut f = None;
        for _ in 0..2 {
            frames.changed().await.unwrap();
            let next = frames.borrow_and_update().clone();
            if (next.intensity[0] - 1000.0 * f32::from(dimmer) / 255.0).abs() < 1e-3 {
                f = Some(next);
                break;
            }
        }
        let f = f.unwrap_or_else(|| panic!("step {i}: the frame is more than one tick behind the DMX"));
        assert_eq!(status().view.phase, Phase::Moving, "step {i}");
        // The frame is the moving preview of this pose at this level, and finite.
        let linear = preview(&scene, &camera, W, H, 2, &[(&spot(x), k)]);
        check_finite(&linear).unwrap_or_else(|(p, v)| panic!("step {i}: pixel {p} is {v}"));
        assert_eq!(*f.rgb, display.to_srgb8(&linear), "step {i}: the preview of the written pose");
        assert!(linear.iter().any(|v| v.x > 0.0), "step {i}: the preview is lit");
    }

    // The camera stops: the full view is built and ends on the render.
    wait_settled().await;
    let s = status();
    assert_eq!(s.view.cache.misses, 1, "the orbit's last pose was built");
    assert_eq!(s.view.cache.entries, 1, "the start view is cached");
    let last = path.last().unwrap().1.camera().unwrap();
    let k = Vec3::splat(1000.0 * f32::from(255 - 10 * 11u8) / 255.0);
    let settings =
        RenderSettings { width: W, height: H, display, photons: Some(photons()), ..RenderSettings::default() };
    let still = render_still(&scene, last, &[LightJob { light: spot(x), k_full: Vec3::splat(1000.0), k }], &settings)
        .expect("finite");
    check_finite(&still.linear).expect("finite still");
    let expect = display.to_srgb8(&still.linear);
    let rgb = frames.borrow_and_update().rgb.clone();
    let diffs: Vec<u8> = expect.iter().zip(rgb.iter()).map(|(a, b)| a.abs_diff(*b)).collect();
    let mean = diffs.iter().map(|&d| f64::from(d)).sum::<f64>() / diffs.len() as f64;
    let large = diffs.iter().filter(|&&d| d > 8).count() as f64 / diffs.len() as f64;
    assert!(mean <= 0.5 && large <= 0.001, "final still vs render: mean |Δ| {mean:.3}, {:.3} % > 8", large * 100.0);
    assert!(expect.iter().any(|&c| c > 30), "the render is lit");

    // Back to the start view by name: a cache hit, its buffers reused.
    dmx_tx.send(merged(255, 128)).unwrap();
    handle.views.go_to("start").unwrap();
    wait_settled().await;
    let s = status();
    assert_eq!((s.view.cache.hits, s.view.last_restored), (1, 1), "{:?}", s.view);
    assert_eq!(s.view.name.as_deref(), Some("start"));
    assert_eq!(*frames.borrow_and_update().rgb, *at_start, "the start view's picture, from its kept buffer");

    let _ = stop_tx.send(());
    task.await.unwrap().unwrap();
}

/// A raw HTTP/1.1 POST on loopback; returns the status code.
fn http_post(addr: std::net::SocketAddr, path: &str, body: &str, token: Option<&str>) -> u16 {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let token = token.map(|t| format!("x-footlight-token: {t}\r\n")).unwrap_or_default();
    write!(
        s,
        "POST {path} HTTP/1.1\r\nHost: {addr}\r\nContent-Type: application/json\r\n{token}Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    )
    .unwrap();
    let mut out = String::new();
    let _ = s.read_to_string(&mut out);
    out.split(' ').nth(1).and_then(|c| c.parse().ok()).unwrap_or(0)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn camera_writes_need_the_token_from_another_machine_but_not_from_loopback() {
    use footlight::serve::control::Peer;
    use footlight::serve::{ServeConfig, ServeState, Server};
    use tower::ServiceExt;
    let scene = scene();
    let tracer = Arc::new(Tracer::new(scene.clone(), view(&scene, start_camera()), 1, tracer_settings()));
    let views = Arc::new(Views::new(
        scene.clone(),
        tracer,
        start_camera(),
        Vec::new(),
        RecursionLimits::default(),
        Default::default(),
    ));
    let frame = footlight::live::Frame {
        number: 0,
        width: W,
        height: H,
        rgb: Arc::new(vec![0; (W * H * 3) as usize]),
        intensity: Arc::new(vec![0.0]),
        composite_time: Duration::ZERO,
        update: Default::default(),
        k: Arc::new(vec![glam::Vec3::ZERO]),
        buffers: Arc::new(Vec::new()),
        display: footlight::render::Display::default(),
        preview: false,
        haze_density: None,
    };
    let (_tx, rx) = watch::channel(Arc::new(frame));
    let state = ServeState {
        frames: rx,
        status: Arc::new(|| serde_json::json!({})),
        views: Some(views.clone()),
        write_token: Some("s3cret".into()),
    };
    let pose = r#"{"position": [1.0, 4.0, 6.0], "target": [0.0, 0.0, 0.0], "fov_y": 55.0}"#;
    // A client on another machine (its peer address as the accept loop sets it).
    let remote = |token: Option<&str>| {
        let mut req = axum::http::Request::post("/api/camera").header("content-type", "application/json");
        if let Some(t) = token {
            req = req.header("x-footlight-token", t);
        }
        let app =
            footlight::serve::router(state.clone()).layer(axum::Extension(Peer("192.168.1.20:50000".parse().unwrap())));
        let req = req.body(axum::body::Body::from(pose)).unwrap();
        async move { app.oneshot(req).await.unwrap().status().as_u16() }
    };
    // Orbiting turns around what the picture centres on: the cube's front
    // face, where the start camera's centre ray (from (0, 5, 6) at the origin) meets it.
    let focus = views.status().current.target;
    assert!(Vec3::from_array(focus).abs_diff_eq(Vec3::new(0.0, 0.5, 0.6), 1e-3), "{focus:?}");
    assert_eq!(remote(None).await, 403, "no token");
    assert_eq!(remote(Some("guess")).await, 403, "wrong token");
    assert_eq!(views.status().writes, 0, "a refused write moves nothing");
    assert_eq!(remote(Some("s3cret")).await, 204, "the printed token");
    let s = views.status();
    assert_eq!((s.writes, s.phase), (1, Phase::Moving));
    assert_eq!(s.current.position, [1.0, 4.0, 6.0]);
    // A form-style POST (no CORS preflight in a browser) is refused even from loopback.
    let app = footlight::serve::router(state.clone()).layer(axum::Extension(Peer("127.0.0.1:50000".parse().unwrap())));
    let form = axum::http::Request::post("/api/camera")
        .header("content-type", "text/plain")
        .body(axum::body::Body::from(pose))
        .unwrap();
    assert_eq!(app.oneshot(form).await.unwrap().status().as_u16(), 415);
    assert_eq!(views.status().writes, 1);
    // Reads stay open to everyone.
    let app =
        footlight::serve::router(state.clone()).layer(axum::Extension(Peer("192.168.1.20:50000".parse().unwrap())));
    let read = app.oneshot(axum::http::Request::get("/api/views").body(axum::body::Body::empty()).unwrap()).await;
    assert_eq!(read.unwrap().status().as_u16(), 200);

    // Through the real accept loop on loopback: no token needed, bad input is a 400.
    let listener = footlight::serve::bind("127.0.0.1:0".parse().unwrap()).unwrap();
    let addr = listener.local_addr().unwrap();
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let server = Server::new(state.clone(), ServeConfig::for_address(addr));
    let serving = tokio::spawn(server.run(listener, async move {
        let _ = stop_rx.await;
    }));
    let (ok, bad, named, saved) = tokio::task::spawn_blocking(move || {
        (
            http_post(addr, "/api/camera", pose, None),
            http_post(addr, "/api/camera", r#"{"position": [0, 0, 0], "target": [0, 0, 0], "fov_y": 40}"#, None),
            http_post(addr, "/api/camera", r#"{"view": "nowhere"}"#, None),
            http_post(addr, "/api/views", r#"{"name": "balcony"}"#, None),
        )
    })
    .await
    .unwrap();
    assert_eq!((ok, bad, named, saved), (204, 400, 400, 201));
    assert_eq!(views.status().writes, 2);
    assert!(views.list().iter().any(|v| v.name == "balcony" && v.pose.position == [1.0, 4.0, 6.0]));
    let _ = stop_tx.send(());
    serving.await.unwrap().unwrap();
}

#[test]
fn headless_chromium_drags_on_the_page_and_the_picture_changes() {
    let chromium = ["chromium", "chromium-browser"]
        .into_iter()
        .find(|c| std::process::Command::new(c).arg("--version").output().map(|o| o.status.success()).unwrap_or(false));
    let Some(chromium) = chromium else {
        assert!(std::env::var_os("FOOTLIGHT_REQUIRE_BROWSER").is_none(), "chromium required but not installed");
        eprintln!("skipping: chromium not installed");
        return;
    };
    let (tx, rx) = std::sync::mpsc::channel();
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let thread = std::thread::spawn(move || {
        let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
        rt.block_on(async move {
            let listener = footlight::live::bind_http("127.0.0.1:0".parse().unwrap()).await.unwrap();
            let http = listener.local_addr().unwrap();
            let (_dmx_tx, dmx_rx) = watch::channel(merged(255, 128));
            let config = DaemonConfig {
                width: 160,
                height: 100,
                fps: 30.0,
                display: Display::neutral(1000.0),
                compositor: CompositorChoice::Cpu,
                tracer: tracer_settings(),
                ..DaemonConfig::default()
            };
            let (run_tx, run_rx) = std::sync::mpsc::channel();
            let daemon = Daemon::with_decoder(scene(), Arc::new(OneSpot), start_camera(), config)
                .input(DmxSource::Channel(dmx_rx))
                .serve(listener)
                .on_running(run_tx);
            let announce = tokio::task::spawn_blocking(move || {
                let handle = run_rx.recv().unwrap();
                tx.send((http, handle)).unwrap();
            });
            daemon
                .run(async move {
                    let _ = stop_rx.await;
                })
                .await
                .unwrap();
            let _ = announce.await;
        });
    });
    let (http, handle) = rx.recv().unwrap();
    let wait_still = || {
        let t = Instant::now();
        loop {
            let s = (handle.status)();
            if s.view.phase == Phase::Still
                && s.lights.iter().all(|l| l.build.as_ref().is_some_and(|b| b.stage == Stage::Ready))
            {
                std::thread::sleep(Duration::from_millis(200));
                return s;
            }
            assert!(t.elapsed() < Duration::from_secs(60), "never ready: {:?}", s.view);
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    let shot = |name: &str, query: &str| -> image::RgbImage {
        let dir = std::env::temp_dir().join(format!("footlight-views-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("shot.png");
        let o = std::process::Command::new(chromium)
            .args(["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run"])
            .args(["--disable-background-networking", "--disable-component-update", "--disable-sync"])
            .arg(format!("--user-data-dir={}", dir.join("profile").display()))
            .arg(format!("--screenshot={}", file.display()))
            .args(["--window-size=900,400", "--virtual-time-budget=3000"])
            .arg(format!("http://{http}/{query}"))
            .output()
            .unwrap();
        assert!(file.exists(), "no screenshot: {}", String::from_utf8_lossy(&o.stderr));
        let img = image::open(&file).unwrap().to_rgb8();
        let _ = std::fs::remove_dir_all(&dir);
        img
    };
    wait_still();
    // The page's default mode, the buffer stream: while the camera moves it
    // shows the server's moving preview pictures, then the new view's buffers.
    let before = shot("before", "");
    assert_eq!((handle.status)().view.writes, 0, "loading the page writes nothing");
    let after = shot("drag", "?selftest=drag");
    let s = (handle.status)();
    assert!(s.view.writes >= 5, "the drag wrote camera moves: {:?}", s.view);
    assert_ne!(s.view.current.position, Pose::of(&start_camera()).position, "the camera moved");
    // The picture (top left of the page, where the stage image sits) changed.
    let crop = |img: &image::RgbImage| -> Vec<u8> {
        (0..100u32).flat_map(|y| (0..160u32).flat_map(move |x| img.get_pixel(x + 12, y + 12).0)).collect()
    };
    assert!(crop(&before).iter().any(|&c| c > 30), "the stage shows in the page");
    assert_ne!(crop(&before), crop(&after), "the drag changed the picture");
    let _ = stop_tx.send(());
    thread.join().unwrap();
}
