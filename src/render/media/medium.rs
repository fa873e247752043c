//! The homogeneous medium: coefficients, the Henyey-Greenstein phase
//! function, the haze box and optical lengths through it.
//!
//! Conventions (also in `docs/rendering.md`):
//! * σ_s, σ_a, σ_t = σ_s + σ_a are per metre at 100 % density; a density d
//!   scales σ_s and σ_a alike (`Medium::at_density`).
//! * The phase function is normalised over the sphere, ∫ p dω = 1, and
//!   depends on cos θ = ω_in · ω_out, the cosine between the light's
//!   propagation direction before and after scattering: g > 0 sends light
//!   on forward (theatre haze), g = 0 is isotropic.
//! * Haze fills an axis-aligned box (the patch's `box`, else the scene's
//!   bounds); outside it the air is clear.

use crate::scene::Scene;
use footlight_fixture::HazeSpec;
use glam::Vec3;
use std::f32::consts::PI;

/// A homogeneous haze in an axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Medium {
    /// Scattering coefficient σ_s per metre (at the density this medium is for).
    pub sigma_s: f32,
    /// Absorption coefficient σ_a per metre.
    pub sigma_a: f32,
    /// Henyey-Greenstein asymmetry, |g| < 1.
    pub g: f32,
    /// Box minimum corner.
    pub min: Vec3,
    /// Box maximum corner.
    pub max: Vec3,
    /// Multiple scattering: volume and surface photons where a build adds
    /// them ([`super::multiple`]: orders ≥ 2, surface light into the haze,
    /// haze light onto surfaces), the similarity relation on light paths
    /// (the beam's and the surfaces') where it does not (the live coarse stage and the moving
    /// camera's preview, [`Medium::sigma_t_light`]); off: single
    /// scattering only.
    pub multiple: bool,
}

/// Why a medium could not be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MediumError {
    /// σ_s or σ_a negative, NaN or infinite.
    #[error("haze coefficients must be finite and >= 0 (scattering {0}, absorption {1})")]
    Coefficients(f32, f32),
    /// |g| ≥ 1 or NaN.
    #[error("haze g {0} must be between -1 and 1 (exclusive)")]
    Asymmetry(f32),
    /// A box with zero or negative size on some axis, or non-finite corners.
    #[error("haze box {0} .. {1} must be finite with min < max on every axis")]
    Box(Vec3, Vec3),
}

impl Medium {
    /// A validated medium (the patch checks the same with file:line).
    pub fn new(sigma_s: f32, sigma_a: f32, g: f32, min: Vec3, max: Vec3) -> Result<Self, MediumError> {
        if !(sigma_s.is_finite() && sigma_s >= 0.0 && sigma_a.is_finite() && sigma_a >= 0.0) {
            return Err(MediumError::Coefficients(sigma_s, sigma_a));
        }
        if !(g.abs() < 1.0) {
            return Err(MediumError::Asymmetry(g));
        }
        if !(min.is_finite() && max.is_finite() && (max - min).cmpgt(Vec3::ZERO).all()) {
            return Err(MediumError::Box(min, max));
        }
        Ok(Self { sigma_s, sigma_a, g, min, max, multiple: false })
    }

    /// The medium of a patch's `[haze]` at 100 % density over `scene`
    /// (its bounds when the patch gives no box). `None` when neither gives
    /// a box of positive size (an empty or flat scene without `box`).
    pub fn from_spec(spec: &HazeSpec, scene: &Scene) -> Option<Self> {
        let (min, max) = spec.bounds.or_else(|| scene_bounds(scene))?;
        let m = Self::new(spec.scattering, spec.absorption, spec.g, min, max).ok()?;
        Some(Self { multiple: spec.multiple, ..m })
    }

    /// The same haze at density `d` (0-1 of the patch's; clamped, NaN → 0).
    pub fn at_density(&self, d: f32) -> Self {
        let d = clean_density(d);
        Self { sigma_s: self.sigma_s * d, sigma_a: self.sigma_a * d, ..*self }
    }

    /// σ_t = σ_s + σ_a: extinction along camera rays.
    pub fn sigma_t(&self) -> f32 {
        self.sigma_s + self.sigma_a
    }

    /// Extinction along light paths whose scattered light is not traced
    /// (see [`super::resolve::surface_medium`] for the surfaces). Single scattering: σ_t. With `multiple`, the similarity
    /// relation (van de Hulst; Wyman, Patterson
    /// and Hsu): light scattered into the forward lobe stays in the beam,
    /// so the beam decays with σ_t* = σ_a + (1 − g) σ_s (g < 0 counts as 0).
    pub fn sigma_t_light(&self) -> f32 {
        if self.multiple { self.sigma_a + (1.0 - self.g.max(0.0)) * self.sigma_s } else { self.sigma_t() }
    }

    /// True when the medium does nothing (σ_s = σ_a = 0).
    pub fn is_clear(&self) -> bool {
        self.sigma_t() <= 0.0
    }

    /// Henyey-Greenstein p(cos θ) = (1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2}),
    /// normalised over the sphere; cos θ between propagation directions.
    pub fn phase(&self, cos_theta: f32) -> f32 {
        hg(self.g, cos_theta)
    }

    /// The part (t0, t1) of the ray `origin + t·dir`, t in [0, `t_max`],
    /// inside the box (slab method), or `None`.
    pub fn clip(&self, origin: Vec3, dir: Vec3, t_max: f32) -> Option<(f32, f32)> {
        let (mut t0, mut t1) = (f32::NEG_INFINITY, f32::INFINITY);
        for axis in 0..3 {
            let (o, d, lo, hi) = (origin[axis], dir[axis], self.min[axis], self.max[axis]);
            if d == 0.0 || !d.is_finite() {
                // Parallel to this slab: inside it (faces included) or never.
                if o < lo || o > hi || o.is_nan() {
                    return None;
                }
                continue;
            }
            let (a, b) = ((lo - o) / d, (hi - o) / d);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
        let (t0, t1) = (t0.max(0.0), t1.min(t_max));
        (t1 > t0).then_some((t0, t1))
    }

    /// Length in metres of the segment a–b inside the box.
    pub fn length_inside(&self, a: Vec3, b: Vec3) -> f32 {
        let d = b - a;
        let len = d.length();
        if !(len > 0.0) || !len.is_finite() {
            return 0.0;
        }
        self.clip(a, d / len, len).map_or(0.0, |(t0, t1)| t1 - t0)
    }
}

/// Henyey-Greenstein phase function with asymmetry `g` (|g| < 1).
pub fn hg(g: f32, cos_theta: f32) -> f32 {
    let c = cos_theta.clamp(-1.0, 1.0);
    let denom = (1.0 + g * g - 2.0 * g * c).max(1e-12);
    (1.0 - g * g) / (4.0 * PI * denom * denom.sqrt())
}

/// A density in [0, 1]; NaN counts as 0 (no haze), never as a NaN pixel.
pub fn clean_density(d: f32) -> f32 {
    if d.is_nan() { 0.0 } else { d.clamp(0.0, 1.0) }
}

/// The axis-aligned bounds of a scene's triangles, if they have volume.
pub fn scene_bounds(scene: &Scene) -> Option<(Vec3, Vec3)> {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for p in scene.positions.iter().flatten() {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    ((hi - lo).cmpgt(Vec3::ZERO).all() && lo.is_finite() && hi.is_finite()).then_some((lo, hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hg_is_normalised_and_forward_for_positive_g() {
        for g in [-0.9f32, -0.3, 0.0, 0.5, 0.9] {
            // ∫ p dω = 2π ∫_{-1}^{1} p(μ) dμ, midpoint rule in μ.
            let n = 200_000;
            let sum: f64 = (0..n).map(|i| f64::from(hg(g, -1.0 + (i as f32 + 0.5) * 2.0 / n as f32))).sum();
            let total = sum * 2.0 / n as f64 * std::f64::consts::TAU;
            assert!((total - 1.0).abs() < 2e-3, "g {g}: {total}");
        }
        assert!(hg(0.7, 1.0) > hg(0.7, -1.0));
        assert!((hg(0.0, 0.3) - 1.0 / (4.0 * PI)).abs() < 1e-7);
    }

    #[test]
    fn box_clip_and_lengths() {
        let m = Medium::new(0.1, 0.0, 0.5, Vec3::ZERO, Vec3::ONE).unwrap();
        assert_eq!(m.clip(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, 10.0), Some((1.0, 2.0)));
        assert_eq!(m.clip(Vec3::new(0.5, 0.5, 0.5), Vec3::X, 10.0), Some((0.0, 0.5)));
        assert_eq!(m.clip(Vec3::new(-1.0, 2.0, 0.5), Vec3::X, 10.0), None);
        assert_eq!(m.clip(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, 1.5), Some((1.0, 1.5)));
        assert!((m.length_inside(Vec3::new(-1.0, -1.0, 0.5), Vec3::new(2.0, 2.0, 0.5)) - 2f32.sqrt()).abs() < 1e-6);
        assert_eq!(m.length_inside(Vec3::ZERO, Vec3::ZERO), 0.0);
        // A ray along a face plane counts as inside.
        assert_eq!(m.clip(Vec3::new(-1.0, 0.0, 0.0), Vec3::X, 10.0), Some((1.0, 2.0)));
    }

    #[test]
    fn bad_media_are_errors() {
        assert!(Medium::new(-0.1, 0.0, 0.0, Vec3::ZERO, Vec3::ONE).is_err());
        assert!(Medium::new(f32::NAN, 0.0, 0.0, Vec3::ZERO, Vec3::ONE).is_err());
        assert!(Medium::new(0.1, f32::INFINITY, 0.0, Vec3::ZERO, Vec3::ONE).is_err());
        assert!(Medium::new(0.1, 0.0, 1.0, Vec3::ZERO, Vec3::ONE).is_err());
        assert!(Medium::new(0.1, 0.0, f32::NAN, Vec3::ZERO, Vec3::ONE).is_err());
        assert!(Medium::new(0.1, 0.0, 0.0, Vec3::ZERO, Vec3::new(1.0, 0.0, 1.0)).is_err());
        let m = Medium::new(0.1, 0.02, 0.8, Vec3::ZERO, Vec3::ONE).unwrap();
        assert_eq!(m.at_density(f32::NAN).sigma_t(), 0.0);
        assert_eq!(m.at_density(3.0), m);
        let ms = Medium { multiple: true, ..m };
        assert!((ms.sigma_t_light() - (0.02 + 0.2 * 0.1)).abs() < 1e-7);
    }
}
