//! Whitted recursion (Vierjahn 2010, eq. 1) split the way eq. 5 needs it.
//!
//! The secondary rays of eq. 1 (k_R reflection, k_T transmission, up to the
//! depth limit) do not depend on any light: they depend on the camera and the
//! geometry only. So instead of re-tracing them for every light as the paper
//! does, [`expand`] follows them once and records every surface point a
//! camera path reaches as a [`ShadingVertex`] carrying the path's weight
//! (the product of k_R/k_T along it and the sample's bin weight). A light's
//! intensity buffer I_h,ε_i (eq. 5, unit source) is then the weighted sum of
//! [`direct`] over those vertices: one shadow ray per vertex, nothing else.
//! This is exact for eq. 1 at every finite depth (same rays, same order of
//! operations per vertex), which the linearity test checks against an
//! independent single-pass eq. 1 renderer ([`super::reference`]).

use crate::fixture::Light;
use crate::scene::bvh::{OccluderHint, offset_origin};
use crate::scene::{Facing, Scene, SurfacePoint};
use glam::Vec3;

/// A surface point seen by the camera, directly or through mirrors/glass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadingVertex {
    /// World position.
    pub position: Vec3,
    /// Shading normal, flipped to the side the view ray came from.
    pub normal: Vec3,
    /// Geometric normal on the same side (for offsets and horizon tests).
    pub geometric_normal: Vec3,
    /// Unit direction toward the viewer (reverse of the arriving ray).
    pub wo: Vec3,
    /// Material index.
    pub material: u32,
    /// Diffuse albedo ρ_d here: the material's times its base-colour
    /// texture ([`crate::scene::Scene::diffuse_at`]).
    pub diffuse: Vec3,
    /// Path weight: bin weight times the k_R/k_T products along the path.
    pub weight: Vec3,
    /// Bounces before this vertex (0 = seen directly by the camera).
    pub depth: u32,
}

/// Limits of the recursion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecursionLimits {
    /// Maximum number of secondary bounces (paper: 5). 0 = primary hits only.
    pub max_depth: u32,
    /// Paths whose weight falls below this (in every channel) are not
    /// followed further: their contribution is below display precision.
    pub min_weight: f32,
}

impl Default for RecursionLimits {
    fn default() -> Self {
        Self { max_depth: 5, min_weight: 1e-3 }
    }
}

/// Follows one camera path from its first surface hit through every mirror
/// and transmission bounce allowed by `limits`, appending a vertex for each
/// surface that has a non-zero Phong BRDF. Recursive (depth ≤ the limit), so
/// no allocation per path.
pub fn expand(
    scene: &Scene,
    first: SurfacePoint,
    dir: Vec3,
    weight: Vec3,
    limits: RecursionLimits,
    out: &mut Vec<ShadingVertex>,
) {
    expand_at(scene, first, dir, weight, 0, limits, out);
}

#[allow(clippy::too_many_arguments)]
fn expand_at(
    scene: &Scene,
    surface: SurfacePoint,
    dir: Vec3,
    weight: Vec3,
    depth: u32,
    limits: RecursionLimits,
    out: &mut Vec<ShadingVertex>,
) {
    let m = &scene.materials[surface.material as usize];
    // Orient normals toward the arriving ray (two-sided surfaces).
    let Facing { front, geometric: ng, shading: ns } = surface.facing(dir);
    if m.diffuse.max_element() > 0.0 || m.specular.max_element() > 0.0 {
        out.push(ShadingVertex {
            position: surface.position,
            normal: ns,
            geometric_normal: ng,
            wo: -dir,
            material: surface.material,
            diffuse: scene.diffuse_at(&surface),
            weight,
            depth,
        });
    }
    if depth >= limits.max_depth {
        return;
    }
    let mut reflect_weight = m.k_r;
    // Transmission: Snell refraction about the facing shading normal;
    // total internal reflection hands its k_T to the mirror ray.
    if m.k_t.max_element() > 0.0 {
        let eta = if front { 1.0 / m.ior } else { m.ior };
        match refract(dir, ns, eta) {
            Some(t) if t.dot(ng) < 0.0 => {
                let w = weight * m.k_t;
                if w.max_element() >= limits.min_weight
                    && let Some(next) = trace(scene, offset_origin(surface.position, -ng), t)
                {
                    expand_at(scene, next, t, w, depth + 1, limits, out);
                }
            }
            _ => reflect_weight += m.k_t,
        }
    }
    if reflect_weight.max_element() > 0.0 {
        let w = weight * reflect_weight;
        if w.max_element() >= limits.min_weight {
            let mut r = reflect(dir, ns);
            if r.dot(ng) <= 0.0 {
                // Interpolated normals can send the mirror ray under the surface.
                r = reflect(dir, ng);
            }
            if let Some(next) = trace(scene, offset_origin(surface.position, ng), r) {
                expand_at(scene, next, r, w, depth + 1, limits, out);
            }
        }
    }
}

fn trace(scene: &Scene, origin: Vec3, dir: Vec3) -> Option<SurfacePoint> {
    scene.accel.intersect(origin, dir, f32::INFINITY).map(|h| scene.surface(&h))
}

/// Mirror direction of incoming `d` about normal `n`.
pub fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    (d - 2.0 * d.dot(n) * n).normalize_or(n)
}

/// Refracted direction of incoming unit `d` through a surface with unit normal
/// `n` facing the incoming side, relative index `eta` = n_from / n_to; `None`
/// on total internal reflection.
pub fn refract(d: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = (-d.dot(n)).clamp(0.0, 1.0);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t > 1.0 {
        return None;
    }
    let t = eta * d + (eta * cos_i - (1.0 - sin2_t).sqrt()) * n;
    t.try_normalize()
}

/// Direct light from one unit-intensity source (1 cd, eq. 5's ε0 = 1) at a
/// vertex, as the luminance (cd/m²) it sends toward the viewer:
/// f_P(wi, wo) · f_ε(P_i → x') · cos θ / r² · g(P_i → x') (eq. 1's light term).
/// Zero behind the surface, outside the beam, or in shadow.
pub fn direct(scene: &Scene, light: &Light, v: &ShadingVertex) -> Vec3 {
    direct_with(scene, light, v, |origin, wi, len| scene.accel.occluded(origin, wi, len))
}

/// [`direct`], its shadow ray tested first against the triangle that
/// blocked the last one tested with `hint` ([`Accel::occluded_hinted`]):
/// the same value, and no traversal when neighbouring vertices (the samples
/// of one re-shaded pixel) lie in the shadow of one triangle.
///
/// [`Accel::occluded_hinted`]: crate::scene::bvh::Accel::occluded_hinted
pub fn direct_hinted(scene: &Scene, light: &Light, v: &ShadingVertex, hint: &mut OccluderHint) -> Vec3 {
    direct_with(scene, light, v, |origin, wi, len| scene.accel.occluded_hinted(origin, wi, len, hint))
}

/// [`direct_hinted`] with the beam's pattern f_ε replaced by `pattern`
/// (the value the pattern would have at the vertex: a beam rim's
/// anti-aliasing ([`crate::render::view::aa`]) shades a sample just
/// outside a hard cone edge with the value just inside it, weighted by
/// the share of its cell inside the cone). Zero where `pattern` ≤ 0.
pub fn direct_with_pattern(
    scene: &Scene,
    light: &Light,
    v: &ShadingVertex,
    pattern: f32,
    hint: &mut OccluderHint,
) -> Vec3 {
    direct_with_f(scene, light, v, |_| pattern, |origin, wi, len| scene.accel.occluded_hinted(origin, wi, len, hint))
}

/// [`direct`] with the shadow test `occluded(origin, direction, length)`.
#[inline(always)]
fn direct_with(
    scene: &Scene,
    light: &Light,
    v: &ShadingVertex,
    occluded: impl FnOnce(Vec3, Vec3, f32) -> bool,
) -> Vec3 {
    direct_with_f(scene, light, v, |dir| light.pattern_toward(dir), occluded)
}

/// [`direct_with`] with the pattern value toward a world direction (from
/// the light) given by `pattern`.
#[inline(always)]
fn direct_with_f(
    scene: &Scene,
    light: &Light,
    v: &ShadingVertex,
    pattern: impl FnOnce(Vec3) -> f32,
    occluded: impl FnOnce(Vec3, Vec3, f32) -> bool,
) -> Vec3 {
    let to_light = light.position - v.position;
    let dist2 = to_light.length_squared();
    if dist2.is_nan() || dist2 <= 1e-12 || dist2.is_infinite() {
        return Vec3::ZERO;
    }
    let dist = dist2.sqrt();
    let wi = to_light / dist;
    if wi.dot(v.geometric_normal) <= 0.0 {
        return Vec3::ZERO;
    }
    let cos = wi.dot(v.normal);
    if cos <= 0.0 {
        return Vec3::ZERO;
    }
    let f_e = pattern(-wi);
    if f_e <= 0.0 {
        return Vec3::ZERO;
    }
    let m = &scene.materials[v.material as usize];
    let brdf = m.brdf_with(v.diffuse, v.normal, wi, v.wo);
    let scale = f_e * cos / dist2;
    // A zero BRDF lights nothing, shadowed or not: no shadow ray (a mirror
    // or chrome vertex, ρ_d = 0 and Phong exponent 10,000, has cos^n α = 0
    // in f32 once the light is ~8° off its mirror direction, i.e. almost
    // always). The same value as after the test: 0 · a finite scale; a NaN
    // BRDF or an infinite scale still takes the test and shows as before.
    if brdf == Vec3::ZERO && scale.is_finite() {
        return Vec3::ZERO;
    }
    let origin = offset_origin(v.position, v.geometric_normal);
    let shadow_len = (light.position - origin).length() * (1.0 - 1e-5);
    if occluded(origin, wi, shadow_len) {
        return Vec3::ZERO;
    }
    brdf * scale
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refraction_obeys_snell_and_total_internal_reflection() {
        let n = Vec3::Y;
        let theta = 30f32.to_radians();
        let d = Vec3::new(theta.sin(), -theta.cos(), 0.0);
        let t = refract(d, n, 1.0 / 1.5).unwrap();
        let sin_t = t.x;
        assert!((sin_t - theta.sin() / 1.5).abs() < 1e-5);
        // From inside glass at 60°: sin 60° · 1.5 > 1 -> TIR.
        let steep = 60f32.to_radians();
        assert!(refract(Vec3::new(steep.sin(), -steep.cos(), 0.0), n, 1.5).is_none());
        // Normal incidence passes straight through.
        assert!((refract(Vec3::NEG_Y, n, 1.0 / 1.5).unwrap() - Vec3::NEG_Y).length() < 1e-6);
    }

    #[test]
    fn chrome_lights_only_near_its_mirror_direction_and_only_unshadowed() {
        use crate::fixture::{Beam, SpotBeam};
        use crate::scene::{Material, SceneBuilder};
        // A chrome vertex at the origin (ρ_d = 0, ρ_s = 0.9, n = 10,000)
        // under a spot at (1, 1, 0), with and without a black card between.
        let build = |card: bool| {
            let mut b = SceneBuilder::new();
            let black = b.add_material(Material::lambert("black", Vec3::ZERO));
            let chrome = b.add_material(Material {
                specular: Vec3::splat(0.9),
                exponent: 10_000.0,
                ..Material::lambert("chrome", Vec3::ZERO)
            });
            let (a, c) = (Vec3::new(-0.5, 0.0, -0.5), Vec3::new(0.5, 0.0, 0.5));
            b.add_quad(a, Vec3::new(c.x, 0.0, a.z), c, Vec3::new(a.x, 0.0, c.z), chrome);
            if card {
                // Across the segment to the light at its midpoint.
                let m = Vec3::new(0.5, 0.5, 0.0);
                let (u, w) = (Vec3::new(0.2, -0.2, 0.0), Vec3::new(0.0, 0.0, 0.2));
                b.add_quad(m - u - w, m + u - w, m + u + w, m - u + w, black);
            }
            (b.build(), chrome)
        };
        let at = Vec3::new(1.0, 1.0, 0.0);
        let light = Light::aimed(at, Vec3::ZERO, Beam::Spot(SpotBeam::from_beam_field(40.0, 60.0)));
        let wi = at.normalize();
        let vertex = |chrome: u32, wo: Vec3| ShadingVertex {
            position: Vec3::ZERO,
            normal: Vec3::Y,
            geometric_normal: Vec3::Y,
            wo,
            material: chrome,
            diffuse: Vec3::ZERO,
            weight: Vec3::ONE,
            depth: 0,
        };
        let mirror = Vec3::new(-1.0, 1.0, 0.0).normalize();
        // 20° off the mirror direction: cos^10000 20° is 0 in f32.
        let off = glam::Quat::from_rotation_z(20f32.to_radians()) * mirror;
        let (open, chrome) = build(false);
        let (shut, _) = build(true);
        // Phong's specular lobe at α = 0: ρ_s (n + 2) / 2π · f_ε cos θ / d².
        let f_e = light.pattern_toward(-wi);
        assert!(f_e > 0.9, "on the beam axis: {f_e}");
        let expected = 0.9 * 10_002.0 / std::f32::consts::TAU * f_e * wi.y / 2.0;
        let lit = direct(&open, &light, &vertex(chrome, mirror));
        // cos α rounds to 1 − ~6e-8 in f32, and cos^10000 α to 1 − ~6e-4.
        assert!((lit.x / expected - 1.0).abs() < 1e-3 && lit.x == lit.y && lit.y == lit.z, "{lit} vs {expected}");
        assert_eq!(direct(&shut, &light, &vertex(chrome, mirror)), Vec3::ZERO, "the card shadows the highlight");
        assert_eq!(direct(&open, &light, &vertex(chrome, off)), Vec3::ZERO, "no highlight 20° off the mirror");
        assert_eq!(direct(&shut, &light, &vertex(chrome, off)), Vec3::ZERO);
    }

    #[test]
    fn reflection_mirrors_about_the_normal() {
        let r = reflect(Vec3::new(1.0, -1.0, 0.0).normalize(), Vec3::Y);
        assert!((r - Vec3::new(1.0, 1.0, 0.0).normalize()).length() < 1e-6);
    }
}
