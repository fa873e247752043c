//! Footlight's stage lights, independent of the renderer: emission
//! patterns, lights as the tracer sees them, and the patch file.
//!
//! # Layout (data flow)
//! * [`patch`]: the patch file (TOML): fixtures, positions, default look.
//! * [`light`]: a light for the tracer: position, orientation, [`Beam`].
//! * [`beam`]: emission patterns f_ε with peak 1 and their importance sampler.
#![deny(missing_docs)]

pub mod beam;
pub mod light;
pub mod patch;

pub use beam::{Beam, BeamSample, BeamSampler, SpotBeam};
pub use light::Light;
pub use patch::{CameraSpec, Patch, PatchError};
