//! CIE 1931 2° standard observer: colour-matching functions and spectrum → XYZ.
//!
//! The paper turns a lamp's spectrum into a colour "with suitable color
//! matching functions \[CIE09\]" (Vierjahn 2010, section 3.2). The table is the
//! CIE 1931 2° observer x̄(λ), ȳ(λ), z̄(λ) at 1 nm from 360 to 830 nm, as the
//! CIE publishes it (CIE 018:2019 / ISO 11664-1, table "CIE_xyz_1931_2deg").
//! It is generated into `cie/cmf_1931_2deg.rs` by `tools/extract_cmf.py` from
//! the PyPI package colour-science 0.4.7, which ships the same table; the
//! generated file names the wheel's sha256.
//!
//! Integrals are plain 1 nm sums, X = Σ S(λ) x̄(λ) · 1 nm, the CIE's own
//! recommended practice, so an equal-energy spectrum S = 1 has Y = 106.857.

mod cmf_1931_2deg;

use crate::spectrum::{LAMBDA_MIN_NM, SAMPLES, Sampled, wavelength};
use cmf_1931_2deg::CMF_1931_2DEG;
use glam::{DVec3, Vec3};

/// x̄, ȳ, z̄ at `nm` (linear between the 1 nm table values, zero outside
/// 360-830 nm). At whole nanometres this is the table value itself.
pub fn cmf(nm: f32) -> Vec3 {
    cmf_f64(f64::from(nm)).as_vec3()
}

/// [`cmf`] in double precision.
pub fn cmf_f64(nm: f64) -> DVec3 {
    let s = nm - f64::from(LAMBDA_MIN_NM);
    if !(0.0..=(SAMPLES - 1) as f64).contains(&s) {
        return DVec3::ZERO;
    }
    let i = (s.floor() as usize).min(SAMPLES - 2);
    let f = s - i as f64;
    DVec3::from(CMF_1931_2DEG[i]) * (1.0 - f) + DVec3::from(CMF_1931_2DEG[i + 1]) * f
}

/// x̄, ȳ, z̄ at grid sample `i` (360 + i nm).
pub(crate) fn cmf_sample(i: usize) -> DVec3 {
    DVec3::from(CMF_1931_2DEG[i])
}

/// Tristimulus XYZ of the spectrum `f(nm)`: Σ f(λ) (x̄, ȳ, z̄)(λ) over
/// λ = 360, 361, …, 830 nm (Δλ = 1 nm, so equal energy gives Y ≈ 106.86).
/// Non-finite values of `f` count as zero.
pub fn spectrum_to_xyz(f: impl Fn(f32) -> f32) -> Vec3 {
    let mut xyz = DVec3::ZERO;
    for i in 0..SAMPLES {
        let s = f64::from(f(wavelength(i) as f32));
        if s.is_finite() {
            xyz += cmf_sample(i) * s;
        }
    }
    xyz.as_vec3()
}

/// Tristimulus XYZ of a sampled spectrum (the same 1 nm sum as
/// [`spectrum_to_xyz`], in double precision).
pub fn sampled_to_xyz(s: &Sampled) -> DVec3 {
    sampled_to_xyz_range(s, 0..SAMPLES)
}

/// XYZ of the product `a · b` sample by sample (light through a filter),
/// without allocating the product.
pub(crate) fn product_to_xyz(a: &Sampled, b: &Sampled) -> DVec3 {
    let mut xyz = DVec3::ZERO;
    for (i, (x, y)) in a.values().iter().zip(b.values().iter()).enumerate() {
        xyz += cmf_sample(i) * (x * y);
    }
    xyz
}

/// XYZ of the part of `s` on grid samples `range` (used to split a spectrum
/// into wavelength bands that CMY flags act on separately).
pub(crate) fn sampled_to_xyz_range(s: &Sampled, range: std::ops::Range<usize>) -> DVec3 {
    let mut xyz = DVec3::ZERO;
    for i in range {
        xyz += cmf_sample(i) * s.values()[i];
    }
    xyz
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_energy_sums_to_the_published_106_857() {
        let e = spectrum_to_xyz(|_| 1.0);
        // CIE 1931 2°, 1 nm, 360-830: Σȳ = 106.8566 (CIE 015:2018 uses k = 100/Σ S ȳ).
        assert!((e.y - 106.857).abs() < 0.01, "{e}");
        let s = e.x + e.y + e.z;
        assert!((e.x / s - 1.0 / 3.0).abs() < 1e-4 && (e.y / s - 1.0 / 3.0).abs() < 1e-4, "{e}");
    }

    #[test]
    fn table_holds_the_published_peaks() {
        // Spot values of the CIE 1931 2° table (CIE 018:2019): ȳ(555) = 1.0,
        // x̄(600) = 1.0622, z̄(445) = 1.78.
        assert!((cmf(555.0).y - 1.0).abs() < 1e-6);
        assert!((cmf(600.0).x - 1.0622).abs() < 1e-4);
        assert!((cmf(445.0).z - 1.78).abs() < 1e-2);
        assert_eq!(cmf(359.0), Vec3::ZERO);
        assert_eq!(cmf(831.0), Vec3::ZERO);
        assert_eq!(cmf(f32::NAN), Vec3::ZERO);
        assert!(cmf(830.0).y > 0.0);
    }

    #[test]
    fn sampled_and_closure_sums_agree() {
        let s = Sampled::from_fn(|nm| (nm / 500.0).powi(2));
        let a = sampled_to_xyz(&s).as_vec3();
        let b = spectrum_to_xyz(|nm| (nm / 500.0).powi(2));
        assert!((a - b).abs().max_element() < 1e-4 * a.y, "{a} {b}");
    }
}
