//! Measured photometry as a beam: a table of relative intensity over
//! C-planes and γ angles (type C photometry, as IES LM-63 and EULUMDAT
//! files store it; see [`crate::photometric`]).
//!
//! Axes: γ is the angle from the beam axis (type C: γ = 0 is the nadir of a
//! luminaire measured pointing down, which is our local −Z). The C angle is
//! the azimuth about the axis, C = 0 toward local +X and C = 90° toward
//! local +Y. Values are interpolated bilinearly in (C, γ) and are zero past
//! the last γ with light in any plane.

use super::axis_angle;
use glam::Vec3;
use std::sync::Arc;

/// A full (0-360°) table of relative intensities with peak 1.
#[derive(Clone, Debug, PartialEq)]
pub struct PhotometricTable {
    /// C angles in degrees, ascending, from 0 to 360 (the 360 plane repeats
    /// the 0 plane); a single plane (`[0]`) means rotational symmetry.
    c_deg: Vec<f32>,
    /// γ angles in degrees, ascending, within [0, 180].
    g_deg: Vec<f32>,
    /// Relative intensity, `values[c * g_deg.len() + g]`, peak 1.
    values: Vec<f32>,
    /// Peak intensity in candela (Î of the measured fixture).
    peak_cd: f32,
    /// γ past which every plane is dark, degrees.
    cut_deg: f32,
    /// ∫ f dω, steradians.
    solid_angle: f32,
}

impl PhotometricTable {
    /// Builds a table from absolute candela values over a full set of
    /// C-planes (`c_deg` ascending in [0, 360], either a single plane or
    /// starting at 0; a missing 360 plane is added as a copy of 0) and
    /// ascending `g_deg`. `candela[c][g]`.
    pub fn new(c_deg: Vec<f32>, g_deg: Vec<f32>, candela: &[Vec<f32>]) -> Result<Self, String> {
        if c_deg.is_empty() || g_deg.is_empty() || candela.len() != c_deg.len() {
            return Err("photometric table needs at least one C-plane and one γ angle".into());
        }
        if candela.iter().any(|p| p.len() != g_deg.len()) {
            return Err("every C-plane needs one value per γ angle".into());
        }
        let ascending = |v: &[f32]| v.windows(2).all(|w| w[1] > w[0]) && v.iter().all(|a| a.is_finite());
        if !ascending(&c_deg) || !ascending(&g_deg) {
            return Err("C and γ angles must be finite and strictly ascending".into());
        }
        if g_deg[0] < 0.0 || g_deg[g_deg.len() - 1] > 180.0 {
            return Err("γ angles must lie in 0..180 degrees".into());
        }
        if c_deg.len() > 1 && (c_deg[0] != 0.0 || c_deg[c_deg.len() - 1] > 360.0) {
            return Err("C angles must start at 0 and end at or before 360 degrees".into());
        }
        if candela.iter().flatten().any(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err("candela values must be finite and >= 0".into());
        }
        let peak = candela.iter().flatten().fold(0.0f32, |m, &v| m.max(v));
        if !(peak > 0.0) {
            return Err("every candela value is 0: the fixture emits nothing".into());
        }
        let mut c_deg = c_deg;
        let mut planes: Vec<Vec<f32>> = candela.to_vec();
        if c_deg.len() > 1 && c_deg[c_deg.len() - 1] < 360.0 {
            c_deg.push(360.0);
            planes.push(planes[0].clone());
        }
        let ng = g_deg.len();
        let values: Vec<f32> = planes.iter().flat_map(|p| p.iter().map(|v| v / peak)).collect();
        // Cut-off: the γ after the last lit sample in any plane (interpolation reaches 0 there).
        let last_lit = (0..ng).rev().find(|&g| planes.iter().any(|p| p[g] > 0.0)).unwrap_or(0);
        let cut_deg = g_deg[(last_lit + 1).min(ng - 1)];
        let mut table = Self { c_deg, g_deg, values, peak_cd: peak, cut_deg, solid_angle: 0.0 };
        table.solid_angle = table.integrate();
        Ok(table)
    }

    /// Relative intensity at azimuth `c` and angle `g` from the axis, degrees.
    pub fn at(&self, c: f32, g: f32) -> f32 {
        let ng = self.g_deg.len();
        if !(g >= self.g_deg[0]) || g > self.cut_deg {
            return 0.0;
        }
        let (g0, tg) = bracket(&self.g_deg, g);
        let plane = |ci: usize| {
            let row = &self.values[ci * ng..(ci + 1) * ng];
            if g0 + 1 < ng { row[g0] * (1.0 - tg) + row[g0 + 1] * tg } else { row[g0] }
        };
        if self.c_deg.len() == 1 {
            return plane(0);
        }
        let c = c.rem_euclid(360.0);
        let (c0, tc) = bracket(&self.c_deg, c);
        let c1 = (c0 + 1).min(self.c_deg.len() - 1);
        (plane(c0) * (1.0 - tc) + plane(c1) * tc).clamp(0.0, 1.0)
    }

    /// Î: the peak intensity in candela.
    pub fn peak_cd(&self) -> f32 {
        self.peak_cd
    }

    /// C angles (degrees), incl. the closing 360 plane.
    pub fn c_angles(&self) -> &[f32] {
        &self.c_deg
    }

    /// γ angles (degrees).
    pub fn g_angles(&self) -> &[f32] {
        &self.g_deg
    }

    /// γ past which the table is dark, degrees.
    pub fn cutoff_deg(&self) -> f32 {
        self.cut_deg
    }

    /// ∫ f dω, steradians.
    pub fn solid_angle(&self) -> f32 {
        self.solid_angle
    }

    /// ∫ f dω by the midpoint rule, 8 × 8 points per (C, γ) cell.
    fn integrate(&self) -> f32 {
        let cs: Vec<f64> =
            if self.c_deg.len() == 1 { vec![0.0, 360.0] } else { self.c_deg.iter().map(|&c| f64::from(c)).collect() };
        let mut gs: Vec<f64> =
            self.g_deg.iter().map(|&g| f64::from(g)).filter(|&g| g <= f64::from(self.cut_deg)).collect();
        if gs.len() < 2 {
            gs = vec![0.0, f64::from(self.cut_deg)];
        }
        let mut sum = 0.0f64;
        for cw in cs.windows(2) {
            for gw in gs.windows(2) {
                let (dc, dg) = ((cw[1] - cw[0]).to_radians() / 8.0, (gw[1] - gw[0]).to_radians() / 8.0);
                for i in 0..8 {
                    let c = cw[0] + (cw[1] - cw[0]) * (i as f64 + 0.5) / 8.0;
                    for j in 0..8 {
                        let g = gw[0] + (gw[1] - gw[0]) * (j as f64 + 0.5) / 8.0;
                        sum += f64::from(self.at(c as f32, g as f32)) * g.to_radians().sin() * dc * dg;
                    }
                }
            }
        }
        sum as f32
    }
}

/// Index i and fraction t with v[i] ≤ x ≤ v[i+1] (clamped to the ends).
fn bracket(v: &[f32], x: f32) -> (usize, f32) {
    let n = v.len();
    if n == 1 || x <= v[0] {
        return (0, 0.0);
    }
    if x >= v[n - 1] {
        return (n - 1, 0.0);
    }
    let i = v.partition_point(|&a| a <= x).clamp(1, n - 1) - 1;
    let t = (x - v[i]) / (v[i + 1] - v[i]);
    (i, t.clamp(0.0, 1.0))
}

/// A beam from measured photometry (shared table: cloning is cheap).
#[derive(Clone, Debug, PartialEq)]
pub struct MeasuredBeam {
    table: Arc<PhotometricTable>,
    cos_cut: f32,
}

impl MeasuredBeam {
    /// Wraps a table.
    pub fn new(table: Arc<PhotometricTable>) -> Self {
        let cos_cut = if table.cut_deg >= 180.0 { -1.0 } else { table.cut_deg.to_radians().cos() };
        Self { table, cos_cut }
    }

    /// The table.
    pub fn table(&self) -> &PhotometricTable {
        &self.table
    }

    /// f_ε for a unit local direction.
    pub fn pattern(&self, dir: Vec3) -> f32 {
        if -dir.z < self.cos_cut {
            return 0.0;
        }
        let g = axis_angle(dir).to_degrees();
        let c = if dir.x == 0.0 && dir.y == 0.0 { 0.0 } else { dir.y.atan2(dir.x).to_degrees() };
        self.table.at(c, g)
    }

    /// Cosine of the cut-off angle.
    pub fn cos_cutoff(&self) -> f32 {
        self.cos_cut
    }

    /// ∫ f dω, steradians.
    pub fn solid_angle(&self) -> f32 {
        self.table.solid_angle
    }

    /// True for a single-plane (rotationally symmetric) table.
    pub fn is_symmetric(&self) -> bool {
        self.table.c_deg.len() == 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_bilinearly_and_wraps_azimuth() {
        let t = PhotometricTable::new(
            vec![0.0, 90.0, 180.0, 270.0],
            vec![0.0, 10.0, 20.0],
            &[vec![100.0, 50.0, 0.0], vec![100.0, 80.0, 0.0], vec![100.0, 50.0, 0.0], vec![100.0, 20.0, 0.0]],
        )
        .unwrap();
        assert_eq!(t.peak_cd(), 100.0);
        assert_eq!(t.at(0.0, 0.0), 1.0);
        assert!((t.at(0.0, 5.0) - 0.75).abs() < 1e-6);
        assert!((t.at(45.0, 10.0) - 0.65).abs() < 1e-6);
        assert!((t.at(315.0, 10.0) - 0.35).abs() < 1e-6, "between 270 and the closing 360 = 0 plane");
        assert!((t.at(-45.0, 10.0) - 0.35).abs() < 1e-6);
        assert_eq!(t.at(0.0, 25.0), 0.0);
        assert_eq!(t.cutoff_deg(), 20.0);
        let b = MeasuredBeam::new(Arc::new(t));
        let d = |c: f32, g: f32| {
            let (c, g) = (c.to_radians(), g.to_radians());
            Vec3::new(g.sin() * c.cos(), g.sin() * c.sin(), -g.cos())
        };
        assert!((b.pattern(d(90.0, 10.0)) - 0.8).abs() < 1e-5, "C90 is local +Y");
        assert!((b.pattern(d(270.0, 10.0)) - 0.2).abs() < 1e-5);
        assert_eq!(b.pattern(Vec3::Z), 0.0);
        assert!(!b.is_symmetric());
    }

    #[test]
    fn solid_angle_of_a_flat_cap() {
        // 1 everywhere up to 30°, then a linear ramp to 0 at 30.001°: ≈ the cap 2π(1 − cos 30°).
        let t = PhotometricTable::new(vec![0.0], vec![0.0, 30.0, 30.001], &[vec![7.0, 7.0, 0.0]]).unwrap();
        let cap = std::f32::consts::TAU * (1.0 - 30f32.to_radians().cos());
        assert!((t.solid_angle() / cap - 1.0).abs() < 1e-3, "{} vs {cap}", t.solid_angle());
    }

    #[test]
    fn broken_tables_are_refused() {
        assert!(PhotometricTable::new(vec![], vec![0.0], &[]).is_err());
        assert!(PhotometricTable::new(vec![0.0], vec![0.0, 0.0], &[vec![1.0, 1.0]]).is_err());
        assert!(PhotometricTable::new(vec![0.0], vec![0.0, 10.0], &[vec![0.0, 0.0]]).is_err());
        assert!(PhotometricTable::new(vec![0.0], vec![0.0, 10.0], &[vec![1.0, f32::NAN]]).is_err());
        assert!(PhotometricTable::new(vec![10.0, 20.0], vec![0.0], &[vec![1.0], vec![1.0]]).is_err());
    }
}
