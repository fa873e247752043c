//! One still image through the whole pipeline: view (G-buffer + camera
//! paths), one unit-intensity buffer per light, composite (eq. 5), display.
//! `footlight render` and the benchmarks use this; the live daemon uses the
//! same pieces with a scheduler in between.

use super::RenderSettings;
use super::buffer::{LightBuffer, SharedLayer};
use super::build::{BuildError, Cancel, GroupBuild, Haze, LightBuild, NextStage};
use super::composite::composite;
use super::footprint::TileBounds;
use super::media::{HazeQuality, HazeView, Medium};
use super::view::View;
use crate::fixture::Light;
use crate::scene::{Camera, Scene};
use glam::Vec3;
use std::time::{Duration, Instant};

/// A light to render: its geometry, k_i at dimmer 1 (for anti-aliasing
/// decisions) and its current k_i (for the composite).
#[derive(Clone, Debug)]
pub struct LightJob {
    /// Tracer geometry and pattern.
    pub light: Light,
    /// k_i with the dimmer at full.
    pub k_full: Vec3,
    /// k_i now (eq. 4).
    pub k: Vec3,
    /// The fixture the light belongs to: consecutive jobs with the same
    /// `Some` id are one fixture's cells, built together (one Whitted pass,
    /// one photon stage shared by the cells alike:
    /// [`super::build::shared_indirect`]); `None`: built alone.
    pub fixture: Option<u32>,
}

/// A light's build failed: a NaN/Inf in its buffer (a bug, reported with
/// the light and pixel), or a cancelled build.
#[derive(Debug, thiserror::Error)]
#[error("light {light}: {source}")]
pub struct RenderError {
    /// Index of the light in the job list.
    pub light: usize,
    /// Where and what.
    pub source: BuildError,
}

/// Timings of the stages of a still render.
#[derive(Clone, Debug, Default)]
pub struct StillTimings {
    /// G-buffer and camera-path expansion.
    pub view: Duration,
    /// All light buffers (direct and Whitted terms).
    pub lights: Duration,
    /// Photon tracing and indirect estimates.
    pub photons: Duration,
    /// Haze: in-scattering and density re-weighting.
    pub haze: Duration,
    /// Composite.
    pub composite: Duration,
}

/// The result of a still render.
pub struct Still {
    /// Camera-dependent state (reusable).
    pub view: View,
    /// One buffer per light, in job order: its own. A cell that shares a
    /// group's indirect term holds its own Whitted term here and the term
    /// in [`Still::layers`] ([`Still::light_buffer`] adds them).
    pub buffers: Vec<LightBuffer>,
    /// The groups' shared indirect terms A_g, each with the lights that
    /// show it (eq. 5 regrouped: Σ_i k_i (W_i + A_g) = Σ_i k_i W_i +
    /// (Σ_i k_i) A_g; [`GroupBuild::with_shared_layers`]).
    pub layers: Vec<(SharedLayer, Vec<usize>)>,
    /// Linear composite in cd/m².
    pub linear: Vec<Vec3>,
    /// Pixels re-shaded by adaptive anti-aliasing, summed over lights.
    pub reshaded: usize,
    /// Stage timings.
    pub timings: StillTimings,
}

impl Still {
    /// Light `i`'s whole unit buffer: its own plus the shared layer it
    /// shows, if any (what it adds to eq. 5 at k_i = 1).
    pub fn light_buffer(&self, i: usize) -> LightBuffer {
        match self.layers.iter().find(|(_, members)| members.contains(&i)) {
            Some((layer, _)) => {
                let own = &self.buffers[i];
                LightBuffer::from_dense(own.width, own.height, &layer.plus(own))
            }
            None => self.buffers[i].clone(),
        }
    }
}

pub use super::build::light_seed;

/// Haze for a still: the medium at 100 % density and the density now.
#[derive(Clone, Copy, Debug)]
pub struct StillHaze {
    /// The patch's `[haze]` at 100 %.
    pub medium: Medium,
    /// Density 0-1 (the hazer channel or the patch's default).
    pub density: f32,
    /// Beam sampling.
    pub quality: HazeQuality,
}

/// Runs of consecutive jobs with the same `Some` fixture id (one fixture's
/// cells); a job without an id is a run of its own.
fn fixture_runs(jobs: &[LightJob]) -> Vec<std::ops::Range<usize>> {
    let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
    for (i, job) in jobs.iter().enumerate() {
        match runs.last_mut() {
            Some(r) if job.fixture.is_some() && jobs[r.start].fixture == job.fixture => r.end = i + 1,
            _ => runs.push(i..i + 1),
        }
    }
    runs
}

/// Renders `jobs` over `scene` from `camera`.
pub fn render_still(
    scene: &Scene,
    camera: Camera,
    jobs: &[LightJob],
    settings: &RenderSettings,
) -> Result<Still, RenderError> {
    render_still_hazy(scene, camera, jobs, settings, None)
}

/// As [`render_still`], in haze when `haze` is given: each light's buffer
/// is its surface buffer re-weighted with its beam at the density
/// ([`LightBuild::haze`]).
pub fn render_still_hazy(
    scene: &Scene,
    camera: Camera,
    jobs: &[LightJob],
    settings: &RenderSettings,
    haze: Option<&StillHaze>,
) -> Result<Still, RenderError> {
    let t0 = Instant::now();
    let view = View::build(scene, camera, settings.width, settings.height, settings.sampling, settings.limits);
    let haze = haze.map(|h| Haze {
        medium: h.medium,
        view: HazeView::new(scene, &view.gbuffer),
        density: h.density,
        quality: h.quality,
    });
    let mut haze_time = Duration::ZERO;
    let t1 = Instant::now();
    let mut buffers = Vec::with_capacity(jobs.len());
    let mut reshaded = 0;
    let mut photon_time = Duration::ZERO;
    let build_settings = settings.build;
    // Only what the look lights is built: a dark light adds exactly 0 to
    // eq. 5. Lit lights keep their index, so their photon seeds are the
    // daemon's.
    let (w, h) = (settings.width.max(1), settings.height.max(1));
    let mut surfaces: Vec<Option<LightBuffer>> = vec![None; jobs.len()];
    // Per light: the shared layer it shows beside its own buffer. Not in
    // haze: there each light's surface buffer is re-weighted whole.
    let mut shown: Vec<Option<SharedLayer>> = vec![None; jobs.len()];
    let bounds = TileBounds::paths(&view);
    for run in fixture_runs(jobs) {
        // A fixture's lit cells are one group ([`GroupBuild`]): one Whitted
        // pass over their footprints (equal to each built alone), one photon
        // stage for the cells alike, led by the one nearest their centre.
        let lit: Vec<usize> = run.filter(|&i| jobs[i].k != Vec3::ZERO).collect();
        if lit.is_empty() {
            continue;
        }
        let builds =
            lit.iter().map(|&i| LightBuild::new(jobs[i].light.clone(), i, build_settings, Cancel::never())).collect();
        let group = GroupBuild::new(builds, true);
        let mut group = if haze.is_none() { group.with_shared_layers() } else { group };
        while let Some(stage) = group.next_stage() {
            let t = Instant::now();
            let steps = group
                .next(scene, &view, &bounds)
                .map_err(|e| RenderError { light: lit[e.member], source: e.source })?;
            if matches!(stage, NextStage::Photons | NextStage::Refine) {
                photon_time += t.elapsed();
            }
            for s in steps {
                let light = lit[s.member];
                surfaces[light] = Some(s.step.map_err(|source| RenderError { light, source })?.buffer);
                shown[light] = s.shared;
            }
        }
        reshaded += group.reshaded();
    }
    for (i, (job, surface)) in jobs.iter().zip(surfaces).enumerate() {
        let buffer = match (surface, &haze) {
            (None, _) => LightBuffer::empty(w, h),
            (Some(b), None) => b,
            (Some(b), Some(hz)) => {
                let th = Instant::now();
                let mut build = LightBuild::new(job.light.clone(), i, build_settings, Cancel::never());
                let hazy = build.haze(scene, hz, &b).map_err(|source| RenderError { light: i, source })?;
                haze_time += th.elapsed();
                hazy
            }
        };
        buffers.push(buffer);
    }
    let t2 = Instant::now();
    let mut layers: Vec<(SharedLayer, Vec<usize>)> = Vec::new();
    for (i, layer) in shown.into_iter().enumerate() {
        let Some(layer) = layer else { continue };
        match layers.iter_mut().find(|(l, _)| l.id == layer.id) {
            Some((_, members)) => members.push(i),
            None => layers.push((layer, vec![i])),
        }
    }
    // Eq. 5 regrouped: each light's own buffer at k_i, each layer once at Σ k_i of its lights.
    let mut refs: Vec<&LightBuffer> = buffers.iter().collect();
    let mut k: Vec<Vec3> = jobs.iter().map(|j| j.k).collect();
    for (layer, members) in &layers {
        refs.push(&layer.buffer);
        k.push(members.iter().map(|&i| jobs[i].k).sum());
    }
    let linear = composite(&refs, &k, settings.width.max(1), settings.height.max(1));
    let t3 = Instant::now();
    Ok(Still {
        view,
        buffers,
        layers,
        linear,
        reshaded,
        timings: StillTimings {
            view: t1 - t0,
            lights: t2 - t1 - photon_time - haze_time,
            haze: haze_time,
            photons: photon_time,
            composite: t3 - t2,
        },
    })
}
