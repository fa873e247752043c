//! `footlight` command line: thin clap front over the library. Only this
//! file uses `anyhow` and decides exit codes.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use footlight::live::{Daemon, DaemonConfig, Decode, DmxSource, Show, TracerSettings};
use footlight::render::display::{Display, balanced, check_finite, white_balance_for, write_exr, write_pfm, write_png};
use footlight::render::photon::PhotonSettings;
use footlight::render::still::{LightJob, StillHaze, render_still_hazy};
use footlight::render::{BuildSettings, RecursionLimits, RenderSettings, Sampling};
use footlight::scene::Camera;
use footlight::{Patch, Scene, bench};
use glam::Vec3;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Flag validators: every numeric flag is checked at parse time, with a
/// message naming the allowed range (clap prefixes the flag's name).
mod flags {
    /// A finite number in `lo..=hi`.
    fn number(v: &str, lo: f64, hi: f64, unit: &str) -> Result<f64, String> {
        let x: f64 = v.trim().parse().map_err(|_| format!("expected a number from {lo} to {hi}{unit}"))?;
        if x.is_finite() && (lo..=hi).contains(&x) {
            Ok(x)
        } else {
            Err(format!("must be a number from {lo} to {hi}{unit}"))
        }
    }

    /// `--fps`: 1-240 Hz.
    pub fn fps(v: &str) -> Result<f64, String> {
        number(v, 1.0, 240.0, " Hz")
    }

    /// `--speed`: 0.01-1000 × real time.
    pub fn speed(v: &str) -> Result<f64, String> {
        number(v, 0.01, 1000.0, " (× real time)")
    }

    /// `--at`: 0 s to one week.
    pub fn at(v: &str) -> Result<f64, String> {
        number(v, 0.0, 7.0 * 86400.0, " seconds")
    }

    /// `--white-lux`: (0, 10^7] lx.
    pub fn white_lux(v: &str) -> Result<f32, String> {
        let x = number(v, 0.0, 1e7, " lx")?;
        if x > 0.0 { Ok(x as f32) } else { Err("must be above 0 lx (the illuminance shown as display white)".into()) }
    }

    /// `--rolloff`: off, on, or the display-linear level shown as white.
    pub fn rolloff(v: &str) -> Result<Rolloff, String> {
        footlight::render::display::parse_rolloff(v).map(Rolloff)
    }

    /// `--white-balance` of `run`: auto, none, tungsten or 1000-25000 K (`auto` is
    /// resolved on the loaded rig).
    pub fn white_balance(v: &str) -> Result<String, String> {
        footlight::render::display::white_balance_for(v, None).map(|_| v.trim().to_string())
    }

    /// A parsed `--rolloff` (`None`: clip at display white).
    #[derive(Clone, Copy, Debug)]
    pub struct Rolloff(pub Option<footlight::render::display::HighlightRolloff>);

    /// `--aa-threshold`: 0-255 display steps.
    pub fn aa_threshold(v: &str) -> Result<f32, String> {
        number(v, 0.0, 255.0, " (0-255 display steps)").map(|x| x as f32)
    }

    /// `--memory`: bytes (K/M/G/T) or a percentage of the machine's memory.
    pub fn memory(v: &str) -> Result<u64, String> {
        footlight::memory::parse_budget(v, footlight::memory::total())
    }

    /// `--build-threads`: 1-256, whole.
    pub fn build_threads(v: &str) -> Result<usize, String> {
        number(v, 1.0, 256.0, " threads").and_then(|x| {
            if x.fract() == 0.0 { Ok(x as usize) } else { Err("must be a whole number of threads".into()) }
        })
    }

    /// `--width`/`--height`: 1-16384 pixels.
    pub fn pixels(v: &str) -> Result<u32, String> {
        number(v, 1.0, 16384.0, " pixels")
            .and_then(|x| if x.fract() == 0.0 { Ok(x as u32) } else { Err("must be a whole number of pixels".into()) })
    }

    /// Bytes a light's photon map needs per stored photon (photon, k-d tree
    /// node and irradiance cache share), for the `--photons` message.
    const BYTES_PER_PHOTON: f64 = 64.0;
    /// Most photons stored per light.
    pub const MAX_PHOTONS: usize = 20_000_000;

    /// `--photons`: 0-20,000,000 per light, with the memory it needs.
    pub fn photons(v: &str) -> Result<usize, String> {
        let n: f64 = v.trim().parse().map_err(|_| "expected a whole number of photons".to_string())?;
        if !(n.is_finite() && n >= 0.0 && n.fract() == 0.0) {
            return Err("expected a whole number of photons (0 = direct light only)".into());
        }
        if n > MAX_PHOTONS as f64 {
            return Err(format!(
                "{n} photons per light would need about {:.1} GB per light; at most {MAX_PHOTONS} ({:.1} GB)",
                n * BYTES_PER_PHOTON / 1e9,
                MAX_PHOTONS as f64 * BYTES_PER_PHOTON / 1e9
            ));
        }
        Ok(n as usize)
    }

    /// `--estimate`: 2-10000 photons.
    pub fn estimate(v: &str) -> Result<usize, String> {
        number(v, 2.0, 10_000.0, " photons").map(|x| x as usize)
    }

    /// `--depth`: 0-64 bounces.
    pub fn depth(v: &str) -> Result<u32, String> {
        number(v, 0.0, 64.0, " bounces").map(|x| x as u32)
    }

    /// `--refine`: 0-1000 progressive passes.
    pub fn refine(v: &str) -> Result<u32, String> {
        let x = number(v, 0.0, 1000.0, " passes")?;
        if x.fract() != 0.0 {
            return Err(format!("expected a whole number of passes, got {v}"));
        }
        Ok(x as u32)
    }
}

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
    /// Render a still of the scene lit by the patch's default look, given levels, or a recording.
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
        /// The patch file (TOML or MVR).
        patch: PathBuf,
        /// List every fixture on its own line; without it a show of more than 40 fixtures is
        /// listed in runs of one type and mode.
        #[arg(long)]
        list: bool,
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
    /// sACN (E1.31) bind address, or `off`. Joins the multicast groups of the routed universes.
    #[arg(long, default_value = "0.0.0.0:5568")]
    sacn: String,
    /// Network interface (its IPv4 address) for the sACN multicast joins on a machine with
    /// several network cards; 0.0.0.0 lets the kernel choose (docs/dmx.md).
    #[arg(long, default_value = "0.0.0.0")]
    sacn_iface: std::net::Ipv4Addr,
    /// Serial port of an Enttec DMX USB Pro (e.g. /dev/ttyUSB0).
    #[arg(long)]
    usbpro: Option<String>,
}

/// `--artnet`/`--sacn` value: an address, or `off`.
fn bind_address(flag: &str, v: &str) -> Result<Option<std::net::SocketAddr>> {
    if v.eq_ignore_ascii_case("off") {
        return Ok(None);
    }
    v.parse().map(Some).with_context(|| format!("--{flag} {v:?}: expected an address like 0.0.0.0:6454, or off"))
}

impl DmxArgs {
    /// The full input configuration for `show`: the nodes these flags ask
    /// for, with the show's routes, universes and LTP masks.
    fn config(&self, show: &Show) -> Result<footlight_dmx::InputConfig> {
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
    fn source(&self, show: &Show) -> Result<DmxSource> {
        let c = self.config(show)?;
        Ok(DmxSource::Network { artnet: c.artnet, sacn: c.sacn, usbpro: c.usbpro })
    }
}

#[derive(Args)]
struct RecordArgs {
    #[command(flatten)]
    dmx: DmxArgs,
    /// Patch whose `[[input]]` routes and universes decide the sACN groups joined and the
    /// Art-Net ports announced.
    #[arg(long, default_value = footlight::DEFAULT_PATCH)]
    patch: PathBuf,
    /// Output file (pcapng; Wireshark opens it). An existing file is never replaced without --force.
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing output file.
    #[arg(long)]
    force: bool,
}

/// When `footlight run` draws fixture bodies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum BodiesChoice {
    /// On for an MVR patch, off for a TOML one.
    Auto,
    /// Always.
    On,
    /// Never.
    Off,
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
    /// Replay speed (1 = real time; 0.01-1000).
    #[arg(long, default_value_t = 1.0, value_parser = flags::speed)]
    speed: f64,
    /// Play the recording again from the start each time it ends, until stopped
    /// (without it the last look holds).
    #[arg(long = "loop")]
    looped: bool,
    /// Picture width in pixels.
    #[arg(long, default_value_t = DaemonConfig::default().width, value_parser = flags::pixels)]
    width: u32,
    /// Picture height in pixels.
    #[arg(long, default_value_t = DaemonConfig::default().height, value_parser = flags::pixels)]
    height: u32,
    /// Display frame rate (Hz, 1-240).
    #[arg(long, default_value_t = DaemonConfig::default().fps, value_parser = flags::fps)]
    fps: f64,
    /// Address of the HTTP preview (loopback by default: nothing is exposed to the network).
    #[arg(long, default_value = footlight::live::daemon::DEFAULT_HTTP)]
    http: std::net::SocketAddr,
    /// Photons stored per light (0 = direct light only).
    #[arg(long, default_value_t = PhotonSettings::default().stored, value_parser = flags::photons)]
    photons: usize,
    /// Memory budget for the lights' buffers, photon maps and caches: bytes with K/M/G/T
    /// (binary) or a percentage of the machine's memory (default 50%); past it, dark lights'
    /// buffers go first.
    #[arg(long, default_value = "50%", value_parser = flags::memory)]
    memory: u64,
    /// Threads of the light-build pool, 1-256 (default: the machine's cores less one,
    /// at least 1, so the frame clock keeps a core).
    #[arg(long, default_value_t = footlight::live::tracer::default_build_threads(), value_parser = flags::build_threads)]
    build_threads: usize,
    /// Illuminance (lx) on a white Lambert surface shown as display white.
    #[arg(long, default_value_t = footlight::render::display::DEFAULT_WHITE_LUX, value_parser = flags::white_lux)]
    white_lux: f32,
    /// Highlight roll-off of the live picture (every compositor): on (the
    /// default: beams over display white keep their gradation), off (clip at
    /// white) or the level shown as white, e.g. 8 (docs/rendering.md).
    #[arg(long, value_name = "off|on|WHITE", value_parser = flags::rolloff)]
    rolloff: Option<flags::Rolloff>,
    /// White balance of the live picture: auto (the rig's own white at full: its tungsten
    /// lamps' when it has any, else the luminous-flux-weighted white of every source), none,
    /// tungsten (3200 K neutral) or a colour temperature such as 5600K; changed live with
    /// `POST /api/display`.
    #[arg(long, default_value = "auto", value_parser = flags::white_balance)]
    white_balance: String,
    /// Fixture bodies over the picture: auto (on for an MVR patch, from its GDTF models), on (TOML
    /// fixtures get an estimated box), or off.
    #[arg(long, value_enum, default_value_t = BodiesChoice::Auto)]
    bodies: BodiesChoice,
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
    /// glTF 2.0 scene (.gltf/.glb). Default: an MVR patch's own geometry, else the bundled stage.
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Patch file: TOML, or an MVR show (its GDTF fixture types, and its geometry unless `--scene`).
    /// Default: patch/default.toml (`bench`: patch/paper-rig.toml, the paper's rig).
    #[arg(long)]
    patch: Option<PathBuf>,
}

impl SceneArgs {
    /// The patch asked for, else the bundled default.
    fn patch(&self) -> &Path {
        self.patch.as_deref().unwrap_or(Path::new(footlight::DEFAULT_PATCH))
    }
}

#[derive(Args)]
struct RenderArgs {
    #[command(flatten)]
    input: SceneArgs,
    /// Image width in pixels.
    #[arg(long, default_value_t = RenderSettings::default().width, value_parser = flags::pixels)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = RenderSettings::default().height, value_parser = flags::pixels)]
    height: u32,
    /// Maximum Whitted recursion depth (reflection/transmission bounces, 0-64).
    #[arg(long, default_value_t = RecursionLimits::default().max_depth, value_parser = flags::depth)]
    depth: u32,
    /// Sampling: one, geometry, adaptive (the paper's) or nine.
    #[arg(long, value_enum, default_value_t = Sampling::Adaptive)]
    sampling: Sampling,
    /// Anti-aliasing gradient threshold on the 0-255 scale (paper: 15-25).
    #[arg(long, default_value_t = BuildSettings::default().aa_threshold, value_parser = flags::aa_threshold)]
    aa_threshold: f32,
    /// Illuminance (lx) on a white Lambert surface shown as display white.
    #[arg(long, default_value_t = footlight::render::display::DEFAULT_WHITE_LUX, value_parser = flags::white_lux)]
    white_lux: f32,
    /// DMX levels for the still: `U/ADDR=VALUE,...` (patch universe and address from 1, value 0-255).
    #[arg(long, value_delimiter = ',')]
    set: Vec<String>,
    /// Render the state of this DMX recording (pcapng/pcap) at `--at` seconds, through the
    /// patch's `[[input]]` routes.
    #[arg(long)]
    dmx: Option<PathBuf>,
    /// Time into the `--dmx` recording in seconds, from its first DMX packet of a patched universe.
    #[arg(long, default_value_t = 0.0, value_parser = flags::at)]
    at: f64,
    /// Photons stored per light for the indirect term (paper: 50000); 0 = direct light only.
    #[arg(long, default_value_t = PhotonSettings::default().stored, value_parser = flags::photons)]
    photons: usize,
    /// Photons in each radiance estimate (paper: 150).
    #[arg(long, default_value_t = PhotonSettings::default().estimate, value_parser = flags::estimate)]
    estimate: usize,
    /// Progressive (SPPM) passes after the photon-map estimate, each blended with it
    /// by photon counts so no pass is worse than the one before (0 = none).
    #[arg(long, default_value_t = 0, value_parser = flags::refine)]
    refine: u32,
    /// Roll highlights over display white off smoothly (beams in haze) instead
    /// of clipping them in a PNG: `--rolloff` (on), `--rolloff 8` (8× white
    /// shown as white) or `--rolloff off` (the default); linear outputs are
    /// never rolled off (docs/rendering.md).
    #[arg(long, value_name = "off|on|WHITE", num_args = 0..=1, default_missing_value = "on", value_parser = flags::rolloff)]
    rolloff: Option<flags::Rolloff>,
    /// Output file: `.png` (8-bit sRGB, exposure and clipping as on screen), or
    /// `.exr` / `.pfm` (linear cd/m² times the white balance, float, unclipped).
    /// An existing file is never replaced without --force.
    #[arg(long)]
    out: PathBuf,
    /// White balance: auto (the rig's own white at full: its tungsten lamps' when it has any,
    /// else the luminous-flux-weighted white of every source), none, tungsten (3200 K
    /// neutral) or a colour temperature such as 5600K.
    #[arg(long, default_value = "auto")]
    white_balance: String,
    /// Replace an existing output file.
    #[arg(long)]
    force: bool,
    /// Draw each light's fixture body (a primitive box posed at its pan/tilt, its
    /// lens glowing with the light's own level; docs/rendering.md).
    #[arg(long)]
    bodies: bool,
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
    /// Only the "walking the stage" section (issue 16), printed as Markdown.
    #[arg(long)]
    walk_only: bool,
    /// Only the haze section (issue 15): beam time vs error, density
    /// re-weighting, a moved beam through the live tracer on 2 threads, and
    /// (without --quick) the 600-fixture rig at 1920×1080.
    #[arg(long)]
    haze_only: bool,
    /// Only the accuracy round's section (issue 13: AA cost and error, moved-light
    /// convergence, indirect error), printed as Markdown.
    #[arg(long)]
    accuracy_only: bool,
    /// With --accuracy-only: the parts to run (aa, converge, indirect; default all).
    #[arg(long, value_delimiter = ',', requires = "accuracy_only")]
    accuracy_part: Vec<bench::accuracy::Part>,
    /// Only the gate section (issue 14: gobos, shutters, prism, frost on
    /// tests/data/gate-patch.toml), printed as Markdown.
    #[arg(long)]
    gate_only: bool,
    /// Only the pixel-bar rig of the 150-fixture MVR (issue 14): its build and
    /// composite cost, printed as text. Without --patch the MVR is the patch.
    #[arg(long)]
    pixels_only: bool,
    /// Only the fixture-body section (issue 14 item 5): the 44 chase heads'
    /// bodies redrawn per frame (none, one, all moving; dimmer only) and the
    /// browser stream's body bytes per frame, printed as Markdown.
    #[arg(long)]
    bodies_only: bool,
    /// Only the festival section (issue 38: every target on
    /// tests/data/mvr/festival.mvr: renders, the live build, moved heads,
    /// broad cue, pixel chase, RSS, SIGTERM), written as report.md,
    /// report.json and festival-ready.svg into --out.
    #[arg(long)]
    festival_only: bool,
    /// With --festival-only: picture size WxH (default 800x500; --quick 200x125).
    #[arg(long, requires = "festival_only", value_parser = festival_size)]
    festival_size: Option<(u32, u32)>,
    /// With --festival-only: the deadline of each phase in seconds (default 240; --quick 30).
    #[arg(long, requires = "festival_only", value_parser = festival_seconds)]
    festival_seconds: Option<f64>,
}

/// `--festival-size WxH`, 16x16 to 3840x2160.
fn festival_size(v: &str) -> Result<(u32, u32), String> {
    let (w, h) = v.split_once(['x', 'X']).ok_or("expected WxH, e.g. 800x500")?;
    let parse = |s: &str, max: u32| s.trim().parse::<u32>().ok().filter(|n| (16..=max).contains(n));
    match (parse(w, 3840), parse(h, 2160)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err("expected WxH with W in 16..3840 and H in 16..2160".into()),
    }
}

/// `--festival-seconds`: 1 to 3600.
fn festival_seconds(v: &str) -> Result<f64, String> {
    v.trim()
        .parse::<f64>()
        .ok()
        .filter(|s| (1.0..=3600.0).contains(s))
        .ok_or_else(|| "expected 1 to 3600 seconds".into())
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()))
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .init();
    let cli = Cli::parse();
    let size = match &cli.command {
        Command::Render(a) => Some((a.width, a.height)),
        Command::Run(a) => Some((a.width, a.height)),
        Command::Replay { run, .. } => Some((run.width, run.height)),
        _ => None,
    };
    if let Some(why) = size.and_then(|(w, h)| footlight::memory::picture_too_big(w, h, footlight::memory::available()))
    {
        use clap::CommandFactory;
        Cli::command().error(clap::error::ErrorKind::ValueValidation, why).exit();
    }
    let result = match cli.command {
        Command::Render(args) => render(args),
        Command::Run(args) => run(args),
        Command::Record(args) => record(args),
        Command::Replay { file, mut run } => {
            run.replay = Some(file);
            self::run(*run)
        }
        Command::Check { patch, list } => check(&patch, list),
        Command::Bench(args) => bench_command(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn bench_command(mut args: BenchArgs) -> Result<()> {
    if args.festival_only {
        let mut cfg = bench::festival::FestivalConfig::new(args.quick);
        if let Some(p) = &args.input.patch {
            cfg.show = resolve(p);
        }
        (cfg.width, cfg.height) = args.festival_size.unwrap_or((cfg.width, cfg.height));
        cfg.seconds = args.festival_seconds.unwrap_or(cfg.seconds);
        let out = args.out.unwrap_or_else(bench::default_out_dir);
        let report = bench::festival::run(&cfg).map_err(|e| anyhow::anyhow!("festival: {e}"))?;
        report.write(&out)?;
        print!("{}", report.lines());
        println!("report written to {}", out.display());
        return Ok(());
    }
    // The paper's figures are measured on the paper's rig.
    args.input.patch.get_or_insert_with(|| PathBuf::from(footlight::PAPER_PATCH));
    let (scene, patch, _) = load_inputs(&args.input)?;
    let camera = choose_camera(&scene, &patch);
    if args.walk_only {
        let (size, seconds, photons) = if args.quick {
            ((200, 125), 1.0, 0)
        } else {
            ((800, 500), 5.0, footlight::render::photon::PhotonSettings::default().stored)
        };
        let walk = bench::walk::run(&Arc::new(scene), &patch, camera, size, seconds, photons)
            .map_err(|e| anyhow::anyhow!("walking the stage: {e}"))?;
        println!("{}", walk.markdown());
        return Ok(());
    }
    if args.haze_only {
        let scene = Arc::new(scene);
        let light = patch.fixtures.first().map(|f| f.light.clone()).context("the patch has no fixtures")?;
        let (size, repeats, paths, moves) =
            if args.quick { ((200, 125), 1, 20_000, 2) } else { ((800, 500), 3, 200_000, 10) };
        let rig = (!args.quick).then(bench::haze::rig_lights);
        let mut report = bench::haze::run(&scene, camera, size.0, size.1, &light, repeats, paths, rig.as_deref())
            .context("haze: the scene has no volume for the haze box")?;
        report.moved = bench::haze::moved_beam(&scene, camera, size, 2, &light, moves);
        println!("{}", report.lines());
        return Ok(());
    }
    if args.accuracy_only {
        let (size, repeats) = if args.quick { ((200, 125), 1) } else { ((800, 500), 3) };
        let report = bench::accuracy::run(
            &scene,
            &resolve(args.input.scene.as_deref().unwrap_or(Path::new(footlight::DEFAULT_SCENE))),
            &patch,
            camera,
            size,
            repeats,
            &args.accuracy_part,
        )
        .map_err(|e| anyhow::anyhow!("accuracy section: {e}"))?;
        println!("{}", report.markdown());
        return Ok(());
    }
    if args.gate_only {
        let size = if args.quick { (200, 125) } else { (800, 500) };
        let gate_patch = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/gate-patch.toml");
        let rows = bench::gate::run(&scene, camera, size, &gate_patch).map_err(|e| anyhow::anyhow!("gate: {e}"))?;
        println!("{}", bench::gate::markdown(&rows, size));
        return Ok(());
    }
    if args.pixels_only {
        let size = if args.quick { (200, 125) } else { (800, 500) };
        let show = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mvr/show150.mvr");
        let report = bench::mvr::pixels(&Arc::new(scene), camera, size, &show)
            .map_err(|e| anyhow::anyhow!("pixel bars: {e}"))?;
        print!("{}", report.lines());
        return Ok(());
    }
    if args.bodies_only {
        let (size, frames) = if args.quick { ((200, 125), 30) } else { ((800, 500), 240) };
        let report = bench::bodies::run(&Arc::new(scene), camera, size, frames)
            .map_err(|e| anyhow::anyhow!("fixture bodies: {e}"))?;
        println!("{}", report.markdown());
        return Ok(());
    }
    let out = args.out.unwrap_or_else(bench::default_out_dir);
    let config = bench::BenchConfig::new(
        args.quick,
        resolve(args.input.scene.as_deref().unwrap_or(Path::new(footlight::DEFAULT_SCENE))),
    );
    let report = bench::run(&scene, &patch, camera, &config, &out)?;
    println!("{}", report.summary());
    println!("report written to {}", out.display());
    Ok(())
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

fn load_inputs(args: &SceneArgs) -> Result<(Scene, Patch, footlight::output::ImportStatus)> {
    let t = std::time::Instant::now();
    let (scene_path, scene) = load_scene(args)?;
    tracing::info!(
        "{}: {} triangles, {:.1} % specular, {} materials, loaded in {:.0} ms",
        scene_path.display(),
        scene.triangle_count(),
        scene.specular_fraction() * 100.0,
        scene.materials.len(),
        t.elapsed().as_secs_f64() * 1e3
    );
    // A TOML patch, or an MVR show whose fixtures come from its GDTF files.
    let patch_path = resolve(args.patch());
    let checked = footlight_mvr::check_report(&patch_path).map_err(|e| problems(&patch_path, &e))?;
    let import = footlight::output::ImportStatus::of(&checked);
    log_import(&patch_path, &checked);
    let patch = checked.patch;
    tracing::info!("{}: {}", patch.path.display(), fixture_summary(&patch, &patch.listing()));
    Ok((scene, patch, import))
}

/// A patch's errors as one error: each on its own line (they are said once
/// per file and problem already), at most 20.
fn problems(path: &Path, errors: &[footlight::fixture::PatchError]) -> anyhow::Error {
    const SHOWN: usize = 20;
    let mut lines: Vec<String> = errors.iter().take(SHOWN).map(ToString::to_string).collect();
    match errors.len() {
        0 => lines.push(format!("{}: invalid patch", path.display())),
        n if n > SHOWN => lines.push(format!("… and {} more (`footlight check {}`)", n - SHOWN, path.display())),
        _ => {}
    }
    anyhow::anyhow!(lines.join("\n"))
}

/// What `run` and `render` say of an import at start, once: each fixture
/// type's summary (a missing GDTF, a type partly modelled: a warning) and
/// the warnings, or how many there are and where `footlight check` lists them.
fn log_import(path: &Path, checked: &footlight_mvr::Checked) {
    /// Warnings printed at start before they are only counted.
    const SHOWN: usize = 5;
    for t in &checked.types {
        match t.status {
            footlight_mvr::Modelled::Modelled => tracing::info!("fixture type {t}"),
            _ => tracing::warn!("fixture type {t}"),
        }
    }
    for n in &checked.notes {
        tracing::info!("{n}");
    }
    if checked.warnings.len() <= SHOWN {
        checked.warnings.iter().for_each(|w| tracing::warn!("{w}"));
    } else {
        tracing::warn!(
            "{} import warnings (each said once, with its file and line): `footlight check {}` lists them",
            checked.warnings.len(),
            path.display()
        );
    }
}

/// The scene: `--scene`, else an MVR patch's own geometry (issue 14), else the bundled stage.
fn load_scene(args: &SceneArgs) -> Result<(PathBuf, Scene)> {
    use footlight::scene::mvr_scene::{SceneSource, scene_source};
    let patch = resolve(args.patch());
    let default = resolve(Path::new(footlight::DEFAULT_SCENE));
    match scene_source(args.scene.as_deref().map(resolve).as_deref(), &patch, &default) {
        SceneSource::Gltf(path) => {
            let scene = footlight::scene::load(&path)?;
            Ok((path, scene))
        }
        SceneSource::Mvr(path) => {
            let loaded = footlight::scene::load_mvr_scene(&path)?;
            if loaded.objects == 0 {
                // A rig without a venue (what a desk exports): light it on the bundled stage.
                tracing::info!(
                    "{}: no scene objects; the bundled stage {} is used (--scene chooses another)",
                    path.display(),
                    default.display()
                );
                return Ok((default.clone(), footlight::scene::load(&default)?));
            }
            for w in &loaded.warnings {
                tracing::warn!("{w}");
            }
            Ok((path, loaded.scene))
        }
    }
}

/// Patch camera first, then the scene's, then a seat in the stalls.
/// The patch's camera, else the scene's, else (an MVR venue has none) the
/// "frame the rig" view: the lit rig and the stage from a designer's height,
/// instead of a seat level with the deck.
fn choose_camera(scene: &Scene, patch: &Patch) -> Camera {
    if let Some(c) = patch.camera.map(|c| Camera::look_at(c.position, c.look_at, c.fov_y)).or(scene.camera) {
        return c;
    }
    let seat = Camera::look_at(Vec3::new(0.0, 1.7, 14.0), Vec3::new(0.0, 1.5, 0.0), 40f32.to_radians());
    let framed = footlight::live::views::named_views(&seat, scene, Some(patch))
        .into_iter()
        .find(|v| v.name == footlight::live::views::FRAME_VIEW)
        .and_then(|v| v.pose.camera().ok());
    match framed {
        Some(c) => {
            let p = c.position;
            tracing::info!(
                "camera: no camera in the patch or scene; framing the rig from ({:.1}, {:.1}, {:.1}) m",
                p.x,
                p.y,
                p.z
            );
            c
        }
        None => seat,
    }
}

/// The stop signal: SIGINT (Ctrl-C) or SIGTERM. Installed as soon as the
/// runtime exists, so a signal during loading is a clean stop too.
struct Signals {
    #[cfg(unix)]
    int: tokio::signal::unix::Signal,
    #[cfg(unix)]
    term: tokio::signal::unix::Signal,
}

impl Signals {
    /// Registers the handlers (call inside the runtime).
    fn install() -> Result<Self> {
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
    async fn wait(mut self) {
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

fn runtime() -> Result<tokio::runtime::Runtime> {
    Ok(tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build()?)
}

fn run(args: RunArgs) -> Result<()> {
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
            let shown = footlight::window::show(frames, Some(views));
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
    args: RunArgs,
    tap: Option<std::sync::mpsc::Sender<footlight::live::daemon::FramesTap>>,
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
        let listener = footlight::live::bind_http(args.http).await?;
        let input = args.input.clone();
        let loading = tokio::task::spawn_blocking(move || load_inputs(&input));
        let (scene, patch, import) = tokio::select! {
            loaded = loading => loaded.context("loading the scene")??,
            _ = &mut stop => return Ok(()),
        };
        let camera = choose_camera(&scene, &patch);
        let named = footlight::live::views::named_views(&camera, &scene, Some(&patch));
        // The addresses a desk needs, at start (a big show: `footlight check` lists them).
        let listing = patch.listing();
        if listing.len() <= MAX_LISTED {
            listing.iter().for_each(|f| println!("{f}"));
        } else {
            println!(
                "{} fixtures: `footlight check {}` lists their addresses (and the page's light table)",
                listing.len(),
                args.input.patch().display()
            );
        }
        let show = Arc::new(Show::new(patch)?);
        let bodies = match args.bodies {
            BodiesChoice::On => true,
            BodiesChoice::Off => false,
            BodiesChoice::Auto => footlight_mvr::show_of(args.input.patch()).is_some(),
        };
        let bodies = bodies.then(|| {
            let names: Vec<String> = show.patch().fixtures.iter().map(|f| f.name.clone()).collect();
            let (models, warnings) =
                footlight::render::bodies::body_models(args.input.patch(), &names, &show.fixture_ids());
            for w in warnings {
                tracing::warn!("{w}");
            }
            let from_gdtf = models.iter().filter(|m| !m.is_estimated()).count();
            tracing::info!("bodies: {} ({from_gdtf} from GDTF models, the rest estimated boxes)", models.len());
            models
        });
        let defaults = DaemonConfig::default();
        let rolloff = args.rolloff.map_or(defaults.display.rolloff, |r| r.0);
        let display = Display::for_white_lux(args.white_lux).with_rolloff(rolloff);
        let photons = (args.photons > 0).then(|| PhotonSettings { stored: args.photons, ..PhotonSettings::default() });
        let config = DaemonConfig {
            width: args.width,
            height: args.height,
            fps: args.fps,
            display,
            white_balance: Some(args.white_balance.clone()),
            compositor: args.compositor,
            tracer: TracerSettings {
                build: BuildSettings { photons, ..defaults.tracer.build },
                threads: args.build_threads,
                memory: args.memory,
                ..defaults.tracer
            },
            ..defaults
        };
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

/// The DMX state a still shows: a recording at a moment (through the show's
/// routes), then `--set` levels.
fn still_universes(args: &RenderArgs, show: &Show) -> Result<footlight::fixture::Universes> {
    let mut universes = footlight::fixture::Universes::new();
    if let Some(path) = &args.dmx {
        let recording = footlight_dmx::Recording::open(path)?;
        for frame in
            footlight_dmx::state_at(&recording, std::time::Duration::from_secs_f64(args.at), show.input_patch())?
        {
            universes.set(frame.universe, &frame.slots);
        }
    }
    let patch = show.patch();
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
        if universes.get(u).is_none() {
            universes.set(u, patch.look_universes.get(u).unwrap_or(&[0; 512]));
        }
        universes.set_slot(u, a, v);
    }
    Ok(universes)
}

/// Every fixture's tracer light and k_i for a DMX state (eq. 4).
/// The body layer of a still: every light's body at its decoded pan/tilt
/// (GDTF models for an MVR patch, estimated boxes otherwise).
#[allow(clippy::type_complexity)]
fn still_bodies(
    show: &Show,
    universes: &footlight::fixture::Universes,
    patch: &Path,
    scene: &footlight::scene::Scene,
    camera: &footlight::scene::Camera,
    settings: &RenderSettings,
) -> (footlight::render::bodies::BodyLayer, Vec<footlight::render::bodies::Body>, Vec<footlight::Light>, Vec<glam::Vec3>)
{
    use footlight::render::bodies::{BodyLayer, body_models};
    let inputs = show.decode(universes);
    let names: Vec<String> = show.patch().fixtures.iter().map(|f| f.name.clone()).collect();
    let (models, warnings) = body_models(patch, &names, &show.fixture_ids());
    for w in warnings {
        tracing::warn!("{w}");
    }
    let bodies: Vec<_> = models
        .iter()
        .map(|m| {
            let i = &inputs[m.driver];
            m.pose(&i.light, i.state.pan, i.state.tilt)
        })
        .collect();
    let layer = BodyLayer::build(scene, camera, settings.width, settings.height, &bodies);
    let lights = inputs.iter().map(|i| i.light.clone()).collect();
    let k = inputs.iter().map(|i| i.k).collect();
    (layer, bodies, lights, k)
}

fn jobs_for(show: &Show, universes: &footlight::fixture::Universes) -> Vec<LightJob> {
    // One input per patch fixture, in patch order (`Show::decode`).
    show.decode(universes)
        .into_iter()
        .zip(&show.patch().fixtures)
        .map(|(i, f)| LightJob { light: i.light, k_full: i.k_full, k: i.k, fixture: Some(f.id) })
        .collect()
}

/// `footlight check`: notes and warnings (each said once, with its file,
/// line and the fixtures it concerns), the scene, the fixtures (each, or in
/// runs of one type and mode past [`MAX_LISTED`] unless `list_all`), one
/// summary line per fixture type, and the verdict.
fn check(path: &Path, list_all: bool) -> Result<()> {
    match footlight_mvr::check_report(path) {
        Ok(checked) => {
            for n in &checked.notes {
                eprintln!("note: {n}");
            }
            for w in &checked.warnings {
                eprintln!("warning: {w}");
            }
            if let Some(show) = footlight_mvr::show_of(path) {
                // The MVR's geometry is the show's scene (unless `--scene`): its problems too.
                let loaded = footlight::scene::load_mvr_scene(&show)?;
                if loaded.objects == 0 {
                    println!("{}: no scene objects; shows use the bundled stage", show.display());
                } else {
                    for w in &loaded.warnings {
                        eprintln!("warning: {w}");
                    }
                    println!(
                        "{}: scene of {} object(s), {} triangles",
                        show.display(),
                        loaded.objects,
                        loaded.scene.triangle_count()
                    );
                }
            }
            let patch = &checked.patch;
            let listing = patch.listing();
            if list_all || listing.len() <= MAX_LISTED {
                listing.iter().for_each(|f| println!("{f}"));
            } else {
                let runs = fixture_runs(&listing);
                runs.iter().for_each(|r| println!("{r}"));
                println!(
                    "({} fixtures in {} runs of one type and mode: `footlight check --list {}` lists each)",
                    listing.len(),
                    runs.len(),
                    path.display()
                );
            }
            if !checked.types.is_empty() {
                println!("fixture types:");
                checked.types.iter().for_each(|t| println!("  {t}"));
            }
            println!("{}: ok, {}", path.display(), fixture_summary(patch, &listing));
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

/// Fixtures listed with their addresses when `run` starts, and by `check`
/// one per line; a bigger show prints where to find them (`run`) or lists
/// them in runs (`check`).
const MAX_LISTED: usize = 40;

/// Consecutive fixtures of one type, mode and cell count as one line each:
/// `  1001-1096  PixelBar 16 1 … PixelBar 16 96  [PixelBar 16 (65ch), 16 cells] × 96  DMX 1/1 … 14/261-325`
/// (ids, first and last name, the type as `check --list` shows it, how
/// many, the first fixture's start and the last one's range).
fn fixture_runs(listing: &[footlight::fixture::patch::ListedFixture]) -> Vec<String> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < listing.len() {
        let first = &listing[i];
        let mut j = i;
        while j + 1 < listing.len() {
            let next = &listing[j + 1];
            if (&next.type_name, &next.mode, next.lights) != (&first.type_name, &first.mode, first.lights) {
                break;
            }
            j += 1;
        }
        let last = &listing[j];
        let n = j - i + 1;
        if n == 1 {
            out.push(first.to_string());
            i = j + 1;
            continue;
        }
        let ids = if last.id >= first.id && (last.id - first.id) as usize == n - 1 {
            format!("{}-{}", first.id, last.id)
        } else {
            format!("{}…{}", first.id, last.id)
        };
        let kind = match &first.mode {
            Some(m) => format!("{} ({m})", first.type_name),
            None => first.type_name.clone(),
        };
        let cells = if first.lights > 1 { format!(", {} cells", first.lights) } else { String::new() };
        let start = |f: &footlight::fixture::patch::ListedFixture| f.dmx.map(|(u, a)| format!("{u}/{a}"));
        let end = |f: &footlight::fixture::patch::ListedFixture| {
            f.dmx.map(|(u, a)| match f.footprint {
                0 | 1 => format!("{u}/{a}"),
                w => format!("{u}/{a}-{}", u32::from(a) + u32::from(w) - 1),
            })
        };
        let dmx = match (start(first), end(last)) {
            (Some(a), Some(b)) => format!("{a} … {b}"),
            (Some(a), None) => format!("{a} …"),
            (None, Some(b)) => format!("… {b}"),
            (None, None) => "not patched".to_string(),
        };
        out.push(format!("{ids:>11}  {} … {}  [{kind}{cells}] × {n}  DMX {dmx}", first.name, last.name));
        i = j + 1;
    }
    out
}

/// "10 fixtures on universe 1", "150 fixtures (336 lights: cells counted) on
/// universes 1-3, 5", "2 fixtures, none patched": fixtures and their cells
/// counted apart, universes as the patch uses them.
fn fixture_summary(patch: &Patch, listing: &[footlight::fixture::patch::ListedFixture]) -> String {
    let lights = patch.fixtures.len();
    let cells = if lights > listing.len() { format!(" ({lights} lights: cells counted)") } else { String::new() };
    let mut universes: Vec<u16> = listing.iter().filter_map(|f| f.dmx.map(|(u, _)| u)).collect();
    universes.sort_unstable();
    universes.dedup();
    let mut runs: Vec<String> = Vec::new();
    let mut i = 0;
    while i < universes.len() {
        let mut j = i;
        while j + 1 < universes.len() && universes[j + 1] == universes[j] + 1 {
            j += 1;
        }
        // Runs of three or more as a range, else each number.
        if j >= i + 2 {
            runs.push(format!("{}-{}", universes[i], universes[j]));
        } else {
            runs.extend(universes[i..=j].iter().map(u16::to_string));
        }
        i = j + 1;
    }
    let unpatched = listing.iter().filter(|f| f.dmx.is_none()).count();
    let on = match (runs.len(), universes.len()) {
        (0, _) => ", none patched".to_string(),
        (_, 1) => format!(" on universe {}", runs.join(", ")),
        _ => format!(" on universes {}", runs.join(", ")),
    };
    let loose = if unpatched > 0 && !runs.is_empty() { format!(", {unpatched} not patched") } else { String::new() };
    let fixtures = if listing.len() == 1 { "1 fixture".to_string() } else { format!("{} fixtures", listing.len()) };
    format!("{fixtures}{cells}{on}{loose}")
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
    let show = Show::new(footlight_mvr::load_patch(&resolve(&args.patch))?)?;
    runtime()?.block_on(async move {
        let signals = Signals::install()?;
        let config = args.dmx.config(&show)?;
        println!("recording DMX to {} until Ctrl-C", args.out.display());
        let summary = footlight_dmx::record(&args.out, config, signals.wait()).await?;
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

fn render(args: RenderArgs) -> Result<()> {
    check_output(&args.out, args.force)?;
    // Checked before anything loads; `auto` is resolved on the loaded rig below.
    white_balance_for(&args.white_balance, None).map_err(|e| anyhow::anyhow!("--white-balance {e}"))?;
    let format = match args.out.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("png") => "png",
        Some("exr") => "exr",
        Some("pfm") => "pfm",
        _ => bail!("--out {}: the name must end in .png, .exr or .pfm", args.out.display()),
    };
    let (scene, patch, _) = load_inputs(&args.input)?;
    let camera = choose_camera(&scene, &patch);
    let white = white_balance_for(&args.white_balance, patch.rig_white().as_ref())
        .map_err(|e| anyhow::anyhow!("--white-balance {e}"))?;
    tracing::info!("white balance {}: {}", white.setting, white.note);
    let gains = white.gains;
    let show = Show::new(patch)?;
    let settings = RenderSettings {
        width: args.width,
        height: args.height,
        limits: RecursionLimits { max_depth: args.depth, ..RecursionLimits::default() },
        sampling: args.sampling,
        aa_threshold: args.aa_threshold,
        display: Display { white_balance: gains, ..Display::for_white_lux(args.white_lux) },
        photons: (args.photons > 0).then(|| PhotonSettings {
            stored: args.photons,
            estimate: args.estimate,
            ..PhotonSettings::default()
        }),
        refine_passes: args.refine,
    };
    if args.refine > 0 && args.photons == 0 {
        bail!("--refine {}: refinement needs photons (--photons is 0)", args.refine);
    }
    let universes = still_universes(&args, &show)?;
    // render_still_hazy builds only the lit ones (a dark light adds exactly 0 to eq. 5).
    let jobs = jobs_for(&show, &universes);
    let lit = jobs.iter().filter(|j| j.k != Vec3::ZERO).count();
    if lit < jobs.len() {
        tracing::info!("{lit} of {} lights are lit; the dark ones are not built", jobs.len());
    }
    // Haze from the patch's [haze] at the hazer channel's density (issue 15).
    let haze = show.patch().haze.as_ref().and_then(|spec| {
        let medium = footlight::render::media::Medium::from_spec(spec, &scene);
        if medium.is_none() {
            tracing::warn!("[haze] has no box and the scene has no volume: no haze");
        }
        Some(StillHaze {
            medium: medium?,
            density: match spec.dmx.and_then(|(u, _)| universes.get(u)) {
                Some(slots) => spec.density_from_slots(slots),
                None => spec.density,
            },
            quality: footlight::render::media::HazeQuality::REFINED,
        })
    });
    let mut still = render_still_hazy(&scene, camera, &jobs, &settings, haze.as_ref())?;
    if args.bodies {
        // Fixture bodies: a layer over the composite, never in the light buffers (issue 14).
        let t = std::time::Instant::now();
        let (layer, bodies, lights, k) =
            still_bodies(&show, &universes, args.input.patch(), &scene, &camera, &settings);
        layer.overlay(&camera, &bodies, &lights, &k, &mut still.linear);
        let tested: u64 = (0..bodies.len()).map(|i| layer.footprint_pixels(i)).sum();
        tracing::info!(
            "bodies: {} drawn, {tested} pixel tests ({:.0} per body), {:.1} ms",
            bodies.len(),
            tested as f64 / bodies.len().max(1) as f64,
            t.elapsed().as_secs_f64() * 1e3
        );
    }
    if let Err((i, v)) = check_finite(&still.linear) {
        bail!("composite pixel {i} is {v}: this is a bug, please report it");
    }
    let (w, h) = (settings.width, settings.height);
    match format {
        "exr" => write_exr(&args.out, w, h, &balanced(&still.linear, gains)).map_err(anyhow::Error::msg)?,
        "pfm" => write_pfm(&args.out, w, h, &balanced(&still.linear, gains))
            .with_context(|| format!("writing {}", args.out.display()))?,
        _ => {
            let rolloff = args.rolloff.and_then(|r| r.0);
            let rgb8 = settings.display.with_rolloff(rolloff).to_srgb8(&still.linear);
            write_png(&args.out, w, h, rgb8).with_context(|| format!("writing {}", args.out.display()))?
        }
    }
    let t = &still.timings;
    tracing::info!(
        "view {:.0} ms, {} light buffers {:.0} ms ({} pixels re-shaded for anti-aliasing), photon maps {:.0} ms, haze {:.0} ms, composite {:.1} ms",
        t.view.as_secs_f64() * 1e3,
        lit,
        t.lights.as_secs_f64() * 1e3,
        still.reshaded,
        t.photons.as_secs_f64() * 1e3,
        t.haze.as_secs_f64() * 1e3,
        t.composite.as_secs_f64() * 1e3
    );
    println!("wrote {}", args.out.display());
    Ok(())
}
