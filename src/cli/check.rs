//! `footlight check`, and the fixture listings `run` and `render` print.

use crate::Patch;
use anyhow::{Result, bail};
use std::path::Path;

/// `footlight check`: notes and warnings (each said once, with its file,
/// line and the fixtures it concerns), the scene, the fixtures (each, or in
/// runs of one type and mode past [`MAX_LISTED`] unless `list_all`), one
/// summary line per fixture type, and the verdict.
pub fn check(path: &Path, list_all: bool) -> Result<()> {
    match footlight_mvr::check_report(path) {
        Ok(checked) => {
            for n in &checked.notes {
                eprintln!("note: {n}");
            }
            for w in &checked.warnings {
                eprintln!("warning: {w}");
            }
            if let Some(show) = footlight_mvr::show_of(path) {
                // The MVR's geometry is the show's scene (unless `--scene`): its problems too.
                let loaded = crate::scene::load_mvr_scene(&show)?;
                if loaded.objects == 0 {
                    println!("{}: no scene objects; shows use the bundled stage", show.display());
                } else {
                    for w in &loaded.warnings {
                        eprintln!("warning: {w}");
                    }
                    println!(
                        "{}: scene of {} object(s), {} triangles",
                        show.display(),
                        loaded.objects,
                        loaded.scene.triangle_count()
                    );
                }
            }
            let patch = &checked.patch;
            let listing = patch.listing();
            if list_all || listing.len() <= MAX_LISTED {
                listing.iter().for_each(|f| println!("{f}"));
            } else {
                let runs = fixture_runs(&listing);
                runs.iter().for_each(|r| println!("{r}"));
                println!(
                    "({} fixtures in {} runs of one type and mode: `footlight check --list {}` lists each)",
                    listing.len(),
                    runs.len(),
                    path.display()
                );
            }
            if !checked.types.is_empty() {
                println!("fixture types:");
                checked.types.iter().for_each(|t| println!("  {t}"));
            }
            println!("{}: ok, {}", path.display(), fixture_summary(patch, &listing));
            Ok(())
        }
        Err(errors) => {
            for e in &errors {
                eprintln!("{e}");
            }
            bail!("{}: {} problem(s)", path.display(), errors.len())
        }
    }
}

/// Fixtures listed with their addresses when `run` starts, and by `check`
/// one per line; a bigger show prints where to find them (`run`) or lists
/// them in runs (`check`).
pub const MAX_LISTED: usize = 40;

/// Consecutive fixtures of one type, mode and cell count as one line each:
/// `  1001-1096  PixelBar 16 1 … PixelBar 16 96  [PixelBar 16 (65ch), 16 cells] × 96  DMX 1/1 … 14/261-325`
/// (ids, first and last name, the type as `check --list` shows it, how
/// many, the first fixture's start and the last one's range).
pub fn fixture_runs(listing: &[crate::fixture::patch::ListedFixture]) -> Vec<String> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < listing.len() {
        let first = &listing[i];
        let mut j = i;
        while j + 1 < listing.len() {
            let next = &listing[j + 1];
            if (&next.type_name, &next.mode, next.lights) != (&first.type_name, &first.mode, first.lights) {
                break;
            }
            j += 1;
        }
        let last = &listing[j];
        let n = j - i + 1;
        if n == 1 {
            out.push(first.to_string());
            i = j + 1;
            continue;
        }
        let ids = if last.id >= first.id && (last.id - first.id) as usize == n - 1 {
            format!("{}-{}", first.id, last.id)
        } else {
            format!("{}…{}", first.id, last.id)
        };
        let kind = match &first.mode {
            Some(m) => format!("{} ({m})", first.type_name),
            None => first.type_name.clone(),
        };
        let cells = if first.lights > 1 { format!(", {} cells", first.lights) } else { String::new() };
        let start = |f: &crate::fixture::patch::ListedFixture| f.dmx.map(|(u, a)| format!("{u}/{a}"));
        let end = |f: &crate::fixture::patch::ListedFixture| {
            f.dmx.map(|(u, a)| match f.footprint {
                0 | 1 => format!("{u}/{a}"),
                w => format!("{u}/{a}-{}", u32::from(a) + u32::from(w) - 1),
            })
        };
        let dmx = match (start(first), end(last)) {
            (Some(a), Some(b)) => format!("{a} … {b}"),
            (Some(a), None) => format!("{a} …"),
            (None, Some(b)) => format!("… {b}"),
            (None, None) => "not patched".to_string(),
        };
        out.push(format!("{ids:>11}  {} … {}  [{kind}{cells}] × {n}  DMX {dmx}", first.name, last.name));
        i = j + 1;
    }
    out
}

/// "10 fixtures on universe 1", "150 fixtures (336 lights: cells counted) on
/// universes 1-3, 5", "2 fixtures, none patched": fixtures and their cells
/// counted apart, universes as the patch uses them.
pub fn fixture_summary(patch: &Patch, listing: &[crate::fixture::patch::ListedFixture]) -> String {
    let lights = patch.fixtures.len();
    let cells = if lights > listing.len() { format!(" ({lights} lights: cells counted)") } else { String::new() };
    let mut universes: Vec<u16> = listing.iter().filter_map(|f| f.dmx.map(|(u, _)| u)).collect();
    universes.sort_unstable();
    universes.dedup();
    let mut runs: Vec<String> = Vec::new();
    let mut i = 0;
    while i < universes.len() {
        let mut j = i;
        while j + 1 < universes.len() && universes[j + 1] == universes[j] + 1 {
            j += 1;
        }
        // Runs of three or more as a range, else each number.
        if j >= i + 2 {
            runs.push(format!("{}-{}", universes[i], universes[j]));
        } else {
            runs.extend(universes[i..=j].iter().map(u16::to_string));
        }
        i = j + 1;
    }
    let unpatched = listing.iter().filter(|f| f.dmx.is_none()).count();
    let on = match (runs.len(), universes.len()) {
        (0, _) => ", none patched".to_string(),
        (_, 1) => format!(" on universe {}", runs.join(", ")),
        _ => format!(" on universes {}", runs.join(", ")),
    };
    let loose = if unpatched > 0 && !runs.is_empty() { format!(", {unpatched} not patched") } else { String::new() };
    let fixtures = if listing.len() == 1 { "1 fixture".to_string() } else { format!("{} fixtures", listing.len()) };
    format!("{fixtures}{cells}{on}{loose}")
}

/// Refuses to replace a file the user already has, unless `force`.
pub fn check_output(path: &Path, force: bool) -> Result<()> {
    if path.exists() && !force {
        bail!("{} already exists; choose another name or add --force to replace it", path.display());
    }
    Ok(())
}
