//! k_i of eq. 4: lamp colour through the gel, dimmer and intensity.
//!
//! Vierjahn 2010, eq. 4: ε_i = c_F c_I f_ε v Î ε̄₀ = k_i f_ε ε̄₀, with
//! k_i = c_F ⊙ c_I · v · Î. [`colour()`] gives c_F ⊙ c_I directly: the linear-sRGB
//! colour of the lamp's spectrum times the gel's transmission, relative to
//! the unfiltered lamp's luminance. Its Y is the gel's luminous
//! transmittance for that lamp at that dimmer level (a gel also dims), times
//! the lamp's own mix factor (see [`crate::lamp`]). c_F alone, as the paper
//! names it, is [`filter_factor`].
//!
//! Everything here reads precomputed tables ([`crate::response`]): about
//! 50-95 ns per call on the 2-core development machine (`examples/measure.rs`),
//! so 600 lights cost ~35 µs per display frame. [`colour_exact`] integrates
//! the spectra instead (~27 µs per call) and is the reference the tables are
//! tested against (largest difference 1.3e-5 in linear sRGB, lamp white Y = 1).

use crate::cie::sampled_to_xyz;
use crate::gel::{Gel, GelMix};
use crate::lamp::Lamp;
use crate::response::Response;
use crate::spectrum::Sampled;
use crate::srgb;
use crate::white_balance::WhiteBalance;
use glam::Vec3;

/// c_F ⊙ c_I: colour of `lamp` at dimmer `v` through `gel` (or open), linear
/// sRGB, Y = luminous transmittance × the lamp's own Y. Black at v = 0;
/// never negative or NaN (out-of-gamut colours are desaturated at equal
/// white-balanced luminance toward the 3200 K white, see `fit`).
pub fn colour(lamp: &Lamp, v: f32, gel: Option<&Gel>) -> Vec3 {
    colour_mix(lamp, v, &GelMix::single(gel))
}

/// [`colour()`] through a mix of two filters (a half-scrolled colour frame):
/// linear in the transmission spectrum, so the two frames' XYZ mix by area.
pub fn colour_mix(lamp: &Lamp, v: f32, mix: &GelMix) -> Vec3 {
    let f = if mix.f > 0.0 { mix.f.min(1.0) } else { 0.0 };
    let mut xyz = lamp.xyz_through(v, response(mix.a));
    if f > 0.0 {
        xyz = xyz * (1.0 - f) + lamp.xyz_through(v, response(mix.b)) * f;
    }
    fit(srgb::xyz_to_linear_srgb(xyz))
}

/// Brings an out-of-gamut colour into sRGB *after* the stage's default white
/// balance (tungsten 3200 K at full neutral, [`WhiteBalance::default`]):
/// the fit desaturates toward the balanced display's white, so a saturated
/// gel keeps the hue it shows on the balanced picture (issue 13: fitting
/// before the balance showed LEE 106 on tungsten with blue at 0.21 × red).
fn fit(rgb: Vec3) -> Vec3 {
    static GAINS: std::sync::OnceLock<Vec3> = std::sync::OnceLock::new();
    srgb::fit_gamut_balanced(rgb, *GAINS.get_or_init(|| WhiteBalance::default().gains))
}

/// The precomputed response of a filter slot (`None`: open beam).
fn response(gel: Option<&Gel>) -> &Response {
    gel.map_or(Response::open(), Gel::response)
}

/// k_i of eq. 4: c_F ⊙ c_I · v · Î, the RGB weight of light i's unit-intensity
/// buffer (`intensity_cd` = Î in candela; non-finite or negative → black).
pub fn k(lamp: &Lamp, v: f32, mix: &GelMix, intensity_cd: f32) -> Vec3 {
    let v = if v > 0.0 { v.min(1.0) } else { 0.0 };
    let i = if intensity_cd > 0.0 && intensity_cd.is_finite() { intensity_cd } else { 0.0 };
    colour_mix(lamp, v, mix) * (v * i) // Vierjahn 2010, eq. (4)
}

/// c_F of eq. 4: the gel's colour relative to the unfiltered lamp, per
/// channel (filtered / unfiltered). Channels where the unfiltered lamp is
/// below 1e-6 give 0. Renderers should prefer [`colour()`], which is the
/// product c_F ⊙ c_I without the division.
pub fn filter_factor(lamp: &Lamp, v: f32, gel: Option<&Gel>) -> Vec3 {
    let c_i = lamp.colour(v);
    let c = colour(lamp, v, gel);
    Vec3::select(c_i.cmpgt(Vec3::splat(1e-6)), c / c_i.max(Vec3::splat(1e-6)), Vec3::ZERO)
}

/// [`colour()`] by direct spectral integration of lamp × `transmission` (no
/// tables). Slow (allocates, ~2000 multiply-adds); the reference for tests
/// and for measuring the tables' error.
pub fn colour_exact(lamp: &Lamp, v: f32, transmission: Option<&Sampled>) -> Vec3 {
    let Some(spectrum) = lamp.spectrum(v) else {
        return Vec3::ZERO;
    };
    let filtered = match transmission {
        Some(t) => spectrum.mul(t),
        None => spectrum,
    };
    fit(srgb::xyz_to_linear_srgb(sampled_to_xyz(&filtered).as_vec3()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dimmer::DimmerCurve;
    use crate::gel::tests::library;
    use crate::lamp::tests::every_kind;
    use crate::srgb::luminance;
    use proptest::prelude::*;

    #[test]
    fn tables_match_exact_integration_for_every_lamp_and_gel() {
        let mut worst: f32 = 0.0;
        for (_, g) in library().iter() {
            for lamp in every_kind() {
                for v in [1.0, 0.5, 0.1, 0.01, 1e-3, 1e-5] {
                    let fast = colour(&lamp, v, Some(g));
                    let exact = colour_exact(&lamp, v, Some(g.sampled()));
                    worst = worst.max((fast - exact).abs().max_element());
                }
            }
        }
        assert!(worst < 1e-4, "worst |table − exact| = {worst}");
    }

    #[test]
    fn every_dmx_level_on_every_curve_is_finite_and_non_negative() {
        let curves = [DimmerCurve::Linear, DimmerCurve::SquareLaw, DimmerCurve::Theatre];
        for lamp in every_kind() {
            for curve in curves {
                for d in 0..=255u8 {
                    let v = curve.from_dmx8(d);
                    for (_, g) in library().iter() {
                        let c = colour(&lamp, v, Some(g));
                        assert!(c.is_finite() && c.min_element() >= 0.0, "{lamp:?} {curve:?} {d} {}: {c}", g.id);
                    }
                    if d == 0 {
                        assert_eq!(colour(&lamp, v, None), Vec3::ZERO);
                    }
                }
            }
        }
    }

    #[test]
    fn k_is_colour_times_dimmer_times_intensity() {
        let lamp = Lamp::tungsten();
        let g = library().get(library().find("L201").unwrap());
        let mix = GelMix::single(g);
        let k_i = k(&lamp, 0.5, &mix, 1000.0);
        assert!((k_i - colour(&lamp, 0.5, g) * 500.0).abs().max_element() < 1e-3, "{k_i}");
        assert_eq!(k(&lamp, 0.0, &mix, 1000.0), Vec3::ZERO);
        assert_eq!(k(&lamp, 0.5, &mix, f32::NAN), Vec3::ZERO);
        assert_eq!(k(&lamp, 0.5, &mix, -3.0), Vec3::ZERO);
        // Open beam, full: k = c_I · Î with luminance Î.
        assert!((luminance(k(&lamp, 1.0, &GelMix::OPEN, 1000.0)) - 1000.0).abs() < 0.1);
    }

    /// Independent reference for a gel on 3200 K tungsten: Planck's law and
    /// the CIE 1931 functions summed here at 1 nm, the sRGB matrix, the
    /// tungsten white balance, and the gamut fit done after the balance by
    /// hand. Returns the balanced colour relative to its largest channel.
    fn balanced_by_quadrature(transmission: &Sampled) -> Vec3 {
        let planck = |nm: f64| {
            let l = nm * 1e-9;
            1.0 / (l.powi(5) * ((1.438_776_877e-2 / (l * 3200.0)).exp() - 1.0))
        };
        let mut white = glam::DVec3::ZERO;
        let mut gel = glam::DVec3::ZERO;
        for nm in 360..=830 {
            let (cmf, b) = (crate::cie::cmf_f64(f64::from(nm)), planck(f64::from(nm)));
            white += cmf * b;
            gel += cmf * b * transmission.at(f64::from(nm));
        }
        let to_rgb = |xyz: glam::DVec3| {
            let m = [
                [3.2406255, -1.537208, -0.4986286],
                [-0.9689307, 1.8757561, 0.0415175],
                [0.0557101, -0.2040211, 1.0569959],
            ];
            glam::DVec3::new(
                m[0][0] * xyz.x + m[0][1] * xyz.y + m[0][2] * xyz.z,
                m[1][0] * xyz.x + m[1][1] * xyz.y + m[1][2] * xyz.z,
                m[2][0] * xyz.x + m[2][1] * xyz.y + m[2][2] * xyz.z,
            )
        };
        let (w, g) = (to_rgb(white), to_rgb(gel));
        let balanced = g / w; // tungsten white -> (1, 1, 1) up to a common scale
        let y = 0.2126 * balanced.x + 0.7152 * balanced.y + 0.0722 * balanced.z;
        let low = balanced.min_element();
        let fitted = if low < 0.0 {
            glam::DVec3::splat(y) + (balanced - glam::DVec3::splat(y)) * (y / (y - low))
        } else {
            balanced
        };
        (fitted / fitted.max_element()).as_vec3()
    }

    #[test]
    fn saturated_gels_keep_their_hue_after_white_balance() {
        // Issue 13.6: LEE 106 (primary red) and 119 (dark blue) on 3200 K tungsten,
        // as the balanced display shows them, against the quadrature above.
        let gains = WhiteBalance::default().gains;
        for id in ["L106", "L119"] {
            let g = library().get(library().find(id).unwrap()).unwrap();
            let shown = colour(&Lamp::tungsten(), 1.0, Some(g)) * gains;
            let shown = shown / shown.max_element();
            let want = balanced_by_quadrature(g.sampled());
            eprintln!("{id}: balanced, relative to the largest channel: {shown} (quadrature {want})");
            assert!((shown - want).abs().max_element() < 2e-3, "{id}: shown {shown}, quadrature {want}");
        }
        // Red stays red: little blue once balanced (fitting before the balance gave 0.21).
        let red = colour(&Lamp::tungsten(), 1.0, library().get(library().find("L106").unwrap())) * gains;
        assert!(red.z < 0.06 * red.x, "{red}");
    }

    fn any_lamp() -> impl Strategy<Value = Lamp> {
        prop_oneof![
            (1000.0f32..12_000.0).prop_map(|t| Lamp::Tungsten { cct_full: t }),
            (2000.0f32..25_000.0).prop_map(|t| Lamp::Discharge { cct: t }),
            (0.0f32..=1.0, 0.0f32..=1.0, 0.0f32..=1.0, 2500.0f32..9000.0).prop_map(|(c, m, y, t)| Lamp::Cmy {
                cct: t,
                cyan: c,
                magenta: m,
                yellow: y,
                filters: None
            }),
            proptest::collection::vec((0.0f32..0.8, 0.0f32..0.9, 0.0f32..=1.0, 0.0f32..=1.0), 1..6).prop_map(|es| {
                Lamp::Led {
                    emitters: es
                        .into_iter()
                        .map(|(x, y, share, level)| {
                            let mut e =
                                crate::lamp::Emitter::new("e", crate::lamp::Chroma::Xy(glam::Vec2::new(x, y)), share);
                            e.level = level;
                            e
                        })
                        .collect(),
                }
            }),
        ]
    }

    proptest! {
        // A fixed seed, so every run tries the same cases (every RNG is
        // seeded); proptest's own `PROPTEST_RNG_SEED=<n>` tries another by hand.
        #![proptest_config(match ProptestConfig::default() {
            c if c.rng_seed == proptest::test_runner::RngSeed::Random => {
                ProptestConfig { rng_seed: proptest::test_runner::RngSeed::Fixed(0x6c61_6d70), ..c }
            }
            c => c,
        })]

        #[test]
        fn colours_are_finite_and_non_negative(
            lamp in any_lamp(),
            dmx in any::<u16>(),
            curve in prop_oneof![Just(DimmerCurve::Linear), Just(DimmerCurve::SquareLaw), Just(DimmerCurve::Theatre)],
            gel in 0usize..100,
            frame in -1.0f32..5.0,
        ) {
            let lib = library();
            let v = curve.from_dmx16(dmx);
            let g = lib.get(crate::gel::GelId((gel % lib.len()) as u32));
            let c = colour(&lamp, v, g);
            prop_assert!(c.is_finite() && c.min_element() >= 0.0, "{:?}", c);
            let last = g.and_then(|g| lib.find(&g.id));
            let s = crate::gel::Scroller { frames: vec![None, lib.find("L201"), lib.find("L106"), last] };
            let mix = s.at(lib, frame).unwrap();
            let k_i = k(&lamp, v, &mix, 2500.0);
            prop_assert!(k_i.is_finite() && k_i.min_element() >= 0.0, "{:?}", k_i);
            if v == 0.0 {
                prop_assert_eq!(k_i, Vec3::ZERO);
            }
        }
    }
}
