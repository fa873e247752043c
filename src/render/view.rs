//! A [`View`] is everything that depends on the camera and the geometry but
//! not on any light: the 9-sample G-buffer and the camera paths expanded
//! through mirrors and glass. It is built once and reused for every light
//! until the camera moves (Vierjahn 2010, section 3.4).
//!
//! [`View::render_light`] produces one light's unit-intensity buffer
//! I_h,ε_i (eq. 5) from it: one shade per surface bin over the view's
//! camera paths, then, with adaptive sampling, the anti-aliasing policy of
//! [`aa`] (which pixels to re-shade with the 9 samples, and how) applied to
//! it. The view holds what that policy needs from the camera: the 9-sample
//! expansions of re-shaded pixels, cached for the next light or rebuild.

pub mod aa;
pub mod edges;
pub mod rim;

pub use aa::{
    AA_REFERENCE_PERCENTILE, AA_THRESHOLD, AaDecision, AaMarking, AaParams, CORNER_AGREEMENT, GLINT_EXPONENT,
    LitWindow, RESHADE_MIN_BRANCH, Reshading, RowSpans, dilate, facing_corners, is_sharp, lit_window, mark_gradients,
    mark_gradients_with, mark_highlights_into, mark_pairs, mark_pairs_into, mark_rim_into, reference_in_window,
    reference_level, row_spans,
};
pub use edges::{EDGE_CONTRAST, EDGE_SAMPLES_PER_PASS, EdgeSamples};
pub use rim::{BeamEdge, BeamRim};

use super::buffer::LightBuffer;
use super::gbuffer::PrimarySample;
use super::gbuffer::{Bin, CENTRE_SAMPLE, GBuffer, NO_HIT, SAMPLES_PER_PIXEL, bin_samples, single_bin};
use super::photon::{PhotonMaps, Progressive};
use super::whitted::{RecursionLimits, ShadingVertex, direct, direct_hinted, expand};
use crate::fixture::Light;
use crate::scene::bvh::OccluderHint;
use crate::scene::{Camera, Hit, Scene};
use aa::CORNERS_FIRST;
use glam::Vec3;
use rayon::prelude::*;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Which primary samples a pixel is shaded with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleSet {
    /// Only the pixel-centre sample (1 sample per pixel, no anti-aliasing).
    Centre,
    /// One shade per surface bin ([`super::gbuffer::surface_bins`]:
    /// triangle-ID bins, those on one smooth surface merged; geometry
    /// anti-aliasing).
    Binned,
    /// One shade per triangle-ID bin, tessellation edges included (the
    /// binning before issue 13; kept as the bench's "before").
    TriangleBins,
    /// All 9 samples, each weighted 1/9 (the 9× oversampled reference).
    All,
}

/// How a light's buffer is sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Sampling {
    /// One sample per pixel.
    One,
    /// Triangle-ID bins only (anti-aliases geometry edges).
    Geometry,
    /// Bins plus gradient re-shading with all 9 samples (the paper's method).
    Adaptive,
    /// All 9 samples everywhere (reference).
    Nine,
}

impl Sampling {
    /// The sample set shaded first (before any adaptive re-shading).
    pub fn base_set(self) -> SampleSet {
        match self {
            Sampling::One => SampleSet::Centre,
            Sampling::Geometry | Sampling::Adaptive => SampleSet::Binned,
            Sampling::Nine => SampleSet::All,
        }
    }
}

/// A pixel's 9-sample camera paths, sample `order[k]`'s path the k-th,
/// with each one's number of vertices.
struct NinePaths {
    order: [usize; SAMPLES_PER_PIXEL],
    counts: [u32; SAMPLES_PER_PIXEL],
    vertices: Box<[ShadingVertex]>,
}

impl NinePaths {
    /// Where each sample's path lies in `vertices`, by sample index.
    fn ranges(&self) -> [std::ops::Range<usize>; SAMPLES_PER_PIXEL] {
        let mut ranges: [std::ops::Range<usize>; SAMPLES_PER_PIXEL] = Default::default();
        let mut at = 0;
        for (&s, &n) in self.order.iter().zip(&self.counts) {
            ranges[s] = at..at + n as usize;
            at += n as usize;
        }
        ranges
    }
}

/// Expanded camera paths of every pixel for one sample set, stored as a
/// compressed row list (pixel i owns vertices[start[i]..start[i+1]]).
pub struct ShadingSet {
    /// Which samples were expanded.
    pub set: SampleSet,
    start: Vec<u32>,
    vertices: Vec<ShadingVertex>,
}

impl ShadingSet {
    /// Vertices of pixel `index` (row-major).
    pub fn pixel(&self, index: usize) -> &[ShadingVertex] {
        &self.vertices[self.start[index] as usize..self.start[index + 1] as usize]
    }

    /// Total number of vertices (shadow rays per light at most).
    pub fn vertex_count(&self) -> usize {
        self.vertices.len()
    }

    /// All vertices, pixel after pixel.
    pub fn vertices(&self) -> &[ShadingVertex] {
        &self.vertices
    }

    /// Number of bins pixel `index` is shaded with in this set (1 for
    /// [`SampleSet::Centre`], 9 for [`SampleSet::All`]).
    pub fn bins_of(&self, gbuffer: &GBuffer, index: usize) -> usize {
        match self.set {
            SampleSet::Centre => 1,
            SampleSet::All => SAMPLES_PER_PIXEL,
            SampleSet::Binned => gbuffer.bins(index).len(),
            SampleSet::TriangleBins => bin_samples(&gbuffer.samples[index]).as_slice().len(),
        }
    }

    /// Range of `vertices()` belonging to pixel `index`.
    pub fn pixel_range(&self, index: usize) -> std::ops::Range<usize> {
        self.start[index] as usize..self.start[index + 1] as usize
    }
}

/// Byte budget for cached 9-sample expansions of re-shaded pixels (see
/// [`View::render_light`]); past it, expansions are recomputed per use.
pub const NINE_SAMPLE_CACHE_BYTES: usize = 256 << 20;

/// Camera-dependent, light-independent state reused across lights and rebuilds.
pub struct View {
    /// 9 primary samples per pixel.
    pub gbuffer: GBuffer,
    /// Expanded camera paths for the base sample set.
    pub shading: ShadingSet,
    /// Sampling mode the view was built for.
    pub sampling: Sampling,
    /// Recursion limits used for every path.
    pub limits: RecursionLimits,
    /// 9-sample expansions of pixels some light re-shaded, kept for the
    /// next light or rebuild that re-shades the same pixel (its secondary
    /// rays are the expensive part and depend only on the camera).
    nine_cache: Vec<OnceLock<Box<NinePaths>>>,
    nine_cache_bytes: AtomicUsize,
    /// Per-tile bounds of the directly seen vertices, built on first use
    /// (footprint-culled direct stages, [`super::footprint`]).
    tile_bounds: OnceLock<super::footprint::TileBounds>,
}

impl View {
    /// Traces primary samples and expands camera paths for `sampling`.
    pub fn build(
        scene: &Scene,
        camera: Camera,
        width: u32,
        height: u32,
        sampling: Sampling,
        limits: RecursionLimits,
    ) -> Self {
        Self::from_gbuffer(scene, GBuffer::build(scene, camera, width, height), sampling, limits)
    }

    /// Expands camera paths over an existing G-buffer (e.g. to switch the
    /// sampling mode without re-tracing primary rays).
    pub fn from_gbuffer(scene: &Scene, gbuffer: GBuffer, sampling: Sampling, limits: RecursionLimits) -> Self {
        Self::from_gbuffer_with_set(scene, gbuffer, sampling, sampling.base_set(), limits)
    }

    /// As [`View::from_gbuffer`] with the base sample set given explicitly
    /// (the bench renders the pre-issue-13 [`SampleSet::TriangleBins`] this way).
    pub fn from_gbuffer_with_set(
        scene: &Scene,
        gbuffer: GBuffer,
        sampling: Sampling,
        set: SampleSet,
        limits: RecursionLimits,
    ) -> Self {
        let shading = Self::expand_all(scene, &gbuffer, set, limits);
        let nine_cache = (0..gbuffer.samples.len()).map(|_| OnceLock::new()).collect();
        Self {
            gbuffer,
            shading,
            sampling,
            limits,
            nine_cache,
            nine_cache_bytes: AtomicUsize::new(0),
            tile_bounds: OnceLock::new(),
        }
    }

    /// Per-tile bounds of the directly seen vertices (built once per view).
    pub fn tile_bounds(&self) -> &super::footprint::TileBounds {
        self.tile_bounds.get_or_init(|| super::footprint::TileBounds::build(self))
    }

    /// Memory held: G-buffer samples and bins, camera-path vertices and the
    /// cached 9-sample expansions (what a view cache counts against its budget).
    pub fn bytes(&self) -> usize {
        self.gbuffer.bytes()
            + std::mem::size_of_val(self.shading.vertices())
            + (self.gbuffer.samples.len() + 1) * std::mem::size_of::<u32>()
            + self.nine_cache.len() * std::mem::size_of::<OnceLock<Box<NinePaths>>>()
            + self.nine_cache_bytes.load(Ordering::Relaxed).min(NINE_SAMPLE_CACHE_BYTES)
    }

    /// Image width.
    pub fn width(&self) -> u32 {
        self.gbuffer.width
    }

    /// Image height.
    pub fn height(&self) -> u32 {
        self.gbuffer.height
    }

    /// Expands every pixel's camera paths for `set` (parallel over rows).
    pub fn expand_all(scene: &Scene, gbuffer: &GBuffer, set: SampleSet, limits: RecursionLimits) -> ShadingSet {
        let w = gbuffer.width as usize;
        let rows: Vec<(Vec<u32>, Vec<ShadingVertex>)> = (0..gbuffer.height as usize)
            .into_par_iter()
            .map(|y| {
                let mut counts = Vec::with_capacity(w);
                let mut verts = Vec::new();
                // The two sets every view uses walk the row directly (the
                // same samples as expand_pixel, without its per-pixel
                // dispatch and range look-up); the bench's others take it.
                if set == SampleSet::Centre {
                    for samples in &gbuffer.samples[y * w..(y + 1) * w] {
                        let before = verts.len();
                        expand_sample(scene, gbuffer, samples[CENTRE_SAMPLE], 1.0, limits, &mut verts);
                        counts.push((verts.len() - before) as u32);
                    }
                } else if set == SampleSet::Binned {
                    for bins in gbuffer.row_bins(y) {
                        let before = verts.len();
                        expand_bins(scene, gbuffer, bins, limits, &mut verts);
                        counts.push((verts.len() - before) as u32);
                    }
                } else {
                    for x in 0..w {
                        let before = verts.len();
                        expand_pixel(scene, gbuffer, y * w + x, set, limits, &mut verts);
                        counts.push((verts.len() - before) as u32);
                    }
                }
                (counts, verts)
            })
            .collect();
        let mut start = Vec::with_capacity(w * gbuffer.height as usize + 1);
        let mut vertices = Vec::with_capacity(rows.iter().map(|r| r.1.len()).sum());
        start.push(0u32);
        for (counts, verts) in rows {
            for c in counts {
                let last = *start.last().unwrap_or(&0);
                start.push(last + c);
            }
            vertices.extend(verts);
        }
        ShadingSet { set, start, vertices }
    }

    /// Renders light `light`'s unit-intensity buffer I_h,ε_i (eq. 5). With
    /// `aa` set and adaptive sampling, high-gradient pixels are re-shaded
    /// with all 9 samples. Returns the buffer and the number of re-shaded pixels.
    pub fn render_light(&self, scene: &Scene, light: &Light, aa: Option<AaParams>) -> (LightBuffer, usize) {
        let (dense, reshaded) = self.render_direct(scene, light, aa);
        (LightBuffer::from_dense(self.width(), self.height(), &dense), reshaded)
    }

    /// The first build stage of a moved light: direct light at the surfaces
    /// the camera sees directly (no mirrors, no glass, no anti-aliasing
    /// re-shading), so a moving light is seen moving within one cheap pass.
    pub fn render_primary_direct(&self, scene: &Scene, light: &Light) -> Vec<Vec3> {
        let w = self.width() as usize;
        let mut dense = vec![Vec3::ZERO; w * self.height() as usize];
        dense.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                *out = self
                    .shading
                    .pixel(y * w + x)
                    .iter()
                    .filter(|v| v.depth == 0)
                    .map(|v| v.weight * direct(scene, light, v))
                    .sum();
            }
        });
        dense
    }

    /// As [`View::render_light`], returning the dense row-major direct buffer.
    pub fn render_direct(&self, scene: &Scene, light: &Light, aa: Option<AaParams>) -> (Vec<Vec3>, usize) {
        self.render_direct_until(scene, light, aa, &|| false).unwrap_or_default()
    }

    /// As [`View::render_direct`], abandoned (`None`) once `stop` returns
    /// true: checked on every row, so a cancelled build stops within a row.
    pub fn render_direct_until(
        &self,
        scene: &Scene,
        light: &Light,
        aa: Option<AaParams>,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Option<(Vec<Vec3>, usize)> {
        let (w, h) = (self.width() as usize, self.height() as usize);
        let mut dense = vec![Vec3::ZERO; w * h];
        // Each row's lit span comes with its shading when anti-aliasing
        // follows (the decision reads only the lit spans: no pass over the
        // dark part of the picture).
        let aa = aa.filter(|_| self.sampling == Sampling::Adaptive);
        let spans: RowSpans = dense
            .par_chunks_mut(w)
            .enumerate()
            .map(|(y, row)| {
                if stop() {
                    return None;
                }
                let pixel = |x: usize| shade(scene, light, self.shading.pixel(y * w + x));
                if aa.is_none() {
                    for (x, out) in row.iter_mut().enumerate() {
                        *out = pixel(x);
                    }
                    return None;
                }
                // The row's lit span ([`row_span`]'s rule: a NaN counts as
                // lit), found as the row is written. Written out here: the
                // same rule through a shared helper cost this loop ~8 M
                // instructions a pass (callgrind), as it compiled.
                let mut span: Option<(usize, usize)> = None;
                for (x, out) in row.iter_mut().enumerate() {
                    *out = pixel(x);
                    if *out != Vec3::ZERO {
                        span = Some((span.map_or(x, |s| s.0), x + 1));
                    }
                }
                span
            })
            .collect();
        if stop() {
            return None;
        }
        let mut reshaded = 0;
        if let Some(aa) = aa {
            let decision = self.aa_decision_in(scene, light, &dense, &spans, aa);
            reshaded = self.reshade(scene, light, &mut dense, decision.reshading());
        }
        if stop() {
            return None;
        }
        Some((dense, reshaded))
    }
}

impl View {
    /// The indirect buffer I_h,ε_A,i (eq. 3, 5) of a light from its photon
    /// maps: Σ over each pixel's vertices of path weight ⊙ ρ_d/π ⊙ E(x).
    /// Indirect light is smooth, so it is evaluated on the base sample set
    /// only (anti-aliasing re-shades the direct term).
    pub fn render_indirect(&self, scene: &Scene, maps: &PhotonMaps) -> Vec<Vec3> {
        self.dense_from_vertices(scene, |_, v| maps.irradiance(v.position, v.normal))
    }

    /// The photon maps' indirect irradiance E(x) at every vertex of the base
    /// sample set (zero at vertices without a diffuse part): what
    /// [`View::render_indirect`] shades with, kept to start refinement from
    /// ([`Progressive::starting_from`]).
    pub fn vertex_irradiance(&self, scene: &Scene, maps: &PhotonMaps) -> Vec<Vec3> {
        self.vertex_irradiance_until(scene, maps, &|| false).unwrap_or_default()
    }

    /// As [`View::vertex_irradiance`], abandoned (`None`) once `stop`
    /// returns true (checked at every vertex: a cancelled build stops at once).
    pub fn vertex_irradiance_until(
        &self,
        scene: &Scene,
        maps: &PhotonMaps,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Option<Vec<Vec3>> {
        let e = self
            .shading
            .vertices()
            .par_iter()
            .map(|v| {
                if stop() || scene.materials[v.material as usize].diffuse.max_element() <= 0.0 {
                    Vec3::ZERO
                } else {
                    maps.irradiance(v.position, v.normal)
                }
            })
            .collect();
        (!stop()).then_some(e)
    }

    /// The coarse first indirect estimate of a view change (issue 16): the
    /// photon maps' irradiance is looked up exactly at the vertices of every
    /// `step`-th pixel in x and y (the anchor pixels); a vertex of any other
    /// pixel takes the distance-weighted mean of the anchor vertices around
    /// it (the up to 4 anchor pixels of its cell) that lie on the same
    /// surface: same bounce depth and material, normals within ~18°, and
    /// within 1 % of its distance from the eye (or 1.5 anchor spacings of
    /// pixel footprint, when that is more). A vertex with no such
    /// neighbour is looked up exactly. Indirect light is smooth, so this
    /// costs about 1/`step`² of [`View::vertex_irradiance`] with a small
    /// error (the walk bench reports it); returns the values and which
    /// ones are exact, for [`View::fill_vertex_irradiance_until`] to finish.
    pub fn coarse_vertex_irradiance_until(
        &self,
        scene: &Scene,
        maps: &PhotonMaps,
        step: u32,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Option<(Vec<Vec3>, Vec<bool>)> {
        let (w, h) = (self.width() as usize, self.height() as usize);
        let step = step.max(1) as usize;
        let vertices = self.shading.vertices();
        let eye = self.gbuffer.camera.position;
        // A surface point within this share of its distance from the eye is
        // "near": 1 %, or 1.5 anchor spacings of pixel footprint when larger.
        let pixel = 2.0 * (self.gbuffer.camera.yfov / 2.0).tan() / h.max(1) as f32;
        let near = (1.5 * step as f32 * pixel).max(0.01);
        let exact = |v: &ShadingVertex| {
            if scene.materials[v.material as usize].diffuse.max_element() <= 0.0 {
                Vec3::ZERO
            } else {
                maps.irradiance(v.position, v.normal)
            }
        };
        let mut e = vec![Vec3::ZERO; vertices.len()];
        let mut known = vec![false; vertices.len()];
        // Anchors: every step-th pixel of every step-th row.
        let anchors: Vec<(usize, Vec<Vec3>)> = (0..h)
            .step_by(step)
            .flat_map(|y| (0..w).step_by(step).map(move |x| y * w + x))
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|i| (i, if stop() { Vec::new() } else { self.shading.pixel(i).iter().map(exact).collect() }))
            .collect();
        if stop() {
            return None;
        }
        for (i, values) in anchors {
            let range = self.shading.pixel_range(i);
            e[range.clone()].copy_from_slice(&values);
            known[range].iter_mut().for_each(|k| *k = true);
        }
        let anchor_of = |x: usize, y: usize| -> [usize; 4] {
            let (x0, y0) = (x - x % step, y - y % step);
            let x1 = if x0 + step < w { x0 + step } else { x0 };
            let y1 = if y0 + step < h { y0 + step } else { y0 };
            [y0 * w + x0, y0 * w + x1, y1 * w + x0, y1 * w + x1]
        };
        let (e_ref, known_ref) = (&e, &known);
        let rest: Vec<(usize, Vec<(Vec3, bool)>)> = (0..w * h)
            .into_par_iter()
            .filter(|i| (i % w) % step != 0 || (i / w) % step != 0)
            .map(|i| {
                if stop() {
                    return (i, Vec::new());
                }
                let cell = anchor_of(i % w, i / w);
                let values = self
                    .shading
                    .pixel(i)
                    .iter()
                    .map(|v| {
                        if scene.materials[v.material as usize].diffuse.max_element() <= 0.0 {
                            return (Vec3::ZERO, true);
                        }
                        let tolerance = near * v.position.distance(eye);
                        let (mut sum, mut weights) = (Vec3::ZERO, 0.0f32);
                        for (n, &a) in cell.iter().enumerate() {
                            if cell[..n].contains(&a) {
                                continue; // a cell on the picture's edge repeats anchors
                            }
                            for j in self.shading.pixel_range(a) {
                                let u = &vertices[j];
                                let d = u.position.distance(v.position);
                                if known_ref[j]
                                    && u.depth == v.depth
                                    && u.material == v.material
                                    && u.normal.dot(v.normal) >= 0.95
                                    && d <= tolerance
                                {
                                    let wt = 1.0 / (d + 1e-3 * tolerance);
                                    sum += e_ref[j] * wt;
                                    weights += wt;
                                }
                            }
                        }
                        if weights > 0.0 { (sum / weights, false) } else { (exact(v), true) }
                    })
                    .collect();
                (i, values)
            })
            .collect();
        if stop() {
            return None;
        }
        for (i, values) in rest {
            for (j, (value, is_exact)) in self.shading.pixel_range(i).zip(values) {
                e[j] = value;
                known[j] = is_exact;
            }
        }
        Some((e, known))
    }

    /// Replaces every value of `e` not marked `exact` by the photon maps'
    /// irradiance there: afterwards `e` equals [`View::vertex_irradiance`].
    /// `None` once `stop` returns true.
    pub fn fill_vertex_irradiance_until(
        &self,
        scene: &Scene,
        maps: &PhotonMaps,
        e: &mut [Vec3],
        exact: &[bool],
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Option<()> {
        e.par_iter_mut().zip(self.shading.vertices().par_iter()).zip(exact.par_iter()).for_each(|((out, v), &done)| {
            if !done && !stop() {
                *out = if scene.materials[v.material as usize].diffuse.max_element() <= 0.0 {
                    Vec3::ZERO
                } else {
                    maps.irradiance(v.position, v.normal)
                };
            }
        });
        (!stop()).then_some(())
    }

    /// The indirect buffer from per-vertex irradiance `e` (one value per
    /// vertex of `shading.vertices()`): Σ w_v ⊙ ρ_d/π ⊙ e_v per pixel.
    pub fn render_vertex_irradiance(&self, scene: &Scene, e: &[Vec3]) -> Vec<Vec3> {
        self.dense_from_vertices(scene, |i, _| e.get(i).copied().unwrap_or(Vec3::ZERO))
    }

    /// The indirect buffer from progressive photon mapping state.
    pub fn render_progressive(&self, scene: &Scene, sppm: &Progressive) -> Vec<Vec3> {
        self.render_vertex_irradiance(scene, &sppm.irradiance())
    }

    /// Per pixel Σ_v w_v ⊙ ρ_d/π ⊙ irradiance(v) over the base sample set.
    /// `irradiance` gets the vertex's index in `shading.vertices()` and the vertex.
    fn dense_from_vertices(
        &self,
        scene: &Scene,
        irradiance: impl Fn(usize, &ShadingVertex) -> Vec3 + Sync,
    ) -> Vec<Vec3> {
        let (w, h) = (self.width() as usize, self.height() as usize);
        let vertices = self.shading.vertices();
        let mut dense = vec![Vec3::ZERO; w * h];
        dense.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                *out = self
                    .shading
                    .pixel_range(y * w + x)
                    .map(|i| {
                        let v = &vertices[i];
                        // ρ_d at the vertex (material times texture).
                        let rho = v.diffuse;
                        if scene.materials[v.material as usize].diffuse.max_element() <= 0.0 {
                            Vec3::ZERO
                        } else {
                            v.weight * rho * std::f32::consts::FRAC_1_PI * irradiance(i, v)
                        }
                    })
                    .sum();
            }
        });
        dense
    }

    /// The 9-sample camera paths of pixel `index`: the order of the
    /// samples (a cached expansion's, else [`CORNERS_FIRST`]), each one's
    /// vertex count in that order and the vertices, from the cache or
    /// freshly expanded (into `scratch` once the cache budget is spent).
    fn nine_paths<'a>(
        &'a self,
        scene: &Scene,
        index: usize,
        scratch: &'a mut Vec<ShadingVertex>,
    ) -> ([usize; SAMPLES_PER_PIXEL], [u32; SAMPLES_PER_PIXEL], &'a [ShadingVertex]) {
        if let Some(paths) = self.nine_cache[index].get() {
            return (paths.order, paths.counts, &paths.vertices);
        }
        scratch.clear();
        let mut counts = [0u32; SAMPLES_PER_PIXEL];
        self.expand_samples(scene, index, &CORNERS_FIRST, &mut counts, scratch);
        match self.cache_nine(index, CORNERS_FIRST, counts, scratch) {
            Some(paths) => (paths.order, paths.counts, &paths.vertices),
            None => (CORNERS_FIRST, counts, scratch),
        }
    }

    /// Appends the camera paths of pixel `index`'s `samples` (weight 1/9
    /// each), each one's vertex count into `counts`.
    fn expand_samples(
        &self,
        scene: &Scene,
        index: usize,
        samples: &[usize],
        counts: &mut [u32],
        out: &mut Vec<ShadingVertex>,
    ) {
        let limits = self.sample_limits(index);
        for (&s, count) in samples.iter().zip(counts) {
            let before = out.len();
            let p = self.gbuffer.samples[index][s];
            expand_sample(scene, &self.gbuffer, p, 1.0 / SAMPLES_PER_PIXEL as f32, limits, out);
            *count = u32::try_from(out.len() - before).unwrap_or(u32::MAX);
        }
    }

    /// Keeps pixel `index`'s 9-sample paths for the next light or rebuild
    /// that re-shades it, while the cache's byte budget lasts.
    fn cache_nine(
        &self,
        index: usize,
        order: [usize; SAMPLES_PER_PIXEL],
        counts: [u32; SAMPLES_PER_PIXEL],
        vertices: &[ShadingVertex],
    ) -> Option<&NinePaths> {
        let bytes = std::mem::size_of::<NinePaths>() + std::mem::size_of_val(vertices);
        if self.nine_cache_bytes.fetch_add(bytes, Ordering::Relaxed) + bytes <= NINE_SAMPLE_CACHE_BYTES {
            let paths =
                self.nine_cache[index].get_or_init(|| Box::new(NinePaths { order, counts, vertices: vertices.into() }));
            return Some(paths);
        }
        self.nine_cache_bytes.fetch_sub(bytes, Ordering::Relaxed);
        None
    }
}

/// Σ over a pixel's vertices of path weight ⊙ direct light.
fn shade(scene: &Scene, light: &Light, vertices: &[ShadingVertex]) -> Vec3 {
    vertices.iter().map(|v| v.weight * direct(scene, light, v)).sum()
}

/// [`shade`] with the shadow rays' [`OccluderHint`] kept across calls (the
/// samples of one re-shaded pixel): the same sum, in the same order.
fn shade_hinted(scene: &Scene, light: &Light, vertices: &[ShadingVertex], hint: &mut OccluderHint) -> Vec3 {
    vertices.iter().map(|v| v.weight * direct_hinted(scene, light, v, hint)).sum()
}

/// Appends the camera-path vertices of pixel `index` for sample set `set`.
pub fn expand_pixel(
    scene: &Scene,
    gbuffer: &GBuffer,
    index: usize,
    set: SampleSet,
    limits: RecursionLimits,
    out: &mut Vec<ShadingVertex>,
) {
    let samples = &gbuffer.samples[index];
    match set {
        SampleSet::Centre => expand_sample(scene, gbuffer, samples[CENTRE_SAMPLE], 1.0, limits, out),
        SampleSet::Binned => expand_bins(scene, gbuffer, gbuffer.bins(index), limits, out),
        SampleSet::TriangleBins => match single_bin(samples) {
            // Most pixels see one triangle: its bin without the 9-slot array.
            Some(b) => expand_bins(scene, gbuffer, &[b], limits, out),
            None => expand_bins(scene, gbuffer, bin_samples(samples).as_slice(), limits, out),
        },
        SampleSet::All => {
            for &s in samples {
                expand_sample(scene, gbuffer, s, 1.0 / SAMPLES_PER_PIXEL as f32, limits, out);
            }
        }
    }
}

/// Appends the camera paths of a pixel's `bins`, each from its mean point
/// with its weight.
#[inline]
fn expand_bins(scene: &Scene, gbuffer: &GBuffer, bins: &[Bin], limits: RecursionLimits, out: &mut Vec<ShadingVertex>) {
    for b in bins {
        let s = PrimarySample { triangle: b.triangle, u: b.u, v: b.v };
        expand_sample(scene, gbuffer, s, b.weight, limits, out);
    }
}

/// Appends the camera path of one primary sample (or bin: its mean point)
/// with path weight `weight`; nothing for a miss.
fn expand_sample(
    scene: &Scene,
    gbuffer: &GBuffer,
    s: PrimarySample,
    weight: f32,
    limits: RecursionLimits,
    out: &mut Vec<ShadingVertex>,
) {
    if s.triangle == NO_HIT || weight <= 0.0 {
        return;
    }
    let cam = gbuffer.camera.position;
    let p = scene.point_on(s.triangle, s.u, s.v);
    let Some(dir) = (p - cam).try_normalize() else { return };
    let surface = scene.surface(&Hit { triangle: s.triangle, t: p.distance(cam), u: s.u, v: s.v });
    expand(scene, surface, dir, Vec3::splat(weight), limits, out);
}
