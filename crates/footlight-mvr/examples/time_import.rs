//! Times the MVR import of a file (default: the generated 150-fixture show):
//! `cargo run -p footlight-mvr --example time_import [--release] -- [file.mvr]`.

fn main() {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/data/mvr/show150.mvr").to_string());
    match footlight_mvr::time_load_mvr(std::path::Path::new(&path)) {
        Ok(s) => println!("{path}: imported in {:.1} ms", s * 1e3),
        Err(e) => e.iter().for_each(|e| eprintln!("{e}")),
    }
}
