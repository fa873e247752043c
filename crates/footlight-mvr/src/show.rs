//! From GDTF and MVR to Footlight's fixture model: a GDTF file as a
//! [`FixtureType`] ([`fixture_type`]) and an MVR file as a [`Patch`]
//! ([`load_mvr`]).
//!
//! What maps onto the existing model (Vierjahn 2010, eq. 4: k_i = c_F ⊙ c_I · v · Î):
//! * the first `<Beam>` of the first mode's tree gives the optics: a cone +
//!   penumbra [`SpotOptics`] from `BeamAngle`/`FieldAngle`, and
//!   Î = `LuminousFlux` / ∫f dω (all the flux in the pattern);
//! * `Dimmer` → v (a DMX profile with a pure square law → square curve,
//!   otherwise linear); `Pan`/`Tilt` → the yoke with the channel's
//!   physical range (GDTF: pan about the Axis' Z, tilt about X, rest beam
//!   −Z: the same frame as Footlight's hanging head, see `light.rs`);
//!   `Zoom` → field angle (GDTF's zoom is the beam angle, scaled by the
//!   beam's field/beam ratio); `Focus1` → focus 0..1; `Iris` → iris fraction;
//! * `ColorAdd_*` with an emitter → LED emitters: from the emitter's
//!   measured spectrum (`<Measurement>`) when it has one, else its CIE xy;
//!   Y share from the `Color` (see `emitter`); `ColorAdd_*` without an
//!   emitter (files that define none) → LED emitters from the attribute
//!   definitions' `Color`, else GDTF Annex B's nominal colours (estimated;
//!   [`crate::colour`]), said once per type; `ColorSub_C/M/Y` → CMY
//!   flags over the beam's CCT, each from its `Filter`'s measured
//!   transmission where there is one (see `cmy_filters`), else ideal bands;
//!   otherwise the lamp type (tungsten/halogen dims redder, discharge and
//!   LED white keep their CCT).
//!
//! * `Shutter1`/`Shutter1Strobe…` → shutter open/closed/strobe Hz by DMX
//!   range (`channel_functions`); `Color1` with a wheel → the slot from
//!   the channel sets, its c_F from the slot's filter spectrum or xyY
//!   (`colour_wheel`); `CTO`/`CTB`/`CTC` on a Planckian lamp → target CCT
//!   with the ideal correction filter's transmittance.
//!
//! * `Gobo1`/`Gobo1Pos…`, `Gobo2…`, `AnimationWheel1…`, `Prism1…`,
//!   `Blade…`, `ShaperRot`, `Frost1` → the spot's gate (gobo images,
//!   rotation, blades, prism facets, frost), see [`crate::gate`]: a changed
//!   gate is a geometry change (rebuild).
//!
//! * The attributes real files use (issue 36, [`map_name`]): `HSB_*`,
//!   `CIE_*`, `ColorMacro1` (slot colours), `Tint`/`Green/Magenta`,
//!   CTO/CTB/CTC on LED types (a colour target or a correction of the mix,
//!   in the emitter levels), `Color2`-`Color4` wheels, `DimmerCurve`/
//!   `DimmerMode`, `StrobeDuration`; master and cell dimmers multiply; a
//!   channel function applies only while its mode master selects it
//!   ([`mode_gate`]; `ColorMixMode`, `LEDZoneMode` and every master become
//!   [`Attribute::Mode`]). The table: docs/mvr-gdtf.md, "Attributes real GDTFs use".
//!
//! Every other attribute still occupies its
//! slots as an `other` channel, with **one warning per fixture type**
//! naming them.
//!
//! Multi-beam fixtures are one light per emitting cell ([`cells`]): each
//! `GeometryReference` holding a beam (pixel bars, matrices), else each
//! plain beam (multi-lamp blinders), with the cell's own channels and the
//! shared ones (the master dimmer). A mode spanning several DMX breaks
//! puts break b's channels at offsets from `BREAK_STRIDE · (b − 1)`; the
//! MVR `<Addresses>` of break 2, 3… go to `TypedFixture::breaks`
//! ([`footlight_fixture::Fixture::slot_address`] resolves them).

use crate::gdtf::{BeamInfo, ChannelInfo, FunctionInfo, Gdtf, GeometryKind, GeometryNode, LampType, Layout};
use crate::mvr::{Mvr, Scene, stage_pose};
use crate::report::{self, Modelled, Tally, TypeSummary};
use footlight_fixture::beam::SpotBeam;
use footlight_fixture::fixture_type::{
    Action, Attribute, Channel, CorrectionTable, Function, Mode, ModeGate, Movement, Optics, SlotOverride, SpotOptics,
    WheelSlot, colour::FULL_TINT_DUV, wheel_factor,
};
use footlight_fixture::patch::{BREAK_STRIDE, BuiltinSpot, FixtureCell, TypeLoader, TypedFixture};
use footlight_fixture::state::{MAX_MIX, SLOTS, Universes};
use footlight_fixture::{Beam, Fixture, FixtureModel, FixtureState, FixtureType, Light, Manual, Patch, PatchError};
use footlight_photometry::{Chroma, CmyFilters, DimmerCurve, Emitter, Gel, Lamp, Sampled};
use gdtf::wheel::WheelSlotOptic;
use glam::{DMat4, DQuat, Quat, Vec2, Vec3};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// An imported MVR: the patch, what did not stop the import, and the scene
/// (venue geometry, truss, focus points) for the lead's scene wiring.
#[derive(Clone, Debug)]
pub struct Import {
    /// The patch: one fixture per emitting MVR fixture.
    pub patch: Patch,
    /// Problems that did not stop the import (missing GDTFs, unsupported
    /// attributes…), each said once per file and problem at the line of the
    /// element concerned, with the fixtures (and cells) it concerns ([`crate::report`]).
    pub warnings: Vec<PatchError>,
    /// How names were read that are not quite what the file says (a
    /// `GDTFSpec` without `.gdtf`); one line each, not a problem.
    pub notes: Vec<PatchError>,
    /// One summary per fixture type (GDTFSpec), in the order the show first names them.
    pub types: Vec<TypeSummary>,
    /// The flattened MVR scene.
    pub scene: Scene,
}

/// The first `<Beam>` instance under `node`, depth-first.
pub fn first_beam(node: &GeometryNode) -> Option<(&GeometryNode, BeamInfo)> {
    if let GeometryKind::Beam(b) = &node.kind {
        return Some((node, *b));
    }
    node.children.iter().find_map(first_beam)
}

/// A GDTF file as a Footlight fixture type (every mode), with one warning
/// per unsupported attribute set. `None` in the error position means the
/// type has no beam (a hazer, a truss…): not a light.
pub fn fixture_type(g: &Gdtf) -> Result<(FixtureType, Vec<PatchError>), PatchError> {
    let label = g.label.join("description.xml");
    let mut warnings = Vec::new();
    let layouts: Vec<Layout> = g.mode_names().iter().map(|m| g.layout(m)).collect::<Result<_, _>>()?;
    let Some((_, beam)) = layouts.iter().find_map(|l| first_beam(&l.root)) else {
        return Err(PatchError::new(&label, 0, "no <Beam> geometry in any mode: not a light"));
    };
    let all = || layouts.iter().flat_map(|l| l.channels.iter());
    // Optics.
    let (mut beam_angle, mut field_angle) = (beam.beam_angle as f32, beam.field_angle as f32);
    if !(beam_angle > 0.0 && beam_angle <= 180.0) {
        warnings.push(PatchError::new(&label, 0, format!("BeamAngle {beam_angle} is not in (0, 180]; 25 used")));
        beam_angle = 25.0;
    }
    if !(field_angle >= beam_angle && field_angle <= 180.0) {
        field_angle = beam_angle;
    }
    let ratio = (beam_angle / field_angle).clamp(0.05, 1.0);
    let zoom = match all().find(|c| c.attribute == "Zoom").and_then(|c| c.functions.first()) {
        Some(f) => [f.physical_from as f32 / ratio, f.physical_to as f32 / ratio].map(|a| a.clamp(0.5, 180.0)),
        None => [field_angle; 2],
    };
    let iris_min = all()
        .find(|c| c.attribute == "Iris")
        .and_then(|c| c.functions.first())
        .map(|f| (f.physical_from.min(f.physical_to) as f32).clamp(0.01, 0.99));
    let lo = zoom[0].min(zoom[1]);
    let omega = SpotBeam::from_beam_field(lo * ratio, lo).solid_angle();
    let flux = if beam.flux_lm.is_finite() && beam.flux_lm > 0.0 { beam.flux_lm as f32 } else { 10_000.0 };
    let intensity = if omega > 0.0 { flux / omega } else { 0.0 };
    let optics = Optics::Spot(SpotOptics::new(zoom, [ratio; 2], intensity, lo, iris_min));
    // Lamp and colour mixing.
    let cct = if (1000.0..=20000.0).contains(&beam.cct_k) { beam.cct_k as f32 } else { 6000.0 };
    let mut mix_names: Vec<String> = Vec::new();
    let mut emitters = Vec::new();
    // ColorAdd_* channels no <Emitter> colours (many real files define none):
    // mixed from the attribute definitions' colours, else GDTF's nominal ones
    // (`crate::colour`), said once per type.
    let mut uncoloured: Vec<String> = Vec::new();
    for c in all().filter(|c| c.attribute.starts_with("ColorAdd_")) {
        if mix_names.contains(&c.attribute) || uncoloured.contains(&c.attribute) {
            continue;
        }
        let e = c
            .functions
            .iter()
            .find_map(|f| f.emitter.as_deref())
            .and_then(|name| g.ft.physical_descriptions.emitters.iter().find(|e| e.name.as_deref() == Some(name)));
        match e.and_then(|e| emitter(e, &c.attribute.to_ascii_lowercase())) {
            Some(em) if mix_names.len() < MAX_MIX => {
                emitters.push(em);
                mix_names.push(c.attribute.clone());
            }
            Some(_) => {}
            None => uncoloured.push(c.attribute.clone()),
        }
    }
    if !uncoloured.is_empty() {
        let note = attribute_emitters(g, &uncoloured, &mut emitters, &mut mix_names);
        warnings.push(PatchError::new(&label, 0, note));
    }
    let cmy = ["ColorSub_C", "ColorSub_M", "ColorSub_Y"];
    let lamp = if !emitters.is_empty() {
        Lamp::Led { emitters }
    } else if all().any(|c| cmy.contains(&c.attribute.as_str())) {
        mix_names = cmy.map(String::from).to_vec();
        let filters = cmy_filters(g, &layouts, &cmy);
        Lamp::Cmy { cct, cyan: 0.0, magenta: 0.0, yellow: 0.0, filters }
    } else {
        match beam.lamp_type {
            LampType::Tungsten | LampType::Halogen => Lamp::Tungsten { cct_full: cct },
            _ => Lamp::Discharge { cct },
        }
    };
    let movement = {
        let span = |a: &str| {
            all()
                .find(|c| c.attribute == a)
                .and_then(|c| c.functions.first())
                .map(|f| (f.physical_to - f.physical_from).abs() as f32)
        };
        match (span("Pan"), span("Tilt")) {
            (None, None) => None,
            (p, t) => {
                Some(Movement { pan: p.unwrap_or(0.0).clamp(1e-3, 720.0), tilt: t.unwrap_or(0.0).clamp(1e-3, 720.0) })
            }
        }
    };
    // An LED type's own white for CTO/CTB/CTC corrections: the beam's colour temperature.
    let lamp_cct = lamp.temperature(1.0).or(Some(cct));
    // Colour wheels 2-4 and the colour-macro wheel (docs/mvr-gdtf.md, "Attributes").
    let extra_wheels: Vec<Vec<WheelSlot>> = ["Color2", "Color3", "Color4"]
        .iter()
        .map(|a| linked_wheel(g, &layouts, a, &mut warnings).map(|w| wheel_slots(g, w)).unwrap_or_default())
        .collect();
    let colour_macros = linked_wheel(g, &layouts, "ColorMacro1", &mut warnings)
        .map(|w| macro_colours(g, w))
        .filter(|m| m.iter().any(Option::is_some))
        .unwrap_or_default();
    let wheel_names: Vec<&str> = if colour_macros.is_empty() { Vec::new() } else { vec!["ColorMacro1"] };
    let ctx = MapContext {
        mix: &mix_names,
        moving: movement.is_some(),
        unmixed: !matches!(lamp, Lamp::Led { .. } | Lamp::Cmy { .. }),
        cct: lamp_cct.unwrap_or(cct),
        wheels: &wheel_names,
    };
    let mut unsupported: Vec<String> = Vec::new();
    let mut modes = Vec::new();
    for l in &layouts {
        let mut channels = Vec::new();
        let mut footprint = 0u16;
        let mut later_breaks = false;
        let masters = masters(l);
        // Channels other functions name as their mode master.
        let selecting: std::collections::BTreeSet<&str> = l
            .channels
            .iter()
            .flat_map(|c| c.functions.iter())
            .filter_map(|f| f.mode_master.as_ref().and_then(|m| m.0.split('.').next()))
            .collect();
        for c in &l.channels {
            if c.offsets.is_empty() {
                continue;
            }
            // Later breaks: offsets from BREAK_STRIDE · (break − 1) (see `TypedFixture::breaks`).
            let Some(base) = break_base(c.dmx_break) else {
                later_breaks = true;
                continue;
            };
            if c.dmx_break == 1 {
                footprint = footprint.max(*c.offsets.iter().max().unwrap_or(&0));
            }
            let (mut attribute, range) = map_attribute(c, &ctx);
            if attribute == Attribute::Other && selecting.contains(format!("{}_{}", c.template, c.attribute).as_str()) {
                attribute = Attribute::Mode; // its value selects other channels' functions
            }
            let functions = channel_functions(c, attribute, &ctx, &masters);
            if attribute == Attribute::Other && !unsupported.contains(&c.attribute) {
                unsupported.push(c.attribute.clone());
            }
            let curve = c
                .functions
                .first()
                .and_then(|f| f.dmx_profile.as_deref())
                .map(|p| profile_curve(g, p))
                .unwrap_or_default();
            let fine = c.offsets.get(1).map(|o| o.saturating_sub(1));
            let default = match c.offsets.len() {
                1 => c.default.min(255),
                n => (c.default >> (8 * (n - 2).min(6))).min(65535),
            } as u16;
            channels.push(Channel {
                attribute,
                name: c.attribute.to_ascii_lowercase(),
                offset: base + c.offsets[0].saturating_sub(1).min(BREAK_STRIDE - 1),
                fine: fine.map(|o| base + o.min(BREAK_STRIDE - 1)),
                default,
                curve,
                range,
                scroller: None,
                functions,
                line: 0,
            });
        }
        if later_breaks {
            warnings.push(PatchError::new(
                &label,
                0,
                format!("mode {:?}: channels on DMX breaks past {MAX_BREAKS} are not decoded", l.mode),
            ));
        }
        let overrides = override_relations(l, &mut channels).map_err(|m| PatchError::new(&label, 0, m))?;
        modes.push(Mode { name: l.mode.clone(), channels, footprint: footprint.min(SLOTS as u16), line: 0, overrides });
    }
    if !unsupported.is_empty() {
        // One warning per type, each attribute with the line of its first channel.
        let lines: Vec<String> = unsupported.iter().map(|a| format!("{a} (line {})", g.attribute_line(a))).collect();
        warnings.push(PatchError::new(
            &label,
            g.attribute_line(&unsupported[0]),
            format!(
                "{}: {}: {}; their channels keep their slots",
                g.name(),
                crate::report::NOT_MODELLED,
                lines.join(", ")
            ),
        ));
    }
    let ty = FixtureType {
        name: g.name(),
        maker: g.ft.manufacturer.clone(),
        path: g.label.clone(),
        lamp: lamp.clone(),
        mix_names: mix_names.iter().map(|n| n.to_ascii_lowercase()).collect(),
        optics,
        movement,
        colour_wheel: colour_wheel(g, &layouts, &mut warnings),
        cto: cto_table(&layouts, &lamp_cct),
        gate: crate::gate::gate_optics(g, &layouts, &mut warnings),
        modes,
        extra_wheels,
        colour_macros,
    };
    warnings.extend(g.model_warnings());
    // Every warning about the file at the line of what it names (issue 36 item 3).
    g.locate(&mut warnings);
    Ok((ty, warnings))
}

/// What [`map_name`] needs to know of the type.
pub(crate) struct MapContext<'a> {
    /// The colour-mix attributes, in [`FixtureState::mix`] order.
    pub mix: &'a [String],
    /// The type has a yoke (pan and tilt channels move it).
    pub moving: bool,
    /// No colour-mix channel could be mixed (no emitter colours): additive
    /// colour channels scale intensity instead ([`Attribute::Level`]).
    pub unmixed: bool,
    /// The lamp's (beam's) colour temperature, K.
    pub cct: f32,
    /// Colour wheels 1-4 and the colour-macro wheel the type links (by attribute: `Color1` … `ColorMacro1`).
    pub wheels: &'a [&'a str],
}

/// Footlight attribute and real-unit range of a GDTF channel (its first
/// logical channel's attribute and first function's physical range).
fn map_attribute(c: &ChannelInfo, ctx: &MapContext) -> (Attribute, [f32; 2]) {
    let phys = c.functions.first().map(|f| [f.physical_from as f32, f.physical_to as f32]).unwrap_or([0.0, 1.0]);
    map_name(&c.attribute, phys, c.functions.iter().any(|f| f.wheel.is_some()), ctx)
}

/// Footlight attribute and real-unit range of a GDTF attribute `a` with
/// physical range `phys` (`wheel`: the channel links a wheel). The table of
/// what each attribute becomes is in docs/mvr-gdtf.md.
pub(crate) fn map_name(a: &str, phys: [f32; 2], wheel: bool, ctx: &MapContext) -> (Attribute, [f32; 2]) {
    let unit = [0.0, 1.0];
    if let Some(gate) = crate::gate::gate_attribute(a, wheel) {
        return (gate, unit);
    }
    let percent = |r: [f32; 2]| if r[0].abs().max(r[1].abs()) > 1.0 { r.map(|x| x / 100.0) } else { r };
    match a {
        "Dimmer" => (Attribute::Dimmer, percent(phys).map(|x| x.clamp(0.0, 1.0))),
        a if is_shutter(a) => (Attribute::Shutter, unit),
        "Color1" if wheel => (Attribute::ColourWheel, unit),
        "Color2" | "Color3" | "Color4" if wheel => (Attribute::ColourWheelN(a.as_bytes()[5] - b'2'), unit),
        "ColorMacro1" if wheel && ctx.wheels.contains(&"ColorMacro1") => (Attribute::ColourMacro, unit),
        "CTO" | "CTB" | "CTC" => (Attribute::Cto, cto_kelvin(a, phys, ctx.cct)),
        a if is_tint(a) => (Attribute::Tint, tint_duv(phys)),
        "HSB_Hue" => {
            (Attribute::Hue, if phys[0].abs().max(phys[1].abs()) <= 1.0 { phys.map(|x| x * 360.0) } else { phys })
        }
        "HSB_Saturation" => (Attribute::Saturation, percent(phys)),
        "HSB_Brightness" => (Attribute::HsbBrightness, percent(phys)),
        "CIE_X" => (Attribute::CieX, percent(phys)),
        "CIE_Y" => (Attribute::CieY, percent(phys)),
        "CIE_Brightness" => (Attribute::CieBrightness, percent(phys)),
        "DimmerCurve" | "DimmerMode" => (Attribute::DimmerCurve, unit),
        "StrobeDuration" => (Attribute::StrobeDuration, phys),
        "ColorMixMode" | "LEDZoneMode" => (Attribute::Mode, unit),
        "Pan" if ctx.moving => (Attribute::Pan, phys),
        "Tilt" if ctx.moving => (Attribute::Tilt, phys),
        "Zoom" => (Attribute::Zoom, phys),
        "Focus1" => (Attribute::Focus, phys.map(|x| x.clamp(0.0, 1.0))),
        "Iris" => (Attribute::Iris, phys.map(|x| x.clamp(0.0, 1.0))),
        a => match ctx.mix.iter().position(|m| m == a) {
            Some(i) => (Attribute::Mix(i as u8), unit),
            None if ctx.unmixed && (a.starts_with("ColorAdd_") || a.starts_with("ColorRGB_")) => {
                (Attribute::Level, unit)
            }
            None => (Attribute::Other, unit),
        },
    }
}

/// A green/magenta tint attribute: GDTF `Tint`, or a maker's own name for it
/// (`Green/Magenta`, `MagentaGreen`, `Green-Magenta`…), ASCII case and
/// punctuation ignored.
fn is_tint(a: &str) -> bool {
    let k: String = a.chars().filter(char::is_ascii_alphanumeric).collect::<String>().to_ascii_lowercase();
    matches!(k.as_str(), "tint" | "greenmagenta" | "magentagreen" | "plusminusgreen" | "gm" | "mg")
}

/// A tint channel's physical range as Duv (positive: green): a range with
/// negative and positive ends reads p / max|p| of a full tint
/// ([`FULL_TINT_DUV`]); a range of one sign (`0..1`, `0..100`) runs from
/// full magenta at its start through neutral at its middle to full green
/// at its end. Estimated (GDTF gives Tint no unit).
fn tint_duv(phys: [f32; 2]) -> [f32; 2] {
    let m = phys[0].abs().max(phys[1].abs());
    if !(m > 0.0 && m.is_finite()) {
        return [0.0, 0.0];
    }
    if phys[0].min(phys[1]) < 0.0 && phys[0].max(phys[1]) > 0.0 {
        phys.map(|p| FULL_TINT_DUV * p / m)
    } else {
        [-FULL_TINT_DUV, FULL_TINT_DUV]
    }
}

/// A full CTO in mired (LEE 204, 5600 K → 3200 K) and a full CTB (LEE 201, 3200 K → 5600 K).
const FULL_CTO_MIRED: f32 = 159.0;
const FULL_CTB_MIRED: f32 = -137.0;

/// The target colour temperatures (K) at the ends of a CTO/CTB/CTC
/// channel: its physical range when both ends are kelvin (1000-20,000),
/// else a fraction of a full correction from the type's own CCT `cct`
/// (CTO: to +159 mired, CTB: to −137 mired; CTC: from the full CTB at the
/// start to the full CTO at the end), interpolated linearly in kelvin
/// between those ends (estimated).
fn cto_kelvin(a: &str, phys: [f32; 2], cct: f32) -> [f32; 2] {
    if phys.iter().all(|k| (1000.0..=20000.0).contains(k)) {
        return phys;
    }
    let k = |mired: f32| (1e6 / (1e6 / cct + mired)).clamp(1000.0, 20000.0);
    match a {
        "CTO" => [cct, k(FULL_CTO_MIRED)],
        "CTB" => [cct, k(FULL_CTB_MIRED)],
        _ => [k(FULL_CTB_MIRED), k(FULL_CTO_MIRED)],
    }
}

/// GDTF shutter attributes of the first shutter (`Shutter1`, `Shutter1Strobe…`, `StrobeFrequency`).
fn is_shutter(a: &str) -> bool {
    a == "Shutter1" || a.starts_with("Shutter1Strobe") || a == "StrobeFrequency"
}

/// A wheel channel function as Footlight functions: one `Slot` per channel
/// set naming a wheel slot (GDTF slots count from 1), else the whole
/// function as `Hold`. Shared by colour, gobo and prism wheels.
pub(crate) fn wheel_slot_functions(
    f: &crate::gdtf::FunctionInfo,
    range: [f32; 2],
    raw16: &dyn Fn(u64) -> u16,
) -> Vec<Function> {
    let slots: Vec<Function> = if f.wheel.is_some() {
        f.sets
            .iter()
            .filter_map(|s| s.wheel_slot.filter(|i| *i >= 1).map(|i| (s, i)))
            .map(|(s, i)| Function {
                from: raw16(s.dmx_from),
                to: raw16(s.dmx_to),
                action: Action::Slot((i - 1) as u16),
                range,
                mode: None,
            })
            .collect()
    } else {
        Vec::new()
    };
    if slots.is_empty() {
        return vec![Function {
            from: raw16(f.dmx_from),
            to: raw16(f.dmx_to),
            action: Action::Hold,
            range,
            mode: None,
        }];
    }
    slots
}

/// A raw DMX value at `bytes` of resolution as Footlight reads the channel
/// (8-bit, or 16-bit from coarse and fine: a 24-bit value loses its last byte).
fn raw16(v: u64, bytes: u8) -> u16 {
    let v = if bytes > 2 { v >> (8 * u32::from(bytes - 2).min(6)) } else { v };
    v.min(u64::from(u16::MAX)) as u16
}

/// The dimmer curve a `DimmerCurve`/`DimmerMode` channel set or function
/// names: `linear`; `square` (also `quadratic`, `exponential`, `TV`) →
/// square law; `S-curve` (also `theatre`/`theater`) → the theatre S-curve.
/// Other names (logarithmic, inverse square, speed modes) select nothing:
/// the dimmers keep their own curves.
fn named_curve(name: &str) -> Option<DimmerCurve> {
    let k: String = name.chars().filter(char::is_ascii_alphanumeric).collect::<String>().to_ascii_lowercase();
    if k.contains("inverse") || k.contains("log") {
        None
    } else if k.contains("scurve") || k.contains("theat") {
        Some(DimmerCurve::Theatre)
    } else if k.contains("square") || k.contains("quadr") || k.contains("expo") || k == "tv" {
        Some(DimmerCurve::SquareLaw)
    } else if k.contains("lin") {
        Some(DimmerCurve::Linear)
    } else {
        None
    }
}

/// Mode masters of a layout: the channel named `Geometry_Attribute` (GDTF's
/// DMX channel name), its instances (geometry instance, slot offsets, bytes).
pub(crate) type Masters = BTreeMap<String, Vec<(String, (u16, Option<u16>), u8)>>;

/// Every channel instance of `l` by its DMX channel name, for mode masters.
pub(crate) fn masters(l: &Layout) -> Masters {
    let mut out: Masters = BTreeMap::new();
    for c in &l.channels {
        let Some(base) = break_base(c.dmx_break) else { continue };
        let at = |o: u16| base + o.saturating_sub(1).min(BREAK_STRIDE - 1);
        let Some(&first) = c.offsets.first() else { continue };
        out.entry(format!("{}_{}", c.template, c.attribute)).or_default().push((
            c.geometry.clone(),
            (at(first), c.offsets.get(1).map(|o| at(*o))),
            c.bytes(),
        ));
    }
    out
}

/// The mode master of function `f` of channel `c` as a [`ModeGate`]: the
/// master's instance in the same geometry reference as `c` (a cell's own
/// master), else its first instance. `None` without a mode master or when
/// the master names no channel of the mode (then the function always applies).
pub(crate) fn mode_gate(f: &FunctionInfo, c: &ChannelInfo, masters: &Masters) -> Option<ModeGate> {
    let (node, from, to) = f.mode_master.as_ref()?;
    let instances = masters.get(node.split('.').next()?)?;
    let cell = |g: &str| g.split('.').next().unwrap_or(g).to_string();
    let own = cell(&c.geometry);
    let (_, master, bytes) = instances.iter().find(|(g, _, _)| cell(g) == own).or(instances.first())?;
    Some(ModeGate { master: *master, from: raw16(*from, *bytes), to: raw16(*to, *bytes) })
}

/// The DMX ranges of a channel (`attribute` its Footlight attribute) as
/// [`Function`]s, each with its mode master ([`mode_gate`]):
/// * shutter functions: open and closed by their channel-set names, else
///   by the physical value ≥ 0.5; strobe functions with their physical range in Hz;
/// * colour wheels 1-4, the colour-macro wheel: slots from the channel
///   sets' `WheelSlotIndex` (1-based in the file, 0-based here);
/// * gobo, prism and gate channels: [`crate::gate::gate_functions`];
/// * `DimmerCurve`/`DimmerMode`: each channel set (else function) naming a
///   curve ([`named_curve`]);
/// * any other channel whose functions a mode master selects, or whose
///   functions control different attributes: each function sets its own
///   attribute over its physical range ([`Action::Set`]).
///
/// Empty for a plain channel: the whole range is the attribute's.
fn channel_functions(c: &ChannelInfo, attribute: Attribute, ctx: &MapContext, masters: &Masters) -> Vec<Function> {
    let bytes = c.bytes().max(1);
    let raw = |v: u64| raw16(v, bytes);
    let gated = c.functions.iter().any(|f| f.mode_master.is_some());
    let mapped = |f: &FunctionInfo| {
        map_name(&f.attribute, [f.physical_from as f32, f.physical_to as f32], f.wheel.is_some(), ctx)
    };
    let mixed_attributes = c.functions.iter().any(|f| mapped(f).0 != attribute);
    let mut out = Vec::new();
    for f in &c.functions {
        let (from, to) = (raw(f.dmx_from), raw(f.dmx_to));
        let range = [f.physical_from as f32, f.physical_to as f32];
        let mut here: Vec<Function> = match attribute {
            Attribute::Shutter => vec![Function { from, to, action: shutter_action(f, range), range, mode: None }],
            Attribute::ColourWheel | Attribute::ColourWheelN(_) | Attribute::ColourMacro => {
                wheel_slot_functions(f, range, &raw)
            }
            Attribute::Gobo | Attribute::Gobo2 | Attribute::Animation | Attribute::Prism | Attribute::Gate => {
                crate::gate::gate_functions_of(f, attribute, &raw)
            }
            Attribute::DimmerCurve => {
                // A set naming no curve (logarithmic, a speed) holds: the dimmers keep their own.
                let sets: Vec<Function> = f
                    .sets
                    .iter()
                    .map(|s| Function {
                        from: raw(s.dmx_from),
                        to: raw(s.dmx_to),
                        action: named_curve(&s.name).map_or(Action::Hold, Action::Curve),
                        range,
                        mode: None,
                    })
                    .collect();
                if sets.is_empty() {
                    let action = named_curve(&f.name).map_or(Action::Hold, Action::Curve);
                    vec![Function { from, to, action, range, mode: None }]
                } else {
                    sets
                }
            }
            _ if gated || mixed_attributes => {
                let (a, r) = mapped(f);
                let action = match a {
                    Attribute::Shutter => shutter_action(f, range),
                    Attribute::Other | Attribute::Mode | Attribute::Scroller => Action::Hold,
                    Attribute::ColourWheel
                    | Attribute::ColourWheelN(_)
                    | Attribute::ColourMacro
                    | Attribute::Gobo
                    | Attribute::Gobo2
                    | Attribute::Animation
                    | Attribute::Prism
                    | Attribute::Gate
                    | Attribute::DimmerCurve => Action::Hold,
                    a => Action::Set(a),
                };
                vec![Function { from, to, action, range: r, mode: None }]
            }
            _ => return Vec::new(),
        };
        let mode = mode_gate(f, c, masters);
        here.iter_mut().for_each(|h| h.mode = mode);
        out.extend(here);
    }
    out.sort_by_key(|f| f.from);
    out
}

/// A shutter channel function's action: `Shutter1` open or closed by its
/// channel-set names ("Open"/"Closed"), else by its physical value ≥ 0.5;
/// strobe attributes strobe at their physical range in Hz.
fn shutter_action(f: &FunctionInfo, range: [f32; 2]) -> Action {
    let named = |w: &str| f.sets.iter().any(|s| s.name.to_ascii_lowercase().contains(w));
    if f.attribute == "Shutter1" {
        if named("open") {
            Action::Open
        } else if named("close") {
            Action::Closed
        } else if (range[0] + range[1]) / 2.0 >= 0.5 {
            Action::Open
        } else {
            Action::Closed
        }
    } else if is_shutter(&f.attribute) {
        Action::Strobe
    } else {
        Action::Hold
    }
}

/// The slots of the wheel the first channel with `attribute` links, by
/// `slot` (`None`: no such channel or wheel; a warning when the link names
/// a wheel the file lacks).
fn linked_wheel<'a>(
    g: &'a Gdtf,
    layouts: &[Layout],
    attribute: &str,
    warnings: &mut Vec<PatchError>,
) -> Option<&'a gdtf::wheel::Wheel> {
    let name = layouts
        .iter()
        .flat_map(|l| l.channels.iter())
        .flat_map(|c| c.functions.iter())
        .filter(|f| f.attribute == attribute)
        .find_map(|f| f.wheel.clone())?;
    let wheel = g.ft.wheels.iter().find(|w| w.name.as_deref() == Some(name.as_str()));
    if wheel.is_none() {
        warnings.push(PatchError::new(
            &g.label.join("description.xml"),
            0,
            format!("{attribute} links wheel {name:?}, which the file does not define; it stays open"),
        ));
    }
    wheel
}

/// A colour wheel's slots as c_F: each slot's linked filter's measured
/// spectrum when it has one, else its CIE xyY ([`wheel_factor`]).
fn wheel_slots(g: &Gdtf, wheel: &gdtf::wheel::Wheel) -> Vec<WheelSlot> {
    wheel
        .slots
        .iter()
        .map(|slot| {
            if let Some(gel) = slot.filter(&g.ft).and_then(|f| filter_gel(f, slot.name.as_deref().unwrap_or("slot"))) {
                return WheelSlot::Filter(Arc::new(gel));
            }
            match &slot.optic {
                WheelSlotOptic::Color(c) => WheelSlot::Factor(wheel_factor(c.x as f32, c.y as f32, c.z as f32)),
                WheelSlotOptic::Filter(_) => match slot.filter(&g.ft) {
                    Some(f) => WheelSlot::Factor(wheel_factor(f.color.x as f32, f.color.y as f32, f.color.z as f32)),
                    None => WheelSlot::Factor(Vec3::ONE),
                },
            }
        })
        .collect()
}

/// The colour-macro wheel's slot colours (CIE xy of the slot's `Color`, or
/// of its linked filter's); `None` for a slot without a usable colour.
fn macro_colours(g: &Gdtf, wheel: &gdtf::wheel::Wheel) -> Vec<Option<Vec2>> {
    wheel
        .slots
        .iter()
        .map(|slot| {
            let c = match &slot.optic {
                WheelSlotOptic::Color(c) => Some(*c),
                WheelSlotOptic::Filter(_) => slot.filter(&g.ft).map(|f| f.color),
            }?;
            let xy = Vec2::new(c.x as f32, c.y as f32);
            (xy.x > 0.0 && xy.y > 0.0 && xy.x + xy.y < 1.0).then_some(xy)
        })
        .collect()
}

/// The colour wheel the first `Color1` channel links: a c_F per slot
/// ([`wheel_slots`]).
fn colour_wheel(g: &Gdtf, layouts: &[Layout], warnings: &mut Vec<PatchError>) -> Vec<WheelSlot> {
    linked_wheel(g, layouts, "Color1", warnings).map(|w| wheel_slots(g, w)).unwrap_or_default()
}

/// Emitters for the `ColorAdd_*` channels in `uncoloured` (no `<Emitter>`
/// colours them): from the file's attribute definitions' `Color` (CIE xyY),
/// else GDTF's nominal attribute colours (estimated; [`crate::colour`]),
/// each through [`Emitter::new`] like an emitter's CIE colour without a
/// measurement. Appends them (up to [`MAX_MIX`] mixed channels in all) and
/// returns the type's one note, e.g. `Astera AX2: no emitters;
/// ColorAdd_R/G/B/W mixed from the attribute definitions' colours
/// (estimated primaries for ColorAdd_RY: GDTF Annex B's nominal colours)`.
fn attribute_emitters(g: &Gdtf, uncoloured: &[String], emitters: &mut Vec<Emitter>, mix: &mut Vec<String>) -> String {
    use crate::colour::{Source, primaries, short_list};
    let defs = &g.ft.attribute_definitions;
    let colour = |a: &str| {
        defs.attributes
            .iter()
            .find(|d| d.name.as_ref().is_some_and(|n| n.as_ref().eq_ignore_ascii_case(a)))
            .and_then(|d| d.color.as_ref())
            .map(|c| [c.x, c.y, c.z])
    };
    let (primaries, unknown) = primaries(uncoloured, &colour);
    let mut dropped: Vec<&str> = Vec::new();
    let mut used: Vec<&crate::colour::Primary> = Vec::new();
    for p in &primaries {
        if mix.len() >= MAX_MIX {
            dropped.push(&p.attribute);
            continue;
        }
        emitters.push(Emitter::new(p.attribute.to_ascii_lowercase(), Chroma::Xy(p.xy), p.share));
        mix.push(p.attribute.clone());
        used.push(p);
    }
    let names =
        |s: Source| -> Vec<&str> { used.iter().filter(|p| p.source == s).map(|p| p.attribute.as_str()).collect() };
    let (file, nominal) = (names(Source::File), names(Source::Nominal));
    let mut note = if g.ft.physical_descriptions.emitters.is_empty() {
        format!("{}: no emitters", g.name())
    } else {
        let all: Vec<&str> = uncoloured.iter().map(String::as_str).collect();
        format!("{}: no emitter for {}", g.name(), short_list(&all))
    };
    match (file.is_empty(), nominal.is_empty()) {
        (false, true) => note += &format!("; {} mixed from the attribute definitions' colours", short_list(&file)),
        (false, false) => {
            note += &format!(
                "; {} mixed from the attribute definitions' colours (estimated primaries for {}: GDTF Annex B's nominal colours)",
                short_list(&file),
                short_list(&nominal)
            )
        }
        (true, false) => {
            note +=
                &format!("; {} mixed from estimated primaries (GDTF Annex B's nominal colours)", short_list(&nominal))
        }
        (true, true) => {}
    }
    let weighted: Vec<&str> = used.iter().filter(|p| p.weighted).map(|p| p.attribute.as_str()).collect();
    if !weighted.is_empty() {
        note += &format!("; luminous shares of {} by equal-white weighting (no usable Y)", short_list(&weighted));
    }
    if !unknown.is_empty() {
        let u: Vec<&str> = unknown.iter().map(String::as_str).collect();
        note += &format!("; {}: no colour known, decoded but not mixed", short_list(&u));
    }
    if !dropped.is_empty() {
        note += &format!("; {}: past {MAX_MIX} mixed channels, not mixed", short_list(&dropped));
    }
    note
}

/// An LED emitter from a GDTF `<Emitter>`: from its measured spectrum when
/// it has a `<Measurement>` with at least two points (the one with the
/// highest `Physical`, i.e. the emitter at full; its shape is taken to hold
/// at every level), else from its CIE xy. The luminous share is the
/// `Color`'s Y when the file gives one, else the measurement's
/// `LuminousIntensity`, else the spectrum's own luminance (so emitters
/// measured on one scale mix by their measured output). `None` when
/// neither a usable spectrum nor a usable xy is given.
fn emitter(e: &gdtf::physical_descriptions::Emitter, name: &str) -> Option<Emitter> {
    let xy_y = match e.optic {
        gdtf::physical_descriptions::EmitterOptic::Color { color, .. } => {
            Some((Vec2::new(color.x as f32, color.y as f32), color.z as f32))
        }
        _ => None,
    };
    let file_y = xy_y.map(|(_, y)| y).filter(|y| *y > 0.0 && y.is_finite());
    let spectral = e.measurements.iter().max_by(|a, b| a.physical.total_cmp(&b.physical)).and_then(|m| {
        let pts: Vec<(f64, f64)> = m.points.iter().map(|p| (p.wave_length, p.energy)).collect();
        let share = file_y.or(m.luminous_intensity.map(|i| i as f32).filter(|i| *i > 0.0 && i.is_finite()));
        Emitter::from_spectrum(name, &Sampled::from_points(&pts)?, share)
    });
    spectral.or_else(|| match xy_y {
        Some((xy, y)) if xy.x > 0.0 && xy.y > 0.0 && xy.x + xy.y < 1.0 => {
            Some(Emitter::new(name, Chroma::Xy(xy), y.max(1e-3)))
        }
        _ => None,
    })
}

/// Measured CMY flags: each `ColorSub_C/M/Y` channel function whose `Filter`
/// has a measurement gives that flag's full-insertion transmission
/// ([`filter_gel`]); the others keep the ideal band model. `None` when no
/// flag is measured.
fn cmy_filters(g: &Gdtf, layouts: &[Layout], cmy: &[&str; 3]) -> Option<Arc<CmyFilters>> {
    let flag = |attr: &str| {
        layouts
            .iter()
            .flat_map(|l| l.channels.iter())
            .filter(|c| c.attribute == attr)
            .flat_map(|c| c.functions.iter())
            .find_map(|f| f.filter.as_deref())
            .and_then(|name| g.ft.physical_descriptions.filters.iter().find(|f| f.name.as_deref() == Some(name)))
            .and_then(|f| filter_gel(f, attr))
            .map(|gel| gel.sampled().clone())
    };
    let [c, m, y] = cmy.map(flag);
    (c.is_some() || m.is_some() || y.is_some()).then(|| Arc::new(CmyFilters::new(c, m, y)))
}

/// A GDTF filter's first measurement as a gel: transmission at 5 nm from
/// 380 to 780 nm, interpolated linearly between the measured points
/// (values over 1 are read as percent). `None` without at least two points.
fn filter_gel(f: &gdtf::physical_descriptions::Filter, name: &str) -> Option<Gel> {
    let m = f.measurements.first()?;
    let mut pts: Vec<(f64, f64)> = m.points.iter().map(|p| (p.wave_length, p.energy)).collect();
    pts.retain(|p| p.0.is_finite() && p.1.is_finite());
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    if pts.len() < 2 {
        return None;
    }
    let scale = if pts.iter().any(|p| p.1 > 1.0) { 0.01 } else { 1.0 };
    let at = |nm: f64| -> f32 {
        let i = pts.partition_point(|p| p.0 < nm);
        let v = match i {
            0 => pts[0].1,
            i if i >= pts.len() => pts[pts.len() - 1].1,
            i => {
                let ((x0, y0), (x1, y1)) = (pts[i - 1], pts[i]);
                if x1 > x0 { y0 + (y1 - y0) * (nm - x0) / (x1 - x0) } else { y1 }
            }
        };
        (v * scale) as f32
    };
    let samples: Vec<f32> = (0..=80).map(|k| at(380.0 + 5.0 * f64::from(k))).collect();
    let label = f.name.as_deref().unwrap_or(name).to_string();
    Some(Gel::from_samples(label.clone(), label, 380.0, 5.0, samples))
}

/// The CTO/CTB/CTC table from the lamp's CCT (an LED type's: its beam's
/// colour temperature) over the first correction channel's targets ([`cto_kelvin`]).
fn cto_table(layouts: &[Layout], cct: &Option<f32>) -> Option<CorrectionTable> {
    let from = (*cct)?;
    let f = layouts
        .iter()
        .flat_map(|l| l.channels.iter())
        .flat_map(|c| c.functions.iter())
        .find(|f| matches!(f.attribute.as_str(), "CTO" | "CTB" | "CTC"))?;
    Some(CorrectionTable::new(from, cto_kelvin(&f.attribute, [f.physical_from as f32, f.physical_to as f32], from)))
}

/// The dimmer curve of a GDTF DMX profile: a single cubic segment
/// y = x² is the square law; anything else is read as linear.
fn profile_curve(g: &Gdtf, name: &str) -> DimmerCurve {
    let p = g.ft.physical_descriptions.dmx_profiles.iter().find(|p| p.name.as_deref() == Some(name));
    match p.map(|p| p.points.as_slice()) {
        Some([pt])
            if pt.cfc0.abs() < 1e-9 && pt.cfc1.abs() < 1e-9 && (pt.cfc2 - 1.0).abs() < 1e-9 && pt.cfc3.abs() < 1e-9 =>
        {
            DimmerCurve::SquareLaw
        }
        _ => DimmerCurve::Linear,
    }
}

/// Reads an MVR file as a patch: every problem that stops it, or the
/// import with its warnings. GDTF files are parsed once each.
pub fn load_mvr(path: &Path) -> Result<Import, Vec<PatchError>> {
    let m = Mvr::open(path).map_err(|e| vec![e])?;
    build(path, m)
}

/// Wall time of [`load_mvr`] for the benchmark: seconds to read and build.
pub fn time_load_mvr(path: &Path) -> Result<f64, Vec<PatchError>> {
    let t = std::time::Instant::now();
    load_mvr(path)?;
    Ok(t.elapsed().as_secs_f64())
}

/// A parsed type and its first beam's offset from the fixture origin (GDTF
/// axes, metres); or why not: `None` when the archive lacks the file, else
/// the file's error.
type TypeEntry = Result<(Arc<FixtureType>, Vec3), Option<PatchError>>;

/// What the import knows of one `GDTFSpec`: the type (or why none), its
/// warnings, and the fixtures and lights (cells) made of it.
struct SpecUse {
    entry: TypeEntry,
    warnings: Vec<PatchError>,
    fixtures: usize,
    lights: usize,
}

fn build(path: &Path, m: Mvr) -> Result<Import, Vec<PatchError>> {
    let mut warnings = m.warnings.clone();
    let mut errors = Vec::new();
    // Problems of single fixtures, said once per file and problem (crate::report).
    let (mut fixture_warnings, mut fixture_errors) = (Tally::default(), Tally::default());
    let gsd = m.archive.label("GeneralSceneDescription.xml");
    let line_of = |f: &crate::mvr::MvrFixture| m.fixture_line(&f.uuid);
    // By GDTFSpec, in the order the show first names them.
    let mut specs: Vec<String> = Vec::new();
    let mut types: BTreeMap<String, SpecUse> = BTreeMap::new();
    let mut fixtures: Vec<Fixture> = Vec::new();
    let mut used: Vec<(u16, u16, u16, String, usize)> = Vec::new(); // universe, first, last, fixture name, line
    let mut frames = Universes::new();
    let mut cell_plans: BTreeMap<String, BTreeMap<String, Vec<Cell>>> = BTreeMap::new();
    let beam_frame = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2); // GDTF local → stage local
    for (n, f) in m.scene.fixtures.iter().enumerate() {
        let id = f.fixture_id_numeric.or_else(|| f.fixture_id.parse().ok()).unwrap_or(n as u32 + 1);
        let (p, q) = stage_pose(f.world);
        let (position, q) = (p.as_vec3(), quat(q));
        let who = format!("{} (id {id})", f.name);
        let line = line_of(f);
        let spec = types.entry(f.gdtf_spec.clone()).or_insert_with(|| {
            specs.push(f.gdtf_spec.clone());
            let mut type_warnings = Vec::new();
            let entry = (|| {
                let bytes = m.archive.get(&f.gdtf_spec).ok_or(None)?;
                let g = Gdtf::from_bytes(&m.archive.label(&f.gdtf_spec), bytes.to_vec()).map_err(Some)?;
                match fixture_type(&g) {
                    Ok((ty, w)) => {
                        type_warnings.extend(w);
                        let beam = g
                            .layout(&g.mode_names()[0])
                            .ok()
                            .and_then(|l| first_beam(&l.root).map(|(n, _)| n.to_fixture));
                        let off = beam.map(|t| t.w_axis.truncate().as_vec3()).unwrap_or(Vec3::ZERO);
                        let mut cell_warnings = Vec::new();
                        cell_plans.insert(f.gdtf_spec.clone(), mode_cells(&g, &ty, &mut cell_warnings));
                        g.locate(&mut cell_warnings);
                        type_warnings.extend(cell_warnings);
                        Ok((Arc::new(ty), off))
                    }
                    Err(mut e) => {
                        g.locate(std::slice::from_mut(&mut e));
                        Err(Some(e))
                    }
                }
            })();
            SpecUse { entry, warnings: type_warnings, fixtures: 0, lights: 0 }
        });
        spec.fixtures += 1;
        let dmx = f.addresses.iter().find(|a| a.dmx_break == 0).map(|a| (a.universe, a.address));
        let breaks = later_breaks(f);
        match &spec.entry {
            Err(None) => {
                fixture_warnings.add(
                    &gsd,
                    line,
                    format!("GDTF file {:?} is named but not in the archive; shown as dark placeholders", f.gdtf_spec),
                    who,
                );
                spec.lights += 1;
                // A dark placeholder where the fixture hangs.
                let beam = SpotBeam::from_beam_field(25.0, 35.0);
                let light = Light { position, rotation: q * beam_frame, beam: Beam::Spot(beam.clone()) };
                fixtures.push(Fixture {
                    id,
                    name: f.name.clone(),
                    light,
                    dmx: None,
                    line,
                    model: FixtureModel::Builtin(BuiltinSpot { beam, intensity: 0.0, colour: Vec3::ZERO }),
                    look: FixtureState::default(),
                    position,
                    cell: None,
                });
            }
            Err(Some(e)) => {
                if e.message.contains("not a light") {
                    fixture_warnings.add(&e.path, e.line, format!("{}; its slots stay reserved", e.message), who);
                    if let (Some((u, a)), Ok(g)) = (dmx, footprint_of(&m, &f.gdtf_spec, &f.gdtf_mode)) {
                        used.push((u, a, a + g.saturating_sub(1), f.name.clone(), line));
                    }
                } else {
                    fixture_errors.add(&gsd, line, e.to_string(), format!("{:?} (id {id})", f.name));
                }
            }
            Ok((ty, beam_offset)) => {
                let Some(mode) = ty.mode(&f.gdtf_mode) else {
                    let names: Vec<_> = ty.modes.iter().map(|m| m.name.clone()).collect();
                    fixture_errors.add(
                        &gsd,
                        line,
                        format!("{} has no mode {:?}; its modes: {names:?}", f.gdtf_spec, f.gdtf_mode),
                        format!("{:?} (id {id})", f.name),
                    );
                    continue;
                };
                let md = &ty.modes[mode];
                let rotation = if ty.movement.is_some() { q } else { q * beam_frame };
                // Channel defaults by (break-aware) offset.
                let mut local: BTreeMap<u16, u8> = BTreeMap::new();
                for c in &md.channels {
                    local.extend(c.slots_for(c.default));
                }
                let cells = cell_plans.get(&f.gdtf_spec).and_then(|m| m.get(&md.name)).filter(|c| !c.is_empty());
                // A cell's own rotation (its GeometryReference's and beam's
                // matrices) turns its beam within the fixture; a moving head's
                // cells follow the head's pan/tilt instead.
                type Part = (String, Arc<FixtureType>, usize, Vec3, Quat, Option<FixtureCell>);
                let parts: Vec<Part> = match cells {
                    Some(cells) => cells
                        .iter()
                        .zip(1..)
                        .map(|(c, number)| {
                            let turn = if ty.movement.is_some() { Quat::IDENTITY } else { c.rotation };
                            let cell = FixtureCell { number, fixture_name: f.name.clone() };
                            (format!("{} / {}", f.name, c.name), c.fixture_type.clone(), 0, c.offset, turn, Some(cell))
                        })
                        .collect(),
                    None => vec![(f.name.clone(), ty.clone(), mode, *beam_offset, Quat::IDENTITY, None)],
                };
                let ranges = match dmx {
                    Some(start) => break_ranges(md, start, &breaks),
                    None => Ok((Vec::new(), Vec::new())),
                };
                match ranges {
                    Err(why) => {
                        errors.push(PatchError::new(&gsd, line, format!("fixture {:?} (id {id}): {why}", f.name)));
                        continue;
                    }
                    Ok((ranges, missing)) => {
                        used.extend(ranges.into_iter().map(|(u, a, e)| (u, a, e, f.name.clone(), line)));
                        if !missing.is_empty() {
                            fixture_warnings.add(
                                &gsd,
                                line,
                                format!(
                                    "mode {:?} of {} uses DMX breaks {missing:?}, which the fixture's <Addresses> \
                                     do not give; those channels read 0",
                                    md.name, f.gdtf_spec
                                ),
                                who,
                            );
                        }
                    }
                }
                spec.lights += parts.len();
                for (name, fixture_type, mode, beam_offset, turn, cell) in parts {
                    let typed = TypedFixture {
                        fixture_type,
                        mode,
                        position: position + q * beam_frame * beam_offset,
                        rotation: (rotation * turn).normalize(),
                        gel: None,
                        scroller: None,
                        gels: None,
                        manual: Manual::default(),
                        breaks: breaks.clone(),
                    };
                    let mut fixture = Fixture {
                        id,
                        name,
                        light: Light { position, rotation, beam: Beam::Spot(SpotBeam::from_half_angles(0.0, 0.0)) },
                        dmx,
                        line,
                        model: FixtureModel::Typed(typed),
                        look: FixtureState::default(),
                        position,
                        cell,
                    };
                    for (o, v) in &local {
                        if let Some((u, a)) = fixture.slot_address(*o) {
                            frames.set_slot(u, a, *v);
                        }
                    }
                    fixture.look = fixture.decode_with(&|o| local.get(&o).copied().unwrap_or(0));
                    fixture.light = fixture.light_of(&fixture.look);
                    fixtures.push(fixture);
                }
            }
        }
    }
    used.sort();
    for w in used.windows(2) {
        if w[0].0 == w[1].0 && w[1].1 <= w[0].2 {
            errors.push(PatchError::new(
                &gsd,
                w[1].4,
                format!(
                    "{} (slots {}.{}..{}) overlaps {} (slots {}.{}..{})",
                    w[1].3, w[1].0, w[1].1, w[1].2, w[0].3, w[0].0, w[0].1, w[0].2
                ),
            ));
        }
    }
    errors.extend(fixture_errors.into_errors_named_first());
    if !errors.is_empty() {
        return Err(errors);
    }
    // Each type's warnings once, merged by problem, with the fixtures and cells they concern.
    let mut counts: BTreeMap<PathBuf, (usize, usize)> = BTreeMap::new();
    let mut summaries = Vec::new();
    for spec in &specs {
        let u = types.remove(spec).expect("every named spec has an entry");
        let label = m.archive.label(spec);
        let type_warnings = report::merge_heads(u.warnings);
        let summary = match &u.entry {
            Ok((ty, _)) => report::summarise(
                type_display_name(ty),
                spec.clone(),
                &label,
                &ty.name,
                u.fixtures,
                u.lights,
                &type_warnings,
            ),
            Err(e) => TypeSummary {
                name: spec.clone(),
                file: spec.clone(),
                fixtures: u.fixtures,
                cells: u.lights,
                status: Modelled::Not,
                reasons: vec![match e {
                    None => "the GDTF is not in the archive; dark placeholders".to_string(),
                    Some(e) => e.message.split("; ").next().unwrap_or(&e.message).to_string(),
                }],
                not_modelled: Vec::new(),
            },
        };
        summaries.push(summary);
        counts.insert(label, (u.fixtures, u.lights));
        warnings.extend(type_warnings);
    }
    report::count_fixtures(&mut warnings, &counts);
    warnings.extend(fixture_warnings.into_errors());
    let patch = Patch {
        path: path.to_path_buf(),
        camera: None,
        fixtures,
        inputs: Vec::new(),
        look_universes: frames,
        gels: None,
        haze: None,
        views: Vec::new(),
        warnings: Vec::new(),
    };
    Ok(Import { patch, warnings: report::dedupe(warnings), notes: m.notes.clone(), types: summaries, scene: m.scene })
}

/// `Maker Name` of a type (the name alone when the maker is empty or already in it).
fn type_display_name(ty: &FixtureType) -> String {
    let maker = ty.maker.trim();
    if maker.is_empty() || ty.name.starts_with(maker) { ty.name.clone() } else { format!("{maker} {}", ty.name) }
}

fn footprint_of(m: &Mvr, spec: &str, mode: &str) -> Result<u16, PatchError> {
    let bytes = m.archive.get(spec).ok_or_else(|| PatchError::new(&m.archive.path, 0, "missing"))?;
    let g = Gdtf::from_bytes(&m.archive.label(spec), bytes.to_vec())?;
    let l = g.layout(mode)?;
    Ok(l.footprints.get(&1).copied().unwrap_or(0))
}

/// The cells of every mode of a type ([`cells`]), by mode name; a mode
/// whose cells cannot be worked out stays one light, with a warning.
fn mode_cells(g: &Gdtf, ty: &FixtureType, warnings: &mut Vec<PatchError>) -> BTreeMap<String, Vec<Cell>> {
    let mut out = BTreeMap::new();
    for m in &ty.modes {
        match cells(g, ty, &m.name) {
            Ok(c) => {
                out.insert(m.name.clone(), c);
            }
            Err(e) => warnings.push(e),
        }
    }
    out
}

/// `(universe, address)` of an MVR fixture's breaks after the first, in
/// break order (MVR numbers breaks from 0; break 2 is the first entry). A
/// break the fixture gives no address for reads nothing: its channels
/// decode as 0, and the gap ends the list.
fn later_breaks(f: &crate::mvr::MvrFixture) -> Vec<(u16, u16)> {
    let mut out = Vec::new();
    for b in 1..MAX_BREAKS {
        match f.addresses.iter().find(|a| a.dmx_break == b) {
            Some(a) => out.push((a.universe, a.address)),
            None => break,
        }
    }
    out
}

/// The slots a mode occupies on each break, `(universe, first, last)`,
/// from the start address and the later breaks' addresses, and the breaks
/// the mode uses that have no address (their channels read 0); an error
/// when a break's slots run past 512.
fn break_ranges(md: &Mode, start: (u16, u16), breaks: &[(u16, u16)]) -> Result<BreakRanges, String> {
    let mut missing = Vec::new();
    let mut hi: BTreeMap<u16, u16> = BTreeMap::new();
    for c in &md.channels {
        for o in std::iter::once(c.offset).chain(c.fine) {
            let e = hi.entry(o / BREAK_STRIDE).or_insert(0);
            *e = (*e).max(o % BREAK_STRIDE + 1);
        }
    }
    hi.entry(0).or_insert(md.footprint);
    let mut out = Vec::new();
    for (k, n) in hi {
        let n = if k == 0 { n.max(md.footprint) } else { n };
        let Some(&(u, a)) = (if k == 0 { Some(&start) } else { breaks.get(usize::from(k) - 1) }) else {
            missing.push(k + 1);
            continue;
        };
        let end = u32::from(a) + u32::from(n.max(1)) - 1;
        if end > SLOTS as u32 {
            return Err(format!("its {n} slots of DMX break {} from {u}.{a} run past slot 512", k + 1));
        }
        out.push((u, a, end as u16));
    }
    Ok((out, missing))
}

/// Slots per break `(universe, first, last)`, and the breaks without an address.
type BreakRanges = (Vec<(u16, u16, u16)>, Vec<u16>);

/// Most DMX breaks a mode may span: break `b`'s channels sit at offsets
/// from `BREAK_STRIDE · (b − 1)`, which must fit a `u16`.
pub const MAX_BREAKS: u16 = (u16::MAX / BREAK_STRIDE) + 1;

/// First channel offset of GDTF DMX break `b` (1-based); `None` past [`MAX_BREAKS`].
fn break_base(b: u16) -> Option<u16> {
    (1..=MAX_BREAKS).contains(&b).then(|| (b - 1) * BREAK_STRIDE)
}

/// One emitting cell of a multi-instance fixture (a `GeometryReference`
/// whose referenced geometry holds a `<Beam>`: an LED bar's pixel, a
/// matrix's cell, a ring wash's segment; or, in a type without such
/// references, one of several plain `<Beam>`s: a multi-lamp blinder's
/// lamp): one light of its own.
#[derive(Clone, Debug)]
pub struct Cell {
    /// The reference's name in the GDTF (e.g. `Cell3`).
    pub name: String,
    /// Its beam's position from the fixture origin (GDTF axes, metres).
    pub offset: Vec3,
    /// Its beam's orientation in the fixture (GDTF axes): the rotation of
    /// the beam's matrix to the fixture (the GeometryReference's matrix
    /// times the referenced geometries'). The cell's beam points along
    /// `rotation · (−Z)` in fixture axes.
    pub rotation: Quat,
    /// The cell's fixture type: the fixture's type with one mode holding
    /// the cell's own channels (on the reference's geometries, at the
    /// reference's break offsets) and the channels of geometries outside
    /// every cell (the bar's master dimmer, whose value multiplies each
    /// cell's as a GDTF `Multiply` relation would).
    pub fixture_type: Arc<FixtureType>,
}

/// The emitting cells of DMX mode `mode` of `g`, as built on `ty` (the
/// fixture type [`fixture_type`] made of `g`), in tree order. Empty when
/// the mode has fewer than two emitting references and fewer than two
/// plain beams: such a fixture stays one light.
pub fn cells(g: &Gdtf, ty: &FixtureType, mode: &str) -> Result<Vec<Cell>, PatchError> {
    let l = g.layout(mode)?;
    let Some(index) = ty.mode(&l.mode) else { return Ok(Vec::new()) };
    let base = &ty.modes[index];
    let mut refs: Vec<(&GeometryNode, DMat4)> = Vec::new();
    emitting_references(&l.root, &mut refs);
    if refs.len() < 2 {
        // No instanced cells: several plain `<Beam>`s (a multi-lamp blinder) are cells too.
        refs.clear();
        plain_beams(&l.root, &mut refs);
    }
    if refs.len() < 2 {
        return Ok(Vec::new());
    }
    if refs.len() > MAX_CELLS {
        return Err(PatchError::new(
            &g.label.join("description.xml"),
            0,
            format!(
                "mode {:?} has {} emitting cells, more than {MAX_CELLS}; the fixture stays one light",
                l.mode,
                refs.len()
            ),
        ));
    }
    let slot = |c: &ChannelInfo| {
        break_base(c.dmx_break)
            .map(|b| b + c.offsets.first().copied().unwrap_or(1).saturating_sub(1).min(BREAK_STRIDE - 1))
    };
    // Each channel's slot goes to the cells whose name is its geometry
    // instance or a `.`-prefix of it (`Cell3`, `Cell3.Beam`), or to every
    // cell when it is in none (a shared master dimmer). Looked up by name,
    // so the work grows with channels + cells × shared channels.
    let mut by_name: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    for (i, (node, _)) in refs.iter().enumerate() {
        by_name.entry(node.name.as_str()).or_default().push(i);
    }
    let mut own: Vec<Vec<u16>> = vec![Vec::new(); refs.len()];
    let mut shared: Vec<u16> = Vec::new();
    for c in l.channels.iter().filter(|c| !c.offsets.is_empty()) {
        let Some(o) = slot(c) else { continue };
        let g = c.geometry.as_str();
        let prefixes = g.match_indices('.').map(|(i, _)| &g[..i]).chain(std::iter::once(g));
        let mut hit = false;
        for i in prefixes.filter_map(|p| by_name.get(p)).flatten() {
            own[*i].push(o);
            hit = true;
        }
        if !hit {
            shared.push(o);
        }
    }
    // The base mode's channels and overrides by slot; the type without its
    // modes, cloned once per cell (not every mode's channels per cell).
    let mut channel_at: BTreeMap<u16, Vec<usize>> = BTreeMap::new();
    for (i, c) in base.channels.iter().enumerate() {
        channel_at.entry(c.offset).or_default().push(i);
    }
    let mut override_at: BTreeMap<u16, Vec<usize>> = BTreeMap::new();
    for (i, r) in base.overrides.iter().enumerate() {
        override_at.entry(r.follower.0).or_default().push(i);
    }
    let template = FixtureType { modes: Vec::new(), ..ty.clone() };
    let mut out = Vec::new();
    for ((node, offset), own) in refs.iter().zip(own) {
        let pick = |at: &BTreeMap<u16, Vec<usize>>| {
            let mut picked: Vec<usize> =
                own.iter().chain(&shared).filter_map(|o| at.get(o)).flatten().copied().collect();
            picked.sort_unstable();
            picked.dedup();
            picked
        };
        let channels: Vec<Channel> = pick(&channel_at).into_iter().map(|i| base.channels[i].clone()).collect();
        let overrides = pick(&override_at).into_iter().map(|i| base.overrides[i]).collect();
        let mode = Mode { name: base.name.clone(), channels, footprint: base.footprint, line: base.line, overrides };
        let cell_ty = FixtureType { modes: vec![mode], ..template.clone() };
        let (_, rotation, translation) = offset.to_scale_rotation_translation();
        let rotation = Quat::from_xyzw(rotation.x as f32, rotation.y as f32, rotation.z as f32, rotation.w as f32);
        let rotation = if rotation.is_finite() { rotation.normalize() } else { Quat::IDENTITY };
        let offset = translation.as_vec3();
        out.push(Cell { name: node.name.clone(), offset, rotation, fixture_type: Arc::new(cell_ty) });
    }
    Ok(out)
}

/// Most emitting cells (lights) one fixture's mode may have: a 64 × 64
/// pixel matrix. A mode with more stays one light, with a warning.
pub const MAX_CELLS: usize = 4096;

/// The mode's GDTF `Override` relations as [`SlotOverride`]s: the master
/// DMX channel (named `<Geometry>_<Attribute>`, GDTF's default channel
/// name) over every instance of the follower's channel (the first part of
/// the follower's `Channel.LogicalChannel.ChannelFunction` path; a
/// follower on a referenced geometry is every cell's). A master acts only
/// through its overrides: its own attribute becomes [`Attribute::Other`]
/// (two dimmers would otherwise both set v). `Multiply` relations need no
/// mapping: a shared dimmer already multiplies (v · the emitter mix, eq. 4).
fn override_relations(l: &Layout, channels: &mut [Channel]) -> Result<Vec<SlotOverride>, String> {
    let slots = |c: &ChannelInfo| -> Option<(u16, Option<u16>)> {
        let base = break_base(c.dmx_break)?;
        let at = |o: u16| base + o.saturating_sub(1).min(BREAK_STRIDE - 1);
        Some((at(*c.offsets.first()?), c.offsets.get(1).map(|o| at(*o))))
    };
    // Channel name → its instances' slots, and slot → channel: made once,
    // not searched once per relation.
    let mut named: BTreeMap<String, Vec<(u16, Option<u16>)>> = BTreeMap::new();
    for c in &l.channels {
        if let Some(s) = slots(c) {
            named.entry(format!("{}_{}", c.template, c.attribute)).or_default().push(s);
        }
    }
    let mut at: BTreeMap<u16, usize> = BTreeMap::new();
    for (i, c) in channels.iter().enumerate() {
        at.entry(c.offset).or_insert(i);
    }
    let mut out = Vec::new();
    for r in l.relations.iter().filter(|r| r.kind.eq_ignore_ascii_case("Override")) {
        let Some(&master) = named.get(&r.master).and_then(|m| m.first()) else { continue };
        let follower = r.follower.split('.').next().unwrap_or("");
        for &f in named.get(follower).into_iter().flatten().filter(|f| **f != master) {
            if out.len() >= crate::gdtf::MAX_CHANNELS {
                return Err(format!(
                    "mode {:?}: its Override relations bind more than {} follower channels",
                    l.mode,
                    crate::gdtf::MAX_CHANNELS
                ));
            }
            out.push(SlotOverride { master, follower: f });
        }
        if let Some(&i) = at.get(&master.0) {
            channels[i].attribute = Attribute::Other;
        }
    }
    Ok(out)
}

/// The `<Beam>` geometries under `node` outside references, with their matrices to the fixture.
fn plain_beams<'a>(node: &'a GeometryNode, out: &mut Vec<(&'a GeometryNode, DMat4)>) {
    match node.kind {
        GeometryKind::Reference(_) => {}
        GeometryKind::Beam(_) => out.push((node, node.to_fixture)),
        _ => node.children.iter().for_each(|c| plain_beams(c, out)),
    }
}

/// GeometryReferences under `node` whose instance holds a beam, with that
/// beam's matrix to the fixture (depth-first; a reference inside a cell is part of it).
fn emitting_references<'a>(node: &'a GeometryNode, out: &mut Vec<(&'a GeometryNode, DMat4)>) {
    if matches!(node.kind, GeometryKind::Reference(_))
        && let Some((beam, _)) = first_beam(node)
    {
        out.push((node, beam.to_fixture));
        return;
    }
    node.children.iter().for_each(|c| emitting_references(c, out));
}

fn quat(q: DQuat) -> Quat {
    Quat::from_xyzw(q.x as f32, q.y as f32, q.z as f32, q.w as f32).normalize()
}

/// The GDTF reader for TOML patches: `type = "types/x.gdtf"` (relative to
/// the patch) with `mode = "…"` becomes a [`FixtureType`] through
/// [`fixture_type`], every mode included. Handed to
/// [`footlight_fixture::patch::check_with`] as a trait object because the
/// fixture crate cannot depend on this one (this crate builds on its types).
/// The patch's `position` is where the light is (the GDTF beam's offset
/// from the fixture origin is not added, unlike in an MVR).
pub struct GdtfTypes;

impl TypeLoader for GdtfTypes {
    fn load(&self, path: &Path) -> Result<(FixtureType, Vec<PatchError>), PatchError> {
        let g = Gdtf::open(path)?;
        fixture_type(&g)
    }

    fn load_show(&self, path: &Path) -> Option<footlight_fixture::patch::Checked> {
        Some(load_mvr(path).map(|i| (i.patch, i.warnings)))
    }
}

/// Loads a patch: an `.mvr` through [`load_mvr`] (warnings logged to
/// stderr by the caller's choice: they are returned by [`check_patch`]),
/// anything else as a TOML patch whose types may be GDTF files ([`GdtfTypes`]).
pub fn load_patch(path: &Path) -> Result<Patch, PatchError> {
    check_patch(path)
        .map(|(p, _)| p)
        .map_err(|mut e| if e.is_empty() { PatchError::new(path, 0, "invalid patch") } else { e.swap_remove(0) })
}

/// Every problem of a patch or MVR file: the patch and the warnings (each
/// said once), or the errors. [`check_report`] adds the notes and the
/// per-type summary.
pub fn check_patch(path: &Path) -> Result<(Patch, Vec<PatchError>), Vec<PatchError>> {
    check_report(path).map(|c| (c.patch, c.warnings))
}

/// A checked patch or MVR show: what `footlight check` prints, and what
/// `run` and `render` sum up at start and `/api/status` lists.
#[derive(Clone, Debug)]
pub struct Checked {
    /// The patch.
    pub patch: Patch,
    /// Its warnings, each said once per file and problem (with a count).
    pub warnings: Vec<PatchError>,
    /// Notes (names read not quite as written).
    pub notes: Vec<PatchError>,
    /// One summary per GDTF fixture type (none for a patch of built-in types only).
    pub types: Vec<TypeSummary>,
}

/// [`check_patch`] with notes and the per-type summary: an `.mvr` through
/// [`load_mvr`], a TOML patch through its GDTF types ([`GdtfTypes`]), its
/// GDTF types summed up from their warnings.
pub fn check_report(path: &Path) -> Result<Checked, Vec<PatchError>> {
    if is_mvr(path) {
        let i = load_mvr(path)?;
        return Ok(Checked { patch: i.patch, warnings: i.warnings, notes: i.notes, types: i.types });
    }
    let (patch, warnings) = footlight_fixture::patch::check_with(path, &GdtfTypes)?;
    let warnings = report::merge_heads(warnings);
    // The GDTF types a TOML patch names, in patch order: fixtures and lights of each.
    let mut order: Vec<Arc<FixtureType>> = Vec::new();
    let mut count: BTreeMap<PathBuf, (usize, usize)> = BTreeMap::new();
    let mut last_id = None;
    for f in &patch.fixtures {
        let FixtureModel::Typed(t) = &f.model else { continue };
        let ty = &t.fixture_type;
        if !ty.path.extension().is_some_and(|e| e.eq_ignore_ascii_case("gdtf")) {
            continue;
        }
        let c = count.entry(ty.path.clone()).or_insert_with(|| {
            order.push(ty.clone());
            (0, 0)
        });
        if f.cell.is_none() || last_id != Some(f.id) {
            c.0 += 1;
        }
        c.1 += 1;
        last_id = Some(f.id);
    }
    let types = order
        .iter()
        .map(|ty| {
            let (fixtures, lights) = count[&ty.path];
            let file = ty.path.display().to_string();
            report::summarise(type_display_name(ty), file, &ty.path, &ty.name, fixtures, lights, &warnings)
        })
        .collect();
    let mut warnings = warnings;
    report::count_fixtures(&mut warnings, &count);
    Ok(Checked { patch, warnings: report::dedupe(warnings), notes: Vec::new(), types })
}

/// True for a path ending in `.mvr` (any case).
pub fn is_mvr(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("mvr"))
}

/// The MVR show a patch draws its rig (and, without `--scene`, its venue
/// and fixture bodies) from: the file itself when it is an `.mvr`, the file
/// a TOML patch names with `show = "…"` (relative to the patch), else
/// `None`. A TOML file that cannot be read or parsed gives `None` here; its
/// loading reports why.
pub fn show_of(path: &Path) -> Option<std::path::PathBuf> {
    if is_mvr(path) {
        return Some(path.to_path_buf());
    }
    #[derive(serde::Deserialize)]
    struct ShowKey {
        show: Option<String>,
    }
    let text = std::fs::read_to_string(path).ok()?;
    let key: ShowKey = toml::from_str(&text).ok()?;
    Some(path.parent().unwrap_or(Path::new("")).join(key.show?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use gdtf::physical_descriptions::{Filter, Interpolation, Measurement, MeasurementPoint};
    use gdtf::values::{ColorCie, Name};

    /// A long-pass filter: 0 % below 550 nm, 100 % from 560 nm (percent, as GDTF files often write it).
    fn long_pass() -> Filter {
        let points = (380..=780)
            .step_by(10)
            .map(|nm| MeasurementPoint { wave_length: f64::from(nm), energy: if nm < 560 { 0.0 } else { 100.0 } })
            .collect();
        Filter {
            name: Some(Name::new_lossy("LongPass")),
            color: ColorCie { x: 0.6, y: 0.38, z: 30.0 },
            measurements: vec![Measurement {
                physical: 100.0,
                luminous_intensity: None,
                transmission: Some(30.0),
                interpolation_to: Interpolation::Linear,
                points,
            }],
        }
    }

    #[test]
    fn filter_spectrum_becomes_a_gel_applied_spectrally() {
        let gel = filter_gel(&long_pass(), "slot").unwrap();
        assert_eq!(gel.transmission(500.0), 0.0);
        assert_eq!(gel.transmission(600.0), 1.0);
        assert!((gel.transmission(555.0) - 0.5).abs() < 1e-6, "linear between 550 and 560 nm");
        // Through the gel tables vs direct integration of lamp × transmission.
        let lamp = Lamp::Discharge { cct: 6000.0 };
        let mix = footlight_photometry::GelMix::single(Some(&gel));
        let fast = footlight_photometry::colour_mix(&lamp, 1.0, &mix);
        let exact = footlight_photometry::colour_exact(&lamp, 1.0, Some(gel.sampled()));
        assert!((fast - exact).abs().max_element() < 1e-3, "{fast} {exact}");
        assert!(fast.x > 5.0 * fast.z, "a long-pass filter passes red, not blue: {fast}");
        // Fewer than two points: no gel (the slot's xyY is used instead).
        let mut one = long_pass();
        one.measurements[0].points.truncate(1);
        assert!(filter_gel(&one, "slot").is_none());
    }
}
