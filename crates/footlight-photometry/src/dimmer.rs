//! Dimmer curves: a DMX intensity level → the dimmer factor v of eq. 4.
//!
//! v ∈ [0, 1] is the light's relative output (Vierjahn 2010, eq. 4:
//! k = c_F c_I v Î). A desk or fixture maps its intensity control through a
//! law ("curve"); Footlight offers the three that matter for a preview.
//! Every curve is monotone with v(0) = 0 and v(1) = 1.
//!
//! * `linear`: v = c.
//! * `square`: v = c², the square law television lighting uses (finer control
//!   at the top; IES "square law" as desks describe it).
//! * `theatre`: v = c − sin(2πc) / (2π), the S-curve of a leading-edge phase
//!   control dimmer whose firing angle follows the control linearly: the
//!   conduction from α = π(1 − c) to π passes this fraction of the full
//!   power (∫ sin² over the conducting part). Its shape — slow at the bottom,
//!   fast in the middle, slow at the top, 50 % at half — is the traditional
//!   analogue-dimmer S-law (blue-room.org.uk "Dimmer Laws"). Using the power
//!   fraction directly as relative light output is our choice (estimated):
//!   manufacturers' tabulated "theatre" curves (ETC, Strand) are not
//!   published as formulas.
//!
//! ```toml
//! curve = "theatre"   # or "linear", "square"
//! ```

use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// How a control level maps to the dimmer factor v.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DimmerCurve {
    /// v = c.
    #[default]
    Linear,
    /// v = c² (television square law).
    #[serde(alias = "square")]
    SquareLaw,
    /// v = c − sin(2πc)/(2π): the phase-control S-curve (estimated as light output).
    Theatre,
}

impl DimmerCurve {
    /// v for a control level `c` in [0, 1] (clamped; NaN counts as 0).
    pub fn v(self, c: f32) -> f32 {
        let c = if c > 0.0 { f64::from(c.min(1.0)) } else { 0.0 };
        let v = match self {
            Self::Linear => c,
            Self::SquareLaw => c * c,
            // Double precision: at c = 1/65535 the result is ~2e-14, far below f32 cancellation.
            Self::Theatre => c - (TAU * c).sin() / TAU,
        };
        v.clamp(0.0, 1.0) as f32
    }

    /// v for an 8-bit DMX level (0 → 0, 255 → 1).
    pub fn from_dmx8(self, level: u8) -> f32 {
        self.v(level_from_dmx8(level))
    }

    /// v for a 16-bit (coarse, fine) DMX level (0 → 0, 65535 → 1).
    pub fn from_dmx16(self, level: u16) -> f32 {
        self.v(level_from_dmx16(level))
    }
}

/// An 8-bit DMX level normalised to [0, 1].
pub fn level_from_dmx8(level: u8) -> f32 {
    f32::from(level) / 255.0
}

/// A 16-bit DMX level normalised to [0, 1].
pub fn level_from_dmx16(level: u16) -> f32 {
    (f64::from(level) / 65535.0) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: [DimmerCurve; 3] = [DimmerCurve::Linear, DimmerCurve::SquareLaw, DimmerCurve::Theatre];

    #[test]
    fn ends_are_exact() {
        for c in ALL {
            assert_eq!(c.from_dmx8(0), 0.0, "{c:?}");
            assert_eq!(c.from_dmx8(255), 1.0, "{c:?}");
            assert_eq!(c.from_dmx16(0), 0.0, "{c:?}");
            assert_eq!(c.from_dmx16(65535), 1.0, "{c:?}");
            assert_eq!(c.v(f32::NAN), 0.0);
            assert_eq!(c.v(-3.0), 0.0);
            assert_eq!(c.v(7.0), 1.0);
        }
    }

    #[test]
    fn monotone_over_every_16_bit_level() {
        for c in ALL {
            let mut last = 0.0;
            for d in 1..=u16::MAX {
                let v = c.from_dmx16(d);
                assert!(v >= last && v.is_finite(), "{c:?} at {d}: {v} < {last}");
                last = v;
            }
        }
        // Strictly increasing at 8 bits (every desk step visibly moves the light).
        for c in ALL {
            for d in 1..=255u8 {
                assert!(c.from_dmx8(d) > c.from_dmx8(d - 1), "{c:?} at {d}");
            }
        }
    }

    #[test]
    fn known_points() {
        assert!((DimmerCurve::SquareLaw.v(0.5) - 0.25).abs() < 1e-7);
        // Phase-control S-curve: half control is half power; at c = 1/4 the
        // conducting quarter-cycle carries 1/4 − 1/(2π) of the power.
        assert!((DimmerCurve::Theatre.v(0.5) - 0.5).abs() < 1e-7);
        let quarter = 0.25 - 1.0 / (2.0 * std::f64::consts::PI);
        assert!((f64::from(DimmerCurve::Theatre.v(0.25)) - quarter).abs() < 1e-7);
        assert!(DimmerCurve::Theatre.v(0.1) < 0.1 && DimmerCurve::Theatre.v(0.9) > 0.9);
    }

    #[test]
    fn reads_from_toml() {
        #[derive(Deserialize)]
        struct F {
            curve: DimmerCurve,
        }
        let f: F = toml::from_str("curve = \"theatre\"").unwrap();
        assert_eq!(f.curve, DimmerCurve::Theatre);
        let f: F = toml::from_str("curve = \"square\"").unwrap();
        assert_eq!(f.curve, DimmerCurve::SquareLaw);
    }
}
