//! What the frame clock publishes every display frame ([`Frame`]) and the
//! fixture body layer as the browser stream sends it ([`BodyTiles`]).
//!
//! The frame clock (`live::clock`) makes them; the HTTP preview, the
//! browser stream, the window and the tests read them from the daemon's
//! `watch` channel.

use crate::render::bodies::BodyPixel;
use crate::render::buffer::{LightBuffer, TILE};
use crate::render::composite::UpdateStats;
use crate::render::display::Display;
use glam::Vec3;
use std::sync::Arc;
use std::time::Duration;

/// A published frame.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Frame number (0 = the first).
    pub number: u64,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// 8-bit sRGB, row-major RGB.
    pub rgb: Arc<Vec<u8>>,
    /// Luminance of each light's k_i (cd) in this frame, 0 when dark.
    pub intensity: Arc<Vec<f32>>,
    /// Composite time of this frame; for a moving preview, the time its picture took (also when reused).
    pub composite_time: Duration,
    /// What the incremental composite did.
    pub update: UpdateStats,
    /// Each buffer's weight in this frame, in light order: k_i (eq. 4) per
    /// light, then in clear air one weight per shared-layer place (a
    /// fixture's cells sharing one indirect layer: the summed k of the
    /// cells showing it, 0 where a place holds none;
    /// `live::clock::FrameEntries`); in haze, w_j(d) k_i for the knots
    /// j = 0, ½, 1 (all lights' knot-0 buffers, then all knot-½, then all
    /// knot-1; [`crate::render::media::knot_weights`]). What the browser
    /// stream sends every frame (issue 17).
    pub k: Arc<Vec<Vec3>>,
    /// The buffers those weights apply to, with their generations: each
    /// light's published buffer in light order, then in clear air each
    /// shared-layer place's layer (its id as generation; an empty buffer
    /// where it holds none), in haze every light's knot-½ and knot-1
    /// buffers (shared, never copied: the stream sends a buffer when its
    /// generation changes).
    pub buffers: Arc<Vec<(u64, Arc<LightBuffer>)>>,
    /// The haze density of this frame (0-1), `None` without haze.
    pub haze_density: Option<f32>,
    /// The display settings the frame's sRGB pixels were encoded with.
    pub display: Display,
    /// A moving-camera preview (not a composite of the per-light buffers):
    /// the browser stream pushes it as a picture.
    pub preview: bool,
    /// The fixture body layer as tiles, when bodies are shown (the browser
    /// stream sends the tiles that changed; [`BodyTiles`]).
    pub bodies: Option<Arc<BodyTiles>>,
}

/// One 16×16 tile of the body layer as the stream sends it.
#[derive(Clone, Debug, PartialEq)]
pub struct BodyTile {
    /// Changes whenever the tile's pixels change (counts up over the life of the daemon's body layer).
    pub revision: u64,
    /// 16×16 pixels row-major; `None` where the stage shows (and beyond the picture's edge).
    pub pixels: Vec<Option<BodyPixel>>,
}

impl BodyTile {
    /// True when no pixel of the tile shows a body.
    pub fn is_empty(&self) -> bool {
        self.pixels.iter().all(Option::is_none)
    }
}

/// The body layer as tiles (row-major over ⌈width/16⌉ × ⌈height/16⌉), the
/// browser stream's view of it.
#[derive(Clone, Debug)]
pub struct BodyTiles {
    /// Picture width.
    pub width: u32,
    /// Picture height.
    pub height: u32,
    /// Number of lights N (a glow's k_i is light i's; in haze the frame's k
    /// vector holds N entries per density knot).
    pub lights: u32,
    /// The tiles, shared between snapshots.
    pub tiles: Vec<Arc<BodyTile>>,
}

impl BodyTiles {
    /// Tiles across.
    pub fn tiles_x(&self) -> usize {
        (self.width as usize).div_ceil(TILE)
    }
}
