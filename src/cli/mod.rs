//! The `footlight` commands as library functions: what `src/main.rs` calls
//! once clap has parsed the command line (issue 33 item 4: a thin binary).
//! Each command takes a plain options struct and returns an
//! [`anyhow::Result`]; `main.rs` prints the error and decides the exit code.
//!
//! * [`inputs`]: the scene, the patch and the camera, one choice for
//!   `run`, `render` and `bench`;
//! * [`still`]: `render`, the still pipeline (DMX state, jobs, haze
//!   density, bodies, the written file);
//! * [`run`]: `run`/`replay` (the daemon's wiring) and `record`;
//! * [`bench`]: which `bench` section runs at what size;
//! * [`check`]: `check` and the fixture listings;
//! * [`flags`]: the flags' parse-time validators.

pub mod bench;
pub mod check;
pub mod flags;
pub mod inputs;
pub mod run;
pub mod still;

use anyhow::{Context, Result};

/// The stop signal: SIGINT (Ctrl-C) or SIGTERM. Installed as soon as the
/// runtime exists, so a signal during loading is a clean stop too.
pub struct Signals {
    #[cfg(unix)]
    int: tokio::signal::unix::Signal,
    #[cfg(unix)]
    term: tokio::signal::unix::Signal,
}

impl Signals {
    /// Registers the handlers (call inside the runtime).
    pub fn install() -> Result<Self> {
        #[cfg(unix)]
        {
            use tokio::signal::unix::{SignalKind, signal};
            Ok(Self {
                int: signal(SignalKind::interrupt()).context("installing the SIGINT handler")?,
                term: signal(SignalKind::terminate()).context("installing the SIGTERM handler")?,
            })
        }
        #[cfg(not(unix))]
        Ok(Self {})
    }

    /// Completes on the first signal.
    pub async fn wait(mut self) {
        #[cfg(unix)]
        tokio::select! {
            _ = self.int.recv() => {}
            _ = self.term.recv() => {}
        }
        #[cfg(not(unix))]
        {
            let _ = tokio::signal::ctrl_c().await;
        }
    }
}

/// The commands' tokio runtime: two workers (DMX input and HTTP), timers and I/O.
pub fn runtime() -> Result<tokio::runtime::Runtime> {
    Ok(tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build()?)
}
