//! The daemon as the live benchmarks run it (chase, preview clients, browser
//! stream, walking the stage): one place that starts `live::Daemon` on its
//! own runtime and thread, waits until it runs, and stops it.

use crate::live::{Daemon, DaemonConfig, DaemonHandle};
use std::time::Duration;

/// The benchmarks' daemon settings at `width`×`height`: the CPU compositor
/// (comparable across machines) and a long shutdown grace (a bench waits
/// for its builds).
pub fn config(width: u32, height: u32) -> DaemonConfig {
    DaemonConfig {
        width,
        height,
        compositor: crate::gpu::CompositorChoice::Cpu,
        shutdown_grace: Duration::from_secs(30),
        ..DaemonConfig::default()
    }
}

/// A daemon running on its own thread and runtime.
pub struct Running {
    /// What the daemon tells its embedder (status, frames, addresses).
    pub handle: DaemonHandle,
    stop: tokio::sync::oneshot::Sender<()>,
    runner: std::thread::JoinHandle<Result<(), crate::live::DaemonError>>,
}

/// A two-worker runtime for a benchmark's daemon.
pub fn runtime() -> Result<tokio::runtime::Runtime, String> {
    tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().map_err(|e| e.to_string())
}

impl Running {
    /// Runs `daemon` on `rt` in a thread of its own and waits until every
    /// task runs (at most 10 minutes: the view is built first).
    pub fn start(rt: tokio::runtime::Runtime, daemon: Daemon) -> Result<Self, String> {
        let (running_tx, running_rx) = std::sync::mpsc::channel();
        let (stop, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let daemon = daemon.on_running(running_tx);
        let runner = std::thread::spawn(move || {
            rt.block_on(daemon.run(async {
                let _ = stop_rx.await;
            }))
        });
        let handle =
            running_rx.recv_timeout(Duration::from_secs(600)).map_err(|e| format!("daemon did not start: {e}"))?;
        Ok(Self { handle, stop, runner })
    }

    /// Stops the daemon and returns its result.
    pub fn stop(self) -> Result<(), String> {
        let _ = self.stop.send(());
        self.runner.join().map_err(|_| "the daemon thread panicked".to_string())?.map_err(|e| e.to_string())
    }
}
