//! The real-time update of Vierjahn 2010, section 3.3 and eq. 5 on the CPU:
//! I = Σ_i k_i ⊙ buffer_i, where buffer_i holds the light's unit-intensity
//! direct (and, once photon maps land, indirect) terms and k_i = c_F c_I v Î
//! is an RGB weight (eq. 4).
//!
//! Dimmer and colour changes only change k_i, so this is all that runs per
//! display frame for them. [`composite`] recomputes a whole frame (the
//! reference the GPU compositor matches); [`Compositor`] keeps the last frame
//! and recomposes only the tiles that lights with a changed k_i (or a rebuilt
//! buffer) cover, so one fader move costs the area its beam lights, not the
//! whole rig. Tiles are recomposed from scratch (never by adding a delta), so
//! repeated updates cannot drift. Work is skipped where it cannot contribute:
//! lights with k_i = 0 and tiles a light does not reach. In haze,
//! [`Compositor::update_layers`] keeps one such sum per density knot, so a
//! hazer change (new knot weights) recombines the sums instead of
//! recomposing every light.
//!
//! **Emitter groups** (issue 38, [`super::group`]): lights given to
//! [`Compositor::set_groups`] (a fixture's cells) are composited through
//! their group's storage, per tile low-rank or exact, so a pixel chase
//! costs what the cells' buffers differ by, not cells × tiles. A group whose
//! storage was built from other buffers than its members' current ones (a
//! member rebuilt) is composited per light, exactly, until
//! [`Compositor::rebuild_stale_groups`] (or a new `set_groups`) catches up.
//! Lights in no group take the per-light path unchanged.

use super::buffer::{LightBuffer, TILE};
use super::display::Display;
use super::group::{GroupBuffer, GroupSettings};
use glam::Vec3;
use rayon::prelude::*;
use std::sync::Arc;

/// Composites `buffers` with weights `k` (same length) into a dense
/// row-major linear image of `width`×`height` (cd/m²).
pub fn composite(buffers: &[&LightBuffer], k: &[Vec3], width: u32, height: u32) -> Vec<Vec3> {
    let mut out = vec![Vec3::ZERO; (width * height) as usize];
    composite_into(buffers, k, width, height, &mut out);
    out
}

/// As [`composite`], writing into an existing image (no allocation per frame).
pub fn composite_into(buffers: &[&LightBuffer], k: &[Vec3], width: u32, height: u32, out: &mut [Vec3]) {
    assert_eq!(buffers.len(), k.len(), "one k per buffer");
    let w = width as usize;
    assert_eq!(out.len(), w * height as usize, "output size");
    let parts = Parts { lights: active_lights(buffers, k), groups: Vec::new() };
    parts.composite_into(width, height, out);
}

/// What contributes to a frame: lights composited on their own and groups
/// composited through their storage (with their cells' k).
struct Parts<'a> {
    lights: Vec<(&'a LightBuffer, Vec3)>,
    groups: Vec<(&'a GroupBuffer, Vec<Vec3>)>,
}

impl Parts<'_> {
    /// Adds every part's tile (tx, ty) into `band` (lights first, in order,
    /// then groups), which must be zero there beforehand.
    fn accumulate_tile(&self, tx: usize, ty: usize, w: usize, band: &mut [Vec3]) {
        accumulate_tile(&self.lights, tx, ty, w, band);
        for (g, k) in &self.groups {
            g.accumulate_tile(k, tx, ty, w, band);
        }
    }

    /// The whole frame into `out` (row-major, `width`×`height`).
    fn composite_into(&self, width: u32, height: u32, out: &mut [Vec3]) {
        let w = width as usize;
        assert_eq!(out.len(), w * height as usize, "output size");
        let tiles_x = w.div_ceil(TILE);
        out.par_chunks_mut(w * TILE).enumerate().for_each(|(ty, band)| {
            band.fill(Vec3::ZERO);
            for tx in 0..tiles_x {
                self.accumulate_tile(tx, ty, w, band);
            }
        });
    }
}

/// Lights that can contribute: k_i ≠ 0 (dimmer at zero or a black gel
/// costs nothing) and at least one occupied tile.
fn active_lights<'a>(buffers: &[&'a LightBuffer], k: &[Vec3]) -> Vec<(&'a LightBuffer, Vec3)> {
    buffers.iter().zip(k).filter(|(b, k)| **k != Vec3::ZERO && b.occupied_tiles() > 0).map(|(b, k)| (*b, *k)).collect()
}

/// Adds every active light's tile (tx, ty) into `band` (the image rows of
/// tile row ty, `w` pixels wide), which must be zero there beforehand.
fn accumulate_tile(active: &[(&LightBuffer, Vec3)], tx: usize, ty: usize, w: usize, band: &mut [Vec3]) {
    for (buf, k) in active {
        buf.add_tile_scaled(tx, ty, *k, w, band); // Vierjahn 2010, eq. (5)
    }
}

/// What one [`Compositor::update`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UpdateStats {
    /// Tiles recomposed and re-encoded.
    pub tiles: usize,
    /// Lights whose k or buffer changed.
    pub changed_lights: usize,
    /// Tiles whose new buffers wait for a later frame (the composite
    /// budget, [`Compositor::update`]).
    pub deferred: usize,
}

/// One light as the compositor sees it.
#[derive(Clone, Copy, Debug)]
pub struct CompositeInput<'a> {
    /// The light's current unit-intensity buffer.
    pub buffer: &'a LightBuffer,
    /// Bumped by the caller whenever `buffer` is replaced (a rebuild).
    pub generation: u64,
    /// k_i now (eq. 4).
    pub k: Vec3,
}

/// One emitter group as the compositor sees it: which lights are its
/// cells and their storage.
#[derive(Clone, Debug)]
pub struct CompositeGroup {
    /// Per cell of `storage` (in its order), the index of that light in
    /// the lights given to [`Compositor::update`].
    pub members: Vec<usize>,
    /// Per cell, the [`CompositeInput::generation`] its buffer had when
    /// `storage` was built: another generation now means the storage is stale.
    pub generations: Vec<u64>,
    /// The cells' buffers, stored by what differs.
    pub storage: Arc<GroupBuffer>,
}

impl CompositeGroup {
    /// Builds the storage of the group of `members` (indices into
    /// `lights`) from their current buffers.
    ///
    /// # Panics
    /// If `members` is empty or names a light past `lights`.
    pub fn build(lights: &[CompositeInput], members: Vec<usize>, settings: GroupSettings) -> Self {
        let buffers: Vec<&LightBuffer> = members.iter().map(|&m| lights[m].buffer).collect();
        let generations = members.iter().map(|&m| lights[m].generation).collect();
        Self { storage: Arc::new(GroupBuffer::build(&buffers, settings)), members, generations }
    }

    /// Whether the storage holds the members' current buffers (every
    /// member in range, each at the generation it was built from).
    pub fn is_current(&self, lights: &[CompositeInput]) -> bool {
        self.members.len() == self.storage.cells()
            && self
                .members
                .iter()
                .zip(&self.generations)
                .all(|(&m, &g)| lights.get(m).is_some_and(|l| l.generation == g))
    }
}

/// Incremental compositor: keeps the last linear frame and its sRGB
/// encoding, and recomposes only tiles covered by changed lights.
pub struct Compositor {
    width: u32,
    height: u32,
    display: Display,
    linear: Vec<Vec3>,
    srgb: Vec<u8>,
    /// Per light: last k, last generation, and the tiles its buffer covered.
    seen: Vec<(Vec3, u64, Vec<u32>)>,
    /// The layer sums of [`Compositor::update_layers`] (haze knots), when in use.
    layers: Option<LayerSums>,
    /// Emitter groups composited through their storage ([`Compositor::set_groups`]).
    groups: Vec<CompositeGroup>,
    /// Per group, whether its storage was current at the last update (a
    /// change moves its cells between the group and the per-light path).
    group_current: Vec<bool>,
    /// The groups changed since the last update: recompose everything.
    regrouped: bool,
    /// Stale groups rebuilt in the background, when asked for
    /// ([`Compositor::with_group_members`]).
    background: Option<Background>,
    /// A dense term added to every pixel before encoding, with its
    /// generation ([`Compositor::set_overlay`]).
    overlay: Option<(u64, Arc<Vec<Vec3>>)>,
    /// The overlay changed since the last update: re-encode every tile.
    overlay_changed: bool,
    /// Tiles whose new buffers are not composited yet (the budget).
    deferred: Vec<bool>,
    /// Where the next deferred tiles are taken from (round robin).
    deferred_cursor: usize,
    /// Per tile, the buffers covering it: a tile's composite cost.
    coverage: Vec<u32>,
    /// Composite time per covering buffer of a recomposed tile, ms
    /// (running mean of recent updates).
    ms_per_cover: f64,
}

/// Rebuilds of stale groups off the frame clock, on a pool of their own
/// (one thread at the lowest OS priority, like the tracer's builds: on
/// the global pool they took the frame clock's cores while a festival rig
/// built, p99 frame interval 155 ms): a channel of finished storages
/// (group index, the epoch of the groups it was asked for, the group), and
/// which groups have a rebuild in flight.
/// At most [`Background::MAX_IN_FLIGHT`] at once, so a rig whose buffers
/// all change (a camera move) does not flood the pool or copy every buffer.
struct Background {
    settings: GroupSettings,
    tx: std::sync::mpsc::Sender<(usize, u64, CompositeGroup)>,
    rx: std::sync::mpsc::Receiver<(usize, u64, CompositeGroup)>,
    in_flight: Vec<bool>,
    epoch: u64,
    pool: Arc<rayon::ThreadPool>,
}

impl Background {
    const MAX_IN_FLIGHT: usize = 2;

    /// The group-build pool: one thread at the lowest OS priority (failure
    /// to lower it, on a platform without per-thread priorities, only costs
    /// that protection).
    fn pool() -> Arc<rayon::ThreadPool> {
        Arc::new(lowest_priority_pool("footlight-groups"))
    }
}

/// What [`Compositor::update_layers`] keeps between frames.
struct LayerSums {
    /// Lights per layer.
    lights: usize,
    /// The weights the frame was last combined with.
    weights: Vec<f32>,
    /// Per layer, Σ_i k_i ⊙ buffer_i of its lights; `None` while its weight
    /// is 0 (then it is not kept up to date, and rebuilt when it is needed).
    sums: Vec<Option<Vec<Vec3>>>,
}

/// The parts of a frame: the `current` ones of `groups` through their
/// storage, every other light on its own (those with k = 0 or no tile skipped).
fn frame_parts<'a>(groups: &'a [CompositeGroup], current: &[bool], lights: &[CompositeInput<'a>]) -> Parts<'a> {
    let mut grouped = vec![false; lights.len()];
    let mut active = Vec::new();
    for (g, &current) in groups.iter().zip(current) {
        if !current {
            continue;
        }
        g.members.iter().for_each(|&m| grouped[m] = true);
        let k: Vec<Vec3> = g.members.iter().map(|&m| lights[m].k).collect();
        if k.iter().any(|k| *k != Vec3::ZERO) {
            active.push((&*g.storage, k));
        }
    }
    let lights = lights
        .iter()
        .zip(&grouped)
        .filter(|(l, g)| !**g && l.k != Vec3::ZERO && l.buffer.occupied_tiles() > 0)
        .map(|(l, _)| (l.buffer, l.k))
        .collect();
    Parts { lights, groups: active }
}

/// A pool of one thread named `name` at the lowest OS priority
/// ([`lower_current_thread`]), for work kept off the frame clock's cores
/// (group storages, the shared layers' sum).
pub fn lowest_priority_pool(name: &'static str) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .thread_name(move |_| name.into())
        .start_handler(|_| lower_current_thread())
        .build()
        .expect("a one-thread pool")
}

/// Puts the calling thread at the lowest OS priority, for background work
/// (light builds, group storages, the shared layers' sum): nice 19 on
/// Linux, via the `thread-priority` crate. It still takes every idle cycle.
/// (`SCHED_IDLE`, which a waking normal thread preempts at once, was
/// measured on the festival show and did not lower the frame clock's p99:
/// 18.9-22.1 ms against 18.4-22.7 ms.) Failure (a platform without
/// per-thread priorities) only costs that protection, so it is ignored.
pub fn lower_current_thread() {
    let _ = thread_priority::set_current_thread_priority(thread_priority::ThreadPriority::Min);
}

/// Encodes `linear` (plus `overlay`, the same length, when given) into
/// `out` on the calling thread: a span of at most one tile row.
fn encode_span_with(display: &Display, linear: &[Vec3], overlay: Option<&[Vec3]>, out: &mut [u8]) {
    match overlay {
        None => display.encode_span(linear, out),
        Some(o) => {
            let mut sum = [Vec3::ZERO; TILE];
            for ((l, o), out) in linear.chunks(TILE).zip(o.chunks(TILE)).zip(out.chunks_mut(TILE * 3)) {
                let n = l.len();
                sum[..n].iter_mut().zip(l.iter().zip(o)).for_each(|(s, (a, b))| *s = *a + *b);
                display.encode_span(&sum[..n], out);
            }
        }
    }
}

/// Encodes the whole frame `linear` (plus `overlay` when given) into `out`.
fn encode_all(display: &Display, linear: &[Vec3], overlay: Option<&[Vec3]>, out: &mut [u8]) {
    match overlay {
        None => display.to_srgb8_into(linear, out),
        Some(o) => out
            .par_chunks_mut(3 * 4096)
            .zip(linear.par_chunks(4096).zip(o.par_chunks(4096)))
            .for_each(|(out, (l, o))| encode_span_with(display, l, Some(o), out)),
    }
}

/// The tiles a light's buffer covers (its occupied tiles), as tile indices.
fn covered_tiles(buffer: &LightBuffer, tiles_x: usize, n_tiles: usize) -> Vec<u32> {
    (0..n_tiles as u32).filter(|&t| buffer.has_tile(t as usize % tiles_x, t as usize / tiles_x)).collect()
}

/// Marks in `dirty` the tiles that `lights` changed since `seen` (their old
/// and new tiles where k or the buffer changed) and brings `seen` up to
/// date; returns how many lights changed. NaN in `seen` counts as a change.
fn mark_changes(
    lights: &[CompositeInput],
    seen: &mut [(Vec3, u64, Vec<u32>)],
    tiles_x: usize,
    dirty: &mut [bool],
) -> usize {
    let n_tiles = dirty.len();
    mark_changes_by(lights, seen, tiles_x, n_tiles, None, |t, _| dirty[t] = true)
}

/// [`mark_changes`], telling `mark(tile, k_changed)` whether the light's
/// k changed (a desk change: due in this very frame) or only its buffer
/// (a new build stage: [`Compositor::update`] may defer it), and keeping
/// `coverage` (buffers per tile) up to date when given.
fn mark_changes_by(
    lights: &[CompositeInput],
    seen: &mut [(Vec3, u64, Vec<u32>)],
    tiles_x: usize,
    n_tiles: usize,
    mut coverage: Option<&mut Vec<u32>>,
    mut mark: impl FnMut(usize, bool),
) -> usize {
    let mut changed = 0;
    for (l, (k, generation, covered)) in lights.iter().zip(seen.iter_mut()) {
        // NaN != NaN: the first update always counts as a change.
        if *k == l.k && *generation == l.generation {
            continue;
        }
        changed += 1;
        let k_changed = *k != l.k;
        // The tiles the light's old buffer covered need recomposing too;
        // its tile list is rebuilt only when the buffer was replaced.
        for &t in covered.iter() {
            mark(t as usize, k_changed);
        }
        if *generation != l.generation {
            if let Some(c) = coverage.as_deref_mut() {
                covered.iter().for_each(|&t| c[t as usize] = c[t as usize].saturating_sub(1));
            }
            *covered = covered_tiles(l.buffer, tiles_x, n_tiles);
            for &t in covered.iter() {
                mark(t as usize, k_changed);
            }
            if let Some(c) = coverage.as_deref_mut() {
                covered.iter().for_each(|&t| c[t as usize] += 1);
            }
        }
        *k = l.k;
        *generation = l.generation;
    }
    changed
}

impl Compositor {
    /// A black frame of `width`×`height`.
    pub fn new(width: u32, height: u32, display: Display) -> Self {
        let n = (width * height) as usize;
        Self {
            width,
            height,
            display,
            linear: vec![Vec3::ZERO; n],
            srgb: vec![0; n * 3],
            seen: Vec::new(),
            layers: None,
            groups: Vec::new(),
            group_current: Vec::new(),
            regrouped: false,
            background: None,
            overlay: None,
            overlay_changed: false,
            deferred: Vec::new(),
            deferred_cursor: 0,
            coverage: Vec::new(),
            ms_per_cover: 0.0,
        }
    }

    /// The time an update spends on tiles whose only change is a new
    /// buffer (a build stage, a group's storage): past it the rest wait
    /// for the next frames ([`Compositor::update`]).
    pub const DEFERRED_BUDGET_MS: f64 = 6.0;

    /// Sets the dense term added to every pixel after the lights' composite
    /// and before encoding: `(generation, pixels)` (row-major, the frame's
    /// size), or `None`. The live clock's sum of the shared indirect
    /// layers ([`super::layers::LayerSum`]). A new generation re-encodes
    /// every tile at the next [`Compositor::update`]; nothing is
    /// recomposed for it. [`Compositor::linear`] stays the lights' sum
    /// without it. Not used by [`Compositor::update_layers`] (haze).
    ///
    /// # Panics
    /// If the pixels are not the frame's size.
    pub fn set_overlay(&mut self, overlay: Option<(u64, Arc<Vec<Vec3>>)>) {
        if let Some((_, o)) = &overlay {
            assert_eq!(o.len(), self.linear.len(), "overlay size");
        }
        let before = self.overlay.as_ref().map(|(g, _)| *g);
        if before != overlay.as_ref().map(|(g, _)| *g) {
            self.overlay_changed = true;
        }
        self.overlay = overlay;
    }

    /// This compositor with emitter groups of the given members (indices
    /// into the lights of [`Compositor::update`], in cell order; groups of
    /// fewer than two are left out) whose storage is built in the
    /// background: each update takes the storages finished since the last
    /// one and starts rebuilding stale groups that are lit (any k ≠ 0), at
    /// most two at a time, from copies of their members' buffers. Until a
    /// group's storage is current its cells composite per light, exactly.
    /// The live clock's call: one group per fixture with cells.
    pub fn with_group_members(mut self, members: Vec<Vec<usize>>, settings: GroupSettings) -> Self {
        let (w, h) = (self.width, self.height);
        let empty = Arc::new(GroupBuffer::empty(w, h));
        let groups: Vec<CompositeGroup> = members
            .into_iter()
            .filter(|m| m.len() > 1)
            .map(|members| CompositeGroup {
                generations: vec![u64::MAX; members.len()],
                members,
                storage: empty.clone(),
            })
            .collect();
        let (tx, rx) = std::sync::mpsc::channel();
        let epoch = self.background.as_ref().map_or(0, |b| b.epoch + 1);
        let pool = self.background.as_ref().map_or_else(Background::pool, |b| b.pool.clone());
        self.background = Some(Background { settings, tx, rx, in_flight: vec![false; groups.len()], epoch, pool });
        self.set_groups(groups);
        self
    }

    /// Takes the group storages finished in the background and starts
    /// rebuilds of lit stale groups (see [`Compositor::with_group_members`]).
    fn poll_background(&mut self, lights: &[CompositeInput], shared: &[(u64, Arc<LightBuffer>)]) {
        let Some(bg) = self.background.as_mut() else { return };
        while let Ok((gi, epoch, group)) = bg.rx.try_recv() {
            if epoch != bg.epoch || gi >= self.groups.len() {
                continue;
            }
            bg.in_flight[gi] = false;
            if group.members == self.groups[gi].members {
                self.groups[gi] = group;
            }
        }
        let mut running = bg.in_flight.iter().filter(|&&f| f).count();
        for (gi, g) in self.groups.iter().enumerate() {
            if running >= Background::MAX_IN_FLIGHT {
                break;
            }
            let lit = g.members.iter().any(|&m| lights.get(m).is_some_and(|l| l.k != Vec3::ZERO));
            if bg.in_flight[gi] || !lit || g.is_current(lights) || g.members.iter().any(|&m| m >= lights.len()) {
                continue;
            }
            // The caller's shared handle where it is this very buffer, else a
            // copy. (Copying every cell's buffer on the frame clock took
            // 100-200 ms frames on the festival show while its direct stages
            // published: two groups of 40 cells at once.)
            let buffers: Vec<Arc<LightBuffer>> = g
                .members
                .iter()
                .map(|&m| match shared.get(m) {
                    Some((_, b)) if std::ptr::eq(Arc::as_ptr(b), lights[m].buffer) => b.clone(),
                    _ => Arc::new(lights[m].buffer.clone()),
                })
                .collect();
            let generations: Vec<u64> = g.members.iter().map(|&m| lights[m].generation).collect();
            let (members, settings, tx, epoch) = (g.members.clone(), bg.settings, bg.tx.clone(), bg.epoch);
            bg.in_flight[gi] = true;
            running += 1;
            bg.pool.spawn(move || {
                let refs: Vec<&LightBuffer> = buffers.iter().map(|b| &**b).collect();
                let storage = Arc::new(GroupBuffer::build(&refs, settings));
                // The compositor may be gone: nothing to deliver to then.
                let _ = tx.send((gi, epoch, CompositeGroup { members, generations, storage }));
            });
        }
    }

    /// Sets the emitter groups (replacing any): each group's cells are
    /// composited through its storage while it is current. The next
    /// [`Compositor::update`] recomposes the whole frame. Lights in no
    /// group keep the per-light path. Not used by
    /// [`Compositor::update_layers`] (haze), which stays per light.
    ///
    /// # Panics
    /// If a light is a member of two groups (it would count twice).
    pub fn set_groups(&mut self, groups: Vec<CompositeGroup>) {
        let mut seen = std::collections::HashSet::new();
        for g in &groups {
            for &m in &g.members {
                assert!(seen.insert(m), "light {m} is in two groups");
            }
        }
        if let Some(bg) = self.background.as_mut() {
            // Rebuilds in flight were for the old groups: dropped on arrival.
            bg.epoch += 1;
            bg.in_flight = vec![false; groups.len()];
        }
        self.groups = groups;
        self.group_current.clear();
        self.regrouped = true;
    }

    /// The emitter groups.
    pub fn groups(&self) -> &[CompositeGroup] {
        &self.groups
    }

    /// Rebuilds the storage of every group one of whose members was
    /// rebuilt (another generation) from the members' current buffers;
    /// returns how many were rebuilt. Until then such a group composites
    /// per light (exact); the next [`Compositor::update`] recomposes the
    /// rebuilt groups' tiles.
    pub fn rebuild_stale_groups(&mut self, lights: &[CompositeInput], settings: GroupSettings) -> usize {
        let mut rebuilt = 0;
        for g in &mut self.groups {
            if !g.is_current(lights) && g.members.iter().all(|&m| m < lights.len()) && !g.members.is_empty() {
                *g = CompositeGroup::build(lights, std::mem::take(&mut g.members), settings);
                rebuilt += 1;
            }
        }
        rebuilt
    }

    /// Bytes of the groups' storage.
    pub fn group_bytes(&self) -> usize {
        self.groups.iter().map(|g| g.storage.bytes()).sum()
    }

    /// Marks in `dirty` every tile of the groups whose storage became
    /// current or stale since the last update, and records the state.
    fn mark_group_changes(&mut self, lights: &[CompositeInput], dirty: &mut [bool]) {
        let current: Vec<bool> = self.groups.iter().map(|g| g.is_current(lights)).collect();
        if self.group_current.len() == current.len() {
            for (g, (now, before)) in self.groups.iter().zip(current.iter().zip(&self.group_current)) {
                if now != before {
                    for &t in g.members.iter().filter_map(|&m| self.seen.get(m)).flat_map(|s| s.2.iter()) {
                        dirty[t as usize] = true;
                    }
                }
            }
        } else {
            dirty.fill(true);
        }
        self.group_current = current;
    }

    /// The display settings the sRGB pixels are encoded with.
    pub fn display(&self) -> Display {
        self.display
    }

    /// Frame width.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Frame height.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The current linear frame (cd/m²).
    pub fn linear(&self) -> &[Vec3] {
        &self.linear
    }

    /// The current frame as 8-bit sRGB, row-major RGB.
    pub fn srgb8(&self) -> &[u8] {
        &self.srgb
    }

    /// Changes exposure, white balance and roll-off (re-encodes every pixel,
    /// recomposes nothing).
    pub fn set_display(&mut self, display: Display) {
        self.display = display;
        let overlay = self.overlay.as_ref().map(|(_, o)| o.as_slice());
        encode_all(&self.display, &self.linear, overlay, &mut self.srgb);
    }

    /// Brings the frame up to date with `lights` (stable order: index i is
    /// the same light every call; a changed count recomposes everything),
    /// plus the overlay ([`Compositor::set_overlay`]).
    ///
    /// **Budget.** Tiles a k_i change touches (a desk change) are
    /// recomposed in this very update. Tiles whose only change is a new
    /// buffer (a build stage published, a group's storage became current
    /// or stale) are recomposed up to [`Compositor::DEFERRED_BUDGET_MS`] of
    /// composite time (a tile costs 1 + the buffers covering it, timed per
    /// buffer over recent updates); a tile that would pass the budget
    /// waits, except the first one waiting (so every update makes
    /// progress). The rest wait for the next updates, taken round robin, and
    /// [`UpdateStats::deferred`] counts them. On the festival show a batch
    /// of cells publishing at once dirtied 500 tiles under ~340 buffers
    /// each: 190 ms on the frame clock. Every tile is recomposed from
    /// scratch whenever it is taken, so nothing drifts, and a tile shows
    /// either its old or its new buffers' sum, never a mix within a light.
    pub fn update(&mut self, lights: &[CompositeInput]) -> UpdateStats {
        self.update_sharing(lights, &[])
    }

    /// [`Compositor::update`] where the caller holds the lights' buffers
    /// as shared handles, `shared[i]` = (generation, buffer) of light i (the
    /// frame clock's entries): a stale group's background rebuild takes
    /// its cells' handles instead of copying every cell's buffer on the
    /// caller's thread (festival show: two groups of 40 cells at once made
    /// 100-200 ms frames). A light without a handle (or another buffer
    /// there) is copied.
    pub fn update_sharing(&mut self, lights: &[CompositeInput], shared: &[(u64, Arc<LightBuffer>)]) -> UpdateStats {
        let start = std::time::Instant::now();
        let w = self.width as usize;
        let tiles_x = w.div_ceil(TILE);
        let tiles_y = (self.height as usize).div_ceil(TILE);
        let n_tiles = tiles_x * tiles_y;
        let mut dirty = vec![false; n_tiles];
        if self.deferred.len() != n_tiles {
            self.deferred = vec![false; n_tiles];
        }
        self.poll_background(lights, shared);
        // Coming from layers, every entry is new.
        let full = self.layers.take().is_some() || self.seen.len() != lights.len() || self.regrouped;
        if full || self.coverage.len() != n_tiles {
            dirty.fill(true);
            self.seen = lights.iter().map(|_| (Vec3::NAN, u64::MAX, Vec::new())).collect();
            self.coverage = vec![0; n_tiles];
            self.regrouped = false;
        }
        let deferred = &mut self.deferred;
        let changed = mark_changes_by(lights, &mut self.seen, tiles_x, n_tiles, Some(&mut self.coverage), |t, now| {
            if now { dirty[t] = true } else { deferred[t] = true }
        });
        let mut regrouped = vec![false; n_tiles];
        self.mark_group_changes(lights, &mut regrouped);
        self.deferred.iter_mut().zip(&regrouped).for_each(|(d, r)| *d |= *r);
        self.take_deferred(&mut dirty);
        let tiles = dirty.iter().filter(|&&d| d).count();
        let left = self.deferred.iter().filter(|&&d| d).count();
        let reencode = std::mem::take(&mut self.overlay_changed);
        if tiles == 0 && !reencode {
            return UpdateStats { tiles, changed_lights: changed, deferred: left };
        }
        let covers: u64 = dirty.iter().zip(&self.coverage).filter(|(d, _)| **d).map(|(_, &c)| u64::from(c) + 1).sum();
        let stats = self.compose(lights, &dirty, tiles, reencode, changed);
        if covers > 0 {
            let ms = start.elapsed().as_secs_f64() * 1e3 / covers as f64;
            self.ms_per_cover = if self.ms_per_cover > 0.0 { 0.7 * self.ms_per_cover + 0.3 * ms } else { ms };
        }
        UpdateStats { deferred: self.deferred.iter().filter(|&&d| d).count(), ..stats }
    }

    /// Moves deferred tiles into `dirty`: every one `dirty` already has,
    /// then round robin up to the budget.
    fn take_deferred(&mut self, dirty: &mut [bool]) {
        let n = dirty.len();
        for (d, now) in self.deferred.iter_mut().zip(dirty.iter()) {
            if *now {
                *d = false;
            }
        }
        let waiting = self.deferred.iter().filter(|&&d| d).count();
        if waiting == 0 {
            return;
        }
        // The budget in covering buffers (a tile's cost: 1 + the buffers covering it).
        let budget = if self.ms_per_cover > 0.0 { Self::DEFERRED_BUDGET_MS / self.ms_per_cover } else { f64::INFINITY };
        // Until the next tile would pass the budget; the first is always
        // taken, so every update makes progress.
        let (mut taken, mut spent) = (0, 0.0);
        for step in 0..n {
            let t = (self.deferred_cursor + step) % n;
            if self.deferred[t] {
                let cost = f64::from(self.coverage.get(t).copied().unwrap_or(0)) + 1.0;
                if taken > 0 && spent + cost > budget {
                    self.deferred_cursor = t;
                    return;
                }
                self.deferred[t] = false;
                dirty[t] = true;
                taken += 1;
                spent += cost;
            }
        }
    }

    /// Recomposes the `dirty` tiles (`tiles` of them) and encodes them
    /// (every tile when `reencode`: the overlay changed).
    fn compose(
        &mut self,
        lights: &[CompositeInput],
        dirty: &[bool],
        tiles: usize,
        reencode: bool,
        changed: usize,
    ) -> UpdateStats {
        let w = self.width as usize;
        let tiles_x = w.div_ceil(TILE);
        let n_tiles = dirty.len();
        let parts = frame_parts(&self.groups, &self.group_current, lights);
        let display = self.display;
        let overlay = self.overlay.as_ref().map(|(_, o)| o.as_slice());
        if tiles * 2 > n_tiles {
            // Most of the frame changed (a grand-master fade): one full pass
            // is cheaper than tile-by-tile recomposing and encoding.
            parts.composite_into(self.width, self.height, &mut self.linear);
            encode_all(&display, &self.linear, overlay, &mut self.srgb);
            // Every tile is current now.
            self.deferred.fill(false);
            return UpdateStats { tiles: if reencode { n_tiles } else { tiles }, changed_lights: changed, deferred: 0 };
        }
        self.linear.par_chunks_mut(w * TILE).zip(self.srgb.par_chunks_mut(w * TILE * 3)).enumerate().for_each(
            |(ty, (band, band_srgb))| {
                let rows = band.len() / w.max(1);
                let start = ty * TILE * w;
                for tx in (0..tiles_x).filter(|tx| reencode || dirty[ty * tiles_x + tx]) {
                    let x0 = tx * TILE;
                    let cols = TILE.min(w - x0);
                    if dirty[ty * tiles_x + tx] {
                        for r in 0..rows {
                            band[r * w + x0..r * w + x0 + cols].fill(Vec3::ZERO);
                        }
                        parts.accumulate_tile(tx, ty, w, band);
                    }
                    for r in 0..rows {
                        let px = r * w + x0;
                        let over = overlay.map(|o| &o[start + px..start + px + cols]);
                        encode_span_with(&display, &band[px..px + cols], over, &mut band_srgb[px * 3..(px + cols) * 3]);
                    }
                }
            },
        );
        UpdateStats { tiles: if reencode { n_tiles } else { tiles }, changed_lights: changed, deferred: 0 }
    }

    /// Brings the frame up to date with lights in weighted layers: I = Σ_j
    /// w_j Σ_i k_i ⊙ buffer_ij. `lights` holds `weights.len()` blocks of the
    /// same number of entries (block j is layer j, entry i the same light in
    /// every block); their k are the layer's own (unweighted). Used for haze,
    /// whose density knots are the layers (`live::clock::FrameEntries`): each
    /// layer's sum is kept, tile-incrementally as in [`Compositor::update`],
    /// so a hazer change (new weights, same k) only recombines the sums,
    /// O(pixels), instead of recomposing every light's buffers. A layer of
    /// weight 0 is not kept up to date; it is rebuilt (one full composite
    /// of that layer) when its weight becomes non-zero.
    pub fn update_layers(&mut self, lights: &[CompositeInput], weights: &[f32]) -> UpdateStats {
        let w = self.width as usize;
        let tiles_x = w.div_ceil(TILE);
        let n_tiles = tiles_x * (self.height as usize).div_ceil(TILE);
        let layers = weights.len().max(1);
        let per_layer = lights.len() / layers;
        assert_eq!(per_layer * layers, lights.len(), "one block of lights per layer");
        let fresh = !matches!(&self.layers, Some(l) if l.lights == per_layer && l.sums.len() == layers)
            || self.seen.len() != lights.len();
        if fresh {
            self.layers =
                Some(LayerSums { lights: per_layer, weights: vec![f32::NAN; layers], sums: vec![None; layers] });
            self.seen = lights.iter().map(|_| (Vec3::NAN, u64::MAX, Vec::new())).collect();
        }
        let Some(state) = self.layers.as_mut() else { return UpdateStats::default() };
        let (width, height) = (self.width, self.height);
        // Recombine every tile after a weight change or a rebuilt layer.
        let mut all = false;
        let mut dirty = vec![false; n_tiles];
        let mut changed = 0;
        for (j, &wj) in weights.iter().enumerate() {
            let block = &lights[j * per_layer..(j + 1) * per_layer];
            let seen = &mut self.seen[j * per_layer..(j + 1) * per_layer];
            if wj != state.weights[j] && !(wj == 0.0 && state.weights[j] == 0.0) {
                all = true;
                changed += block.len();
            }
            if wj == 0.0 {
                state.sums[j] = None;
                continue;
            }
            let buffers: Vec<&LightBuffer> = block.iter().map(|l| l.buffer).collect();
            let k: Vec<Vec3> = block.iter().map(|l| l.k).collect();
            let Some(sum) = state.sums[j].as_mut() else {
                // Not kept while its weight was 0: one full composite.
                let mut sum = vec![Vec3::ZERO; w * height as usize];
                composite_into(&buffers, &k, width, height, &mut sum);
                for (l, s) in block.iter().zip(seen.iter_mut()) {
                    *s = (l.k, l.generation, covered_tiles(l.buffer, tiles_x, n_tiles));
                }
                state.sums[j] = Some(sum);
                all = true;
                continue;
            };
            let mut layer_dirty = vec![false; n_tiles];
            let moved = mark_changes(block, seen, tiles_x, &mut layer_dirty);
            if !all {
                changed += moved;
            }
            let count = layer_dirty.iter().filter(|&&d| d).count();
            if count * 2 > n_tiles {
                composite_into(&buffers, &k, width, height, sum);
            } else if count > 0 {
                let active = active_lights(&buffers, &k);
                sum.par_chunks_mut(w * TILE).enumerate().for_each(|(ty, band)| {
                    let rows = band.len() / w.max(1);
                    for tx in (0..tiles_x).filter(|tx| layer_dirty[ty * tiles_x + tx]) {
                        let (x0, cols) = (tx * TILE, TILE.min(w - tx * TILE));
                        for r in 0..rows {
                            band[r * w + x0..r * w + x0 + cols].fill(Vec3::ZERO);
                        }
                        accumulate_tile(&active, tx, ty, w, band);
                    }
                });
            }
            dirty.iter_mut().zip(&layer_dirty).for_each(|(d, l)| *d |= *l);
        }
        state.weights = weights.to_vec();
        let tiles = if all { n_tiles } else { dirty.iter().filter(|&&d| d).count() };
        if tiles == 0 {
            return UpdateStats { tiles, changed_lights: changed, deferred: 0 };
        }
        // I = Σ_j w_j S_j over the layers that count (in layer order).
        let live: Vec<(f32, &[Vec3])> = weights
            .iter()
            .zip(&state.sums)
            .filter_map(|(&wj, s)| s.as_deref().filter(|_| wj != 0.0).map(|s| (wj, s)))
            .collect();
        let display = self.display;
        self.linear.par_chunks_mut(w * TILE).zip(self.srgb.par_chunks_mut(w * TILE * 3)).enumerate().for_each(
            |(ty, (band, band_srgb))| {
                let rows = band.len() / w.max(1);
                let start = ty * TILE * w;
                for tx in (0..tiles_x).filter(|tx| all || dirty[ty * tiles_x + tx]) {
                    let (x0, cols) = (tx * TILE, TILE.min(w - tx * TILE));
                    for r in 0..rows {
                        let px = r * w + x0;
                        for (p, out) in band[px..px + cols].iter_mut().enumerate() {
                            *out = live.iter().fold(Vec3::ZERO, |acc, (wj, s)| acc + *wj * s[start + px + p]);
                        }
                        display.encode_span(&band[px..px + cols], &mut band_srgb[px * 3..(px + cols) * 3]);
                    }
                }
            },
        );
        UpdateStats { tiles, changed_lights: changed, deferred: 0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn buffers(w: u32, h: u32) -> (LightBuffer, LightBuffer) {
        let a: Vec<Vec3> = (0..w * h).map(|i| Vec3::new(i as f32, 0.5, 0.0)).collect();
        let mut b = vec![Vec3::ZERO; (w * h) as usize];
        b[100] = Vec3::ONE;
        (LightBuffer::from_dense(w, h, &a), LightBuffer::from_dense(w, h, &b))
    }

    #[test]
    fn weighted_sum_of_sparse_buffers() {
        let (w, h) = (35u32, 19u32);
        let (ba, bb) = buffers(w, h);
        let (a, b) = (ba.to_dense(), bb.to_dense());
        let k = [Vec3::new(2.0, 1.0, 3.0), Vec3::splat(10.0)];
        let out = composite(&[&ba, &bb], &k, w, h);
        for i in 0..(w * h) as usize {
            let expect = k[0] * a[i] + k[1] * b[i];
            assert!((out[i] - expect).length() <= 1e-4 * expect.length().max(1.0), "{i}");
        }
        // A dark light costs nothing and adds nothing.
        let out2 = composite(&[&ba, &bb], &[Vec3::ZERO, Vec3::ZERO], w, h);
        assert!(out2.iter().all(|v| *v == Vec3::ZERO));
    }

    /// The tile-by-tile path encodes with the display's roll-off like a full
    /// encode, and a live `set_display` re-encodes without recomposing.
    #[test]
    fn incremental_updates_roll_off_like_a_full_encode() {
        let (w, h) = (50u32, 40u32);
        let (ba, bb) = buffers(w, h);
        let display = Display::for_white_lux(50.0).with_rolloff(Some(Default::default()));
        let mut c = Compositor::new(w, h, display);
        let inputs = |kb: f32| {
            [
                CompositeInput { buffer: &ba, generation: 0, k: Vec3::splat(0.05) },
                CompositeInput { buffer: &bb, generation: 0, k: Vec3::splat(kb) },
            ]
        };
        c.update(&inputs(2.0));
        // One tile, far over white.
        let s = c.update(&inputs(4000.0));
        assert_eq!(s.tiles, 1);
        let full = composite(&[&ba, &bb], &[Vec3::splat(0.05), Vec3::splat(4000.0)], w, h);
        assert_eq!(c.srgb8(), &display.to_srgb8(&full)[..]);
        // 250× white: the brightest channel (blue, after the tungsten white
        // balance) at white, the others keep their ratio to it (hue kept) ...
        assert!(c.srgb8()[300] < 200 && c.srgb8()[302] == 255, "{:?}", &c.srgb8()[300..303]);
        let clip = Display { rolloff: None, ..display };
        c.set_display(clip);
        assert_eq!(c.srgb8(), &clip.to_srgb8(&full)[..]);
        // ... where clipping shows white in all three.
        assert_eq!(&c.srgb8()[300..303], &[255, 255, 255]);
        assert_eq!(c.linear(), &full[..]);
    }

    #[test]
    fn incremental_updates_match_full_composites_and_touch_only_changed_tiles() {
        let (w, h) = (50u32, 40u32);
        let (ba, bb) = buffers(w, h);
        let display = Display::for_white_lux(50.0);
        let mut c = Compositor::new(w, h, display);
        let mut k = [Vec3::splat(0.01), Vec3::splat(2.0)];
        let first = c.update(&[
            CompositeInput { buffer: &ba, generation: 0, k: k[0] },
            CompositeInput { buffer: &bb, generation: 0, k: k[1] },
        ]);
        assert_eq!(first.tiles, 4 * 3);
        for step in 0..5 {
            // Move only light b's fader: one tile changes.
            k[1] = Vec3::splat(step as f32 * 0.7);
            let s = c.update(&[
                CompositeInput { buffer: &ba, generation: 0, k: k[0] },
                CompositeInput { buffer: &bb, generation: 0, k: k[1] },
            ]);
            assert_eq!((s.tiles, s.changed_lights), (1, 1));
            let full = composite(&[&ba, &bb], &k, w, h);
            assert_eq!(c.linear(), &full[..]);
            assert_eq!(c.srgb8(), &display.to_srgb8(&full)[..]);
        }
        let idle = c.update(&[
            CompositeInput { buffer: &ba, generation: 0, k: k[0] },
            CompositeInput { buffer: &bb, generation: 0, k: k[1] },
        ]);
        assert_eq!(idle, UpdateStats::default());
        // A rebuilt buffer that moved clears its old tiles.
        let empty = LightBuffer::empty(w, h);
        c.update(&[
            CompositeInput { buffer: &ba, generation: 0, k: k[0] },
            CompositeInput { buffer: &empty, generation: 1, k: k[1] },
        ]);
        assert_eq!(c.linear(), &composite(&[&ba], &k[..1], w, h)[..]);
    }

    /// Layers (haze knots): the kept sums, recombined with new weights,
    /// equal a full composite of every entry with k_i w_j; a k change
    /// recomposes only its tiles; a layer whose weight was 0 is rebuilt
    /// when it comes back; one layer of weight 1 is that layer's sum exactly.
    #[test]
    fn layers_recombine_like_a_weighted_full_composite() {
        let (w, h) = (50u32, 40u32);
        let (ba, bb) = buffers(w, h);
        let bc =
            LightBuffer::from_dense(w, h, &(0..w * h).map(|i| Vec3::new(0.0, (i % 7) as f32, 1.0)).collect::<Vec<_>>());
        // Layer j, light i: the buffers of the 3 knots of 2 lights.
        let layer_buffers = [[&ba, &bb], [&bc, &bb], [&ba, &bc]];
        let display = Display::for_white_lux(50.0);
        let mut c = Compositor::new(w, h, display);
        let entries = |k: [Vec3; 2], generation: u64| -> Vec<CompositeInput> {
            layer_buffers
                .iter()
                .flat_map(|pair| pair.iter().zip(k).map(move |(b, k)| CompositeInput { buffer: b, generation, k }))
                .collect()
        };
        let full = |k: [Vec3; 2], weights: [f32; 3]| {
            let refs: Vec<&LightBuffer> = layer_buffers.iter().flatten().copied().collect();
            let ks: Vec<Vec3> = weights.iter().flat_map(|wj| k.map(|k| k * *wj)).collect();
            composite(&refs, &ks, w, h)
        };
        let close = |got: &[Vec3], want: &[Vec3]| {
            for (i, (a, b)) in got.iter().zip(want).enumerate() {
                assert!(
                    (*a - *b).abs().max_element() <= 1e-5 * b.abs().max_element().max(1.0),
                    "pixel {i}: {a} vs {b}"
                );
            }
        };
        let mut k = [Vec3::splat(0.01), Vec3::splat(2.0)];
        let all_tiles = 4 * 3;
        let first = c.update_layers(&entries(k, 0), &[0.5, 0.5, 0.0]);
        assert_eq!(first.tiles, all_tiles);
        close(c.linear(), &full(k, [0.5, 0.5, 0.0]));
        // Light b's fader: only layer 0's single lit tile of bb and layer 1's
        // (the same tile) change; the kept layers are not recomposed.
        k[1] = Vec3::splat(3.0);
        let s = c.update_layers(&entries(k, 0), &[0.5, 0.5, 0.0]);
        assert_eq!((s.tiles, s.changed_lights), (1, 2));
        close(c.linear(), &full(k, [0.5, 0.5, 0.0]));
        assert_eq!(c.srgb8(), &display.to_srgb8(c.linear())[..]);
        // A hazer change: weights only, every tile recombined; layer 2 (weight 0 so far) rebuilt.
        let s = c.update_layers(&entries(k, 0), &[0.0, 0.4, 0.6]);
        assert_eq!(s.tiles, all_tiles);
        assert!(s.changed_lights > 0);
        close(c.linear(), &full(k, [0.0, 0.4, 0.6]));
        // Light a's fader while layer 0 is not kept, then back to the
        // first weights: layer 0 is rebuilt with the new k.
        k[0] = Vec3::splat(0.2);
        c.update_layers(&entries(k, 0), &[0.0, 0.4, 0.6]);
        close(c.linear(), &full(k, [0.0, 0.4, 0.6]));
        c.update_layers(&entries(k, 0), &[0.5, 0.5, 0.0]);
        close(c.linear(), &full(k, [0.5, 0.5, 0.0]));
        // Nothing changed: nothing recomposed.
        assert_eq!(c.update_layers(&entries(k, 0), &[0.5, 0.5, 0.0]), UpdateStats::default());
        // One layer at weight 1 is exactly its sum (a rebuilt buffer: new generation).
        c.update_layers(&entries(k, 1), &[0.0, 0.0, 1.0]);
        assert_eq!(c.linear(), &composite(&[&ba, &bc], &k, w, h)[..]);
        // Back to plain updates: everything recomposed from the entries given.
        let plain = [CompositeInput { buffer: &ba, generation: 0, k: k[0] }];
        assert_eq!(c.update(&plain).tiles, all_tiles);
        assert_eq!(c.linear(), &composite(&[&ba], &k[..1], w, h)[..]);
    }

    /// The overlay (the shared layers' sum) is added before encoding: the
    /// sRGB pixels are the encoding of the lights' composite plus the
    /// overlay, after a full pass, after a tile-by-tile update and after an
    /// overlay change alone (which re-encodes every tile and recomposes
    /// nothing: `linear` stays the lights' sum); `None` drops it.
    #[test]
    fn the_overlay_is_added_before_encoding() {
        let (w, h) = (50u32, 40u32);
        let (ba, bb) = buffers(w, h);
        let display = Display::for_white_lux(50.0).with_rolloff(Some(Default::default()));
        let mut c = Compositor::new(w, h, display);
        let n = (w * h) as usize;
        let over = |v: f32| Arc::new((0..n).map(|i| Vec3::new(v, 0.5 * v, (i % 7) as f32 * v)).collect::<Vec<_>>());
        let expect = |lights: &[Vec3], o: &[Vec3]| {
            let sum: Vec<Vec3> = composite(&[&ba, &bb], lights, w, h).iter().zip(o).map(|(a, b)| *a + *b).collect();
            display.to_srgb8(&sum)
        };
        let k = [Vec3::new(0.02, 0.01, 0.03), Vec3::splat(40.0)];
        let lights = |k: &[Vec3; 2]| {
            [
                CompositeInput { buffer: &ba, generation: 0, k: k[0] },
                CompositeInput { buffer: &bb, generation: 0, k: k[1] },
            ]
        };
        let (o1, o2) = (over(3.0), over(7.0));
        c.set_overlay(Some((1, o1.clone())));
        c.update(&lights(&k));
        assert_eq!(c.srgb8(), &expect(&k, &o1)[..], "full pass");
        // The small light alone changes: one tile, with the overlay.
        let k2 = [k[0], Vec3::splat(90.0)];
        let stats = c.update(&lights(&k2));
        assert!(
            stats.tiles >= 1 && stats.tiles * 2 <= c.width().div_ceil(16) as usize * c.height().div_ceil(16) as usize
        );
        assert_eq!(c.srgb8(), &expect(&k2, &o1)[..], "tile by tile");
        // A new overlay alone: every tile re-encoded, nothing recomposed.
        let before = c.linear().to_vec();
        c.set_overlay(Some((2, o2.clone())));
        assert!(c.update(&lights(&k2)).tiles > 0);
        assert_eq!(c.linear(), &before[..], "the lights' sum is untouched");
        assert_eq!(c.srgb8(), &expect(&k2, &o2)[..], "overlay change");
        c.set_overlay(Some((2, o2.clone())));
        assert_eq!(c.update(&lights(&k2)).tiles, 0, "same generation: nothing to do");
        c.set_overlay(None);
        c.update(&lights(&k2));
        assert_eq!(c.srgb8(), &display.to_srgb8(&composite(&[&ba, &bb], &k2, w, h))[..], "no overlay");
    }

    /// New buffers past the budget wait for later updates, round robin,
    /// until every tile is current (then the frame equals a full
    /// composite); a k change is composited in the very update even while
    /// tiles wait.
    #[test]
    fn new_buffers_past_the_budget_wait_and_desk_changes_do_not() {
        let (w, h) = (320u32, 160u32); // 20 × 10 = 200 tiles
        let dense = |v: f32| LightBuffer::from_dense(w, h, &vec![Vec3::splat(v); (w * h) as usize]);
        let (a0, a1, b) = (dense(1.0), dense(2.0), dense(0.5));
        let mut c = Compositor::new(w, h, Display::neutral(100.0));
        let k = [Vec3::splat(3.0), Vec3::splat(5.0)];
        fn entries<'a>(a: &'a LightBuffer, ga: u64, b: &'a LightBuffer, k: [Vec3; 2]) -> [CompositeInput<'a>; 2] {
            [
                CompositeInput { buffer: a, generation: ga, k: k[0] },
                CompositeInput { buffer: b, generation: 0, k: k[1] },
            ]
        }
        c.update(&entries(&a0, 0, &b, k));
        assert_eq!(c.linear(), &composite(&[&a0, &b], &k, w, h)[..]);
        // Pretend a covering buffer costs 1/32 ms: a tile (2 buffers + 1) 3/32 ms, 64 tiles in 6 ms.
        c.ms_per_cover = 0.03125;
        let first = c.update(&entries(&a1, 1, &b, k));
        assert_eq!((first.tiles, first.deferred), (64, 136), "64 now, the rest later");
        assert!(c.linear().iter().any(|p| *p == Vec3::splat(3.0 + 2.5)), "old tiles still show");
        // The desk moves the other light meanwhile: all its tiles now.
        c.ms_per_cover = 0.03125;
        let k2 = [k[0], Vec3::splat(9.0)];
        let desk = c.update(&entries(&a1, 1, &b, k2));
        assert_eq!((desk.tiles, desk.deferred), (200, 0), "a k change is due in this frame");
        assert_eq!(c.linear(), &composite(&[&a1, &b], &k2, w, h)[..]);
        // Again, without a desk change: drained over the next updates.
        c.ms_per_cover = 0.03125;
        assert_eq!(c.update(&entries(&a0, 2, &b, k2)).deferred, 136);
        let mut updates = 1;
        loop {
            c.ms_per_cover = 0.03125;
            let u = c.update(&entries(&a0, 2, &b, k2));
            updates += 1;
            if u.deferred == 0 {
                break;
            }
            assert!(updates < 10, "never drained");
        }
        assert_eq!(updates, 4, "200 tiles at 64 a frame");
        assert_eq!(c.linear(), &composite(&[&a0, &b], &k2, w, h)[..]);
    }

    /// Tiles dearer than the budget are taken one per update (never a
    /// batch of them in one frame), and a cheap tile never passes the
    /// budget to follow a dear one.
    #[test]
    fn dear_tiles_past_the_budget_come_one_per_update() {
        let (w, h) = (64u32, 16u32); // 4 tiles
        let dense = |v: f32| LightBuffer::from_dense(w, h, &vec![Vec3::splat(v); (w * h) as usize]);
        let (a0, a1, b) = (dense(1.0), dense(2.0), dense(0.5));
        let k = [Vec3::ONE, Vec3::ONE];
        fn entries<'a>(a: &'a LightBuffer, ga: u64, b: &'a LightBuffer) -> [CompositeInput<'a>; 2] {
            [
                CompositeInput { buffer: a, generation: ga, k: Vec3::ONE },
                CompositeInput { buffer: b, generation: 0, k: Vec3::ONE },
            ]
        }
        let mut c = Compositor::new(w, h, Display::neutral(100.0));
        c.update(&entries(&a0, 0, &b));
        // At 1 ms per covering buffer a tile (2 buffers + 1) costs 3 ms: two fit the 6 ms budget.
        c.ms_per_cover = 1.0;
        assert_eq!(c.update(&entries(&a1, 1, &b)).tiles, 2, "two tiles of 3 ms fill the 6 ms budget");
        // At 4 ms per covering buffer a tile costs 12 ms, twice the budget: one per update.
        c.ms_per_cover = 4.0;
        let mut counts = Vec::new();
        loop {
            c.ms_per_cover = 4.0;
            let u = c.update(&entries(&a0, 2, &b));
            counts.push(u.tiles);
            if u.deferred == 0 {
                break;
            }
            assert!(counts.len() < 10, "never drained: {counts:?}");
        }
        assert_eq!(counts, vec![1, 1, 1, 1], "one dear tile per update");
        assert_eq!(c.linear(), &composite(&[&a0, &b], &k, w, h)[..]);
    }
}
