//! [`LightBuild`]: the only place a light's unit-intensity buffer
//! I_h,ε_i (Vierjahn 2010, eq. 5) is built: a state machine whose
//! [`LightBuild::next`] runs the next [`Stage`] and returns the buffer to
//! publish. `footlight render`, the live tracer, the stress matrix and the
//! bench are loops over `next()`; the tracer only decides *which* light
//! advances and *when*.
//!
//! ```text
//!            with_direct_first(q)                 settings.photons     refine_passes > 0
//! new ──> [Direct(q)] ──> Whitted ──> Photons ──> Refining(1) ─ … ─> Ready
//!          D⁰: primary      D: eq. 1    D + A:      D + A_sppm, pass
//!          surfaces only    recursion,  eq. 3       after pass
//!          (a moving light  mirrors,
//!          is seen moving)  glass, AA
//! ```
//! Without photon settings the Whitted stage is `Ready`; without refinement
//! the photon stage is. `with_maps(maps)` (a new view of an unmoved light)
//! reuses the photon maps: only the per-vertex estimates are redone. The
//! stage methods ([`LightBuild::direct`], [`LightBuild::whitted`],
//! [`LightBuild::photons`], [`LightBuild::into_refinement`]) are the steps
//! `next()` takes; tests call them one by one.
//!
//! Every stage returns the buffer to publish, or [`Cancelled`] when the
//! build's [`Cancel`] token fired (a newer position of the same light, or
//! shutdown). A [`GroupBuild`] (a fixture's cells) is the same machine for
//! several lights at once: its direct and Whitted stages are one pass over
//! the cells' footprints, its photon stage is shared by the cells alike.

use super::buffer::{BadValue, LightBuffer, TILE};
use super::footprint::{DirectQuality, FootprintStats, primary_direct};
use super::photon::{PhotonMaps, PhotonSettings, Progressive, trace_photons_until};
use super::view::{AaParams, EdgeSamples, View};
use crate::fixture::Light;
use crate::scene::Scene;
use glam::Vec3;
use serde::Serialize;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

pub mod group;
pub mod together;

pub use group::{GroupBuild, GroupError, GroupStep, photon_leader};

/// How far a light's published buffer has got (the stage [`LightBuild::next`]
/// just ran; the live status shows it per light).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    /// Nothing built yet.
    Queued,
    /// Direct light on directly seen surfaces (full or moving quality).
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

/// The stage [`LightBuild::next`] runs next (what a scheduler orders by).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NextStage {
    /// The direct stage at this quality ([`LightBuild::with_direct_first`]).
    Direct(DirectQuality),
    /// The Whitted stage.
    Whitted,
    /// The photon stage.
    Photons,
    /// A progressive refinement pass, or, after
    /// [`LightBuild::give_up_refinement`], finishing a coarse start.
    Refine,
}

/// What one [`LightBuild::next`] produced.
pub struct Step {
    /// The stage the buffer is at ([`Stage::Ready`]: the build ended with it).
    pub stage: Stage,
    /// The buffer to publish.
    pub buffer: LightBuffer,
    /// The direct stage's footprint figures (direct stages only).
    pub footprint: Option<FootprintStats>,
}

/// Where a [`LightBuild`] stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Next(NextStage),
    Ended,
}

/// Defaults of a light build, in one place (CLI flags and the daemon
/// override them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildSettings {
    /// Anti-aliasing gradient threshold on the light's relative 0-255 scale
    /// ([`super::view::AA_THRESHOLD`]; paper: 15-25 on the displayed picture).
    pub aa_threshold: f32,
    /// Photon mapping for the indirect term; `None`: direct light (and
    /// Whitted recursion) only.
    pub photons: Option<PhotonSettings>,
    /// Progressive (SPPM) passes after the photon-map estimate; 0 = none.
    pub refine_passes: u32,
    /// The photon stage and refinement supersample the direct term's edge
    /// pixels ([`EdgeSamples`]); off, the Whitted stage's edges stay.
    pub edge_samples: bool,
    /// Every buffer the build returns or holds is compact
    /// ([`LightBuffer::compact`]: f16, 2^-11 relative per value): the live
    /// tracer's builds, which the daemon holds for every light of a rig
    /// (issue 38: half the festival show's buffer memory). Off for
    /// `footlight render` and the reference paths.
    pub compact: bool,
}

impl BuildSettings {
    /// A still's settings (`footlight render`): the defaults without
    /// refinement passes, which a still runs only when asked (`--refine N`);
    /// the live tracer refines while idle ([`BuildSettings::default`]).
    pub fn still() -> Self {
        Self { refine_passes: 0, ..Self::default() }
    }
}

impl Default for BuildSettings {
    /// The paper's settings (section 4): 50,000 photons, 150 in the
    /// estimate; the anti-aliasing threshold of [`super::view::AA_THRESHOLD`]
    /// (the paper's 20 is on displayed values, this one on the light's own
    /// relative scale); 16 refinement passes while idle; edge supersampling.
    fn default() -> Self {
        Self {
            aa_threshold: super::view::AA_THRESHOLD,
            photons: Some(PhotonSettings::default()),
            refine_passes: 16,
            edge_samples: true,
            compact: false,
        }
    }
}

/// Haze for light builds over one view: the medium at 100 % density, the
/// view's haze geometry, the density now and the beam sampling.
pub struct Haze {
    /// The patch's `[haze]` at 100 %.
    pub medium: super::media::Medium,
    /// Camera rays through the medium (from the view's G-buffer).
    pub view: super::media::HazeView,
    /// Density 0-1 (the hazer channel or the patch's default).
    pub density: f32,
    /// Beam sampling.
    pub quality: super::media::HazeQuality,
}

/// A build was abandoned because its [`Cancel`] token fired.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("light build cancelled")]
pub struct Cancelled;

/// Why a stage produced no buffer.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// The token fired (not an error for the caller's user).
    #[error(transparent)]
    Cancelled(#[from] Cancelled),
    /// A NaN/Inf in the buffer: a bug, reported with the pixel.
    #[error(transparent)]
    Bad(#[from] BadValue),
}

/// A cancellation token: a request id compared with the light's latest
/// request, plus a global stop flag. Cheap to clone and to check.
#[derive(Clone, Debug, Default)]
pub struct Cancel {
    latest: Option<(Arc<AtomicU64>, u64)>,
    stop: Option<Arc<AtomicBool>>,
    /// Set by a scheduler that wants the stage in progress to yield to
    /// more urgent work ([`Cancel::preempted`]); the build itself stays good.
    preempt: Option<Arc<AtomicBool>>,
}

impl Cancel {
    /// A token that never fires.
    pub fn never() -> Self {
        Self::default()
    }

    /// Fires when `latest` no longer holds `id` (a newer request) or `stop` is set.
    pub fn new(latest: Arc<AtomicU64>, id: u64, stop: Arc<AtomicBool>) -> Self {
        Self { latest: Some((latest, id)), stop: Some(stop), preempt: None }
    }

    /// Fires when `stop` is set.
    pub fn on_stop(stop: Arc<AtomicBool>) -> Self {
        Self { latest: None, stop: Some(stop), preempt: None }
    }

    /// True once the build should stop.
    pub fn fired(&self) -> bool {
        self.superseded() || self.preempt.as_ref().is_some_and(|p| p.load(Ordering::Relaxed))
    }

    /// True once the build is of no use any more: a newer request, or the stop.
    pub fn superseded(&self) -> bool {
        self.stop.as_ref().is_some_and(|s| s.load(Ordering::Relaxed))
            || self.latest.as_ref().is_some_and(|(l, id)| l.load(Ordering::Relaxed) != *id)
    }

    /// True when the token fired only because its stage was asked to yield
    /// ([`Cancel::with_preempt`]): the build is still good and may be run again.
    pub fn preempted(&self) -> bool {
        !self.superseded() && self.preempt.as_ref().is_some_and(|p| p.load(Ordering::Relaxed))
    }

    /// The token that also fires when `preempt` is set (`None`: never for that).
    pub fn with_preempt(&self, preempt: Option<Arc<AtomicBool>>) -> Self {
        Self { preempt, ..self.clone() }
    }

    /// `Err(Cancelled)` once fired.
    pub fn check(&self) -> Result<(), Cancelled> {
        if self.fired() { Err(Cancelled) } else { Ok(()) }
    }
}

/// Photon seed of light `index`: distinct, reproducible streams per light.
pub fn light_seed(seed: u64, index: usize) -> u64 {
    seed ^ (index as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// One light's build over one view, stage by stage. It owns only the
/// light and its intermediate results; the scene and view are passed to
/// each stage, so a scheduler can keep a build between stages (the live
/// tracer serves other lights' direct stages in between).
pub struct LightBuild {
    light: Light,
    index: usize,
    settings: BuildSettings,
    cancel: Cancel,
    /// The Whitted direct term D, once built (kept for the indirect sum),
    /// tile-sparse: a light waiting for its photon stage holds only the
    /// tiles its light reaches (dense, a festival rig's 3,600 lights waiting
    /// between stages held 4.8 MB each at 800×500: 13 GB), and shared
    /// with what the tracer publishes ([`LightBuild::whitted_shared`]), not
    /// a second copy.
    direct: Option<Arc<LightBuffer>>,
    /// Pixels re-shaded by anti-aliasing in the Whitted stage.
    reshaded: usize,
    /// The light's photon maps: traced by [`LightBuild::photons`], or
    /// handed in by [`LightBuild::with_maps`] (they do not depend on the
    /// camera, so a new view of an unmoved light reuses them).
    maps: Option<Arc<PhotonMaps>>,
    /// True once [`LightBuild::photons`] traced photons itself.
    traced: bool,
    /// The photon-map irradiance at every shading vertex (refinement starts from it).
    start: Option<Vec<Vec3>>,
    /// Coarse first indirect estimate every this many pixels (0, 1: off);
    /// see [`LightBuild::with_coarse_indirect`].
    coarse: u32,
    /// Which values of `start` are exact (a coarse estimate's), to finish
    /// before refinement.
    exact: Option<Vec<bool>>,
    /// Refinement starts SPPM from the coarse estimate itself (no exact
    /// fill first); see [`LightBuild::with_refinement_from_coarse`].
    from_coarse: bool,
    /// The stage [`LightBuild::next`] runs next.
    phase: Phase,
    /// A stage of it yielded once to more urgent work ([`LightBuild::yielded`]).
    yielded: bool,
    /// Refinement state once the photon stage ran through `next()`.
    refinement: Option<Refinement>,
    /// Refinement passes also supersample the direct term's edge pixels
    /// ([`EdgeSamples`]); off for a photon leader ([`LightBuild::set_edge_refinement`]).
    edges: bool,
    /// The edge pixels the photon stage supersampled first
    /// ([`EDGE_PASSES_AT_PHOTONS`]), for refinement to go on from.
    edge_samples: Option<EdgeSamples>,
}

/// Batches of edge samples ([`EdgeSamples::pass_until`]) the photon stage
/// adds before it publishes: 2 (32 samples per edge pixel) take the box
/// stage's direct term from 4.0e-4 to 3.1e-5 rel. MSE for ~16 % of the
/// photon stage's time (`footlight bench --converge-only`), so the first
/// full picture has its edges resolved and refinement goes on from there.
pub const EDGE_PASSES_AT_PHOTONS: u32 = 2;

impl LightBuild {
    /// A build of light number `index` (its photon seed).
    pub fn new(light: Light, index: usize, settings: BuildSettings, cancel: Cancel) -> Self {
        Self {
            light,
            index,
            settings,
            cancel,
            direct: None,
            reshaded: 0,
            maps: None,
            traced: false,
            start: None,
            coarse: 0,
            exact: None,
            from_coarse: false,
            phase: Phase::Next(NextStage::Whitted),
            yielded: false,
            refinement: None,
            edges: settings.edge_samples,
            edge_samples: None,
        }
    }

    /// Lets the next stage yield to more urgent work: it stops with
    /// [`Cancelled`] once `preempt` is set, and [`Cancel::preempted`] then
    /// says the build is still good (the stage runs again from its start).
    /// `None`: it does not yield.
    pub fn set_preempt(&mut self, preempt: Option<Arc<AtomicBool>>) {
        self.cancel = self.cancel.with_preempt(preempt);
    }

    /// Marks that a stage of this build yielded: a scheduler lets each
    /// build yield once, so a light moved again and again cannot starve it.
    pub fn mark_yielded(&mut self) {
        self.yielded = true;
    }

    /// True once a stage of this build yielded ([`LightBuild::mark_yielded`]).
    pub fn yielded(&self) -> bool {
        self.yielded
    }

    /// This light's edge pixels in its Whitted term `direct` ([`EdgeSamples::select`]).
    fn select_edges(&self, scene: &Scene, view: &View, direct: &LightBuffer) -> EdgeSamples {
        EdgeSamples::select(scene, view, &self.light, direct, light_seed(EDGE_SEED, self.index))
    }

    /// Whether refinement passes supersample the direct term's edge pixels
    /// ([`EdgeSamples`], on by default). A photon leader turns it off: the
    /// indirect term it shares is its buffer less its Whitted term
    /// ([`shared_indirect`]), so a refined edge of its own would reach its
    /// followers' pictures.
    pub fn set_edge_refinement(&mut self, on: bool) {
        self.edges = on;
    }

    /// Starts with a direct stage at `quality` ([`LightBuild::direct`]: the
    /// live tracer's first picture of a moved light); without it `next()`
    /// starts at the Whitted stage (`footlight render`).
    pub fn with_direct_first(mut self, quality: DirectQuality) -> Self {
        self.phase = Phase::Next(NextStage::Direct(quality));
        self
    }

    /// The stage [`LightBuild::next`] runs next; `None` once the build ended.
    pub fn next_stage(&self) -> Option<NextStage> {
        match self.phase {
            Phase::Next(stage) => Some(stage),
            Phase::Ended => None,
        }
    }

    /// Runs the next stage ([`LightBuild::next_stage`]) and returns its
    /// buffer with the stage it is at; `Ok(None)` once the build has ended,
    /// or when a refinement given up had nothing left to finish (the last
    /// buffer returned stays the final one). A cancelled or failed stage
    /// leaves the build where it was.
    pub fn next(&mut self, scene: &Scene, view: &View) -> Result<Option<Step>, BuildError> {
        let Phase::Next(stage) = self.phase else { return Ok(None) };
        let step = |stage, buffer| Ok(Some(Step { stage, buffer, footprint: None }));
        match stage {
            NextStage::Direct(quality) => {
                let (buffer, stats) = self.direct(scene, view, quality)?;
                Ok(Some(Step { stage: Stage::Direct, buffer, footprint: Some(stats) }))
            }
            NextStage::Whitted => {
                let buffer = self.whitted(scene, view)?;
                step(if self.has_photons() { Stage::Whitted } else { Stage::Ready }, buffer)
            }
            NextStage::Photons => {
                let buffer = self.photons(scene, view)?;
                self.refinement = self.start_refinement(scene, view);
                self.phase = if self.refinement.is_some() { Phase::Next(NextStage::Refine) } else { Phase::Ended };
                step(if self.refinement.is_some() { Stage::Photons } else { Stage::Ready }, buffer)
            }
            NextStage::Refine => {
                let Some(refine) = self.refinement.as_mut() else {
                    self.phase = Phase::Ended;
                    return Ok(None);
                };
                if refine.finishing() {
                    let last = refine.exact_start(scene, view)?;
                    self.end();
                    return last.map_or(Ok(None), |buffer| step(Stage::Ready, buffer));
                }
                let buffer = refine.pass(scene, view)?;
                if refine.finished() {
                    self.end();
                    return step(Stage::Ready, buffer);
                }
                let done = refine.done();
                step(Stage::Refining(done), buffer)
            }
        }
    }

    /// Runs every remaining stage; the last buffer (`None` if none was left
    /// to build).
    pub fn run_to_end(&mut self, scene: &Scene, view: &View) -> Result<Option<LightBuffer>, BuildError> {
        let mut last = None;
        while let Some(step) = self.next(scene, view)? {
            last = Some(step.buffer);
        }
        Ok(last)
    }

    /// Progressive passes done so far.
    pub fn refined(&self) -> u32 {
        self.refinement.as_ref().map_or(0, Refinement::done)
    }

    /// True while refinement passes are to come (not given up).
    pub fn refining(&self) -> bool {
        self.phase == Phase::Next(NextStage::Refine) && self.refinement.as_ref().is_some_and(|r| !r.finishing())
    }

    /// Gives refinement up (a tracer holding refinement state for too many
    /// lights): true when a coarse photon-map start is still to finish
    /// ([`Refinement::exact_start`], the next `next()`), false when the
    /// build has ended at its last buffer.
    pub fn give_up_refinement(&mut self) -> bool {
        match self.refinement.as_mut() {
            Some(r) if self.phase == Phase::Next(NextStage::Refine) && r.has_coarse_start() => {
                r.finish_only();
                true
            }
            _ => {
                self.end();
                false
            }
        }
    }

    fn end(&mut self) {
        self.phase = Phase::Ended;
        self.refinement = None;
    }

    /// With [`LightBuild::with_coarse_indirect`]: the first SPPM pass blends
    /// with the coarse estimate on screen instead of finishing the exact
    /// lookups first (issue 13: a moved light converges in < 2 s). The exact
    /// fill costs as much as the exact estimate (0.5 s of the bundled stage's
    /// 0.86 s photon stage at 800×500); blended with the passes, the coarse
    /// values' interpolation error fades like the photon map's own
    /// (weight k/(k + N)). A refinement given up before its first pass still
    /// ends on the exact estimate ([`Refinement::exact_start`]); after a pass
    /// the pass's picture stays. Measured in `footlight bench --accuracy-only
    /// --accuracy-part converge`.
    pub fn with_refinement_from_coarse(mut self, on: bool) -> Self {
        self.from_coarse = on;
        self
    }

    /// Makes [`LightBuild::photons`] publish a coarse indirect estimate first
    /// (exact at every `step`-th pixel, interpolated on the same surface in
    /// between: [`View::coarse_vertex_irradiance_until`]) when refinement
    /// follows; the first refinement pass finishes the exact estimate
    /// before SPPM starts from it, so the refined picture is the same as
    /// without. The live tracer uses it (issue 16: full quality sooner after
    /// a camera stop); `footlight render` does not.
    pub fn with_coarse_indirect(mut self, step: u32) -> Self {
        self.coarse = step;
        self
    }

    /// Starts from photon maps traced earlier for this same light geometry
    /// (another view of it): [`LightBuild::photons`] then re-does only the
    /// per-vertex estimates ([`View::render_indirect`]), not the photon
    /// tracing. The caller guarantees the maps belong to this light.
    pub fn with_maps(mut self, maps: Arc<PhotonMaps>) -> Self {
        self.maps = Some(maps);
        self
    }

    /// True when [`LightBuild::photons`] traced photons itself (false when
    /// it reused maps from [`LightBuild::with_maps`]).
    pub fn traced_photons(&self) -> bool {
        self.traced
    }

    /// The photon maps, shared (after [`LightBuild::photons`] or [`LightBuild::with_maps`]).
    pub fn shared_maps(&self) -> Option<Arc<PhotonMaps>> {
        self.maps.clone()
    }

    /// The build's cancellation token.
    pub fn cancel(&self) -> &Cancel {
        &self.cancel
    }

    /// Bytes this build holds between stages (the Whitted term, the
    /// per-vertex start of refinement and its exact flags; photon maps are
    /// counted with the light's maps), for the tracer's memory budget.
    pub fn bytes(&self) -> usize {
        self.direct.as_ref().map_or(0, only_here)
            + self.start.as_ref().map_or(0, |s| s.len() * std::mem::size_of::<Vec3>())
            + self.exact.as_ref().map_or(0, Vec::len)
            + self.refinement.as_ref().map_or(0, Refinement::bytes)
            + self.edge_samples.as_ref().map_or(0, EdgeSamples::bytes)
    }

    /// The light being built.
    pub fn light(&self) -> &Light {
        &self.light
    }

    /// Pixels re-shaded by adaptive anti-aliasing (after [`LightBuild::whitted`]).
    pub fn reshaded(&self) -> usize {
        self.reshaded
    }

    /// Whether the settings ask for an indirect term.
    pub fn has_photons(&self) -> bool {
        self.settings.photons.is_some()
    }

    fn finish(&self, view: &View, dense: &[Vec3]) -> Result<LightBuffer, BuildError> {
        let buffer = LightBuffer::from_dense(view.width(), view.height(), dense);
        buffer.check()?;
        Ok(self.stored(buffer))
    }

    /// `buffer` as the build stores it ([`BuildSettings::compact`]).
    fn stored(&self, buffer: LightBuffer) -> LightBuffer {
        stored(buffer, self.settings.compact)
    }

    /// Stage 1: direct light on the surfaces the camera sees directly (no
    /// mirrors, glass or anti-aliasing), the cheapest picture of a moved light.
    ///
    /// Footprint-culled ([`super::footprint`]): only the tiles the cone
    /// reaches are shaded; `quality` is [`DirectQuality::Moving`] for a light
    /// still in motion.
    pub fn direct(
        &mut self,
        scene: &Scene,
        view: &View,
        quality: DirectQuality,
    ) -> Result<(LightBuffer, FootprintStats), BuildError> {
        self.cancel.check()?;
        let (buffer, stats) = primary_direct(scene, view, view.tile_bounds(), &self.light, quality);
        self.cancel.check()?;
        buffer.check()?;
        self.direct_done();
        Ok((self.stored(buffer), stats))
    }

    /// Stage 2: the full Whitted direct term (eq. 1: k_R, k_T recursion)
    /// with adaptive anti-aliasing (§3.4).
    pub fn whitted(&mut self, scene: &Scene, view: &View) -> Result<LightBuffer, BuildError> {
        self.cancel.check()?;
        // Decided on the light's own relative gradient: independent of
        // exposure, dimmer and colour (issue 13).
        let aa = AaParams::new(self.settings.aa_threshold);
        let cancel = &self.cancel;
        let (dense, reshaded) =
            view.render_direct_until(scene, &self.light, Some(aa), &|| cancel.fired()).ok_or(Cancelled)?;
        self.reshaded = reshaded;
        let buffer = self.finish(view, &dense)?;
        self.direct = Some(Arc::new(buffer.clone()));
        self.after_whitted();
        Ok(buffer)
    }

    /// The Whitted direct term D, once built (a follower's own term when
    /// its fixture's cells share the indirect term: [`follower_sum`]).
    pub fn whitted_term(&self) -> Option<&LightBuffer> {
        self.direct.as_deref()
    }

    /// [`LightBuild::whitted_term`], shared: what a caller publishes or
    /// keeps of it is the build's own buffer, not a copy.
    pub fn whitted_shared(&self) -> Option<Arc<LightBuffer>> {
        self.direct.clone()
    }

    /// Hands in a Whitted stage built elsewhere for this same light and view
    /// (the lights built together by [`together::whitted_together`]):
    /// [`LightBuild::photons`] then goes on from it as if
    /// [`LightBuild::whitted`] had run.
    pub fn with_whitted(mut self, buffer: &LightBuffer, reshaded: usize) -> Self {
        self.set_whitted(buffer, reshaded);
        self
    }

    /// [`LightBuild::with_whitted`] in place.
    pub fn set_whitted(&mut self, buffer: &LightBuffer, reshaded: usize) {
        self.direct = Some(Arc::new(self.stored(buffer.clone())));
        self.reshaded = reshaded;
        self.after_whitted();
    }

    /// A direct stage built elsewhere for this light ([`together`]): the
    /// build goes on at its Whitted stage.
    pub fn direct_done(&mut self) {
        if matches!(self.phase, Phase::Next(NextStage::Direct(_))) {
            self.phase = Phase::Next(NextStage::Whitted);
        }
    }

    /// The anti-aliasing threshold of its Whitted stage.
    pub fn aa_threshold(&self) -> f32 {
        self.settings.aa_threshold
    }

    fn after_whitted(&mut self) {
        self.phase = if self.has_photons() { Phase::Next(NextStage::Photons) } else { Phase::Ended };
    }

    /// Stage 3: direct plus the photon-mapped indirect term (eq. 3, 5:
    /// buffer_i = D_i + A_i, both scaled by k_i). Without photon settings it
    /// is the Whitted buffer.
    pub fn photons(&mut self, scene: &Scene, view: &View) -> Result<LightBuffer, BuildError> {
        if self.direct.is_none() {
            self.whitted(scene, view)?;
        }
        let Some(direct) = self.direct.as_deref() else { return Err(Cancelled.into()) };
        let Some(photons) = self.settings.photons else {
            self.phase = Phase::Ended;
            return Ok(direct.clone());
        };
        self.cancel.check()?;
        let cancel = &self.cancel;
        let stop = || cancel.fired();
        let maps = match &self.maps {
            Some(maps) => maps.clone(),
            None => {
                let settings = PhotonSettings { seed: light_seed(photons.seed, self.index), ..photons };
                let maps = Arc::new(trace_photons_until(scene, &self.light, &settings, &stop).ok_or(Cancelled)?);
                self.traced = true;
                maps
            }
        };
        // Per vertex first: refinement starts from these values (issue 13.4).
        let coarse = self.coarse > 1 && self.settings.refine_passes > 0 && !maps.global.is_empty();
        let at_vertices = if coarse {
            let (e, exact) = view.coarse_vertex_irradiance_until(scene, &maps, self.coarse, &stop).ok_or(Cancelled)?;
            self.exact = Some(exact);
            e
        } else {
            view.vertex_irradiance_until(scene, &maps, &stop).ok_or(Cancelled)?
        };
        let indirect = view.render_vertex_irradiance(scene, &at_vertices);
        self.cancel.check()?;
        if self.edges {
            let mut edges = self.select_edges(scene, view, direct);
            for _ in 0..EDGE_PASSES_AT_PHOTONS {
                if !edges.pass_until(scene, view, &self.light, &stop) {
                    return Err(Cancelled.into());
                }
            }
            self.edge_samples = Some(edges);
        }
        let sum = direct_plus(direct, self.edge_samples.as_ref(), &indirect);
        self.maps = Some(maps);
        self.start = Some(at_vertices);
        // `next()` goes on to refinement from here; called alone, the stage ends the build.
        self.phase = Phase::Ended;
        self.finish(view, &sum)
    }

    /// The haze stage (issue 15): the light's single-scattered beam at unit
    /// intensity ([`super::media::render_inscatter`]), then `surface` (this
    /// light's direct + indirect buffer) re-weighted with it at the medium's
    /// density ([`super::media::resolve`]: extinction along camera and light
    /// paths plus in-scattering; with `multiple`, volume photons for
    /// orders ≥ 2: [`super::media::multiple`]). Linear in the light, so
    /// still eq. 5.
    pub fn haze(&mut self, scene: &Scene, haze: &Haze, surface: &LightBuffer) -> Result<LightBuffer, BuildError> {
        self.cancel.check()?;
        let beam = if haze.medium.multiple {
            // Volume photons for orders ≥ 2 (issue 15.5).
            let settings = super::media::multiple::MultipleSettings::default();
            super::media::multiple::render_beam_with_multiple(
                scene,
                &haze.view,
                &self.light,
                &haze.medium,
                haze.quality,
                &settings,
                &[haze.density],
            )
        } else {
            super::media::render_inscatter(scene, &haze.view, &self.light, &haze.medium, haze.quality)
        };
        self.cancel.check()?;
        let buffer =
            super::media::resolve(&haze.view, &haze.medium, self.light.position, surface, Some(&beam), haze.density);
        buffer.check()?;
        Ok(buffer)
    }

    /// The live haze stage (issue 15): the light's beam at `quality`
    /// ([`super::media::render_inscatter`]) in `medium` (the haze at 100 %),
    /// resolved by the tracer into the knot buffers with the surface buffer
    /// it publishes next ([`super::media::knot_buffers`]) and then dropped.
    /// With `medium.multiple` the refined stage (`quality.refine_edges`)
    /// also carries the volume-photon multiple scattering
    /// ([`super::media::multiple::render_beam_with_multiple`]).
    pub fn haze_beam(
        &self,
        scene: &Scene,
        view: &super::media::HazeView,
        medium: &super::media::Medium,
        quality: super::media::HazeQuality,
    ) -> Result<super::buffer::HazeBuffer, BuildError> {
        self.cancel.check()?;
        // Multiple scattering (volume photons) with the refined beam only:
        // the coarse first stage stays fast.
        let beam = if medium.multiple && quality.refine_edges {
            let settings = super::media::multiple::MultipleSettings::default();
            // The term at the live knots ½ and 1 (resolved there exactly).
            let knots = &super::media::live::KNOTS[1..];
            super::media::multiple::render_beam_with_multiple(
                scene,
                view,
                &self.light,
                medium,
                quality,
                &settings,
                knots,
            )
        } else {
            super::media::render_inscatter(scene, view, &self.light, medium, quality)
        };
        self.cancel.check()?;
        beam.check()?;
        Ok(beam)
    }

    /// The light's photon maps, after [`LightBuild::photons`].
    pub fn maps(&self) -> Option<&PhotonMaps> {
        self.maps.as_deref()
    }

    /// Whether [`LightBuild::into_refinement`] would refine the indirect
    /// term (photons traced, passes configured, some global photons
    /// stored); it may refine the direct term's edges alone otherwise.
    pub fn will_refine(&self) -> bool {
        self.settings.refine_passes > 0 && self.maps.as_ref().is_some_and(|m| !m.global.is_empty())
    }

    /// Stage 4 state: progressive photon mapping (SPPM) from the photon
    /// maps, `None` when there is nothing to refine.
    pub fn into_refinement(mut self, scene: &Scene, view: &View) -> Option<Refinement> {
        self.start_refinement(scene, view)
    }

    /// [`LightBuild::into_refinement`] in place: the Whitted term and the
    /// per-vertex start move into the refinement (the photon maps stay
    /// shared with [`LightBuild::shared_maps`]).
    fn start_refinement(&mut self, scene: &Scene, view: &View) -> Option<Refinement> {
        if self.settings.refine_passes == 0 || self.cancel.fired() {
            return None;
        }
        let edges = match (self.edges, self.edge_samples.take(), self.direct.as_deref()) {
            (false, ..) => None,
            (true, Some(edges), _) => Some(edges),
            (true, None, Some(direct)) => Some(self.select_edges(scene, view, direct)),
            (true, None, None) => None,
        }
        .filter(|e| !e.is_empty());
        if !self.will_refine() {
            // No indirect term to refine: the edges alone, over the photon
            // estimate as it is.
            let (edges, direct) = (edges?, self.direct.take()?);
            let fixed = match self.start.take() {
                Some(start) => view.render_vertex_irradiance(scene, &start),
                None => vec![Vec3::ZERO; view.width() as usize * view.height() as usize],
            };
            return Some(Refinement {
                light: self.light.clone(),
                direct,
                edges: Some(edges),
                sppm: None,
                fixed: Some(fixed),
                pending: None,
                from_coarse: false,
                passes: self.settings.refine_passes,
                done: 0,
                cancel: self.cancel.with_preempt(None),
                compact: self.settings.compact,
            });
        }
        let (maps, direct) = (self.maps.clone()?, self.direct.take()?);
        let mut refinement = Refinement {
            light: self.light.clone(),
            direct,
            edges,
            sppm: None,
            fixed: None,
            pending: None,
            from_coarse: false,
            passes: self.settings.refine_passes,
            done: 0,
            // Refinement passes are short: they never yield.
            cancel: self.cancel.with_preempt(None),
            compact: self.settings.compact,
        };
        let start = self.start.take();
        if let (Some(start), Some(exact)) = (start.clone(), self.exact.take()) {
            // A coarse start: finished by the first pass (not here: the
            // tracer serves the other lights' stages first), or blended with
            // it as it is (`from_coarse`, also set up by the first pass).
            refinement.from_coarse = self.from_coarse;
            refinement.pending = Some(PendingStart { maps, start, exact: Some(exact) });
            return Some(refinement);
        }
        // Never worse than the picture on screen: the passes are blended with
        // the photon-map estimate just shown, weighted by photon counts. The
        // SPPM state is set up by the first pass ([`Refinement::pass`]).
        match start {
            Some(start) => refinement.pending = Some(PendingStart { maps, start, exact: None }),
            None => refinement.sppm = Some(Progressive::new(scene, view, &maps)),
        }
        Some(refinement)
    }
}

/// A refinement's start before its first pass. SPPM's per-vertex state
/// (radius, count, flux: 20 bytes a vertex beside the start's 12) is made
/// only by the first pass, so a light waiting for its turn to refine holds
/// its start alone (issue 38: the festival show's ~228 photon leaders all
/// wait after their photon stage; at its 250,444 shading vertices a
/// waiting leader held 45 bytes a vertex, 11 MB, and now holds 13, 3.3 MB).
struct PendingStart {
    /// The light's photon maps (the SPPM start radii come from them).
    maps: Arc<PhotonMaps>,
    /// The photon-map irradiance at every shading vertex.
    start: Vec<Vec3>,
    /// For a coarse start, which values are exact (`None`: all are).
    exact: Option<Vec<bool>>,
}

/// `buffer`, compact when `compact` ([`BuildSettings::compact`]).
fn stored(buffer: LightBuffer, compact: bool) -> LightBuffer {
    if compact { buffer.compact() } else { buffer }
}

/// Seed of the edge samples' per-pixel shifts ([`light_seed`] per light).
const EDGE_SEED: u64 = 0xED6E_5000;

/// A light's progressive refinement (stage 4): each pass is one SPPM
/// iteration at the view's shading vertices and one batch of stratified
/// samples in each edge pixel of the direct term ([`EdgeSamples`]).
pub struct Refinement {
    light: Light,
    direct: Arc<LightBuffer>,
    /// The direct term's edge pixels and their samples (`None`: none, or
    /// a photon leader's).
    edges: Option<EdgeSamples>,
    /// `None` until a coarse start is finished ([`Refinement::exact_start`]),
    /// and for a light whose photon maps hold no global photon.
    sppm: Option<Progressive>,
    /// The indirect term, dense, of a light without global photons (its
    /// photon estimate stays; only its edges are refined).
    fixed: Option<Vec<Vec3>>,
    /// A start still to set up ([`PendingStart`]).
    pending: Option<PendingStart>,
    /// A coarse start's first pass blends with it as it is instead of
    /// finishing it ([`LightBuild::with_refinement_from_coarse`]).
    from_coarse: bool,
    passes: u32,
    /// Passes done.
    done: u32,
    cancel: Cancel,
    /// Its buffers are compact ([`BuildSettings::compact`]).
    compact: bool,
}

impl Refinement {
    /// Passes done.
    pub fn done(&self) -> u32 {
        self.done
    }

    /// The direct term's edge pixels being supersampled (`None`: none).
    pub fn edges(&self) -> Option<&EdgeSamples> {
        self.edges.as_ref()
    }

    /// Bytes this refinement holds (the Whitted term, a coarse start still
    /// to finish, and the SPPM state: [`Progressive::bytes`]), for the
    /// tracer's memory budget.
    pub fn bytes(&self) -> usize {
        only_here(&self.direct)
            + self.pending.as_ref().map_or(0, |PendingStart { start, exact, .. }| {
                start.len() * std::mem::size_of::<Vec3>() + exact.as_ref().map_or(0, Vec::len)
            })
            + self.sppm.as_ref().map_or(0, Progressive::bytes)
            + self.edges.as_ref().map_or(0, EdgeSamples::bytes)
            + self.fixed.as_ref().map_or(0, |f| std::mem::size_of_val(&f[..]))
    }

    /// True when every configured pass has run.
    pub fn finished(&self) -> bool {
        self.done() >= self.passes
    }

    /// Gives refinement up but keeps a coarse start to finish: no SPPM pass
    /// will run, [`Refinement::exact_start`] gives the final picture. The
    /// coarse values are dropped: the finish looks every vertex up anew
    /// (1/9 more lookups at the live step of 3) instead of a light holding
    /// 13 bytes a vertex until its turn comes, after every other light's
    /// photon stage (issue 38: ~224 of the festival's photon leaders, 0.74 GB).
    pub fn finish_only(&mut self) {
        self.passes = 0;
        if let Some(p) = self.pending.as_mut()
            && p.exact.is_some()
        {
            p.start = Vec::new();
            p.exact = Some(Vec::new());
        }
    }

    /// True after [`Refinement::finish_only`] (or with no passes configured).
    pub fn finishing(&self) -> bool {
        self.passes == 0
    }

    /// True while a coarse start waits for [`Refinement::exact_start`].
    pub fn has_coarse_start(&self) -> bool {
        self.pending.as_ref().is_some_and(|p| p.exact.is_some())
    }

    /// Finishes a coarse photon-map start ([`LightBuild::with_coarse_indirect`]):
    /// the remaining vertices are looked up exactly and SPPM is set up from
    /// the exact values. Returns the exact photon-map buffer D + A, or `None`
    /// when the start was exact already. A tracer that gives a light's
    /// refinement up calls it so the light never stays at the coarse estimate.
    pub fn exact_start(&mut self, scene: &Scene, view: &View) -> Result<Option<LightBuffer>, BuildError> {
        let Some(PendingStart { maps, mut start, exact }) = self.pending.take() else { return Ok(None) };
        let weight = maps.settings.estimate as f32;
        let cancel = &self.cancel;
        let stop = || cancel.fired();
        match exact {
            None => {
                // An exact start: the picture on screen is already this one.
                self.sppm = Some(Progressive::new(scene, view, &maps).starting_from(start, weight));
                return Ok(None);
            }
            // Given up before its first pass ([`Refinement::finish_only`]): every vertex anew.
            Some(_) if start.is_empty() => {
                start = view.vertex_irradiance_until(scene, &maps, &stop).ok_or(Cancelled)?
            }
            Some(exact) => {
                view.fill_vertex_irradiance_until(scene, &maps, &mut start, &exact, &stop).ok_or(Cancelled)?
            }
        }
        let indirect = view.render_vertex_irradiance(scene, &start);
        let sum = direct_plus(&self.direct, self.edges.as_ref(), &indirect);
        let buffer = LightBuffer::from_dense(view.width(), view.height(), &sum);
        buffer.check()?;
        let buffer = stored(buffer, self.compact);
        if !self.finishing() {
            self.sppm = Some(Progressive::new(scene, view, &maps).starting_from(start, weight));
        }
        Ok(Some(buffer))
    }

    /// The light being refined.
    pub fn light(&self) -> &Light {
        &self.light
    }

    /// True once the token fired.
    pub fn cancelled(&self) -> bool {
        self.cancel.fired()
    }

    /// One pass; returns D + A: A the SPPM estimate blended with the
    /// photon-map estimate ([`Progressive::starting_from`]), D the Whitted
    /// term with each edge pixel the mean of its stratified samples so far
    /// ([`EdgeSamples::pass_until`]; a batch at passes 1, 2, 4, 8, …).
    /// A cancelled pass keeps the edge batch it finished, nothing else.
    pub fn pass(&mut self, scene: &Scene, view: &View) -> Result<LightBuffer, BuildError> {
        self.cancel.check()?;
        if self.sppm.is_none() && self.fixed.is_none() {
            match &self.pending {
                // Blended as it is; kept until a pass ran, so a refinement
                // given up before still ends on the exact estimate.
                Some(PendingStart { maps, start, exact: Some(_) }) if self.from_coarse => {
                    let w = maps.settings.estimate as f32;
                    self.sppm = Some(Progressive::new(scene, view, maps).starting_from(start.clone(), w));
                }
                _ => {
                    self.exact_start(scene, view)?;
                }
            }
        }
        let cancel = &self.cancel;
        let stop = || cancel.fired();
        // The edges first, at passes 1, 2, 4, 8, …: their error falls as
        // n^-3/2 and sits far below the indirect term's after the photon
        // stage's batches (box stage: 3.9e-5 at 32 samples, 4.9e-6 at 128,
        // against 2-3e-4 for the whole picture), so a batch every pass
        // would double a pass's cost for nothing a reference can see.
        if (self.done + 1).is_power_of_two()
            && let Some(edges) = self.edges.as_mut()
            && !edges.pass_until(scene, view, &self.light, &stop)
        {
            return Err(Cancelled.into());
        }
        // A cancelled SPPM pass keeps the edge batch: more samples never
        // hurt, and the next pass goes on from them.
        let indirect = match (self.sppm.as_mut(), self.fixed.as_ref()) {
            (Some(sppm), _) => {
                if !sppm.pass_until(scene, view, &self.light, &stop) {
                    return Err(Cancelled.into());
                }
                // SPPM from a coarse start: after a pass its picture is the
                // one to keep, not the exact photon-map estimate.
                self.pending = None;
                view.render_progressive(scene, sppm)
            }
            (None, Some(fixed)) => fixed.clone(),
            (None, None) => return Err(Cancelled.into()),
        };
        self.cancel.check()?;
        let sum = direct_plus(&self.direct, self.edges.as_ref(), &indirect);
        let buffer = LightBuffer::from_dense(view.width(), view.height(), &sum);
        buffer.check()?;
        let buffer = stored(buffer, self.compact);
        self.done += 1;
        Ok(buffer)
    }
}

/// Cosine of the largest angle between two cells' beam axes for them to
/// share an indirect term (1°).
const ALIKE_COS: f32 = 0.999_847_7;

/// Two cells of one fixture may share an indirect term
/// ([`shared_indirect`]) when their beams are the same (pattern, zoom,
/// gobo) and aimed within 1°.
pub fn indirect_alike(a: &Light, b: &Light) -> bool {
    a.beam == b.beam && a.axis().dot(b.axis()) >= ALIKE_COS
}

/// Bytes of `buffer` held by this owner alone (0 while another, such as the
/// tracer's published buffer, holds it too: counted there).
pub fn only_here(buffer: &Arc<LightBuffer>) -> usize {
    if Arc::strong_count(buffer) == 1 { buffer.bytes() } else { 0 }
}

/// The indirect term a leader shares with the other cells of its fixture
/// (issue 38: emitter groups that share photon tracing): the leader's
/// buffer (D_l + A_l, eq. 3) less its Whitted term D_l, dense. The cells
/// sit centimetres apart with the same beam and aim, so their
/// photon-mapped indirect light (eq. 3's A) is the same to within the
/// error `tests/pixels.rs` measures. A difference below 0 (f32 rounding
/// where A_l is 0) is 0; a NaN stays NaN for [`LightBuffer::check`].
pub fn shared_indirect(leader: &LightBuffer, leader_whitted: &LightBuffer) -> Vec<Vec3> {
    let mut indirect = leader.to_dense();
    combine_tiles(&mut indirect, leader_whitted, |p, d| {
        let a = *p - d;
        *p = Vec3::select(a.cmplt(Vec3::ZERO), Vec3::ZERO, a);
    });
    indirect
}

/// A follower's buffer: its own Whitted term D_f plus the leader's
/// [`shared_indirect`] term; each cell keeps its own k_i (eq. 5).
pub fn follower_sum(own_whitted: &LightBuffer, indirect: &[Vec3]) -> LightBuffer {
    LightBuffer::from_dense(own_whitted.width, own_whitted.height, &plus_dense(own_whitted, indirect))
}

/// D + A with each of `edges`' pixels' direct term its samples' mean
/// ([`EdgeSamples::replace_in`]; `None`: the Whitted term as it is).
fn direct_plus(direct: &LightBuffer, edges: Option<&EdgeSamples>, indirect: &[Vec3]) -> Vec<Vec3> {
    let mut sum = plus_dense(direct, indirect);
    if let Some(edges) = edges {
        edges.replace_in(&mut sum, direct);
    }
    sum
}

/// D + A: the tile-sparse direct term added to a dense indirect term
/// (`indirect` is the view's width × height, row-major).
fn plus_dense(direct: &LightBuffer, indirect: &[Vec3]) -> Vec<Vec3> {
    let mut sum = indirect.to_vec();
    combine_tiles(&mut sum, direct, |p, d| *p += d);
    sum
}

/// `f(pixel of dense, value of sparse)` at every pixel of `sparse`'s
/// occupied tiles (within `dense`, a frame of `sparse`'s width).
fn combine_tiles(dense: &mut [Vec3], sparse: &LightBuffer, mut f: impl FnMut(&mut Vec3, Vec3)) {
    let w = sparse.width as usize;
    for (tx, ty) in sparse.occupied() {
        let Some(tile) = sparse.tile(tx, ty) else { continue };
        for (j, row) in tile.chunks_exact(TILE).enumerate() {
            let y = ty * TILE + j;
            for (i, d) in row.iter().enumerate() {
                let x = tx * TILE + i;
                if x < w
                    && let Some(p) = dense.get_mut(y * w + x)
                {
                    f(p, *d);
                }
            }
        }
    }
}
