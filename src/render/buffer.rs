//! Per-light intensity buffers I_h,ε_i (eq. 5) stored as sparse tiles.
//!
//! A stage light lights a part of the picture; the rest of its buffer is
//! zero. Buffers keep only the 16×16 tiles with any non-zero pixel, so
//! memory and composite time scale with what the beams reach (a 600-fixture
//! rig at 1920×1080 would need 15 GB as dense RGB f32 buffers).

use glam::Vec3;

/// Tile edge in pixels.
pub const TILE: usize = 16;
const TILE_PIXELS: usize = TILE * TILE;
const EMPTY: u32 = u32::MAX;

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
    /// Occupied tiles, TILE×TILE row-major each (edge tiles padded with 0).
    data: Vec<Vec3>,
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
        Self { width, height, tiles_x, slot: vec![EMPTY; tiles_x * tiles_y], data: Vec::new() }
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
                buf.slot[ty * buf.tiles_x + tx] = (buf.data.len() / TILE_PIXELS) as u32;
                let start = buf.data.len();
                buf.data.resize(start + TILE_PIXELS, Vec3::ZERO);
                for y in rows.clone() {
                    for x in cols.clone() {
                        buf.data[start + (y - ty * TILE) * TILE + (x - tx * TILE)] = dense[y * w + x];
                    }
                }
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
            buf.slot[t] = (buf.data.len() / TILE_PIXELS) as u32;
            buf.data.extend_from_slice(&pixels);
        }
        buf
    }

    /// Value at pixel (x, y).
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        let (x, y) = (x as usize, y as usize);
        match self.slot[(y / TILE) * self.tiles_x + x / TILE] {
            EMPTY => Vec3::ZERO,
            s => self.data[s as usize * TILE_PIXELS + (y % TILE) * TILE + x % TILE],
        }
    }

    /// The tile at tile coordinates (tx, ty), if occupied.
    pub fn tile(&self, tx: usize, ty: usize) -> Option<&[Vec3]> {
        match self.slot[ty * self.tiles_x + tx] {
            EMPTY => None,
            s => Some(&self.data[s as usize * TILE_PIXELS..(s as usize + 1) * TILE_PIXELS]),
        }
    }

    /// The raw storage: occupied tiles (TILE×TILE row-major each) and the
    /// per-tile slot table (`u32::MAX` = empty), for the GPU compositor.
    pub fn raw(&self) -> (&[Vec3], &[u32]) {
        (&self.data, &self.slot)
    }

    /// Number of occupied tiles.
    pub fn occupied_tiles(&self) -> usize {
        self.data.len() / TILE_PIXELS
    }

    /// Total number of tiles in the image.
    pub fn total_tiles(&self) -> usize {
        self.slot.len()
    }

    /// Bytes of pixel data held.
    pub fn bytes(&self) -> usize {
        self.data.len() * std::mem::size_of::<Vec3>() + self.slot.len() * 4
    }

    /// Expands to a dense row-major buffer.
    pub fn to_dense(&self) -> Vec<Vec3> {
        let mut out = Vec::with_capacity((self.width * self.height) as usize);
        for y in 0..self.height {
            for x in 0..self.width {
                out.push(self.get(x, y));
            }
        }
        out
    }

    /// Checks every stored value is finite and non-negative. Called on each
    /// finished buffer: a NaN is a bug to report, never to clamp away.
    pub fn check(&self) -> Result<(), BadValue> {
        for (i, v) in self.data.iter().enumerate() {
            if !v.is_finite() || v.min_element() < 0.0 {
                let tile = self.slot.iter().position(|&s| s as usize == i / TILE_PIXELS).unwrap_or(0);
                let x = (tile % self.tiles_x * TILE + (i % TILE_PIXELS) % TILE) as u32;
                let y = (tile / self.tiles_x * TILE + (i % TILE_PIXELS) / TILE) as u32;
                return Err(BadValue { x, y, value: *v });
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
        buf.data.reserve(filled.len() * TILE_PIXELS);
        for (slot, tile) in filled {
            buf.slot[slot] = (buf.data.len() / TILE_PIXELS) as u32;
            buf.data.extend(tile);
        }
        buf
    }

    /// Tile coordinates (x, y) of every occupied tile.
    pub fn occupied(&self) -> Vec<(usize, usize)> {
        (0..self.slot.len()).filter(|&t| self.slot[t] != EMPTY).map(|t| (t % self.tiles_x, t / self.tiles_x)).collect()
    }
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

    #[test]
    fn check_reports_nan_position() {
        let (w, h) = (40u32, 40u32);
        let mut dense = vec![Vec3::ZERO; (w * h) as usize];
        dense[(33 * w + 17) as usize] = Vec3::new(f32::NAN, 0.0, 0.0);
        let err = LightBuffer::from_dense(w, h, &dense).check().unwrap_err();
        assert_eq!((err.x, err.y), (17, 33));
    }
}
