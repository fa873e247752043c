//! Bridges DMX sources into the frame clock's input: a live network input
//! (`footlight-dmx`'s `DmxInput`) or a recording replayed through the same
//! parsers. Both publish the latest merged universes on a `watch` channel,
//! which the frame clock reads without ever waiting on the input.

use super::clock::Universes;
use crate::serve::StatusFn;
use std::future::Future;
use std::sync::Arc;
use tokio::sync::watch;
use tokio::task::JoinHandle;

/// A running DMX source: its status fields and its task.
pub struct InputHandle {
    /// Counters for `/api/status`.
    pub status: StatusFn,
    /// Finishes when the source stops (error, end of a replay, or shutdown).
    pub task: JoinHandle<Result<(), footlight_dmx::Error>>,
}

/// Runs a bound network input until `shutdown`, forwarding merged frames to `tx`.
pub fn start_network(
    input: footlight_dmx::DmxInput,
    tx: watch::Sender<Arc<Universes>>,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> InputHandle {
    let stats = input.stats();
    let mut frames = input.frames();
    let forward = tokio::spawn(async move {
        while frames.changed().await.is_ok() {
            let u: Universes = frames.borrow_and_update().iter().map(|f| (f.universe, f.slots)).collect();
            if tx.send(Arc::new(u)).is_err() {
                break;
            }
        }
    });
    let task = tokio::spawn(async move {
        let result = input.run(shutdown).await;
        forward.abort();
        result
    });
    let status: StatusFn = Arc::new(move || {
        let s = stats.snapshot();
        let packets = s.artnet.received + s.sacn.received + s.usbpro.received;
        let malformed = s.artnet.malformed + s.sacn.malformed + s.usbpro.malformed;
        serde_json::json!({"input": "network", "packets": packets, "malformed": malformed})
    });
    InputHandle { status, task }
}

/// Replays a recording at `options.speed`, publishing the merged frames to `tx`.
pub fn start_replay(
    recording: footlight_dmx::Recording,
    options: footlight_dmx::ReplayOptions,
    tx: watch::Sender<Arc<Universes>>,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> InputHandle {
    let packets = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let counted = packets.clone();
    let task = tokio::spawn(async move {
        let mut current = Universes::new();
        let summary = footlight_dmx::replay(
            &recording,
            &options,
            |frame| {
                current.insert(frame.universe, frame.slots);
                counted.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let _ = tx.send(Arc::new(current.clone()));
            },
            shutdown,
        )
        .await?;
        tracing::info!("replay finished: {} DMX packets", summary.packets);
        Ok(())
    });
    let status: StatusFn = Arc::new(
        move || serde_json::json!({"input": "replay", "frames": packets.load(std::sync::atomic::Ordering::Relaxed)}),
    );
    InputHandle { status, task }
}
