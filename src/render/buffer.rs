//! Per-light intensity buffers I_h,ε_i (eq. 5) stored as sparse tiles.
//!
//! A stage light lights a part of the picture; the rest of its buffer is
//! zero. Buffers keep only the 16×16 tiles with any non-zero pixel, so
//! memory and composite time scale with what the beams reach (a 600-fixture
//! rig at 1920×1080 would need 15 GB as dense RGB f32 buffers).
//!
//! A buffer the live daemon holds may be compact ([`LightBuffer::compact`],
//! `BuildSettings::compact`): half precision with one power-of-two scale
//! per buffer, value = f16 · scale, the scale putting the largest value at
//! most at 2^14 (f16 overflows at 65504). f16 keeps 11 significant bits, a
//! relative rounding error of at most 2^-11 ≈ 4.9e-4 per value (rel. MSE
//! ≤ 8e-8 of a buffer: 1/10,000 of the grouped-build bound and below an
//! 8-bit display step) for every value down to 2^-28 of the buffer's
//! largest; fainter ones keep an absolute step of 2^-38 of the largest.
//! The browser stream sends buffers as f16 with the same scale rule
//! ([`crate::serve::stream::buffer_scale`]): a compact buffer goes out
//! with its own values. Issue 38: the
//! festival show's 3,684 Whitted terms and ~228 indirect layers held
//! 2.30 GB as f32. `footlight render` and the reference paths keep f32.

use std::borrow::Cow;

use glam::Vec3;
use half::f16;
use half::slice::HalfFloatSliceExt;

/// Tile edge in pixels.
pub const TILE: usize = 16;
const TILE_PIXELS: usize = TILE * TILE;
/// Values per tile (RGB).
const TILE_VALUES: usize = 3 * TILE_PIXELS;
const EMPTY: u32 = u32::MAX;

/// The power-of-two scale a compact buffer is stored with, so its largest
/// value is at most 2^14 in f16: value = f16 · scale. 1 when there is no
/// finite positive value.
pub fn f16_scale(values: impl IntoIterator<Item = Vec3>) -> f32 {
    let max = values.into_iter().map(|v| v.max_element()).fold(0.0f32, f32::max);
    if !(max.is_finite() && max > 0.0) {
        return 1.0;
    }
    2f32.powi((max.log2().ceil() as i32 - 14).clamp(-100, 100))
}

/// The occupied tiles' values, TILE×TILE row-major each (edge tiles padded with 0).
#[derive(Clone, Debug, PartialEq)]
enum Values {
    /// As computed.
    F32(Vec<Vec3>),
    /// Compact ([`LightBuffer::compact`]): RGB as value / `scale` in f16.
    F16 { bits: Vec<f16>, scale: f32 },
}

/// One light's unit-intensity RGB buffer, in cd/m² per cd of the source.
#[derive(Clone, Debug, PartialEq)]
pub struct LightBuffer {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    tiles_x: usize,
    /// Per tile: index into `data` (in tiles), or EMPTY.
    slot: Vec<u32>,
    /// Occupied tiles' values.
    data: Values,
}

/// An indirect term one photon leader shares with the cells that follow it
/// (issue 38, emitter groups): the leader's buffer less its Whitted term
/// ([`crate::render::build::shared_indirect`]). Each cell of the group
/// shows its own Whitted term W_i plus this A_g, and eq. 5 regroups as
/// Σ_i k_i (W_i + A_g) = Σ_i k_i W_i + (Σ_i k_i) A_g: the group's indirect
/// light is stored once and composited once with the summed weight,
/// instead of a dense buffer per cell.
#[derive(Clone, Debug)]
pub struct SharedLayer {
    /// Unique per layer and never reused (a new layer for each leader
    /// publish): the compositor's and the stream's generation for it.
    pub id: u64,
    /// A_g, in the units of a light's buffer (cd/m² per cd).
    pub buffer: std::sync::Arc<LightBuffer>,
}

impl SharedLayer {
    /// A new layer with a fresh id.
    pub fn new(buffer: LightBuffer) -> Self {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        Self { id: NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed), buffer: std::sync::Arc::new(buffer) }
    }

    /// `own` plus this layer, dense row-major (what the cell shows).
    pub fn plus(&self, own: &LightBuffer) -> Vec<Vec3> {
        own.to_dense().iter().zip(self.buffer.to_dense()).map(|(a, b)| *a + b).collect()
    }
}

/// A NaN/Inf or negative value found in a buffer, with where it is.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("buffer value {value} at pixel ({x}, {y}) is not a finite non-negative number")]
pub struct BadValue {
    /// Pixel column.
    pub x: u32,
    /// Pixel row.
    pub y: u32,
    /// The offending value.
    pub value: Vec3,
}

impl LightBuffer {
    /// An all-zero buffer (a light that reaches nothing in view).
    pub fn empty(width: u32, height: u32) -> Self {
        let tiles_x = (width as usize).div_ceil(TILE);
        let tiles_y = (height as usize).div_ceil(TILE);
        Self { width, height, tiles_x, slot: vec![EMPTY; tiles_x * tiles_y], data: Values::F32(Vec::new()) }
    }

    /// Packs a dense row-major buffer, keeping tiles with any non-zero pixel.
    pub fn from_dense(width: u32, height: u32, dense: &[Vec3]) -> Self {
        let mut buf = Self::empty(width, height);
        let (w, h) = (width as usize, height as usize);
        assert_eq!(dense.len(), w * h, "dense buffer size");
        let tiles_y = h.div_ceil(TILE);
        for ty in 0..tiles_y {
            for tx in 0..buf.tiles_x {
                let rows = (ty * TILE)..((ty + 1) * TILE).min(h);
                let cols = (tx * TILE)..((tx + 1) * TILE).min(w);
                let any =
                    rows.clone().any(|y| dense[y * w + cols.start..y * w + cols.end].iter().any(|p| *p != Vec3::ZERO));
                if !any {
                    continue;
                }
                let data = f32_of(&mut buf.data);
                let start = data.len();
                data.resize(start + TILE_PIXELS, Vec3::ZERO);
                for y in rows.clone() {
                    for x in cols.clone() {
                        data[start + (y - ty * TILE) * TILE + (x - tx * TILE)] = dense[y * w + x];
                    }
                }
                buf.slot[ty * buf.tiles_x + tx] = (start / TILE_PIXELS) as u32;
            }
        }
        buf
    }

    /// Packs tiles given by tile index (row-major over the tile grid), each
    /// TILE×TILE row-major; all-zero tiles and indices outside the grid are
    /// dropped. What a footprint-culled stage produces (no dense buffer).
    pub fn from_tile_list(width: u32, height: u32, tiles: Vec<(usize, Vec<Vec3>)>) -> Self {
        let mut buf = Self::empty(width, height);
        for (t, pixels) in tiles {
            if t >= buf.slot.len() || pixels.len() != TILE_PIXELS || pixels.iter().all(|p| *p == Vec3::ZERO) {
                continue;
            }
            let data = f32_of(&mut buf.data);
            buf.slot[t] = (data.len() / TILE_PIXELS) as u32;
            data.extend_from_slice(&pixels);
        }
        buf
    }

    /// This buffer in half precision with one power-of-two scale (module
    /// doc: 2^-11 relative per value), for a buffer held long (the live
    /// tracer's); a compact buffer is returned as it is.
    pub fn compact(self) -> Self {
        let Values::F32(values) = &self.data else { return self };
        let scale = f16_scale(values.iter().copied());
        let flat: Vec<f32> = values.iter().flat_map(|v| (*v / scale).to_array()).collect();
        let mut bits = vec![f16::ZERO; flat.len()];
        bits.convert_from_f32_slice(&flat);
        Self { data: Values::F16 { bits, scale }, ..self }
    }

    /// True for a [`LightBuffer::compact`] buffer.
    pub fn is_compact(&self) -> bool {
        matches!(self.data, Values::F16 { .. })
    }

    /// Value at pixel (x, y).
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        let (x, y) = (x as usize, y as usize);
        match self.slot[(y / TILE) * self.tiles_x + x / TILE] {
            EMPTY => Vec3::ZERO,
            s => {
                let i = s as usize * TILE_PIXELS + (y % TILE) * TILE + x % TILE;
                match &self.data {
                    Values::F32(v) => v[i],
                    Values::F16 { bits, scale } => {
                        Vec3::new(bits[3 * i].to_f32(), bits[3 * i + 1].to_f32(), bits[3 * i + 2].to_f32()) * *scale
                    }
                }
            }
        }
    }

    /// True when the tile at tile coordinates (tx, ty) is occupied (no decoding).
    pub fn has_tile(&self, tx: usize, ty: usize) -> bool {
        self.slot[ty * self.tiles_x + tx] != EMPTY
    }

    /// The tile at tile coordinates (tx, ty), if occupied: borrowed from an
    /// f32 buffer, decoded from a compact one.
    pub fn tile(&self, tx: usize, ty: usize) -> Option<Cow<'_, [Vec3]>> {
        match self.slot[ty * self.tiles_x + tx] {
            EMPTY => None,
            s => Some(match &self.data {
                Values::F32(v) => Cow::Borrowed(&v[s as usize * TILE_PIXELS..(s as usize + 1) * TILE_PIXELS]),
                Values::F16 { bits, scale } => {
                    Cow::Owned(decode(&bits[s as usize * TILE_VALUES..(s as usize + 1) * TILE_VALUES], *scale))
                }
            }),
        }
    }

    /// Adds k ⊙ tile (tx, ty) into `band` (the image rows of tile row ty,
    /// `w` pixels wide): the composite's inner loop (eq. 5), a compact
    /// buffer decoded a tile row at a time. False when the tile is empty.
    pub fn add_tile_scaled(&self, tx: usize, ty: usize, k: Vec3, w: usize, band: &mut [Vec3]) -> bool {
        let s = match self.slot[ty * self.tiles_x + tx] {
            EMPTY => return false,
            s => s as usize,
        };
        let rows = (band.len() / w.max(1)).min(TILE);
        let x0 = tx * TILE;
        let cols = TILE.min(w - x0);
        // k repeated over a tile row, so the inner loop is a plain
        // element-wise multiply-add over f32 that the compiler vectorises.
        match &self.data {
            Values::F32(v) => {
                let kk: [f32; 3 * TILE] = std::array::from_fn(|i| k[i % 3]);
                let tile = &v[s * TILE_PIXELS..(s + 1) * TILE_PIXELS];
                for r in 0..rows {
                    let src: &[f32] = bytemuck::cast_slice(&tile[r * TILE..r * TILE + cols]);
                    let dst: &mut [f32] = bytemuck::cast_slice_mut(&mut band[r * w + x0..r * w + x0 + cols]);
                    for ((d, s), k) in dst.iter_mut().zip(src).zip(&kk) {
                        *d += k * s; // Vierjahn 2010, eq. (5)
                    }
                }
            }
            Values::F16 { bits, scale } => {
                let ks = k * *scale;
                let kk: [f32; 3 * TILE] = std::array::from_fn(|i| ks[i % 3]);
                let tile = &bits[s * TILE_VALUES..(s + 1) * TILE_VALUES];
                for r in 0..rows {
                    let src = &tile[r * 3 * TILE..r * 3 * TILE + 3 * cols];
                    let dst: &mut [f32] = bytemuck::cast_slice_mut(&mut band[r * w + x0..r * w + x0 + cols]);
                    for ((d, h), k) in dst.iter_mut().zip(src).zip(&kk) {
                        *d += k * f16_value(h.to_bits()); // Vierjahn 2010, eq. (5)
                    }
                }
            }
        }
        true
    }

    /// The occupied tiles (TILE×TILE row-major each, decoded from a compact
    /// buffer) and the per-tile slot table (`u32::MAX` = empty), for the
    /// GPU compositor.
    pub fn raw(&self) -> (Cow<'_, [Vec3]>, &[u32]) {
        let values = match &self.data {
            Values::F32(v) => Cow::Borrowed(&v[..]),
            Values::F16 { bits, scale } => Cow::Owned(decode(bits, *scale)),
        };
        (values, &self.slot)
    }

    /// Every stored value (the occupied tiles' pixels, padding included).
    pub fn values(&self) -> Box<dyn Iterator<Item = Vec3> + '_> {
        match &self.data {
            Values::F32(v) => Box::new(v.iter().copied()),
            Values::F16 { bits, scale } => {
                Box::new(bits.chunks_exact(3).map(|c| Vec3::new(c[0].to_f32(), c[1].to_f32(), c[2].to_f32()) * *scale))
            }
        }
    }

    /// Number of occupied tiles.
    pub fn occupied_tiles(&self) -> usize {
        match &self.data {
            Values::F32(v) => v.len() / TILE_PIXELS,
            Values::F16 { bits, .. } => bits.len() / TILE_VALUES,
        }
    }

    /// Total number of tiles in the image.
    pub fn total_tiles(&self) -> usize {
        self.slot.len()
    }

    /// Bytes of pixel data held.
    pub fn bytes(&self) -> usize {
        let values = match &self.data {
            Values::F32(v) => v.len() * std::mem::size_of::<Vec3>(),
            Values::F16 { bits, .. } => bits.len() * std::mem::size_of::<f16>(),
        };
        values + self.slot.len() * 4
    }

    /// Expands to a dense row-major buffer.
    pub fn to_dense(&self) -> Vec<Vec3> {
        let (w, h) = (self.width as usize, self.height as usize);
        let mut out = vec![Vec3::ZERO; w * h];
        for t in 0..self.slot.len() {
            let (tx, ty) = (t % self.tiles_x, t / self.tiles_x);
            let Some(tile) = self.tile(tx, ty) else { continue };
            let cols = TILE.min(w - tx * TILE);
            for r in 0..TILE.min(h - ty * TILE) {
                out[(ty * TILE + r) * w + tx * TILE..][..cols].copy_from_slice(&tile[r * TILE..r * TILE + cols]);
            }
        }
        out
    }

    /// Checks every stored value is finite and non-negative. Called on each
    /// finished buffer: a NaN is a bug to report, never to clamp away.
    pub fn check(&self) -> Result<(), BadValue> {
        for (i, v) in self.values().enumerate() {
            if !v.is_finite() || v.min_element() < 0.0 {
                let tile = self.slot.iter().position(|&s| s as usize == i / TILE_PIXELS).unwrap_or(0);
                let x = (tile % self.tiles_x * TILE + (i % TILE_PIXELS) % TILE) as u32;
                let y = (tile / self.tiles_x * TILE + (i % TILE_PIXELS) / TILE) as u32;
                return Err(BadValue { x, y, value: v });
            }
        }
        Ok(())
    }
}

impl LightBuffer {
    /// Builds a buffer from the tiles listed in `candidates` (tile x, tile
    /// y), each filled by `fill(tx, ty, tile)` (TILE×TILE row-major, zeroed
    /// beforehand; pixels past the image edge must stay 0). Tiles that stay
    /// all zero are dropped. Parallel over tiles. Used by the haze density
    /// re-weighting, which touches only the tiles a light covers.
    pub fn from_tiles(
        width: u32,
        height: u32,
        candidates: &[(usize, usize)],
        fill: impl Fn(usize, usize, &mut [Vec3]) + Sync,
    ) -> Self {
        use rayon::prelude::*;
        let mut buf = Self::empty(width, height);
        let filled: Vec<(usize, Vec<Vec3>)> = candidates
            .par_iter()
            .filter_map(|&(tx, ty)| {
                let mut tile = vec![Vec3::ZERO; TILE_PIXELS];
                fill(tx, ty, &mut tile);
                tile.iter().any(|p| *p != Vec3::ZERO).then_some((ty * buf.tiles_x + tx, tile))
            })
            .collect();
        let data = f32_of(&mut buf.data);
        data.reserve(filled.len() * TILE_PIXELS);
        for (slot, tile) in filled {
            buf.slot[slot] = (data.len() / TILE_PIXELS) as u32;
            data.extend(tile);
        }
        buf
    }

    /// Tile coordinates (x, y) of every occupied tile.
    pub fn occupied(&self) -> Vec<(usize, usize)> {
        (0..self.slot.len()).filter(|&t| self.slot[t] != EMPTY).map(|t| (t % self.tiles_x, t / self.tiles_x)).collect()
    }
}

/// The value of an f16 given by its bits, exactly as `half` decodes it
/// (test: every one of the 65,536 patterns), in integer and float steps the
/// compiler vectorises in the composite's inner loop (`half`'s slice
/// conversion goes through a call per 8 values). A normal f16 is its bits
/// moved into f32 place with the exponent rebiased (+112); a subnormal one
/// (and zero) is its 10-bit mantissa times 2^-24; Inf and NaN stay Inf and
/// NaN (a NaN is never hidden). No path makes an f32 subnormal, which x86
/// computes with microcode assists: a first version, the bits times 2^112,
/// made the festival show's pixel chase composite 3× slower.
#[inline(always)]
fn f16_value(bits: u16) -> f32 {
    let h = u32::from(bits);
    let (sign, mag) = ((h & 0x8000) << 16, h & 0x7fff);
    let value = if mag >= 0x7c00 {
        f32::from_bits((mag << 13) | 0x7f80_0000)
    } else if mag >= 0x0400 {
        f32::from_bits((mag << 13) + (112 << 23))
    } else {
        mag as f32 * (1.0 / 16_777_216.0)
    };
    f32::from_bits(value.to_bits() | sign)
}

/// The f32 values of a buffer being built (constructors make f32 buffers).
fn f32_of(data: &mut Values) -> &mut Vec<Vec3> {
    match data {
        Values::F32(v) => v,
        Values::F16 { .. } => unreachable!("constructors build f32 buffers"),
    }
}

/// f16 values (RGB, value / `scale`) decoded to pixels.
fn decode(bits: &[f16], scale: f32) -> Vec<Vec3> {
    let mut flat = vec![0.0f32; bits.len()];
    bits.convert_to_f32_slice(&mut flat);
    flat.chunks_exact(3).map(|c| Vec3::from_slice(c) * scale).collect()
}

/// One light's haze buffer (issue 15): per pixel the in-scattered light of
/// a unit source along the pixel's centre ray, kept so that a density change
/// is a re-weighting (`render::media::resolve`), stored tile-sparse like
/// [`LightBuffer`]. Channels of the beam: x = a0 = ∫ p f_ε g / r² dt (per
/// unit σ_s, no extinction), y = κ, the effective optical depth at the
/// medium's full density (single-scattered radiance at density d =
/// d σ_s a0 e^(−d κ)), z = 0. Pixels whose ray misses the beam hold
/// (0, 0, 0) and cost no storage. With multiple scattering
/// (`render::media::multiple`) it also holds the photons' radiance (orders
/// ≥ 2, surface light into the haze, haze light onto surfaces; per 1 cd,
/// RGB) rendered at one or more densities, each a tile-sparse buffer.
#[derive(Clone, Debug, PartialEq)]
pub struct HazeBuffer {
    beam: LightBuffer,
    multiple: Vec<(f32, LightBuffer)>,
}

impl HazeBuffer {
    /// An all-zero haze buffer (the beam is nowhere in view, or no haze).
    pub fn empty(width: u32, height: u32) -> Self {
        Self::from_light_buffer(LightBuffer::empty(width, height))
    }

    /// Packs dense (a0, κ, 0) pixels, keeping tiles with any non-zero pixel.
    pub fn from_dense(width: u32, height: u32, dense: &[Vec3]) -> Self {
        Self::from_light_buffer(LightBuffer::from_dense(width, height, dense))
    }

    /// Wraps tiles of (a0, κ, 0) pixels (a tile-sparse haze stage).
    pub fn from_light_buffer(buffer: LightBuffer) -> Self {
        Self { beam: buffer, multiple: Vec::new() }
    }

    /// This buffer with the multiply scattered radiance at haze density
    /// `density` (0-1 of the medium's) added: `term` holds it (RGB). A term
    /// already held for that density is replaced; terms stay sorted by density.
    pub fn with_multiple(mut self, density: f32, term: LightBuffer) -> Self {
        self.multiple.retain(|(d, _)| *d != density);
        self.multiple.push((density, term));
        self.multiple.sort_by(|a, b| a.0.total_cmp(&b.0));
        self
    }

    /// The multiply scattered radiance terms, (density, term), sorted by
    /// density; empty for single scattering.
    pub fn multiple(&self) -> &[(f32, LightBuffer)] {
        &self.multiple
    }

    /// (a0, κ) at pixel (x, y).
    pub fn get(&self, x: u32, y: u32) -> (f32, f32) {
        let v = self.beam.get(x, y);
        (v.x, v.y)
    }

    /// The beam's tiles as a [`LightBuffer`] (channels as documented on the type).
    pub fn as_light_buffer(&self) -> &LightBuffer {
        &self.beam
    }

    /// Tile coordinates of every tile the beam or a multiple-scattering term occupies.
    pub fn occupied(&self) -> Vec<(usize, usize)> {
        let mut tiles = self.beam.occupied();
        for (_, m) in &self.multiple {
            tiles.extend(m.occupied());
        }
        tiles.sort_unstable();
        tiles.dedup();
        tiles
    }

    /// Checks the beam and every multiple-scattering term for NaN/Inf.
    pub fn check(&self) -> Result<(), BadValue> {
        self.beam.check()?;
        self.multiple.iter().try_for_each(|(_, m)| m.check())
    }

    /// Image width.
    pub fn width(&self) -> u32 {
        self.beam.width
    }

    /// Image height.
    pub fn height(&self) -> u32 {
        self.beam.height
    }

    /// Number of occupied tiles of the beam.
    pub fn occupied_tiles(&self) -> usize {
        self.beam.occupied_tiles()
    }

    /// Bytes of pixel data held (beam and multiple-scattering terms).
    pub fn bytes(&self) -> usize {
        self.beam.bytes() + self.multiple.iter().map(|(_, m)| m.bytes()).sum::<usize>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_drops_zero_tiles() {
        let (w, h) = (37u32, 21u32);
        let mut dense = vec![Vec3::ZERO; (w * h) as usize];
        dense[(20 * w + 36) as usize] = Vec3::new(1.0, 2.0, 3.0);
        dense[3] = Vec3::splat(0.5);
        let b = LightBuffer::from_dense(w, h, &dense);
        assert_eq!(b.occupied_tiles(), 2);
        assert_eq!(b.total_tiles(), 3 * 2);
        assert_eq!(b.to_dense(), dense);
        assert_eq!(b.get(36, 20), Vec3::new(1.0, 2.0, 3.0));
        assert!(b.check().is_ok());
    }

    #[test]
    fn from_tiles_keeps_only_non_zero_candidates() {
        let (w, h) = (40u32, 20u32);
        let b = LightBuffer::from_tiles(w, h, &[(0, 0), (2, 1), (1, 0)], |tx, ty, tile| {
            if (tx, ty) == (2, 1) {
                tile[3 * TILE + 5] = Vec3::ONE; // pixel (37, 19)
            }
        });
        assert_eq!(b.occupied_tiles(), 1);
        assert_eq!(b.occupied(), vec![(2, 1)]);
        assert_eq!(b.get(37, 19), Vec3::ONE);
        assert_eq!(b.get(5, 5), Vec3::ZERO);
    }

    /// Compact buffers (f16, one power-of-two scale): every value within
    /// 2^-11 relative of the f32 one over a range of 2^26, the same tiles,
    /// `tile`, `get`, `values`, `raw` and `to_dense` agreeing, the
    /// composite's multiply-add (its own f16 decoding) exactly k times the
    /// decoded values, values past f16's range kept by the scale, and a NaN
    /// still a NaN.
    #[test]
    fn compact_buffers_round_to_f16_and_composite_alike() {
        let (w, h) = (37u32, 21u32);
        let mut dense = vec![Vec3::ZERO; (w * h) as usize];
        for (i, v) in dense.iter_mut().enumerate().filter(|(i, _)| i % 3 != 0 && i % 40 < 30) {
            // 3e5 down to 3e5 · 2^-26 (f16's normal range under the scale).
            let e = -(((i * 7919) % 27) as f32);
            *v = Vec3::new(3e5 * 2f32.powf(e), 1.7e5 * 2f32.powf(e - 0.3), 0.0);
        }
        let f32s = LightBuffer::from_dense(w, h, &dense);
        let c = f32s.clone().compact();
        assert!(c.is_compact() && !f32s.is_compact());
        assert_eq!(c.occupied(), f32s.occupied());
        assert!(c.bytes() < f32s.bytes() * 3 / 5);
        let got = c.to_dense();
        for (g, want) in got.iter().zip(&dense) {
            for (g, want) in g.to_array().into_iter().zip(want.to_array()) {
                assert!((g - want).abs() <= want * 2f32.powi(-11), "{g} vs {want}");
            }
        }
        assert_eq!(c.values().count(), f32s.values().count());
        assert_eq!(c.raw().0.to_vec(), c.values().collect::<Vec<_>>());
        for (x, y) in [(0, 0), (36, 20), (17, 5)] {
            assert_eq!(c.get(x, y), got[(y * w + x) as usize]);
        }
        let tx = 1;
        let tile = c.tile(tx, 0).unwrap();
        assert_eq!(tile[3 * TILE + 2], got[3 * w as usize + TILE + 2]);
        // The composite's inner loop over one tile row band, k ⊙ tile.
        let k = Vec3::new(0.5, 2.0, 3.0);
        let mut band = vec![Vec3::ZERO; w as usize * TILE];
        assert!(c.add_tile_scaled(tx, 0, k, w as usize, &mut band));
        for r in 0..TILE {
            for col in 0..TILE.min(w as usize - TILE) {
                let want = k * got[r * w as usize + TILE + col];
                let have = band[r * w as usize + TILE + col];
                assert_eq!(have, want, "the decoded value times k");
            }
        }
        assert!(c.clone().compact() == c, "compacting twice changes nothing");
        let mut bad = dense.clone();
        bad[5] = Vec3::new(f32::NAN, 1.0, 1.0);
        assert!(LightBuffer::from_dense(w, h, &bad).compact().check().is_err(), "a NaN is never rounded away");
    }

    /// The composite's own f16 decoding against `half`'s, bit for bit (NaN
    /// for NaN) over every f16.
    #[test]
    fn f16_values_decode_like_half_for_every_pattern() {
        for bits in 0..=u16::MAX {
            let (got, want) = (f16_value(bits), f16::from_bits(bits).to_f32());
            assert!(got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()), "{bits:#06x}: {got} vs {want}");
        }
    }

    #[test]
    fn check_reports_nan_position() {
        let (w, h) = (40u32, 40u32);
        let mut dense = vec![Vec3::ZERO; (w * h) as usize];
        dense[(33 * w + 17) as usize] = Vec3::new(f32::NAN, 0.0, 0.0);
        let err = LightBuffer::from_dense(w, h, &dense).check().unwrap_err();
        assert_eq!((err.x, err.y), (17, 33));
    }
}
