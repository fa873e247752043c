//! The real-time update of Vierjahn 2010, section 3.3 and eq. 5 on the CPU:
//! I = Σ_i k_i ⊙ buffer_i, where buffer_i holds the light's unit-intensity
//! direct (and, once photon maps land, indirect) terms and k_i = c_F c_I v Î
//! is an RGB weight (eq. 4).
//!
//! Dimmer and colour changes only change k_i, so this is all that runs per
//! display frame for them. [`composite`] recomputes a whole frame (the
//! reference the GPU compositor matches); [`Compositor`] keeps the last frame
//! and recomposes only the tiles that lights with a changed k_i (or a rebuilt
//! buffer) cover, so one fader move costs the area its beam lights, not the
//! whole rig. Tiles are recomposed from scratch (never by adding a delta), so
//! repeated updates cannot drift. Work is skipped where it cannot contribute:
//! lights with k_i = 0 and tiles a light does not reach.

use super::buffer::{LightBuffer, TILE};
use super::display::Display;
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
    assert_eq!(out.len(), w * height as usize, "output size");
    let active = active_lights(buffers, k);
    let tiles_x = w.div_ceil(TILE);
    out.par_chunks_mut(w * TILE).enumerate().for_each(|(ty, band)| {
        band.fill(Vec3::ZERO);
        for tx in 0..tiles_x {
            accumulate_tile(&active, tx, ty, w, band);
        }
    });
}

/// Lights that can contribute: k_i ≠ 0 (dimmer at zero or a black gel
/// costs nothing) and at least one occupied tile.
fn active_lights<'a>(buffers: &[&'a LightBuffer], k: &[Vec3]) -> Vec<(&'a LightBuffer, Vec3)> {
    buffers.iter().zip(k).filter(|(b, k)| **k != Vec3::ZERO && b.occupied_tiles() > 0).map(|(b, k)| (*b, *k)).collect()
}

/// Adds every active light's tile (tx, ty) into `band` (the image rows of
/// tile row ty, `w` pixels wide), which must be zero there beforehand.
fn accumulate_tile(active: &[(&LightBuffer, Vec3)], tx: usize, ty: usize, w: usize, band: &mut [Vec3]) {
    let rows = band.len() / w.max(1);
    let x0 = tx * TILE;
    let cols = TILE.min(w - x0);
    for (buf, k) in active {
        let Some(tile) = buf.tile(tx, ty) else { continue };
        // k repeated over a tile row, so the inner loop is a plain
        // element-wise multiply-add over f32 that the compiler vectorises.
        let kk: [f32; 3 * TILE] = std::array::from_fn(|i| k[i % 3]);
        for r in 0..rows {
            let dst: &mut [f32] = bytemuck::cast_slice_mut(&mut band[r * w + x0..r * w + x0 + cols]);
            let src: &[f32] = bytemuck::cast_slice(&tile[r * TILE..r * TILE + cols]);
            for ((d, s), k) in dst.iter_mut().zip(src).zip(&kk) {
                *d += k * s; // Vierjahn 2010, eq. (5)
            }
        }
    }
}

/// What one [`Compositor::update`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UpdateStats {
    /// Tiles recomposed and re-encoded.
    pub tiles: usize,
    /// Lights whose k or buffer changed.
    pub changed_lights: usize,
}

/// One light as the compositor sees it.
#[derive(Clone, Copy, Debug)]
pub struct CompositeInput<'a> {
    /// The light's current unit-intensity buffer.
    pub buffer: &'a LightBuffer,
    /// Bumped by the caller whenever `buffer` is replaced (a rebuild).
    pub generation: u64,
    /// k_i now (eq. 4).
    pub k: Vec3,
}

/// Incremental compositor: keeps the last linear frame and its sRGB
/// encoding, and recomposes only tiles covered by changed lights.
pub struct Compositor {
    width: u32,
    height: u32,
    display: Display,
    linear: Vec<Vec3>,
    srgb: Vec<u8>,
    /// Per light: last k, last generation, and the tiles its buffer covered.
    seen: Vec<(Vec3, u64, Vec<u32>)>,
}

impl Compositor {
    /// A black frame of `width`×`height`.
    pub fn new(width: u32, height: u32, display: Display) -> Self {
        let n = (width * height) as usize;
        Self { width, height, display, linear: vec![Vec3::ZERO; n], srgb: vec![0; n * 3], seen: Vec::new() }
    }

    /// The display settings the sRGB pixels are encoded with.
    pub fn display(&self) -> Display {
        self.display
    }

    /// Frame width.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Frame height.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The current linear frame (cd/m²).
    pub fn linear(&self) -> &[Vec3] {
        &self.linear
    }

    /// The current frame as 8-bit sRGB, row-major RGB.
    pub fn srgb8(&self) -> &[u8] {
        &self.srgb
    }

    /// Changes exposure, white balance and roll-off (re-encodes every pixel,
    /// recomposes nothing).
    pub fn set_display(&mut self, display: Display) {
        self.display = display;
        self.display.to_srgb8_into(&self.linear, &mut self.srgb);
    }

    /// Brings the frame up to date with `lights` (stable order: index i is
    /// the same light every call; a changed count recomposes everything).
    pub fn update(&mut self, lights: &[CompositeInput]) -> UpdateStats {
        let w = self.width as usize;
        let tiles_x = w.div_ceil(TILE);
        let tiles_y = (self.height as usize).div_ceil(TILE);
        let n_tiles = tiles_x * tiles_y;
        let mut dirty = vec![false; n_tiles];
        let mut changed = 0;
        let full = self.seen.len() != lights.len();
        if full {
            dirty.fill(true);
            self.seen = lights.iter().map(|_| (Vec3::NAN, u64::MAX, Vec::new())).collect();
        }
        for (l, (k, generation, covered)) in lights.iter().zip(self.seen.iter_mut()) {
            // NaN != NaN: the first update always counts as a change.
            if *k == l.k && *generation == l.generation {
                continue;
            }
            changed += 1;
            // The tiles the light's old buffer covered need recomposing too;
            // its tile list is rebuilt only when the buffer was replaced.
            for &t in covered.iter() {
                dirty[t as usize] = true;
            }
            if *generation != l.generation {
                *covered = (0..n_tiles as u32)
                    .filter(|&t| l.buffer.tile(t as usize % tiles_x, t as usize / tiles_x).is_some())
                    .collect();
                for &t in covered.iter() {
                    dirty[t as usize] = true;
                }
            }
            *k = l.k;
            *generation = l.generation;
        }
        let tiles = dirty.iter().filter(|&&d| d).count();
        if tiles == 0 {
            return UpdateStats { tiles, changed_lights: changed };
        }
        let buffers: Vec<&LightBuffer> = lights.iter().map(|l| l.buffer).collect();
        let k: Vec<Vec3> = lights.iter().map(|l| l.k).collect();
        if tiles * 2 > n_tiles {
            // Most of the frame changed (a grand-master fade): one full pass
            // is cheaper than tile-by-tile recomposing and encoding.
            composite_into(&buffers, &k, self.width, self.height, &mut self.linear);
            self.display.to_srgb8_into(&self.linear, &mut self.srgb);
            return UpdateStats { tiles, changed_lights: changed };
        }
        let active = active_lights(&buffers, &k);
        let display = self.display;
        self.linear.par_chunks_mut(w * TILE).zip(self.srgb.par_chunks_mut(w * TILE * 3)).enumerate().for_each(
            |(ty, (band, band_srgb))| {
                let rows = band.len() / w.max(1);
                for tx in (0..tiles_x).filter(|tx| dirty[ty * tiles_x + tx]) {
                    let x0 = tx * TILE;
                    let cols = TILE.min(w - x0);
                    for r in 0..rows {
                        band[r * w + x0..r * w + x0 + cols].fill(Vec3::ZERO);
                    }
                    accumulate_tile(&active, tx, ty, w, band);
                    for r in 0..rows {
                        let px = r * w + x0;
                        display.to_srgb8_into(&band[px..px + cols], &mut band_srgb[px * 3..(px + cols) * 3]);
                    }
                }
            },
        );
        UpdateStats { tiles, changed_lights: changed }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn buffers(w: u32, h: u32) -> (LightBuffer, LightBuffer) {
        let a: Vec<Vec3> = (0..w * h).map(|i| Vec3::new(i as f32, 0.5, 0.0)).collect();
        let mut b = vec![Vec3::ZERO; (w * h) as usize];
        b[100] = Vec3::ONE;
        (LightBuffer::from_dense(w, h, &a), LightBuffer::from_dense(w, h, &b))
    }

    #[test]
    fn weighted_sum_of_sparse_buffers() {
        let (w, h) = (35u32, 19u32);
        let (ba, bb) = buffers(w, h);
        let (a, b) = (ba.to_dense(), bb.to_dense());
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

    /// The tile-by-tile path encodes with the display's roll-off like a full
    /// encode, and a live `set_display` re-encodes without recomposing.
    #[test]
    fn incremental_updates_roll_off_like_a_full_encode() {
        let (w, h) = (50u32, 40u32);
        let (ba, bb) = buffers(w, h);
        let display = Display::for_white_lux(50.0).with_rolloff(Some(Default::default()));
        let mut c = Compositor::new(w, h, display);
        let inputs = |kb: f32| {
            [
                CompositeInput { buffer: &ba, generation: 0, k: Vec3::splat(0.05) },
                CompositeInput { buffer: &bb, generation: 0, k: Vec3::splat(kb) },
            ]
        };
        c.update(&inputs(2.0));
        // One tile, far over white.
        let s = c.update(&inputs(4000.0));
        assert_eq!(s.tiles, 1);
        let full = composite(&[&ba, &bb], &[Vec3::splat(0.05), Vec3::splat(4000.0)], w, h);
        assert_eq!(c.srgb8(), &display.to_srgb8(&full)[..]);
        // 250× white: the brightest channel (blue, after the tungsten white
        // balance) at white, the others keep their ratio to it (hue kept) ...
        assert!(c.srgb8()[300] < 200 && c.srgb8()[302] == 255, "{:?}", &c.srgb8()[300..303]);
        let clip = Display { rolloff: None, ..display };
        c.set_display(clip);
        assert_eq!(c.srgb8(), &clip.to_srgb8(&full)[..]);
        // ... where clipping shows white in all three.
        assert_eq!(&c.srgb8()[300..303], &[255, 255, 255]);
        assert_eq!(c.linear(), &full[..]);
    }

    #[test]
    fn incremental_updates_match_full_composites_and_touch_only_changed_tiles() {
        let (w, h) = (50u32, 40u32);
        let (ba, bb) = buffers(w, h);
        let display = Display::for_white_lux(50.0);
        let mut c = Compositor::new(w, h, display);
        let mut k = [Vec3::splat(0.01), Vec3::splat(2.0)];
        let first = c.update(&[
            CompositeInput { buffer: &ba, generation: 0, k: k[0] },
            CompositeInput { buffer: &bb, generation: 0, k: k[1] },
        ]);
        assert_eq!(first.tiles, 4 * 3);
        for step in 0..5 {
            // Move only light b's fader: one tile changes.
            k[1] = Vec3::splat(step as f32 * 0.7);
            let s = c.update(&[
                CompositeInput { buffer: &ba, generation: 0, k: k[0] },
                CompositeInput { buffer: &bb, generation: 0, k: k[1] },
            ]);
            assert_eq!((s.tiles, s.changed_lights), (1, 1));
            let full = composite(&[&ba, &bb], &k, w, h);
            assert_eq!(c.linear(), &full[..]);
            assert_eq!(c.srgb8(), &display.to_srgb8(&full)[..]);
        }
        let idle = c.update(&[
            CompositeInput { buffer: &ba, generation: 0, k: k[0] },
            CompositeInput { buffer: &bb, generation: 0, k: k[1] },
        ]);
        assert_eq!(idle, UpdateStats { tiles: 0, changed_lights: 0 });
        // A rebuilt buffer that moved clears its old tiles.
        let empty = LightBuffer::empty(w, h);
        c.update(&[
            CompositeInput { buffer: &ba, generation: 0, k: k[0] },
            CompositeInput { buffer: &empty, generation: 1, k: k[1] },
        ]);
        assert_eq!(c.linear(), &composite(&[&ba], &k[..1], w, h)[..]);
    }
}
