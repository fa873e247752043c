//! The preview page's light table (issue 37) in headless Chromium at
//! 1280×800 on the 150-fixture MVR show (336 lights): every column is on
//! screen (no horizontal overflow, no header cut), one row per fixture with
//! its cells folded (a click unfolds them), lit fixtures first, and the
//! "lit" filter and "patch order" sort do what they say. The page's layout
//! is read with `Runtime.evaluate` on its DOM; a screenshot is written to
//! the temp folder for a look.

use crate::common::browser::{Browser, chromium};
use crate::common::*;
use crate::live::ShowDaemon;
use footlight::fixture::{Attribute, FixtureModel};
use std::time::{Duration, Instant};

/// Opens `url` with exactly a `width`×`height` viewport, whatever the
/// window's frame takes.
fn open_at(chromium: &str, url: &str, width: u32, height: u32) -> Browser {
    let mut browser = Browser::open(chromium, url, (width, height));
    browser.call(
        "Emulation.setDeviceMetricsOverride",
        serde_json::json!({"width": width, "height": height, "deviceScaleFactor": 1, "mobile": false}),
    );
    browser
}

/// The page's table once it shows `rows` rows and `lit` lit fixtures (waits
/// up to 60 s in the page): the overflow figures, every header's box and
/// whether it is cut, the cells that must never be cut (address, cd,
/// state, Hz, build) that are, and every row's class and fixture id.
fn table(browser: &mut Browser, rows: usize, lit: usize) -> serde_json::Value {
    browser.eval(&format!(
        "new Promise((ok, fail) => {{ const t0 = performance.now(); const t = () => {{
           const rows = document.querySelectorAll('#lights tr');
           const lit = document.querySelectorAll('#lights tr.fixture.lit');
           if (rows.length === {rows} && lit.length === {lit}) {{
             const panel = document.getElementById('table-panel'), table = document.getElementById('light-table');
             const cut = el => el.scrollWidth > el.clientWidth;
             const heads = [...table.querySelectorAll('th')].map(th => {{ const r = th.getBoundingClientRect();
               return {{ text: th.textContent, left: r.left, right: r.right, cut: cut(th) }}; }});
             const cutCells = [...rows].flatMap(r => [2, 4, 5, 6, 7].map(i => r.cells[i]))
               .filter(td => td && cut(td)).map(td => td.textContent);
             ok({{ width: innerWidth, height: innerHeight,
               page: [document.documentElement.scrollWidth, document.documentElement.clientWidth],
               panel: [panel.scrollWidth, panel.clientWidth], table: [table.scrollWidth, table.clientWidth],
               right: table.getBoundingClientRect().right, heads, cutCells,
               rows: [...rows].map(r => ({{ cls: r.className, fixture: r.dataset.fixture ?? null }})) }});
           }} else if (performance.now() - t0 > 60000) fail(new Error(`${{rows.length}} rows, ${{lit.length}} lit`));
           else setTimeout(t, 50); }}; t(); }})"
    ))
}

/// Every column on screen: nothing scrolls sideways (page, panel, table),
/// no header is cut or past the right edge, and the number cells are whole.
fn assert_fits(t: &serde_json::Value, width: f64) {
    let pair = |k: &str| (t[k][0].as_f64().unwrap(), t[k][1].as_f64().unwrap());
    for k in ["page", "panel", "table"] {
        let (scroll, client) = pair(k);
        assert!(scroll <= client, "{k} overflows sideways: scrollWidth {scroll} > clientWidth {client}");
    }
    assert!(t["right"].as_f64().unwrap() <= width, "table ends past the viewport: {}", t["right"]);
    let heads = t["heads"].as_array().unwrap();
    let names: Vec<&str> = heads.iter().map(|h| h["text"].as_str().unwrap()).collect();
    for want in ["#", "fixture", "addr", "mode", "cd", "state", "Hz", "build", "DMX"] {
        assert!(names.contains(&want), "no {want} column: {names:?}");
    }
    for h in heads {
        assert!(h["right"].as_f64().unwrap() <= width && h["cut"] == false, "header off screen or cut: {h}");
    }
    assert_eq!(t["cutCells"], serde_json::json!([]), "address/cd/state/Hz/build cells cut");
}

#[test]
fn light_table_fits_1280_px_with_one_row_per_fixture_cells_folded_and_lit_fixtures_first() {
    let Some(chromium) = chromium() else { return };
    let patch = footlight_mvr::load_mvr(&root().join("tests/data/mvr/show150.mvr")).unwrap().patch;
    // Light three fixtures far down the patch (a wash, a pixel bar: its
    // master dimmer and every pixel's colour, a Fresnel): dimmer and
    // colour-mix channels at full over the file's channel defaults.
    let lit_names = ["Wash 7", "Bar8 2", "Fresnel 5"];
    let mut levels = patch.look_universes.clone();
    for f in &patch.fixtures {
        let fixture = f.cell.as_ref().map_or(f.name.as_str(), |c| c.fixture_name.as_str());
        let FixtureModel::Typed(t) = &f.model else { continue };
        if !lit_names.contains(&fixture) {
            continue;
        }
        for c in t.fixture_type.modes[t.mode]
            .channels
            .iter()
            .filter(|c| matches!(c.attribute, Attribute::Dimmer | Attribute::Mix(_)))
        {
            for (o, v) in c.slots_for(c.full_scale()) {
                let (u, a) = f.slot_address(o).unwrap();
                levels.set_slot(u, a, v);
            }
        }
    }
    let mut dmx = footlight_dmx::Universes::default();
    for universe in 1..=5 {
        let slots = *levels.get(universe).unwrap();
        dmx.update(&footlight_dmx::UniverseFrame { universe, slots, at: tokio::time::Instant::now(), stale: false });
    }
    // The default picture size: the page lays out an 800×500 picture.
    let daemon = ShowDaemon::start(patch, 800, 500, dmx);

    // The status's fixtures (a fixture's cells are consecutive lights under
    // its id) and the lit ones, in patch order.
    let t = Instant::now();
    let (fixtures, lit) = loop {
        let s = daemon.status();
        let mut fixtures: Vec<(u64, bool, usize)> = Vec::new(); // id, lit, cells
        for l in s["lights"].as_array().unwrap() {
            let (id, on) = (l["fixture"].as_u64().unwrap(), l["intensity"].as_f64().unwrap() > 0.0);
            match fixtures.last_mut() {
                Some(f) if l["cell"].as_u64().is_some_and(|c| c > 1) && f.0 == id => {
                    f.1 |= on;
                    f.2 += 1;
                }
                _ => fixtures.push((id, on, 1)),
            }
        }
        let lit: Vec<u64> = fixtures.iter().filter(|f| f.1).map(|f| f.0).collect();
        if lit.len() == lit_names.len() {
            break (fixtures, lit);
        }
        assert!(t.elapsed() < Duration::from_secs(60), "never lit: {lit:?}");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert_eq!((fixtures.len(), fixtures.iter().map(|f| f.2).sum::<usize>()), (148, 336));
    assert!(!fixtures[0].1, "the patch's first fixture is dark: the lit ones must move up");
    let bar = fixtures.iter().find(|f| f.2 == 8 && f.1).expect("a lit pixel bar").0;

    let mut browser = open_at(chromium, &format!("http://{}/", daemon.http), 1280, 800);
    let folded = table(&mut browser, fixtures.len(), lit.len());
    assert_eq!((folded["width"].as_u64(), folded["height"].as_u64()), (Some(1280), Some(800)));
    assert_fits(&folded, 1280.0);
    let rows = folded["rows"].as_array().unwrap();
    let ids: Vec<u64> = rows.iter().map(|r| r["fixture"].as_str().unwrap().parse().unwrap()).collect();
    assert!(rows.iter().all(|r| r["cls"].as_str().unwrap().split(' ').any(|c| c == "fixture")), "cells folded");
    let mut sorted = ids.clone();
    sorted.sort_unstable();
    let mut all: Vec<u64> = fixtures.iter().map(|f| f.0).collect();
    all.sort_unstable();
    assert_eq!(sorted, all, "one row per fixture");
    assert_eq!(ids[..lit.len()], lit[..], "lit fixtures first, in patch order");
    let row_lit = |r: &serde_json::Value| r["cls"].as_str().unwrap().split(' ').any(|c| c == "lit");
    assert!(rows[..lit.len()].iter().all(row_lit) && !rows[lit.len()..].iter().any(row_lit));

    // A click on the pixel bar unfolds its eight cells under it; still no overflow.
    browser.eval(&format!("document.querySelector('#lights tr.fixture[data-fixture=\"{bar}\"]').click()"));
    let open = table(&mut browser, fixtures.len() + 8, lit.len());
    assert_fits(&open, 1280.0);
    let rows = open["rows"].as_array().unwrap();
    let bar_id = bar.to_string();
    let at = rows.iter().position(|r| r["fixture"] == bar_id.as_str()).unwrap();
    assert!(rows[at + 1..at + 9].iter().all(|r| r["cls"].as_str().unwrap().starts_with("cell")), "{rows:?}");
    let png = browser.screenshot();
    let shot = std::env::temp_dir().join("footlight-light-table-1280x800.png");
    std::fs::write(&shot, &png).unwrap();
    eprintln!("screenshot: {}", shot.display());

    // The "lit" filter leaves the lit fixtures; "patch order" puts the patch's first fixture first.
    let set = |id: &str, v: &str| {
        format!(
            "(() => {{ const e = document.getElementById('{id}'); e.value = '{v}'; e.dispatchEvent(new Event('input')); }})()"
        )
    };
    browser.eval(&set("filter", "lit"));
    let only_lit = table(&mut browser, lit.len() + 8, lit.len());
    let shown: Vec<&str> = only_lit["rows"].as_array().unwrap().iter().filter_map(|r| r["fixture"].as_str()).collect();
    assert_eq!(shown, lit.iter().map(u64::to_string).collect::<Vec<_>>());
    browser.eval(&set("filter", "all"));
    browser.eval(&set("sort", "patch"));
    let by_patch = table(&mut browser, fixtures.len() + 8, lit.len());
    assert_eq!(by_patch["rows"][0]["fixture"], fixtures[0].0.to_string());
}

/// Issue 36 item 3: the page lists what the import said, folded under
/// "import warnings": one line per fixture type (a GDTF the archive lacks
/// marked not modelled) and each warning once, as `/api/status` gives them;
/// a click unfolds it.
#[test]
fn the_page_lists_the_import_summary_in_a_folded_section() {
    let Some(chromium) = chromium() else { return };
    let checked = footlight_mvr::check_report(&root().join("tests/data/mvr/features.mvr")).unwrap();
    let (types, warnings) = (checked.types.len(), checked.warnings.len());
    let import = footlight::output::ImportStatus::of(&checked);
    let daemon = ShowDaemon::start_with_import(checked.patch, 160, 100, Default::default(), import);
    let mut browser = open_at(chromium, &format!("http://{}/", daemon.http), 1280, 800);
    let read = "new Promise((ok, fail) => { const t0 = performance.now(); const t = () => {
         const box = document.getElementById('import');
         if (box && !box.hidden) {
           const lines = [...document.querySelectorAll('#import-list div')];
           ok({ open: box.open, summary: document.getElementById('import-summary').textContent,
             lines: lines.map(d => ({ cls: d.className, text: d.textContent, shown: d.checkVisibility() })) });
         } else if (performance.now() - t0 > 60000) fail(new Error('the import section never showed'));
         else setTimeout(t, 50); }; t(); })";
    let folded = browser.eval(read);
    assert_eq!(folded["open"], false, "folded at first: {folded}");
    let summary = folded["summary"].as_str().unwrap();
    assert!(summary.starts_with(&format!("import warnings: {warnings} · {types} fixture types")), "{summary}");
    let lines = folded["lines"].as_array().unwrap();
    assert_eq!(lines.len(), types + warnings, "{folded}");
    assert!(lines.iter().all(|l| l["shown"] == false), "hidden while folded: {folded}");
    let missing = lines.iter().find(|l| l["text"].as_str().unwrap().contains("Footlight@Missing.gdtf")).unwrap();
    assert_eq!(missing["cls"], "not", "{missing}");
    assert!(missing["text"].as_str().unwrap().contains("(2 fixtures): not modelled — "), "{missing}");
    browser.eval("document.getElementById('import-summary').click()");
    let open = browser.eval(read);
    assert_eq!(open["open"], true);
    assert!(open["lines"].as_array().unwrap().iter().all(|l| l["shown"] == true), "{open}");
}
