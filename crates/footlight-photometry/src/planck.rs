//! Planck's law: the spectrum of a blackbody at temperature T.
//!
//! Tungsten-halogen and (as the paper models them) discharge lamps are
//! evaluated on the Planckian locus at their correlated colour temperature
//! (Vierjahn 2010, section 3.2: "the Planckian locus has to be evaluated for
//! the respective color temperatures").
//!
//! L(λ, T) = c1 / (λ⁵ (exp(c2 / (λT)) − 1)) with the CODATA 2018 radiation
//! constants. Footlight only needs relative spectra (every colour is
//! normalised afterwards), so [`relative_radiance`] works in the log domain
//! and stays finite for any temperature: a 300 K "blackbody" is a vanishing
//! but well-defined red, never 0/0.

/// First radiation constant for spectral radiance, 2hc² in W·m²·sr⁻¹ (CODATA 2018).
pub const C1L: f64 = 1.191_042_972e-16;
/// Second radiation constant hc/k in m·K (CODATA 2018, exact in the 2019 SI).
pub const C2: f64 = 1.438_776_877e-2;
/// Wavelength at which [`relative_radiance`] is 1, in nm.
pub const REFERENCE_NM: f64 = 560.0;

/// Spectral radiance in W·sr⁻¹·m⁻³ of a blackbody at `t_k` kelvin and
/// wavelength `nm`. Zero for non-positive or non-finite inputs; may
/// underflow to zero for very cold bodies (use [`relative_radiance`]).
pub fn spectral_radiance(nm: f64, t_k: f64) -> f64 {
    if !(nm > 0.0 && t_k > 0.0 && nm.is_finite() && t_k.is_finite()) {
        return 0.0;
    }
    let l = nm * 1e-9;
    let d = l.powi(5) * (C2 / (l * t_k)).exp_m1();
    if d > 0.0 && d.is_finite() { C1L / d } else { 0.0 }
}

/// Spectral radiance relative to its value at 560 nm: L(λ, T) / L(560 nm, T).
/// Zero for non-positive or non-finite inputs. Always finite: the ratio is
/// capped at e⁷⁰⁰, which only bodies colder than ~15 K reach in 360-830 nm.
pub fn relative_radiance(nm: f64, t_k: f64) -> f64 {
    if !(nm > 0.0 && t_k > 0.0 && nm.is_finite() && t_k.is_finite()) {
        return 0.0;
    }
    (ln_radiance(nm, t_k) - ln_radiance(REFERENCE_NM, t_k)).min(700.0).exp()
}

/// ln L(λ, T) up to the constant ln c1 (λ in nm).
fn ln_radiance(nm: f64, t_k: f64) -> f64 {
    let l = nm * 1e-9;
    -5.0 * l.ln() - ln_exp_m1(C2 / (l * t_k))
}

/// ln(eˣ − 1) for x > 0 without overflow.
fn ln_exp_m1(x: f64) -> f64 {
    if x > 30.0 { x + (-(-x).exp()).ln_1p() } else { x.exp_m1().ln() }
}

/// The relative spectrum of a blackbody at `t_k` kelvin as a function of
/// wavelength in nm (1 at 560 nm), ready for [`crate::cie::spectrum_to_xyz`].
pub fn blackbody(t_k: f32) -> impl Fn(f32) -> f32 + Copy {
    move |nm| relative_radiance(f64::from(nm), f64::from(t_k)) as f32
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::cie::spectrum_to_xyz;

    fn xy(t: f32) -> (f32, f32) {
        let c = spectrum_to_xyz(blackbody(t));
        let s = c.x + c.y + c.z;
        (c.x / s, c.y / s)
    }

    /// Kim, Kang et al. (2002), "Design of advanced color temperature control
    /// system for HDTV applications", J. Korean Phys. Soc. 41(6): cubic-spline
    /// fit of the CIE 1931 Planckian locus, 1667-25000 K (as quoted in
    /// Wikipedia's "Planckian locus"). Independent of this crate's tables.
    pub(crate) fn kim_locus(t: f64) -> (f64, f64) {
        let (t2, t3) = (t * t, t * t * t);
        let x = if t >= 4000.0 {
            -3.025_846_9e9 / t3 + 2.107_037_9e6 / t2 + 0.222_634_7e3 / t + 0.240_390
        } else {
            -0.266_123_9e9 / t3 - 0.234_358_9e6 / t2 + 0.877_695_6e3 / t + 0.179_910
        };
        let (x2, x3) = (x * x, x * x * x);
        let y = if t >= 4000.0 {
            3.081_758_0 * x3 - 5.873_386_70 * x2 + 3.751_129_97 * x - 0.370_014_83
        } else if t >= 2222.0 {
            -0.954_947_6 * x3 - 1.374_185_93 * x2 + 2.091_370_15 * x - 0.167_488_67
        } else {
            -1.106_381_4 * x3 - 1.348_110_20 * x2 + 2.185_558_32 * x - 0.202_196_83
        };
        (x, y)
    }

    #[test]
    fn planckian_locus_matches_published_chromaticities() {
        // Published CIE 1931 xy on the Planckian locus: illuminant A (2856 K)
        // from CIE 015:2018 table T.3 (0.44757, 0.40745); 3200 K (0.4234,
        // 0.3990) and 6500 K (0.3135, 0.3237) as quoted in
        // /work/shared/notes/dependencies.md; 6000 K (0.3220, 0.3318) from the
        // Kim et al. (2002) locus fit, which we also check on a range.
        for (t, x, y) in
            [(2856.0, 0.44757, 0.40745), (3200.0, 0.4234, 0.3990), (6000.0, 0.3220, 0.3318), (6500.0, 0.3135, 0.3237)]
        {
            let (cx, cy) = xy(t);
            assert!((cx - x).abs() < 1e-3 && (cy - y).abs() < 1e-3, "{t} K: ({cx}, {cy}) vs ({x}, {y})");
        }
        for t in (1700..=25000).step_by(100) {
            let (cx, cy) = xy(t as f32);
            let (kx, ky) = kim_locus(f64::from(t));
            let d = (f64::from(cx) - kx).hypot(f64::from(cy) - ky);
            assert!(d < 1e-3, "{t} K: ({cx}, {cy}) vs Kim ({kx}, {ky})");
        }
    }

    #[test]
    fn wien_peak_and_absolute_radiance() {
        // Wien's displacement law: λ_max = 2.897771955e-3 m·K / T.
        let t = 5800.0;
        let peak = (300..1200)
            .max_by(|&a, &b| spectral_radiance(a as f64, t).partial_cmp(&spectral_radiance(b as f64, t)).unwrap());
        assert_eq!(peak, Some((2.897_771_955e-3 / t * 1e9).round() as i32));
        // L(500 nm, 3000 K) = 2hc² / (λ⁵ (e^(c2/λT) − 1)) = 2.6027e11 W sr⁻¹ m⁻³ (evaluated separately).
        let l = spectral_radiance(500.0, 3000.0);
        assert!((l / 2.6027e11 - 1.0).abs() < 1e-4, "{l}");
    }

    #[test]
    fn relative_radiance_is_finite_for_cold_and_hot_bodies() {
        for t in [1.0, 50.0, 300.0, 1000.0, 3200.0, 1e5, 1e9] {
            for nm in [360.0, 560.0, 830.0] {
                let r = relative_radiance(nm, t);
                assert!(r.is_finite() && r >= 0.0, "{t} K {nm} nm: {r}");
            }
            assert_eq!(relative_radiance(560.0, t), 1.0);
        }
        assert_eq!(relative_radiance(500.0, 0.0), 0.0);
        assert_eq!(relative_radiance(500.0, f64::NAN), 0.0);
        assert_eq!(spectral_radiance(500.0, -1.0), 0.0);
    }
}
