//! GPU compositor for Footlight: the real-time update of Vierjahn et al.
//! 2010, section 3.3, as a wgpu compute shader.
//!
//! Each light's unit-intensity buffer lives on the GPU as sparse 16×16 tiles
//! and is uploaded only when the light is rebuilt; each display frame
//! computes I = Σ_i k_i ⊙ buffer_i (eq. 5), white balance, exposure, the highlight roll-off, clipping
//! and the sRGB transfer function on the GPU and reads back RGBA8 for the
//! preview. It matches the CPU reference (`footlight::render::composite` +
//! `display`) to within one 8-bit code value.
//!
//! The crate knows nothing about the renderer (STYLE.md §15): inputs are
//! plain slices laid out like footlight's `LightBuffer` ([`LightTiles`]), so
//! the main crate hands its buffers over without copying and keeps the CPU
//! compositor as the fallback when [`GpuContext::new`] finds no adapter.
//!
//! ```no_run
//! use footlight_gpu::{CompositorOptions, DisplayParams, GpuCompositor, GpuContext, LightTiles};
//! # fn main() -> Result<(), footlight_gpu::GpuError> {
//! let ctx = GpuContext::new()?; // Err(NoAdapter): use the CPU compositor
//! let mut gpu = GpuCompositor::new(ctx.device(), ctx.queue(), 800, 500, CompositorOptions::default())?;
//! # let (tiles, slots): (Vec<[f32; 3]>, Vec<u32>) = (vec![], vec![u32::MAX; 50 * 32]);
//! gpu.set_light(0, LightTiles { tiles: &tiles, slots: &slots })?; // when light 0 is rebuilt
//! let frame = gpu.composite(&[[120.0, 110.0, 90.0]], &DisplayParams::default())?; // per frame
//! assert_eq!(frame.rgba8.len(), 800 * 500 * 4);
//! # Ok(()) }
//! ```
//!
//! # Layout (in data-flow order)
//! - [`input`]: the input types ([`LightTiles`], [`DisplayParams`], [`CompositorOptions`]).
//! - [`context`]: the device, [`GpuContext`], created once (or injected).
//! - `pool`: free-slot book-keeping of the GPU tile pool (pages within the binding limit).
//! - [`composite`]: the compositor, [`GpuCompositor`] (uploads, the per-screen-tile index, the
//!   passes); its shader is the workspace's top-level `shaders/composite.wgsl`.
//! - [`readback`]: the staging ring that brings [`Frame`]s back without stalling.
//! - [`error`]: the crate's error, [`GpuError`].
#![deny(missing_docs)]

pub mod composite;
pub mod context;
pub mod error;
pub mod input;
mod pool;
pub mod readback;

pub use composite::{FrameStats, GpuCompositor, PoolStats};
pub use context::GpuContext;
pub use error::GpuError;
pub use input::{CompositorOptions, DisplayParams, EMPTY_SLOT, LightTiles, MAX_LIGHTS, TILE, TILE_PIXELS, TileFormat};
pub use readback::{Frame, FrameId};
/// The wgpu this crate is built against, for callers that inject a device.
pub use wgpu;
