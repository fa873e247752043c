//! The attributes real GDTF files use, and intensity and mode logic as the
//! file means them (issue 36 items 2 and 5), on `tests/data/mvr/colour.mvr`
//! (written by `tools/gen_gdtf_mvr.py`: a 4-cell RGBW bar without a dimmer
//! in five modes, a 4-cell blinder with master and cell dimmers, a
//! discharge spot with mode-mastered gobo rotation).
//!
//! Each attribute is checked twice: the channel functions (DMX ranges,
//! physical ranges, mode masters, channel sets, wheel slot colours) against
//! pygdtf 1.4.5's reading (`peers/functions.py`; skipped when pygdtf is
//! missing), and the decoded state and k_i against a computation written
//! here: HSV → RGB by the hexcone formula, sRGB → XYZ by IEC 61966-2-1's
//! matrix, the Planckian locus by Kim et al.'s cubic spline, Duv in CIE 1960
//! (u, v), the correction filter's transmittance by Planck's law and Wyman
//! et al.'s analytic ȳ, the emitters' mix from their xyY in the file.

use super::{gdtf, mvr, root};
use footlight_fixture::beam::Beam;
use footlight_fixture::fixture_type::{Action, Attribute, WheelSlot};
use footlight_fixture::{Fixture, FixtureModel, FixtureState, Patch, Universes};
use footlight_mvr::gdtf::Gdtf;
use footlight_mvr::{fixture_type, load_mvr};
use glam::Vec3;
use serde_json::Value;
use std::process::Command;

const TYPES: [&str; 3] = ["ColourBar", "Cluster4", "ViperSpot"];

// --- Independent colour computations -----------------------------------------

/// IEC 61966-2-1 linear sRGB → XYZ (rows).
const RGB_TO_XYZ: [[f64; 3]; 3] = [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]];

fn mul(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|r| m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2])
}

fn xy_of_xyz(v: [f64; 3]) -> [f64; 2] {
    let s = v[0] + v[1] + v[2];
    [v[0] / s, v[1] / s]
}

fn xyz_of_xyy(x: f64, y: f64, big_y: f64) -> [f64; 3] {
    [x / y * big_y, big_y, (1.0 - x - y) / y * big_y]
}

/// Chromaticity of a light's k_i (linear sRGB).
fn xy_of_k(k: Vec3) -> [f64; 2] {
    xy_of_xyz(mul(&RGB_TO_XYZ, [f64::from(k.x), f64::from(k.y), f64::from(k.z)]))
}

/// Luminance of a light's k_i.
fn y_of_k(k: Vec3) -> f64 {
    mul(&RGB_TO_XYZ, [f64::from(k.x), f64::from(k.y), f64::from(k.z)])[1]
}

/// HSV → RGB, the hexcone formula (Smith 1978).
fn hsv(h: f64, s: f64, v: f64) -> [f64; 3] {
    let h6 = (h.rem_euclid(360.0)) / 60.0;
    let i = h6.floor();
    let f = h6 - i;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    match i as i32 {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    }
}

/// Planckian locus by Kim et al.'s cubic spline (1667-25,000 K).
fn kim_xy(t: f64) -> [f64; 2] {
    let x = if t <= 4000.0 {
        -0.2661239e9 / t.powi(3) - 0.2343589e6 / t.powi(2) + 0.8776956e3 / t + 0.179910
    } else {
        -3.0258469e9 / t.powi(3) + 2.1070379e6 / t.powi(2) + 0.2226347e3 / t + 0.240390
    };
    let y = if t <= 2222.0 {
        -1.1063814 * x.powi(3) - 1.34811020 * x.powi(2) + 2.18555832 * x - 0.20219683
    } else if t <= 4000.0 {
        -0.9549476 * x.powi(3) - 1.37418593 * x.powi(2) + 2.09137015 * x - 0.16748867
    } else {
        3.0817580 * x.powi(3) - 5.87338670 * x.powi(2) + 3.75112997 * x - 0.37001483
    };
    [x, y]
}

/// CIE 1960 (u, v).
fn uv(xy: [f64; 2]) -> [f64; 2] {
    let d = -2.0 * xy[0] + 12.0 * xy[1] + 3.0;
    [4.0 * xy[0] / d, 6.0 * xy[1] / d]
}

fn xy_of_uv(uv: [f64; 2]) -> [f64; 2] {
    let d = 2.0 * uv[0] - 8.0 * uv[1] + 4.0;
    [3.0 * uv[0] / d, 2.0 * uv[1] / d]
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Luminous transmittance of the ideal filter turning a blackbody at
/// `from` K into one at `to` K, peak 1 over 380-780 nm: Planck's law and
/// Wyman, Sloan and Shirley's (2013) two-lobe ȳ.
fn correction_tau(from: f64, to: f64) -> f64 {
    let planck = |nm: f64, t: f64| {
        let l = nm * 1e-9;
        l.powi(-5) / ((1.4388e-2 / (l * t)).exp() - 1.0)
    };
    let g = |x: f64, mu: f64, s1: f64, s2: f64| {
        let s = if x < mu { s1 } else { s2 };
        (-0.5 * ((x - mu) / s).powi(2)).exp()
    };
    let ybar = |nm: f64| 0.821 * g(nm, 568.8, 46.9, 40.5) + 0.286 * g(nm, 530.9, 16.3, 31.1);
    let ratio = |nm: f64| planck(nm, to) / planck(nm, from);
    let peak = ratio(380.0).max(ratio(780.0));
    let (mut a, mut b) = (0.0, 0.0);
    for nm in (360..=830).map(f64::from) {
        a += planck(nm, to) * ybar(nm);
        b += planck(nm, from) * ybar(nm);
    }
    a / (peak * b)
}

/// The emitters of the bar and the cluster as the file gives them
/// (`EMITTERS` in tools/gen_gdtf_mvr.py: CIE x, y and Y, the luminous share).
const EMITTERS: [(f64, f64, f64); 4] =
    [(0.7, 0.299, 20.0), (0.17, 0.7, 60.0), (0.14, 0.04, 8.0), (0.3127, 0.329, 100.0)];

/// XYZ of the emitters at `levels` (each emitter's XYZ at its share).
fn mix_xyz(levels: [f64; 4]) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (l, (x, y, share)) in levels.iter().zip(EMITTERS) {
        let e = xyz_of_xyy(x, y, share);
        (0..3).for_each(|i| out[i] += l * e[i]);
    }
    out
}

// --- The rig -------------------------------------------------------------------

fn rig() -> Patch {
    let import = load_mvr(&mvr("colour")).unwrap();
    import.patch
}

/// The lights of fixture `name` (its cells in order, or the one light).
fn lights<'a>(p: &'a Patch, name: &str) -> Vec<&'a Fixture> {
    p.fixtures.iter().filter(|f| f.name == name || f.name.starts_with(&format!("{name} / "))).collect()
}

/// The rig's power-up frame with `sets` (universe 1 address, value) on top.
fn frame(p: &Patch, sets: &[(u16, u8)]) -> Universes {
    let mut u = p.look_universes.clone();
    for &(a, v) in sets {
        u.set_slot(1, a, v);
    }
    u
}

fn decode(f: &Fixture, u: &Universes) -> (FixtureState, Vec3) {
    let s = f.decode_universes(u);
    (s, f.k_of(&s))
}

fn typed(f: &Fixture) -> &footlight_fixture::fixture_type::FixtureType {
    match &f.model {
        FixtureModel::Typed(t) => &t.fixture_type,
        FixtureModel::Builtin(_) => panic!("{} is not typed", f.name),
    }
}

// Addresses in colour.mvr (COLOUR_RIG in the generator).
const MIXED: u16 = 1; // MixBar 1-7, cell k at 8 + 4k: R/Hue, G/Sat, B/Bright, W
const RGBW: u16 = 31; // cell k at 31 + 4k: R, G, B, W
const CCT: u16 = 51; // dimmer, CTC (16-bit), Green/Magenta
const CLUSTER: u16 = 61; // master, curve, dimmer mode, shutter, duration, strobe mode, tint; cell k at 68 + 5k
const VIPER: u16 = 101;
const HSB: u16 = 131; // cell k at 131 + 4k: hue (16-bit), saturation, brightness
const CIE: u16 = 151; // cell k at 151 + 5k: x (16-bit), y (16-bit), brightness

/// The Mixed bar's CTC at the bar's own 6500 K (2700-8000 K over 16 bits) and no tint.
fn neutral_mixed() -> Vec<(u16, u8)> {
    let raw = ((6500.0 - 2700.0) / 5300.0 * 65535.0_f64).round() as u16;
    vec![(MIXED + 4, (raw >> 8) as u8), (MIXED + 5, raw as u8), (MIXED + 6, 128)]
}

// --- pygdtf ----------------------------------------------------------------------

fn peer() -> Option<Value> {
    match Command::new("python3").args(["-c", "import pygdtf"]).output() {
        Ok(o) if o.status.success() => {}
        _ => {
            assert!(
                std::env::var_os("FOOTLIGHT_REQUIRE_PEERS").is_none(),
                "FOOTLIGHT_REQUIRE_PEERS is set but python3 cannot import pygdtf"
            );
            eprintln!("skipped: python3 with pygdtf is missing (.ci/run installs it with pip)");
            return None;
        }
    }
    let script = root().join("crates/footlight-mvr/tests/peers/functions.py");
    let paths: Vec<_> = TYPES.iter().map(|t| gdtf(t)).collect();
    let out = Command::new("timeout").arg("120").arg("python3").arg(script).args(&paths).output().expect("python3");
    assert!(out.status.success(), "functions.py failed:\n{}", String::from_utf8_lossy(&out.stderr));
    let v: Value = serde_json::from_slice(&out.stdout).expect("JSON");
    Some(Value::Object(
        TYPES.iter().zip(&paths).map(|(t, p)| (t.to_string(), v[p.to_str().unwrap()].clone())).collect(),
    ))
}

/// A raw DMX value written with `bytes` bytes at `want` bytes (GDTF's
/// non-shifting rule: 255/1 is 65535/2; a wider value keeps its top bytes).
fn rescale(v: u64, bytes: u64, want: u64) -> u64 {
    let max = |b: u64| (1u64 << (8 * b)) - 1;
    if bytes == want {
        v
    } else if bytes > want {
        v >> (8 * (bytes - want))
    } else {
        v * max(want) / max(bytes)
    }
}

fn pair(v: &Value) -> (u64, u64) {
    (v[0].as_u64().unwrap(), v[1].as_u64().unwrap())
}

/// What Footlight makes of each GDTF attribute of these files (docs/mvr-gdtf.md, "Attributes").
fn expected_attribute(a: &str) -> Option<Attribute> {
    Some(match a {
        "Dimmer" => Attribute::Dimmer,
        "ColorAdd_R" => Attribute::Mix(0),
        "ColorAdd_G" => Attribute::Mix(1),
        "ColorAdd_B" => Attribute::Mix(2),
        "ColorAdd_W" => Attribute::Mix(3),
        "HSB_Hue" => Attribute::Hue,
        "HSB_Saturation" => Attribute::Saturation,
        "HSB_Brightness" => Attribute::HsbBrightness,
        "CIE_X" => Attribute::CieX,
        "CIE_Y" => Attribute::CieY,
        "CIE_Brightness" => Attribute::CieBrightness,
        "ColorMixMode" | "LEDZoneMode" | "StrobeMode" => Attribute::Mode,
        "ColorMacro1" => Attribute::ColourMacro,
        "Color1" => Attribute::ColourWheel,
        "Color2" => Attribute::ColourWheelN(0),
        "CTC" | "CTO" => Attribute::Cto,
        "Green/Magenta" | "Tint" => Attribute::Tint,
        "DimmerCurve" | "DimmerMode" => Attribute::DimmerCurve,
        "StrobeDuration" => Attribute::StrobeDuration,
        "Shutter1" => Attribute::Shutter,
        "Gobo1" => Attribute::Gobo,
        "Gobo2" => Attribute::Gobo2,
        "AnimationWheel1" => Attribute::Animation,
        "Prism1" => Attribute::Prism,
        "Gobo1Pos" | "AnimationWheel1Pos" | "Prism1PosRotate" | "Frost1" => Attribute::Gate,
        "Pan" => Attribute::Pan,
        "Tilt" => Attribute::Tilt,
        "Zoom" => Attribute::Zoom,
        "Focus1" => Attribute::Focus,
        "ColorSub_C" => Attribute::Mix(0),
        "ColorSub_M" => Attribute::Mix(1),
        "ColorSub_Y" => Attribute::Mix(2),
        _ => return None,
    })
}

#[test]
fn channel_functions_and_mode_masters_agree_with_pygdtf() {
    let Some(peer) = peer() else { return };
    for t in TYPES {
        let theirs = &peer[t];
        let g = Gdtf::open(&gdtf(t)).unwrap();
        let (ty, warnings) = fixture_type(&g).unwrap();
        // Every attribute of these files is modelled: no "not modelled" warning.
        assert!(!warnings.iter().any(|w| w.message.contains("not modelled")), "{t}: {warnings:?}");
        for (mode, chans) in theirs["modes"].as_object().unwrap() {
            let layout = g.layout(mode).unwrap();
            let md = &ty.modes[ty.mode(mode).unwrap()];
            let chans = chans.as_array().unwrap();
            for pc in chans {
                let offsets: Vec<u64> = pc["offsets"].as_array().unwrap().iter().map(|o| o.as_u64().unwrap()).collect();
                let bytes = offsets.len() as u64;
                let ours = layout
                    .channels
                    .iter()
                    .find(|c| c.offsets.iter().map(|&o| u64::from(o)).collect::<Vec<_>>() == offsets)
                    .unwrap_or_else(|| panic!("{t} {mode}: no channel at {offsets:?}"));
                let at = format!("{t} {mode} {} {offsets:?}", pc["name"]);
                let pf = pc["functions"].as_array().unwrap();
                assert_eq!(ours.functions.len(), pf.len(), "{at}: functions");
                for (f, p) in ours.functions.iter().zip(pf) {
                    assert_eq!(f.attribute, p["attribute"].as_str().unwrap(), "{at}");
                    let (from, fb) = pair(&p["dmx_from"]);
                    let (to, tb) = pair(&p["dmx_to"]);
                    assert_eq!(f.dmx_from, rescale(from, fb, bytes), "{at} {}: DMX from", f.attribute);
                    assert_eq!(
                        f.dmx_to,
                        rescale(to, tb, bytes),
                        "{at} {}: DMX to (within its mode master)",
                        f.attribute
                    );
                    assert_eq!(
                        [f.physical_from, f.physical_to],
                        [p["physical"][0].as_f64().unwrap(), p["physical"][1].as_f64().unwrap()],
                        "{at}"
                    );
                    assert_eq!(f.wheel.as_deref().unwrap_or("None"), p["wheel"].as_str().unwrap(), "{at}");
                    let sets: Vec<(String, u64, i32)> =
                        f.sets.iter().map(|s| (s.name.clone(), s.dmx_from, s.wheel_slot.unwrap_or(0))).collect();
                    let psets: Vec<(String, u64, i32)> = p["sets"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|s| {
                            (
                                s[0].as_str().unwrap().to_string(),
                                rescale(s[1].as_u64().unwrap(), s[2].as_u64().unwrap(), bytes),
                                s[3].as_i64().unwrap() as i32,
                            )
                        })
                        .collect();
                    assert_eq!(sets, psets, "{at}: channel sets");
                    // Mode master: its name, and its range at the master's resolution.
                    let master = p["mode_master"].as_str().unwrap();
                    match &f.mode_master {
                        None => assert_eq!(master, "None", "{at}"),
                        Some((name, mf, mt)) => {
                            assert_eq!(name, master, "{at}");
                            let m = chans.iter().find(|c| c["name"] == master).expect("the master channel");
                            let mbytes = m["offsets"].as_array().unwrap().len() as u64;
                            let (a, ab) = pair(&p["mode_from"]);
                            let (b, bb) = pair(&p["mode_to"]);
                            assert_eq!(
                                (*mf, *mt),
                                (rescale(a, ab, mbytes), rescale(b, bb, mbytes)),
                                "{at}: mode range"
                            );
                        }
                    }
                }
                // Footlight's channel: its attribute, and a mode gate on the master's slot for each gated function.
                let base = (pc["break"].as_u64().unwrap() - 1) * 512;
                let offset = (base + offsets[0] - 1) as u16;
                let ch = md
                    .channels
                    .iter()
                    .find(|c| c.offset == offset)
                    .unwrap_or_else(|| panic!("{at}: no Footlight channel"));
                let attr = pf[0]["attribute"].as_str().unwrap();
                assert_eq!(Some(ch.attribute), expected_attribute(attr), "{at}");
                for p in pf.iter().filter(|p| p["mode_master"] != "None") {
                    let m = chans.iter().find(|c| c["name"] == p["mode_master"]).unwrap();
                    let mo = m["offsets"][0].as_u64().unwrap() - 1 + (m["break"].as_u64().unwrap() - 1) * 512;
                    let (a, ab) = pair(&p["mode_from"]);
                    let (from, fb) = pair(&p["dmx_from"]);
                    let gated: Vec<_> = ch
                        .functions
                        .iter()
                        .filter(|f| f.mode.is_some_and(|g| u64::from(g.from) == rescale(a, ab, 1).min(255)))
                        .collect();
                    assert!(!gated.is_empty(), "{at}: no function selected from master value {a}");
                    assert!(gated.iter().all(|f| f.mode.unwrap().master.0 == mo as u16), "{at}: master slot");
                    assert!(gated.iter().any(|f| u64::from(f.from) <= rescale(from, fb, bytes.min(2))), "{at}");
                }
            }
        }
        // Wheel slot colours: the macro's xy, the gels' xyY as c_F by the sRGB matrix.
        let wheels = theirs["wheels"].as_object().unwrap();
        if let Some(slots) = wheels.get("ColorMacro1") {
            for (k, s) in slots.as_array().unwrap().iter().enumerate() {
                let xy = ty.colour_macros[k].unwrap();
                assert!(
                    (f64::from(xy.x) - s[1].as_f64().unwrap()).abs() < 1e-6
                        && (f64::from(xy.y) - s[2].as_f64().unwrap()).abs() < 1e-6
                );
            }
        }
        let gels = wheels.get("Color2").and_then(Value::as_array).cloned().unwrap_or_default();
        assert_eq!(ty.extra_wheels.first().map_or(0, Vec::len), gels.len(), "{t}");
        for (slot, s) in ty.extra_wheels.first().into_iter().flatten().zip(&gels) {
            let (x, y, big_y) = (s[1].as_f64().unwrap(), s[2].as_f64().unwrap(), s[3].as_f64().unwrap() / 100.0);
            let want = srgb_of_xyz(xyz_of_xyy(x, y, big_y)).map(|c| c.max(0.0));
            let WheelSlot::Factor(c) = slot else { panic!("{t}: an xyY slot is a factor") };
            for i in 0..3 {
                assert!((f64::from(c[i]) - want[i]).abs() < 2e-4, "{t} {}: {c} vs {want:?}", s[0]);
            }
        }
        if t == "ViperSpot" {
            let media = |w: &str| -> Vec<String> {
                wheels[w].as_array().unwrap().iter().map(|s| s[4].as_str().unwrap().to_string()).collect()
            };
            let names = |v: &[Option<std::sync::Arc<footlight_fixture::beam::GoboImage>>]| -> Vec<String> {
                v.iter().map(|i| i.as_ref().map(|i| i.name.clone()).unwrap_or_default()).collect()
            };
            assert_eq!(names(&ty.gate.gobo_wheel2), media("Gobo2"));
            assert_eq!(names(&ty.gate.animation_wheel), media("AnimationWheel1"));
        }
    }
}

/// XYZ → linear sRGB (the exact inverse of [`RGB_TO_XYZ`], by Cramer's rule).
fn srgb_of_xyz(v: [f64; 3]) -> [f64; 3] {
    let m = RGB_TO_XYZ;
    let det = |a: [[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let d = det(m);
    [0, 1, 2].map(|c| {
        let mut a = m;
        (0..3).for_each(|r| a[r][c] = v[r]);
        det(a) / d
    })
}

// --- Intensity from the colour channels, master and cell dimmers -------------------

#[test]
fn a_bar_without_a_dimmer_goes_dark_with_its_colour_channels() {
    let p = rig();
    let cells = lights(&p, "Bar RGBW");
    assert_eq!(cells.len(), 4);
    // Power-up: every colour channel at 0 → every cell dark (no dimmer keeps them lit).
    let u = frame(&p, &[]);
    for c in &cells {
        assert_eq!(decode(c, &u).1, Vec3::ZERO, "{}", c.name);
    }
    // Cell 2's red at full: only cell 2 lights, red.
    let u = frame(&p, &[(RGBW + 4, 255)]);
    for (k, c) in cells.iter().enumerate() {
        let (_, kk) = decode(c, &u);
        if k == 1 {
            assert!(kk.x > 10.0 * kk.y.max(kk.z) && kk.x > 0.0, "{kk}");
        } else {
            assert_eq!(kk, Vec3::ZERO, "{}", c.name);
        }
    }
    // Half red is half the light of full red (the emitter level is linear).
    let half = decode(cells[1], &frame(&p, &[(RGBW + 4, 128)])).1;
    let full = decode(cells[1], &u).1;
    assert!((half.x / full.x - 128.0 / 255.0).abs() < 1e-5);
}

#[test]
fn master_and_cell_dimmers_multiply_through_the_selected_curve() {
    let p = rig();
    let cells = lights(&p, "Cluster");
    assert_eq!(cells.len(), 4);
    // Power-up: the master at its default 0 and the cells' own dimmers at full: dark (B4-FC lenses shone).
    let u = frame(&p, &[]);
    assert!(cells.iter().all(|c| decode(c, &u).1 == Vec3::ZERO));
    let full = decode(cells[0], &frame(&p, &[(CLUSTER, 255)])).1;
    assert!(full.min_element() > 0.0);
    let (m, c): (f64, f64) = (128.0 / 255.0, 64.0 / 255.0);
    let at = |curve: u8| decode(cells[0], &frame(&p, &[(CLUSTER, 128), (CLUSTER + 1, curve), (CLUSTER + 7, 64)])).1;
    // DimmerCurve sets (pygdtf: Linear 0, Square 64, S-Curve 128, Log 192).
    let theatre = |x: f64| x - (std::f64::consts::TAU * x).sin() / std::f64::consts::TAU;
    for (curve, v) in [(0, m * c), (64, (m * c).powi(2)), (128, theatre(m) * theatre(c)), (192, m * c)] {
        let k = at(curve);
        assert!((f64::from(k.y / full.y) - v).abs() < 1e-5, "curve set at {curve}: {} vs {v}", k.y / full.y);
    }
    // Only cell 1's own dimmer moved: cell 2 follows the master alone.
    let k2 = decode(cells[1], &frame(&p, &[(CLUSTER, 128), (CLUSTER + 7, 64)])).1;
    assert!((f64::from(k2.y / full.y) - m).abs() < 1e-5);
}

#[test]
fn strobe_mode_selects_strobe_or_open_and_the_duration_sets_the_duty() {
    let p = rig();
    let cell = lights(&p, "Cluster")[0];
    // StrobeMode 0-127 (pygdtf's mode range of Shutter1Strobe): 16-255 strobes 1..20 Hz.
    let (s, _) = decode(cell, &frame(&p, &[(CLUSTER, 255), (CLUSTER + 3, 100), (CLUSTER + 5, 0)]));
    let hz = 1.0 + 19.0 * (100.0 - 16.0) / (255.0 - 16.0);
    assert!((f64::from(s.strobe) - hz).abs() < 1e-4, "{} vs {hz}", s.strobe);
    // StrobeMode 128-255: the same shutter value is open, steady.
    let (open, _) = decode(cell, &frame(&p, &[(CLUSTER, 255), (CLUSTER + 3, 100), (CLUSTER + 5, 200)]));
    assert_eq!((open.shutter, open.strobe), (1.0, 0.0));
    // StrobeDuration 0.01..0.2 s: 128 → 0.1054 s flashes, duty = duration × rate.
    let d = 0.01 + 0.19 * 128.0 / 255.0;
    let (s, _) = decode(cell, &frame(&p, &[(CLUSTER, 255), (CLUSTER + 3, 40), (CLUSTER + 4, 128), (CLUSTER + 5, 0)]));
    let hz = 1.0 + 19.0 * (40.0 - 16.0) / (255.0 - 16.0);
    let n = 200_000;
    let mean: f64 = (0..n).map(|i| f64::from(s.shutter_at((i as f64 + 0.5) * 20.0 / n as f64))).sum::<f64>() / n as f64;
    assert!((mean - d * hz).abs() < 5e-3, "duty {mean} vs {}", d * hz);
}

// --- Colour targets -------------------------------------------------------------

#[test]
fn hsb_channels_mix_the_hue_from_the_emitters() {
    let p = rig();
    let cell = lights(&p, "Bar HSB")[0];
    // Hue 0..360° over 16 bits, saturation and brightness 0..100 % (pygdtf's physical ranges).
    for (hue_raw, sat) in [(0u16, 255u8), (10923, 255), (36409, 128), (54613, 204), (5000, 0)] {
        let u = frame(&p, &[(HSB, (hue_raw >> 8) as u8), (HSB + 1, hue_raw as u8), (HSB + 2, sat), (HSB + 3, 255)]);
        let (s, k) = decode(cell, &u);
        let (h, sv) = (360.0 * f64::from(hue_raw) / 65535.0, f64::from(sat) / 255.0);
        let want = xy_of_xyz(mul(&RGB_TO_XYZ, hsv(h, sv, 1.0)));
        assert!(dist(xy_of_k(k), want) < 1.5e-3, "hue {h} sat {sv}: {:?} vs {want:?} ({s:?})", xy_of_k(k));
        // Brightness multiplies the light, not the colour.
        let u = frame(&p, &[(HSB, (hue_raw >> 8) as u8), (HSB + 1, hue_raw as u8), (HSB + 2, sat), (HSB + 3, 102)]);
        let (_, dim) = decode(cell, &u);
        assert!((f64::from(dim.y / k.y) - 102.0 / 255.0).abs() < 1e-5);
    }
}

#[test]
fn cie_channels_set_the_chromaticity() {
    let p = rig();
    let cell = lights(&p, "Bar CIE")[2];
    let base = CIE + 10;
    for (x, y) in [(0.45, 0.41), (0.30, 0.30), (0.28, 0.42), (0.55, 0.33)] {
        let (xr, yr) = ((x * 65535.0_f64).round() as u16, (y * 65535.0_f64).round() as u16);
        let sets = [
            (base, (xr >> 8) as u8),
            (base + 1, xr as u8),
            (base + 2, (yr >> 8) as u8),
            (base + 3, yr as u8),
            (base + 4, 255),
        ];
        let (s, k) = decode(cell, &frame(&p, &sets));
        let want = [f64::from(xr) / 65535.0, f64::from(yr) / 65535.0];
        assert!(dist(xy_of_k(k), want) < 5e-4, "{:?} vs {want:?}", xy_of_k(k));
        // The emitters' levels mix exactly that chromaticity (their xyY from the file).
        let mix = xy_of_xyz(mix_xyz([0, 1, 2, 3].map(|i| f64::from(s.mix[i]))));
        assert!(dist(mix, want) < 1e-4, "{mix:?} vs {want:?}");
        let mut dim = sets;
        dim[4].1 = 102;
        let (_, d) = decode(cell, &frame(&p, &dim));
        assert!((f64::from(d.y / k.y) - 102.0 / 255.0).abs() < 1e-5);
    }
}

#[test]
fn a_cct_mode_mixes_the_planckian_white_and_the_tint_moves_it_off_the_locus() {
    let p = rig();
    let cell = lights(&p, "Bar CCT")[0];
    let ctc = |k: f64| ((k - 2700.0) / 5300.0 * 65535.0).round() as u16;
    for target in [3200.0, 4300.0, 5600.0, 7500.0] {
        let raw = ctc(target);
        let kelvin = 2700.0 + 5300.0 * f64::from(raw) / 65535.0;
        // Green/Magenta −1..1: 128 is +0.004 of a full tint (Duv 7.8e-5), 255 full green, 0 full magenta.
        let at = |gm: u8| {
            decode(cell, &frame(&p, &[(CCT, 255), (CCT + 1, (raw >> 8) as u8), (CCT + 2, raw as u8), (CCT + 3, gm)])).1
        };
        let on = xy_of_k(at(128));
        assert!(dist(on, kim_xy(kelvin)) < 1.5e-3, "{kelvin} K: {on:?} vs Kim {:?}", kim_xy(kelvin));
        // Full green: 0.02 in Duv above the locus, along its normal (docs: a full tint is Duv 0.02).
        let locus = uv(kim_xy(kelvin));
        let tangent = {
            let (a, b) = (uv(kim_xy(kelvin - 20.0)), uv(kim_xy(kelvin + 20.0)));
            let n = dist(a, b);
            [(b[0] - a[0]) / n, (b[1] - a[1]) / n]
        };
        for (gm, sign) in [(255u8, 1.0), (0, -1.0)] {
            let off = uv(xy_of_k(at(gm)));
            let d = [off[0] - locus[0], off[1] - locus[1]];
            let len = d[0].hypot(d[1]);
            assert!((len - 0.02).abs() < 1.5e-3, "{kelvin} K, tint {gm}: Duv {len}");
            assert!((d[0] * tangent[0] + d[1] * tangent[1]).abs() / len < 0.08, "{kelvin} K: not along the normal");
            assert!(d[1] * sign > 0.0, "{kelvin} K: green is above the locus (larger v)");
        }
    }
}

#[test]
fn ctc_corrects_an_rgbw_mix_like_a_filter() {
    let p = rig();
    let cell = lights(&p, "Bar Mixed")[0];
    let full: Vec<(u16, u8)> = (0..4).map(|i| (MIXED + 7 + i, 255)).collect();
    let mut neutral = full.clone();
    neutral.extend(neutral_mixed());
    let (_, open) = decode(cell, &frame(&p, &neutral));
    // The emitters' own white (all at full), from their xyY in the file.
    let native = xy_of_xyz(mix_xyz([1.0; 4]));
    assert!(dist(xy_of_k(open), native) < 5e-4, "{:?} vs {native:?}", xy_of_k(open));
    let raw = ((3200.0 - 2700.0) / 5300.0 * 65535.0_f64).round() as u16;
    let kelvin = 2700.0 + 5300.0 * f64::from(raw) / 65535.0;
    let mut warm = full;
    warm.extend([(MIXED + 4, (raw >> 8) as u8), (MIXED + 5, raw as u8), (MIXED + 6, 128)]);
    let (_, k) = decode(cell, &frame(&p, &warm));
    // The white moves as the locus does from the bar's 6500 K to the target.
    let (a, b) = (uv(kim_xy(6500.0)), uv(kim_xy(kelvin)));
    let n = uv(native);
    let want = xy_of_uv([n[0] + b[0] - a[0], n[1] + b[1] - a[1]]);
    assert!(dist(xy_of_k(k), want) < 1.5e-3, "{:?} vs {want:?}", xy_of_k(k));
    // And loses what an ideal CTO filter from 6500 K would.
    let tau = correction_tau(6500.0, kelvin);
    assert!((y_of_k(k) / y_of_k(open) - tau).abs() < 0.02 * tau, "{} vs {tau}", y_of_k(k) / y_of_k(open));
}

#[test]
fn the_colour_mix_mode_master_selects_rgbw_or_hsb_on_the_same_channels() {
    let p = rig();
    let cell = lights(&p, "Bar Mixed")[1];
    let values = [(MIXED + 11, 128u8), (MIXED + 12, 255), (MIXED + 13, 255), (MIXED + 14, 0)];
    let with = |mode: u8| {
        let mut s: Vec<(u16, u8)> = values.to_vec();
        s.extend(neutral_mixed());
        s.push((MIXED, mode));
        decode(cell, &frame(&p, &s))
    };
    // ColorMixMode 0-127 (pygdtf: ColorAdd_* functions' mode range): the channels are R, G, B, W.
    let (s, k) = with(0);
    assert!(s.hsb.is_none());
    let want = xy_of_xyz(mix_xyz([128.0 / 255.0, 1.0, 1.0, 0.0]));
    assert!(dist(xy_of_k(k), want) < 1e-3, "RGBW: {:?} vs {want:?}", xy_of_k(k));
    // 128-255: the same channels are hue, saturation, brightness.
    let (s, k) = with(128);
    assert!(s.hsb.is_some());
    let want = xy_of_xyz(mul(&RGB_TO_XYZ, hsv(360.0 * 128.0 / 255.0, 1.0, 1.0)));
    assert!(dist(xy_of_k(k), want) < 1.5e-3, "HSB: {:?} vs {want:?}", xy_of_k(k));
}

#[test]
fn colour_macros_mix_their_slot_colour_and_gels_multiply() {
    let p = rig();
    let cell = lights(&p, "Bar Mixed")[0];
    let mut base = neutral_mixed();
    base.extend((0..4).map(|i| (MIXED + 7 + i, 255)));
    let at = |macro_value: u8, gel: u8| {
        let mut s = base.clone();
        s.extend([(MIXED + 2, macro_value), (MIXED + 3, gel)]);
        decode(cell, &frame(&p, &s)).1
    };
    // Slots (pygdtf): Red 0.64/0.33 at 32, Lavender 0.25/0.20 at 96: inside the emitters' gamut.
    for (v, want) in [(32u8, [0.64, 0.33]), (96, [0.25, 0.20])] {
        assert!(dist(xy_of_k(at(v, 0)), want) < 1.5e-3, "macro {v}: {:?}", xy_of_k(at(v, 0)));
    }
    // Amber 0.57/0.42 lies beyond the red-green edge: the mix is where the line to the white meets it.
    let (w, amber) = (xy_of_xyz(mix_xyz([1.0; 4])), [0.57, 0.42]);
    let (r, g) = ([EMITTERS[0].0, EMITTERS[0].1], [EMITTERS[1].0, EMITTERS[1].1]);
    let cross = |a: [f64; 2], b: [f64; 2]| a[0] * b[1] - a[1] * b[0];
    let (d1, d2) = ([amber[0] - w[0], amber[1] - w[1]], [g[0] - r[0], g[1] - r[1]]);
    let t = cross([r[0] - w[0], r[1] - w[1]], d2) / cross(d1, d2);
    let edge = [w[0] + t * d1[0], w[1] + t * d1[1]];
    // (Outside sRGB too: the emitters' levels say it, k_i is fitted into sRGB.)
    let mut s = base.clone();
    s.push((MIXED + 2, 64));
    let levels = decode(cell, &frame(&p, &s)).0.mix;
    let mix = xy_of_xyz(mix_xyz([0, 1, 2, 3].map(|i| f64::from(levels[i]))));
    assert!(dist(mix, edge) < 2e-3, "{mix:?} vs {edge:?}");
    // Off (0-31): the RGBW mix itself.
    assert!(dist(xy_of_k(at(0, 0)), w) < 5e-4);
    // Color2's blue gel (0.2, 0.2, Y 30 %) multiplies the mix by its linear sRGB per channel.
    let (open, blue) = (at(0, 0), at(0, 40));
    let f = srgb_of_xyz(xyz_of_xyy(0.2, 0.2, 0.3)).map(|c| c.max(0.0));
    for i in 0..3 {
        assert!(
            (f64::from(blue[i]) - f64::from(open[i]) * f[i]).abs() < 1e-3 * f64::from(open.max_element()),
            "{blue} vs {open} × {f:?}"
        );
    }
}

// --- The spot: gobo index vs rotation, second gobo, animation, colour wheels, CTO -------

#[test]
fn gobo_rotation_applies_only_in_the_mode_the_gobo_wheel_selects() {
    let p = rig();
    let viper = lights(&p, "Viper")[0];
    let at = |gobo: u8| {
        decode(viper, &frame(&p, &[(VIPER + 4, 255), (VIPER + 9, gobo), (VIPER + 10, 128), (VIPER + 11, 0)])).0
    };
    // Gobo1 10 ("Ring", an index set: mode 0-63): Gobo1Pos −180..180° at 32768, no spin: the state holds still.
    let s = at(10);
    assert_eq!((s.gobo, s.gobo_spin), (1.0, 0.0));
    assert!((f64::from(s.gobo_angle) - (-180.0 + 360.0 * 32768.0 / 65535.0)).abs() < 1e-4, "{}", s.gobo_angle);
    let later = s.at_time(7.3, 3);
    assert_eq!(
        (later.gobo, later.gobo_angle),
        (s.gobo, s.gobo_angle),
        "an indexed gobo at the file's default never moves"
    );
    // Gobo1 74 ("Ring rotating": mode 64-127): the same 32768 is Gobo1PosRotate −200..200°/s.
    let r = at(74);
    assert_eq!(r.gobo, 1.0);
    assert!((f64::from(r.gobo_spin) - (-200.0 + 400.0 * 32768.0 / 65535.0)).abs() < 1e-4, "{}", r.gobo_spin);
    assert_eq!(r.gobo_angle, 0.0, "the index range does not apply while rotating");
}

#[test]
fn a_second_gobo_and_the_animation_wheel_sit_in_the_gate() {
    let p = rig();
    let viper = lights(&p, "Viper")[0];
    let ty = typed(viper);
    // Gobo2 128 (Dots), AnimationWheel1 128 (Stripes), AnimationWheel1Pos 64 of 0-127 → 360 · 64/127°.
    let (s, _) = decode(viper, &frame(&p, &[(VIPER + 4, 255), (VIPER + 12, 128), (VIPER + 13, 128), (VIPER + 14, 64)]));
    assert_eq!((s.gobo2[0], s.animation[0]), (1.0, 1.0));
    assert!((f64::from(s.animation[1]) - 360.0 * 64.0 / 127.0).abs() < 1e-3, "{}", s.animation[1]);
    let gate = ty.gate_of(&s);
    let names: Vec<&str> = gate.layers.iter().map(|l| l.image.name.as_str()).collect();
    assert_eq!(names, ["viper_dots", "viper_stripes"]);
    assert!(matches!(ty.beam(&s), Beam::Shaped(_)));
    // AnimationWheel1PosRotate 128-255: −100..100°/s, stepped on the frame clock.
    let (s, _) = decode(viper, &frame(&p, &[(VIPER + 4, 255), (VIPER + 13, 128), (VIPER + 14, 255)]));
    assert_eq!(s.animation[2], 100.0);
    assert!(s.spins());
    assert!((s.at_time(1.0, 3).animation[1] - 100.0).abs() < 1e-3);
}

#[test]
fn colour_wheels_multiply_and_cto_as_an_amount_reaches_a_full_cto() {
    let p = rig();
    let viper = lights(&p, "Viper")[0];
    let k = |sets: &[(u16, u8)]| {
        let mut s = vec![(VIPER + 4, 255u8), (VIPER + 5, 255)];
        s.extend_from_slice(sets);
        decode(viper, &frame(&p, &s))
    };
    let (_, open) = k(&[]);
    assert!(open.min_element() > 0.0);
    // Color2 80: the amber gel (0.5, 0.42, Y 60 %) as a per-channel factor.
    let (_, amber) = k(&[(VIPER + 8, 80)]);
    let f = srgb_of_xyz(xyz_of_xyy(0.5, 0.42, 0.6)).map(|c| c.max(0.0));
    for i in 0..3 {
        assert!((f64::from(amber[i]) - f64::from(open[i]) * f[i]).abs() < 1e-3 * f64::from(open.max_element()));
    }
    // Color1 10 (Red, slot 2) and Color2 80 together: both factors.
    let (_, red) = k(&[(VIPER + 7, 10)]);
    let (_, both) = k(&[(VIPER + 7, 10), (VIPER + 8, 80)]);
    for i in 0..3 {
        assert!((f64::from(both[i]) - f64::from(red[i]) * f[i]).abs() < 1e-3 * f64::from(open.max_element()));
    }
    // CTO 0..1 (no kelvin in the file): full is a full CTO (+159 mired) from the lamp's 6000 K.
    let (s, _) = k(&[(VIPER + 20, 255)]);
    let want = 1e6 / (1e6 / 6000.0 + 159.0);
    assert!((f64::from(s.cto) - want).abs() < 0.5, "{} vs {want}", s.cto);
    let (s0, _) = k(&[(VIPER + 20, 0)]);
    assert!((s0.cto - 6000.0).abs() < 0.5);
}

#[test]
fn mode_gated_functions_are_read_from_the_masters_own_slot() {
    // The ColourBar's Mixed mode: every cell's gated functions point at the bar's ColorMixMode (slot 0).
    let (ty, _) = fixture_type(&Gdtf::open(&gdtf("ColourBar")).unwrap()).unwrap();
    let md = &ty.modes[ty.mode("Mixed").unwrap()];
    let gated: Vec<_> = md.channels.iter().flat_map(|c| c.functions.iter()).filter_map(|f| f.mode).collect();
    assert_eq!(gated.len(), 4 * 7, "R/Hue, G/Sat, B/Bright and W in each of 4 cells");
    assert!(gated.iter().all(|g| g.master == (0, None)));
    let hue = md.channels.iter().find(|c| c.offset == 7).unwrap();
    assert!(hue.functions.iter().any(|f| f.action == Action::Set(Attribute::Hue) && f.mode.unwrap().from == 128));
    assert!(hue.functions.iter().any(|f| f.action == Action::Set(Attribute::Mix(0)) && f.mode.unwrap().to == 127));
    assert_eq!(md.channels.iter().find(|c| c.offset == 0).unwrap().attribute, Attribute::Mode);
}
