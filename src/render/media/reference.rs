//! Independent references for the haze.
//!
//! * [`render_hazy_eq1`]: all lights in one pass at a given density, the
//!   surface terms through the eq. 1 reference renderer with each light's
//!   extinction folded into its weight, plus each light's in-scattering
//!   integrated at that density (no buffers, no re-weighting): what the
//!   composite of resolved per-light buffers must equal (linearity), and
//!   the exact rebuild the density re-weighting is measured against.
//! * [`path_traced_ray`]: a Monte Carlo volume path tracer for one camera
//!   ray in an unoccluded haze box (all scattering orders, next-event
//!   estimation to the light at every vertex, seeded): the reference the
//!   multiple-scattering approximation is measured against.

use super::medium::{Medium, hg};
use super::single::{HazeView, integrate_ray};
use crate::fixture::Light;
use crate::render::gbuffer::GBuffer;
use crate::render::reference::render_eq1_weighted;
use crate::render::view::SampleSet;
use crate::render::whitted::RecursionLimits;
use crate::scene::Scene;
use glam::Vec3;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

/// Everything the single-pass reference needs besides the scene and view.
#[derive(Clone, Copy, Debug)]
pub struct HazyReference {
    /// The haze at 100 % density.
    pub medium: Medium,
    /// The density to render at (0-1).
    pub density: f32,
    /// Equiangular samples per ray for in-scattering.
    pub samples: u32,
    /// Primary sample set of the surface terms.
    pub set: SampleSet,
    /// Recursion limits of the surface terms.
    pub limits: RecursionLimits,
}

/// All `lights` with weights `k` in haze, in one pass (linear RGB, row-major).
pub fn render_hazy_eq1(
    scene: &Scene,
    gbuffer: &GBuffer,
    hv: &HazeView,
    lights: &[Light],
    k: &[Vec3],
    r: &HazyReference,
) -> Vec<Vec3> {
    let m = r.medium.at_density(r.density);
    let cam = gbuffer.camera.position;
    // Surface terms: each light's weight times its extinction on the centre
    // ray's camera and light paths at this density.
    let mut out = render_eq1_weighted(
        scene,
        gbuffer,
        lights,
        |i, kk| {
            let hit = hv.hit_point(i);
            for ((out, light), k) in kk.iter_mut().zip(lights).zip(k) {
                let tau = hit.map_or(0.0, |p| {
                    m.sigma_t() * m.length_inside(cam, p) + m.sigma_t_light() * m.length_inside(p, light.position)
                });
                *out = *k * (-tau).exp();
            }
        },
        r.set,
        r.limits,
    );
    if m.sigma_s > 0.0 {
        let w = hv.width as usize;
        out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, px) in row.iter_mut().enumerate() {
                let i = y * w + x;
                for (light, k) in lights.iter().zip(k) {
                    let s = integrate_ray(scene, &m, light, cam, hv.dir(i), hv.t_hit(i), r.samples);
                    *px += *k * (m.sigma_s * s.a1());
                }
            }
        });
    }
    out
}

/// Radiance of a unit light scattered toward the camera along one ray.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathTraced {
    /// Single scattering only (order 1).
    pub single: f64,
    /// All orders up to the path-length cap.
    pub all: f64,
    /// Standard error of `all`.
    pub std_error: f64,
}

/// Monte Carlo reference for the ray `origin` + t·`dir` (t up to `t_max`)
/// through `medium` (taken at face value: `multiple` is ignored, every
/// path sees σ_t) with no geometry, lit by `light` at 1 cd. `paths`
/// random walks, `max_order` scattering events at most, seeded by `seed`.
#[allow(clippy::too_many_arguments)]
pub fn path_traced_ray(
    medium: &Medium,
    light: &Light,
    origin: Vec3,
    dir: Vec3,
    t_max: f32,
    paths: usize,
    max_order: u32,
    seed: u64,
) -> PathTraced {
    let Some((tb0, tb1)) = medium.clip(origin, dir, t_max) else { return PathTraced::default() };
    let sigma_t = f64::from(medium.sigma_t());
    if sigma_t <= 0.0 || medium.sigma_s <= 0.0 {
        return PathTraced::default();
    }
    let albedo = f64::from(medium.sigma_s) / sigma_t;
    let seg = f64::from(tb1 - tb0);
    let p_seg = 1.0 - (-sigma_t * seg).exp();
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    let (mut single, mut sum, mut sum2) = (0.0f64, 0.0f64, 0.0f64);
    // Next-event estimate at x for light leaving along `w_out`.
    let nee = |x: Vec3, w_out: Vec3| -> f64 {
        let to_x = x - light.position;
        let r2 = to_x.length_squared();
        if !(r2 > 1e-12) {
            return 0.0;
        }
        let w_in = to_x / r2.sqrt();
        let f = light.pattern_toward(w_in);
        if f <= 0.0 {
            return 0.0;
        }
        let t = (-sigma_t * f64::from(medium.length_inside(x, light.position))).exp();
        f64::from(hg(medium.g, w_in.dot(w_out)) * f) / f64::from(r2) * t
    };
    for _ in 0..paths {
        // First vertex on the camera ray: free flight truncated to the box.
        let u: f64 = rng.random();
        let s = -(1.0 - u * p_seg).ln() / sigma_t;
        let mut x = origin + dir * (tb0 + s as f32);
        let mut w_out = -dir;
        let mut weight = albedo * p_seg;
        let first = weight * nee(x, w_out);
        single += first;
        let mut total = first;
        for _ in 1..max_order {
            // The light arriving at x came along w_in ~ HG about w_out, from
            // x − s·w_in with s ~ σ_t e^(−σ_t s); leaving the box ends the walk.
            let w_in = sample_hg(medium.g, w_out, rng.random(), rng.random());
            let s = -(1.0 - rng.random::<f64>()).ln() / sigma_t;
            let back = -w_in;
            let Some((_, exit)) = medium.clip(x, back, f32::INFINITY) else { break };
            if s >= f64::from(exit) {
                break;
            }
            x += back * s as f32;
            w_out = w_in;
            weight *= albedo;
            total += weight * nee(x, w_out);
        }
        sum += total;
        sum2 += total * total;
    }
    let n = paths.max(1) as f64;
    let mean = sum / n;
    PathTraced { single: single / n, all: mean, std_error: ((sum2 / n - mean * mean).max(0.0) / n).sqrt() }
}

/// A direction with cos θ to `axis` distributed by Henyey-Greenstein `g`.
pub fn sample_hg(g: f32, axis: Vec3, u1: f64, u2: f64) -> Vec3 {
    let g = f64::from(g);
    let cos = if g.abs() < 1e-4 {
        1.0 - 2.0 * u1
    } else {
        let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u1);
        ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
    };
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let phi = std::f64::consts::TAU * u2;
    let (b1, b2) = axis.any_orthonormal_pair();
    (axis * cos as f32 + b1 * (sin * phi.cos()) as f32 + b2 * (sin * phi.sin()) as f32).normalize_or(axis)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hg_sampling_matches_the_mean_cosine() {
        // E[cos θ] = g for Henyey-Greenstein.
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
        for g in [-0.5f32, 0.0, 0.8] {
            let n = 200_000;
            let mean: f64 =
                (0..n).map(|_| f64::from(sample_hg(g, Vec3::Z, rng.random(), rng.random()).z)).sum::<f64>() / n as f64;
            assert!((mean - f64::from(g)).abs() < 5e-3, "g {g}: {mean}");
        }
    }
}
