//! Haze in the live daemon: the two buffers per light that keep a hazer
//! change a composite-time re-weighting (issue 15, items 1 and 2).
//!
//! The tracer publishes, per light, the surface buffer S_i(d0) (direct +
//! indirect, dimmed by the haze on the camera and light paths at the density
//! d0 of its build, [`extinguish`]) and a haze buffer
//! H_i(d0) = σ_s a0 e^(−d0 κ) ([`live_haze_buffer`]): the in-scattered
//! radiance per unit density. The frame clock composites
//!
//!   I = Σ k_i S_i(d0) + Σ (d · k_i) H_i(d0)                    (eq. 5)
//!
//! with d the hazer's density now: both are plain entries of the eq. 5 sum,
//! so every compositor (CPU, GPU, the browser stream) shows haze without
//! haze-specific code, and a density change is a new weight d · k_i (no
//! light is rebuilt). At d = d0 the picture is the exact resolve
//! ([`super::resolve`]); away from d0 the extinction is still d0's (the bench
//! reports the error against a rebuild at d), and every build after the
//! change uses the new density.

use super::medium::{Medium, clean_density};
use super::resolve::resolve;
use super::single::HazeView;
use crate::render::buffer::{HazeBuffer, LightBuffer, TILE};
use glam::Vec3;

/// The haze buffer the compositors take: σ_s a0 e^(−d0 κ) per pixel, grey,
/// per unit density (the composite weight is d · k_i). `medium` is the haze
/// at 100 % that `haze` was rendered with; `d0` the density of the build.
/// Same tiles as `haze`.
pub fn live_haze_buffer(haze: &HazeBuffer, medium: &Medium, d0: f32) -> LightBuffer {
    let d0 = clean_density(d0);
    let src = haze.as_light_buffer();
    let (w, h) = (haze.width() as usize, haze.height() as usize);
    LightBuffer::from_tiles(haze.width(), haze.height(), &src.occupied(), |tx, ty, tile| {
        let Some(s) = src.tile(tx, ty) else { return };
        for r in 0..TILE.min(h - ty * TILE) {
            for c in 0..TILE.min(w - tx * TILE) {
                let k = r * TILE + c;
                let (a0, kappa) = (s[k].x, s[k].y);
                if a0 > 0.0 {
                    tile[k] = Vec3::splat(medium.sigma_s * a0 * (-d0 * kappa).exp());
                }
            }
        }
    })
}

/// A surface buffer (direct + indirect, no haze) seen through the haze at
/// density `d0`: each pixel times e^(−d0 κ_s), κ_s the optical depth to the
/// camera and to the light at 100 % ([`super::resolve`] without a beam).
pub fn extinguish(hv: &HazeView, medium: &Medium, light_position: Vec3, surface: &LightBuffer, d0: f32) -> LightBuffer {
    resolve(hv, medium, light_position, surface, None, d0)
}
