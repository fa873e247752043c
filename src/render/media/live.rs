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

use super::medium::{Medium, clean_density};
use super::resolve::resolve;
use super::single::HazeView;
use crate::render::buffer::{HazeBuffer, LightBuffer};
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
