//! The renderer: per-light unit-intensity buffers (Vierjahn 2010, eq. 5)
//! and their composite.
//!
//! # Layout (data flow)
//! * [`gbuffer`]: 9 primary samples per pixel, binned by triangle ID (§3.4).
//! * [`whitted`]: Whitted recursion (eq. 1) expanded into camera-path
//!   vertices once per camera; direct Phong light from one unit source.
//! * [`view`]: the camera-dependent state and per-light buffer rendering;
//!   [`view::aa`], its adaptive anti-aliasing of the illumination (§3.4).
//! * [`photon`]: per-light photon maps for the indirect term (eq. 3),
//!   progressive refinement, and the path-traced reference.
//! * [`buffer`]: sparse tiled per-light buffers.
//! * [`group`]: an emitter group's cell buffers, per tile low-rank or exact.
//! * [`footprint`]: direct light in proportion to a beam's footprint (tile culling).
//! * [`build`]: [`LightBuild`], the only builder of a light's buffer, one
//!   method per stage (direct, Whitted + AA, photons, refinement).
//! * [`media`]: haze: per-light single scattering, density re-weighting.
//! * [`composite`]: I = Σ k_i ⊙ buffer_i (eq. 5, §3.3) on the CPU.
//! * [`display`]: exposure, white balance, sRGB, PNG.
//! * [`reference`]: single-pass eq. 1 renderer for the linearity tests,
//!   with its own light term (closed-form tests for what it shares).
//! * [`still`]: the whole pipeline for one still image (`footlight render`).

pub mod bodies;
pub mod buffer;
pub mod build;
pub mod composite;
pub mod display;
pub mod footprint;
pub mod gbuffer;
pub mod group;
pub mod layers;
pub mod media;
pub mod photon;
pub mod reference;
pub mod still;
pub mod view;
pub mod whitted;

pub use buffer::LightBuffer;
pub use build::{BuildSettings, Cancel, LightBuild};
pub use composite::composite;
pub use display::Display;
pub use view::{AaParams, SampleSet, Sampling, View};
pub use whitted::RecursionLimits;

/// The picture size of every default (width, height): `render`'s and
/// `run`'s `--width`/`--height`, [`RenderSettings::default`],
/// `DaemonConfig::default` and the bench's full-size figures (paper: 800×500).
pub const PICTURE_SIZE: (u32, u32) = (800, 500);

/// The bench's CI-sized picture (`footlight bench --quick`): a quarter of
/// [`PICTURE_SIZE`] on each side.
pub const QUICK_SIZE: (u32, u32) = (PICTURE_SIZE.0 / 4, PICTURE_SIZE.1 / 4);

/// Settings of one render, with the paper's defaults (section 4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels (paper: 800).
    pub width: u32,
    /// Image height in pixels (paper: 500).
    pub height: u32,
    /// Recursion limits (paper: depth 5).
    pub limits: RecursionLimits,
    /// Sampling mode (paper: adaptive).
    pub sampling: Sampling,
    /// Exposure and white balance.
    pub display: Display,
    /// How each light's buffer is built (anti-aliasing threshold, photons,
    /// refinement passes): [`BuildSettings`], the one owner of those defaults.
    pub build: BuildSettings,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: PICTURE_SIZE.0,
            height: PICTURE_SIZE.1,
            limits: RecursionLimits::default(),
            sampling: Sampling::Adaptive,
            display: Display::default(),
            build: BuildSettings::still(),
        }
    }
}
