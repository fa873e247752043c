//! Reading a fixture-type file: serde fills plain structs, then they are
//! validated into a [`FixtureType`] (two stages, as ripgrep's
//! LowArgs/HiArgs). Every error names the type file and the line.

use super::{Attribute, Channel, FixtureType, HermiteOptics, Mode, Movement, Optics, SpotOptics};
use crate::beam::HermitePattern;
use crate::error::{PatchError, line_of, toml_error};
use crate::state::{MAX_MIX, SLOTS};
use footlight_photometry::lamp::{HMI_CCT_K, TUNGSTEN_CCT_K};
use footlight_photometry::{Chroma, DimmerCurve, Emitter, GelLibrary, Lamp, Scroller};
use glam::{Vec2, Vec3};
use serde::Deserialize;
use std::ops::Range;
use std::path::Path;
use std::sync::Arc;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TypeFile {
    name: Spanned<String>,
    #[serde(default)]
    maker: Option<String>,
    #[serde(default)]
    notes: Option<String>,
    lamp: Spanned<LampFile>,
    beam: Spanned<BeamFile>,
    movement: Option<Spanned<MovementFile>>,
    #[serde(default)]
    mode: Vec<Spanned<ModeFile>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LampFile {
    kind: Spanned<String>,
    cct: Option<Spanned<f32>>,
    #[serde(default)]
    power: Option<f32>,
    #[serde(default)]
    flux: Option<f32>,
    #[serde(default)]
    emitter: Vec<Spanned<EmitterFile>>,
    source: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EmitterFile {
    name: String,
    x: Option<f32>,
    y: Option<f32>,
    rgb: Option<[f32; 3]>,
    share: f32,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BeamFile {
    model: Spanned<String>,
    source: Option<String>,
    field: Option<Spanned<f32>>,
    zoom: Option<Spanned<[f32; 2]>>,
    beam_ratio: Option<Spanned<OneOrTwo>>,
    intensity: Option<Spanned<f32>>,
    intensity_field: Option<Spanned<f32>>,
    iris_min: Option<Spanned<f32>>,
    spot: Option<Spanned<PatternFile>>,
    flood: Option<Spanned<PatternFile>>,
    file: Option<Spanned<String>>,
}

/// A number, or a list of them (`beam_ratio = 0.6` or `[0.8, 0.55]`).
#[derive(Deserialize)]
#[serde(untagged)]
enum OneOrTwo {
    One(f32),
    Many(Vec<f32>),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PatternFile {
    intensity: Spanned<f32>,
    angles: Vec<f32>,
    values: Vec<f32>,
    slopes: Option<Vec<f32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MovementFile {
    pan: Spanned<f32>,
    tilt: Spanned<f32>,
    #[serde(default)]
    source: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ModeFile {
    name: Spanned<String>,
    #[serde(default)]
    channel: Vec<Spanned<ChannelFile>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ChannelFile {
    attribute: Spanned<String>,
    offset: Spanned<i64>,
    fine: Option<Spanned<i64>>,
    default: Option<Spanned<i64>>,
    curve: Option<Spanned<DimmerCurve>>,
    range: Option<Spanned<[f32; 2]>>,
    frames: Option<Spanned<Vec<String>>>,
    #[serde(default)]
    label: Option<String>,
}

/// Reads and validates the fixture-type file at `path`. Scroller frames
/// name gels in `gels` (the patch's gel library).
pub fn load_type(path: &Path, gels: Option<&GelLibrary>) -> Result<FixtureType, PatchError> {
    let text = std::fs::read_to_string(path).map_err(|e| PatchError::new(path, 0, format!("cannot read: {e}")))?;
    parse_type(path, &text, gels)
}

/// Parses fixture-type text; `path` is used in messages and to find a
/// photometric file named relative to it.
pub fn parse_type(path: &Path, text: &str, gels: Option<&GelLibrary>) -> Result<FixtureType, PatchError> {
    let file: TypeFile = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
    let at = |span: Range<usize>, m: String| PatchError::new(path, line_of(text, span.start), m);
    let name = file.name.get_ref().trim().to_string();
    if name.is_empty() {
        return Err(at(file.name.span(), "name must not be empty".into()));
    }
    let _ = (&file.notes, file.lamp.get_ref().power, file.lamp.get_ref().flux);
    let (lamp, mix_names) = lamp(&at, &file.lamp)?;
    let optics = optics(path, &at, &file.beam)?;
    let movement = match &file.movement {
        None => None,
        Some(m) => {
            let _ = &m.get_ref().source;
            let ok = |v: f32| v.is_finite() && v > 0.0 && v <= 720.0;
            let (pan, tilt) = (*m.get_ref().pan.get_ref(), *m.get_ref().tilt.get_ref());
            if !ok(pan) {
                return Err(at(m.get_ref().pan.span(), format!("pan range {pan} must be in (0, 720] degrees")));
            }
            if !ok(tilt) {
                return Err(at(m.get_ref().tilt.span(), format!("tilt range {tilt} must be in (0, 720] degrees")));
            }
            Some(Movement { pan, tilt })
        }
    };
    let mut ty = FixtureType {
        name,
        maker: file.maker.unwrap_or_else(|| "generic".into()),
        path: path.to_path_buf(),
        lamp,
        mix_names,
        optics,
        movement,
        modes: Vec::new(),
        colour_wheel: Vec::new(),
        cto: None,
        gate: Default::default(),
        extra_wheels: Vec::new(),
        colour_macros: Vec::new(),
    };
    if file.mode.is_empty() {
        return Err(PatchError::new(path, 1, "needs at least one [[mode]] with its channels"));
    }
    for m in &file.mode {
        let mode = mode(&at, &ty, m, text, gels)?;
        if let Some(other) = ty.modes.iter().find(|o| o.name.eq_ignore_ascii_case(&mode.name)) {
            return Err(at(
                m.get_ref().name.span(),
                format!("mode {:?} already defined on line {}", mode.name, other.line),
            ));
        }
        ty.modes.push(mode);
    }
    Ok(ty)
}

type At<'a> = dyn Fn(Range<usize>, String) -> PatchError + 'a;

fn lamp(at: &At, l: &Spanned<LampFile>) -> Result<(Lamp, Vec<String>), PatchError> {
    let f = l.get_ref();
    let _ = &f.source;
    let kind = f.kind.get_ref().as_str();
    let cct = |default: f32| -> Result<f32, PatchError> {
        let t = f.cct.as_ref().map(|c| *c.get_ref()).unwrap_or(default);
        if !(t.is_finite() && (1000.0..=20000.0).contains(&t)) {
            let span = f.cct.as_ref().map(|c| c.span()).unwrap_or(l.span());
            return Err(at(span, format!("cct {t} K must be in 1000..20000")));
        }
        Ok(t)
    };
    let no_emitters = |k: &str| -> Result<(), PatchError> {
        match f.emitter.first() {
            Some(e) => Err(at(e.span(), format!("a {k} lamp has no [[lamp.emitter]]; use kind = \"led\""))),
            None => Ok(()),
        }
    };
    match kind {
        "tungsten" => {
            no_emitters(kind)?;
            Ok((Lamp::Tungsten { cct_full: cct(TUNGSTEN_CCT_K)? }, Vec::new()))
        }
        "discharge" | "hmi" => {
            no_emitters(kind)?;
            Ok((Lamp::Discharge { cct: cct(HMI_CCT_K)? }, Vec::new()))
        }
        "cmy" => {
            no_emitters(kind)?;
            let names = ["cyan", "magenta", "yellow"].map(String::from).to_vec();
            Ok((Lamp::Cmy { cct: cct(HMI_CCT_K)?, cyan: 0.0, magenta: 0.0, yellow: 0.0, filters: None }, names))
        }
        "led" => {
            if let Some(c) = &f.cct {
                return Err(at(c.span(), "an LED lamp's colour comes from its emitters; remove cct".into()));
            }
            if f.emitter.is_empty() || f.emitter.len() > MAX_MIX {
                return Err(at(l.span(), format!("an LED lamp needs 1..{MAX_MIX} [[lamp.emitter]] entries")));
            }
            let mut emitters = Vec::new();
            let mut names: Vec<String> = Vec::new();
            for e in &f.emitter {
                let d = e.get_ref();
                let name = d.name.trim().to_ascii_lowercase();
                if name.is_empty() || names.contains(&name) || RESERVED.contains(&name.as_str()) {
                    return Err(at(
                        e.span(),
                        format!("emitter name {name:?} must be non-empty, unique and not an attribute name"),
                    ));
                }
                let chroma = match (d.x, d.y, d.rgb) {
                    (Some(x), Some(y), None) if x > 0.0 && y > 0.0 && x + y < 1.0 => Chroma::Xy(Vec2::new(x, y)),
                    (None, None, Some(rgb))
                        if rgb.iter().all(|c| c.is_finite() && *c >= 0.0) && rgb.iter().sum::<f32>() > 0.0 =>
                    {
                        Chroma::LinearSrgb(Vec3::from(rgb))
                    }
                    _ => {
                        return Err(at(
                            e.span(),
                            format!("emitter {name}: give CIE x and y (both > 0, x + y < 1) or a linear rgb, not both"),
                        ));
                    }
                };
                if !(d.share.is_finite() && d.share > 0.0) {
                    return Err(at(e.span(), format!("emitter {name}: share {} must be > 0", d.share)));
                }
                emitters.push(Emitter::new(name.clone(), chroma, d.share));
                names.push(name);
            }
            Ok((Lamp::Led { emitters }, names))
        }
        other => Err(at(
            f.kind.span(),
            format!("unknown lamp kind {other:?}; use \"tungsten\", \"discharge\", \"led\" or \"cmy\""),
        )),
    }
}

/// Attribute names an emitter may not take.
const RESERVED: [&str; 8] = ["dimmer", "pan", "tilt", "zoom", "focus", "iris", "scroller", "other"];

fn optics(path: &Path, at: &At, b: &Spanned<BeamFile>) -> Result<Optics, PatchError> {
    let f = b.get_ref();
    let _ = &f.source;
    let model = f.model.get_ref().as_str();
    let unexpected = |keys: &[(&str, Option<Range<usize>>)]| -> Result<(), PatchError> {
        for (k, span) in keys {
            if let Some(span) = span {
                return Err(at(span.clone(), format!("beam model {model:?} has no key {k}")));
            }
        }
        Ok(())
    };
    let span_of = |s: &Option<Spanned<f32>>| s.as_ref().map(|v| v.span());
    match model {
        "spot" => {
            unexpected(&[
                ("spot", f.spot.as_ref().map(|s| s.span())),
                ("flood", f.flood.as_ref().map(|s| s.span())),
                ("file", f.file.as_ref().map(|s| s.span())),
            ])?;
            let zoom = match (&f.field, &f.zoom) {
                (Some(x), None) => [*x.get_ref(); 2],
                (None, Some(z)) => *z.get_ref(),
                _ => {
                    return Err(at(
                        b.span(),
                        "a spot beam needs either field (fixed) or zoom = [at DMX 0, at full]".into(),
                    ));
                }
            };
            let zspan = f.field.as_ref().map(|s| s.span()).or(f.zoom.as_ref().map(|s| s.span())).unwrap_or(b.span());
            if zoom.iter().any(|a| !(a.is_finite() && *a > 0.0 && *a <= 180.0)) {
                return Err(at(zspan, format!("field angles {zoom:?} must be in (0, 180] degrees")));
            }
            let ratio = match &f.beam_ratio {
                None => [0.7, 0.7],
                Some(r) => match r.get_ref() {
                    OneOrTwo::One(a) => [*a, *a],
                    OneOrTwo::Many(v) if v.len() == 2 => [v[0], v[1]],
                    OneOrTwo::Many(_) => {
                        return Err(at(r.span(), "beam_ratio is one number or [hard edge, soft edge]".into()));
                    }
                },
            };
            if ratio.iter().any(|r| !(r.is_finite() && *r > 0.0 && *r <= 1.0)) {
                let span = f.beam_ratio.as_ref().map(|r| r.span()).unwrap_or(b.span());
                return Err(at(span, format!("beam_ratio {ratio:?} (beam/field) must be in (0, 1]")));
            }
            let Some(i) = &f.intensity else {
                return Err(at(b.span(), "a spot beam needs intensity (Î in candela, from the datasheet)".into()));
            };
            if !(i.get_ref().is_finite() && *i.get_ref() > 0.0) {
                return Err(at(i.span(), format!("intensity {} cd must be > 0", i.get_ref())));
            }
            let (lo, hi) = (zoom[0].min(zoom[1]), zoom[0].max(zoom[1]));
            let reference = f.intensity_field.as_ref().map(|r| *r.get_ref()).unwrap_or(lo);
            if !(reference >= lo && reference <= hi) {
                let span = span_of(&f.intensity_field).unwrap_or(b.span());
                return Err(at(span, format!("intensity_field {reference} must lie in the zoom range {lo}..{hi}")));
            }
            let iris_min = match &f.iris_min {
                None => None,
                Some(m) if m.get_ref().is_finite() && *m.get_ref() > 0.0 && *m.get_ref() < 1.0 => Some(*m.get_ref()),
                Some(m) => return Err(at(m.span(), format!("iris_min {} must be in (0, 1)", m.get_ref()))),
            };
            Ok(Optics::Spot(SpotOptics::new(zoom, ratio, *i.get_ref(), reference, iris_min)))
        }
        "hermite" => {
            unexpected(&[
                ("field", span_of(&f.field)),
                ("zoom", f.zoom.as_ref().map(|s| s.span())),
                ("beam_ratio", f.beam_ratio.as_ref().map(|s| s.span())),
                ("intensity (give it in [beam.spot] and [beam.flood])", span_of(&f.intensity)),
                ("intensity_field", span_of(&f.intensity_field)),
                ("iris_min", span_of(&f.iris_min)),
                ("file", f.file.as_ref().map(|s| s.span())),
            ])?;
            let pattern =
                |p: &Option<Spanned<PatternFile>>, which: &str| -> Result<(Arc<HermitePattern>, f32), PatchError> {
                    let Some(p) = p else {
                        return Err(at(
                            b.span(),
                            format!("a hermite beam needs [beam.{which}] with intensity, angles, values"),
                        ));
                    };
                    let d = p.get_ref();
                    let cd = *d.intensity.get_ref();
                    if !(cd.is_finite() && cd > 0.0) {
                        return Err(at(d.intensity.span(), format!("{which} intensity {cd} cd must be > 0")));
                    }
                    let h = HermitePattern::new(&d.angles, &d.values, d.slopes.as_deref())
                        .map_err(|m| at(p.span(), format!("[beam.{which}]: {m}")))?;
                    Ok((Arc::new(h), cd))
                };
            let (spot, spot_cd) = pattern(&f.spot, "spot")?;
            let (flood, flood_cd) = pattern(&f.flood, "flood")?;
            Ok(Optics::Hermite(HermiteOptics { spot, spot_cd, flood, flood_cd }))
        }
        "measured" => {
            unexpected(&[
                ("field", span_of(&f.field)),
                ("zoom", f.zoom.as_ref().map(|s| s.span())),
                ("beam_ratio", f.beam_ratio.as_ref().map(|s| s.span())),
                ("intensity (the file gives Î)", span_of(&f.intensity)),
                ("spot", f.spot.as_ref().map(|s| s.span())),
                ("flood", f.flood.as_ref().map(|s| s.span())),
            ])?;
            let Some(file) = &f.file else {
                return Err(at(
                    b.span(),
                    "a measured beam needs file = \"….ies\" or \"….ldt\" (relative to this file)".into(),
                ));
            };
            let photometry = path.parent().unwrap_or(Path::new("")).join(file.get_ref());
            let table = crate::photometric::load(&photometry)
                .map_err(|e| if e.line == 0 { at(file.span(), e.to_string()) } else { e })?;
            Ok(Optics::Measured(Arc::new(table)))
        }
        other => {
            Err(at(f.model.span(), format!("unknown beam model {other:?}; use \"spot\", \"hermite\" or \"measured\"")))
        }
    }
}

fn mode(
    at: &At,
    ty: &FixtureType,
    m: &Spanned<ModeFile>,
    text: &str,
    gels: Option<&GelLibrary>,
) -> Result<Mode, PatchError> {
    let d = m.get_ref();
    let name = d.name.get_ref().trim().to_string();
    if name.is_empty() {
        return Err(at(d.name.span(), "mode name must not be empty".into()));
    }
    let mut channels: Vec<Channel> = Vec::new();
    let mut used: Vec<(u16, usize)> = Vec::new(); // (slot offset, line)
    for c in &d.channel {
        let line = line_of(text, c.span().start);
        let f = c.get_ref();
        let attr_name = f.attribute.get_ref().trim().to_ascii_lowercase();
        let attribute = attribute(at, ty, &f.attribute, &attr_name)?;
        let _ = &f.label;
        if attribute != Attribute::Other
            && let Some(o) = channels.iter().find(|o| o.attribute == attribute)
        {
            return Err(at(f.attribute.span(), format!("{attr_name} is already on the channel at line {}", o.line)));
        }
        let slot = |s: &Spanned<i64>, what: &str| -> Result<u16, PatchError> {
            let v = *s.get_ref();
            if !(1..=SLOTS as i64).contains(&v) {
                return Err(at(
                    s.span(),
                    format!("{what} {v} must be in 1..512 (slots from the start address, from 1)"),
                ));
            }
            Ok(v as u16 - 1)
        };
        let offset = slot(&f.offset, "offset")?;
        let fine = f.fine.as_ref().map(|s| slot(s, "fine")).transpose()?;
        for (o, span) in
            std::iter::once((offset, f.offset.span())).chain(fine.map(|x| (x, f.fine.as_ref().unwrap().span())))
        {
            if let Some((_, l)) = used.iter().find(|(u, _)| *u == o) {
                return Err(at(span, format!("slot offset {} is already used by the channel at line {l}", o + 1)));
            }
            used.push((o, line));
        }
        let full: i64 = if fine.is_some() { 65535 } else { 255 };
        let default = match &f.default {
            Some(v) if (0..=full).contains(v.get_ref()) => *v.get_ref() as u16,
            Some(v) => return Err(at(v.span(), format!("default {} must be in 0..{full}", v.get_ref()))),
            None => default_value(attribute, full as u16, matches!(ty.lamp, Lamp::Led { .. })),
        };
        if let Some(cv) = &f.curve
            && attribute != Attribute::Dimmer
        {
            return Err(at(cv.span(), "curve applies only to the dimmer channel".into()));
        }
        let range = range(at, ty, attribute, f, &attr_name)?;
        let scroller = match (&f.frames, attribute) {
            (Some(fr), Attribute::Scroller) => Some(scroller(fr, gels).map_err(|m| at(fr.span(), m))?),
            (Some(fr), _) => return Err(at(fr.span(), "frames apply only to the scroller channel".into())),
            (None, Attribute::Scroller) => {
                return Err(at(
                    f.attribute.span(),
                    "a scroller channel needs frames = [gel names on the string]".into(),
                ));
            }
            (None, _) => None,
        };
        channels.push(Channel {
            attribute,
            name: attr_name,
            offset,
            fine,
            default,
            curve: f.curve.as_ref().map(|c| *c.get_ref()).unwrap_or_default(),
            range,
            scroller,
            functions: Vec::new(),
            line,
        });
    }
    if channels.is_empty() {
        return Err(at(m.span(), format!("mode {name:?} has no [[mode.channel]]")));
    }
    let footprint = used.iter().map(|(o, _)| o + 1).max().unwrap_or(0);
    Ok(Mode { name, channels, footprint, line: line_of(text, m.span().start), overrides: Vec::new() })
}

/// Resolves an attribute name for this type, or says which names it takes.
fn attribute(at: &At, ty: &FixtureType, span: &Spanned<String>, name: &str) -> Result<Attribute, PatchError> {
    let bad = |why: &str| Err(at(span.span(), format!("attribute {name:?}: {why}")));
    let a = match name {
        "dimmer" | "intensity" => Attribute::Dimmer,
        "pan" | "tilt" if ty.movement.is_none() => return bad("this type has no [movement] (pan/tilt ranges)"),
        "pan" => Attribute::Pan,
        "tilt" => Attribute::Tilt,
        "zoom" => match &ty.optics {
            Optics::Spot(s) if s.zoom[0] != s.zoom[1] => Attribute::Zoom,
            _ => return bad("the beam has no zoom range (beam.zoom = [a, b])"),
        },
        "focus" => match &ty.optics {
            Optics::Measured(_) => return bad("a measured beam has no focus"),
            _ => Attribute::Focus,
        },
        "iris" => match &ty.optics {
            Optics::Spot(s) if s.iris_min.is_some() => Attribute::Iris,
            _ => return bad("the beam has no iris (beam.iris_min)"),
        },
        "scroller" | "colour_frame" | "color_frame" => Attribute::Scroller,
        "other" => Attribute::Other,
        _ => match ty.mix_names.iter().position(|n| n == name) {
            Some(i) => Attribute::Mix(i as u8),
            None => {
                let mut known = vec!["dimmer", "focus", "scroller", "other"];
                if ty.movement.is_some() {
                    known.extend(["pan", "tilt"]);
                }
                if let Optics::Spot(s) = &ty.optics {
                    if s.zoom[0] != s.zoom[1] {
                        known.push("zoom");
                    }
                    if s.iris_min.is_some() {
                        known.push("iris");
                    }
                }
                known.extend(ty.mix_names.iter().map(String::as_str));
                return bad(&format!("unknown for this type; it takes {}", known.join(", ")));
            }
        },
    };
    Ok(a)
}

/// The power-up DMX value when the file gives none: pan/tilt centred,
/// LED emitters full (so the dimmer alone brings up white), else 0.
fn default_value(attribute: Attribute, full: u16, led: bool) -> u16 {
    match attribute {
        Attribute::Pan | Attribute::Tilt => full / 2 + 1,
        Attribute::Mix(_) if led => full,
        _ => 0,
    }
}

fn range(at: &At, ty: &FixtureType, attribute: Attribute, f: &ChannelFile, name: &str) -> Result<[f32; 2], PatchError> {
    let (default, lo, hi): ([f32; 2], f32, f32) = match attribute {
        Attribute::Pan => {
            let p = ty.movement.map(|m| m.pan).unwrap_or(0.0);
            ([-p / 2.0, p / 2.0], -p / 2.0, p / 2.0)
        }
        Attribute::Tilt => {
            let t = ty.movement.map(|m| m.tilt).unwrap_or(0.0);
            ([-t / 2.0, t / 2.0], -t / 2.0, t / 2.0)
        }
        Attribute::Zoom => match &ty.optics {
            Optics::Spot(s) => (s.zoom, s.field_range().0, s.field_range().1),
            _ => ([0.0, 0.0], 0.0, 0.0),
        },
        Attribute::Iris => match &ty.optics {
            Optics::Spot(s) => ([1.0, s.iris_min.unwrap_or(1.0)], s.iris_min.unwrap_or(1.0), 1.0),
            _ => ([1.0, 1.0], 1.0, 1.0),
        },
        Attribute::Focus | Attribute::Mix(_) => ([0.0, 1.0], 0.0, 1.0),
        Attribute::Dimmer
        | Attribute::Scroller
        | Attribute::Other
        | Attribute::Shutter
        | Attribute::ColourWheel
        | Attribute::Gobo
        | Attribute::Prism
        | Attribute::Gate
        | Attribute::Cto
        | Attribute::ColourWheelN(_)
        | Attribute::ColourMacro
        | Attribute::Tint
        | Attribute::Hue
        | Attribute::Saturation
        | Attribute::HsbBrightness
        | Attribute::CieX
        | Attribute::CieY
        | Attribute::CieBrightness
        | Attribute::DimmerCurve
        | Attribute::StrobeDuration
        | Attribute::Level
        | Attribute::Gobo2
        | Attribute::Animation
        | Attribute::Mode => {
            if let Some(r) = &f.range {
                return Err(at(r.span(), format!("{name} takes no range")));
            }
            return Ok([0.0, 1.0]);
        }
    };
    match &f.range {
        None => Ok(default),
        Some(r) => {
            let v = *r.get_ref();
            if v.iter().all(|x| x.is_finite() && *x >= lo - 1e-4 && *x <= hi + 1e-4) && v[0] != v[1] {
                Ok(v)
            } else {
                Err(at(r.span(), format!("{name} range {v:?} must be two different values within {lo}..{hi}")))
            }
        }
    }
}

fn scroller(frames: &Spanned<Vec<String>>, gels: Option<&GelLibrary>) -> Result<Scroller, String> {
    let names = frames.get_ref();
    if names.is_empty() {
        return Err("frames must list at least one gel (\"open\" for an open frame)".into());
    }
    let mut out = Vec::with_capacity(names.len());
    for n in names {
        if n.eq_ignore_ascii_case("open") {
            out.push(None);
            continue;
        }
        let Some(lib) = gels else {
            return Err(format!("frame {n:?} names a gel, but the patch has no gel library (patch/gels.toml)"));
        };
        match lib.find(n) {
            Some(id) => out.push(Some(id)),
            None => {
                return Err(format!(
                    "unknown gel {n:?} in frames; the gel library {} has no such id",
                    lib.path.display()
                ));
            }
        }
    }
    Ok(Scroller { frames: out })
}
