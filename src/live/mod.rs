//! The live daemon (`footlight run`): DMX in, a background tracer for lights
//! whose geometry changed, a composite every display frame, the preview out.
//!
//! # Layout
//! * [`clock`]: the frame clock: decode → k_i → composite → publish.
//! * [`tracer`]: worker threads that rebuild dirty lights in stages.
//! * [`cache`]: recent geometry states per light (position presets are instant).
//! * [`input`]: DMX sources (network or a replayed recording) into the clock.
//!
//! Threads: DMX input and HTTP run on tokio; builds run on their own rayon
//! pool; the frame clock runs on a tokio task and only reads published
//! buffers, so neither input nor the clock ever waits for the tracer.
//! Shutdown is an argument (mini-redis style): [`run`] returns when the
//! `shutdown` future completes, after stopping every task.

pub mod cache;
pub mod clock;
pub mod input;
pub mod tracer;

pub use clock::{Decode, Frame, FrameClock, LightInput, Universes};
pub use tracer::{Stage, Tracer, TracerSettings};

use crate::render::composite::Compositor;
use crate::render::{Display, RecursionLimits, Sampling, View};
use crate::scene::{Camera, Scene};
use crate::serve::{ServeState, StatusFn};
use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::watch;

/// Daemon settings.
#[derive(Clone, Debug)]
pub struct LiveConfig {
    /// Picture width.
    pub width: u32,
    /// Picture height.
    pub height: u32,
    /// Display frame rate (Hz).
    pub fps: f64,
    /// HTTP preview address.
    pub http: SocketAddr,
    /// Exposure and white balance.
    pub display: Display,
    /// Recursion limits.
    pub limits: RecursionLimits,
    /// Tracer settings.
    pub tracer: TracerSettings,
    /// CPU or GPU compositing.
    pub compositor: crate::gpu::CompositorChoice,
}

/// Why the daemon could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The preview port is taken (often: another Footlight is running).
    #[error(
        "cannot serve the preview on {addr}: {source} (is another footlight already running? choose another --http address)"
    )]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// The OS error.
        source: std::io::Error,
    },
    /// An internal task failed.
    #[error("internal task failed: {0}")]
    Task(String),
}

/// Binds the preview listener first, so a taken port is reported before any work starts.
pub async fn bind_http(addr: SocketAddr) -> Result<tokio::net::TcpListener, LiveError> {
    tokio::net::TcpListener::bind(addr).await.map_err(|source| LiveError::Bind { addr, source })
}

/// Runs the daemon until `shutdown` completes: builds the view, starts the
/// tracer, the frame clock and the preview server, and stops them in order.
/// `inputs` carries the latest merged DMX universes; `status` adds input
/// counters to `/api/status`; `frames_tap`, if given, receives the channel
/// of published frames (for a window).
#[allow(clippy::too_many_arguments)]
pub async fn run(
    scene: Arc<Scene>,
    camera: Camera,
    decoder: Arc<dyn Decode>,
    inputs: watch::Receiver<Arc<Universes>>,
    listener: tokio::net::TcpListener,
    config: LiveConfig,
    status: StatusFn,
    frames_tap: Option<std::sync::mpsc::Sender<watch::Receiver<Arc<Frame>>>>,
    shutdown: impl Future<Output = ()>,
) -> Result<(), LiveError> {
    let t = std::time::Instant::now();
    let (w, h, limits) = (config.width, config.height, config.limits);
    let view_scene = scene.clone();
    let view = tokio::task::spawn_blocking(move || View::build(&view_scene, camera, w, h, Sampling::Adaptive, limits))
        .await
        .map_err(|e| LiveError::Task(e.to_string()))?;
    tracing::info!(
        "view {w}×{h} ready in {:.0} ms ({} shading vertices)",
        t.elapsed().as_secs_f64() * 1e3,
        view.shading.vertex_count()
    );
    let tracer = Arc::new(Tracer::new(scene, Arc::new(view), decoder.len(), config.tracer));
    let (choice, display) = (config.compositor, config.display);
    let gpu = tokio::task::spawn_blocking(move || crate::gpu::GpuFrames::open(choice, w, h, display))
        .await
        .map_err(|e| LiveError::Task(e.to_string()))?
        .map_err(|e| LiveError::Task(format!("GPU compositor: {e}")))?;
    let mut clock = FrameClock::new(decoder, tracer.clone(), Compositor::new(w, h, config.display)).with_gpu(gpu);
    let compositor_name = clock.gpu_adapter().map(|a| format!("GPU: {a}")).unwrap_or_else(|| "CPU".into());
    let first = Arc::new(clock.tick(&inputs.borrow().clone()));
    let (frames_tx, frames_rx) = watch::channel(first);
    if let Some(tap) = frames_tap {
        let _ = tap.send(frames_rx.clone());
    }

    let (stop_tx, stop_rx) = watch::channel(false);
    let fps = Arc::new(std::sync::Mutex::new(0.0f64));
    let clock_task = tokio::spawn(run_clock(clock, config.fps, inputs, frames_tx, fps.clone(), stop_rx.clone()));
    let status_fn: StatusFn = {
        let fps = fps.clone();
        Arc::new(move || {
            let mut v = status();
            if let Some(o) = v.as_object_mut() {
                o.insert("fps".into(), (*fps.lock().expect("fps lock")).into());
                o.insert("compositor".into(), compositor_name.clone().into());
            }
            v
        })
    };
    let app = crate::serve::router(ServeState { frames: frames_rx, status: status_fn });
    let mut http_stop = stop_rx.clone();
    let http_task = tokio::spawn(async move {
        axum::serve(listener, app)
            .with_graceful_shutdown(async move {
                let _ = http_stop.wait_for(|s| *s).await;
            })
            .await
    });
    shutdown.await;
    tracing::info!("shutting down");
    let _ = stop_tx.send(true);
    let _ = clock_task.await;
    let _ = http_task.await;
    if let Ok(t) = Arc::try_unwrap(tracer) {
        tokio::task::spawn_blocking(move || t.shutdown()).await.map_err(|e| LiveError::Task(e.to_string()))?;
    }
    Ok(())
}

/// The frame clock task: one tick per display frame until `stop` turns true.
/// Missed ticks are skipped (a slow frame never causes a burst).
pub async fn run_clock(
    mut clock: FrameClock,
    fps: f64,
    inputs: watch::Receiver<Arc<Universes>>,
    frames: watch::Sender<Arc<Frame>>,
    measured_fps: Arc<std::sync::Mutex<f64>>,
    mut stop: watch::Receiver<bool>,
) {
    let period = Duration::from_secs_f64(1.0 / fps.clamp(1.0, 240.0));
    let mut interval = tokio::time::interval(period);
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut window = (tokio::time::Instant::now(), 0u32);
    loop {
        tokio::select! {
            _ = interval.tick() => {}
            _ = stop.wait_for(|s| *s) => return,
        }
        let universes = inputs.borrow().clone();
        let frame = clock.tick(&universes);
        let _ = frames.send(Arc::new(frame));
        window.1 += 1;
        let elapsed = window.0.elapsed();
        if elapsed >= Duration::from_secs(1) {
            *measured_fps.lock().expect("fps lock") = f64::from(window.1) / elapsed.as_secs_f64();
            window = (tokio::time::Instant::now(), 0);
        }
    }
}

/// Decodes DMX through the patch: each fixture's channels to its state in
/// real units, then to its tracer geometry and its k_i (eq. 4). Universes
/// without any frame yet show the patch's default look.
pub struct PatchDecoder {
    patch: Arc<crate::Patch>,
}

impl PatchDecoder {
    /// A decoder for `patch`.
    pub fn new(patch: Arc<crate::Patch>) -> Self {
        Self { patch }
    }
}

impl Decode for PatchDecoder {
    fn len(&self) -> usize {
        self.patch.fixtures.len()
    }

    fn decode(&self, universes: &Universes) -> Vec<LightInput> {
        let mut frames = footlight_fixture::Universes::new();
        for (u, slots) in universes {
            frames.set(*u, slots);
        }
        let states = self.patch.decode(&frames);
        self.patch
            .fixtures
            .iter()
            .zip(&states)
            .map(|(f, s)| {
                let dmx = match f.dmx {
                    Some((u, addr)) => {
                        let slots = frames.get(u).or_else(|| self.patch.look_universes.get(u));
                        let start = usize::from(addr.max(1)) - 1;
                        let end = (start + usize::from(f.footprint())).min(512);
                        slots.map(|sl| sl[start..end].to_vec()).unwrap_or_default()
                    }
                    None => Vec::new(),
                };
                LightInput { name: f.name.clone(), light: f.light_of(s), k: f.k_of(s), k_full: f.k_full_of(s), dmx }
            })
            .collect()
    }
}

/// The patch's default look, without DMX: every fixture as the patch file
/// sets it. Used until DMX decoding is configured.
pub struct DefaultLook {
    inputs: Vec<LightInput>,
}

impl DefaultLook {
    /// Takes the fixtures' default states from the patch.
    pub fn new(patch: &crate::Patch) -> Self {
        let inputs = patch
            .fixtures
            .iter()
            .map(|f| LightInput {
                name: f.name.clone(),
                light: f.light.clone(),
                k: f.k(),
                k_full: f.k_full(),
                dmx: Vec::new(),
            })
            .collect();
        Self { inputs }
    }
}

impl Decode for DefaultLook {
    fn len(&self) -> usize {
        self.inputs.len()
    }

    fn decode(&self, _universes: &Universes) -> Vec<LightInput> {
        self.inputs.clone()
    }
}
