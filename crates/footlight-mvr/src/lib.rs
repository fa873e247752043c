//! GDTF fixture types and MVR scenes (DIN SPEC 15800:2022) for Footlight:
//! readers, and their mapping onto `footlight-fixture`'s types (no
//! renderer dependency).
//!
//! ```text
//! show.mvr ─ archive (checked zip) ─┬─ GeneralSceneDescription.xml ─ mvr::Mvr ─ Scene (world matrices, mm, Z up)
//!                                   └─ x.gdtf ─ gdtf::Gdtf ─ layout(mode): geometry instances, channels per break
//!                                                   └─ show::fixture_type ─> FixtureType
//! Scene + types ─ show::load_mvr ─> Import { Patch (metres, Y up), warnings, Scene }
//! ```
//!
//! # Why these crates
//! * **quick-xml** (+ serde) reads the MVR scene and, with its pull reader,
//!   finds where malformed XML breaks (line and column) before serde runs.
//! * **zip** (pure Rust, zlib-rs) inflates; [`archive`] refuses `..` and
//!   absolute entry names, more than 1 GiB in all, and > 100:1 entries.
//! * **gdtf** (0.3.0, MIT) is used for `description.xml`: it models GDTF 1.2
//!   completely (every geometry kind, GeometryReference breaks, channel
//!   functions with wheel/emitter/filter/mode master/DMX profile, channel
//!   sets, relations, emitters with measurements, filters, DMX profiles,
//!   wheels with facets) on the same quick-xml/zip stack. Its gaps are
//!   worked around here: `Matrix` has no accessor ([`gdtf::matrix`] reads it
//!   back through its serialiser), `DmxValue::to` can overflow a shift on a
//!   hostile value ([`gdtf::dmx`]), its errors carry no position (the XML is
//!   checked first), and it requires `DominantWaveLength` next to an
//!   emitter's `Color` although GDTF 1.2 makes it optional (such files are
//!   refused with the crate's message). No Rust MVR reader was found, so
//!   [`mvr`] is written here (a few serde structs).
//!
//! # Layout
//! * [`archive`]: the checked zip, in memory.
//! * [`xml`]: well-formedness with file, line and column; nesting depth bounded before any recursive reader runs.
//! * [`gdtf`]: GDTF files and DMX-mode expansion (geometry walked by reference).
//! * [`colour`]: LED colour of `ColorAdd_*` channels without an `<Emitter>` (attribute colours, GDTF Annex B).
//! * [`gate`]: gobo and prism wheels, blades and frost of a GDTF spot (its gate).
//! * [`mvr`]: the MVR scene, flattened; MVR → stage axes ([`mvr::stage_matrix`]).
//! * [`show`]: GDTF → `FixtureType`, MVR → `Patch` ([`load_mvr`], [`load_patch`], [`check_patch`], [`check_report`]).
//! * [`report`]: warnings said once per file and problem, with their lines
//!   and counts; one summary per fixture type ([`TypeSummary`]).
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod archive;
pub mod body;
pub mod colour;
pub mod gate;
pub mod gdtf;
pub mod mvr;
pub mod report;
pub mod show;
pub mod xml;

pub use report::{Modelled, TypeSummary};
pub use show::{
    Cell, Checked, GdtfTypes, Import, cells, check_patch, check_report, fixture_type, is_mvr, load_mvr, load_patch,
    show_of, time_load_mvr,
};
