//! Measured photometry files: IES LM-63 (`.ies`) and EULUMDAT (`.ldt`,
//! `.eul`), read into a [`PhotometricTable`] for a [`crate::beam::MeasuredBeam`].
//!
//! Both formats store type C photometry: intensities over C-planes (azimuth
//! about the luminaire axis) and γ angles (from the nadir, which is the beam
//! axis, local −Z). Both may store only a sector and declare a symmetry; the
//! reader mirrors the sector to a full 0-360° set.
//!
//! Why not a crate: `eulumdat` 0.7 (the most complete reader, both formats)
//! is AGPL-3.0-or-later, which Footlight (MIT OR Apache-2.0) cannot link
//! without becoming AGPL; `lidrs` 0.2.3 (MIT) panics on some inputs (a
//! `[MORE]` keyword first, a one-angle plane), splits numbers on spaces and
//! commas but not tabs, opens `TILT=<file>` relative to the working
//! directory, and gives no line numbers in our `file:line` form. Both
//! formats are small, fixed, line- or token-based texts, so Footlight reads
//! them itself (IES LM-63-2002 and EULUMDAT as specified by Stockmar, 1990)
//! and every error names the file and line.

pub mod ies;
pub mod ldt;

use crate::beam::PhotometricTable;
use crate::error::PatchError;
use std::path::Path;

/// Which sector a file stores and how to mirror it to 0-360°.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Symmetry {
    /// All planes given (0 ≤ C < 360).
    None,
    /// One plane stands for every C (rotationally symmetric).
    Rotational,
    /// Planes C0-C180 given; mirrored about the C0-C180 plane.
    AboutC0C180,
    /// Planes C90-C270 given; mirrored about the C90-C270 plane.
    AboutC90C270,
    /// Planes C0-C90 given; mirrored about both planes.
    Quadrant,
}

/// Type C photometry as read: the stored sector in absolute candela.
#[derive(Clone, Debug, PartialEq)]
pub struct Photometry {
    /// C angles of the stored planes, degrees.
    pub c_deg: Vec<f32>,
    /// γ angles, degrees from the nadir (beam axis).
    pub g_deg: Vec<f32>,
    /// Absolute candela, `candela[c][g]`.
    pub candela: Vec<Vec<f32>>,
    /// How the stored sector extends to a full circle.
    pub symmetry: Symmetry,
}

impl Photometry {
    /// The full 0-360° table (relative values, peak 1, and Î in candela).
    pub fn to_table(&self) -> Result<PhotometricTable, String> {
        let (c, planes) = expand(&self.c_deg, &self.candela, self.symmetry)?;
        PhotometricTable::new(c, self.g_deg.clone(), &planes)
    }
}

/// Reads an `.ies` or `.ldt`/`.eul` file (chosen by extension) into a table.
pub fn load(path: &Path) -> Result<PhotometricTable, PatchError> {
    let text = std::fs::read(path).map_err(|e| PatchError::new(path, 0, format!("cannot read: {e}")))?;
    // Photometric files are often Latin-1; keep ASCII digits exact and replace the rest.
    let text = String::from_utf8_lossy(&text);
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let photometry = match ext.as_str() {
        "ies" => ies::parse(path, &text)?,
        "ldt" | "eul" => ldt::parse(path, &text)?,
        _ => {
            return Err(PatchError::new(
                path,
                0,
                "unknown photometry format: use a .ies (LM-63) or .ldt (EULUMDAT) file",
            ));
        }
    };
    photometry.to_table().map_err(|m| PatchError::new(path, 0, m))
}

/// Mirrors a stored sector to a full set of planes in [0, 360), sorted.
fn expand(c: &[f32], planes: &[Vec<f32>], symmetry: Symmetry) -> Result<(Vec<f32>, Vec<Vec<f32>>), String> {
    if c.is_empty() || c.len() != planes.len() {
        return Err("no C-planes".into());
    }
    if symmetry == Symmetry::Rotational {
        return Ok((vec![0.0], vec![planes[0].clone()]));
    }
    let mut all: Vec<(f32, &Vec<f32>)> = c.iter().copied().zip(planes.iter()).collect();
    let mirror_c0 = |v: &mut Vec<(f32, &'_ Vec<f32>)>| {
        let extra: Vec<_> = v.iter().map(|&(a, p)| (360.0 - a, p)).collect();
        v.extend(extra);
    };
    match symmetry {
        Symmetry::None | Symmetry::Rotational => {}
        Symmetry::AboutC0C180 => mirror_c0(&mut all),
        Symmetry::AboutC90C270 => {
            let extra: Vec<_> = all.iter().map(|&(a, p)| (180.0 - a, p)).collect();
            all.extend(extra);
        }
        Symmetry::Quadrant => {
            let extra: Vec<_> = all.iter().map(|&(a, p)| (180.0 - a, p)).collect();
            all.extend(extra);
            mirror_c0(&mut all);
        }
    }
    let mut out: Vec<(f32, Vec<f32>)> = Vec::with_capacity(all.len());
    for (a, p) in all {
        let a = a.rem_euclid(360.0);
        let a = if (360.0 - a) < 1e-4 { 0.0 } else { a };
        if !out.iter().any(|(b, _)| (b - a).abs() < 1e-4) {
            out.push((a, p.clone()));
        }
    }
    out.sort_by(|x, y| x.0.total_cmp(&y.0));
    if out[0].0 != 0.0 {
        return Err(format!("the C-planes do not include C0 after applying the symmetry (first is C{})", out[0].0));
    }
    Ok(out.into_iter().unzip())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sectors_mirror_to_full_circles() {
        let p = |v: f32| vec![v];
        let (c, v) = expand(&[0.0, 45.0, 90.0], &[p(1.0), p(2.0), p(3.0)], Symmetry::Quadrant).unwrap();
        assert_eq!(c, vec![0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0]);
        assert_eq!(v.iter().map(|x| x[0]).collect::<Vec<_>>(), vec![1.0, 2.0, 3.0, 2.0, 1.0, 2.0, 3.0, 2.0]);
        let (c, v) = expand(&[90.0, 180.0, 270.0], &[p(1.0), p(2.0), p(3.0)], Symmetry::AboutC90C270).unwrap();
        assert_eq!(c, vec![0.0, 90.0, 180.0, 270.0]);
        assert_eq!(v.iter().map(|x| x[0]).collect::<Vec<_>>(), vec![2.0, 1.0, 2.0, 3.0]);
        let (c, _) = expand(&[0.0, 90.0, 180.0], &[p(1.0), p(2.0), p(3.0)], Symmetry::AboutC0C180).unwrap();
        assert_eq!(c, vec![0.0, 90.0, 180.0, 270.0]);
        let (c, _) = expand(&[0.0, 180.0, 360.0], &[p(1.0), p(2.0), p(1.0)], Symmetry::None).unwrap();
        assert_eq!(c, vec![0.0, 180.0]);
        assert!(expand(&[10.0, 20.0], &[p(1.0), p(2.0)], Symmetry::None).is_err());
    }
}
