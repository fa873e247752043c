//! The rim of a hard-edged beam (issue 34, item 1): where a light's
//! pattern jumps at its cut-off cone ([`BeamEdge`]), the pixels whose
//! footprint the cone's edge crosses ([`View::beam_rim`]) are anti-aliased
//! beyond the 9 samples: the cone's edge is not a geometry edge, so the
//! surface bins do not see it, the gradient pairs miss pixels it crosses
//! only at a corner, and the corner reconstruction ([`super::Reshading`])
//! weighs each probed corner 2/9, a coarser estimate than the 9 samples
//! (measured in `tests/beam_rim.rs`: adaptive 2-3× the error of 9 samples,
//! whatever the threshold).
//!
//! A rim pixel that sees one surface with all 9 samples is shaded from its
//! 9 sample paths, each sample standing for its cell of the 3×3 grid: the
//! direct light at the sample's first vertex is taken with the pattern just
//! inside the cone and weighted by the share of the cell inside the cone
//! ([`cell_coverage`]: exact for the cone's cosine to the axis linear across
//! the pixel, which the 9 samples fit); the vertices behind mirrors and
//! glass keep their 9-sample value. A rim pixel of several surfaces takes
//! all 9 samples. Only rim pixels cost more: a light without a hard edge
//! (every profile with a penumbra) finds none at no cost.

use super::View;
use crate::fixture::Light;
use crate::render::gbuffer::{CENTRE_SAMPLE, NO_HIT, SAMPLES_PER_PIXEL, sample_offset};
use crate::scene::Scene;
use glam::Vec3;
use rayon::prelude::*;

/// Pattern value just inside the cut-off cone (at [`RIM_INSET`] from it,
/// the largest over 8 azimuths) above which the cone's edge is a hard
/// edge ([`BeamEdge::of`]): a profile's penumbra of a degree or more is
/// ~0 there and takes no rim work.
pub const RIM_STEP: f32 = 0.01;

/// Angle (radians) inside the cut-off cone at which a hard edge's pattern
/// is read ([`BeamEdge::of`], [`BeamEdge::inside_value`]).
pub const RIM_INSET: f32 = 1e-4;

/// A light's hard cone edge: its pattern is zero outside the cone of
/// cosine `cos_cut` about its axis and at least [`RIM_STEP`] just inside.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamEdge {
    /// The light's position.
    pub position: Vec3,
    /// The beam axis (unit, world).
    pub axis: Vec3,
    /// Cosine of the cut-off half-angle ([`crate::fixture::Beam::cos_cutoff`]).
    pub cos_cut: f32,
    /// cos and sin of the half-angle less [`RIM_INSET`].
    inset: (f32, f32),
}

impl BeamEdge {
    /// The light's cone edge when its pattern jumps there (`None` for an
    /// omnidirectional light or a soft edge).
    pub fn of(light: &Light) -> Option<Self> {
        let cos_cut = light.beam.cos_cutoff();
        if !(cos_cut > -1.0 + 1e-6 && cos_cut < 1.0) {
            return None;
        }
        let theta = cos_cut.acos() - RIM_INSET;
        if theta.is_nan() || theta <= 0.0 {
            return None;
        }
        let (sin, cos) = theta.sin_cos();
        let step = (0..8)
            .map(|k| {
                let phi = std::f32::consts::TAU * k as f32 / 8.0;
                light.beam.pattern(Vec3::new(sin * phi.cos(), sin * phi.sin(), -cos))
            })
            .fold(0.0f32, f32::max);
        (step > RIM_STEP).then(|| Self { position: light.position, axis: light.axis(), cos_cut, inset: (cos, sin) })
    }

    /// Cosine of the angle between the axis and the direction to `p`
    /// (NaN at the light's position).
    pub fn cos_to(&self, p: Vec3) -> f32 {
        (p - self.position).normalize().dot(self.axis)
    }

    /// The pattern toward world direction `dir` (unit, from the light)
    /// where it lies inside the cone; outside, the pattern just inside the
    /// cone on the same side (the value the edge cuts off).
    pub fn inside_value(&self, light: &Light, dir: Vec3) -> f32 {
        let c = dir.dot(self.axis);
        if c >= self.cos_cut {
            return light.pattern_toward(dir);
        }
        let Some(side) = (dir - self.axis * c).try_normalize() else { return 0.0 };
        light.pattern_toward(self.axis * self.inset.0 + side * self.inset.1)
    }
}

/// The rim pixels of one light ([`View::beam_rim`]), sorted.
#[derive(Clone, Debug, Default)]
pub struct BeamRim {
    /// The light's hard edge (`None`: no rim).
    pub edge: Option<BeamEdge>,
    /// Rim pixels of one surface: shaded by cell coverage.
    pub cover: Vec<usize>,
    /// Rim pixels of several surfaces (or partly background): all 9 samples.
    pub nine: Vec<usize>,
}

impl BeamRim {
    /// The rim pixels inside `window` of a `w`-wide image only.
    pub fn within(mut self, window: super::LitWindow, w: usize) -> Self {
        let inside = |i: &usize| (window.x0..window.x1).contains(&(i % w)) && (window.y0..window.y1).contains(&(i / w));
        self.cover.retain(inside);
        self.nine.retain(inside);
        self
    }
}

/// The share of the unit square where p + q x + r y ≥ 0 (x, y in [0, 1]):
/// exact (the integral of a clamped linear function). A non-finite
/// coefficient counts the square as inside where p ≥ 0.
pub fn half_plane_share(p: f32, q: f32, r: f32) -> f32 {
    if !(p.is_finite() && q.is_finite() && r.is_finite()) {
        return if p >= 0.0 { 1.0 } else { 0.0 };
    }
    // Integrate over the variable with the smaller coefficient.
    let (q, r) = if q.abs() > r.abs() { (r, q) } else { (q, r) };
    if r == 0.0 {
        return if p >= 0.0 { 1.0 } else { 0.0 };
    }
    // For fixed x the share of y is clamp(a + b x, 0, 1).
    let (a, b) = if r > 0.0 { (1.0 + p / r, q / r) } else { (-p / r, -q / r) };
    let antiderivative = |t: f32| {
        if t <= 0.0 {
            0.0
        } else if t <= 1.0 {
            0.5 * t * t
        } else {
            t - 0.5
        }
    };
    if b.abs() < 1e-4 {
        return (a + 0.5 * b).clamp(0.0, 1.0);
    }
    ((antiderivative(a + b) - antiderivative(a)) / b).clamp(0.0, 1.0)
}

/// The share of sample `s`'s cell (the third of the pixel around it) inside
/// the cone, for the cone's cosine to the axis `c` at the sample and its
/// gradient (`gx`, `gy`) per pixel: [`half_plane_share`] of c − cos_cut
/// across the cell.
pub fn cell_coverage(c: f32, cos_cut: f32, gx: f32, gy: f32) -> f32 {
    let third = 1.0 / 3.0;
    let (q, r) = (gx * third, gy * third);
    half_plane_share(c - cos_cut - 0.5 * (q + r), q, r)
}

/// Least-squares gradient (per pixel, x and y) of values at the 3×3 grid
/// of [`sample_offset`].
pub fn grid_gradient(c: &[f32; SAMPLES_PER_PIXEL]) -> (f32, f32) {
    let (mut gx, mut gy) = (0.0, 0.0);
    for (s, v) in c.iter().enumerate() {
        let (ox, oy) = sample_offset(s);
        gx += v * (ox - 0.5);
        gy += v * (oy - 0.5);
    }
    // Σ (o − 1/2)² over the grid: 6 · (1/3)².
    (gx * 1.5, gy * 1.5)
}

impl View {
    /// The cosines to the beam axis of pixel `i`'s 9 samples (NaN for a
    /// miss) and whether it sees one surface with all 9 (one bin).
    pub(super) fn sample_cosines(&self, scene: &Scene, edge: &BeamEdge, i: usize) -> ([f32; SAMPLES_PER_PIXEL], bool) {
        let samples = &self.gbuffer.samples[i];
        let c = std::array::from_fn(|s| {
            let p = samples[s];
            if p.triangle == NO_HIT { f32::NAN } else { edge.cos_to(scene.point_on(p.triangle, p.u, p.v)) }
        });
        let one = matches!(self.gbuffer.bins(i), [b] if b.weight >= 1.0 && b.triangle != NO_HIT);
        (c, one)
    }

    /// The pixels whose footprint `light`'s hard cone edge crosses
    /// ([`BeamEdge`]), among the pixels within one of a row's lit span in
    /// `spans` (one entry per image row, [`super::RowSpans`]): a pixel
    /// lit in part has a lit neighbour or is lit itself.
    ///
    /// First the pixel centres' cosines to the axis; a pixel whose 3×3
    /// neighbourhood of centres has some inside the cone and some outside
    /// is a candidate (the centres around a pixel enclose its footprint,
    /// so a straight edge crossing it leaves a centre on each side). A
    /// candidate of one surface is a rim pixel when the range of its
    /// samples' cosines, widened to the pixel's corners by their fitted
    /// gradient, holds the cut-off; a candidate of several surfaces takes
    /// all 9 samples.
    pub fn beam_rim(&self, scene: &Scene, light: &Light, spans: &[Option<(usize, usize)>]) -> BeamRim {
        let Some(edge) = BeamEdge::of(light) else { return BeamRim::default() };
        let (w, h) = (self.width() as usize, self.height() as usize);
        let (Some(first), Some(last)) =
            (spans.iter().position(Option::is_some), spans.iter().rposition(Option::is_some))
        else {
            return BeamRim { edge: Some(edge), ..BeamRim::default() };
        };
        let (y0, y1) = (first.saturating_sub(1), (last + 2).min(h));
        // Each row's columns: its own and its neighbours' spans, grown by 1.
        let columns = |y: usize| {
            let rows = y.saturating_sub(1)..(y + 2).min(h);
            let hull = rows.filter_map(|r| spans.get(r).copied().flatten()).fold(None, |acc, (a, b)| match acc {
                None => Some((a, b)),
                Some((c, d)) => Some((a.min(c), b.max(d))),
            });
            hull.map(|(a, b)| (a.saturating_sub(1), (b + 1).min(w)))
        };
        // Centre cosines of rows y0 - 1 .. y1 + 1 (a candidate's neighbours).
        let (c0, c1) = (y0.saturating_sub(1), (y1 + 1).min(h));
        let centre: Vec<Vec<f32>> = (c0..c1)
            .into_par_iter()
            .map(|y| {
                let mut row = vec![f32::NAN; w];
                // The columns of the candidates of rows y - 1 ..= y + 1, grown by 1.
                let near = (y.saturating_sub(1)..(y + 2).min(h)).filter_map(columns);
                let Some((a, b)) = near.reduce(|x, z| (x.0.min(z.0), x.1.max(z.1))) else { return row };
                let (a, b) = (a.saturating_sub(1), (b + 1).min(w));
                for (out, samples) in row[a..b].iter_mut().zip(&self.gbuffer.samples[y * w + a..y * w + b]) {
                    let p = samples[CENTRE_SAMPLE];
                    if p.triangle != NO_HIT {
                        *out = edge.cos_to(scene.point_on(p.triangle, p.u, p.v));
                    }
                }
                row
            })
            .collect();
        let cut = edge.cos_cut;
        let found: Vec<(usize, bool)> = (y0..y1)
            .into_par_iter()
            .flat_map_iter(|y| {
                let mut out = Vec::new();
                let Some((a, b)) = columns(y) else { return out };
                for x in a..b {
                    let (mut inside, mut outside) = (false, false);
                    for yy in y.saturating_sub(1)..(y + 2).min(h) {
                        let row = &centre[yy - c0];
                        for &c in &row[x.saturating_sub(1)..(x + 2).min(w)] {
                            inside |= c >= cut;
                            outside |= c < cut;
                        }
                    }
                    if !(inside && outside) {
                        continue;
                    }
                    let i = y * w + x;
                    let (c, one) = self.sample_cosines(scene, &edge, i);
                    if !one {
                        out.push((i, false));
                        continue;
                    }
                    let (gx, gy) = grid_gradient(&c);
                    let reach = (gx.abs() + gy.abs()) / 6.0;
                    let lo = c.iter().copied().fold(f32::INFINITY, f32::min) - reach;
                    let hi = c.iter().copied().fold(f32::NEG_INFINITY, f32::max) + reach;
                    if lo < cut && hi >= cut {
                        out.push((i, true));
                    }
                }
                out
            })
            .collect();
        let pick = |one: bool| found.iter().filter(|f| f.1 == one).map(|f| f.0).collect();
        BeamRim { edge: Some(edge), cover: pick(true), nine: pick(false) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_plane_share_matches_a_fine_grid() {
        let mut seed = 3u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            seed as f32 / u32::MAX as f32 * 2.0 - 1.0
        };
        for _ in 0..200 {
            let (p, q, r) = (next(), 2.0 * next(), 2.0 * next());
            let n = 400;
            let mut inside = 0;
            for j in 0..n {
                for i in 0..n {
                    let (x, y) = ((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                    inside += usize::from(p + q * x + r * y >= 0.0);
                }
            }
            let grid = inside as f32 / (n * n) as f32;
            let exact = half_plane_share(p, q, r);
            assert!((grid - exact).abs() < 5e-3, "p {p} q {q} r {r}: grid {grid} exact {exact}");
        }
        assert_eq!(half_plane_share(0.5, 0.0, 0.0), 1.0);
        assert_eq!(half_plane_share(-0.5, 0.0, 0.0), 0.0);
        assert_eq!(half_plane_share(f32::NAN, 1.0, 0.0), 0.0);
    }

    #[test]
    fn grid_gradient_of_a_plane_is_its_slope() {
        let c = std::array::from_fn(|s| {
            let (x, y) = sample_offset(s);
            0.3 + 0.7 * x - 0.2 * y
        });
        let (gx, gy) = grid_gradient(&c);
        assert!((gx - 0.7).abs() < 1e-5 && (gy + 0.2).abs() < 1e-5, "{gx} {gy}");
    }

    #[test]
    fn only_hard_cones_have_an_edge() {
        use crate::fixture::{Beam, SpotBeam};
        let at = |beam| Light::aimed(Vec3::Y, Vec3::ZERO, Beam::Spot(beam));
        assert!(BeamEdge::of(&at(SpotBeam::from_half_angles(0.2, 0.2))).is_some());
        assert!(BeamEdge::of(&at(SpotBeam::from_beam_field(20.0, 30.0))).is_none());
        assert!(BeamEdge::of(&at(SpotBeam::from_beam_field(360.0, 360.0))).is_none());
        let edge = BeamEdge::of(&at(SpotBeam::from_half_angles(0.2, 0.2))).unwrap();
        let light = at(SpotBeam::from_half_angles(0.2, 0.2));
        // Outside the cone: the value just inside it.
        let out = Vec3::new(0.5f32.sin(), -0.5f32.cos(), 0.0);
        assert_eq!(light.pattern_toward(out), 0.0);
        assert_eq!(edge.inside_value(&light, out), 1.0);
    }
}
