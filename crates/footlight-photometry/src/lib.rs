//! Photometry for Footlight: the colour part of k_i (Vierjahn 2010, eq. 4).
//!
//! Footlight renders every stage light with a unit 1 cd source and
//! composites I = Σ k_i ⊙ buffer_i (eq. 5), with k_i = c_F c_I v Î (eq. 4) an
//! RGB weight. This crate turns a fixture's lamp, dimmer level and gel into
//! that weight, physically: lamp spectra from Planck's law (tungsten cools
//! as it dims, T ≈ v^(1/8) T̂), measured gel transmission spectra, the CIE
//! 1931 observer, and linear sRGB (section 3.2). Colours are linear sRGB
//! normalised by luminance: Y = 1 for a lamp's own full white, and a gel's
//! colour has Y = its luminous transmittance; Î in candela carries the
//! absolute scale.
//!
//! The per-frame path ([`colour()`], [`k`]) reads tables precomputed per gel
//! ([`response`]), because k_i is recomputed every display frame for every
//! light (section 3.3). The exact spectral integration stays available
//! ([`colour_exact`]) as the reference the tables are tested against.
//! The crate knows nothing of DMX or the renderer (split at that seam,
//! like ripgrep's crates); it only depends on glam, serde and toml.
//!
//! # Layout
//!
//! In data-flow order, DMX level to RGB weight:
//!
//! * [`dimmer`]: DMX level → dimmer factor v (linear, square, theatre S-curve).
//! * [`spectrum`]: the 1 nm grid (360-830 nm) and sampled spectra.
//! * [`planck`]: blackbody spectra for a colour temperature.
//! * [`lamp`]: tungsten, discharge, LED and CMY sources; c_I and the tungsten dimming shift.
//! * [`gel`]: measured gel spectra from `patch/gels.toml`, colour scrollers.
//! * [`cie`]: CIE 1931 2° colour-matching functions, spectrum → XYZ.
//! * [`response`]: per-gel precomputed integrals over lamp temperature and LED basis.
//! * [`srgb`]: XYZ → linear sRGB, chromaticity, CCT (McCamy), gamut fitting.
//! * [`colour`](mod@colour): c_F ⊙ c_I and k_i (eq. 4).
//! * [`white_balance`]: camera-style gains that make a reference lamp neutral (section 3.3).

#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod cie;
pub mod colour;
pub mod dimmer;
pub mod gel;
pub mod lamp;
pub mod planck;
pub mod response;
pub mod spectrum;
pub mod srgb;
pub mod white_balance;

pub use cie::spectrum_to_xyz;
pub use colour::{colour, colour_exact, colour_mix, filter_factor, k};
pub use dimmer::DimmerCurve;
pub use gel::{Gel, GelError, GelId, GelLibrary, GelMix, Published, Scroller};
pub use lamp::{Chroma, CmyFilters, Emitter, Lamp};
pub use planck::blackbody;
pub use response::Response;
pub use spectrum::Sampled;
pub use white_balance::WhiteBalance;
