//! Scheduling the cells of one fixture (issue 14: pixel cells; issue 33:
//! the tracer only schedules). An LED bar's cells are lights of their own
//! (one unit buffer each, eq. 5), a few centimetres apart, and they are due
//! at the same moments: at start-up, after a view change, when the bar
//! moves. The build of a fixture's cells is [`GroupBuild`]'s (one pass over
//! the union of the cells' footprints, one photon leader for the cells
//! alike: [`crate::render::build::group`]); this module decides which cells
//! go into a pass and publishes each cell's result under its own request.
//!
//! The tracer's scheduling ([`super::schedule`]) is unchanged: it picks a
//! light and a stage. When that light is a cell of a fixture (a group set
//! by [`super::Tracer::set_groups`]) and other cells of the same fixture
//! are due for the same stage, the whole set is one [`GroupBuild::next`]:
//! - **direct stage**: every cell of the group with a pending request at
//!   the same quality (a moving bar's cells at moving quality, one pixel
//!   per 2×2 block, together too);
//! - **Whitted stage** (with the view's [`TileBounds::paths`] made once per
//!   view): every settled cell of the group whose build waits for its
//!   Whitted stage.
//!
//! Each cell keeps its own request id, [`LightBuild`] and buffer: after the
//! pass each buffer goes through the same steps as a cell built alone (haze
//! beam, publish under its request id, build kept for its later stages), so
//! a cell that moved again during the pass is refused at publish (never
//! shown stale) and its newer request is served next; the pass stops early
//! only when every cell in it was superseded. Cells of different fixtures
//! are never mixed.
//!
//! **Photons and refinement are shared** (issue 38: emitter groups that
//! share photon tracing; [`super::TracerSettings::share_indirect`]): when
//! a cell's photon stage is due, the other settled cells of its fixture
//! whose Whitted stage is done and whose beam and aim are the same
//! ([`indirect_alike`]; the leader is [`photon_leader`]'s, as in
//! [`GroupBuild`]) become its *followers* ([`gather_followers`]): they drop
//! their builds (no photon maps, no refinement state of their own) and
//! keep only their Whitted term. When the leader publishes its photon
//! estimate and its final picture (not each refinement pass) each follower
//! publishes its own Whitted term plus the leader's indirect term
//! ([`shared_indirect`], [`follower_sum`], [`lead`]) under its own request id and at the
//! leader's stage. A follower that moves leaves (its newer request is
//! served as usual); when the leader moves or fails, its followers are
//! released to trace photons of their own ([`release_orphans`]).

use super::{Request, Shared, Stage, after_direct, after_whitted, finished, new_build, report_bug, take_request};
use crate::Light;
use crate::live::cache::Finished;
use crate::render::View;
use crate::render::buffer::{LightBuffer, SharedLayer};
use crate::render::build::{
    BuildError, GroupBuild, LightBuild, NextStage, follower_sum, indirect_alike, only_here, photon_leader,
    shared_indirect,
};
use crate::render::footprint::DirectQuality;
use crate::render::footprint::TileBounds;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, Weak};
use std::time::Instant;

/// The tracer's fixture groups, the current view's path bounds and the
/// batch counters.
pub(super) struct Cells {
    /// Per light: the lights of its fixture (itself alone by default).
    groups: Mutex<Arc<Vec<Range<usize>>>>,
    /// The lights in a group of two or more, ascending: those that can
    /// show a shared layer ([`super::Tracer::shared_places`]).
    places: Mutex<Arc<Vec<usize>>>,
    /// [`TileBounds`] of the current view (made at the first Whitted pass),
    /// with a `Weak` to its view: it keeps no view alive (the view cache
    /// lets a view's caches go when nothing holds it), and the `Weak` keeps
    /// the allocation, so a new view never matches an old one's address.
    bounds: Mutex<Option<(Weak<View>, Arc<TileBounds>)>>,
    /// Passes that built two cells or more.
    passes: AtomicU64,
    /// Light stages built in those passes.
    lights: AtomicU64,
    /// Cells that followed another's photon stage (shared indirect term).
    followers: AtomicU64,
    /// Set when a lead is made, cleared by a [`release_orphans`] sweep that
    /// found none: the worker's per-job sweep is skipped while no cell
    /// leads or follows.
    sharing: AtomicBool,
}

impl Cells {
    /// `n` lights, each alone.
    pub(super) fn new(n: usize) -> Self {
        Self {
            groups: Mutex::new(Arc::new((0..n).map(|i| i..i + 1).collect())),
            bounds: Mutex::new(None),
            passes: AtomicU64::new(0),
            lights: AtomicU64::new(0),
            followers: AtomicU64::new(0),
            sharing: AtomicBool::new(false),
            places: Mutex::new(Arc::new(Vec::new())),
        }
    }

    /// Consecutive lights with the same `Some` fixture id form a group.
    pub(super) fn set_groups(&self, fixture: &[Option<u32>]) {
        let n = self.groups.lock().expect("groups lock").len();
        let id = |i: usize| fixture.get(i).copied().flatten();
        let mut groups = Vec::with_capacity(n);
        let mut start = 0;
        while start < n {
            let mut end = start + 1;
            while end < n && id(start).is_some() && id(end) == id(start) {
                end += 1;
            }
            groups.extend((start..end).map(|_| start..end));
            start = end;
        }
        let places = (0..n).filter(|&i| groups[i].len() >= 2).collect();
        *self.groups.lock().expect("groups lock") = Arc::new(groups);
        *self.places.lock().expect("places lock") = Arc::new(places);
    }

    /// The lights in a group of two or more, ascending.
    pub(super) fn places(&self) -> Arc<Vec<usize>> {
        self.places.lock().expect("places lock").clone()
    }

    /// The lights of light `index`'s fixture (itself alone by default).
    pub(super) fn group(&self, index: usize) -> Range<usize> {
        self.groups.lock().expect("groups lock").get(index).cloned().unwrap_or(index..index + 1)
    }

    /// The path bounds of `view`, made once per view.
    fn bounds(&self, view: &Arc<View>) -> Arc<TileBounds> {
        let mut kept = self.bounds.lock().expect("bounds lock");
        if let Some((v, b)) = kept.as_ref()
            && std::ptr::eq(v.as_ptr(), Arc::as_ptr(view))
        {
            return b.clone();
        }
        let b = Arc::new(TileBounds::paths(view));
        *kept = Some((Arc::downgrade(view), b.clone()));
        b
    }

    fn count(&self, lights: usize) {
        if lights >= 2 {
            self.passes.fetch_add(1, Ordering::SeqCst);
            self.lights.fetch_add(lights as u64, Ordering::SeqCst);
        }
    }

    fn count_followers(&self, n: usize) {
        self.followers.fetch_add(n as u64, Ordering::SeqCst);
    }

    /// Cells that followed another's photon stage so far.
    pub(super) fn followers(&self) -> u64 {
        self.followers.load(Ordering::SeqCst)
    }

    pub(super) fn passes(&self) -> u64 {
        self.passes.load(Ordering::SeqCst)
    }

    pub(super) fn lights(&self) -> u64 {
        self.lights.load(Ordering::SeqCst)
    }
}

/// The cells of light `index`'s fixture when they may be built together
/// (batching on, two cells or more); `None`: the caller builds it alone.
fn batch_group(s: &Shared, index: usize) -> Option<Range<usize>> {
    let group = s.cells.group(index);
    (s.settings.batch_cells && group.len() >= 2).then_some(group)
}

/// The direct stage of light `index` together with every other cell of
/// its fixture that has a request waiting at the same quality (full, or
/// moving for cells in motion; every cell at moving quality with `rush`,
/// [`super::rushed`]). False (nothing
/// done) when fewer than two cells are due: the caller builds `index` alone.
pub(super) fn direct_batch(s: &Shared, index: usize, rush: bool) -> bool {
    let Some(group) = batch_group(s, index) else { return false };
    // Due: a request waits; in motion or not (the quality of its stage).
    let due = |j: usize| {
        let st = s.slots[j].state.lock().expect("slot lock");
        st.pending
            .as_ref()
            .map(|r| rush || st.previous_move.is_some_and(|p| r.at.duration_since(p) < s.settings.settle))
    };
    let Some(moving) = due(index) else { return false };
    let members: Vec<usize> = group.filter(|&j| due(j) == Some(moving)).collect();
    if members.len() < 2 {
        return false;
    }
    // Only the worker takes requests: each member's is still there.
    let mut taken: Vec<(usize, Request, Instant, Option<LightBuild>)> = members
        .into_iter()
        .filter_map(|j| {
            let (req, since, _) = take_request(s, j)?;
            let build = new_build(s, j, &req);
            Some((j, req, since, Some(build)))
        })
        .collect();
    for (j, ..) in &taken {
        s.injected_panic(*j);
    }
    let view = s.view();
    s.builds.fetch_add(taken.len() as u64, Ordering::SeqCst);
    s.cells.count(taken.len());
    let quality = if moving { DirectQuality::Moving } else { DirectQuality::Full };
    let builds = taken.iter_mut().filter_map(|t| t.3.take()).map(|b| b.with_direct_first(quality)).collect();
    let mut group = GroupBuild::new(builds, false);
    let bounds = s.cells.bounds(&view);
    // Every cell superseded (their newer requests wait) or shutdown.
    let Ok(steps) = s.stage_pool().install(|| group.next(&s.scene, &view, &bounds)) else { return true };
    let mut builds = group.into_builds();
    for step in steps {
        let (j, req, since, _) = &mut taken[step.member];
        let Some(build) = builds[step.member].take() else {
            if let Err(e) = &step.step {
                report_bug(s, *j, e);
            }
            continue;
        };
        if build.cancel().fired() {
            continue; // moved during the pass: its newer request is served next
        }
        let Ok(step) = step.step else { continue };
        let share = step.footprint.map_or(0.0, |f| f.tiles_in_beam as f32 / f.tiles.max(1) as f32);
        let req = Request { id: req.id, light: req.light.clone(), at: req.at };
        after_direct(s, *j, req, *since, build, step.buffer, share);
    }
    true
}

/// The Whitted stage of light `index` together with every other settled
/// cell of its fixture whose build waits for its Whitted stage. False
/// (nothing done) when fewer than two are: the caller goes on alone.
pub(super) fn whitted_batch(s: &Shared, index: usize) -> bool {
    let Some(group) = batch_group(s, index) else { return false };
    let now = Instant::now();
    let due = |j: usize| {
        let st = s.slots[j].state.lock().expect("slot lock");
        st.pending.is_none()
            && st.build.as_ref().is_some_and(|(_, b, _)| b.next_stage() == Some(NextStage::Whitted))
            && st.last_move.is_none_or(|t| now.duration_since(t) >= s.settings.settle)
    };
    if !due(index) {
        return false;
    }
    let members: Vec<usize> = group.filter(|&j| due(j)).collect();
    if members.len() < 2 {
        return false;
    }
    let taken: Vec<(usize, u64, LightBuild, Instant)> = members
        .into_iter()
        .filter_map(|j| {
            let slot = &s.slots[j];
            let (id, build, at) = slot.state.lock().expect("slot lock").build.take()?;
            (slot.latest.load(Ordering::SeqCst) == id).then_some((j, id, build, at))
        })
        .collect();
    for (j, ..) in &taken {
        s.injected_panic(*j);
    }
    let view = s.view();
    let bounds = s.cells.bounds(&view);
    s.cells.count(taken.len());
    let ids: Vec<(usize, u64, Instant)> = taken.iter().map(|t| (t.0, t.1, t.3)).collect();
    let mut group = GroupBuild::new(taken.into_iter().map(|t| t.2).collect(), false);
    let Ok(steps) = s.stage_pool().install(|| group.next(&s.scene, &view, &bounds)) else { return true };
    let mut builds = group.into_builds();
    for step in steps {
        let (j, id, at) = ids[step.member];
        let Some(build) = builds[step.member].take() else {
            if let Err(e) = &step.step {
                report_bug(s, j, e);
            }
            continue;
        };
        if build.cancel().fired() {
            continue;
        }
        let Ok(step) = step.step else { continue };
        after_whitted(s, j, id, build, step.buffer, at);
    }
    true
}

/// A cell following another of its fixture through the photon and
/// refinement stages (module doc).
pub(super) struct Follow {
    /// The leader's light index.
    leader: usize,
    /// The leader's request id it follows.
    leader_id: u64,
    /// This cell's request id, geometry, and when the request arrived.
    id: u64,
    light: Light,
    at: Instant,
    /// This cell's own Whitted term (what it shows with the shared layer).
    whitted: Arc<LightBuffer>,
}

impl Follow {
    /// Bytes held (its Whitted term, unless it is also published).
    pub(super) fn bytes(&self) -> usize {
        only_here(&self.whitted)
    }
}

/// A cell leading others of its fixture (module doc).
#[derive(Clone)]
pub(super) struct Lead {
    /// The request id it leads under.
    id: u64,
    /// Its own Whitted term (its buffer less this is the shared indirect term).
    whitted: Arc<LightBuffer>,
    /// Its followers' light indices.
    followers: Vec<usize>,
}

impl Lead {
    /// Bytes held (its Whitted term, unless it is also published).
    pub(super) fn bytes(&self) -> usize {
        only_here(&self.whitted)
    }
}

/// Light `j`'s build (state `st`, under its lock) when it waits for its
/// photon stage and may lead or follow: settled, nothing pending, its
/// Whitted term done, photons configured, neither leading nor following.
fn photon_due<'a>(s: &Shared, j: usize, st: &'a super::SlotState, now: Instant) -> Option<&'a LightBuild> {
    let settled = st.last_move.is_none_or(|t| now.duration_since(t) >= s.settings.settle);
    if st.pending.is_some() || st.follow.is_some() || st.lead.is_some() || !settled {
        return None;
    }
    st.build
        .as_ref()
        .filter(|(bid, b, _)| {
            s.slots[j].latest.load(Ordering::SeqCst) == *bid
                && b.next_stage() == Some(NextStage::Photons)
                && b.whitted_term().is_some()
        })
        .map(|(_, b, _)| b)
}

/// The light whose later stage runs when light `index`'s is scheduled:
/// when `index` waits for its photon stage and cells of its fixture will
/// follow it, the one of them (and it) nearest their centre leads, so no
/// follower is farther from its leader than half the fixture (the
/// 8-cell bar of `a_bars_cells_share_one_photon_stage_within_the_bound`
/// led from its end: worst cell rel. MSE 8.1e-4; from its middle: 7.0e-4,
/// and 1.8e-4 in the still, whose reference cells all refine). Otherwise
/// `index` itself.
pub(super) fn leader_of(s: &Shared, index: usize) -> usize {
    if !s.settings.share_indirect {
        return index;
    }
    let Some(group) = batch_group(s, index) else { return index };
    let now = Instant::now();
    let waiting = |j: usize| -> Option<Light> {
        let st = s.slots[j].state.lock().expect("slot lock");
        photon_due(s, j, &st, now).map(|b| b.light().clone())
    };
    let Some(me) = waiting(index) else { return index };
    let cells: Vec<(usize, Light)> =
        group.filter_map(|j| if j == index { Some(me.clone()) } else { waiting(j) }.map(|l| (j, l))).collect();
    let lights: Vec<&Light> = cells.iter().map(|(_, l)| l).collect();
    let first = cells.iter().position(|(j, _)| *j == index).unwrap_or(0);
    let all: Vec<usize> = (0..cells.len()).collect();
    cells[photon_leader(&lights, &all, first).0].0
}

/// Before light `index`'s photon stage (request `id`, its Whitted term in
/// `build`): the settled cells of its fixture that wait for theirs, with
/// the same beam and aim ([`indirect_alike`]), become its followers.
/// True when it leads (its own edges then stay at the Whitted stage's:
/// [`LightBuild::set_edge_refinement`]).
pub(super) fn gather_followers(s: &Shared, index: usize, id: u64, build: &LightBuild) -> bool {
    if !s.settings.share_indirect || !build.has_photons() {
        return false;
    }
    let (Some(group), Some(whitted)) = (batch_group(s, index), build.whitted_shared()) else { return false };
    let now = Instant::now();
    // Leads and follows are made and swept on the worker thread alone.
    s.cells.sharing.store(true, Ordering::SeqCst);
    let mut followers = Vec::new();
    for j in group.filter(|&j| j != index) {
        let mut st = s.slots[j].state.lock().expect("slot lock");
        if !photon_due(s, j, &st, now).is_some_and(|b| indirect_alike(b.light(), build.light())) {
            continue;
        }
        let Some((fid, b, at)) = st.build.take() else { continue };
        let Some(whitted) = b.whitted_shared() else { continue };
        st.follow = Some(Follow { leader: index, leader_id: id, id: fid, light: b.light().clone(), at, whitted });
        followers.push(j);
    }
    if followers.is_empty() {
        return false;
    }
    s.cells.count_followers(followers.len());
    s.slots[index].state.lock().expect("slot lock").lead = Some(Lead { id, whitted, followers });
    true
}

/// Light `index`'s request `id` has `buffer` at `stage` (photons or
/// later): if it leads, it shares its indirect term.
///
/// In clear air the term becomes one [`SharedLayer`] for the group: the
/// leader and each follower show their own Whitted term with it
/// ([`Published::shared`](super::Published)); the frame composites the
/// layer once with the summed weight. A cell's own buffer does not
/// change, so its generation does not either (its emitter group's
/// composite storage stays current): each refinement pass costs one dense
/// layer, not a dense sum per cell. The leader is published here too, and
/// what it shows is returned (the geometry cache keeps that pair at
/// [`Stage::Ready`]); `None`: the caller publishes `buffer` itself (not a
/// leader, haze, or superseded).
///
/// In haze each cell's knot buffers depend on its own position, so each
/// follower publishes its own Whitted term plus the term, dense, at the
/// photon estimate and at the final picture only (module doc).
pub(super) fn lead(
    s: &Shared,
    index: usize,
    id: u64,
    stage: Stage,
    light: &Light,
    buffer: &LightBuffer,
) -> Option<Finished> {
    if s.slots[index].latest.load(Ordering::SeqCst) != id {
        return None; // superseded: neither it nor its followers publish
    }
    let hazy = s.haze.is_some();
    // In haze, between the photon estimate and the final picture the
    // followers keep the estimate: each follower publish costs a dense sum
    // on this thread and makes its emitter group's composite storage stale
    // (festival show: every refinement pass published to 15 followers took
    // the pixel chase from 33 to 25 Hz and the moved heads from 0.26 to 1.08 s).
    if hazy && !matches!(stage, Stage::Photons | Stage::Ready) {
        return None;
    }
    let lead = {
        let mut st = s.slots[index].state.lock().expect("slot lock");
        match &st.lead {
            Some(l) if l.id == id && stage == Stage::Ready => st.lead.take(),
            Some(l) if l.id == id => Some(l.clone()),
            _ => None,
        }
    }?;
    let indirect = shared_indirect(buffer, &lead.whitted);
    if hazy {
        publish_dense_followers(s, index, id, stage, &lead, &indirect);
        return None;
    }
    let layer = LightBuffer::from_dense(buffer.width, buffer.height, &indirect);
    let layer = SharedLayer::new(if s.settings.build.compact { layer.compact() } else { layer });
    let shows = |own: &Arc<LightBuffer>| Finished { buffer: own.clone(), shared: Some(layer.clone()), knots: None };
    if !s.publish_shared(index, id, lead.whitted.clone(), layer.clone(), stage, light) {
        return None;
    }
    for &j in &lead.followers {
        let Some((fid, light, at, own)) = following(s, j, index, id, |f| f.whitted.clone()) else { continue };
        if s.publish_shared(j, fid, own.clone(), layer.clone(), stage, &light) && stage == Stage::Ready {
            s.slots[j].state.lock().expect("slot lock").follow = None;
            finished(s, j, fid, &light, shows(&own), at);
        }
    }
    Some(shows(&lead.whitted))
}

/// Light `j` if it still follows light `index`'s request `id` with its own
/// latest request: its request id, geometry, request time and `what` of
/// its [`Follow`].
fn following<T>(
    s: &Shared,
    j: usize,
    index: usize,
    id: u64,
    what: impl FnOnce(&Follow) -> T,
) -> Option<(u64, Light, Instant, T)> {
    let slot = &s.slots[j];
    let st = slot.state.lock().expect("slot lock");
    st.follow
        .as_ref()
        .filter(|f| f.leader == index && f.leader_id == id && slot.latest.load(Ordering::SeqCst) == f.id)
        .map(|f| (f.id, f.light.clone(), f.at, what(f)))
}

/// [`lead`] in haze: each follower publishes its own Whitted term plus
/// the leader's `indirect` term, dense.
fn publish_dense_followers(s: &Shared, index: usize, id: u64, stage: Stage, lead: &Lead, indirect: &[glam::Vec3]) {
    for &j in &lead.followers {
        let slot = &s.slots[j];
        let next = following(s, j, index, id, |f| follower_sum(&f.whitted, indirect));
        let Some((fid, light, at, buffer)) = next else { continue };
        if let Err(e) = buffer.check() {
            report_bug(s, j, &BuildError::from(e));
            continue;
        }
        if let Some(b) = s.publish(j, fid, Arc::new(buffer), stage, &light)
            && stage == Stage::Ready
        {
            slot.state.lock().expect("slot lock").follow = None;
            finished(s, j, fid, &light, Finished::alone(b), at);
        }
    }
}

/// Light `index` (request `id`) ended its later stages without a new
/// buffer: its followers end with it, at their last buffer.
pub(super) fn lead_ready(s: &Shared, index: usize, id: u64) {
    let lead = {
        let mut st = s.slots[index].state.lock().expect("slot lock");
        if st.lead.as_ref().is_some_and(|l| l.id == id) { st.lead.take() } else { None }
    };
    for j in lead.map(|l| l.followers).unwrap_or_default() {
        let slot = &s.slots[j];
        let mut st = slot.state.lock().expect("slot lock");
        let Some(fid) = st.follow.as_ref().filter(|f| f.leader == index && f.leader_id == id).map(|f| f.id) else {
            continue;
        };
        st.follow = None;
        drop(st);
        if slot.latest.load(Ordering::SeqCst) == fid {
            slot.published.lock().expect("published lock").stage = Stage::Ready;
        }
    }
}

/// Followers whose own request was superseded drop their place (the newer
/// request builds them); followers whose leader moved, failed or was
/// evicted go back to a photon stage of their own, from their Whitted
/// term. A lead superseded by its light's newer request is dropped.
pub(super) fn release_orphans(s: &Shared) {
    if !s.cells.sharing.load(Ordering::SeqCst) {
        return;
    }
    let mut any = false;
    for (j, slot) in s.slots.iter().enumerate() {
        let (follow, lead) = {
            let st = slot.state.lock().expect("slot lock");
            (st.follow.as_ref().map(|f| (f.leader, f.leader_id, f.id)), st.lead.as_ref().map(|l| l.id))
        };
        any |= follow.is_some() || lead.is_some();
        let latest = slot.latest.load(Ordering::SeqCst);
        if lead.is_some_and(|l| l != latest) {
            let mut st = slot.state.lock().expect("slot lock");
            if st.lead.as_ref().is_some_and(|l| l.id != latest) {
                st.lead = None;
            }
        }
        let Some((leader, leader_id, fid)) = follow else { continue };
        let led = fid == latest
            && s.slots.get(leader).is_some_and(|l| {
                l.latest.load(Ordering::SeqCst) == leader_id
                    && l.state
                        .lock()
                        .expect("slot lock")
                        .lead
                        .as_ref()
                        .is_some_and(|x| x.id == leader_id && x.followers.contains(&j))
            });
        if led {
            continue;
        }
        let mut st = slot.state.lock().expect("slot lock");
        let Some(f) = st.follow.take_if(|f| f.id == fid) else { continue };
        if f.id == slot.latest.load(Ordering::SeqCst) {
            let req = Request { id: f.id, light: f.light, at: f.at };
            drop(st);
            let build = new_build(s, j, &req).with_whitted(&f.whitted, 0);
            let mut st = slot.state.lock().expect("slot lock");
            if slot.latest.load(Ordering::SeqCst) == f.id && st.build.is_none() {
                st.build = Some((f.id, build, f.at));
            }
        }
    }
    if !any {
        s.cells.sharing.store(false, Ordering::SeqCst);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Consecutive lights with the same fixture id are one group; a light
    /// without an id, or the same id further on, is not joined to them.
    #[test]
    fn groups_are_runs_of_one_fixture_id() {
        let cells = Cells::new(7);
        cells.set_groups(&[Some(1), Some(1), None, None, Some(2), Some(1)]);
        let groups: Vec<Range<usize>> = (0..7).map(|i| cells.group(i)).collect();
        assert_eq!(groups, vec![0..2, 0..2, 2..3, 3..4, 4..5, 5..6, 6..7]);
        assert_eq!(cells.group(9), 9..10, "a light past the table is alone");
        cells.count(1);
        cells.count(8);
        assert_eq!((cells.passes(), cells.lights()), (1, 8), "a single light is no batched pass");
    }
}
