//! A fixture's state in real units, decoded from DMX, and how a change of
//! state reaches the renderer (DESIGN.md data flow; issue 5 item 6).
//!
//! ```text
//! 512-slot frames ──decode──> FixtureState ──┬─ light_of ─> Light (geometry: tracer)
//!                                             └─ k_of ────> k_i (eq. 4: compositor)
//! ```
//!
//! [`classify`] compares two states of one fixture: nothing changed → no
//! event; dimmer, colour mix, colour frame, colour-wheel slots (wheels 1-4),
//! CTO/CTB, tint, HSB, CIE, colour macro, shutter, strobe rate or duration
//! → the composite only (k_i); pan, tilt, zoom, focus, iris, gobo (both
//! wheels: slot, rotation, spin), animation wheel, framing-shutter blades,
//! prism and frost → geometry, which marks the light dirty for a rebuild (and,
//! since zoom changes Î, also needs a new k_i). Spinning gobos and prisms
//! step on the frame clock at [`SPIN_UPDATE_HZ`] ([`FixtureState::at_time`]).
//!
//! A strobing fixture's state does not change from frame to frame: the
//! strobe is a time factor on k_i ([`FixtureState::shutter_at`]), evaluated
//! on the frame clock, so it costs a composite per frame and never a
//! rebuild.

use std::collections::BTreeMap;

/// Slots in a DMX universe.
pub const SLOTS: usize = 512;

/// Most colour-mix channels (LED emitters or CMY flags) a fixture type may have
/// (the length of [`FixtureState::mix`], written as a literal there: rustc 1.9x
/// ICEs on a closure that moves a struct whose array length is a named const).
pub const MAX_MIX: usize = 8;

/// One fixture's state in real units. Attributes the fixture does not have
/// hold its fixed value (e.g. a PAR's field angle, pan 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FixtureState {
    /// Dimmer factor v of eq. 4, 0..1, after the mode's dimmer curve.
    pub v: f32,
    /// Colour-scroller position in frames (0 = first frame; 1.5 = half frame 1, half frame 2).
    pub frame: f32,
    /// Colour mix 0..1: LED emitter levels in the type's emitter order, or CMY flags [c, m, y].
    pub mix: [f32; 8],
    /// Pan in degrees, 0 at the DMX centre of the range.
    pub pan: f32,
    /// Tilt in degrees, 0 at the DMX centre of the range.
    pub tilt: f32,
    /// Zoom as the full field angle (10 % of peak) in degrees.
    pub zoom: f32,
    /// Focus 0..1: Fresnel/PC spot → flood, profile hard → soft edge.
    pub focus: f32,
    /// Iris as a fraction of the open gate diameter (1 = open).
    pub iris: f32,
    /// Colour-wheel slot, 0-based (0 is the wheel's first slot, usually open).
    pub wheel: f32,
    /// Colour-correction target in kelvin (CTO below the lamp's CCT, CTB
    /// above); 0 = no correction filter.
    pub cto: f32,
    /// Shutter: 1 open, 0 closed (a closed shutter makes k_i black).
    pub shutter: f32,
    /// Strobe rate in Hz while the shutter strobes; 0 = steady.
    pub strobe: f32,
    /// Gobo-wheel position in slots, 0-based (0 is the wheel's first slot, usually open).
    pub gobo: f32,
    /// Gobo rotation (indexed), degrees counter-clockwise.
    pub gobo_angle: f32,
    /// Continuous gobo rotation, degrees per second (added on the frame clock: [`FixtureState::at_time`]).
    pub gobo_spin: f32,
    /// Gobo-wheel spin through its slots, degrees of the wheel per second.
    pub gobo_wheel_spin: f32,
    /// Framing-shutter blades 1-4: [insertion A, insertion B (fractions of
    /// the gate diameter), edge rotation in degrees].
    pub blades: [[f32; 3]; 4],
    /// Rotation of the blade assembly, degrees.
    pub shaper_rot: f32,
    /// Prism-wheel slot, 0-based (0: usually no prism).
    pub prism: f32,
    /// Prism rotation (indexed), degrees.
    pub prism_angle: f32,
    /// Continuous prism rotation, degrees per second.
    pub prism_spin: f32,
    /// Frost 0 (none) .. 1 (full).
    pub frost: f32,
    /// Colour wheels 2-4 (GDTF `Color2` … `Color4`): slots, 0-based; their
    /// filters multiply the first wheel's ([`crate::FixtureType::filters`]).
    pub wheels: [f32; 3],
    /// HSB control (GDTF `HSB_Hue`, `HSB_Saturation`, `HSB_Brightness`):
    /// [hue in degrees, saturation 0..1, brightness 0..1]; `None` when the
    /// mode has no active HSB channel. An LED type mixes its emitters to the
    /// hue's chromaticity; the brightness multiplies v.
    pub hsb: Option<[f32; 3]>,
    /// CIE control (GDTF `CIE_X`, `CIE_Y`, `CIE_Brightness`): [x, y,
    /// brightness 0..1]; `None` when the mode has no active CIE channel.
    pub cie: Option<[f32; 3]>,
    /// Colour-macro slot (GDTF `ColorMacro1` linked to a wheel whose slots
    /// carry colours), 0-based; `None` when no macro is active.
    pub colour_macro: Option<f32>,
    /// Green/magenta tint as Duv (CIE 1960 distance from the Planckian
    /// locus, positive toward green); 0 = none.
    pub tint: f32,
    /// Duration of one strobe flash in seconds (GDTF `StrobeDuration`);
    /// 0 = not given (the duty cycle is [`STROBE_DUTY`]).
    pub strobe_duration: f32,
    /// Second gobo wheel: [slot (0-based), indexed angle in degrees,
    /// rotation in degrees per second].
    pub gobo2: [f32; 3],
    /// Animation wheel: [slot (0-based), indexed angle in degrees, rotation
    /// in degrees per second].
    pub animation: [f32; 3],
}

/// Most rebuilds per second that a spinning gobo, prism or gobo wheel asks
/// for: [`FixtureState::at_time`] steps the angles on this clock, so a
/// spinning light is marked dirty at most this often (a rebuild of one
/// narrow spot costs a few ms, docs/mvr-gdtf.md).
pub const SPIN_UPDATE_HZ: f64 = 15.0;

/// Fraction of each strobe period the shutter is open (estimated: a
/// mechanical or LED strobe at a 50 % duty cycle; discharge flash tubes are
/// shorter, GDTF gives no duty cycle).
pub const STROBE_DUTY: f64 = 0.5;

impl FixtureState {
    /// True when something turns on the frame clock (gobo or prism
    /// rotation, gobo-wheel spin).
    pub fn spins(&self) -> bool {
        [self.gobo_spin, self.gobo_wheel_spin, self.prism_spin, self.gobo2[2], self.animation[2]]
            .iter()
            .any(|v| v.is_finite() && *v != 0.0)
    }

    /// The state at frame time `t_seconds` with its spins applied: gobo and
    /// prism angles advanced by their rates, the gobo wheel advanced through
    /// its `gobo_slots` slots (360°/slots per slot, wrapping), all on a
    /// clock stepped at [`SPIN_UPDATE_HZ`], so consecutive frames within one
    /// step give equal states (no rebuild) and a spinning light is rebuilt
    /// at most [`SPIN_UPDATE_HZ`] times a second. The spin rates are kept,
    /// so [`classify`] of two timed states sees only the angle steps. Pure.
    pub fn at_time(&self, t_seconds: f64, gobo_slots: usize) -> FixtureState {
        if !self.spins() || !t_seconds.is_finite() {
            return *self;
        }
        let t = (t_seconds * SPIN_UPDATE_HZ).floor() / SPIN_UPDATE_HZ;
        let turn = |base: f32, rate: f32| {
            if rate.is_finite() && rate != 0.0 {
                (f64::from(base) + f64::from(rate) * t).rem_euclid(360.0) as f32
            } else {
                base
            }
        };
        let mut s = *self;
        s.gobo_angle = turn(self.gobo_angle, self.gobo_spin);
        s.prism_angle = turn(self.prism_angle, self.prism_spin);
        s.gobo2[1] = turn(self.gobo2[1], self.gobo2[2]);
        s.animation[1] = turn(self.animation[1], self.animation[2]);
        if gobo_slots > 0 && self.gobo_wheel_spin.is_finite() && self.gobo_wheel_spin != 0.0 {
            let n = gobo_slots as f64;
            let pos = f64::from(self.gobo) + f64::from(self.gobo_wheel_spin) * t * n / 360.0;
            s.gobo = pos.rem_euclid(n) as f32;
        }
        s
    }

    /// The strobe's duty cycle: the flash duration times the rate when the
    /// type gives a duration (GDTF `StrobeDuration`), clamped to [0, 1];
    /// else [`STROBE_DUTY`].
    pub fn strobe_duty(&self) -> f64 {
        let (d, hz) = (f64::from(self.strobe_duration), f64::from(self.strobe));
        if d > 0.0 && d.is_finite() && hz > 0.0 && hz.is_finite() { (d * hz).clamp(0.0, 1.0) } else { STROBE_DUTY }
    }

    /// The shutter's transmission at frame time `t_seconds`: 0 closed, 1
    /// open, and while strobing 1 for the first [`FixtureState::strobe_duty`]
    /// of each period `1/strobe` and 0 after it. The phase origin is t = 0 of the
    /// frame clock, so fixtures at the same rate flash together (as a desk's
    /// "strobe sync"). Pure: stills evaluate it at t = 0 (open).
    pub fn shutter_at(&self, t_seconds: f64) -> f32 {
        if !(self.shutter >= 0.5) {
            return 0.0;
        }
        let hz = f64::from(self.strobe);
        if !(hz > 0.0 && hz.is_finite() && t_seconds.is_finite()) {
            return 1.0;
        }
        let phase = (t_seconds * hz).rem_euclid(1.0);
        if phase < self.strobe_duty() { 1.0 } else { 0.0 }
    }
}

impl Default for FixtureState {
    /// Dark, open, centred: v 0, frame 0, no mix, pan/tilt 0, zoom 0, focus 0,
    /// iris open, first wheel slot, no CTO, shutter open, no strobe.
    fn default() -> Self {
        Self {
            v: 0.0,
            frame: 0.0,
            mix: [0.0; MAX_MIX],
            pan: 0.0,
            tilt: 0.0,
            zoom: 0.0,
            focus: 0.0,
            iris: 1.0,
            wheel: 0.0,
            cto: 0.0,
            shutter: 1.0,
            strobe: 0.0,
            gobo: 0.0,
            gobo_angle: 0.0,
            gobo_spin: 0.0,
            gobo_wheel_spin: 0.0,
            blades: [[0.0; 3]; 4],
            shaper_rot: 0.0,
            prism: 0.0,
            prism_angle: 0.0,
            prism_spin: 0.0,
            frost: 0.0,
            wheels: [0.0; 3],
            hsb: None,
            cie: None,
            colour_macro: None,
            tint: 0.0,
            strobe_duration: 0.0,
            gobo2: [0.0; 3],
            animation: [0.0; 3],
        }
    }
}

/// What a state change costs the renderer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Change {
    /// Nothing the renderer sees changed: no event.
    Unchanged,
    /// Only k_i changed (dimmer, colour mix, colour frame, colour wheel,
    /// CTO/CTB, shutter, strobe rate, and with them CCT): recomposite.
    Composite,
    /// The beam moved or changed shape (pan, tilt, zoom, focus, iris, gobo,
    /// blades, prism, frost): mark
    /// the light dirty and rebuild it; k_i is recomputed too.
    Geometry,
}

/// Classifies the change from `old` to `new` of one fixture. Pure: the
/// same two states always give the same answer.
pub fn classify(old: &FixtureState, new: &FixtureState) -> Change {
    let geometry = old.pan != new.pan
        || old.tilt != new.tilt
        || old.zoom != new.zoom
        || old.focus != new.focus
        || old.iris != new.iris
        || gate_changed(old, new);
    if geometry {
        return Change::Geometry;
    }
    if old.v != new.v
        || old.frame != new.frame
        || old.mix != new.mix
        || old.wheel != new.wheel
        || old.cto != new.cto
        || old.shutter != new.shutter
        || old.strobe != new.strobe
        || old.wheels != new.wheels
        || old.hsb != new.hsb
        || old.cie != new.cie
        || old.colour_macro != new.colour_macro
        || old.tint != new.tint
        || old.strobe_duration != new.strobe_duration
    {
        return Change::Composite;
    }
    Change::Unchanged
}

/// True when anything in the gate changed (gobo slot, angle or spin,
/// blades, shaper rotation, prism, frost): the beam's shape, so the light
/// is rebuilt.
fn gate_changed(old: &FixtureState, new: &FixtureState) -> bool {
    old.gobo != new.gobo
        || old.gobo_angle != new.gobo_angle
        || old.gobo_spin != new.gobo_spin
        || old.gobo_wheel_spin != new.gobo_wheel_spin
        || old.blades != new.blades
        || old.shaper_rot != new.shaper_rot
        || old.prism != new.prism
        || old.prism_angle != new.prism_angle
        || old.prism_spin != new.prism_spin
        || old.frost != new.frost
        || old.gobo2 != new.gobo2
        || old.animation != new.animation
}

/// Read access to the latest 512-slot frame of each patch universe, in
/// place: what decoding reads. The daemon implements it over the DMX
/// crate's merged frames (no copy per packet or per frame); stills and tests
/// use [`Universes`].
pub trait DmxSlots {
    /// The frame of patch `universe` (1-based), if any arrived.
    fn slots(&self, universe: u16) -> Option<&[u8; SLOTS]>;
}

impl DmxSlots for Universes {
    fn slots(&self, universe: u16) -> Option<&[u8; SLOTS]> {
        self.get(universe)
    }
}

/// The latest 512-slot frame of each patch universe (1-based numbers, as
/// desks show them). Slot `ADDR` is `slots[ADDR - 1]`. Kept independent of
/// the DMX crate (stills, `--set`, tests); the daemon reads the DMX crate's
/// frames through [`DmxSlots`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Universes {
    frames: BTreeMap<u16, Box<[u8; SLOTS]>>,
}

impl Universes {
    /// No universes.
    pub fn new() -> Self {
        Self::default()
    }

    /// The frame of `universe`, if any arrived.
    pub fn get(&self, universe: u16) -> Option<&[u8; SLOTS]> {
        self.frames.get(&universe).map(|b| &**b)
    }

    /// Replaces the frame of `universe`.
    pub fn set(&mut self, universe: u16, slots: &[u8; SLOTS]) {
        self.frames.insert(universe, Box::new(*slots));
    }

    /// The frame of `universe` for writing, created dark if absent.
    pub fn frame_mut(&mut self, universe: u16) -> &mut [u8; SLOTS] {
        self.frames.entry(universe).or_insert_with(|| Box::new([0; SLOTS]))
    }

    /// Sets one slot (`address` 1-512; others are ignored).
    pub fn set_slot(&mut self, universe: u16, address: u16, value: u8) {
        if (1..=SLOTS as u16).contains(&address) {
            self.frame_mut(universe)[usize::from(address) - 1] = value;
        }
    }

    /// Universe numbers present, ascending.
    pub fn universes(&self) -> impl Iterator<Item = u16> + '_ {
        self.frames.keys().copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classification_cases() {
        let a = FixtureState { v: 0.5, zoom: 20.0, ..FixtureState::default() };
        assert_eq!(classify(&a, &a), Change::Unchanged);
        for change in [
            FixtureState { v: 0.6, ..a },
            FixtureState { frame: 1.5, ..a },
            FixtureState { mix: [0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], ..a },
            FixtureState { wheel: 2.0, ..a },
            FixtureState { cto: 3200.0, ..a },
            FixtureState { shutter: 0.0, ..a },
            FixtureState { strobe: 10.0, ..a },
            FixtureState { wheels: [0.0, 1.0, 0.0], ..a },
            FixtureState { hsb: Some([120.0, 1.0, 1.0]), ..a },
            FixtureState { cie: Some([0.4, 0.4, 1.0]), ..a },
            FixtureState { colour_macro: Some(2.0), ..a },
            FixtureState { tint: 0.01, ..a },
            FixtureState { strobe_duration: 0.05, ..a },
        ] {
            assert_eq!(classify(&a, &change), Change::Composite, "{change:?}");
        }
        for change in [
            FixtureState { pan: 1.0, ..a },
            FixtureState { tilt: -1.0, ..a },
            FixtureState { zoom: 21.0, ..a },
            FixtureState { focus: 0.5, ..a },
            FixtureState { iris: 0.5, ..a },
            FixtureState { pan: 1.0, v: 0.0, ..a },
            FixtureState { gobo: 1.0, ..a },
            FixtureState { gobo_angle: 15.0, ..a },
            FixtureState { gobo_spin: 90.0, ..a },
            FixtureState { gobo_wheel_spin: 30.0, ..a },
            FixtureState { blades: [[0.0, 0.3, 0.0], [0.0; 3], [0.0; 3], [0.0; 3]], ..a },
            FixtureState { blades: [[0.0; 3], [0.0; 3], [0.0; 3], [0.0, 0.0, 5.0]], ..a },
            FixtureState { shaper_rot: 10.0, ..a },
            FixtureState { prism: 1.0, ..a },
            FixtureState { prism_angle: 1.0, ..a },
            FixtureState { prism_spin: 1.0, ..a },
            FixtureState { frost: 0.5, ..a },
            FixtureState { gobo2: [1.0, 0.0, 0.0], ..a },
            FixtureState { gobo2: [0.0, 0.0, 5.0], ..a },
            FixtureState { animation: [1.0, 30.0, 0.0], ..a },
        ] {
            assert_eq!(classify(&a, &change), Change::Geometry, "{change:?}");
        }
        assert!(Change::Geometry > Change::Composite && Change::Composite > Change::Unchanged);
    }

    #[test]
    fn shutter_is_a_square_wave_on_the_frame_clock() {
        let open = FixtureState::default();
        assert_eq!(open.shutter_at(0.0), 1.0);
        assert_eq!(open.shutter_at(12.345), 1.0);
        assert_eq!(FixtureState { shutter: 0.0, ..open }.shutter_at(0.0), 0.0);
        let s = FixtureState { strobe: 10.0, ..open };
        // 10 Hz, 50 % duty: open 0..50 ms, closed 50..100 ms, then again.
        assert_eq!(s.shutter_at(0.0), 1.0);
        assert_eq!(s.shutter_at(0.049), 1.0);
        assert_eq!(s.shutter_at(0.051), 0.0);
        assert_eq!(s.shutter_at(0.101), 1.0);
        // The mean over many periods is the duty cycle (midpoint sampling, not aligned to the period).
        let n = 100_000;
        let mean: f64 = (0..n).map(|i| f64::from(s.shutter_at((i as f64 + 0.5) * 1e-5 * 7.3))).sum::<f64>() / n as f64;
        assert!((mean - STROBE_DUTY).abs() < 2e-3, "{mean}");
        assert_eq!(FixtureState { strobe: f32::NAN, ..open }.shutter_at(0.07), 1.0);
        // A flash duration (GDTF StrobeDuration) sets the duty: 20 ms at 10 Hz is open 20 % of the time.
        let short = FixtureState { strobe: 10.0, strobe_duration: 0.02, ..open };
        assert!((short.strobe_duty() - 0.2).abs() < 1e-6);
        assert_eq!((short.shutter_at(0.019), short.shutter_at(0.021)), (1.0, 0.0));
        // Longer than the period: open all the time; nonsense: the default duty.
        assert_eq!(FixtureState { strobe_duration: 1.0, ..s }.strobe_duty(), 1.0);
        assert_eq!(FixtureState { strobe_duration: f32::NAN, ..s }.strobe_duty(), STROBE_DUTY);
        assert_eq!(FixtureState { shutter: f32::NAN, ..open }.shutter_at(0.0), 0.0);
    }

    #[test]
    fn spins_step_on_the_frame_clock_at_a_bounded_rate() {
        let still = FixtureState { gobo_angle: 10.0, ..FixtureState::default() };
        assert_eq!(still.at_time(3.7, 6), still);
        let s = FixtureState { gobo_angle: 10.0, gobo_spin: 90.0, prism_spin: -45.0, ..FixtureState::default() };
        // 90°/s for 2 s: 190°; the prism turns back 90° and wraps to 270°.
        assert!((s.at_time(2.0, 6).gobo_angle - 190.0).abs() < 1e-4);
        assert!((s.at_time(2.0, 6).prism_angle - 270.0).abs() < 1e-4);
        // Within one clock step the state does not change: no rebuild.
        let step = 1.0 / SPIN_UPDATE_HZ;
        assert_eq!(classify(&s.at_time(2.0 + 0.1 * step, 6), &s.at_time(2.0 + 0.9 * step, 6)), Change::Unchanged);
        assert_eq!(classify(&s.at_time(2.0, 6), &s.at_time(2.0 + step, 6)), Change::Geometry);
        // Rebuilds over 10 s of 60 Hz frames: at most SPIN_UPDATE_HZ per second.
        let mut rebuilds = 0;
        let mut last = s.at_time(0.0, 6);
        for f in 1..600 {
            let now = s.at_time(f as f64 / 60.0, 6);
            if classify(&last, &now) == Change::Geometry {
                rebuilds += 1;
            }
            last = now;
        }
        assert!(rebuilds <= (10.0 * SPIN_UPDATE_HZ) as usize && rebuilds > 100, "{rebuilds}");
        // Wheel spin: 60°/s on a 6-slot wheel is one slot per second, wrapping.
        let w = FixtureState { gobo: 1.0, gobo_wheel_spin: 60.0, ..FixtureState::default() };
        assert!((w.at_time(2.0, 6).gobo - 3.0).abs() < 1e-4);
        assert!((w.at_time(5.0, 6).gobo - 0.0).abs() < 1e-4);
        assert_eq!(w.at_time(5.0, 0).gobo, 1.0, "no wheel: nothing to spin through");
        assert_eq!(s.at_time(f64::NAN, 6), s);
        // The second gobo and the animation wheel turn like the first gobo.
        let layers = FixtureState { gobo2: [1.0, 10.0, 45.0], animation: [1.0, 0.0, -30.0], ..FixtureState::default() };
        assert!(layers.spins());
        let t = layers.at_time(2.0, 6);
        assert!((t.gobo2[1] - 100.0).abs() < 1e-4 && (t.animation[1] - 300.0).abs() < 1e-4, "{t:?}");
    }

    #[test]
    fn universes_store_frames_by_number() {
        let mut u = Universes::new();
        assert!(u.get(1).is_none());
        u.set_slot(2, 512, 9);
        u.set_slot(2, 0, 9);
        u.set_slot(2, 513, 9);
        assert_eq!(u.get(2).unwrap()[511], 9);
        assert_eq!(u.get(2).unwrap().iter().map(|&v| u32::from(v)).sum::<u32>(), 9);
        u.set(1, &[1; SLOTS]);
        assert_eq!(u.universes().collect::<Vec<_>>(), vec![1, 2]);
    }
}
