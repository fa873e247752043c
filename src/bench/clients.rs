//! "200 preview clients leave the frame clock at 60 Hz" (issues 12 and 17):
//! the daemon with the paper rig serves `/api/frame.png` to N loopback
//! clients polling back to back (what the preview page does) while a light
//! rebuilds; the frame clock's p99 frame interval and rate are read from
//! the typed status, with and without the clients.

use crate::live::{Daemon, DmxSource, Show};
use crate::scene::{Camera, Scene};
use serde::Serialize;
use std::sync::Arc;
use std::time::Duration;

/// One load level.
#[derive(Clone, Debug, Serialize)]
pub struct ClientsRow {
    /// Polling clients.
    pub clients: usize,
    /// Frame clock p99 frame interval, ms.
    pub frame_interval_p99_ms: f64,
    /// Frame clock rate, fps.
    pub fps: f64,
    /// PNG responses per second over all clients.
    pub responses_per_s: f64,
    /// Response bytes per second, MB/s.
    pub mb_per_s: f64,
    /// Clients that got at least one frame.
    pub clients_served: usize,
    /// Failed requests.
    pub errors: u64,
}

/// Runs each client count for `seconds` against one daemon at `width`×`height`.
pub fn run(
    scene: &Arc<Scene>,
    patch: &crate::Patch,
    camera: Camera,
    (width, height): (u32, u32),
    client_counts: &[usize],
    seconds: f64,
) -> Result<Vec<ClientsRow>, String> {
    let mut config = super::harness::config(width, height);
    config.tracer.build.refine_passes = 64; // the tracer stays busy the whole run
    let rt = super::harness::runtime()?;
    let listener = rt.block_on(crate::live::bind_http("127.0.0.1:0".parse().map_err(|e| format!("{e}"))?));
    let listener = listener.map_err(|e| e.to_string())?;
    let addr = listener.local_addr().map_err(|e| e.to_string())?;
    let daemon =
        Daemon::new(scene.clone(), Arc::new(Show::new(patch.clone()).map_err(|e| e.to_string())?), camera, config)
            .input(DmxSource::None)
            .serve(listener);
    let running = super::harness::Running::start(rt, daemon)?;
    let handle = running.handle.clone();
    // The clients run on their own runtime, as separate processes would.
    let load = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .map_err(|e| e.to_string())?;
    let mut rows = Vec::new();
    for &clients in client_counts {
        let duration = Duration::from_secs_f64(seconds);
        let report = if clients == 0 {
            std::thread::sleep(duration);
            crate::serve::load::LoadReport::default()
        } else {
            load.block_on(crate::serve::load::poll_frames(addr, clients, duration))
        };
        let s = (handle.status)();
        rows.push(ClientsRow {
            clients,
            frame_interval_p99_ms: s.clock.frame_interval_p99_ms,
            fps: s.clock.fps,
            responses_per_s: report.frames as f64 / seconds,
            mb_per_s: report.bytes as f64 / seconds / 1e6,
            clients_served: report.clients_served,
            errors: report.errors,
        });
    }
    running.stop()?;
    Ok(rows)
}

/// Markdown section for report.md.
pub fn markdown(rows: &[ClientsRow]) -> String {
    let mut s = String::from(
        "\n## Preview clients (issues 12, 17)\n\nThe paper rig through the daemon, lights rebuilding and refining, N loopback \
         clients polling `/api/frame.png` back to back (each frame PNG-encoded once for all of them).\n\n\
         | clients | p99 frame interval | frame rate | PNG responses/s | MB/s | clients served | errors |\n\
         |---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {:.1} ms | {:.1} fps | {:.0} | {:.1} | {} | {} |\n",
            r.clients, r.frame_interval_p99_ms, r.fps, r.responses_per_s, r.mb_per_s, r.clients_served, r.errors
        );
    }
    s
}
