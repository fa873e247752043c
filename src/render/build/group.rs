//! [`GroupBuild`]: a fixture's cells built as one state machine (issue 33
//! item 1; issue 38 item 2: emitter groups that share work). A single light
//! is a group of one and builds exactly as its [`LightBuild`] alone.
//!
//! Each cell keeps its own [`LightBuild`] and its own unit buffer (eq. 5:
//! every cell its own k_i). What the group shares:
//! - **direct and Whitted stages**: the cells due for the same stage are
//!   shaded in one pass over the union of their footprints
//!   ([`super::together`]), equal to each cell built alone;
//! - **the photon stage**: the cells with the same beam and aim
//!   ([`indirect_alike`]) follow the one nearest their centre
//!   ([`photon_leader`]); only it traces photons and refines, and at its
//!   photon estimate and its final picture each follower gets its own
//!   Whitted term plus the leader's indirect term ([`shared_indirect`],
//!   [`follower_sum`]), within the bound `tests/pixels.rs` measures.
//!
//! With [`GroupBuild::with_shared_layers`] the indirect term is not added
//! into a dense buffer per cell: the leader and each follower give their
//! own Whitted term and the group's one [`SharedLayer`] (eq. 5 regrouped,
//! Σ_i k_i (W_i + A_g) = Σ_i k_i W_i + (Σ_i k_i) A_g), as the live tracer
//! publishes them: a festival's 3,660 lit cells then hold 3,660
//! tile-sparse buffers and ~230 dense layers instead of 3,660 dense
//! buffers (`footlight render` of `festival.mvr`: 10 GB of RSS before).
//!
//! `footlight render` drives groups with [`GroupBuild::next`]; the live
//! tracer schedules cells one by one (each has its own request id and may
//! move alone) and uses the same passes and the same leader rule.

use super::together::{direct_together_at, whitted_together};
use super::{BuildError, Cancelled, LightBuild, NextStage, Stage, Step, follower_sum, indirect_alike, shared_indirect};
use crate::fixture::Light;
use crate::render::buffer::{LightBuffer, SharedLayer};
use crate::render::footprint::TileBounds;
use crate::render::view::{AaParams, View};
use crate::scene::Scene;
use glam::Vec3;

/// The photon leader of the cells `lights[i]` for `i` in `waiting` that
/// are alike ([`indirect_alike`]) with `lights[first]`: the one nearest
/// their centre, so no follower is farther from its leader than half the
/// fixture (an 8-cell bar led from its end: worst cell rel. MSE 8.1e-4;
/// from its middle 7.0e-4, `tests/pixels.rs`). Returns the leader and its
/// followers (the others alike); `first` alone leads nobody when no other
/// waiting cell is alike.
pub fn photon_leader(lights: &[&Light], waiting: &[usize], first: usize) -> (usize, Vec<usize>) {
    let alike: Vec<usize> =
        waiting.iter().copied().filter(|&j| j == first || indirect_alike(lights[j], lights[first])).collect();
    if alike.len() < 2 {
        return (first, Vec::new());
    }
    let centre = alike.iter().map(|&j| lights[j].position).sum::<Vec3>() / alike.len() as f32;
    let d = |j: usize| (lights[j].position - centre).length_squared();
    let leader = alike.iter().copied().min_by(|&a, &b| d(a).total_cmp(&d(b))).unwrap_or(first);
    (leader, alike.into_iter().filter(|&j| j != leader).collect())
}

/// One cell's result of a [`GroupBuild::next`].
pub struct GroupStep {
    /// The cell (its place in the group).
    pub member: usize,
    /// Its stage and buffer; an error (a NaN/Inf in its buffer: a bug) for
    /// this cell alone in a pass together, whose build is dropped while the
    /// other cells go on.
    pub step: Result<Step, BuildError>,
    /// With [`GroupBuild::with_shared_layers`], at the leader's photon
    /// estimate and final picture: the group's indirect term A_g, which the
    /// cell shows beside `step`'s buffer (its own Whitted term).
    pub shared: Option<SharedLayer>,
}

/// A stage of a [`GroupBuild`] failed for one cell.
#[derive(Debug, thiserror::Error)]
#[error("cell {member}: {source}")]
pub struct GroupError {
    /// The cell (its place in the group).
    pub member: usize,
    /// What failed.
    #[source]
    pub source: BuildError,
}

/// A cell following the group's photon leader: its own Whitted term.
struct Follower {
    member: usize,
    whitted: LightBuffer,
}

/// A fixture's cells built together (module doc).
pub struct GroupBuild {
    /// Per cell: its build, `None` while it follows or once it ended.
    builds: Vec<Option<LightBuild>>,
    /// Whether cells alike share the photon stage.
    share_indirect: bool,
    /// Whether the shared indirect term is given as a [`SharedLayer`]
    /// beside each cell's own Whitted term (else added in, dense).
    layers: bool,
    /// The photon leader, its Whitted term and its followers.
    lead: Option<(usize, LightBuffer, Vec<Follower>)>,
    /// Passes that built two cells or more, and the cells in them.
    passes: (u64, u64),
    /// Pixels re-shaded by adaptive anti-aliasing, summed over the cells.
    reshaded: usize,
    /// Cells that followed a photon leader.
    followed: usize,
}

impl GroupBuild {
    /// The cells' builds, in the fixture's order. `share_indirect`: cells
    /// alike share one photon stage (off: each traces its own).
    pub fn new(builds: Vec<LightBuild>, share_indirect: bool) -> Self {
        Self {
            builds: builds.into_iter().map(Some).collect(),
            share_indirect,
            layers: false,
            lead: None,
            passes: (0, 0),
            reshaded: 0,
            followed: 0,
        }
    }

    /// The cells alike give their own Whitted term and the group's
    /// [`SharedLayer`] ([`GroupStep::shared`]) instead of a dense sum each
    /// (module doc). A cell's picture is the same either way (the
    /// layer's pixels added to its own buffer's).
    pub fn with_shared_layers(mut self) -> Self {
        self.layers = true;
        self
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.builds.len()
    }

    /// True for a group without cells.
    pub fn is_empty(&self) -> bool {
        self.builds.is_empty()
    }

    /// Passes that built two cells or more, and the cell stages built in them.
    pub fn together_passes(&self) -> (u64, u64) {
        self.passes
    }

    /// Pixels re-shaded by adaptive anti-aliasing in the cells' Whitted
    /// stages so far, summed.
    pub fn reshaded(&self) -> usize {
        self.reshaded
    }

    /// The cells' builds back (a scheduler that keeps each cell's build
    /// between passes: the live tracer); `None` for a cell that follows,
    /// failed or ended.
    pub fn into_builds(self) -> Vec<Option<LightBuild>> {
        self.builds
    }

    /// Cells that followed a photon leader instead of tracing photons of
    /// their own (0 before the photon stage).
    pub fn followers(&self) -> usize {
        self.followed
    }

    /// True once every cell's build has ended.
    pub fn ended(&self) -> bool {
        self.lead.is_none() && self.builds.iter().all(|b| b.as_ref().is_none_or(|b| b.next_stage().is_none()))
    }

    /// The earliest stage a cell of the group runs next (`None` once every
    /// cell ended; a follower waits for its leader's stages).
    pub fn next_stage(&self) -> Option<NextStage> {
        self.earliest().map(|(s, _)| s)
    }

    /// The stage each cell is at next, earliest first (direct, Whitted,
    /// photons, refinement), with the cells at it.
    fn earliest(&self) -> Option<(NextStage, Vec<usize>)> {
        let rank = |s: NextStage| match s {
            NextStage::Direct(_) => 0,
            NextStage::Whitted => 1,
            NextStage::Photons => 2,
            NextStage::Refine => 3,
        };
        let stages: Vec<(usize, NextStage)> =
            self.builds.iter().enumerate().filter_map(|(i, b)| Some((i, b.as_ref()?.next_stage()?))).collect();
        let first = stages.iter().map(|&(_, s)| s).min_by_key(|&s| rank(s))?;
        Some((first, stages.iter().filter(|&&(_, s)| s == first).map(|&(i, _)| i).collect()))
    }

    /// Runs the group's next stage: the cells due for the earliest stage,
    /// in one pass when two or more are due for a direct or Whitted stage;
    /// at the photon stage the leader's (the followers' buffers come with
    /// its photon estimate and its final picture). Empty once every cell
    /// has ended. `bounds`: [`TileBounds::paths`] of `view` (for Whitted
    /// passes together).
    pub fn next(&mut self, scene: &Scene, view: &View, bounds: &TileBounds) -> Result<Vec<GroupStep>, GroupError> {
        let Some((stage, due)) = self.earliest() else { return Ok(Vec::new()) };
        match stage {
            NextStage::Direct(quality) if due.len() >= 2 => self.direct_together(scene, view, quality, &due),
            NextStage::Whitted if due.len() >= 2 => self.whitted_together(scene, view, bounds, &due),
            NextStage::Photons if self.share_indirect && self.lead.is_none() && due.len() >= 2 => {
                self.gather(&due);
                if self.lead.is_some() { self.leader_step(scene, view) } else { self.one(scene, view, stage, due[0]) }
            }
            _ if self.lead.as_ref().is_some_and(|(l, ..)| due.contains(l)) => self.leader_step(scene, view),
            _ => self.one(scene, view, stage, due[0]),
        }
    }

    /// The next stage of cell `member` alone.
    fn one(
        &mut self,
        scene: &Scene,
        view: &View,
        stage: NextStage,
        member: usize,
    ) -> Result<Vec<GroupStep>, GroupError> {
        let build = self.builds[member].as_mut().ok_or(GroupError { member, source: Cancelled.into() })?;
        let step = build.next(scene, view).map_err(|source| GroupError { member, source })?;
        if stage == NextStage::Whitted {
            self.reshaded += build.reshaded();
        }
        Ok(step.map(|step| GroupStep { member, step: Ok(step), shared: None }).into_iter().collect())
    }

    /// Runs every stage of every cell; each cell's last buffer.
    pub fn run_to_end(
        &mut self,
        scene: &Scene,
        view: &View,
        bounds: &TileBounds,
    ) -> Result<Vec<Option<LightBuffer>>, GroupError> {
        let mut last: Vec<Option<LightBuffer>> = vec![None; self.len()];
        while !self.ended() {
            let steps = self.next(scene, view, bounds)?;
            if steps.is_empty() {
                break;
            }
            for s in steps {
                last[s.member] = Some(s.step.map_err(|source| GroupError { member: s.member, source })?.buffer);
            }
        }
        Ok(last)
    }

    fn count(&mut self, cells: usize) {
        self.passes.0 += 1;
        self.passes.1 += cells as u64;
    }

    fn direct_together(
        &mut self,
        scene: &Scene,
        view: &View,
        quality: crate::render::footprint::DirectQuality,
        due: &[usize],
    ) -> Result<Vec<GroupStep>, GroupError> {
        let lights: Vec<Light> = due.iter().filter_map(|&i| Some(self.builds[i].as_ref()?.light().clone())).collect();
        let fired = self.fired(due);
        let (buffers, _) = direct_together_at(scene, view, &lights, quality, &fired)
            .ok_or(GroupError { member: due[0], source: Cancelled.into() })?;
        self.count(due.len());
        let tiles = view.tile_bounds();
        let mut steps = Vec::with_capacity(due.len());
        for (&member, buffer) in due.iter().zip(buffers) {
            if let Err(e) = buffer.check() {
                self.builds[member] = None;
                steps.push(GroupStep { member, step: Err(e.into()), shared: None });
                continue;
            }
            let Some(build) = self.builds[member].as_mut() else { continue };
            build.direct_done();
            let footprint = crate::render::footprint::FootprintStats {
                tiles: tiles.len(),
                tiles_in_beam: tiles.tiles_in_beam(build.light()).len(),
                vertices: 0,
            };
            steps.push(GroupStep {
                member,
                step: Ok(Step { stage: Stage::Direct, buffer, footprint: Some(footprint) }),
                shared: None,
            });
        }
        Ok(steps)
    }

    fn whitted_together(
        &mut self,
        scene: &Scene,
        view: &View,
        bounds: &TileBounds,
        due: &[usize],
    ) -> Result<Vec<GroupStep>, GroupError> {
        let lights: Vec<Light> = due.iter().filter_map(|&i| Some(self.builds[i].as_ref()?.light().clone())).collect();
        let aa = self.builds[due[0]].as_ref().map(|b| AaParams::new(b.aa_threshold()));
        let fired = self.fired(due);
        let (built, _) = whitted_together(scene, view, bounds, &lights, aa, &fired)
            .ok_or(GroupError { member: due[0], source: Cancelled.into() })?;
        self.count(due.len());
        let mut steps = Vec::with_capacity(due.len());
        for (&member, (buffer, reshaded)) in due.iter().zip(built) {
            if let Err(e) = buffer.check() {
                self.builds[member] = None;
                steps.push(GroupStep { member, step: Err(e.into()), shared: None });
                continue;
            }
            let Some(build) = self.builds[member].as_mut() else { continue };
            build.set_whitted(&buffer, reshaded);
            self.reshaded += reshaded;
            let stage = if build.has_photons() { Stage::Whitted } else { Stage::Ready };
            steps.push(GroupStep { member, step: Ok(Step { stage, buffer, footprint: None }), shared: None });
        }
        Ok(steps)
    }

    /// True once every due cell's token fired (the pass stops).
    fn fired(&self, due: &[usize]) -> impl Fn() -> bool + Sync + use<> {
        let cancels: Vec<super::Cancel> =
            due.iter().filter_map(|&i| Some(self.builds[i].as_ref()?.cancel().clone())).collect();
        move || cancels.iter().all(super::Cancel::fired)
    }

    /// The cells due for their photon stage alike with the first become
    /// followers of the one nearest their centre.
    fn gather(&mut self, due: &[usize]) {
        let lights: Vec<&Light> = due.iter().filter_map(|&i| Some(self.builds[i].as_ref()?.light())).collect();
        if lights.len() != due.len() {
            return;
        }
        let all: Vec<usize> = (0..due.len()).collect();
        let (leader, followers) = photon_leader(&lights, &all, 0);
        let leader = due[leader];
        let Some(leader_whitted) = self.builds[leader].as_ref().and_then(|b| b.whitted_term().cloned()) else { return };
        let mut follow = Vec::new();
        for member in followers.into_iter().map(|f| due[f]) {
            let Some(build) = self.builds[member].take() else { continue };
            match build.whitted_term().cloned() {
                Some(whitted) => follow.push(Follower { member, whitted }),
                None => self.builds[member] = Some(build),
            }
        }
        self.followed += follow.len();
        if !follow.is_empty()
            && let Some(b) = self.builds[leader].as_mut()
        {
            // Its shared term is its buffer less its Whitted term.
            b.set_edge_refinement(false);
        }
        self.lead = Some((leader, leader_whitted, follow));
    }

    /// The leader's next stage; at its photon estimate and its final
    /// picture its followers' buffers too.
    fn leader_step(&mut self, scene: &Scene, view: &View) -> Result<Vec<GroupStep>, GroupError> {
        let Some(member) = self.lead.as_ref().map(|(l, ..)| *l) else { return Ok(Vec::new()) };
        let build = self.builds[member].as_mut().ok_or(GroupError { member, source: Cancelled.into() })?;
        let step = build.next(scene, view).map_err(|source| GroupError { member, source })?;
        let Some(step) = step else {
            // Ended without a new buffer: the followers keep their last one.
            self.lead = None;
            return Ok(Vec::new());
        };
        let stage = step.stage;
        let mut steps = Vec::new();
        if matches!(stage, Stage::Photons | Stage::Ready)
            && let Some((_, leader_whitted, followers)) = self.lead.as_ref()
        {
            let indirect = shared_indirect(&step.buffer, leader_whitted);
            if self.layers {
                // Each cell: its own Whitted term and the one layer.
                let layer = SharedLayer::new(LightBuffer::from_dense(view.width(), view.height(), &indirect));
                for f in followers {
                    let own = Step { stage, buffer: f.whitted.clone(), footprint: None };
                    steps.push(GroupStep { member: f.member, step: Ok(own), shared: Some(layer.clone()) });
                }
                let own = Step { stage, buffer: leader_whitted.clone(), footprint: None };
                steps.insert(0, GroupStep { member, step: Ok(own), shared: Some(layer) });
                if stage == Stage::Ready {
                    self.lead = None;
                }
                return Ok(steps);
            }
            for f in followers {
                let buffer = follower_sum(&f.whitted, &indirect);
                let step = buffer.check().map(|()| Step { stage, buffer, footprint: None }).map_err(BuildError::from);
                steps.push(GroupStep { member: f.member, step, shared: None });
            }
        }
        if stage == Stage::Ready {
            self.lead = None;
        }
        steps.insert(0, GroupStep { member, step: Ok(step), shared: None });
        Ok(steps)
    }
}
