//! Fresnel and PC patterns: piecewise cubic Hermite polynomials of the angle
//! from the axis, one for "spot" and one for "flood", mixed by focus
//! (Vierjahn 2010, section 3.2: "They are modelled by piecewise-continuous
//! Hermite polynomials [...] Finally, the polynomials are interpolated with
//! respect to the focus value of the fixture").
//!
//! A pattern is given by knots (angle, value) and optional slopes; without
//! slopes they come from Fritsch & Carlson, "Monotone Piecewise Cubic
//! Interpolation" (SIAM J. Numer. Anal. 17(2), 1980), so a falling
//! datasheet curve never overshoots. The slope is 0 at the axis (the
//! pattern is symmetric, so anything else would be a cusp) and at the last
//! knot, whose value must be 0: the pattern joins the zero beyond it with
//! continuous value and slope.
//!
//! ```toml
//! [beam.spot]
//! intensity = 150000          # Î at full spot, cd
//! angles = [0, 4, 8, 12, 16]  # degrees from the axis
//! values = [1, 0.8, 0.4, 0.1, 0]
//! ```
//!
//! Focus φ mixes the two in candela, the way light from a lamp moving
//! between two positions would: I_φ(θ) = (1 − φ) Î_s f_s(θ) + φ Î_f f_f(θ).
//! The beam is I_φ normalised to peak 1 and Î_φ is that peak, i.e.
//! (1 − φ) Î_s + φ Î_f when both patterns peak on the axis. φ = 0 and φ = 1
//! reproduce the spot and flood patterns exactly.

use super::{axis_angle, integrate_sin};
use glam::Vec3;
use std::sync::Arc;

/// One piecewise cubic Hermite pattern, peak 1, zero past its last knot.
#[derive(Clone, Debug, PartialEq)]
pub struct HermitePattern {
    /// Knot angles from the axis, radians, strictly increasing from 0.
    knots: Vec<f32>,
    /// Values at the knots (scaled so the curve's peak is 1).
    values: Vec<f32>,
    /// dvalue/dθ at the knots, per radian (same scale).
    slopes: Vec<f32>,
    /// cos of the last knot.
    cos_cut: f32,
    /// ∫ f dω, steradians.
    solid_angle: f32,
}

impl HermitePattern {
    /// Builds a pattern from knot angles in degrees, relative values (any
    /// positive scale: they are divided by the curve's maximum) and optional
    /// slopes in value per degree. Errors say what is wrong with the input.
    pub fn new(angles_deg: &[f32], values: &[f32], slopes_per_deg: Option<&[f32]>) -> Result<Self, String> {
        let n = angles_deg.len();
        if n < 2 || values.len() != n {
            return Err(format!("needs at least 2 knots and as many values as angles (got {n} and {})", values.len()));
        }
        if angles_deg[0] != 0.0 {
            return Err(format!("the first angle must be 0 (the beam axis), not {}", angles_deg[0]));
        }
        for w in angles_deg.windows(2) {
            if !(w[1] > w[0] && w[1].is_finite()) {
                return Err(format!("angles must increase strictly: {} then {}", w[0], w[1]));
            }
        }
        if angles_deg[n - 1] > 180.0 {
            return Err(format!("the last angle {} is past 180 degrees", angles_deg[n - 1]));
        }
        if values.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err("values must be finite and >= 0".into());
        }
        if values[n - 1] != 0.0 {
            return Err(format!("the last value must be 0 (the pattern ends there), not {}", values[n - 1]));
        }
        let top = values.iter().fold(0.0f32, |m, &v| m.max(v));
        if !(top > 0.0) {
            return Err("at least one value must be > 0".into());
        }
        let knots: Vec<f32> = angles_deg.iter().map(|a| a.to_radians()).collect();
        let slopes = match slopes_per_deg {
            Some(s) => {
                if s.len() != n || s.iter().any(|m| !m.is_finite()) {
                    return Err(format!("slopes must be {n} finite numbers (value per degree)"));
                }
                s.iter().map(|m| m.to_degrees()).collect() // per degree → per radian
            }
            None => fritsch_carlson(&knots, values),
        };
        let mut p = Self { knots, values: values.to_vec(), slopes, cos_cut: 1.0, solid_angle: 0.0 };
        // Normalise to peak 1 (given slopes may overshoot between knots).
        let peak = p.sampled_max();
        let scale = if peak > 0.0 { 1.0 / peak } else { 1.0 / top };
        p.values.iter_mut().for_each(|v| *v *= scale);
        p.slopes.iter_mut().for_each(|m| *m *= scale);
        p.cos_cut = p.knots[n - 1].cos();
        let last = f64::from(p.knots[n - 1]);
        p.solid_angle = integrate_sin(0.0, last, 4 * n, |t| f64::from(p.at_angle(t as f32))) as f32;
        Ok(p)
    }

    /// Value at angle `theta` (radians) from the axis: clamped to [0, 1],
    /// zero past the last knot.
    pub fn at_angle(&self, theta: f32) -> f32 {
        let n = self.knots.len();
        if !(theta >= 0.0) || theta > self.knots[n - 1] {
            return if theta < 0.0 { self.values[0].clamp(0.0, 1.0) } else { 0.0 };
        }
        let k = self.knots.partition_point(|&t| t <= theta).clamp(1, n - 1) - 1;
        self.eval(k, theta).clamp(0.0, 1.0)
    }

    /// Unclamped cubic of segment `k` at `theta`.
    fn eval(&self, k: usize, theta: f32) -> f32 {
        let h = self.knots[k + 1] - self.knots[k];
        let t = (theta - self.knots[k]) / h;
        let (t2, t3) = (t * t, t * t * t);
        let h00 = 2.0 * t3 - 3.0 * t2 + 1.0;
        let h10 = t3 - 2.0 * t2 + t;
        let h01 = -2.0 * t3 + 3.0 * t2;
        let h11 = t3 - t2;
        h00 * self.values[k] + h10 * h * self.slopes[k] + h01 * self.values[k + 1] + h11 * h * self.slopes[k + 1]
    }

    /// Derivative d/dθ (per radian) of segment `k`'s cubic at `theta`.
    pub fn slope_in_segment(&self, k: usize, theta: f32) -> f32 {
        let h = self.knots[k + 1] - self.knots[k];
        let t = (theta - self.knots[k]) / h;
        let d00 = 6.0 * t * t - 6.0 * t;
        let d10 = 3.0 * t * t - 4.0 * t + 1.0;
        let d01 = -6.0 * t * t + 6.0 * t;
        let d11 = 3.0 * t * t - 2.0 * t;
        (d00 * self.values[k] + d01 * self.values[k + 1]) / h + d10 * self.slopes[k] + d11 * self.slopes[k + 1]
    }

    /// Value of segment `k`'s cubic at `theta` (unclamped, for continuity checks).
    pub fn value_in_segment(&self, k: usize, theta: f32) -> f32 {
        self.eval(k, theta)
    }

    /// Knot angles in radians.
    pub fn knots(&self) -> &[f32] {
        &self.knots
    }

    /// Cosine of the last knot (the cut-off).
    pub fn cos_cutoff(&self) -> f32 {
        self.cos_cut
    }

    /// ∫ f dω in steradians.
    pub fn solid_angle(&self) -> f32 {
        self.solid_angle
    }

    /// Largest unclamped value over the knots and 64 points per segment.
    fn sampled_max(&self) -> f32 {
        let mut m = self.values.iter().fold(0.0f32, |m, &v| m.max(v));
        for k in 0..self.knots.len() - 1 {
            for i in 1..64 {
                let th = self.knots[k] + (self.knots[k + 1] - self.knots[k]) * i as f32 / 64.0;
                m = m.max(self.eval(k, th));
            }
        }
        m
    }
}

/// Fritsch–Carlson monotone slopes (per radian) with zero slope at both ends.
fn fritsch_carlson(x: &[f32], y: &[f32]) -> Vec<f32> {
    let n = x.len();
    let delta: Vec<f32> = (0..n - 1).map(|k| (y[k + 1] - y[k]) / (x[k + 1] - x[k])).collect();
    let mut m = vec![0.0f32; n];
    for k in 1..n - 1 {
        m[k] = if delta[k - 1] * delta[k] > 0.0 { 0.5 * (delta[k - 1] + delta[k]) } else { 0.0 };
    }
    for k in 0..n - 1 {
        if delta[k] == 0.0 {
            m[k] = 0.0;
            m[k + 1] = 0.0;
            continue;
        }
        let (a, b) = (m[k] / delta[k], m[k + 1] / delta[k]);
        let r = a * a + b * b;
        if r > 9.0 {
            let tau = 3.0 / r.sqrt();
            m[k] = tau * a * delta[k];
            m[k + 1] = tau * b * delta[k];
        }
    }
    m[0] = 0.0;
    m[n - 1] = 0.0;
    m
}

/// A Fresnel/PC beam: spot and flood patterns mixed by focus, normalised to peak 1.
#[derive(Clone, Debug, PartialEq)]
pub struct HermiteBeam {
    spot: Arc<HermitePattern>,
    flood: Arc<HermitePattern>,
    /// Weight of the flood pattern in the normalised mix.
    w_flood: f32,
    /// 1 / peak of the unnormalised mix.
    norm: f32,
    cos_cut: f32,
    solid_angle: f32,
    /// Î of the mix: its peak in candela.
    peak_cd: f32,
}

impl HermiteBeam {
    /// The beam at focus `focus` (0 spot … 1 flood) for patterns with peak
    /// intensities `spot_cd` and `flood_cd` (Î at full spot and full flood).
    pub fn new(spot: Arc<HermitePattern>, spot_cd: f32, flood: Arc<HermitePattern>, flood_cd: f32, focus: f32) -> Self {
        let phi = if focus.is_finite() { focus.clamp(0.0, 1.0) } else { 0.0 };
        let (is, iflood) = (spot_cd.max(0.0), flood_cd.max(0.0));
        let (a, b) = ((1.0 - phi) * is, phi * iflood);
        // Weights of the mix in units of its peak-free sum; equal weights if both Î are zero.
        let w_flood = if a + b > 0.0 { b / (a + b) } else { phi };
        let mut beam = Self { spot, flood, w_flood, norm: 1.0, cos_cut: 1.0, solid_angle: 0.0, peak_cd: 0.0 };
        let last = beam.max_angle();
        // Both peaking on the axis (the usual case) makes the mix peak 1 there;
        // otherwise scan for the peak. Either way it is cheap enough per frame
        // for the common case, since k_i needs Î_φ every display frame.
        let mut peak = beam.mix(0.0);
        if !(beam.spot.at_angle(0.0) >= 1.0 && beam.flood.at_angle(0.0) >= 1.0) {
            for i in 0..=2048 {
                peak = peak.max(beam.mix(last * i as f32 / 2048.0));
            }
            for k in beam.spot.knots().iter().chain(beam.flood.knots()) {
                peak = peak.max(beam.mix(*k));
            }
        }
        beam.norm = if peak > 0.0 { 1.0 / peak } else { 1.0 };
        beam.peak_cd = (a + b) * peak;
        beam.cos_cut = last.cos();
        beam.solid_angle = (f64::from(1.0 - beam.w_flood) * f64::from(beam.spot.solid_angle())
            + f64::from(beam.w_flood) * f64::from(beam.flood.solid_angle())) as f32
            * beam.norm;
        beam
    }

    /// Widest angle (radians) of the patterns that take part.
    fn max_angle(&self) -> f32 {
        let s = if self.w_flood < 1.0 { *self.spot.knots().last().unwrap_or(&0.0) } else { 0.0 };
        let f = if self.w_flood > 0.0 { *self.flood.knots().last().unwrap_or(&0.0) } else { 0.0 };
        s.max(f)
    }

    /// Unnormalised mix at `theta`.
    fn mix(&self, theta: f32) -> f32 {
        let (ws, wf) = (1.0 - self.w_flood, self.w_flood);
        let s = if ws > 0.0 { ws * self.spot.at_angle(theta) } else { 0.0 };
        let f = if wf > 0.0 { wf * self.flood.at_angle(theta) } else { 0.0 };
        s + f
    }

    /// f_ε for a unit local direction.
    pub fn pattern(&self, dir: Vec3) -> f32 {
        if -dir.z < self.cos_cut {
            return 0.0;
        }
        self.at_angle(axis_angle(dir))
    }

    /// f_ε at angle `theta` (radians) from the axis.
    pub fn at_angle(&self, theta: f32) -> f32 {
        (self.mix(theta) * self.norm).min(1.0)
    }

    /// Cosine of the cut-off angle.
    pub fn cos_cutoff(&self) -> f32 {
        self.cos_cut
    }

    /// ∫ f_ε dω in steradians.
    pub fn solid_angle(&self) -> f32 {
        self.solid_angle
    }

    /// Î at this focus: the peak of the candela mix.
    pub fn peak_cd(&self) -> f32 {
        self.peak_cd
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spot() -> HermitePattern {
        HermitePattern::new(&[0.0, 3.0, 5.0, 7.0, 10.0, 14.0, 20.0], &[1.0, 0.85, 0.6, 0.35, 0.12, 0.03, 0.0], None)
            .unwrap()
    }

    fn flood() -> HermitePattern {
        HermitePattern::new(&[0.0, 10.0, 20.0, 28.0, 35.0, 45.0, 60.0], &[1.0, 0.92, 0.7, 0.5, 0.3, 0.1, 0.0], None)
            .unwrap()
    }

    fn dir(deg: f32) -> Vec3 {
        let a = deg.to_radians();
        Vec3::new(0.0, a.sin(), -a.cos())
    }

    #[test]
    fn continuous_value_and_slope_at_every_knot() {
        let with_slopes =
            HermitePattern::new(&[0.0, 5.0, 12.0, 20.0], &[1.0, 0.7, 0.2, 0.0], Some(&[0.0, -0.06, -0.04, 0.0]))
                .unwrap();
        for p in [spot(), flood(), with_slopes] {
            let k = p.knots().to_vec();
            for (i, &ki) in k.iter().enumerate().take(k.len() - 1).skip(1) {
                let (l, r) = (p.value_in_segment(i - 1, ki), p.value_in_segment(i, ki));
                assert!((l - r).abs() < 1e-5, "value jump at knot {i}: {l} vs {r}");
                let (sl, sr) = (p.slope_in_segment(i - 1, ki), p.slope_in_segment(i, ki));
                assert!((sl - sr).abs() < 1e-3 * (1.0 + sl.abs()), "slope jump at knot {i}: {sl} vs {sr}");
            }
            // Joins the zero tail with zero value and slope, and is flat on the axis.
            let n = k.len();
            assert!(p.value_in_segment(n - 2, k[n - 1]).abs() < 1e-6);
            assert!(p.slope_in_segment(n - 2, k[n - 1]).abs() < 1e-4);
            assert!(p.slope_in_segment(0, 0.0).abs() < 1e-4);
            assert_eq!(p.at_angle(k[n - 1] + 1e-3), 0.0);
            assert_eq!(p.at_angle(0.0), 1.0);
        }
    }

    #[test]
    fn fritsch_carlson_is_monotone_and_passes_the_knots() {
        let p = spot();
        let mut last = 2.0;
        for i in 0..=2000 {
            let v = p.at_angle((20.0f32 * i as f32 / 2000.0).to_radians());
            assert!(v <= last + 1e-6, "rises at step {i}: {v} > {last}");
            last = v;
        }
        let want = [1.0, 0.85, 0.6, 0.35, 0.12, 0.03, 0.0];
        for (a, w) in [0.0f32, 3.0, 5.0, 7.0, 10.0, 14.0, 20.0].iter().zip(want) {
            assert!((p.at_angle(a.to_radians()) - w).abs() < 1e-6);
        }
    }

    #[test]
    fn focus_ends_reproduce_spot_and_flood_exactly() {
        let (s, f) = (Arc::new(spot()), Arc::new(flood()));
        let at0 = HermiteBeam::new(s.clone(), 100_000.0, f.clone(), 20_000.0, 0.0);
        let at1 = HermiteBeam::new(s.clone(), 100_000.0, f.clone(), 20_000.0, 1.0);
        for i in 0..=700 {
            let deg = i as f32 * 0.1;
            let th = deg.to_radians();
            assert_eq!(at0.at_angle(th), s.at_angle(th), "spot at {deg}");
            assert_eq!(at1.at_angle(th), f.at_angle(th), "flood at {deg}");
            assert_eq!(at0.pattern(dir(deg)), s.at_angle(axis_angle(dir(deg))), "spot at {deg}");
        }
        assert_eq!(at0.peak_cd(), 100_000.0);
        assert_eq!(at1.peak_cd(), 20_000.0);
        assert_eq!(at0.solid_angle(), s.solid_angle());
        let mid = HermiteBeam::new(s.clone(), 100_000.0, f.clone(), 20_000.0, 0.5);
        assert!((mid.peak_cd() - 60_000.0).abs() < 1.0, "{}", mid.peak_cd());
        assert_eq!(mid.pattern(dir(0.0)), 1.0);
        // The half-focus beam is the candela mix: I(θ) = ½·1e5·f_s + ½·2e4·f_f.
        for deg in [2.0f32, 8.0, 15.0, 30.0, 50.0] {
            let i = 50_000.0 * s.at_angle(deg.to_radians()) + 10_000.0 * f.at_angle(deg.to_radians());
            assert!((mid.pattern(dir(deg)) * mid.peak_cd() - i).abs() < 1.0, "{deg}");
        }
        assert!((mid.cos_cutoff() - 60f32.to_radians().cos()).abs() < 1e-6);
    }

    #[test]
    fn solid_angle_matches_a_midpoint_integral() {
        let beam = HermiteBeam::new(Arc::new(spot()), 5.0, Arc::new(flood()), 3.0, 0.3);
        let n = 100_000;
        let top = 60f64.to_radians();
        let mut sum = 0.0;
        for i in 0..n {
            let th = (i as f64 + 0.5) / n as f64 * top;
            sum += f64::from(beam.at_angle(th as f32)) * th.sin() * top / n as f64;
        }
        sum *= std::f64::consts::TAU;
        assert!((f64::from(beam.solid_angle()) / sum - 1.0).abs() < 1e-4, "{} vs {sum}", beam.solid_angle());
    }

    #[test]
    fn bad_knots_are_refused() {
        assert!(HermitePattern::new(&[0.0], &[1.0], None).is_err());
        assert!(HermitePattern::new(&[1.0, 5.0], &[1.0, 0.0], None).is_err());
        assert!(HermitePattern::new(&[0.0, 5.0, 5.0], &[1.0, 0.5, 0.0], None).is_err());
        assert!(HermitePattern::new(&[0.0, 5.0], &[1.0, 0.5], None).is_err());
        assert!(HermitePattern::new(&[0.0, 5.0], &[f32::NAN, 0.0], None).is_err());
        assert!(HermitePattern::new(&[0.0, 5.0], &[0.0, 0.0], None).is_err());
        assert!(HermitePattern::new(&[0.0, 5.0], &[1.0, 0.0], Some(&[0.0])).is_err());
        // Any positive scale is normalised to peak 1.
        let cd = HermitePattern::new(&[0.0, 5.0, 9.0], &[80_000.0, 40_000.0, 0.0], None).unwrap();
        assert_eq!(cd.at_angle(0.0), 1.0);
    }
}
