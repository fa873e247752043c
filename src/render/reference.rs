//! Single-pass eq. 1 renderer: the independent reference for linearity.
//!
//! It shades every camera ray with all lights at once, recursing through
//! k_R and k_T exactly as Whitted's model (Vierjahn 2010, eq. 1) reads:
//! I(x'→x) = Σ_i k_i f_P f_ε cos/r² g + k_R I(x''_R) + k_T I(x''_T).
//! `composite(per-light buffers) == reference` then checks eq. 5 end to
//! end, and the anti-aliasing tests check re-shaded pixels against its 9
//! samples. So that a bug in the renderer's shading cannot cancel out, the
//! reference is written apart from it:
//!
//! * **Its own**: the recursion ([`radiance`]: which rays are followed, the
//!   k_R/k_T weights, total internal reflection handing k_T to the mirror
//!   ray), and eq. 1's light term ([`light_term`]): distance, cos θ, the
//!   horizon tests, the shadow ray's origin and length, and the Phong BRDF
//!   f_P ([`phong`]) written from its formula, not
//!   [`crate::scene::Material::brdf_with`] nor [`super::whitted::direct`].
//! * **Shared, with closed-form tests of their own**: the primary samples
//!   and bins (the G-buffer is the input both render), the surface queries
//!   ([`Scene::surface`], [`Scene::diffuse_at`], [`SurfacePoint::facing`]),
//!   the BVH's ray and shadow queries, the beam pattern f_ε
//!   ([`Light::pattern_toward`]) and the mirror and Snell directions
//!   ([`reflect`], [`refract`]: `whitted`'s unit tests). This module's
//!   tests check the reference itself against numbers computed from first
//!   principles: a Lambert floor under a spot of known cone (E = I cos θ /
//!   d², L = ρ/π E), a Phong lobe, a card's shadow, and a mirror.

use super::gbuffer::{CENTRE_SAMPLE, GBuffer, NO_HIT, SAMPLES_PER_PIXEL, bin_samples, surface_bins};
use super::view::SampleSet;
use super::whitted::{RecursionLimits, reflect, refract};
use crate::fixture::Light;
use crate::scene::{Facing, Hit, Material, Scene, SurfacePoint, bvh::offset_origin};
use glam::Vec3;
use rayon::prelude::*;

pub mod path;

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
        let at = Lit {
            position: s.position,
            ns,
            ng,
            wo: -dir,
            material: m,
            rho_d: scene.diffuse_at(&s),
            lambert_only: false,
        };
        for (light, k) in lights.iter().zip(k) {
            total += *k * light_term(scene, light, &at);
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

/// A surface point as eq. 1's light term needs it: the shading normal `ns`
/// and the geometric one `ng`, both on the side the viewer sees, the unit
/// direction `wo` toward the viewer, the material and its diffuse albedo
/// ρ_d there (texture included). `lambert_only`: the BRDF is ρ_d/π alone
/// (a vertex after a diffuse bounce of [`path`]: the photon model carries
/// light on from a surface diffusely, never along its Phong lobe).
pub(super) struct Lit<'a> {
    pub(super) position: Vec3,
    pub(super) ns: Vec3,
    pub(super) ng: Vec3,
    pub(super) wo: Vec3,
    pub(super) material: &'a Material,
    pub(super) rho_d: Vec3,
    pub(super) lambert_only: bool,
}

/// Eq. 1's light term for one unit-intensity light at `at`, from the
/// formula: f_P(ω_i, ω_o) · f_ε(P → x) · cos θ / r² · g(P → x), with θ
/// between ω_i (toward the light) and the shading normal and g the
/// visibility. Zero for a light behind the surface (either normal), at the
/// point itself or at infinity.
pub(super) fn light_term(scene: &Scene, light: &Light, at: &Lit) -> Vec3 {
    let toward = light.position - at.position;
    let r2 = toward.length_squared();
    let wi = toward / r2.sqrt();
    let cos_theta = wi.dot(at.ns);
    let in_front = r2 > 1e-12 && r2.is_finite() && cos_theta > 0.0 && wi.dot(at.ng) > 0.0;
    let f_e = if in_front { light.pattern_toward(-wi) } else { 0.0 };
    if f_e <= 0.0 || !visible(scene, at.position, at.ng, wi, light.position) {
        return Vec3::ZERO;
    }
    let brdf =
        if at.lambert_only { at.rho_d / std::f32::consts::PI } else { phong(at.material, at.rho_d, at.ns, wi, at.wo) };
    brdf * (f_e * cos_theta / r2)
}

/// g(P → x): no surface along the ray from the point `x` toward the light
/// at `p` (direction `wi`), from `x` lifted off its surface along `ng`
/// (against self-intersection) to just short of the light.
fn visible(scene: &Scene, x: Vec3, ng: Vec3, wi: Vec3, p: Vec3) -> bool {
    let from = offset_origin(x, ng);
    !scene.accel.occluded(from, wi, from.distance(p) * (1.0 - 1e-5))
}

/// Phong's BRDF f_P (eq. 1) about the unit normal `n`, from its
/// definition: ρ_d/π + ρ_s (e + 2)/2π cos^e α, with α the angle between
/// `wo` and `wi` mirrored about `n`, and e the Phong exponent (the lobe
/// normalised so that it reflects at most ρ_s).
fn phong(m: &Material, rho_d: Vec3, n: Vec3, wi: Vec3, wo: Vec3) -> Vec3 {
    let mirrored = 2.0 * n.dot(wi) * n - wi;
    let cos_alpha = mirrored.dot(wo);
    let lobe =
        if cos_alpha > 0.0 { (m.exponent + 2.0) / std::f32::consts::TAU * cos_alpha.powf(m.exponent) } else { 0.0 };
    rho_d / std::f32::consts::PI + m.specular * lobe
}

#[cfg(test)]
mod tests {
    //! The reference against numbers computed here from first principles,
    //! pixel by pixel at each pixel's centre sample.
    use super::*;
    use crate::fixture::{Beam, SpotBeam};
    use crate::scene::{Camera, SceneBuilder};
    use std::f32::consts::PI;

    /// A square of half-size `half` at height `y`, facing +Y.
    fn square(b: &mut SceneBuilder, half: f32, y: f32, m: u32) {
        let (a, c) = (-half, half);
        b.add_quad(Vec3::new(a, y, c), Vec3::new(c, y, c), Vec3::new(c, y, a), Vec3::new(a, y, a), m);
    }

    /// A spot of 1 cd on its axis, at `at` pointing straight down, whose
    /// pattern is 1 inside `inner` and falls off as 1 − smoothstep to 0 at
    /// `outer` (half-angles, degrees).
    fn spot(at: Vec3, inner: f32, outer: f32) -> Light {
        let beam = SpotBeam::from_half_angles(inner.to_radians(), outer.to_radians());
        Light::aimed(at, at + Vec3::NEG_Y, Beam::Spot(beam))
    }

    /// f_ε of [`spot`] at `theta` radians off its axis, from the definition.
    fn cone(theta: f32, inner: f32, outer: f32) -> f32 {
        let t = ((theta - inner.to_radians()) / (outer - inner).to_radians()).clamp(0.0, 1.0);
        1.0 - t * t * (3.0 - 2.0 * t)
    }

    /// The reference of `lights` (weights 1) at the centre samples, with
    /// each pixel's surface point (`None` for a miss).
    fn render(scene: &Scene, camera: Camera, lights: &[Light], depth: u32) -> Vec<(Vec3, Option<Vec3>)> {
        let g = GBuffer::build(scene, camera, 64, 48);
        let limits = RecursionLimits { max_depth: depth, min_weight: 0.0 };
        let k = vec![Vec3::ONE; lights.len()];
        let out = render_eq1(scene, &g, lights, &k, SampleSet::Centre, limits);
        out.into_iter().zip(&g.samples).map(|(v, s)| (v, g.position(scene, &s[CENTRE_SAMPLE]))).collect()
    }

    /// Lambert: L = ρ/π · E with E = I f_ε(θ) cos θ / d², where θ is both
    /// the angle off the beam's axis and the angle of incidence (the spot
    /// points straight down at a floor).
    #[test]
    fn lambert_floor_under_a_spot_is_rho_over_pi_times_i_cos_over_d2() {
        let mut b = SceneBuilder::new();
        let rho = Vec3::new(0.7, 0.5, 0.2);
        let m = b.add_material(Material::lambert("floor", rho));
        square(&mut b, 20.0, 0.0, m);
        let scene = b.build();
        let at = Vec3::new(0.2, 3.0, -0.1);
        let (inner, outer) = (15.0, 25.0);
        let camera = Camera::look_at(Vec3::new(0.0, 5.0, 0.01), Vec3::ZERO, 60f32.to_radians());
        let (mut lit, mut dark, mut edge) = (0, 0, 0);
        for (got, p) in render(&scene, camera, &[spot(at, inner, outer)], 0) {
            let p = p.expect("the floor fills the view");
            let d = at - p;
            let cos = d.y / d.length();
            let f = cone(cos.acos(), inner, outer);
            let expected = rho / PI * f * cos / d.length_squared();
            let off = (got - expected).abs().max_element();
            // The pattern's slope at the cone's edge (≤ 1.5 per 10°) turns
            // the f32 angle's rounding into ~1e-6 of f_ε.
            assert!(off <= 1e-5 * expected.max_element() + 1e-6, "at {p}: {got} vs {expected}");
            match f {
                1.0 => lit += 1,
                0.0 => dark += 1,
                _ => edge += 1,
            }
        }
        assert!(lit > 100 && dark > 100 && edge > 100, "{lit} in the core, {edge} on the edge, {dark} outside");
    }

    /// Phong: a glossy floor (ρ_d, ρ_s, exponent e) under a point light:
    /// L = (ρ_d/π + ρ_s (e + 2)/2π cos^e α) · cos θ / d², α between the
    /// view direction and the light's mirror direction.
    #[test]
    fn glossy_floor_is_lambert_plus_the_normalised_phong_lobe() {
        let mut b = SceneBuilder::new();
        let (rho_d, rho_s, e) = (Vec3::splat(0.3), Vec3::new(0.5, 0.4, 0.3), 40.0);
        let m = b.add_material(Material { specular: rho_s, exponent: e, ..Material::lambert("gloss", rho_d) });
        square(&mut b, 20.0, 0.0, m);
        let scene = b.build();
        let at = Vec3::new(0.0, 2.0, -1.0);
        let eye = Vec3::new(0.0, 2.0, 3.0);
        let camera = Camera::look_at(eye, Vec3::new(0.0, 0.0, 0.5), 50f32.to_radians());
        let mut glossy = 0;
        for (got, p) in render(&scene, camera, &[spot(at, 180.0, 180.0)], 0) {
            let Some(p) = p else { continue };
            let (to_light, to_eye) = ((at - p).normalize(), (eye - p).normalize());
            let mirror = Vec3::new(-to_light.x, to_light.y, -to_light.z);
            let cos_alpha = mirror.dot(to_eye).max(0.0);
            let lobe = rho_s * (e + 2.0) / (2.0 * PI) * cos_alpha.powf(e);
            let expected = (rho_d / PI + lobe) * to_light.y / (at - p).length_squared();
            assert!(
                (got - expected).abs().max_element() <= 1e-4 * expected.max_element(),
                "at {p}: {got} vs {expected}"
            );
            glossy += usize::from(lobe.x > 10.0 * rho_d.x / PI);
        }
        assert!(glossy > 20, "{glossy} pixels in the highlight");
    }

    /// Visibility: a black card 1 m above the floor casts the shadow found
    /// by intersecting each point's segment to the light with the card's
    /// plane; outside it the floor is lit as a Lambert floor.
    #[test]
    fn a_card_shadows_exactly_the_points_whose_segment_to_the_light_it_crosses() {
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::lambert("floor", Vec3::splat(0.5)));
        let black = b.add_material(Material::lambert("card", Vec3::ZERO));
        square(&mut b, 20.0, 0.0, m);
        square(&mut b, 0.4, 1.0, black);
        let scene = b.build();
        let at = Vec3::new(0.3, 2.5, 0.2);
        let camera = Camera::look_at(Vec3::new(0.0, 6.0, 3.0), Vec3::ZERO, 50f32.to_radians());
        let (mut shadowed, mut lit) = (0, 0);
        for (got, p) in render(&scene, camera, &[spot(at, 180.0, 180.0)], 0) {
            let Some(p) = p.filter(|p| p.y < 0.5) else { continue };
            // Where the segment p → light crosses y = 1.
            let c = p + (at - p) * ((1.0 - p.y) / (at.y - p.y));
            let inside = c.x.abs().max(c.z.abs());
            if (inside - 0.4).abs() < 1e-3 {
                continue; // on the shadow's edge
            }
            let d = at - p;
            let expected = if inside < 0.4 { 0.0 } else { 0.5 / PI * (d.y / d.length()) / d.length_squared() };
            assert!((got.x - expected).abs() <= 1e-5 * expected + 1e-9, "at {p} (card at {c}): {got} vs {expected}");
            if inside < 0.4 { shadowed += 1 } else { lit += 1 }
        }
        assert!(shadowed > 50 && lit > 500, "{shadowed} shadowed, {lit} lit");
    }

    /// Recursion: a mirror floor (k_R, nothing else) shows a Lambert
    /// ceiling lit from below: L = k_R · ρ/π · cos θ_q / |P − q|² at the
    /// point q where the mirrored view ray meets the ceiling.
    #[test]
    fn a_mirror_floor_shows_k_r_times_the_lit_ceiling() {
        let mut b = SceneBuilder::new();
        let k_r = Vec3::new(0.8, 0.6, 0.4);
        let mirror = b.add_material(Material { k_r, ..Material::lambert("mirror", Vec3::ZERO) });
        let ceiling = b.add_material(Material::lambert("ceiling", Vec3::splat(0.6)));
        square(&mut b, 20.0, 0.0, mirror);
        square(&mut b, 20.0, 2.0, ceiling);
        let scene = b.build();
        let at = Vec3::new(0.4, 0.8, -0.3);
        let eye = Vec3::new(0.0, 1.5, 0.0);
        let camera = Camera::look_at(eye, Vec3::new(0.0, 0.0, -0.01), 60f32.to_radians());
        let lights = [spot(at, 180.0, 180.0)];
        let mut seen = 0;
        for (got, p) in render(&scene, camera, &lights, 1) {
            let p = p.expect("the mirror fills the view");
            assert!(p.y.abs() < 1e-5, "the camera sees the mirror at {p}");
            let d = (p - eye).normalize();
            let r = Vec3::new(d.x, -d.y, d.z);
            let q = p + r * (2.0 / r.y);
            let to_light = at - q;
            let expected = k_r * 0.6 / PI * (-to_light.y / to_light.length()) / to_light.length_squared();
            assert!(
                (got - expected).abs().max_element() <= 1e-4 * expected.max_element(),
                "at {p}: {got} vs {expected}"
            );
            seen += 1;
        }
        assert_eq!(seen, 64 * 48);
        // Depth 0: the mirror alone, which reflects no light directly.
        assert!(render(&scene, camera, &lights, 0).iter().all(|(v, _)| *v == Vec3::ZERO));
    }
}
