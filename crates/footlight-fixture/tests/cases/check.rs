//! `check` reports every problem with its file, line and what to do.

use super::{data, root, temp_dir};
use footlight_fixture::{Patch, check_text};
use std::path::Path;

fn header() -> String {
    format!("fixtures = \"{0}/patch/fixtures\"\ngels = \"{0}/patch/gels.toml\"\n", root().display())
}

/// Checks `body` after the two header lines; returns "line: message" per error.
fn problems(body: &str) -> Vec<(usize, String)> {
    let text = format!("{}{body}", header());
    match check_text(Path::new("/x/show.toml"), &text) {
        Ok(_) => Vec::new(),
        Err(errors) => errors
            .into_iter()
            .map(|e| {
                assert_eq!(e.path, Path::new("/x/show.toml"), "{e}");
                (e.line, e.message)
            })
            .collect(),
    }
}

fn has(errors: &[(usize, String)], line: usize, text: &str) -> bool {
    errors.iter().any(|(l, m)| *l == line && m.contains(text))
}

/// Line (in the checked text, after the two header lines) of the `n`-th line of `body` containing `needle`.
fn line(body: &str, needle: &str, n: usize) -> usize {
    let hits: Vec<usize> = body.lines().enumerate().filter(|(_, l)| l.contains(needle)).map(|(i, _)| i + 3).collect();
    *hits.get(n).unwrap_or_else(|| panic!("{needle:?} #{n} not in the test patch"))
}

const GOOD: &str = r#"[[fixture]]
id = 1
type = "generic-moving-spot"
mode = "standard"
universe = 1
address = 1
position = [0, 7, 0]
"#;

#[test]
fn a_good_patch_has_no_problems() {
    assert!(problems(GOOD).is_empty(), "{:?}", problems(GOOD));
}

#[test]
fn each_kind_of_error_on_its_line() {
    // Lines count from 1 including the two header lines.
    let body = r#"[[fixture]]
id = 1
type = "no-such-lamp"
position = [0, 7, 0]

[[fixture]]
id = 2
type = "generic-moving-spot"
mode = "wild"
universe = 1
address = 1
position = [0, 7, 0]

[[fixture]]
id = 3
type = "generic-moving-spot"
mode = "standard"
universe = 1
address = 1
position = [0, 7, 0]

[[fixture]]
id = 4
type = "generic-moving-spot"
mode = "standard"
universe = 1
address = 10
position = [0, 7, 0]

[[fixture]]
id = 5
type = "generic-moving-spot"
mode = "basic"
universe = 2
address = 510
position = [0, 7, 0]

[[fixture]]
id = 6
type = "strand-castor"
mode = "1ch"
universe = 0
address = 600
position = [0, 5, 5]
aim = [0, 0, 0]

[[fixture]]
id = 7
type = "strand-castor"
mode = "1ch"
position = [0, 5, 5]
aim = [0, 0, 0]
gel = "L999"
focus = 1.5

[[fixture]]
id = 8
type = "niethammer-hpz-115-d"
position = [0, 5, 5]
aim = [0, 0, 0]
zoom = 70

[look]
3 = { dimmer = 70000 }
4 = { gobo = 3 }
9 = { dimmer = 1 }
"2/1" = 300
"#;
    let e = problems(body);
    let show = format!("{e:#?}");
    assert!(has(&e, line(body, "no-such-lamp", 0), "unknown fixture type \"no-such-lamp\""), "unknown type: {show}");
    assert!(has(&e, line(body, "no-such-lamp", 0), "generic-moving-spot"), "lists the known types: {show}");
    assert!(
        has(&e, line(body, "\"wild\"", 0), "has no mode \"wild\"")
            && has(&e, line(body, "\"wild\"", 0), "\"standard\""),
        "unknown mode: {show}"
    );
    assert!(
        has(&e, line(body, "address = 10", 0), "overlap fixture 3")
            && has(&e, line(body, "address = 10", 0), "first free address with 13 slots in universe 1 is 14"),
        "overlap: {show}"
    );
    assert!(
        has(&e, line(body, "address = 510", 0), "run past slot 512")
            && has(&e, line(body, "address = 510", 0), "last address that fits is 509"),
        "footprint: {show}"
    );
    assert!(has(&e, line(body, "universe = 0", 0), "universe 0 must be in 1..63999"), "universe: {show}");
    assert!(has(&e, line(body, "address = 600", 0), "address 600 must be in 1..512"), "address: {show}");
    assert!(has(&e, line(body, "L999", 0), "unknown gel \"L999\""), "gel: {show}");
    assert!(has(&e, line(body, "focus = 1.5", 0), "focus 1.5 must be in 0..1"), "manual focus: {show}");
    assert!(has(&e, line(body, "zoom = 70", 0), "zoom 70 must be in 15..40"), "manual zoom: {show}");
    assert!(has(&e, line(body, "70000", 0), "dimmer 70000 must be in 0..65535"), "look value: {show}");
    assert!(has(&e, line(body, "gobo", 0), "has no gobo channel"), "look attribute: {show}");
    assert!(has(&e, line(body, "9 = {", 0), "no fixture with that id"), "look id: {show}");
    assert!(has(&e, line(body, "\"2/1\"", 0), "DMX value 0..255"), "look slot: {show}");
    // The first error is what Patch::parse reports.
    let err = Patch::parse(Path::new("/x/show.toml"), &format!("{}{body}", header())).unwrap_err();
    assert!(err.to_string().starts_with(&format!("/x/show.toml:{}:", line(body, "no-such-lamp", 0))), "{err}");
}

#[test]
fn more_errors_on_their_lines() {
    let body = r#"[[fixture]]
id = 1
type = "strand-castor"
mode = "scroller"
universe = 1
address = 1
position = [0, 5, 5]
aim = [0, 0, 0]
gel = "L201"
frames = ["open", "L777"]

[[fixture]]
id = 1
type = "generic-pc"
position = [0, 5, 5]
aim = [0, 0, 0]
intensity = 5

[[fixture]]
id = 3
type = "generic-led-par-rgbw"
universe = 1
address = 20
position = [0, 5, 5]
aim = [0, 0, 0]

[[input]]
protocol = "sacn"
universe = 0
patch_universe = 1

[[input]]
protocol = "dmx512"
universe = 1
patch_universe = 1
"#;
    let e = problems(body);
    let show = format!("{e:#?}");
    assert!(has(&e, line(body, "gel = \"L201\"", 0), "either a fixed gel or the scroller"), "{show}");
    assert!(has(&e, line(body, "L777", 0), "unknown gel \"L777\" in frames"), "{show}");
    // Both point at the key itself, not the [[fixture]] header (issue 12 item 10).
    assert!(has(&e, line(body, "id = 1", 1), "id already used on line 3"), "{show}");
    assert!(has(&e, line(body, "intensity = 5", 0), "remove intensity"), "{show}");
    assert!(
        has(&e, line(body, "generic-led-par-rgbw", 0), "several modes")
            && has(&e, line(body, "generic-led-par-rgbw", 0), "\"4ch\""),
        "{show}"
    );
    assert!(has(&e, line(body, "universe = 0", 0), "sACN universe 0 must be in 1..63999"), "{show}");
    assert!(has(&e, line(body, "dmx512", 0), "unknown input protocol"), "{show}");
}

#[test]
fn a_broken_fixture_type_names_its_file_and_line() {
    let text = format!(
        "fixtures = \"{}\"\n[[fixture]]\nid = 1\ntype = \"broken\"\nposition = [0, 5, 0]\naim = [0, 0, 0]\n",
        data().join("fixtures").display()
    );
    let errors = check_text(Path::new("/x/p.toml"), &text).unwrap_err();
    let type_file = data().join("fixtures/broken.toml");
    assert_eq!(errors[0].path, type_file, "{errors:?}");
    assert_eq!(errors[0].line, 10, "{errors:?}");
    assert!(errors[0].message.contains("intensity -5 cd must be > 0"), "{errors:?}");
    assert_eq!((errors[1].path.as_path(), errors[1].line), (Path::new("/x/p.toml"), 4), "{errors:?}");
    // A TOML syntax error in a type file, and an unknown key, with their lines.
    let d = temp_dir("types");
    std::fs::write(d.join("typo.toml"), "name = \"x\"\n[lamp]\nkind = \"tungsten\"\ncolour = 3\n").unwrap();
    let text = format!(
        "fixtures = \"{}\"\n[[fixture]]\nid = 1\ntype = \"typo\"\nposition = [0, 5, 0]\naim = [0, 0, 0]\n",
        d.display()
    );
    let errors = check_text(Path::new("/x/p.toml"), &text).unwrap_err();
    assert_eq!((errors[0].path.clone(), errors[0].line), (d.join("typo.toml"), 4), "{errors:?}");
    assert!(errors[0].message.contains("colour"), "{errors:?}");
}

#[test]
fn check_reads_files_and_reports_unreadable_ones() {
    let e = footlight_fixture::check(Path::new("/no/such/patch.toml")).unwrap_err();
    assert!(e[0].to_string().starts_with("/no/such/patch.toml:0: cannot read"), "{e:?}");
    assert!(footlight_fixture::check(&root().join("patch/paper-rig.toml")).is_ok());
    assert!(footlight_fixture::check(&root().join("patch/default.toml")).is_ok());
}

#[test]
fn the_format_docs_example_patch_is_valid() {
    let doc = std::fs::read_to_string(root().join("docs/patch-format.md")).unwrap();
    let example = doc.split("## Example").nth(1).expect("an Example section");
    let toml = example.split("```toml").nth(1).and_then(|s| s.split("```").next()).expect("a toml block");
    let patch = Patch::parse(&root().join("patch/doc-example.toml"), toml).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(patch.fixtures.len(), 2);
    let head = &patch.fixtures[1];
    assert!(head.look.v == 1.0 && head.look.tilt > 0.0);
    assert!(head.light.axis().z < 0.0, "positive tilt swings a hanging head upstage");
}
