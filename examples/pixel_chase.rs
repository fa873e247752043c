//! The pixel chase of `footlight::bench::scale::pixel_chase` on its own
//! (issue 38 item 5): `cargo run --release --example pixel_chase [W H FRAMES]`
//! (default 800 500 30), printed as Markdown.

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let num = |i: usize, default: usize| args.get(i).and_then(|a| a.parse().ok()).unwrap_or(default);
    let show = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mvr/festival.mvr");
    let report = footlight::bench::scale::pixel_chase(&show, num(0, 800) as u32, num(1, 500) as u32, num(2, 30))?;
    print!("{}", report.markdown());
    Ok(())
}
