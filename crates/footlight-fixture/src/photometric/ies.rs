//! IES LM-63 photometric files (ANSI/IESNA LM-63-2002; the 1986, 1991 and
//! 1995 variants read the same way).
//!
//! Layout: an optional first line (`IESNA:LM-63-2002`), keyword lines
//! (`[TEST] …`), a `TILT=` line, then whitespace- or comma-separated
//! numbers:
//!
//! ```text
//! <lamps> <lumens/lamp> <multiplier> <#vertical> <#horizontal> <type> <units> <width> <length> <height>
//! <ballast factor> <ballast-lamp factor / future use> <input watts>
//! <vertical angles …> <horizontal angles …> <candela: #vertical per horizontal angle …>
//! ```
//!
//! Only photometric type 1 (type C, the type of every stage luminaire file
//! seen) is read. Candela = value × multiplier × ballast factor. The
//! horizontal angles declare the symmetry: last 0 → rotational, last 90 →
//! quadrant, last 180 → about C0-C180, first 90 and last 270 → about
//! C90-C270, else a full set. `TILT=INCLUDE` data is skipped and a tilt file
//! is not opened: lamp tilt factors do not change the pattern's shape.

use super::{Photometry, Symmetry};
use crate::error::PatchError;
use std::path::Path;

/// Most angles in either direction (bounds memory on a broken file).
const MAX_ANGLES: usize = 10_000;

/// Parses IES text; `path` is used in messages.
pub fn parse(path: &Path, text: &str) -> Result<Photometry, PatchError> {
    let err = |line: usize, m: String| PatchError::new(path, line, m);
    let lines: Vec<&str> = text.lines().collect();
    let tilt = lines
        .iter()
        .position(|l| l.trim_start().to_ascii_uppercase().starts_with("TILT="))
        .ok_or_else(|| err(1, "no TILT= line: not an IES LM-63 file".into()))?;
    let tilt_value = lines[tilt].trim_start()[5..].trim().to_ascii_uppercase();
    // Every token after the TILT line with its 1-based line number.
    let mut tokens = lines.iter().enumerate().skip(tilt + 1).flat_map(|(i, l)| {
        l.split(|c: char| c.is_whitespace() || c == ',').filter(|t| !t.is_empty()).map(move |t| (i + 1, t))
    });
    let last_line = lines.len().max(1);
    let mut next = |what: &str| -> Result<(usize, f64), PatchError> {
        let (line, t) = tokens.next().ok_or_else(|| err(last_line, format!("file ends before {what}")))?;
        let v: f64 = t.parse().map_err(|_| err(line, format!("{what}: {t:?} is not a number")))?;
        if !v.is_finite() {
            return Err(err(line, format!("{what}: {t:?} is not finite")));
        }
        Ok((line, v))
    };
    let count = |(line, v): (usize, f64), what: &str| -> Result<usize, PatchError> {
        if v.fract() != 0.0 || v < 1.0 || v > MAX_ANGLES as f64 {
            return Err(err(line, format!("{what} {v} must be a whole number in 1..{MAX_ANGLES}")));
        }
        Ok(v as usize)
    };
    if tilt_value == "INCLUDE" {
        next("the TILT lamp-to-luminaire geometry")?;
        let n = count(next("the number of TILT angles")?, "number of TILT angles")?;
        for _ in 0..2 * n {
            next("the TILT angles and factors")?;
        }
    }
    next("the number of lamps")?;
    next("the lumens per lamp")?;
    let (mline, multiplier) = next("the candela multiplier")?;
    let nv = count(next("the number of vertical angles")?, "number of vertical angles")?;
    let nh = count(next("the number of horizontal angles")?, "number of horizontal angles")?;
    let (tline, kind) = next("the photometric type")?;
    if kind != 1.0 {
        return Err(err(tline, format!("photometric type {kind} is not supported: only type C (1) is read")));
    }
    for what in ["the units type", "the luminous opening width", "the length", "the height"] {
        next(what)?;
    }
    let (bline, ballast) = next("the ballast factor")?;
    next("the ballast-lamp photometric factor")?;
    next("the input watts")?;
    let scale = multiplier * ballast;
    if !(scale > 0.0) {
        return Err(err(mline.min(bline), format!("candela multiplier × ballast factor = {scale} must be > 0")));
    }
    let mut angles = |n: usize, what: &str| -> Result<(usize, Vec<f32>), PatchError> {
        let mut v = Vec::with_capacity(n);
        let mut first_line = 0;
        for i in 0..n {
            let (line, a) = next(what)?;
            if i == 0 {
                first_line = line;
            }
            if let Some(&prev) = v.last()
                && !(a as f32 > prev)
            {
                return Err(err(line, format!("{what} must increase: {a} after {prev}")));
            }
            v.push(a as f32);
        }
        Ok((first_line, v))
    };
    let (vline, g_deg) = angles(nv, "vertical angles")?;
    let (hline, c_deg) = angles(nh, "horizontal angles")?;
    if g_deg[0] < 0.0 || g_deg[nv - 1] > 180.0 {
        return Err(err(vline, "type C vertical angles must lie in 0..180".into()));
    }
    let (c0, cl) = (c_deg[0], c_deg[nh - 1]);
    let symmetry = match (c0, cl) {
        (0.0, 0.0) => Symmetry::Rotational,
        (0.0, 90.0) => Symmetry::Quadrant,
        (0.0, 180.0) => Symmetry::AboutC0C180,
        (90.0, 270.0) => Symmetry::AboutC90C270,
        (0.0, l) if l > 180.0 && l <= 360.0 => Symmetry::None,
        _ => {
            return Err(err(
                hline,
                format!("horizontal angles {c0}..{cl}: type C needs 0 (symmetric), 0..90, 0..180, 90..270 or 0..360"),
            ));
        }
    };
    let mut candela = Vec::with_capacity(nh);
    for _ in 0..nh {
        let mut plane = Vec::with_capacity(nv);
        for _ in 0..nv {
            let (line, v) = next("the candela values")?;
            if v < 0.0 {
                return Err(err(line, format!("candela value {v} is negative")));
            }
            plane.push((v * scale) as f32);
        }
        candela.push(plane);
    }
    Ok(Photometry { c_deg, g_deg, candela, symmetry })
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMALL: &str = "IESNA:LM-63-2002\n[TEST] none\n[MORE] first\nTILT=NONE\n1 -1 2.0 3 1 1 2 0 0 0\n\
                         1.0 1.0 100\n0 10 20\n0\n500\t250, 0\n";

    #[test]
    fn reads_a_rotational_file_with_tabs_commas_and_multiplier() {
        let p = parse(Path::new("t.ies"), SMALL).unwrap();
        assert_eq!(p.symmetry, Symmetry::Rotational);
        assert_eq!(p.g_deg, vec![0.0, 10.0, 20.0]);
        assert_eq!(p.candela, vec![vec![1000.0, 500.0, 0.0]]);
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse(Path::new("t.ies"), &SMALL.replace("500\t250", "500\tx")).unwrap_err().to_string();
        assert!(e.starts_with("t.ies:9:") && e.contains("not a number"), "{e}");
        let e = parse(Path::new("t.ies"), &SMALL.replace("3 1 1 2", "3 1 2 2")).unwrap_err().to_string();
        assert!(e.starts_with("t.ies:5:") && e.contains("type C"), "{e}");
        let e = parse(Path::new("t.ies"), "garbage\n").unwrap_err().to_string();
        assert!(e.contains("TILT"), "{e}");
        let e = parse(Path::new("t.ies"), &SMALL.replace("500\t250, 0\n", "500\n")).unwrap_err().to_string();
        assert!(e.contains("ends before"), "{e}");
        let e = parse(Path::new("t.ies"), &SMALL.replace("0 10 20", "0 20 10")).unwrap_err().to_string();
        assert!(e.starts_with("t.ies:7:") && e.contains("increase"), "{e}");
        let e = parse(Path::new("t.ies"), &SMALL.replace("2.0 3 1", "2.0 1e9 1")).unwrap_err().to_string();
        assert!(e.contains("whole number"), "{e}");
    }
}
