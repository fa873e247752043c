//! Haze in the live daemon: what the tracer publishes per light so that a
//! hazer change is a composite-time re-weighting (issue 15, items 1 and 2).
//!
//! A light's buffer in haze of density d, b_i(d) = S_i e^(−d κ_s) +
//! d σ_s a0 e^(−d κ_h) ([`super::resolve`]), is not linear in d. The tracer
//! publishes it at the density knots [`KNOTS`] (0, ½, 1): at 0 it is the
//! surface buffer S_i itself (today's buffer, bit for bit), at ½ and 1 the
//! two resolved buffers of [`knot_buffers`]. The frame clock composites
//!
//!   I = Σ_i Σ_j (w_j(d) k_i) b_i(d_j)                          (eq. 5)
//!
//! with w_j the piecewise-linear hat weights of [`knot_weights`]: every term
//! is an ordinary eq. 5 entry (a buffer and an RGB weight), so every
//! compositor (CPU, GPU, the browser stream) shows haze without
//! haze-specific code, and a density change is a new set of weights: no
//! light is rebuilt, no pixel re-resolved. Exact at the knots; between them
//! the error is that of linear interpolation of e^(−d κ) (the bench reports
//! it against an exact rebuild at d).
//!
//! # No beam is kept
//! A light's beam is needed only when it is made (the coarse beam with the
//! direct stage, the refined one with the Whitted stage): the knots are
//! resolved from it at once. A later stage of the same light (photons,
//! refinement passes) changes only the surface buffer S → S', and the
//! knots follow without the beam ([`update_knots`]):
//!
//!   b_j' = b_j + (S' − S) e^(−d_j κ_s)
//!
//! (the haze term of b_j is untouched; e^(−d_j κ_s) is computed from the
//! view as [`resolve`] does, so S' = S gives b_j back exactly). The live
//! tracer thus holds per light its surface buffer and two knot buffers,
//! and no beam between stages (the 600-fixture rig held 611 MiB of beams).

use super::medium::{Medium, clean_density};
use super::resolve::{resolve, surface_depth};
use super::single::HazeView;
use crate::render::buffer::{HazeBuffer, LightBuffer, TILE};
use glam::Vec3;

/// Densities at which a light's buffer is published: 0, ½ and 1 of the
/// patch's haze.
pub const KNOTS: [f32; 3] = [0.0, 0.5, 1.0];

/// The weights w_j(d) of the knots for density `d` (0-1, NaN → 0): hat
/// functions, non-negative, summing to 1, exactly one 1 at a knot.
pub fn knot_weights(d: f32) -> [f32; 3] {
    let d = clean_density(d);
    let mut w = [0.0; 3];
    for j in 0..KNOTS.len() - 1 {
        let (a, b) = (KNOTS[j], KNOTS[j + 1]);
        if d <= b {
            let f = (d - a) / (b - a);
            w[j] = 1.0 - f;
            w[j + 1] = f;
            return w;
        }
    }
    w[KNOTS.len() - 1] = 1.0;
    w
}

/// A light's buffers at the knots ½ and 1 (the knot 0 is `surface`
/// itself): `surface` (direct + indirect, no haze) and `beam` (its haze
/// buffer) resolved at those densities of `medium` (the haze at 100 %).
pub fn knot_buffers(
    hv: &HazeView,
    medium: &Medium,
    light_position: Vec3,
    surface: &LightBuffer,
    beam: Option<&HazeBuffer>,
) -> [LightBuffer; 2] {
    [KNOTS[1], KNOTS[2]].map(|d| resolve(hv, medium, light_position, surface, beam, d))
}

/// A light's knot buffers ½ and 1 for its new surface buffer `surface`,
/// from `knots`, those of its previous surface buffer `previous` (same
/// light, same beam, same view): b_j + (S' − S) e^(−d_j κ_s) (module doc).
/// `medium` is the one the knots' surfaces were dimmed with
/// ([`super::resolve::surface_medium`] of the beam they were made with).
/// A rounding residue below 0 where the surface term cancels is 0; a NaN
/// stays NaN (the buffer check reports it).
pub fn update_knots(
    hv: &HazeView,
    medium: &Medium,
    light_position: Vec3,
    previous: &LightBuffer,
    surface: &LightBuffer,
    knots: [&LightBuffer; 2],
) -> [LightBuffer; 2] {
    let (w, h) = (hv.width as usize, hv.height as usize);
    let zero_tile = [Vec3::ZERO; TILE * TILE];
    [0, 1].map(|j| {
        let d = KNOTS[j + 1];
        let knot = knots[j];
        let mut candidates = knot.occupied();
        candidates.extend(surface.occupied());
        candidates.sort_unstable();
        candidates.dedup();
        LightBuffer::from_tiles(hv.width, hv.height, &candidates, |tx, ty, tile| {
            let old = knot.tile(tx, ty).unwrap_or(std::borrow::Cow::Borrowed(&zero_tile[..]));
            let (s0, s1) = (
                previous.tile(tx, ty).unwrap_or(std::borrow::Cow::Borrowed(&zero_tile[..])),
                surface.tile(tx, ty).unwrap_or(std::borrow::Cow::Borrowed(&zero_tile[..])),
            );
            for r in 0..TILE.min(h - ty * TILE) {
                for c in 0..TILE.min(w - tx * TILE) {
                    let k = r * TILE + c;
                    let mut v = old[k];
                    if s1[k] != s0[k] {
                        let i = (ty * TILE + r) * w + tx * TILE + c;
                        let t = (-d * surface_depth(hv, medium, light_position, i)).exp();
                        // As `resolve` forms S e^(−d κ_s): S' = 0 cancels exactly.
                        v = v - s0[k] * t + s1[k] * t;
                        v = Vec3::select(v.cmplt(Vec3::ZERO), Vec3::ZERO, v);
                    }
                    tile[k] = v;
                }
            }
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn knot_weights_are_hats() {
        assert_eq!(knot_weights(0.0), [1.0, 0.0, 0.0]);
        assert_eq!(knot_weights(0.5), [0.0, 1.0, 0.0]);
        assert_eq!(knot_weights(1.0), [0.0, 0.0, 1.0]);
        assert_eq!(knot_weights(0.25), [0.5, 0.5, 0.0]);
        assert_eq!(knot_weights(0.75), [0.0, 0.5, 0.5]);
        assert_eq!(knot_weights(f32::NAN), [1.0, 0.0, 0.0]);
        assert_eq!(knot_weights(7.0), [0.0, 0.0, 1.0]);
        for k in 0..=100 {
            let w = knot_weights(k as f32 / 100.0);
            assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6 && w.iter().all(|&x| x >= 0.0));
        }
    }
}
