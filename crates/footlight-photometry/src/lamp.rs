//! Lamps: the source's own colour c_I and how dimming changes it.
//!
//! Vierjahn 2010, section 3.2: a fixture's colour c_I comes from its lamp's
//! correlated colour temperature, evaluated on the Planckian locus —
//! tungsten halogen nominally 3200 K, discharge (HMI) 6000 K. Tungsten is
//! dimmed by lowering the supply voltage, which cools the filament:
//! T ≈ v^(1/8) · T̂ (\[FB78, Osr03\]), so it reddens as it dims. A discharge
//! lamp is dimmed by a mechanical shutter and keeps its colour.
//!
//! Two families the paper does not cover are added for today's rigs:
//!
//! * **LED** fixtures mix emitters (RGB, RGBW, RGBA, …) electronically. Each
//!   [`Emitter`] is given by its chromaticity (CIE xy from the datasheet, or
//!   a linear-sRGB colour) and its luminous share at full. For filtering by
//!   a gel an emitter needs a spectrum, which xy alone does not fix; Footlight
//!   uses a metamer (estimated): the non-negative mix of a flat
//!   (equal-energy) spectrum and two adjacent narrow bands (15 nm FWHM,
//!   5 nm apart) whose chromaticity is the emitter's — i.e. a narrow line at
//!   the emitter's dominant wavelength diluted with white by its purity. The
//!   unfiltered colour is exact for any chromaticity inside that band
//!   polygon (all of sRGB and typical LED primaries); outside it is moved
//!   onto the polygon's edge.
//!
//!   An emitter with a **measured spectrum** ([`Emitter::from_spectrum`],
//!   e.g. a GDTF `<Measurement>`) uses that spectrum instead of the metamer:
//!   its unfiltered XYZ is integrated once, and through a filter it is
//!   integrated against the filter's transmission
//!   ([`Response::integrate`], ~1,400 multiply-adds per emitter per
//!   frame, only while a filter is in the beam). The mix of several
//!   emitters is Σ level · share · XYZ(spectrum)/Y(spectrum).
//! * **CMY** colour mixing on a white (discharge-type) source: three
//!   dichroic flags, each covering a fraction of the beam. Modelled as ideal
//!   subtractive filters (estimated edges): yellow removes < 490 nm, magenta
//!   490-589 nm, cyan ≥ 590 nm, each in proportion to its insertion.
//!   Flags with a **measured** full-insertion transmission T_f ([`CmyFilters`],
//!   e.g. a GDTF `Filter` with a `<Measurement>`) use it instead: a flag
//!   inserted by c covers c of the beam, so the beam passes (1 − c) + c·T_f(λ),
//!   and the three flags in series pass the product. That product is a sum
//!   of 8 subset products Π_{f∈S} T_f, each integrated once over the
//!   Planckian table ([`Response`]), so a frame is 8 table lookups; with a
//!   filter on top (a wheel gel) it is one pass over the 1 nm grid.
//!
//! Normalisation: c_I is linear sRGB with luminance Y = 1 for the lamp's
//! own full-output white. Tungsten and discharge lamps are therefore always
//! Y = 1 (their output is v · Î). A CMY lamp's Y is the flags' luminous
//! transmittance, and an LED's Y is Σ level · share / Σ share, because the
//! datasheet Î is measured at full white. At v = 0 every lamp is exactly black.

use crate::cie::{cmf_sample, sampled_to_xyz};
use crate::planck::relative_radiance;
use crate::response::{CMY_BANDS, LED_BASIS, Response, T_MAX_K, T_MIN_K, led_basis, led_basis_xyz, planck_unit_y};
use crate::spectrum::{SAMPLES, Sampled};
use crate::srgb;
use glam::{DMat3, DVec3, Vec2, Vec3};
use std::sync::Arc;

/// Nominal colour temperature of stage tungsten-halogen lamps, K (paper, section 3.2).
pub const TUNGSTEN_CCT_K: f32 = 3200.0;
/// Nominal colour temperature of stage discharge (HMI) lamps, K (paper, section 3.2).
pub const HMI_CCT_K: f32 = 6000.0;

/// A fixture's light source and its current colour-mixing state.
#[derive(Clone, Debug, PartialEq)]
pub enum Lamp {
    /// Tungsten halogen at `cct_full` kelvin at full; dims along T ≈ v^(1/8) · T̂.
    Tungsten {
        /// Colour temperature at full, K (nominally 3200).
        cct_full: f32,
    },
    /// Discharge lamp (HMI) dimmed by a shutter: Planckian at `cct`, no colour shift.
    Discharge {
        /// Correlated colour temperature, K (nominally 6000).
        cct: f32,
    },
    /// LED engine mixing emitters additively; each emitter's `level` is its current mix level.
    Led {
        /// The emitters (R, G, B, W, A, …).
        emitters: Vec<Emitter>,
    },
    /// White source at `cct` (shutter-dimmed) with subtractive CMY flags, each 0 (out) to 1 (full).
    Cmy {
        /// Correlated colour temperature of the source, K.
        cct: f32,
        /// Cyan flag insertion 0..1 (removes ≥ 590 nm).
        cyan: f32,
        /// Magenta flag insertion 0..1 (removes 490-589 nm).
        magenta: f32,
        /// Yellow flag insertion 0..1 (removes < 490 nm).
        yellow: f32,
        /// Measured flag transmissions; `None`: the ideal band model above.
        filters: Option<Arc<CmyFilters>>,
    },
}

/// Three CMY flags' transmission at full insertion, measured or ideal, with
/// the precomputed responses of every product of them (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct CmyFilters {
    /// Full-insertion transmission of [cyan, magenta, yellow].
    flags: [Sampled; 3],
    /// Which flags were measured (the others use the ideal band edges).
    measured: [bool; 3],
    /// Response of Π_{f∈S} T_f for subset S (bit 0 cyan, 1 magenta, 2 yellow).
    subsets: Vec<Response>,
}

impl CmyFilters {
    /// Flags from full-insertion transmissions in 0..1 (cyan, magenta,
    /// yellow); a `None` flag keeps the ideal band model (estimated edges).
    /// Integrates 7 filter responses: milliseconds, once per fixture type.
    pub fn new(cyan: Option<Sampled>, magenta: Option<Sampled>, yellow: Option<Sampled>) -> Self {
        let measured = [cyan.is_some(), magenta.is_some(), yellow.is_some()];
        let mut given = [cyan, magenta, yellow];
        let flags: [Sampled; 3] = std::array::from_fn(|f| given[f].take().unwrap_or_else(|| ideal_flag(f)));
        let subsets = (0..8usize)
            .map(|s| {
                if s == 0 {
                    return Response::open().clone();
                }
                let mut t = Sampled::constant(1.0);
                for (f, flag) in flags.iter().enumerate() {
                    if s & (1 << f) != 0 {
                        t = t.mul(flag);
                    }
                }
                Response::new(&t)
            })
            .collect();
        Self { flags, measured, subsets }
    }

    /// Whether flag `f` (0 cyan, 1 magenta, 2 yellow) was measured.
    pub fn is_measured(&self, f: usize) -> bool {
        self.measured.get(f).copied().unwrap_or(false)
    }

    /// Full-insertion transmission of flag `f` (0 cyan, 1 magenta, 2 yellow).
    pub fn flag(&self, f: usize) -> Option<&Sampled> {
        self.flags.get(f)
    }

    /// Transmission of the three flags in series at insertions `c`:
    /// Π_f ((1 − c_f) + c_f · T_f(λ)).
    pub fn transmission(&self, c: [f32; 3]) -> Sampled {
        let mut t = Sampled::constant(1.0);
        for (f, flag) in self.flags.iter().enumerate() {
            t = t.mul(&Sampled::lerp(&Sampled::constant(1.0), flag, f64::from(unit(c[f]))));
        }
        t
    }

    /// XYZ of a blackbody at `t_k` (unfiltered Y = 1) through the flags at
    /// insertions `c` and then `response`'s filter: one pass over the 1 nm
    /// grid (the table's node spectra interpolated as in
    /// [`Response::planck_bands`], flags and filter multiplied in, no
    /// allocation). The path for a filter on top of measured flags.
    fn through(&self, t_k: f32, c: [f32; 3], response: &Response) -> Vec3 {
        let nodes = planck_unit_y(t_k);
        let c = c.map(|c| f64::from(unit(c)));
        let g = response.transmission().values();
        let flags = self.flags.each_ref().map(Sampled::values);
        let mut xyz = DVec3::ZERO;
        for i in 0..SAMPLES {
            let b: f64 = nodes.iter().map(|(s, w)| s.values()[i] * w).sum();
            let pass: f64 = (0..3).map(|f| 1.0 - c[f] + c[f] * flags[f][i]).product();
            xyz += cmf_sample(i) * (b * pass * g[i]);
        }
        xyz.as_vec3()
    }

    /// Weight of subset S in the expansion of the product: Π_{f∈S} c_f · Π_{f∉S} (1 − c_f).
    fn weights(c: [f32; 3]) -> [f32; 8] {
        let c = c.map(unit);
        std::array::from_fn(|s| (0..3).map(|f| if s & (1 << f) != 0 { c[f] } else { 1.0 - c[f] }).product())
    }
}

/// The ideal flag of the band model: 0 in its band, 1 elsewhere
/// (f = 0 cyan: red band, 1 magenta: green, 2 yellow: blue).
fn ideal_flag(f: usize) -> Sampled {
    let band = CMY_BANDS[2 - f.min(2)].clone();
    Sampled::from_fn(|nm| if band.contains(&((nm - 360.0).round() as usize)) { 0.0 } else { 1.0 })
}

/// How an emitter's colour is given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Chroma {
    /// CIE 1931 xy chromaticity (as LED datasheets give it).
    Xy(Vec2),
    /// A linear-sRGB colour (only its chromaticity is used).
    LinearSrgb(Vec3),
}

/// One LED emitter: its colour, luminous share at full, and current level.
#[derive(Clone, Debug, PartialEq)]
pub struct Emitter {
    /// Name as the fixture calls it ("red", "lime", …).
    pub name: String,
    /// Luminous share of this emitter at full, relative to the others (any scale).
    pub share: f32,
    /// Current mix level 0..1 (from DMX), clamped when used.
    pub level: f32,
    chroma: Chroma,
    /// Metamer weights on the LED basis (see the module doc); Σ weights = 1.
    proxy: [(usize, f64); 3],
    /// A measured spectrum, used instead of the metamer when present.
    measured: Option<Arc<MeasuredSpectrum>>,
}

/// An emitter's measured spectrum, scaled to Y = 1, with its XYZ.
#[derive(Clone, Debug, PartialEq)]
struct MeasuredSpectrum {
    spectrum: Sampled,
    xyz: DVec3,
}

impl Emitter {
    /// An emitter at full level. An unusable colour (non-finite, y ≤ 0, or a
    /// non-positive-luminance sRGB value) gives an emitter that emits nothing.
    pub fn new(name: impl Into<String>, chroma: Chroma, share: f32) -> Self {
        Self { name: name.into(), share, level: 1.0, chroma, proxy: metamer(chroma), measured: None }
    }

    /// An emitter at full level from its measured spectral power
    /// distribution (any scale, e.g. W/m²/nm on the 1 nm grid): it mixes
    /// from this spectrum, not from a metamer. `share` is its luminous share
    /// at full as the source gives it; `None` (or non-positive) takes the
    /// spectrum's own luminance Y = Σ S(λ) ȳ(λ), which is right when all
    /// emitters of a fixture were measured on the same scale. Negative
    /// values (a spectrometer's noise floor) count as zero. `None` for a
    /// spectrum with no luminance or with non-finite values.
    pub fn from_spectrum(name: impl Into<String>, spectrum: &Sampled, share: Option<f32>) -> Option<Self> {
        if spectrum.values().iter().any(|v| !v.is_finite()) {
            return None;
        }
        let spectrum = &Sampled::from_fn(|nm| spectrum.at(nm).max(0.0));
        let xyz = sampled_to_xyz(spectrum);
        if !(xyz.y > 0.0 && xyz.is_finite()) {
            return None;
        }
        let mut unit_y = Sampled::constant(0.0);
        unit_y.add_scaled(spectrum, 1.0 / xyz.y);
        let sum = xyz.x + xyz.y + xyz.z;
        let chroma = Chroma::Xy(Vec2::new((xyz.x / sum) as f32, (xyz.y / sum) as f32));
        let share = match share {
            Some(s) if s > 0.0 && s.is_finite() => s,
            _ => xyz.y as f32,
        };
        // A luminance past f32's range (absurd measured energies): no share.
        if !share.is_finite() {
            return None;
        }
        let measured = Some(Arc::new(MeasuredSpectrum { spectrum: unit_y, xyz: xyz / xyz.y }));
        Some(Self { name: name.into(), share, level: 1.0, chroma, proxy: metamer(chroma), measured })
    }

    /// The measured spectrum (scaled to Y = 1), if the emitter has one.
    pub fn spectrum(&self) -> Option<&Sampled> {
        self.measured.as_ref().map(|m| &m.spectrum)
    }

    /// The colour it was given.
    pub fn chroma(&self) -> Chroma {
        self.chroma
    }

    /// XYZ (Y = 1, or zero for an unusable colour) that the emitter renders
    /// as: its measured spectrum's, else its chromaticity or the nearest
    /// point of the band polygon.
    pub fn rendered_xyz(&self) -> Vec3 {
        if let Some(m) = &self.measured {
            return m.xyz.as_vec3();
        }
        let basis = led_basis_xyz();
        self.proxy.iter().map(|&(k, w)| basis[k] * w).sum::<DVec3>().as_vec3()
    }

    fn weight(&self) -> f32 {
        unit(self.level) * nonneg(self.share)
    }
}

impl Lamp {
    /// Tungsten halogen at the nominal 3200 K.
    pub fn tungsten() -> Self {
        Self::Tungsten { cct_full: TUNGSTEN_CCT_K }
    }

    /// HMI discharge at the nominal 6000 K.
    pub fn hmi() -> Self {
        Self::Discharge { cct: HMI_CCT_K }
    }

    /// Colour temperature at dimmer `v`, K, clamped to the evaluated range
    /// [500, 20000] K: T = v^(1/8) · T̂ for tungsten (\[FB78, Osr03\]), the
    /// fixed CCT for discharge and CMY. `None` for LEDs, at v = 0, and for a
    /// non-finite or non-positive CCT.
    pub fn temperature(&self, v: f32) -> Option<f32> {
        let v = unit(v);
        if v == 0.0 {
            return None;
        }
        let (t, scale) = match *self {
            Self::Tungsten { cct_full } => (cct_full, v.sqrt().sqrt().sqrt()), // v^(1/8), section 3.2
            Self::Discharge { cct } | Self::Cmy { cct, .. } => (cct, 1.0),
            Self::Led { .. } => return None,
        };
        (t.is_finite() && t > 0.0).then(|| (t * scale).clamp(T_MIN_K, T_MAX_K))
    }

    /// c_I of eq. 4: the lamp's colour at dimmer `v` in linear sRGB, Y = 1 for
    /// its own full white (see the module doc), black at v = 0, never
    /// negative or NaN (out-of-gamut colours are desaturated at equal Y).
    pub fn colour(&self, v: f32) -> Vec3 {
        srgb::fit_gamut(srgb::xyz_to_linear_srgb(self.xyz_through(v, Response::open())))
    }

    /// CIE XYZ of this lamp at dimmer `v` seen through a filter with
    /// precomputed `response`, relative to the lamp's own full white (Y = 1).
    /// Linear in the filter's transmission. Not gamut-mapped.
    pub fn xyz_through(&self, v: f32, response: &Response) -> Vec3 {
        if unit(v) == 0.0 {
            return Vec3::ZERO;
        }
        match self {
            Self::Tungsten { .. } | Self::Discharge { .. } => match self.temperature(v) {
                Some(t) => response.planck_bands(t).iter().sum(),
                None => Vec3::ZERO,
            },
            Self::Cmy { cyan, magenta, yellow, filters, .. } => match (self.temperature(v), filters) {
                (Some(t), None) => {
                    let b = response.planck_bands(t);
                    let pass = cmy_pass(*cyan, *magenta, *yellow);
                    b[0] * pass[0] + b[1] * pass[1] + b[2] * pass[2]
                }
                (Some(t), Some(f)) if response.is_unity() => {
                    let w = CmyFilters::weights([*cyan, *magenta, *yellow]);
                    let mut xyz = Vec3::ZERO;
                    for (s, r) in f.subsets.iter().enumerate() {
                        if w[s] > 0.0 {
                            let b = r.planck_bands(t);
                            xyz += (b[0] + b[1] + b[2]) * w[s];
                        }
                    }
                    xyz
                }
                (Some(t), Some(f)) => f.through(t, [*cyan, *magenta, *yellow], response),
                (None, _) => Vec3::ZERO,
            },
            Self::Led { emitters } => {
                let total: f32 = emitters.iter().map(|e| nonneg(e.share)).sum();
                if !(total > 0.0 && total.is_finite()) {
                    return Vec3::ZERO;
                }
                let mut xyz = Vec3::ZERO;
                for e in emitters {
                    let w = e.weight() / total;
                    if w > 0.0 {
                        if let Some(m) = &e.measured {
                            let c = if response.is_unity() { m.xyz } else { response.integrate(&m.spectrum) };
                            xyz += c.as_vec3() * w;
                            continue;
                        }
                        for &(k, p) in &e.proxy {
                            xyz += response.led_basis(k) * (w * p as f32);
                        }
                    }
                }
                xyz
            }
        }
    }

    /// The lamp's relative spectral power at dimmer `v`, scaled so that its
    /// own full white has Y = 1: what [`Lamp::xyz_through`] integrates from
    /// its tables. `None` when the lamp is dark. For references and checks;
    /// this allocates and integrates, so the frame loop does not use it.
    pub fn spectrum(&self, v: f32) -> Option<Sampled> {
        if unit(v) == 0.0 {
            return None;
        }
        match self {
            Self::Tungsten { .. } | Self::Discharge { .. } | Self::Cmy { .. } => {
                let t = f64::from(self.temperature(v)?);
                let b = Sampled::from_fn(|nm| relative_radiance(nm, t));
                let y = sampled_to_xyz(&b).y;
                let pass = match *self {
                    Self::Cmy { cyan, magenta, yellow, .. } => cmy_pass(cyan, magenta, yellow),
                    _ => [1.0; 3],
                };
                let filter = match self {
                    Self::Cmy { cyan, magenta, yellow, filters: Some(f), .. } => {
                        f.transmission([*cyan, *magenta, *yellow])
                    }
                    _ => Sampled::from_fn(|nm| {
                        let i = (nm - 360.0).round() as usize;
                        let band = CMY_BANDS.iter().position(|r| r.contains(&i)).unwrap_or(2);
                        f64::from(pass[band])
                    }),
                };
                let mut out = Sampled::constant(0.0);
                out.add_scaled(&b.mul(&filter), 1.0 / y);
                Some(out)
            }
            Self::Led { emitters } => {
                let total: f32 = emitters.iter().map(|e| nonneg(e.share)).sum();
                let mut out = Sampled::constant(0.0);
                if total > 0.0 {
                    for e in emitters {
                        let w = f64::from(e.weight() / total);
                        if let Some(m) = &e.measured {
                            out.add_scaled(&m.spectrum, w);
                            continue;
                        }
                        for &(k, p) in &e.proxy {
                            out.add_scaled(&led_basis()[k], w * p);
                        }
                    }
                }
                Some(out)
            }
        }
    }
}

/// Fraction of each CMY band [blue, green, red] that the flags let through:
/// a flag inserted by c covers c of the beam and removes its band there.
fn cmy_pass(cyan: f32, magenta: f32, yellow: f32) -> [f32; 3] {
    [1.0 - unit(yellow), 1.0 - unit(magenta), 1.0 - unit(cyan)]
}

/// Clamps to [0, 1]; NaN → 0.
fn unit(x: f32) -> f32 {
    if x > 0.0 { x.min(1.0) } else { 0.0 }
}

/// Clamps to [0, ∞) and finite; NaN and ∞ → 0.
fn nonneg(x: f32) -> f32 {
    if x > 0.0 && x.is_finite() { x } else { 0.0 }
}

/// XYZ with Y = 1 for an emitter colour, or `None` if it has none.
fn target_xyz(chroma: Chroma) -> Option<DVec3> {
    let xyz = match chroma {
        Chroma::Xy(c) => srgb::xy_to_xyz(c, 1.0),
        Chroma::LinearSrgb(rgb) => srgb::linear_srgb_to_xyz(rgb.max(Vec3::ZERO)),
    }
    .as_dvec3();
    (xyz.is_finite() && xyz.y > 0.0 && xyz.min_element() >= 0.0).then(|| xyz / xyz.y)
}

/// Metamer of `chroma` on the LED basis: flat + two adjacent bands with
/// non-negative weights (fan triangulation of the band polygon from the
/// flat spectrum's white point). Σ weights = 1 (each basis has Y = 1).
fn metamer(chroma: Chroma) -> [(usize, f64); 3] {
    let Some(target) = target_xyz(chroma) else {
        return [(0, 0.0); 3];
    };
    let basis = led_basis_xyz();
    let mut best: Option<([(usize, f64); 3], f64)> = None;
    for a in 1..LED_BASIS {
        let b = if a + 1 < LED_BASIS { a + 1 } else { 1 }; // last band closes to the first (purples)
        let m = DMat3::from_cols(basis[0], basis[a], basis[b]);
        if m.determinant().abs() < 1e-12 {
            continue;
        }
        let w = m.inverse() * target;
        let min = w.min_element();
        if best.as_ref().is_none_or(|(_, m)| min > *m) {
            best = Some(([(0, w.x), (a, w.y), (b, w.z)], min));
        }
        if min >= -1e-9 {
            break;
        }
    }
    let Some((mut w, _)) = best else {
        return [(0, 1.0), (0, 0.0), (0, 0.0)];
    };
    for p in &mut w {
        p.1 = p.1.max(0.0);
    }
    let sum: f64 = w.iter().map(|p| p.1).sum();
    if sum > 0.0 {
        w.iter_mut().for_each(|p| p.1 /= sum);
        w
    } else {
        [(0, 1.0), (0, 0.0), (0, 0.0)]
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::dimmer::DimmerCurve;
    use crate::srgb::{cct_mccamy, luminance, xy};

    fn rgb_led() -> Lamp {
        // sRGB primaries with luminous shares equal to their sRGB luminance:
        // at full the mix is D65 white, linear RGB (1, 1, 1).
        Lamp::Led {
            emitters: vec![
                Emitter::new("red", Chroma::LinearSrgb(Vec3::X), 0.2126),
                Emitter::new("green", Chroma::LinearSrgb(Vec3::Y), 0.7152),
                Emitter::new("blue", Chroma::LinearSrgb(Vec3::Z), 0.0722),
            ],
        }
    }

    pub(crate) fn every_kind() -> Vec<Lamp> {
        vec![
            Lamp::tungsten(),
            Lamp::hmi(),
            rgb_led(),
            Lamp::Cmy { cct: 6000.0, cyan: 0.3, magenta: 0.6, yellow: 0.1, filters: None },
        ]
    }

    #[test]
    fn tungsten_reddens_along_the_planckian_locus_as_it_dims() {
        let lamp = Lamp::tungsten();
        let mut last_x = 0.0;
        let mut last_cct = f32::INFINITY;
        for d in (1..=255u8).rev() {
            let v = DimmerCurve::Linear.from_dmx8(d);
            let c = xy(lamp.xyz_through(v, Response::open())).unwrap();
            assert!(c.x > last_x, "DMX {d}: x {} did not rise from {last_x}", c.x);
            last_x = c.x;
            let t = 3200.0 * f64::from(v).powf(0.125); // the paper's T ≈ v^(1/8) T̂
            if t >= 1700.0 {
                // Kim et al. (2002) locus fit, independent of our tables.
                let (kx, ky) = crate::planck::tests::kim_locus(t);
                assert!((f64::from(c.x) - kx).hypot(f64::from(c.y) - ky) < 1e-3, "DMX {d} ({t} K): {c}");
                let cct = cct_mccamy(c);
                assert!(cct < last_cct, "DMX {d}: CCT {cct} did not fall from {last_cct}");
                last_cct = cct;
                assert!((f64::from(cct) / t - 1.0).abs() < 0.02, "DMX {d}: McCamy {cct} K vs T {t} K");
            }
        }
        assert_eq!(lamp.temperature(1.0), Some(3200.0));
        assert!((lamp.temperature(0.5).unwrap() - 3200.0 * 0.5f32.powf(0.125)).abs() < 1e-3);
    }

    #[test]
    fn full_white_has_unit_luminance_at_every_level() {
        for lamp in [Lamp::tungsten(), Lamp::hmi()] {
            for curve in [DimmerCurve::Linear, DimmerCurve::SquareLaw, DimmerCurve::Theatre] {
                for d in 1..=255u8 {
                    let c = lamp.colour(curve.from_dmx8(d));
                    assert!((luminance(c) - 1.0).abs() < 1e-4 && c.min_element() >= 0.0, "{lamp:?} {curve:?} {d}: {c}");
                }
            }
        }
        // 3200 K tungsten is warm: R > G > B.
        let c = Lamp::tungsten().colour(1.0);
        assert!(c.x > c.y && c.y > c.z, "{c}");
    }

    #[test]
    fn zero_and_invalid_levels_are_exactly_black() {
        let mut lamps = every_kind();
        lamps.push(Lamp::Tungsten { cct_full: f32::NAN });
        lamps.push(Lamp::Discharge { cct: -5.0 });
        lamps.push(Lamp::Led { emitters: vec![] });
        for lamp in &lamps {
            for v in [0.0, -1.0, f32::NAN, f32::NEG_INFINITY] {
                assert_eq!(lamp.colour(v), Vec3::ZERO, "{lamp:?} at {v}");
                assert_eq!(lamp.spectrum(v), None);
            }
            for v in [1e-30, 1e-7, 0.5, 1.0, 2.0, f32::INFINITY] {
                let c = lamp.colour(v);
                assert!(c.is_finite() && c.min_element() >= 0.0, "{lamp:?} at {v}: {c}");
            }
        }
        assert_eq!(Lamp::Tungsten { cct_full: f32::NAN }.colour(1.0), Vec3::ZERO);
    }

    #[test]
    fn discharge_keeps_its_colour_when_dimmed() {
        let lamp = Lamp::hmi();
        assert_eq!(lamp.colour(0.01), lamp.colour(1.0));
        let c = xy(lamp.xyz_through(1.0, Response::open())).unwrap();
        assert!((c.x - 0.3221).abs() < 1e-3 && (c.y - 0.3318).abs() < 1e-3, "{c}");
    }

    #[test]
    fn rgb_led_mixes_additively() {
        let mut lamp = rgb_led();
        let white = lamp.colour(1.0);
        assert!((white - Vec3::ONE).abs().max_element() < 1e-4, "{white}");
        if let Lamp::Led { emitters } = &mut lamp {
            emitters[1].level = 0.0;
            emitters[2].level = 0.0;
        }
        // Red alone: the sRGB red primary at its luminous share 0.2126.
        let red = lamp.colour(0.3);
        assert!((red - Vec3::X).abs().max_element() < 1e-4, "{red}");
        assert!((luminance(red) - 0.2126).abs() < 1e-4);
    }

    #[test]
    fn emitters_keep_their_chromaticity() {
        // Datasheet-like LED colours inside the band polygon, and sRGB's primaries.
        for (x, y) in [(0.69, 0.30), (0.17, 0.70), (0.14, 0.05), (0.55, 0.42), (0.3127, 0.3290), (0.25, 0.10)] {
            let e = Emitter::new("e", Chroma::Xy(Vec2::new(x, y)), 1.0);
            let c = xy(e.rendered_xyz()).unwrap();
            assert!((c.x - x).abs() < 1e-4 && (c.y - y).abs() < 1e-4, "({x}, {y}) -> {c}");
            assert!((e.rendered_xyz().y - 1.0).abs() < 1e-5);
        }
        // Outside the spectral locus: moved onto the polygon, still Y = 1.
        let e = Emitter::new("impossible", Chroma::Xy(Vec2::new(0.05, 0.95)), 1.0);
        assert!((e.rendered_xyz().y - 1.0).abs() < 1e-5);
        for bad in [Chroma::Xy(Vec2::new(0.3, 0.0)), Chroma::Xy(Vec2::NAN), Chroma::LinearSrgb(Vec3::ZERO)] {
            assert_eq!(Emitter::new("bad", bad, 1.0).rendered_xyz(), Vec3::ZERO, "{bad:?}");
        }
    }

    #[test]
    fn cmy_flags_subtract_their_bands() {
        let open = Lamp::Cmy { cct: 6000.0, cyan: 0.0, magenta: 0.0, yellow: 0.0, filters: None };
        assert!((open.colour(1.0) - Lamp::hmi().colour(1.0)).abs().max_element() < 1e-6);
        let full = Lamp::Cmy { cct: 6000.0, cyan: 1.0, magenta: 1.0, yellow: 1.0, filters: None };
        assert_eq!(full.colour(1.0), Vec3::ZERO);
        // Each full flag removes one band; the three bands sum to the whole, so
        // the three single-flag luminances sum to 3 − 1 = 2.
        let y =
            |c, m, ye| luminance(Lamp::Cmy { cct: 6000.0, cyan: c, magenta: m, yellow: ye, filters: None }.colour(1.0));
        assert!((y(1.0, 0.0, 0.0) + y(0.0, 1.0, 0.0) + y(0.0, 0.0, 1.0) - 2.0).abs() < 1e-4);
        // A half-inserted flag removes half of its band.
        assert!((y(0.5, 0.0, 0.0) - (1.0 + y(1.0, 0.0, 0.0)) / 2.0).abs() < 1e-5);
        // Magenta + yellow leave red.
        let red = Lamp::Cmy { cct: 6000.0, cyan: 0.0, magenta: 1.0, yellow: 1.0, filters: None }.colour(1.0);
        assert!(red.x > 10.0 * red.y && red.x > 10.0 * red.z, "{red}");
    }

    fn gaussian(peak: f64, fwhm: f64, scale: f64) -> Sampled {
        let sigma = fwhm / (2.0 * (2.0 * std::f64::consts::LN_2).sqrt());
        Sampled::from_fn(|nm| scale * (-0.5 * ((nm - peak) / sigma).powi(2)).exp())
    }

    #[test]
    fn measured_emitters_mix_their_spectra() {
        // Two measured emitters at full: the mix is the summed spectrum (the
        // file's absolute scale, so shares default to each spectrum's Y).
        let (r, b) = (gaussian(630.0, 20.0, 2.0), gaussian(460.0, 25.0, 5.0));
        let mut lamp = Lamp::Led {
            emitters: vec![
                Emitter::from_spectrum("red", &r, None).unwrap(),
                Emitter::from_spectrum("blue", &b, None).unwrap(),
            ],
        };
        let mut sum = r.clone();
        sum.add_scaled(&b, 1.0);
        let want = sampled_to_xyz(&sum);
        let got = lamp.xyz_through(1.0, Response::open()).as_dvec3();
        // Relative to the full white (Y = 1): compare chromaticity, and Y = 1.
        let (gs, ws) = (got.x + got.y + got.z, want.x + want.y + want.z);
        assert!((got.x / gs - want.x / ws).abs() < 1e-6 && (got.y / gs - want.y / ws).abs() < 1e-6, "{got} {want}");
        assert!((got.y - 1.0).abs() < 1e-6);
        // Blue alone at half level: its share of Y at full, halved.
        if let Lamp::Led { emitters } = &mut lamp {
            emitters[0].level = 0.0;
            emitters[1].level = 0.5;
        }
        let y_blue = sampled_to_xyz(&b).y / want.y;
        assert!((f64::from(lamp.xyz_through(1.0, Response::open()).y) - 0.5 * y_blue).abs() < 1e-6);
        // Through a filter: the direct integral of spectrum × transmission.
        let t = Sampled::from_fn(|nm| if nm < 500.0 { 0.8 } else { 0.1 });
        let through = lamp.xyz_through(1.0, &Response::new(&t)).as_dvec3();
        let exact = sampled_to_xyz(&b.mul(&t)) * (0.5 / want.y);
        assert!((through - exact).abs().max_element() < 1e-6, "{through} {exact}");
        // The lamp's spectrum is what it integrates.
        let s = lamp.spectrum(1.0).unwrap();
        assert!((sampled_to_xyz(&s) - lamp.xyz_through(1.0, Response::open()).as_dvec3()).abs().max_element() < 1e-5);
        // A given share wins over the spectrum's luminance; unusable spectra give None.
        assert_eq!(Emitter::from_spectrum("r", &r, Some(3.0)).unwrap().share, 3.0);
        assert!(Emitter::from_spectrum("dark", &Sampled::constant(0.0), None).is_none());
        assert!(Emitter::from_spectrum("nan", &Sampled::constant(f64::NAN), None).is_none());
        assert!(Emitter::from_spectrum("neg", &Sampled::constant(-1.0), None).is_none());
        // Energies so large that their luminance leaves f32: no share, no emitter.
        assert!(Emitter::from_spectrum("huge", &Sampled::constant(1e300), None).is_none());
        // Noise below zero counts as zero: the same colour as the clean line.
        let noisy = Sampled::from_fn(|nm| r.at(nm) - if (nm as i64) % 7 == 0 { 1e-3 } else { 0.0 });
        let clean = Sampled::from_fn(|nm| (r.at(nm) - if (nm as i64) % 7 == 0 { 1e-3 } else { 0.0 }).max(0.0));
        let e = Emitter::from_spectrum("noisy", &noisy, None).unwrap();
        assert_eq!(
            e.rendered_xyz().as_dvec3(),
            (sampled_to_xyz(&clean) / sampled_to_xyz(&clean).y).as_vec3().as_dvec3()
        );
    }

    #[test]
    fn ideal_cmy_filters_reproduce_the_band_model() {
        let ideal = Some(Arc::new(CmyFilters::new(None, None, None)));
        for (c, m, y) in [(0.0, 0.0, 0.0), (0.3, 0.6, 0.1), (1.0, 0.0, 0.5), (1.0, 1.0, 1.0)] {
            for cct in [3200.0, 6000.0] {
                let band = Lamp::Cmy { cct, cyan: c, magenta: m, yellow: y, filters: None };
                let table = Lamp::Cmy { cct, cyan: c, magenta: m, yellow: y, filters: ideal.clone() };
                let d = (band.xyz_through(1.0, Response::open()) - table.xyz_through(1.0, Response::open())).abs();
                assert!(d.max_element() < 1e-5, "({c}, {m}, {y}) at {cct} K: {d}");
            }
        }
    }

    #[test]
    fn measured_cmy_flags_match_direct_integration() {
        // Smooth measured flags that do not look like the ideal bands.
        let cyan = Sampled::from_fn(|nm| 0.05 + 0.9 / (1.0 + ((nm - 585.0) / 12.0).exp()));
        let magenta = Sampled::from_fn(|nm| 1.0 - 0.85 * (-0.5 * ((nm - 540.0) / 30.0).powi(2)).exp());
        let yellow = Sampled::from_fn(|nm| 0.92 / (1.0 + ((505.0 - nm) / 10.0).exp()));
        let f = Arc::new(CmyFilters::new(Some(cyan.clone()), Some(magenta.clone()), Some(yellow.clone())));
        assert!(f.is_measured(0) && f.is_measured(2));
        let gel = Sampled::from_fn(|nm| if nm < 600.0 { 0.7 } else { 0.2 });
        for (c, m, y) in [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.25, 0.5, 0.75), (1.0, 1.0, 1.0)] {
            for cct in [3000.0f32, 6000.0] {
                let lamp = Lamp::Cmy { cct, cyan: c, magenta: m, yellow: y, filters: Some(f.clone()) };
                let b = Sampled::from_fn(|nm| relative_radiance(nm, f64::from(cct)));
                let y0 = sampled_to_xyz(&b).y;
                // Written out here: (1 − c) + c·T per flag, in series.
                let pass = Sampled::from_fn(|nm| {
                    [(c, &cyan), (m, &magenta), (y, &yellow)]
                        .iter()
                        .map(|(k, t)| 1.0 - f64::from(*k) + f64::from(*k) * t.at(nm))
                        .product()
                });
                for (t, resp) in [(None, Response::open().clone()), (Some(&gel), Response::new(&gel))] {
                    let mut s = b.mul(&pass);
                    if let Some(g) = t {
                        s = s.mul(g);
                    }
                    let exact = sampled_to_xyz(&s) / y0;
                    let got = lamp.xyz_through(1.0, &resp).as_dvec3();
                    assert!(
                        (got - exact).abs().max_element() < 2e-5,
                        "({c}, {m}, {y}) {cct} K gel {}: {got} vs {exact}",
                        t.is_some()
                    );
                }
            }
        }
    }
}
