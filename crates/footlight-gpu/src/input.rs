//! What the caller hands over: a light's sparse tiles, the weights and the
//! display settings, in plain types that mirror footlight's
//! `src/render/buffer.rs` and `src/render/display.rs` so the main crate can
//! pass its buffers without copying (this crate does not depend on it).
//!
//! A `LightBuffer` keeps `data: Vec<Vec3>` (occupied tiles, 16×16 row-major
//! each, edge tiles padded with zeros) and `slot: Vec<u32>` (one entry per
//! screen tile, row-major, the tile's index into `data` or `u32::MAX`).
//! glam's `Vec3` is `#[repr(C)]` three `f32`s, so
//! `bytemuck::cast_slice::<Vec3, [f32; 3]>(&data)` is the [`LightTiles::tiles`]
//! this crate takes.

/// Tile edge in pixels (buffer.rs `TILE`).
pub const TILE: u32 = 16;

/// Pixels in one tile.
pub const TILE_PIXELS: usize = (TILE * TILE) as usize;

/// Slot table value of a tile the light does not reach (buffer.rs `EMPTY`).
pub const EMPTY_SLOT: u32 = u32::MAX;

/// Most lights one compositor holds (light indices are `0..MAX_LIGHTS`); a
/// guard against a stray index allocating a huge table, well above the
/// 600-fixture scale target.
pub const MAX_LIGHTS: usize = 1 << 16;

/// One light's unit-intensity buffer I_h,ε_i (cd/m² per cd), as sparse tiles.
#[derive(Clone, Copy, Debug)]
pub struct LightTiles<'a> {
    /// Occupied tiles, each [`TILE_PIXELS`] RGB values, row-major, concatenated
    /// (buffer.rs `data`). Values must be finite and non-negative.
    pub tiles: &'a [[f32; 3]],
    /// Per screen tile, row-major over `ceil(width/16) × ceil(height/16)`: the
    /// index (in tiles) into `tiles`, or [`EMPTY_SLOT`] (buffer.rs `slot`).
    /// Each tile is used by at most one entry.
    pub slots: &'a [u32],
}

/// Display settings applied after the composite (display.rs `Display`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DisplayParams {
    /// Linear multiplier from cd/m² to display units (1 = white).
    pub exposure: f32,
    /// Per-channel white-balance gains (1 = none).
    pub white_balance: [f32; 3],
    /// Highlight roll-off `[knee, white]` in display-linear units (display.rs
    /// `HighlightRolloff::uniforms`: 0 ≤ knee < 1 < white); `None` clips at white.
    pub rolloff: Option<[f32; 2]>,
}

impl DisplayParams {
    /// Exposure such that a white Lambert surface under `lux` is display
    /// white, no white balance (display.rs `Display::for_white_lux`).
    pub fn for_white_lux(lux: f32) -> Self {
        let lux = if lux.is_finite() && lux > 0.0 { lux } else { 1000.0 };
        Self { exposure: std::f32::consts::PI / lux, white_balance: [1.0; 3], rolloff: None }
    }

    /// white_balance × exposure: linear cd/m² to display-linear RGB.
    pub fn scale(&self) -> [f32; 3] {
        self.white_balance.map(|w| w * self.exposure)
    }

    /// The shader's `rolloff` uniform: knee, white, 1 (on) or all 0 (off).
    pub(crate) fn rolloff_uniform(&self) -> [f32; 4] {
        self.rolloff.map_or([0.0; 4], |[knee, white]| [knee, white, 1.0, 0.0])
    }

    pub(crate) fn is_valid(&self) -> bool {
        self.exposure.is_finite()
            && self.exposure >= 0.0
            && self.white_balance.iter().all(|w| w.is_finite() && *w >= 0.0)
            && self.rolloff.is_none_or(|[knee, white]| (0.0..1.0).contains(&knee) && white.is_finite() && white > 1.0)
    }
}

impl Default for DisplayParams {
    /// 1000 lx on a white Lambert surface is display white (DESIGN.md).
    fn default() -> Self {
        Self::for_white_lux(1000.0)
    }
}

/// How tile pixels are stored on the GPU.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TileFormat {
    /// RGB f32, exactly what the CPU holds (3 KiB per tile).
    #[default]
    F32,
    /// RGB IEEE half floats (1.5 KiB per tile): half the memory and memory
    /// traffic. Relative error ≤ 2⁻¹¹ per value, values above 65504
    /// saturate there; the tests measure it at ≤ 1 sRGB code value.
    F16,
}

impl TileFormat {
    /// Bytes one tile takes in the pool.
    pub const fn tile_bytes(self) -> u64 {
        match self {
            Self::F32 => (TILE_PIXELS * 3 * 4) as u64,
            Self::F16 => (TILE_PIXELS * 3 * 2) as u64,
        }
    }
}

/// Settings fixed when a compositor is made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CompositorOptions {
    /// Tile storage on the GPU.
    pub tile_format: TileFormat,
    /// Upper bound on one pool page (one storage buffer), in bytes. `None`:
    /// the device's `max_storage_buffer_binding_size` and `max_buffer_size`.
    /// Tests set it small to exercise several pages.
    pub max_page_bytes: Option<u64>,
    /// Readback buffers in flight at once (at least 1; 3 lets the GPU run one
    /// frame ahead while the caller still reads the previous one).
    pub readback_slots: usize,
}

impl Default for CompositorOptions {
    fn default() -> Self {
        Self { tile_format: TileFormat::F32, max_page_bytes: None, readback_slots: 3 }
    }
}
