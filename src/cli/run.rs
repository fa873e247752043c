//! `footlight run`, `replay` and `record`: the daemon's wiring from the
//! command's options ([`RunOptions`] → [`DaemonConfig`], the DMX source,
//! the preview, the window) and the DMX recorder.

use super::check::{MAX_LISTED, check_output};
use super::inputs::{Inputs, choose_camera, load_inputs};
use super::{Signals, runtime};
use crate::live::{Daemon, DaemonConfig, DmxSource, Show, TracerSettings};
use crate::render::BuildSettings;
use crate::render::display::{Display, HighlightRolloff};
use crate::render::photon::PhotonSettings;
use anyhow::{Context, Result, bail};
use std::path::PathBuf;
use std::sync::Arc;

/// Where DMX comes from (`--artnet`, `--sacn`, `--sacn-iface`, `--usbpro`).
#[derive(Clone, Debug)]
pub struct DmxOptions {
    /// Art-Net bind address, or `off`.
    pub artnet: String,
    /// sACN bind address, or `off`.
    pub sacn: String,
    /// The network interface (its IPv4 address) for the sACN multicast joins.
    pub sacn_iface: std::net::Ipv4Addr,
    /// Serial port of an Enttec DMX USB Pro.
    pub usbpro: Option<String>,
}

/// `--artnet`/`--sacn` value: an address, or `off`.
fn bind_address(flag: &str, v: &str) -> Result<Option<std::net::SocketAddr>> {
    if v.eq_ignore_ascii_case("off") {
        return Ok(None);
    }
    v.parse().map(Some).with_context(|| format!("--{flag} {v:?}: expected an address like 0.0.0.0:6454, or off"))
}

impl DmxOptions {
    /// The full input configuration for `show`: the nodes these options ask
    /// for, with the show's routes, universes and LTP masks.
    pub fn config(&self, show: &Show) -> Result<footlight_dmx::InputConfig> {
        use footlight_dmx::{artnet::ArtNetConfig, sacn::SacnConfig, usbpro::UsbProConfig};
        Ok(footlight_dmx::InputConfig {
            artnet: bind_address("artnet", &self.artnet)?.map(|bind| ArtNetConfig { bind, ..ArtNetConfig::default() }),
            sacn: bind_address("sacn", &self.sacn)?.map(|bind| SacnConfig {
                bind,
                interface: self.sacn_iface,
                ..SacnConfig::default()
            }),
            usbpro: self.usbpro.as_ref().map(UsbProConfig::new),
            patch: show.input_patch().clone(),
        })
    }

    /// The daemon's network source (the daemon adds the show's routes).
    pub fn source(&self, show: &Show) -> Result<DmxSource> {
        let c = self.config(show)?;
        Ok(DmxSource::Network { artnet: c.artnet, sacn: c.sacn, usbpro: c.usbpro })
    }
}

/// `footlight record`: the DMX that arrives, to a pcapng file until a signal.
pub fn record(dmx: &DmxOptions, patch: &std::path::Path, out: &std::path::Path, force: bool) -> Result<()> {
    check_output(out, force)?;
    let show = Show::new(footlight_mvr::load_patch(&crate::bundled::resolve(patch))?)?;
    runtime()?.block_on(async move {
        let signals = Signals::install()?;
        let config = dmx.config(&show)?;
        println!("recording DMX to {} until Ctrl-C", out.display());
        let summary = footlight_dmx::record(out, config, signals.wait()).await?;
        println!(
            "wrote {} packets ({:.1} s, {} lost) to {}",
            summary.packets,
            summary.duration.as_secs_f64(),
            summary.lost,
            out.display()
        );
        Ok(())
    })
}

/// When `footlight run` draws fixture bodies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BodiesChoice {
    /// On for an MVR patch, off for a TOML one.
    Auto,
    /// Always.
    On,
    /// Never.
    Off,
}

/// Everything `footlight run` (and `replay`) was asked for (its flags, parsed).
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Scene and patch.
    pub inputs: Inputs,
    /// The network DMX input (unused with `replay`).
    pub dmx: DmxOptions,
    /// A recording to play instead of the network.
    pub replay: Option<PathBuf>,
    /// Replay speed (1 = real time).
    pub speed: f64,
    /// Play the recording again each time it ends.
    pub looped: bool,
    /// Picture width in pixels.
    pub width: u32,
    /// Picture height in pixels.
    pub height: u32,
    /// Display frame rate in Hz.
    pub fps: f64,
    /// Address of the HTTP preview.
    pub http: std::net::SocketAddr,
    /// Photons stored per light (0: direct light only).
    pub photons: usize,
    /// Memory budget in bytes.
    pub memory: u64,
    /// Threads of the light-build pool.
    pub build_threads: usize,
    /// Build threads added while the frame clock is quiet (`None`: the
    /// cores `build_threads` leaves, [`crate::live::tracer::quiet_threads_for`]).
    pub quiet_build_threads: Option<usize>,
    /// Illuminance (lx) shown as display white.
    pub white_lux: f32,
    /// Highlight roll-off: `None` keeps the daemon's default (on),
    /// `Some(None)` clips, `Some(Some(r))` rolls off with `r`.
    pub rolloff: Option<Option<HighlightRolloff>>,
    /// White balance to resolve on the rig.
    pub white_balance: String,
    /// When fixture bodies are drawn.
    pub bodies: BodiesChoice,
    /// CPU or GPU compositing.
    pub compositor: crate::gpu::CompositorChoice,
    /// Also show the picture in a window (the `window` feature).
    pub window: bool,
}

impl RunOptions {
    /// The daemon's configuration: [`DaemonConfig::default`] with these options' overrides.
    pub fn daemon_config(&self) -> DaemonConfig {
        let defaults = DaemonConfig::default();
        let rolloff = self.rolloff.unwrap_or(defaults.display.rolloff);
        let display = Display::for_white_lux(self.white_lux).with_rolloff(rolloff);
        let photons = (self.photons > 0).then(|| PhotonSettings { stored: self.photons, ..PhotonSettings::default() });
        DaemonConfig {
            width: self.width,
            height: self.height,
            fps: self.fps,
            display,
            white_balance: Some(self.white_balance.clone()),
            compositor: self.compositor,
            tracer: TracerSettings {
                build: BuildSettings { photons, ..defaults.tracer.build },
                threads: self.build_threads,
                quiet_threads: self
                    .quiet_build_threads
                    .unwrap_or_else(|| crate::live::tracer::quiet_threads_for(self.build_threads)),
                memory: self.memory,
                ..defaults.tracer
            },
            ..defaults
        }
    }
}

/// `footlight run`: the daemon until a signal (or the window's close); with
/// `window`, the window on this thread and the daemon on its own.
pub fn run(args: RunOptions) -> Result<()> {
    if args.looped && args.replay.is_none() {
        bail!("--loop plays a recording again: give one with --replay FILE (or use `footlight replay FILE --loop`)");
    }
    if args.window && !cfg!(feature = "window") {
        bail!(
            "this footlight was built without the window; rebuild with `cargo run --release --features window -- run --window`"
        );
    }
    let (tap_tx, tap_rx) = std::sync::mpsc::channel();
    let tap = args.window.then_some(tap_tx);
    let (close_tx, close_rx) = tokio::sync::oneshot::channel::<()>();
    let daemon = std::thread::spawn(move || run_daemon(args, tap, close_rx));
    if let Ok((frames, views)) = tap_rx.recv() {
        #[cfg(feature = "window")]
        {
            let shown = crate::window::show(frames, Some(views));
            let _ = close_tx.send(());
            shown?;
        }
        #[cfg(not(feature = "window"))]
        drop((frames, views, close_tx));
    }
    daemon.join().map_err(|_| anyhow::anyhow!("the daemon thread panicked (a bug; please report it)"))?
}

/// The daemon on its own tokio runtime; returns when a signal or `close` (the window) stops it.
fn run_daemon(
    args: RunOptions,
    tap: Option<std::sync::mpsc::Sender<crate::live::daemon::FramesTap>>,
    close: tokio::sync::oneshot::Receiver<()>,
) -> Result<()> {
    let rt = runtime()?;
    let result = rt.block_on(async move {
        let signals = Signals::install()?;
        let stop = async move {
            tokio::select! {
                _ = signals.wait() => {}
                _ = close => {}
            }
        };
        tokio::pin!(stop);
        // Bind the preview first: a taken port is reported before minutes of loading.
        let listener = crate::live::bind_http(args.http).await?;
        let input = args.inputs.clone();
        let loading = tokio::task::spawn_blocking(move || load_inputs(&input));
        let (scene, patch, import) = tokio::select! {
            loaded = loading => loaded.context("loading the scene")??,
            _ = &mut stop => return Ok(()),
        };
        let camera = choose_camera(&scene, &patch);
        let named = crate::live::views::named_views(&camera, &scene, Some(&patch));
        // The addresses a desk needs, at start (a big show: `footlight check` lists them).
        let listing = patch.listing();
        if listing.len() <= MAX_LISTED {
            listing.iter().for_each(|f| println!("{f}"));
        } else {
            println!(
                "{} fixtures: `footlight check {}` lists their addresses (and the page's light table)",
                listing.len(),
                args.inputs.patch().display()
            );
        }
        let show = Arc::new(Show::new(patch)?);
        let patch_path = args.inputs.patch_path()?;
        let bodies = match args.bodies {
            BodiesChoice::On => true,
            BodiesChoice::Off => false,
            BodiesChoice::Auto => footlight_mvr::show_of(&patch_path).is_some(),
        };
        let bodies = bodies.then(|| {
            let names: Vec<String> = show.patch().fixtures.iter().map(|f| f.name.clone()).collect();
            let (models, warnings) = crate::render::bodies::body_models(&patch_path, &names, &show.fixture_ids());
            for w in warnings {
                tracing::warn!("{w}");
            }
            let from_gdtf = models.iter().filter(|m| !m.is_estimated()).count();
            tracing::info!("bodies: {} ({from_gdtf} from GDTF models, the rest estimated boxes)", models.len());
            models
        });
        let config = args.daemon_config();
        let source = match &args.replay {
            Some(path) => {
                let recording = footlight_dmx::Recording::open(path)?;
                println!(
                    "replaying {} ({:.1} s) at {}× once the preview serves{}",
                    path.display(),
                    recording.duration().as_secs_f64(),
                    args.speed,
                    if args.looped { ", in a loop" } else { "" }
                );
                DmxSource::Replay { recording, speed: args.speed, looped: args.looped }
            }
            None => args.dmx.source(&show)?,
        };
        let (running_tx, running_rx) = std::sync::mpsc::channel();
        let http = listener.local_addr()?;
        let mut daemon = Daemon::new(Arc::new(scene), show.clone(), camera, config)
            .input(source)
            .serve(listener)
            .named_views(named)
            .import_status(import)
            .bodies(bodies)
            .on_running(running_tx);
        if let Some(tap) = tap {
            daemon = daemon.frames_tap(tap);
        }
        let universes = show.universes();
        let announce = tokio::task::spawn_blocking(move || {
            if let Ok(handle) = running_rx.recv() {
                match &handle.http_token {
                    // The page keeps the token from its address and sends it with camera writes.
                    Some(token) => println!(
                        "Footlight preview: http://{http}/  (camera control from other machines: http://{http}/?token={token})"
                    ),
                    None => println!("Footlight preview: http://{http}/"),
                }
                if let Some(dmx) = handle.dmx {
                    let on = |a: Option<std::net::SocketAddr>| a.map_or("off".to_string(), |a| a.to_string());
                    println!(
                        "listening for DMX: Art-Net {}, sACN {} (patch universes {})",
                        on(dmx.artnet),
                        on(dmx.sacn),
                        universes.iter().map(u16::to_string).collect::<Vec<_>>().join(", ")
                    );
                }
            }
        });
        daemon.run(stop).await?;
        announce.abort();
        Ok::<(), anyhow::Error>(())
    });
    // The daemon has had its grace: a blocking job still running (a view
    // being built, a composite) ends with the process instead of holding
    // the exit (dropping the runtime would wait for it).
    rt.shutdown_background();
    result
}
