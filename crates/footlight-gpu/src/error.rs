//! The crate's one error type.
//!
//! Two kinds of failure matter to the caller: "no GPU here" ([`GpuError::NoAdapter`],
//! [`GpuError::Device`], [`GpuError::Unsupported`]), after which it uses the CPU
//! compositor and logs why, and bad input (a slot table of the wrong size, a NaN in
//! a buffer, a NaN weight), which is a bug upstream and names the light and pixel.
//! wgpu's own errors (out of memory, a lost device) are caught with error scopes
//! and returned as [`GpuError::Wgpu`] instead of reaching wgpu's default handler,
//! which panics.

/// Everything that can go wrong in this crate.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GpuError {
    /// No adapter (GPU or software rasteriser such as lavapipe) for the
    /// requested backends. The caller falls back to the CPU compositor.
    #[error("no GPU adapter found ({source}); using the CPU compositor")]
    NoAdapter {
        /// What wgpu reported (which backends were tried).
        #[source]
        source: wgpu::RequestAdapterError,
    },
    /// An adapter exists but refused to create a device.
    #[error("the GPU adapter could not create a device: {source}")]
    Device {
        /// What wgpu reported.
        #[source]
        source: wgpu::RequestDeviceError,
    },
    /// The device's limits cannot hold what the compositor needs.
    #[error("the GPU cannot run the compositor: {what}")]
    Unsupported {
        /// Which limit, with the value needed and the value the device has.
        what: String,
    },
    /// An error wgpu reported while running our commands (out of memory,
    /// a lost device, or a validation error, which is a bug in this crate).
    #[error("wgpu error during {during}: {message}")]
    Wgpu {
        /// What the compositor was doing.
        during: &'static str,
        /// wgpu's description.
        message: String,
    },
    /// A light's slot table does not have one entry per screen tile.
    #[error("light {light}: slot table has {got} entries, the {width}x{height} image has {expected} tiles")]
    SlotTableLength {
        /// Light index.
        light: usize,
        /// Entries given.
        got: usize,
        /// tiles_x × tiles_y.
        expected: usize,
        /// Image width.
        width: u32,
        /// Image height.
        height: u32,
    },
    /// A light's tile data is not a whole number of 16×16 tiles.
    #[error("light {light}: {len} pixels of tile data is not a multiple of 256")]
    TileDataLength {
        /// Light index.
        light: usize,
        /// Pixels given.
        len: usize,
    },
    /// A slot table entry points past the tile data, or at a tile another
    /// entry already uses.
    #[error("light {light}: screen tile {tile} has slot {slot}, but there are {tiles} tiles (or it is used twice)")]
    BadSlot {
        /// Light index.
        light: usize,
        /// Screen tile index (row-major).
        tile: usize,
        /// The slot.
        slot: u32,
        /// Tiles of data given.
        tiles: usize,
    },
    /// A buffer value is NaN, infinite or negative: a bug upstream, reported,
    /// never clamped away.
    #[error("light {light}: buffer value {value:?} at pixel ({x}, {y}) is not a finite non-negative number")]
    BadValue {
        /// Light index.
        light: usize,
        /// Pixel column (may be past the image in an edge tile's padding).
        x: u32,
        /// Pixel row.
        y: u32,
        /// The value.
        value: [f32; 3],
    },
    /// A light index past [`crate::MAX_LIGHTS`].
    #[error("light index {index} is past the limit of {max} lights")]
    LightIndex {
        /// The index given.
        index: usize,
        /// The limit.
        max: usize,
    },
    /// Fewer weights than lights with buffers.
    #[error("{got} weights for {lights} lights")]
    WeightCount {
        /// Lights with a slot in the compositor.
        lights: usize,
        /// Weights given.
        got: usize,
    },
    /// A weight k_i is NaN, infinite or negative.
    #[error("light {light}: weight {value:?} is not a finite non-negative colour")]
    BadWeight {
        /// Light index.
        light: usize,
        /// The weight.
        value: [f32; 3],
    },
    /// Exposure or white balance is NaN, infinite or negative, or the
    /// roll-off is not 0 ≤ knee < 1 < white (finite).
    #[error(
        "display settings {0:?}: exposure and white balance must be finite and non-negative, a roll-off 0 <= knee < 1 < white"
    )]
    BadDisplay(crate::DisplayParams),
    /// The image size is zero or too large for one dispatch.
    #[error("image size {width}x{height} is not supported: {why}")]
    BadSize {
        /// Width asked for.
        width: u32,
        /// Height asked for.
        height: u32,
        /// Which limit it breaks.
        why: String,
    },
    /// Mapping a readback buffer failed (the device was lost).
    #[error("reading the frame back failed: {0}")]
    Map(#[from] wgpu::BufferAsyncError),
    /// Waiting for the GPU failed.
    #[error("waiting for the GPU failed: {0}")]
    Poll(#[from] wgpu::PollError),
}

impl GpuError {
    /// Whether the error means "no usable GPU here" (fall back to the CPU
    /// compositor) rather than bad input.
    pub fn is_unavailable(&self) -> bool {
        matches!(self, Self::NoAdapter { .. } | Self::Device { .. } | Self::Unsupported { .. })
    }
}
