//! `[haze]`: a homogeneous participating medium over the stage (issue 15).
//!
//! ```toml
//! [haze]
//! scattering = 0.05            # σ_s per metre at 100 % density
//! absorption = 0.005           # σ_a per metre at 100 % density
//! g = 0.7                      # Henyey-Greenstein asymmetry, g > 0 forward
//! box = [[-8.0, 0.0, -8.0], [8.0, 8.0, 8.0]]   # optional; default: the scene bounds
//! universe = 1                 # optional hazer channel: density 0-255 → 0-100 %
//! address = 500
//! density = 100                # density in % until DMX arrives (default 100)
//! multiple = true              # similarity-relation multiple scattering (default true)
//! ```
//!
//! Coefficients are per metre at 100 % density; density scales σ_s and σ_a
//! together (both are proportional to the droplet count). The renderer
//! (`footlight::render::media`) turns a [`HazeSpec`] into its medium; this
//! crate only reads and checks the table, with `file:line` on every error.

use super::Fixture;
use super::file::PatchFile;
use crate::error::{PatchError, line_of};
use crate::state::{SLOTS, Universes};
use glam::Vec3;
use serde::Deserialize;
use std::path::Path;
use toml::Spanned;

/// `[haze]` as written (first stage).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HazeFile {
    /// Scattering coefficient σ_s per metre at 100 % density.
    pub scattering: Spanned<f32>,
    /// Absorption coefficient σ_a per metre at 100 % density (default 0).
    pub absorption: Option<Spanned<f32>>,
    /// Henyey-Greenstein asymmetry g, −1 < g < 1 (default 0.7, theatre haze).
    pub g: Option<Spanned<f32>>,
    /// The haze volume `[[min x, y, z], [max x, y, z]]` (default: the scene bounds).
    #[serde(rename = "box")]
    pub bounds: Option<Spanned<[[f32; 3]; 2]>>,
    /// Hazer channel: patch universe (with `address`).
    pub universe: Option<Spanned<i64>>,
    /// Hazer channel: slot 1-512 (with `universe`).
    pub address: Option<Spanned<i64>>,
    /// Density in percent (0-100) used until DMX arrives, and always without a channel.
    pub density: Option<Spanned<f32>>,
    /// Multiple scattering: volume photons for orders ≥ 2 (default true).
    pub multiple: Option<bool>,
}

/// A validated `[haze]` table.
#[derive(Clone, Debug, PartialEq)]
pub struct HazeSpec {
    /// σ_s per metre at 100 % density (finite, ≥ 0).
    pub scattering: f32,
    /// σ_a per metre at 100 % density (finite, ≥ 0).
    pub absorption: f32,
    /// Henyey-Greenstein g, |g| < 1; g > 0 scatters forward.
    pub g: f32,
    /// Explicit haze box (min, max), each axis min < max; `None`: the scene bounds.
    pub bounds: Option<(Vec3, Vec3)>,
    /// Hazer channel (patch universe, address 1-512).
    pub dmx: Option<(u16, u16)>,
    /// Density 0-1 of the default look (the `density` key / 100).
    pub density: f32,
    /// Multiple scattering: volume photons for orders ≥ 2 in `render` and the
    /// live refined stage, the similarity relation in the live coarse stage.
    pub multiple: bool,
    /// Line of the `[haze]` table, for later messages.
    pub line: usize,
}

/// Default Henyey-Greenstein g: theatre haze (glycol/water droplets) is
/// strongly forward scattering; 0.7 is mid-range of the 0.6-0.9 reported
/// for stage haze (estimated, `notes/productions.md`; no datasheet gives g).
pub const DEFAULT_G: f32 = 0.7;

impl HazeSpec {
    /// Density 0-1 now: the hazer channel's slot / 255 when its universe has
    /// a frame, else the default look's density. 0 and 255 map exactly to
    /// 0 and 1 (no clamping needed: a slot cannot leave 0-255).
    pub fn density_of(&self, universes: &Universes) -> f32 {
        match self.dmx.and_then(|(u, a)| universes.get(u).map(|s| s[usize::from(a) - 1])) {
            Some(v) => f32::from(v) / 255.0,
            None => self.density,
        }
    }

    /// Writes the default density into the default look's frames (the
    /// hazer slot = density · 255, rounded), so a frame that starts from the
    /// look keeps the patch's haze.
    pub fn write_look(&self, look: &mut Universes) {
        if let Some((u, a)) = self.dmx {
            look.set_slot(u, a, (self.density * 255.0).round() as u8);
        }
    }

    /// Density from one universe's slots (the hazer's universe).
    pub fn density_from_slots(&self, slots: &[u8; SLOTS]) -> f32 {
        match self.dmx {
            Some((_, a)) => f32::from(slots[usize::from(a) - 1]) / 255.0,
            None => self.density,
        }
    }
}

/// Validates `[haze]`: coefficients finite and ≥ 0, |g| < 1, a box with
/// positive size on every axis, a hazer channel with both universe and
/// address in range and clear of every fixture's slots, density 0-100 %.
/// Every problem is pushed to `errors` with the key's line.
pub(super) fn build_haze(
    path: &Path,
    text: &str,
    file: &PatchFile,
    fixtures: &[Fixture],
    errors: &mut Vec<PatchError>,
) -> Option<HazeSpec> {
    let h = file.haze.as_ref()?;
    let line = line_of(text, h.span().start);
    let h = h.get_ref();
    let before = errors.len();
    let mut err = |span: std::ops::Range<usize>, msg: String| {
        errors.push(PatchError::new(path, line_of(text, span.start), msg));
    };
    let coefficient = |v: &Spanned<f32>, name: &str, err: &mut dyn FnMut(std::ops::Range<usize>, String)| {
        let x = *v.get_ref();
        if !(x.is_finite() && x >= 0.0) {
            err(v.span(), format!("haze {name} {x} must be a finite number >= 0 (per metre)"));
        }
        x
    };
    let scattering = coefficient(&h.scattering, "scattering", &mut err);
    let absorption = h.absorption.as_ref().map_or(0.0, |a| coefficient(a, "absorption", &mut err));
    let g = h.g.as_ref().map_or(DEFAULT_G, |g| {
        let x = *g.get_ref();
        if !(x.abs() < 1.0) {
            err(g.span(), format!("haze g {x} must be between -1 and 1 (exclusive); theatre haze is 0.6-0.9"));
        }
        x
    });
    let bounds = h.bounds.as_ref().and_then(|b| {
        let [lo, hi] = *b.get_ref();
        let (lo, hi) = (Vec3::from(lo), Vec3::from(hi));
        if !lo.is_finite() || !hi.is_finite() || !(hi - lo).cmpgt(Vec3::ZERO).all() {
            err(
                b.span(),
                format!("haze box {lo} .. {hi} must be finite with min < max on every axis (a box of zero size holds no haze)"),
            );
            return None;
        }
        Some((lo, hi))
    });
    let density = h.density.as_ref().map_or(1.0, |d| {
        let x = *d.get_ref();
        if !(0.0..=100.0).contains(&x) {
            err(d.span(), format!("haze density {x} must be a percentage 0-100"));
        }
        x / 100.0
    });
    let dmx = match (&h.universe, &h.address) {
        (None, None) => None,
        (Some(u), Some(a)) => {
            let (uv, av) = (*u.get_ref(), *a.get_ref());
            if !(1..=63999).contains(&uv) {
                err(u.span(), format!("haze universe {uv} must be in 1..63999 (desks count from 1)"));
                None
            } else if !(1..=512).contains(&av) {
                err(a.span(), format!("haze address {av} must be in 1..512"));
                None
            } else {
                let (uv, av) = (uv as u16, av as u16);
                let clash = fixtures
                    .iter()
                    .find(|f| f.dmx.is_some_and(|(fu, fa)| fu == uv && fa <= av && av < fa + f.footprint()));
                if let Some(f) = clash {
                    err(
                        a.span(),
                        format!(
                            "haze channel {uv}/{av} is a slot of fixture {} (line {}); give the hazer a free address",
                            f.id, f.line
                        ),
                    );
                }
                Some((uv, av))
            }
        }
        (Some(s), None) | (None, Some(s)) => {
            err(s.span(), "haze: give both universe and address for the hazer channel, or neither".into());
            None
        }
    };
    if errors.len() > before {
        return None;
    }
    Some(HazeSpec { scattering, absorption, g, bounds, dmx, density, multiple: h.multiple.unwrap_or(true), line })
}

#[cfg(test)]
mod tests {
    use crate::Patch;
    use std::path::Path;

    const BASE: &str = "[[fixture]]\nid = 1\ntype = \"spot\"\nposition = [0.0, 6.0, 0.0]\naim = [0.0, 0.0, 0.0]\nintensity = 1000.0\nuniverse = 1\naddress = 1\n";

    fn parse(haze: &str) -> Result<Patch, String> {
        Patch::parse(Path::new("h.toml"), &format!("{BASE}\n[haze]\n{haze}")).map_err(|e| e.to_string())
    }

    #[test]
    fn reads_the_table_with_defaults() {
        let p = parse("scattering = 0.05\n").unwrap();
        let h = p.haze.unwrap();
        assert_eq!((h.scattering, h.absorption, h.g, h.density, h.multiple), (0.05, 0.0, 0.7, 1.0, true));
        assert_eq!((h.bounds, h.dmx, h.line), (None, None, 10));
        let p = parse("scattering = 0.1\nabsorption = 0.01\ng = -0.2\nbox = [[-1, 0, -1], [1, 2, 1]]\nuniverse = 2\naddress = 7\ndensity = 40\nmultiple = false\n").unwrap();
        let h = p.haze.unwrap();
        assert_eq!(h.bounds.unwrap().1, glam::Vec3::new(1.0, 2.0, 1.0));
        assert_eq!((h.dmx, h.density, h.multiple), (Some((2, 7)), 0.4, false));
        assert!(Patch::parse(Path::new("h.toml"), BASE).unwrap().haze.is_none());
    }

    #[test]
    fn bad_values_name_the_line() {
        for (haze, line, what) in [
            ("scattering = -0.1\n", 11, "scattering"),
            ("scattering = nan\n", 11, "scattering"),
            ("scattering = 0.1\nabsorption = inf\n", 12, "absorption"),
            ("scattering = 0.1\ng = 1.0\n", 12, "between -1 and 1"),
            ("scattering = 0.1\ng = -1.5\n", 12, "between -1 and 1"),
            ("scattering = 0.1\nbox = [[0, 0, 0], [1, 0, 1]]\n", 12, "zero size"),
            ("scattering = 0.1\nuniverse = 1\n", 12, "both universe and address"),
            ("scattering = 0.1\nuniverse = 1\naddress = 1\n", 13, "slot of fixture 1"),
            ("scattering = 0.1\nuniverse = 1\naddress = 513\n", 13, "1..512"),
            ("scattering = 0.1\ndensity = 101\n", 12, "0-100"),
            ("absorption = 0.1\n", 10, "scattering"),
        ] {
            let e = parse(haze).unwrap_err();
            assert!(e.starts_with(&format!("h.toml:{line}:")) && e.contains(what), "{haze:?}: {e}");
        }
    }

    #[test]
    fn hazer_channel_ends_map_to_zero_and_full() {
        let h = parse("scattering = 0.1\nuniverse = 1\naddress = 9\ndensity = 50\n").unwrap().haze.unwrap();
        let p = parse("scattering = 0.1\nuniverse = 1\naddress = 9\ndensity = 50\n").unwrap();
        assert_eq!(p.look_universes.get(1).unwrap()[8], 128, "the default look carries the density");
        let mut u = crate::Universes::new();
        assert_eq!(h.density_of(&u), 0.5, "default look until DMX arrives");
        u.set_slot(1, 9, 0);
        assert_eq!(h.density_of(&u), 0.0);
        u.set_slot(1, 9, 255);
        assert_eq!(h.density_of(&u), 1.0);
    }
}
