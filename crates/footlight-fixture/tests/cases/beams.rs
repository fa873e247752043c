//! Beam models against independent numerical references.

use super::library_type;
use footlight_fixture::beam::{BeamSampler, HermiteBeam, HermitePattern, MeasuredBeam, PhotometricTable};
use footlight_fixture::{Beam, FixtureState, Optics};
use glam::Vec3;
use std::sync::Arc;

/// ∫ f dω by a midpoint rule over θ and φ (independent of the beams' own
/// Gauss–Legendre integrals).
fn flux(beam: &Beam) -> f64 {
    let (nt, np) = (4000, 64);
    let top = f64::from(beam.cos_cutoff().clamp(-1.0, 1.0)).acos();
    let mut sum = 0.0;
    for i in 0..nt {
        let th = (i as f64 + 0.5) / nt as f64 * top;
        for j in 0..np {
            let ph = (j as f64 + 0.5) / np as f64 * std::f64::consts::TAU;
            let d = Vec3::new((th.sin() * ph.cos()) as f32, (th.sin() * ph.sin()) as f32, -(th.cos() as f32));
            sum += f64::from(beam.pattern(d)) * th.sin();
        }
    }
    sum * (top / nt as f64) * (std::f64::consts::TAU / np as f64)
}

#[test]
fn zoom_conserves_flux_and_iris_keeps_peak_intensity() {
    for stem in ["niethammer-hpz-115-d", "generic-moving-spot"] {
        let ty = library_type(stem);
        let Optics::Spot(o) = &ty.optics else { panic!("{stem} is a spot") };
        let (lo, hi) = o.field_range();
        let base = FixtureState { v: 1.0, zoom: lo, ..FixtureState::default() };
        let phi0 = f64::from(ty.intensity(&base)) * flux(&ty.beam(&base));
        assert!((ty.intensity(&base) / o.intensity - 1.0).abs() < 1e-5, "{stem}: Î at the reference field");
        for zoom in [lo, (lo + hi) / 2.0, hi] {
            for focus in [0.0, 0.5, 1.0] {
                let s = FixtureState { zoom, focus, ..base };
                let phi = f64::from(ty.intensity(&s)) * flux(&ty.beam(&s));
                assert!((phi / phi0 - 1.0).abs() < 2e-3, "{stem} zoom {zoom} focus {focus}: flux {phi} vs {phi0}");
            }
        }
        // Zooming out lowers Î.
        assert!(ty.intensity(&FixtureState { zoom: hi, ..base }) < 0.5 * ty.intensity(&base));
        // The iris narrows the beam but keeps Î and the peak.
        if let Some(min) = o.iris_min {
            let open = FixtureState { zoom: hi, ..base };
            let closed = FixtureState { iris: min, ..open };
            assert_eq!(ty.intensity(&open), ty.intensity(&closed), "{stem}: iris keeps Î");
            assert_eq!(ty.beam(&closed).pattern(Vec3::NEG_Z), 1.0);
            assert!(ty.beam(&closed).cos_cutoff() > ty.beam(&open).cos_cutoff(), "{stem}: iris narrows the cone");
            assert!(flux(&ty.beam(&closed)) < 0.5 * flux(&ty.beam(&open)));
        }
    }
}

#[test]
fn fresnel_focus_ends_are_the_datasheet_patterns() {
    let ty = library_type("strand-castor");
    let Optics::Hermite(h) = &ty.optics else { panic!("the Castor is a Hermite beam") };
    let at = |focus: f32| ty.beam(&FixtureState { focus, ..FixtureState::default() });
    let (spot, flood) = (at(0.0), at(1.0));
    for i in 0..=900 {
        let th = (i as f32 * 0.1).to_radians();
        let d = Vec3::new(th.sin(), 0.0, -th.cos());
        let angle = (-d.z / d.length()).clamp(-1.0, 1.0).acos(); // as the beams compute it
        assert_eq!(spot.pattern(d), h.spot.at_angle(angle), "spot at {}", i as f32 * 0.1);
        assert_eq!(flood.pattern(d), h.flood.at_angle(angle), "flood at {}", i as f32 * 0.1);
    }
    assert_eq!(ty.intensity(&FixtureState { focus: 0.0, ..FixtureState::default() }), h.spot_cd);
    assert_eq!(ty.intensity(&FixtureState { focus: 1.0, ..FixtureState::default() }), h.flood_cd);
    let mid = ty.intensity(&FixtureState { focus: 0.25, ..FixtureState::default() });
    assert!((mid - (0.75 * h.spot_cd + 0.25 * h.flood_cd)).abs() < 1e-3 * mid, "Î interpolates: {mid}");
}

/// Chi-square of the sampler's θ histogram against the pattern, fixed seed
/// (a low-discrepancy sequence), 12 bins up to the cut-off.
fn chi_square(beam: &Beam) -> f64 {
    let s = BeamSampler::new(beam);
    let edge = f64::from(beam.cos_cutoff().clamp(-1.0, 1.0)).acos();
    let bins = 12;
    let m = 60_000;
    let mut counts = vec![0f64; bins];
    for i in 0..m {
        let u1 = ((i as f64 + 0.5) / m as f64) as f32;
        let u2 = ((i as f64 * 0.618_033_988_75).fract()) as f32;
        let smp = s.sample(u1, u2).expect("a lit beam samples");
        assert!(smp.pdf.is_finite() && smp.pdf > 0.0);
        let th = f64::from(-smp.dir.z).clamp(-1.0, 1.0).acos();
        counts[((th / edge * bins as f64) as usize).min(bins - 1)] += 1.0;
    }
    let total = flux_symmetric(beam, 0.0, edge);
    let mut chi2 = 0.0;
    for (b, &c) in counts.iter().enumerate() {
        let (a0, a1) = (edge * b as f64 / bins as f64, edge * (b + 1) as f64 / bins as f64);
        let expected = flux_symmetric(beam, a0, a1) / total * m as f64;
        if expected > 5.0 {
            chi2 += (c - expected).powi(2) / expected;
        }
    }
    chi2
}

/// ∫ over θ in [a, b] of the azimuthal mean of the pattern, × sin θ.
fn flux_symmetric(beam: &Beam, a: f64, b: f64) -> f64 {
    let (n, np) = (400, 32);
    let mut sum = 0.0;
    for i in 0..n {
        let th = a + (b - a) * (i as f64 + 0.5) / n as f64;
        let mut mean = 0.0;
        for j in 0..np {
            let ph = std::f64::consts::TAU * (j as f64 + 0.5) / np as f64;
            mean += f64::from(beam.pattern(Vec3::new(
                (th.sin() * ph.cos()) as f32,
                (th.sin() * ph.sin()) as f32,
                -(th.cos() as f32),
            )));
        }
        sum += mean / np as f64 * th.sin() * (b - a) / n as f64;
    }
    sum
}

#[test]
fn sampler_histograms_match_every_pattern_kind() {
    let castor = library_type("strand-castor");
    let spot = library_type("niethammer-hpz-115-d");
    let s = Arc::new(HermitePattern::new(&[0.0, 4.0, 8.0, 12.0], &[1.0, 0.7, 0.2, 0.0], None).unwrap());
    let f = Arc::new(HermitePattern::new(&[0.0, 20.0, 40.0], &[1.0, 0.6, 0.0], None).unwrap());
    let table = PhotometricTable::new(
        vec![0.0, 90.0, 180.0, 270.0],
        vec![0.0, 10.0, 20.0, 30.0],
        &[vec![9.0, 8.0, 3.0, 0.0], vec![9.0, 5.0, 1.0, 0.0], vec![9.0, 8.0, 3.0, 0.0], vec![9.0, 2.0, 0.5, 0.0]],
    )
    .unwrap();
    let beams = [
        ("zoom spot", spot.beam(&FixtureState { zoom: 25.0, focus: 0.5, ..FixtureState::default() })),
        ("irised spot", spot.beam(&FixtureState { zoom: 40.0, iris: 0.3, ..FixtureState::default() })),
        ("fresnel spot", castor.beam(&FixtureState { focus: 0.0, ..FixtureState::default() })),
        ("fresnel mid", castor.beam(&FixtureState { focus: 0.6, ..FixtureState::default() })),
        ("fresnel flood", castor.beam(&FixtureState { focus: 1.0, ..FixtureState::default() })),
        ("hermite mix", Beam::Hermite(HermiteBeam::new(s, 1.0, f, 1.0, 0.5))),
        ("measured asymmetric", Beam::Measured(MeasuredBeam::new(Arc::new(table)))),
    ];
    for (name, beam) in &beams {
        let chi2 = chi_square(beam);
        // 12 bins: the 99.9 % point of chi-square with 11 degrees of freedom is 31.3.
        assert!(chi2 < 31.3, "{name}: chi2 {chi2}");
        let sampler_flux = f64::from(BeamSampler::new(beam).flux());
        let reference = flux(beam);
        assert!((sampler_flux / reference - 1.0).abs() < 5e-3, "{name}: sampler flux {sampler_flux} vs {reference}");
        assert!((f64::from(beam.solid_angle()) / reference - 1.0).abs() < 5e-3, "{name}: solid_angle");
    }
}
