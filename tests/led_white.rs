//! LED rigs without GDTF emitters, through the binary (issue 36 items 1
//! and 7): `tests/data/mvr/led-bars.mvr` (two 16-cell RGBW pixel bars and
//! an RGB + amber + warm-white can, colours only in the attribute
//! definitions) renders white at full RGBW under the default
//! `--white-balance auto`, `check` says the colour source once per type,
//! a tungsten rig renders exactly as with the old 3200 K default, and the
//! live daemon shows and changes the white balance over `/api/display`.

use crate::common::*;
use std::path::{Path, PathBuf};
use std::process::Command;

const LED_BARS: &str = "tests/data/mvr/led-bars.mvr";

fn footlight() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_footlight"));
    c.current_dir(root());
    c
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("footlight-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `--set` for both bars' dimmer and every cell's R, G, B, W at full
/// (65 channels at 1/1 and 1/101); the can (1/201) stays dark.
fn bars_at_full() -> String {
    (1..=65).chain(101..=165).map(|a| format!("1/{a}=255")).collect::<Vec<_>>().join(",")
}

/// Renders the LED rig with `extra` arguments (white at 3000 lx: the pools
/// do not clip); the picture as linear RGB.
fn render(dir: &Path, name: &str, extra: &[&str]) -> Vec<[f64; 3]> {
    let out = dir.join(format!("{name}.png"));
    let o = footlight()
        .args(["render", "--patch", LED_BARS, "--width", "320", "--height", "200", "--photons", "0"])
        .args(["--white-lux", "3000"])
        .args(["--set", &bars_at_full()])
        .args(extra)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let decode = |c: u8| {
        let c = f64::from(c) / 255.0;
        if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
    };
    image::open(&out).unwrap().to_rgb8().pixels().map(|p| p.0.map(decode)).collect()
}

/// Median b/r and g/r over the lit, unclipped pixels (some channel above
/// 5 % of white, none at 255), and how many there were.
fn ratios(px: &[[f64; 3]]) -> (f64, f64, usize) {
    let lit: Vec<&[f64; 3]> =
        px.iter().filter(|p| p.iter().any(|&c| c > 0.05) && p.iter().all(|&c| c < 0.999)).collect();
    let median = |f: &dyn Fn(&[f64; 3]) -> f64| {
        let mut v: Vec<f64> = lit.iter().map(|p| f(p)).filter(|x| x.is_finite()).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    (median(&|p| p[2] / p[0]), median(&|p| p[1] / p[0]), lit.len())
}

#[test]
fn an_led_rig_without_emitters_renders_white_at_full_under_auto_white_balance() {
    let dir = temp_dir("led-white");
    let (b_r, g_r, n) = ratios(&render(&dir, "auto", &[]));
    eprintln!("auto: median b/r {b_r:.3}, g/r {g_r:.3} over {n} lit pixels");
    assert!(n > 400, "the bars light the floor: {n} pixels");
    assert!((0.8..=1.25).contains(&b_r) && (0.8..=1.25).contains(&g_r), "b/r {b_r}, g/r {g_r}: not white");
    // The old default (tungsten 3200 K neutral) shows the same light blue.
    let (tb_r, tg_r, _) = ratios(&render(&dir, "tungsten", &["--white-balance", "tungsten"]));
    eprintln!("tungsten: median b/r {tb_r:.3}, g/r {tg_r:.3}");
    assert!(tb_r > 1.5 && tb_r > b_r * 1.4, "under a tungsten balance full RGBW is blue: b/r {tb_r}");
}

#[test]
fn check_says_the_colour_source_once_per_type_not_per_cell() {
    let o = footlight().args(["check", LED_BARS]).output().unwrap();
    let (out, err) = (String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "{err}");
    let warned = |t: &str| err.lines().filter(|l| l.starts_with("warning:") && l.contains(t)).count();
    assert_eq!(
        warned("PixelBar16: no emitters; ColorAdd_R/G/B/W mixed from the attribute definitions' colours"),
        1,
        "{err}"
    );
    assert_eq!(
        warned("LedRyWw: no emitters; ColorAdd_R/G/B mixed from the attribute definitions' colours"),
        1,
        "{err}"
    );
    assert!(!err.contains("decoded but not mixed") && !err.contains("Pixel7"), "nothing per cell or channel: {err}");
    assert!(out.contains("3 fixtures (33 lights: cells counted)"), "{out}");
}

/// A tungsten rig under `auto` is the old 3200 K picture, byte for byte
/// (the goldens of tests/golden.rs use `Display::default()`, 3200 K, too).
#[test]
fn auto_white_balance_leaves_a_tungsten_rig_as_it_was() {
    let dir = temp_dir("tungsten-auto");
    let size = ["--width", "64", "--height", "40", "--photons", "0"];
    let mut pictures = Vec::new();
    for (name, wb) in [("auto", None), ("tungsten", Some("tungsten"))] {
        let out = dir.join(format!("{name}.png"));
        let mut c = footlight();
        c.arg("render").args(size).args(["--patch", footlight::PAPER_PATCH]);
        if let Some(wb) = wb {
            c.args(["--white-balance", wb]);
        }
        let o = c.arg("--out").arg(&out).output().unwrap();
        let log = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{log}");
        if wb.is_none() {
            assert!(log.contains("white balance auto: 3200 K: the rig's 2 tungsten lamps at full"), "{log}");
        }
        pictures.push(std::fs::read(&out).unwrap());
    }
    assert_eq!(pictures[0], pictures[1], "auto == tungsten on the paper rig");
}

/// `footlight run` starts with the rig's white (`auto`), `/api/display`
/// shows it, and `POST /api/display` switches to tungsten and back.
#[test]
fn the_live_display_shows_and_changes_the_white_balance() {
    use std::io::BufRead;
    let mut child = footlight()
        .args(["run", "--artnet", "off", "--sacn", "off", "--http", "127.0.0.1:0", "--patch", LED_BARS])
        .args(["--width", "48", "--height", "30", "--photons", "0", "--compositor", "cpu"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Read stdout to the end on a thread: a closed pipe would fail the daemon's prints.
    let stdout = child.stdout.take().unwrap();
    let (lines_tx, lines) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = lines_tx.send(line);
        }
    });
    let http = loop {
        let line = lines.recv_timeout(std::time::Duration::from_secs(120)).expect("the preview address");
        if let Some(url) = line.strip_prefix("Footlight preview: http://") {
            break url.trim_end_matches('/').parse::<std::net::SocketAddr>().unwrap();
        }
    };
    let display = || -> serde_json::Value { serde_json::from_slice(&http_get(http, "/api/display").1).unwrap() };
    let gains = |d: &serde_json::Value| -> Vec<f64> {
        d["white_balance"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect()
    };
    let d = display();
    assert_eq!(d["white_balance_setting"], "auto", "{d}");
    let rig = &d["rig_white"];
    assert_eq!((rig["tungsten"].as_bool(), rig["lights"].as_u64()), (Some(false), Some(33)), "{d}");
    let cct = rig["cct_k"].as_f64().unwrap();
    assert!((5000.0..7500.0).contains(&cct), "an LED white: {cct} K");
    let auto = gains(&d);
    let tungsten = footlight_photometry::WhiteBalance::default().gains.to_array().map(f64::from).to_vec();
    assert!(auto[2] < tungsten[2] * 0.8, "a daylight white cuts blue far less than tungsten: {auto:?}");
    let settle = |want: &[f64]| {
        let t = std::time::Instant::now();
        loop {
            let d = display();
            if gains(&d).iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-6) {
                return d;
            }
            assert!(t.elapsed() < std::time::Duration::from_secs(30), "never applied: {d}");
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
    };
    assert_eq!(crate::views::http_post(http, "/api/display", r#"{"white_balance": "tungsten"}"#, None), 200);
    let d = settle(&tungsten);
    assert_eq!(d["white_balance_setting"], "tungsten", "{d}");
    assert_eq!(crate::views::http_post(http, "/api/display", r#"{"white_balance": "auto"}"#, None), 200);
    let d = settle(&auto);
    assert_eq!(d["white_balance_setting"], "auto", "{d}");
    assert!(d["white_balance_note"].as_str().unwrap().contains("luminous-flux-weighted white of 33 lights"), "{d}");
    assert_eq!(crate::views::http_post(http, "/api/display", r#"{"white_balance": "blue"}"#, None), 400);
    let stopped = Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap();
    assert!(stopped.success());
    let status = child.wait().unwrap();
    assert!(status.success(), "{status}");
}
