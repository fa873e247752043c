//! Colour from the GDTF's own spectra (issue 14, item 2): LED emitters that
//! carry a `<Measurement>` mix from their spectra, and CMY flags whose
//! `Filter` is measured filter by their transmission. The expected values
//! are integrated here, at 1 nm against the CIE 1931 2° table (data from
//! the photometry crate), from the same analytic spectra that
//! `tools/gen_gdtf_mvr.py` wrote into `Footlight@SpectralLed.gdtf` and
//! `Footlight@CmySpot.gdtf` (rounded to 6 decimals as the file holds them).

use super::gdtf;
use footlight_fixture::fixture_type::Attribute;
use footlight_fixture::{FixtureType, Manual};
use footlight_mvr::fixture_type;
use footlight_mvr::gdtf::Gdtf;
use footlight_photometry::Response;
use footlight_photometry::cie::cmf_f64;
use glam::DVec3;

/// Measured points (nm, value) as the file holds them (6 decimals).
fn points(step: usize, f: impl Fn(f64) -> f64) -> Vec<(f64, f64)> {
    (380..=780)
        .step_by(step)
        .map(|nm| {
            let nm = f64::from(nm);
            (nm, format!("{:.6}", f(nm)).parse().unwrap())
        })
        .collect()
}

/// Linear interpolation between points; `hold` keeps the end values outside
/// the measured range (filters), otherwise zero there (light sources).
fn interp(p: &[(f64, f64)], nm: f64, hold: bool) -> f64 {
    if nm < p[0].0 {
        return if hold { p[0].1 } else { 0.0 };
    }
    if nm > p[p.len() - 1].0 {
        return if hold { p[p.len() - 1].1 } else { 0.0 };
    }
    let i = p.iter().position(|q| q.0 >= nm).unwrap();
    if i == 0 {
        return p[0].1;
    }
    let ((x0, y0), (x1, y1)) = (p[i - 1], p[i]);
    y0 + (y1 - y0) * (nm - x0) / (x1 - x0)
}

/// Σ S(λ) (x̄, ȳ, z̄)(λ) over 360..830 nm at 1 nm.
fn integrate(s: impl Fn(f64) -> f64) -> DVec3 {
    (360..=830).map(|nm| cmf_f64(f64::from(nm)) * s(f64::from(nm))).sum()
}

fn xy(v: DVec3) -> (f64, f64) {
    let s = v.x + v.y + v.z;
    (v.x / s, v.y / s)
}

/// Gaussian components (weight, peak nm, FWHM nm) of a measured emitter.
type Lines = Vec<(f64, f64, f64)>;

fn gauss(comps: &[(f64, f64, f64)]) -> impl Fn(f64) -> f64 + '_ {
    move |nm| comps.iter().map(|(w, p, f)| w * (-0.5 * ((nm - p) / (f / 2.3548)).powi(2)).exp()).sum()
}

/// XYZ of the fixture type's lamp at `dmx` (offsets from 0), relative to its
/// full white (Y = 1), before any gamut mapping.
fn xyz_at(ty: &FixtureType, dmx: &[u8]) -> DVec3 {
    let state = ty.decode(&ty.modes[0], &Manual::default(), &|o| dmx.get(usize::from(o)).copied().unwrap_or(0));
    ty.lamp_for(&state).xyz_through(1.0, Response::open()).as_dvec3()
}

#[test]
fn spectral_emitters_mix_from_their_measured_spectra() {
    let (ty, warnings) = fixture_type(&Gdtf::open(&gdtf("SpectralLed")).unwrap()).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(ty.mix_names, ["coloradd_r", "coloradd_g", "coloradd_b", "coloradd_w"]);
    // The generator's emitters: (Color's Y = luminous share, Gaussian components).
    let emitters: [(f64, Lines); 4] = [
        (12.5, vec![(1.0, 630.0, 18.0)]),
        (37.5, vec![(1.0, 525.0, 32.0)]),
        (5.0, vec![(1.0, 455.0, 20.0)]),
        (50.0, vec![(0.35, 450.0, 20.0), (1.0, 570.0, 110.0)]),
    ];
    // Each emitter's XYZ per unit luminance, integrated here.
    let unit: Vec<DVec3> = emitters
        .iter()
        .map(|(_, c)| {
            let p = points(2, gauss(c));
            let v = integrate(|nm| interp(&p, nm, false));
            v / v.y
        })
        .collect();
    let total: f64 = emitters.iter().map(|e| e.0).sum();
    let expect = |levels: [f64; 4]| -> DVec3 { (0..4).map(|i| unit[i] * (emitters[i].0 * levels[i] / total)).sum() };
    let cases: [([u8; 5], [f64; 4]); 6] = [
        ([255, 255, 255, 255, 255], [1.0; 4]),
        ([255, 255, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]),
        ([255, 0, 255, 0, 0], [0.0, 1.0, 0.0, 0.0]),
        ([255, 0, 0, 255, 0], [0.0, 0.0, 1.0, 0.0]),
        ([255, 0, 0, 0, 255], [0.0, 0.0, 0.0, 1.0]),
        ([255, 255, 0, 128, 0], [1.0, 0.0, 128.0 / 255.0, 0.0]),
    ];
    for (dmx, levels) in cases {
        let got = xyz_at(&ty, &dmx);
        let want = expect(levels);
        let ((gx, gy), (wx, wy)) = (xy(got), xy(want));
        assert!((gx - wx).abs() < 2e-5 && (gy - wy).abs() < 2e-5, "{dmx:?}: xy ({gx}, {gy}) vs ({wx}, {wy})");
        assert!((got.y / want.y - 1.0).abs() < 1e-4, "{dmx:?}: Y {} vs {}", got.y, want.y);
    }
    // Full white is the lamp's own white: Y = 1. Green's Physical-50 measurement (515 nm)
    // is not the one used: green alone sits at the 525 nm line's chromaticity (checked above),
    // far from the 515 nm line's.
    assert!((xyz_at(&ty, &[255; 5]).y - 1.0).abs() < 1e-5);
    let p515 = points(2, gauss(&[(1.0, 515.0, 32.0)]));
    let (x515, _) = xy(integrate(|nm| interp(&p515, nm, false)));
    assert!((x515 - xy(unit[1]).0).abs() > 0.02);
    // Nor is the file's nominal xy: the white's spectrum is far from (0.3127, 0.3290).
    let (wx, wy) = xy(unit[3]);
    assert!((wx - 0.3127).hypot(wy - 0.3290) > 0.01, "({wx}, {wy})");
    // A mix channel is decoded as Mix(i) in the order of the file's channels.
    assert_eq!(ty.modes[0].channel(Attribute::Mix(3)).map(|c| c.offset), Some(4));
}

#[test]
fn cmy_flags_filter_by_their_measured_transmission() {
    let (ty, warnings) = fixture_type(&Gdtf::open(&gdtf("CmySpot")).unwrap()).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    // The generator's flags (full insertion), sampled every 5 nm as the file holds them.
    let flags: [Vec<(f64, f64)>; 3] = [
        points(5, |nm| 0.03 + 0.92 / (1.0 + ((nm - 585.0) / 10.0).exp())),
        points(5, |nm| 1.0 - 0.88 * (-0.5 * ((nm - 540.0) / 25.0).powi(2)).exp()),
        points(5, |nm| 0.02 + 0.93 / (1.0 + ((500.0 - nm) / 9.0).exp())),
    ];
    // Planck's law for the 6000 K discharge lamp, written here.
    let planck = |nm: f64| {
        let l = nm * 1e-9;
        1.0 / (l.powi(5) * ((1.438_776_877e-2 / (l * 6000.0)).exp() - 1.0))
    };
    let white = integrate(planck);
    for dmx in [
        [255u8, 0, 0, 0],
        [255, 255, 0, 0],
        [255, 0, 255, 0],
        [255, 0, 0, 255],
        [255, 128, 255, 0],
        [255, 64, 191, 255],
    ] {
        let state = ty.decode(&ty.modes[0], &Manual::default(), &|o| dmx[usize::from(o)]);
        // A flag inserted by c covers c of the beam: it passes (1 − c) + c·T(λ); in series.
        let c: Vec<f64> = (0..3).map(|i| f64::from(state.mix[i])).collect();
        for i in 0..3 {
            assert!((c[i] - f64::from(dmx[i + 1]) / 255.0).abs() < 1e-6, "{dmx:?}: insertion {i} = {}", c[i]);
        }
        let want = integrate(|nm| {
            planck(nm) * (0..3).map(|i| 1.0 - c[i] + c[i] * interp(&flags[i], nm, true)).product::<f64>()
        }) / white.y;
        let got = xyz_at(&ty, &dmx);
        let ((gx, gy), (wx, wy)) = (xy(got), xy(want));
        assert!((gx - wx).abs() < 1e-4 && (gy - wy).abs() < 1e-4, "{dmx:?}: xy ({gx}, {gy}) vs ({wx}, {wy})");
        assert!((got.y - want.y).abs() < 1e-4 * want.y.max(0.01), "{dmx:?}: Y {} vs {}", got.y, want.y);
    }
    // The measured cyan flag is not the ideal band model: it leaks 3 % of the red.
    let cyan = xyz_at(&ty, &[255, 255, 0, 0]);
    let spot = fixture_type(&Gdtf::open(&gdtf("Spot")).unwrap()).unwrap().0;
    assert!(matches!(spot.lamp, footlight_photometry::Lamp::Cmy { filters: None, .. }), "Spot keeps the band model");
    let ideal = footlight_photometry::Lamp::Cmy { cct: 6000.0, cyan: 1.0, magenta: 0.0, yellow: 0.0, filters: None };
    assert!((ideal.xyz_through(1.0, Response::open()).as_dvec3() - cyan).abs().max_element() > 1e-2);
}
