//! The white point of a rig (issue 36 item 7): what `--white-balance auto`
//! makes neutral.
//!
//! A camera balanced for tungsten shows an LED rig's full white deep blue;
//! balanced for daylight it shows a tungsten rig orange. The display's
//! white should be the rig's own white, the light of its sources at full
//! (Vierjahn 2010, section 3.3: the monitor's white point "does not match
//! the dominant illuminant on a stage"):
//!
//! * a rig with **tungsten** lamps is balanced for them: the
//!   luminous-flux-weighted chromaticity of its tungsten lamps at full
//!   (3200 K for the paper's rig, exactly what the default balance was).
//!   Discharge, LED and CMY sources hung beside them are the accents and
//!   colours of a tungsten-keyed stage (the paper's rig: four HMIs with
//!   LEE 136 back-light beside a tungsten front light balanced at 3200 K),
//!   and a lighting designer sets such LEDs' whites to the tungsten;
//! * a rig **without tungsten** is balanced for all its sources: the
//!   luminous-flux-weighted chromaticity of every light at full, each LED
//!   with every emitter at full, each CMY engine with its flags open, each
//!   discharge lamp at its CCT, so full RGB(W) on an LED rig shows white.
//!
//! Fluxes are each light's Î (cd) at its default look (zoom, focus) times
//! its pattern's ∫ f dω (lm per cd), so a 2.5 kW HMI outweighs a pixel.
//! Gels, wheels and CTO are left out: they colour the light, they do not
//! set the stage's white. The built-in spot (an RGB stand-in, no lamp) is
//! left out too; a patch with nothing else has no rig white.

use super::{FixtureModel, Patch};
use footlight_photometry::{Lamp, Response, srgb};
use glam::{DVec3, Vec2, Vec3};

/// A rig's white at full ([`Patch::rig_white`]).
#[derive(Clone, Debug, PartialEq)]
pub struct RigWhite {
    /// Its colour, linear sRGB with luminance 1 (each lamp's full white is
    /// Y = 1; in gamut).
    pub rgb: Vec3,
    /// CIE 1931 chromaticity.
    pub xy: Vec2,
    /// Correlated colour temperature, K: the lamps' own when one kind of
    /// Planckian lamp sets the white, else McCamy's formula (meaningful near
    /// the Planckian locus).
    pub cct_k: f32,
    /// The lights that set it.
    pub lights: usize,
    /// True when the rig's tungsten lamps set it (the rest left out).
    pub tungsten: bool,
}

impl RigWhite {
    /// One line for logs and `/api/display`: `3200 K: the rig's 6 tungsten
    /// lamps at full` or `6480 K: luminous-flux-weighted white of 32 lights at full`.
    pub fn describe(&self) -> String {
        let (n, s) = (self.lights, if self.lights == 1 { "" } else { "s" });
        if self.tungsten {
            format!("{:.0} K: the rig's {n} tungsten lamp{s} at full (the other sources left out)", self.cct_k)
        } else {
            format!("{:.0} K: luminous-flux-weighted white of {n} light{s} at full", self.cct_k)
        }
    }
}

impl Patch {
    /// The white point of the rig's sources at full (see the module doc);
    /// `None` when no fixture has a lamp (only built-in spots).
    pub fn rig_white(&self) -> Option<RigWhite> {
        // (lamp at full, flux in lm) of every typed light.
        let mut sources: Vec<(Lamp, f64)> = Vec::new();
        for f in &self.fixtures {
            let FixtureModel::Typed(t) = &f.model else { continue };
            let state = f.look;
            let lamp = at_full(&t.fixture_type.lamp);
            let flux =
                f64::from(t.fixture_type.intensity(&state)) * f64::from(t.fixture_type.beam(&state).solid_angle());
            sources.push((lamp, if flux.is_finite() && flux > 0.0 { flux } else { 0.0 }));
        }
        let tungsten = sources.iter().any(|(l, _)| matches!(l, Lamp::Tungsten { .. }));
        if tungsten {
            sources.retain(|(l, _)| matches!(l, Lamp::Tungsten { .. }));
        }
        let first = sources.first()?.0.clone();
        let single = sources.iter().all(|(l, _)| *l == first);
        let rgb = if single {
            // One kind of lamp: its own white, exactly (the paper's rig keeps its 3200 K gains).
            first.colour(1.0)
        } else {
            let total: f64 = sources.iter().map(|(_, w)| w).sum();
            let weight = |w: f64| if total > 0.0 { w / total } else { 1.0 / sources.len() as f64 };
            let xyz: DVec3 =
                sources.iter().map(|(l, w)| l.xyz_through(1.0, Response::open()).as_dvec3() * weight(*w)).sum();
            srgb::fit_gamut(srgb::xyz_to_linear_srgb(xyz.as_vec3()))
        };
        if !(srgb::luminance(rgb) > 0.0 && rgb.is_finite()) {
            return None;
        }
        let xy = srgb::xy(srgb::linear_srgb_to_xyz(rgb))?;
        // A Planckian lamp's own CCT when it alone sets the white (McCamy reads 3200 K as 3208 K).
        let cct_k = first.temperature(1.0).filter(|_| single).unwrap_or_else(|| srgb::cct_mccamy(xy));
        Some(RigWhite { rgb, xy, cct_k, lights: sources.len(), tungsten })
    }
}

/// The lamp's own white at full: every LED emitter at full, CMY flags open.
fn at_full(lamp: &Lamp) -> Lamp {
    match lamp {
        Lamp::Led { emitters } => {
            let mut emitters = emitters.clone();
            emitters.iter_mut().for_each(|e| e.level = 1.0);
            Lamp::Led { emitters }
        }
        Lamp::Cmy { cct, filters, .. } => {
            Lamp::Cmy { cct: *cct, cyan: 0.0, magenta: 0.0, yellow: 0.0, filters: filters.clone() }
        }
        other => other.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn bundled(name: &str) -> Patch {
        Patch::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../../patch").join(name)).unwrap()
    }

    fn lamp_of(f: &crate::Fixture) -> Option<&Lamp> {
        match &f.model {
            FixtureModel::Typed(t) => Some(&t.fixture_type.lamp),
            FixtureModel::Builtin(_) => None,
        }
    }

    #[test]
    fn a_rig_with_tungsten_is_balanced_for_its_tungsten_exactly() {
        // The paper's rig (tungsten front light, HMI back-light) and the
        // default patch (that rig plus LED PARs and CMY spots): 3200 K, bit
        // for bit the lamp's own white, so the display keeps its gains.
        for name in ["paper-rig.toml", "default.toml"] {
            let w = bundled(name).rig_white().unwrap();
            assert!(w.tungsten && w.lights == 2, "{name}: {w:?}");
            assert_eq!(w.rgb, Lamp::tungsten().colour(1.0), "{name}");
            assert!((w.cct_k - 3200.0).abs() < 30.0, "{name}: {}", w.cct_k);
            assert!(w.describe().starts_with("3200 K: the rig's 2 tungsten lamps"), "{}", w.describe());
        }
    }

    #[test]
    fn a_rig_without_tungsten_mixes_its_sources_by_flux() {
        let mut p = bundled("default.toml");
        p.fixtures.retain(|f| matches!(lamp_of(f), Some(Lamp::Led { .. })));
        assert_eq!(p.fixtures.len(), 2, "the two RGBW PARs");
        let w = p.rig_white().unwrap();
        let own = at_full(lamp_of(&p.fixtures[0]).unwrap()).colour(1.0);
        assert!(!w.tungsten && w.lights == 2);
        assert_eq!(w.rgb, own, "one kind of lamp: its own white with every emitter at full");
        // LED PARs and CMY spots (7000 K): between the two whites, on the
        // line joining them in xy (additive mixing), weighted by flux.
        let mut p = bundled("default.toml");
        p.fixtures.retain(|f| matches!(lamp_of(f), Some(Lamp::Led { .. } | Lamp::Cmy { .. })));
        let xy_of = |l: &Lamp| srgb::xy(at_full(l).xyz_through(1.0, Response::open())).unwrap();
        let first = |pick: fn(&Lamp) -> bool| xy_of(p.fixtures.iter().filter_map(lamp_of).find(|l| pick(l)).unwrap());
        let led = first(|l| matches!(l, Lamp::Led { .. }));
        let cmy = first(|l| matches!(l, Lamp::Cmy { .. }));
        let w = p.rig_white().unwrap();
        assert!(!w.tungsten && w.lights == 4, "{w:?}");
        let (d, e) = (cmy - led, w.xy - led);
        assert!((d.perp_dot(e)).abs() < 1e-4 * d.length(), "on the mixing line: {led} {cmy} {}", w.xy);
        let t = e.dot(d) / d.length_squared();
        assert!(t > 0.0 && t < 1.0, "between the two whites: {t}");
        // Nothing with a lamp (only built-in spots): no rig white.
        assert!(Patch { fixtures: Vec::new(), ..bundled("paper-rig.toml") }.rig_white().is_none());
    }
}
