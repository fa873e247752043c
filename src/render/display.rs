//! From linear luminance to display pixels: white balance, exposure, sRGB.
//!
//! Exposure is a fixed user setting, never automatic: by default a white
//! Lambert surface under 1000 lx (luminance 1000/π cd/m²) is display white.
//! White balance is a camera's (Vierjahn 2010, section 3.3; gains from
//! footlight-photometry, luminance-preserving): [`Display::default`] makes
//! a 3200 K tungsten lamp at full neutral; `render` and `run` default to
//! `auto`, the rig's own white at full ([`white_balance_for`]).
//! Values above white clip at the display, like an overexposed camera,
//! unless the display has a highlight roll-off ([`HighlightRolloff`], on by
//! default in the live daemon): then beams brighter than white keep their
//! gradation. The roll-off is the one tone curve of every compositor (CPU
//! here, the GPU's WGSL and the browser's GLSL in `shaders/`, which get
//! its two constants as uniforms). A non-finite value is an error found
//! before this step ([`check_finite`]), never clamped away here. Stills can also be written linear and unclipped
//! ([`write_exr`], [`write_pfm`]): cd/m² times the white-balance gains only.

use glam::Vec3;

/// Illuminance (lx) on a white Lambert surface that maps to display white by default.
pub const DEFAULT_WHITE_LUX: f32 = 1000.0;

/// Display settings applied after the composite (paper section 3.3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Display {
    /// Linear multiplier from cd/m² to display units (1 = white).
    pub exposure: f32,
    /// Per-channel white-balance gains (1 = none).
    pub white_balance: Vec3,
    /// Highlight roll-off applied to display-linear colour before the
    /// transfer function; `None` clips at white.
    pub rolloff: Option<HighlightRolloff>,
}

impl Default for Display {
    fn default() -> Self {
        Self::for_white_lux(DEFAULT_WHITE_LUX)
    }
}

impl Display {
    /// Exposure such that a white Lambert surface under `lux` is display
    /// white, white-balanced for tungsten 3200 K at full.
    pub fn for_white_lux(lux: f32) -> Self {
        Self { white_balance: footlight_photometry::WhiteBalance::default().gains, ..Self::neutral(lux) }
    }

    /// As [`Display::for_white_lux`] without white balance (gains 1): linear
    /// RGB goes to the display unchanged (analytic tests, RGB stand-in lights).
    pub fn neutral(lux: f32) -> Self {
        let lux = if lux.is_finite() && lux > 0.0 { lux } else { DEFAULT_WHITE_LUX };
        Self { exposure: std::f32::consts::PI / lux, white_balance: Vec3::ONE, rolloff: None }
    }

    /// White balance for a lamp at dimmer `v` (that lamp's light shows neutral).
    pub fn balanced_for(mut self, lamp: &footlight_photometry::Lamp, v: f32) -> Self {
        self.white_balance = footlight_photometry::WhiteBalance::for_lamp(lamp, v).gains;
        self
    }

    /// The same display with highlight roll-off `rolloff` (`None`: clip at white).
    pub fn with_rolloff(mut self, rolloff: Option<HighlightRolloff>) -> Self {
        self.rolloff = rolloff;
        self
    }

    /// Linear cd/m² to display-linear RGB (before the transfer function).
    pub fn scale(&self) -> Vec3 {
        self.white_balance * self.exposure
    }

    /// Display-linear colour (1 = white) of a linear cd/m² value: white
    /// balance, exposure and the roll-off if any, before clipping and the
    /// transfer function.
    pub fn display_linear(&self, linear: Vec3) -> Vec3 {
        match self.rolloff {
            None => linear * self.scale(),
            Some(r) => r.apply(linear * self.scale()),
        }
    }

    /// Encodes a linear image to 8-bit sRGB, row-major RGB triplets. Runs
    /// every display frame, so it uses a 64 Ki-entry table instead of `powf`
    /// (≤ 1 code value from the exact curve, checked in the tests).
    pub fn to_srgb8(&self, linear: &[Vec3]) -> Vec<u8> {
        let mut out = vec![0u8; linear.len() * 3];
        self.to_srgb8_into(linear, &mut out);
        out
    }

    /// As [`Display::to_srgb8`], into an existing RGB8 buffer (3 bytes per
    /// pixel), in parallel over chunks of 4096 pixels.
    pub fn to_srgb8_into(&self, linear: &[Vec3], out: &mut [u8]) {
        use rayon::prelude::*;
        assert_eq!(out.len(), linear.len() * 3, "output size");
        out.par_chunks_mut(3 * 4096).zip(linear.par_chunks(4096)).for_each(|(o, l)| self.encode_span(l, o));
    }

    /// As [`Display::to_srgb8_into`], on the calling thread: for the short
    /// spans (one tile row) the incremental compositor encodes from inside
    /// its own parallel pass, where a parallel iterator per span cost more
    /// than the encoding (one fader: 3,904 spans of 16 pixels).
    pub fn encode_span(&self, linear: &[Vec3], out: &mut [u8]) {
        assert_eq!(out.len(), linear.len() * 3, "output size");
        let s = self.scale() * LUT_MAX;
        let (scale, rolloff) = (self.scale(), self.rolloff);
        let lut = srgb_lut();
        let pixels = out.chunks_exact_mut(3).zip(linear);
        match rolloff {
            // Without a roll-off: one multiply into the table's index (the
            // bits the GPU and browser shaders reproduce).
            None => pixels.for_each(|(px, v)| px.copy_from_slice(&lut_codes(lut, *v * s))),
            Some(r) => pixels.for_each(|(px, v)| px.copy_from_slice(&lut_codes(lut, r.apply(*v * scale) * LUT_MAX))),
        }
    }
}

/// An optional highlight roll-off for the *display* encoding, so beams in
/// haze brighter than display white still read as beams instead of flat
/// clipped areas (issue 15). Linear output (the composite, PFM/EXR, every
/// measurement) never passes through it.
///
/// Applied to the largest channel m of a display-linear colour (1 = white),
/// scaling all three by f(m)/m so hue and saturation stay: identity up to
/// the `knee`, then an extended-Reinhard shoulder that is C¹ at the knee and
/// reaches 1 exactly at `white`:
///
///   u = (m − knee) / (1 − knee),  U = (white − knee) / (1 − knee),
///   f(m) = knee + (1 − knee) · u (1 + u / U²) / (1 + u)   (m ≤ white), 1 above.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HighlightRolloff {
    /// Display-linear level (0-1) below which nothing changes (default 0.6).
    pub knee: f32,
    /// Display-linear level shown as white (default 16: four stops over).
    pub white: f32,
}

impl Default for HighlightRolloff {
    fn default() -> Self {
        Self { knee: 0.6, white: 16.0 }
    }
}

impl HighlightRolloff {
    /// The roll-off of one display-linear colour (non-finite input → black).
    pub fn apply(&self, c: Vec3) -> Vec3 {
        if !c.is_finite() {
            return Vec3::ZERO;
        }
        let m = c.max_element();
        let [knee, white] = self.uniforms();
        if m <= knee {
            return c;
        }
        let f = if m >= white {
            1.0
        } else {
            let (u, big_u) = ((m - knee) / (1.0 - knee), (white - knee) / (1.0 - knee));
            knee + (1.0 - knee) * u * (1.0 + u / (big_u * big_u)) / (1.0 + u)
        };
        c * (f / m)
    }

    /// The curve's two constants as every compositor uses them, `[knee,
    /// white]`, knee clamped to [0, 0.99] and white to at least 1.001: what
    /// [`HighlightRolloff::apply`] computes with and what the GPU (WGSL) and
    /// browser (GLSL) shaders receive as uniforms.
    pub fn uniforms(&self) -> [f32; 2] {
        let knee = if self.knee.is_finite() { self.knee.clamp(0.0, 0.99) } else { 0.6 };
        let white = if self.white.is_finite() { self.white.max(1.0 + 1e-3) } else { 16.0 };
        [knee, white]
    }
}

/// A roll-off from a command-line value: `off` (clip at white), `on` (the
/// default curve) or the display-linear level shown as white (a number > 1,
/// e.g. `16` = four stops over white; the knee stays at its default).
pub fn parse_rolloff(value: &str) -> Result<Option<HighlightRolloff>, String> {
    let v = value.trim();
    if v.eq_ignore_ascii_case("off") || v.eq_ignore_ascii_case("clip") {
        return Ok(None);
    }
    if v.eq_ignore_ascii_case("on") {
        return Ok(Some(HighlightRolloff::default()));
    }
    match v.parse::<f32>() {
        Ok(white) if white.is_finite() && white > 1.0 && white <= 65_536.0 => {
            Ok(Some(HighlightRolloff { white, ..HighlightRolloff::default() }))
        }
        _ => Err(format!("{value:?}: expected off, on or the level shown as white (a number over 1, at most 65536)")),
    }
}

impl Display {
    /// As [`Display::to_srgb8`] with `rolloff` instead of this display's own.
    pub fn to_srgb8_rolloff(&self, linear: &[Vec3], rolloff: HighlightRolloff) -> Vec<u8> {
        self.with_rolloff(Some(rolloff)).to_srgb8(linear)
    }
}

const SRGB_LUT_SIZE: usize = 1 << 16;

/// The largest index into the sRGB table.
const LUT_MAX: f32 = (SRGB_LUT_SIZE - 1) as f32;

/// 8-bit sRGB code values of a display-linear colour (1 = white), through
/// the same table as [`Display::to_srgb8`].
pub fn srgb8(display_linear: Vec3) -> [u8; 3] {
    lut_codes(srgb_lut(), display_linear * LUT_MAX)
}

/// The table's codes for a colour already scaled to its index range
/// (display-linear × [`LUT_MAX`]): the one rounding rule every encoder
/// here shares. The clamped value + 0.5 lies in [0.5, 65535.5], so the
/// cast to u16 (which truncates, saturates and maps NaN to 0) is the index
/// and needs no bounds check. NaN gives code 0: never reached for checked
/// buffers, and never a panic.
fn lut_codes(lut: &[u8; SRGB_LUT_SIZE], x: Vec3) -> [u8; 3] {
    let idx = x.clamp(Vec3::ZERO, Vec3::splat(LUT_MAX)) + 0.5;
    [lut[idx.x as u16 as usize], lut[idx.y as u16 as usize], lut[idx.z as u16 as usize]]
}

/// Linear [0, 1] in 65536 steps to 8-bit sRGB.
fn srgb_lut() -> &'static [u8; SRGB_LUT_SIZE] {
    static LUT: std::sync::OnceLock<Box<[u8; SRGB_LUT_SIZE]>> = std::sync::OnceLock::new();
    LUT.get_or_init(|| {
        let mut lut = Box::new([0u8; SRGB_LUT_SIZE]);
        for (i, code) in lut.iter_mut().enumerate() {
            *code = (srgb_encode(Vec3::splat(i as f32 / LUT_MAX)).x * 255.0 + 0.5) as u8;
        }
        lut
    })
}

/// sRGB transfer function (IEC 61966-2-1) per channel, input clamped to [0, 1].
pub fn srgb_encode(linear: Vec3) -> Vec3 {
    let f = |c: f32| {
        let c = c.clamp(0.0, 1.0);
        if c <= 0.003_130_8 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 }
    };
    Vec3::new(f(linear.x), f(linear.y), f(linear.z))
}

/// First pixel index holding NaN, Inf or a negative value.
pub fn check_finite(linear: &[Vec3]) -> Result<(), (usize, Vec3)> {
    match linear.iter().position(|v| !v.is_finite() || v.min_element() < 0.0) {
        None => Ok(()),
        Some(i) => Err((i, linear[i])),
    }
}

/// White balance gains from an explicit value: `none` (gains 1),
/// `tungsten` (3200 K at full is neutral) or a colour temperature in kelvin
/// (a Planckian source at that temperature is neutral). `auto` needs the
/// rig: [`white_balance_for`].
pub fn parse_white_balance(value: &str) -> Result<Vec3, String> {
    use footlight_photometry::{Lamp, WhiteBalance};
    let v = value.trim();
    if v.eq_ignore_ascii_case("none") {
        return Ok(Vec3::ONE);
    }
    if v.eq_ignore_ascii_case("tungsten") {
        return Ok(WhiteBalance::default().gains);
    }
    let kelvin: f32 = v
        .trim_end_matches(['K', 'k'])
        .parse()
        .map_err(|_| format!("{value:?}: expected auto, none, tungsten or a colour temperature such as 5600K"))?;
    if !(1000.0..=25_000.0).contains(&kelvin) {
        return Err(format!("{value:?}: colour temperature must be 1000-25000 K"));
    }
    Ok(WhiteBalance::for_lamp(&Lamp::Discharge { cct: kelvin }, 1.0).gains)
}

/// A white balance as asked for (`--white-balance`, `POST /api/display`)
/// and what it resolved to.
#[derive(Clone, Debug, PartialEq)]
pub struct WhiteChoice {
    /// As asked: `auto`, `none`, `tungsten` or a temperature (`5600K`).
    pub setting: String,
    /// The per-channel gains in force.
    pub gains: Vec3,
    /// What they make neutral, in words (`auto`: the rig's white, see
    /// [`footlight_fixture::patch::RigWhite`]).
    pub note: String,
}

impl WhiteChoice {
    /// Names `gains` set directly (a library caller's [`Display`]):
    /// `tungsten` or `none` when they are those, else `custom`.
    pub fn of_gains(gains: Vec3) -> Self {
        let (setting, note) = if gains == footlight_photometry::WhiteBalance::default().gains {
            ("tungsten", "3200 K: tungsten at full")
        } else if gains == Vec3::ONE {
            ("none", "no white balance: linear sRGB as rendered")
        } else {
            ("custom", "gains set by the caller")
        };
        Self { setting: setting.into(), gains, note: note.into() }
    }
}

/// The white balance for `value` on a rig whose white is `rig`
/// ([`footlight_fixture::Patch::rig_white`]): `auto` makes the rig's own
/// white at full neutral (its tungsten at their CCT when it has tungsten
/// lamps, so the paper's rig keeps the 3200 K gains bit for bit; else the
/// luminous-flux-weighted white of every source at full), or tungsten
/// 3200 K when the patch has no lamp; anything else as
/// [`parse_white_balance`].
pub fn white_balance_for(value: &str, rig: Option<&footlight_fixture::patch::RigWhite>) -> Result<WhiteChoice, String> {
    use footlight_photometry::WhiteBalance;
    let v = value.trim();
    if v.eq_ignore_ascii_case("auto") {
        let (gains, note) = match rig {
            Some(w) => (WhiteBalance::for_colour(w.rgb).gains, w.describe()),
            None => (WhiteBalance::default().gains, "3200 K: no lamp in the patch, tungsten at full".to_string()),
        };
        return Ok(WhiteChoice { setting: "auto".into(), gains, note });
    }
    let gains = parse_white_balance(v)?;
    let note = if v.eq_ignore_ascii_case("none") {
        "no white balance: linear sRGB as rendered".to_string()
    } else if v.eq_ignore_ascii_case("tungsten") {
        "3200 K: tungsten at full".to_string()
    } else {
        format!("{} K: a Planckian source at that temperature", v.trim_end_matches(['K', 'k']).trim())
    };
    Ok(WhiteChoice { setting: v.to_ascii_lowercase(), gains, note })
}

/// `linear` (cd/m²) times per-channel white-balance `gains`: what the HDR
/// writers store. No exposure, no clipping, no transfer curve.
pub fn balanced(linear: &[Vec3], gains: Vec3) -> Vec<Vec3> {
    linear.iter().map(|v| *v * gains).collect()
}

/// Writes a linear, unclipped RGB OpenEXR image (32-bit float channels,
/// through the `exr` crate), row-major from the top, values as given.
pub fn write_exr(path: &std::path::Path, width: u32, height: u32, linear: &[Vec3]) -> Result<(), String> {
    let w = width as usize;
    if linear.len() != w * height as usize {
        return Err(format!("{}: {} pixels for a {width}×{height} image", path.display(), linear.len()));
    }
    exr::prelude::write_rgb_file(path, w, height as usize, |x, y| {
        let v = linear[y * w + x];
        (v.x, v.y, v.z)
    })
    .map_err(|e| format!("{}: {e}", path.display()))
}

/// Writes a linear, unclipped Portable Float Map (`PF`, RGB f32). The format
/// is three text lines (`PF`, `width height`, scale; a negative scale means
/// little-endian) and the rows bottom to top; written by hand because it is
/// that small and no maintained crate writes it.
pub fn write_pfm(path: &std::path::Path, width: u32, height: u32, linear: &[Vec3]) -> std::io::Result<()> {
    let w = width as usize;
    if linear.len() != w * height as usize {
        return Err(std::io::Error::other(format!("{} pixels for a {width}×{height} image", linear.len())));
    }
    let mut out = format!("PF\n{width} {height}\n-1.0\n").into_bytes();
    out.reserve(linear.len() * 12);
    for row in linear.chunks(w.max(1)).rev() {
        for v in row {
            for c in v.to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    std::fs::write(path, out)
}

/// Writes an 8-bit sRGB PNG.
pub fn write_png(path: &std::path::Path, width: u32, height: u32, rgb8: Vec<u8>) -> Result<(), image::ImageError> {
    let img = image::RgbImage::from_raw(width, height, rgb8).ok_or_else(|| {
        image::ImageError::Parameter(image::error::ParameterError::from_kind(
            image::error::ParameterErrorKind::DimensionMismatch,
        ))
    })?;
    img.save(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn white_lambert_at_reference_lux_is_white() {
        let d = Display::neutral(DEFAULT_WHITE_LUX);
        let l = DEFAULT_WHITE_LUX / std::f32::consts::PI;
        assert_eq!(d.to_srgb8(&[Vec3::splat(l)]), vec![255, 255, 255]);
        assert_eq!(d.to_srgb8(&[Vec3::ZERO]), vec![0, 0, 0]);
        // 18 % grey card -> sRGB ~118.
        let grey = d.to_srgb8(&[Vec3::splat(0.18 * l)]);
        assert!((grey[0] as i32 - 118).abs() <= 1, "{grey:?}");
    }

    #[test]
    fn table_matches_the_exact_curve() {
        let d = Display { exposure: 1.0, white_balance: Vec3::ONE, rolloff: None };
        // Tungsten at full is neutral under the default white balance.
        let wb = Display::default();
        let tungsten = footlight_photometry::Lamp::tungsten().colour(1.0);
        let px = wb.to_srgb8(&[tungsten * (0.5 / wb.exposure)]);
        assert!(px[0].abs_diff(px[1]) <= 1 && px[1].abs_diff(px[2]) <= 1, "{px:?}");
        let mut worst = 0;
        for i in 0..=20_000 {
            let x = (i as f32 / 20_000.0).powi(3) * 1.2;
            let exact = (srgb_encode(Vec3::splat(x)).x * 255.0 + 0.5) as i32;
            let got = d.to_srgb8(&[Vec3::splat(x)])[0] as i32;
            worst = worst.max((exact - got).abs());
        }
        assert!(worst <= 1, "worst {worst}");
        assert_eq!(d.to_srgb8(&[Vec3::new(f32::NAN, -1.0, f32::INFINITY)]), vec![0, 0, 255]);
    }

    #[test]
    fn rolloff_keeps_the_knee_and_grades_beams_over_white() {
        let r = HighlightRolloff::default();
        assert_eq!(r.apply(Vec3::new(0.5, 0.2, 0.1)), Vec3::new(0.5, 0.2, 0.1));
        // C¹ at the knee: the slope just above it is 1.
        let e = 1e-3;
        assert!(((r.apply(Vec3::splat(0.6 + e)).x - 0.6) / e - 1.0).abs() < 1e-2);
        assert!((r.apply(Vec3::splat(16.0)).x - 1.0).abs() < 1e-6);
        assert_eq!(r.apply(Vec3::splat(100.0)), Vec3::ONE);
        // 1x, 2x, 4x, 8x white stay distinct 8-bit codes (they all clip to 255 without it).
        let d = Display { exposure: 1.0, white_balance: Vec3::ONE, rolloff: None };
        let codes: Vec<u8> =
            [1.0f32, 2.0, 4.0, 8.0].iter().map(|&x| d.to_srgb8_rolloff(&[Vec3::new(x, 0.0, 0.0)], r)[0]).collect();
        assert!(codes.windows(2).all(|w| w[0] < w[1]), "{codes:?}");
        assert!(codes[3] < 255);
        // Hue stays: a saturated beam keeps its channel ratios.
        let c = r.apply(Vec3::new(4.0, 1.0, 0.0));
        assert!((c.y / c.x - 0.25).abs() < 1e-6 && c.z == 0.0);
        assert_eq!(r.apply(Vec3::new(f32::NAN, 1.0, 1.0)), Vec3::ZERO);
    }

    /// The curve against its closed form, evaluated here in f64 from the
    /// formula (not through `apply`), for values up to 4× past white, and
    /// the display encoding with the roll-off against the exact sRGB curve.
    #[test]
    fn rolloff_matches_its_closed_form_and_encodes_within_one_level() {
        let closed = |m: f64, knee: f64, white: f64| -> f64 {
            if m <= knee {
                return m;
            }
            if m >= white {
                return 1.0;
            }
            let (u, uw) = ((m - knee) / (1.0 - knee), (white - knee) / (1.0 - knee));
            knee + (1.0 - knee) * u * (1.0 + u / (uw * uw)) / (1.0 + u)
        };
        for r in [HighlightRolloff::default(), HighlightRolloff { knee: 0.3, white: 4.0 }] {
            let (knee, white) = (r.knee as f64, r.white as f64);
            let mut worst = 0.0f64;
            for i in 0..=4000 {
                let m = i as f64 / 4000.0 * 4.0 * white;
                // A saturated colour whose largest channel is m.
                let c = r.apply(Vec3::new(m as f32, 0.5 * m as f32, 0.0));
                let want = closed(m, knee, white);
                worst = worst.max((c.x as f64 - want).abs()).max((c.y as f64 - 0.5 * want).abs());
            }
            assert!(worst < 2e-6, "{r:?}: worst {worst}");
            // Monotonic and ≤ 1 past the knee (a brighter beam is never darker).
            let f: Vec<f32> = (0..1000).map(|i| r.apply(Vec3::splat(1.0 + i as f32 * 0.02)).x).collect();
            assert!(f.windows(2).all(|w| w[0] <= w[1] + 1e-6 && w[1] <= 1.0 + 1e-6), "{f:?}");
        }
        // to_srgb8 with the roll-off: exposure first, then the curve, then sRGB.
        let d = Display { exposure: 0.5, white_balance: Vec3::new(1.0, 0.9, 0.8), rolloff: Some(Default::default()) };
        let mut worst = 0;
        for i in 0..2000 {
            let v = Vec3::new(i as f32 * 0.03, i as f32 * 0.011, 0.2);
            let c = v * d.scale();
            let m = c.max_element() as f64;
            let s = if m > 0.6 { closed(m, 0.6, 16.0) / m } else { 1.0 };
            let want = srgb_encode(c * s as f32) * 255.0 + 0.5;
            let got = d.to_srgb8(&[v]);
            for ch in 0..3 {
                worst = worst.max((want[ch] as i32 - got[ch] as i32).abs());
            }
        }
        assert!(worst <= 1, "worst {worst} levels");
        assert_eq!(parse_rolloff("off"), Ok(None));
        assert_eq!(parse_rolloff("on"), Ok(Some(HighlightRolloff::default())));
        assert_eq!(parse_rolloff("8").unwrap().unwrap().white, 8.0);
        for bad in ["1", "0.5", "nan", "inf", "bright"] {
            assert!(parse_rolloff(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn finite_check_finds_nan() {
        assert_eq!(check_finite(&[Vec3::ONE, Vec3::new(0.0, f32::NAN, 0.0)]).unwrap_err().0, 1);
        assert!(check_finite(&[Vec3::ZERO]).is_ok());
    }

    #[test]
    fn auto_white_balance_keeps_the_tungsten_gains_on_a_tungsten_rig() {
        use footlight_photometry::WhiteBalance;
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let paper = footlight_fixture::Patch::load(&root.join(crate::PAPER_PATCH)).unwrap();
        let auto = white_balance_for("auto", paper.rig_white().as_ref()).unwrap();
        assert_eq!(auto.gains, WhiteBalance::default().gains, "bit for bit: the goldens do not move");
        assert_eq!(auto.setting, "auto");
        assert!(auto.note.starts_with("3200 K"), "{}", auto.note);
        assert_eq!(white_balance_for("AUTO", None).unwrap().gains, WhiteBalance::default().gains);
        for v in ["none", "tungsten", "5600K", "4000"] {
            let c = white_balance_for(v, paper.rig_white().as_ref()).unwrap();
            assert_eq!(c.gains, parse_white_balance(v).unwrap(), "{v}");
        }
        let e = white_balance_for("blue", None).unwrap_err();
        assert!(e.contains("auto") && e.contains("tungsten"), "{e}");
    }
}
