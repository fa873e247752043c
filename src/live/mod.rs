//! The live daemon (`footlight run`): DMX in, a background tracer for lights
//! whose geometry changed, a composite every display frame, the preview out.
//!
//! # Layout (data flow)
//! * [`show`]: [`Show`], the owner of everything between merged DMX and the
//!   fixtures (routes, universes, LTP, decoding, change classes).
//! * [`clock`]: the frame clock: decode → k_i → composite → publish.
//! * [`tracer`]: the scheduler that rebuilds dirty lights stage by stage
//!   (every stage is a [`crate::render::LightBuild`] method).
//! * [`cache`]: recent geometry states per light (position presets are instant).
//! * [`views`]: camera writes, named views, the moving preview and the view cache.
//! * [`bodies`]: fixture bodies over each composite (issue 14 item 5).
//! * [`daemon`]: [`Daemon`], the owner of every task and the one stop signal;
//!   it fills in the output contract ([`crate::output`]: frames, the typed
//!   status, the camera control) and starts the HTTP preview with it.
//!
//! Threads: DMX input and HTTP run on tokio; each frame-clock tick runs on
//! tokio's blocking pool; builds run on the tracer's own thread and rayon
//! pool. Neither input nor the clock ever waits for the tracer.

pub mod bodies;
pub mod cache;
pub mod clock;
pub mod daemon;
pub mod show;
pub mod tracer;
pub mod views;

pub use clock::{Decode, FrameClock, LightInput};
pub use daemon::{Daemon, DaemonConfig, DaemonError, DaemonHandle, DmxSource, bind_http, run_clock};
pub use show::{LiveSlots, Show};
pub use tracer::{Kept, Tracer, TracerSettings};
pub use views::{ViewSettings, Views};
