//! festival.mvr (issue 38 item 7, issue 36 items 3-4): a festival-scale show
//! written by `tools/gen_gdtf_mvr.py --festival`. Its counts against the
//! generator's known answers (`tests/data/mvr/festival.json`) and against
//! pymvr and pygdtf (`tests/peers/festival.py`: fixtures, the lights each
//! fixture is, universes, every GDTFSpec resolved); its warnings each said
//! once, at the line of what they name, with the fixtures they concern;
//! one summary per fixture type; the extension-less specs resolved with a note.

use super::{mvr, root};
use footlight_mvr::{Modelled, load_mvr};
use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet};
use std::io::Read;
use std::process::Command;

fn known() -> Value {
    let text = std::fs::read_to_string(root().join("tests/data/mvr/festival.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn universes_of(patch: &footlight_fixture::Patch) -> Vec<u64> {
    let u: BTreeSet<u64> = patch.listing().iter().filter_map(|f| f.dmx.map(|(u, _)| u64::from(u))).collect();
    u.into_iter().collect()
}

/// The text of an entry of the festival archive (the zip read here with the
/// `zip` crate, not Footlight's reader).
fn entry_text(archive: &std::path::Path, name: &str) -> String {
    let mut z = zip::ZipArchive::new(std::fs::File::open(archive).unwrap()).unwrap();
    let mut text = String::new();
    z.by_name(name).unwrap().read_to_string(&mut text).unwrap();
    text
}

/// 1-based line of the first line of `text` containing `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).map(|i| i + 1).unwrap_or_else(|| panic!("{needle:?} not found"))
}

#[test]
fn festival_counts_match_the_generators_known_answers() {
    let k = known();
    let import = load_mvr(&mvr("festival")).unwrap();
    let p = &import.patch;
    assert_eq!(p.listing().len() as u64, k["fixtures"].as_u64().unwrap(), "fixtures");
    assert_eq!(p.fixtures.len() as u64, k["lights"].as_u64().unwrap(), "lights: cells and placeholders");
    assert!(k["fixtures"].as_u64().unwrap() >= 140 && k["emitters"].as_u64().unwrap() >= 3500, "{k}");
    let universes: Vec<u64> = k["universes"].as_array().unwrap().iter().map(|u| u.as_u64().unwrap()).collect();
    assert!(universes.len() >= 20, "{universes:?}");
    assert_eq!(universes_of(p), universes);
    // One summary per type, with the generator's fixtures and cells.
    let types = k["types"].as_object().unwrap();
    assert_eq!(import.types.len(), types.len(), "{:#?}", import.types);
    for t in &import.types {
        let want = &types[&t.file];
        let fixtures = want["fixtures"].as_u64().unwrap() as usize;
        assert_eq!(
            (t.fixtures, t.cells),
            (fixtures, fixtures * want["cells_per_fixture"].as_u64().unwrap() as usize),
            "{t}"
        );
    }
}

#[test]
fn festival_agrees_with_pymvr_and_pygdtf() {
    if !super::peers::peers_available() {
        return;
    }
    let path = mvr("festival");
    let script = root().join("crates/footlight-mvr/tests/peers/festival.py");
    let out = Command::new("timeout").arg("300").arg("python3").arg(script).arg(&path).output().expect("run python3");
    assert!(out.status.success(), "festival.py failed:\n{}", String::from_utf8_lossy(&out.stderr));
    let peer: Value = serde_json::from_slice(&out.stdout).expect("festival.py prints JSON");
    let import = load_mvr(&path).unwrap();
    let p = &import.patch;
    assert_eq!(p.listing().len() as u64, peer["fixtures"].as_u64().unwrap(), "fixtures");
    assert_eq!(p.fixtures.len() as u64, peer["lights"].as_u64().unwrap(), "lights");
    let theirs: Vec<u64> = peer["universes"].as_array().unwrap().iter().map(|u| u.as_u64().unwrap()).collect();
    assert_eq!(universes_of(p), theirs, "universes");
    // Every type as the peer resolved and counted it.
    let per_type = peer["types"].as_object().unwrap();
    for t in &import.types {
        let theirs = &per_type[&t.file];
        assert_eq!(t.fixtures as u64, theirs["fixtures"].as_u64().unwrap(), "{t}");
        assert_eq!(t.cells as u64, theirs["lights"].as_u64().unwrap(), "{t}");
    }
    assert_eq!(import.types.len(), per_type.len());
    // The extension-less specs resolve to the same files.
    let resolved: BTreeMap<String, String> = peer["specs"]
        .as_object()
        .unwrap()
        .iter()
        .filter_map(|(spec, file)| Some((spec.clone(), file.as_str()?.to_string())))
        .collect();
    assert!(resolved.values().any(|f| f == "Raylight@Sharpline_330@rev2.gdtf"), "{resolved:?}");
    for file in resolved.values() {
        assert!(import.types.iter().any(|t| &t.file == file), "{file}: {:#?}", import.types);
    }
}

#[test]
fn festival_warnings_are_said_once_at_their_lines() {
    let path = mvr("festival");
    let import = load_mvr(&path).unwrap();
    let gsd = entry_text(&path, "GeneralSceneDescription.xml");
    // A handful of warnings for 3,687 lights: each problem once.
    assert!(import.warnings.len() <= 12, "{:#?}", import.warnings);
    let mut seen = BTreeSet::new();
    for w in &import.warnings {
        assert!(w.line > 0, "every warning has its line: {w}");
        assert!(seen.insert((w.path.clone(), w.message.clone())), "said twice: {w}");
    }
    // The missing GDTF: one warning at its first fixture's <Fixture> line, naming the count.
    let missing: Vec<_> = import.warnings.iter().filter(|w| w.message.contains("Floor Wash 7.gdtf")).collect();
    assert_eq!(missing.len(), 1, "{:#?}", import.warnings);
    assert_eq!(missing[0].line, line_of(&gsd, "<Fixture name=\"Floor Wash 7 1\""), "{}", missing[0]);
    assert!(missing[0].message.ends_with("(3 fixtures)"), "{}", missing[0]);
    let t = import.types.iter().find(|t| t.file.contains("Floor Wash 7")).unwrap();
    assert_eq!((t.status, t.fixtures), (Modelled::Not, 3), "{t}");
    // A warning about a type's file is at a line of that file's description.xml and counts its fixtures.
    for w in import.warnings.iter().filter(|w| w.path.ends_with("description.xml")) {
        let entry = w.path.parent().unwrap().file_name().unwrap().to_str().unwrap();
        let text = entry_text_of_gdtf(&path, entry);
        assert!(w.line <= text.lines().count(), "{w}");
        let t = import.types.iter().find(|t| t.file == entry).unwrap();
        assert!(w.message.contains(&format!("({} fixtures", t.fixtures)), "{w}");
    }
    // Not-modelled attributes, if any, are listed with the line of their first <LogicalChannel>.
    for w in import.warnings.iter().filter(|w| w.message.contains(footlight_mvr::report::NOT_MODELLED)) {
        let entry = w.path.parent().unwrap().file_name().unwrap().to_str().unwrap();
        let text = entry_text_of_gdtf(&path, entry);
        let list = w.message.split(footlight_mvr::report::NOT_MODELLED).nth(1).unwrap();
        let first = list.trim_start_matches(": ").split(" (line").next().unwrap();
        assert_eq!(w.line, line_of(&text, &format!("<LogicalChannel Attribute=\"{first}\"")), "{w}");
    }
    // Both extension-less specs resolve, each with one note at its first fixture.
    assert_eq!(import.notes.len(), 2, "{:#?}", import.notes);
    let note = import.notes.iter().find(|n| n.message.contains("\"Blitzwerk@Cluster S2\"")).unwrap();
    assert!(note.message.contains("read as \"Blitzwerk@Cluster S2.gdtf\"") && note.message.ends_with("(24 fixtures)"));
    assert_eq!(note.line, line_of(&gsd, "<Fixture name=\"Cluster S2 1\""));
    let note = import.notes.iter().find(|n| n.message.contains("\"Sharpline 330\"")).unwrap();
    assert!(note.message.contains("Raylight@Sharpline_330@rev2.gdtf") && note.message.contains("FixtureType Name"));
    // The resolved types are patched, not placeholders.
    for name in ["Cluster S2 1 / Lamp1", "Sharpline 330 1"] {
        let f = import.patch.fixtures.iter().find(|f| f.name == name).unwrap_or_else(|| panic!("{name}"));
        assert!(matches!(f.model, footlight_fixture::FixtureModel::Typed(_)), "{name}");
    }
}

/// `description.xml` of the GDTF entry `entry` inside the festival archive.
fn entry_text_of_gdtf(archive: &std::path::Path, entry: &str) -> String {
    let mut z = zip::ZipArchive::new(std::fs::File::open(archive).unwrap()).unwrap();
    let mut bytes = Vec::new();
    z.by_name(entry).unwrap().read_to_end(&mut bytes).unwrap();
    let mut inner = zip::ZipArchive::new(std::io::Cursor::new(bytes)).unwrap();
    let mut text = String::new();
    inner.by_name("description.xml").unwrap().read_to_string(&mut text).unwrap();
    text
}
