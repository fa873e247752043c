//! The festival section of `footlight bench` (issue 38 item 7): every
//! target figure of "a real festival, live" measured on the generated
//! festival-scale show `tests/data/mvr/festival.mvr` (231 fixtures, 3,684
//! emitters + 3 placeholders, 34 universes, 204,450 venue triangles;
//! `tools/gen_gdtf_mvr.py --festival`, docs/mvr-gdtf.md).
//!
//! What a new user does, bounded in time: `footlight render` of the dark
//! rig and of the lit rig (the release binary as a subprocess, killed at
//! the phase's deadline), then the daemon in this process, lit by a look
//! sent as Art-Net over loopback (its status polled every
//! [`SAMPLE_S`]: per light its stage, the frame clock, the process's
//! RSS), then moved heads, a broad cue and a pixel chase on the lit rig,
//! and last `footlight run` as a subprocess stopped with SIGTERM while it
//! builds. Every phase has a deadline (`--festival-seconds`); a target not
//! reached within it is reported as such, never waited for.
//!
//! The look ([`Look`]) is computed from the patch's own channel layout
//! (each light's mode and channel functions), as a desk's programmer
//! would set it: dimmers full, shutters at their "open" range, additive
//! colour channels full (CMY flags out), wheels, gobos and prisms at their
//! open slot, iris open, everything else at its default.

use crate::Patch;
use crate::fixture::fixture_type::{Action, Channel};
use crate::fixture::{Attribute, FixtureModel, Universes};
use crate::live::{Daemon, DmxSource, Show};
use crate::output::Stage;
use crate::render::photon::PhotonSettings;
use crate::render::{RecursionLimits, Sampling, View};
use crate::scene::{Camera, Scene};
use serde::Serialize;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Seconds between two samples of the emitters-ready plot.
pub const SAMPLE_S: f64 = 0.5;
/// Moving heads turned in the "moved heads" phase (as in issue 38's report).
pub const MOVED_HEADS: usize = 18;
/// Time from the daemon running to the look being sent (a desk comes up after the renderer).
pub const LOOK_AFTER: Duration = Duration::from_secs(2);
/// DMX frames per second of the broad cue and the pixel chase (every frame of a 60 Hz clock).
pub const CUE_HZ: f64 = 60.0;

/// What to measure and how long each phase may take.
#[derive(Clone, Debug)]
pub struct FestivalConfig {
    /// The show (default: `tests/data/mvr/festival.mvr`).
    pub show: PathBuf,
    /// Picture width (target: 800).
    pub width: u32,
    /// Picture height (target: 500).
    pub height: u32,
    /// Deadline of each phase, s (a render, the live build, the moved heads).
    pub seconds: f64,
    /// Length of the broad cue and of the pixel chase, s.
    pub cue_seconds: f64,
    /// Photons per light, live and in `render` (default: the paper's 50,000).
    pub photons: usize,
    /// The `footlight` binary for the `render` and `run` phases (default:
    /// this executable, which is `footlight` when run as `footlight bench`).
    pub binary: Option<PathBuf>,
}

/// The festival show, relative to the bundled files ([`crate::bundled`]).
pub const FESTIVAL_SHOW: &str = "tests/data/mvr/festival.mvr";

impl FestivalConfig {
    /// 800×500 and 240 s per phase; `quick`: 200×125 and 30 s.
    pub fn new(quick: bool) -> Self {
        Self {
            show: crate::bundled::resolve(Path::new(FESTIVAL_SHOW)),
            width: if quick { crate::render::QUICK_SIZE.0 } else { crate::render::PICTURE_SIZE.0 },
            height: if quick { crate::render::QUICK_SIZE.1 } else { crate::render::PICTURE_SIZE.1 },
            seconds: if quick { 30.0 } else { 240.0 },
            cue_seconds: if quick { 2.0 } else { 5.0 },
            photons: PhotonSettings::default().stored,
            binary: None,
        }
    }
}

/// One target of issue 38 with what was measured.
#[derive(Clone, Debug, Serialize)]
pub struct TargetRow {
    /// What is measured.
    pub measure: String,
    /// The measured value, as read (with units), or why there is none.
    pub value: String,
    /// The target.
    pub target: String,
    /// Met, missed, or `None` where nothing was measured.
    pub pass: Option<bool>,
    /// How it was measured.
    pub note: String,
}

/// Counts of the lit lights by the stage on screen at one moment of the live build.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ReadySample {
    /// Seconds since the look was sent.
    pub t_s: f64,
    /// Lit lights with nothing on screen yet.
    pub queued: usize,
    /// Lit lights at their direct stage or later (direct light on screen).
    pub direct: usize,
    /// … at Whitted or later.
    pub whitted: usize,
    /// … with indirect light (photons, refining, ready): converged.
    pub photons: usize,
    /// … `ready` (every refinement pass done).
    pub ready: usize,
    /// Dark lights built (any stage past queued).
    pub dark_built: usize,
    /// Lights the daemon shows lit (its status' intensity > 0).
    pub lit_seen: usize,
    /// Frame clock: frames per second over the last second.
    pub fps: f64,
    /// Frame clock: p99 frame interval over the last 600 frames, ms.
    pub p99_ms: f64,
    /// Composite time of the last frame, ms.
    pub composite_ms: f64,
    /// Resident memory of this process (the daemon runs in it), MB.
    pub rss_mb: f64,
    /// The tracer's light buffers (own buffers, shared layers, builds in
    /// progress; the status' `memory.buffers_bytes`), MB.
    pub buffers_mb: f64,
    /// The tracer's photon maps, MB.
    pub maps_mb: f64,
    /// The geometry caches, MB.
    pub caches_mb: f64,
    /// The compositor's emitter-group storage, MB.
    pub groups_mb: f64,
}

/// A `footlight` subprocess' run: its wall time, whether it finished.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Subprocess {
    /// Wall time from spawn to exit (or to the kill at the deadline), s.
    pub wall_s: f64,
    /// Exited on its own within the deadline.
    pub finished: bool,
    /// Its exit code (`None`: killed or by a signal).
    pub code: Option<i32>,
    /// Peak RSS seen (VmHWM, polled every 100 ms), MB.
    pub peak_rss_mb: f64,
    /// `render`'s own figures from its log: view, light buffers, photon maps, composite, ms.
    pub render_ms: Option<RenderLog>,
    /// `render`: lights it said are lit ("N of M lights are lit"), when it said so.
    pub lit_of: Option<(usize, usize)>,
}

/// The timing line `footlight render` logs.
#[derive(Clone, Debug, Default, Serialize)]
pub struct RenderLog {
    /// The view (G-buffer and Whitted paths), ms.
    pub view: f64,
    /// Light buffers, ms.
    pub lights: f64,
    /// Photon maps, ms.
    pub photons: f64,
    /// Composite, ms.
    pub composite: f64,
}

/// Everything the festival section measured.
#[derive(Clone, Debug, Serialize)]
pub struct FestivalReport {
    /// The show file.
    pub show: String,
    /// Picture size.
    pub width: u32,
    /// Picture size.
    pub height: u32,
    /// The deadline of each phase, s.
    pub seconds: f64,
    /// Length of the broad cue and of the pixel chase, s.
    pub cue_seconds: f64,
    /// Photons per light.
    pub photons: usize,
    /// Fixtures (distinct fixture ids), lights (cells and placeholders), universes, triangles.
    pub fixtures: usize,
    /// Lights of the patch.
    pub lights: usize,
    /// Lights the look lights (decoded through the patch: k_i > 0).
    pub lit: usize,
    /// Patch universes the look is sent on.
    pub universes: usize,
    /// Scene triangles.
    pub triangles: usize,
    /// Cores the machine offers, and the 1-minute load average at the start and at the end.
    pub cores: usize,
    /// `/proc/loadavg`'s 1-minute figure at the start and at the end.
    pub load_average: (f64, f64),
    /// The commit the binary was built from (`git rev-parse` of the checkout), when known.
    pub commit: Option<String>,
    /// `View::build` (9-sample G-buffer, Whitted paths) alone, in process, ms.
    pub gbuffer_ms: f64,
    /// `footlight render` with no DMX.
    pub dark_render: Option<Subprocess>,
    /// `footlight render` with the look (`--set`).
    pub lit_render: Option<Subprocess>,
    /// The live build, sampled every [`SAMPLE_S`] from the look's arrival.
    pub samples: Vec<ReadySample>,
    /// Lights built before the look arrived (all dark then).
    pub built_before_look: usize,
    /// Look sent → the daemon shows every lit light lit, s.
    pub look_seen_s: Option<f64>,
    /// Look sent → every lit light's direct stage on screen, s.
    pub direct_s: Option<f64>,
    /// Look sent → every lit light with indirect light (Whitted + photons), s.
    pub converged_s: Option<f64>,
    /// Look sent → every lit light `ready`, s.
    pub ready_s: Option<f64>,
    /// Moved heads: lights turned (the heads' cells), and the time to every one's direct stage at the new position, s.
    pub moved_lights: usize,
    /// … the time, s (`None`: not within the deadline).
    pub moved_s: Option<f64>,
    /// Broad cue: frames per second published while every level changed each frame.
    pub broad_fps: f64,
    /// … composite time, median and largest sample, ms.
    pub broad_composite_ms: (f64, f64),
    /// … build stages that ran with the quiet threads during it
    /// (`TracerSettings::quiet_threads`: they should stop at the cue's first frame).
    pub broad_quiet_stages: u64,
    /// Pixel chase: frames per second while every cell's colour changed each frame.
    pub chase_fps: f64,
    /// … composite time, median and largest sample, ms.
    pub chase_composite_ms: (f64, f64),
    /// … build stages that ran with the quiet threads during it.
    pub chase_quiet_stages: u64,
    /// Largest VmRSS sampled while live, and VmHWM at the end, MB.
    pub rss_mb: (f64, f64),
    /// SIGTERM while `footlight run` builds: time to exit, s, and its exit code.
    pub sigterm: Option<SigtermRun>,
    /// Phases that failed to run, with why.
    pub errors: Vec<String>,
    /// The targets.
    pub rows: Vec<TargetRow>,
    /// The CPU compositor alone on the same show and size, per cell vs
    /// through emitter groups ([`super::scale::pixel_chase`]).
    pub composite_chase: Option<super::scale::PixelChaseReport>,
}

/// `footlight run` stopped with SIGTERM during its build.
#[derive(Clone, Debug, Serialize)]
pub struct SigtermRun {
    /// Spawn → "listening for DMX", s (loading the show and the first view).
    pub start_s: f64,
    /// Look sent → SIGTERM, s.
    pub after_look_s: f64,
    /// SIGTERM → exit, s (`None`: not within 30 s, then killed).
    pub exit_s: Option<f64>,
    /// Its exit code.
    pub code: Option<i32>,
    /// Log lines saying some task did not stop in time.
    pub late_tasks: usize,
}

// ------------------------------------------------------------------ the look

/// What a look does with one channel.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Role {
    /// A fixed raw value (defaults, open slots, the shutter's open range).
    Fixed(u16),
    /// Intensity: dimmers, HSB/CIE brightness, additive colour without an emitter colour.
    Level,
    /// An additive colour channel (LED emitter `index`); subtractive: a CMY flag.
    Colour { index: u8, subtractive: bool },
    /// Pan at its default (the moved-heads phase turns it).
    Pan(u16),
}

/// One channel of one light, where it sits.
#[derive(Clone, Debug)]
struct LookChannel {
    /// Index of the light in the patch.
    light: usize,
    /// Universe and address of the coarse slot.
    coarse: (u16, u16),
    /// … of the fine slot of a 16-bit channel.
    fine: Option<(u16, u16)>,
    /// The channel's full scale (255 or 65535).
    full: u16,
    role: Role,
}

/// A look over a patch: every channel of every light with its role, so the
/// lit look, a broad cue, a pixel chase and moved heads are frames of it.
pub struct Look {
    channels: Vec<LookChannel>,
    /// The patch's channel defaults per universe (what is not set).
    base: Universes,
    /// Patch universes the look is sent on.
    universes: Vec<u16>,
    /// Light indices of each moving fixture (a head's cells), by fixture id.
    heads: Vec<(u32, Vec<usize>)>,
}

/// A sawtooth in [0, 1): changes every frame at any rate but a multiple of the frame rate.
fn saw(x: f64) -> f64 {
    x.rem_euclid(1.0)
}

impl Look {
    /// The look of `patch`: each typed light's channels by attribute and
    /// channel function; a built-in spot's dimmer.
    pub fn of(patch: &Patch) -> Self {
        let mut channels = Vec::new();
        let mut heads: Vec<(u32, Vec<usize>)> = Vec::new();
        for (i, f) in patch.fixtures.iter().enumerate() {
            match &f.model {
                FixtureModel::Builtin(_) => {
                    if let Some(at) = f.slot_address(0) {
                        channels.push(LookChannel { light: i, coarse: at, fine: None, full: 255, role: Role::Level });
                    }
                }
                FixtureModel::Typed(t) => {
                    let ty = &t.fixture_type;
                    let cmy = matches!(ty.lamp, footlight_photometry::Lamp::Cmy { .. });
                    if ty.movement.is_some() {
                        match heads.iter_mut().find(|(id, _)| *id == f.id) {
                            Some((_, lights)) => lights.push(i),
                            None => heads.push((f.id, vec![i])),
                        }
                    }
                    for c in &ty.modes[t.mode].channels {
                        let Some(coarse) = f.slot_address(c.offset) else { continue };
                        let fine = c.fine.and_then(|o| f.slot_address(o));
                        let full = c.full_scale();
                        let role = channel_role(c, full, cmy);
                        channels.push(LookChannel { light: i, coarse, fine, full, role });
                    }
                }
            }
        }
        let show = Show::new(patch.clone()).expect("the generated festival patch has no [[input]] routes");
        let universes = show.universes();
        let mut base = Universes::new();
        for &u in &universes {
            base.set(u, patch.look_universes.get(u).unwrap_or(&[0; 512]));
        }
        Self { channels, base, universes, heads }
    }

    /// Patch universes the look is sent on.
    pub fn universes(&self) -> &[u16] {
        &self.universes
    }

    /// The frames with every channel at `value(channel)` (raw, in its full scale).
    fn frames(&self, value: impl Fn(&LookChannel) -> u16) -> Universes {
        let mut u = self.base.clone();
        for c in &self.channels {
            let v = value(c);
            match c.fine {
                Some(fine) => {
                    u.set_slot(c.coarse.0, c.coarse.1, (v >> 8) as u8);
                    u.set_slot(fine.0, fine.1, (v & 0xff) as u8);
                }
                None => u.set_slot(c.coarse.0, c.coarse.1, v.min(255) as u8),
            }
        }
        u
    }

    /// The lit look: levels and additive colour full, CMY out, the rest fixed.
    pub fn lit(&self) -> Universes {
        self.frames(|c| match c.role {
            Role::Fixed(v) | Role::Pan(v) => v,
            Role::Level | Role::Colour { subtractive: false, .. } => c.full,
            Role::Colour { subtractive: true, .. } => 0,
        })
    }

    /// A broad cue at `t` s: every light's level (its intensity and colour
    /// channels together) on a 0.5 Hz sawtooth between 30 % and full, each
    /// light at its own phase.
    pub fn broad(&self, t: f64) -> Universes {
        self.frames(|c| {
            let level = 0.3 + 0.7 * saw(0.5 * t + c.light as f64 * 0.618);
            match c.role {
                Role::Fixed(v) | Role::Pan(v) => v,
                Role::Level | Role::Colour { subtractive: false, .. } => (f64::from(c.full) * level) as u16,
                Role::Colour { subtractive: true, .. } => 0,
            }
        })
    }

    /// A pixel chase at `t` s: levels full, every colour channel of every
    /// light on a 0.5 Hz sawtooth, phased by the light and the emitter (a
    /// rainbow travelling along each bar).
    pub fn chase(&self, t: f64) -> Universes {
        self.frames(|c| match c.role {
            Role::Fixed(v) | Role::Pan(v) => v,
            Role::Level => c.full,
            Role::Colour { index, subtractive } => {
                let x = saw(0.5 * t + c.light as f64 * 0.05 + f64::from(index) / 3.0);
                (f64::from(c.full) * if subtractive { 0.5 * x } else { x }) as u16
            }
        })
    }

    /// The lit look with the pan of `heads` (fixture ids) turned by
    /// `share` of its range from its default.
    pub fn moved(&self, heads: &[u32], share: f64) -> Universes {
        let moved: Vec<usize> =
            self.heads.iter().filter(|(id, _)| heads.contains(id)).flat_map(|(_, l)| l.iter().copied()).collect();
        let lit = |c: &LookChannel| match c.role {
            Role::Fixed(v) => v,
            Role::Level | Role::Colour { subtractive: false, .. } => c.full,
            Role::Colour { subtractive: true, .. } => 0,
            Role::Pan(v) => v,
        };
        self.frames(|c| match c.role {
            Role::Pan(v) if moved.contains(&c.light) => {
                let turned = f64::from(v) + share * f64::from(c.full);
                let turned = if turned > f64::from(c.full) { f64::from(v) - share * f64::from(c.full) } else { turned };
                turned.clamp(0.0, f64::from(c.full)) as u16
            }
            _ => lit(c),
        })
    }

    /// `n` moving heads spread over the rig's moving fixtures (every k-th
    /// by fixture order): their fixture ids and light indices.
    pub fn spread_heads(&self, n: usize) -> (Vec<u32>, Vec<usize>) {
        let step = (self.heads.len() / n.max(1)).max(1);
        let chosen: Vec<&(u32, Vec<usize>)> = self.heads.iter().step_by(step).take(n).collect();
        (chosen.iter().map(|(id, _)| *id).collect(), chosen.iter().flat_map(|(_, l)| l.iter().copied()).collect())
    }

    /// The lights `universes` lights (k_i > 0 decoded through the patch).
    pub fn lit_lights(patch: &Patch, universes: &Universes) -> Vec<bool> {
        patch
            .fixtures
            .iter()
            .map(|f| {
                let k = f.k_of(&f.decode_universes(universes));
                k.max_element() > 0.0 && k.is_finite()
            })
            .collect()
    }

    /// `--set U/ADDR=V` items for `footlight render`: every slot where
    /// `universes` differs from the patch's defaults.
    pub fn set_items(&self, universes: &Universes) -> Vec<String> {
        let mut items = Vec::new();
        for &u in &self.universes {
            let (Some(base), Some(now)) = (self.base.get(u), universes.get(u)) else { continue };
            for (a, (b, v)) in base.iter().zip(now.iter()).enumerate() {
                if b != v {
                    items.push(format!("{u}/{}={v}", a + 1));
                }
            }
        }
        items
    }
}

/// A channel's role in the look.
fn channel_role(c: &Channel, full: u16, cmy: bool) -> Role {
    // The first ungated channel function doing `action` (else a gated one), at its first value.
    let first = |want: &dyn Fn(&Action) -> bool| {
        let mut fs = c.functions.iter().filter(|f| want(&f.action)).collect::<Vec<_>>();
        fs.sort_by_key(|f| f.mode.is_some());
        fs.first().map(|f| f.from)
    };
    match c.attribute {
        Attribute::Dimmer | Attribute::HsbBrightness | Attribute::CieBrightness | Attribute::Level => Role::Level,
        Attribute::Mix(index) => {
            let subtractive = cmy || c.name.to_ascii_lowercase().starts_with("colorsub");
            Role::Colour { index, subtractive }
        }
        Attribute::Shutter => Role::Fixed(first(&|a| *a == Action::Open).unwrap_or(c.default)),
        Attribute::ColourWheel
        | Attribute::ColourWheelN(_)
        | Attribute::Gobo
        | Attribute::Gobo2
        | Attribute::Prism
        | Attribute::Animation => Role::Fixed(first(&|a| *a == Action::Slot(0)).unwrap_or(0)),
        Attribute::Saturation => Role::Fixed(if c.range[0] <= c.range[1] { 0 } else { full }),
        Attribute::Iris => Role::Fixed(if c.range[1] >= c.range[0] { full } else { 0 }),
        Attribute::Pan => Role::Pan(c.default),
        _ => Role::Fixed(c.default),
    }
}

// ------------------------------------------------------------ the measures

/// Resident and peak memory of process `pid` ("self" for this one), MB: VmRSS and VmHWM.
pub fn rss_mb(pid: &str) -> (f64, f64) {
    let text = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    let field = |name: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(name))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
            .map_or(f64::NAN, |kib| kib / 1024.0)
    };
    (field("VmRSS:"), field("VmHWM:"))
}

/// The 1-minute load average.
fn load_average() -> f64 {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().and_then(|v| v.parse().ok()))
        .unwrap_or(f64::NAN)
}

/// Loads the show as `footlight run --patch SHOW` does: its venue as the
/// scene, its fixtures as the patch, the "frame the rig" camera.
pub fn load(show: &Path) -> Result<(Scene, Patch, Camera), String> {
    let scene = crate::scene::load_mvr_scene(show).map_err(|e| e.to_string())?.scene;
    let patch = footlight_mvr::check_report(show)
        .map_err(|e| e.first().map_or("invalid show".to_string(), ToString::to_string))?
        .patch;
    let seat = Camera::look_at(glam::Vec3::new(0.0, 1.7, 14.0), glam::Vec3::new(0.0, 1.5, 0.0), 40f32.to_radians());
    let camera =
        patch.camera.map(|c| Camera::look_at(c.position, c.look_at, c.fov_y)).or(scene.camera).unwrap_or_else(|| {
            crate::live::views::named_views(&seat, &scene, Some(&patch))
                .into_iter()
                .find(|v| v.name == crate::live::views::FRAME_VIEW)
                .and_then(|v| v.pose.camera().ok())
                .unwrap_or(seat)
        });
    Ok((scene, patch, camera))
}

/// Sends universes as ArtDmx to the daemon (Port-Address = patch universe − 1).
struct Sender {
    sock: std::net::UdpSocket,
    target: std::net::SocketAddr,
    sequence: u8,
}

impl Sender {
    fn new(target: std::net::SocketAddr) -> Result<Self, String> {
        let sock = std::net::UdpSocket::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
        Ok(Self { sock, target, sequence: 0 })
    }

    fn send(&mut self, frames: &Universes, universes: &[u16]) -> Result<(), String> {
        self.sequence = self.sequence % 255 + 1;
        for &u in universes {
            let Some(slots) = frames.get(u) else { continue };
            let packet = footlight_dmx::artnet::packet::build_dmx(self.sequence, 0, u - 1, slots);
            self.sock.send_to(&packet, self.target).map_err(|e| e.to_string())?;
        }
        Ok(())
    }
}

/// Waits for `child` until `deadline`, polling its peak RSS; kills it at the deadline.
fn wait_child(child: &mut Child, start: Instant, deadline: Duration) -> Subprocess {
    let pid = child.id().to_string();
    let mut peak: f64 = 0.0;
    loop {
        let hwm = rss_mb(&pid).1;
        if hwm.is_finite() {
            peak = peak.max(hwm);
        }
        match child.try_wait() {
            Ok(Some(status)) => {
                return Subprocess {
                    wall_s: start.elapsed().as_secs_f64(),
                    finished: true,
                    code: status.code(),
                    peak_rss_mb: peak,
                    ..Subprocess::default()
                };
            }
            Ok(None) if start.elapsed() < deadline => std::thread::sleep(Duration::from_millis(100)),
            _ => {
                let wall_s = start.elapsed().as_secs_f64();
                let _ = child.kill();
                let _ = child.wait();
                return Subprocess { wall_s, finished: false, code: None, peak_rss_mb: peak, ..Subprocess::default() };
            }
        }
    }
}

/// `footlight render` of the show with `set` items, bounded by `deadline`.
fn render(cfg: &FestivalConfig, binary: &Path, dir: &Path, name: &str, set: &[String]) -> Result<Subprocess, String> {
    let log = dir.join(format!("{name}.log"));
    let mut cmd = Command::new(binary);
    cmd.arg("render")
        .arg("--patch")
        .arg(&cfg.show)
        .args(["--width", &cfg.width.to_string(), "--height", &cfg.height.to_string()])
        .args(["--photons", &cfg.photons.to_string()])
        .arg("--out")
        .arg(dir.join(format!("{name}.png")))
        .arg("--force");
    // One `--set` per 1,000 slots: no argument near the kernel's 128 KiB limit.
    for chunk in set.chunks(1000) {
        cmd.arg("--set").arg(chunk.join(","));
    }
    let stderr = std::fs::File::create(&log).map_err(|e| e.to_string())?;
    let start = Instant::now();
    let mut child = cmd
        .env("RUST_LOG", "info")
        .stdout(Stdio::null())
        .stderr(stderr)
        .spawn()
        .map_err(|e| format!("{}: {e}", binary.display()))?;
    let mut run = wait_child(&mut child, start, Duration::from_secs_f64(cfg.seconds));
    let text = std::fs::read_to_string(&log).unwrap_or_default();
    run.render_ms = parse_render_log(&text);
    run.lit_of = text.lines().find_map(parse_lit_of);
    Ok(run)
}

/// Strips ANSI colour codes (the log is a file, but a terminal's env may force them).
fn plain(line: &str) -> String {
    let mut out = String::with_capacity(line.len());
    let mut chars = line.chars();
    while let Some(c) = chars.next() {
        if c == '\u{1b}' {
            for d in chars.by_ref() {
                if d.is_ascii_alphabetic() {
                    break;
                }
            }
        } else {
            out.push(c);
        }
    }
    out
}

/// The number before `unit` that follows `key` in `line`.
fn number_after(line: &str, key: &str, unit: &str) -> Option<f64> {
    let rest = &line[line.find(key)? + key.len()..];
    let end = rest.find(unit)?;
    rest[..end].split_whitespace().last()?.parse().ok()
}

/// `render`'s timing line: "view N ms, L light buffers N ms (…), photon maps N ms, haze N ms, composite N ms".
fn parse_render_log(text: &str) -> Option<RenderLog> {
    let line = text.lines().map(plain).find(|l| l.contains("light buffers") && l.contains("composite"))?;
    Some(RenderLog {
        view: number_after(&line, "view ", " ms")?,
        lights: number_after(&line, "light buffers ", " ms")?,
        photons: number_after(&line, "photon maps ", " ms")?,
        composite: number_after(&line, "composite ", " ms")?,
    })
}

/// "N of M lights are lit".
fn parse_lit_of(line: &str) -> Option<(usize, usize)> {
    let line = plain(line);
    let head = &line[..line.find(" lights are lit")?];
    let mut words = head.split_whitespace().rev();
    let m = words.next()?.parse().ok()?;
    (words.next()? == "of").then_some(())?;
    Some((words.next()?.parse().ok()?, m))
}

/// A stage's rank: queued 0, direct 1, Whitted 2, with indirect light 3, ready 4.
fn rank(stage: Stage) -> u8 {
    match stage {
        Stage::Queued => 0,
        Stage::Direct => 1,
        Stage::Whitted => 2,
        Stage::Photons | Stage::Refining(_) => 3,
        Stage::Ready => 4,
    }
}

/// Bytes per MB in the report (MiB, like the RSS column).
const MB: f64 = (1u64 << 20) as f64;

/// One sample of the daemon's status, counting the lights `lit` marks.
fn sample(status: &crate::output::DaemonStatus, lit: &[bool], t_s: f64) -> ReadySample {
    let mut s = ReadySample {
        t_s,
        fps: status.clock.fps,
        p99_ms: status.clock.frame_interval_p99_ms,
        composite_ms: status.clock.composite_ms,
        rss_mb: rss_mb("self").0,
        buffers_mb: status.memory.buffers_bytes as f64 / MB,
        maps_mb: status.memory.photon_maps_bytes as f64 / MB,
        caches_mb: status.memory.caches_bytes as f64 / MB,
        groups_mb: status.clock.group_storage_bytes as f64 / MB,
        ..ReadySample::default()
    };
    for (l, &is_lit) in status.lights.iter().zip(lit) {
        let r = l.build.as_ref().map_or(0, |b| rank(b.stage));
        s.lit_seen += usize::from(l.intensity > 0.0);
        if !is_lit {
            s.dark_built += usize::from(r > 0);
            continue;
        }
        // A light waiting for a build at its new geometry shows an older one: count what is on screen.
        match r {
            0 => s.queued += 1,
            r => {
                s.direct += 1;
                s.whitted += usize::from(r >= 2);
                s.photons += usize::from(r >= 3);
                s.ready += usize::from(r >= 4);
            }
        }
    }
    s
}

/// True when every lit light's direct stage for its current geometry is on screen.
fn direct_done(status: &crate::output::DaemonStatus, lit: &[bool]) -> bool {
    status
        .lights
        .iter()
        .zip(lit)
        .filter(|(_, l)| **l)
        .all(|(l, _)| l.build.as_ref().is_some_and(|b| b.stage != Stage::Queued && b.pending_ms.is_none()))
}

/// Median and largest of some values.
fn median_max(mut v: Vec<f64>) -> (f64, f64) {
    v.retain(|x| x.is_finite());
    v.sort_by(f64::total_cmp);
    (v.get(v.len() / 2).copied().unwrap_or(f64::NAN), v.last().copied().unwrap_or(f64::NAN))
}

/// Runs the section and returns its report (a phase that cannot run is
/// noted in `errors` and its targets left unmeasured).
pub fn run(cfg: &FestivalConfig) -> Result<FestivalReport, String> {
    let load_start = load_average();
    let (scene, patch, camera) = load(&cfg.show)?;
    let (w, h) = (cfg.width, cfg.height);
    let look = Look::of(&patch);
    let lit_frames = look.lit();
    let lit = Look::lit_lights(&patch, &lit_frames);
    let lit_count = lit.iter().filter(|l| **l).count();
    let mut fixture_ids: Vec<u32> = patch.fixtures.iter().map(|f| f.id).collect();
    fixture_ids.dedup();
    let mut report = FestivalReport {
        show: cfg.show.display().to_string(),
        width: w,
        height: h,
        seconds: cfg.seconds,
        cue_seconds: cfg.cue_seconds,
        photons: cfg.photons,
        fixtures: fixture_ids.len(),
        lights: patch.fixtures.len(),
        lit: lit_count,
        universes: look.universes().len(),
        triangles: scene.triangle_count(),
        cores: std::thread::available_parallelism().map_or(0, |n| n.get()),
        load_average: (load_start, f64::NAN),
        commit: commit(),
        gbuffer_ms: f64::NAN,
        dark_render: None,
        lit_render: None,
        samples: Vec::new(),
        built_before_look: 0,
        look_seen_s: None,
        direct_s: None,
        converged_s: None,
        ready_s: None,
        moved_lights: 0,
        moved_s: None,
        broad_fps: f64::NAN,
        broad_composite_ms: (f64::NAN, f64::NAN),
        broad_quiet_stages: 0,
        chase_fps: f64::NAN,
        chase_composite_ms: (f64::NAN, f64::NAN),
        chase_quiet_stages: 0,
        rss_mb: (f64::NAN, f64::NAN),
        sigterm: None,
        errors: Vec::new(),
        rows: Vec::new(),
        composite_chase: None,
    };

    // 1. The G-buffer alone (View::build: the 9-sample G-buffer and the Whitted paths), as `render` builds it.
    let t = Instant::now();
    drop(View::build(&scene, camera, w, h, Sampling::Adaptive, RecursionLimits::default()));
    report.gbuffer_ms = t.elapsed().as_secs_f64() * 1e3;

    // 2. `render`, dark and lit, as subprocesses.
    let binary = cfg.binary.clone().or_else(|| std::env::current_exe().ok());
    let dir = std::env::temp_dir().join(format!("footlight-festival-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    if let Some(binary) = &binary {
        tracing::info!("festival: dark render");
        match render(cfg, binary, &dir, "dark", &[]) {
            Ok(r) => report.dark_render = Some(r),
            Err(e) => report.errors.push(format!("dark render: {e}")),
        }
        tracing::info!("festival: lit render (at most {} s)", cfg.seconds);
        match render(cfg, binary, &dir, "lit", &look.set_items(&lit_frames)) {
            Ok(r) => report.lit_render = Some(r),
            Err(e) => report.errors.push(format!("lit render: {e}")),
        }
    } else {
        report.errors.push("no footlight binary for the render and SIGTERM phases".into());
    }

    // 3. Live: the daemon in this process, lit over Art-Net on loopback.
    tracing::info!("festival: live build (at most {} s per phase)", cfg.seconds);
    if let Err(e) = live(cfg, scene, patch, camera, &look, &lit, &mut report) {
        report.errors.push(format!("live: {e}"));
    }

    // 4. SIGTERM while `footlight run` builds.
    if let Some(binary) = &binary {
        tracing::info!("festival: SIGTERM while building");
        match sigterm(cfg, binary, &look, &lit_frames, &dir) {
            Ok(r) => report.sigterm = Some(r),
            Err(e) => report.errors.push(format!("SIGTERM: {e}")),
        }
    }
    let _ = std::fs::remove_dir_all(&dir);

    // 5. The pixel chase on the compositor alone: per cell vs grouped.
    tracing::info!("festival: pixel chase on the compositor, per cell vs grouped");
    match super::scale::pixel_chase(&cfg.show, w, h, 30) {
        Ok(r) => report.composite_chase = Some(r),
        Err(e) => report.errors.push(format!("composite pixel chase: {e}")),
    }
    report.load_average.1 = load_average();
    report.rows = rows(&report);
    Ok(report)
}

/// The commit of the checkout the festival show is read from (where the
/// bundled files are found at run time), when git knows it, with
/// "+ uncommitted changes" when tracked files differ from it.
fn commit() -> Option<String> {
    let git = |args: &[&str]| {
        let out = Command::new("git")
            .arg("-C")
            .arg(crate::bundled::root_of(FESTIVAL_SHOW).unwrap_or_else(|_| PathBuf::from(".")))
            .args(args)
            .stderr(Stdio::null())
            .output()
            .ok()?;
        out.status.success().then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
    };
    let head = git(&["rev-parse", "--short", "HEAD"])?;
    let dirty = git(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
    Some(if dirty { format!("{head} + uncommitted changes in the working tree") } else { head })
}

/// The live phases: build, moved heads, broad cue, pixel chase.
fn live(
    cfg: &FestivalConfig,
    scene: Scene,
    patch: Patch,
    camera: Camera,
    look: &Look,
    lit: &[bool],
    report: &mut FestivalReport,
) -> Result<(), String> {
    let show = Arc::new(Show::new(patch).map_err(|e| e.to_string())?);
    let mut config = super::harness::config(cfg.width, cfg.height);
    config.tracer.build.photons =
        (cfg.photons > 0).then(|| PhotonSettings { stored: cfg.photons, ..PhotonSettings::default() });
    let daemon = Daemon::new(Arc::new(scene), show, camera, config).input(DmxSource::Network {
        artnet: Some(footlight_dmx::artnet::ArtNetConfig {
            bind: "127.0.0.1:0".parse().map_err(|e| format!("{e}"))?,
            ..Default::default()
        }),
        sacn: None,
        usbpro: None,
    });
    let running = super::harness::Running::start(super::harness::runtime()?, daemon)?;
    let result = live_phases(cfg, &running.handle, look, lit, report);
    running.stop()?;
    result
}

fn live_phases(
    cfg: &FestivalConfig,
    handle: &crate::live::DaemonHandle,
    look: &Look,
    lit: &[bool],
    report: &mut FestivalReport,
) -> Result<(), String> {
    let target = handle.dmx.as_ref().and_then(|d| d.artnet).ok_or("no Art-Net socket")?;
    let mut sender = Sender::new(target)?;
    let universes = look.universes().to_vec();
    let lit_frames = look.lit();
    let deadline = Duration::from_secs_f64(cfg.seconds);
    let mut max_rss: f64 = 0.0;
    // The desk comes up a moment after the daemon (and the clock's one-second figures fill).
    std::thread::sleep(LOOK_AFTER);
    report.built_before_look = sample(&(handle.status)(), &vec![false; lit.len()], 0.0).dark_built;

    // The build: the look sent at 4 Hz (a desk's refresh), the status polled every 250 ms.
    let sent = Instant::now();
    let mut next_sample = 0.0;
    let mut next_send = 0.0;
    loop {
        let t = sent.elapsed().as_secs_f64();
        if t >= next_send {
            sender.send(&lit_frames, &universes)?;
            next_send += 0.25;
        }
        let status = (handle.status)();
        let s = sample(&status, lit, t);
        max_rss = max_rss.max(s.rss_mb);
        if report.look_seen_s.is_none() && s.lit_seen >= report.lit {
            report.look_seen_s = Some(t);
        }
        if report.look_seen_s.is_some() {
            if report.direct_s.is_none() && direct_done(&status, lit) {
                report.direct_s = Some(t);
            }
            if report.converged_s.is_none() && s.photons == report.lit {
                report.converged_s = Some(t);
            }
            if report.ready_s.is_none() && s.ready == report.lit {
                report.ready_s = Some(t);
            }
        }
        let all = report.ready_s.is_some() || (cfg.photons == 0 && report.converged_s.is_some());
        if t >= next_sample || all {
            report.samples.push(s);
            next_sample += SAMPLE_S;
        }
        if all || sent.elapsed() >= deadline {
            break;
        }
        std::thread::sleep(Duration::from_millis(250));
    }

    // Moved heads: 18 heads' pan turned by 10 % of its range, in the lit (building) rig.
    let (heads, moved) = look.spread_heads(MOVED_HEADS);
    report.moved_lights = moved.len();
    let frames = look.moved(&heads, 0.1);
    let before = (handle.status)();
    let updates =
        |s: &crate::output::DaemonStatus, i: usize| s.lights[i].build.as_ref().map_or(0, |b| b.direct_updates);
    let dmx_before: Vec<Vec<u8>> = moved.iter().map(|&i| before.lights[i].dmx.clone()).collect();
    let updates_before: Vec<u64> = moved.iter().map(|&i| updates(&before, i)).collect();
    let start = Instant::now();
    let mut next_send = 0.0;
    let mut seen = false;
    while start.elapsed() < deadline {
        let t = start.elapsed().as_secs_f64();
        if t >= next_send {
            sender.send(&frames, &universes)?;
            next_send += 0.25;
        }
        let s = (handle.status)();
        // The move has arrived once every moved light's DMX shows it.
        seen = seen || moved.iter().zip(&dmx_before).all(|(&i, d)| s.lights[i].dmx != *d);
        let done = seen
            && moved.iter().zip(&updates_before).all(|(&i, &u)| {
                s.lights[i].build.as_ref().is_some_and(|b| b.pending_ms.is_none() && b.direct_updates > u)
            });
        if done {
            report.moved_s = Some(t);
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }

    // The broad cue and the pixel chase: a frame of DMX per 60 Hz frame, every universe.
    let cue = |frame: &dyn Fn(f64) -> Universes, sender: &mut Sender| -> Result<(f64, (f64, f64), f64, u64), String> {
        let start = Instant::now();
        let at_start = (handle.status)();
        let first = at_start.frame;
        let mut composite = Vec::new();
        let mut rss: f64 = 0.0;
        let mut n = 0u32;
        let mut next_sample = SAMPLE_S;
        while start.elapsed().as_secs_f64() < cfg.cue_seconds {
            let t = start.elapsed().as_secs_f64();
            sender.send(&frame(t), &universes)?;
            if t >= next_sample {
                let s = (handle.status)();
                composite.push(s.clock.composite_ms);
                rss = rss.max(rss_mb("self").0);
                next_sample += SAMPLE_S;
            }
            n += 1;
            let due = Duration::from_secs_f64(f64::from(n) / CUE_HZ);
            if let Some(wait) = due.checked_sub(start.elapsed()) {
                std::thread::sleep(wait);
            }
        }
        let at_end = (handle.status)();
        let frames = at_end.frame - first;
        let quiet = at_end.builds.quiet_stages - at_start.builds.quiet_stages;
        Ok((frames as f64 / start.elapsed().as_secs_f64(), median_max(composite), rss, quiet))
    };
    let (fps, comp, rss, quiet) = cue(&|t| look.broad(t), &mut sender)?;
    (report.broad_fps, report.broad_composite_ms, report.broad_quiet_stages) = (fps, comp, quiet);
    max_rss = max_rss.max(rss);
    let (fps, comp, rss, quiet) = cue(&|t| look.chase(t), &mut sender)?;
    (report.chase_fps, report.chase_composite_ms, report.chase_quiet_stages) = (fps, comp, quiet);
    max_rss = max_rss.max(rss);
    report.rss_mb = (max_rss, rss_mb("self").1);
    Ok(())
}

/// `footlight run --patch SHOW` as a user starts it; the look over Art-Net,
/// SIGTERM 3 s later (during the build), the time to exit.
fn sigterm(
    cfg: &FestivalConfig,
    binary: &Path,
    look: &Look,
    lit_frames: &Universes,
    dir: &Path,
) -> Result<SigtermRun, String> {
    let log = dir.join("run.log");
    let start = Instant::now();
    let mut child = Command::new(binary)
        .arg("run")
        .arg("--patch")
        .arg(&cfg.show)
        .args(["--artnet", "127.0.0.1:0", "--sacn", "off", "--http", "127.0.0.1:0"])
        .args(["--width", &cfg.width.to_string(), "--height", &cfg.height.to_string()])
        .args(["--compositor", "cpu"])
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(&log).map_err(|e| e.to_string())?)
        .spawn()
        .map_err(|e| format!("{}: {e}", binary.display()))?;
    let stdout = child.stdout.take().ok_or("no stdout")?;
    // "listening for DMX: Art-Net 127.0.0.1:PORT, sACN off (…)".
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if let Some(rest) = line.strip_prefix("listening for DMX: Art-Net ") {
                let addr = rest.split(',').next().and_then(|a| a.trim().parse::<std::net::SocketAddr>().ok());
                let _ = tx.send(addr);
            }
        }
    });
    let kill = |child: &mut Child| {
        let _ = child.kill();
        let _ = child.wait();
    };
    let target = match rx.recv_timeout(Duration::from_secs_f64(cfg.seconds)) {
        Ok(Some(a)) => a,
        _ => {
            kill(&mut child);
            return Err(format!("`footlight run` did not listen within {} s", cfg.seconds));
        }
    };
    let start_s = start.elapsed().as_secs_f64();
    let mut sender = Sender::new(target)?;
    let lit_at = Instant::now();
    while lit_at.elapsed() < Duration::from_secs(3) {
        sender.send(lit_frames, look.universes())?;
        std::thread::sleep(Duration::from_millis(100));
    }
    let after_look_s = lit_at.elapsed().as_secs_f64();
    let signalled = Instant::now();
    let ok = Command::new("kill").args(["-TERM", &child.id().to_string()]).status().map_err(|e| e.to_string())?;
    if !ok.success() {
        kill(&mut child);
        return Err("kill -TERM failed".into());
    }
    let (exit_s, code) = loop {
        match child.try_wait() {
            Ok(Some(status)) => break (Some(signalled.elapsed().as_secs_f64()), status.code()),
            Ok(None) if signalled.elapsed() < Duration::from_secs(30) => std::thread::sleep(Duration::from_millis(5)),
            _ => {
                kill(&mut child);
                break (None, None);
            }
        }
    };
    let text = std::fs::read_to_string(&log).unwrap_or_default();
    let late_tasks = text.lines().filter(|l| l.contains("did not stop")).count();
    Ok(SigtermRun { start_s, after_look_s, exit_s, code, late_tasks })
}

/// Seconds, or "not reached within N s".
fn within(v: Option<f64>, limit: f64) -> String {
    v.map_or(format!("not reached within {limit:.0} s"), |s| format!("{s:.1} s"))
}

/// The target table.
fn rows(r: &FestivalReport) -> Vec<TargetRow> {
    let mut rows = Vec::new();
    let mut row = |measure: &str, value: String, target: &str, pass: Option<bool>, note: String| {
        rows.push(TargetRow { measure: measure.into(), value, target: target.into(), pass, note });
    };
    let g = r.gbuffer_ms;
    match &r.dark_render {
        Some(d) if d.finished => {
            row(
                "dark rig `render` (whole command)",
                format!("{:.1} s = {:.1}× the G-buffer", d.wall_s, d.wall_s * 1e3 / g),
                "≤ 2× the G-buffer",
                Some(d.wall_s * 1e3 <= 2.0 * g),
                format!(
                    "G-buffer (`View::build`, in process) {:.0} ms; the command includes loading the show; \
                     peak RSS {:.0} MB; lit: {}",
                    g,
                    d.peak_rss_mb,
                    d.lit_of.map_or("all".to_string(), |(a, b)| format!("{a} of {b}"))
                ),
            );
            if let Some(l) = &d.render_ms {
                let work = l.view + l.lights + l.photons + l.composite;
                row(
                    "dark rig `render` (after loading)",
                    format!("{:.1} s = {:.1}× the G-buffer", work / 1e3, work / g),
                    "≤ 2× the G-buffer",
                    Some(work <= 2.0 * g),
                    format!(
                        "render's own log: view {:.0} ms, light buffers {:.0} ms, photon maps {:.0} ms, composite {:.0} ms",
                        l.view, l.lights, l.photons, l.composite
                    ),
                );
            }
        }
        Some(d) => row(
            "dark rig `render`",
            format!("not finished within {:.0} s", d.wall_s),
            "≤ 2× the G-buffer",
            Some(false),
            format!("G-buffer {g:.0} ms; killed at the deadline"),
        ),
        None => row("dark rig `render`", "not run".into(), "≤ 2× the G-buffer", None, String::new()),
    }
    match &r.lit_render {
        Some(d) => row(
            "lit rig `render` (default photons)",
            if d.finished { format!("{:.1} s", d.wall_s) } else { format!("not finished within {:.0} s", d.wall_s) },
            "≤ 60 s",
            Some(d.finished && d.wall_s <= 60.0 && d.code == Some(0)),
            format!(
                "{} photons, whole command; peak RSS {:.0} MB; lit: {}{}",
                r.photons,
                d.peak_rss_mb,
                d.lit_of.map_or("?".to_string(), |(a, b)| format!("{a} of {b}")),
                d.render_ms.as_ref().map_or(String::new(), |l| format!(
                    "; view {:.0} ms, light buffers {:.0} ms, photon maps {:.0} ms",
                    l.view, l.lights, l.photons
                ))
            ),
        ),
        None => row("lit rig `render`", "not run".into(), "≤ 60 s", None, String::new()),
    }
    row(
        "lit rig live: every lit emitter's direct stage on screen",
        within(r.direct_s, r.seconds),
        "≤ 10 s after the look arrives",
        Some(r.direct_s.is_some_and(|s| s <= 10.0)),
        format!(
            "{} lit lights; the daemon showed them lit {} after the look was sent; {} (dark) lights built before it",
            r.lit,
            within(r.look_seen_s, r.seconds),
            r.built_before_look
        ),
    );
    row(
        "moved heads in the lit rig: beams at the new position",
        r.moved_s.map_or(format!("not reached within {:.0} s", r.seconds), |s| format!("{:.2} s", s)),
        "≤ 0.5 s",
        Some(r.moved_s.is_some_and(|s| s <= 0.5)),
        format!(
            "{MOVED_HEADS} heads ({} lights) panned by 10 % of their range while the rig builds; \
             every one's direct stage at the new pan published",
            r.moved_lights
        ),
    );
    row(
        "broad cue (every emitter's level changes every frame)",
        format!("{:.1} fps", r.broad_fps),
        "≥ 30 fps",
        Some(r.broad_fps >= 30.0),
        format!(
            "frames published per second over {:.0} s of DMX at {CUE_HZ} Hz on every universe; composite median {:.1} ms, largest {:.1} ms; {} build stages with the quiet threads during it",
            r.cue_seconds, r.broad_composite_ms.0, r.broad_composite_ms.1, r.broad_quiet_stages
        ),
    );
    row(
        "lit rig live: every emitter converged (Whitted + indirect)",
        within(r.converged_s, r.seconds),
        "≤ 3 min",
        Some(r.converged_s.is_some_and(|s| s <= 180.0)),
        format!(
            "every lit light at the photons stage or later; every one `ready` (16 refinement passes): {}",
            within(r.ready_s, r.seconds)
        ),
    );
    let during: Vec<&ReadySample> = r.samples.iter().filter(|s| r.converged_s.is_none_or(|c| s.t_s <= c)).collect();
    let worst_p99 = during.iter().map(|s| s.p99_ms).filter(|v| v.is_finite()).fold(f64::NAN, f64::max);
    let fps = median_max(during.iter().map(|s| s.fps).collect());
    let min_fps = during.iter().map(|s| s.fps).fold(f64::INFINITY, f64::min);
    row(
        "frame clock while building",
        format!("p99 {worst_p99:.1} ms (worst window), {:.1} fps median, {min_fps:.1} fps lowest", fps.0),
        "60 fps, p99 ≤ 20 ms",
        Some(worst_p99 <= 20.0 && fps.0 >= 57.0),
        format!(
            "the status' `frame_interval_p99_ms` (last 600 frames) and `fps`, sampled every {SAMPLE_S} s while building"
        ),
    );
    row(
        "pixel chase (every cell's colour changes every frame, over Art-Net)",
        format!("{:.1} Hz", r.chase_fps),
        "≥ 30 Hz composite",
        Some(r.chase_fps >= 30.0),
        format!(
            "frames published per second, CPU compositor; composite median {:.1} ms, largest {:.1} ms; {} build stages with the quiet threads during it",
            r.chase_composite_ms.0, r.chase_composite_ms.1, r.chase_quiet_stages
        ),
    );
    row(
        "RSS, lit rig",
        format!("{:.2} GB peak (VmHWM), {:.2} GB largest VmRSS sampled", r.rss_mb.1 / 1024.0, r.rss_mb.0 / 1024.0),
        "≤ 3 GB",
        Some(r.rss_mb.1.is_finite() && r.rss_mb.1 <= 3072.0),
        "this process: the daemon plus the bench's own show, scene and look".into(),
    );
    match &r.sigterm {
        Some(s) => row(
            "SIGTERM while building",
            s.exit_s.map_or("did not exit within 30 s".to_string(), |e| format!("{:.2} s", e)),
            "< 1 s",
            Some(s.exit_s.is_some_and(|e| e < 1.0) && s.code == Some(0)),
            format!(
                "`footlight run --patch` (release binary) listening after {:.1} s, SIGTERM {:.1} s after the look; \
                 exit code {}; {} \"did not stop\" log lines",
                s.start_s,
                s.after_look_s,
                s.code.map_or("none".to_string(), |c| c.to_string()),
                s.late_tasks
            ),
        ),
        None => row("SIGTERM while building", "not run".into(), "< 1 s", None, String::new()),
    }
    rows
}

impl FestivalReport {
    /// The section for report.md.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "\n## A festival, live (issue 38)\n\n`{}`: {} fixtures, {} lights ({} lit by the look), {} universes, \
             {} triangles; {}×{}, {} photons per light, each phase bounded by {:.0} s. {} cores, 1-minute load \
             average {:.2} at the start and {:.2} at the end (other work on the machine slows every figure){}.\n\n\
             | measure | value | target | |\n|---|---|---|---|\n",
            self.show.rsplit('/').next().unwrap_or(&self.show),
            self.fixtures,
            self.lights,
            self.lit,
            self.universes,
            self.triangles,
            self.width,
            self.height,
            self.photons,
            self.seconds,
            self.cores,
            self.load_average.0,
            self.load_average.1,
            self.commit.as_ref().map_or(String::new(), |c| format!("; commit {c}")),
        );
        for r in &self.rows {
            let verdict = match r.pass {
                Some(true) => "pass",
                Some(false) => "**fail**",
                None => "-",
            };
            s += &format!("| {} | {} | {} | {verdict} |\n", r.measure, r.value, r.target);
        }
        s += "\n";
        for r in self.rows.iter().filter(|r| !r.note.is_empty()) {
            s += &format!("* {}: {}\n", r.measure, r.note);
        }
        for e in &self.errors {
            s += &format!("* error: {e}\n");
        }
        s += "\nLit lights by the stage on screen after the look was sent (`festival-ready.svg`):\n\n\
              | t (s) | queued | direct | Whitted | indirect | ready | dark built | fps | p99 (ms) | composite (ms) | RSS (MB) | buffers (MB) | photon maps (MB) | caches (MB) | groups (MB) |\n\
              |---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
        let step = (self.samples.len() / 24).max(1);
        let last = self.samples.len().saturating_sub(1);
        for (_, p) in self.samples.iter().enumerate().filter(|(i, _)| i % step == 0 || *i == last) {
            s += &format!(
                "| {:.1} | {} | {} | {} | {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} |\n",
                p.t_s,
                p.queued,
                p.direct,
                p.whitted,
                p.photons,
                p.ready,
                p.dark_built,
                p.fps,
                p.p99_ms,
                p.composite_ms,
                p.rss_mb,
                p.buffers_mb,
                p.maps_mb,
                p.caches_mb,
                p.groups_mb
            );
        }
        if let Some(chase) = &self.composite_chase {
            s += &chase.markdown();
        }
        s
    }

    /// Lines for the terminal.
    pub fn lines(&self) -> String {
        let mut s = format!("  festival: {} lights, {}×{}\n", self.lights, self.width, self.height);
        for r in &self.rows {
            let verdict = match r.pass {
                Some(true) => "pass",
                Some(false) => "FAIL",
                None => "-",
            };
            s += &format!("    {:<66} {:<48} {:<30} {verdict}\n", r.measure, r.value, r.target);
        }
        s
    }

    /// The emitters-ready plot: lit lights per stage against time.
    pub fn ready_svg(&self) -> String {
        let series = |name: &str, colour: &str, f: &dyn Fn(&ReadySample) -> usize| super::plots::Series {
            name: name.into(),
            colour: colour.into(),
            points: self.samples.iter().map(|p| (p.t_s, f(p) as f64)).collect(),
        };
        super::plots::series_svg(
            &format!("festival.mvr: lit emitters on screen by stage ({}×{})", self.width, self.height),
            "seconds since the look was sent",
            &format!("lit emitters (of {})", self.lit),
            self.lit as f64,
            &[
                series("direct", "#d62728", &|p| p.direct),
                series("Whitted", "#ff7f0e", &|p| p.whitted),
                series("indirect (converged)", "#1f77b4", &|p| p.photons),
                series("ready", "#2ca02c", &|p| p.ready),
            ],
        )
    }

    /// Writes report.md, report.json and festival-ready.svg into `out`.
    pub fn write(&self, out: &Path) -> std::io::Result<()> {
        std::fs::create_dir_all(out)?;
        std::fs::write(out.join("report.md"), format!("# footlight bench: festival\n{}", self.markdown()))?;
        std::fs::write(out.join("report.json"), serde_json::to_string_pretty(self).map_err(std::io::Error::other)?)?;
        std::fs::write(out.join("festival-ready.svg"), self.ready_svg())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn render_log_lines_parse() {
        let line = "\u{1b}[2m2026\u{1b}[0m INFO footlight: view 1234 ms, 3684 light buffers 56789 ms \
                    (12 pixels re-shaded for anti-aliasing), photon maps 321 ms, haze 0 ms, composite 4.5 ms";
        let l = parse_render_log(line).unwrap();
        assert_eq!((l.view, l.lights, l.photons, l.composite), (1234.0, 56789.0, 321.0, 4.5));
        assert_eq!(
            parse_lit_of("INFO footlight: 0 of 3687 lights are lit; the dark ones are not built"),
            Some((0, 3687))
        );
        assert_eq!(parse_lit_of("nothing here"), None);
    }
}

#[cfg(test)]
mod festival_look {
    use super::*;

    /// The look computed from the patch's channel layout lights every
    /// emitter of festival.mvr: per fixture type, as many lit lights as
    /// festival.json (the generator's own answers) gives fixtures × cells;
    /// every dimmer channel at full in the frames and decoded at v = 1.
    #[test]
    fn the_look_lights_every_emitter_of_the_festival_show_by_type() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let patch = footlight_mvr::load_patch(&root.join("tests/data/mvr/festival.mvr")).unwrap();
        let known: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(root.join("tests/data/mvr/festival.json")).unwrap()).unwrap();
        let look = Look::of(&patch);
        let frames = look.lit();
        let lit = Look::lit_lights(&patch, &frames);
        assert_eq!(look.universes().len(), known["universes"].as_array().unwrap().len());
        let mut by_type: std::collections::BTreeMap<String, usize> = Default::default();
        let mut dimmers = 0;
        for (f, lit) in patch.fixtures.iter().zip(&lit) {
            let FixtureModel::Typed(t) = &f.model else { continue };
            let file = t.fixture_type.path.file_name().unwrap().to_string_lossy().to_string();
            *by_type.entry(file).or_default() += usize::from(*lit);
            let mode = &t.fixture_type.modes[t.mode];
            for c in mode.channels.iter().filter(|c| c.attribute == Attribute::Dimmer) {
                let (u, a) = f.slot_address(c.offset).unwrap();
                assert_eq!(frames.get(u).unwrap()[usize::from(a) - 1], 255, "{} dimmer at {u}/{a}", f.name);
                dimmers += 1;
            }
            if mode.channels.iter().any(|c| c.attribute == Attribute::Dimmer) {
                assert_eq!(f.decode_universes(&frames).v, 1.0, "{}", f.name);
            }
        }
        assert!(dimmers > 0);
        // A type whose GDTF the archive lacks is a placeholder per fixture (no channels, not lit).
        let mut placeholders = 0;
        for (file, t) in known["types"].as_object().unwrap() {
            let want = t["fixtures"].as_u64().unwrap() * t["cells_per_fixture"].as_u64().unwrap();
            match by_type.get(file) {
                Some(&lit) => assert_eq!(lit as u64, want, "{file}: lit lights"),
                None => placeholders += want,
            }
        }
        assert_eq!(placeholders, known["placeholders"].as_u64().unwrap());
        let total: usize = by_type.values().sum();
        assert_eq!(total as u64, known["emitters"].as_u64().unwrap(), "every emitter lit");
    }
}
