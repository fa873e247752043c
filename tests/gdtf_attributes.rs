//! The attributes real GDTF files use, through the binary (issue 36 items 2
//! and 5): `footlight check` on `tests/data/mvr/colour.mvr` (an RGBW bar
//! without a dimmer in RGBW, HSB, CIE, mixed and CCT modes, a blinder with
//! master and cell dimmers, a spot with mode-mastered gobo rotation, second
//! gobo and animation wheels) lists no attribute as not modelled, and a
//! render of the rig shows the dimmer-less bar dark at RGB 0 and lit red at
//! red full. Values and peers: crates/footlight-mvr/tests/cases/attributes.rs.

use crate::common::*;
use std::process::Command;

const COLOUR: &str = "tests/data/mvr/colour.mvr";

fn footlight() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_footlight"));
    c.current_dir(root());
    c
}

#[test]
fn check_lists_none_of_the_attributes_as_not_modelled() {
    let o = footlight().args(["check", COLOUR]).output().unwrap();
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "{text}");
    assert!(!text.contains("not modelled"), "{text}");
    for t in ["ColourBar", "Cluster4", "ViperSpot"] {
        assert!(text.lines().any(|l| l.contains(t) && l.trim_end().ends_with("modelled")), "{t}: {text}");
    }
}

/// Renders the rig (160×100, no photons) with `sets` on universe 1; the picture as 8-bit RGB.
fn render(name: &str, sets: &[(u16, u8)]) -> Vec<[u8; 3]> {
    let dir = std::env::temp_dir().join(format!("footlight-test-{}-attrs", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join(format!("{name}.png"));
    let set: Vec<String> = sets.iter().map(|(a, v)| format!("1/{a}={v}")).collect();
    let o = footlight()
        .args(["render", "--patch", COLOUR, "--width", "160", "--height", "100", "--photons", "0", "--force"])
        .args(["--set", &set.join(",")])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    image::open(&out).unwrap().to_rgb8().pixels().map(|p| p.0).collect()
}

#[test]
fn a_dimmer_less_bar_renders_dark_at_rgb_0_and_red_at_red_full() {
    // Every other fixture at its power-up dark: the HSB and CIE bars' brightness to 0
    // (their power-up is full white); the others start dark (master dimmers at 0, RGB 0).
    let mut dark: Vec<(u16, u8)> = (0..4).map(|k| (134 + 4 * k, 0)).collect();
    dark.extend((0..4).map(|k| (155 + 5 * k, 0)));
    let px = render("dark", &dark);
    let brightest = px.iter().map(|p| *p.iter().max().unwrap()).max().unwrap();
    assert!(brightest <= 1, "the rig at RGB 0 lights the stage: {brightest}");
    // The RGBW bar (1/31, four cells of R, G, B, W) with red at full.
    let mut red = dark.clone();
    red.extend((0..4).map(|k| (31 + 4 * k, 255)));
    let px = render("red", &red);
    let lit: Vec<&[u8; 3]> = px.iter().filter(|p| p[0] > 20).collect();
    assert!(lit.len() > 50, "the bar lights the floor: {} pixels", lit.len());
    assert!(lit.iter().all(|p| p[0] >= p[1] && p[0] >= p[2]), "red light");
}
