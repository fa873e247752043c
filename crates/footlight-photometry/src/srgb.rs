//! CIE XYZ ↔ linear sRGB, chromaticity, CCT, and fitting into the gamut.
//!
//! The renderer works in linear sRGB (Vierjahn 2010, section 3.2: colours
//! "have to be converted to sRGB color space \[SACM95\]"). The matrices are
//! those of IEC 61966-2-1:1999 (sRGB, D65 white): the standard's RGB → XYZ
//! matrix, and as XYZ → RGB its exact inverse (which agrees with the
//! standard's printed 4-digit inverse to 1e-4), so that the luminance
//! Y = 0.2126 R + 0.7152 G + 0.0722 B of any converted colour is exactly the
//! Y it came from. Footlight's colours keep that Y as their photometric
//! meaning, so this matters more than the 5th digit of the matrix.
//!
//! The correlated colour temperature estimate is McCamy's cubic (McCamy,
//! "Correlated color temperature as an explicit function of chromaticity
//! coordinates", Color Res. Appl. 17(2), 1992), accurate to a few kelvin
//! from 2856 to 6504 K and usable (tens of kelvin) from about 2000 to
//! 12500 K. It is here for tests and diagnostics, not for the colour path.

use glam::{DVec3, Vec2, Vec3};

/// Linear sRGB → CIE XYZ, rows (IEC 61966-2-1:1999, D65).
pub const RGB_TO_XYZ: [[f64; 3]; 3] = [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]];

/// CIE XYZ → linear sRGB, rows: the exact inverse of [`RGB_TO_XYZ`] to 10
/// digits (the standard prints 3.2406 −1.5372 −0.4986 / −0.9689 1.8758
/// 0.0415 / 0.0557 −0.2040 1.0570).
pub const XYZ_TO_RGB: [[f64; 3]; 3] = [
    [3.240_625_477_3, -1.537_207_972_2, -0.498_628_598_7],
    [-0.968_930_714_7, 1.875_756_060_9, 0.041_517_523_8],
    [0.055_710_120_4, -0.204_021_050_6, 1.056_995_942_3],
];

/// Luminance weights of linear sRGB (the Y row of [`RGB_TO_XYZ`]).
pub const LUMINANCE: Vec3 = Vec3::new(0.2126, 0.7152, 0.0722);

fn mul(m: &[[f64; 3]; 3], v: DVec3) -> DVec3 {
    DVec3::new(DVec3::from(m[0]).dot(v), DVec3::from(m[1]).dot(v), DVec3::from(m[2]).dot(v))
}

/// CIE XYZ → linear sRGB (may have negative channels out of gamut).
pub fn xyz_to_linear_srgb(xyz: Vec3) -> Vec3 {
    mul(&XYZ_TO_RGB, xyz.as_dvec3()).as_vec3()
}

/// [`xyz_to_linear_srgb`] in double precision.
pub fn xyz_to_linear_srgb_f64(xyz: DVec3) -> DVec3 {
    mul(&XYZ_TO_RGB, xyz)
}

/// Linear sRGB → CIE XYZ.
pub fn linear_srgb_to_xyz(rgb: Vec3) -> Vec3 {
    mul(&RGB_TO_XYZ, rgb.as_dvec3()).as_vec3()
}

/// Luminance Y of a linear sRGB colour.
pub fn luminance(rgb: Vec3) -> f32 {
    LUMINANCE.dot(rgb)
}

/// Chromaticity (x, y) = (X, Y) / (X + Y + Z); `None` when X + Y + Z is not
/// positive and finite (black has no chromaticity).
pub fn xy(xyz: Vec3) -> Option<Vec2> {
    let s = xyz.x + xyz.y + xyz.z;
    if s > 0.0 && s.is_finite() { Some(Vec2::new(xyz.x / s, xyz.y / s)) } else { None }
}

/// XYZ with chromaticity `xy` and luminance `y_lum`; black when `xy.y` is
/// not positive.
pub fn xy_to_xyz(xy: Vec2, y_lum: f32) -> Vec3 {
    if !(xy.y > 0.0 && xy.is_finite()) {
        return Vec3::ZERO;
    }
    Vec3::new(xy.x / xy.y, 1.0, (1.0 - xy.x - xy.y) / xy.y) * y_lum
}

/// Correlated colour temperature in kelvin by McCamy's formula (1992):
/// n = (x − 0.3320) / (0.1858 − y), CCT = 449 n³ + 3525 n² + 6823.3 n + 5520.33.
/// Meaningful near the Planckian locus, roughly 2000-12500 K.
pub fn cct_mccamy(xy: Vec2) -> f32 {
    let d = 0.1858 - xy.y;
    if d.abs() < 1e-6 {
        return f32::INFINITY;
    }
    let n = (xy.x - 0.3320) / d;
    ((449.0 * n + 3525.0) * n + 6823.3) * n + 5520.33
}

/// Brings a linear sRGB colour into the gamut without changing its
/// luminance: desaturates toward the grey of equal luminance (Y, Y, Y) just
/// enough that no channel is negative. In-gamut colours pass unchanged;
/// non-finite colours and colours with non-positive luminance become black.
/// (Saturated gels and very dim tungsten lie outside sRGB; clipping channels
/// to zero instead would add luminance.)
pub fn fit_gamut(rgb: Vec3) -> Vec3 {
    if !rgb.is_finite() {
        return Vec3::ZERO;
    }
    if rgb.min_element() >= 0.0 {
        return rgb;
    }
    let y = luminance(rgb);
    if !(y > 0.0 && y.is_finite()) {
        return Vec3::ZERO;
    }
    // y + s (c − y) = 0 for the most negative channel c: s = y / (y − c).
    let s = y / (y - rgb.min_element());
    (Vec3::splat(y) + (rgb - Vec3::splat(y)) * s).max(Vec3::ZERO)
}

/// [`fit_gamut`] in the white-balanced space of per-channel `gains`: the
/// colour is balanced, desaturated toward the grey of equal (balanced)
/// luminance there, and unbalanced again. Gains are positive, so the result
/// has no negative channel either way; what changes is the direction of the
/// desaturation: toward the reference white the picture is balanced for, so
/// the hue seen on the balanced display is kept (a saturated red gel on
/// tungsten stays red instead of turning magenta). The result is scaled to
/// the input's luminance Y, as [`fit_gamut`] keeps it. Gains that are not
/// positive and finite fall back to [`fit_gamut`].
pub fn fit_gamut_balanced(rgb: Vec3, gains: Vec3) -> Vec3 {
    if !(gains.is_finite() && gains.min_element() > 0.0) {
        return fit_gamut(rgb);
    }
    if !rgb.is_finite() {
        return Vec3::ZERO;
    }
    if rgb.min_element() >= 0.0 {
        return rgb;
    }
    let fitted = fit_gamut(rgb * gains) / gains;
    // Keep the colour's own luminance Y (its photometric meaning).
    let (y, y_fit) = (luminance(rgb), luminance(fitted));
    if y > 0.0 && y_fit > 0.0 { fitted * (y / y_fit) } else { Vec3::ZERO }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn d65_white_maps_to_rgb_one() {
        // IEC 61966-2-1: D65 (X, Y, Z) = (0.9505, 1.0000, 1.0890) is RGB (1, 1, 1).
        let rgb = xyz_to_linear_srgb(Vec3::new(0.9505, 1.0, 1.089));
        assert!((rgb - Vec3::ONE).abs().max_element() < 2e-4, "{rgb}");
    }

    #[test]
    fn matrices_are_inverse_and_match_the_printed_inverse() {
        let printed = [[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]];
        for r in 0..3 {
            for c in 0..3 {
                assert!((XYZ_TO_RGB[r][c] - printed[r][c]).abs() < 1e-4);
                let id: f64 = (0..3).map(|k| XYZ_TO_RGB[r][k] * RGB_TO_XYZ[k][c]).sum();
                assert!((id - if r == c { 1.0 } else { 0.0 }).abs() < 1e-9);
            }
        }
        let xyz = Vec3::new(0.3, 0.7, 0.2);
        assert!((luminance(xyz_to_linear_srgb(xyz)) - 0.7).abs() < 1e-6);
    }

    #[test]
    fn srgb_primaries_have_their_published_chromaticities() {
        // IEC 61966-2-1: R (0.64, 0.33), G (0.30, 0.60), B (0.15, 0.06), D65 (0.3127, 0.3290).
        for (rgb, x, y) in
            [(Vec3::X, 0.64, 0.33), (Vec3::Y, 0.30, 0.60), (Vec3::Z, 0.15, 0.06), (Vec3::ONE, 0.3127, 0.3290)]
        {
            let c = xy(linear_srgb_to_xyz(rgb)).unwrap();
            assert!((c.x - x).abs() < 1e-3 && (c.y - y).abs() < 1e-3, "{rgb}: {c}");
        }
        assert_eq!(xy(Vec3::ZERO), None);
    }

    #[test]
    fn mccamy_reproduces_its_anchor_points() {
        // Illuminant A (0.44757, 0.40745) is 2856 K; D65 (0.31271, 0.32902) is 6504 K.
        assert!((cct_mccamy(Vec2::new(0.44757, 0.40745)) - 2856.0).abs() < 5.0);
        assert!((cct_mccamy(Vec2::new(0.31271, 0.32902)) - 6504.0).abs() < 5.0);
    }

    #[test]
    fn fit_gamut_keeps_luminance_and_in_gamut_colours() {
        let inside = Vec3::new(0.9, 0.5, 0.1);
        assert_eq!(fit_gamut(inside), inside);
        let out = Vec3::new(2.0, 0.5, -0.3);
        let f = fit_gamut(out);
        assert!(f.min_element() >= 0.0 && f.min_element() < 1e-6, "{f}");
        assert!((luminance(f) - luminance(out)).abs() < 1e-6);
        // Hue direction kept: red still dominates, ordering unchanged.
        assert!(f.x > f.y && f.y > f.z);
        assert_eq!(fit_gamut(Vec3::new(f32::NAN, 0.0, 0.0)), Vec3::ZERO);
        assert_eq!(fit_gamut(Vec3::new(-1.0, 0.0, 0.0)), Vec3::ZERO);
    }
}
