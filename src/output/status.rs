//! `/api/status`: the daemon's typed status ([`DaemonStatus`], documented
//! field by field in docs/live.md) and its parts.
//!
//! The daemon (`live::daemon`) builds it on request; the HTTP server
//! ([`crate::serve`]) fills in what only it knows (the frame it serves, its
//! stream counters: [`DaemonStatus::serving`]) and serialises it as it is.
//! The tests and `footlight bench` read the same value from
//! `DaemonHandle::status`.

use super::camera::ViewStatus;
use super::frame::Frame;
use serde::Serialize;
use std::sync::Arc;

/// Builds the daemon's status on request (the HTTP server's `/api/status`,
/// `DaemonHandle::status`).
pub type StatusFn = Arc<dyn Fn() -> DaemonStatus + Send + Sync>;

/// The frame clock's own measurements.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ClockStatus {
    /// Frames per second over the last second.
    pub fps: f64,
    /// 99th percentile of the interval between published frames over the
    /// last 600 frames, ms (the clock's jitter).
    pub frame_interval_p99_ms: f64,
    /// Composite time of the last frame, ms.
    pub composite_ms: f64,
    /// Bytes the CPU compositor's emitter groups hold (their cells'
    /// buffers stored by what differs, `render::group`), outside the
    /// tracer's memory budget.
    pub group_storage_bytes: u64,
    /// Compositor in use.
    pub compositor: String,
}

/// The tracer's build threads (`footlight run --build-threads`,
/// `--quiet-build-threads`), in `/api/status` as `builds`.
#[derive(Clone, Debug, Default, Serialize)]
pub struct BuildThreads {
    /// Threads every stage may use (the frame clock keeps the other cores).
    pub threads: usize,
    /// Threads added to a stage that starts while the frame clock is quiet.
    pub quiet_threads: usize,
    /// Whether the clock is quiet now (no tick over `quiet_tick` within
    /// `quiet_hold`): the next stage gets the quiet threads.
    pub clock_quiet: bool,
    /// Stages run with the quiet threads so far.
    pub quiet_stages: u64,
}

/// A light in `/api/status`.
#[derive(Clone, Debug, Serialize)]
pub struct LightStatus {
    /// Fixture id and name as the patch gives them.
    #[serde(flatten)]
    pub label: LightLabel,
    /// Its fixture (a cell's fixture), DMX address, mode and position
    /// (all `null` for a daemon without a patch).
    #[serde(flatten)]
    pub patch: LightPatch,
    /// DMX values of its footprint.
    pub dmx: Vec<u8>,
    /// Luminance of its k_i now (cd), 0 when dark.
    pub intensity: f32,
    /// Build state.
    #[serde(flatten)]
    pub build: Option<LightReport>,
}

/// The DMX input in `/api/status`: the DMX crate's typed status
/// (`footlight_dmx::InputStatus`: per patch universe its inputs, sources,
/// packets, age and `stale`; unpatched input universes) plus totals.
#[derive(Clone, Debug, Default, Serialize)]
pub struct InputSummary {
    /// `network`, `replay`, `channel` or `none`.
    pub kind: &'static str,
    /// DMX packets received (all protocols).
    pub packets: u64,
    /// Malformed packets.
    pub malformed: u64,
    /// Per universe and unpatched input, with counters per protocol.
    #[serde(flatten)]
    pub dmx: footlight_dmx::InputStatus,
}

/// Cache usage in `/api/status`.
#[derive(Clone, Debug, Default, Serialize)]
pub struct CacheSummary {
    /// Geometry states cached.
    pub entries: usize,
    /// Bytes they hold.
    pub bytes: usize,
    /// The budget.
    pub budget_bytes: usize,
}

/// `/api/status`: the typed status of the daemon (documented in docs/live.md).
#[derive(Clone, Debug, Serialize)]
pub struct DaemonStatus {
    /// Footlight version.
    pub version: &'static str,
    /// Number of the latest frame.
    pub frame: u64,
    /// Picture width.
    pub width: u32,
    /// Picture height.
    pub height: u32,
    /// Frame clock figures.
    #[serde(flatten)]
    pub clock: ClockStatus,
    /// DMX input.
    pub input: InputSummary,
    /// Geometry cache.
    pub cache: CacheSummary,
    /// The memory budget and what the tracer holds against it (light
    /// buffers, photon maps, caches; `--memory`).
    pub memory: MemoryUsage,
    /// The build threads and how many stages had the quiet ones.
    pub builds: BuildThreads,
    /// The camera: current view, its build stage, the view cache.
    pub view: ViewStatus,
    /// Problems a user should see (stale universes, unpatched DMX).
    pub warnings: Vec<String>,
    /// Every light, in patch order.
    pub lights: Vec<LightStatus>,
    /// What importing the patch said: one summary per fixture type, the
    /// warnings once each (issue 36 item 3; empty for a patch without GDTF types).
    pub import: ImportStatus,
    /// The browser stream's counters: filled by the HTTP server that
    /// answers `/api/status` ([`DaemonStatus::serving`]); `None` (and
    /// absent from the JSON) in the daemon's own status.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stream: Option<StreamCounters>,
}

impl DaemonStatus {
    /// The status as the HTTP server answers it: frame number, picture
    /// size and composite time of `frame` (the frame it serves now, so the
    /// status and `/api/frame.png` agree) and its stream counters.
    pub fn serving(mut self, frame: &Frame, stream: StreamCounters) -> Self {
        self.set_frame(frame);
        self.stream = Some(stream);
        self
    }

    /// Takes frame number, picture size and composite time from `frame`.
    pub fn set_frame(&mut self, frame: &Frame) {
        self.frame = frame.number;
        self.width = frame.width;
        self.height = frame.height;
        self.clock.composite_ms = frame.composite_time.as_secs_f64() * 1e3;
    }
}

impl Default for DaemonStatus {
    /// The status of a daemon with no lights, no input and nothing shown
    /// yet (a preview server run without a daemon: the tests).
    fn default() -> Self {
        Self {
            version: env!("CARGO_PKG_VERSION"),
            frame: 0,
            width: 0,
            height: 0,
            clock: ClockStatus::default(),
            input: InputSummary { kind: "none", ..InputSummary::default() },
            cache: CacheSummary::default(),
            memory: MemoryUsage::default(),
            builds: BuildThreads::default(),
            view: ViewStatus::default(),
            warnings: Vec::new(),
            lights: Vec::new(),
            import: ImportStatus::default(),
            stream: None,
        }
    }
}

/// `/api/status` `stream`: the browser stream's counters since the server
/// started (docs/stream.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct StreamCounters {
    /// Streams open now.
    pub open: u64,
    /// Streams accepted since start.
    pub accepted: u64,
    /// Streams refused over the client limit.
    pub refused: u64,
    /// Buffer (and cleared) messages sent.
    pub buffer_messages: u64,
    /// Body-tile messages sent (fixture bodies, type 6).
    pub body_messages: u64,
    /// Body tiles sent in them.
    pub body_tiles: u64,
    /// Bodies messages encoded (one per snapshot step, shared by the clients making it).
    pub body_encodes: u64,
    /// k messages sent.
    pub frame_messages: u64,
    /// Picture messages sent.
    pub picture_messages: u64,
    /// Bytes sent over all streams.
    pub bytes_sent: u64,
    /// Frames a client skipped because it was still sending an older one.
    pub frames_skipped: u64,
    /// Clients dropped for a send that exceeded the stall limit.
    pub dropped_stalled: u64,
    /// Streams closed for a malformed or oversized client message.
    pub closed_bad_message: u64,
    /// Mode-switch messages received (`[0x10, mode]`).
    pub mode_switches: u64,
    /// Restarts of a stream by a mode switch (hello and everything again).
    pub mode_restarts: u64,
    /// Mode-switch messages not applied at once (a switch to the mode in
    /// force, or one within the minimum restart interval).
    pub switches_limited: u64,
    /// Buffers encoded (f16 + DEFLATE), over all clients.
    pub buffer_encodes: u64,
    /// Message bytes held by the server for all clients now.
    pub pending_bytes: u64,
    /// The largest message one client had pending at a time.
    pub max_pending_per_client: u64,
}

/// `/api/status` `import`: the patch's fixture types summed up (modelled,
/// partly and why, or not) and its warnings and notes, each said once
/// ([`footlight_mvr::check_report`]); the preview lists them under "import warnings".
#[derive(Clone, Debug, Default, Serialize)]
pub struct ImportStatus {
    /// One per GDTF fixture type, in the order the patch names them.
    pub types: Vec<footlight_mvr::TypeSummary>,
    /// Each warning once, `file:line: message (N fixtures, M cells)`.
    pub warnings: Vec<String>,
    /// Names read not quite as written (a `GDTFSpec` without `.gdtf`).
    pub notes: Vec<String>,
}

impl ImportStatus {
    /// The summary of a checked patch.
    pub fn of(checked: &footlight_mvr::Checked) -> Self {
        Self {
            types: checked.types.clone(),
            warnings: checked.warnings.iter().map(ToString::to_string).collect(),
            notes: checked.notes.iter().map(ToString::to_string).collect(),
        }
    }
}

/// How a light is named in logs and in the status.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct LightLabel {
    /// The fixture id as the patch (and the desk) numbers it.
    pub fixture: Option<u32>,
    /// Display name.
    pub name: String,
}

/// Where a light is patched and hung, as a desk shows it (the status's
/// per-light patch fields, `live::Show::light_patches`; docs/live.md).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct LightPatch {
    /// The fixture's own name: for a cell, its fixture's (the light's
    /// `name` is `"fixture / cell"`); else the light's name.
    pub fixture_name: Option<String>,
    /// 1-based number of the cell within its fixture, when the fixture is
    /// several lights (an MVR pixel bar's pixels); `None` for a one-light
    /// fixture. A fixture's cells are consecutive lights under one id.
    pub cell: Option<u32>,
    /// Patch universe of the start address; `None` when unpatched.
    pub universe: Option<u16>,
    /// Start address, 1-512; `None` when unpatched.
    pub address: Option<u16>,
    /// `universe.address` as desks write it (`"2.17"`); `None` when unpatched.
    pub dmx_address: Option<String>,
    /// Channels the fixture's mode uses from its start address.
    pub footprint: Option<u16>,
    /// The DMX mode's name (GDTF and library types); `None` for the built-in spot.
    pub mode: Option<String>,
    /// Where the fixture hangs, metres to the millimetre, stage axes (y up):
    /// the patch's `position`, an MVR fixture's origin (shared by its cells).
    pub position: Option<[f64; 3]>,
}

impl LightPatch {
    /// The patch data of one fixture instance.
    pub fn of(f: &footlight_fixture::Fixture) -> Self {
        let fixture_name = f.cell.as_ref().map_or_else(|| f.name.clone(), |c| c.fixture_name.clone());
        Self {
            fixture_name: Some(fixture_name),
            cell: f.cell.as_ref().map(|c| c.number),
            universe: f.dmx.map(|(u, _)| u),
            address: f.dmx.map(|(_, a)| a),
            dmx_address: f.dmx.map(|(u, a)| format!("{u}.{a}")),
            footprint: Some(f.footprint()),
            mode: f.mode_name().map(str::to_string),
            position: Some(f.position.to_array().map(|v| (f64::from(v) * 1000.0).round() / 1000.0)),
        }
    }
}

/// How far a light's published buffer has got: the stage the build
/// pipeline published ([`crate::render::build::LightBuild::next`]).
pub use crate::render::build::Stage;

/// A light's build state for the status page (issue 18: the status tells
/// the truth about moving lights).
#[derive(Clone, Debug, Serialize)]
pub struct LightReport {
    /// The stage of the buffer on screen.
    pub stage: Stage,
    /// A request is waiting, or the last one is younger than the settle time.
    pub moving: bool,
    /// Age of the oldest unserved request, ms (`None`: nothing waiting).
    pub pending_ms: Option<f64>,
    /// Direct stages published in the last second (Hz).
    pub direct_hz: f64,
    /// Direct stages published since start.
    pub direct_updates: u64,
    /// Time from the oldest unserved request to its direct stage on screen, ms (last one).
    pub first_stage_ms: Option<f64>,
    /// Time from the last request to the light's final stage, ms (last finished build).
    pub last_build_ms: Option<f64>,
    /// Why the light's last build failed (it panicked: a bug), while no
    /// later build of it has published; its last picture stays on screen.
    pub failed: Option<String>,
}

/// What the tracer holds against its memory budget
/// (`live::TracerSettings::memory`, `footlight run --memory`), in `/api/status` as `memory`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MemoryUsage {
    /// The budget.
    pub budget_bytes: u64,
    /// Everything below, summed.
    pub used_bytes: u64,
    /// The published buffers (and haze knot buffers) of the lights, and
    /// the state their builds in progress keep between stages (the Whitted
    /// term, the start and state of refinement: `LightBuild::bytes`,
    /// `Refinement::bytes`).
    pub buffers_bytes: u64,
    /// The lights' photon maps and irradiance caches (an estimate: photons
    /// and cache points with their kd-tree, twice their size).
    pub photon_maps_bytes: u64,
    /// The geometry caches (the current view's and those kept for others).
    pub caches_bytes: u64,
    /// Of those, held by the lit lights alone (never evicted).
    pub lit_bytes: u64,
    /// Dark lights evicted to stay within the budget (rebuilt when lit).
    pub evicted_lights: usize,
    /// Evictions so far.
    pub evictions: u64,
    /// Set when the lit lights alone need more than the budget: nothing
    /// more can go, the daemon keeps going over it (never an OOM kill by
    /// choice) and the status warns.
    pub over_budget: bool,
}
