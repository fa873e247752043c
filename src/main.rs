//! `footlight` command line: thin clap front over the library. Only this
//! file uses `anyhow` and decides exit codes.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use footlight::render::display::{
    Display, balanced, check_finite, parse_white_balance, write_exr, write_pfm, write_png,
};
use footlight::render::photon::PhotonSettings;
use footlight::render::still::{LightJob, render_still};
use footlight::render::{RecursionLimits, RenderSettings, Sampling};
use footlight::scene::Camera;
use footlight::{Patch, Scene, bench};
use glam::Vec3;
use std::path::{Path, PathBuf};

#[derive(Parser)]
#[command(
    name = "footlight",
    version,
    about = "Live, physically grounded stage-lighting preview (Vierjahn et al. 2010)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a still of the scene lit by the patch's default look.
    Render(RenderArgs),
    /// Run the live daemon: DMX in, background tracer, composite every frame, preview over HTTP.
    Run(RunArgs),
    /// Record the DMX that arrives (Art-Net, sACN, USB Pro) to a pcapng file until Ctrl-C.
    Record(RecordArgs),
    /// Play a recording (ours, or any Wireshark/tcpdump capture of Art-Net or sACN) through the
    /// daemon: `footlight run --replay FILE`.
    Replay {
        /// The recording (pcapng or pcap).
        file: PathBuf,
        #[command(flatten)]
        run: Box<RunArgs>,
    },
    /// Validate a patch file: types, modes, addresses, values; every problem with file:line.
    Check {
        /// The patch file.
        patch: PathBuf,
    },
    /// Measure the paper's figure 6 ratios and anti-aliasing error; writes a report.
    Bench(BenchArgs),
}

/// Where DMX comes from.
#[derive(Args, Clone)]
struct DmxArgs {
    /// Art-Net bind address, or `off`.
    #[arg(long, default_value = "0.0.0.0:6454")]
    artnet: String,
    /// sACN (E1.31) bind address, or `off`. Joins the multicast groups of the patched universes.
    #[arg(long, default_value = "0.0.0.0:5568")]
    sacn: String,
    /// Serial port of an Enttec DMX USB Pro (e.g. /dev/ttyUSB0).
    #[arg(long)]
    usbpro: Option<String>,
}

impl DmxArgs {
    /// The input configuration for patch universes `universes`.
    fn config(&self, universes: Vec<u16>) -> Result<footlight_dmx::InputConfig> {
        use footlight_dmx::{artnet::ArtNetConfig, sacn::SacnConfig, usbpro::UsbProConfig};
        let parse = |what: &str, v: &str| -> Result<Option<std::net::SocketAddr>> {
            if v.eq_ignore_ascii_case("off") {
                return Ok(None);
            }
            v.parse()
                .map(Some)
                .with_context(|| format!("--{what} {v:?}: expected an address like 0.0.0.0:6454, or off"))
        };
        Ok(footlight_dmx::InputConfig {
            artnet: parse("artnet", &self.artnet)?.map(|bind| ArtNetConfig { bind, ..ArtNetConfig::default() }),
            sacn: parse("sacn", &self.sacn)?.map(|bind| SacnConfig { bind, ..SacnConfig::default() }),
            usbpro: self.usbpro.as_ref().map(UsbProConfig::new),
            patch: footlight_dmx::InputPatch { universes, ..footlight_dmx::InputPatch::default() },
        })
    }
}

#[derive(Args)]
struct RecordArgs {
    #[command(flatten)]
    dmx: DmxArgs,
    /// Patch universes to listen to (sACN multicast joins), e.g. 1,2,3.
    #[arg(long, value_delimiter = ',', default_value = "1")]
    universes: Vec<u16>,
    /// Output file (pcapng; Wireshark opens it). An existing file is never replaced without --force.
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing output file.
    #[arg(long)]
    force: bool,
}

#[derive(Args)]
struct RunArgs {
    #[command(flatten)]
    input: SceneArgs,
    #[command(flatten)]
    dmx: DmxArgs,
    /// Play this recording (pcapng/pcap of Art-Net or sACN) instead of listening to the network.
    #[arg(long)]
    replay: Option<PathBuf>,
    /// Replay speed (1 = real time).
    #[arg(long, default_value_t = 1.0)]
    speed: f64,
    /// Picture width in pixels.
    #[arg(long, default_value_t = 800)]
    width: u32,
    /// Picture height in pixels.
    #[arg(long, default_value_t = 500)]
    height: u32,
    /// Display frame rate (Hz).
    #[arg(long, default_value_t = 60.0)]
    fps: f64,
    /// Address of the HTTP preview (127.0.0.1 by default: nothing is exposed to the network).
    #[arg(long, default_value = "127.0.0.1:8080")]
    http: std::net::SocketAddr,
    /// Photons stored per light (0 = direct light only).
    #[arg(long, default_value_t = 50_000)]
    photons: usize,
    /// Illuminance (lx) on a white Lambert surface shown as display white.
    #[arg(long, default_value_t = 1000.0)]
    white_lux: f32,
    /// Compositor: auto (GPU if a hardware adapter exists), cpu, or gpu.
    #[arg(long, value_enum, default_value_t = footlight::gpu::CompositorChoice::Auto)]
    compositor: footlight::gpu::CompositorChoice,
    /// Also show the live picture in a window (build with `--features window`).
    #[arg(long)]
    window: bool,
}

/// Scene, patch and image options shared by `render` and `bench`.
#[derive(Args, Clone)]
struct SceneArgs {
    /// glTF 2.0 scene (.gltf/.glb).
    #[arg(long, default_value = footlight::DEFAULT_SCENE)]
    scene: PathBuf,
    /// Patch file (TOML).
    #[arg(long, default_value = footlight::DEFAULT_PATCH)]
    patch: PathBuf,
}

#[derive(Args)]
struct RenderArgs {
    #[command(flatten)]
    input: SceneArgs,
    /// Image width in pixels.
    #[arg(long, default_value_t = 800)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 500)]
    height: u32,
    /// Maximum Whitted recursion depth (reflection/transmission bounces).
    #[arg(long, default_value_t = 5)]
    depth: u32,
    /// Sampling: one, geometry, adaptive (the paper's) or nine.
    #[arg(long, value_enum, default_value_t = Sampling::Adaptive)]
    sampling: Sampling,
    /// Anti-aliasing gradient threshold on the 0-255 scale (paper: 15-25).
    #[arg(long, default_value_t = 20.0)]
    aa_threshold: f32,
    /// Illuminance (lx) on a white Lambert surface shown as display white.
    #[arg(long, default_value_t = 1000.0)]
    white_lux: f32,
    /// DMX levels for the still: `U/ADDR=VALUE,...` (universe and address from 1, value 0-255).
    #[arg(long, value_delimiter = ',')]
    set: Vec<String>,
    /// Render the state of this DMX recording (pcapng/pcap) at `--at` seconds.
    #[arg(long)]
    dmx: Option<PathBuf>,
    /// Time into the `--dmx` recording, in seconds.
    #[arg(long, default_value_t = 0.0)]
    at: f64,
    /// Photons stored per light for the indirect term (paper: 50000); 0 = direct light only.
    #[arg(long, default_value_t = 50_000)]
    photons: usize,
    /// Photons in each radiance estimate (paper: 150).
    #[arg(long, default_value_t = 150)]
    estimate: usize,
    /// Output file: `.png` (8-bit sRGB, exposure and clipping as on screen), or
    /// `.exr` / `.pfm` (linear cd/m² times the white balance, float, unclipped).
    /// An existing file is never replaced without --force.
    #[arg(long)]
    out: PathBuf,
    /// White balance: none, tungsten (3200 K neutral) or a colour temperature such as 5600K.
    #[arg(long, default_value = "tungsten")]
    white_balance: String,
    /// Replace an existing output file.
    #[arg(long)]
    force: bool,
}

#[derive(Args)]
struct BenchArgs {
    #[command(flatten)]
    input: SceneArgs,
    /// CI-sized run: 200×125, one repetition.
    #[arg(long)]
    quick: bool,
    /// Output folder (default bench/runs/<date>-<host>/).
    #[arg(long)]
    out: Option<PathBuf>,
}

fn main() -> Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()))
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    match cli.command {
        Command::Render(args) => render(args),
        Command::Run(args) => run(args),
        Command::Record(args) => record(args),
        Command::Replay { file, mut run } => {
            run.replay = Some(file);
            self::run(*run)
        }
        Command::Check { patch } => check(&patch),
        Command::Bench(args) => {
            let (scene, patch) = load_inputs(&args.input)?;
            let camera = choose_camera(&scene, &patch);
            let out = args.out.unwrap_or_else(bench::default_out_dir);
            let config = bench::BenchConfig::new(args.quick, resolve(&args.input.scene));
            let report = bench::run(&scene, &patch, camera, &config, &out)?;
            println!("{}", report.summary());
            println!("report written to {}", out.display());
            Ok(())
        }
    }
}

/// Finds a bundled file relative to the working directory, else relative to
/// the source checkout the binary was built from.
fn resolve(path: &Path) -> PathBuf {
    if path.exists() || path.is_absolute() {
        return path.to_path_buf();
    }
    let from_checkout = Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
    if from_checkout.exists() { from_checkout } else { path.to_path_buf() }
}

fn load_inputs(args: &SceneArgs) -> Result<(Scene, Patch)> {
    let scene_path = resolve(&args.scene);
    let t = std::time::Instant::now();
    let scene = footlight::scene::load(&scene_path)?;
    tracing::info!(
        "{}: {} triangles, {:.1} % specular, {} materials, loaded in {:.0} ms",
        scene_path.display(),
        scene.triangle_count(),
        scene.specular_fraction() * 100.0,
        scene.materials.len(),
        t.elapsed().as_secs_f64() * 1e3
    );
    let patch = Patch::load(&resolve(&args.patch))?;
    tracing::info!("{}: {} fixtures", patch.path.display(), patch.fixtures.len());
    Ok((scene, patch))
}

/// Patch camera first, then the scene's, then a seat in the stalls.
fn choose_camera(scene: &Scene, patch: &Patch) -> Camera {
    patch
        .camera
        .map(|c| Camera::look_at(c.position, c.look_at, c.fov_y))
        .or(scene.camera)
        .unwrap_or_else(|| Camera::look_at(Vec3::new(0.0, 1.7, 14.0), Vec3::new(0.0, 1.5, 0.0), 40f32.to_radians()))
}

fn run(args: RunArgs) -> Result<()> {
    use footlight::live::{LiveConfig, TracerSettings};
    if args.width == 0 || args.height == 0 || args.width > 16384 || args.height > 16384 {
        bail!("--width and --height must be between 1 and 16384 (got {}×{})", args.width, args.height);
    }
    let (scene, patch) = load_inputs(&args.input)?;
    let camera = choose_camera(&scene, &patch);
    let display = Display::for_white_lux(args.white_lux);
    let photons = (args.photons > 0).then(|| PhotonSettings { stored: args.photons, ..PhotonSettings::default() });
    let config = LiveConfig {
        width: args.width,
        height: args.height,
        fps: args.fps,
        http: args.http,
        display,
        limits: RecursionLimits::default(),
        tracer: TracerSettings { photons, ..TracerSettings::default() },
        compositor: args.compositor,
    };
    if args.window && !cfg!(feature = "window") {
        bail!(
            "this footlight was built without the window; rebuild with `cargo run --release --features window -- run --window`"
        );
    }
    let (tap_tx, tap_rx) = std::sync::mpsc::channel();
    let tap = args.window.then_some(tap_tx);
    let (close_tx, close_rx) = tokio::sync::oneshot::channel::<()>();
    let daemon = std::thread::spawn(move || run_daemon(args, scene, patch, camera, config, tap, close_rx));
    if let Ok(frames) = tap_rx.recv() {
        #[cfg(feature = "window")]
        {
            let shown = footlight::window::show(frames);
            let _ = close_tx.send(());
            shown?;
        }
        #[cfg(not(feature = "window"))]
        drop((frames, close_tx));
    }
    daemon.join().map_err(|_| anyhow::anyhow!("the daemon thread panicked"))?
}

/// The daemon on its own tokio runtime; returns when a signal or `close` (the window) stops it.
fn run_daemon(
    args: RunArgs,
    scene: footlight::Scene,
    patch: footlight::Patch,
    camera: Camera,
    config: footlight::live::LiveConfig,
    tap: Option<std::sync::mpsc::Sender<tokio::sync::watch::Receiver<std::sync::Arc<footlight::live::Frame>>>>,
    close: tokio::sync::oneshot::Receiver<()>,
) -> Result<()> {
    use footlight::live::Universes;
    use std::sync::Arc;
    let runtime = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build()?;
    runtime.block_on(async move {
        let listener = footlight::live::bind_http(config.http).await?;
        println!("Footlight preview: http://{}/", listener.local_addr()?);
        let (inputs_tx, inputs) = tokio::sync::watch::channel(Arc::new(Universes::new()));
        let patch = Arc::new(patch);
        let decoder = Arc::new(footlight::live::PatchDecoder::new(patch.clone()));
        let (stop_tx, stop_rx) = tokio::sync::watch::channel(false);
        let stopped = |mut rx: tokio::sync::watch::Receiver<bool>| async move {
            let _ = rx.wait_for(|s| *s).await;
        };
        let universes: Vec<u16> = (1..=patch_universes(&patch)).collect();
        let handle = match &args.replay {
            Some(path) => {
                let recording = footlight_dmx::Recording::open(path)?;
                println!(
                    "replaying {} ({:.1} s) at {}×",
                    path.display(),
                    recording.duration().as_secs_f64(),
                    args.speed
                );
                let options = footlight_dmx::ReplayOptions {
                    speed: args.speed,
                    start: std::time::Duration::ZERO,
                    patch: dmx_input_patch(&patch, Vec::new()),
                };
                footlight::live::input::start_replay(recording, options, inputs_tx, stopped(stop_rx.clone()))
            }
            None => {
                let mut config = args.dmx.config(universes.clone())?;
                config.patch = dmx_input_patch(&patch, universes);
                let input = footlight_dmx::DmxInput::bind(config).await?;
                let addrs = input.local_addrs();
                println!("listening for DMX: Art-Net {:?}, sACN {:?}", addrs.artnet, addrs.sacn);
                footlight::live::input::start_network(input, inputs_tx, stopped(stop_rx.clone()))
            }
        };
        let (status, input_task) = (handle.status, handle.task);
        let shutdown = async move {
            tokio::select! {
                _ = shutdown_signal() => {}
                _ = close => {}
            }
        };
        footlight::live::run(Arc::new(scene), camera, decoder, inputs, listener, config, status, tap, shutdown).await?;
        let _ = stop_tx.send(true);
        match input_task.await {
            Ok(result) => result?,
            Err(e) if e.is_cancelled() => {}
            Err(e) => bail!("DMX input task failed: {e}"),
        }
        Ok::<(), anyhow::Error>(())
    })
}

/// The DMX state a still shows: a recording at a moment, then `--set` levels.
fn still_universes(args: &RenderArgs, patch: &footlight::Patch) -> Result<footlight::live::Universes> {
    let mut universes = footlight::live::Universes::new();
    if let Some(path) = &args.dmx {
        if !(args.at.is_finite() && args.at >= 0.0) {
            bail!("--at {} must be a time in seconds >= 0", args.at);
        }
        let recording = footlight_dmx::Recording::open(path)?;
        let input = dmx_input_patch(patch, Vec::new());
        for frame in footlight_dmx::state_at(&recording, std::time::Duration::from_secs_f64(args.at), &input)? {
            universes.insert(frame.universe, frame.slots);
        }
    }
    for item in &args.set {
        let (lhs, value) =
            item.split_once('=').with_context(|| format!("--set {item:?}: expected U/ADDR=VALUE, e.g. 1/1=255"))?;
        let (u, a) = lhs.split_once('/').with_context(|| format!("--set {item:?}: expected U/ADDR=VALUE"))?;
        let u: u16 = u.trim().parse().with_context(|| format!("--set {item:?}: universe must be a number from 1"))?;
        let a: u16 = a.trim().parse().with_context(|| format!("--set {item:?}: address must be 1-512"))?;
        let v: u8 = value.trim().parse().with_context(|| format!("--set {item:?}: value must be 0-255"))?;
        if u == 0 || !(1..=512).contains(&a) {
            bail!("--set {item:?}: universe counts from 1 and the address is 1-512");
        }
        let frame = universes.entry(u).or_insert_with(|| patch.look_universes.get(u).copied().unwrap_or([0; 512]));
        frame[usize::from(a) - 1] = v;
    }
    Ok(universes)
}

/// Every fixture's tracer light and k_i for a DMX state (eq. 4).
fn jobs_for(patch: &footlight::Patch, universes: &footlight::live::Universes) -> Vec<LightJob> {
    use footlight::live::Decode;
    footlight::live::PatchDecoder::new(std::sync::Arc::new(patch.clone()))
        .decode(universes)
        .into_iter()
        .map(|i| LightJob { light: i.light, k_full: i.k_full, k: i.k })
        .collect()
}

/// The DMX input's universes and LTP masks from the patch.
fn dmx_input_patch(patch: &footlight::Patch, universes: Vec<u16>) -> footlight_dmx::InputPatch {
    let ltp = patch
        .ltp_addresses()
        .into_iter()
        .map(|(u, addrs)| (u, footlight_dmx::SlotMask::from_addresses(addrs)))
        .collect();
    footlight_dmx::InputPatch { universes, ltp, ..footlight_dmx::InputPatch::default() }
}

fn check(path: &Path) -> Result<()> {
    match footlight::fixture::check(path) {
        Ok(patch) => {
            let mut universes: Vec<u16> = patch.fixtures.iter().filter_map(|f| f.dmx.map(|(u, _)| u)).collect();
            universes.sort_unstable();
            universes.dedup();
            println!("{}: ok, {} fixtures on universes {universes:?}", path.display(), patch.fixtures.len());
            Ok(())
        }
        Err(errors) => {
            for e in &errors {
                eprintln!("{e}");
            }
            bail!("{}: {} problem(s)", path.display(), errors.len())
        }
    }
}

/// Highest patch universe any fixture uses (at least 1).
fn patch_universes(patch: &footlight::Patch) -> u16 {
    patch.fixtures.iter().filter_map(|f| f.dmx.map(|(u, _)| u)).max().unwrap_or(1)
}

/// Refuses to replace a file the user already has, unless `force`.
fn check_output(path: &Path, force: bool) -> Result<()> {
    if path.exists() && !force {
        bail!("{} already exists; choose another name or add --force to replace it", path.display());
    }
    Ok(())
}

fn record(args: RecordArgs) -> Result<()> {
    check_output(&args.out, args.force)?;
    let runtime = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build()?;
    runtime.block_on(async move {
        let config = args.dmx.config(args.universes.clone())?;
        println!("recording DMX to {} until Ctrl-C", args.out.display());
        let summary = footlight_dmx::record(&args.out, config, shutdown_signal()).await?;
        println!(
            "wrote {} packets ({:.1} s, {} lost) to {}",
            summary.packets,
            summary.duration.as_secs_f64(),
            summary.lost,
            args.out.display()
        );
        Ok(())
    })
}

/// Completes on Ctrl-C or SIGTERM.
async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        _ = ctrl_c => {}
        _ = term => {}
    }
}

fn render(args: RenderArgs) -> Result<()> {
    if args.width == 0 || args.height == 0 || args.width > 16384 || args.height > 16384 {
        bail!("--width and --height must be between 1 and 16384 (got {}×{})", args.width, args.height);
    }
    if !(args.aa_threshold.is_finite() && args.aa_threshold >= 0.0) {
        bail!("--aa-threshold must be a number >= 0");
    }
    if args.depth > 64 {
        bail!("--depth {} is past the supported 64 bounces", args.depth);
    }
    check_output(&args.out, args.force)?;
    let gains = parse_white_balance(&args.white_balance).map_err(|e| anyhow::anyhow!("--white-balance {e}"))?;
    let format = match args.out.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("png") => "png",
        Some("exr") => "exr",
        Some("pfm") => "pfm",
        _ => bail!("--out {}: the name must end in .png, .exr or .pfm", args.out.display()),
    };
    let (scene, patch) = load_inputs(&args.input)?;
    let camera = choose_camera(&scene, &patch);
    let settings = RenderSettings {
        width: args.width,
        height: args.height,
        limits: RecursionLimits { max_depth: args.depth, ..RecursionLimits::default() },
        sampling: args.sampling,
        aa_threshold: args.aa_threshold,
        display: Display { white_balance: gains, ..Display::for_white_lux(args.white_lux) },
        photons: (args.photons > 0).then(|| PhotonSettings {
            stored: args.photons,
            estimate: args.estimate.max(2),
            ..PhotonSettings::default()
        }),
    };
    let universes = still_universes(&args, &patch)?;
    let jobs = jobs_for(&patch, &universes);
    let still = render_still(&scene, camera, &jobs, &settings)?;
    if let Err((i, v)) = check_finite(&still.linear) {
        bail!("composite pixel {i} is {v}: this is a bug, please report it");
    }
    let (w, h) = (settings.width, settings.height);
    match format {
        "exr" => write_exr(&args.out, w, h, &balanced(&still.linear, gains)).map_err(anyhow::Error::msg)?,
        "pfm" => write_pfm(&args.out, w, h, &balanced(&still.linear, gains))
            .with_context(|| format!("writing {}", args.out.display()))?,
        _ => write_png(&args.out, w, h, settings.display.to_srgb8(&still.linear))
            .with_context(|| format!("writing {}", args.out.display()))?,
    }
    let t = &still.timings;
    tracing::info!(
        "view {:.0} ms, {} light buffers {:.0} ms ({} pixels re-shaded for anti-aliasing), photon maps {:.0} ms, composite {:.1} ms",
        t.view.as_secs_f64() * 1e3,
        still.buffers.len(),
        t.lights.as_secs_f64() * 1e3,
        still.reshaded,
        t.photons.as_secs_f64() * 1e3,
        t.composite.as_secs_f64() * 1e3
    );
    println!("wrote {}", args.out.display());
    Ok(())
}
