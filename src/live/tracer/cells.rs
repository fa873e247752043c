//! The cells of one fixture built together by the live tracer (issue 14:
//! pixel cells). An LED bar's cells are lights of their own (one unit
//! buffer each, eq. 5), a few centimetres apart, and they are due at the
//! same moments: at start-up, after a view change, when the bar moves. Built
//! one by one, each cell's stages walk the picture on their own; built
//! together ([`crate::render::cells`]), one pass over the union of the
//! cells' footprints evaluates every cell at each vertex.
//!
//! The tracer's scheduling ([`super::schedule`]) is unchanged: it picks a
//! light and a stage. When that light is a cell of a fixture (a group set
//! by [`super::Tracer::set_groups`]) and other cells of the same fixture
//! are due for the same stage, the whole set is built in one pass:
//! - **direct stage** ([`direct_together_at`]): every cell of the group
//!   with a pending request at the same quality (a moving bar's cells at
//!   moving quality, one pixel per 2×2 block, together too);
//! - **Whitted stage** ([`whitted_together`], with the view's
//!   [`PathBounds`] made once per view): every settled cell of the group
//!   whose build waits for its Whitted stage.
//!
//! Each cell keeps its own request id, [`LightBuild`] and buffer: after the
//! pass each buffer goes through the same steps as a cell built alone (haze
//! beam, publish under its request id, build kept for its later stages), so
//! a cell that moved again during the pass is refused at publish (never
//! shown stale) and its newer request is served next; the pass stops early
//! only when every cell in it was superseded. Photons and refinement stay
//! per cell (each cell traces its own photon maps). Cells of different
//! fixtures are never mixed.

use super::{Request, Shared, after_direct, after_whitted, new_build, report_bug, take_request};
use crate::Light;
use crate::render::View;
use crate::render::build::{BuildError, Cancel, LightBuild};
use crate::render::cells::{PathBounds, direct_together_at, whitted_together};
use crate::render::footprint::DirectQuality;
use crate::render::view::AaParams;
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, Weak};
use std::time::Instant;

/// The tracer's fixture groups, the current view's path bounds and the
/// batch counters.
pub(super) struct Cells {
    /// Per light: the lights of its fixture (itself alone by default).
    groups: Mutex<Arc<Vec<Range<usize>>>>,
    /// [`PathBounds`] of the current view (made at the first Whitted pass),
    /// with a `Weak` to its view: it keeps no view alive (the view cache
    /// lets a view's caches go when nothing holds it), and the `Weak` keeps
    /// the allocation, so a new view never matches an old one's address.
    bounds: Mutex<Option<(Weak<View>, Arc<PathBounds>)>>,
    /// Passes that built two cells or more.
    passes: AtomicU64,
    /// Light stages built in those passes.
    lights: AtomicU64,
}

impl Cells {
    /// `n` lights, each alone.
    pub(super) fn new(n: usize) -> Self {
        Self {
            groups: Mutex::new(Arc::new((0..n).map(|i| i..i + 1).collect())),
            bounds: Mutex::new(None),
            passes: AtomicU64::new(0),
            lights: AtomicU64::new(0),
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
        *self.groups.lock().expect("groups lock") = Arc::new(groups);
    }

    /// The lights of light `index`'s fixture (itself alone by default).
    pub(super) fn group(&self, index: usize) -> Range<usize> {
        self.groups.lock().expect("groups lock").get(index).cloned().unwrap_or(index..index + 1)
    }

    /// The path bounds of `view`, made once per view.
    fn bounds(&self, view: &Arc<View>) -> Arc<PathBounds> {
        let mut kept = self.bounds.lock().expect("bounds lock");
        if let Some((v, b)) = kept.as_ref()
            && std::ptr::eq(v.as_ptr(), Arc::as_ptr(view))
        {
            return b.clone();
        }
        let b = Arc::new(PathBounds::build(view));
        *kept = Some((Arc::downgrade(view), b.clone()));
        b
    }

    fn count(&self, lights: usize) {
        if lights >= 2 {
            self.passes.fetch_add(1, Ordering::SeqCst);
            self.lights.fetch_add(lights as u64, Ordering::SeqCst);
        }
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

/// True once every token of `cancels` fired: the pass stops.
fn all_fired(cancels: &[Cancel]) -> bool {
    cancels.iter().all(Cancel::fired)
}

/// The direct stage of light `index` together with every other cell of
/// its fixture that has a request waiting at the same quality (full, or
/// moving for cells in motion). False (nothing
/// done) when fewer than two cells are due: the caller builds `index` alone.
pub(super) fn direct_batch(s: &Shared, index: usize) -> bool {
    let Some(group) = batch_group(s, index) else { return false };
    // Due: a request waits; in motion or not (the quality of its stage).
    let due = |j: usize| {
        let st = s.slots[j].state.lock().expect("slot lock");
        st.pending.as_ref().map(|r| st.previous_move.is_some_and(|p| r.at.duration_since(p) < s.settings.settle))
    };
    let Some(moving) = due(index) else { return false };
    let members: Vec<usize> = group.filter(|&j| due(j) == Some(moving)).collect();
    if members.len() < 2 {
        return false;
    }
    // Only the worker takes requests: each member's is still there.
    let taken: Vec<(usize, Request, Instant, LightBuild)> = members
        .into_iter()
        .filter_map(|j| {
            let (req, since, _) = take_request(s, j)?;
            let build = new_build(s, j, &req);
            Some((j, req, since, build))
        })
        .collect();
    for (j, ..) in &taken {
        s.injected_panic(*j);
    }
    let view = s.view();
    s.builds.fetch_add(taken.len() as u64, Ordering::SeqCst);
    s.cells.count(taken.len());
    let lights: Vec<Light> = taken.iter().map(|t| t.1.light.clone()).collect();
    let cancels: Vec<Cancel> = taken.iter().map(|t| t.3.cancel().clone()).collect();
    let quality = if moving { DirectQuality::Moving } else { DirectQuality::Full };
    let result = s.pool.install(|| direct_together_at(&s.scene, &view, &lights, quality, &|| all_fired(&cancels)));
    // Every cell superseded (their newer requests wait) or shutdown.
    let Some((buffers, _)) = result else { return true };
    let bounds = view.tile_bounds();
    for ((j, req, since, build), buffer) in taken.into_iter().zip(buffers) {
        if build.cancel().fired() {
            continue; // moved during the pass: its newer request is served next
        }
        if let Err(e) = buffer.check() {
            report_bug(j, &BuildError::from(e));
            continue;
        }
        let share = bounds.tiles_in_beam(&req.light).len() as f32 / bounds.len().max(1) as f32;
        after_direct(s, j, req, since, build, buffer, share);
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
            && st.build.as_ref().is_some_and(|(_, b, _)| !b.has_whitted())
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
    let lights: Vec<Light> = taken.iter().map(|t| t.2.light().clone()).collect();
    let cancels: Vec<Cancel> = taken.iter().map(|t| t.2.cancel().clone()).collect();
    // The threshold `LightBuild::whitted` uses: the light's own relative gradient.
    let aa = Some(AaParams::new(s.settings.build.aa_threshold));
    let result = s.pool.install(|| whitted_together(&s.scene, &view, &bounds, &lights, aa, &|| all_fired(&cancels)));
    let Some((built, _)) = result else { return true };
    for ((j, id, build, at), (buffer, reshaded)) in taken.into_iter().zip(built) {
        if build.cancel().fired() {
            continue;
        }
        if let Err(e) = buffer.check() {
            report_bug(j, &BuildError::from(e));
            continue;
        }
        // Its photons stage goes on from this Whitted term (without photons
        // the build ends here and needs no copy of it).
        let build = if build.has_photons() { build.with_whitted(&buffer, reshaded) } else { build };
        after_whitted(s, j, id, build, buffer, at);
    }
    true
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
