//! The real-time update of Vierjahn 2010, section 3.3 and eq. 5 on the CPU:
//! I = Σ_i k_i ⊙ buffer_i, where buffer_i holds the light's unit-intensity
//! direct (and, once photon maps land, indirect) terms and k_i = c_F c_I v Î
//! is an RGB weight (eq. 4).
//!
//! Dimmer and colour changes only change k_i, so this is all that runs per
//! display frame for them. It is the reference the GPU compositor matches.
//! Work is skipped where it cannot contribute: lights with k_i = 0 and tiles
//! a light's beam does not reach.

use super::buffer::{LightBuffer, TILE};
use glam::Vec3;
use rayon::prelude::*;

/// Composites `buffers` with weights `k` (same length) into a dense
/// row-major linear image of `width`×`height` (cd/m²).
pub fn composite(buffers: &[&LightBuffer], k: &[Vec3], width: u32, height: u32) -> Vec<Vec3> {
    let mut out = vec![Vec3::ZERO; (width * height) as usize];
    composite_into(buffers, k, width, height, &mut out);
    out
}

/// As [`composite`], writing into an existing image (no allocation per frame).
pub fn composite_into(buffers: &[&LightBuffer], k: &[Vec3], width: u32, height: u32, out: &mut [Vec3]) {
    assert_eq!(buffers.len(), k.len(), "one k per buffer");
    let w = width as usize;
    let h = height as usize;
    assert_eq!(out.len(), w * h, "output size");
    // Only lights that can contribute (k_i = 0: dimmer at zero, or a black gel).
    let active: Vec<(&LightBuffer, Vec3)> = buffers
        .iter()
        .zip(k)
        .filter(|(b, k)| **k != Vec3::ZERO && b.occupied_tiles() > 0)
        .map(|(b, k)| (*b, *k))
        .collect();
    let tiles_x = w.div_ceil(TILE);
    out.par_chunks_mut(w * TILE).enumerate().for_each(|(ty, band)| {
        band.fill(Vec3::ZERO);
        let rows = band.len() / w.max(1);
        for (buf, k) in &active {
            for tx in 0..tiles_x {
                let Some(tile) = buf.tile(tx, ty) else { continue };
                let x0 = tx * TILE;
                let cols = TILE.min(w - x0);
                for r in 0..rows {
                    let dst = &mut band[r * w + x0..r * w + x0 + cols];
                    let src = &tile[r * TILE..r * TILE + cols];
                    for (d, s) in dst.iter_mut().zip(src) {
                        *d += *k * *s; // Vierjahn 2010, eq. (5)
                    }
                }
            }
        }
    });
    let _ = h;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weighted_sum_of_sparse_buffers() {
        let (w, h) = (35u32, 19u32);
        let a: Vec<Vec3> = (0..w * h).map(|i| Vec3::new(i as f32, 0.5, 0.0)).collect();
        let mut b = vec![Vec3::ZERO; (w * h) as usize];
        b[100] = Vec3::ONE;
        let (ba, bb) = (LightBuffer::from_dense(w, h, &a), LightBuffer::from_dense(w, h, &b));
        let k = [Vec3::new(2.0, 1.0, 3.0), Vec3::splat(10.0)];
        let out = composite(&[&ba, &bb], &k, w, h);
        for i in 0..(w * h) as usize {
            let expect = k[0] * a[i] + k[1] * b[i];
            assert!((out[i] - expect).length() <= 1e-4 * expect.length().max(1.0), "{i}");
        }
        // A dark light costs nothing and adds nothing.
        let out2 = composite(&[&ba, &bb], &[Vec3::ZERO, Vec3::ZERO], w, h);
        assert!(out2.iter().all(|v| *v == Vec3::ZERO));
    }
}
