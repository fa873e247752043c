//! Footlight's stage lights, independent of the renderer: emission
//! patterns, fixture types, the patch file, and the path from DMX slots to
//! what the renderer needs (Vierjahn 2010, section 3.2, eq. 4).
//!
//! ```text
//! patch file ─> Patch ─┬─ Fixture (type, mode, address, position, gel)
//! fixture types ───────┘        │
//! 512-slot frames ──────────────┴─ decode ─> FixtureState (real units)
//!                                              ├─ light_of ─> Light { position, rotation, Beam }   (tracer)
//!                                              ├─ k_of ─────> k_i = c_F ⊙ c_I · v · Î           (compositor)
//!                                              └─ classify(old, new) ─> Unchanged | Composite | Geometry
//! ```
//!
//! The crate does not depend on the renderer or the DMX input: frames come
//! in as plain `[u8; 512]` ([`Universes`]), colour comes from
//! `footlight-photometry`.
//!
//! # Layout (data flow)
//! * [`patch`]: the patch file: instances, addresses, `[look]`, `[[input]]`; [`check`].
//! * [`fixture_type`]: fixture-type files: lamp, optics, yoke, modes and channels; decoding.
//! * [`photometric`]: IES LM-63 and EULUMDAT readers.
//! * [`state`]: [`FixtureState`] in real units, [`classify`], [`Universes`].
//! * [`light`]: a light for the tracer, moving-head orientation.
//! * [`beam`]: emission patterns f_ε with peak 1 and their importance sampler.
//! * [`error`]: [`PatchError`], `file:line: message` for every file above.
#![deny(missing_docs)]
#![forbid(unsafe_code)]
// `!(x > 0.0)` is how this crate rejects NaN along with out-of-range
// values: every such comparison is deliberate.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod beam;
pub mod error;
pub mod fixture_type;
pub mod light;
pub mod patch;
pub mod photometric;
pub mod state;

pub use beam::{Beam, BeamSample, BeamSampler, HermiteBeam, HermitePattern, MeasuredBeam, SpotBeam};
pub use error::PatchError;
pub use fixture_type::{Attribute, FixtureType, Manual, Mode, Optics};
pub use light::Light;
pub use patch::{CameraSpec, Fixture, FixtureModel, HazeSpec, InputProtocol, InputRoute, Patch, check, check_text};
pub use state::{Change, DmxSlots, FixtureState, Universes, classify};

#[cfg(test)]
mod tests {
    /// The daemon shares patches and lights across threads.
    #[test]
    fn shared_types_are_send_and_sync() {
        fn check<T: Send + Sync>() {}
        check::<crate::Patch>();
        check::<crate::Light>();
        check::<crate::Beam>();
        check::<crate::FixtureState>();
        check::<crate::Universes>();
    }
}
