//! The background tracer: rebuilds lights whose geometry changed while the
//! rest of the picture stays live (Vierjahn 2010, section 3.3 and fig. 1).
//! It only *schedules*: every buffer is built by [`LightBuild`].
//!
//! Each light has a slot holding its newest *request* (coalesced: a pan
//! sweep replaces the pending request instead of queueing every step), the
//! build in progress between stages, and its latest *published* buffer.
//!
//! # Scheduling (fair and deadline-driven)
//! 1. **Direct stages first.** While any light has a pending request, the
//!    worker builds a direct stage ([`LightBuild::direct`], footprint-culled)
//!    for the light that has waited longest, its wait weighted by the share
//!    of the picture it changes (1 + fraction of tiles its beam covered last
//!    time, so the weight is in [1, 2]). A light's wait starts at its
//!    *oldest* unserved request and coalescing never resets it, so no light
//!    starves: with N lights moving every frame, each one is served within
//!    2N direct stages (unit-tested on [`schedule`]).
//! 2. **Later stages only on still lights.** Whitted + anti-aliasing,
//!    photons and refinement start on a light whose last request is at
//!    least [`TracerSettings::settle`] old (150 ms by default): no work is
//!    spent on a position already stale. All settled lights get their
//!    Whitted stage before any gets photons, and photons before any
//!    refinement pass; within a stage, the brightest light goes first.
//!    Only [`TracerSettings::max_refining`] lights refine; a light whose
//!    photon stage starts with that many at least as bright refining
//!    does its exact estimate there and is ready when it ends.
//! 3. **Lit first, dark in idle time.** A light whose k_i is 0 (priority
//!    0: dimmer, shutter or colour at zero) is scheduled only when no lit
//!    light has a direct or later stage due: every stage of every lit
//!    light goes first, and a dark light that lights (priority above 0 in
//!    the next frame) joins the lit ones at once. Rules 1 and 2 hold among
//!    the lit lights and again among the dark ones.
//! 4. **A light in motion is shaded at moving quality**
//!    ([`DirectQuality::Moving`]: one pixel per 2×2 block) when its
//!    previous request was less than `settle` earlier; the settled Whitted
//!    stage replaces it.
//! 5. **A long queue is rushed.** While more than
//!    [`TracerSettings::rush_backlog`] lights of a class (lit, or dark)
//!    wait for their direct stage (a look that lights a festival rig at
//!    once: 3,684 lights), their direct stages are built at moving quality
//!    too (a quarter of the pixels shaded), and each light's Whitted stage
//!    replaces it as in rule 4: every lit light is on screen about four
//!    times sooner.
//! 6. **A photon stage yields to a moved lit light.** A lit light's new
//!    request sets a flag that stops the photon stage in progress (its
//!    [`Cancel`] fires, [`Cancel::preempted`] says the build is still
//!    good): the build waits for its turn again and the moved light's
//!    direct stage runs first, instead of after up to a second of photon
//!    tracing. Each build yields once ([`LightBuild::yielded`]), so lights
//!    that move again and again cannot starve it
//!    ([`Tracer::photon_yields`] counts them).
//! 7. **Every core while the clock is quiet.** The build pool leaves the
//!    frame clock a core ([`TracerSettings::threads`]). A stage that starts
//!    while the clock is quiet (no tick longer than
//!    [`TracerSettings::quiet_tick`] in the last
//!    [`TracerSettings::quiet_hold`], as [`Tracer::clock_tick`] reports)
//!    runs on a second pool with [`TracerSettings::quiet_threads`] more: a
//!    look that holds still builds on every core, and while the desk plays
//!    (a broad cue, a pixel chase: 25-60 ms composites on the festival show)
//!    the composite has its core back when the stage in progress ends.
//!    The choice is per stage (a photon stage of a festival leader takes
//!    about a second), so a cue waits at most one stage for its core.
//!
//! A newer request for a light cancels its build in progress (the
//! [`Cancel`] token compares request ids) at the next stage boundary; a
//! geometry state found in the [`GeometryCache`] is published at once.
//! Builds run on the tracer's own rayon pools, so the frame clock's composite
//! never queues behind them; the frame clock only reads published buffers
//! (an `Arc` swap under a short lock).
//!
//! # Cells of one fixture (issue 14)
//! The lights of one fixture's pixel cells ([`Tracer::set_groups`]: the
//! daemon groups consecutive lights with the same fixture id) that are due
//! for the same stage at once (start-up, a view change, a moved bar) get
//! their direct stage, then their Whitted stage, in one pass over the union
//! of their footprints ([`crate::render::build::together`]; scheduling, request ids,
//! cancellation and publishing per cell as above: `src/live/tracer/cells.rs`).
//! [`Tracer::batched_builds`] counts the passes; [`TracerSettings::batch_cells`]
//! turns it off. Cells with the same beam and aim share one photon stage
//! and its refinement (issue 38): one traces photons, the others follow it
//! with their own Whitted term plus its indirect term
//! ([`TracerSettings::share_indirect`], [`Tracer::shared_indirect_cells`]).
//!
//! # Haze (issue 15)
//! With a medium ([`Tracer::with_haze`]) each light keeps its beam
//! ([`LightBuild::haze_beam`]): a coarse beam ([`HazeQuality::COARSE`]) in
//! the same job as each direct stage, so a moved beam shows with its first
//! picture, and a refined beam ([`HazeQuality::REFINED`]) with the Whitted
//! stage of a settled light. Every publish resolves the surface buffer with
//! the kept beam at the density knots ½ and 1
//! ([`crate::render::media::live`], [`Published::hazy`]), published
//! together with the surface buffer (the knot 0). A hazer change is a
//! weight in the frame clock: no light is rebuilt ([`Tracer::builds`] and
//! [`Tracer::haze_stages`] count the work). No beam is kept between
//! stages: a beam is resolved into the knots by the publish right after it
//! is made, and a later stage without a new beam (photons, refinement)
//! updates the knots from the previous ones
//! ([`crate::render::media::update_knots`]). The geometry cache keeps a finished light's knot buffers with its buffer,
//! keyed by the geometry and the haze ([`GeometryCache::get_in`]), so a
//! position preset recalled in haze, and a view switched back to (its
//! geometry cache comes back with it), are published with their beams at
//! once, without a build. Buffers kept by the view cache
//! ([`Kept`]) carry no knots: in haze only the geometry cache restores.
//!
//! # View changes (issue 16)
//! [`Tracer::set_view`] swaps the camera-dependent [`View`]: every build in
//! progress is cancelled (its request id is superseded), the geometry cache
//! (view-dependent buffers) is put aside with the old view (and the new
//! view's own comes back if it was shown before), and every light is rebuilt for the
//! new view, brightest first, through the same stages and rules as above.
//! A light's photon maps do not depend on the camera: the tracer keeps the
//! latest maps of each light with the geometry they were traced for, and a
//! build of that same geometry starts from them ([`LightBuild::with_maps`]),
//! so a camera move re-does only the per-vertex estimates
//! ([`Tracer::photon_traces`] counts real photon traces). Buffers that a
//! cached view kept ([`super::views`]) are published at once for every light
//! that has not moved since. While the camera moves the tracer is paused
//! ([`Tracer::set_paused`]): the frame clock shows the cheap moving preview
//! and no work is spent on a view about to be replaced.
//!
//! # Memory (issue 38)
//! After every job the tracer counts what it holds ([`MemoryUsage`]: the
//! published buffers, the state builds keep between stages, photon maps,
//! the geometry caches) against its budget (`run --memory`). Past it, dark
//! lights' buffers and maps go first (least recently lit first), then the
//! geometry caches. When the lit lights alone are over it, no dark light is
//! built and the stages that add memory (photons and refinement) wait
//! ([`within_budget`]); direct and Whitted stages, which replace a light's
//! tile-sparse buffer, still run. The Whitted term a build keeps for its
//! photon stage is tile-sparse ([`LightBuild::bytes`]).

mod cells;

use super::cache::{Finished, GeometryCache, Knots};
use crate::Light;
use crate::output::{LightReport, MemoryUsage, Stage};
use crate::render::buffer::{HazeBuffer, SharedLayer};
use crate::render::build::{BuildError, BuildSettings, Cancel, LightBuild, NextStage};
use crate::render::footprint::DirectQuality;
use crate::render::media::resolve::surface_medium;
use crate::render::media::{HazeQuality, HazeView, Medium, knot_buffers, update_knots};
use crate::render::photon::PhotonMaps;
use crate::render::{LightBuffer, View};
use crate::scene::Scene;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// Tracer settings; [`Default`] holds every default in one place.
#[derive(Clone, Copy, Debug)]
pub struct TracerSettings {
    /// Threads of the build pool (each stage is data-parallel): by default
    /// one fewer than the machine's cores, at least 1
    /// ([`default_build_threads`]), so the frame clock keeps a core (issue 38
    /// item 4); `footlight run --build-threads N`.
    pub threads: usize,
    /// Build threads added while the frame clock is quiet: a stage that
    /// starts when no frame of the last [`TracerSettings::quiet_hold`] took
    /// more than [`TracerSettings::quiet_tick`] runs on `threads` + this many
    /// threads, any other on `threads` alone (by default the cores the clock
    /// keeps: [`quiet_threads_for`]). A look that holds still builds on
    /// every core; while the desk plays (a cue, a pixel chase) the composite
    /// has its core back within one stage. `footlight run --quiet-build-threads N`.
    pub quiet_threads: usize,
    /// A frame tick longer than this makes the clock busy (module doc, rule 7).
    pub quiet_tick: Duration,
    /// The clock is quiet once no busy tick came for this long.
    pub quiet_hold: Duration,
    /// What each light build does (AA threshold, photons, refinement passes).
    pub build: BuildSettings,
    /// How long a light must be still before its later stages start.
    pub settle: Duration,
    /// Lights refined at the same time (each holds per-vertex SPPM state).
    pub max_refining: usize,
    /// Geometry cache budget in bytes (the current view's; the caches kept
    /// for views left behind share another budget of the same size).
    pub cache_bytes: usize,
    /// Photon maps kept after a light's build ended, in bytes: they serve a
    /// camera move or a return to the same geometry (no new photon trace)
    /// and are not needed for the picture, so past this the maps of dark
    /// lights go first (least recently lit first), then those of the
    /// dimmest lit lights (issue 38: the festival show's ~228 photon
    /// leaders kept ~1 GB of maps).
    pub kept_maps_bytes: u64,
    /// The first indirect estimate of a build is exact every this many
    /// pixels and interpolated in between (0 or 1: exact everywhere); the
    /// first refinement pass finishes it ([`LightBuild::with_coarse_indirect`]).
    pub coarse_indirect: u32,
    /// A moved light's refinement blends its first SPPM pass with the
    /// coarse estimate instead of finishing the exact lookups first
    /// ([`LightBuild::with_refinement_from_coarse`]; issue 13).
    pub refine_from_coarse: bool,
    /// Cells of one fixture (lights grouped by [`Tracer::set_groups`]) that
    /// are due at once get their direct and Whitted stages in one pass
    /// ([`crate::render::build::together`]); false: every light alone (the bench's
    /// comparison).
    pub batch_cells: bool,
    /// While more than this many lights of one class (lit, or dark) wait
    /// for their direct stage (a look that lights a festival rig at once),
    /// their direct stages are built at moving quality
    /// ([`DirectQuality::Moving`], a quarter of the pixels) and each one's
    /// Whitted stage replaces it: every lit light is on screen sooner.
    pub rush_backlog: usize,
    /// Cells of one fixture with the same beam and aim that wait for their
    /// photon stage together share one: the cell nearest their centre
    /// traces photons and refines, the others follow it with their own
    /// Whitted term plus its indirect term
    /// ([`crate::render::build::shared_indirect`]); false: every cell
    /// traces its own photons.
    pub share_indirect: bool,
    /// Memory budget in bytes for the lights' buffers, photon maps and the
    /// geometry caches ([`MemoryUsage`]): past it, dark lights' buffers and
    /// maps go first (least recently lit first), then cache entries; by
    /// default half the machine's memory ([`crate::memory::default_budget`];
    /// `footlight run --memory`).
    pub memory: u64,
}

impl Default for TracerSettings {
    fn default() -> Self {
        Self {
            threads: default_build_threads(),
            quiet_threads: quiet_threads_for(default_build_threads()),
            // Half a 60 Hz frame: a static look's ticks take 2-3 ms on the
            // festival show, a broad cue's or a pixel chase's 25-60 ms.
            quiet_tick: Duration::from_millis(8),
            quiet_hold: Duration::from_secs(1),
            // Compact buffers: the daemon holds one per light of the rig.
            build: BuildSettings { compact: true, ..BuildSettings::default() },
            settle: Duration::from_millis(150),
            max_refining: 4,
            cache_bytes: 512 << 20,
            kept_maps_bytes: 512 << 20,
            coarse_indirect: 3,
            refine_from_coarse: true,
            batch_cells: true,
            rush_backlog: 64,
            share_indirect: true,
            memory: crate::memory::default_budget(),
        }
    }
}

/// The build pool's default size: the machine's cores less one for the
/// frame clock, at least 1 (on 2 cores: 1 build thread).
pub fn default_build_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get().saturating_sub(1).max(1))
}

/// Build threads added while the frame clock is quiet
/// ([`TracerSettings::quiet_threads`]) to a pool of `threads`: the cores it
/// leaves to the clock (on 2 cores with the default 1 build thread: 1; on
/// 1 core: 0).
pub fn quiet_threads_for(threads: usize) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    cores.saturating_sub(threads)
}

/// What the frame clock sees of a light.
#[derive(Clone, Debug)]
pub struct Published {
    /// The light's current unit-intensity buffer.
    pub buffer: Arc<LightBuffer>,
    /// Bumped on every publish (the compositor recomposes on change).
    pub generation: u64,
    /// How far the build got.
    pub stage: Stage,
    /// In haze: the light's buffer at the density knots ½ and 1
    /// ([`crate::render::media::knot_buffers`]; `buffer` is the knot 0),
    /// published with `buffer` and under its `generation`. Empty without haze.
    pub hazy: [Arc<LightBuffer>; 2],
    /// The indirect term this cell shares with its photon leader's group
    /// (issue 38; without haze only): the light shows `buffer` (then its
    /// own Whitted term) plus this layer, which the frame composites once
    /// for the whole group ([`super::clock::FrameEntries`]).
    pub shared: Option<SharedLayer>,
}

impl Published {
    /// What the light shows, dense row-major: its buffer plus its shared layer.
    pub fn to_dense(&self) -> Vec<glam::Vec3> {
        match &self.shared {
            Some(layer) => layer.plus(&self.buffer),
            None => self.buffer.to_dense(),
        }
    }
}

/// What a light showed in a view: kept by the view cache
/// ([`super::views::ViewCache`]) and handed back to [`Tracer::set_view`].
#[derive(Clone, Debug)]
pub struct Kept {
    /// The geometry the buffer was built for.
    pub light: Light,
    /// The buffer.
    pub buffer: Arc<LightBuffer>,
    /// The group's indirect layer shown with it ([`Published::shared`]).
    pub shared: Option<SharedLayer>,
    /// Its stage.
    pub stage: Stage,
}

struct Request {
    id: u64,
    light: Light,
    at: Instant,
}

/// A light's scheduling state (under its slot's lock).
#[derive(Default)]
struct SlotState {
    /// The newest unserved position.
    pending: Option<Request>,
    /// When the oldest unserved request arrived (coalescing keeps it).
    waiting_since: Option<Instant>,
    /// When the newest request arrived (settle rule).
    last_move: Option<Instant>,
    /// The request before the newest (moving-quality rule).
    previous_move: Option<Instant>,
    /// A build past its direct stage, waiting for its later stages
    /// (Whitted, photons, refinement: [`LightBuild::next_stage`]).
    build: Option<(u64, LightBuild, Instant)>,
    /// Brightness priority (luminance of k_i).
    priority: f32,
    /// The newest requested geometry (what a view change rebuilds).
    current: Option<Light>,
    /// The geometry of the published buffer.
    shown: Option<Light>,
    /// The light's latest photon maps and the geometry they were traced
    /// for: view-independent, reused by a build of the same geometry.
    maps: Option<(Light, Arc<PhotonMaps>)>,
    /// Share of the picture the light changes, in [1, 2].
    weight: f32,
    /// In haze: a beam just made and the request it was built for, taken
    /// by the publish that follows it.
    beam: Option<(u64, HazeBuffer)>,
    /// In haze: the surface buffer and knot buffers last published and
    /// their request (a later stage updates these knots; a finished light
    /// leaves them in the geometry cache).
    /// The medium their surfaces were dimmed with
    /// ([`crate::render::media::resolve::surface_medium`]), which a later
    /// stage's update keeps.
    knots: Option<(u64, Arc<LightBuffer>, Knots, Medium)>,
    /// Direct-stage publish times in the last second.
    direct_times: VecDeque<Instant>,
    direct_total: u64,
    first_stage: Option<Duration>,
    last_build: Option<Duration>,
    /// The last build panicked (its message); cleared by the next publish.
    failed: Option<String>,
    /// When the light was last lit (priority above 0): the eviction order.
    last_lit: Option<Instant>,
    /// Its buffers and maps were dropped for the memory budget while dark;
    /// it is rebuilt as soon as it lights.
    evicted: bool,
    /// Publish order ([`Tracer::publish_order`]): the first and the last
    /// publish of the light, numbered across all lights.
    first_publish: Option<u64>,
    last_publish: Option<u64>,
    /// Following another cell of its fixture through the photon and
    /// refinement stages ([`cells::Follow`]).
    follow: Option<cells::Follow>,
    /// Leading cells of its fixture through those stages ([`cells::Lead`]).
    lead: Option<cells::Lead>,
}

struct Slot {
    /// Id of the newest request: the [`Cancel`] token of its builds.
    latest: Arc<AtomicU64>,
    /// Test hook ([`Tracer::inject_build_panic`]): the light's next build panics.
    panic_next: AtomicBool,
    state: Mutex<SlotState>,
    published: Mutex<Published>,
}

struct Shared {
    scene: Arc<Scene>,
    /// The current view (swapped by [`Tracer::set_view`]); a job takes its
    /// `Arc` once and keeps it, a superseded job's publish is refused.
    view: Mutex<Arc<View>>,
    /// Bumped by every [`Tracer::set_view`].
    view_generation: AtomicU64,
    /// While set, the worker runs no job (the camera is moving).
    paused: AtomicBool,
    /// Photon traces run (a reused map is not counted).
    photon_traces: AtomicU64,
    settings: TracerSettings,
    slots: Vec<Slot>,
    wake: (Mutex<u64>, Condvar),
    stop: Arc<AtomicBool>,
    next_id: AtomicU64,
    cache: Mutex<GeometryCache>,
    /// Geometry caches of views left behind, with the view they belong to
    /// (a `Weak` keeps the allocation, so a new view never matches an old
    /// one's address); given back when [`Tracer::set_view`] returns to it.
    kept_caches: Mutex<Vec<(std::sync::Weak<View>, GeometryCache)>>,
    pool: rayon::ThreadPool,
    /// `threads` + `quiet_threads` build threads, for stages that start
    /// while the clock is quiet; `None` without quiet threads.
    quiet_pool: Option<rayon::ThreadPool>,
    /// The clock's last busy tick (`Tracer::clock_tick`), as nanoseconds
    /// after `epoch`; 0: none yet.
    busy_at: AtomicU64,
    /// The origin of `busy_at`.
    epoch: Instant,
    /// Stages run on `quiet_pool`.
    quiet_stages: AtomicU64,
    /// The haze at 100 % density, if the patch has one.
    haze: Option<Medium>,
    /// The haze geometry of the current view (rebuilt when the view changes).
    haze_view: Mutex<Option<(Arc<View>, Arc<HazeView>)>>,
    /// Light builds started (direct stages run).
    builds: AtomicU64,
    /// Haze stages run (coarse and refined beams).
    haze_stages: AtomicU64,
    /// Cells of one fixture built together ([`cells`]).
    cells: cells::Cells,
    /// Lights' names for log lines ([`Tracer::set_names`]; else `light i`).
    names: Mutex<Vec<String>>,
    /// Why the worker thread ended while the tracer was not stopped (a
    /// panic outside any build: a bug); `None` while it runs.
    died: Mutex<Option<String>>,
    /// Worker restarts after a panic outside any build, and the last panic.
    restarts: AtomicU64,
    last_panic: Mutex<Option<String>>,
    /// Test hook ([`Tracer::inject_worker_panic`]): the worker loop panics.
    panic_worker: AtomicBool,
    /// The memory budget (changed by [`Tracer::set_memory_budget`]).
    memory_budget: AtomicU64,
    /// The last [`MemoryUsage`] worked out (after each job).
    memory: Mutex<MemoryUsage>,
    /// Evictions so far.
    evictions: AtomicU64,
    /// Publishes so far, all lights (the publish order).
    publishes: AtomicU64,
    /// Set by a lit light's new request: a photon stage in progress yields
    /// to its direct stage (once per build: [`LightBuild::yielded`]).
    urgent: Arc<AtomicBool>,
    /// Photon stages that yielded so far.
    yields: AtomicU64,
}

/// Background builder of per-light buffers.
pub struct Tracer {
    shared: Arc<Shared>,
    worker: Option<std::thread::JoinHandle<()>>,
}

/// A light's scheduling facts, as [`schedule`] sees them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SlotView {
    /// The oldest unserved request's time, if a request waits.
    pub waiting_since: Option<Instant>,
    /// Share of the picture the light changes, in [1, 2].
    pub weight: f32,
    /// Brightness priority; 0: dark (k_i = 0), built only when no lit
    /// light has any work left.
    pub priority: f32,
    /// Still for at least the settle time.
    pub settled: bool,
    /// The next later stage it needs: 0 Whitted, 1 photons, 2 refinement.
    pub later: Option<u8>,
}

/// The next job of the tracer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Job {
    /// The direct stage of this light.
    Direct(usize),
    /// The next later stage of this (settled) light.
    Later(usize),
}

/// The scheduling policy (module doc): pure, so its fairness is tested
/// without threads or clocks.
pub fn schedule(slots: &[SlotView], now: Instant) -> Option<Job> {
    // Lit first: every stage of the lit lights, then the dark ones (idle time).
    schedule_among(slots, now, true).or_else(|| schedule_among(slots, now, false))
}

/// [`schedule`] over the lit (`priority > 0`) or the dark lights only.
fn schedule_among(slots: &[SlotView], now: Instant, lit: bool) -> Option<Job> {
    let mine = |s: &&SlotView| (s.priority > 0.0) == lit;
    let waited =
        |s: &SlotView| s.waiting_since.map(|t| now.saturating_duration_since(t).as_secs_f64() * f64::from(s.weight));
    let direct = slots
        .iter()
        .enumerate()
        .filter(|(_, s)| mine(s))
        .filter_map(|(i, s)| waited(s).map(|w| (i, w)))
        // Longest weighted wait; ties go to the lower index.
        .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)));
    if let Some((i, _)) = direct {
        return Some(Job::Direct(i));
    }
    slots
        .iter()
        .enumerate()
        .filter(|(_, s)| mine(s) && s.settled && s.waiting_since.is_none())
        .filter_map(|(i, s)| s.later.map(|stage| (i, stage, s.priority)))
        .min_by(|a, b| a.1.cmp(&b.1).then(b.2.total_cmp(&a.2)).then(a.0.cmp(&b.0)))
        .map(|(i, _, _)| Job::Later(i))
}

/// The views a tracer over its memory budget schedules from: the photon
/// and refinement stages (`later` 1 and 2), which add a dense indirect
/// buffer, photon maps and per-vertex state per light (about 12 MB each at
/// 800×500 on the festival show), are withheld; direct and Whitted stages,
/// which replace a light's tile-sparse buffer, still run, so moved lights
/// follow and every lit light gets its whole direct term. They start again
/// once the usage is back within the budget.
pub fn within_budget(mut views: Vec<SlotView>) -> Vec<SlotView> {
    for v in &mut views {
        if v.later.is_some_and(|stage| stage >= 1) {
            v.later = None;
        }
    }
    views
}

impl Tracer {
    /// Starts the worker for `lights` lights over `view`.
    pub fn new(scene: Arc<Scene>, view: Arc<View>, lights: usize, settings: TracerSettings) -> Self {
        Self::with_haze(scene, view, lights, settings, None)
    }

    /// As [`Tracer::new`], in `haze` (at 100 % density; `None`: clear air).
    pub fn with_haze(
        scene: Arc<Scene>,
        view: Arc<View>,
        lights: usize,
        settings: TracerSettings,
        haze: Option<Medium>,
    ) -> Self {
        let empty = Arc::new(LightBuffer::empty(view.width(), view.height()));
        let slots = (0..lights)
            .map(|_| Slot {
                latest: Arc::new(AtomicU64::new(0)),
                panic_next: AtomicBool::new(false),
                state: Mutex::new(SlotState { weight: 1.0, ..SlotState::default() }),
                published: Mutex::new(Published {
                    buffer: empty.clone(),
                    generation: 0,
                    stage: Stage::Queued,
                    hazy: [empty.clone(), empty.clone()],
                    shared: None,
                }),
            })
            .collect();
        let pool = build_pool(settings.threads.max(1), "footlight-build");
        let quiet_pool = (settings.quiet_threads > 0)
            .then(|| build_pool(settings.threads.max(1) + settings.quiet_threads, "footlight-quiet"));
        let shared = Arc::new(Shared {
            scene,
            view: Mutex::new(view),
            view_generation: AtomicU64::new(0),
            paused: AtomicBool::new(false),
            photon_traces: AtomicU64::new(0),
            settings,
            slots,
            wake: (Mutex::new(0), Condvar::new()),
            stop: Arc::new(AtomicBool::new(false)),
            next_id: AtomicU64::new(1),
            cache: Mutex::new(GeometryCache::new(settings.cache_bytes)),
            kept_caches: Mutex::new(Vec::new()),
            pool,
            quiet_pool,
            busy_at: AtomicU64::new(0),
            epoch: Instant::now(),
            quiet_stages: AtomicU64::new(0),
            haze: haze.filter(|m| !m.is_clear()),
            haze_view: Mutex::new(None),
            builds: AtomicU64::new(0),
            haze_stages: AtomicU64::new(0),
            cells: cells::Cells::new(lights),
            names: Mutex::new(Vec::new()),
            died: Mutex::new(None),
            restarts: AtomicU64::new(0),
            last_panic: Mutex::new(None),
            panic_worker: AtomicBool::new(false),
            memory_budget: AtomicU64::new(settings.memory),
            memory: Mutex::new(MemoryUsage { budget_bytes: settings.memory, ..MemoryUsage::default() }),
            evictions: AtomicU64::new(0),
            publishes: AtomicU64::new(0),
            urgent: Arc::new(AtomicBool::new(false)),
            yields: AtomicU64::new(0),
        });
        let worker = {
            let shared = shared.clone();
            std::thread::Builder::new()
                .name("footlight-tracer".into())
                .spawn(move || supervised_worker(&shared))
                .expect("spawn tracer worker")
        };
        Self { shared, worker: Some(worker) }
    }

    /// Number of light slots.
    pub fn len(&self) -> usize {
        self.shared.slots.len()
    }

    /// True when there are no lights.
    pub fn is_empty(&self) -> bool {
        self.shared.slots.is_empty()
    }

    /// The view the lights are built for now.
    pub fn view(&self) -> Arc<View> {
        self.shared.view()
    }

    /// Number of [`Tracer::set_view`] calls so far.
    pub fn view_generation(&self) -> u64 {
        self.shared.view_generation.load(Ordering::SeqCst)
    }

    /// The frame clock reports each tick's duration: one longer than
    /// [`TracerSettings::quiet_tick`] makes the clock busy, and stages that
    /// start within [`TracerSettings::quiet_hold`] of it leave the clock its
    /// core (module doc, rule 7).
    pub fn clock_tick(&self, took: Duration) {
        if took > self.shared.settings.quiet_tick {
            let at = self.shared.epoch.elapsed().as_nanos().clamp(1, u128::from(u64::MAX)) as u64;
            self.shared.busy_at.store(at, Ordering::Relaxed);
        }
    }

    /// Stages run with the quiet threads added ([`TracerSettings::quiet_threads`]).
    pub fn quiet_stages(&self) -> u64 {
        self.shared.quiet_stages.load(Ordering::Relaxed)
    }

    /// The build threads for `/api/status`.
    pub fn build_threads(&self) -> crate::output::BuildThreads {
        let s = &self.shared;
        crate::output::BuildThreads {
            threads: s.pool.current_num_threads(),
            quiet_threads: s.quiet_pool.as_ref().map_or(0, |p| p.current_num_threads() - s.pool.current_num_threads()),
            clock_quiet: s.quiet_pool.is_some() && s.clock_quiet_now(),
            quiet_stages: self.quiet_stages(),
        }
    }

    /// Photon traces run since start. A light's maps are traced once per
    /// geometry: a camera move ([`Tracer::set_view`]) does not add to it.
    pub fn photon_traces(&self) -> u64 {
        self.shared.photon_traces.load(Ordering::SeqCst)
    }

    /// True when light `index` keeps photon maps (for a camera move or a
    /// return to the same geometry; [`TracerSettings::kept_maps_bytes`]).
    pub fn keeps_maps(&self, index: usize) -> bool {
        self.shared.slots.get(index).is_some_and(|s| s.state.lock().expect("slot lock").maps.is_some())
    }

    /// True when the lights are built in haze ([`Tracer::with_haze`]).
    pub fn has_haze(&self) -> bool {
        self.shared.haze.is_some()
    }

    /// The haze at 100 % (the patch's `[haze]`), if the lights are built in it.
    pub fn medium(&self) -> Option<crate::render::media::Medium> {
        self.shared.haze
    }

    /// Light builds started since start (one per direct stage run).
    pub fn builds(&self) -> u64 {
        self.shared.builds.load(Ordering::SeqCst)
    }

    /// Haze stages run since start (coarse and refined beams).
    pub fn haze_stages(&self) -> u64 {
        self.shared.haze_stages.load(Ordering::SeqCst)
    }

    /// Groups the lights into fixtures: `fixture[i]` is light i's fixture
    /// id ([`super::clock::LightLabel::fixture`]); consecutive lights with
    /// the same id are the cells of one fixture (the MVR import emits a
    /// fixture's cells one after another under its id) and are built
    /// together when due at once ([`TracerSettings::batch_cells`]). `None`,
    /// or a light not listed: built alone.
    pub fn set_groups(&self, fixture: &[Option<u32>]) {
        self.shared.cells.set_groups(fixture);
    }

    /// The lights that can show a shared indirect layer
    /// ([`Published::shared`]), ascending: the cells of a fixture with two
    /// or more, when cells share photon stages in clear air (else none).
    /// The frame gives each a place for the layer it is the first to show
    /// ([`super::clock::FrameEntries`]); fixed once the groups are set.
    pub fn shared_places(&self) -> Arc<Vec<usize>> {
        if self.shared.settings.share_indirect && self.shared.haze.is_none() {
            self.shared.cells.places()
        } else {
            Arc::new(Vec::new())
        }
    }

    /// Names the lights for log lines (`names[i]` is light i's, e.g. the
    /// status's `name`); a light not listed is `light i`.
    pub fn set_names(&self, names: Vec<String>) {
        *self.shared.names.lock().expect("names lock") = names;
    }

    /// Why the worker thread died for good (panics outside any single
    /// build, a bug, more often than it is restarted), `None` while it runs.
    /// No light is rebuilt after it; the daemon stops with this error.
    pub fn worker_error(&self) -> Option<String> {
        self.shared.died.lock().unwrap_or_else(std::sync::PoisonError::into_inner).clone()
    }

    /// Times the worker was restarted after a panic outside any build, and
    /// that panic's message (the status shows both).
    pub fn worker_restarts(&self) -> (u64, Option<String>) {
        let last = self.shared.last_panic.lock().unwrap_or_else(std::sync::PoisonError::into_inner).clone();
        (self.shared.restarts.load(Ordering::SeqCst), last)
    }

    /// Lights whose last build failed, with the error, in light order.
    pub fn failed(&self) -> Vec<(usize, String)> {
        self.shared
            .slots
            .iter()
            .enumerate()
            .filter_map(|(i, s)| s.state.lock().expect("slot lock").failed.clone().map(|e| (i, e)))
            .collect()
    }

    /// What the tracer holds against its memory budget, worked out now
    /// (evicting past the budget first, as the worker does after each job).
    pub fn memory(&self) -> MemoryUsage {
        self.shared.enforce_budget()
    }

    /// Changes the memory budget (bytes); the next job (or
    /// [`Tracer::memory`]) evicts down to it.
    pub fn set_memory_budget(&self, bytes: u64) {
        self.shared.memory_budget.store(bytes, Ordering::SeqCst);
        self.shared.notify();
    }

    /// Light `index`'s first and last publish, numbered across all lights
    /// in the order they happened (`None`: never published): which builds
    /// finished before which started, without a clock.
    pub fn publish_order(&self, index: usize) -> (Option<u64>, Option<u64>) {
        self.shared.slots.get(index).map_or((None, None), |s| {
            let st = s.state.lock().expect("slot lock");
            (st.first_publish, st.last_publish)
        })
    }

    /// True when light `index`'s buffers were evicted for the memory budget.
    pub fn evicted(&self, index: usize) -> bool {
        self.shared.slots.get(index).is_some_and(|s| s.state.lock().expect("slot lock").evicted)
    }

    /// Test hook: the next build stage of light `index` panics inside the
    /// build pool, as a bug in a stage would.
    #[doc(hidden)]
    pub fn inject_build_panic(&self, index: usize) {
        if let Some(slot) = self.shared.slots.get(index) {
            slot.panic_next.store(true, Ordering::SeqCst);
        }
    }

    /// Test hook: the worker loop itself panics (outside any build).
    #[doc(hidden)]
    pub fn inject_worker_panic(&self) {
        self.shared.panic_worker.store(true, Ordering::SeqCst);
        self.shared.notify();
    }

    /// Passes that built several cells of one fixture together (a direct
    /// or a Whitted stage each); a light built alone does not count.
    pub fn batched_builds(&self) -> u64 {
        self.shared.cells.passes()
    }

    /// Light stages built in those passes (the cells of every batch, summed).
    pub fn batched_lights(&self) -> u64 {
        self.shared.cells.lights()
    }

    /// Photon stages that yielded to a lit light's new request so far
    /// (scheduling rule 6).
    pub fn photon_yields(&self) -> u64 {
        self.shared.yields.load(Ordering::SeqCst)
    }

    /// Cells that followed another cell's photon stage (shared indirect
    /// term, [`TracerSettings::share_indirect`]) instead of their own.
    pub fn shared_indirect_cells(&self) -> u64 {
        self.shared.cells.followers()
    }

    /// Pauses (true) or resumes the worker. A stage in progress finishes;
    /// requests keep coalescing while paused and are served on resume.
    pub fn set_paused(&self, paused: bool) {
        self.shared.paused.store(paused, Ordering::SeqCst);
        self.shared.notify();
    }

    /// True when some light has nothing on screen for the current view yet
    /// (the frame clock keeps the moving preview up until then).
    pub fn any_queued(&self) -> bool {
        self.shared.slots.iter().any(|s| {
            // A dark light evicted for the memory budget adds nothing to the picture.
            !s.state.lock().expect("slot lock").evicted
                && s.published.lock().expect("published lock").stage == Stage::Queued
        })
    }

    /// What each light shows now: the geometry of its published buffer, the
    /// buffer and its stage (`None`: nothing built). A view cache keeps this
    /// when the camera leaves the view.
    pub fn snapshot(&self) -> Vec<Option<Kept>> {
        self.shared
            .slots
            .iter()
            .map(|slot| {
                let shown = slot.state.lock().expect("slot lock").shown.clone()?;
                let p = slot.published.lock().expect("published lock");
                (p.stage != Stage::Queued).then(|| Kept {
                    light: shown,
                    buffer: p.buffer.clone(),
                    shared: p.shared.clone(),
                    stage: p.stage,
                })
            })
            .collect()
    }

    /// Switches to `view` (same size as the old one). Builds in progress are
    /// cancelled; the geometry cache of the old view is kept with it (and
    /// the new view's comes back if it was shown before: a light finished
    /// there for its current geometry is published at once). A light whose `kept` buffer (from a cached view) was
    /// built for its current geometry is published at once (a view-cache
    /// hit; a kept buffer that had not reached [`Stage::Ready`] shows while
    /// its build runs again); every other light is rebuilt for the new view
    /// from its direct stage, brightest first, reusing its photon maps.
    /// Returns what the old view showed ([`Tracer::snapshot`]) and how many
    /// lights were restored.
    pub fn set_view(&self, view: Arc<View>, kept: &[Option<Kept>]) -> (Vec<Option<Kept>>, usize) {
        let s = &self.shared;
        let old = self.snapshot();
        let old_view = std::mem::replace(&mut *s.view.lock().expect("view lock"), view.clone());
        s.view_generation.fetch_add(1, Ordering::SeqCst);
        // Supersede every build of the old view first: none of them may
        // publish or fill a cache from here on.
        for slot in &s.slots {
            slot.latest.store(s.next_id.fetch_add(1, Ordering::Relaxed), Ordering::SeqCst);
        }
        if !Arc::ptr_eq(&old_view, &view) {
            let mut cache = s.cache.lock().expect("cache lock");
            // The old view's finished buffers stay with it; the new view gets
            // its own back if it was here before (issue 16).
            let mut stash = s.kept_caches.lock().expect("kept caches lock");
            let back = stash.iter().position(|(w, _)| std::ptr::eq(w.as_ptr(), Arc::as_ptr(&view)));
            let mine = back.map_or_else(|| GeometryCache::new(s.settings.cache_bytes), |i| stash.remove(i).1);
            let left = std::mem::replace(&mut *cache, mine);
            if !left.is_empty() {
                stash.push((Arc::downgrade(&old_view), left));
            }
            // Views no longer held anywhere take their caches with them; past
            // the budget the oldest kept caches go first.
            stash.retain(|(w, _)| w.strong_count() > 0);
            while stash.iter().map(|(_, c)| c.bytes()).sum::<usize>() > s.settings.cache_bytes && !stash.is_empty() {
                stash.remove(0);
            }
        }
        let empty = Arc::new(LightBuffer::empty(view.width(), view.height()));
        let now = Instant::now();
        // Brightest first: the direct stages go by longest wait, so the
        // brightest light gets the oldest `waiting_since`.
        let mut order: Vec<(usize, f32)> =
            s.slots.iter().enumerate().map(|(i, slot)| (i, slot.state.lock().expect("slot lock").priority)).collect();
        order.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        let n = order.len() as u32;
        let mut restored = 0;
        for (rank, &(i, _)) in order.iter().enumerate() {
            let slot = &s.slots[i];
            let id = s.next_id.fetch_add(1, Ordering::Relaxed);
            slot.latest.store(id, Ordering::SeqCst);
            let mut st = slot.state.lock().expect("slot lock");
            st.build = None;
            // Nothing of the old view's haze is kept.
            st.beam = None;
            st.knots = None;
            // The footprint share is a property of the old view.
            st.weight = 1.0;
            if st.evicted {
                // Dark and evicted for the memory budget: built when it lights.
                st.pending = None;
                st.waiting_since = None;
                continue;
            }
            let current = st.pending.take().map(|r| r.light).or_else(|| st.current.clone());
            let Some(light) = current else {
                st.shown = None;
                drop(st);
                let mut p = slot.published.lock().expect("published lock");
                p.buffer = empty.clone();
                p.shared = None;
                p.generation += 1;
                p.stage = Stage::Queued;
                continue;
            };
            // Kept buffers carry no knot buffers: in haze only the geometry cache restores.
            let hit = kept.get(i).and_then(Option::as_ref).filter(|k| k.light == light && s.haze.is_none());
            // A finished kept buffer first (the very `Arc` the view showed),
            // else this view's geometry cache. Lock order as in `request`:
            // slot state, then the cache.
            // In haze the cache entry carries the knot buffers and its key the haze.
            let finished_kept = hit
                .filter(|k| k.stage == Stage::Ready)
                .map(|k| Finished { shared: k.shared.clone(), ..Finished::alone(k.buffer.clone()) });
            let cached =
                finished_kept.or_else(|| s.cache.lock().expect("cache lock").get_in(i, &light, s.haze.as_ref()));
            if let Some(finished) = cached {
                // Finished for this very view and geometry before.
                restore(slot, st, light, finished);
                restored += 1;
                continue;
            }
            if hit.is_some() {
                st.shown = Some(light.clone());
                restored += 1;
            }
            // Rebuilt for this view. A kept buffer the old visit left
            // unfinished stays on screen until the new direct stage lands.
            st.pending = Some(Request { id, light: light.clone(), at: now });
            st.waiting_since = Some(now - Duration::from_micros(u64::from(n - rank as u32)));
            // Not moving: full-quality direct stage, later stages at once.
            st.last_move = None;
            st.previous_move = None;
            if hit.is_none() {
                st.shown = None;
            }
            drop(st);
            let mut p = slot.published.lock().expect("published lock");
            match hit {
                Some(k) => {
                    p.buffer = k.buffer.clone();
                    p.shared = k.shared.clone();
                    p.stage = k.stage;
                }
                None => {
                    p.buffer = empty.clone();
                    p.shared = None;
                    p.stage = Stage::Queued;
                }
            }
            p.generation += 1;
            if s.haze.is_some() {
                p.hazy = [empty.clone(), empty.clone()];
            }
        }
        s.notify();
        (old, restored)
    }

    /// Asks for light `index` to be rebuilt with new geometry. Replaces any
    /// pending request and cancels a build in progress. A geometry state
    /// found in the cache is published at once.
    pub fn request(&self, index: usize, light: Light, priority: f32) {
        let s = &self.shared;
        let Some(slot) = s.slots.get(index) else { return };
        let id = s.next_id.fetch_add(1, Ordering::Relaxed);
        slot.latest.store(id, Ordering::SeqCst);
        let now = Instant::now();
        let mut st = slot.state.lock().expect("slot lock");
        st.build = None;
        st.beam = None;
        st.priority = priority;
        if priority > 0.0 {
            st.last_lit = Some(now);
            // A lit light moved: a photon stage in progress yields to its direct stage.
            s.urgent.store(true, Ordering::SeqCst);
        }
        st.evicted = false;
        st.current = Some(light.clone());
        st.previous_move = st.last_move.replace(now);
        let cached = s.cache.lock().expect("cache lock").get_in(index, &light, s.haze.as_ref());
        if let Some(finished) = cached {
            restore(slot, st, light, finished);
            tracing::debug!("light {index}: geometry found in cache");
            return;
        }
        st.pending = Some(Request { id, light, at: now });
        st.waiting_since.get_or_insert(now);
        drop(st);
        s.notify();
    }

    /// Updates a light's priority (its brightness changes every frame). A
    /// light evicted for the memory budget that lights is rebuilt at once
    /// (it joins the lit lights' queue with the oldest wait).
    pub fn set_priority(&self, index: usize, priority: f32) {
        let Some(slot) = self.shared.slots.get(index) else { return };
        let mut st = slot.state.lock().expect("slot lock");
        let was_lit = st.priority > 0.0;
        st.priority = priority;
        if was_lit && priority.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            // The eviction order's "last lit": when it went dark (a caller
            // may leave an unchanged priority unsaid).
            st.last_lit = Some(Instant::now());
        }
        if priority > 0.0 {
            st.last_lit = Some(Instant::now());
            if st.evicted {
                st.evicted = false;
                if let Some(light) = st.current.clone() {
                    drop(st);
                    // Its geometry as it was: a cached state is published at once.
                    self.request(index, light, priority);
                }
            }
        }
    }

    /// The light's latest published buffer and state.
    pub fn published(&self, index: usize) -> Published {
        self.shared.slots[index].published.lock().expect("published lock").clone()
    }

    /// The light's build state for the status page.
    pub fn report(&self, index: usize) -> Option<LightReport> {
        let slot = self.shared.slots.get(index)?;
        let stage = slot.published.lock().expect("published lock").stage;
        let now = Instant::now();
        let mut st = slot.state.lock().expect("slot lock");
        prune(&mut st.direct_times, now);
        let settle = self.shared.settings.settle;
        Some(LightReport {
            stage,
            moving: st.pending.is_some() || st.last_move.is_some_and(|t| now.duration_since(t) < settle),
            pending_ms: st.waiting_since.map(|t| now.duration_since(t).as_secs_f64() * 1e3),
            direct_hz: st.direct_times.len() as f64,
            direct_updates: st.direct_total,
            first_stage_ms: st.first_stage.map(|d| d.as_secs_f64() * 1e3),
            last_build_ms: st.last_build.map(|d| d.as_secs_f64() * 1e3),
            failed: st.failed.clone(),
        })
    }

    /// True when no light has a pending request or a stage before its
    /// first indirect estimate still to build.
    pub fn idle(&self) -> bool {
        self.shared.slots.iter().all(|s| {
            let st = s.state.lock().expect("slot lock");
            st.pending.is_none()
                && st.build.is_none()
                && !matches!(
                    s.published.lock().expect("published lock").stage,
                    Stage::Queued | Stage::Direct | Stage::Whitted
                )
        })
    }

    /// Geometry cache entries and bytes: the current view's plus those
    /// kept for views left behind.
    pub fn cache_usage(&self) -> (usize, usize) {
        let c = self.shared.cache.lock().expect("cache lock");
        let kept = self.shared.kept_caches.lock().expect("kept caches lock");
        (
            c.len() + kept.iter().map(|(_, k)| k.len()).sum::<usize>(),
            c.bytes() + kept.iter().map(|(_, k)| k.bytes()).sum::<usize>(),
        )
    }

    /// Tells the worker to stop: every build's [`Cancel`] token fires (each
    /// stage checks it per tile row or per chunk of photons) and no new job
    /// starts. [`Tracer::shutdown`] then waits for it.
    pub fn stop(&self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        self.shared.notify();
    }

    /// True once the worker thread has ended (after [`Tracer::stop`], or
    /// dead: [`Tracer::worker_error`]).
    pub fn worker_finished(&self) -> bool {
        self.worker.as_ref().is_none_or(|w| w.is_finished())
    }

    /// Stops the worker: every build's [`Cancel`] token fires, and the
    /// worker is joined for at most `grace`. A stage that cannot stop in
    /// time is left to end with the process; returns false then.
    pub fn shutdown(mut self, grace: Duration) -> bool {
        self.shared.stop.store(true, Ordering::SeqCst);
        self.shared.notify();
        let Some(worker) = self.worker.take() else { return true };
        let deadline = Instant::now() + grace;
        while !worker.is_finished() {
            if Instant::now() >= deadline {
                tracing::warn!("a light build is still running; leaving it to end with the process");
                return false;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        let _ = worker.join();
        true
    }
}

impl Drop for Tracer {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        self.shared.notify();
    }
}

impl Shared {
    /// The pool a stage starting now runs on: every build thread while the
    /// frame clock is quiet, else the ones that leave it its core (module
    /// doc, rule 7).
    fn stage_pool(&self) -> &rayon::ThreadPool {
        let Some(quiet) = &self.quiet_pool else { return &self.pool };
        if self.clock_quiet_now() {
            self.quiet_stages.fetch_add(1, Ordering::Relaxed);
            quiet
        } else {
            &self.pool
        }
    }

    /// Whether the frame clock is quiet now: its last busy tick
    /// ([`Tracer::clock_tick`]), if any, is at least `quiet_hold` old.
    fn clock_quiet_now(&self) -> bool {
        let busy = self.busy_at.load(Ordering::Relaxed);
        let last_busy = (busy > 0).then(|| self.epoch + Duration::from_nanos(busy));
        clock_quiet(last_busy, Instant::now(), self.settings.quiet_hold)
    }

    fn notify(&self) {
        let (lock, cv) = &self.wake;
        *lock.lock().expect("wake lock") += 1;
        cv.notify_all();
    }

    fn stopped(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }

    /// Works out what is held against the memory budget and, past it,
    /// evicts: dark lights' buffers and photon maps first (least recently
    /// lit first), then geometry cache entries (views left behind first).
    /// The lit lights are never evicted: if they alone are over, the usage
    /// says so and the tracer keeps going.
    fn enforce_budget(&self) -> MemoryUsage {
        let budget = self.memory_budget.load(Ordering::SeqCst);
        // Shared layers (issue 38): counted once each, lit when a lit light shows it.
        let mut layers: std::collections::HashMap<u64, (u64, bool)> = std::collections::HashMap::new();
        // Per light: bytes held, lit, last lit.
        let held: Vec<(u64, u64, bool, Option<Instant>)> = self
            .slots
            .iter()
            .map(|slot| {
                let st = slot.state.lock().expect("slot lock");
                let maps = st.maps.as_ref().map_or(0, |(_, m)| maps_bytes(m));
                let (lit, last_lit) = (st.priority > 0.0, st.last_lit);
                let building = st.build.as_ref().map_or(0, |(_, b, _)| b.bytes())
                    + st.follow.as_ref().map_or(0, cells::Follow::bytes)
                    + st.lead.as_ref().map_or(0, cells::Lead::bytes);
                drop(st);
                let p = slot.published.lock().expect("published lock");
                let buffers = building + p.buffer.bytes() + p.hazy.iter().map(|b| b.bytes()).sum::<usize>();
                if let Some(layer) = &p.shared {
                    layers.entry(layer.id).or_insert((layer.buffer.bytes() as u64, false)).1 |= lit;
                }
                (buffers as u64, maps, lit, last_lit)
            })
            .collect();
        let caches = |s: &Self| {
            let c = s.cache.lock().expect("cache lock").bytes();
            (c + s.kept_caches.lock().expect("kept caches lock").iter().map(|(_, k)| k.bytes()).sum::<usize>()) as u64
        };
        // Evicting a dark light frees its own buffers; a layer it shares
        // stays counted (freed only with its last light: an upper bound).
        let mut buffers: u64 = held.iter().map(|h| h.0).sum::<u64>() + layers.values().map(|l| l.0).sum::<u64>();
        let mut maps: u64 = held.iter().map(|h| h.1).sum::<u64>() - self.trim_kept_maps();
        let mut cache = caches(self);
        let lit_bytes: u64 = held.iter().filter(|h| h.2).map(|h| h.0 + h.1).sum::<u64>()
            + layers.values().filter(|l| l.1).map(|l| l.0).sum::<u64>();
        if buffers + maps + cache > budget {
            // 1. Dark lights, least recently lit first (never lit: first of all).
            let mut dark: Vec<(Option<Instant>, usize)> =
                held.iter().enumerate().filter(|(_, h)| !h.2 && h.0 + h.1 > 0).map(|(i, h)| (h.3, i)).collect();
            dark.sort();
            for (_, i) in dark {
                if buffers + maps + cache <= budget {
                    break;
                }
                if self.evict(i) {
                    buffers -= held[i].0;
                    // Its maps may have gone already (`trim_kept_maps`).
                    maps = maps.saturating_sub(held[i].1);
                }
            }
            // 2. The geometry caches: views left behind first, then this view's.
            if buffers + maps + cache > budget {
                let mut room = budget.saturating_sub(buffers + maps) as usize;
                let mut kept = self.kept_caches.lock().expect("kept caches lock");
                for (_, c) in kept.iter_mut() {
                    let keep = room.min(c.bytes());
                    c.shrink_to(keep);
                    room -= keep;
                }
                kept.retain(|(_, c)| !c.is_empty());
                drop(kept);
                let mut own = self.cache.lock().expect("cache lock");
                let keep = room.min(own.bytes());
                own.shrink_to(keep);
                drop(own);
                cache = caches(self);
            }
        }
        let used = buffers + maps + cache;
        let over = used > budget;
        let usage = MemoryUsage {
            budget_bytes: budget,
            used_bytes: used,
            buffers_bytes: buffers,
            photon_maps_bytes: maps,
            caches_bytes: cache,
            lit_bytes,
            evicted_lights: self.slots.iter().filter(|s| s.state.lock().expect("slot lock").evicted).count(),
            evictions: self.evictions.load(Ordering::SeqCst),
            over_budget: over,
        };
        let mut last = self.memory.lock().expect("memory lock");
        if over && !last.over_budget {
            tracing::warn!(
                "the lit lights need {:.0} MB, over the memory budget of {:.0} MB (--memory): keeping going over it",
                used as f64 / 1e6,
                budget as f64 / 1e6
            );
        }
        *last = usage.clone();
        usage
    }

    /// Drops the photon maps of lights without a build in progress past
    /// [`TracerSettings::kept_maps_bytes`]: dark lights' first (least
    /// recently lit first), then the dimmest lit lights'. Returns the
    /// bytes dropped ([`maps_bytes`]).
    fn trim_kept_maps(&self) -> u64 {
        // Per light without a build: bytes of its kept maps, lit, priority, last lit.
        let mut kept: Vec<(usize, u64, bool, f32, Option<Instant>)> = self
            .slots
            .iter()
            .enumerate()
            .filter_map(|(i, slot)| {
                let st = slot.state.lock().expect("slot lock");
                let (_, m) = st.maps.as_ref().filter(|_| st.build.is_none() && st.lead.is_none())?;
                Some((i, maps_bytes(m), st.priority > 0.0, st.priority, st.last_lit))
            })
            .collect();
        let mut total: u64 = kept.iter().map(|k| k.1).sum();
        if total <= self.settings.kept_maps_bytes {
            return 0;
        }
        // Dark before lit; dark by when last lit, lit by priority (dimmest first).
        kept.sort_by(|a, b| a.2.cmp(&b.2).then(if a.2 { a.3.total_cmp(&b.3) } else { a.4.cmp(&b.4) }));
        let mut dropped = 0;
        for (i, bytes, ..) in kept {
            if total <= self.settings.kept_maps_bytes {
                break;
            }
            let mut st = self.slots[i].state.lock().expect("slot lock");
            if st.build.is_none() && st.lead.is_none() && st.maps.take().is_some() {
                total -= bytes;
                dropped += bytes;
            }
        }
        dropped
    }

    /// Drops dark light `index`'s buffers, photon maps and build state for
    /// the memory budget; it is rebuilt when it lights. False when it lit
    /// in the meantime.
    fn evict(&self, index: usize) -> bool {
        let slot = &self.slots[index];
        let mut st = slot.state.lock().expect("slot lock");
        if st.priority > 0.0 {
            return false;
        }
        // Supersedes its build in progress (its token fires).
        slot.latest.store(self.next_id.fetch_add(1, Ordering::Relaxed), Ordering::SeqCst);
        st.pending = None;
        st.waiting_since = None;
        st.build = None;
        st.follow = None;
        st.lead = None;
        st.beam = None;
        st.knots = None;
        st.maps = None;
        st.shown = None;
        st.evicted = true;
        drop(st);
        let view = self.view();
        let empty = Arc::new(LightBuffer::empty(view.width(), view.height()));
        let mut p = slot.published.lock().expect("published lock");
        p.buffer = empty.clone();
        p.hazy = [empty.clone(), empty];
        p.shared = None;
        p.generation += 1;
        p.stage = Stage::Queued;
        self.evictions.fetch_add(1, Ordering::SeqCst);
        true
    }

    /// Light `index`'s name for log lines.
    fn name(&self, index: usize) -> String {
        self.names.lock().ok().and_then(|n| n.get(index).cloned()).unwrap_or_else(|| format!("light {index}"))
    }

    /// Test hook: panics, inside the build pool, when light `index`'s next
    /// build was asked to ([`Tracer::inject_build_panic`]).
    fn injected_panic(&self, index: usize) {
        if self.slots[index].panic_next.swap(false, Ordering::SeqCst) {
            self.pool.install(|| panic!("injected build panic (test hook)"));
        }
    }

    fn view(&self) -> Arc<View> {
        self.view.lock().expect("view lock").clone()
    }

    /// Publishes `buffer` (of geometry `light`) for `index` if request `id`
    /// still owns the slot; returns the published buffer (shared, never
    /// copied: the geometry cache keeps the same one).
    fn publish(
        &self,
        index: usize,
        id: u64,
        buffer: Arc<LightBuffer>,
        stage: Stage,
        light: &Light,
    ) -> Option<Arc<LightBuffer>> {
        let slot = &self.slots[index];
        if slot.latest.load(Ordering::SeqCst) != id {
            return None; // superseded: a newer request owns the slot
        }
        // Held until the light changes: compact (a build's own buffers are already).
        let buffer = if self.settings.build.compact && !buffer.is_compact() {
            Arc::new(Arc::unwrap_or_clone(buffer).compact())
        } else {
            buffer
        };
        let hazy = match (&self.haze, self.haze_view()) {
            (Some(m), Some(hv)) => {
                let (beam, previous) = {
                    let mut st = slot.state.lock().expect("slot lock");
                    (st.beam.take().filter(|(bid, _)| *bid == id), st.knots.clone().filter(|(kid, ..)| *kid == id))
                };
                let (knots, surfaces) = match (beam, previous) {
                    // A new beam: resolved at once, then dropped.
                    (Some((_, beam)), _) => {
                        (knot_buffers(&hv, m, light.position, &buffer, Some(&beam)), surface_medium(m, Some(&beam)))
                    }
                    // A later stage: the knots follow the surface buffer.
                    (None, Some((_, before, k, surfaces))) => (
                        update_knots(&hv, &surfaces, light.position, &before, &buffer, [k[0].as_ref(), k[1].as_ref()]),
                        surfaces,
                    ),
                    (None, None) => (knot_buffers(&hv, m, light.position, &buffer, None), *m),
                };
                Some((knots.map(Arc::new), surfaces))
            }
            _ => None,
        };
        {
            let mut st = slot.state.lock().expect("slot lock");
            st.shown = Some(light.clone());
            st.knots = hazy.clone().map(|(k, surfaces)| (id, buffer.clone(), k, surfaces));
            st.failed = None;
            let n = self.publishes.fetch_add(1, Ordering::SeqCst);
            st.first_publish.get_or_insert(n);
            st.last_publish = Some(n);
        }
        let mut p = slot.published.lock().expect("published lock");
        if let Some((knots, _)) = hazy {
            p.hazy = knots;
        }
        p.buffer = buffer.clone();
        p.shared = None;
        p.generation += 1;
        p.stage = stage;
        Some(buffer)
    }

    /// Publishes a cell of a group (clear air only): its own Whitted term
    /// `own` with the group's indirect `layer` ([`Published::shared`]), if
    /// request `id` still owns the slot.
    fn publish_shared(
        &self,
        index: usize,
        id: u64,
        own: Arc<LightBuffer>,
        layer: SharedLayer,
        stage: Stage,
        light: &Light,
    ) -> bool {
        debug_assert!(self.haze.is_none(), "shared layers are for clear air");
        let slot = &self.slots[index];
        let mut st = slot.state.lock().expect("slot lock");
        if slot.latest.load(Ordering::SeqCst) != id {
            return false;
        }
        let mut p = slot.published.lock().expect("published lock");
        st.shown = Some(light.clone());
        st.failed = None;
        let n = self.publishes.fetch_add(1, Ordering::SeqCst);
        st.first_publish.get_or_insert(n);
        st.last_publish = Some(n);
        // The cell's own buffer unchanged (a follower at its leader's next
        // pass): same generation, so its emitter group's composite storage
        // stays current; the new layer has an id of its own.
        if !Arc::ptr_eq(&p.buffer, &own) {
            p.generation += 1;
        }
        p.buffer = own;
        p.shared = Some(layer);
        p.stage = stage;
        true
    }

    /// The haze geometry of the current view (made once per view), `None`
    /// without haze.
    fn haze_view(&self) -> Option<Arc<HazeView>> {
        self.haze.as_ref()?;
        let view = self.view();
        let mut cached = self.haze_view.lock().expect("haze view lock");
        if let Some((v, hv)) = cached.as_ref()
            && Arc::ptr_eq(v, &view)
        {
            return Some(hv.clone());
        }
        let hv = Arc::new(HazeView::new(&self.scene, &view.gbuffer));
        *cached = Some((view, hv.clone()));
        Some(hv)
    }

    /// The haze stage of `build` at `quality`: keeps the light's beam for
    /// the next publishes of request `id`. Nothing without haze.
    fn haze_stage(&self, index: usize, id: u64, build: &LightBuild, quality: HazeQuality) {
        let (Some(medium), Some(hv)) = (&self.haze, self.haze_view()) else { return };
        self.haze_stages.fetch_add(1, Ordering::SeqCst);
        let result = self.stage_pool().install(|| build.haze_beam(&self.scene, &hv, medium, quality));
        let beam = match result {
            Ok(b) => b,
            Err(e) => return report_bug(self, index, &e),
        };
        let slot = &self.slots[index];
        let mut st = slot.state.lock().expect("slot lock");
        if slot.latest.load(Ordering::SeqCst) == id {
            st.beam = Some((id, beam));
        }
    }

    fn views(&self, now: Instant) -> Vec<SlotView> {
        cells::release_orphans(self);
        self.slots
            .iter()
            .map(|slot| {
                let st = slot.state.lock().expect("slot lock");
                let later = st.build.as_ref().and_then(|(_, b, _)| match b.next_stage()? {
                    NextStage::Direct(_) | NextStage::Whitted => Some(0),
                    NextStage::Photons => Some(1),
                    NextStage::Refine => Some(2),
                });
                SlotView {
                    waiting_since: st.waiting_since.filter(|_| st.pending.is_some()),
                    weight: st.weight,
                    priority: st.priority,
                    settled: st.last_move.is_none_or(|t| now.duration_since(t) >= self.settings.settle),
                    later,
                }
            })
            .collect()
    }

    /// How long the worker may sleep: until the next light settles, else 50 ms.
    fn idle_wait(&self, now: Instant) -> Duration {
        self.slots
            .iter()
            .filter_map(|slot| {
                let st = slot.state.lock().expect("slot lock");
                let waiting = st.build.is_some();
                st.last_move.filter(|_| waiting).map(|t| (t + self.settings.settle).saturating_duration_since(now))
            })
            .min()
            .unwrap_or(Duration::from_millis(50))
            .clamp(Duration::from_millis(1), Duration::from_millis(50))
    }
}

/// Publishes a finished buffer found in a cache (the geometry cache, or a
/// view's kept buffers) for `light` at once, as ready: the one restore of
/// [`Tracer::set_view`] and [`Tracer::request`]. Nothing of an earlier
/// build waits on: no request, no knots of another geometry (in haze the
/// cache entry brings its own knot buffers).
fn restore(slot: &Slot, mut st: std::sync::MutexGuard<'_, SlotState>, light: Light, finished: Finished) {
    st.pending = None;
    st.waiting_since = None;
    st.shown = Some(light);
    st.knots = None;
    drop(st);
    let mut p = slot.published.lock().expect("published lock");
    p.buffer = finished.buffer;
    p.shared = finished.shared;
    p.generation += 1;
    p.stage = Stage::Ready;
    if let Some(knots) = finished.knots {
        p.hazy = knots;
    }
}

/// Bytes of a light's photon maps: the photons and irradiance cache
/// points, twice over for their kd-trees (an estimate).
fn maps_bytes(m: &PhotonMaps) -> u64 {
    let photons = (m.global.len() + m.caustic.len()) * std::mem::size_of::<crate::render::photon::Photon>();
    let points = m.irradiance.len() * 40;
    2 * (photons + points) as u64
}

fn prune(times: &mut VecDeque<Instant>, now: Instant) {
    while times.front().is_some_and(|t| now.duration_since(*t) > Duration::from_secs(1)) {
        times.pop_front();
    }
}

/// Panics outside any single build after which the worker restarts; one
/// more within [`RESTART_WINDOW`] of the first ends it for good.
const MAX_RESTARTS: usize = 2;
/// The window over which worker panics are counted.
const RESTART_WINDOW: Duration = Duration::from_secs(10);

/// The worker thread's body: [`worker`] under `catch_unwind`, restarted
/// after a panic that escapes it (outside any build: a bug, logged and
/// counted in [`Tracer::worker_restarts`]); the scheduling state lives in
/// the slots, so the restarted loop goes on where it was. A third panic
/// within [`RESTART_WINDOW`] ends it: the reason is kept for
/// [`Tracer::worker_error`], so the daemon stops with that error instead of
/// the lights staying queued in silence.
fn supervised_worker(s: &Shared) {
    let mut panics: VecDeque<Instant> = VecDeque::new();
    loop {
        let Err(panic) = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| worker(s))) else { return };
        let message = panic_message(panic.as_ref());
        let now = Instant::now();
        panics.push_back(now);
        while panics.front().is_some_and(|t| now.duration_since(*t) > RESTART_WINDOW) {
            panics.pop_front();
        }
        // Every slot lock a panic may have poisoned holds whole state (each
        // field is set in one step): taken back.
        for slot in &s.slots {
            slot.state.clear_poison();
            slot.published.clear_poison();
        }
        if panics.len() > MAX_RESTARTS || s.stopped() {
            tracing::error!(
                "the light builder stopped: {message}; no light is rebuilt from now on (a bug; please report it)"
            );
            *s.died.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(message);
            return;
        }
        s.restarts.fetch_add(1, Ordering::SeqCst);
        *s.last_panic.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(message.clone());
        tracing::error!("the light builder panicked: {message}; restarting it (a bug; please report it)");
    }
}

/// The text of a panic's payload.
fn panic_message(panic: &(dyn std::any::Any + Send)) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| (*s).to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".into())
}

/// A build pool of `threads` threads named `name-i`. Builds yield to the
/// frame clock, the network tasks and the preview server: on 2 cores a
/// build at normal priority delays frame ticks (p99 21-26 ms with no client
/// at all). At the lowest OS priority
/// ([`crate::render::composite::lower_current_thread`]) a build still
/// takes every idle cycle.
fn build_pool(threads: usize, name: &'static str) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(move |i| format!("{name}-{i}"))
        .start_handler(|_| crate::render::composite::lower_current_thread())
        .build()
        .expect("build thread pool")
}

/// Whether the frame clock is quiet at `now`: its last busy tick (None:
/// none yet) is at least `hold` old (module doc, rule 7).
pub fn clock_quiet(last_busy: Option<Instant>, now: Instant, hold: Duration) -> bool {
    last_busy.is_none_or(|t| now.saturating_duration_since(t) >= hold)
}

fn worker(s: &Shared) {
    while !s.stopped() {
        if s.panic_worker.swap(false, Ordering::SeqCst) {
            panic!("injected worker panic (test hook)");
        }
        let now = Instant::now();
        let views = s.views(now);
        let job = if s.paused.load(Ordering::SeqCst) {
            None
        } else if s.memory.lock().expect("memory lock").over_budget {
            // Over budget with the lit lights alone: no dark light is built,
            // and no stage that adds memory starts (module doc, "Memory").
            schedule_among(&within_budget(views.clone()), now, true)
        } else {
            schedule(&views, now)
        };
        match job {
            Some(job) => {
                let rush = matches!(job, Job::Direct(i) if rushed(&views, i, s.settings.rush_backlog));
                run_job(s, job, rush);
                s.enforce_budget();
            }
            None => {
                let wait = s.idle_wait(now);
                let (lock, cv) = &s.wake;
                let guard = lock.lock().expect("wake lock");
                let _ = cv.wait_timeout(guard, wait);
            }
        }
    }
}

/// True when more than `backlog` lights of light `i`'s class (lit or
/// dark) wait for their direct stage: it is built at moving quality
/// ([`TracerSettings::rush_backlog`]).
pub fn rushed(views: &[SlotView], i: usize, backlog: usize) -> bool {
    let Some(me) = views.get(i) else { return false };
    let lit = me.priority > 0.0;
    views.iter().filter(|v| (v.priority > 0.0) == lit && v.waiting_since.is_some()).count() > backlog
}

/// One job under `catch_unwind`: a build that panics (a bug) marks its
/// light failed, keeps its last published buffer, and the worker goes on
/// with the other lights. The lights of the same fixture that the job took
/// for a pass together and left with nothing to do are marked failed too.
/// `rush`: a direct stage at moving quality ([`rushed`]).
fn run_job(s: &Shared, job: Job, rush: bool) {
    let i = match job {
        Job::Direct(i) | Job::Later(i) => i,
    };
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| match job {
        Job::Direct(i) => {
            if !cells::direct_batch(s, i, rush) {
                direct_stage(s, i, rush);
            }
        }
        Job::Later(i) => {
            if !cells::whitted_batch(s, i) {
                later_stage(s, cells::leader_of(s, i));
            }
        }
    }));
    let Err(panic) = result else { return };
    let message = panic_message(panic.as_ref());
    for j in s.cells.group(i) {
        let slot = &s.slots[j];
        // A panic under a slot's lock poisons it: the state is still whole
        // (each field is set in one step), so it is taken back.
        let mut st = slot.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        // A follower is not stranded: it is released when its leader is
        // ([`cells::release_orphans`]: the failed leader leads no more).
        let stranded = st.pending.is_none() && st.build.is_none() && st.follow.is_none();
        if j != i && !(stranded && slot.published.lock().is_ok_and(|p| p.stage != Stage::Ready)) {
            continue;
        }
        // The build state of the failed stage is dropped: a new request builds it again.
        st.build = None;
        st.lead = None;
        st.beam = None;
        if st.failed.is_none() {
            tracing::error!(
                "{}: its build panicked: {message}; keeping its last picture (a bug; please report it)",
                s.name(j)
            );
        }
        st.failed = Some(format!("its build panicked: {message}"));
        drop(st);
        slot.state.clear_poison();
        slot.published.clear_poison();
    }
}

/// A stage that failed with a NaN/Inf (a bug): logged once, and the light
/// marked failed with the error in its status until a later build of it
/// publishes; its previous buffer stays on screen. A cancelled stage is no
/// failure.
fn report_bug(s: &Shared, index: usize, e: &BuildError) {
    let BuildError::Bad(bad) = e else { return };
    let mut st = s.slots[index].state.lock().expect("slot lock");
    if st.failed.is_none() {
        tracing::error!("{}: {bad}; keeping the previous buffer (this is a bug)", s.name(index));
    }
    st.failed = Some(bad.to_string());
}

/// Stage 1 for the light that waited longest; at moving quality when it
/// moves or when `rush` ([`rushed`]).
fn direct_stage(s: &Shared, index: usize, rush: bool) {
    let Some((req, waiting_since, moving)) = take_request(s, index) else { return };
    let quality = if moving || rush { DirectQuality::Moving } else { DirectQuality::Full };
    s.injected_panic(index);
    let mut build = new_build(s, index, &req).with_direct_first(quality);
    let view = s.view();
    s.builds.fetch_add(1, Ordering::SeqCst);
    let step = match s.stage_pool().install(|| build.next(&s.scene, &view)) {
        Ok(Some(step)) => step,
        Ok(None) => return,
        Err(e) => return report_bug(s, index, &e),
    };
    let share = step.footprint.map_or(0.0, |f| f.tiles_in_beam as f32 / f.tiles.max(1) as f32);
    after_direct(s, index, req, waiting_since, build, step.buffer, share);
}

/// Takes light `index`'s pending request: the request, when its wait
/// began, and whether the light is in motion (its previous request less
/// than the settle time before). `None` when nothing waits.
fn take_request(s: &Shared, index: usize) -> Option<(Request, Instant, bool)> {
    let mut st = s.slots[index].state.lock().expect("slot lock");
    let req = st.pending.take()?;
    let moving = st.previous_move.is_some_and(|p| req.at.duration_since(p) < s.settings.settle);
    let since = st.waiting_since.take().unwrap_or(req.at);
    Some((req, since, moving))
}

/// A new build of request `req` for light `index`, starting from the
/// light's photon maps when they were traced for this very geometry.
fn new_build(s: &Shared, index: usize, req: &Request) -> LightBuild {
    let slot = &s.slots[index];
    let cancel = Cancel::new(slot.latest.clone(), req.id, s.stop.clone());
    let build = LightBuild::new(req.light.clone(), index, s.settings.build, cancel)
        .with_coarse_indirect(s.settings.coarse_indirect);
    let maps = slot.state.lock().expect("slot lock").maps.clone();
    if let Some((light, maps)) = maps
        && light == req.light
    {
        build.with_maps(maps)
    } else {
        // A moved light (its photons are traced anew): see the setting.
        build.with_refinement_from_coarse(s.settings.refine_from_coarse)
    }
}

/// After a direct stage (alone or together): the coarse haze beam, the
/// publish, the light's counters and its build kept for the later stages.
/// `share`: the fraction of the picture's tiles its cone reaches.
fn after_direct(
    s: &Shared,
    index: usize,
    req: Request,
    waiting_since: Instant,
    build: LightBuild,
    buffer: LightBuffer,
    share: f32,
) {
    let slot = &s.slots[index];
    // The moved beam comes with the first picture of the moved light.
    s.haze_stage(index, req.id, &build, HazeQuality::COARSE);
    if s.publish(index, req.id, Arc::new(buffer), Stage::Direct, &req.light).is_none() {
        return;
    }
    let now = Instant::now();
    let mut st = slot.state.lock().expect("slot lock");
    st.first_stage = Some(now.duration_since(waiting_since));
    st.direct_times.push_back(now);
    st.direct_total += 1;
    prune(&mut st.direct_times, now);
    st.weight = 1.0 + share;
    if slot.latest.load(Ordering::SeqCst) == req.id {
        st.build = Some((req.id, build, req.at));
    }
}

/// After a Whitted stage (alone or together): the refined haze beam, the
/// publish, then the build kept for its photons, or finished.
fn after_whitted(s: &Shared, index: usize, id: u64, build: LightBuild, buffer: LightBuffer, at: Instant) {
    let stage = if build.has_photons() { Stage::Whitted } else { Stage::Ready };
    let light = build.light().clone();
    s.haze_stage(index, id, &build, HazeQuality::REFINED);
    // The build keeps its Whitted term for the photon stage: publish that
    // very buffer (one copy, not two, per light waiting for its photons).
    let buffer = build.whitted_shared().unwrap_or_else(|| Arc::new(buffer));
    if let Some(b) = s.publish(index, id, buffer, stage, &light) {
        match stage {
            Stage::Ready => finished(s, index, id, build.light(), Finished::alone(b), at),
            _ => keep_build(s, index, id, build, at),
        }
    }
}

/// The next later stage (Whitted, photons or a refinement pass) of a
/// settled light: one [`LightBuild::next`], published.
fn later_stage(s: &Shared, index: usize) {
    let slot = &s.slots[index];
    let Some((id, mut build, at)) = slot.state.lock().expect("slot lock").build.take() else { return };
    s.injected_panic(index);
    let view = s.view();
    let next = build.next_stage();
    if next == Some(NextStage::Photons) {
        if cells::gather_followers(s, index, id, &build) {
            build.set_edge_refinement(false);
        }
        if refinement_taken(s, index) {
            // It would give its refinement up as soon as its photon stage
            // ends: the exact estimate now, not a coarse one finished later.
            build = build.with_coarse_indirect(0);
        }
        // Rule 6: the photon stage yields (once) to a lit light that moves
        // meanwhile; only requests from now on count.
        if !build.yielded() {
            s.urgent.store(false, Ordering::SeqCst);
            build.set_preempt(Some(s.urgent.clone()));
        }
    }
    let result = s.stage_pool().install(|| build.next(&s.scene, &view));
    if next == Some(NextStage::Photons) && build.cancel().preempted() {
        // Not done, still good: it waits for its turn again, after the direct stage.
        build.set_preempt(None);
        build.mark_yielded();
        s.yields.fetch_add(1, Ordering::SeqCst);
        return keep_build(s, index, id, build, at);
    }
    build.set_preempt(None);
    if next == Some(NextStage::Photons) {
        if build.traced_photons() {
            s.photon_traces.fetch_add(1, Ordering::SeqCst);
        }
        if let (Ok(_), Some(maps)) = (&result, build.shared_maps())
            && slot.latest.load(Ordering::SeqCst) == id
        {
            slot.state.lock().expect("slot lock").maps = Some((build.light().clone(), maps));
        }
    }
    let step = match result {
        Ok(Some(step)) => step,
        // A refinement given up with nothing left to finish: its last picture stays.
        Ok(None) => return mark_ready(s, index, id, at),
        Err(e) => return report_bug(s, index, &e),
    };
    if next == Some(NextStage::Whitted) {
        // The refined haze beam comes with the Whitted stage.
        return after_whitted(s, index, id, build, step.buffer, at);
    }
    let stage = step.stage;
    let light = build.light().clone();
    // A leader in clear air publishes its own Whitted term with its
    // indirect term as the group's shared layer; any other light its buffer.
    let shown = match cells::lead(s, index, id, stage, &light, &step.buffer) {
        Some(split) => split,
        None => match s.publish(index, id, Arc::new(step.buffer), stage, &light) {
            Some(b) => Finished::alone(b),
            None => return,
        },
    };
    match stage {
        Stage::Ready => {
            if build.refined() > 0 {
                tracing::debug!("light {index}: converged after {} progressive passes", build.refined());
            }
            finished(s, index, id, &light, shown, at);
        }
        _ if next == Some(NextStage::Photons) => start_refining(s, index, id, build, at),
        _ => keep_build(s, index, id, build, at),
    }
}

fn keep_build(s: &Shared, index: usize, id: u64, build: LightBuild, at: Instant) {
    let slot = &s.slots[index];
    let mut st = slot.state.lock().expect("slot lock");
    if slot.latest.load(Ordering::SeqCst) == id {
        st.build = Some((id, build, at));
    }
}

/// True when `max_refining` other lit lights at least as bright as light
/// `index` hold refinement state already: its refinement would be given up
/// the moment its photon stage ends ([`start_refining`]). Its photon stage
/// then looks every shading vertex up exactly instead of publishing a
/// coarse estimate first (issue 38). A coarse start given up waits for its
/// exact finish after every other light's photon stage, holding the
/// light's photon maps all that time: the festival show's ~224 photon
/// leaders held 1.07 GB of maps that way, and each did its lookups twice
/// (the coarse step's, then every vertex anew).
fn refinement_taken(s: &Shared, index: usize) -> bool {
    let priority = s.slots[index].state.lock().expect("slot lock").priority;
    let brighter = s
        .slots
        .iter()
        .enumerate()
        .filter(|&(i, sl)| {
            let st = sl.state.lock().expect("slot lock");
            i != index && st.priority >= priority && st.build.as_ref().is_some_and(|(_, b, _)| b.refining())
        })
        .count();
    brighter >= s.settings.max_refining.max(1)
}

/// Holds refinement state for at most `max_refining` lights: the dimmest
/// holder gives its state up (its picture stays at the photon estimate).
fn start_refining(s: &Shared, index: usize, id: u64, build: LightBuild, at: Instant) {
    keep_build(s, index, id, build, at);
    let mut holders: Vec<(usize, f32)> = s
        .slots
        .iter()
        .enumerate()
        .filter_map(|(i, sl)| {
            let st = sl.state.lock().expect("slot lock");
            st.build.as_ref().filter(|(_, b, _)| b.refining()).map(|_| (i, st.priority))
        })
        .collect();
    holders.sort_by(|a, b| b.1.total_cmp(&a.1));
    for &(i, _) in holders.iter().skip(s.settings.max_refining.max(1)) {
        let mut st = s.slots[i].state.lock().expect("slot lock");
        let Some((rid, b, rat)) = st.build.as_mut() else { continue };
        // Never left at a coarse first estimate: its exact estimate is its
        // final picture, computed as a later stage of its own (after every
        // light's photons stage, not here).
        if !b.give_up_refinement() {
            let (rid, rat) = (*rid, *rat);
            st.build = None;
            drop(st);
            mark_ready(s, i, rid, rat);
        }
    }
}

/// Marks a light whose later stages ended without a new buffer as ready.
fn mark_ready(s: &Shared, index: usize, id: u64, at: Instant) {
    let slot = &s.slots[index];
    if slot.latest.load(Ordering::SeqCst) == id {
        slot.published.lock().expect("published lock").stage = Stage::Ready;
        slot.state.lock().expect("slot lock").last_build = Some(at.elapsed());
        // Its followers end where it ended (their last buffer follows its).
        cells::lead_ready(s, index, id);
    }
}

/// A light's final buffer: cached for position presets, build time recorded.
fn finished(s: &Shared, index: usize, id: u64, light: &Light, finished: Finished, at: Instant) {
    if s.slots[index].latest.load(Ordering::SeqCst) != id {
        return; // a view change or a newer request superseded it
    }
    let mut st = s.slots[index].state.lock().expect("slot lock");
    // In haze the entry keeps the knot buffers published with `buffer`.
    let knots = st.knots.clone().filter(|(kid, ..)| *kid == id).map(|(_, _, k, _)| k);
    if s.haze.is_none() || knots.is_some() {
        // Lock order: slot state, then the cache.
        s.cache.lock().expect("cache lock").insert_in(index, light, s.haze, Finished { knots, ..finished });
    }
    let elapsed = at.elapsed();
    st.last_build = Some(elapsed);
    drop(st);
    tracing::debug!("light {index}: finished {:.0} ms after its last move", elapsed.as_secs_f64() * 1e3);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The clock is quiet with no busy tick yet, busy for `hold` after one
    /// (at its very instant too), and quiet again from `hold` on.
    #[test]
    fn the_clock_is_quiet_a_hold_after_its_last_busy_tick() {
        let t = Instant::now();
        let hold = Duration::from_secs(1);
        assert!(clock_quiet(None, t, hold), "no busy tick yet");
        assert!(!clock_quiet(Some(t), t, hold));
        assert!(!clock_quiet(Some(t), t + Duration::from_millis(999), hold));
        assert!(clock_quiet(Some(t), t + hold, hold));
        assert!(!clock_quiet(Some(t + Duration::from_secs(5)), t, hold), "a tick after now: busy");
    }

    /// A backlog of more than `rush_backlog` waiting lights of a class
    /// (lit, or dark) rushes that class's direct stages; the other class,
    /// a light with nothing waiting and an index past the table do not
    /// count or rush.
    #[test]
    fn a_long_queue_of_lit_lights_rushes_their_direct_stages() {
        let now = Instant::now();
        let waiting =
            |priority: f32| SlotView { waiting_since: Some(now), weight: 1.0, priority, ..SlotView::default() };
        let idle = SlotView { weight: 1.0, priority: 1.0, ..SlotView::default() };
        let mut views: Vec<SlotView> = (0..3).map(|_| waiting(1.0)).collect();
        views.extend((0..5).map(|_| waiting(0.0)));
        views.push(idle);
        assert!(!rushed(&views, 0, 3), "3 lit lights waiting: not more than 3");
        assert!(rushed(&views, 0, 2), "3 lit lights waiting: more than 2");
        assert!(rushed(&views, 3, 4) && !rushed(&views, 3, 5), "the dark ones count among themselves");
        assert!(rushed(&views, 8, 2), "a lit light's class is the lit one");
        assert!(!rushed(&views, 99, 0), "past the table");
    }

    /// N lights re-requested every frame, one direct stage per frame: every
    /// light is served within 2N stages (the weight is at most 2), and
    /// later stages never run while a request waits.
    #[test]
    fn no_light_starves_when_every_light_moves_every_frame() {
        for n in [1usize, 2, 8, 44] {
            let t0 = Instant::now();
            let frame = Duration::from_millis(16);
            let mut slots: Vec<SlotView> = (0..n)
                .map(|i| SlotView {
                    waiting_since: Some(t0),
                    // Uneven footprints: the weight spans its whole range.
                    weight: 1.0 + (i % 3) as f32 * 0.5,
                    priority: 1.0,
                    settled: false,
                    later: Some(0),
                })
                .collect();
            let mut last_served = vec![0usize; n];
            let mut worst = 0;
            for step in 1..=20 * n {
                let now = t0 + frame * step as u32;
                let Some(Job::Direct(i)) = schedule(&slots, now) else { panic!("a direct stage must run first") };
                worst = worst.max(step - last_served[i]);
                last_served[i] = step;
                // The served light moves again during the next frame.
                slots[i].waiting_since = Some(now + frame / 2);
            }
            assert!(worst <= 2 * n, "n = {n}: a light waited {worst} stages (bound {})", 2 * n);
            // Every light was served at least once in the last 2N steps.
            assert!(last_served.iter().all(|&s| s + 2 * n >= 20 * n), "{last_served:?}");
        }
    }

    /// Lit first (issue 38): a dark light's direct stage waits for every
    /// stage of every lit light, however long it has waited; a dark light
    /// that lights joins the lit ones at once.
    #[test]
    fn dark_lights_wait_for_every_stage_of_the_lit_ones() {
        let t0 = Instant::now();
        let now = t0 + Duration::from_secs(60);
        let waiting = |since: Instant, priority: f32| SlotView {
            waiting_since: Some(since),
            weight: 1.0,
            priority,
            settled: false,
            later: Some(0),
        };
        let refining = SlotView { waiting_since: None, weight: 1.0, priority: 5.0, settled: true, later: Some(2) };
        // A dark light waiting a minute goes after a lit light's refinement pass.
        assert_eq!(schedule(&[waiting(t0, 0.0), refining], now), Some(Job::Later(1)));
        // ... and after a lit light that has waited a millisecond.
        let fresh = waiting(now - Duration::from_millis(1), 1.0);
        assert_eq!(schedule(&[waiting(t0, 0.0), fresh, refining], now), Some(Job::Direct(1)));
        // With nothing lit left to do, the dark ones are built (longest wait first).
        let done = SlotView { later: None, ..refining };
        let dark = [waiting(t0 + Duration::from_secs(1), 0.0), waiting(t0, 0.0), done];
        assert_eq!(schedule(&dark, now), Some(Job::Direct(1)));
        // A dark light that lights jumps the queue of the dark ones.
        let mut lit_now = dark;
        lit_now[0].priority = 0.5;
        assert_eq!(schedule(&lit_now, now), Some(Job::Direct(0)));
        // Later stages of dark lights come last of all.
        let dark_whitted = SlotView { priority: 0.0, later: Some(0), ..refining };
        assert_eq!(schedule(&[dark_whitted, refining], now), Some(Job::Later(1)));
        assert_eq!(schedule(&[dark_whitted, done], now), Some(Job::Later(0)));
    }

    #[test]
    fn later_stages_wait_for_settled_lights_and_go_stage_by_stage() {
        let now = Instant::now();
        let still = |later: u8, priority: f32| SlotView {
            waiting_since: None,
            weight: 1.0,
            priority,
            settled: true,
            later: Some(later),
        };
        // A moving (unsettled) light never gets a later stage.
        let moving = SlotView { settled: false, ..still(0, 100.0) };
        assert_eq!(schedule(&[moving], now), None);
        // Whitted before photons before refinement; the brightest first within a stage.
        let slots = [still(2, 100.0), still(1, 50.0), still(1, 80.0), moving];
        assert_eq!(schedule(&slots, now), Some(Job::Later(2)));
        assert_eq!(schedule(&[still(2, 100.0), still(0, 1.0)], now), Some(Job::Later(1)));
        // Any waiting request goes before every later stage.
        let waiting = SlotView { waiting_since: Some(now), settled: false, later: None, ..still(0, 0.1) };
        assert_eq!(schedule(&[still(0, 100.0), waiting], now), Some(Job::Direct(1)));
    }

    #[test]
    fn over_budget_withholds_the_stages_that_add_memory_and_keeps_the_direct_ones() {
        let now = Instant::now();
        let lit = |later: Option<u8>, waiting: bool| SlotView {
            waiting_since: waiting.then_some(now - Duration::from_millis(500)),
            weight: 1.0,
            priority: 1.0,
            settled: !waiting,
            later,
        };
        // A light waiting for photons, one for refinement, one for Whitted.
        let views = vec![lit(Some(1), false), lit(Some(2), false), lit(Some(0), false)];
        assert_eq!(schedule_among(&views, now, true), Some(Job::Later(2)), "Whitted goes first anyway");
        let photons_only = vec![lit(Some(1), false), lit(Some(2), false)];
        assert_eq!(schedule_among(&photons_only, now, true), Some(Job::Later(0)));
        assert_eq!(schedule_among(&within_budget(photons_only), now, true), None, "over budget: no photon stage");
        let views = within_budget(vec![lit(Some(1), false), lit(None, true), lit(Some(0), false)]);
        assert_eq!(schedule_among(&views, now, true), Some(Job::Direct(1)), "a moved light is still served");
        assert_eq!(views[2].later, Some(0), "Whitted stages still run");
    }
}
