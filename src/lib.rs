//! Footlight: a live, physically grounded picture of a theatre stage as a
//! lighting desk plays it.
//!
//! The renderer follows Vierjahn, Meik, Mostafawy and Bohn, "Improving
//! Photon Mapping Towards an Interactive Stage Lighting Framework" (EGVE
//! 2010): every light gets its own buffer rendered with a unit-intensity
//! source, and the picture is the weighted sum I = Σ k_i · buffer_i (eq. 5),
//! so a dimmer or colour change costs a composite, not a re-render.
//!
//! # Layout (in data-flow order)
//! * [`patch`]: the patch file: fixtures, positions, default look.
//! * [`fixture`]: lights as the tracer sees them, with emission patterns.
//! * [`scene`]: glTF import, materials, camera, BVH.
//! * [`render`]: G-buffer, Whitted per-light buffers, anti-aliasing,
//!   composite, display.
//! * [`gpu`]: the GPU compositor adapter (crate `footlight-gpu`).
//! * [`live`]: the daemon: frame clock, background tracer, geometry cache;
//!   it starts the HTTP preview.
//! * [`output`]: the output contract: [`output::Frame`], the typed
//!   [`output::DaemonStatus`], the [`output::CameraControl`] trait. The
//!   daemon fills it in; [`serve`] and the window import only it.
//! * [`serve`]: the HTTP preview.
//! * [`bench`]: `footlight bench`, the paper's figure 6 as same-run ratios.
//! * [`cli`]: the `footlight` commands (`render`'s still pipeline, `run`'s
//!   daemon wiring, `bench`'s dispatch); `src/main.rs` only parses flags.
//! * [`bundled`]: the bundled scenes, patches and test files, found at run
//!   time (no path of the build checkout in the binary).
#![deny(missing_docs)]

pub mod bench;
pub mod bundled;
pub mod cli;
pub mod gpu;
pub mod live;
pub mod memory;
pub mod output;
pub mod render;
pub mod scene;
pub mod serve;
#[cfg(feature = "window")]
pub mod window;

/// Lights for the tracer and their emission patterns (crate `footlight-fixture`).
pub use footlight_fixture as fixture;
/// The patch file (crate `footlight-fixture`).
pub use footlight_fixture::patch;
pub use footlight_fixture::{Beam, Light, Patch};
pub use render::{RenderSettings, Sampling};
pub use scene::Scene;

/// Path of the bundled default stage, relative to the repository root
/// (found at run time by [`bundled::find`]).
pub const DEFAULT_SCENE: &str = "scenes/stage.glb";
/// Path of the bundled default patch, relative to the repository root: the
/// paper's rig plus colour and moving heads a desk can play.
pub const DEFAULT_PATCH: &str = "patch/default.toml";
/// Path of the paper's section 4.3 rig (six lights, the bench's and the
/// golden images' rig), relative to the repository root.
pub const PAPER_PATCH: &str = "patch/paper-rig.toml";
