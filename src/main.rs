//! `footlight` command line: clap's flags and one library call per command
//! ([`footlight::cli`] holds the commands: the still pipeline, the daemon's
//! wiring, the bench's dispatch). Only this file decides exit codes.

use clap::{Args, Parser, Subcommand};
use footlight::bench;
use footlight::cli::bench::{BenchOptions, BenchSection};
use footlight::cli::inputs::Inputs;
use footlight::cli::run::{DmxOptions, RunOptions};
use footlight::cli::still::StillOptions;
use footlight::cli::{self, flags};
use footlight::live::DaemonConfig;
use footlight::render::photon::PhotonSettings;
use footlight::render::view::AA_THRESHOLD;
use footlight::render::{PICTURE_SIZE, RecursionLimits, Sampling};
use std::io::IsTerminal;
use std::path::PathBuf;

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
    #[arg(long, default_value_t = PICTURE_SIZE.0, value_parser = flags::pixels)]
    width: u32,
    /// Picture height in pixels.
    #[arg(long, default_value_t = PICTURE_SIZE.1, value_parser = flags::pixels)]
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
    /// Build threads added while the frame clock is quiet (no frame over 8 ms for a
    /// second), 0-256 (default: the cores --build-threads leaves, so a still look builds
    /// on every core; 0: never more than --build-threads).
    #[arg(long, value_parser = flags::quiet_build_threads)]
    quiet_build_threads: Option<usize>,
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
    #[arg(long, value_enum, default_value_t = footlight::cli::run::BodiesChoice::Auto)]
    bodies: footlight::cli::run::BodiesChoice,
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
    /// Default: patch/default.toml (`bench`: patch/paper-rig.toml, the paper's rig). Relative
    /// paths not in the working directory are looked up under $FOOTLIGHT_DATA, else beside the
    /// executable (the bundled files).
    #[arg(long)]
    patch: Option<PathBuf>,
}

#[derive(Args)]
struct RenderArgs {
    #[command(flatten)]
    input: SceneArgs,
    /// Image width in pixels.
    #[arg(long, default_value_t = PICTURE_SIZE.0, value_parser = flags::pixels)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = PICTURE_SIZE.1, value_parser = flags::pixels)]
    height: u32,
    /// Maximum Whitted recursion depth (reflection/transmission bounces, 0-64).
    #[arg(long, default_value_t = RecursionLimits::default().max_depth, value_parser = flags::depth)]
    depth: u32,
    /// Sampling: one, geometry, adaptive (the paper's) or nine.
    #[arg(long, value_enum, default_value_t = Sampling::Adaptive)]
    sampling: Sampling,
    #[arg(long, default_value_t = AA_THRESHOLD, value_parser = flags::aa_threshold, help = aa_help())]
    aa_threshold: f32,
    /// Illuminance (lx) on a white Lambert surface shown as display white.
    #[arg(long, default_value_t = footlight::render::display::DEFAULT_WHITE_LUX, value_parser = flags::white_lux)]
    white_lux: f32,
    /// DMX levels for the still: `U/ADDR=VALUE,...` (patch universe and address from 1, value 0-255).
    /// A `[haze]` hazer channel's value / 255 is the haze density, as in `run`; without a frame of
    /// its universe, the patch's look (its `density` as a DMX value: 50 % is 128/255).
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
    /// With --haze-only: the whole hazy picture's reference samples per
    /// pixel (default 1024; --quick 256).
    #[arg(long, requires = "haze_only", value_parser = clap::value_parser!(u32).range(2..=1_000_000))]
    haze_spp: Option<u32>,
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
    /// Only the error-against-time section (issue 34): the renderer's
    /// picture stage by stage and the reference path tracer's, as relative
    /// MSE against a converged box-filtered path-traced reference, with the
    /// speed ratio at equal error, written as report.md, report.json and
    /// error-time.svg into --out. Runs on its own box stage (--scene and
    /// --patch are not used).
    #[arg(long)]
    converge_only: bool,
    /// With --converge-only: the reference's samples per pixel (default
    /// 4096; --quick 256).
    #[arg(long, requires = "converge_only", value_parser = clap::value_parser!(u32).range(2..=1_000_000))]
    converge_spp: Option<u32>,
    /// Only the festival section (issue 38: every target on
    /// tests/data/mvr/festival.mvr: renders, the live build, moved heads,
    /// broad cue, pixel chase, RSS, SIGTERM), written as report.md,
    /// report.json and festival-ready.svg into --out.
    #[arg(long)]
    festival_only: bool,
    /// With --festival-only: picture size WxH (default 800x500; --quick 200x125).
    #[arg(long, requires = "festival_only", value_parser = flags::festival_size)]
    festival_size: Option<(u32, u32)>,
    /// With --festival-only: the deadline of each phase in seconds (default 240; --quick 30).
    #[arg(long, requires = "festival_only", value_parser = flags::festival_seconds)]
    festival_seconds: Option<f64>,
}

/// `--aa-threshold`'s help: the scale and the default as the renderer defines them.
fn aa_help() -> String {
    format!(
        "Anti-aliasing gradient threshold: 0-255 on each light's own relative scale (its \
         99th-percentile pixel = 255), not display steps; neighbour pixels further apart are \
         re-sampled. Default {AA_THRESHOLD} (the paper's 15-25 are steps of the displayed picture; \
         docs/rendering.md)"
    )
}

impl SceneArgs {
    /// The library's inputs.
    fn inputs(&self) -> Inputs {
        Inputs { scene: self.scene.clone(), patch: self.patch.clone() }
    }
}

impl DmxArgs {
    /// The library's DMX options.
    fn options(&self) -> DmxOptions {
        DmxOptions {
            artnet: self.artnet.clone(),
            sacn: self.sacn.clone(),
            sacn_iface: self.sacn_iface,
            usbpro: self.usbpro.clone(),
        }
    }
}

impl RunArgs {
    /// The library's run options.
    fn options(self) -> RunOptions {
        RunOptions {
            inputs: self.input.inputs(),
            dmx: self.dmx.options(),
            replay: self.replay,
            speed: self.speed,
            looped: self.looped,
            width: self.width,
            height: self.height,
            fps: self.fps,
            http: self.http,
            photons: self.photons,
            memory: self.memory,
            build_threads: self.build_threads,
            quiet_build_threads: self.quiet_build_threads,
            white_lux: self.white_lux,
            rolloff: self.rolloff.map(|r| r.0),
            white_balance: self.white_balance,
            bodies: self.bodies,
            compositor: self.compositor,
            window: self.window,
        }
    }
}

impl RenderArgs {
    /// The library's still options.
    fn options(self) -> StillOptions {
        StillOptions {
            inputs: self.input.inputs(),
            width: self.width,
            height: self.height,
            depth: self.depth,
            sampling: self.sampling,
            aa_threshold: self.aa_threshold,
            white_lux: self.white_lux,
            set: self.set,
            dmx: self.dmx,
            at: self.at,
            photons: self.photons,
            estimate: self.estimate,
            refine: self.refine,
            rolloff: self.rolloff.and_then(|r| r.0),
            out: self.out,
            white_balance: self.white_balance,
            force: self.force,
            bodies: self.bodies,
        }
    }
}

impl BenchArgs {
    /// The library's bench options: the first section flag asked for, else the whole bench.
    fn options(self) -> BenchOptions {
        let section = if self.festival_only {
            BenchSection::Festival { size: self.festival_size, seconds: self.festival_seconds }
        } else if self.converge_only {
            BenchSection::Converge { spp: self.converge_spp }
        } else if self.walk_only {
            BenchSection::Walk
        } else if self.haze_only {
            BenchSection::Haze { spp: self.haze_spp }
        } else if self.accuracy_only {
            BenchSection::Accuracy(self.accuracy_part)
        } else if self.gate_only {
            BenchSection::Gate
        } else if self.pixels_only {
            BenchSection::Pixels
        } else if self.bodies_only {
            BenchSection::Bodies
        } else {
            BenchSection::All
        };
        BenchOptions { inputs: self.input.inputs(), quick: self.quick, out: self.out, section }
    }
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
        Command::Render(args) => cli::still::render(&args.options()),
        Command::Run(args) => cli::run::run(args.options()),
        Command::Record(args) => cli::run::record(&args.dmx.options(), &args.patch, &args.out, args.force),
        Command::Replay { file, mut run } => {
            run.replay = Some(file);
            cli::run::run(run.options())
        }
        Command::Check { patch, list } => cli::check::check(&patch, list),
        Command::Bench(args) => cli::bench::bench(args.options()),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
