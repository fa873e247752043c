//! A fixture's state in real units, decoded from DMX, and how a change of
//! state reaches the renderer (DESIGN.md data flow; issue 5 item 6).
//!
//! ```text
//! 512-slot frames ──decode──> FixtureState ──┬─ light_of ─> Light (geometry: tracer)
//!                                             └─ k_of ────> k_i (eq. 4: compositor)
//! ```
//!
//! [`classify`] compares two states of one fixture: nothing changed → no
//! event; dimmer, colour mix, colour frame, colour-wheel slot, CTO/CTB,
//! shutter or strobe rate → the composite only (k_i); pan, tilt, zoom,
//! focus or iris → geometry, which marks the light dirty for a rebuild
//! (and, since zoom changes Î, also needs a new k_i).
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
}

/// Fraction of each strobe period the shutter is open (estimated: a
/// mechanical or LED strobe at a 50 % duty cycle; discharge flash tubes are
/// shorter, GDTF gives no duty cycle).
pub const STROBE_DUTY: f64 = 0.5;

impl FixtureState {
    /// The shutter's transmission at frame time `t_seconds`: 0 closed, 1
    /// open, and while strobing 1 for the first [`STROBE_DUTY`] of each
    /// period `1/strobe` and 0 after it. The phase origin is t = 0 of the
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
        if phase < STROBE_DUTY { 1.0 } else { 0.0 }
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
    /// The beam moved or changed shape (pan, tilt, zoom, focus, iris): mark
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
        || old.iris != new.iris;
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
    {
        return Change::Composite;
    }
    Change::Unchanged
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
        assert_eq!(FixtureState { shutter: f32::NAN, ..open }.shutter_at(0.0), 0.0);
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
