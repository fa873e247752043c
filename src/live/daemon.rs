//! [`Daemon`]: the one owner of every task and channel of `footlight run`,
//! stopped by one signal (DESIGN.md "Owners"). The binary and the
//! integration tests run this same code.
//!
//! ```text
//! Daemon::new(scene, show, camera, config)
//!     .input(DmxSource::Network{..} | Replay{..} | Channel(..))
//!     .serve(listener)
//!     .run(shutdown)
//!
//!   DMX input task ──watch<Universes>──> frame clock task ──watch<Frame>──> HTTP / window
//!   (network nodes or replay)              (tick on the blocking pool:      (typed status
//!                                           decode, k_i, composite)          on request)
//!                                tracer thread + build pool (LightBuild stages)
//!   camera writes (HTTP, window) ──> views task (settle, View build, Tracer::set_view);
//!                                    the clock shows its moving preview meanwhile
//! ```
//!
//! Lifecycle: [`Daemon::run`] starts the tracer, the frame clock, the HTTP
//! server and then the DMX input (a replay starts only once the preview
//! serves). It returns when `shutdown` completes — or, with an error, when
//! any task fails (a task that dies never leaves the daemon running
//! silently). On the way out every task sees the same stop signal, open
//! work gets [`DaemonConfig::shutdown_grace`], and a light build still
//! running after it is left to end with the process.

use super::clock::{Decode, FrameClock};
use super::show::{LiveSlots, Show};
use super::tracer::{Tracer, TracerSettings};
use super::views::{ViewSettings, Views};
use crate::output::{
    CacheSummary, CameraControl, ClockStatus, DaemonStatus, Frame, ImportStatus, InputSummary, LightStatus, NamedView,
    StatusFn,
};
use crate::render::composite::Compositor;
use crate::render::{Display, RecursionLimits, Sampling, View};
use crate::scene::{Camera, Scene};
use crate::serve::{ServeConfig, ServeState};
use footlight_dmx::artnet::ArtNetConfig;
use footlight_dmx::sacn::SacnConfig;
use footlight_dmx::usbpro::UsbProConfig;
use footlight_dmx::{InputConfig, Recording, ReplayOptions, Universes};
use std::collections::VecDeque;
use std::future::Future;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::watch;
use tokio::task::JoinSet;

/// How long open work gets on shutdown, all of it together: the tasks (the
/// HTTP server's connections among them) and the light build in progress
/// share this one deadline, so `footlight run` exits within a second of
/// SIGTERM (issue 33: one value, in one place: the server's
/// [`ServeConfig::SHUTDOWN_GRACE`]).
pub const SHUTDOWN_GRACE: Duration = ServeConfig::SHUTDOWN_GRACE;

/// Every default of the daemon, in one place (CLI flags override them).
#[derive(Clone, Debug)]
pub struct DaemonConfig {
    /// Picture width (paper: 800).
    pub width: u32,
    /// Picture height (paper: 500).
    pub height: u32,
    /// Display frame rate in Hz (1-240).
    pub fps: f64,
    /// Exposure, white balance and highlight roll-off (on by default: beams over white read as beams).
    pub display: Display,
    /// Recursion limits (paper: depth 5).
    pub limits: RecursionLimits,
    /// Tracer and light-build settings.
    pub tracer: TracerSettings,
    /// CPU or GPU compositing.
    pub compositor: crate::gpu::CompositorChoice,
    /// How long open work gets on shutdown, all together (one deadline for
    /// the tasks, the HTTP server's connections and the light build in
    /// progress; [`SHUTDOWN_GRACE`]).
    pub shutdown_grace: Duration,
    /// Camera moves: settle time, view cache budget, preview scale.
    pub views: ViewSettings,
    /// The token non-loopback clients send with camera writes; `None`: one
    /// is made when the preview binds a non-loopback address (and logged).
    pub http_token: Option<String>,
    /// White balance to resolve on the patch at start (`auto`, `none`,
    /// `tungsten`, `5600K`: [`crate::render::display::white_balance_for`]),
    /// replacing `display`'s gains; `None` keeps them (what `footlight run`
    /// passes: `--white-balance`, default `auto`).
    pub white_balance: Option<String>,
}

impl Default for DaemonConfig {
    fn default() -> Self {
        Self {
            width: crate::render::PICTURE_SIZE.0,
            height: crate::render::PICTURE_SIZE.1,
            fps: 60.0,
            // Beams in haze over display white must read as beams (issue 15):
            // the live picture rolls highlights off; `render` PNGs clip unless asked.
            display: Display::default().with_rolloff(Some(crate::render::display::HighlightRolloff::default())),
            limits: RecursionLimits::default(),
            tracer: TracerSettings::default(),
            compositor: crate::gpu::CompositorChoice::Auto,
            shutdown_grace: SHUTDOWN_GRACE,
            views: ViewSettings::default(),
            http_token: None,
            white_balance: None,
        }
    }
}

/// The default preview address: loopback only, nothing exposed to the network.
pub const DEFAULT_HTTP: &str = "127.0.0.1:8080";

/// Where the daemon's DMX comes from.
pub enum DmxSource {
    /// No DMX: the patch's default look.
    None,
    /// Art-Net, sACN and/or an Enttec USB Pro (`None` = off); the show's
    /// routes, universes and LTP masks are added by the daemon.
    Network {
        /// Art-Net node.
        artnet: Option<ArtNetConfig>,
        /// sACN node.
        sacn: Option<SacnConfig>,
        /// USB Pro widget.
        usbpro: Option<UsbProConfig>,
    },
    /// A recording played at `speed` through the show's routes.
    Replay {
        /// The capture.
        recording: Recording,
        /// 1 = real time.
        speed: f64,
        /// Play it again from the start each time it ends (until shutdown);
        /// otherwise the last look holds.
        looped: bool,
    },
    /// Merged universes from elsewhere (tests, embedding).
    Channel(watch::Receiver<Universes>),
}

/// Why the daemon stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
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
    /// The DMX input could not start or failed.
    #[error("DMX input: {0}")]
    Dmx(#[from] footlight_dmx::Error),
    /// The GPU compositor could not start.
    #[error("GPU compositor: {0}")]
    Gpu(String),
    /// A task of the daemon failed; the daemon stopped.
    #[error("the {task} task failed: {message}")]
    Task {
        /// Which task.
        task: &'static str,
        /// What happened.
        message: String,
    },
}

/// Binds the preview listener first, so a taken port is reported before any
/// work starts (a 1024-connection backlog: [`crate::serve::bind`]).
pub async fn bind_http(addr: SocketAddr) -> Result<tokio::net::TcpListener, DaemonError> {
    crate::serve::bind(addr).map_err(|source| DaemonError::Bind { addr, source })
}

/// One stop signal for every task (mini-redis `Shutdown`): cloneable,
/// remembers that it fired.
#[derive(Clone)]
pub struct StopSignal(watch::Receiver<bool>);

/// A new stop signal and the sender that fires it (`send(true)`).
pub fn stop_signal() -> (watch::Sender<bool>, StopSignal) {
    let (tx, rx) = watch::channel(false);
    (tx, StopSignal(rx))
}

impl StopSignal {
    /// Completes once the signal fired (at once if it already had).
    pub async fn fired(mut self) {
        let _ = self.0.wait_for(|s| *s).await;
    }

    /// True once fired.
    pub fn is_fired(&self) -> bool {
        *self.0.borrow()
    }
}

/// What [`Daemon::frames_tap`] hands a window: the frames and the camera control.
pub type FramesTap = (watch::Receiver<Arc<Frame>>, Arc<Views>);

/// The daemon, built up and then [`run`](Daemon::run).
pub struct Daemon {
    scene: Arc<Scene>,
    decoder: Arc<dyn Decode>,
    show: Option<Arc<Show>>,
    camera: Camera,
    config: DaemonConfig,
    source: DmxSource,
    listener: Option<tokio::net::TcpListener>,
    tap: Option<std::sync::mpsc::Sender<FramesTap>>,
    bound: Option<std::sync::mpsc::Sender<DaemonHandle>>,
    named: Vec<NamedView>,
    bodies: Option<Vec<crate::render::bodies::BodyModel>>,
    import: ImportStatus,
}

/// What a running daemon tells its embedder (tests, the binary).
#[derive(Clone)]
pub struct DaemonHandle {
    /// Published frames.
    pub frames: watch::Receiver<Arc<Frame>>,
    /// Local addresses of the DMX sockets, when network input runs.
    pub dmx: Option<footlight_dmx::LocalAddrs>,
    /// The typed status, built on request.
    pub status: StatusFn,
    /// The camera control (what the HTTP routes and the window write to).
    pub views: Arc<Views>,
    /// The write token for non-loopback clients, if the preview needs one.
    pub http_token: Option<String>,
}

impl Daemon {
    /// A daemon showing `scene` from `camera`, lit by `show`.
    pub fn new(scene: Arc<Scene>, show: Arc<Show>, camera: Camera, config: DaemonConfig) -> Self {
        let decoder: Arc<dyn Decode> = show.clone();
        Self {
            scene,
            decoder,
            show: Some(show),
            camera,
            config,
            source: DmxSource::None,
            listener: None,
            tap: None,
            bound: None,
            named: Vec::new(),
            bodies: None,
            import: ImportStatus::default(),
        }
    }

    /// A daemon over any decoder (tests): no routes, the input patch is the
    /// default one.
    pub fn with_decoder(scene: Arc<Scene>, decoder: Arc<dyn Decode>, camera: Camera, config: DaemonConfig) -> Self {
        Self {
            scene,
            decoder,
            show: None,
            camera,
            config,
            source: DmxSource::None,
            listener: None,
            tap: None,
            bound: None,
            named: Vec::new(),
            bodies: None,
            import: ImportStatus::default(),
        }
    }

    /// The named views offered besides the start view
    /// ([`super::views::named_views`]: scene camera, patch `[camera]`, `[[view]]`).
    pub fn named_views(mut self, named: Vec<NamedView>) -> Self {
        self.named = named;
        self
    }

    /// What importing the patch said, for `/api/status` (`import`).
    pub fn import_status(mut self, import: ImportStatus) -> Self {
        self.import = import;
        self
    }

    /// Draws these fixture bodies over every composite (issue 14 item 5;
    /// [`crate::render::bodies::body_models`]); `None` or empty: no bodies.
    pub fn bodies(mut self, models: Option<Vec<crate::render::bodies::BodyModel>>) -> Self {
        self.bodies = models;
        self
    }

    /// Where DMX comes from.
    pub fn input(mut self, source: DmxSource) -> Self {
        self.source = source;
        self
    }

    /// Serves the preview on `listener` (see [`bind_http`]).
    pub fn serve(mut self, listener: tokio::net::TcpListener) -> Self {
        self.listener = Some(listener);
        self
    }

    /// Sends the published frames' channel and the camera control to `tap`
    /// once running (a window).
    pub fn frames_tap(mut self, tap: std::sync::mpsc::Sender<FramesTap>) -> Self {
        self.tap = Some(tap);
        self
    }

    /// Sends a [`DaemonHandle`] once every task runs (tests, embedding).
    pub fn on_running(mut self, tx: std::sync::mpsc::Sender<DaemonHandle>) -> Self {
        self.bound = Some(tx);
        self
    }

    /// Runs until `shutdown` completes (`Ok`) or a task fails (`Err`).
    pub async fn run(self, shutdown: impl Future<Output = ()>) -> Result<(), DaemonError> {
        let Daemon { scene, decoder, show, camera, config, source, listener, tap, bound, named, bodies, import } = self;
        let (stop_tx, stop) = stop_signal();
        tokio::pin!(shutdown);

        // The view (G-buffer and camera paths) and the GPU, off the async workers.
        let t = std::time::Instant::now();
        let (w, h, limits) = (config.width, config.height, config.limits);
        let view_scene = scene.clone();
        let mut view_task =
            tokio::task::spawn_blocking(move || View::build(&view_scene, camera, w, h, Sampling::Adaptive, limits));
        let view = tokio::select! {
            v = &mut view_task => v.map_err(|e| task_error("view", e))?,
            _ = &mut shutdown => return Ok(()),
        };
        tracing::info!(
            "view {w}×{h} ready in {:.0} ms ({} shading vertices)",
            t.elapsed().as_secs_f64() * 1e3,
            view.shading.vertex_count()
        );
        // Haze (issue 15): the patch's [haze] at 100 %; the frame clock
        // weights the density knots with the hazer channel's density.
        let haze = show.as_ref().and_then(|s| {
            let spec = s.patch().haze.as_ref()?;
            let medium = crate::render::media::Medium::from_spec(spec, &scene);
            if medium.is_none() {
                tracing::warn!("[haze] has no box and the scene has no volume: no haze");
            }
            medium
        });
        let tracer = Arc::new(Tracer::with_haze(scene.clone(), Arc::new(view), decoder.len(), config.tracer, haze));
        // A fixture's cells (one light each, under its id) are built together.
        tracer.set_groups(&decoder.labels().iter().map(|l| l.fixture).collect::<Vec<_>>());
        // A failed build's log line names the light as the status does.
        tracer.set_names(decoder.labels().into_iter().map(|l| l.name).collect());
        let named = if named.is_empty() { super::views::named_views(&camera, &scene, None) } else { named };
        let bodies = bodies.map(|m| super::bodies::LiveBodies::new(m, scene.clone()));
        let views = Arc::new(Views::new(scene, tracer.clone(), camera, named, config.limits, config.views));
        // White balance (issue 36 item 7): `config.white_balance` on this rig
        // (`auto`: its own white at full); without one, the display's gains.
        let rig_white = show.as_ref().and_then(|s| s.patch().rig_white());
        let mut display = config.display;
        let white = config
            .white_balance
            .as_deref()
            .and_then(|v| match crate::render::display::white_balance_for(v, rig_white.as_ref()) {
                Ok(c) => Some(c),
                Err(e) => {
                    tracing::warn!("white balance {e}; the display's gains are kept");
                    None
                }
            })
            .unwrap_or_else(|| crate::render::display::WhiteChoice::of_gains(display.white_balance));
        display.white_balance = white.gains;
        tracing::info!("white balance {}: {}", white.setting, white.note);
        views.set_white(white, rig_white);
        let choice = config.compositor;
        let gpu = tokio::task::spawn_blocking(move || crate::gpu::GpuFrames::open(choice, w, h, display))
            .await
            .map_err(|e| task_error("GPU setup", e))?
            .map_err(|e| DaemonError::Gpu(e.to_string()))?;
        // A fixture's cells composite through their group's storage (issue 38).
        let cells = crate::render::group::runs_of(&decoder.labels().iter().map(|l| l.fixture).collect::<Vec<_>>());
        let compositor = Compositor::new(w, h, display).with_group_members(cells, Default::default());
        let mut clock = FrameClock::new(decoder.clone(), tracer.clone(), compositor)
            .with_gpu(gpu)
            .with_views(views.clone(), display)
            .with_bodies(bodies);
        let compositor = clock.gpu_adapter().map(|a| format!("GPU: {a}")).unwrap_or_else(|| "CPU".into());

        // DMX: a network input is bound now (a taken port is an error before
        // anything runs); a replay starts once the preview serves.
        let input_patch = show.as_ref().map(|s| s.input_patch().clone()).unwrap_or_default();
        let mut input_kind = "none";
        let (universes_tx, universes_rx) = watch::channel(Universes::default());
        let mut dmx_status = footlight_dmx::StatusHandle::new();
        let mut local = None;
        let mut network = None;
        let mut replay = None;
        let mut external = None;
        match source {
            DmxSource::None => {}
            DmxSource::Network { artnet, sacn, usbpro } => {
                let input =
                    footlight_dmx::DmxInput::bind(InputConfig { artnet, sacn, usbpro, patch: input_patch.clone() })
                        .await?;
                local = Some(input.local_addrs());
                dmx_status = input.status();
                input_kind = "network";
                network = Some(input);
            }
            DmxSource::Replay { recording, speed, looped } => {
                input_kind = "replay";
                let options = ReplayOptions {
                    speed,
                    start: Duration::ZERO,
                    patch: input_patch.clone(),
                    status: dmx_status.clone(),
                };
                replay = Some((recording, options, looped));
            }
            DmxSource::Channel(rx) => {
                input_kind = "channel";
                external = Some(rx);
            }
        }
        let inputs = match (&network, external) {
            (Some(input), _) => input.frames(),
            (None, Some(rx)) => rx,
            (None, None) => universes_rx,
        };

        let first = {
            let u = inputs.borrow().clone();
            Arc::new(clock.tick(&LiveSlots(&u)))
        };
        let (frames_tx, frames_rx) = watch::channel(first);
        let clock_status = Arc::new(Mutex::new(ClockStatus { compositor, ..ClockStatus::default() }));

        let status_fn: StatusFn = {
            let (frames, inputs, tracer, decoder) =
                (frames_rx.clone(), inputs.clone(), tracer.clone(), decoder.clone());
            let clock_status = clock_status.clone();
            let views = views.clone();
            let map = input_patch.map.clone();
            let labels = decoder.labels();
            let patches = show.as_ref().map(|s| s.light_patches()).unwrap_or_default();
            let cache_budget = config.tracer.cache_bytes;
            let import = import.clone();
            Arc::new(move || {
                let frame = frames.borrow().clone();
                let universes = inputs.borrow();
                let slots = LiveSlots(&universes);
                let lights = labels
                    .iter()
                    .enumerate()
                    .map(|(i, label)| LightStatus {
                        label: label.clone(),
                        patch: patches.get(i).cloned().unwrap_or_default(),
                        dmx: decoder.slots_of(i, &slots),
                        intensity: frame.intensity.get(i).copied().unwrap_or(0.0),
                        build: tracer.report(i),
                    })
                    .collect();
                let dmx = dmx_status.snapshot();
                let counters = [dmx.counters.artnet, dmx.counters.sacn, dmx.counters.usbpro];
                let mut warnings = warnings(&dmx, &map);
                // The tracer is supervised (issue 33): a dead worker or a failed build is said here.
                if let Some(e) = tracer.worker_error() {
                    warnings.push(format!(
                        "the light builder stopped ({e}): no light is rebuilt, the picture shows the last \
                         buffers (a bug; please report it)"
                    ));
                }
                if let (n @ 1.., Some(e)) = tracer.worker_restarts() {
                    warnings.push(format!(
                        "the light builder panicked and was restarted ({n}×; last: {e}) (a bug; please report it)"
                    ));
                }
                warnings.extend(tracer.failed().into_iter().map(|(i, e)| {
                    let name = labels.get(i).map_or_else(|| format!("light {i}"), |l| l.name.clone());
                    format!("{name}: {e}; its last picture stays (a bug; please report it)")
                }));
                let input = InputSummary {
                    kind: input_kind,
                    packets: counters.iter().map(|c| c.received).sum(),
                    malformed: counters.iter().map(|c| c.malformed).sum(),
                    dmx,
                };
                let (entries, bytes) = tracer.cache_usage();
                let memory = tracer.memory();
                if memory.over_budget {
                    warnings.push(format!(
                        "the lit lights alone need {:.0} MB, over the memory budget of {:.0} MB (--memory): \
                         running over it; no dark light is built",
                        memory.used_bytes as f64 / 1e6,
                        memory.budget_bytes as f64 / 1e6
                    ));
                }
                DaemonStatus {
                    version: env!("CARGO_PKG_VERSION"),
                    frame: frame.number,
                    width: frame.width,
                    height: frame.height,
                    clock: clock_status.lock().expect("clock status lock").clone(),
                    input,
                    cache: CacheSummary { entries, bytes, budget_bytes: cache_budget },
                    memory,
                    builds: tracer.build_threads(),
                    view: views.status(),
                    warnings,
                    lights,
                    import: import.clone(),
                    stream: None,
                }
            })
        };

        let mut tasks: JoinSet<(&'static str, Result<(), String>)> = JoinSet::new();
        tasks.spawn(run_clock(clock, config.fps, inputs.clone(), frames_tx, clock_status, stop.clone()));
        tasks.spawn(views.clone().run(stop.clone()));
        tasks.spawn(supervise_tracer(tracer.clone(), stop.clone()));
        let mut http_token = None;
        if let Some(listener) = listener {
            // Timeouts, connection limit and Host check; loopback-only Host
            // unless the address is public on purpose (docs/live.md).
            let local = listener.local_addr().ok();
            let mut serve_config = local.map_or_else(ServeConfig::default, ServeConfig::for_address);
            // One shutdown deadline for the whole daemon (the server's own default is longer).
            serve_config.shutdown_grace = config.shutdown_grace;
            // Camera writes from other machines need a token (serve/control.rs).
            if local.is_some_and(|a| !a.ip().is_loopback()) {
                let token = config.http_token.clone().unwrap_or_else(crate::serve::control::new_token);
                tracing::info!("camera writes from other machines need the token {token}");
                http_token = Some(token);
            }
            let state = ServeState {
                frames: frames_rx.clone(),
                status: status_fn.clone(),
                views: Some(views.clone()),
                write_token: http_token.clone(),
            };
            let server = crate::serve::Server::new(state, serve_config);
            let http_stop = stop.clone();
            tasks.spawn(async move {
                let result = server.run(listener, http_stop.fired()).await;
                ("HTTP", result.map_err(|e| e.to_string()))
            });
        }
        if let Some(input) = network {
            let input_stop = stop.clone();
            tasks.spawn(async move { ("DMX input", input.run(input_stop.fired()).await.map_err(|e| e.to_string())) });
        }
        if let Some((recording, options, looped)) = replay {
            let replay_stop = stop.clone();
            tasks.spawn(async move {
                for pass in 1u64.. {
                    let result = footlight_dmx::replay(
                        &recording,
                        &options,
                        |frame| universes_tx.send_modify(|u| u.update(frame)),
                        replay_stop.clone().fired(),
                    )
                    .await;
                    match result {
                        // An empty recording would loop without waiting: play it once.
                        Ok(summary) if looped && !summary.interrupted && summary.packets > 0 => {
                            tracing::info!("replay pass {pass} finished: {} DMX packets; again", summary.packets);
                            // A replay at unbounded speed never waits: give the other tasks their turn.
                            tokio::task::yield_now().await;
                        }
                        Ok(summary) => {
                            tracing::info!("replay finished: {} DMX packets; holding the last look", summary.packets);
                            return ("replay", Ok(()));
                        }
                        Err(e) => return ("replay", Err(e.to_string())),
                    }
                }
                ("replay", Ok(()))
            });
        }
        if let Some(tap) = tap {
            let _ = tap.send((frames_rx.clone(), views.clone()));
        }
        if let Some(bound) = bound {
            let _ = bound.send(DaemonHandle {
                frames: frames_rx.clone(),
                dmx: local,
                status: status_fn.clone(),
                views: views.clone(),
                http_token: http_token.clone(),
            });
        }

        // Run until the shutdown signal or the first failing task.
        let mut failure = None;
        loop {
            tokio::select! {
                _ = &mut shutdown => break,
                joined = tasks.join_next() => match joined {
                    None => std::future::pending::<()>().await,
                    Some(Ok((_, Ok(())))) => continue, // a finished replay: the look holds
                    Some(Ok((task, Err(message)))) => {
                        failure = Some(DaemonError::Task { task, message });
                        break;
                    }
                    Some(Err(e)) => {
                        failure = Some(task_error("daemon", e));
                        break;
                    }
                }
            }
        }
        tracing::info!("shutting down");
        let _ = stop_tx.send(true);
        // Every build's cancel token fires now, with the tasks' stop signal.
        tracer.stop();
        let grace = config.shutdown_grace;
        let deadline = std::time::Instant::now() + grace;
        let drained = tokio::time::timeout(grace, async {
            while let Some(joined) = tasks.join_next().await {
                if let Ok((task, Err(message))) = joined {
                    tracing::warn!("{task} task ended with an error during shutdown: {message}");
                }
            }
        })
        .await;
        if drained.is_err() {
            tracing::warn!("some tasks did not stop within {} ms; closing them", grace.as_millis());
            tasks.abort_all();
        }
        // The light build gets what is left of the same deadline (it was
        // told to stop with the tasks: every stage checks its token).
        if let Ok(t) = Arc::try_unwrap(tracer) {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            let _ = tokio::task::spawn_blocking(move || t.shutdown(left)).await;
        }
        match failure {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }
}

/// The light builder in the daemon's task set (issue 33: a supervised
/// tracer). Its worker restarts itself after a panic outside any build
/// ([`Tracer::worker_restarts`]); once it has died for good
/// ([`Tracer::worker_error`]) this task ends with the error, so the daemon
/// stops with a non-zero exit code instead of showing a picture that no
/// longer follows the desk. Polled every 100 ms (paused time in tests).
pub async fn supervise_tracer(tracer: Arc<Tracer>, stop: StopSignal) -> (&'static str, Result<(), String>) {
    const TASK: &str = "light builder";
    let mut tick = tokio::time::interval(std::time::Duration::from_millis(100));
    let fired = stop.fired();
    tokio::pin!(fired);
    loop {
        tokio::select! {
            () = &mut fired => return (TASK, Ok(())),
            _ = tick.tick() => {
                if let Some(e) = tracer.worker_error() {
                    return (TASK, Err(format!("it stopped: {e}")));
                }
            }
        }
    }
}

/// What the page should warn about: stale universes and DMX that reaches
/// no patch universe.
fn warnings(dmx: &footlight_dmx::InputStatus, map: &footlight_dmx::UniverseMap) -> Vec<String> {
    use footlight_dmx::FeedState;
    let stale = dmx
        .universes
        .iter()
        .filter(|u| u.state == FeedState::Stale)
        .map(|u| format!("patch universe {}: every source stopped sending; holding the last levels", u.universe));
    // Show's one protocol → input mapping (the DMX crate only reports
    // inputs it received, so a USB Pro widget past 255 is said, not clamped).
    let unpatched = dmx.unpatched.iter().filter(|u| !u.blocked).map(|u| {
        match Show::input_universe(u.input.protocol, u.input.universe) {
            Ok(input) => footlight_dmx::status::unpatched_message(map, input, u.packets),
            Err(e) => format!("unpatched input: {e}"),
        }
    });
    let sockets = [("Art-Net", dmx.sockets.artnet), ("sACN", dmx.sockets.sacn)];
    let drops = sockets.into_iter().filter_map(|(name, s)| {
        let s = s?;
        let drops = s.kernel_drops.filter(|&d| d > 0)?;
        Some(format!(
            "{name}: the kernel dropped {drops} datagram(s) because the receive buffer ({} KiB) was full; \
             levels may have skipped (a larger buffer: docs/dmx.md)",
            s.recv_buffer_bytes / 1024
        ))
    });
    stale.chain(unpatched).chain(drops).collect()
}

fn task_error(task: &'static str, e: tokio::task::JoinError) -> DaemonError {
    let message = if e.is_panic() { "it panicked (a bug; please report it)".to_string() } else { e.to_string() };
    DaemonError::Task { task, message }
}

/// The frame clock task: one tick per display frame until `stop`.
///
/// Each tick (decode, k_i, composite) runs on the blocking pool, so the
/// async workers serving HTTP and DMX never wait for a composite. Frames are
/// *presented on the tick*, one period after they were made, as a display
/// presents on vertical sync: at every tick the frame composited during the
/// last period is sent, then the next one is started. So frames go out at
/// the clock's own cadence whatever each composite took (issue 38 item 4:
/// while a festival rig built, composites of 2-19 ms made the intervals of
/// a send-when-done clock vary by as much, p99 21-42 ms), at the cost of a
/// fixed period of latency (16.7 ms at 60 Hz) from the DMX a tick read to
/// its picture. A composite longer than a period delays its frame to when
/// it ends (the interval shows it), and missed ticks are skipped (a slow
/// frame never causes a burst). Intervals over 20 ms are logged at trace
/// level (`footlight::live::daemon=trace`) with where the time went.
pub async fn run_clock(
    clock: FrameClock,
    fps: f64,
    inputs: watch::Receiver<Universes>,
    frames: watch::Sender<Arc<Frame>>,
    status: Arc<Mutex<ClockStatus>>,
    stop: StopSignal,
) -> (&'static str, Result<(), String>) {
    if !(fps.is_finite() && (1.0..=240.0).contains(&fps)) {
        return ("frame clock", Err(format!("frame rate {fps} Hz is outside 1-240")));
    }
    let period = Duration::from_secs_f64(1.0 / fps);
    let mut interval = tokio::time::interval(period);
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut window = (tokio::time::Instant::now(), 0u32);
    let mut intervals: VecDeque<f64> = VecDeque::with_capacity(600);
    let mut last = tokio::time::Instant::now();
    let stopped = stop.clone().fired();
    tokio::pin!(stopped);
    // The clock is on the blocking pool while a frame is being made.
    let mut idle = Some(clock);
    let mut making: Option<tokio::task::JoinHandle<(FrameClock, Frame)>> = None;
    loop {
        let due = tokio::select! {
            due = interval.tick() => due,
            _ = &mut stopped => return ("frame clock", Ok(())),
        };
        if let Some(handle) = making.take() {
            // Normally finished a while ago; a composite longer than a
            // period is waited for here (this frame is late).
            let (back, frame) = match handle.await {
                Ok(r) => r,
                Err(e) => return ("frame clock", Err(task_error("frame clock", e).to_string())),
            };
            let composite_ms = frame.composite_time.as_secs_f64() * 1e3;
            let group_bytes = back.group_storage_bytes() as u64;
            idle = Some(back);
            let number = frame.number;
            let _ = frames.send(Arc::new(frame));
            let now = tokio::time::Instant::now();
            let interval_ms = now.duration_since(last).as_secs_f64() * 1e3;
            if interval_ms > 20.0 {
                tracing::trace!(
                    "frame {number} sent {interval_ms:.1} ms after the one before ({:.1} ms after its tick; composite {composite_ms:.1} ms)",
                    now.duration_since(due).as_secs_f64() * 1e3
                );
            }
            if intervals.len() == 600 {
                intervals.pop_front();
            }
            intervals.push_back(interval_ms);
            last = now;
            window.1 += 1;
            let elapsed = window.0.elapsed();
            let mut s = status.lock().expect("clock status lock");
            s.composite_ms = composite_ms;
            s.group_storage_bytes = group_bytes;
            if elapsed >= Duration::from_secs(1) {
                s.fps = f64::from(window.1) / elapsed.as_secs_f64();
                s.frame_interval_p99_ms = percentile(intervals.iter().copied(), 0.99);
                window = (now, 0);
            }
        }
        let mut clock = idle.take().expect("the clock is back before the next frame starts");
        let rx = inputs.clone();
        making = Some(tokio::task::spawn_blocking(move || {
            let frame = {
                let universes = rx.borrow();
                clock.tick(&LiveSlots(&universes))
            };
            (clock, frame)
        }));
    }
}

/// The `q` quantile of `values` (nearest rank), 0 when empty.
pub fn percentile(values: impl Iterator<Item = f64>, q: f64) -> f64 {
    let mut v: Vec<f64> = values.filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let rank = ((q.clamp(0.0, 1.0) * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[rank - 1]
}

/// The median of `values` by the same nearest-rank rule as [`percentile`]
/// (the lower middle value of an even count; 0 when there are none).
pub fn median(values: Vec<f64>) -> f64 {
    percentile(values.into_iter(), 0.5)
}
