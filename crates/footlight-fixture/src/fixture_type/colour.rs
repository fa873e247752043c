//! Colour targets for fixtures that mix their colour (issue 36): HSB, CIE
//! xy, colour macros, a colour temperature with a green/magenta tint, and
//! a CTO/CTB/CTC correction of the mixed colour, turned into LED emitter
//! levels ([`EmitterSet`]) or, for a Planckian lamp, a per-channel factor.
//!
//! * **Emitter levels for a chromaticity** ([`EmitterSet::levels_for_xy`]):
//!   the emitters at levels l_i ∈ [0, 1] make XYZ = Σ l_i E_i (E_i: the
//!   emitter's XYZ at full, its luminous share of the lamp's white Y = 1).
//!   The set of reachable XYZ is a zonotope; the target chromaticity is the
//!   ray t·T (T its XYZ at Y = 1), and the mix is the ray's exit point, the
//!   most light the emitters make at that colour:
//!   t* = min over directions d with d·T > 0 of h(d)/(d·T), h(d) = Σ max(0, d·E_i)
//!   (the zonotope's support function). The ratio is linear-fractional on
//!   each cell of the arrangement of the planes d·E_i = 0, so its minimum
//!   sits on a cell edge d = ±E_i × E_j: n(n−1) candidates of n dot
//!   products each. At the minimising d every emitter with d·E_k > 0 is at
//!   full, every one below 0 off, and the two in the plane share the rest
//!   (a 2×2 solve). A chromaticity outside the emitters' gamut is moved
//!   toward their full white until it is inside (bisection): a fixture
//!   shows the nearest colour it can make.
//! * **A given XYZ** ([`EmitterSet::levels_for_xyz`]): the levels for its
//!   chromaticity scaled to its Y, at most the emitters' maximum.
//! * **Planckian locus** ([`planck_xy`]): CIE 1931 xy of a blackbody from
//!   Planck's law and the 2° observer (`footlight_photometry`), tabulated
//!   every 2 mired from 1000 to 25,000 K and interpolated in mired.
//! * **Tint** ([`white_xy`]): the point at distance Duv from the locus
//!   along its normal in the CIE 1960 (u, v) diagram, positive toward
//!   green (above the locus). A tint channel's full physical value is
//!   [`FULL_TINT_DUV`] (estimated: about a full plus-green gel).
//! * **HSB** ([`hsb_xy`]): hue and saturation by the standard HSV → RGB
//!   formula at value 1, read as linear sRGB (IEC 61966-2-1 primaries, D65
//!   white): saturation 0 is D65, hue 0 at full saturation the sRGB red.
//! * **Correcting a mixed colour** ([`bradford`]): a CTO/CTB/CTC or tint on
//!   an LED fixture that mixes a colour of its own (RGB, HSB, CIE, macro) is
//!   applied as a correction filter would be: the mix is adapted from the
//!   emitters' full white to the target white by the Bradford transform
//!   (Lam 1985; the ICC profile specification's matrices) and scaled by
//!   the ideal correction filter's luminous transmittance
//!   ([`super::correction_transmittance`]); the emitters are then set to
//!   that XYZ.

use footlight_photometry::{Emitter, blackbody, spectrum_to_xyz, srgb};
use glam::{DVec3, Vec2, Vec3};
use std::sync::OnceLock;

use crate::state::MAX_MIX;

/// Duv of a tint channel at its full physical value (positive: green).
/// Estimated: a full "plus green" or "minus green" correction gel moves a
/// source about 0.02 in Duv; GDTF gives the attribute no unit.
pub const FULL_TINT_DUV: f32 = 0.02;

/// The emitters of an LED lamp as XYZ at full (each scaled by its share of
/// the lamp's white, Y = 1 with every emitter at full).
#[derive(Clone, Copy, Debug)]
pub struct EmitterSet {
    e: [DVec3; MAX_MIX],
    n: usize,
}

impl EmitterSet {
    /// The set of `emitters` (the first [`MAX_MIX`]); `None` when their shares sum to nothing.
    pub fn of(emitters: &[Emitter]) -> Option<Self> {
        let share = |e: &Emitter| if e.share > 0.0 && e.share.is_finite() { f64::from(e.share) } else { 0.0 };
        let total: f64 = emitters.iter().take(MAX_MIX).map(share).sum();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let mut e = [DVec3::ZERO; MAX_MIX];
        let n = emitters.len().min(MAX_MIX);
        for (k, em) in emitters.iter().take(n).enumerate() {
            e[k] = em.rendered_xyz().as_dvec3() * (share(em) / total);
        }
        Some(Self { e, n })
    }

    /// XYZ of the mix at `levels` (each clamped to [0, 1]).
    pub fn xyz(&self, levels: &[f32]) -> DVec3 {
        (0..self.n).map(|k| self.e[k] * f64::from(unit(levels.get(k).copied().unwrap_or(0.0)))).sum()
    }

    /// XYZ with every emitter at full (Y = 1).
    pub fn white(&self) -> DVec3 {
        self.e[..self.n].iter().sum()
    }

    /// The most light at chromaticity `t` (XYZ, Y = 1): (t*, levels) with
    /// Σ l_i E_i = t*·t; `None` when `t` is outside the emitters' gamut.
    pub fn max_at(&self, t: DVec3) -> Option<(f64, [f32; MAX_MIX])> {
        let e = &self.e[..self.n];
        let scale = e.iter().map(|v| v.length()).fold(0.0, f64::max);
        if !(scale > 0.0) || !t.is_finite() {
            return None;
        }
        let mut best: Option<(f64, DVec3)> = None;
        for i in 0..e.len() {
            for j in i + 1..e.len() {
                let c = e[i].cross(e[j]);
                if c.length() <= 1e-9 * scale * scale {
                    continue; // parallel emitters span no plane
                }
                for d in [c, -c] {
                    // A face plane through the target (d·T ≈ 0) bounds nothing along the ray.
                    let dt = d.dot(t);
                    if dt <= 1e-9 * d.length() * t.length() {
                        continue;
                    }
                    let tol = 1e-9 * d.length() * scale;
                    let h: f64 = e.iter().map(|v| d.dot(*v)).filter(|s| *s > tol).sum();
                    let r = h / dt;
                    if best.is_none_or(|(b, _)| r < b) {
                        best = Some((r, d));
                    }
                }
            }
        }
        let (t_max, d) = best?;
        if !(t_max > 1e-9 * scale && t_max.is_finite()) {
            return None;
        }
        // Emitters in front of the face at full, behind it off, in it shared.
        let tol = 1e-9 * d.length() * scale;
        let mut levels = [0.0f32; MAX_MIX];
        let mut rest = t * t_max;
        let mut free: Vec<usize> = Vec::new();
        for (k, v) in e.iter().enumerate() {
            let s = d.dot(*v);
            if s > tol {
                levels[k] = 1.0;
                rest -= *v;
            } else if s >= -tol {
                free.push(k);
            }
        }
        let mut a = vec![0.0f64; free.len()];
        if let [i, j] = free[..] {
            // Least squares on the two in-plane emitters (normal equations).
            let (p, q) = (e[i], e[j]);
            let (pp, pq, qq) = (p.dot(p), p.dot(q), q.dot(q));
            let det = pp * qq - pq * pq;
            if det.abs() > 1e-18 * pp * qq {
                let (rp, rq) = (rest.dot(p), rest.dot(q));
                a = vec![((qq * rp - pq * rq) / det).clamp(0.0, 1.0), ((pp * rq - pq * rp) / det).clamp(0.0, 1.0)];
            }
        }
        // Coordinate descent with bounds: polishes the 2×2 answer after
        // clamping and handles faces holding more than two (parallel) emitters.
        let mut residual = rest - free.iter().zip(&a).map(|(&k, &x)| e[k] * x).sum::<DVec3>();
        for _ in 0..if free.len() == 2 { 4 } else { 200 } {
            for (slot, &k) in free.iter().enumerate() {
                let len2 = e[k].length_squared();
                if len2 <= 0.0 {
                    continue;
                }
                let next = (a[slot] + residual.dot(e[k]) / len2).clamp(0.0, 1.0);
                residual -= e[k] * (next - a[slot]);
                a[slot] = next;
            }
        }
        for (&k, &x) in free.iter().zip(&a) {
            levels[k] = x as f32;
        }
        Some((t_max, levels))
    }

    /// Levels for the most light at chromaticity `xy`; a chromaticity
    /// outside the emitters' gamut moves toward their full white until it
    /// is inside. `None` only for an unusable `xy` or emitters without a gamut.
    pub fn levels_for_xy(&self, xy: Vec2) -> Option<[f32; MAX_MIX]> {
        self.max_for_xy(xy).map(|(_, l)| l)
    }

    fn max_for_xy(&self, xy: Vec2) -> Option<(f64, [f32; MAX_MIX])> {
        if !(xy.is_finite() && xy.y > 1e-6) {
            return None;
        }
        let t = DVec3::new(f64::from(xy.x) / f64::from(xy.y), 1.0, f64::from(1.0 - xy.x - xy.y) / f64::from(xy.y));
        if let Some(hit) = self.max_at(t) {
            return Some(hit);
        }
        let w = self.white();
        if !(w.y > 0.0) {
            return None;
        }
        let w = w / w.y;
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        let mut found = self.max_at(w)?;
        for _ in 0..30 {
            let mid = 0.5 * (lo + hi);
            match self.max_at(t * (1.0 - mid) + w * mid) {
                Some(hit) => {
                    found = hit;
                    hi = mid;
                }
                None => lo = mid,
            }
        }
        Some(found)
    }

    /// Levels that make `xyz` (its chromaticity as [`EmitterSet::levels_for_xy`],
    /// its luminance as far as the emitters reach). Black gives zeros.
    pub fn levels_for_xyz(&self, xyz: DVec3) -> [f32; MAX_MIX] {
        let sum = xyz.x + xyz.y + xyz.z;
        if !(xyz.y > 0.0 && sum > 0.0 && xyz.is_finite()) {
            return [0.0; MAX_MIX];
        }
        let xy = Vec2::new((xyz.x / sum) as f32, (xyz.y / sum) as f32);
        match self.max_for_xy(xy) {
            Some((t_max, levels)) => {
                let f = (xyz.y / t_max).min(1.0) as f32;
                levels.map(|l| l * f)
            }
            None => [0.0; MAX_MIX],
        }
    }
}

fn unit(x: f32) -> f32 {
    if x > 0.0 { x.min(1.0) } else { 0.0 }
}

/// CIE 1931 xy of a blackbody at `t_k` kelvin (clamped to 1000-25,000 K),
/// from a table every 2 mired interpolated linearly in mired.
pub fn planck_xy(t_k: f32) -> Vec2 {
    static TABLE: OnceLock<Vec<Vec2>> = OnceLock::new();
    let table = TABLE.get_or_init(|| {
        (0..=((MIRED_HI - MIRED_LO) / MIRED_STEP) as usize)
            .map(|k| {
                let mired = MIRED_LO + MIRED_STEP * k as f32;
                let c = spectrum_to_xyz(blackbody(1e6 / mired));
                let s = c.x + c.y + c.z;
                Vec2::new(c.x / s, c.y / s)
            })
            .collect()
    });
    let t = if t_k.is_finite() { t_k.clamp(1000.0, 25_000.0) } else { 6500.0 };
    let f = ((1e6 / t - MIRED_LO) / MIRED_STEP).clamp(0.0, (table.len() - 1) as f32);
    let i = (f.floor() as usize).min(table.len() - 2);
    table[i].lerp(table[i + 1], f - i as f32)
}

const MIRED_LO: f32 = 40.0;
const MIRED_HI: f32 = 1000.0;
const MIRED_STEP: f32 = 2.0;

/// CIE 1960 (u, v) of a chromaticity.
pub fn uv_of(xy: Vec2) -> Vec2 {
    let d = -2.0 * xy.x + 12.0 * xy.y + 3.0;
    Vec2::new(4.0 * xy.x / d, 6.0 * xy.y / d)
}

/// CIE 1931 xy of a CIE 1960 (u, v).
pub fn xy_of_uv(uv: Vec2) -> Vec2 {
    let d = 2.0 * uv.x - 8.0 * uv.y + 4.0;
    Vec2::new(3.0 * uv.x / d, 2.0 * uv.y / d)
}

/// The white at `t_k` kelvin shifted by `duv` along the Planckian locus'
/// normal in (u, v), positive toward green (larger v).
pub fn white_xy(t_k: f32, duv: f32) -> Vec2 {
    let on = planck_xy(t_k);
    if !(duv != 0.0 && duv.is_finite()) {
        return on;
    }
    let mired = 1e6 / t_k.clamp(1000.0, 25_000.0);
    let (a, b) = (uv_of(planck_xy(1e6 / (mired - 1.0))), uv_of(planck_xy(1e6 / (mired + 1.0))));
    let tangent = (b - a).normalize_or_zero();
    let mut normal = tangent.perp();
    if normal.y < 0.0 {
        normal = -normal;
    }
    xy_of_uv(uv_of(on) + normal * duv)
}

/// Linear RGB of HSV (hue in degrees, saturation and value 0..1) by the
/// standard hexcone formula.
pub fn hsv_to_rgb(hue: f32, sat: f32, value: f32) -> Vec3 {
    let h = if hue.is_finite() { hue.rem_euclid(360.0) / 60.0 } else { 0.0 };
    let (s, v) = (unit(sat), unit(value));
    let c = v * s;
    let x = c * (1.0 - ((h % 2.0) - 1.0).abs());
    let rgb = match h as u32 {
        0 => Vec3::new(c, x, 0.0),
        1 => Vec3::new(x, c, 0.0),
        2 => Vec3::new(0.0, c, x),
        3 => Vec3::new(0.0, x, c),
        4 => Vec3::new(x, 0.0, c),
        _ => Vec3::new(c, 0.0, x),
    };
    rgb + Vec3::splat(v - c)
}

/// The chromaticity of hue and saturation ([`hsv_to_rgb`] at value 1 as
/// linear sRGB).
pub fn hsb_xy(hue: f32, sat: f32) -> Vec2 {
    srgb::xy(srgb::linear_srgb_to_xyz(hsv_to_rgb(hue, sat, 1.0))).unwrap_or(Vec2::new(0.3127, 0.3290))
}

/// XYZ with Y = 1 at chromaticity `xy`.
fn unit_xyz(xy: Vec2) -> DVec3 {
    let (x, y) = (f64::from(xy.x), f64::from(xy.y.max(1e-6)));
    DVec3::new(x / y, 1.0, (1.0 - x - y) / y)
}

/// `xyz` chromatically adapted from white `from` to white `to` (xy) by the
/// Bradford transform; luminance of the whites kept.
pub fn bradford(xyz: DVec3, from: Vec2, to: Vec2) -> DVec3 {
    const M: [[f64; 3]; 3] = [[0.8951, 0.2664, -0.1614], [-0.7502, 1.7135, 0.0367], [0.0389, -0.0685, 1.0296]];
    const M_INV: [[f64; 3]; 3] = [
        [0.986_992_9, -0.147_054_3, 0.159_962_7],
        [0.432_305_3, 0.518_360_3, 0.049_291_2],
        [-0.008_528_7, 0.040_042_8, 0.968_486_7],
    ];
    let mul = |m: &[[f64; 3]; 3], v: DVec3| {
        DVec3::new(DVec3::from(m[0]).dot(v), DVec3::from(m[1]).dot(v), DVec3::from(m[2]).dot(v))
    };
    let (a, b) = (mul(&M, unit_xyz(from)), mul(&M, unit_xyz(to)));
    if !(a.min_element() > 0.0 && b.is_finite()) {
        return xyz;
    }
    mul(&M_INV, mul(&M, xyz) * (b / a))
}

/// A per-channel factor (linear sRGB, largest channel 1) that turns a
/// source of chromaticity `from` into `to`: the ideal filter for a
/// Planckian lamp asked for a colour it cannot mix (HSB, CIE, a colour
/// macro on a discharge or tungsten fixture). An estimated model: the
/// filter is taken to act per sRGB channel.
pub fn filter_between(from: Vec2, to: Vec2) -> Vec3 {
    let (a, b) = (srgb::xyz_to_linear_srgb(unit_xyz(from).as_vec3()), srgb::xyz_to_linear_srgb(unit_xyz(to).as_vec3()));
    let f = (b.max(Vec3::ZERO) / a.max(Vec3::splat(1e-6))).max(Vec3::ZERO);
    let m = f.max_element();
    if m > 0.0 && m.is_finite() { f / m } else { Vec3::ONE }
}

/// A per-channel factor moving a source of chromaticity `from` to `to` at
/// equal luminance (a tint on a Planckian lamp: Y kept, estimated as lossless).
pub fn shift_between(from: Vec2, to: Vec2) -> Vec3 {
    let (a, b) = (srgb::xyz_to_linear_srgb(unit_xyz(from).as_vec3()), srgb::xyz_to_linear_srgb(unit_xyz(to).as_vec3()));
    let f = (b.max(Vec3::ZERO) / a.max(Vec3::splat(1e-6))).max(Vec3::ZERO);
    let y = srgb::luminance(a * f);
    if y > 0.0 && y.is_finite() { f * (srgb::luminance(a) / y) } else { Vec3::ONE }
}

#[cfg(test)]
mod tests {
    use super::*;
    use footlight_photometry::Chroma;

    fn srgb_emitters() -> EmitterSet {
        let e = [
            Emitter::new("r", Chroma::Xy(Vec2::new(0.64, 0.33)), 0.2126),
            Emitter::new("g", Chroma::Xy(Vec2::new(0.30, 0.60)), 0.7152),
            Emitter::new("b", Chroma::Xy(Vec2::new(0.15, 0.06)), 0.0722),
        ];
        EmitterSet::of(&e).unwrap()
    }

    fn rgbw() -> EmitterSet {
        let e = [
            Emitter::new("r", Chroma::Xy(Vec2::new(0.70, 0.299)), 20.0),
            Emitter::new("g", Chroma::Xy(Vec2::new(0.17, 0.70)), 60.0),
            Emitter::new("b", Chroma::Xy(Vec2::new(0.14, 0.04)), 8.0),
            Emitter::new("w", Chroma::Xy(Vec2::new(0.3127, 0.329)), 100.0),
        ];
        EmitterSet::of(&e).unwrap()
    }

    fn xy_of(v: DVec3) -> Vec2 {
        let s = v.x + v.y + v.z;
        Vec2::new((v.x / s) as f32, (v.y / s) as f32)
    }

    #[test]
    fn srgb_primaries_mix_hsb_hues_exactly() {
        let set = srgb_emitters();
        // Hue 0, 120, 240 at full saturation: one primary at full.
        for (hue, k) in [(0.0, 0), (120.0, 1), (240.0, 2)] {
            let l = set.levels_for_xy(hsb_xy(hue, 1.0)).unwrap();
            for (i, &x) in l.iter().take(3).enumerate() {
                let want = if i == k { 1.0 } else { 0.0 };
                assert!((x - want).abs() < 2e-3, "hue {hue}: {l:?}");
            }
        }
        // Saturation 0: the D65 white, all at full (the emitters are the sRGB primaries).
        let l = set.levels_for_xy(hsb_xy(200.0, 0.0)).unwrap();
        assert!(l.iter().take(3).all(|x| (x - 1.0).abs() < 2e-3), "{l:?}");
    }

    #[test]
    fn the_mix_is_the_brightest_at_its_chromaticity() {
        let set = rgbw();
        for xy in [Vec2::new(0.45, 0.41), Vec2::new(0.3, 0.3), Vec2::new(0.25, 0.45), Vec2::new(0.5, 0.33)] {
            let (t, l) = set.max_at(unit_xyz(xy)).unwrap();
            let got = set.xyz(&l);
            assert!((xy_of(got) - xy).length() < 1e-4, "{xy}: {}", xy_of(got));
            assert!((got.y - t).abs() < 1e-6);
            // Brute force at exactly this chromaticity: white and blue on a
            // grid, red and green from the two chromaticity equations.
            let e: Vec<DVec3> =
                (0..4).map(|k| set.xyz(&[0, 1, 2, 3].map(|i| if i == k { 1.0 } else { 0.0 }))).collect();
            let (kx, kz) = (f64::from(xy.x / xy.y), f64::from((1.0 - xy.x - xy.y) / xy.y));
            let g = |v: DVec3| (v.x - kx * v.y, v.z - kz * v.y);
            let (r, gr, b, w) = (g(e[0]), g(e[1]), g(e[2]), g(e[3]));
            let det = r.0 * gr.1 - r.1 * gr.0;
            let n = 400;
            let mut brute = 0.0f64;
            for i in 0..=n {
                for j in 0..=n {
                    let (lw, lb) = (i as f64 / n as f64, j as f64 / n as f64);
                    let rhs = (-(lw * w.0 + lb * b.0), -(lw * w.1 + lb * b.1));
                    let lr = (rhs.0 * gr.1 - rhs.1 * gr.0) / det;
                    let lg = (r.0 * rhs.1 - r.1 * rhs.0) / det;
                    if (0.0..=1.0).contains(&lr) && (0.0..=1.0).contains(&lg) {
                        brute = brute.max(lr * e[0].y + lg * e[1].y + lb * e[2].y + lw * e[3].y);
                    }
                }
            }
            assert!((t - brute).abs() < 5e-3, "{xy}: solver {t}, grid {brute}");
            assert!(t >= brute - 1e-9, "{xy}: the grid found more light than the solver: {t} < {brute}");
        }
    }

    #[test]
    fn out_of_gamut_targets_move_toward_white_and_xyz_scales() {
        let set = srgb_emitters();
        // Spectral green is outside sRGB: the mix lands on the gamut edge between it and white.
        let l = set.levels_for_xy(Vec2::new(0.08, 0.83)).unwrap();
        assert!(l.iter().all(|x| (0.0..=1.0).contains(x)));
        assert!(l[1] > 0.99, "{l:?}");
        // An XYZ at half the maximum: half the levels.
        let (t, full) = set.max_at(unit_xyz(Vec2::new(0.4, 0.4))).unwrap();
        let half = set.levels_for_xyz(unit_xyz(Vec2::new(0.4, 0.4)) * (0.5 * t));
        for k in 0..3 {
            assert!((half[k] - 0.5 * full[k]).abs() < 1e-4);
        }
        assert_eq!(set.levels_for_xyz(DVec3::ZERO), [0.0; MAX_MIX]);
    }

    #[test]
    fn tint_moves_along_the_locus_normal() {
        for t in [2700.0, 3200.0, 5600.0, 10_000.0] {
            let on = uv_of(planck_xy(t));
            let up = uv_of(white_xy(t, 0.01));
            assert!(((up - on).length() - 0.01).abs() < 1e-5, "{t}");
            assert!(up.y > on.y, "positive Duv is above the locus");
            let down = uv_of(white_xy(t, -0.01));
            assert!((((up + down) * 0.5) - on).length() < 1e-5);
        }
    }

    #[test]
    fn bradford_maps_white_to_white() {
        let (a, b) = (planck_xy(6500.0), planck_xy(3200.0));
        let out = bradford(unit_xyz(a) * 2.0, a, b);
        assert!((xy_of(out) - b).length() < 1e-6);
        assert!((out.y - 2.0).abs() < 1e-3);
    }
}
