//! Gel filters from measured transmission spectra, and colour scrollers.
//!
//! Vierjahn 2010, section 3.2: "The transmission spectra of these filters
//! can be found in the filter's datasheet. Applying these spectra as filter
//! functions to the Planckian locus leads to an sRGB color of the filtered
//! light. The value of c_F can be determined from this color and the color
//! of unfiltered light." Footlight reads the spectra from `patch/gels.toml`
//! (LEE Filters data; the file's header names the source and terms):
//!
//! ```toml
//! [[gel]]
//! id = "L201"
//! name = "Full C.T. Blue"
//! maker = "LEE Filters"
//! published = { x = 0.3300, y = 0.3390, y_percent = 35.00, transmission = 0.3400 }
//! start_nm = 405
//! step_nm = 5
//! transmission = [0.62901, 0.65673, 0.67194]   # … one value per step, 0..1
//! ```
//!
//! Spectra are interpolated linearly between samples and held at their end
//! values outside the measured range. Each gel precomputes its
//! [`Response`], so the per-frame colour is a table lookup.
//!
//! A colour scroller ([`Scroller`]) carries N frames on a string; between two
//! frames part of the beam passes one gel and the rest the other, so the
//! transmission is the area-weighted mix (1 − f)·t_a + f·t_b — linear in the
//! spectrum, not in RGB. Because colour is linear in the spectrum, mixing
//! the two frames' precomputed XYZ is exact.

use crate::response::Response;
use crate::spectrum::{Sampled, interpolate_table};
use serde::Deserialize;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// A gel-library error with the file and 1-based line it refers to.
#[derive(Debug, thiserror::Error)]
#[error("{}:{line}: {message}", path.display())]
pub struct GelError {
    /// The gel file.
    pub path: PathBuf,
    /// 1-based line number (0 when the file could not be read at all).
    pub line: usize,
    /// What is wrong and what to do about it.
    pub message: String,
}

/// Index of a gel in its [`GelLibrary`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct GelId(pub u32);

/// The maker's own published figures for a gel.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Published {
    /// CIE x of the filtered light (LEE: 3200 K source, see `patch/gels.toml`).
    pub x: f32,
    /// CIE y of the filtered light.
    pub y: f32,
    /// Luminous transmittance Y in percent.
    pub y_percent: f32,
    /// The maker's "transmission" figure, 0..1.
    pub transmission: f32,
}

/// One filter: its measured spectrum and precomputed response.
#[derive(Clone, Debug, PartialEq)]
pub struct Gel {
    /// Identifier a patch names, e.g. "L201".
    pub id: String,
    /// Maker's name, e.g. "Full C.T. Blue".
    pub name: String,
    /// Maker ("LEE Filters", or "none" for the open frame).
    pub maker: String,
    /// Maker's description.
    pub description: String,
    /// Maker's published colour figures, when given.
    pub published: Option<Published>,
    /// First measured wavelength, nm.
    pub start_nm: f32,
    /// Spacing of the measured samples, nm.
    pub step_nm: f32,
    /// Measured transmittance 0..1 at `start_nm + i · step_nm`.
    pub samples: Vec<f32>,
    /// Line of the `[[gel]]` entry in its file.
    pub line: usize,
    transmission: Sampled,
    response: Response,
}

impl Gel {
    /// A gel from measured samples at `start_nm + i · step_nm`. Samples are
    /// clamped to 0..1 (NaN → 0); no samples means an open filter. (The
    /// library loader rejects such values with file:line instead.)
    pub fn from_samples(
        id: impl Into<String>,
        name: impl Into<String>,
        start_nm: f32,
        step_nm: f32,
        samples: Vec<f32>,
    ) -> Self {
        let mut samples: Vec<f32> = samples.into_iter().map(|t| if t > 0.0 { t.min(1.0) } else { 0.0 }).collect();
        if samples.is_empty() {
            samples.push(1.0);
        }
        let table: Vec<f64> = samples.iter().map(|&t| f64::from(t)).collect();
        let transmission = Sampled::from_table(f64::from(start_nm), f64::from(step_nm), &table);
        let response = Response::new(&transmission);
        Self {
            id: id.into(),
            name: name.into(),
            maker: String::new(),
            description: String::new(),
            published: None,
            start_nm,
            step_nm,
            samples,
            line: 0,
            transmission,
            response,
        }
    }

    /// Transmittance at `nm` from the measured samples (linear, held at the ends).
    pub fn transmission(&self, nm: f32) -> f32 {
        interpolate_table(f64::from(self.start_nm), f64::from(self.step_nm), &self.samples, f64::from(nm)) as f32
    }

    /// The transmission on the 1 nm grid.
    pub fn sampled(&self) -> &Sampled {
        &self.transmission
    }

    /// The precomputed response (what [`crate::colour()`] reads).
    pub fn response(&self) -> &Response {
        &self.response
    }
}

/// The gels of one file, in file order.
#[derive(Clone, Debug)]
pub struct GelLibrary {
    /// Where it was read from.
    pub path: PathBuf,
    gels: Vec<Gel>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GelsFile {
    #[serde(default)]
    gel: Vec<Spanned<GelEntry>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GelEntry {
    id: Spanned<String>,
    name: String,
    #[serde(default)]
    maker: String,
    #[serde(default)]
    description: String,
    published: Option<Spanned<Published>>,
    start_nm: Spanned<f32>,
    step_nm: Spanned<f32>,
    transmission: Spanned<Vec<Spanned<f32>>>,
}

impl GelLibrary {
    /// Reads and validates a gel file such as `patch/gels.toml`.
    pub fn load(path: &Path) -> Result<Self, GelError> {
        let text = std::fs::read_to_string(path).map_err(|e| GelError {
            path: path.to_path_buf(),
            line: 0,
            message: format!("cannot read: {e}"),
        })?;
        Self::parse(path, &text)
    }

    /// Parses and validates gel-file text; `path` is used in messages.
    pub fn parse(path: &Path, text: &str) -> Result<Self, GelError> {
        let err = |span: Range<usize>, message: String| GelError {
            path: path.to_path_buf(),
            line: line_of(text, span.start),
            message,
        };
        let file: GelsFile = toml::from_str(text).map_err(|e| GelError {
            path: path.to_path_buf(),
            line: e.span().map(|s| line_of(text, s.start)).unwrap_or(0),
            message: e.message().to_string(),
        })?;
        let mut gels: Vec<Gel> = Vec::with_capacity(file.gel.len());
        for entry in file.gel {
            let line = line_of(text, entry.span().start);
            let e = entry.into_inner();
            let id = e.id.get_ref().trim().to_string();
            if id.is_empty() {
                return Err(err(e.id.span(), "gel id must not be empty".into()));
            }
            if let Some(other) = gels.iter().find(|g| normalise(&g.id) == normalise(&id)) {
                return Err(err(e.id.span(), format!("gel id {id:?} already used on line {}", other.line)));
            }
            let start = *e.start_nm.get_ref();
            if !(start.is_finite() && (200.0..=2000.0).contains(&start)) {
                return Err(err(e.start_nm.span(), format!("gel {id}: start_nm {start} must be a wavelength in nm")));
            }
            let step = *e.step_nm.get_ref();
            if !(step.is_finite() && step > 0.0 && step <= 100.0) {
                return Err(err(e.step_nm.span(), format!("gel {id}: step_nm {step} must be in (0, 100] nm")));
            }
            if e.transmission.get_ref().is_empty() {
                return Err(err(e.transmission.span(), format!("gel {id}: transmission needs at least one value")));
            }
            let mut samples = Vec::with_capacity(e.transmission.get_ref().len());
            for (i, t) in e.transmission.get_ref().iter().enumerate() {
                let v = *t.get_ref();
                if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                    let nm = start + step * i as f32;
                    return Err(err(t.span(), format!("gel {id}: transmission {v} at {nm} nm must be in 0..1")));
                }
                samples.push(v);
            }
            let published = match e.published {
                None => None,
                Some(p) => {
                    let span = p.span();
                    let p = p.into_inner();
                    let ok = [p.x, p.y].iter().all(|c| c.is_finite() && (0.0..=1.0).contains(c))
                        && p.y_percent.is_finite()
                        && (0.0..=100.0).contains(&p.y_percent)
                        && p.transmission.is_finite()
                        && (0.0..=1.0).contains(&p.transmission);
                    if !ok {
                        return Err(err(
                            span,
                            format!("gel {id}: published x, y, transmission must be in 0..1 and y_percent in 0..100"),
                        ));
                    }
                    Some(p)
                }
            };
            let mut gel = Gel::from_samples(id, e.name, start, step, samples);
            gel.maker = e.maker;
            gel.description = e.description;
            gel.published = published;
            gel.line = line;
            gels.push(gel);
        }
        Ok(Self { path: path.to_path_buf(), gels })
    }

    /// The gel with index `id`.
    pub fn get(&self, id: GelId) -> Option<&Gel> {
        self.gels.get(id.0 as usize)
    }

    /// Looks a gel up by id, ignoring case and spaces; "LEE 201", "lee201"
    /// and "L201" all find LEE 201.
    pub fn find(&self, name: &str) -> Option<GelId> {
        let want = normalise(name);
        self.gels.iter().position(|g| normalise(&g.id) == want).map(|i| GelId(i as u32))
    }

    /// Every gel with its id, in file order.
    pub fn iter(&self) -> impl Iterator<Item = (GelId, &Gel)> {
        self.gels.iter().enumerate().map(|(i, g)| (GelId(i as u32), g))
    }

    /// Number of gels.
    pub fn len(&self) -> usize {
        self.gels.len()
    }

    /// True when the file held no gels.
    pub fn is_empty(&self) -> bool {
        self.gels.is_empty()
    }
}

/// Upper case without spaces, with a leading "LEE" shortened to "L".
fn normalise(id: &str) -> String {
    let s: String = id.chars().filter(|c| !c.is_whitespace()).collect::<String>().to_uppercase();
    match s.strip_prefix("LEE") {
        Some(rest) if !rest.is_empty() => format!("L{rest}"),
        _ => s,
    }
}

/// 1-based line number of byte offset `at` in `text`.
fn line_of(text: &str, at: usize) -> usize {
    text[..at.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

/// What is in the beam: gel `a` over part 1 − f of it and gel `b` over part
/// f (`None` = open). A single gel is `f = 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GelMix<'a> {
    /// The first filter (`None`: open).
    pub a: Option<&'a Gel>,
    /// The second filter (`None`: open).
    pub b: Option<&'a Gel>,
    /// Fraction of the beam through `b`, 0..1.
    pub f: f32,
}

impl<'a> GelMix<'a> {
    /// No filter.
    pub const OPEN: GelMix<'static> = GelMix { a: None, b: None, f: 0.0 };

    /// One gel over the whole beam (or open).
    pub fn single(gel: Option<&'a Gel>) -> Self {
        Self { a: gel, b: None, f: 0.0 }
    }

    /// Transmittance at `nm`: (1 − f)·t_a + f·t_b.
    pub fn transmission(&self, nm: f32) -> f32 {
        let t = |g: Option<&Gel>| g.map_or(1.0, |g| g.transmission(nm));
        let f = self.f.clamp(0.0, 1.0);
        (1.0 - f) * t(self.a) + f * t(self.b)
    }

    /// The mixed transmission on the 1 nm grid (allocates; for references).
    pub fn sampled(&self) -> Sampled {
        let open = Sampled::constant(1.0);
        let a = self.a.map_or(&open, Gel::sampled);
        let b = self.b.map_or(&open, Gel::sampled);
        Sampled::lerp(a, b, f64::from(self.f.clamp(0.0, 1.0)))
    }
}

/// A colour scroller: frames on a string, `None` = an open frame.
///
/// Frame k sits at frame position k (0-based); position 1.5 is half frame 1,
/// half frame 2. [`Scroller::position_from_dmx8`] spreads the frames evenly
/// over the DMX range with every frame on an exact DMX value.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Scroller {
    /// The frames in string order.
    pub frames: Vec<Option<GelId>>,
}

impl Scroller {
    /// What is in the beam at frame position `position` (clamped to
    /// 0..N−1; NaN → 0): the two neighbouring frames and the fraction of
    /// the second. `None` if a frame's gel is not in `library`.
    pub fn at<'a>(&self, library: &'a GelLibrary, position: f32) -> Option<GelMix<'a>> {
        let n = self.frames.len();
        if n == 0 {
            return Some(GelMix::OPEN);
        }
        let p = if position > 0.0 { position.min((n - 1) as f32) } else { 0.0 };
        let i = (p.floor() as usize).min(n - 1);
        let f = p - i as f32;
        let gel = |k: usize| match self.frames[k] {
            None => Some(None),
            Some(id) => library.get(id).map(Some),
        };
        let a = gel(i)?;
        let b = if f > 0.0 { gel(i + 1)? } else { None };
        Some(GelMix { a, b, f: if f > 0.0 { f } else { 0.0 } })
    }

    /// Frame position for an 8-bit DMX value: frame k sits at DMX
    /// round(k · 255 / (N − 1)), positions in between are linear.
    pub fn position_from_dmx8(&self, value: u8) -> f32 {
        self.position_from_dmx(u32::from(value), 255)
    }

    /// Frame position for a 16-bit DMX value (as [`Scroller::position_from_dmx8`] over 0..65535).
    pub fn position_from_dmx16(&self, value: u16) -> f32 {
        self.position_from_dmx(u32::from(value), 65535)
    }

    /// DMX value (full scale `max`) at which frame `k` sits exactly.
    pub fn frame_dmx(&self, k: usize, max: u32) -> u32 {
        let gaps = self.frames.len().saturating_sub(1) as u64;
        if gaps == 0 {
            return 0;
        }
        ((k.min(gaps as usize) as u64 * u64::from(max) * 2 + gaps) / (2 * gaps)) as u32
    }

    fn position_from_dmx(&self, value: u32, max: u32) -> f32 {
        let gaps = self.frames.len().saturating_sub(1);
        for k in 0..gaps {
            let (lo, hi) = (self.frame_dmx(k, max), self.frame_dmx(k + 1, max));
            if value <= hi {
                let f = if hi > lo { (value.saturating_sub(lo)) as f32 / (hi - lo) as f32 } else { 0.0 };
                return k as f32 + f;
            }
        }
        gaps as f32
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::colour::{colour, colour_exact, colour_mix, filter_factor};
    use crate::lamp::Lamp;
    use crate::response::Response;
    use crate::srgb::{cct_mccamy, luminance, xy};
    use glam::Vec3;
    use std::sync::OnceLock;

    /// `patch/gels.toml`, loaded once for all tests.
    pub(crate) fn library() -> &'static GelLibrary {
        static LIB: OnceLock<GelLibrary> = OnceLock::new();
        LIB.get_or_init(|| {
            let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../patch/gels.toml");
            GelLibrary::load(&path).unwrap_or_else(|e| panic!("{e}"))
        })
    }

    fn gel(id: &str) -> &'static Gel {
        let lib = library();
        lib.get(lib.find(id).unwrap_or_else(|| panic!("{id} missing"))).unwrap()
    }

    #[test]
    fn library_holds_the_theatre_set() {
        let lib = library();
        assert!(lib.len() >= 80, "{}", lib.len());
        for id in ["clear", "L201", "L136", "L106", "L119", "L132", "L147", "L202", "L203"] {
            assert!(lib.find(id).is_some(), "{id}");
        }
        assert_eq!(lib.find("LEE 201"), lib.find("L201"));
        assert_eq!(lib.find("lee201"), lib.find("l201"));
        assert_eq!(lib.find("R201"), None);
        assert_eq!(gel("L201").name, "Full C.T. Blue");
        assert_eq!(gel("L201").samples.len(), 60);
        // Held at the end values outside 405-700 nm, linear in between.
        let g = gel("L201");
        assert_eq!(g.transmission(380.0), g.samples[0]);
        assert_eq!(g.transmission(800.0), g.samples[59]);
        assert!((g.transmission(407.5) - (g.samples[0] + g.samples[1]) / 2.0).abs() < 1e-6);
    }

    /// XYZ of `spd` over the gel's own samples by the trapezoid rule on the
    /// tabulated CMF — written out here, independent of the crate's 1 nm sums.
    fn trapezoid_xyz(g: &Gel, filtered: bool, t_k: f64) -> [f64; 3] {
        let planck = |nm: f64| {
            let l = nm * 1e-9;
            1.0 / (l.powi(5) * ((1.438_776_877e-2 / (l * t_k)).exp() - 1.0))
        };
        let mut xyz = [0.0; 3];
        let n = g.samples.len();
        for (i, &t) in g.samples.iter().enumerate() {
            let nm = f64::from(g.start_nm) + f64::from(g.step_nm) * i as f64;
            let w = if i == 0 || i == n - 1 { 0.5 } else { 1.0 } * f64::from(g.step_nm);
            let s = planck(nm) * if filtered { f64::from(t) } else { 1.0 };
            let c = crate::cie::cmf_f64(nm);
            xyz[0] += w * s * c.x;
            xyz[1] += w * s * c.y;
            xyz[2] += w * s * c.z;
        }
        xyz
    }

    #[test]
    fn lee_201_makes_tungsten_bluer_and_darker() {
        let (lamp, g) = (Lamp::tungsten(), gel("L201"));
        let open = lamp.xyz_through(1.0, Response::open());
        let blue = lamp.xyz_through(1.0, g.response());
        let (cct_open, cct_blue) = (cct_mccamy(xy(open).unwrap()), cct_mccamy(xy(blue).unwrap()));
        assert!(cct_blue > cct_open + 1500.0, "{cct_open} K -> {cct_blue} K");
        // Luminous transmittance: the crate's value against the data file's
        // own spectrum integrated separately (trapezoid over 405-700 nm).
        let y = luminance(colour(&lamp, 1.0, Some(g)));
        let (f, u) = (trapezoid_xyz(g, true, 3200.0), trapezoid_xyz(g, false, 3200.0));
        let y_trap = (f[1] / u[1]) as f32;
        assert!((y - y_trap).abs() < 0.005, "crate {y} vs trapezoid {y_trap}");
        assert!((y - 0.33).abs() < 0.01, "{y}");
        // LEE publishes Y = 35 % and "transmission 34 %" for 201 (3200 K source).
        let p = g.published.unwrap();
        assert!((y * 100.0 - p.y_percent).abs() < 2.5, "{y} vs {}", p.y_percent);
        assert!((y - p.transmission).abs() < 0.02);
        let c = xy(blue).unwrap();
        assert!((c.x - p.x).abs() < 0.005 && (c.y - p.y).abs() < 0.005, "{c} vs ({}, {})", p.x, p.y);
    }

    #[test]
    fn lee_136_is_pale_lavender() {
        let c_f = filter_factor(&Lamp::tungsten(), 1.0, Some(gel("L136")));
        assert!(c_f.x > c_f.y && c_f.z > c_f.y, "c_F {c_f}");
        assert!(c_f.max_element() < 1.0 + 1e-4);
    }

    #[test]
    fn every_shipped_gel_agrees_with_its_published_colour() {
        // LEE's xy and Y for a 3200 K source (see patch/gels.toml's header).
        // Most agree to 0.006 in xy; the worst, 0.9 ND (L211), is 0.012 off
        // in y, with LEE's own figure (0.421, 0.421) as far from the lamp. Y agrees to
        // 5 percentage points (worst: L104 Deep Amber, 68.1 % here, 73.0 % published).
        let mut worst_xy = (0.0f32, "");
        let mut worst_y = (0.0f32, "");
        for (_, g) in library().iter() {
            let Some(p) = g.published else { continue };
            let xyz = Lamp::tungsten().xyz_through(1.0, g.response());
            let c = xy(xyz).unwrap();
            let published = glam::Vec2::new(p.x, p.y);
            let d = (c - published).length();
            let dy = (xyz.y * 100.0 - p.y_percent).abs();
            if d > worst_xy.0 {
                worst_xy = (d, &g.id);
            }
            if dy > worst_y.0 {
                worst_y = (dy, &g.id);
            }
            assert!(d < 0.015, "{}: {c} vs {published}", g.id);
            assert!(dy < 5.0, "{}: Y {} % vs {} %", g.id, xyz.y * 100.0, p.y_percent);
        }
        eprintln!("worst xy distance {worst_xy:?}, worst Y difference {worst_y:?} (percentage points)");
        assert!(worst_xy.0 > 0.0 && worst_y.0 > 0.0);
    }

    #[test]
    fn clear_frame_changes_nothing() {
        let clear = gel("clear");
        for lamp in crate::lamp::tests::every_kind() {
            for v in [1.0, 0.5, 0.01, 1e-6] {
                assert_eq!(colour(&lamp, v, Some(clear)), colour(&lamp, v, None), "{lamp:?} {v}");
            }
        }
    }

    #[test]
    fn every_gel_gives_finite_colours_for_every_lamp() {
        for (_, g) in library().iter() {
            for lamp in crate::lamp::tests::every_kind() {
                for v in [1.0, 0.3, 1e-3, 1e-7] {
                    let c = colour(&lamp, v, Some(g));
                    assert!(c.is_finite() && c.min_element() >= 0.0, "{} {lamp:?} {v}: {c}", g.id);
                    assert!(
                        luminance(c) <= luminance(colour(&lamp, v, None)) + 1e-4,
                        "{}: a gel cannot add light",
                        g.id
                    );
                }
            }
        }
    }

    #[test]
    fn scroller_frames_and_half_frames() {
        let lib = library();
        let ids = ["L201", "L106", "L119"].map(|id| lib.find(id));
        let s = Scroller { frames: vec![None, ids[0], ids[1], ids[2]] };
        let lamp = Lamp::tungsten();
        // On a frame: exactly that frame.
        for (k, want) in [(0, None), (1, Some(gel("L201"))), (2, Some(gel("L106"))), (3, Some(gel("L119")))] {
            let pos = s.position_from_dmx8(s.frame_dmx(k, 255) as u8);
            assert_eq!(pos, k as f32);
            let mix = s.at(lib, pos).unwrap();
            assert_eq!(colour_mix(&lamp, 0.8, &mix), colour(&lamp, 0.8, want), "frame {k}");
        }
        assert_eq!([0, 1, 2, 3].map(|k| s.frame_dmx(k, 255)), [0, 85, 170, 255]);
        // Halfway between 201 and 106: half the beam through each gel.
        let mix = s.at(lib, 1.5).unwrap();
        let (a, b) = (gel("L201"), gel("L106"));
        assert!((mix.transmission(550.0) - (a.transmission(550.0) + b.transmission(550.0)) / 2.0).abs() < 1e-6);
        let hand = Sampled::from_fn(|nm| 0.5 * f64::from(a.transmission(nm as f32) + b.transmission(nm as f32)));
        let want = colour_exact(&lamp, 0.8, Some(&hand));
        let got = colour_mix(&lamp, 0.8, &mix);
        assert!((got - want).abs().max_element() < 1e-4, "{got} vs {want}");
        // DMX between frames moves linearly; ends clamp.
        assert!((s.position_from_dmx8(42) - 42.0 / 85.0).abs() < 1e-6);
        assert_eq!(s.at(lib, 99.0).unwrap().a, Some(gel("L119")));
        assert_eq!(s.at(lib, f32::NAN).unwrap(), GelMix::OPEN);
        assert_eq!(Scroller::default().at(lib, 3.0), Some(GelMix::OPEN));
        assert_eq!(Scroller { frames: vec![Some(GelId(9999))] }.at(lib, 0.0), None);
        assert_eq!(s.position_from_dmx16(65535), 3.0);
    }

    fn parse_err(text: &str) -> String {
        GelLibrary::parse(Path::new("bad.toml"), text).unwrap_err().to_string()
    }

    #[test]
    fn broken_files_name_file_and_line() {
        let good = "[[gel]]\nid = \"X1\"\nname = \"x\"\nstart_nm = 400\nstep_nm = 5\ntransmission = [0.5, 0.6]\n";
        assert_eq!(GelLibrary::parse(Path::new("ok.toml"), good).unwrap().len(), 1);
        let e = parse_err(&good.replace("0.6]", "\n  1.7]"));
        assert!(e.starts_with("bad.toml:7:") && e.contains("1.7 at 405 nm"), "{e}");
        let e = parse_err(&good.replace("step_nm = 5", "step_nm = -5"));
        assert!(e.starts_with("bad.toml:5:") && e.contains("step_nm"), "{e}");
        let e = parse_err(&format!("{good}\n{}", good.replace("X1", "x 1")));
        assert!(e.starts_with("bad.toml:9:") && e.contains("already used on line 1"), "{e}");
        let e = parse_err(&good.replace("name = \"x\"", "name = \"x\"\ncolour = 3"));
        assert!(e.starts_with("bad.toml:4:") && e.contains("colour"), "{e}");
        let e = parse_err(&good.replace("transmission = [0.5, 0.6]", "transmission = [0.5, 0.6"));
        assert!(e.starts_with("bad.toml:"), "{e}");
        assert!(!e.starts_with("bad.toml:0:"), "{e}");
        let e = parse_err(&good.replace("[0.5, 0.6]", "[]"));
        assert!(e.starts_with("bad.toml:6:"), "{e}");
        let e = GelLibrary::load(Path::new("/nonexistent/gels.toml")).unwrap_err().to_string();
        assert!(e.starts_with("/nonexistent/gels.toml:0: cannot read"), "{e}");
        let e = parse_err(
            &good.replace("name", "published = { x = 2.0, y = 0.3, y_percent = 5.0, transmission = 0.1 }\nname"),
        );
        assert!(e.starts_with("bad.toml:3:") && e.contains("published"), "{e}");
    }

    #[test]
    fn gels_dim_coloured_leds_by_their_spectrum() {
        use crate::lamp::{Chroma, Emitter};
        let lamp = |r: f32, g: f32, b: f32| {
            let mut e = vec![
                Emitter::new("r", Chroma::Xy(glam::Vec2::new(0.69, 0.30)), 0.25),
                Emitter::new("g", Chroma::Xy(glam::Vec2::new(0.17, 0.70)), 0.65),
                Emitter::new("b", Chroma::Xy(glam::Vec2::new(0.14, 0.05)), 0.10),
            ];
            (e[0].level, e[1].level, e[2].level) = (r, g, b);
            Lamp::Led { emitters: e }
        };
        let red = gel("L106");
        // Primary red passes a red LED far better than a blue one.
        let through = |l: &Lamp| luminance(colour(l, 1.0, Some(red))) / luminance(colour(l, 1.0, None));
        let (through_red, through_blue) = (through(&lamp(1.0, 0.0, 0.0)), through(&lamp(0.0, 0.0, 1.0)));
        assert!(through_red > 0.5 && through_red <= 1.0 && through_blue < 0.05, "{through_red} {through_blue}");
        assert!((luminance(colour(&lamp(1.0, 0.0, 0.0), 1.0, None)) - 0.25).abs() < 1e-4);
        let c = colour(&lamp(1.0, 1.0, 1.0), 1.0, Some(red));
        assert!(c.x > 5.0 * c.y && c.x > 5.0 * c.z, "{c}");
        assert!(Vec3::ZERO.cmple(c).all());
    }
}
