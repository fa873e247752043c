//! Bounded, seeded fuzzing of the zip and XML readers: no input panics.
//! proptest with a fixed seed and case count, so the run is reproducible
//! and short (part of the normal test suite).

use super::{gdtf, mvr};
use footlight_mvr::archive::{Archive, Limits};
use footlight_mvr::gdtf::Gdtf;
use footlight_mvr::mvr::Mvr;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use std::path::Path;

fn runner(cases: u32) -> TestRunner {
    let config = Config { cases, failure_persistence: None, ..Config::default() };
    TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &[7; 32]))
}

/// The description.xml of the generated spot, for mutation.
fn spot_xml() -> String {
    let a = Archive::open(&gdtf("Spot")).unwrap();
    String::from_utf8(a.get("description.xml").unwrap().to_vec()).unwrap()
}

fn zip_of(entries: &[(&str, &[u8])]) -> Vec<u8> {
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

#[test]
fn mutated_zip_bytes_never_panic() {
    let bytes = std::fs::read(mvr("features")).unwrap();
    runner(96)
        .run(&(proptest::collection::vec((0..bytes.len(), any::<u8>()), 1..8), 0..bytes.len()), |(flips, cut)| {
            let mut b = bytes.clone();
            for (i, v) in flips {
                b[i] = v;
            }
            b.truncate(cut.max(1));
            let _ = Archive::from_bytes(Path::new("fuzz.mvr"), b.clone(), Limits::default()).map(Mvr::from_archive);
            Ok(())
        })
        .unwrap();
}

#[test]
fn mutated_gdtf_xml_never_panics() {
    let xml = spot_xml();
    runner(64)
        .run(&(proptest::collection::vec((0..xml.len(), "[<>/=\"a-z0-9 {},.]{0,4}"), 1..6)), |edits| {
            let mut s = xml.clone();
            for (at, text) in edits {
                let at = (0..=at.min(s.len())).rev().find(|&i| s.is_char_boundary(i)).unwrap_or(0);
                s.insert_str(at, &text);
            }
            let z = zip_of(&[("description.xml", s.as_bytes())]);
            if let Ok(g) = Gdtf::from_bytes(Path::new("fuzz.gdtf"), z) {
                for m in g.mode_names() {
                    let _ = g.layout(&m);
                }
            }
            Ok(())
        })
        .unwrap();
}

#[test]
fn mutated_scene_xml_never_panics() {
    let a = Archive::open(&mvr("features")).unwrap();
    let gsd = String::from_utf8(a.get("GeneralSceneDescription.xml").unwrap().to_vec()).unwrap();
    runner(64)
        .run(&(proptest::collection::vec((0..gsd.len(), "[<>/=\"a-zA-Z0-9 {},.-]{0,5}"), 1..6)), |edits| {
            let mut s = gsd.clone();
            for (at, text) in edits {
                let at = (0..=at.min(s.len())).rev().find(|&i| s.is_char_boundary(i)).unwrap_or(0);
                s.insert_str(at, &text);
            }
            let z = zip_of(&[("GeneralSceneDescription.xml", s.as_bytes())]);
            let _ = Archive::from_bytes(Path::new("fuzz.mvr"), z, Limits::default()).map(Mvr::from_archive);
            Ok(())
        })
        .unwrap();
}
