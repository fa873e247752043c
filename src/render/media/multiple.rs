//! Multiple scattering in haze by volume photons (issue 15, item 5).
//!
//! The single-scattered beam ([`super::single`]) is light that scattered
//! once, on the camera ray. Everything scattered two or more times (the
//! *glow* around and between beams, and the forward-scattered light that
//! stays in the beam) is estimated here, per light at unit intensity, so it
//! stays linear in the light (eq. 5).
//!
//! # Volume photons (Jensen and Christensen 1998)
//! Photons leave the light inside its cut-off cone (uniform in the cap,
//! power f_ε(ω) Ω / N for Ω the cap's solid angle: 1 cd, the light's own
//! pattern), fly through the haze box and collide with free-flight
//! distances drawn from σ_t e^(−σ_t s) *truncated to the segment in the
//! medium* (forced collisions: the power is multiplied by the probability
//! 1 − e^(−σ_t L) of colliding in the segment, so thin haze costs no more
//! photons than thick haze). A segment ends at the box or at the first
//! surface (the scene's BVH); at a collision the power is multiplied by the
//! albedo σ_s / σ_t and the direction drawn from Henyey-Greenstein
//! ([`super::reference::sample_hg`]). Photons are stored at every collision
//! *after the first scattering* (orders ≥ 2: order 1 is the analytic beam),
//! with the power arriving there. Russian roulette ends weak paths.
//!
//! The stored powers sum, in expectation, to σ_t L⁽ⁿ⁾ per unit volume and
//! solid angle (collision density), so the in-scattered source toward −ω is
//!
//!   S(x, ω) = (σ_s / σ_t) Σ_{|x_p − x| < r} p(ω_p · −ω) Φ_p / (4/3 π r³)
//!
//! and the camera ray collects L = ∫ e^(−σ_t τ_cam(t)) S(x(t)) dt, taken by
//! ray marching with steps of about r through the box (the photons sit in a
//! uniform grid of cell r, so one step reads 27 cells). Multiple scattering
//! is smooth, so the screen is traced on a coarse grid (every `scale`-th
//! pixel) and upsampled bilinearly with depth-aware weights.
//!
//! # Left out
//! Light reflected by surfaces into the haze and haze light reaching
//! surfaces (photons end at the first surface); secondary camera segments
//! (mirrors, glass); the blur of the kernel radius r (beam edges of the
//! glow are r wide). Measured against the volume path tracer
//! ([`super::reference::path_traced_ray`]) in `footlight bench
//! --haze-only` ("multiple scattering" rows) and in `tests/haze.rs`.
//!
//! # Density
//! Photons are traced once, at 100 %, and each keeps its scattering order
//! k and the optical depth τ of its path; at density d its power is
//! multiplied by d^k e^((1 − d) τ), the ratio of the path's contribution at
//! the two densities ([`VolumePhotons::at_density`]): unbiased, the same as
//! tracing at d in expectation. The term is rendered at the densities the
//! caller needs and kept next to the beam ([`HazeBuffer::with_multiple`]):
//! `render` at its own density, the live tracer at its knots ½ and 1, so
//! [`super::resolve`] reads it exactly there. The bench reports the
//! re-weighting against photons traced at d, and what the live knots'
//! interpolation leaves.

use super::medium::{Medium, hg};
use super::reference::sample_hg;
use super::single::HazeView;
use crate::fixture::Light;
use crate::render::buffer::{HazeBuffer, LightBuffer, TILE};
use crate::scene::Scene;
use glam::Vec3;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

/// How many volume photons, how wide the kernel, how coarse the screen grid.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MultipleSettings {
    /// Photons emitted per light.
    pub photons: usize,
    /// Kernel radius as a fraction of the haze box's largest side.
    pub radius_frac: f32,
    /// Screen grid: trace every `scale`-th pixel in x and y.
    pub scale: u32,
    /// Scattering events followed per photon at most.
    pub max_order: u32,
    /// RNG seed (photon chunk k uses `seed + k`).
    pub seed: u64,
}

impl Default for MultipleSettings {
    fn default() -> Self {
        Self { photons: 20_000, radius_frac: 0.05, scale: 8, max_order: 64, seed: 0x5EED_0D15 }
    }
}

/// Photons per rayon chunk (each chunk has its own seeded RNG, so the
/// result does not depend on the thread count).
const CHUNK: usize = 1024;

/// Largest grid size per axis.
const MAX_CELLS: usize = 128;

/// The stored volume photons of one light, in a uniform grid.
pub struct VolumePhotons {
    /// Photon positions, sorted by cell.
    pos: Vec<Vec3>,
    /// Propagation directions (unit), arriving at the position.
    dir: Vec<Vec3>,
    /// Powers (per 1 cd of the light).
    power: Vec<f32>,
    /// Scattering order of the collision each photon is stored at (≥ 2).
    order: Vec<u16>,
    /// Optical depth (at the traced medium's density) of the photon's path
    /// from the light to where it is stored.
    tau: Vec<f32>,
    /// Kernel radius r = grid cell size, metres.
    radius: f32,
    /// Grid origin (the box's minimum).
    origin: Vec3,
    /// Cells per axis.
    dims: [usize; 3],
    /// `start[c]..start[c + 1]` are the photons of cell c.
    start: Vec<u32>,
}

impl VolumePhotons {
    /// Photons stored.
    pub fn len(&self) -> usize {
        self.pos.len()
    }

    /// True when no photon was stored.
    pub fn is_empty(&self) -> bool {
        self.pos.is_empty()
    }

    /// The kernel radius in metres.
    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// These photons re-weighted from the density they were traced at to
    /// `d` times it (0-1; clamped, NaN → 0): each photon's path is kept and
    /// its power multiplied by the ratio of the path's contribution at the
    /// two densities, d^k e^((1 − d) τ) for a photon stored at its k-th
    /// collision after optical depth τ (every collision density and every
    /// σ_s scales by d, every transmittance e^(−σ_t s) becomes
    /// e^(−d σ_t s); the albedo does not change). Unbiased at any d, the
    /// same as tracing at d in expectation: ray-march the result through
    /// the medium at d ([`Medium::at_density`]).
    pub fn at_density(&self, d: f32) -> VolumePhotons {
        let d = super::medium::clean_density(d);
        let power = self
            .power
            .iter()
            .zip(&self.order)
            .zip(&self.tau)
            .map(|((&p, &k), &tau)| if d > 0.0 { p * d.powi(i32::from(k)) * ((1.0 - d) * tau).exp() } else { 0.0 })
            .collect();
        VolumePhotons {
            pos: self.pos.clone(),
            dir: self.dir.clone(),
            power,
            order: self.order.clone(),
            tau: self.tau.clone(),
            radius: self.radius,
            origin: self.origin,
            dims: self.dims,
            start: self.start.clone(),
        }
    }

    fn cell_of(&self, p: Vec3) -> [usize; 3] {
        let c = (p - self.origin) / self.radius;
        [0, 1, 2].map(|a| (c[a].max(0.0) as usize).min(self.dims[a] - 1))
    }

    /// Σ p(ω_p · w_out) Φ_p over the photons within r of `x`.
    fn gather(&self, x: Vec3, w_out: Vec3, g: f32) -> f32 {
        let c = self.cell_of(x);
        let r2 = self.radius * self.radius;
        let mut sum = 0.0;
        for z in c[2].saturating_sub(1)..(c[2] + 2).min(self.dims[2]) {
            for y in c[1].saturating_sub(1)..(c[1] + 2).min(self.dims[1]) {
                let row = (z * self.dims[1] + y) * self.dims[0];
                let x0 = row + c[0].saturating_sub(1);
                let x1 = row + (c[0] + 2).min(self.dims[0]);
                for i in self.start[x0] as usize..self.start[x1] as usize {
                    if (self.pos[i] - x).length_squared() < r2 {
                        sum += hg(g, self.dir[i].dot(w_out)) * self.power[i];
                    }
                }
            }
        }
        sum
    }
}

/// One stored photon before gridding.
#[derive(Clone, Copy)]
struct Stored {
    pos: Vec3,
    dir: Vec3,
    power: f32,
    order: u16,
    tau: f32,
}

/// Traces `settings.photons` photons of `light` (1 cd) through `medium`
/// and stores them at every collision after the first scattering (module
/// doc). Surfaces of `scene` end a photon's path. Seeded, deterministic.
pub fn trace_volume_photons(
    scene: &Scene,
    light: &Light,
    medium: &Medium,
    settings: &MultipleSettings,
) -> VolumePhotons {
    let extent = medium.max - medium.min;
    let radius = (settings.radius_frac.max(1e-3) * extent.max_element()).max(extent.max_element() / MAX_CELLS as f32);
    let dims = [0, 1, 2].map(|a| ((extent[a] / radius).ceil() as usize).clamp(1, MAX_CELLS));
    let empty = VolumePhotons {
        pos: Vec::new(),
        dir: Vec::new(),
        power: Vec::new(),
        order: Vec::new(),
        tau: Vec::new(),
        radius,
        origin: medium.min,
        dims,
        start: vec![0; dims[0] * dims[1] * dims[2] + 1],
    };
    let sigma_t = medium.sigma_t();
    if !(sigma_t > 0.0) || !(medium.sigma_s > 0.0) || settings.photons == 0 {
        return empty;
    }
    let albedo = medium.sigma_s / sigma_t;
    let cos_cut = light.beam.cos_cutoff().clamp(-1.0, 1.0);
    let solid = std::f32::consts::TAU * (1.0 - cos_cut);
    let axis = light.axis();
    let (b1, b2) = axis.any_orthonormal_pair();
    let n = settings.photons;
    let per_photon = solid / n as f32;
    let chunks = n.div_ceil(CHUNK);
    let stored: Vec<Stored> = (0..chunks)
        .into_par_iter()
        .flat_map_iter(|k| {
            let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(settings.seed.wrapping_add(k as u64));
            let mut out = Vec::new();
            for _ in k * CHUNK..((k + 1) * CHUNK).min(n) {
                // Uniform in the cap cos θ ≥ cos_cut around the axis.
                let cos = 1.0 - rng.random::<f32>() * (1.0 - cos_cut);
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                let phi = std::f32::consts::TAU * rng.random::<f32>();
                let w = (axis * cos + b1 * (sin * phi.cos()) + b2 * (sin * phi.sin())).normalize_or(axis);
                let f = light.pattern_toward(w);
                if !(f > 0.0) {
                    continue;
                }
                walk(scene, medium, light.position, w, f * per_photon, albedo, settings.max_order, &mut rng, &mut out);
            }
            out
        })
        .collect();
    grid(stored, empty)
}

/// One photon's random walk with forced collisions (module doc).
#[allow(clippy::too_many_arguments)]
fn walk(
    scene: &Scene,
    medium: &Medium,
    mut x: Vec3,
    mut w: Vec3,
    mut power: f32,
    albedo: f32,
    max_order: u32,
    rng: &mut rand_pcg::Pcg64Mcg,
    out: &mut Vec<Stored>,
) {
    let sigma_t = medium.sigma_t();
    let start = power;
    let mut tau = 0.0f32;
    for order in 1..=max_order {
        let t_surface = scene.accel.intersect(x, w, f32::INFINITY).map_or(f32::INFINITY, |h| h.t);
        let Some((t0, t1)) = medium.clip(x, w, t_surface) else { return };
        let p_seg = 1.0 - (-sigma_t * (t1 - t0)).exp();
        if !(p_seg > 0.0) {
            return;
        }
        let u: f32 = rng.random();
        let s = (-(1.0 - u * p_seg).ln() / sigma_t).min(t1 - t0);
        x += w * (t0 + s);
        power *= p_seg;
        tau += sigma_t * s;
        if order >= 2 {
            out.push(Stored { pos: x, dir: w, power, order: order.min(u32::from(u16::MAX)) as u16, tau });
        }
        power *= albedo;
        // Russian roulette below 1 % of the emitted power.
        if power < 0.01 * start {
            if rng.random::<f32>() < 0.5 {
                return;
            }
            power *= 2.0;
        }
        w = sample_hg(medium.g, w, rng.random(), rng.random());
    }
}

/// Sorts `stored` into the grid of `grid` (a counting sort by cell).
fn grid(stored: Vec<Stored>, mut grid: VolumePhotons) -> VolumePhotons {
    let ncells = grid.start.len() - 1;
    let cells: Vec<usize> = stored
        .iter()
        .map(|s| {
            let c = grid.cell_of(s.pos);
            (c[2] * grid.dims[1] + c[1]) * grid.dims[0] + c[0]
        })
        .collect();
    let mut count = vec![0u32; ncells + 1];
    for &c in &cells {
        count[c + 1] += 1;
    }
    for c in 0..ncells {
        count[c + 1] += count[c];
    }
    grid.start = count.clone();
    let mut next = count;
    let mut order = vec![0usize; stored.len()];
    for (i, &c) in cells.iter().enumerate() {
        order[next[c] as usize] = i;
        next[c] += 1;
    }
    grid.pos = order.iter().map(|&i| stored[i].pos).collect();
    grid.dir = order.iter().map(|&i| stored[i].dir).collect();
    grid.power = order.iter().map(|&i| stored[i].power).collect();
    grid.order = order.iter().map(|&i| stored[i].order).collect();
    grid.tau = order.iter().map(|&i| stored[i].tau).collect();
    grid
}

/// Multiply scattered radiance (orders ≥ 2, per 1 cd, at `medium`'s
/// density) reaching `origin` along the ray `origin + t·dir` (unit), t up to
/// `t_surface` (∞: none): a ray march through the photons (module doc).
pub fn multiple_along_ray(medium: &Medium, photons: &VolumePhotons, origin: Vec3, dir: Vec3, t_surface: f32) -> f32 {
    if photons.is_empty() {
        return 0.0;
    }
    let Some((t0, t1)) = medium.clip(origin, dir, t_surface) else { return 0.0 };
    let r = photons.radius;
    let steps = ((t1 - t0) / r).ceil().clamp(1.0, 4096.0) as usize;
    let step = (t1 - t0) / steps as f32;
    let sigma_t = medium.sigma_t();
    let mut sum = 0.0;
    for k in 0..steps {
        let tau = (k as f32 + 0.5) * step;
        let s = photons.gather(origin + dir * (t0 + tau), -dir, medium.g);
        if s > 0.0 {
            sum += s * (-sigma_t * tau).exp();
        }
    }
    let volume = 4.0 / 3.0 * std::f32::consts::PI * r * r * r;
    sum * step * medium.sigma_s / sigma_t / volume
}

/// Renders the multiply scattered radiance of the light whose `photons`
/// these are for the view `hv` (per 1 cd, at `medium`'s density): dense,
/// row-major, traced every `scale`-th pixel and upsampled with depth-aware
/// bilinear weights.
pub fn render_multiple(hv: &HazeView, medium: &Medium, photons: &VolumePhotons, scale: u32) -> Vec<f32> {
    let (w, h) = (hv.width as usize, hv.height as usize);
    if photons.is_empty() || w == 0 || h == 0 {
        return vec![0.0; w * h];
    }
    let s = scale.max(1) as usize;
    let (cw, ch) = (w.div_ceil(s), h.div_ceil(s));
    let rep = |c: usize, n: usize| (c * s + s / 2).min(n - 1);
    let cam = hv.camera.position;
    let trace = |i: usize| multiple_along_ray(medium, photons, cam, hv.dir(i), hv.t_hit(i));
    let coarse: Vec<f32> = (0..cw * ch).into_par_iter().map(|k| trace(rep(k / cw, h) * w + rep(k % cw, w))).collect();
    if s == 1 {
        return coarse;
    }
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let (cx0, fx) = cell(x, s, cw, w);
            let (cy0, fy) = cell(y, s, ch, h);
            let (cx1, cy1) = ((cx0 + 1).min(cw - 1), (cy0 + 1).min(ch - 1));
            let t_here = hv.t_hit(i);
            let mut sum = 0.0;
            let mut wsum = 0.0;
            for (cx, cy, wb) in [
                (cx0, cy0, (1.0 - fx) * (1.0 - fy)),
                (cx1, cy0, fx * (1.0 - fy)),
                (cx0, cy1, (1.0 - fx) * fy),
                (cx1, cy1, fx * fy),
            ] {
                let wt = wb * depth_weight(t_here, hv.t_hit(rep(cy, h) * w + rep(cx, w)));
                sum += wt * coarse[cy * cw + cx];
                wsum += wt;
            }
            if wsum > 1e-3 { sum / wsum } else { trace(i) }
        })
        .collect()
}

/// The coarse cell left of / above full pixel `p` and the bilinear fraction.
fn cell(p: usize, s: usize, n: usize, full: usize) -> (usize, f32) {
    let centre = |c: usize| (c * s + s / 2).min(full - 1) as f32;
    let c0 = (p.saturating_sub(s / 2) / s).min(n - 1);
    let c1 = (c0 + 1).min(n - 1);
    if c1 == c0 {
        return (c0, 0.0);
    }
    (c0, ((p as f32 - centre(c0)) / (centre(c1) - centre(c0)).max(1.0)).clamp(0.0, 1.0))
}

/// Depth weight of a coarse neighbour: 1 at the same depth, ~0 beyond 10 %
/// relative difference; a miss and a hit do not mix.
fn depth_weight(a: f32, b: f32) -> f32 {
    match (a.is_finite(), b.is_finite()) {
        (false, false) => 1.0,
        (true, true) => (-((a - b).abs() / a.min(b).max(1e-3) / 0.05).powi(2)).exp(),
        _ => 0.0,
    }
}

/// Tiles whose largest value is below this fraction of the image's peak
/// are dropped from the haze buffer (the glow fades smoothly; the bench's
/// captured fraction includes what this drops).
pub const TILE_CUTOFF: f32 = 1e-3;

/// The multiply scattered radiance `multiple` (dense, row-major, from
/// [`render_multiple`]) as a tile-sparse buffer with the value in x
/// ([`HazeBuffer::with_multiple`]): tiles whose largest value is at least
/// [`TILE_CUTOFF`] of the peak are kept, plus the tiles in `keep` (the
/// beam's, so the glow inside the beam is never cut). Non-finite or
/// negative values are stored as they are: the buffer check reports them.
pub fn multiple_buffer(width: u32, height: u32, multiple: &[f32], keep: &[(usize, usize)]) -> LightBuffer {
    let (w, h) = (width as usize, height as usize);
    if multiple.len() != w * h {
        return LightBuffer::empty(width, height);
    }
    let peak = multiple.iter().fold(0.0f32, |a, &m| if m.is_finite() { a.max(m) } else { a });
    let mut tiles = keep.to_vec();
    for ty in 0..h.div_ceil(TILE) {
        for tx in 0..w.div_ceil(TILE) {
            let lit = (ty * TILE..((ty + 1) * TILE).min(h))
                .any(|y| (tx * TILE..((tx + 1) * TILE).min(w)).any(|x| !(multiple[y * w + x] < TILE_CUTOFF * peak)));
            if peak > 0.0 && lit {
                tiles.push((tx, ty));
            }
        }
    }
    tiles.sort_unstable();
    tiles.dedup();
    LightBuffer::from_tiles(width, height, &tiles, |tx, ty, tile| {
        for r in 0..TILE.min(h - ty * TILE) {
            for c in 0..TILE.min(w - tx * TILE) {
                tile[r * TILE + c] = Vec3::new(multiple[(ty * TILE + r) * w + tx * TILE + c], 0.0, 0.0);
            }
        }
    })
}

/// A light's haze buffer with multiple scattering: the single-scattered
/// beam at `quality` with σ_t on the light paths (the photons carry what
/// the similarity relation approximated, so it is not used in the air),
/// plus the volume-photon term rendered at each of `densities` (0-1 of
/// `medium`'s) from one set of photons traced at 100 % and re-weighted
/// ([`VolumePhotons::at_density`]): `render` asks for its own density, the
/// live tracer for its knots ½ and 1, so [`super::resolve`] finds the term
/// exactly where it resolves. Surface extinction in [`super::resolve`]
/// still follows `medium` (`multiple`: the similarity relation).
pub fn render_beam_with_multiple(
    scene: &Scene,
    hv: &HazeView,
    light: &Light,
    medium: &Medium,
    quality: super::single::HazeQuality,
    settings: &MultipleSettings,
    densities: &[f32],
) -> HazeBuffer {
    let air = Medium { multiple: false, ..*medium };
    let beam = super::single::render_inscatter(scene, hv, light, &air, quality);
    let photons = trace_volume_photons(scene, light, &air, settings);
    let keep = beam.as_light_buffer().occupied();
    let (w, h) = (beam.width(), beam.height());
    densities.iter().fold(beam, |haze, &d| {
        let d = super::medium::clean_density(d);
        if d == 0.0 {
            return haze;
        }
        let term = render_multiple(hv, &air.at_density(d), &photons.at_density(d), settings.scale);
        haze.with_multiple(d, multiple_buffer(w, h, &term, &keep))
    })
}

/// The multiply scattered radiance at density `to` from its value `m` at
/// density `from` (`from` > 0) and the pixel's beam optical depth `kappa`
/// at 100 %: m · (to/from)² · e^((from − to) κ) (order 2 grows as the
/// square of the density, its extinction as the beam's). Only used between
/// the densities a haze buffer holds the term at; exact at `from`.
pub fn anchored(m: f32, kappa: f32, from: f32, to: f32) -> f32 {
    if m > 0.0 && from > 0.0 {
        let r = to / from;
        m * r * r * ((from - to) * kappa).exp()
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::SceneBuilder;

    #[test]
    fn photons_are_seeded_and_the_grid_holds_them_all() {
        let scene = SceneBuilder::new().build();
        let m = Medium::new(0.3, 0.01, 0.8, Vec3::new(-4.0, 0.0, -4.0), Vec3::new(4.0, 6.0, 4.0)).unwrap();
        let light = Light::aimed(
            Vec3::new(0.0, 5.5, 0.0),
            Vec3::new(0.0, 4.5, 0.0),
            crate::fixture::Beam::Spot(crate::fixture::SpotBeam::from_beam_field(20.0, 30.0)),
        );
        let s = MultipleSettings { photons: 3000, ..Default::default() };
        let a = trace_volume_photons(&scene, &light, &m, &s);
        let b = trace_volume_photons(&scene, &light, &m, &s);
        assert!(a.len() > 1000, "{}", a.len());
        assert_eq!(a.pos, b.pos);
        assert_eq!(*a.start.last().unwrap() as usize, a.len());
        // Every photon is in its own cell.
        for c in 0..a.start.len() - 1 {
            for i in a.start[c] as usize..a.start[c + 1] as usize {
                let k = a.cell_of(a.pos[i]);
                assert_eq!((k[2] * a.dims[1] + k[1]) * a.dims[0] + k[0], c);
            }
        }
        // Clear haze stores nothing.
        assert!(trace_volume_photons(&scene, &light, &m.at_density(0.0), &s).is_empty());
    }
}
