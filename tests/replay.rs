//! Recorded DMX end to end: the daemon plays a recording and its final
//! frame equals `footlight render --dmx FILE --at T` (a separate process);
//! frames at marked cues against golden images; a packet flood over
//! loopback loses no state; the preview page in headless Chromium.

use crate::common::*;
use footlight::live::{DaemonConfig, Decode, DmxSource, Show};
use footlight::render::photon::PhotonSettings;
use footlight::render::still::{LightJob, render_still};
use footlight::render::{BuildSettings, Display, RenderSettings};
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

const W: u32 = 160;
const H: u32 = 100;
const PHOTONS: usize = 5_000;

fn replay_patch() -> footlight::Patch {
    footlight::Patch::load(&root().join("tests/replays/replay-patch.toml")).expect("replay patch")
}

fn recording(name: &str) -> std::path::PathBuf {
    root().join("tests/replays").join(name)
}

enum Source {
    Replay(&'static str),
    ArtNet,
}

struct Daemon {
    http: SocketAddr,
    artnet: Option<SocketAddr>,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Daemon {
    /// The daemon over the bundled stage with the replay patch, on loopback
    /// only: the same `footlight::live::Daemon` the binary runs.
    fn start(source: Source) -> Self {
        Self::start_with(source, replay_patch)
    }

    /// [`Daemon::start`] with another patch.
    fn start_with(source: Source, patch: fn() -> footlight::Patch) -> Self {
        let (tx, rx) = std::sync::mpsc::channel();
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let thread = std::thread::spawn(move || {
            let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
            rt.block_on(async move {
                let scene = Arc::new(stage());
                let camera = scene.camera.unwrap();
                let show = Arc::new(Show::new(patch()).unwrap());
                let listener = footlight::live::bind_http("127.0.0.1:0".parse().unwrap()).await.unwrap();
                let http = listener.local_addr().unwrap();
                let dmx = match source {
                    Source::Replay(name) => DmxSource::Replay {
                        recording: footlight_dmx::Recording::open(recording(name)).unwrap(),
                        speed: f64::INFINITY,
                        looped: false,
                    },
                    Source::ArtNet => DmxSource::Network {
                        artnet: Some(footlight_dmx::artnet::ArtNetConfig {
                            bind: "127.0.0.1:0".parse().unwrap(),
                            ..Default::default()
                        }),
                        sacn: None,
                        usbpro: None,
                    },
                };
                let mut config = DaemonConfig {
                    width: W,
                    height: H,
                    fps: 60.0,
                    display: Display::default(),
                    compositor: footlight::gpu::CompositorChoice::Cpu,
                    ..DaemonConfig::default()
                };
                config.tracer.build.photons = Some(PhotonSettings { stored: PHOTONS, ..PhotonSettings::default() });
                config.tracer.build.refine_passes = 0;
                let (running_tx, running_rx) = std::sync::mpsc::channel();
                let daemon = footlight::live::Daemon::new(scene, show, camera, config)
                    .input(dmx)
                    .serve(listener)
                    .on_running(running_tx);
                let announce = std::thread::spawn(move || {
                    let handle = running_rx.recv().unwrap();
                    tx.send((http, handle.dmx.and_then(|d| d.artnet))).unwrap();
                });
                daemon
                    .run(async {
                        let _ = stop_rx.await;
                    })
                    .await
                    .unwrap();
                announce.join().unwrap();
            });
        });
        let (http, artnet) = rx.recv_timeout(Duration::from_secs(120)).unwrap();
        Self { http, artnet, stop: Some(stop_tx), thread: Some(thread) }
    }

    fn status(&self) -> serde_json::Value {
        serde_json::from_slice(&http_get(self.http, "/api/status").1).unwrap()
    }

    /// Waits until every light is built and a few frames have passed since.
    fn wait_ready(&self) -> serde_json::Value {
        let t = Instant::now();
        loop {
            let s = self.status();
            if s["lights"].as_array().is_some_and(|l| l.iter().all(|l| l["stage"] == "ready")) {
                std::thread::sleep(Duration::from_millis(150));
                return self.status();
            }
            assert!(t.elapsed() < Duration::from_secs(120), "never ready: {s}");
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    fn frame(&self) -> image::RgbImage {
        png_after_now(self.http)
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn max_diff(a: &image::RgbImage, b: &image::RgbImage) -> u8 {
    a.as_raw().iter().zip(b.as_raw()).map(|(x, y)| x.abs_diff(*y)).max().unwrap_or(0)
}

/// Writes actual and amplified difference images under target/golden/ and panics.
fn fail_with_diff(name: &str, actual: &image::RgbImage, expected: &image::RgbImage, why: &str) -> ! {
    let dir = root().join("target/golden");
    std::fs::create_dir_all(&dir).unwrap();
    actual.save(dir.join(format!("{name}.actual.png"))).unwrap();
    let diff: Vec<u8> =
        actual.as_raw().iter().zip(expected.as_raw()).map(|(a, b)| a.abs_diff(*b).saturating_mul(8)).collect();
    image::RgbImage::from_raw(actual.width(), actual.height(), diff)
        .unwrap()
        .save(dir.join(format!("{name}.diff.png")))
        .unwrap();
    panic!("{name}: {why}; see target/golden/{name}.actual.png and .diff.png");
}

#[test]
fn daemon_replay_matches_render_of_the_same_moment() {
    let daemon = Daemon::start(Source::Replay("pan-tilt-sweep.pcapng"));
    let status = daemon.wait_ready();
    assert_eq!(status["input"]["kind"], "replay");
    assert!(status["input"]["packets"].as_u64().unwrap() > 200, "{status}");
    let live = daemon.frame();
    drop(daemon);
    // The same moment through the command line, an independent process.
    let out = std::env::temp_dir().join(format!("footlight-replay-{}.png", std::process::id()));
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_footlight"))
        .current_dir(root())
        .args(["render", "--patch", "tests/replays/replay-patch.toml", "--dmx", "tests/replays/pan-tilt-sweep.pcapng"])
        .args(["--at", "60", "--width", &W.to_string(), "--height", &H.to_string(), "--photons", &PHOTONS.to_string()])
        .args(["--force", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rendered = image::open(&out).unwrap().to_rgb8();
    assert!(live.pixels().any(|p| p.0[0] > 40), "the head lights the stage");
    let d = max_diff(&live, &rendered);
    if d > 1 {
        fail_with_diff("replay-end", &live, &rendered, &format!("daemon frame differs from render by {d} code values"));
    }
}

#[test]
fn frames_at_marked_cues_match_golden_images() {
    let scene = stage();
    let patch = Arc::new(replay_patch());
    let settings = RenderSettings {
        width: W,
        height: H,
        build: BuildSettings {
            photons: Some(PhotonSettings { stored: PHOTONS, ..PhotonSettings::default() }),
            ..BuildSettings::still()
        },
        ..RenderSettings::default()
    };
    let cues = [
        ("cue-fades.pcapng", 2.0, "cue1-fade-in"),
        ("cue-fades.pcapng", 5.0, "cue2-crossfade"),
        ("colour-chase.pcapng", 1.0, "chase-frame"),
        ("pan-tilt-sweep.pcapng", 3.0, "sweep-centre"),
    ];
    for (file, at, name) in cues {
        let rec = footlight_dmx::Recording::open(recording(file)).unwrap();
        let show = Show::new((*patch).clone()).unwrap();
        let frames = footlight_dmx::state_at(&rec, Duration::from_secs_f64(at), show.input_patch()).unwrap();
        let mut universes = footlight::fixture::Universes::new();
        for f in &frames {
            universes.set(f.universe, &f.slots);
        }
        let jobs: Vec<LightJob> = show
            .decode(&universes)
            .into_iter()
            .map(|i| LightJob { light: i.light, k_full: i.k_full, k: i.k, fixture: None })
            .collect();
        let still = render_still(&scene, scene.camera.unwrap(), &jobs, &settings).unwrap();
        let actual = image::RgbImage::from_raw(W, H, settings.display.to_srgb8(&still.linear)).unwrap();
        let golden = root().join(format!("tests/golden/{name}.png"));
        if std::env::var_os("FOOTLIGHT_BLESS").is_some() {
            actual.save(&golden).unwrap();
            blessed(&golden);
            continue;
        }
        let expected = image::open(&golden).expect("golden image (bless with FOOTLIGHT_BLESS=1)").to_rgb8();
        let mean = actual.as_raw().iter().zip(expected.as_raw()).map(|(a, b)| a.abs_diff(*b) as f64).sum::<f64>()
            / actual.as_raw().len() as f64;
        if mean > 0.5 || max_diff(&actual, &expected) > 16 {
            fail_with_diff(name, &actual, &expected, &format!("mean |Δ| {mean:.3}"));
        }
    }
}

fn show150_patch() -> footlight::Patch {
    footlight_mvr::load_patch(&root().join("tests/data/mvr/show150.mvr")).expect("show150.mvr")
}

/// Issue 37: the README's MVR demo starts lit. `show150-look.pcapng`
/// (recorded by `tools/show_look.py`, see tests/replays/README.md) played
/// through show150.mvr: every one of the 336 lights is lit, the moving heads
/// move during the recording, and the picture is lit and coloured.
#[test]
fn show150_look_recording_lights_the_mvr_show_in_colour_and_moves_its_heads() {
    // The recording itself: 44 heads turn between two moments 5 s apart
    // (the file's decoded states, independent of the daemon's timing).
    let rec = footlight_dmx::Recording::open(recording("show150-look.pcapng")).unwrap();
    let show = Show::new(show150_patch()).unwrap();
    let axes = |at: f64| -> Vec<glam::Vec3> {
        let frames = footlight_dmx::state_at(&rec, Duration::from_secs_f64(at), show.input_patch()).unwrap();
        let mut universes = footlight::fixture::Universes::new();
        for f in &frames {
            universes.set(f.universe, &f.slots);
        }
        show.decode(&universes).iter().map(|i| i.light.axis()).collect()
    };
    let (a, b) = (axes(2.5), axes(7.5));
    let turned = a.iter().zip(&b).filter(|(a, b)| a.angle_between(**b).to_degrees() > 2.0).count();
    assert_eq!(turned, 44, "the 44 spots turn, nothing else does");

    // Through the daemon (infinite speed: the last look, which is the first).
    let daemon = Daemon::start_with(Source::Replay("show150-look.pcapng"), show150_patch);
    let t = Instant::now();
    let status = loop {
        let s = daemon.status();
        let lights = s["lights"].as_array().unwrap();
        if s["input"]["packets"].as_u64() == Some(rec.dmx_packets() as u64)
            && lights.iter().all(|l| l["stage"] != "queued")
        {
            break s;
        }
        assert!(t.elapsed() < Duration::from_secs(300), "lights never built: {s}");
        std::thread::sleep(Duration::from_millis(100));
    };
    let lights = status["lights"].as_array().unwrap();
    assert_eq!(lights.len(), 336, "148 fixtures, 336 lights (cells counted)");
    let dark: Vec<&serde_json::Value> =
        lights.iter().filter(|l| l["intensity"].as_f64().is_none_or(|i| i <= 0.0)).map(|l| &l["name"]).collect();
    assert!(dark.is_empty(), "every light is lit; dark: {dark:?}");
    let frame = daemon.frame();
    let n = (frame.width() * frame.height()) as f64;
    let mean = frame.as_raw().iter().map(|&c| f64::from(c)).sum::<f64>() / (3.0 * n);
    let coloured = frame.pixels().filter(|p| p.0.iter().max().unwrap() - p.0.iter().min().unwrap() > 60).count();
    assert!(mean > 10.0, "the stage is lit: mean {mean:.1}");
    assert!(coloured as f64 > 0.05 * n, "the stage is coloured: {coloured} of {n} pixels");
}

fn artdmx(sequence: u8, level: u8) -> Vec<u8> {
    let mut slots = [0u8; 512];
    slots[0] = level; // profile dimmer
    slots[10] = 128; // head pan centre
    slots[12] = 128; // head tilt centre
    slots[14] = 255 - level; // head dimmer
    art_dmx(0, sequence, &slots) // Port-Address 0: patch universe 1
}

#[test]
fn packet_flood_loses_no_state_and_the_clock_keeps_running() {
    let daemon = Daemon::start(Source::ArtNet);
    let target = daemon.artnet.expect("Art-Net bound on loopback");
    assert!(target.ip().is_loopback());
    let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    sock.send_to(&artdmx(1, 10), target).unwrap();
    daemon.wait_ready();
    let before = daemon.status();
    // 10× a desk's 44 Hz for 2 s: 880 packets, bounded, loopback only.
    let start = Instant::now();
    let mut sent = 1u64;
    for i in 0..880u32 {
        let level = (i % 251) as u8;
        sock.send_to(&artdmx((i % 255 + 1) as u8, level), target).unwrap();
        sent += 1;
        let due = Duration::from_micros(2_272 * (u64::from(i) + 1));
        if let Some(wait) = due.checked_sub(start.elapsed()) {
            std::thread::sleep(wait);
        }
    }
    // The final level, with sequence 0 ("off"): always applied, whatever came before.
    let last = 200u8;
    sock.send_to(&artdmx(0, last), target).unwrap();
    sent += 1;
    // Wait (bounded) for the daemon to have taken every packet: no fixed
    // sleep, no wall-clock rate (speed is the bench's: `footlight bench`).
    let deadline = Instant::now() + Duration::from_secs(60);
    let after = loop {
        let s = daemon.status();
        if s["input"]["packets"].as_u64() == Some(sent) && s["lights"][0]["dmx"][0] == last {
            break s;
        }
        assert!(Instant::now() < deadline, "{sent} packets sent, the last level {last}; the daemon has: {s}");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(after["input"]["packets"].as_u64().unwrap(), sent, "every packet received: {after}");
    assert_eq!(after["lights"][0]["dmx"][0], last, "the last level is shown");
    // The clock ran through the flood and still runs after it: frame
    // numbers, not a rate.
    let through = after["frame"].as_u64().unwrap();
    assert!(through > before["frame"].as_u64().unwrap(), "no frame published during the flood: {after}");
    loop {
        let s = daemon.status();
        if s["frame"].as_u64().unwrap() >= through + 10 {
            break;
        }
        assert!(Instant::now() < deadline, "the frame clock stopped at frame {through}: {s}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn preview_page_in_headless_chromium_shows_the_stage_and_follows_a_dimmer() {
    let chromium = ["chromium", "chromium-browser"]
        .into_iter()
        .find(|c| std::process::Command::new(c).arg("--version").output().map(|o| o.status.success()).unwrap_or(false));
    let Some(chromium) = chromium else {
        assert!(std::env::var_os("FOOTLIGHT_REQUIRE_BROWSER").is_none(), "chromium required but not installed");
        eprintln!("skipping: chromium not installed");
        return;
    };
    let daemon = Daemon::start(Source::ArtNet);
    let target = daemon.artnet.unwrap();
    let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let shot = |name: &str| -> image::RgbImage {
        let dir = std::env::temp_dir().join(format!("footlight-chromium-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("shot.png");
        let o = std::process::Command::new(chromium)
            .args(["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run"])
            .args(["--disable-background-networking", "--disable-component-update", "--disable-sync"])
            .arg(format!("--user-data-dir={}", dir.join("profile").display()))
            .arg(format!("--screenshot={}", file.display()))
            .args(["--window-size=900,400", "--virtual-time-budget=3000"])
            .arg(format!("http://{}/", daemon.http))
            .output()
            .unwrap();
        assert!(file.exists(), "no screenshot: {}", String::from_utf8_lossy(&o.stderr));
        image::open(&file).unwrap().to_rgb8()
    };
    sock.send_to(&artdmx(0, 255), target).unwrap();
    daemon.wait_ready();
    let bright = shot("bright");
    sock.send_to(&artdmx(0, 0), target).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    daemon.wait_ready();
    let dark = shot("dark");
    let sum = |img: &image::RgbImage| img.as_raw().iter().map(|&c| c as u64).sum::<u64>();
    assert!(bright.pixels().any(|p| p.0[0] > 60), "the stage picture shows in the page");
    assert_ne!(sum(&bright), sum(&dark), "the page follows the dimmer");
}
