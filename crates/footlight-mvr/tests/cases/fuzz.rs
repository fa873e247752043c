//! Bounded, seeded fuzzing of the zip and XML readers: no input panics.
//! proptest with a fixed seed and case count, so the run is reproducible
//! and short (part of the normal test suite).

use super::{gdtf, mvr, zip_of};
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

/// The Bar8's `description.xml` with its eight cells replaced by `n`
/// GeometryReferences to the Pixel beam (mode 25ch: a master dimmer and
/// three colour channels per cell, so `1 + 3n` channel instances).
fn bar_with_cells(n: usize) -> String {
    let a = Archive::open(&gdtf("Bar8")).unwrap();
    let xml = String::from_utf8(a.get("description.xml").unwrap().to_vec()).unwrap();
    let start = xml.find("<GeometryReference Name=\"Cell1\"").unwrap();
    let end = xml.find("</Geometry><Geometry Name=\"BarSplit\"").unwrap();
    let mut refs = String::with_capacity(n * 160);
    for i in 0..n {
        refs.push_str(&format!(
            "<GeometryReference Name=\"C{i}\" Geometry=\"Pixel\" Position=\"{{1,0,0,0}}{{0,1,0,0}}{{0,0,1,0}}{{0,0,0,1}}\">\
             <Break DMXOffset=\"{}\" DMXBreak=\"1\"/></GeometryReference>",
            2 + 3 * (i % 100)
        ));
    }
    format!("{}{refs}{}", &xml[..start], &xml[end..])
}

/// An MVR hanging `gdtf` (mode `mode`) once, as `B.gdtf`.
fn one_fixture_mvr(gdtf: &[u8], mode: &str) -> Vec<u8> {
    let gsd = format!(
        "<GeneralSceneDescription verMajor=\"1\" verMinor=\"6\"><Scene><Layers><Layer name=\"R\" uuid=\"L\"><ChildList>\
         <Fixture name=\"B\" uuid=\"F\"><GDTFSpec>B.gdtf</GDTFSpec><GDTFMode>{mode}</GDTFMode>\
         <Addresses><Address break=\"0\">1</Address></Addresses></Fixture></ChildList></Layer></Layers></Scene>\
         </GeneralSceneDescription>"
    );
    zip_of(&[("GeneralSceneDescription.xml", gsd.as_bytes()), ("B.gdtf", gdtf)])
}

/// Issue 35: huge-count seeds, each through `load_mvr` on a 2 MiB stack,
/// finish quickly with a patch, a warning or an error, never a crash or a
/// hang. A 1,600-cell pixel matrix took 75 s before the cell split was
/// made linear (now ~0.1 s); past 4,096 cells the fixture stays one light;
/// past 65,536 channel instances (references × their channels) the mode
/// is an error; an MVR of 20,000 fixtures loads.
#[test]
fn huge_count_seeds_finish_quickly() {
    use footlight_mvr::gdtf::MAX_CHANNELS;
    use footlight_mvr::show::MAX_CELLS;
    let dir = super::temp_dir("huge");
    let bar = |n: usize| zip_of(&[("description.xml", bar_with_cells(n).as_bytes())]);
    let mut fixtures = String::new();
    for i in 0..20_000 {
        fixtures.push_str(&format!(
            "<Fixture name=\"F{i}\" uuid=\"f{i}\"><GDTFSpec>Footlight@Spot.gdtf</GDTFSpec><GDTFMode>Basic</GDTFMode>\
             <Addresses><Address break=\"0\">{}</Address></Addresses></Fixture>",
            1 + 512 * i
        ));
    }
    let rig = format!(
        "<GeneralSceneDescription verMajor=\"1\" verMinor=\"6\"><Scene><Layers><Layer name=\"R\" uuid=\"L\">\
         <ChildList>{fixtures}</ChildList></Layer></Layers></Scene></GeneralSceneDescription>"
    );
    let spot_bytes = std::fs::read(gdtf("Spot")).unwrap();
    let seeds: Vec<(&str, Vec<u8>, &str)> = vec![
        ("cells-1600.mvr", one_fixture_mvr(&bar(1600), "25ch"), "1600 lights"),
        ("cells-over.mvr", one_fixture_mvr(&bar(MAX_CELLS + 1), "25ch"), "stays one light"),
        ("channels-over.mvr", one_fixture_mvr(&bar(MAX_CHANNELS / 3 + 1), "25ch"), "channel instances"),
        (
            "rig-20000.mvr",
            zip_of(&[("GeneralSceneDescription.xml", rig.as_bytes()), ("Footlight@Spot.gdtf", &spot_bytes)]),
            "20000 lights",
        ),
    ];
    for (name, bytes, want) in seeds {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        let t = std::time::Instant::now();
        let got = std::thread::Builder::new()
            .stack_size(2 << 20)
            .spawn(move || match footlight_mvr::load_mvr(&path) {
                Ok(i) => {
                    let w: Vec<String> = i.warnings.iter().map(ToString::to_string).collect();
                    format!("{} lights; {}", i.patch.fixtures.len(), w.join("\n"))
                }
                Err(e) => e.iter().map(ToString::to_string).collect::<Vec<_>>().join("\n"),
            })
            .unwrap()
            .join()
            .unwrap();
        assert!(got.contains(want), "{name}: want {want:?} in {}", &got[..got.len().min(2000)]);
        assert!(t.elapsed().as_secs() < 60, "{name}: {:?}", t.elapsed());
    }
}
