//! The browser stream against the frame clock (issue 17 item 4 and its
//! benchmark): the daemon with the given rig, a fader moving on Art-Net
//! (loopback, 44 Hz, so k_i changes every DMX frame) and N loopback viewers
//! of `/api/stream` in buffers mode, in pictures mode, or polling
//! `/api/frame.png`. Per level: the frame clock's p99 frame interval and rate
//! (typed status), bytes per frame per client, the server's CPU per client
//! (CPU time of the daemon runtime's threads, from /proc, above the run
//! without clients), and, for the buffer stream, the time from a fader step
//! (the Art-Net packet leaving) to the k message reaching a viewer (the
//! server side of "fader to canvas": the viewer's composite adds one
//! display frame at most).
//!
//! The switch storm (issue 35 item 4) is N buffers-mode viewers that each
//! send a mode switch (`[0x10, 1]`, `[0x10, 0]`, …) every
//! [`SWITCH_EVERY`]: without the per-client rate limit every switch made
//! the server send every light's buffer again (20 viewers pulled 12.2 GB in
//! 10 s and the clock fell to 55 fps); the row shows the clock, the bytes
//! the viewers got and the switches they sent.

use crate::live::{Daemon, DmxSource, Show};
use crate::scene::{Camera, Scene};
use crate::serve::stream::{FRAME_HEADER_BYTES, MSG_BUFFER, MSG_CLEARED, MSG_FRAME, MSG_PICTURE};
use futures_util::{SinkExt, StreamExt};
use serde::Serialize;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// How often each viewer of the switch storm sends a mode switch.
pub const SWITCH_EVERY: Duration = Duration::from_millis(10);

/// Name prefix of the daemon runtime's threads (CPU accounting).
const SERVER_THREADS: &str = "fl-daemon";

/// How the viewers watch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Viewer {
    /// No viewers (the baseline).
    None,
    /// `/api/stream?mode=buffers`: the browser composites.
    Buffers,
    /// `/api/stream?mode=pictures`: server PNGs pushed on change.
    Pictures,
    /// `/api/frame.png` polled back to back (the page before issue 17).
    Polling,
    /// `/api/stream?mode=buffers`, each viewer switching modes back and
    /// forth every [`SWITCH_EVERY`] (the issue 35 storm).
    Switching,
}

/// One load level.
#[derive(Clone, Debug, Serialize)]
pub struct StreamRow {
    /// How the viewers watch.
    pub viewer: Viewer,
    /// Viewers.
    pub clients: usize,
    /// Frame clock p99 frame interval, ms.
    pub frame_interval_p99_ms: f64,
    /// Frame clock rate, fps.
    pub fps: f64,
    /// Bytes received per published frame per client.
    pub bytes_per_frame_per_client: f64,
    /// Daemon-runtime CPU per client above the baseline, % of one core.
    pub server_cpu_per_client_pct: f64,
    /// Buffer messages received over all clients.
    pub buffer_messages: u64,
    /// Median fader step → k message at a viewer, ms (buffers mode).
    pub fader_to_viewer_ms: Option<f64>,
    /// Clients that received anything.
    pub clients_served: usize,
    /// Mode switches the viewers sent (the switch storm; 0 otherwise).
    pub switches_sent: u64,
}

/// CPU seconds of this process's threads whose name starts with `prefix`
/// (Linux /proc; USER_HZ taken as 100, its value on every Linux port).
fn thread_cpu_s(prefix: &str) -> f64 {
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else { return f64::NAN };
    let mut ticks = 0u64;
    for task in dir.flatten() {
        let comm = std::fs::read_to_string(task.path().join("comm")).unwrap_or_default();
        if !comm.starts_with(prefix) {
            continue;
        }
        let stat = std::fs::read_to_string(task.path().join("stat")).unwrap_or_default();
        // Fields after the parenthesised name: state is field 3; utime, stime are 14, 15.
        let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
        let f: Vec<&str> = rest.split_whitespace().collect();
        ticks += f.get(11).and_then(|v| v.parse::<u64>().ok()).unwrap_or(0)
            + f.get(12).and_then(|v| v.parse::<u64>().ok()).unwrap_or(0);
    }
    ticks as f64 / 100.0
}

/// Counters of one load level's viewers.
#[derive(Default)]
struct Received {
    bytes: AtomicU64,
    buffers: AtomicU64,
    served: AtomicU64,
    /// Mode switches sent (the switch storm).
    switches: AtomicU64,
    /// Nanoseconds since `epoch` of the last k message whose first k_i changed.
    k_changed_ns: AtomicU64,
}

/// One stream viewer reading until `stop`; with `switching` it also sends a
/// mode switch every [`SWITCH_EVERY`], alternating pictures and buffers.
async fn viewer(
    addr: SocketAddr,
    mode: &str,
    switching: bool,
    rx: Arc<Received>,
    stop: Arc<AtomicBool>,
    epoch: Instant,
    probe: bool,
) {
    let Ok((ws, _)) = tokio_tungstenite::connect_async(format!("ws://{addr}/api/stream?mode={mode}")).await else {
        return;
    };
    let (mut tx, mut ws) = ws.split();
    let mut switch = tokio::time::interval(SWITCH_EVERY);
    let mut next_mode = 1u8;
    let mut first = true;
    let mut last_k = f32::NAN;
    while !stop.load(Ordering::Relaxed) {
        let msg = tokio::select! {
            msg = tokio::time::timeout(Duration::from_millis(200), ws.next()) => msg,
            _ = switch.tick(), if switching => {
                let message = tokio_tungstenite::tungstenite::Message::binary(vec![crate::serve::stream::MSG_SET_MODE, next_mode]);
                if tx.send(message).await.is_err() {
                    break;
                }
                rx.switches.fetch_add(1, Ordering::Relaxed);
                next_mode ^= 1;
                continue;
            }
        };
        let msg = match msg {
            Err(_) => continue,
            Ok(Some(Ok(m))) => m,
            Ok(_) => break,
        };
        let tokio_tungstenite::tungstenite::Message::Binary(b) = msg else { continue };
        if first {
            rx.served.fetch_add(1, Ordering::Relaxed);
            first = false;
        }
        rx.bytes.fetch_add(b.len() as u64, Ordering::Relaxed);
        match b.first() {
            Some(&MSG_BUFFER | &MSG_CLEARED) => {
                rx.buffers.fetch_add(1, Ordering::Relaxed);
            }
            Some(&MSG_FRAME) if probe && b.len() >= FRAME_HEADER_BYTES + 4 => {
                // The first light's k (red): the header grew with the
                // display's roll-off, and a fixed offset read a constant.
                let h = FRAME_HEADER_BYTES;
                let k0 = f32::from_le_bytes([b[h], b[h + 1], b[h + 2], b[h + 3]]);
                if k0 != last_k {
                    last_k = k0;
                    rx.k_changed_ns.store(epoch.elapsed().as_nanos() as u64, Ordering::Relaxed);
                }
            }
            Some(&MSG_PICTURE) | Some(_) | None => {}
        }
    }
}

/// Runs each (viewer, clients) level for `seconds` against one daemon at `width`×`height`.
pub fn run(
    scene: &Arc<Scene>,
    patch: &crate::Patch,
    camera: Camera,
    (width, height): (u32, u32),
    levels: &[(Viewer, usize)],
    seconds: f64,
) -> Result<Vec<StreamRow>, String> {
    let config = super::harness::config(width, height);
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name(SERVER_THREADS)
        .enable_all()
        .build()
        .map_err(|e| e.to_string())?;
    let listener = rt.block_on(crate::live::bind_http("127.0.0.1:0".parse().map_err(|e| format!("{e}"))?));
    let listener = listener.map_err(|e| e.to_string())?;
    let addr = listener.local_addr().map_err(|e| e.to_string())?;
    let daemon =
        Daemon::new(scene.clone(), Arc::new(Show::new(patch.clone()).map_err(|e| e.to_string())?), camera, config)
            .input(DmxSource::Network {
                artnet: Some(footlight_dmx::artnet::ArtNetConfig {
                    bind: "127.0.0.1:0".parse().map_err(|e| format!("{e}"))?,
                    ..Default::default()
                }),
                sacn: None,
                usbpro: None,
            })
            .serve(listener);
    let running = super::harness::Running::start(rt, daemon)?;
    let handle = running.handle.clone();
    let target = handle.dmx.as_ref().and_then(|d| d.artnet).ok_or("no Art-Net socket")?;
    let sock = std::net::UdpSocket::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
    let send = |level: u8, seq: u8| {
        let mut slots = [255u8; 24];
        slots[0] = level;
        sock.send_to(&footlight_dmx::artnet::packet::build_dmx(seq, 0, 0, &slots), target).map_err(|e| e.to_string())
    };
    // Every light built before measuring.
    send(255, 0)?;
    let t = Instant::now();
    let ready =
        |l: &crate::output::LightStatus| l.build.as_ref().is_some_and(|b| b.stage == crate::output::Stage::Ready);
    while !(handle.status)().lights.iter().all(ready) {
        if t.elapsed() > Duration::from_secs(600) {
            return Err("lights never finished building".into());
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    // The viewers run on their own runtime, as separate processes would.
    let load = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .thread_name("fl-viewers")
        .enable_all()
        .build()
        .map_err(|e| e.to_string())?;
    let mut rows = Vec::new();
    let mut baseline_cpu = None;
    for &(viewer_kind, clients) in levels {
        let rx = Arc::new(Received::default());
        let stop = Arc::new(AtomicBool::new(false));
        let epoch = Instant::now();
        let mut tasks = Vec::new();
        let duration = Duration::from_secs_f64(seconds);
        let mode = match viewer_kind {
            Viewer::Buffers | Viewer::Switching => Some("buffers"),
            Viewer::Pictures => Some("pictures"),
            Viewer::None | Viewer::Polling => None,
        };
        let frame_spawn = (handle.status)().frame;
        let poll = (viewer_kind == Viewer::Polling && clients > 0)
            .then(|| load.spawn(crate::serve::load::poll_frames(addr, clients, duration)));
        if let Some(mode) = mode {
            for c in 0..clients {
                let switching = viewer_kind == Viewer::Switching;
                tasks.push(load.spawn(viewer(addr, mode, switching, rx.clone(), stop.clone(), epoch, c == 0)));
            }
        }
        // Connected, initial buffers received (the measured window is the steady state).
        let lights = (handle.status)().lights.len() as u64;
        let t = Instant::now();
        while mode == Some("buffers")
            && rx.buffers.load(Ordering::Relaxed) < lights * clients as u64
            && t.elapsed() < Duration::from_secs(30)
        {
            std::thread::sleep(Duration::from_millis(20));
        }
        std::thread::sleep(Duration::from_millis(300));
        let (frame0, cpu0, bytes0) =
            ((handle.status)().frame, thread_cpu_s(SERVER_THREADS), rx.bytes.load(Ordering::Relaxed));
        // The fader: a ramp at 44 Hz for most of the level, then single steps
        // 120 ms apart, each timed to the k message at viewer 0.
        let start = Instant::now();
        let mut i = 0u32;
        let ramp = duration.mul_f64(0.6);
        while start.elapsed() < ramp {
            send((i % 200) as u8 + 20, (i % 255 + 1) as u8)?;
            i += 1;
            if let Some(w) = Duration::from_secs_f64(f64::from(i) / 44.0).checked_sub(start.elapsed()) {
                std::thread::sleep(w);
            }
        }
        let mut latencies = Vec::new();
        let mut step = 0u8;
        while start.elapsed() < duration {
            std::thread::sleep(Duration::from_millis(60));
            let before = rx.k_changed_ns.load(Ordering::Relaxed);
            step = step.wrapping_add(1);
            let sent = epoch.elapsed();
            send(if step.is_multiple_of(2) { 60 } else { 180 }, 0)?;
            let t = Instant::now();
            while t.elapsed() < Duration::from_millis(60) {
                let now = rx.k_changed_ns.load(Ordering::Relaxed);
                if now != before && mode == Some("buffers") {
                    latencies.push((now as f64 - sent.as_nanos() as f64) / 1e6);
                    break;
                }
                std::thread::sleep(Duration::from_micros(200));
            }
        }
        let elapsed = start.elapsed().as_secs_f64();
        let status = (handle.status)();
        let mut frames = status.frame.saturating_sub(frame0).max(1) as f64;
        let cpu = (thread_cpu_s(SERVER_THREADS) - cpu0) / elapsed;
        stop.store(true, Ordering::Relaxed);
        let mut bytes = rx.bytes.load(Ordering::Relaxed) - bytes0;
        let mut served = rx.served.load(Ordering::Relaxed) as usize;
        if let Some(p) = poll {
            let report = load.block_on(p).map_err(|e| e.to_string())?;
            // The pollers ran from their start, not from the window's.
            frames = (handle.status)().frame.saturating_sub(frame_spawn).max(1) as f64;
            bytes = report.bytes;
            served = report.clients_served;
        }
        for t in tasks {
            let _ = load.block_on(t);
        }
        let base = *baseline_cpu.get_or_insert(if clients == 0 { cpu } else { 0.0 });
        latencies.sort_by(f64::total_cmp);
        rows.push(StreamRow {
            viewer: viewer_kind,
            clients,
            frame_interval_p99_ms: status.clock.frame_interval_p99_ms,
            fps: status.clock.fps,
            bytes_per_frame_per_client: if clients == 0 { 0.0 } else { bytes as f64 / frames / clients as f64 },
            server_cpu_per_client_pct: if clients == 0 { 0.0 } else { (cpu - base) * 100.0 / clients as f64 },
            buffer_messages: rx.buffers.load(Ordering::Relaxed),
            fader_to_viewer_ms: latencies.get(latencies.len() / 2).copied(),
            clients_served: served,
            switches_sent: rx.switches.load(Ordering::Relaxed),
        });
    }
    running.stop()?;
    Ok(rows)
}

/// Markdown section for report.md.
pub fn markdown(rows: &[StreamRow], (width, height): (u32, u32)) -> String {
    let every = SWITCH_EVERY.as_millis();
    let interval = crate::serve::stream::MIN_RESTART_INTERVAL.as_secs_f64();
    let mut s = format!(
        "\n## Browser stream (issue 17)\n\nThe rig through the daemon at {width}×{height}, a fader moving on Art-Net \
         (44 Hz ramp, then steps), N loopback viewers: the buffer stream (`/api/stream`, the browser composites), \
         pushed server PNGs (`?mode=pictures`), or `/api/frame.png` polled back to back. Server CPU is the daemon \
         runtime's threads (HTTP, frame clock, PNG encodes) above the run without viewers, per viewer; \
         fader → viewer is the Art-Net packet leaving until the k message arrives (median). \
         `Switching` is the mode-switch storm (issue 35): buffers-mode viewers each sending a switch every \
         {every} ms, pictures and buffers in turn (the server restarts a client's stream at most once per \
         {interval} s).\n\n\
         | viewers | mode | p99 frame interval | frame rate | bytes/frame/viewer | server CPU/viewer | buffer msgs | switches sent | fader → viewer | served |\n\
         |---:|---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {:?} | {:.1} ms | {:.1} fps | {:.0} | {:.2} % | {} | {} | {} | {} |\n",
            r.clients,
            r.viewer,
            r.frame_interval_p99_ms,
            r.fps,
            r.bytes_per_frame_per_client,
            r.server_cpu_per_client_pct,
            r.buffer_messages,
            r.switches_sent,
            r.fader_to_viewer_ms.map_or("–".into(), |v| format!("{v:.1} ms")),
            r.clients_served,
        );
    }
    s
}
