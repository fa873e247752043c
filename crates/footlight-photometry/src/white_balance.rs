//! White balance: per-channel gains that render a reference lamp as neutral.
//!
//! Vierjahn 2010, section 3.3: the compositor "implements white balancing
//! since the white point of the monitor does not match the dominant
//! illuminant on a stage". Footlight balances the way a camera does: gains
//! on the linear-sRGB channels (a von Kries-style scaling in the display's
//! RGB, not a cone-space adaptation such as Bradford), chosen so that the
//! reference lamp's colour becomes R = G = B, and scaled so that its
//! luminance is unchanged. The default reference is tungsten at 3200 K at
//! full, the dominant illuminant of a conventional rig.

use crate::lamp::Lamp;
use crate::srgb::luminance;
use glam::Vec3;

/// Linear-sRGB channel gains applied after the composite (eq. 5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WhiteBalance {
    /// Gain per channel (R, G, B).
    pub gains: Vec3,
}

impl WhiteBalance {
    /// No correction: gains (1, 1, 1).
    pub const IDENTITY: WhiteBalance = WhiteBalance { gains: Vec3::ONE };

    /// Gains that make `reference` (a linear-sRGB colour) neutral at its
    /// own luminance: g = Y_ref / reference per channel. A reference with
    /// non-positive luminance or a channel below 1e-6 · Y is not balanced
    /// on that channel (gain clamped at 1e6); non-finite input gives identity.
    pub fn for_colour(reference: Vec3) -> Self {
        let y = luminance(reference);
        if !(y > 0.0 && reference.is_finite()) {
            return Self::IDENTITY;
        }
        Self { gains: Vec3::splat(y) / reference.max(Vec3::splat(1e-6 * y)) }
    }

    /// Gains that make `lamp` at dimmer `v` (unfiltered) neutral.
    pub fn for_lamp(lamp: &Lamp, v: f32) -> Self {
        Self::for_colour(lamp.colour(v))
    }

    /// Applies the gains to a linear-sRGB colour.
    pub fn apply(&self, rgb: Vec3) -> Vec3 {
        rgb * self.gains
    }
}

impl Default for WhiteBalance {
    /// Tungsten 3200 K at full is white.
    fn default() -> Self {
        Self::for_lamp(&Lamp::tungsten(), 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_lamp_becomes_neutral_at_equal_luminance() {
        for lamp in [Lamp::tungsten(), Lamp::hmi(), Lamp::Tungsten { cct_full: 2700.0 }] {
            let wb = WhiteBalance::for_lamp(&lamp, 1.0);
            let c = lamp.colour(1.0);
            let out = wb.apply(c);
            assert!((out.x - out.y).abs() < 1e-5 && (out.y - out.z).abs() < 1e-5, "{lamp:?}: {out}");
            assert!((luminance(out) - luminance(c)).abs() < 1e-5);
        }
        let d = WhiteBalance::default();
        let out = d.apply(Lamp::tungsten().colour(1.0));
        assert!((out.x - out.z).abs() < 1e-5 && (out.x - 1.0).abs() < 1e-5, "{out}");
        // Tungsten is warm: balancing it boosts blue and cuts red.
        assert!(d.gains.z > 1.0 && d.gains.x < 1.0, "{:?}", d.gains);
    }

    #[test]
    fn degenerate_references_are_safe() {
        assert_eq!(WhiteBalance::for_colour(Vec3::ZERO), WhiteBalance::IDENTITY);
        assert_eq!(WhiteBalance::for_colour(Vec3::splat(f32::NAN)), WhiteBalance::IDENTITY);
        let g = WhiteBalance::for_colour(Vec3::new(1.0, 0.0, 0.0)).gains;
        assert!(g.is_finite(), "{g}");
        assert_eq!(WhiteBalance::for_lamp(&Lamp::tungsten(), 0.0), WhiteBalance::IDENTITY);
    }
}
