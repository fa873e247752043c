//! LED colour of `ColorAdd_*` channels that no `<Emitter>` colours (issue 36
//! item 1).
//!
//! Many manufacturers' GDTF files (LED pixel bars, matrix panels, moving
//! LED heads) define no `<Emitter>` in their `PhysicalDescriptions`, so their
//! `ColorAdd_*` channel functions link none. Such a channel is still mixed,
//! as an LED emitter given by a CIE 1931 xy and a luminous share (the same
//! [`Emitter::new`] path as an `<Emitter>` with a `Color` and no
//! measurement), from, in this order:
//!
//! 1. the `Color` (CIE xyY) of its attribute in the file's own
//!    `AttributeDefinitions` (DIN SPEC 15800:2022 / GDTF 1.2: an
//!    `<Attribute>` may carry `Color`, "the color representation of the
//!    attribute");
//! 2. else the colour the GDTF specification itself gives the attribute:
//!    DIN SPEC 15800:2022, Annex B "Attribute Listing" (normative; the
//!    `AttributeDefinitions` block of the spec, `github.com/mvrdevelopment/spec`,
//!    copied by GDTF Builder into the files it writes), [`ANNEX_B`], for
//!    the 16 additive colour attributes it lists; and for a few names real
//!    files use outside that list, [`ALIASES`] (`ColorAdd_A` → amber `RY`,
//!    `ColorAdd_Lime` → `GY`…) and [`ESTIMATED`] (`ColorAdd_Indigo`).
//!    These are **estimated**: the spec's colours are nominal (the R/G/B of
//!    sRGB, its other colours sums of them), not any fixture's emitter; a
//!    real red LED is more saturated, and Annex B's `ColorAdd_WW`
//!    (0.319, 0.340, ≈ 6000 K) is far cooler than a warm-white LED
//!    (2700-3200 K). They are used because a file with the spec's standard
//!    definitions and one without them then mix alike.
//!
//! **Luminous share** (how bright each primary is at full, on one scale):
//! the colour's Y, which in Annex B is the primary's luminance on a scale
//! where white (W, and R + G + B) is 100, so full R + G + B is white and
//! full R + G + B + W twice that white. Where a file gives no usable Y (none,
//! not positive, or the same Y for every primary of the type, which says
//! nothing about their brightness), **equal-white weighting**: the
//! primary's share is the luminance of the brightest colour of its
//! chromaticity that the display's white (R = G = B = 1, Y = 100) can make,
//! [`white_share`] = 100 / max(R, G, B) of its unit-luminance linear sRGB
//! colour (negative channels of out-of-gamut colours ignored). This is how
//! Annex B's own Y are made (sRGB red 21.26, cyan = G + B 78.7, amber
//! 0.477,0.460 = R + ½ G 57.0, UV 0.6): the rule reproduces them within the
//! spec's rounding (`tests::equal_white_weighting_reproduces_annex_b`).

use footlight_photometry::srgb;
use glam::Vec2;

/// DIN SPEC 15800:2022 (GDTF 1.2), Annex B "Attribute Listing": the `Color`
/// (CIE 1931 x, y, Y) of each additive colour attribute, verbatim.
pub const ANNEX_B: [(&str, [f32; 3]); 16] = [
    ("ColorAdd_R", [0.64, 0.33, 21.3]),
    ("ColorAdd_G", [0.3, 0.6, 71.5]),
    ("ColorAdd_B", [0.15, 0.06, 7.2]),
    ("ColorAdd_C", [0.225, 0.329, 78.7]),
    ("ColorAdd_M", [0.321, 0.154, 28.5]),
    ("ColorAdd_Y", [0.419, 0.505, 92.8]),
    ("ColorAdd_RY", [0.477, 0.460, 57.0]),
    ("ColorAdd_GY", [0.372, 0.543, 82.1]),
    ("ColorAdd_GC", [0.250, 0.419, 75.1]),
    ("ColorAdd_BC", [0.200, 0.239, 43.0]),
    ("ColorAdd_BM", [0.254, 0.117, 17.9]),
    ("ColorAdd_RM", [0.403, 0.200, 24.9]),
    ("ColorAdd_W", [0.313, 0.329, 100.0]),
    ("ColorAdd_WW", [0.319, 0.340, 99.3]),
    ("ColorAdd_CW", [0.306, 0.329, 97.9]),
    ("ColorAdd_UV", [0.176, 0.005, 0.6]),
];

/// Names outside GDTF's attribute list that real files use for the same
/// emitters, read as the Annex B attribute they stand for (estimated).
pub const ALIASES: [(&str, &str); 8] = [
    ("ColorAdd_A", "ColorAdd_RY"),
    ("ColorAdd_Amber", "ColorAdd_RY"),
    ("ColorAdd_Lime", "ColorAdd_GY"),
    ("ColorAdd_L", "ColorAdd_GY"),
    ("ColorAdd_Cyan", "ColorAdd_C"),
    ("ColorAdd_White", "ColorAdd_W"),
    ("ColorAdd_WarmWhite", "ColorAdd_WW"),
    ("ColorAdd_CoolWhite", "ColorAdd_CW"),
];

/// Names in neither list, with an estimated chromaticity (their share by
/// [`white_share`]): `ColorAdd_Indigo` as the CIE 1931 spectral locus at
/// 450 nm (x̄ 0.3362, ȳ 0.0380, z̄ 1.7721: a royal-blue/indigo LED's line).
pub const ESTIMATED: [(&str, [f32; 2]); 1] = [("ColorAdd_Indigo", [0.1566, 0.0177])];

/// Where a primary's colour came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// The `Color` of the attribute in the file's `AttributeDefinitions`.
    File,
    /// GDTF's Annex B (or an alias of it, or [`ESTIMATED`]): estimated.
    Nominal,
}

/// One `ColorAdd_*` primary without an emitter, as it will be mixed.
#[derive(Clone, Debug, PartialEq)]
pub struct Primary {
    /// The GDTF attribute (`ColorAdd_R`).
    pub attribute: String,
    /// CIE 1931 chromaticity.
    pub xy: Vec2,
    /// Luminous share at full (Annex B's scale: white = 100).
    pub share: f32,
    /// Where the chromaticity came from.
    pub source: Source,
    /// True when the share was made by equal-white weighting ([`white_share`]).
    pub weighted: bool,
}

/// The luminance (white = 100) of the brightest colour of chromaticity `xy`
/// the display white can make: 100 / max(R, G, B) of its unit-luminance
/// linear sRGB colour; 0 for an unusable chromaticity.
pub fn white_share(xy: Vec2) -> f32 {
    let m = srgb::xyz_to_linear_srgb(srgb::xy_to_xyz(xy, 1.0)).max_element();
    if m > 0.0 && m.is_finite() { 100.0 / m } else { 0.0 }
}

/// GDTF attribute names are compared without case (DIN SPEC 15800 Annex B).
fn same(a: &str, b: &str) -> bool {
    a.eq_ignore_ascii_case(b)
}

/// The nominal colour (x, y, Y) of `attribute`: Annex B, an alias of it, or
/// [`ESTIMATED`] (Y 0 there: its share comes from [`white_share`]).
pub fn nominal(attribute: &str) -> Option<[f32; 3]> {
    let annex = |a: &str| ANNEX_B.iter().find(|(n, _)| same(n, a)).map(|(_, c)| *c);
    annex(attribute)
        .or_else(|| ALIASES.iter().find(|(n, _)| same(n, attribute)).and_then(|(_, to)| annex(to)))
        .or_else(|| ESTIMATED.iter().find(|(n, _)| same(n, attribute)).map(|(_, xy)| [xy[0], xy[1], 0.0]))
}

fn usable(xy: Vec2) -> bool {
    xy.is_finite() && xy.x > 0.0 && xy.y > 0.0 && xy.x + xy.y < 1.0
}

/// The primaries of `attributes` (the type's `ColorAdd_*` channels that no
/// emitter colours), from `definitions` (the file's attribute colours, by
/// name) else [`nominal`]; with the attributes that have no colour at all
/// (decoded, not mixed). Shares as in the module doc.
pub fn primaries(attributes: &[String], definitions: &dyn Fn(&str) -> Option<[f64; 3]>) -> (Vec<Primary>, Vec<String>) {
    let mut out = Vec::new();
    let mut unknown = Vec::new();
    for a in attributes {
        let file = definitions(a).map(|c| c.map(|v| v as f32)).filter(|c| usable(Vec2::new(c[0], c[1])));
        let (c, source) = match (file, nominal(a)) {
            (Some(c), _) => (c, Source::File),
            (None, Some(c)) => (c, Source::Nominal),
            (None, None) => {
                unknown.push(a.clone());
                continue;
            }
        };
        let xy = Vec2::new(c[0], c[1]);
        out.push(Primary { attribute: a.clone(), xy, share: c[2], source, weighted: false });
    }
    // A file's Y that says nothing about brightness: the same for every
    // primary of several colours (e.g. all 100).
    let from_file: Vec<&Primary> = out.iter().filter(|p| p.source == Source::File).collect();
    let uniform = from_file.len() >= 2
        && from_file.iter().all(|p| (p.share - from_file[0].share).abs() <= 1e-6 * from_file[0].share.abs())
        && from_file.iter().any(|p| (p.xy - from_file[0].xy).length() > 1e-3);
    for p in &mut out {
        if !(p.share > 0.0 && p.share.is_finite()) || (uniform && p.source == Source::File) {
            p.share = white_share(p.xy).max(1e-3);
            p.weighted = true;
        }
    }
    (out, unknown)
}

/// `ColorAdd_R/G/B/W`: the first name in full, the rest by their suffix
/// after `ColorAdd_` (the one-line note of a type).
pub fn short_list(names: &[&str]) -> String {
    let mut s = String::new();
    for (i, n) in names.iter().enumerate() {
        if i > 0 {
            s.push('/');
            s.push_str(n.strip_prefix("ColorAdd_").unwrap_or(n));
        } else {
            s.push_str(n);
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_white_weighting_reproduces_annex_b() {
        // Annex B's Y are the luminance of each nominal colour as the sRGB
        // white (Y 100) makes it at its brightest: white_share gives them
        // back within the spec's rounding (3 digits of x and y).
        for (name, [x, y, lum]) in ANNEX_B {
            let w = white_share(Vec2::new(x, y));
            let tol = if lum < 5.0 { 0.05 } else { 0.01 * lum };
            assert!((w - lum).abs() <= tol, "{name}: white_share {w}, Annex B {lum}");
        }
        assert!((white_share(Vec2::new(0.3127, 0.3290)) - 100.0).abs() < 0.1);
        assert_eq!(white_share(Vec2::new(f32::NAN, 0.3)), 0.0);
    }

    #[test]
    fn file_colours_first_then_the_spec_then_nothing() {
        let names: Vec<String> =
            ["ColorAdd_R", "ColorAdd_RY", "ColorAdd_Foo", "colorAdd_a", "ColorAdd_Indigo"].map(String::from).to_vec();
        let defs = |a: &str| (a == "ColorAdd_R").then_some([0.69, 0.3, 18.0]);
        let (p, unknown) = primaries(&names, &defs);
        assert_eq!(unknown, vec!["ColorAdd_Foo".to_string()]);
        assert_eq!(p.len(), 4);
        assert_eq!((p[0].xy, p[0].share, p[0].source), (Vec2::new(0.69, 0.3), 18.0, Source::File));
        assert_eq!((p[1].xy, p[1].share, p[1].source), (Vec2::new(0.477, 0.460), 57.0, Source::Nominal));
        assert_eq!(p[2].xy, p[1].xy, "ColorAdd_A is amber (RY), whatever its case");
        assert!(p[3].weighted && p[3].share > 0.0 && p[3].share < 10.0, "{:?}", p[3]);
    }

    #[test]
    fn uniform_file_luminances_are_reweighted_to_mix_white() {
        let names: Vec<String> = ["ColorAdd_R", "ColorAdd_G", "ColorAdd_B"].map(String::from).to_vec();
        let defs = |a: &str| match a {
            "ColorAdd_R" => Some([0.64, 0.33, 100.0]),
            "ColorAdd_G" => Some([0.30, 0.60, 100.0]),
            _ => Some([0.15, 0.06, 100.0]),
        };
        let (p, _) = primaries(&names, &defs);
        let shares: Vec<f32> = p.iter().map(|p| p.share).collect();
        assert!(p.iter().all(|p| p.weighted));
        for (s, want) in shares.iter().zip([21.26, 71.52, 7.22]) {
            assert!((s - want).abs() < 0.05, "{shares:?}");
        }
        assert_eq!(short_list(&["ColorAdd_R", "ColorAdd_G", "ColorAdd_B"]), "ColorAdd_R/G/B");
    }
}
