//! EULUMDAT photometric files (`.ldt`), the line-based format of Axel
//! Stockmar (1990) used by European makers.
//!
//! One field per line:
//!
//! | line | field |
//! |---|---|
//! | 1 | company / databank / version |
//! | 2 | Ityp (type indicator) |
//! | 3 | Isym: 0 none, 1 about the vertical axis, 2 about C0-C180, 3 about C90-C270, 4 about both |
//! | 4, 5 | Mc (number of C-planes in 0-360°), Dc (their spacing) |
//! | 6, 7 | Ng (number of γ angles per plane), Dg (their spacing) |
//! | 8-12 | report number, luminaire name, number, file name, date/user |
//! | 13-21 | luminaire and luminous-area dimensions, mm |
//! | 22-25 | downward flux fraction %, light output ratio %, intensity conversion factor, tilt |
//! | 26 | n lamp sets, then 6 lines each: lamps, type, total flux (lm), colour, CRI, watts |
//! | then | 10 direct ratios, Mc C angles, Ng γ angles, intensities in cd/klm |
//!
//! Intensities are stored for C0-C360 (Isym 0, Mc planes), one plane
//! (Isym 1), C0-C180 (Isym 2, Mc/2+1), C90-C270 (Isym 3, Mc/2+1) or C0-C90
//! (Isym 4, Mc/4+1), each plane listing Ng values. Candela = value ×
//! (total flux of the first lamp set / 1000) × conversion factor. A decimal
//! comma is read as a point.

use super::{Photometry, Symmetry};
use crate::error::PatchError;
use std::path::Path;

/// Most C-planes or γ angles (bounds memory on a broken file).
const MAX_ANGLES: usize = 10_000;

/// Parses EULUMDAT text; `path` is used in messages.
pub fn parse(path: &Path, text: &str) -> Result<Photometry, PatchError> {
    let err = |line: usize, m: String| PatchError::new(path, line, m);
    let lines: Vec<&str> = text.lines().map(str::trim).collect();
    let field = |line: usize| -> Result<&str, PatchError> {
        lines.get(line - 1).copied().ok_or_else(|| err(lines.len().max(1), format!("file ends before line {line}")))
    };
    let number = |line: usize, what: &str| -> Result<f64, PatchError> {
        let t = field(line)?;
        let v: f64 = t.replace(',', ".").parse().map_err(|_| err(line, format!("{what}: {t:?} is not a number")))?;
        if !v.is_finite() {
            return Err(err(line, format!("{what}: {t:?} is not finite")));
        }
        Ok(v)
    };
    let whole = |line: usize, what: &str, lo: usize, hi: usize| -> Result<usize, PatchError> {
        let v = number(line, what)?;
        if v.fract() != 0.0 || v < lo as f64 || v > hi as f64 {
            return Err(err(line, format!("{what} {v} must be a whole number in {lo}..{hi}")));
        }
        Ok(v as usize)
    };
    let isym = whole(3, "Isym (symmetry indicator)", 0, 4)?;
    let mc = whole(4, "Mc (number of C-planes)", 1, MAX_ANGLES)?;
    let ng = whole(6, "Ng (number of intensities per C-plane)", 1, MAX_ANGLES)?;
    let factor = number(24, "the intensity conversion factor")?;
    let sets = whole(26, "n (number of lamp sets)", 1, 100)?;
    let flux_line = 26 + 3; // 26c of the first set
    let flux = number(flux_line, "the total lamp flux (lm)")?;
    let scale = flux / 1000.0 * factor;
    if !(scale > 0.0) {
        return Err(err(flux_line, format!("lamp flux {flux} lm × conversion factor {factor} must be > 0")));
    }
    let c_start = 26 + 6 * sets + 10 + 1;
    let g_start = c_start + mc;
    let v_start = g_start + ng;
    let read = |start: usize, n: usize, what: &str| -> Result<Vec<f32>, PatchError> {
        (0..n).map(|i| number(start + i, what).map(|v| v as f32)).collect()
    };
    let c_all = read(c_start, mc, "C angle")?;
    let g_deg = read(g_start, ng, "γ angle")?;
    for (i, w) in g_deg.windows(2).enumerate() {
        if !(w[1] > w[0]) {
            return Err(err(g_start + i + 1, format!("γ angles must increase: {} after {}", w[1], w[0])));
        }
    }
    for (i, w) in c_all.windows(2).enumerate() {
        if !(w[1] > w[0]) {
            return Err(err(c_start + i + 1, format!("C angles must increase: {} after {}", w[1], w[0])));
        }
    }
    // Which stored planes, and which C angle each one has.
    let (first, count, symmetry) = match isym {
        0 => (0, mc, Symmetry::None),
        1 => (0, 1, Symmetry::Rotational),
        2 => (0, mc / 2 + 1, Symmetry::AboutC0C180),
        3 => (mc / 4, mc / 2 + 1, Symmetry::AboutC90C270),
        _ => (0, mc / 4 + 1, Symmetry::Quadrant),
    };
    let expect = match isym {
        2 => Some((0.0, 180.0)),
        3 => Some((90.0, 270.0)),
        4 => Some((0.0, 90.0)),
        _ => None,
    };
    if first + count > mc {
        return Err(err(4, format!("Mc = {mc} is too small for symmetry {isym}")));
    }
    let c_deg: Vec<f32> = if isym == 1 { vec![0.0] } else { c_all[first..first + count].to_vec() };
    if let Some((a, b)) = expect
        && ((c_deg[0] - a).abs() > 1e-3 || (c_deg[count - 1] - b).abs() > 1e-3)
    {
        let (lo, hi) = (c_deg[0], c_deg[count - 1]);
        let msg = format!("symmetry {isym} stores C{a}..C{b}, but the C angles there run {lo}..{hi}");
        return Err(err(c_start + first, msg));
    }
    let mut candela = Vec::with_capacity(count);
    for p in 0..count {
        let mut plane = Vec::with_capacity(ng);
        for g in 0..ng {
            let line = v_start + p * ng + g;
            let v = number(line, "intensity (cd/klm)")?;
            if v < 0.0 {
                return Err(err(line, format!("intensity {v} cd/klm is negative")));
            }
            plane.push((v * scale) as f32);
        }
        candela.push(plane);
    }
    Ok(Photometry { c_deg, g_deg, candela, symmetry })
}
