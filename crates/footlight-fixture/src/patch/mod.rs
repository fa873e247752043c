//! The patch file: which fixtures hang where, how the desk addresses them,
//! and the default look (schema: `docs/patch-format.md`).
//!
//! ```toml
//! [[fixture]]
//! id = 2
//! name = "Castor front left"
//! type = "strand-castor"        # patch/fixtures/strand-castor.toml
//! mode = "1ch"
//! universe = 1
//! address = 2
//! position = [-5.5, 5.0, 7.0]
//! aim = [-0.5, 0.8, -2.5]
//! gel = "L201"                  # patch/gels.toml
//!
//! [look]
//! 2 = { dimmer = 255 }          # DMX values until DMX arrives
//! ```
//!
//! Loading is two-stage (ripgrep's LowArgs/HiArgs): serde fills the plain
//! [`file`] structs, then [`build`] validates them, loads fixture types and
//! the gel library, and builds each [`Fixture`]. Validation collects every
//! problem ([`check`]); [`Patch::load`] reports the first. Each fixture then
//! turns DMX into its state ([`Fixture::decode`]), its state into geometry
//! ([`Fixture::light_of`]) and into k_i ([`Fixture::k_of`], eq. 4).

mod build;
pub mod file;
pub mod haze;
mod listing;
pub mod views;
mod white;

pub use file::PatchFile;
pub use haze::HazeSpec;
pub use listing::ListedFixture;
pub use views::ViewSpec;
pub use white::RigWhite;

use crate::beam::{Beam, SpotBeam};
use crate::error::PatchError;
use crate::fixture_type::{Attribute, FixtureType, Manual};
use crate::light::{Light, head_rotation};
use crate::state::{DmxSlots, FixtureState, SLOTS, Universes};
use footlight_photometry::{GelId, GelLibrary, GelMix, Scroller};
use glam::{Quat, Vec3};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// One validated fixture instance.
#[derive(Clone, Debug)]
pub struct Fixture {
    /// Desk fixture id.
    pub id: u32,
    /// Display name.
    pub name: String,
    /// Geometry of the default look, for the tracer (unit intensity).
    pub light: Light,
    /// DMX universe and start address when patched.
    pub dmx: Option<(u16, u16)>,
    /// Line in the patch file, for later messages.
    pub line: usize,
    /// What the fixture is.
    pub model: FixtureModel,
    /// The state of the default look (the `[look]` table over the channel defaults).
    pub look: FixtureState,
    /// Where the fixture hangs, metres: the patch's `position`, an MVR
    /// fixture's origin (the same for each of its cells). What the status
    /// shows; the light's source may sit off it (a lens, a cell: `light`).
    pub position: Vec3,
    /// Which cell of its fixture this light is, when the fixture is several
    /// lights (an MVR pixel bar's pixels, a blinder's lamps); `None` for a
    /// one-light fixture.
    pub cell: Option<FixtureCell>,
}

/// One light of a fixture made of several ([`Fixture::cell`]): the MVR
/// import emits a fixture's cells one after another, under its id and DMX
/// address, each named `"fixture / cell"`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FixtureCell {
    /// 1-based number among its fixture's cells, in patch order (as desks
    /// number sub-fixtures).
    pub number: u32,
    /// The whole fixture's name.
    pub fixture_name: String,
}

/// The two kinds of fixture instance.
#[derive(Clone, Debug)]
pub enum FixtureModel {
    /// The built-in parametric spot (`type = "spot"`), with its own angles,
    /// intensity and linear-RGB colour; one 8-bit linear dimmer channel.
    Builtin(BuiltinSpot),
    /// A fixture type from the library.
    Typed(TypedFixture),
}

/// The built-in spot's data.
#[derive(Clone, Debug)]
pub struct BuiltinSpot {
    /// Its beam.
    pub beam: SpotBeam,
    /// Î in candela.
    pub intensity: f32,
    /// Linear RGB colour at full (stands in for c_I · c_F; a fixed gel is folded in).
    pub colour: Vec3,
}

/// A typed fixture's data.
#[derive(Clone, Debug)]
pub struct TypedFixture {
    /// The fixture type (shared by every instance of it).
    pub fixture_type: Arc<FixtureType>,
    /// Index of the mode in `fixture_type.modes`.
    pub mode: usize,
    /// Position in metres.
    pub position: Vec3,
    /// Orientation: the light frame (conventional) or the body mount (moving head).
    pub rotation: Quat,
    /// A fixed gel.
    pub gel: Option<GelId>,
    /// The scroller string (the instance's `frames`, else the mode's scroller channel).
    pub scroller: Option<Scroller>,
    /// The patch's gel library (when any gel is used).
    pub gels: Option<Arc<GelLibrary>>,
    /// Hand-set values for attributes the mode has no channel for.
    pub manual: Manual,
    /// DMX breaks after the first (a GDTF mode spanning several
    /// universes/addresses, MVR `<Addresses>`): `(universe, start address)`
    /// of break 2, 3…. A channel offset `o ≥ BREAK_STRIDE` reads slot
    /// `o % BREAK_STRIDE` of break `o / BREAK_STRIDE + 1` ([`Fixture::slot_address`]).
    /// Empty for a one-break fixture (every TOML patch).
    pub breaks: Vec<(u16, u16)>,
}

/// Channel offsets per DMX break in a mode whose channels span several
/// breaks: offset `o` is slot `o % BREAK_STRIDE` of break `o / BREAK_STRIDE + 1`.
pub const BREAK_STRIDE: u16 = SLOTS as u16;

impl Fixture {
    /// k_i of eq. 4 for this fixture's default look.
    pub fn k(&self) -> Vec3 {
        self.k_of(&self.look)
    }

    /// k_i with the dimmer at full and everything else as in the default
    /// look: the scale adaptive anti-aliasing decides on (so dimming never
    /// changes a light's sample set).
    pub fn k_full(&self) -> Vec3 {
        self.k_full_of(&self.look)
    }

    /// The DMX mode's name (a typed fixture's, a GDTF mode's as the file
    /// names it); `None` for the built-in spot.
    pub fn mode_name(&self) -> Option<&str> {
        match &self.model {
            FixtureModel::Builtin(_) => None,
            FixtureModel::Typed(t) => t.fixture_type.modes.get(t.mode).map(|m| m.name.as_str()),
        }
    }

    /// Slots the fixture uses from its start address.
    pub fn footprint(&self) -> u16 {
        match &self.model {
            FixtureModel::Builtin(_) => 1,
            FixtureModel::Typed(t) => t.fixture_type.modes[t.mode].footprint,
        }
    }

    /// The state from one universe's 512 slots, read at this fixture's
    /// start address (address 1 when unpatched). Never fails: slots past
    /// 512 read as 0.
    pub fn decode(&self, slots: &[u8; SLOTS]) -> FixtureState {
        let start = self.dmx.map_or(0, |(_, a)| usize::from(a) - 1);
        let read = |o: u16| slots.get(start + usize::from(o)).copied().unwrap_or(0);
        self.decode_with(&read)
    }

    /// The state from the patch's universes; the default look when the
    /// fixture is unpatched or none of its universes has a frame yet. A
    /// fixture over several DMX breaks reads each break from its own
    /// universe; a break whose universe has no frame yet reads 0.
    pub fn decode_universes(&self, universes: &(impl DmxSlots + ?Sized)) -> FixtureState {
        if self.breaks().is_empty() {
            return match self.dmx.and_then(|(u, _)| universes.slots(u)) {
                Some(slots) => self.decode(slots),
                None => self.look,
            };
        }
        if !self.universes().into_iter().any(|u| universes.slots(u).is_some()) {
            return self.look;
        }
        let read = |o: u16| {
            self.slot_address(o)
                .and_then(|(u, a)| universes.slots(u).and_then(|s| s.get(usize::from(a).wrapping_sub(1)).copied()))
                .unwrap_or(0)
        };
        self.decode_with(&read)
    }

    /// DMX breaks after the first (empty for most fixtures): see [`TypedFixture::breaks`].
    pub fn breaks(&self) -> &[(u16, u16)] {
        match &self.model {
            FixtureModel::Typed(t) => &t.breaks,
            FixtureModel::Builtin(_) => &[],
        }
    }

    /// Universe and 1-based address of channel offset `o` (break-aware:
    /// offsets from [`BREAK_STRIDE`] on address the later breaks); `None`
    /// when unpatched, past slot 512 or on a break the fixture has no
    /// address for.
    pub fn slot_address(&self, o: u16) -> Option<(u16, u16)> {
        let (k, local) = (o / BREAK_STRIDE, o % BREAK_STRIDE);
        let (u, a) = if k == 0 { self.dmx? } else { *self.breaks().get(usize::from(k) - 1)? };
        let addr = u32::from(a) + u32::from(local);
        (addr >= 1 && addr <= SLOTS as u32).then_some((u, addr as u16))
    }

    /// Every patch universe the fixture reads (its start address's, then its later breaks').
    pub fn universes(&self) -> Vec<u16> {
        let mut out: Vec<u16> = self.dmx.iter().chain(self.breaks()).map(|(u, _)| *u).collect();
        out.dedup();
        out
    }

    /// The state from slot values relative to the start address
    /// (`slot(0)` is the first channel).
    pub fn decode_with(&self, slot: &dyn Fn(u16) -> u8) -> FixtureState {
        match &self.model {
            FixtureModel::Builtin(_) => FixtureState { v: f32::from(slot(0)) / 255.0, ..FixtureState::default() },
            FixtureModel::Typed(t) => {
                let mode = &t.fixture_type.modes[t.mode];
                let mut s = t.fixture_type.decode(mode, &t.manual, slot);
                // The instance's own scroller string (if it has one) decides the frame positions.
                if let (Some(sc), Some(c)) = (&t.scroller, mode.channel(Attribute::Scroller)) {
                    let (raw, full) = c.raw(slot);
                    s.frame = if full == 255 { sc.position_from_dmx8(raw as u8) } else { sc.position_from_dmx16(raw) };
                }
                s
            }
        }
    }

    /// The light (geometry and unit-intensity pattern) for a state: pan,
    /// tilt, zoom, focus and iris. What the tracer renders.
    pub fn light_of(&self, state: &FixtureState) -> Light {
        match &self.model {
            FixtureModel::Builtin(b) => Light { beam: Beam::Spot(b.beam.clone()), ..self.light.clone() },
            FixtureModel::Typed(t) => {
                let ty = &t.fixture_type;
                let rotation = match ty.movement {
                    Some(_) => head_rotation(t.rotation, state.pan, state.tilt),
                    None => t.rotation,
                };
                Light { position: t.position, rotation, beam: ty.beam(state) }
            }
        }
    }

    /// k_i of eq. 4 for a state: c_F ⊙ c_I · v · Î, with c_I from the lamp
    /// at the dimmed CCT (tungsten) or colour mix (LED, CMY), c_F from the
    /// fixed gel or the scroller frames, and Î from the optics at the
    /// state's zoom/focus. Exactly black at v = 0; never NaN.
    pub fn k_of(&self, state: &FixtureState) -> Vec3 {
        match &self.model {
            FixtureModel::Builtin(b) => {
                let v = if state.v > 0.0 { state.v.min(1.0) } else { 0.0 };
                b.colour * (v * b.intensity)
            }
            FixtureModel::Typed(t) => {
                let ty = &t.fixture_type;
                let lamp = ty.lamp_for(state);
                let intensity = ty.intensity(state) * ty.correction(state) * shutter(state);
                // Vierjahn 2010, eq. (4): c_F (gel, wheels, CTO, colour target) ⊙ c_I · v · Î.
                let (spectral, factor) = ty.filters(state, &lamp);
                let k = match spectral {
                    Some(gel) => footlight_photometry::k(&lamp, state.v, &GelMix::single(Some(gel)), intensity),
                    None => footlight_photometry::k(&lamp, state.v, &t.gel_mix(state.frame), intensity),
                };
                k * factor
            }
        }
    }

    /// k_i at frame time `t_seconds`: [`Fixture::k_of`] times the strobe's
    /// open/closed factor ([`FixtureState::shutter_at`]). What the frame
    /// clock composites each frame; a strobe therefore costs a composite,
    /// never a rebuild. Stills use t = 0 (open).
    pub fn k_at(&self, state: &FixtureState, t_seconds: f64) -> Vec3 {
        self.k_of(state) * state.shutter_at(t_seconds)
    }

    /// Î in candela for a state (zoom and focus included; the built-in spot's fixed intensity).
    pub fn intensity_of(&self, state: &FixtureState) -> f32 {
        match &self.model {
            FixtureModel::Builtin(b) => b.intensity,
            FixtureModel::Typed(t) => t.fixture_type.intensity(state),
        }
    }

    /// [`Fixture::k_of`] with the dimmer at full and the shutter open (so
    /// neither dimming nor the shutter changes a light's sample set).
    pub fn k_full_of(&self, state: &FixtureState) -> Vec3 {
        self.k_of(&FixtureState { v: 1.0, shutter: 1.0, ..*state })
    }
}

impl TypedFixture {
    /// What is in the beam at scroller position `frame`: the scroller's two
    /// neighbouring frames, else the fixed gel, else open.
    pub fn gel_mix(&self, frame: f32) -> GelMix<'_> {
        let Some(lib) = self.gels.as_deref() else {
            return GelMix::OPEN;
        };
        if let Some(s) = &self.scroller {
            return s.at(lib, frame).unwrap_or(GelMix::OPEN);
        }
        GelMix::single(self.gel.and_then(|g| lib.get(g)))
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

/// The protocols an `[[input]]` route can name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum InputProtocol {
    /// sACN (E1.31), universes 1-63999.
    Sacn,
    /// Art-Net, 15-bit Port-Address 0-32767.
    ArtNet,
    /// Enttec DMX USB Pro, by widget index.
    UsbPro,
}

/// One `[[input]]` route: a protocol universe feeds a patch universe
/// (`None`: blocked). Inputs without a route use the default rule: sACN
/// universe N and Art-Net Port-Address N−1 (USB Pro widget N−1) feed patch universe N.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InputRoute {
    /// The protocol.
    pub protocol: InputProtocol,
    /// The protocol's universe number as the desk sends it.
    pub universe: u16,
    /// The patch universe it feeds, or `None` to block it.
    pub patch_universe: Option<u16>,
    /// Line in the patch file.
    pub line: usize,
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
    /// `[[input]]` routes in file order.
    pub inputs: Vec<InputRoute>,
    /// The frames of the default look (channel defaults, then `[look]`), per patched universe.
    pub look_universes: Universes,
    /// The gel library, when the patch uses gels.
    pub gels: Option<Arc<GelLibrary>>,
    /// The haze medium (`[haze]`), if any.
    pub haze: Option<HazeSpec>,
    /// Named camera views (`[[view]]`) in file order.
    pub views: Vec<ViewSpec>,
    /// Problems that do not stop the patch from loading (e.g. no fixtures),
    /// each with its file and line; also logged with `tracing::warn!` when
    /// the patch is built, which is how `footlight check` prints them.
    pub warnings: Vec<PatchError>,
}

impl Patch {
    /// Reads and validates a patch file; the first problem is the error.
    pub fn load(path: &Path) -> Result<Self, PatchError> {
        check(path).map_err(first)
    }

    /// Parses and validates patch text; `path` names it in messages and
    /// locates the fixture types and gels (relative to its folder).
    pub fn parse(path: &Path, text: &str) -> Result<Self, PatchError> {
        check_text(path, text).map_err(first)
    }

    /// Tracer lights of the default look, in fixture order.
    pub fn lights(&self) -> Vec<Light> {
        self.fixtures.iter().map(|f| f.light.clone()).collect()
    }

    /// k_i for every fixture's default look (eq. 4).
    pub fn default_k(&self) -> Vec<Vec3> {
        self.fixtures.iter().map(Fixture::k).collect()
    }

    /// Slots that merge latest-takes-precedence, per patch universe: every
    /// patched channel except dimmers (which merge highest-takes-precedence,
    /// as desks expect). What the DMX merge's per-slot policy mask is made from
    /// (DESIGN.md "Merge"). Addresses are 1-based.
    pub fn ltp_addresses(&self) -> BTreeMap<u16, Vec<u16>> {
        let mut out: BTreeMap<u16, Vec<u16>> = BTreeMap::new();
        for f in &self.fixtures {
            let (Some((u, _)), FixtureModel::Typed(t)) = (f.dmx, &f.model) else { continue };
            out.entry(u).or_default();
            for c in &t.fixture_type.modes[t.mode].channels {
                if c.attribute != Attribute::Dimmer {
                    for (u, a) in std::iter::once(c.offset).chain(c.fine).filter_map(|o| f.slot_address(o)) {
                        out.entry(u).or_default().push(a);
                    }
                }
            }
        }
        out.values_mut().for_each(|v| {
            v.sort_unstable();
            v.dedup();
        });
        out
    }

    /// Every fixture's state from `universes`, in fixture order (the default
    /// look for fixtures whose universe has no frame).
    pub fn decode(&self, universes: &(impl DmxSlots + ?Sized)) -> Vec<FixtureState> {
        self.fixtures.iter().map(|f| f.decode_universes(universes)).collect()
    }
}

/// Validates the patch at `path` and every file it uses (fixture types,
/// photometry, gels), collecting every problem: what `footlight check`
/// prints. Each error names its file and line and says what to do.
pub fn check(path: &Path) -> Result<Patch, Vec<PatchError>> {
    let bytes = std::fs::read(path).map_err(|e| vec![PatchError::new(path, 0, format!("cannot read: {e}"))])?;
    let text = String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let line = e.as_bytes()[..at].iter().filter(|&&b| b == b'\n').count() + 1;
        vec![PatchError::new(path, line, format!("byte offset {at} is not valid UTF-8; save the patch as UTF-8 text"))]
    })?;
    check_text(path, &text)
}

/// [`check`] on patch text already read.
pub fn check_text(path: &Path, text: &str) -> Result<Patch, Vec<PatchError>> {
    build::build(path, text)
}

/// A reader for fixture-type files the fixture crate cannot parse itself:
/// GDTF (`type = "types/x.gdtf"` in a patch, relative to the patch file).
/// The fixture crate does not depend on the GDTF reader (that would be a
/// cycle: `footlight-mvr` builds on this crate's types), so the reader is
/// handed in as a trait object; `footlight_mvr::GdtfTypes` implements it.
pub trait TypeLoader {
    /// Reads the type file at `path` (already resolved, existing): the type
    /// with every mode, and warnings that do not stop it (e.g. attributes
    /// not modelled), or the error naming the file.
    fn load(&self, path: &Path) -> Result<(FixtureType, Vec<PatchError>), PatchError>;

    /// Reads the show file at `path` that a patch names with `show = …`
    /// (an MVR): its patch and warnings, or every problem. `None`: this
    /// loader reads no shows (the patch gets an error naming the key).
    fn load_show(&self, _path: &Path) -> Option<Checked> {
        None
    }
}

/// A patch with the warnings that did not stop it, or every problem found.
pub type Checked = Result<(Patch, Vec<PatchError>), Vec<PatchError>>;

/// [`check`] with a reader for foreign type files (GDTF): the patch and the
/// reader's warnings, or every problem.
pub fn check_with(path: &Path, loader: &dyn TypeLoader) -> Result<(Patch, Vec<PatchError>), Vec<PatchError>> {
    let text =
        std::fs::read_to_string(path).map_err(|e| vec![PatchError::new(path, 0, format!("cannot read: {e}"))])?;
    build::build_with(path, &text, Some(loader))
}

/// A closed shutter's factor on k_i (1 open, 0 closed; strobe is applied by [`Fixture::k_at`]).
fn shutter(state: &FixtureState) -> f32 {
    if state.shutter >= 0.5 { 1.0 } else { 0.0 }
}

fn first(mut errors: Vec<PatchError>) -> PatchError {
    if errors.is_empty() { PatchError::new(Path::new("?"), 0, "invalid patch") } else { errors.swap_remove(0) }
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
        assert!(e.starts_with("bad.toml:15:") && e.contains("already used on line 6"), "{e}");
        let e = error_of(&GOOD.replace("type = \"spot\"\nposition = [1.0", "type = \"moving\"\nposition = [1.0"));
        assert!(e.starts_with("bad.toml:16:") && e.contains("unknown fixture type"), "{e}");
        let e = error_of(&GOOD.replace("level = 0.5", "level = 5.0"));
        assert!(e.starts_with("bad.toml:12:") && e.contains("level"), "{e}");
        let e = error_of(&GOOD.replace("intensity = 1000.0", "intensity = \"bright\""));
        assert!(e.starts_with("bad.toml:11:"), "{e}");
        let e = error_of(&GOOD.replace("address = 10", "address = 600"));
        assert!(e.contains("address 600"), "{e}");
        let e = error_of("[[fixture]]\nid = 1\ntype = \"spot\"\nposition = [0,0,0]\naim = [0,0,0]\nintensity = 1\n");
        assert!(e.starts_with("bad.toml:5:") && e.contains("aim"), "{e}");
        let e = error_of("[[fixtur]]\nid = 1\n");
        assert!(e.starts_with("bad.toml:1:"), "{e}");
    }

    /// Each check that used to blame the `[[fixture]]`/`[camera]`/`[[input]]`
    /// header now names the offending key's own line (issue 12 item 10).
    #[test]
    fn errors_point_at_the_offending_key() {
        // GOOD's lines: 2 [camera], 3 position, 4 look_at; 6 [[fixture]] id 1:
        // 7 id, 8 type, 9 position, 10 aim, 11 intensity, 12 level; 14 [[fixture]] id 2:
        // 15 id, 16 type, 17 position, 18 rotation, 19 beam_angle, 20 field_angle,
        // 21 intensity, 22 colour, 23 universe, 24 address.
        let cases: Vec<(String, usize, &str)> = vec![
            (GOOD.replace("id = 2", "id = 1"), 15, "already used on line 6"),
            (
                GOOD.replace("position = [0.0, 6.0, 6.0]", "position = [0.0, nan, 6.0]"),
                9,
                "position must be three finite",
            ),
            (GOOD.replace("aim = [0.0, 0.0, 0.0]", "aim = [0.0, 6.0, 6.0]"), 10, "aim must be finite"),
            (
                GOOD.replace("rotation = [0.0, 0.0, 0.0, 1.0]", "rotation = [0.0, 0.0, 0.0, 0.0]"),
                18,
                "rotation must be",
            ),
            (GOOD.replace("level = 0.5", "level = 0.5\nrotation = [0.0, 0.0, 0.0, 1.0]"), 13, "either aim or rotation"),
            (GOOD.replace("field_angle = 40", "field_angle = 20"), 20, "beam_angle 30 and field_angle 20"),
            (GOOD.replace("beam_angle = 30", "beam_angle = -30"), 19, "beam_angle -30"),
            (GOOD.replace("intensity = 2000.0", "intensity = -2000.0"), 21, "intensity -2000"),
            (GOOD.replace("colour = [1.0, 0.5, 0.25]", "colour = [1.0, -0.5, 0.25]"), 22, "colour must be"),
            (GOOD.replace("level = 0.5", "level = 1.5"), 12, "level 1.5"),
            (GOOD.replace("level = 0.5", "level = 0.5\npan = 10.0"), 13, "built-in spot has no pan"),
            (GOOD.replace("look_at = [0.0, 1.0, 0.0]", "look_at = [0.0, 2.0, 10.0]"), 4, "camera look_at"),
            (GOOD.replace("position = [0.0, 2.0, 10.0]", "position = [0.0, inf, 10.0]"), 3, "camera position"),
            (GOOD.replace("look_at = [0.0, 1.0, 0.0]", "look_at = [0.0, 1.0, 0.0]\nfov_y = 190.0"), 5, "fov_y 190"),
            (
                format!(
                    "{GOOD}\n[[input]]\nprotocol = \"sacn\"\nuniverse = 3\npatch_universe = 1\n\n[[input]]\nprotocol = \"sacn\"\nuniverse = 3\nblock = true\n"
                ),
                33,
                "already routed on line 26",
            ),
        ];
        for (text, line, what) in cases {
            let e = error_of(&text);
            assert!(e.starts_with(&format!("bad.toml:{line}:")) && e.contains(what), "want line {line} {what:?}: {e}");
        }
    }

    #[test]
    fn non_utf8_patch_reports_the_byte_offset() {
        let dir = std::env::temp_dir().join(format!("footlight-patch-utf8-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("latin1.toml");
        let mut bytes = b"[[fixture]]\nid = 1\nname = \"Fa".to_vec();
        let at = bytes.len();
        bytes.extend(b"\xe7ade\"\n");
        std::fs::write(&path, &bytes).unwrap();
        let errors = check(&path).unwrap_err();
        let e = errors[0].to_string();
        assert_eq!(errors[0].line, 3, "{e}");
        assert!(e.contains(&format!("byte offset {at} is not valid UTF-8")), "{e}");
    }

    #[test]
    fn empty_patch_loads_with_a_warning() {
        let p = Patch::parse(Path::new("empty.toml"), "# nothing hung yet\n").unwrap();
        assert!(p.fixtures.is_empty());
        assert_eq!(p.warnings.len(), 1);
        let w = p.warnings[0].to_string();
        assert!(w.starts_with("empty.toml:1: warning:") && w.contains("no [[fixture]]"), "{w}");
        assert!(Patch::parse(Path::new("good.toml"), GOOD).unwrap().warnings.is_empty());
    }

    #[test]
    fn builtin_spot_takes_dmx_and_a_look() {
        let text = format!("{GOOD}\n[look]\n2 = {{ dimmer = 51 }}\n\"1/11\" = [1, 2]\n");
        let p = Patch::parse(Path::new("good.toml"), &text).unwrap();
        assert!((p.fixtures[1].look.v - 0.2).abs() < 1e-7);
        assert_eq!(p.fixtures[0].look.v, 0.5, "an unpatched spot keeps its exact level");
        let frame = p.look_universes.get(1).unwrap();
        assert_eq!(&frame[9..12], &[51, 1, 2]);
        let mut slots = [0u8; SLOTS];
        slots[9] = 255;
        assert_eq!(p.fixtures[1].decode(&slots).v, 1.0);
        assert_eq!(p.fixtures[1].k_of(&p.fixtures[1].decode(&slots)), Vec3::new(2000.0, 1000.0, 500.0));
        assert_eq!(p.fixtures[1].k_of(&FixtureState { v: f32::NAN, ..FixtureState::default() }), Vec3::ZERO);
        assert_eq!(p.fixtures[1].footprint(), 1);
    }
}
