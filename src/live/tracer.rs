//! The background tracer: rebuilds lights whose geometry changed while the
//! rest of the picture stays live (Vierjahn 2010, section 3.3 and fig. 1).
//!
//! Each light has a slot holding its latest *request* (coalesced: a pan
//! sweep replaces the pending request instead of queueing every step) and
//! its latest *published* buffer. Worker threads take the highest-priority
//! pending request (bright lights that reach much of the view first) and
//! build it in stages, publishing each as it finishes:
//! 1. direct light on directly seen surfaces (the moving light is seen moving),
//! 2. full Whitted recursion with adaptive anti-aliasing,
//! 3. the photon-mapped indirect term,
//! 4. while idle, progressive (SPPM) passes refine the brightest lights.
//!
//! A newer request for the same light cancels the build in progress at the
//! next stage boundary. Builds run on their own rayon pool, so the frame
//! clock's composite (global pool) never queues behind them; the frame
//! clock only reads published buffers (an `Arc` swap under a short lock).

use super::cache::{GeometryCache, geometry_key};
use crate::Light;
use crate::render::photon::{PhotonSettings, Progressive, trace_photons};
use crate::render::still::light_seed;
use crate::render::{AaParams, LightBuffer, View};
use crate::scene::Scene;
use glam::Vec3;
use serde::Serialize;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// How far a light's published buffer has got.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    /// Nothing built yet.
    Queued,
    /// Direct light on directly seen surfaces.
    Direct,
    /// Direct light with mirrors, glass and anti-aliasing.
    Whitted,
    /// Plus the first photon-mapped indirect estimate.
    Photons,
    /// Plus this many progressive refinement passes.
    Refining(u32),
    /// Finished (all stages, refinement done or not configured).
    Ready,
}

/// Tracer settings.
#[derive(Clone, Copy, Debug)]
pub struct TracerSettings {
    /// Build worker threads (each build is itself data-parallel).
    pub workers: usize,
    /// Threads of the build pool.
    pub threads: usize,
    /// Anti-aliasing threshold (0-255, relative to each light's own level).
    pub aa_threshold: f32,
    /// Photon mapping, or `None` for direct light only.
    pub photons: Option<PhotonSettings>,
    /// Progressive passes per light before it counts as converged.
    pub refine_passes: u32,
    /// Lights refined at the same time (each holds per-vertex SPPM state).
    pub max_refining: usize,
    /// Geometry cache budget in bytes.
    pub cache_bytes: usize,
}

impl Default for TracerSettings {
    fn default() -> Self {
        Self {
            workers: 1,
            threads: std::thread::available_parallelism().map(|n| n.get()).unwrap_or(2),
            aa_threshold: 20.0,
            photons: Some(PhotonSettings::default()),
            refine_passes: 16,
            max_refining: 4,
            cache_bytes: 512 << 20,
        }
    }
}

/// What the frame clock and the status page see of a light.
#[derive(Clone, Debug)]
pub struct Published {
    /// The light's current unit-intensity buffer.
    pub buffer: Arc<LightBuffer>,
    /// Bumped on every publish (the compositor recomposes on change).
    pub generation: u64,
    /// How far the build got.
    pub stage: Stage,
    /// Wall time of the last completed build (stages 1-3).
    pub last_build: Option<Duration>,
    /// Time from the request to stage 1 of the last build.
    pub first_stage: Option<Duration>,
}

struct Request {
    id: u64,
    light: Light,
    at: Instant,
}

struct Refine {
    request_id: u64,
    light: Light,
    direct: Vec<Vec3>,
    sppm: Progressive,
}

struct Slot {
    pending: Mutex<Option<Request>>,
    latest: AtomicU64,
    published: Mutex<Published>,
    refine: Mutex<Option<Refine>>,
    priority: Mutex<f32>,
}

struct Shared {
    scene: Arc<Scene>,
    view: Arc<View>,
    settings: TracerSettings,
    slots: Vec<Slot>,
    wake: (Mutex<u64>, Condvar),
    stop: AtomicBool,
    next_id: AtomicU64,
    cache: Mutex<GeometryCache>,
    pool: rayon::ThreadPool,
}

/// Background builder of per-light buffers.
pub struct Tracer {
    shared: Arc<Shared>,
    workers: Vec<std::thread::JoinHandle<()>>,
}

impl Tracer {
    /// Starts the worker threads for `lights` lights over `view`.
    pub fn new(scene: Arc<Scene>, view: Arc<View>, lights: usize, settings: TracerSettings) -> Self {
        let empty = Arc::new(LightBuffer::empty(view.width(), view.height()));
        let slots = (0..lights)
            .map(|_| Slot {
                pending: Mutex::new(None),
                latest: AtomicU64::new(0),
                published: Mutex::new(Published {
                    buffer: empty.clone(),
                    generation: 0,
                    stage: Stage::Queued,
                    last_build: None,
                    first_stage: None,
                }),
                refine: Mutex::new(None),
                priority: Mutex::new(0.0),
            })
            .collect();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(settings.threads.max(1))
            .thread_name(|i| format!("footlight-build-{i}"))
            .build()
            .expect("build thread pool");
        let shared = Arc::new(Shared {
            scene,
            view,
            settings,
            slots,
            wake: (Mutex::new(0), Condvar::new()),
            stop: AtomicBool::new(false),
            next_id: AtomicU64::new(1),
            cache: Mutex::new(GeometryCache::new(settings.cache_bytes)),
            pool,
        });
        let workers = (0..settings.workers.max(1))
            .map(|i| {
                let shared = shared.clone();
                std::thread::Builder::new()
                    .name(format!("footlight-tracer-{i}"))
                    .spawn(move || worker(&shared))
                    .expect("spawn tracer worker")
            })
            .collect();
        Self { shared, workers }
    }

    /// Number of light slots.
    pub fn len(&self) -> usize {
        self.shared.slots.len()
    }

    /// True when there are no lights.
    pub fn is_empty(&self) -> bool {
        self.shared.slots.is_empty()
    }

    /// Asks for light `index` to be rebuilt with new geometry. Replaces any
    /// pending request and cancels a build in progress at its next stage.
    /// A geometry state found in the cache is published at once. `_k_full`
    /// is no longer used: anti-aliasing is decided on the light's own buffer.
    pub fn request(&self, index: usize, light: Light, _k_full: Vec3, priority: f32) {
        let s = &self.shared;
        let Some(slot) = s.slots.get(index) else { return };
        let id = s.next_id.fetch_add(1, Ordering::Relaxed);
        slot.latest.store(id, Ordering::SeqCst);
        *slot.refine.lock().expect("refine lock") = None;
        let key = geometry_key(&light);
        if let Some(buffer) = s.cache.lock().expect("cache lock").get(index, key) {
            *slot.pending.lock().expect("pending lock") = None;
            let mut p = slot.published.lock().expect("published lock");
            p.buffer = buffer;
            p.generation += 1;
            p.stage = Stage::Ready;
            p.first_stage = Some(Duration::ZERO);
            tracing::debug!("light {index}: geometry found in cache");
            return;
        }
        *slot.pending.lock().expect("pending lock") = Some(Request { id, light, at: Instant::now() });
        *slot.priority.lock().expect("priority lock") = priority;
        let (lock, cv) = &s.wake;
        *lock.lock().expect("wake lock") += 1;
        cv.notify_all();
    }

    /// Updates a light's priority (its brightness changes every frame).
    pub fn set_priority(&self, index: usize, priority: f32) {
        if let Some(slot) = self.shared.slots.get(index) {
            *slot.priority.lock().expect("priority lock") = priority;
        }
    }

    /// The light's latest published buffer and state.
    pub fn published(&self, index: usize) -> Published {
        self.shared.slots[index].published.lock().expect("published lock").clone()
    }

    /// True when no light has a pending request or unfinished build.
    pub fn idle(&self) -> bool {
        self.shared.slots.iter().all(|s| {
            s.pending.lock().expect("pending lock").is_none()
                && !matches!(
                    s.published.lock().expect("published lock").stage,
                    Stage::Queued | Stage::Direct | Stage::Whitted
                )
        })
    }

    /// Stops the workers after their current stage and joins them.
    pub fn shutdown(mut self) {
        self.stop_workers();
    }

    fn stop_workers(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        self.shared.wake.1.notify_all();
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}

impl Drop for Tracer {
    fn drop(&mut self) {
        self.stop_workers();
    }
}

fn worker(s: &Shared) {
    while !s.stop.load(Ordering::SeqCst) {
        if let Some((index, req)) = take_request(s) {
            build(s, index, req);
            continue;
        }
        if refine_one(s) {
            continue;
        }
        let (lock, cv) = &s.wake;
        let guard = lock.lock().expect("wake lock");
        let _ = cv.wait_timeout(guard, Duration::from_millis(50));
    }
}

/// Takes the pending request with the highest priority.
fn take_request(s: &Shared) -> Option<(usize, Request)> {
    let mut best: Option<(usize, f32)> = None;
    for (i, slot) in s.slots.iter().enumerate() {
        if slot.pending.lock().expect("pending lock").is_some() {
            let p = *slot.priority.lock().expect("priority lock");
            if best.is_none_or(|(_, bp)| p > bp) {
                best = Some((i, p));
            }
        }
    }
    let (i, _) = best?;
    s.slots[i].pending.lock().expect("pending lock").take().map(|r| (i, r))
}

fn publish(s: &Shared, index: usize, id: u64, buffer: LightBuffer, stage: Stage) -> bool {
    let slot = &s.slots[index];
    if slot.latest.load(Ordering::SeqCst) != id {
        return false; // superseded: a newer request owns the slot
    }
    if let Err(e) = buffer.check() {
        tracing::error!("light {index}: {e}; keeping the previous buffer (this is a bug)");
        return false;
    }
    let mut p = slot.published.lock().expect("published lock");
    p.buffer = Arc::new(buffer);
    p.generation += 1;
    p.stage = stage;
    true
}

fn build(s: &Shared, index: usize, req: Request) {
    let (scene, view) = (&*s.scene, &*s.view);
    let slot = &s.slots[index];
    let current = || slot.latest.load(Ordering::SeqCst) == req.id && !s.stop.load(Ordering::SeqCst);
    let (w, h) = (view.width(), view.height());
    let t0 = Instant::now();
    let primary = s.pool.install(|| view.render_primary_direct(scene, &req.light));
    if !publish(s, index, req.id, LightBuffer::from_dense(w, h, &primary), Stage::Direct) {
        return;
    }
    slot.published.lock().expect("published lock").first_stage = Some(req.at.elapsed());
    tracing::debug!("light {index}: direct stage in {:.0} ms", t0.elapsed().as_secs_f64() * 1e3);
    if !current() {
        return;
    }
    let aa = AaParams::new(s.settings.aa_threshold);
    let (direct, _) = s.pool.install(|| view.render_direct(scene, &req.light, Some(aa)));
    let stage = if s.settings.photons.is_some() { Stage::Whitted } else { Stage::Ready };
    if !publish(s, index, req.id, LightBuffer::from_dense(w, h, &direct), stage) || !current() {
        return;
    }
    let final_buffer;
    if let Some(photons) = s.settings.photons {
        let settings = PhotonSettings { seed: light_seed(photons.seed, index), ..photons };
        let (sum, maps) = s.pool.install(|| {
            let maps = trace_photons(scene, &req.light, &settings);
            let indirect = view.render_indirect(scene, &maps);
            let sum: Vec<Vec3> = direct.iter().zip(&indirect).map(|(d, a)| *d + *a).collect();
            (sum, maps)
        });
        let refine = s.settings.refine_passes > 0 && !maps.global.is_empty();
        let buffer = LightBuffer::from_dense(w, h, &sum);
        final_buffer = buffer.clone();
        if !publish(s, index, req.id, buffer, if refine { Stage::Photons } else { Stage::Ready }) {
            return;
        }
        // Progressive state is set up after the first estimate is on screen.
        if refine && current() {
            let sppm = s.pool.install(|| Progressive::new(scene, view, &maps));
            *slot.refine.lock().expect("refine lock") =
                Some(Refine { request_id: req.id, light: req.light.clone(), direct, sppm });
        }
    } else {
        final_buffer = LightBuffer::from_dense(w, h, &direct);
    }
    let elapsed = t0.elapsed();
    slot.published.lock().expect("published lock").last_build = Some(elapsed);
    s.cache.lock().expect("cache lock").insert(index, geometry_key(&req.light), Arc::new(final_buffer));
    tracing::info!("light {index}: rebuilt in {:.0} ms", elapsed.as_secs_f64() * 1e3);
}

/// One SPPM pass on the highest-priority light still refining; false when
/// there is nothing to refine.
fn refine_one(s: &Shared) -> bool {
    let (scene, view) = (&*s.scene, &*s.view);
    let mut candidates: Vec<(usize, f32)> = s
        .slots
        .iter()
        .enumerate()
        .filter(|(_, slot)| slot.refine.lock().expect("refine lock").is_some())
        .map(|(i, slot)| (i, *slot.priority.lock().expect("priority lock")))
        .collect();
    candidates.sort_by(|a, b| b.1.total_cmp(&a.1));
    // Lights beyond the first `max_refining` give their state up (memory bound).
    for &(i, _) in candidates.iter().skip(s.settings.max_refining.max(1)) {
        if let Some(r) = s.slots[i].refine.lock().expect("refine lock").take() {
            finish_refine(s, i, r.request_id);
        }
    }
    let Some(&(index, _)) = candidates.first() else { return false };
    let slot = &s.slots[index];
    let Some(mut r) = slot.refine.lock().expect("refine lock").take() else { return true };
    let sum = s.pool.install(|| {
        r.sppm.pass(scene, view, &r.light);
        let indirect = view.render_progressive(scene, &r.sppm);
        r.direct.iter().zip(&indirect).map(|(d, a)| *d + *a).collect::<Vec<Vec3>>()
    });
    let passes = r.sppm.passes();
    let done = passes >= s.settings.refine_passes;
    let stage = if done { Stage::Ready } else { Stage::Refining(passes) };
    let buffer = LightBuffer::from_dense(view.width(), view.height(), &sum);
    let cached = done.then(|| Arc::new(buffer.clone()));
    if !publish(s, index, r.request_id, buffer, stage) {
        return true;
    }
    if let Some(b) = cached {
        s.cache.lock().expect("cache lock").insert(index, geometry_key(&r.light), b);
        tracing::info!("light {index}: converged after {passes} progressive passes");
    } else if slot.latest.load(Ordering::SeqCst) == r.request_id {
        *slot.refine.lock().expect("refine lock") = Some(r);
    }
    true
}

/// Marks a light whose refinement state was given up as finished.
fn finish_refine(s: &Shared, index: usize, request_id: u64) {
    let slot = &s.slots[index];
    if slot.latest.load(Ordering::SeqCst) == request_id {
        slot.published.lock().expect("published lock").stage = Stage::Ready;
    }
}
