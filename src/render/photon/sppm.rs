//! Stochastic progressive photon mapping (Hachisuka & Jensen 2009) at the
//! view's shading vertices: while the machine is idle, each pass traces a
//! fresh batch of photons and shrinks every vertex's gather radius, so the
//! indirect estimate's error keeps falling toward zero (bias and variance
//! both vanish as passes grow). A geometry change of the light restarts it.
//!
//! Per visible point: R_{i+1}² = R_i² (N_i + α M)/(N_i + M),
//! N_{i+1} = N_i + α M, τ_{i+1} = (τ_i + Φ_M) R_{i+1}²/R_i², and
//! E = τ / (π R² · passes) with photon powers normalised per pass.
//!
//! # Refinement that only improves (issue 13.4)
//!
//! A lone first SPPM pass gathers ~50 photons in a small ball: 2-7× the
//! error of the photon-map estimate it would replace on screen. So the
//! progressive state starts *from* that estimate ([`Progressive::starting_from`]):
//! each vertex keeps its photon-map irradiance E_pm, worth `w_pm` photons
//! (the k of its kNN gather), and shows
//!
//!   E = (w_pm E_pm + N E_sppm) / (w_pm + N)
//!
//! with N the vertex's SPPM photon count. Both parts estimate the same
//! irradiance from independent photons, so the blend is their
//! count-weighted mean: at the first pass it stays close to the photon map
//! (N ≈ 35 against 150) and lowers its variance; as N grows past w_pm the
//! SPPM estimate, whose bias vanishes, takes over.

use super::PhotonSettings;
use super::map::{Photon, PhotonMap};
use super::trace::{PhotonMaps, trace_chunk};
use crate::fixture::{BeamSampler, Light};
use crate::render::view::View;
use crate::scene::Scene;
use glam::Vec3;
use rayon::prelude::*;

/// SPPM radius reduction parameter α (Hachisuka & Jensen use 0.7).
pub const ALPHA: f32 = 0.7;

/// Progressive state of one light over one view.
pub struct Progressive {
    radius2: Vec<f32>,
    count: Vec<f32>,
    tau: Vec<Vec3>,
    passes: u32,
    settings: PhotonSettings,
    /// Per-vertex photon-map irradiance shown before the first pass, and
    /// its weight in photons (see the module docs).
    start: Option<(Vec<Vec3>, f32)>,
    /// Where the last pass's time went.
    last: PassTimes,
}

/// Wall-clock time of one SPPM pass's stages, ms (profiled in `footlight
/// bench --accuracy-only --accuracy-part converge`).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct PassTimes {
    /// Emitting and tracing the pass's photons.
    pub trace_ms: f64,
    /// Building the pass's photon k-d tree.
    pub tree_ms: f64,
    /// Gathering at every vertex and updating its radius, count and flux.
    pub gather_ms: f64,
    /// Photons stored in the pass.
    pub photons: usize,
}

impl Progressive {
    /// Starts from the light's first photon maps: each diffuse vertex's
    /// initial radius is the gather radius of the nearest precomputed
    /// irradiance point (the local photon spacing of the first estimate).
    pub fn new(scene: &Scene, view: &View, maps: &PhotonMaps) -> Self {
        let default_r = maps.max_radius * 0.2;
        let radius2 = view
            .shading
            .vertices()
            .par_iter()
            .map(|v| {
                if scene.materials[v.material as usize].diffuse.max_element() <= 0.0 {
                    return 0.0;
                }
                // The radius holding ~50 photons at this density: √(50/k) of the
                // k-photon cache radius. Smaller starts are noisier than the
                // first estimate for many passes; larger ones stay blurred.
                let share = (50.0 / maps.settings.estimate.max(50) as f32).sqrt();
                let r = maps.irradiance.radius_near(v.position).map(|r| r * share).unwrap_or(default_r);
                r * r
            })
            .collect::<Vec<f32>>();
        let n = radius2.len();
        Self {
            radius2,
            count: vec![0.0; n],
            tau: vec![Vec3::ZERO; n],
            passes: 0,
            settings: maps.settings,
            start: None,
            last: PassTimes::default(),
        }
    }

    /// Blends the passes with `start`, the photon-map irradiance at every
    /// shading vertex (as [`View::vertex_irradiance`] computes it), worth
    /// `weight` photons per vertex (the estimate's k): the picture shown at
    /// every pass is the count-weighted mean of both (module docs). Without
    /// it, the passes alone are shown.
    /// A `start` of the wrong length is ignored (logged as a bug).
    pub fn starting_from(mut self, start: Vec<Vec3>, weight: f32) -> Self {
        if start.len() == self.radius2.len() && weight > 0.0 {
            self.start = Some((start, weight));
        } else {
            tracing::error!(
                "SPPM start: {} estimates for {} vertices (weight {weight}); starting from zero",
                start.len(),
                self.radius2.len()
            );
        }
        self
    }

    /// Each pass emits `emitted` photons (rounded up to whole 2048-photon
    /// chunks) instead of the maps' `pass_emitted` setting.
    pub fn with_pass_emitted(mut self, emitted: usize) -> Self {
        self.settings.pass_emitted = emitted;
        self
    }

    /// Passes done so far.
    pub fn passes(&self) -> u32 {
        self.passes
    }

    /// Bytes of per-vertex state held (radius, count, flux and the start),
    /// for the tracer's memory budget.
    pub fn bytes(&self) -> usize {
        self.radius2.len() * 4
            + self.count.len() * 4
            + self.tau.len() * std::mem::size_of::<Vec3>()
            + self.start.as_ref().map_or(0, |(s, _)| s.len() * std::mem::size_of::<Vec3>())
    }

    /// Where the last pass's time went (zero before the first).
    pub fn last_times(&self) -> PassTimes {
        self.last
    }

    /// Traces one pass of photons (seeded by the pass number) and updates
    /// every vertex.
    pub fn pass(&mut self, scene: &Scene, view: &View, light: &Light) {
        self.pass_until(scene, view, light, &|| false);
    }

    /// As [`Progressive::pass`], abandoned once `stop` returns true: checked
    /// per photon chunk and before the vertices are updated, so the state
    /// stays consistent (a cancelled pass changes nothing). Returns whether
    /// the pass ran.
    pub fn pass_until(&mut self, scene: &Scene, view: &View, light: &Light, stop: &(dyn Fn() -> bool + Sync)) -> bool {
        let t0 = std::time::Instant::now();
        let ms = |t: std::time::Instant| t.elapsed().as_secs_f64() * 1e3;
        let sampler = BeamSampler::new(&light.beam);
        let per_pass = if self.settings.pass_emitted > 0 { self.settings.pass_emitted } else { self.settings.stored };
        let chunks = per_pass.div_ceil(2048).max(1) as u64;
        let mut pass_settings = self.settings;
        pass_settings.seed =
            self.settings.seed ^ (0xA5A5_0000_0000 + u64::from(self.passes + 1)).wrapping_mul(0x2545_F491_4F6C_DD1D);
        let batches: Vec<(Vec<Photon>, Vec<Photon>)> =
            (0..chunks)
                .into_par_iter()
                .map(|c| {
                    if stop() {
                        (Vec::new(), Vec::new())
                    } else {
                        trace_chunk(scene, light, &sampler, &pass_settings, c)
                    }
                })
                .collect();
        if stop() {
            return false;
        }
        let emitted = chunks as f32 * 2048.0;
        let photons: Vec<Photon> = batches
            .into_iter()
            .flat_map(|(g, c)| g.into_iter().chain(c))
            .map(|mut p| {
                p.power /= emitted;
                p
            })
            .collect();
        let trace_ms = ms(t0);
        let t1 = std::time::Instant::now();
        let stored = photons.len();
        let map = PhotonMap::new(photons).with_open_edges(scene.open_edges());
        let tree_ms = ms(t1);
        let t2 = std::time::Instant::now();
        let vertices = view.shading.vertices();
        self.radius2.par_iter_mut().zip(&mut self.count).zip(&mut self.tau).zip(vertices).for_each(
            |(((r2, n), tau), v)| {
                if *r2 <= 0.0 {
                    return;
                }
                let (phi, m) = map.gather(v.position, v.normal, *r2);
                if m == 0 {
                    return;
                }
                let m = m as f32;
                let shrink = (*n + ALPHA * m) / (*n + m);
                *n += ALPHA * m;
                *tau = (*tau + phi) * shrink;
                *r2 *= shrink;
            },
        );
        self.passes += 1;
        self.last = PassTimes { trace_ms, tree_ms, gather_ms: ms(t2), photons: stored };
        true
    }

    /// Indirect irradiance at every shading vertex after the passes so far
    /// (blended with the start estimate when there is one).
    pub fn irradiance(&self) -> Vec<Vec3> {
        let passes = self.passes.max(1) as f32;
        let sppm = |i: usize| {
            let r2 = self.radius2[i];
            if r2 > 0.0 && self.passes > 0 { self.tau[i] / (std::f32::consts::PI * r2 * passes) } else { Vec3::ZERO }
        };
        match &self.start {
            None => (0..self.tau.len()).map(sppm).collect(),
            Some((start, w0)) => (0..self.tau.len())
                .map(|i| {
                    // Vertices without a gather radius (not diffuse) keep the start.
                    let n = if self.radius2[i] > 0.0 { self.count[i] } else { 0.0 };
                    (start[i] * *w0 + sppm(i) * n) / (*w0 + n)
                })
                .collect(),
        }
    }
}
