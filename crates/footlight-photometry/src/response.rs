//! Precomputed filter responses: what one transmission spectrum does to
//! each lamp family, integrated once so a frame costs a table lookup.
//!
//! k_i (Vierjahn 2010, eq. 4) is recomputed every display frame for every
//! light (section 3.3), up to ~600 lights at 60 Hz. Integrating lamp × gel ×
//! x̄ȳz̄ over 471 wavelengths per light per frame would cost microseconds
//! each, so every filter (and the open beam) carries a [`Response`]:
//!
//! * **Planckian lamps** (tungsten, discharge, CMY on a white source): XYZ of
//!   blackbody × transmission, divided by the unfiltered blackbody's Y, on a
//!   grid uniform in mired (10⁶/T, in which chromaticity moves nearly
//!   linearly) from 50 to 2000 mired (20000 K down to 500 K) every
//!   [`MIRED_STEP`] mired, read back with Catmull-Rom interpolation. Each
//!   node is split into the three wavelength bands the CMY flags act on
//!   (below 490 nm, 490-589 nm, 590 nm and up), so the same table serves
//!   plain and CMY lamps. The interpolation error against exact integration
//!   is measured by `examples/measure.rs` and bounded by a unit test.
//! * **LED emitters**: XYZ of each [`LED basis`](led_basis) spectrum ×
//!   transmission (exact, no interpolation; emitters are fixed mixes of
//!   basis spectra, see [`crate::lamp::Emitter`]).
//!
//! * **Measured spectra** (emitters from a GDTF `<Measurement>`): not mixes
//!   of a basis, so the response also keeps the transmission itself and
//!   [`Response::integrate`] multiplies and sums on the 1 nm grid.
//!
//! A transmission of exactly 1 everywhere gives bit-for-bit the same tables
//! as [`Response::open`], so a clear frame changes nothing.

use crate::cie::{product_to_xyz, sampled_to_xyz, sampled_to_xyz_range};
use crate::planck::relative_radiance;
use crate::spectrum::{SAMPLES, Sampled};
use glam::{DVec3, Vec3};
use std::ops::Range;
use std::sync::OnceLock;

/// Lowest temperature a Planckian lamp is evaluated at, K (colder is clamped;
/// a filament below ~800 K barely glows, and v is then below 4e-7).
pub const T_MIN_K: f32 = 500.0;
/// Highest temperature a Planckian lamp is evaluated at, K (hotter is clamped).
pub const T_MAX_K: f32 = 20_000.0;
/// Grid spacing of the Planckian tables in mired.
pub const MIRED_STEP: f64 = 10.0;
const MIRED_MIN: f64 = 1e6 / T_MAX_K as f64;
const MIRED_MAX: f64 = 1e6 / T_MIN_K as f64;
/// Grid nodes: one beyond each end of [MIRED_MIN, MIRED_MAX], so every
/// lookup has two neighbours on each side.
const NODES: usize = ((MIRED_MAX - MIRED_MIN) / MIRED_STEP) as usize + 3;
const MIRED_FIRST_NODE: f64 = MIRED_MIN - MIRED_STEP;

/// Grid-sample ranges of the bands that the cyan, magenta and yellow flags
/// subtract: [blue < 490 nm, green 490-589 nm, red ≥ 590 nm] (360 + index nm).
pub const CMY_BANDS: [Range<usize>; 3] = [0..130, 130..230, 230..SAMPLES];

/// Number of LED basis bands, peaking at 390, 395, …, 710 nm.
pub const LED_BANDS: usize = 65;
/// Full width at half maximum of each LED basis band, nm (estimated: a
/// typical narrow LED line; see [`crate::lamp::Emitter`]).
pub const LED_BAND_FWHM_NM: f64 = 15.0;

/// Peak of LED basis band `k` (1-based; basis 0 is the flat spectrum).
pub fn led_band_peak_nm(k: usize) -> f64 {
    390.0 + 5.0 * (k as f64 - 1.0)
}

/// Number of LED basis spectra: the flat (equal-energy) spectrum plus the bands.
pub const LED_BASIS: usize = 1 + LED_BANDS;

/// The LED basis spectra, each scaled to luminance Y = 1: index 0 is flat
/// (equal energy, x = y = 1/3), index k ≥ 1 a Gaussian band peaking at
/// [`led_band_peak_nm`]`(k)`.
pub fn led_basis() -> &'static [Sampled] {
    static BASIS: OnceLock<Vec<Sampled>> = OnceLock::new();
    BASIS.get_or_init(|| {
        let sigma = LED_BAND_FWHM_NM / (2.0 * (2.0 * std::f64::consts::LN_2).sqrt());
        (0..LED_BASIS)
            .map(|k| {
                let s = if k == 0 {
                    Sampled::constant(1.0)
                } else {
                    let p = led_band_peak_nm(k);
                    Sampled::from_fn(|nm| (-0.5 * ((nm - p) / sigma).powi(2)).exp())
                };
                let y = sampled_to_xyz(&s).y;
                let mut n = Sampled::constant(0.0);
                n.add_scaled(&s, 1.0 / y);
                n
            })
            .collect()
    })
}

/// XYZ (Y = 1) of each LED basis spectrum.
pub fn led_basis_xyz() -> &'static [DVec3] {
    static XYZ: OnceLock<Vec<DVec3>> = OnceLock::new();
    XYZ.get_or_init(|| led_basis().iter().map(sampled_to_xyz).collect())
}

/// Temperature of Planckian table node `j`, K.
fn node_temperature(j: usize) -> f64 {
    1e6 / (MIRED_FIRST_NODE + MIRED_STEP * j as f64)
}

/// Blackbody spectra at the table nodes with their unfiltered Y.
fn planck_nodes() -> &'static [(Sampled, f64)] {
    static NODES_CACHE: OnceLock<Vec<(Sampled, f64)>> = OnceLock::new();
    NODES_CACHE.get_or_init(|| {
        (0..NODES)
            .map(|j| {
                let t = node_temperature(j);
                let s = Sampled::from_fn(|nm| relative_radiance(nm, t));
                let y = sampled_to_xyz(&s).y;
                (s, y)
            })
            .collect()
    })
}

/// The Catmull-Rom interpolation of the mired grid at `t_k` (clamped to
/// [`T_MIN_K`], [`T_MAX_K`]): node index i and the weights of nodes
/// i − 1 … i + 2.
fn catmull_rom(t_k: f32) -> (usize, [f64; 4]) {
    let m = if t_k > 0.0 { 1e6 / f64::from(t_k) } else { MIRED_MAX };
    let s = (m.clamp(MIRED_MIN, MIRED_MAX) - MIRED_FIRST_NODE) / MIRED_STEP;
    let i = (s.floor() as usize).clamp(1, NODES - 3);
    let f = s - i as f64;
    let (f2, f3) = (f * f, f * f * f);
    let w = [
        0.5 * (-f3 + 2.0 * f2 - f),
        0.5 * (3.0 * f3 - 5.0 * f2 + 2.0),
        0.5 * (-3.0 * f3 + 4.0 * f2 + f),
        0.5 * (f3 - f2),
    ];
    (i, w)
}

/// The blackbody spectrum at `t_k` over its own Y (so it integrates to
/// Y = 1), interpolated between the table's node spectra with the same
/// Catmull-Rom weights as [`Response::planck_bands`]: what a source that
/// filters a Planckian lamp by a spectrum of its own integrates (no `exp`).
pub(crate) fn planck_unit_y(t_k: f32) -> [(&'static Sampled, f64); 4] {
    let (i, w) = catmull_rom(t_k);
    let nodes = planck_nodes();
    std::array::from_fn(|k| {
        let (s, y) = &nodes[i - 1 + k];
        (s, w[k] / y)
    })
}

/// What one transmission spectrum does to every lamp family (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct Response {
    /// Per mired node: XYZ of blackbody × transmission in the three CMY
    /// bands, over the unfiltered blackbody's Y.
    planck: Vec<[Vec3; 3]>,
    /// Per LED basis spectrum: XYZ of basis × transmission (basis Y = 1).
    led: Vec<Vec3>,
    /// The transmission itself, for sources that are not mixes of the
    /// tables' bases (measured emitter spectra, measured CMY flags): they
    /// integrate it directly, see [`Response::integrate`].
    transmission: Sampled,
    /// Transmission exactly 1 everywhere (the open beam or a clear frame).
    unity: bool,
}

impl Response {
    /// Integrates `transmission` against every lamp family.
    pub fn new(transmission: &Sampled) -> Self {
        let planck = planck_nodes()
            .iter()
            .map(|(b, y)| {
                let filtered = b.mul(transmission);
                CMY_BANDS.map(|r| (sampled_to_xyz_range(&filtered, r) / *y).as_vec3())
            })
            .collect();
        let led = led_basis().iter().map(|b| sampled_to_xyz(&b.mul(transmission)).as_vec3()).collect();
        let unity = transmission.values().iter().all(|&t| t == 1.0);
        Self { planck, led, transmission: transmission.clone(), unity }
    }

    /// The open beam (transmission 1): the unfiltered lamp.
    pub fn open() -> &'static Response {
        static OPEN: OnceLock<Response> = OnceLock::new();
        OPEN.get_or_init(|| Response::new(&Sampled::constant(1.0)))
    }

    /// XYZ through this filter of a blackbody at `t_k` kelvin (clamped to
    /// [`T_MIN_K`], [`T_MAX_K`]), per CMY band, relative to the unfiltered
    /// blackbody's Y = 1 (Catmull-Rom in mired).
    pub fn planck_bands(&self, t_k: f32) -> [Vec3; 3] {
        let (i, w) = catmull_rom(t_k);
        let w = w.map(|w| w as f32);
        let (p1, p2) = (&self.planck[i], &self.planck[i + 1]);
        let (p0, p3) = (&self.planck[i - 1], &self.planck[i + 2]);
        std::array::from_fn(|b| p0[b] * w[0] + p1[b] * w[1] + p2[b] * w[2] + p3[b] * w[3])
    }

    /// Whether the transmission is exactly 1 everywhere (nothing filtered):
    /// sources with their own precomputed XYZ use it as is.
    pub fn is_unity(&self) -> bool {
        self.unity
    }

    /// XYZ of `spectrum` × this filter's transmission, integrated on the
    /// 1 nm grid (~1,400 multiply-adds, no allocation): the path for
    /// measured spectra, which are not mixes of the table bases. Sources
    /// use it only when a filter is in the beam ([`Response::is_unity`] is
    /// false); otherwise they read their own precomputed XYZ.
    pub fn integrate(&self, spectrum: &Sampled) -> DVec3 {
        product_to_xyz(spectrum, &self.transmission)
    }

    /// The transmission these tables were integrated from.
    pub fn transmission(&self) -> &Sampled {
        &self.transmission
    }

    /// XYZ through this filter of LED basis spectrum `k` (basis Y = 1).
    pub fn led_basis(&self, k: usize) -> Vec3 {
        self.led.get(k).copied().unwrap_or(Vec3::ZERO)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exact_planck(t: f64, transmission: &Sampled) -> DVec3 {
        let b = Sampled::from_fn(|nm| relative_radiance(nm, t));
        sampled_to_xyz(&b.mul(transmission)) / sampled_to_xyz(&b).y
    }

    #[test]
    fn table_matches_exact_integration() {
        // A strongly coloured filter (steep edge) stresses the interpolation.
        // Error in colour units: the unfiltered lamp's Y is 1.
        let t = Sampled::from_fn(|nm| if nm < 480.0 { 0.9 } else { 0.05 });
        let r = Response::new(&t);
        let mut worst: f64 = 0.0;
        for k in (500..=20_000).step_by(7) {
            let bands = r.planck_bands(k as f32);
            let table = (bands[0] + bands[1] + bands[2]).as_dvec3();
            let exact = exact_planck(f64::from(k), &t);
            worst = worst.max((table - exact).abs().max_element());
        }
        assert!(worst < 2e-5, "worst error {worst}");
    }

    #[test]
    fn open_response_has_unit_luminance_and_clamps() {
        let o = Response::open();
        for t in [T_MIN_K, 1000.0, 3200.0, 6000.0, T_MAX_K] {
            let b = o.planck_bands(t);
            assert!(((b[0] + b[1] + b[2]).y - 1.0).abs() < 1e-5, "{t}");
        }
        assert_eq!(o.planck_bands(10.0), o.planck_bands(T_MIN_K));
        assert_eq!(o.planck_bands(1e9), o.planck_bands(T_MAX_K));
        assert_eq!(o.planck_bands(f32::NAN), o.planck_bands(T_MIN_K));
        for k in 0..LED_BASIS {
            assert!((o.led_basis(k).y - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn unit_transmission_reproduces_open_exactly() {
        assert_eq!(&Response::new(&Sampled::from_table(405.0, 5.0, &[1.0])), Response::open());
    }

    #[test]
    fn led_bands_sit_near_the_spectral_locus() {
        // A 15 nm band at 520 nm is a saturated green: CIE 1931 spectral
        // locus at 520 nm is (0.0743, 0.8338); the band is within 0.05 of it.
        let xyz = led_basis_xyz()[1 + (520 - 390) / 5];
        let s = xyz.x + xyz.y + xyz.z;
        assert!((xyz.x / s - 0.0743).abs() < 0.05 && (xyz.y / s - 0.8338).abs() < 0.05, "{xyz}");
    }
}
