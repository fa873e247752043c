//! Surface materials in the paper's model (Vierjahn 2010, eq. 1): a Phong
//! BRDF for direct light plus Whitted's mirror coefficient k_R and
//! transmission coefficient k_T for the recursive terms.
//!
//! glTF describes materials physically (base colour, metallic, roughness,
//! `KHR_materials_transmission`, `KHR_materials_ior`); [`Material::from_pbr`]
//! maps them onto the Phong/Whitted model. The mapping is documented in
//! `docs/rendering.md` and chosen so that it conserves energy and a matte
//! (rough, non-metallic) glTF material is exactly Lambert (ρ/π; the analytic
//! tests and the path-traced references depend on that).

use glam::Vec3;

/// Roughness at and above which a surface gets no mirror recursion (k_R = 0)
/// and a dielectric no specular lobe: matte paint is exactly Lambert (ρ/π),
/// and secondary rays stay on surfaces that look like mirrors, which is what
/// Whitted's model is for. Below it, gloss fades in as (1 − roughness/0.5)².
pub const MIRROR_ROUGHNESS_LIMIT: f32 = 0.5;

/// Phong exponents are clamped to this, so a perfect mirror's highlight is a
/// tiny but finite lobe rather than an overflow (cos^n with huge n).
pub const MAX_PHONG_EXPONENT: f32 = 10_000.0;

/// One surface material in the renderer's model.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name from the scene file, for messages and statistics.
    pub name: String,
    /// Lambert albedo ρ_d per RGB channel (BRDF ρ_d/π).
    pub diffuse: Vec3,
    /// Phong specular coefficient ρ_s (normalised lobe, see [`Material::brdf`]).
    pub specular: Vec3,
    /// Phong exponent n of the specular lobe.
    pub exponent: f32,
    /// Whitted mirror coefficient k_R per channel (eq. 1).
    pub k_r: Vec3,
    /// Whitted transmission coefficient k_T per channel (eq. 1).
    pub k_t: Vec3,
    /// Index of refraction used to bend transmitted rays.
    pub ior: f32,
    /// Base-colour texture: multiplies [`Material::diffuse`] at each surface
    /// point ([`crate::scene::Scene::diffuse_at`]).
    pub base_texture: Option<std::sync::Arc<super::texture::Texture>>,
}

impl Material {
    /// A pure Lambert surface with albedo `rho`: the analytic test material.
    pub fn lambert(name: &str, rho: Vec3) -> Self {
        Self {
            name: name.to_string(),
            diffuse: rho,
            specular: Vec3::ZERO,
            exponent: 1.0,
            k_r: Vec3::ZERO,
            k_t: Vec3::ZERO,
            ior: 1.0,
            base_texture: None,
        }
    }

    /// Maps glTF metallic-roughness parameters to the Phong/Whitted model
    /// (table in `docs/rendering.md`).
    ///
    /// * F0_d = ((ior−1)/(ior+1))²: a dielectric's normal-incidence reflectance.
    /// * gloss g = (1 − roughness/0.5)² below roughness 0.5, else 0: how much
    ///   of a dielectric's Fresnel reflection stays a distinct lobe. A rough
    ///   dielectric (roughness ≥ 0.5) has g = 0 and is exactly Lambert: its
    ///   surface reflection is spread over the hemisphere like the diffuse part.
    /// * ρ_s = (1 − metallic) · F0_d · g + metallic · base (metals keep their
    ///   coloured lobe at any roughness: they have no diffuse part).
    /// * ρ_d = base · (1 − metallic) · (1 − transmission) · (1 − F0_d · g):
    ///   the specular albedo is taken out of the diffuse part, so
    ///   ρ_d + ρ_s ≤ 1 per channel (energy conservation).
    /// * exponent n = 2/α² − 2 with α = roughness², clamped to [1, 10⁴].
    /// * k_R = mix(F0_d, base, metallic) · g: mirror recursion fades out with roughness.
    /// * k_T = transmission · (1 − metallic) · base (tinted glass).
    ///
    /// All inputs are clamped into their glTF ranges first, so absurd files
    /// cannot produce energy gain or NaN.
    pub fn from_pbr(name: &str, base: Vec3, metallic: f32, roughness: f32, transmission: f32, ior: f32) -> Self {
        let base = sanitize_colour(base);
        let metallic = clamp01(metallic);
        let roughness = clamp01(roughness);
        let transmission = clamp01(transmission);
        let ior = if ior.is_finite() && ior >= 1.0 { ior.min(4.0) } else { 1.5 };
        let f0_dielectric = ((ior - 1.0) / (ior + 1.0)).powi(2);
        let f0 = Vec3::splat(f0_dielectric).lerp(base, metallic);
        let alpha = (roughness * roughness).max(1e-3);
        let exponent = (2.0 / (alpha * alpha) - 2.0).clamp(1.0, MAX_PHONG_EXPONENT);
        let gloss = (1.0 - roughness / MIRROR_ROUGHNESS_LIMIT).max(0.0).powi(2);
        let dielectric_specular = f0_dielectric * gloss;
        let specular = Vec3::splat(dielectric_specular * (1.0 - metallic)) + base * metallic;
        let k_t = base * (transmission * (1.0 - metallic));
        // Energy: the diffuse part only gets what is neither mirrored,
        // transmitted nor reflected by the dielectric's specular lobe.
        let diffuse = base * ((1.0 - metallic) * (1.0 - transmission) * (1.0 - dielectric_specular));
        Self { name: name.to_string(), diffuse, specular, exponent, k_r: f0 * gloss, k_t, ior, base_texture: None }
    }

    /// True when the material spawns secondary rays (k_R or k_T non-zero):
    /// the paper's "specular material".
    pub fn is_specular(&self) -> bool {
        self.k_r.max_element() > 0.0 || self.k_t.max_element() > 0.0
    }

    /// True when the material transmits (k_T non-zero).
    pub fn is_transmissive(&self) -> bool {
        self.k_t.max_element() > 0.0
    }

    /// Phong BRDF f_P(wi, wo) for unit vectors about shading normal `n`
    /// (eq. 1's f_P): ρ_d/π + ρ_s (n+2)/(2π) max(0, r·wo)^n, with r the
    /// mirror direction of `wi`. The lobe is normalised so it never reflects
    /// more than ρ_s.
    pub fn brdf(&self, n: Vec3, wi: Vec3, wo: Vec3) -> Vec3 {
        self.brdf_with(self.diffuse, n, wi, wo)
    }

    /// [`Material::brdf`] with the diffuse albedo at the surface point
    /// (`diffuse` = ρ_d times the base-colour texel, [`crate::scene::Scene::diffuse_at`]).
    pub fn brdf_with(&self, diffuse: Vec3, n: Vec3, wi: Vec3, wo: Vec3) -> Vec3 {
        let lambert = diffuse * std::f32::consts::FRAC_1_PI;
        if self.specular.max_element() <= 0.0 {
            return lambert;
        }
        let r = 2.0 * n.dot(wi) * n - wi;
        let cos_alpha = r.dot(wo).max(0.0);
        if cos_alpha <= 0.0 {
            return lambert;
        }
        let lobe = (self.exponent + 2.0) * 0.5 * std::f32::consts::FRAC_1_PI * cos_alpha.powf(self.exponent);
        lambert + self.specular * lobe
    }
}

fn clamp01(x: f32) -> f32 {
    if x.is_finite() { x.clamp(0.0, 1.0) } else { 0.0 }
}

fn sanitize_colour(c: Vec3) -> Vec3 {
    Vec3::new(clamp01(c.x), clamp01(c.y), clamp01(c.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matte_pbr_is_pure_lambert_without_mirror() {
        let m = Material::from_pbr("paint", Vec3::splat(0.5), 0.0, 0.8, 0.0, 1.5);
        assert_eq!(m.k_r, Vec3::ZERO);
        assert_eq!(m.k_t, Vec3::ZERO);
        assert!((m.diffuse - Vec3::splat(0.5)).length() < 1e-6);
        assert_eq!(m.specular, Vec3::ZERO);
        assert!(!m.is_specular());
    }

    #[test]
    fn chrome_reflects_its_base_colour() {
        let m = Material::from_pbr("chrome", Vec3::splat(0.9), 1.0, 0.0, 0.0, 1.5);
        assert!((m.k_r - Vec3::splat(0.9)).length() < 1e-6);
        assert_eq!(m.diffuse, Vec3::ZERO);
        assert!(m.is_specular());
    }

    #[test]
    fn glass_transmits_and_reflects_fresnel_f0() {
        let m = Material::from_pbr("glass", Vec3::ONE, 0.0, 0.0, 0.9, 1.5);
        assert!((m.k_t - Vec3::splat(0.9)).length() < 1e-6);
        assert!((m.k_r.x - 0.04).abs() < 1e-6);
        assert!(m.is_transmissive());
    }

    #[test]
    fn diffuse_plus_specular_never_exceeds_one() {
        for r in [0.0, 0.1, 0.3, 0.49, 0.5, 1.0] {
            for metallic in [0.0, 0.5, 1.0] {
                let m = Material::from_pbr("x", Vec3::ONE, metallic, r, 0.0, 2.5);
                let total = m.diffuse + m.specular;
                assert!(total.max_element() <= 1.0 + 1e-6, "r {r} m {metallic}: {total}");
            }
        }
        // Glossy white plastic: the lobe's F0 comes out of the diffuse albedo.
        let m = Material::from_pbr("plastic", Vec3::ONE, 0.0, 0.0, 0.0, 1.5);
        assert!((m.diffuse.x + m.specular.x - 1.0).abs() < 1e-6 && (m.specular.x - 0.04).abs() < 1e-6);
    }

    #[test]
    fn absurd_inputs_are_clamped_finite() {
        let m = Material::from_pbr("bad", Vec3::new(f32::NAN, 7.0, -1.0), f32::INFINITY, -3.0, 9.0, f32::NAN);
        for v in [m.diffuse, m.specular, m.k_r, m.k_t] {
            assert!(v.is_finite() && v.min_element() >= 0.0 && v.max_element() <= 1.0);
        }
        assert!(m.exponent.is_finite() && m.ior.is_finite());
    }

    #[test]
    fn phong_lobe_is_normalised() {
        // Integrate the lobe times cos over the hemisphere for normal incidence:
        // must not exceed ρ_s (energy conservation), and approach it for large n.
        let m =
            Material { specular: Vec3::ONE, diffuse: Vec3::ZERO, exponent: 20.0, ..Material::lambert("x", Vec3::ZERO) };
        let n = Vec3::Z;
        let wi = Vec3::Z;
        let steps = 400;
        let mut sum = 0.0;
        for i in 0..steps {
            let theta = (i as f32 + 0.5) / steps as f32 * std::f32::consts::FRAC_PI_2;
            let wo = Vec3::new(theta.sin(), 0.0, theta.cos());
            let f = m.brdf(n, wi, wo).x;
            sum += f * theta.cos() * theta.sin() * std::f32::consts::FRAC_PI_2 / steps as f32 * std::f32::consts::TAU;
        }
        assert!(sum <= 1.0 + 1e-3 && sum > 0.9, "albedo {sum}");
    }
}
