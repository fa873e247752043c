//! Importance sampling of emission patterns for photon emission.
//!
//! The pattern "is used for direct lighting as well as for sampling the
//! photons' direction during photon emission" (Vierjahn 2010, section 3.2).
//! Light i's photons together carry ∫f_ε dω of its 1 cd replacement source
//! (DESIGN.md "Beam"), so direct and indirect buffers share k_i.

use super::Beam;
use glam::Vec3;

/// Importance sampler for a [`Beam`] pattern: a piecewise-constant
/// distribution over the polar angle θ (uniform in cos θ inside each of
/// [`BeamSampler::BINS`] bins) and a uniform azimuth, so a narrow spot
/// spends no photons outside its cone. An asymmetric (measured) pattern is
/// averaged over [`Beam::azimuth_samples`] azimuths per θ sample: the pdf is
/// then not proportional to the pattern in azimuth, but it is positive
/// wherever the azimuthal mean is, and photon power uses the exact ratio
/// f_ε(ω)/pdf(ω), so the estimate stays unbiased whatever the binning error.
#[derive(Clone, Debug)]
pub struct BeamSampler {
    /// cos θ at bin edges, from 1 (axis) down to cos(cutoff).
    cos_edges: Vec<f32>,
    /// Cumulative probability at bin ends (last = 1).
    cdf: Vec<f32>,
    /// Probability of each bin.
    prob: Vec<f32>,
    /// Σ of bin pattern means × solid angle: ∫ f_ε dω (lumens per candela).
    flux: f32,
}

/// A sampled emission direction (local frame, beam along −Z) and its pdf
/// with respect to solid angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamSample {
    /// Unit direction in the light's local frame.
    pub dir: Vec3,
    /// Probability density per steradian.
    pub pdf: f32,
}

impl BeamSampler {
    /// Number of θ bins.
    pub const BINS: usize = 256;
    /// Azimuths averaged per θ sample for an asymmetric pattern.
    pub const AZIMUTHS: usize = 16;

    /// Tabulates `beam` (pattern evaluated at 4 points per bin).
    pub fn new(beam: &Beam) -> Self {
        let cos_cut = beam.cos_cutoff().clamp(-1.0, 1.0);
        let theta_max = cos_cut.acos();
        let mut cos_edges = Vec::with_capacity(Self::BINS + 1);
        let mut weight = Vec::with_capacity(Self::BINS);
        for i in 0..=Self::BINS {
            cos_edges.push((theta_max * i as f32 / Self::BINS as f32).cos());
        }
        for i in 0..Self::BINS {
            let (c0, c1) = (cos_edges[i], cos_edges[i + 1]);
            let azimuths = beam.azimuth_samples();
            let mut mean = 0.0;
            for j in 0..4 {
                let c = c0 + (c1 - c0) * (j as f32 + 0.5) / 4.0;
                let s = (1.0 - c * c).max(0.0).sqrt();
                for a in 0..azimuths {
                    let phi = std::f32::consts::TAU * (a as f32 + 0.5) / azimuths as f32;
                    mean += beam.pattern(Vec3::new(s * phi.cos(), s * phi.sin(), -c));
                }
            }
            mean /= (4 * azimuths) as f32;
            weight.push(mean * std::f32::consts::TAU * (c0 - c1).max(0.0));
        }
        let flux: f32 = weight.iter().sum();
        // An asymmetric pattern's azimuthal samples can miss light in a bin
        // (a gobo's thin slit, a prism facet): every bin keeps a small
        // probability so the pdf is positive wherever the pattern may be.
        let floor = if beam.is_symmetric() { 0.0 } else { 1e-3 * flux / Self::BINS as f32 };
        let total: f32 = weight.iter().map(|w| w + floor).sum();
        let prob: Vec<f32> =
            if flux > 0.0 { weight.iter().map(|w| (w + floor) / total).collect() } else { vec![0.0; Self::BINS] };
        let mut acc = 0.0;
        let cdf = prob
            .iter()
            .map(|p| {
                acc += p;
                acc
            })
            .collect();
        Self { cos_edges, cdf, prob, flux }
    }

    /// ∫ f_ε dω: the flux (lm) of this pattern at 1 cd peak.
    pub fn flux(&self) -> f32 {
        self.flux
    }

    /// Samples a direction from two uniform numbers in [0, 1); `None` for a
    /// pattern that emits nothing.
    pub fn sample(&self, u1: f32, u2: f32) -> Option<BeamSample> {
        if self.flux <= 0.0 || !self.flux.is_finite() {
            return None;
        }
        let bin = self.cdf.partition_point(|&c| c <= u1).min(Self::BINS - 1);
        let p = self.prob[bin];
        if p <= 0.0 {
            return None;
        }
        let start = if bin == 0 { 0.0 } else { self.cdf[bin - 1] };
        let t = ((u1 - start) / p).clamp(0.0, 1.0);
        let (c0, c1) = (self.cos_edges[bin], self.cos_edges[bin + 1]);
        let cos = c0 + (c1 - c0) * t;
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        let phi = std::f32::consts::TAU * u2;
        let solid = std::f32::consts::TAU * (c0 - c1);
        Some(BeamSample { dir: Vec3::new(sin * phi.cos(), sin * phi.sin(), -cos), pdf: p / solid })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::beam::SpotBeam;

    #[test]
    fn flux_matches_numerical_integral_and_histogram_matches_pattern() {
        let beam = Beam::Spot(SpotBeam::from_beam_field(20.0, 40.0));
        let s = BeamSampler::new(&beam);
        // Independent integral: midpoint rule in θ with 20k steps.
        let n = 20_000;
        let th_max = std::f32::consts::PI;
        let mut flux = 0.0f64;
        for i in 0..n {
            let th = (i as f32 + 0.5) / n as f32 * th_max;
            let f = beam.pattern(Vec3::new(th.sin(), 0.0, -th.cos()));
            flux += (f * th.sin()) as f64 * (th_max / n as f32) as f64 * std::f64::consts::TAU;
        }
        assert!(((s.flux() as f64) - flux).abs() < 1e-3 * flux, "{} vs {flux}", s.flux());
        // Chi-square of the θ histogram (10 bins up to the cut-off) vs the pattern, fixed low-discrepancy u.
        let bins = 10;
        let edge = beam.cos_cutoff().acos();
        let mut counts = vec![0f64; bins];
        let m = 100_000;
        for i in 0..m {
            let u1 = (i as f32 + 0.5) / m as f32;
            let u2 = (i as f32 * 0.618_034).fract();
            let smp = s.sample(u1, u2).unwrap();
            let th = (-smp.dir.z).acos();
            counts[((th / edge * bins as f32) as usize).min(bins - 1)] += 1.0;
        }
        let mut chi2 = 0.0;
        for (b, &c) in counts.iter().enumerate() {
            let (a0, a1) = (edge * b as f32 / bins as f32, edge * (b + 1) as f32 / bins as f32);
            let mut p = 0.0f64;
            for j in 0..200 {
                let th = a0 + (a1 - a0) * (j as f32 + 0.5) / 200.0;
                let f = beam.pattern(Vec3::new(th.sin(), 0.0, -th.cos()));
                p += (f * th.sin() * (a1 - a0) / 200.0) as f64 * std::f64::consts::TAU / flux;
            }
            let expected = p * m as f64;
            if expected > 5.0 {
                chi2 += (c - expected).powi(2) / expected;
            }
        }
        assert!(chi2 < 30.0, "chi2 {chi2} counts {counts:?}");
    }

    #[test]
    fn narrow_beam_never_samples_outside_its_cone_and_pdf_is_consistent() {
        let beam = Beam::Spot(SpotBeam::from_beam_field(10.0, 14.0));
        let s = BeamSampler::new(&beam);
        let cut = beam.cos_cutoff();
        for i in 0..1000 {
            let smp = s.sample((i as f32 + 0.5) / 1000.0, (i as f32 * 0.37).fract()).unwrap();
            assert!(-smp.dir.z >= cut - 1e-6 && smp.pdf > 0.0 && smp.pdf.is_finite());
            assert!((smp.dir.length() - 1.0).abs() < 1e-5);
        }
    }
}
