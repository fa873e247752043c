//! A GDTF spot's gate (issue 14): gobo wheels with their slot images, prism
//! wheels with their facets, and the channels that turn, insert and frost
//! them, mapped onto `footlight_fixture`'s [`GateOptics`] and gate
//! attributes ([`Attribute::Gobo`], [`Attribute::Prism`], [`Attribute::Gate`]).
//!
//! * `Gobo1` (with a `Wheel` link) → gobo slot by the channel sets'
//!   `WheelSlotIndex`; a `Gobo1WheelSpin` function → wheel spin (deg/s).
//!   Each slot's `MediaFileName` image in `wheels/` (PNG, up to 4096² texels;
//!   luminance × alpha = transmission, white passes) becomes a
//!   [`GoboImage`]; a slot without an image is open.
//! * `Gobo1Pos` → indexed rotation (degrees), `Gobo1PosRotate` → continuous
//!   rotation (deg/s); `Prism1Pos` / `Prism1PosRotate` likewise for the prism.
//! * `Prism1` (with a `Wheel` link) → prism slot; a slot's `<Facet>`
//!   rotation matrices become [`Facet`]s ([`Facet::from_gdtf`]).
//! * `Blade1A` … `Blade4B` (insertion, physical 0..1 of the gate diameter),
//!   `Blade1Rot` … (degrees), `ShaperRot` (degrees), `Frost1` (0..1).
//!
//! * `Gobo2` (with a `Wheel` link), `Gobo2Pos`, `Gobo2PosRotate`: a second
//!   gobo wheel, its image multiplying the first's ([`GoboLayer`]);
//!   `AnimationWheel1` (with a `Wheel` link), `AnimationWheel1Pos`,
//!   `AnimationWheel1PosRotate`: the animation wheel as one more such layer
//!   centred on the axis (estimated: a real one sits off-axis and slides
//!   through the gate as it turns).
//!
//! A second prism wheel (`Prism2`…) stays an `other` channel with the type's warning.
//!
//! [`GoboLayer`]: footlight_fixture::beam::GoboLayer

use crate::gdtf::{FunctionInfo, Gdtf, Layout};
use footlight_fixture::PatchError;
use footlight_fixture::beam::{Facet, GoboImage};
use footlight_fixture::fixture_type::{Action, Attribute, Function, GateOptics, GateTarget};
use std::sync::Arc;

/// Largest gobo image side read (GDTF recommends 256, allows 1024).
pub const MAX_GOBO_SIDE: u32 = 4096;

/// The gate attribute of a GDTF channel, if it is one (`wheel`: the channel links a wheel).
pub fn gate_attribute(attribute: &str, wheel: bool) -> Option<Attribute> {
    match attribute {
        "Gobo1" if wheel => Some(Attribute::Gobo),
        "Gobo2" if wheel => Some(Attribute::Gobo2),
        "AnimationWheel1" if wheel => Some(Attribute::Animation),
        "Prism1" if wheel => Some(Attribute::Prism),
        a if gate_target(a).is_some() => Some(Attribute::Gate),
        _ => None,
    }
}

/// The state field a GDTF function attribute sets.
pub fn gate_target(attribute: &str) -> Option<GateTarget> {
    Some(match attribute {
        "Gobo1Pos" => GateTarget::GoboAngle,
        "Gobo1PosRotate" => GateTarget::GoboSpin,
        "Gobo1WheelSpin" => GateTarget::GoboWheelSpin,
        "Prism1Pos" => GateTarget::PrismAngle,
        "Prism1PosRotate" => GateTarget::PrismSpin,
        "ShaperRot" => GateTarget::ShaperRot,
        "Frost1" => GateTarget::Frost,
        "Gobo2Pos" => GateTarget::Gobo2Angle,
        "Gobo2PosRotate" => GateTarget::Gobo2Spin,
        "AnimationWheel1Pos" => GateTarget::AnimationAngle,
        "AnimationWheel1PosRotate" => GateTarget::AnimationSpin,
        a => {
            let rest = a.strip_prefix("Blade")?;
            let n = rest.chars().next()?.to_digit(10)?;
            if !(1..=4).contains(&n) {
                return None;
            }
            let i = (n - 1) as u8;
            match &rest[1..] {
                "A" => GateTarget::BladeA(i),
                "B" => GateTarget::BladeB(i),
                "Rot" => GateTarget::BladeRot(i),
                _ => return None,
            }
        }
    })
}

/// The DMX ranges of one channel function of a gate channel: wheel slots
/// from the channel sets (gobo, second gobo, animation and prism wheels),
/// or a gate value over its physical range. `raw16` converts a raw value at
/// the channel's resolution to Footlight's 8/16-bit reading. The caller
/// adds the function's mode master.
pub fn gate_functions_of(f: &FunctionInfo, attribute: Attribute, raw16: &dyn Fn(u64) -> u16) -> Vec<Function> {
    let (from, to) = (raw16(f.dmx_from), raw16(f.dmx_to));
    let range = [f.physical_from as f32, f.physical_to as f32];
    if let Some(t) = gate_target(&f.attribute) {
        return vec![Function { from, to, action: Action::Gate(t), range, mode: None }];
    }
    if matches!(attribute, Attribute::Gobo | Attribute::Gobo2 | Attribute::Animation | Attribute::Prism) {
        crate::show::wheel_slot_functions(f, range, raw16)
    } else {
        vec![Function { from, to, action: Action::Hold, range, mode: None }]
    }
}

/// The wheel the first channel with `attribute` links.
fn linked_wheel<'a>(g: &'a Gdtf, layouts: &[Layout], attribute: &str) -> Option<&'a gdtf::wheel::Wheel> {
    let name = layouts
        .iter()
        .flat_map(|l| l.channels.iter())
        .filter(|c| c.attribute == attribute)
        .flat_map(|c| c.functions.iter())
        .find_map(|f| f.wheel.clone())?;
    g.ft.wheels.iter().find(|w| w.name.as_deref() == Some(name.as_str()))
}

/// The gobo and prism wheels of a GDTF type: each gobo slot's image
/// (decoded once per type), each prism slot's facets. A missing or
/// unreadable image is a warning and an open slot.
pub fn gate_optics(g: &Gdtf, layouts: &[Layout], warnings: &mut Vec<PatchError>) -> GateOptics {
    let label = g.label.join("description.xml");
    let gobo_wheel = linked_wheel(g, layouts, "Gobo1")
        .map(|w| {
            w.slots
                .iter()
                .map(|slot| {
                    let media = slot.media_name.as_deref()?;
                    let line = g.lines.line("Slot", "MediaFileName", media).unwrap_or_else(|| g.type_line());
                    match g.wheel_image(media).map(|b| decode(media, b)) {
                        Some(Ok(img)) => Some(Arc::new(img)),
                        Some(Err(why)) => {
                            warnings.push(PatchError::new(
                                &label,
                                line,
                                format!("gobo image {media:?}: {why}; slot left open"),
                            ));
                            None
                        }
                        None => {
                            warnings.push(PatchError::new(
                                &label,
                                line,
                                format!("gobo image {media:?} is not in wheels/; slot left open"),
                            ));
                            None
                        }
                    }
                })
                .collect()
        })
        .unwrap_or_default();
    let prism_wheel = linked_wheel(g, layouts, "Prism1")
        .map(|w| {
            w.slots.iter().map(|s| s.facets.iter().map(|f| Facet::from_gdtf(rotation(&f.rotation))).collect()).collect()
        })
        .unwrap_or_default();
    let gobo_wheel2 = layer_images(g, layouts, "Gobo2", warnings);
    let animation_wheel = layer_images(g, layouts, "AnimationWheel1", warnings);
    GateOptics { gobo_wheel, prism_wheel, gobo_wheel2, animation_wheel }
}

/// The slot images of the wheel the `attribute` channel links (a second
/// gobo wheel, an animation wheel), as the first gobo wheel's: a missing or
/// unreadable image is a warning and an open slot.
fn layer_images(
    g: &Gdtf,
    layouts: &[Layout],
    attribute: &str,
    warnings: &mut Vec<PatchError>,
) -> Vec<Option<Arc<GoboImage>>> {
    let Some(w) = linked_wheel(g, layouts, attribute) else { return Vec::new() };
    let mut out = Vec::new();
    for slot in &w.slots {
        let Some(media) = slot.media_name.as_deref() else {
            out.push(None);
            continue;
        };
        let why = match g.wheel_image(media).map(|b| decode(media, b)) {
            Some(Ok(img)) => {
                out.push(Some(Arc::new(img)));
                continue;
            }
            Some(Err(why)) => format!(": {why}; slot left open"),
            None => " is not in wheels/; slot left open".to_string(),
        };
        warnings.push(PatchError::new(
            &g.label.join("description.xml"),
            0,
            format!("{attribute} image {media:?}{why}"),
        ));
        out.push(None);
    }
    out
}

/// A wheel image as a gobo: PNG (or any format the `image` crate's enabled
/// decoders read), at most [`MAX_GOBO_SIDE`] per side.
pub fn decode(name: &str, bytes: &[u8]) -> Result<GoboImage, String> {
    let mut reader =
        image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format().map_err(|e| e.to_string())?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_GOBO_SIDE);
    limits.max_image_height = Some(MAX_GOBO_SIDE);
    limits.max_alloc = Some(256 << 20);
    reader.limits(limits);
    let img = reader.decode().map_err(|e| e.to_string())?.to_luma_alpha8();
    let (w, h) = img.dimensions();
    let luma: Vec<u8> = img.pixels().map(|p| ((u16::from(p.0[0]) * u16::from(p.0[1]) + 127) / 255) as u8).collect();
    GoboImage::from_luma8(name, w as usize, h as usize, &luma).ok_or_else(|| "empty image".to_string())
}

/// A GDTF `Rotation` (`{a,b,c}{d,e,f}{g,h,i}`, rows) as numbers; the
/// `gdtf` crate keeps them private, so they are read back from its
/// serialiser (as [`crate::gdtf::matrix`] does); identity if unreadable.
pub fn rotation(r: &gdtf::values::Rotation) -> [[f64; 3]; 3] {
    let text = quick_xml::se::to_string_with_root("m", r).unwrap_or_default();
    let inner = text.trim_start_matches("<m>").trim_end_matches("</m>");
    let nums: Vec<f64> =
        inner.split(['{', '}', ',']).filter(|s| !s.trim().is_empty()).filter_map(|s| s.trim().parse().ok()).collect();
    if nums.len() != 9 || nums.iter().any(|x| !x.is_finite()) {
        return [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    }
    [[nums[0], nums[1], nums[2]], [nums[3], nums[4], nums[5]], [nums[6], nums[7], nums[8]]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gate_attribute_names() {
        assert_eq!(gate_target("Blade3Rot"), Some(GateTarget::BladeRot(2)));
        assert_eq!(gate_target("Blade1A"), Some(GateTarget::BladeA(0)));
        assert_eq!(gate_target("Blade4B"), Some(GateTarget::BladeB(3)));
        assert_eq!(gate_target("Blade5A"), None);
        assert_eq!(gate_target("Blade"), None);
        assert_eq!(gate_target("BladeSoft1A"), None);
        assert_eq!(gate_attribute("Gobo1", true), Some(Attribute::Gobo));
        assert_eq!(gate_attribute("Gobo1", false), None);
        assert_eq!(gate_attribute("Frost1", false), Some(Attribute::Gate));
        assert!(decode("x", b"not a png").is_err());
    }
}
