//! Test modules and shared helpers.

mod fuzz;
mod gate;
mod peers;
mod readers;
mod show;
mod spectra;

use std::path::PathBuf;

/// The repository root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A generated GDTF file by stem (`"Spot"` → `tests/data/gdtf/Footlight@Spot.gdtf`).
pub fn gdtf(stem: &str) -> PathBuf {
    root().join(format!("tests/data/gdtf/Footlight@{stem}.gdtf"))
}

/// A generated MVR file by stem.
pub fn mvr(stem: &str) -> PathBuf {
    root().join(format!("tests/data/mvr/{stem}.mvr"))
}
