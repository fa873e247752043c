//! The patch file: which fixtures hang where, and the default look.
//!
//! This is the renderer core's slice of the one schema documented in
//! `docs/patch-format.md`: fixture instances with id, name, type, position,
//! aim (or rotation), beam angles, maximum intensity, colour and a default
//! level, plus an optional `[camera]`. DMX addressing fields (`universe`,
//! `address`, `mode`, `gel`) are read and kept so patches written today stay
//! valid when DMX decoding lands.
//!
//! ```toml
//! [[fixture]]
//! id = 1
//! name = "FOH centre"
//! type = "spot"
//! position = [0.0, 7.5, 10.0]
//! aim = [0.0, 1.0, -2.0]
//! beam_angle = 20.0      # degrees, 50 % of peak
//! field_angle = 30.0     # degrees, 10 % of peak
//! intensity = 60000.0    # candela at full
//! colour = [1.0, 0.9, 0.8]
//! level = 1.0
//! ```
//!
//! Loading is two-stage (ripgrep's LowArgs/HiArgs): serde fills the plain
//! [`PatchFile`] structs, then [`Patch::from_file`] validates and builds the
//! lights. Every error names the file and the line.

use crate::{Beam, Light, SpotBeam};
use glam::{Quat, Vec3};
use serde::Deserialize;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// A patch error with the file and 1-based line it refers to.
#[derive(Debug, thiserror::Error)]
#[error("{}:{line}: {message}", path.display())]
pub struct PatchError {
    /// The patch file.
    pub path: PathBuf,
    /// 1-based line number (0 when the file could not be read at all).
    pub line: usize,
    /// What is wrong and what to do about it.
    pub message: String,
}

/// The patch file as written (first stage: plain data from serde).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PatchFile {
    /// Optional camera overriding the scene's.
    pub camera: Option<Spanned<CameraFile>>,
    /// Fixture instances.
    #[serde(default)]
    pub fixture: Vec<Spanned<FixtureFile>>,
}

/// `[camera]`: eye position, target and vertical field of view.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraFile {
    /// Eye position in metres.
    pub position: [f32; 3],
    /// Point looked at.
    pub look_at: [f32; 3],
    /// Vertical field of view in degrees (default 40).
    #[serde(default = "default_fov")]
    pub fov_y: f32,
}

fn default_fov() -> f32 {
    40.0
}

/// One `[[fixture]]` entry as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FixtureFile {
    /// Fixture id as the desk shows it (unique in the patch).
    pub id: u32,
    /// Human-readable name.
    #[serde(default)]
    pub name: Option<String>,
    /// Fixture type. `"spot"` is the built-in parametric profile spot.
    #[serde(rename = "type")]
    pub kind: String,
    /// DMX mode name of the fixture type (used once fixture types land).
    #[serde(default)]
    pub mode: Option<String>,
    /// Patch universe, counted from 1 as desks show it.
    #[serde(default)]
    pub universe: Option<u16>,
    /// Start address 1-512.
    #[serde(default)]
    pub address: Option<u16>,
    /// A fixed gel name (from the gel library once it lands).
    #[serde(default)]
    pub gel: Option<String>,
    /// Position in metres (stage coordinates, +Y up).
    pub position: [f32; 3],
    /// Point the beam aims at (exclusive with `rotation`).
    #[serde(default)]
    pub aim: Option<[f32; 3]>,
    /// Orientation quaternion [x, y, z, w]; the beam is local −Z.
    #[serde(default)]
    pub rotation: Option<[f32; 4]>,
    /// Full beam angle (50 % of peak), degrees.
    #[serde(default = "default_beam")]
    pub beam_angle: f32,
    /// Full field angle (10 % of peak), degrees; defaults to beam + 10°.
    #[serde(default)]
    pub field_angle: Option<f32>,
    /// Maximum luminous intensity Î in candela.
    pub intensity: f32,
    /// Linear RGB colour of the light at full (stands in for lamp colour and gel).
    #[serde(default = "default_colour")]
    pub colour: [f32; 3],
    /// Dimmer level v in [0, 1] used until DMX arrives (the default look).
    #[serde(default = "default_level")]
    pub level: f32,
}

fn default_beam() -> f32 {
    25.0
}
fn default_colour() -> [f32; 3] {
    [1.0, 1.0, 1.0]
}
fn default_level() -> f32 {
    1.0
}

/// One validated fixture instance.
#[derive(Clone, Debug)]
pub struct Fixture {
    /// Desk fixture id.
    pub id: u32,
    /// Display name.
    pub name: String,
    /// Geometry for the tracer (unit intensity).
    pub light: Light,
    /// Î in candela.
    pub intensity: f32,
    /// Linear RGB colour at full.
    pub colour: Vec3,
    /// Default dimmer level v.
    pub level: f32,
    /// DMX universe and address when patched.
    pub dmx: Option<(u16, u16)>,
    /// Line in the patch file, for later messages.
    pub line: usize,
}

impl Fixture {
    /// k_i of eq. 4 for this fixture's default look: colour · v · Î.
    /// (Lamp colour and gels join here when photometry lands.)
    pub fn k(&self) -> Vec3 {
        self.colour * (self.level * self.intensity)
    }

    /// k_i with the dimmer at full and everything else as in the default
    /// look: the scale adaptive anti-aliasing decides on (so dimming never
    /// changes a light's sample set).
    pub fn k_full(&self) -> Vec3 {
        self.colour * self.intensity
    }
}

/// A camera from the patch: eye, target, vertical field of view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraSpec {
    /// Eye position.
    pub position: Vec3,
    /// Point looked at (distinct from `position`).
    pub look_at: Vec3,
    /// Vertical field of view in radians.
    pub fov_y: f32,
}

/// A validated patch.
#[derive(Clone, Debug)]
pub struct Patch {
    /// Where it was read from.
    pub path: PathBuf,
    /// Camera override.
    pub camera: Option<CameraSpec>,
    /// Fixtures in file order.
    pub fixtures: Vec<Fixture>,
}

impl Patch {
    /// Reads and validates a patch file.
    pub fn load(path: &Path) -> Result<Self, PatchError> {
        let text = std::fs::read_to_string(path).map_err(|e| PatchError {
            path: path.to_path_buf(),
            line: 0,
            message: format!("cannot read: {e}"),
        })?;
        Self::parse(path, &text)
    }

    /// Parses and validates patch text; `path` is used in messages.
    pub fn parse(path: &Path, text: &str) -> Result<Self, PatchError> {
        let file: PatchFile = toml::from_str(text).map_err(|e| PatchError {
            path: path.to_path_buf(),
            line: e.span().map(|s| line_of(text, s.start)).unwrap_or(0),
            message: e.message().to_string(),
        })?;
        Self::from_file(path, text, file)
    }

    /// Second stage: validates the plain structs and builds lights.
    pub fn from_file(path: &Path, text: &str, file: PatchFile) -> Result<Self, PatchError> {
        let err = |span: Range<usize>, message: String| PatchError {
            path: path.to_path_buf(),
            line: line_of(text, span.start),
            message,
        };
        let camera = match file.camera {
            None => None,
            Some(c) => {
                let span = c.span();
                let c = c.into_inner();
                let (p, t) = (Vec3::from(c.position), Vec3::from(c.look_at));
                if !p.is_finite() || !t.is_finite() || p.distance(t) < 1e-6 {
                    return Err(err(span, "camera position and look_at must be finite and distinct".into()));
                }
                if !(c.fov_y > 0.0 && c.fov_y < 179.0) {
                    return Err(err(span, format!("camera fov_y {} must be between 0 and 179 degrees", c.fov_y)));
                }
                Some(CameraSpec { position: p, look_at: t, fov_y: c.fov_y.to_radians() })
            }
        };
        let mut fixtures: Vec<Fixture> = Vec::new();
        for f in file.fixture {
            let span = f.span();
            let line = line_of(text, span.start);
            let f = f.into_inner();
            let here = |m: String| err(span.clone(), format!("fixture {}: {m}", f.id));
            if let Some(other) = fixtures.iter().find(|o| o.id == f.id) {
                return Err(here(format!("id already used on line {}; give each fixture its own id", other.line)));
            }
            if f.kind != "spot" {
                return Err(here(format!("unknown fixture type {:?}; the built-in type is \"spot\"", f.kind)));
            }
            let position = Vec3::from(f.position);
            if !position.is_finite() {
                return Err(here("position must be three finite numbers".into()));
            }
            let rotation = match (f.aim, f.rotation) {
                (Some(_), Some(_)) => return Err(here("give either aim or rotation, not both".into())),
                (None, None) => return Err(here("needs an aim point or a rotation".into())),
                (Some(aim), None) => {
                    let aim = Vec3::from(aim);
                    if !aim.is_finite() || aim.distance(position) < 1e-6 {
                        return Err(here("aim must be finite and differ from position".into()));
                    }
                    Quat::from_rotation_arc(Vec3::NEG_Z, (aim - position).normalize())
                }
                (None, Some(q)) => {
                    let q = Quat::from_array(q);
                    if !q.is_finite() || q.length() < 1e-6 {
                        return Err(here("rotation must be a non-zero finite quaternion [x, y, z, w]".into()));
                    }
                    q.normalize()
                }
            };
            let field = f.field_angle.unwrap_or(f.beam_angle + 10.0);
            if !(f.beam_angle > 0.0 && f.beam_angle <= 360.0 && field >= f.beam_angle && field <= 360.0) {
                return Err(here(format!(
                    "beam_angle {} and field_angle {field} must satisfy 0 < beam <= field <= 360",
                    f.beam_angle
                )));
            }
            if !(f.intensity.is_finite() && f.intensity >= 0.0) {
                return Err(here(format!("intensity {} cd must be a finite number >= 0", f.intensity)));
            }
            let colour = Vec3::from(f.colour);
            if !colour.is_finite() || colour.min_element() < 0.0 {
                return Err(here("colour must be three finite numbers >= 0".into()));
            }
            if !(0.0..=1.0).contains(&f.level) {
                return Err(here(format!("level {} must be in 0..1", f.level)));
            }
            let dmx = match (f.universe, f.address) {
                (Some(u), Some(a)) => {
                    if u == 0 || !(1..=512).contains(&a) {
                        return Err(here(format!("universe {u} must be >= 1 and address {a} in 1..512")));
                    }
                    Some((u, a))
                }
                (None, None) => None,
                _ => return Err(here("give both universe and address, or neither".into())),
            };
            fixtures.push(Fixture {
                id: f.id,
                name: f.name.unwrap_or_else(|| format!("fixture {}", f.id)),
                light: Light { position, rotation, beam: Beam::Spot(SpotBeam::from_beam_field(f.beam_angle, field)) },
                intensity: f.intensity,
                colour,
                level: f.level,
                dmx,
                line,
            });
        }
        Ok(Self { path: path.to_path_buf(), camera, fixtures })
    }

    /// Tracer lights in fixture order.
    pub fn lights(&self) -> Vec<Light> {
        self.fixtures.iter().map(|f| f.light.clone()).collect()
    }

    /// k_i for every fixture's default look (eq. 4).
    pub fn default_k(&self) -> Vec<Vec3> {
        self.fixtures.iter().map(Fixture::k).collect()
    }
}

/// 1-based line number of byte offset `at` in `text`.
fn line_of(text: &str, at: usize) -> usize {
    text[..at.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
[camera]
position = [0.0, 2.0, 10.0]
look_at = [0.0, 1.0, 0.0]

[[fixture]]
id = 1
type = "spot"
position = [0.0, 6.0, 6.0]
aim = [0.0, 0.0, 0.0]
intensity = 1000.0
level = 0.5

[[fixture]]
id = 2
type = "spot"
position = [1.0, 6.0, 6.0]
rotation = [0.0, 0.0, 0.0, 1.0]
beam_angle = 30
field_angle = 40
intensity = 2000.0
colour = [1.0, 0.5, 0.25]
universe = 1
address = 10
"#;

    #[test]
    fn parses_fixtures_and_k() {
        let p = Patch::parse(Path::new("good.toml"), GOOD).unwrap();
        assert_eq!(p.fixtures.len(), 2);
        assert_eq!(p.fixtures[0].k(), Vec3::splat(500.0));
        assert_eq!(p.fixtures[1].k(), Vec3::new(2000.0, 1000.0, 500.0));
        assert_eq!(p.fixtures[1].dmx, Some((1, 10)));
        assert_eq!(p.fixtures[1].line, 14);
        let axis = p.fixtures[0].light.axis();
        assert!((axis - Vec3::new(0.0, -1.0, -1.0).normalize()).length() < 1e-5);
        assert!(p.camera.is_some());
    }

    fn error_of(text: &str) -> String {
        Patch::parse(Path::new("bad.toml"), text).unwrap_err().to_string()
    }

    #[test]
    fn errors_name_file_and_line() {
        let dup = GOOD.replace("id = 2", "id = 1");
        let e = error_of(&dup);
        assert!(e.starts_with("bad.toml:14:") && e.contains("already used on line 6"), "{e}");
        let e = error_of(&GOOD.replace("type = \"spot\"\nposition = [1.0", "type = \"moving\"\nposition = [1.0"));
        assert!(e.starts_with("bad.toml:14:") && e.contains("unknown fixture type"), "{e}");
        let e = error_of(&GOOD.replace("level = 0.5", "level = 5.0"));
        assert!(e.starts_with("bad.toml:6:") && e.contains("level"), "{e}");
        let e = error_of(&GOOD.replace("intensity = 1000.0", "intensity = \"bright\""));
        assert!(e.starts_with("bad.toml:11:"), "{e}");
        let e = error_of(&GOOD.replace("address = 10", "address = 600"));
        assert!(e.contains("address 600"), "{e}");
        let e = error_of("[[fixture]]\nid = 1\ntype = \"spot\"\nposition = [0,0,0]\naim = [0,0,0]\nintensity = 1\n");
        assert!(e.starts_with("bad.toml:1:") && e.contains("aim"), "{e}");
        let e = error_of("[[fixtur]]\nid = 1\n");
        assert!(e.starts_with("bad.toml:1:"), "{e}");
    }
}
