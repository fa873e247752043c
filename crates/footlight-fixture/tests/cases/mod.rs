//! Test areas, and helpers they share.

mod beams; // zoom keeps flux, iris keeps Î, Hermite focus, sampler histograms
mod check; // `check` finds each kind of error on the right line
mod decode; // hand-built universes → real units; moving-head axes and 16-bit steps
mod library; // every fixture type in patch/fixtures and the paper rig
mod photometry; // hand-written IES and EULUMDAT files

use footlight_fixture::FixtureType;
use footlight_photometry::GelLibrary;
use std::path::{Path, PathBuf};

/// The repository root (patch/ and scenes/ live there).
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// This crate's test data.
pub fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data")
}

/// The shipped gel library.
pub fn gels() -> GelLibrary {
    GelLibrary::load(&root().join("patch/gels.toml")).expect("patch/gels.toml loads")
}

/// A library fixture type by file stem.
pub fn library_type(stem: &str) -> FixtureType {
    let lib = gels();
    footlight_fixture::fixture_type::load_type(&root().join(format!("patch/fixtures/{stem}.toml")), Some(&lib))
        .unwrap_or_else(|e| panic!("{e}"))
}

/// A temporary folder for one test.
pub fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("footlight-fixture-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}
