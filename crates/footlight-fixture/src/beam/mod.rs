//! Emission patterns f_ε with peak 1 (Vierjahn 2010, section 3.2, eq. 4).
//!
//! "Typically two types of fixtures are used in the theatres: Profile or zoom
//! spots [...] and fresnell or PC spots." The first family is a cone with a
//! penumbra ([`SpotBeam`]); the second is a pair of "spot" and "flood"
//! patterns, each a piecewise cubic Hermite polynomial of the angle, mixed by
//! the focus value ([`HermiteBeam`]). Fixtures that ship measured photometry
//! (IES LM-63, EULUMDAT) become a [`MeasuredBeam`], a table over C-planes and
//! γ angles.
//!
//! Every pattern takes a unit direction in the light's local frame (beam
//! along −Z), returns a value in [0, 1] with peak 1, is finite everywhere
//! and is exactly zero outside its cut-off cone ([`Beam::cos_cutoff`]).
//! [`Beam`] is a closed enum dispatched by `match`, so the ray loop has no
//! virtual calls (STYLE.md §3).
//!
//! # Layout
//! * [`spot`]: cone + smoothstep penumbra; zoom, iris and edge focus.
//! * [`hermite`]: piecewise cubic Hermite patterns and their focus mix.
//! * [`measured`]: tabulated (C, γ) photometry.
//! * [`gate`]: a spot shaped by its gate: gobo, framing shutters, prism, frost.
//! * [`sampler`]: importance sampling of any pattern for photon emission.

pub mod gate;
pub mod hermite;
pub mod measured;
pub mod sampler;
pub mod spot;

pub use gate::{Blade, Facet, Gate, GoboImage, GoboLayer, ShapedBeam};
pub use hermite::{HermiteBeam, HermitePattern};
pub use measured::{MeasuredBeam, PhotometricTable};
pub use sampler::{BeamSample, BeamSampler};
pub use spot::SpotBeam;

use glam::Vec3;

/// The closed set of emission patterns. All take a unit direction in the
/// light's local frame (beam along −Z) and return a value in [0, 1].
#[derive(Clone, Debug, PartialEq)]
pub enum Beam {
    /// Cone with a smooth penumbra (profile and zoom spots, PARs, moving-head spots).
    Spot(SpotBeam),
    /// Fresnel/PC: spot and flood Hermite patterns mixed by focus.
    Hermite(HermiteBeam),
    /// Measured photometry (IES LM-63 or EULUMDAT), possibly asymmetric.
    Measured(MeasuredBeam),
    /// A spot through a gobo, framing shutters, prism and frost (boxed: it is large).
    Shaped(Box<ShapedBeam>),
}

impl Beam {
    /// f_ε(dir): relative intensity toward local direction `dir` (unit).
    pub fn pattern(&self, dir: Vec3) -> f32 {
        match self {
            Beam::Spot(s) => s.pattern(dir),
            Beam::Hermite(h) => h.pattern(dir),
            Beam::Measured(m) => m.pattern(dir),
            Beam::Shaped(s) => s.pattern(dir),
        }
    }

    /// Cosine of the widest angle from the axis with non-zero output; callers
    /// skip shading and photon emission outside it.
    pub fn cos_cutoff(&self) -> f32 {
        match self {
            Beam::Spot(s) => s.cos_outer,
            Beam::Hermite(h) => h.cos_cutoff(),
            Beam::Measured(m) => m.cos_cutoff(),
            Beam::Shaped(s) => s.cos_cutoff(),
        }
    }

    /// ∫ f_ε dω over the sphere (steradians): the flux in lumens of this
    /// pattern at a peak of 1 cd.
    pub fn solid_angle(&self) -> f32 {
        match self {
            Beam::Spot(s) => s.solid_angle(),
            Beam::Hermite(h) => h.solid_angle(),
            Beam::Measured(m) => m.solid_angle(),
            Beam::Shaped(s) => s.solid_angle(),
        }
    }

    /// True when the pattern depends only on the angle from the axis.
    pub fn is_symmetric(&self) -> bool {
        match self {
            Beam::Spot(_) | Beam::Hermite(_) => true,
            Beam::Measured(m) => m.is_symmetric(),
            Beam::Shaped(_) => false,
        }
    }

    /// Azimuths the photon sampler averages per polar sample: 1 for a
    /// symmetric pattern, more for a finely structured one (a gobo, prism
    /// facets off the axis).
    pub fn azimuth_samples(&self) -> usize {
        match self {
            Beam::Spot(_) | Beam::Hermite(_) => 1,
            Beam::Measured(m) if m.is_symmetric() => 1,
            Beam::Measured(_) => BeamSampler::AZIMUTHS,
            Beam::Shaped(_) => 8 * BeamSampler::AZIMUTHS,
        }
    }
}

/// 8-point Gauss–Legendre nodes on [−1, 1] (Abramowitz & Stegun, table 25.4).
const GL8_X: [f64; 4] =
    [0.183_434_642_495_649_8, 0.525_532_409_916_329, 0.796_666_477_413_626_7, 0.960_289_856_497_536_3];
/// The matching weights.
const GL8_W: [f64; 4] =
    [0.362_683_783_378_362, 0.313_706_645_877_887_3, 0.222_381_034_453_374_5, 0.101_228_536_290_376_3];

/// 2π ∫_a^b f(θ) sin θ dθ by 8-point Gauss–Legendre on each of `pieces`
/// equal sub-intervals: the solid-angle integral of a symmetric pattern
/// between two cone angles (radians). Exact to ~1e-12 for the smooth
/// piecewise cubics used here.
pub(crate) fn integrate_sin(a: f64, b: f64, pieces: usize, f: impl Fn(f64) -> f64) -> f64 {
    if !(b > a) {
        return 0.0;
    }
    let n = pieces.max(1);
    let h = (b - a) / n as f64;
    let mut sum = 0.0;
    for i in 0..n {
        let (lo, hi) = (a + h * i as f64, a + h * (i + 1) as f64);
        let (mid, half) = ((lo + hi) * 0.5, (hi - lo) * 0.5);
        for (x, w) in GL8_X.iter().zip(GL8_W) {
            for t in [mid - half * x, mid + half * x] {
                sum += w * half * f(t) * t.sin();
            }
        }
    }
    sum * std::f64::consts::TAU
}

/// Angle from the −Z axis (radians) of a local direction, robust to
/// non-unit input; 0 for a zero vector.
pub(crate) fn axis_angle(dir: Vec3) -> f32 {
    let len = dir.length();
    if !(len > 0.0) || !len.is_finite() {
        return 0.0;
    }
    (-dir.z / len).clamp(-1.0, 1.0).acos()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_integrates_the_sphere_and_a_cap() {
        let sphere = integrate_sin(0.0, std::f64::consts::PI, 4, |_| 1.0);
        assert!((sphere - 4.0 * std::f64::consts::PI).abs() < 1e-12, "{sphere}");
        let cap = integrate_sin(0.0, 0.3, 1, |_| 1.0);
        assert!((cap - std::f64::consts::TAU * (1.0 - 0.3f64.cos())).abs() < 1e-14);
        assert_eq!(integrate_sin(1.0, 1.0, 3, |_| 1.0), 0.0);
    }
}
