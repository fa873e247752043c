//! The output contract of the live daemon: what it publishes and what its
//! consumers read and write. The HTTP preview ([`crate::serve`]), the
//! window, `footlight bench` and the tests import this module, never
//! [`crate::live`]; the daemon fills it in and starts the server. So the
//! dependencies point one way (`live → serve → output`, `live → output`,
//! `window → output`) and nothing here imports the daemon.
//!
//! * [`frame`]: [`Frame`], what the frame clock publishes every display
//!   frame (pixels, k_i, the shared light buffers), and [`BodyTiles`], the
//!   fixture body layer as the browser stream sends it.
//! * [`status`]: [`DaemonStatus`], the typed `/api/status` (docs/live.md),
//!   built on request through a [`StatusFn`], with its parts (lights,
//!   build [`Stage`], DMX input, memory, the stream's counters).
//! * [`camera`]: [`CameraControl`], the camera and display writes of the
//!   page and the window, and the values they exchange ([`Pose`],
//!   [`NamedView`], [`ViewStatus`]); the pure input-to-pose mapping
//!   [`control`] the window uses.

pub mod camera;
pub mod frame;
pub mod status;

pub use camera::{
    CameraControl, Control, ControlKey, LimitsStatus, NamedView, PIXELS_PER_LINE, Phase, Pose, ViewCacheStatus,
    ViewSource, ViewStatus, WhiteState, control, view_key,
};
pub use frame::{BodyTile, BodyTiles, Frame};
pub use status::{
    BuildThreads, CacheSummary, ClockStatus, DaemonStatus, ImportStatus, InputSummary, LightLabel, LightPatch,
    LightReport, LightStatus, MemoryUsage, Stage, StatusFn, StreamCounters,
};
