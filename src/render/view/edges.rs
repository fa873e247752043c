//! Progressive stratified supersampling of a light's edge pixels (issue 34,
//! items 1 and 2): what takes the direct term from the 9-sample G-buffer
//! to the box-filtered pixel.
//!
//! The Whitted stage shades each pixel from the view's 3×3 sample grid
//! (bins, adaptive re-shading: [`super::aa`]). Where the light's picture
//! is smooth that is the box filter to display precision; where it has an
//! edge (beam rims, gobo and shutter cuts, shadows, geometry edges and
//! silhouettes) a fixed grid quantises the covered share to ninths, and
//! that quantisation was 99 % of the direct term's remaining error
//! (`footlight bench --converge-only`). [`EdgeSamples`] picks those
//! pixels once from the Whitted term and, one batch per refinement pass,
//! shades [`EDGE_SAMPLES_PER_PASS`] new camera paths through each at the
//! points of a (0,2)-sequence ([`sobol_02`], a Cranley-Patterson shift
//! per pixel): every power-of-two count of them is stratified in both
//! axes and their mean converges to the box-filtered pixel as O(n^-3/4)
//! on an edge. Once a batch has run, those samples alone stand for the
//! pixel (the 9-sample value is a fixed quadrature, not an estimate to
//! average with).
//!
//! Each sample is a camera path like the Whitted stage's ([`expand`]:
//! mirrors and glass to the view's limits) shaded with [`direct`], so the
//! result is eq. 1's direct term, per pixel, box-filtered.

use super::{BeamEdge, View};
use crate::fixture::Light;
use crate::render::buffer::{LightBuffer, TILE};
use crate::render::gbuffer::NO_HIT;
use crate::render::reference::path::sobol_02;
use crate::render::whitted::{ShadingVertex, direct, expand};
use crate::scene::Scene;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// New camera paths per edge pixel in each refinement pass: one (0,2)-net
/// of 16 points (a 4×4 stratification, finer than the 3×3 grid it
/// replaces), so after pass k a pixel holds 16·k samples.
pub const EDGE_SAMPLES_PER_PASS: u32 = 16;

/// A pixel is an edge pixel when its direct term differs from a
/// neighbour's (8-neighbourhood) by more than this share of the light's
/// reference level ([`super::aa::reference_level`]: the 99th percentile
/// of its lit pixels). 1 %: below it a pixel's error is below display
/// precision, and a smooth falloff's neighbours differ by less.
pub const EDGE_CONTRAST: f32 = 0.01;

/// One light's edge pixels and their stratified samples so far.
pub struct EdgeSamples {
    /// Row-major indices of the edge pixels, ascending.
    pixels: Vec<u32>,
    /// Σ of each edge pixel's samples (f64: 16·32 samples and more).
    sums: Vec<DVec3>,
    /// Samples per edge pixel so far.
    samples: u32,
    /// Seed of the per-pixel shifts.
    seed: u64,
}

impl EdgeSamples {
    /// The edge pixels of a light's Whitted term `direct` over `view`:
    /// pixels whose value differs from an 8-neighbour's by more than
    /// [`EDGE_CONTRAST`] of the light's reference level (both pixels of
    /// such a pair), and lit pixels that straddle surfaces (more than one
    /// bin). Only the occupied tiles are read, and a pixel of an empty
    /// tile beside a lit one is found from the lit side.
    ///
    /// Not the rim pixels of a hard cone edge that the Whitted stage shaded
    /// by cell coverage ([`super::BeamRim::cover`], [`super::rim`]): that is the
    /// box filter to ~1e-6 already (`tests/beam_rim.rs`), better than 64
    /// samples (`tests/edges.rs`: a gobo's rim went from 1.1e-4 to 7.5e-4
    /// when they were resampled).
    pub fn select(scene: &Scene, view: &View, light: &Light, direct: &LightBuffer, seed: u64) -> Self {
        let (w, h) = (view.width() as usize, view.height() as usize);
        let level = super::aa::reference_level(&direct.raw().0).unwrap_or(0.0);
        let mut pixels: Vec<u32> = Vec::new();
        if level > 0.0 && level.is_finite() && direct.width as usize == w && direct.height as usize == h {
            let jump = EDGE_CONTRAST * level;
            let tiles = direct.occupied();
            let found: Vec<Vec<u32>> = tiles
                .par_iter()
                .map(|&(tx, ty)| {
                    let mut out = Vec::new();
                    for y in ty * TILE..((ty + 1) * TILE).min(h) {
                        for x in tx * TILE..((tx + 1) * TILE).min(w) {
                            let here = direct.get(x as u32, y as u32);
                            let i = y * w + x;
                            if here != Vec3::ZERO && view.gbuffer.bins(i).len() > 1 {
                                out.push(i as u32);
                            }
                            for (dx, dy) in [(-1i64, -1i64), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)]
                            {
                                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                                if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                                    continue;
                                }
                                let there = direct.get(nx as u32, ny as u32);
                                // A NaN compares false: it is not an edge
                                // ([`LightBuffer::check`] reports it).
                                if (here - there).abs().max_element() > jump {
                                    out.push(i as u32);
                                    out.push((ny as usize * w + nx as usize) as u32);
                                }
                            }
                        }
                    }
                    out
                })
                .collect();
            pixels = found.concat();
            pixels.sort_unstable();
            pixels.dedup();
            // A pixel that sees a sharp highlight (a Phong exponent of
            // [`super::GLINT_EXPONENT`] or more) stays with the Whitted
            // stage's glint handling: a glint covers a sliver of the pixel
            // at thousands of times its level, so a few dozen samples make
            // it a firefly (the bundled stage at 40×25: one sample in 32
            // doubled a pixel's value 14,000-fold).
            let sharp: Vec<bool> = scene.materials.iter().map(super::is_sharp).collect();
            if sharp.iter().any(|&s| s) {
                let sees_sharp = |i: u32| {
                    view.gbuffer.samples[i as usize].iter().any(|p| {
                        p.triangle != NO_HIT
                            && scene.material_of.get(p.triangle as usize).is_some_and(|&m| sharp[m as usize])
                    })
                };
                pixels.retain(|&i| !sees_sharp(i));
            }
            if BeamEdge::of(light).is_some() {
                let rim = view.beam_rim(scene, light, &lit_spans(direct));
                pixels.retain(|&i| rim.cover.binary_search(&(i as usize)).is_err());
            }
        }
        let sums = vec![DVec3::ZERO; pixels.len()];
        Self { pixels, sums, samples: 0, seed }
    }

    /// Number of edge pixels.
    pub fn len(&self) -> usize {
        self.pixels.len()
    }

    /// True when the light has no edge pixel.
    pub fn is_empty(&self) -> bool {
        self.pixels.is_empty()
    }

    /// Samples per edge pixel so far.
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// The edge pixels, row-major indices, ascending.
    pub fn pixels(&self) -> &[u32] {
        &self.pixels
    }

    /// Bytes held (for the tracer's memory budget).
    pub fn bytes(&self) -> usize {
        self.pixels.len() * (std::mem::size_of::<u32>() + std::mem::size_of::<DVec3>())
    }

    /// Adds [`EDGE_SAMPLES_PER_PASS`] stratified camera paths to every
    /// edge pixel, shaded with `light`'s direct term; `false` (nothing
    /// added) once `stop` returns true (checked per pixel).
    pub fn pass_until(&mut self, scene: &Scene, view: &View, light: &Light, stop: &(dyn Fn() -> bool + Sync)) -> bool {
        let (w, h) = (view.width(), view.height());
        let (first, seed) = (self.samples, self.seed);
        let camera = view.gbuffer.camera;
        let limits = view.limits;
        let added: Option<Vec<DVec3>> = self
            .pixels
            .par_iter()
            .map_init(Vec::<ShadingVertex>::new, |scratch, &i| {
                if stop() {
                    return None;
                }
                let (x, y) = (i % w, i / w);
                let (sx0, sy0) = pixel_shift(seed, i);
                let mut sum = DVec3::ZERO;
                for n in first..first + EDGE_SAMPLES_PER_PASS {
                    let (sx, sy) = sobol_02(n);
                    let (jx, jy) = ((sx + sx0).fract(), (sy + sy0).fract());
                    let dir = camera.direction(x as f32 + jx as f32, y as f32 + jy as f32, w, h);
                    let Some(hit) = scene.accel.intersect(camera.position, dir, f32::INFINITY) else { continue };
                    scratch.clear();
                    expand(scene, scene.surface(&hit), dir, Vec3::ONE, limits, scratch);
                    let shade: Vec3 = scratch.iter().map(|v| v.weight * direct(scene, light, v)).sum();
                    sum += shade.as_dvec3();
                }
                Some(sum)
            })
            .collect();
        let Some(added) = added else { return false };
        self.sums.iter_mut().zip(added).for_each(|(s, a)| *s += a);
        self.samples += EDGE_SAMPLES_PER_PASS;
        true
    }

    /// Each edge pixel's box-filtered direct term so far (the mean of its
    /// samples), with its row-major index; nothing before the first pass.
    pub fn means(&self) -> impl Iterator<Item = (usize, Vec3)> + '_ {
        let n = f64::from(self.samples.max(1));
        let any = self.samples > 0;
        self.pixels.iter().zip(&self.sums).filter(move |_| any).map(move |(&i, s)| (i as usize, (*s / n).as_vec3()))
    }

    /// `sum` (a dense picture that holds `direct` at every pixel) with each
    /// edge pixel's direct term replaced by its samples' mean.
    pub fn replace_in(&self, sum: &mut [Vec3], direct: &LightBuffer) {
        let w = direct.width as usize;
        for (i, mean) in self.means() {
            if let Some(p) = sum.get_mut(i) {
                *p += mean - direct.get((i % w) as u32, (i / w) as u32);
            }
        }
    }
}

/// Each row's lit span ([`super::RowSpans`]) of a tile-sparse buffer, from
/// its occupied tiles alone.
fn lit_spans(buffer: &LightBuffer) -> super::RowSpans {
    let (w, h) = (buffer.width as usize, buffer.height as usize);
    let mut spans: super::RowSpans = vec![None; h];
    for (tx, ty) in buffer.occupied() {
        for (y, row) in spans.iter_mut().enumerate().take(((ty + 1) * TILE).min(h)).skip(ty * TILE) {
            for x in tx * TILE..((tx + 1) * TILE).min(w) {
                if buffer.get(x as u32, y as u32) != Vec3::ZERO {
                    let span = row.get_or_insert((x, x + 1));
                    *span = (span.0.min(x), span.1.max(x + 1));
                }
            }
        }
    }
    spans
}

/// Pixel `index`'s Cranley-Patterson shift of the (0,2)-sequence (a hash
/// of the seed and the index: no state per pixel).
fn pixel_shift(seed: u64, index: u32) -> (f64, f64) {
    let mut z = seed ^ u64::from(index).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    let mut next = || {
        // splitmix64 (Steele, Lea and Flood 2014).
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut r = z;
        r = (r ^ (r >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        r = (r ^ (r >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        r ^ (r >> 31)
    };
    ((next() >> 11) as f64 / (1u64 << 53) as f64, (next() >> 11) as f64 / (1u64 << 53) as f64)
}
