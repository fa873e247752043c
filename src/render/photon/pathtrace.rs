//! Brute-force path tracing of the indirect term for one light: the
//! independent reference for the photon maps in diffuse scenes.
//!
//! At a diffuse point x the indirect irradiance is E(x) = ∫ L(y→x) cos θ dω
//! over the hemisphere, with L(y→x) the light leaving the surface seen in
//! direction ω: its direct term (next-event estimation to the point light,
//! via the same `direct` as the ray tracer) plus its own indirect term,
//! recursively, with Russian roulette; mirrors and glass are followed.
//! A point light seen through a mirror (caustics) is a delta path that this
//! estimator cannot find, so it is a reference only for scenes without
//! caustic paths. It shares no code with the photon tracer.

use crate::fixture::Light;
use crate::render::whitted::{ShadingVertex, direct, reflect};
use crate::scene::{Facing, Scene, bvh::offset_origin};
use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use super::trace::cosine_hemisphere;

/// Indirect irradiance at `x` (normal `n` facing the side to gather from)
/// estimated with `samples` cosine-weighted paths and seed `seed`.
pub fn indirect_irradiance(scene: &Scene, light: &Light, x: Vec3, n: Vec3, samples: usize, seed: u64) -> Vec3 {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let mut sum = Vec3::ZERO;
    for _ in 0..samples {
        let dir = cosine_hemisphere(n, rng.random(), rng.random());
        // cos-weighted pdf cos/π: E ≈ π · mean(L).
        sum += radiance_along(scene, light, offset_origin(x, n), dir, &mut rng, 0);
    }
    sum * std::f32::consts::PI / samples.max(1) as f32
}

/// Radiance arriving at `origin` from direction `dir` (direct + indirect at the hit).
fn radiance_along(scene: &Scene, light: &Light, origin: Vec3, dir: Vec3, rng: &mut Pcg64Mcg, depth: u32) -> Vec3 {
    if depth > 64 {
        return Vec3::ZERO;
    }
    let Some(hit) = scene.accel.intersect(origin, dir, f32::INFINITY) else { return Vec3::ZERO };
    let s = scene.surface(&hit);
    let m = &scene.materials[s.material as usize];
    let rho = scene.diffuse_at(&s);
    let Facing { geometric: ng, shading: ns, .. } = s.facing(dir);
    let v = ShadingVertex {
        position: s.position,
        normal: ns,
        geometric_normal: ng,
        wo: -dir,
        material: s.material,
        diffuse: rho,
        weight: Vec3::ONE,
        depth: 0,
    };
    let mut l = direct(scene, light, &v);
    // Continue: diffuse bounce or mirror, chosen by Russian roulette.
    let pd = rho.max_element();
    let pr = m.k_r.max_element();
    let total = (pd + pr).min(1.0);
    if total <= 0.0 {
        return l;
    }
    let u: f32 = rng.random();
    if u < pd.min(total) {
        let d = cosine_hemisphere(ns, rng.random(), rng.random());
        if d.dot(ng) > 0.0 {
            l += rho / pd * radiance_along(scene, light, offset_origin(s.position, ng), d, rng, depth + 1);
        }
    } else if u < total {
        let r = reflect(dir, ns);
        l += m.k_r / pr * radiance_along(scene, light, offset_origin(s.position, ng), r, rng, depth + 1);
    }
    l
}
