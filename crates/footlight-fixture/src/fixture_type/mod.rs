//! Fixture types: what one model of stage light is, read from
//! `patch/fixtures/<name>.toml` (schema: `docs/patch-format.md`; the
//! library and its sources: `docs/fixtures.md`).
//!
//! A type gives the lamp (kind and CCT, for c_I), the optics (a zoom/profile
//! spot, a Fresnel/PC with Hermite spot and flood patterns, or measured
//! photometry) with Î from the datasheet, an optional pan/tilt yoke, and
//! DMX modes with their channels. From a mode and 512 slots it decodes a
//! [`FixtureState`] in real units, and from a state it gives the beam
//! geometry, Î and the lamp for k_i (Vierjahn 2010, eq. 4).
//!
//! ```toml
//! name = "Example zoom profile"
//! [lamp]
//! kind = "tungsten"
//! cct = 3200
//! source = "estimated"
//! [beam]
//! model = "spot"
//! zoom = [15, 40]          # field angle at zoom DMX 0 and full
//! beam_ratio = [0.7, 0.5]  # beam/field at focus 0 (hard) and 1 (soft)
//! intensity = 170000       # Î in cd at the narrowest field, hard edge
//! source = "estimated"
//! [[mode]]
//! name = "1ch"
//! [[mode.channel]]
//! attribute = "dimmer"
//! offset = 1
//! ```

pub mod colour;
mod load;

pub use load::load_type;

use crate::beam::{
    Beam, Blade, Facet, Gate, GoboImage, GoboLayer, HermiteBeam, HermitePattern, MeasuredBeam, PhotometricTable,
    ShapedBeam, SpotBeam,
};
use crate::state::{FixtureState, MAX_MIX};
use colour::{EmitterSet, bradford, filter_between, hsb_xy, planck_xy, shift_between, uv_of, white_xy, xy_of_uv};
use footlight_photometry::{DimmerCurve, Gel, Lamp, Scroller, srgb};
use glam::{Vec2, Vec3};
use std::path::PathBuf;
use std::sync::Arc;

/// A validated fixture type.
#[derive(Clone, Debug)]
pub struct FixtureType {
    /// Model name as the maker writes it.
    pub name: String,
    /// The maker ("generic" for generic types).
    pub maker: String,
    /// The file it was read from.
    pub path: PathBuf,
    /// The lamp at full with no colour mixing (LED emitters at full, CMY flags out).
    pub lamp: Lamp,
    /// Names of the colour-mix attributes in [`FixtureState::mix`] order.
    pub mix_names: Vec<String>,
    /// The optics.
    pub optics: Optics,
    /// Pan/tilt yoke, for moving heads.
    pub movement: Option<Movement>,
    /// DMX modes, in file order.
    pub modes: Vec<Mode>,
    /// Colour-wheel slots in wheel order (empty: no colour wheel).
    pub colour_wheel: Vec<WheelSlot>,
    /// The colour-correction (CTO/CTB) channel's transmittance table, if the type has one.
    pub cto: Option<CorrectionTable>,
    /// Gobo and prism wheels (empty for types without them).
    pub gate: GateOptics,
    /// Colour wheels 2-4 (GDTF `Color2` … `Color4`), slots in wheel order;
    /// their filters multiply the first wheel's (empty: no such wheel).
    pub extra_wheels: Vec<Vec<WheelSlot>>,
    /// Colour-macro slots (GDTF `ColorMacro1` linked to a wheel): each
    /// slot's CIE xy where the file gives a colour.
    pub colour_macros: Vec<Option<Vec2>>,
}

/// The wheels a spot's gate can hold (GDTF gobo and prism wheels).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GateOptics {
    /// Gobo-wheel slots in wheel order: the slot's image, `None` for an open slot.
    pub gobo_wheel: Vec<Option<Arc<GoboImage>>>,
    /// Prism-wheel slots in wheel order: the slot's facets, empty for no prism.
    pub prism_wheel: Vec<Vec<Facet>>,
    /// Second gobo wheel (GDTF `Gobo2`), as `gobo_wheel`.
    pub gobo_wheel2: Vec<Option<Arc<GoboImage>>>,
    /// Animation wheel (GDTF `AnimationWheel1`), as `gobo_wheel`.
    pub animation_wheel: Vec<Option<Arc<GoboImage>>>,
}

/// The wheel slot at a position (rounded; clamped to the wheel).
fn slot_at<T>(wheel: &[T], position: f32) -> Option<&T> {
    let i = if position.is_finite() && position > 0.0 { position.round() as usize } else { 0 };
    wheel.get(i.min(wheel.len().saturating_sub(1)))
}

/// A Planckian CCT after a correction filter to `target` (0: none).
fn corrected(cct: f32, target: f32) -> f32 {
    if target > 0.0 && target.is_finite() { target } else { cct }
}

/// One colour-wheel slot: what it does to the beam's colour.
#[derive(Clone, Debug, PartialEq)]
pub enum WheelSlot {
    /// A per-channel factor c_F in linear sRGB (open = 1, 1, 1), from the
    /// slot's CIE xyY (GDTF `Slot Color`: the filtered light's chromaticity
    /// and its luminous transmittance in percent). See [`wheel_factor`].
    Factor(Vec3),
    /// A measured transmission spectrum (GDTF `Filter` with measurements):
    /// applied to the lamp's spectrum like a gel.
    Filter(Arc<Gel>),
}

/// c_F of a filter given by CIE xyY (Y in percent, as GDTF writes slot
/// colours): the linear-sRGB colour of (x, y, Y/100), so D65 white at 100 %
/// is (1, 1, 1) and the sRGB red primary at its luminance 21.26 % is
/// (1, 0, 0). Components below 0 (outside the sRGB gamut) are 0: a filter
/// transmits nothing negative. An approximation (documented in
/// docs/mvr-gdtf.md): the factor multiplies c_I per channel, as if the lamp
/// were white; a measured spectrum ([`WheelSlot::Filter`]) is exact.
pub fn wheel_factor(x: f32, y: f32, y_percent: f32) -> Vec3 {
    if !(x > 0.0 && y > 0.0 && x + y < 1.0 && y_percent >= 0.0 && y_percent.is_finite()) {
        return Vec3::ONE;
    }
    let xyz = srgb::xy_to_xyz(Vec2::new(x, y), y_percent / 100.0);
    srgb::xyz_to_linear_srgb(xyz).max(Vec3::ZERO)
}

/// Luminous transmittance of an ideal colour-correction filter turning a
/// Planckian source at `from_k` into one at `to_k` (CTO when `to_k` is
/// lower, CTB when higher): its transmission is the ratio of the two
/// Planck spectra scaled to peak 1 over 380-780 nm (the ratio is monotonic,
/// so the peak is at an end), and the transmittance is
/// ∫ τ B_from ȳ dλ / ∫ B_from ȳ dλ. 1 when either temperature is not
/// positive and finite. A real gel's spectrum differs (estimated model).
pub fn correction_transmittance(from_k: f32, to_k: f32) -> f32 {
    if !(from_k > 0.0 && to_k > 0.0 && from_k.is_finite() && to_k.is_finite()) || from_k == to_k {
        return 1.0;
    }
    let (b_from, b_to) = (footlight_photometry::blackbody(from_k), footlight_photometry::blackbody(to_k));
    let ratio = |nm: f32| b_to(nm) / b_from(nm);
    let peak = ratio(380.0).max(ratio(780.0));
    let y_from = footlight_photometry::spectrum_to_xyz(b_from).y;
    let y_to = footlight_photometry::spectrum_to_xyz(b_to).y;
    if !(peak > 0.0 && y_from > 0.0) {
        return 1.0;
    }
    (y_to / (peak * y_from)).clamp(0.0, 1.0)
}

/// [`correction_transmittance`] from a lamp's CCT over a target range,
/// tabulated at load (33 points, linear in mired) so the frame loop reads a
/// table instead of integrating two spectra per fixture per frame.
#[derive(Clone, Debug, PartialEq)]
pub struct CorrectionTable {
    /// The lamp's CCT, K.
    pub from_k: f32,
    /// (mired, transmittance), mired ascending.
    points: Vec<(f32, f32)>,
}

impl CorrectionTable {
    /// The table from `from_k` to every target in `range` (K, either order).
    pub fn new(from_k: f32, range: [f32; 2]) -> Self {
        let m = |k: f32| 1e6 / k.clamp(500.0, 100_000.0);
        let (a, b) = (m(range[0]).min(m(range[1])), m(range[0]).max(m(range[1])));
        let n = 32;
        let mut points: Vec<(f32, f32)> = (0..=n)
            .map(|i| {
                let mired = a + (b - a) * i as f32 / n as f32;
                (mired, correction_transmittance(from_k, 1e6 / mired))
            })
            .collect();
        // The lamp's own CCT is a node: the transmittance has a kink there (1, the
        // filter turns from CTB to CTO), which interpolation across it would round off.
        let own = m(from_k);
        if own > a && own < b {
            let at = points.partition_point(|p| p.0 < own);
            points.insert(at, (own, 1.0));
        }
        Self { from_k, points }
    }

    /// Transmittance for target `to_k`, interpolated linearly in mired (1 for no target).
    pub fn at(&self, to_k: f32) -> f32 {
        if !(to_k > 0.0 && to_k.is_finite()) {
            return 1.0;
        }
        let m = 1e6 / to_k;
        let p = &self.points;
        match p.iter().position(|&(x, _)| x >= m) {
            None => p.last().map_or(1.0, |l| l.1),
            Some(0) => p[0].1,
            Some(i) => {
                let ((x0, y0), (x1, y1)) = (p[i - 1], p[i]);
                if x1 > x0 { y0 + (y1 - y0) * (m - x0) / (x1 - x0) } else { y1 }
            }
        }
    }
}

/// A fixture's optical system.
#[derive(Clone, Debug)]
pub enum Optics {
    /// Profile/zoom spot (also PARs and moving-head spots): cone + penumbra.
    Spot(SpotOptics),
    /// Fresnel/PC: spot and flood Hermite patterns mixed by focus.
    Hermite(HermiteOptics),
    /// Measured photometry from an IES or EULUMDAT file.
    Measured(Arc<PhotometricTable>),
}

/// Zoom/profile spot optics (all angles full angles in degrees).
#[derive(Clone, Debug, PartialEq)]
pub struct SpotOptics {
    /// Field angle at zoom DMX 0 and at full (equal for a fixed-field fixture).
    pub zoom: [f32; 2],
    /// Beam/field ratio at focus 0 (hard edge) and 1 (soft edge).
    pub beam_ratio: [f32; 2],
    /// Î in candela at `intensity_field`, focus 0, iris open.
    pub intensity: f32,
    /// The field angle at which `intensity` holds.
    pub intensity_field: f32,
    /// Smallest iris diameter fraction, if the fixture has an iris.
    pub iris_min: Option<f32>,
    /// ∫f dω of the reference beam, steradians.
    reference_solid_angle: f32,
}

impl SpotOptics {
    /// Optics with the reference solid angle computed.
    pub fn new(
        zoom: [f32; 2],
        beam_ratio: [f32; 2],
        intensity: f32,
        intensity_field: f32,
        iris_min: Option<f32>,
    ) -> Self {
        let mut o = Self { zoom, beam_ratio, intensity, intensity_field, iris_min, reference_solid_angle: 0.0 };
        o.reference_solid_angle = o.open_beam(intensity_field, 0.0).solid_angle();
        o
    }

    /// Narrowest and widest field angles.
    pub fn field_range(&self) -> (f32, f32) {
        (self.zoom[0].min(self.zoom[1]), self.zoom[0].max(self.zoom[1]))
    }

    /// The un-irised beam at field angle `field` and focus `focus`.
    pub fn open_beam(&self, field: f32, focus: f32) -> SpotBeam {
        let (lo, hi) = self.field_range();
        let field = if field.is_finite() { field.clamp(lo, hi) } else { lo };
        let f = if focus.is_finite() { focus.clamp(0.0, 1.0) } else { 0.0 };
        let ratio = self.beam_ratio[0] + (self.beam_ratio[1] - self.beam_ratio[0]) * f;
        SpotBeam::from_beam_field(field * ratio, field)
    }

    /// Î at a field angle and focus: the flux stays constant, so Î ∝ 1/∫f dω
    /// (Vierjahn 2010, section 3.2: Î "varies while altering the zoom value").
    pub fn intensity_at(&self, field: f32, focus: f32) -> f32 {
        let omega = self.open_beam(field, focus).solid_angle();
        if omega > 0.0 { self.intensity * self.reference_solid_angle / omega } else { 0.0 }
    }
}

/// Fresnel/PC optics.
#[derive(Clone, Debug)]
pub struct HermiteOptics {
    /// Full-spot pattern.
    pub spot: Arc<HermitePattern>,
    /// Î at full spot, cd.
    pub spot_cd: f32,
    /// Full-flood pattern.
    pub flood: Arc<HermitePattern>,
    /// Î at full flood, cd.
    pub flood_cd: f32,
}

/// A moving head's yoke: full pan and tilt ranges in degrees, centred on 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Movement {
    /// Full pan range (e.g. 540).
    pub pan: f32,
    /// Full tilt range (e.g. 270).
    pub tilt: f32,
}

/// What a DMX channel controls.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Attribute {
    /// Intensity: v through the channel's dimmer curve.
    Dimmer,
    /// Pan, degrees.
    Pan,
    /// Tilt, degrees.
    Tilt,
    /// Zoom: field angle, degrees.
    Zoom,
    /// Focus 0..1.
    Focus,
    /// Iris: fraction of the open diameter.
    Iris,
    /// Colour-scroller frame position.
    Scroller,
    /// Colour mix: LED emitter or CMY flag, by index into [`FixtureState::mix`].
    Mix(u8),
    /// Shutter and strobe: open, closed or strobing at a rate, by the
    /// channel's DMX ranges ([`Channel::functions`]).
    Shutter,
    /// Colour-wheel slot, by the channel's DMX ranges ([`Channel::functions`]).
    ColourWheel,
    /// Colour correction (CTO/CTB): target CCT in kelvin over the channel's range.
    Cto,
    /// Gobo-wheel slot and wheel spin, by the channel's DMX ranges ([`Channel::functions`]).
    Gobo,
    /// Prism-wheel slot, by the channel's DMX ranges.
    Prism,
    /// Gobo or prism rotation, blades, shaper rotation or frost, by the
    /// channel's DMX ranges ([`Action::Gate`]).
    Gate,
    /// Colour wheel 2, 3 or 4 (index 0-2 into [`FixtureState::wheels`]), by the channel's DMX ranges.
    ColourWheelN(u8),
    /// Colour macro: a slot of [`FixtureType::colour_macros`], by the channel's DMX ranges.
    ColourMacro,
    /// Green/magenta tint: Duv over the channel's range (positive: green).
    Tint,
    /// HSB hue, degrees.
    Hue,
    /// HSB saturation, 0..1.
    Saturation,
    /// HSB brightness, 0..1 (multiplies v).
    HsbBrightness,
    /// CIE 1931 x.
    CieX,
    /// CIE 1931 y.
    CieY,
    /// CIE brightness, 0..1 (multiplies v).
    CieBrightness,
    /// The dimmer curve, by the channel's DMX ranges ([`Action::Curve`]).
    DimmerCurve,
    /// Duration of one strobe flash, seconds.
    StrobeDuration,
    /// An additive colour channel the type has no emitter colour for: its
    /// level scales intensity (v × the largest such level), so a fixture
    /// whose colour cannot be mixed still goes dark with its colour channels.
    Level,
    /// Second gobo wheel slot, by the channel's DMX ranges.
    Gobo2,
    /// Animation wheel slot, by the channel's DMX ranges.
    Animation,
    /// A control channel whose only effect is to select which channel
    /// functions of other channels apply (a GDTF mode master such as
    /// `ColorMixMode` or `LEDZoneMode`, [`ModeGate`]): decoded, no state of its own.
    Mode,
    /// Something Footlight does not model (strobe, gobo, control…): decoded and ignored.
    Other,
}

/// One channel of a mode.
#[derive(Clone, Debug)]
pub struct Channel {
    /// What it controls.
    pub attribute: Attribute,
    /// The attribute's name as written.
    pub name: String,
    /// Offset of the (coarse) slot from the start address, 0-based.
    pub offset: u16,
    /// Offset of the fine slot for 16-bit control, 0-based.
    pub fine: Option<u16>,
    /// DMX value at power-up (0-255, or 0-65535 for a 16-bit pair).
    pub default: u16,
    /// Dimmer curve (dimmer channels).
    pub curve: DimmerCurve,
    /// Real-unit values at DMX 0 and at full (continuous attributes).
    pub range: [f32; 2],
    /// Frames on the scroller string (scroller channels).
    pub scroller: Option<Scroller>,
    /// DMX ranges with their own meaning (GDTF channel functions and sets):
    /// shutter open/closed/strobe, wheel slots. Empty: the whole range is `range`.
    pub functions: Vec<Function>,
    /// Line of the channel in its type file.
    pub line: usize,
}

/// One DMX range of a channel with several meanings (a GDTF channel
/// function, or a channel set with a wheel slot).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Function {
    /// First raw value of the range (in the channel's full scale).
    pub from: u16,
    /// Last raw value of the range.
    pub to: u16,
    /// What the range does.
    pub action: Action,
    /// Real values at `from` and `to` (strobe: Hz).
    pub range: [f32; 2],
    /// The mode master that must select this function (GDTF `ModeMaster`,
    /// `ModeFrom`, `ModeTo`); `None`: always available.
    pub mode: Option<ModeGate>,
}

/// A GDTF mode master: a channel function applies only while the master
/// channel's raw value is in `[from, to]` (DIN SPEC 15800 `ModeMaster`,
/// `ModeFrom`, `ModeTo`). Raw values at the master's resolution as
/// Footlight reads it (8-bit, or 16-bit from coarse and fine).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModeGate {
    /// The master's coarse and fine slot offsets.
    pub master: (u16, Option<u16>),
    /// Lowest master value selecting the function.
    pub from: u16,
    /// Highest master value selecting the function.
    pub to: u16,
}

impl ModeGate {
    /// True while the master's value is in `[from, to]`.
    pub fn selects(&self, slot: &dyn Fn(u16) -> u8) -> bool {
        let raw = match self.master.1 {
            Some(f) => u16::from(slot(self.master.0)) << 8 | u16::from(slot(f)),
            None => u16::from(slot(self.master.0)),
        };
        (self.from..=self.to).contains(&raw)
    }
}

impl Function {
    /// True when its mode master (if any) selects it.
    pub fn active(&self, slot: &dyn Fn(u16) -> u8) -> bool {
        self.mode.is_none_or(|m| m.selects(slot))
    }
}

/// What a [`Function`] range does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    /// Shutter open.
    Open,
    /// Shutter closed.
    Closed,
    /// Strobe at the range's rate (Hz, interpolated over the range).
    Strobe,
    /// Wheel slot (0-based) of the channel's wheel: colour, gobo or prism.
    Slot(u16),
    /// A gate value over the range (degrees, degrees per second, insertion or frost).
    Gate(GateTarget),
    /// A continuous attribute over the range's real values (a function of a
    /// channel whose functions control different attributes, or that a mode
    /// master selects): as the channel would set it without functions.
    Set(Attribute),
    /// The dimmer curve every dimmer channel of the mode uses while this range is set.
    Curve(DimmerCurve),
    /// Nothing Footlight models (the state keeps its value).
    Hold,
}

/// Which gate value an [`Action::Gate`] range sets (units in [`FixtureState`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GateTarget {
    /// Indexed gobo rotation, degrees.
    GoboAngle,
    /// Continuous gobo rotation, degrees per second.
    GoboSpin,
    /// Gobo-wheel spin, degrees of the wheel per second.
    GoboWheelSpin,
    /// Indexed prism rotation, degrees.
    PrismAngle,
    /// Continuous prism rotation, degrees per second.
    PrismSpin,
    /// Blade `n` (0-3): insertion A.
    BladeA(u8),
    /// Blade `n` (0-3): insertion B.
    BladeB(u8),
    /// Blade `n` (0-3): edge rotation, degrees.
    BladeRot(u8),
    /// Rotation of the blade assembly, degrees.
    ShaperRot,
    /// Frost 0..1.
    Frost,
    /// Second gobo wheel: indexed rotation, degrees.
    Gobo2Angle,
    /// Second gobo wheel: continuous rotation, degrees per second.
    Gobo2Spin,
    /// Animation wheel: indexed rotation, degrees.
    AnimationAngle,
    /// Animation wheel: continuous rotation, degrees per second.
    AnimationSpin,
}

impl GateTarget {
    /// Writes `value` into the state's field.
    pub fn apply(self, s: &mut FixtureState, value: f32) {
        let blade = |n: u8| usize::from(n).min(3);
        match self {
            GateTarget::GoboAngle => s.gobo_angle = value,
            GateTarget::GoboSpin => s.gobo_spin = value,
            GateTarget::GoboWheelSpin => s.gobo_wheel_spin = value,
            GateTarget::PrismAngle => s.prism_angle = value,
            GateTarget::PrismSpin => s.prism_spin = value,
            GateTarget::BladeA(n) => s.blades[blade(n)][0] = value.clamp(0.0, 1.0),
            GateTarget::BladeB(n) => s.blades[blade(n)][1] = value.clamp(0.0, 1.0),
            GateTarget::BladeRot(n) => s.blades[blade(n)][2] = value,
            GateTarget::ShaperRot => s.shaper_rot = value,
            GateTarget::Frost => s.frost = value.clamp(0.0, 1.0),
            GateTarget::Gobo2Angle => s.gobo2[1] = value,
            GateTarget::Gobo2Spin => s.gobo2[2] = value,
            GateTarget::AnimationAngle => s.animation[1] = value,
            GateTarget::AnimationSpin => s.animation[2] = value,
        }
    }
}

impl Channel {
    /// The channel's raw value and full scale from `slot(offset)`.
    pub fn raw(&self, slot: &dyn Fn(u16) -> u8) -> (u16, u16) {
        match self.fine {
            Some(f) => (u16::from(slot(self.offset)) << 8 | u16::from(slot(f)), u16::MAX),
            None => (u16::from(slot(self.offset)), 255),
        }
    }

    /// The slots this channel writes for a raw `value` (coarse, then fine).
    pub fn slots_for(&self, value: u16) -> Vec<(u16, u8)> {
        match self.fine {
            Some(f) => vec![(self.offset, (value >> 8) as u8), (f, (value & 0xff) as u8)],
            None => vec![(self.offset, value.min(255) as u8)],
        }
    }

    /// Largest raw value (255 or 65535).
    pub fn full_scale(&self) -> u16 {
        if self.fine.is_some() { u16::MAX } else { 255 }
    }
}

/// A DMX mode: a named channel list.
#[derive(Clone, Debug)]
pub struct Mode {
    /// Name as the fixture's menu shows it.
    pub name: String,
    /// Channels in file order.
    pub channels: Vec<Channel>,
    /// Slots used from the start address (highest offset + 1).
    pub footprint: u16,
    /// Line of the `[[mode]]` entry.
    pub line: usize,
    /// GDTF `Override` relations ([`SlotOverride`]); empty for TOML types.
    pub overrides: Vec<SlotOverride>,
}

/// A GDTF `Relation Type="Override"` (DIN SPEC 15800 names the type
/// without a formula; Footlight's reading, docs/mvr-gdtf.md): while the
/// master DMX channel is above 0, the follower channel reads the master's
/// value (the same fraction of its own range); at 0 the follower keeps its
/// own value. Offsets as [`Channel::offset`] / [`Channel::fine`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlotOverride {
    /// The master's coarse and fine slot offsets.
    pub master: (u16, Option<u16>),
    /// The follower's coarse and fine slot offsets.
    pub follower: (u16, Option<u16>),
}

impl Mode {
    /// The value of slot `o` after the mode's [`SlotOverride`]s: a
    /// follower's slot reads its master's while the master is above 0.
    pub fn overridden(&self, slot: &dyn Fn(u16) -> u8, o: u16) -> u8 {
        for r in &self.overrides {
            let (mc, mf) = (slot(r.master.0), r.master.1.map_or(0, slot));
            if mc == 0 && mf == 0 {
                continue;
            }
            if o == r.follower.0 {
                return mc;
            }
            if Some(o) == r.follower.1 {
                // An 8-bit master on a 16-bit follower: m · 257 (the same fraction).
                return if r.master.1.is_some() { mf } else { mc };
            }
        }
        slot(o)
    }

    /// The channel controlling `attribute`, if any.
    pub fn channel(&self, attribute: Attribute) -> Option<&Channel> {
        self.channels.iter().find(|c| c.attribute == attribute)
    }

    /// The channel named `name` (as written in the type file), if any.
    pub fn channel_named(&self, name: &str) -> Option<&Channel> {
        self.channels.iter().find(|c| c.name.eq_ignore_ascii_case(name))
    }
}

/// Values set by hand for attributes a mode has no channel for (a manual
/// zoom or focus knob), in real units.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Manual {
    /// Field angle, degrees.
    pub zoom: Option<f32>,
    /// Focus 0..1.
    pub focus: Option<f32>,
    /// Iris fraction.
    pub iris: Option<f32>,
    /// Pan, degrees.
    pub pan: Option<f32>,
    /// Tilt, degrees.
    pub tilt: Option<f32>,
}

impl FixtureType {
    /// The mode named `name` (case-insensitive).
    pub fn mode(&self, name: &str) -> Option<usize> {
        self.modes.iter().position(|m| m.name.eq_ignore_ascii_case(name))
    }

    /// The state with no DMX: manual values, else each attribute at rest
    /// (v = 1 if the mode has no dimmer, emitters at full, pan/tilt 0, the
    /// first zoom field, focus 0, iris open).
    pub fn rest_state(&self, manual: &Manual) -> FixtureState {
        let mut mix = [0.0; MAX_MIX];
        if matches!(self.lamp, Lamp::Led { .. }) {
            mix.iter_mut().take(self.mix_names.len()).for_each(|m| *m = 1.0);
        }
        let zoom = match &self.optics {
            Optics::Spot(s) => s.zoom[0],
            _ => 0.0,
        };
        FixtureState {
            v: 1.0,
            frame: 0.0,
            mix,
            pan: manual.pan.unwrap_or(0.0),
            tilt: manual.tilt.unwrap_or(0.0),
            zoom: manual.zoom.unwrap_or(zoom),
            focus: manual.focus.unwrap_or(0.0),
            iris: manual.iris.unwrap_or(1.0),
            ..FixtureState::default()
        }
    }

    /// Decodes mode `mode`'s channels, reading slot values with `slot`
    /// (offset from the start address, 0-based; slots past the universe
    /// read as 0). Attributes without a channel keep [`FixtureType::rest_state`].
    ///
    /// A channel with functions applies the function whose range holds its
    /// value among those its mode master selects ([`ModeGate`]; none: the
    /// channel does nothing). Several dimmers multiply (a master dimmer on
    /// the fixture and a cell's own, a GDTF sub-fixture), each through the
    /// curve a `DimmerCurve` channel selects, else its own. Colour targets
    /// (HSB, CIE, a colour macro, a CCT with tint) set an LED type's
    /// emitter levels ([`colour`]); their brightness multiplies v.
    pub fn decode(&self, mode: &Mode, manual: &Manual, slot: &dyn Fn(u16) -> u8) -> FixtureState {
        let read = |o: u16| mode.overridden(slot, o);
        let slot: &dyn Fn(u16) -> u8 = if mode.overrides.is_empty() { slot } else { &read };
        let mut s = self.rest_state(manual);
        // The dimmer curve a DimmerCurve/DimmerMode channel selects shapes every dimmer: read it first.
        let curve = mode
            .channels
            .iter()
            .filter(|c| c.attribute == Attribute::DimmerCurve)
            .filter_map(|c| function_at(c, slot))
            .find_map(|(f, _)| match f.action {
                Action::Curve(k) => Some(k),
                _ => None,
            });
        let mut acc = Decoded::default();
        for c in &mode.channels {
            let curve = curve.unwrap_or(c.curve);
            if !c.functions.is_empty() {
                if let Some((f, x)) = function_at(c, slot) {
                    let real = f.range[0] * (1.0 - x) + f.range[1] * x;
                    match f.action {
                        Action::Open => (s.shutter, s.strobe) = (1.0, 0.0),
                        Action::Closed => (s.shutter, s.strobe) = (0.0, 0.0),
                        Action::Strobe => (s.shutter, s.strobe) = (1.0, if real > 0.0 { real } else { 0.0 }),
                        Action::Slot(i) => {
                            let i = f32::from(i);
                            match c.attribute {
                                Attribute::Gobo => (s.gobo, s.gobo_wheel_spin) = (i, 0.0),
                                Attribute::Prism => s.prism = i,
                                Attribute::ColourWheelN(n) => s.wheels[usize::from(n).min(2)] = i,
                                Attribute::ColourMacro => s.colour_macro = Some(i),
                                Attribute::Gobo2 => s.gobo2[0] = i,
                                Attribute::Animation => s.animation[0] = i,
                                _ => s.wheel = i,
                            }
                        }
                        Action::Gate(t) => {
                            if real.is_finite() {
                                t.apply(&mut s, real);
                            }
                        }
                        Action::Set(a) => set_value(&mut s, &mut acc, a, real, real, curve),
                        Action::Curve(_) | Action::Hold => {}
                    }
                }
                continue;
            }
            let (raw, full) = c.raw(slot);
            let x = f32::from(raw) / f32::from(full);
            let real = c.range[0] * (1.0 - x) + c.range[1] * x; // exact at both ends
            if c.attribute == Attribute::Scroller {
                if let Some(sc) = &c.scroller {
                    s.frame = if full == 255 { sc.position_from_dmx8(raw as u8) } else { sc.position_from_dmx16(raw) };
                }
                continue;
            }
            let level = if full == 255 {
                footlight_photometry::dimmer::level_from_dmx8(raw as u8)
            } else {
                footlight_photometry::dimmer::level_from_dmx16(raw)
            };
            set_value(&mut s, &mut acc, c.attribute, real, level, curve);
        }
        self.finish(&mut s, &acc);
        s
    }

    /// The colour target of a state (a colour macro's slot colour, else the
    /// CIE xy, else the HSB hue and saturation) and its brightness.
    fn colour_target(&self, s: &FixtureState) -> (Option<Vec2>, f32) {
        let macro_xy = s.colour_macro.and_then(|m| slot_at(&self.colour_macros, m).copied().flatten());
        match (macro_xy, s.cie, s.hsb) {
            (Some(xy), _, _) => (Some(xy), 1.0),
            (None, Some([x, y, b]), _) => (Some(Vec2::new(x, y)), b),
            (None, None, Some([h, sat, b])) => (Some(hsb_xy(h, sat)), b),
            _ => (None, 1.0),
        }
    }

    /// After the channels: unmixed colour levels and target brightness
    /// scale v; an LED type's emitters go to the colour target, the CCT
    /// and tint, or the corrected mix.
    fn finish(&self, s: &mut FixtureState, acc: &Decoded) {
        if let Some(l) = acc.level {
            s.v *= l;
        }
        let (target, bright) = self.colour_target(s);
        s.v *= if bright > 0.0 { bright.min(1.0) } else { 0.0 };
        let Lamp::Led { emitters } = &self.lamp else { return };
        let Some(set) = EmitterSet::of(emitters) else { return };
        let correcting = (s.cto > 0.0 && s.cto.is_finite()) || (s.tint != 0.0 && s.tint.is_finite());
        let mut levels = match (target, correcting) {
            (None, false) => return,
            (Some(xy), false) => set.levels_for_xy(xy),
            // A colour-temperature mode (no colour channel): mix the target white.
            (None, true) if !acc.mixed => set.levels_for_xy(self.target_white(s, &set)),
            // A correction of the mixed or targeted colour.
            (t, true) => {
                let base = match t {
                    Some(xy) => set.levels_for_xy(xy).map(|l| set.xyz(&l)),
                    None => Some(set.xyz(&s.mix)),
                };
                let (from, to) = self.correction_whites(s, &set);
                let tau = match (&self.cto, s.cto > 0.0) {
                    (Some(table), true) => table.at(s.cto),
                    _ => 1.0,
                };
                base.map(|xyz| set.levels_for_xyz(bradford(xyz, from, to) * f64::from(tau)))
            }
        };
        if let Some(l) = levels.as_mut() {
            for (m, x) in s.mix.iter_mut().zip(l.iter()).take(emitters.len()) {
                *m = *x;
            }
        }
    }

    /// The white a CCT/tint setting asks of an LED type: the Planckian
    /// locus at the CTO/CTB/CTC target (else the type's own CCT) moved by the tint.
    fn target_white(&self, s: &FixtureState, set: &EmitterSet) -> Vec2 {
        let native_k = self.native_cct(set);
        let k = if s.cto > 0.0 && s.cto.is_finite() { s.cto } else { native_k };
        white_xy(k, if s.tint.is_finite() { s.tint } else { 0.0 })
    }

    /// The whites a correction of an LED type's mix adapts between: the
    /// emitters' full white, and that white moved in (u, v) as the
    /// Planckian locus moves from the type's own CCT to the target (CTO/CTB/CTC)
    /// and then by the tint. A correction to the type's own CCT without a
    /// tint changes nothing.
    fn correction_whites(&self, s: &FixtureState, set: &EmitterSet) -> (Vec2, Vec2) {
        let native = srgb::xy(set.white().as_vec3()).unwrap_or(Vec2::new(0.3127, 0.3290));
        let native_k = self.native_cct(set);
        let shift = uv_of(self.target_white(s, set)) - uv_of(planck_xy(native_k));
        (native, xy_of_uv(uv_of(native) + shift))
    }

    /// The CCT of an LED type's full white: the correction table's (the
    /// beam's colour temperature) when there is one, else McCamy's estimate
    /// of the emitters' full mix.
    fn native_cct(&self, set: &EmitterSet) -> f32 {
        match &self.cto {
            Some(t) => t.from_k,
            None => {
                let xy = srgb::xy(set.white().as_vec3()).unwrap_or(Vec2::new(0.3127, 0.3290));
                srgb::cct_mccamy(xy).clamp(1000.0, 25_000.0)
            }
        }
    }

    /// The beam (unit-intensity pattern) for a state: a spot shaped by its
    /// gate ([`FixtureType::gate_of`]) when anything is in it.
    pub fn beam(&self, state: &FixtureState) -> Beam {
        match &self.optics {
            Optics::Spot(o) => {
                let spot = o.open_beam(state.zoom, state.focus).irised(state.iris);
                let gate = self.gate_of(state);
                if gate.is_open() { Beam::Spot(spot) } else { Beam::Shaped(Box::new(ShapedBeam::new(spot, gate))) }
            }
            Optics::Hermite(h) => {
                Beam::Hermite(HermiteBeam::new(h.spot.clone(), h.spot_cd, h.flood.clone(), h.flood_cd, state.focus))
            }
            Optics::Measured(t) => Beam::Measured(MeasuredBeam::new(t.clone())),
        }
    }

    /// The gate for a state: the gobo-wheel slot's image at the state's
    /// angle, the blades, the prism slot's facets, the frost. Only spot
    /// optics have a gate (GDTF profile and moving-head spots).
    pub fn gate_of(&self, state: &FixtureState) -> Gate {
        let finite = |v: f32| if v.is_finite() { v } else { 0.0 };
        let blade = |b: [f32; 3]| Blade { a: finite(b[0]), b: finite(b[1]), rot: finite(b[2]) };
        Gate {
            gobo: slot_at(&self.gate.gobo_wheel, state.gobo).cloned().flatten(),
            gobo_angle: finite(state.gobo_angle),
            blades: state.blades.map(blade),
            shaper_rot: finite(state.shaper_rot),
            facets: slot_at(&self.gate.prism_wheel, state.prism).cloned().unwrap_or_default(),
            prism_angle: finite(state.prism_angle),
            frost: finite(state.frost),
            layers: [(&self.gate.gobo_wheel2, state.gobo2), (&self.gate.animation_wheel, state.animation)]
                .into_iter()
                .filter_map(|(wheel, [slot, angle, _])| {
                    let image = slot_at(wheel, slot).cloned().flatten()?;
                    Some(GoboLayer { image, angle: finite(angle) })
                })
                .collect(),
        }
    }

    /// The state at frame time `t_seconds` with its gobo/prism spins and
    /// gobo-wheel spin applied ([`FixtureState::at_time`] over this type's
    /// gobo wheel). A rotation with nothing in the beam to turn (an open
    /// gobo slot, no prism in) keeps its angle: it does not change the
    /// beam, so it must not make the light a moving one that is rebuilt at
    /// [`crate::state::SPIN_UPDATE_HZ`] and never reaches its Whitted and photon
    /// stages (issue 38: the festival show's 24 profiles, prism out with its
    /// rotation channel at the default 128, stayed at their direct stage).
    pub fn state_at(&self, state: &FixtureState, t_seconds: f64) -> FixtureState {
        let mut s = state.at_time(t_seconds, self.gate.gobo_wheel.len());
        if slot_at(&self.gate.gobo_wheel, s.gobo).is_none_or(Option::is_none) {
            s.gobo_angle = state.gobo_angle;
        }
        if slot_at(&self.gate.prism_wheel, s.prism).is_none_or(Vec::is_empty) {
            s.prism_angle = state.prism_angle;
        }
        if slot_at(&self.gate.gobo_wheel2, s.gobo2[0]).is_none_or(Option::is_none) {
            s.gobo2[1] = state.gobo2[1];
        }
        if slot_at(&self.gate.animation_wheel, s.animation[0]).is_none_or(Option::is_none) {
            s.animation[1] = state.animation[1];
        }
        s
    }

    /// Î in candela for a state: zoom and edge focus keep the flux (profile),
    /// the iris keeps Î, Fresnel/PC focus mixes the spot and flood peaks.
    pub fn intensity(&self, state: &FixtureState) -> f32 {
        match &self.optics {
            Optics::Spot(o) => o.intensity_at(state.zoom, state.focus),
            Optics::Hermite(h) => {
                HermiteBeam::new(h.spot.clone(), h.spot_cd, h.flood.clone(), h.flood_cd, state.focus).peak_cd()
            }
            Optics::Measured(t) => t.peak_cd(),
        }
    }

    /// The lamp with the state's colour mix applied (c_I of eq. 4 comes from it).
    pub fn lamp_for(&self, state: &FixtureState) -> Lamp {
        let mix = |i: usize| state.mix[i].clamp(0.0, 1.0);
        match &self.lamp {
            Lamp::Led { emitters } => {
                let mut emitters = emitters.clone();
                for (i, e) in emitters.iter_mut().enumerate().take(MAX_MIX) {
                    e.level = mix(i);
                }
                Lamp::Led { emitters }
            }
            Lamp::Cmy { cct, filters, .. } => Lamp::Cmy {
                cct: corrected(*cct, state.cto),
                cyan: mix(0),
                magenta: mix(1),
                yellow: mix(2),
                filters: filters.clone(),
            },
            Lamp::Tungsten { cct_full } => Lamp::Tungsten { cct_full: corrected(*cct_full, state.cto) },
            Lamp::Discharge { cct } => Lamp::Discharge { cct: corrected(*cct, state.cto) },
        }
    }

    /// The colour-wheel slot in the beam for a state (`None`: no wheel).
    pub fn wheel_slot(&self, state: &FixtureState) -> Option<&WheelSlot> {
        let i = if state.wheel.is_finite() && state.wheel > 0.0 { state.wheel.round() as usize } else { 0 };
        self.colour_wheel.get(i.min(self.colour_wheel.len().saturating_sub(1)))
    }

    /// The luminous transmittance of the colour-correction filter for a
    /// state (1 without one): CTO/CTB change the Planckian lamp's CCT in
    /// [`FixtureType::lamp_for`] and cost this much light. An LED type's
    /// correction is in its emitter levels already ([`FixtureType::decode`]): 1.
    pub fn correction(&self, state: &FixtureState) -> f32 {
        match (&self.cto, state.cto > 0.0, &self.lamp) {
            (_, _, Lamp::Led { .. }) => 1.0,
            (Some(t), true, _) => t.at(state.cto),
            _ => 1.0,
        }
    }

    /// The slot of colour wheel `n` (0: `Color1`, 1-3: `Color2`…`Color4`) in the beam.
    pub fn wheel_slot_n(&self, state: &FixtureState, n: usize) -> Option<&WheelSlot> {
        match n {
            0 => self.wheel_slot(state),
            n => slot_at(self.extra_wheels.get(n - 1)?, state.wheels.get(n - 1).copied().unwrap_or(0.0)),
        }
    }

    /// The filters in the beam for a state, as eq. 4's c_F: the first
    /// colour-wheel slot (wheels 1-4 in order) with a measured spectrum,
    /// applied spectrally by the caller, and a per-channel factor for
    /// everything else: the other wheels' slots (xyY factors; a second
    /// measured filter by its [`footlight_photometry::filter_factor`] on
    /// `lamp`) and, on a lamp that cannot mix (tungsten, discharge, CMY), a
    /// colour target (HSB, CIE, macro) as the filter from the lamp's white
    /// to it ([`colour::filter_between`], estimated) and a tint as a shift
    /// at equal luminance ([`colour::shift_between`]).
    pub fn filters<'a>(&'a self, state: &FixtureState, lamp: &Lamp) -> (Option<&'a Arc<Gel>>, Vec3) {
        let mut gel: Option<&Arc<Gel>> = None;
        let mut factor = Vec3::ONE;
        for n in 0..=self.extra_wheels.len() {
            match self.wheel_slot_n(state, n) {
                Some(WheelSlot::Factor(c)) => factor *= *c,
                Some(WheelSlot::Filter(g)) if gel.is_none() => gel = Some(g),
                Some(WheelSlot::Filter(g)) => {
                    factor *= footlight_photometry::filter_factor(lamp, 1.0, Some(g.as_ref()));
                }
                None => {}
            }
        }
        if !matches!(lamp, Lamp::Led { .. }) {
            let (target, _) = self.colour_target(state);
            let tinted = state.tint != 0.0 && state.tint.is_finite();
            if target.is_some() || tinted {
                let white = srgb::xy(srgb::linear_srgb_to_xyz(lamp.colour(1.0))).unwrap_or(Vec2::new(0.3127, 0.3290));
                if let Some(xy) = target {
                    factor *= filter_between(white, xy);
                }
                if tinted {
                    let k = lamp.temperature(1.0).unwrap_or(6500.0);
                    factor *= shift_between(planck_xy(k), white_xy(k, state.tint));
                }
            }
        }
        (gel, if factor.is_finite() { factor.max(Vec3::ZERO) } else { Vec3::ONE })
    }
}

/// Accumulated while decoding, applied after the channels ([`FixtureType::decode`]).
#[derive(Default)]
struct Decoded {
    /// The largest level of the additive colour channels the type cannot mix ([`Attribute::Level`]).
    level: Option<f32>,
    /// True when a colour-mix channel (emitter or flag) was decoded.
    mixed: bool,
}

/// The function of channel `c` that applies at its current value, and
/// where the value sits in its range (0..1): among the functions its mode
/// master selects, the last whose range holds the value, else the last
/// starting at or below it (channel sets that leave gaps).
fn function_at<'a>(c: &'a Channel, slot: &dyn Fn(u16) -> u8) -> Option<(&'a Function, f32)> {
    let (raw, _) = c.raw(slot);
    let active = |f: &&Function| f.active(slot);
    let f = c
        .functions
        .iter()
        .rev()
        .filter(active)
        .find(|f| f.from <= raw && raw <= f.to)
        .or_else(|| c.functions.iter().rev().filter(active).find(|f| f.from <= raw))?;
    let span = f32::from(f.to.saturating_sub(f.from)).max(1.0);
    let x = (f32::from(raw.min(f.to).saturating_sub(f.from)) / span).clamp(0.0, 1.0);
    Some((f, x))
}

/// Writes a continuous attribute's value into the state: `real` in the
/// attribute's unit, `level` the dimmer's control level 0..1 (through `curve`).
fn set_value(s: &mut FixtureState, acc: &mut Decoded, attribute: Attribute, real: f32, level: f32, curve: DimmerCurve) {
    const HSB: [f32; 3] = [0.0, 1.0, 1.0];
    const CIE: [f32; 3] = [0.3127, 0.3290, 1.0];
    let unit = |x: f32| if x > 0.0 { x.min(1.0) } else { 0.0 };
    match attribute {
        Attribute::Dimmer => s.v *= curve.v(level),
        Attribute::Pan => s.pan = real,
        Attribute::Tilt => s.tilt = real,
        Attribute::Zoom => s.zoom = real,
        Attribute::Focus => s.focus = real.clamp(0.0, 1.0),
        Attribute::Iris => s.iris = real.clamp(0.0, 1.0),
        Attribute::Mix(i) => {
            s.mix[usize::from(i).min(MAX_MIX - 1)] = real.clamp(0.0, 1.0);
            acc.mixed = true;
        }
        Attribute::Cto => s.cto = real,
        Attribute::Tint => s.tint = if real.is_finite() { real } else { 0.0 },
        Attribute::Hue => s.hsb.get_or_insert(HSB)[0] = real,
        Attribute::Saturation => s.hsb.get_or_insert(HSB)[1] = unit(real),
        Attribute::HsbBrightness => s.hsb.get_or_insert(HSB)[2] = unit(real),
        Attribute::CieX => s.cie.get_or_insert(CIE)[0] = unit(real),
        Attribute::CieY => s.cie.get_or_insert(CIE)[1] = unit(real),
        Attribute::CieBrightness => s.cie.get_or_insert(CIE)[2] = unit(real),
        Attribute::StrobeDuration => s.strobe_duration = if real > 0.0 && real.is_finite() { real } else { 0.0 },
        Attribute::Level => acc.level = Some(acc.level.unwrap_or(0.0).max(unit(real))),
        Attribute::Scroller
        | Attribute::Shutter
        | Attribute::ColourWheel
        | Attribute::ColourWheelN(_)
        | Attribute::ColourMacro
        | Attribute::Gobo
        | Attribute::Gobo2
        | Attribute::Animation
        | Attribute::Prism
        | Attribute::Gate
        | Attribute::DimmerCurve
        | Attribute::Mode
        | Attribute::Other => {}
    }
}

#[cfg(test)]
mod correction_tests {
    use super::*;

    #[test]
    fn wheel_factor_of_the_srgb_primaries_and_white() {
        let near = |a: Vec3, b: Vec3| (a - b).abs().max_element() < 2e-3;
        assert!(near(wheel_factor(0.3127, 0.3290, 100.0), Vec3::ONE));
        assert!(near(wheel_factor(0.64, 0.33, 21.26), Vec3::X));
        assert!(near(wheel_factor(0.30, 0.60, 71.52), Vec3::Y));
        assert!(near(wheel_factor(0.15, 0.06, 7.22), Vec3::Z));
        // Half the light of white at the white point: a neutral density.
        assert!(near(wheel_factor(0.3127, 0.3290, 50.0), Vec3::splat(0.5)));
        // Out of the sRGB gamut: no negative transmission; nonsense: open.
        assert!(wheel_factor(0.08, 0.83, 50.0).min_element() >= 0.0);
        assert_eq!(wheel_factor(f32::NAN, 0.3, 10.0), Vec3::ONE);
    }

    #[test]
    fn correction_table_matches_the_direct_integral() {
        let t = CorrectionTable::new(5600.0, [5600.0, 2700.0]);
        assert!((t.at(5600.0) - 1.0).abs() < 1e-6);
        // A range across the lamp's own CCT: exactly 1 there (the kink is a node).
        let across = CorrectionTable::new(6500.0, [2700.0, 8000.0]);
        assert!((across.at(6500.0) - 1.0).abs() < 1e-6, "{}", across.at(6500.0));
        assert!((across.at(7000.0) - correction_transmittance(6500.0, 7000.0)).abs() < 2e-3);
        for k in [2700.0, 3000.0, 3200.0, 4100.0, 5000.0] {
            let (a, b) = (t.at(k), correction_transmittance(5600.0, k));
            assert!((a - b).abs() < 2e-3, "{k}: table {a} direct {b}");
            assert!(b > 0.0 && b < 1.0);
        }
        // Stronger correction costs more light; CTB from tungsten too.
        assert!(correction_transmittance(5600.0, 2700.0) < correction_transmittance(5600.0, 4000.0));
        assert!(correction_transmittance(3200.0, 5600.0) < 1.0);
        assert_eq!(correction_transmittance(3200.0, f32::NAN), 1.0);
    }
}
