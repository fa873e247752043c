//! Test modules and shared helpers.

mod attributes;
mod colour_without_emitters;
mod festival;
mod fuzz;
mod gate;
mod limits;
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

/// A zip archive (deflated) of the given entries, for generated GDTF and MVR files.
pub fn zip_of(entries: &[(&str, &[u8])]) -> Vec<u8> {
    use std::io::Write;
    let mut buf = std::io::Cursor::new(Vec::new());
    let mut w = zip::ZipWriter::new(&mut buf);
    for (name, data) in entries {
        w.start_file(*name, zip::write::SimpleFileOptions::default()).unwrap();
        w.write_all(data).unwrap();
    }
    w.finish().unwrap();
    buf.into_inner()
}

/// A fresh temporary folder for one test.
pub fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("footlight-mvr-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}
