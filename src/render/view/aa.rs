//! The anti-aliasing policy of a light's buffer: which pixels
//! [`View::render_direct`] re-shades with the 9 samples, and how.
//!
//! The paper's adaptive anti-aliasing of the illumination (Vierjahn 2010,
//! section 3.4): where the value jumps by more than a threshold (0-255
//! scale) to a neighbour, the paper re-shades the pixel and its 8
//! neighbours with all 9 samples; Footlight re-shades the two pixels of the
//! jump ([`AaMarking::Pair`]), each corners first (a pixel whose facing
//! corner samples agree with its base value keeps it: the jump lies in the
//! other pixel; where they disagree, a pixel of one surface bin is rebuilt
//! from those corners and its base, [`Reshading`]), and, on sharp specular
//! surfaces, with all 9 samples the pixels whose 9 samples would see the
//! light's highlight ([`View::glint_pixels`]: a highlight smaller than a
//! pixel shows no jump), and the pixels a light's hard cone edge crosses
//! by cell coverage ([`super::rim`]: the gradient pairs miss some of them,
//! and the corner reconstruction is coarser than 9 samples there). The
//! bench (`footlight bench --accuracy-only
//! --accuracy-part aa`) measures the error of both against 81 samples per
//! pixel, and their time.
//!
//! The paper compares displayed values; Footlight compares the light's
//! *own relative* values instead: the buffer is shown as if its brightest
//! pixels (the 99th percentile, [`AA_REFERENCE_PERCENTILE`]) were display
//! white, through the sRGB curve. That is a gradient relative to the light
//! itself, so the sample set depends on neither exposure nor dimmer nor
//! k_i: a dim light anti-aliases its shadow edges the same way a bright one
//! does, and a re-shaded light never changes when the operator changes the
//! exposure. Neighbours on different surfaces (another triangle with a
//! normal more than ~8° off, or another material) are not compared: the
//! surface bins already anti-alias those edges, and a jump there is
//! geometry, not illumination.
//!
//! The renderer's parameters are [`AaParams::new`]; the variants measured
//! on the way there (which pixels a pair marks, corners first or not, the
//! reconstruction of one-bin pixels) stay inside the crate, for the bench.

use super::rim::{BeamEdge, BeamRim, cell_coverage, grid_gradient};
use super::{View, shade_hinted};
use crate::fixture::Light;
use crate::render::display::srgb8;
use crate::render::gbuffer::{
    CENTRE_SAMPLE, NO_HIT, PrimarySample, SAME_SURFACE_COS, SAMPLES_PER_PIXEL, sharp_samples,
};
use crate::render::view::SampleSet;
use crate::render::whitted::{RecursionLimits, ShadingVertex, direct_hinted, direct_with_pattern};
use crate::scene::bvh::OccluderHint;
use crate::scene::{Hit, Scene};
use glam::Vec3;
use rayon::prelude::*;

/// A sharp specular material: Phong lobe of exponent ≥ [`GLINT_EXPONENT`]
/// (see [`View::glint_pixels`]).
pub fn is_sharp(m: &crate::scene::Material) -> bool {
    m.specular.max_element() > 0.0 && m.exponent >= GLINT_EXPONENT
}

/// Which pixels an over-threshold neighbour pair marks for re-shading
/// (issue 13, AA cost). The renderer marks [`AaMarking::Pair`]; the others
/// are the bench's comparisons.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub enum AaMarking {
    /// The two pixels of the pair: the jump lies between their centres, so
    /// the edge crosses one of them or both.
    #[default]
    Pair,
    /// The pair and the pixel beyond each, in the pair's direction (4 pixels
    /// in a row across the edge).
    Across,
    /// Both pixels and their 8 neighbours (3×3 dilation: the paper's "the
    /// current and the neighbouring pixels"; the rule before issue 13).
    Dilated,
}

/// Adaptive anti-aliasing parameters (the same for every light: the decision
/// is relative to each light's own buffer, see the module docs). Outside
/// the crate only the threshold is chosen ([`AaParams::new`]); the other
/// fields are the renderer's policy, varied only by the bench.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AaParams {
    /// Gradient threshold on the 0-255 scale, with the light's 99th-percentile
    /// pixel at 255 (paper: 15-25 on the displayed image).
    pub threshold: f32,
    /// Which pixels a pair over the threshold marks ([`AaMarking::Pair`]).
    pub(crate) marking: AaMarking,
    /// Also mark the pixels that may hold the light's highlight on a sharp
    /// specular surface ([`View::glint_pixels`]): a highlight smaller than a
    /// pixel that the one shade per bin misses (true).
    pub(crate) glints: bool,
    /// Re-shade a pair's pixels corners first ([`Reshading::corners_first`]):
    /// a pixel whose facing corner samples agree with its base value keeps
    /// it (true).
    pub(crate) corners_first: bool,
    /// With corners first: a one-bin pixel whose probed corners disagree
    /// with its base is reconstructed from them and the base
    /// ([`Reshading::reconstruct`]) instead of taking all 9 samples (true;
    /// the bench's "before" rows measure it off).
    pub(crate) reconstruct: bool,
    /// Shade the pixels a hard beam edge crosses by cell coverage
    /// ([`View::beam_rim`], [`super::rim`]) whatever their gradient (true;
    /// the bench's "before" rows measure it off).
    pub(crate) rim: bool,
}

impl AaParams {
    /// The renderer's parameters with the given threshold (0-255 scale):
    /// pair marks, highlight pixels, corners first, one-bin pixels
    /// reconstructed from their probed corners, hard beam rims by cell
    /// coverage.
    pub fn new(threshold: f32) -> Self {
        Self { threshold, marking: AaMarking::Pair, glints: true, corners_first: true, reconstruct: true, rim: true }
    }
}

/// Which pixels [`View::reshade`] re-shades with the 9 samples, and how
/// (built by [`AaDecision::reshading`]).
#[derive(Clone, Copy, Debug)]
pub struct Reshading<'a> {
    /// The marked pixels (row-major).
    pub(crate) flags: &'a [bool],
    /// Marked pixels that take all 9 samples at once: the highlight pixels
    /// ([`View::glint_pixels`]), whose highlight can fall between the
    /// corner samples.
    pub(crate) whole: &'a [usize],
    /// `Some(level)`: the other marked pixels are shaded corners first
    /// (Whitted's adaptive supersampling, 1980): the corner samples of the
    /// 3×3 grid that face the pixel's pairs' partners (`facing`; all 4 for
    /// a pixel in no pair), and when each is within [`CORNER_AGREEMENT`] relative
    /// codes of the pixel's base value (the light's reference `level` =
    /// 255, the decision's scale), no edge crosses the pixel (a pair's jump
    /// lies in its other pixel) and it keeps its base value; else all the
    /// other samples too, or, with [`Reshading::reconstruct`], a one-bin
    /// pixel is rebuilt from those corners. `None` (the bench's rule
    /// comparison): all 9 samples for every marked pixel, as if each were
    /// listed in `whole`.
    pub(crate) corners_first: Option<f32>,
    /// The corners a pair's pixel probes first ([`facing_corners`], sorted
    /// by pixel): only those facing its over-threshold partners. A marked
    /// pixel not listed probes all 4.
    pub(crate) facing: &'a [(usize, u8)],
    /// With corners first: where the probed corners of a pixel whose base
    /// is one bin of all 9 samples disagree with it, the pixel is not
    /// shaded with its other samples but reconstructed on the 3×3 grid
    /// ([`reconstructed`]): the probed corners as shaded, the centre and
    /// the corners not probed at the base's value, each edge midpoint the
    /// mean of its two corners. Pixels of several bins take all 9 samples.
    pub(crate) reconstruct: bool,
    /// Marked pixels a hard beam edge crosses, of one surface (sorted,
    /// [`BeamRim::cover`]): shaded from their 9 sample paths with each
    /// sample's first vertex weighted by its cell's share inside the cone
    /// ([`super::rim`]); before any other rule.
    pub(crate) rim: &'a [usize],
    /// Marked pixels a hard beam edge crosses, of several surfaces
    /// (sorted, [`BeamRim::nine`]): all 9 samples at once, as `whole`.
    pub(crate) rim_nine: &'a [usize],
    /// The light's hard edge when `rim` is not empty.
    pub(crate) edge: Option<BeamEdge>,
}

/// What adaptive anti-aliasing re-shades for one light
/// ([`View::aa_decision`]).
#[derive(Clone, Debug)]
pub struct AaDecision {
    /// The marked pixels (row-major).
    pub flags: Vec<bool>,
    /// The highlight pixels among them ([`View::glint_pixels`]).
    pub highlights: Vec<usize>,
    /// The light's reference level when the pairs' pixels are re-shaded
    /// corners first ([`AaParams::corners_first`]).
    pub(crate) level: Option<f32>,
    /// The corners each pair's pixel probes first ([`facing_corners`]).
    pub(crate) facing: Vec<(usize, u8)>,
    /// Whether one-bin pixels are reconstructed from their probed corners
    /// ([`AaParams::reconstruct`]).
    pub(crate) reconstruct: bool,
    /// The pixels a hard beam edge crosses ([`View::beam_rim`]; empty
    /// without one).
    pub rim: BeamRim,
}

impl AaDecision {
    /// How [`View::reshade`] re-shades these pixels.
    pub fn reshading(&self) -> Reshading<'_> {
        Reshading {
            flags: &self.flags,
            whole: &self.highlights,
            corners_first: self.level,
            facing: &self.facing,
            reconstruct: self.reconstruct,
            rim: &self.rim.cover,
            rim_nine: &self.rim.nine,
            edge: self.rim.edge,
        }
    }
}

/// Relative sRGB codes (the light's reference level = 255) within which
/// the probed corner samples of a marked pixel must all lie of its base value
/// for a corners-first re-shade to keep the base ([`Reshading`]). On the
/// bundled stage ~45 % of the pairs' pixels stopped at all 4 corners, and
/// the error against 81 samples was the same to 3 digits as with all 9
/// samples everywhere (5.920e-6 against 5.918e-6; 40 codes gave 5.940e-6);
/// with the facing corners alone it is 6.015e-6.
pub const CORNER_AGREEMENT: f32 = 10.0;

/// Relative path weight below which a re-shaded sample's branches are not
/// followed (issue 13): on a pixel whose base is one bin of all 9 samples,
/// the base's own branches below this weight stand in for the 9 samples'
/// (the weak branches stay 1-sample, the strong ones are anti-aliased).
/// Path weights are products of the materials' constant k_R and k_T, so a
/// sample's tree and the base's split at the same branches. On the bundled
/// stage the re-shaded pixels' 9-sample paths hold 3,346 vertices below it
/// (most of them seen in the glass's k_R = 0.04 reflections), 30 % of
/// their traced rays, for 0.1 % of their light.
pub const RESHADE_MIN_BRANCH: f32 = 0.1;

/// The order in which a pixel's 9 samples are expanded for re-shading:
/// the 4 corners of the 3×3 grid first, then the other 5.
pub(super) const CORNERS_FIRST: [usize; SAMPLES_PER_PIXEL] = [0, 2, 6, 8, 1, 3, 4, 5, 7];

/// All 4 corners in a [`facing_corners`] mask (bit j: sample
/// `CORNERS_FIRST[j]`).
const ALL_CORNERS: u8 = 0b1111;

/// The corner samples of each pair's pixels that face the pair's other
/// pixel, as masks over the 4 corners (bit j: sample `CORNERS_FIRST[j]`;
/// the grid is row-major, 0 at the top left): a pixel and its right
/// neighbour probe samples 2 and 8 and 0 and 6, a pixel and its lower
/// neighbour 6 and 8 and 0 and 2. The jump between two pixel centres lies
/// in one of the two halves facing each other; where a pixel's facing
/// corners agree with its base, its 9 samples on that side do too.
/// `pairs` are (pixel, right or lower neighbour) of a `w`-pixel-wide image.
/// Sorted by pixel, one entry per pixel (the masks of its pairs joined).
pub fn facing_corners(pairs: &[(usize, usize)], w: usize) -> Vec<(usize, u8)> {
    let mut facing: Vec<(usize, u8)> = pairs
        .iter()
        .flat_map(|&(a, b)| if b == a + w { [(a, 0b1100), (b, 0b0011)] } else { [(a, 0b1010), (b, 0b0101)] })
        .collect();
    facing.sort_unstable_by_key(|f| f.0);
    facing.dedup_by(|next, kept| {
        let same = next.0 == kept.0;
        if same {
            kept.1 |= next.1;
        }
        same
    });
    facing
}

/// What a corners-first re-shade of one pixel tests: its base value, the
/// light's reference level (relative code 255) and the corners to probe
/// ([`facing_corners`]).
#[derive(Clone, Copy, Debug)]
struct CornerProbe {
    base: Vec3,
    level: f32,
    mask: u8,
    reconstruct: bool,
}

/// A one-bin pixel reconstructed on its 3×3 sample grid from the base and
/// its probed corners ([`Reshading::reconstruct`]): the probed corners as
/// shaded (`corners`, their sum, each sample weighted 1/9), the centre and
/// the `4 - probed` corners not probed at the base's value, and each of the
/// 4 edge midpoints the mean of its two corners. Each corner then weighs
/// 2/9 and the centre 1/9: (1 + 2 (4 − probed))/9 · base + 2 · corners.
/// The base's weak branches (`weak`, [`RESHADE_MIN_BRANCH`]) are part of
/// `base` and stand in for the samples', so they are added once, whole.
///
/// Why the far corners take the base: a pixel probes the corners facing
/// the partners of its over-threshold pairs ([`facing_corners`]), and the
/// jump between two pixel centres lies between them, so the edge crosses
/// the probed half of the pixel; the half away from it shows what the
/// centre shows. Measured against 81 samples on the bundled stage
/// (docs/rendering.md, "Third session of 2026-12-02"): 6.90e-6 against
/// 6.02e-6 with all 9 samples (threshold 100); a pixel that would have
/// taken all 9 shades 5 to 7 fewer samples.
fn reconstructed(base: Vec3, weak: Vec3, corners: Vec3, probed: usize) -> Vec3 {
    let held = (1 + 2 * (4 - probed.min(4))) as f32 / SAMPLES_PER_PIXEL as f32;
    held * (base - weak) + 2.0 * corners + weak
}

/// The renderer's gradient threshold (relative 0-255 codes, the light's
/// 99th-percentile pixel = 255): the CLI's `--aa-threshold` default, the
/// daemon's and the still renderer's. Chosen from the bench's error-versus-
/// cost curve (`footlight bench --accuracy-only --accuracy-part aa`, issue
/// 13): with pair marks, highlight pixels and one-bin pixels reconstructed
/// from their probed corners, 120 re-shades ~0.25 % of the bundled stage's
/// pixels at a display MSE of 7.4e-6 against 81 samples (round 4: 1.97 %
/// at 8.6e-6 with threshold 20 and 3×3 marks; the triangle-ID rule before
/// issue 13, 8.48e-6), for ~114 % of the 1-sample pass's instructions
/// (100: 6.9e-6, ~115.4 %). That instruction-ratio target was retired
/// (issue 34: the bench reports error against time instead); the value
/// stays, so pictures do not change. On this scale 120 is a jump from 255 down to
/// ~20 % of the light's level, or from 0 up to it; the paper's 15-25 are
/// steps of the displayed picture.
pub const AA_THRESHOLD: f32 = 120.0;

/// Lowest Phong exponent for which [`View::glint_pixels`] looks for the
/// light's highlight inside a pixel: a lobe of exponent 100 is ~7°
/// wide at half height, spread over many pixels unless the surface curves
/// sharply; the bundled stage's chrome, mirror, glass and polished floor
/// use 10,000 (~0.7°), whose highlight on a thin tube is smaller than a pixel.
pub const GLINT_EXPONENT: f32 = 100.0;

/// Share of a light's lit pixels at or below its reference level (the level
/// shown as 255 for the anti-aliasing decision): the 99th percentile, so a
/// few hot pixels next to the lamp do not darken the rest.
pub const AA_REFERENCE_PERCENTILE: f32 = 0.99;

impl View {
    /// Re-shades the marked pixels of `dense` with the 9 samples (their
    /// whole paths through mirrors and glass, from the 9-sample cache or
    /// freshly expanded), corners first where `how` says so; returns how
    /// many pixels were marked. Re-shading only the directly seen points
    /// was measured (issue 13) and doubled the error on the bundled stage,
    /// whose shadow edges show in the glossy floor and glass.
    pub fn reshade(&self, scene: &Scene, light: &Light, dense: &mut [Vec3], how: Reshading) -> usize {
        // Over the list of marked pixels, not over rows: they gather in the
        // few rows a light's edges cross, and splitting rows between the
        // workers left one of two idle for most of the pass (1,192 pixels
        // of the bundled stage: 6.7 → 4.4 ms).
        let flagged: Vec<usize> = how.flags.iter().enumerate().filter(|(_, f)| **f).map(|(i, _)| i).collect();
        let mut whole = how.whole.to_vec();
        whole.sort_unstable();
        let base: &[Vec3] = dense;
        let values: Vec<Vec3> = flagged
            .par_iter()
            .with_min_len(8)
            .map_init(Vec::new, |scratch, &i| {
                // One occluder hint per pixel: its samples' shadow rays are
                // often blocked by one triangle (the same values; a hint per
                // pixel keeps the order of the tests fixed).
                let hint = &mut OccluderHint::default();
                if let Some(edge) = how.edge.filter(|_| how.rim.binary_search(&i).is_ok()) {
                    return self.rim_cover(scene, light, &edge, i, scratch, hint);
                }
                match how.corners_first {
                    Some(level) if whole.binary_search(&i).is_err() && how.rim_nine.binary_search(&i).is_err() => {
                        let mask =
                            how.facing.binary_search_by_key(&i, |f| f.0).map_or(ALL_CORNERS, |k| how.facing[k].1);
                        let probe = CornerProbe { base: base[i], level, mask, reconstruct: how.reconstruct };
                        self.corners_first(scene, light, i, probe, scratch, hint)
                    }
                    _ => {
                        let weak = self.weak_branches(scene, light, i, hint);
                        shade_hinted(scene, light, self.nine_paths(scene, i, scratch).2, hint) + weak
                    }
                }
            })
            .collect();
        for (&i, value) in flagged.iter().zip(values) {
            dense[i] = value;
        }
        flagged.len()
    }

    /// The pixels adaptive anti-aliasing re-shades for `light`, whose base
    /// buffer is `dense` ([`View::aa_decision`]'s marks).
    pub fn aa_flags(&self, scene: &Scene, light: &Light, dense: &[Vec3], aa: AaParams) -> Vec<bool> {
        self.aa_decision(scene, light, dense, aa).flags
    }

    /// What [`View::render_direct`] re-shades for `light`, whose base buffer
    /// is `dense`: the pixels [`AaParams::marking`] marks for every pair of
    /// [`View::gradient_pairs`] and, with [`AaParams::glints`], the pixels
    /// of [`View::glint_pixels`] (which take all 9 samples at once).
    /// Scale-free: neither exposure nor dimmer enters.
    pub fn aa_decision(&self, scene: &Scene, light: &Light, dense: &[Vec3], aa: AaParams) -> AaDecision {
        let w = self.width() as usize;
        self.aa_decision_in(scene, light, dense, &row_spans(&dense[..w * self.height() as usize], w), aa)
    }

    /// [`View::aa_decision`] with the base buffer's [`RowSpans`] given.
    pub(super) fn aa_decision_in(
        &self,
        scene: &Scene,
        light: &Light,
        dense: &[Vec3],
        spans: &[Option<(usize, usize)>],
        aa: AaParams,
    ) -> AaDecision {
        let (w, h) = (self.width() as usize, self.height() as usize);
        let Some(reference) = reference_in_spans(dense, w, spans) else {
            return AaDecision {
                flags: vec![false; w * h],
                highlights: Vec::new(),
                level: None,
                facing: Vec::new(),
                reconstruct: aa.reconstruct,
                rim: BeamRim::default(),
            };
        };
        let pairs = self.pairs_over(scene, dense, reference, aa.threshold, spans);
        let mut flags = mark_pairs(&pairs, w, h, aa.marking);
        let highlights =
            if aa.glints { self.glint_pixels(scene, light, dense, reference, aa.threshold) } else { Vec::new() };
        mark_highlights_into(&mut flags, &highlights, w, h, aa.marking);
        let facing = if aa.corners_first { facing_corners(&pairs, w) } else { Vec::new() };
        let rim = if aa.rim { self.beam_rim(scene, light, spans) } else { BeamRim::default() };
        mark_rim_into(&mut flags, &rim);
        AaDecision {
            flags,
            highlights,
            level: aa.corners_first.then_some(reference),
            facing,
            reconstruct: aa.reconstruct,
            rim,
        }
    }

    /// A marked pixel re-shaded corners first ([`Reshading::corners_first`]):
    /// its base value `probe.base` when each corner sample in `probe.mask`
    /// (the corners facing its pairs' partners, [`facing_corners`]) lies
    /// within [`CORNER_AGREEMENT`] codes of it (on the scale where
    /// `probe.level` is 255), else all 9 samples. The paths come from the
    /// 9-sample cache when another light or rebuild expanded them; a pixel
    /// that stops at its corners is not cached. `hint` carries the pixel's
    /// shadow rays' last occluder from sample to sample.
    fn corners_first(
        &self,
        scene: &Scene,
        light: &Light,
        index: usize,
        probe: CornerProbe,
        scratch: &mut Vec<ShadingVertex>,
        hint: &mut OccluderHint,
    ) -> Vec3 {
        let CornerProbe { base, level, mask, reconstruct } = probe;
        let scale = 1.0 / level;
        let own = srgb8(base * scale);
        // The base's weak branches, standing in for the samples' (zero
        // where the samples are followed to the end).
        let weak = self.weak_branches(scene, light, index, hint);
        let agrees = |corner: Vec3| {
            // Each sample carries weight 1/9: its own value is 9× its sum.
            // A NaN or infinite corner never agrees: all 9 samples are
            // shaded and the pixel shows it, as without corners first.
            let c = srgb8((corner * SAMPLES_PER_PIXEL as f32 + weak) * scale);
            corner.is_finite() && (0..3).all(|k| (f32::from(c[k]) - f32::from(own[k])).abs() <= CORNER_AGREEMENT)
        };
        // The probed corners first (bit j: CORNERS_FIRST[j]), then the
        // other corners and the rest.
        let mut corners = [0, 1, 2, 3];
        corners.sort_by_key(|j| mask & (1 << j) == 0);
        let mut order = CORNERS_FIRST;
        for (slot, j) in order.iter_mut().zip(corners) {
            *slot = CORNERS_FIRST[j];
        }
        let probed = mask.count_ones() as usize;
        // A one-bin pixel whose probed corners disagree is reconstructed
        // from them (the same value from the cache as from a fresh
        // expansion: the same sum of the same paths).
        let reconstruct = reconstruct && self.prunes(index);
        // The probed paths' sum and whether each agrees with the base: the
        // same sums in the same order from the cache as from a fresh
        // expansion, so a rebuild from the cache is the same buffer bit
        // for bit.
        let mut probe = |paths: &mut dyn Iterator<Item = &[ShadingVertex]>| {
            paths.fold((Vec3::ZERO, probed > 0), |(sum, agree), path| {
                let value = shade_hinted(scene, light, path, hint);
                (sum + value, agree && agrees(value))
            })
        };
        if let Some(paths) = self.nine_cache[index].get() {
            let ranges = paths.ranges();
            let path = |s: usize| &paths.vertices[ranges[s].clone()];
            let (sum, agree) = probe(&mut order[..probed].iter().map(|&s| path(s)));
            if agree {
                return base;
            }
            if reconstruct {
                return reconstructed(base, weak, sum, probed);
            }
            let rest = order[probed..].iter().flat_map(|&s| path(s));
            return sum + rest.map(|v| v.weight * direct_hinted(scene, light, v, hint)).sum::<Vec3>() + weak;
        }
        scratch.clear();
        let mut counts = [0u32; SAMPLES_PER_PIXEL];
        self.expand_samples(scene, index, &order[..probed], &mut counts[..probed], scratch);
        let at: usize = counts[..probed].iter().map(|&n| n as usize).sum();
        let mut paths = counts[..probed].iter().scan(0, |start, &n| {
            let path = &scratch[*start..*start + n as usize];
            *start += n as usize;
            Some(path)
        });
        let (sum, agree) = probe(&mut paths);
        if agree {
            return base;
        }
        if reconstruct {
            return reconstructed(base, weak, sum, probed);
        }
        self.expand_samples(scene, index, &order[probed..], &mut counts[probed..], scratch);
        let value = sum + shade_hinted(scene, light, &scratch[at..], hint) + weak;
        self.cache_nine(index, order, counts, scratch);
        value
    }

    /// A rim pixel of one surface shaded by cell coverage ([`super::rim`]):
    /// its 9 sample paths (cache or fresh), the first vertex of each taken
    /// with the pattern just inside the cone ([`BeamEdge::inside_value`])
    /// and weighted by the share of the sample's cell inside the cone
    /// ([`cell_coverage`], the cone's cosine to the axis fitted across the
    /// pixel by [`grid_gradient`]); the deeper vertices as shaded. A cell
    /// wholly inside is its sample's plain value, one wholly outside adds
    /// nothing at its first vertex.
    fn rim_cover(
        &self,
        scene: &Scene,
        light: &Light,
        edge: &BeamEdge,
        index: usize,
        scratch: &mut Vec<ShadingVertex>,
        hint: &mut OccluderHint,
    ) -> Vec3 {
        let (c, _) = self.sample_cosines(scene, edge, index);
        let (gx, gy) = grid_gradient(&c);
        let weak = self.weak_branches(scene, light, index, hint);
        let (order, counts, vertices) = self.nine_paths(scene, index, scratch);
        let mut at = 0;
        let mut sum = Vec3::ZERO;
        for (&s, &n) in order.iter().zip(&counts) {
            let path = &vertices[at..at + n as usize];
            at += n as usize;
            let share = cell_coverage(c[s], edge.cos_cut, gx, gy);
            for v in path {
                sum += if v.depth > 0 || (share >= 1.0 && c[s] >= edge.cos_cut) {
                    v.weight * direct_hinted(scene, light, v, hint)
                } else if share > 0.0 {
                    let toward = (v.position - light.position).normalize_or_zero();
                    let f = edge.inside_value(light, toward);
                    v.weight * direct_with_pattern(scene, light, v, f, hint) * share
                } else {
                    Vec3::ZERO
                };
            }
        }
        sum + weak
    }

    /// The light-free part of [`View::aa_flags`]: the pixels
    /// [`AaParams::marking`] marks for every pair of [`View::gradient_pairs`]
    /// (no highlight pixels). Scale-free: `dense` times any positive factor
    /// gives the same set.
    pub fn gradient_flags(&self, scene: &Scene, dense: &[Vec3], aa: AaParams) -> Vec<bool> {
        let (w, h) = (self.width() as usize, self.height() as usize);
        mark_pairs(&self.gradient_pairs(scene, dense, aa), w, h, aa.marking)
    }

    /// The neighbour pairs (pixel, right or lower neighbour) of `dense`
    /// whose relative values (the light's 99th-percentile pixel = 255,
    /// through the sRGB curve) differ by more than the threshold in any
    /// channel and that lie on the same surface: the jumps
    /// [`View::gradient_flags`] re-shades around, row by row. The sRGB codes
    /// come from one table look-up per channel (no `powf`), the threshold is
    /// tested on the codes first and the same-surface test (two surface
    /// look-ups) only on the few pairs over it; nothing is allocated per
    /// pixel.
    pub fn gradient_pairs(&self, scene: &Scene, dense: &[Vec3], aa: AaParams) -> Vec<(usize, usize)> {
        let (w, h) = (self.width() as usize, self.height() as usize);
        let spans = row_spans(&dense[..w * h], w);
        let Some(reference) = reference_in_spans(dense, w, &spans) else { return Vec::new() };
        self.pairs_over(scene, dense, reference, aa.threshold, &spans)
    }

    /// [`View::gradient_pairs`] with the light's reference level given. A
    /// pair is tested on its codes only when its largest linear difference
    /// could make a code step over the threshold ([`min_jump`]): on the
    /// bundled stage at threshold 100 that leaves few pairs, and no code
    /// buffer is built. Only the pairs touching a row's lit span in `spans`
    /// (one entry per image row, [`RowSpans`]: every non-zero pixel lies
    /// inside; a [`LitWindow::spans`] will do) are tested: outside them both
    /// values are 0, so no pair there is over the threshold.
    ///
    /// Over a binned base the two pixels must lie on one surface (the bins
    /// anti-alias geometry edges already); over a 1-sample base
    /// ([`SampleSet::Centre`], the bench's "no bins" rows) every pair is
    /// compared, geometry edges included.
    pub(crate) fn pairs_over(
        &self,
        scene: &Scene,
        dense: &[Vec3],
        reference: f32,
        threshold: f32,
        spans: &[Option<(usize, usize)>],
    ) -> Vec<(usize, usize)> {
        let (w, h) = (self.width() as usize, self.height() as usize);
        let scale = 1.0 / reference;
        let least = min_jump(threshold) * reference;
        // Centre sample's surface per pixel: material and shading normal,
        // looked up only for pairs over the threshold.
        let surface = |i: usize| centre_surface(scene, &self.gbuffer.samples[i][CENTRE_SAMPLE]);
        let same = |a: usize, b: usize| match (surface(a), surface(b)) {
            (Some((ma, na)), Some((mb, nb))) => ma == mb && na.dot(nb) >= SAME_SURFACE_COS,
            _ => false,
        };
        let across_surfaces = self.shading.set == SampleSet::Centre;
        let over = |a: usize, b: usize| {
            (dense[a] - dense[b]).abs().max_element() >= least
                && codes_differ(srgb8(dense[a] * scale), srgb8(dense[b] * scale), threshold)
                && (across_surfaces || same(a, b))
        };
        neighbour_pairs(w, h, spans, over)
    }

    /// Pixels that may hold the light's highlight on a sharp specular
    /// surface (Phong exponent ≥ [`GLINT_EXPONENT`]) brighter than the
    /// pixel's own relative code by more than `threshold` (the light's
    /// `reference` level = 255): a highlight smaller than a pixel, which the
    /// one shade per bin misses and no neighbour jump shows (on the bundled
    /// stage two such pixels on a chrome tube, black in the base and white
    /// in the 9-sample and 81-sample pictures, held most of the error left
    /// after the 3×3 re-shading of issue 13's fourth round).
    ///
    /// Only pixels that see such a surface directly are tested: at each of
    /// their 9 G-buffer samples on it the unshadowed specular part of the
    /// direct light, ρ_s (n + 2)/2π cos^n α · f_ε cos θ / d² (eq. 1's
    /// specular term without the visibility test), is summed with weight
    /// 1/9: what the 9-sample re-shading would add at most. No shadow ray
    /// and no secondary ray. Scale-free: the value and the reference level
    /// both come from the light.
    ///
    /// `dense` is the light's base buffer and `reference` its level
    /// ([`reference_level`]); only the candidate pixels' values are read, so
    /// a frame-sized buffer holding the light's values only where it lights
    /// anything will do (as in `cells::whitted_together`).
    ///
    /// A pixel whose highlight bound (found with the G-buffer) shows the
    /// light outside every sample's lobe is skipped without a look-up: the
    /// same pixels, at a fraction of the cost (a unit test compares the
    /// two).
    pub fn glint_pixels(
        &self,
        scene: &Scene,
        light: &Light,
        dense: &[Vec3],
        reference: f32,
        threshold: f32,
    ) -> Vec<usize> {
        self.glint_pixels_among(scene, light, dense, reference, threshold, true)
    }

    /// [`View::glint_pixels`], skipping the pixels whose bound misses the
    /// light when `bounded`, or testing every candidate.
    fn glint_pixels_among(
        &self,
        scene: &Scene,
        light: &Light,
        dense: &[Vec3],
        reference: f32,
        threshold: f32,
        bounded: bool,
    ) -> Vec<usize> {
        let scale = 1.0 / reference;
        let shows = |i: usize, sum: Vec3| {
            let (c, own) = (srgb8(sum * scale), srgb8(dense[i] * scale));
            (0..3).any(|k| f32::from(c[k]) - f32::from(own[k]) > threshold)
        };
        // The bounds are light-free and come with the G-buffer
        // ([`GBuffer::highlight_bounds`]): only the pixels whose bound does
        // not miss the light evaluate its highlight (the evaluation, with
        // the light's beam pattern at each sample, costs ~5 ms over every
        // candidate of the bundled stage; the bounds' test ~0.4 ms).
        self.gbuffer
            .highlight_bounds()
            .par_iter()
            .filter(|(_, b)| !(bounded && b.misses(light.position)))
            .map(|&(i, _)| i as usize)
            .filter(|&i| shows(i, self.pixel_highlight(scene, light, i)))
            .collect()
    }

    /// Pixel `i`'s highlight for `light`: the unshadowed specular part of
    /// the direct light summed over its 9 samples on sharp surfaces, weight 1/9.
    fn pixel_highlight(&self, scene: &Scene, light: &Light, i: usize) -> Vec3 {
        let eye = self.gbuffer.camera.position;
        let weight = 1.0 / SAMPLES_PER_PIXEL as f32;
        let mut sum = Vec3::ZERO;
        for (sp, m) in sharp_samples(scene, &self.gbuffer.samples[i]) {
            let Some(dir) = (sp.position - eye).try_normalize() else { continue };
            let f = sp.facing(dir);
            let to = light.position - sp.position;
            let d2 = to.length_squared();
            let wi = to.normalize_or_zero();
            let cos = wi.dot(f.shading);
            if !(d2 > 1e-12 && d2.is_finite() && cos > 0.0 && wi.dot(f.geometric) > 0.0) {
                continue;
            }
            let cos_alpha = (2.0 * cos * f.shading - wi).dot(-dir).max(0.0);
            // cos^n α < e^-40 (n (1 - cos α) > 40): nothing to see.
            if m.exponent * (1.0 - cos_alpha) > 40.0 {
                continue;
            }
            let e = light.pattern_toward(-wi);
            if e <= 0.0 {
                continue;
            }
            let lobe = (m.exponent + 2.0) * 0.5 * std::f32::consts::FRAC_1_PI * cos_alpha.powf(m.exponent);
            sum += m.specular * (lobe * e * cos / d2 * weight);
        }
        sum
    }
}

impl View {
    /// Whether pixel `index`'s re-shaded samples stop at
    /// [`RESHADE_MIN_BRANCH`]: its base is one bin holding all 9 samples
    /// (one path of weight 1, whose weak branches stand in for theirs).
    fn prunes(&self, index: usize) -> bool {
        self.shading.set == SampleSet::Binned && matches!(self.gbuffer.bins(index), [b] if b.weight >= 1.0)
    }

    /// The recursion limits of pixel `index`'s re-shaded samples (weight
    /// 1/9 each): [`RESHADE_MIN_BRANCH`] relative where [`View::prunes`].
    pub(super) fn sample_limits(&self, index: usize) -> RecursionLimits {
        if self.prunes(index) {
            let min_weight = (RESHADE_MIN_BRANCH / SAMPLES_PER_PIXEL as f32).max(self.limits.min_weight);
            RecursionLimits { min_weight, ..self.limits }
        } else {
            self.limits
        }
    }

    /// The direct light of pixel `index`'s base vertices below
    /// [`RESHADE_MIN_BRANCH`] where [`View::prunes`] (they stand in for the
    /// re-shaded samples' weak branches), else zero.
    fn weak_branches(&self, scene: &Scene, light: &Light, index: usize, hint: &mut OccluderHint) -> Vec3 {
        if !self.prunes(index) {
            return Vec3::ZERO;
        }
        let weak = self.shading.pixel(index).iter().filter(|v| v.weight.max_element() < RESHADE_MIN_BRANCH);
        weak.map(|v| v.weight * direct_hinted(scene, light, v, hint)).sum()
    }
}

/// Material and shading normal at a primary sample (`None` for a miss).
fn centre_surface(scene: &Scene, s: &PrimarySample) -> Option<(u32, Vec3)> {
    (s.triangle != NO_HIT).then(|| {
        let sp = scene.surface(&Hit { triangle: s.triangle, t: 0.0, u: s.u, v: s.v });
        (sp.material, sp.shading_normal)
    })
}

/// The light's reference level: the 99th percentile of the largest channel
/// over its lit pixels; `None` when nothing is lit.
///
/// The same value as selecting the k-th smallest of all lit values (the
/// order statistic, [`slice::select_nth_unstable_by`]), found without
/// copying the buffer: a parallel histogram of the values' top bits (the
/// bit pattern of a positive float orders like the float), then the
/// selection among the values of the one bucket that holds the k-th.
pub fn reference_level(dense: &[Vec3]) -> Option<f32> {
    level_over(&dense.chunks(4096).collect::<Vec<_>>())
}

/// [`reference_level`] over the lit pixels of `parts` (the rows' lit spans,
/// [`row_spans`], or chunks of a whole buffer): outside them every value is 0.
fn level_over(parts: &[&[Vec3]]) -> Option<f32> {
    const SHIFT: u32 = 20; // 8 exponent bits and 3 mantissa bits: 2048 buckets
    const BUCKETS: usize = 1 << (31 - SHIFT);
    let lit = |v: &Vec3| Some(v.max_element()).filter(|&m| m > 0.0 && m.is_finite());
    let bucket = |m: f32| (m.to_bits() >> SHIFT) as usize;
    let counts = parts
        .par_iter()
        .fold(
            || vec![0u32; BUCKETS],
            |mut c, part| {
                for m in part.iter().filter_map(lit) {
                    c[bucket(m)] += 1;
                }
                c
            },
        )
        .reduce(
            || vec![0u32; BUCKETS],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                a
            },
        );
    let total: usize = counts.iter().map(|&c| c as usize).sum();
    if total == 0 {
        return None;
    }
    let mut k = ((total - 1) as f32 * AA_REFERENCE_PERCENTILE) as usize;
    let mut target = 0;
    for (b, &c) in counts.iter().enumerate() {
        if k < c as usize {
            target = b;
            break;
        }
        k -= c as usize;
    }
    let mut inside: Vec<f32> =
        parts.par_iter().flat_map_iter(|part| part.iter().filter_map(lit).filter(|&m| bucket(m) == target)).collect();
    let (_, level, _) = inside.select_nth_unstable_by(k, f32::total_cmp);
    Some(*level)
}

/// Marks pixels whose value differs from a right or lower neighbour with
/// `comparable(a, b)` by more than the threshold in any channel, the way
/// [`AaParams::new`] marks them ([`AaMarking::Pair`]: the two pixels of
/// each such pair; what [`View::render_direct`] re-shades without its
/// highlight pixels). Parallel over rows, each pair tested once.
pub fn mark_gradients(
    display: &[Vec3],
    w: usize,
    h: usize,
    threshold: f32,
    comparable: impl Fn(usize, usize) -> bool + Sync,
) -> Vec<bool> {
    mark_gradients_with(display, w, h, threshold, comparable, AaParams::new(threshold).marking)
}

/// As [`mark_gradients`], marking the pixels `marking` marks.
pub fn mark_gradients_with(
    display: &[Vec3],
    w: usize,
    h: usize,
    threshold: f32,
    comparable: impl Fn(usize, usize) -> bool + Sync,
    marking: AaMarking,
) -> Vec<bool> {
    // The threshold first: `comparable` may be costly and is rarely needed.
    let over = |a: usize, b: usize| (display[b] - display[a]).abs().max_element() > threshold && comparable(a, b);
    mark_pairs(&neighbour_pairs(w, h, &LitWindow::full(w, h).spans(h), over), w, h, marking)
}

/// The pixels `marking` marks for `pairs` (each a pixel and its right or
/// lower neighbour) on a `w`×`h` image.
pub fn mark_pairs(pairs: &[(usize, usize)], w: usize, h: usize, marking: AaMarking) -> Vec<bool> {
    let mut flags = vec![false; w * h];
    mark_pairs_into(&mut flags, pairs, w, h, marking);
    flags
}

/// As [`mark_pairs`], setting the marks in `flags` (a frame-sized buffer;
/// marks already set stay).
pub fn mark_pairs_into(flags: &mut [bool], pairs: &[(usize, usize)], w: usize, h: usize, marking: AaMarking) {
    for &(a, b) in pairs {
        match marking {
            AaMarking::Pair => {
                flags[a] = true;
                flags[b] = true;
            }
            AaMarking::Across => {
                flags[a] = true;
                flags[b] = true;
                // b = a + 1 (right) or a + w (lower): one more each way.
                let step = b - a;
                let (ax, bx) = (a % w, b % w);
                if a >= step && (step == w || ax > 0) {
                    flags[a - step] = true;
                }
                if b + step < w * h && (step == w || bx + 1 < w) {
                    flags[b + step] = true;
                }
            }
            AaMarking::Dilated => {
                dilate(flags, w, h, a);
                dilate(flags, w, h, b);
            }
        }
    }
}

/// Marks the highlight pixels ([`View::glint_pixels`]) in `flags` for
/// `marking`: the pixel itself, or with [`AaMarking::Dilated`] its 3×3 block.
pub fn mark_highlights_into(flags: &mut [bool], highlights: &[usize], w: usize, h: usize, marking: AaMarking) {
    for &i in highlights {
        match marking {
            AaMarking::Dilated => dilate(flags, w, h, i),
            AaMarking::Pair | AaMarking::Across => flags[i] = true,
        }
    }
}

/// Marks `rim`'s pixels in `flags` ([`View::beam_rim`]).
pub fn mark_rim_into(flags: &mut [bool], rim: &BeamRim) {
    for &i in rim.cover.iter().chain(&rim.nine) {
        flags[i] = true;
    }
}

/// Whether two relative codes differ by more than `threshold` in any channel.
fn codes_differ(x: [u8; 3], y: [u8; 3], threshold: f32) -> bool {
    (0..3).any(|c| f32::from(x[c].abs_diff(y[c])) > threshold)
}

/// The smallest linear difference (in units of the reference level) of two
/// values whose relative codes ([`srgb8`]) can differ by more than
/// `threshold`: the sRGB curve f is concave with f(0) = 0, so f(y) − f(x) ≤
/// f(y − x) (also after clipping at 0 and 1), and the table's rounding adds
/// at most one code and half a table step; a little less is returned, so
/// no pair over the threshold is skipped.
fn min_jump(threshold: f32) -> f32 {
    let code = ((threshold - 1.0) / 255.0).clamp(0.0, 1.0);
    // Inverse of the sRGB encoding.
    let linear = if code <= 0.04045 { code / 12.92 } else { ((code + 0.055) / 1.055).powf(2.4) };
    (0.999 * linear - 1.0 / 65535.0).max(0.0)
}

/// The smallest rectangle of a `w`×`h` image holding every non-zero pixel
/// of `dense` (a light lights a part of the picture: a spot's pool, a
/// wash's half of the stage): columns `x0..x1`, rows `y0..y1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LitWindow {
    /// First column holding a non-zero pixel.
    pub x0: usize,
    /// One past the last such column.
    pub x1: usize,
    /// First row holding a non-zero pixel.
    pub y0: usize,
    /// One past the last such row.
    pub y1: usize,
}

impl LitWindow {
    /// The whole `w`×`h` image.
    pub fn full(w: usize, h: usize) -> Self {
        Self { x0: 0, x1: w, y0: 0, y1: h }
    }

    /// The window as the [`RowSpans`] of an image `h` rows high: columns
    /// `x0..x1` in each of its rows, nothing in the others.
    pub fn spans(self, h: usize) -> RowSpans {
        (0..h).map(|y| (self.y0..self.y1).contains(&y).then_some((self.x0, self.x1))).collect()
    }
}

/// Each row's lit span: the columns from its first to one past its last
/// non-zero pixel (`None` for a dark row). A NaN pixel counts as non-zero,
/// as everywhere else the decision looks.
pub type RowSpans = Vec<Option<(usize, usize)>>;

/// The [`RowSpans`] of a `w`-wide `dense` buffer (one pass; the shading
/// pass of [`View::render_direct`] finds them as it writes the rows).
pub fn row_spans(dense: &[Vec3], w: usize) -> RowSpans {
    dense.par_chunks(w.max(1)).map(row_span).collect()
}

/// One row's lit span ([`RowSpans`]).
fn row_span(row: &[Vec3]) -> Option<(usize, usize)> {
    let first = row.iter().position(|v| *v != Vec3::ZERO)?;
    let last = row.iter().rposition(|v| *v != Vec3::ZERO)?;
    Some((first, last + 1))
}

/// The [`LitWindow`] of `dense` (`None` when every pixel is 0). A NaN
/// pixel counts as non-zero, as everywhere else the decision looks.
pub fn lit_window(dense: &[Vec3], w: usize, h: usize) -> Option<LitWindow> {
    window_of(&row_spans(&dense[..w * h], w), w)
}

/// The [`LitWindow`] holding every row's lit span.
fn window_of(spans: &[Option<(usize, usize)>], w: usize) -> Option<LitWindow> {
    let y0 = spans.iter().position(Option::is_some)?;
    let y1 = spans.iter().rposition(Option::is_some)? + 1;
    let (x0, x1) = spans.iter().flatten().fold((w, 0), |(a, b), &(f, l)| (a.min(f), b.max(l)));
    Some(LitWindow { x0, x1, y0, y1 })
}

/// The light's reference level ([`reference_level`]) and its
/// [`LitWindow`], the level found among the rows' lit spans only (every
/// lit pixel is there: the same value as over the whole image).
pub fn reference_in_window(dense: &[Vec3], w: usize, h: usize) -> Option<(f32, LitWindow)> {
    let spans = row_spans(&dense[..w * h], w);
    Some((reference_in_spans(dense, w, &spans)?, window_of(&spans, w)?))
}

/// The light's reference level ([`reference_level`]) found among the rows'
/// lit spans `spans` ([`RowSpans`]) of the `w`-wide `dense`.
fn reference_in_spans(dense: &[Vec3], w: usize, spans: &[Option<(usize, usize)>]) -> Option<f32> {
    let parts: Vec<&[Vec3]> =
        spans.iter().enumerate().filter_map(|(y, s)| s.map(|(a, b)| &dense[y * w + a..y * w + b])).collect();
    level_over(&parts)
}

/// Every pair (pixel, right neighbour) and (pixel, lower neighbour) of a
/// `w`×`h` image that touches a row's lit span in `spans` (one entry per
/// row, [`RowSpans`]) and for which `over` holds, row by row and within a
/// row from left to right, each pixel's right pair before its lower one
/// (parallel over rows; a row allocates only once it holds a pair). The
/// pairs reaching one pixel out of a span (a lit edge pixel and its dark
/// neighbour) are included. `over` must be false for two dark (zero)
/// pixels: the pairs outside every span are not tested.
fn neighbour_pairs(
    w: usize,
    h: usize,
    spans: &[Option<(usize, usize)>],
    over: impl Fn(usize, usize) -> bool + Sync,
) -> Vec<(usize, usize)> {
    let span = |y: usize| spans.get(y).copied().flatten();
    let (Some(first), Some(last)) = (spans.iter().position(Option::is_some), spans.iter().rposition(Option::is_some))
    else {
        return Vec::new();
    };
    let rows: Vec<Vec<(usize, usize)>> = (first.saturating_sub(1)..(last + 1).min(h))
        .into_par_iter()
        .map(|y| {
            // Columns x of the right pairs (x, x + 1) touching row y's span,
            // and of the lower pairs (x, x + w) touching row y's or row
            // y + 1's (the hull of the two).
            let right = span(y).map(|(a, b)| (a.saturating_sub(1), b.min(w.saturating_sub(1))));
            let lower = match (span(y), span(y + 1).filter(|_| y + 1 < h)) {
                (Some((a, b)), Some((c, d))) => Some((a.min(c), b.max(d))),
                (one, other) if y + 1 < h => one.or(other),
                _ => None,
            };
            let mut pairs = Vec::new();
            for (step, columns) in [(1, right), (w, lower)] {
                let Some((a, b)) = columns else { continue };
                for i in y * w + a..y * w + b {
                    if over(i, i + step) {
                        pairs.push((i, i + step));
                    }
                }
            }
            // Each pixel's right pair before its lower one (a + 1 < a + w).
            pairs.sort_unstable();
            pairs
        })
        .collect();
    rows.concat()
}

/// Sets `flags` on pixel `i` of a `w`×`h` image and its 8 neighbours.
pub fn dilate(flags: &mut [bool], w: usize, h: usize, i: usize) {
    let (x, y) = (i % w, i / w);
    for yy in y.saturating_sub(1)..(y + 2).min(h) {
        for xx in x.saturating_sub(1)..(x + 2).min(w) {
            flags[yy * w + xx] = true;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::view::Sampling;

    #[test]
    fn facing_corners_are_the_sides_towards_each_partner() {
        // A 3-wide image: pixel 0 jumps to its right (1) and lower (3)
        // neighbours, pixel 1 to its lower one (4). Bits: samples 0, 2, 6, 8.
        let (tl, tr, bl, br) = (0b0001u8, 0b0010, 0b0100, 0b1000);
        let facing = facing_corners(&[(0, 1), (0, 3), (1, 4)], 3);
        assert_eq!(facing, vec![(0, tr | br | bl), (1, tl | bl | br), (3, tl | tr), (4, tl | tr)]);
        // One pixel wide: i + 1 is the lower neighbour.
        assert_eq!(facing_corners(&[(0, 1)], 1), vec![(0, bl | br), (1, tl | tr)]);
        assert!(facing_corners(&[], 3).is_empty());
    }

    #[test]
    fn reference_level_is_the_order_statistic() {
        // The histogram selection against a plain sort, on values spread
        // over many octaves with ties, zeros (unlit) and a NaN.
        let mut seed = 7u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            seed as f32 / u32::MAX as f32
        };
        let mut dense: Vec<Vec3> =
            (0..10_000).map(|_| Vec3::new(next(), next(), next()) * 10f32.powf(6.0 * next() - 3.0)).collect();
        dense[5] = Vec3::ZERO;
        dense[6] = Vec3::splat(f32::NAN);
        dense[7..100].iter_mut().for_each(|v| *v = Vec3::splat(0.25));
        let mut lit: Vec<f32> = dense.iter().map(|v| v.max_element()).filter(|&m| m > 0.0 && m.is_finite()).collect();
        lit.sort_by(f32::total_cmp);
        let k = ((lit.len() - 1) as f32 * AA_REFERENCE_PERCENTILE) as usize;
        assert_eq!(reference_level(&dense), Some(lit[k]));
        assert_eq!(reference_level(&[Vec3::ZERO; 4]), None);
    }

    #[test]
    fn no_code_step_over_the_threshold_is_below_min_jump() {
        // Every pair of values on a fine grid whose codes differ by more
        // than the threshold is at least min_jump apart.
        for t in [0.0f32, 5.0, 20.0, 100.0, 150.0, 254.0] {
            let least = min_jump(t);
            let n = 2000;
            for i in 0..=n {
                let x = i as f32 / n as f32;
                for step in [least * 0.999, least * 0.5] {
                    for y in [x + step, x - step] {
                        let (a, b) = (srgb8(Vec3::splat(x)), srgb8(Vec3::splat(y)));
                        assert!(!codes_differ(a, b, t), "threshold {t}: {x} and {y} differ by {:?} {:?}", a, b);
                    }
                }
            }
        }
    }

    #[test]
    fn markings_mark_the_pair_the_row_across_or_the_3x3() {
        // 5×4 image, one horizontal pair (6, 7) and one vertical pair (13, 18).
        let (w, h) = (5, 4);
        let pairs = [(6, 7), (13, 18)];
        let set = |m| {
            let f = mark_pairs(&pairs, w, h, m);
            (0..w * h).filter(|&i| f[i]).collect::<Vec<_>>()
        };
        assert_eq!(set(AaMarking::Pair), vec![6, 7, 13, 18]);
        assert_eq!(set(AaMarking::Across), vec![5, 6, 7, 8, 13, 18]);
        // x 0-3 of rows 0-2 (12) and x 2-4 of rows 1-3 (9), 4 shared.
        let dilated = set(AaMarking::Dilated);
        assert_eq!(dilated.len(), 17);
        assert!(dilated.contains(&0) && dilated.contains(&19) && !dilated.contains(&4));
    }

    #[test]
    fn pairs_inside_the_lit_window_are_the_pairs_of_the_whole_image() {
        // A 37×23 image, dark but for a few patches (one touching the right
        // edge, one a NaN); the window holds every non-zero pixel, and the
        // pairs found in it are those of a scan over the whole image.
        let (w, h) = (37, 23);
        let mut dense = vec![Vec3::ZERO; w * h];
        let mut seed = 11u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            seed as f32 / u32::MAX as f32
        };
        for (x, y) in [(9, 5), (10, 5), (20, 14), (36, 8), (12, 17)] {
            dense[y * w + x] = Vec3::new(next(), next(), next());
        }
        dense[17 * w + 13] = Vec3::splat(f32::NAN);
        let window = lit_window(&dense, w, h).unwrap();
        assert_eq!(window, LitWindow { x0: 9, x1: 37, y0: 5, y1: 18 });
        for (i, v) in dense.iter().enumerate() {
            let (x, y) = (i % w, i / w);
            let inside = (window.x0..window.x1).contains(&x) && (window.y0..window.y1).contains(&y);
            assert!(inside || *v == Vec3::ZERO, "pixel ({x}, {y}) is lit outside the window");
        }
        let over = |a: usize, b: usize| (dense[a] - dense[b]).abs().max_element() > 0.05;
        let all = neighbour_pairs(w, h, &LitWindow::full(w, h).spans(h), over);
        assert!(all.len() >= 12, "the patches make pairs with their dark neighbours: {}", all.len());
        assert_eq!(neighbour_pairs(w, h, &window.spans(h), over), all);
        assert_eq!(neighbour_pairs(w, h, &row_spans(&dense, w), over), all);
        let (level, same_window) = reference_in_window(&dense, w, h).unwrap();
        assert_eq!((Some(level), same_window), (reference_level(&dense), window));
        assert_eq!(lit_window(&[Vec3::ZERO; 6], 3, 2), None);
    }

    #[test]
    fn highlight_bounds_skip_only_pixels_without_a_highlight() {
        // Chrome spheres (exponent 10,000) on a grey floor under omni
        // lights all around: the highlight test with the per-view bounds
        // finds exactly the pixels the test of every candidate finds, and
        // the bounds skip most candidates.
        use crate::fixture::{Beam, SpotBeam};
        use crate::scene::{Camera, Material, SceneBuilder};
        let mut b = SceneBuilder::new();
        let grey = b.add_material(Material::lambert("grey", Vec3::splat(0.5)));
        b.add_quad(
            Vec3::new(-4.0, 0.0, 4.0),
            Vec3::new(4.0, 0.0, 4.0),
            Vec3::new(4.0, 0.0, -4.0),
            Vec3::new(-4.0, 0.0, -4.0),
            grey,
        );
        let chrome = b.add_material(Material {
            specular: Vec3::splat(0.9),
            exponent: 10_000.0,
            ..Material::lambert("chrome", Vec3::ZERO)
        });
        for k in 0..5 {
            b.add_uv_sphere(Vec3::new(-1.6 + 0.8 * k as f32, 0.3, 0.1 * k as f32), 0.25, 16, 32, chrome);
        }
        let scene = b.build();
        let camera = Camera::look_at(Vec3::new(0.0, 1.2, 6.0), Vec3::new(0.0, 0.3, 0.0), 40f32.to_radians());
        let view = View::build(&scene, camera, 160, 100, Sampling::Adaptive, RecursionLimits::default());
        // The G-buffer's candidates are the pixels whose binned camera paths
        // start on a sharp surface (the set the expansion listed before the
        // bounds moved to the G-buffer).
        let sharp: Vec<u32> = (0..view.shading.start.len() - 1)
            .filter(|&i| {
                view.shading.pixel(i).iter().any(|v| v.depth == 0 && is_sharp(&scene.materials[v.material as usize]))
            })
            .map(|i| i as u32)
            .collect();
        assert!(sharp.len() > 100, "the spheres cover pixels: {}", sharp.len());
        let candidates: Vec<u32> = view.gbuffer.highlight_bounds().iter().map(|c| c.0).collect();
        assert_eq!(candidates, sharp);
        let (mut found, mut skipped, mut candidates) = (0, 0, 0);
        for k in 0..16 {
            let angle = std::f32::consts::TAU * k as f32 / 16.0;
            let at = Vec3::new(3.0 * angle.cos(), 1.0 + 0.5 * (k % 4) as f32, 3.0 * angle.sin());
            let light = Light::aimed(at, at + Vec3::NEG_Y, Beam::Spot(SpotBeam::from_beam_field(360.0, 360.0)));
            let (dense, _) = view.render_direct(&scene, &light, None);
            let Some(level) = reference_level(&dense) else { continue };
            let bounded = view.glint_pixels_among(&scene, &light, &dense, level, AA_THRESHOLD, true);
            let every = view.glint_pixels_among(&scene, &light, &dense, level, AA_THRESHOLD, false);
            assert_eq!(bounded, every, "light {k} at {at}");
            found += every.len();
            let bounds = view.gbuffer.highlight_bounds();
            skipped += bounds.iter().filter(|(_, b)| b.misses(light.position)).count();
            candidates += bounds.len();
        }
        assert!(found >= 16, "the lights show highlights: {found}");
        assert!(2 * skipped > candidates, "the bounds skip most candidates: {skipped} of {candidates}");
    }
}
