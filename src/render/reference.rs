//! Single-pass eq. 1 renderer: the independent reference for linearity.
//!
//! It shades every camera ray with all lights at once, recursing through
//! k_R and k_T exactly as Whitted's model (Vierjahn 2010, eq. 1) reads:
//! I(x'→x) = Σ_i k_i f_P f_ε cos/r² g + k_R I(x''_R) + k_T I(x''_T).
//! It shares no code with the per-light path cache ([`super::view`]) beyond
//! the primary sample positions, the material BRDF and the shadow-ray query,
//! so `composite(per-light buffers) == reference` checks eq. 5 end to end.

use super::gbuffer::{CENTRE_SAMPLE, GBuffer, NO_HIT, SAMPLES_PER_PIXEL, bin_samples, surface_bins};
use super::view::SampleSet;
use super::whitted::{RecursionLimits, ShadingVertex, direct, reflect, refract};
use crate::fixture::Light;
use crate::scene::{Facing, Hit, Scene, SurfacePoint, bvh::offset_origin};
use glam::Vec3;
use rayon::prelude::*;

/// Renders all `lights` with weights `k` in one pass (eq. 1), row-major linear RGB.
pub fn render_eq1(
    scene: &Scene,
    gbuffer: &GBuffer,
    lights: &[Light],
    k: &[Vec3],
    set: SampleSet,
    limits: RecursionLimits,
) -> Vec<Vec3> {
    render_eq1_weighted(scene, gbuffer, lights, |_, out| out.copy_from_slice(k), set, limits)
}

/// As [`render_eq1`] with per-pixel weights: `k_at(pixel, k)` fills the
/// lights' weights for that pixel (row-major index). The haze reference
/// (`media::reference`) folds each light's extinction into them.
pub fn render_eq1_weighted(
    scene: &Scene,
    gbuffer: &GBuffer,
    lights: &[Light],
    k_at: impl Fn(usize, &mut [Vec3]) + Sync,
    set: SampleSet,
    limits: RecursionLimits,
) -> Vec<Vec3> {
    let w = gbuffer.width as usize;
    let mut out = vec![Vec3::ZERO; w * gbuffer.height as usize];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let mut k = vec![Vec3::ZERO; lights.len()];
        for (x, px) in row.iter_mut().enumerate() {
            k_at(y * w + x, &mut k);
            let k = &k[..];
            let samples = &gbuffer.samples[y * w + x];
            let mut weighted: Vec<(u32, f32, f32, f32)> = Vec::new();
            match set {
                SampleSet::Centre => {
                    let s = samples[CENTRE_SAMPLE];
                    weighted.push((s.triangle, s.u, s.v, 1.0));
                }
                SampleSet::Binned => weighted
                    .extend(surface_bins(scene, samples).as_slice().iter().map(|b| (b.triangle, b.u, b.v, b.weight))),
                SampleSet::TriangleBins => {
                    weighted.extend(bin_samples(samples).as_slice().iter().map(|b| (b.triangle, b.u, b.v, b.weight)))
                }
                SampleSet::All => {
                    weighted.extend(samples.iter().map(|s| (s.triangle, s.u, s.v, 1.0 / SAMPLES_PER_PIXEL as f32)))
                }
            }
            for (tri, u, v, weight) in weighted {
                if tri == NO_HIT {
                    continue;
                }
                let p = scene.point_on(tri, u, v);
                let Some(dir) = (p - gbuffer.camera.position).try_normalize() else { continue };
                let surface = scene.surface(&Hit { triangle: tri, t: 0.0, u, v });
                *px += radiance(scene, lights, k, surface, dir, Vec3::splat(weight), 0, limits) * weight;
            }
        }
    });
    out
}

/// Eq. 1 at one surface point, recursively. `path_weight` only decides, as
/// in the per-light renderer, when a path is too faint to follow.
#[allow(clippy::too_many_arguments)]
fn radiance(
    scene: &Scene,
    lights: &[Light],
    k: &[Vec3],
    s: SurfacePoint,
    dir: Vec3,
    path_weight: Vec3,
    depth: u32,
    limits: RecursionLimits,
) -> Vec3 {
    let m = &scene.materials[s.material as usize];
    let Facing { front, geometric: ng, shading: ns } = s.facing(dir);
    let mut total = Vec3::ZERO;
    if m.diffuse.max_element() > 0.0 || m.specular.max_element() > 0.0 {
        let v = ShadingVertex {
            position: s.position,
            normal: ns,
            geometric_normal: ng,
            wo: -dir,
            material: s.material,
            diffuse: scene.diffuse_at(&s),
            weight: Vec3::ONE,
            depth,
        };
        for (light, k) in lights.iter().zip(k) {
            total += *k * direct(scene, light, &v);
        }
    }
    if depth >= limits.max_depth {
        return total;
    }
    let mut k_reflect = m.k_r;
    if m.k_t.max_element() > 0.0 {
        let eta = if front { 1.0 / m.ior } else { m.ior };
        match refract(dir, ns, eta) {
            Some(t) if t.dot(ng) < 0.0 => {
                if (path_weight * m.k_t).max_element() >= limits.min_weight
                    && let Some(h) = scene.accel.intersect(offset_origin(s.position, -ng), t, f32::INFINITY)
                {
                    total += m.k_t
                        * radiance(scene, lights, k, scene.surface(&h), t, path_weight * m.k_t, depth + 1, limits);
                }
            }
            _ => k_reflect += m.k_t,
        }
    }
    if k_reflect.max_element() > 0.0 && (path_weight * k_reflect).max_element() >= limits.min_weight {
        let mut r = reflect(dir, ns);
        if r.dot(ng) <= 0.0 {
            r = reflect(dir, ng);
        }
        if let Some(h) = scene.accel.intersect(offset_origin(s.position, ng), r, f32::INFINITY) {
            total += k_reflect
                * radiance(scene, lights, k, scene.surface(&h), r, path_weight * k_reflect, depth + 1, limits);
        }
    }
    total
}
