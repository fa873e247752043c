//! GDTF fixture types and MVR scenes (DIN SPEC 15800) for Footlight.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod archive;
pub mod gdtf;
pub mod mvr;
pub mod xml;
