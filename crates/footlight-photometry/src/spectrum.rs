//! The wavelength grid every spectrum is sampled on, and sampled spectra.
//!
//! The grid is the CIE colour-matching table's own: 360 to 830 nm in 1 nm
//! steps (471 samples), so integrating against x̄ȳz̄ is an exact sum over
//! the published values with no resampling of the CMFs. Measured data on
//! other grids (gel spectra: 405-700 nm every 5 nm) are resampled onto it by
//! linear interpolation and held at their end values outside their range.
//!
//! Data flow: [`crate::planck`], [`crate::gel`] and [`crate::lamp`] produce
//! [`Sampled`] spectra; [`crate::cie`] integrates them to XYZ.

/// First wavelength of the grid in nm.
pub const LAMBDA_MIN_NM: u32 = 360;
/// Last wavelength of the grid in nm.
pub const LAMBDA_MAX_NM: u32 = 830;
/// Number of grid samples (1 nm apart).
pub const SAMPLES: usize = (LAMBDA_MAX_NM - LAMBDA_MIN_NM + 1) as usize;

/// Wavelength in nm of grid sample `i`.
pub fn wavelength(i: usize) -> f64 {
    f64::from(LAMBDA_MIN_NM) + i as f64
}

/// A spectrum sampled at 360, 361, …, 830 nm (relative units: a spectral
/// power distribution, or a transmittance in 0..1).
#[derive(Clone, Debug, PartialEq)]
pub struct Sampled {
    values: Box<[f64; SAMPLES]>,
}

impl Sampled {
    /// The same value at every wavelength.
    pub fn constant(value: f64) -> Self {
        Self { values: Box::new([value; SAMPLES]) }
    }

    /// Samples `f(nm)` at every grid wavelength.
    pub fn from_fn(f: impl Fn(f64) -> f64) -> Self {
        let mut values = Box::new([0.0; SAMPLES]);
        for (i, v) in values.iter_mut().enumerate() {
            *v = f(wavelength(i));
        }
        Self { values }
    }

    /// Resamples a table measured at `start_nm, start_nm + step_nm, …`:
    /// linear between samples, held at the first and last value outside.
    /// A one-value table is constant. An empty table gives zero.
    pub fn from_table(start_nm: f64, step_nm: f64, table: &[f64]) -> Self {
        Self::from_fn(|nm| interpolate_table(start_nm, step_nm, table, nm))
    }

    /// Resamples measured points `(nm, value)` in any order (a GDTF
    /// `<Measurement>`'s WaveLength/Energy or transmission): linear between
    /// neighbouring points, **zero outside the measured range** (a light
    /// source emits nothing where it was not measured). Non-finite points
    /// are dropped; `None` with fewer than two distinct wavelengths.
    pub fn from_points(points: &[(f64, f64)]) -> Option<Self> {
        let mut pts: Vec<(f64, f64)> = points.iter().copied().filter(|p| p.0.is_finite() && p.1.is_finite()).collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        pts.dedup_by(|a, b| a.0 == b.0);
        if pts.len() < 2 {
            return None;
        }
        let (lo, hi) = (pts[0].0, pts[pts.len() - 1].0);
        Some(Self::from_fn(|nm| {
            if nm < lo || nm > hi {
                return 0.0;
            }
            let i = pts.partition_point(|p| p.0 < nm);
            if i == 0 {
                return pts[0].1;
            }
            let ((x0, y0), (x1, y1)) = (pts[i - 1], pts[i]);
            let t = (nm - x0) / (x1 - x0);
            y0 * (1.0 - t) + y1 * t // convex: never below both neighbours
        }))
    }

    /// The samples, index `i` at `360 + i` nm.
    pub fn values(&self) -> &[f64; SAMPLES] {
        &self.values
    }

    /// Value at `nm`, linear between grid samples, held at the ends.
    pub fn at(&self, nm: f64) -> f64 {
        interpolate_table(f64::from(LAMBDA_MIN_NM), 1.0, &self.values[..], nm)
    }

    /// Product with another spectrum, sample by sample (light through a filter).
    pub fn mul(&self, other: &Sampled) -> Sampled {
        let mut values = self.values.clone();
        for (v, o) in values.iter_mut().zip(other.values.iter()) {
            *v *= o;
        }
        Self { values }
    }

    /// `(1 − f)·a + f·b` sample by sample: two filters each covering part of
    /// the beam (a half-scrolled colour frame mixes this way, by area).
    pub fn lerp(a: &Sampled, b: &Sampled, f: f64) -> Sampled {
        let mut values = a.values.clone();
        for (v, o) in values.iter_mut().zip(b.values.iter()) {
            *v = (1.0 - f) * *v + f * o;
        }
        Self { values }
    }

    /// Adds `weight · other` in place.
    pub fn add_scaled(&mut self, other: &Sampled, weight: f64) {
        for (v, o) in self.values.iter_mut().zip(other.values.iter()) {
            *v += weight * o;
        }
    }
}

/// Linear interpolation in a uniformly spaced table, held at the ends.
pub(crate) fn interpolate_table<T: Copy + Into<f64>>(start_nm: f64, step_nm: f64, table: &[T], nm: f64) -> f64 {
    let (Some(&first), Some(&last)) = (table.first(), table.last()) else {
        return 0.0;
    };
    let (first, last): (f64, f64) = (first.into(), last.into());
    if table.len() == 1 || !(step_nm > 0.0 && nm.is_finite()) {
        return first;
    }
    let s = (nm - start_nm) / step_nm;
    if s.is_nan() || s <= 0.0 {
        return first;
    }
    let i = s.floor() as usize;
    if i >= table.len() - 1 {
        return last;
    }
    let f = s - i as f64;
    table[i].into() * (1.0 - f) + table[i + 1].into() * f
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_is_the_cie_table_grid() {
        assert_eq!(SAMPLES, 471);
        assert_eq!(wavelength(0), 360.0);
        assert_eq!(wavelength(SAMPLES - 1), 830.0);
    }

    #[test]
    fn table_is_linear_inside_and_held_outside() {
        let t = [0.2, 0.4, 1.0];
        assert_eq!(interpolate_table(400.0, 5.0, &t, 300.0), 0.2);
        assert_eq!(interpolate_table(400.0, 5.0, &t, 400.0), 0.2);
        assert!((interpolate_table(400.0, 5.0, &t, 402.5) - 0.3).abs() < 1e-12);
        assert_eq!(interpolate_table(400.0, 5.0, &t, 405.0), 0.4);
        assert!((interpolate_table(400.0, 5.0, &t, 409.0) - 0.88).abs() < 1e-12);
        assert_eq!(interpolate_table(400.0, 5.0, &t, 410.0), 1.0);
        assert_eq!(interpolate_table(400.0, 5.0, &t, 900.0), 1.0);
        assert_eq!(interpolate_table(400.0, 5.0, &[0.7], 550.0), 0.7);
        assert_eq!(interpolate_table::<f64>(400.0, 5.0, &[], 550.0), 0.0);
        assert_eq!(interpolate_table(400.0, 5.0, &t, f64::NAN), 0.2);
    }

    #[test]
    fn lerp_mixes_by_area() {
        let a = Sampled::constant(0.2);
        let b = Sampled::from_fn(|nm| if nm < 500.0 { 1.0 } else { 0.0 });
        let m = Sampled::lerp(&a, &b, 0.25);
        assert!((m.at(400.0) - 0.4).abs() < 1e-12);
        assert!((m.at(600.0) - 0.15).abs() < 1e-12);
    }

    #[test]
    fn measured_points_interpolate_and_are_zero_outside() {
        // Unsorted points 400..600 nm: linear between, zero outside, never
        // below both neighbours (tiny values next to zero stay ≥ 0).
        let s = Sampled::from_points(&[(600.0, 0.0), (400.0, 2.0), (500.0, 1e-300), (450.0, f64::NAN)]).unwrap();
        assert_eq!(s.at(399.0), 0.0);
        assert_eq!(s.at(601.0), 0.0);
        assert_eq!(s.at(400.0), 2.0);
        assert!((s.at(450.0) - 1.0).abs() < 1e-12);
        assert!(s.values().iter().all(|v| *v >= 0.0));
        assert!(Sampled::from_points(&[(500.0, 1.0), (500.0, 2.0)]).is_none());
        assert!(Sampled::from_points(&[]).is_none());
    }
}
