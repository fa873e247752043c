//! Second stage of patch loading: validate the plain structs, load fixture
//! types and the gel library, build fixtures, the default look and the
//! input routes. Every problem is collected (for `footlight check`) with
//! its file, line and what to do.

use super::file::{FixtureFile, InputFile, PatchFile};
use super::{
    BuiltinSpot, CameraSpec, Fixture, FixtureModel, InputProtocol, InputRoute, Patch, TypeLoader, TypedFixture,
};
use crate::beam::{Beam, SpotBeam};
use crate::error::{PatchError, line_of, toml_error};
use crate::fixture_type::{Attribute, FixtureType, Manual, Optics, load_type};
use crate::light::{Light, mount_aimed};
use crate::state::{FixtureState, SLOTS, Universes};
use footlight_photometry::{GelLibrary, Lamp, Scroller};
use glam::{Quat, Vec3};
use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use toml::Spanned;

/// True for a type name that is a foreign type file (`….gdtf`, any case).
fn is_foreign(raw: &str) -> bool {
    Path::new(raw).extension().is_some_and(|e| e.eq_ignore_ascii_case("gdtf"))
}

/// Highest patch universe (the sACN range).
const MAX_UNIVERSE: i64 = 63999;

/// Builds a patch from its text, or every problem found.
pub(super) fn build(path: &Path, text: &str) -> Result<Patch, Vec<PatchError>> {
    build_with(path, text, None).map(|(p, _)| p)
}

/// [`build`] with a reader for foreign fixture-type files (GDTF): the patch
/// and the reader's warnings, or every problem found.
pub(super) fn build_with(
    path: &Path,
    text: &str,
    loader: Option<&dyn TypeLoader>,
) -> Result<(Patch, Vec<PatchError>), Vec<PatchError>> {
    let file: PatchFile = toml::from_str(text).map_err(|e| vec![toml_error(path, text, &e)])?;
    if let Some(show) = &file.show {
        return build_over_show(path, text, &file, show, loader);
    }
    let mut b = Builder::new(path, text, &file);
    b.loader = loader;
    let camera = b.camera(&file);
    let mut built: Vec<Built> = Vec::new();
    for f in &file.fixture {
        if let Some(x) = b.fixture(f) {
            built.push(x);
        }
    }
    b.addresses(&built);
    b.unaddressed(&built);
    let mut look_universes = b.look(&file, &mut built);
    let inputs = b.inputs(&file.input);
    let fixtures: Vec<Fixture> = built.iter().map(|x| x.fixture.clone()).collect();
    let haze = super::haze::build_haze(path, text, &file, &fixtures, &mut b.errors);
    if let Some(h) = &haze {
        h.write_look(&mut look_universes);
    }
    let views = super::views::build_views(path, text, &file, &mut b.errors);
    if !b.errors.is_empty() {
        return Err(b.errors);
    }
    let gels = b.gels.flatten();
    let mut warnings = Vec::new();
    if file.fixture.is_empty() {
        warnings.push(PatchError::new(
            path,
            1,
            "warning: the patch has no [[fixture]] entries, so the stage stays dark; \
             add fixtures (docs/patch-format.md)",
        ));
    }
    for w in &warnings {
        tracing::warn!("{w}");
    }
    let patch = Patch {
        path: path.to_path_buf(),
        camera,
        fixtures: built.into_iter().map(|x| x.fixture).collect(),
        inputs,
        look_universes,
        gels,
        haze,
        views,
        warnings,
    };
    Ok((patch, b.warnings))
}

/// A patch that names an MVR show (`show = "festival.mvr"`): the show's
/// fixtures, addresses and channel defaults, with this file's `[haze]`,
/// `[[view]]`, `[camera]`, `[[input]]` and `[look]` added (issue 36: haze
/// on an MVR show). Its own `[[fixture]]` entries are refused: the show
/// owns the rig, so there is one place to re-patch it.
fn build_over_show(
    path: &Path,
    text: &str,
    file: &PatchFile,
    show: &Spanned<String>,
    loader: Option<&dyn TypeLoader>,
) -> Result<(Patch, Vec<PatchError>), Vec<PatchError>> {
    let mut b = Builder::new(path, text, file);
    let show_path = path.parent().unwrap_or(Path::new("")).join(show.get_ref());
    if let Some(f) = file.fixture.first() {
        b.err(
            f.span(),
            format!(
                "[[fixture]] in a patch that names the show {:?}: the show's fixtures are the rig; \
                 re-patch them in the MVR (this file adds haze, views, camera, inputs and a look)",
                show.get_ref()
            ),
        );
    }
    let loaded = match loader.and_then(|l| l.load_show(&show_path)) {
        Some(r) => r,
        None => {
            b.err(show.span(), format!("show = {:?}: this build reads no MVR shows", show.get_ref()));
            return Err(b.errors);
        }
    };
    let (base, base_warnings) = match loaded {
        Ok(x) => x,
        Err(mut e) => {
            let line = line_of(text, show.span().start);
            e.insert(0, PatchError::new(path, line, format!("show = {:?} cannot be loaded:", show.get_ref())));
            return Err(e);
        }
    };
    let camera = b.camera(file);
    let mut frames = base.look_universes.clone();
    let mut fixtures = base.fixtures.clone();
    // `[look]` over the show's channel defaults: an id sets every cell of
    // that fixture; "U/ADDR" keys set slots.
    if let Some(look) = &file.look {
        let mut raw: Vec<(u16, u16, u8)> = Vec::new();
        for (key, value) in look.get_ref() {
            let span = value.span();
            if key.contains('/') {
                b.look_slots(key, value, &mut raw);
                continue;
            }
            let cells: Vec<usize> = key
                .trim()
                .parse::<u32>()
                .map(|id| (0..fixtures.len()).filter(|&i| fixtures[i].id == id).collect())
                .unwrap_or_default();
            if cells.is_empty() {
                b.err(span, format!("[look] {key:?}: the show has no fixture with that id; keys are fixture ids or \"universe/address\""));
                continue;
            }
            let Some(table) = value.get_ref().as_table() else {
                b.err(span, format!("[look] {key}: give attribute = DMX value pairs, e.g. {key} = {{ dimmer = 255 }}"));
                continue;
            };
            for i in cells {
                let f = &fixtures[i];
                let reach = match &f.model {
                    FixtureModel::Typed(t) => t.fixture_type.modes[t.mode]
                        .channels
                        .iter()
                        .map(|c| c.fine.unwrap_or(c.offset).max(c.offset) + 1)
                        .max()
                        .unwrap_or(0),
                    FixtureModel::Builtin(_) => 1,
                };
                let local: Vec<u8> = (0..reach)
                    .map(|o| {
                        f.slot_address(o).and_then(|(u, a)| frames.get(u).map(|s| s[usize::from(a) - 1])).unwrap_or(0)
                    })
                    .collect();
                let mut one = Built { fixture: f.clone(), address_span: None, level: None, local };
                for (attr, v) in table {
                    b.look_value(&mut one, attr, v, span.clone());
                }
                for (o, v) in one.local.iter().enumerate() {
                    if let Some((u, a)) = f.slot_address(o as u16) {
                        frames.set_slot(u, a, *v);
                    }
                }
            }
        }
        for (u, a, v) in raw {
            frames.set_slot(u, a, v);
        }
        for f in &mut fixtures {
            f.look = f.decode_with(&|o| {
                f.slot_address(o).and_then(|(u, a)| frames.get(u).map(|s| s[usize::from(a) - 1])).unwrap_or(0)
            });
            f.light = f.light_of(&f.look);
        }
    }
    let inputs = b.inputs(&file.input);
    let haze = super::haze::build_haze(path, text, file, &fixtures, &mut b.errors);
    if let Some(h) = &haze {
        h.write_look(&mut frames);
    }
    let views = super::views::build_views(path, text, file, &mut b.errors);
    if !b.errors.is_empty() {
        return Err(b.errors);
    }
    let patch = Patch {
        path: path.to_path_buf(),
        camera: camera.or(base.camera),
        fixtures,
        inputs: if file.input.is_empty() { base.inputs } else { inputs },
        look_universes: frames,
        gels: base.gels,
        haze: haze.or(base.haze),
        views: if views.is_empty() { base.views } else { views },
        warnings: base.warnings,
    };
    Ok((patch, base_warnings))
}

/// A fixture being built, with what the cross-checks need.
struct Built {
    fixture: Fixture,
    /// Span of `address` (for overlap errors).
    address_span: Option<Range<usize>>,
    /// The built-in spot's default level (kept exact, not quantised to DMX).
    level: Option<f32>,
    /// Channel values of the default look relative to the start address.
    local: Vec<u8>,
}

struct Builder<'a> {
    path: &'a Path,
    text: &'a str,
    fixtures_dir: PathBuf,
    gels_path: PathBuf,
    gels_span: Option<Range<usize>>,
    /// `None`: not loaded yet; `Some(None)`: missing or broken.
    gels: Option<Option<Arc<GelLibrary>>>,
    types: HashMap<String, Option<Arc<FixtureType>>>,
    /// Every fixture id seen, with its line (also those that failed to build).
    ids: Vec<(u32, usize)>,
    errors: Vec<PatchError>,
    /// Problems that do not stop the patch (from foreign type readers).
    warnings: Vec<PatchError>,
    /// Reader for `type = "x.gdtf"` (and other foreign type files).
    loader: Option<&'a dyn TypeLoader>,
}

impl<'a> Builder<'a> {
    fn new(path: &'a Path, text: &'a str, file: &PatchFile) -> Self {
        let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
        let fixtures_dir = dir.join(file.fixtures.as_ref().map_or("fixtures", |s| s.get_ref().as_str()));
        let gels_path = dir.join(file.gels.as_ref().map_or("gels.toml", |s| s.get_ref().as_str()));
        Self {
            path,
            text,
            fixtures_dir,
            gels_path,
            gels_span: file.gels.as_ref().map(|s| s.span()),
            gels: None,
            types: HashMap::new(),
            ids: Vec::new(),
            errors: Vec::new(),
            warnings: Vec::new(),
            loader: None,
        }
    }

    fn err(&mut self, span: Range<usize>, message: impl Into<String>) {
        self.errors.push(PatchError::new(self.path, line_of(self.text, span.start), message));
    }

    fn err_line(&mut self, line: usize, message: impl Into<String>) {
        self.errors.push(PatchError::new(self.path, line, message));
    }

    /// The gel library, loaded on first use; `span` is blamed if it is missing.
    fn gels(&mut self, span: Range<usize>) -> Option<Arc<GelLibrary>> {
        if self.gels.is_none() {
            let loaded = match GelLibrary::load(&self.gels_path) {
                Ok(lib) => Some(Arc::new(lib)),
                Err(e) if e.line == 0 => {
                    let at = self.gels_span.clone().unwrap_or(span);
                    let p = self.gels_path.display().to_string();
                    self.err(
                        at,
                        format!("cannot read the gel library {p} ({}); set gels = \"path\" at the top", e.message),
                    );
                    None
                }
                Err(e) => {
                    self.errors.push(PatchError::new(&e.path, e.line, e.message));
                    None
                }
            };
            self.gels = Some(loaded);
        }
        self.gels.clone().flatten()
    }

    /// A fixture type by file stem, loaded once; a path the foreign-type
    /// reader takes (`"types/x.gdtf"`) is read relative to the patch.
    fn fixture_type(&mut self, name: &Spanned<String>) -> Option<Arc<FixtureType>> {
        let raw = name.get_ref().trim();
        if is_foreign(raw) {
            return self.foreign_type(name);
        }
        let stem = raw.strip_suffix(".toml").unwrap_or(raw).to_string();
        if let Some(t) = self.types.get(&stem).cloned() {
            if t.is_none() {
                self.err(name.span(), format!("fixture type {stem:?} has errors (reported above); fix its file first"));
            }
            return t;
        }
        let plain = !stem.is_empty() && !stem.contains(['/', '\\']) && !stem.starts_with('.');
        let file = self.fixtures_dir.join(format!("{stem}.toml"));
        if !plain || !file.is_file() {
            let known = self.known_types();
            let dir = self.fixtures_dir.display().to_string();
            self.err(
                name.span(),
                format!("unknown fixture type {raw:?}: no file {dir}/{stem}.toml; use \"spot\" or one of: {known}"),
            );
            return None;
        }
        let text = std::fs::read_to_string(&file).unwrap_or_default();
        let gels = if text.contains("frames") { self.gels(name.span()) } else { None };
        let loaded = match load_type(&file, gels.as_deref()) {
            Ok(t) => Some(Arc::new(t)),
            Err(e) => {
                self.errors.push(e);
                self.err(name.span(), format!("fixture type {stem:?} has errors (reported above); fix its file first"));
                None
            }
        };
        self.types.insert(stem, loaded.clone());
        loaded
    }

    /// A fixture type from a foreign file (GDTF) through the loader, once per path.
    fn foreign_type(&mut self, name: &Spanned<String>) -> Option<Arc<FixtureType>> {
        let raw = name.get_ref().trim().to_string();
        if let Some(t) = self.types.get(&raw).cloned() {
            if t.is_none() {
                self.err(name.span(), format!("fixture type {raw:?} has errors (reported above); fix its file first"));
            }
            return t;
        }
        let file = self.path.parent().unwrap_or(Path::new("")).join(&raw);
        let loaded = match self.loader {
            None => {
                self.err(
                    name.span(),
                    format!(
                        "fixture type {raw:?} is a GDTF file; this reader has no GDTF support \
                         (the footlight binary reads it: footlight check <patch>)"
                    ),
                );
                None
            }
            Some(_) if !file.is_file() => {
                self.err(
                    name.span(),
                    format!("fixture type {raw:?}: no file {} (paths are relative to the patch)", file.display()),
                );
                None
            }
            Some(l) => match l.load(&file) {
                Ok((t, w)) => {
                    self.warnings.extend(w);
                    Some(Arc::new(t))
                }
                Err(e) => {
                    self.errors.push(e);
                    self.err(
                        name.span(),
                        format!("fixture type {raw:?} has errors (reported above); fix its file first"),
                    );
                    None
                }
            },
        };
        self.types.insert(raw, loaded.clone());
        loaded
    }

    fn known_types(&self) -> String {
        let mut names: Vec<String> = std::fs::read_dir(&self.fixtures_dir)
            .map(|d| {
                d.filter_map(|e| e.ok())
                    .filter_map(|e| e.file_name().to_str().and_then(|n| n.strip_suffix(".toml")).map(String::from))
                    .collect()
            })
            .unwrap_or_default();
        names.sort();
        if names.is_empty() { format!("(none in {})", self.fixtures_dir.display()) } else { names.join(", ") }
    }

    fn camera(&mut self, file: &PatchFile) -> Option<CameraSpec> {
        let c = file.camera.as_ref()?;
        let c = c.get_ref();
        let (p, t) = (Vec3::from(*c.position.get_ref()), Vec3::from(*c.look_at.get_ref()));
        if !p.is_finite() {
            self.err(c.position.span(), "camera position must be three finite numbers");
            return None;
        }
        if !t.is_finite() || p.distance(t) < 1e-6 {
            self.err(c.look_at.span(), "camera look_at must be three finite numbers, distinct from position");
            return None;
        }
        let fov_y = c.fov_y.as_ref().map_or(super::file::DEFAULT_FOV_Y, |f| *f.get_ref());
        if !(fov_y > 0.0 && fov_y < 179.0) {
            let span = c.fov_y.as_ref().map_or(0..0, |f| f.span());
            self.err(span, format!("camera fov_y {fov_y} must be between 0 and 179 degrees"));
            return None;
        }
        Some(CameraSpec { position: p, look_at: t, fov_y: fov_y.to_radians() })
    }

    fn fixture(&mut self, f: &Spanned<FixtureFile>) -> Option<Built> {
        let span = f.span();
        let line = line_of(self.text, span.start);
        let f = f.get_ref();
        let id = *f.id.get_ref();
        let before = self.errors.len();
        if let Some(&(_, l)) = self.ids.iter().find(|(other, _)| *other == id) {
            self.err(f.id.span(), format!("fixture {id}: id already used on line {l}; give each fixture its own id"));
        }
        self.ids.push((id, line));
        let position = Vec3::from(*f.position.get_ref());
        if !position.is_finite() {
            self.err(f.position.span(), format!("fixture {id}: position must be three finite numbers"));
        }
        let dmx = self.dmx(f, id);
        let made = if f.kind.get_ref().trim() == "spot" {
            self.builtin(f, id, line, position)
        } else {
            self.typed(f, id, line, position)
        };
        if self.errors.len() > before {
            return None;
        }
        let made = made?;
        let light = match &made.model {
            FixtureModel::Builtin(b) => Light { position, rotation: made.rotation, beam: Beam::Spot(b.beam.clone()) },
            // Typed fixtures get their light from the look state, once the look is known.
            FixtureModel::Typed(_) => {
                Light { position, rotation: made.rotation, beam: Beam::Spot(SpotBeam::from_half_angles(0.0, 0.0)) }
            }
        };
        let fixture = Fixture {
            id,
            name: f.name.clone().unwrap_or_else(|| format!("fixture {id}")),
            light,
            dmx,
            line,
            model: made.model,
            look: FixtureState { v: made.level.unwrap_or(0.0), ..FixtureState::default() },
            position,
            cell: None,
        };
        Some(Built {
            fixture,
            address_span: f.address.as_ref().map(|a| a.span()),
            level: made.level,
            local: made.local,
        })
    }

    /// Universe and address: both or neither, each in range.
    fn dmx(&mut self, f: &FixtureFile, id: u32) -> Option<(u16, u16)> {
        match (&f.universe, &f.address) {
            (Some(u), Some(a)) => {
                let (uv, av) = (*u.get_ref(), *a.get_ref());
                let mut ok = true;
                if !(1..=MAX_UNIVERSE).contains(&uv) {
                    self.err(
                        u.span(),
                        format!("fixture {id}: universe {uv} must be in 1..{MAX_UNIVERSE} (desks count from 1)"),
                    );
                    ok = false;
                }
                if !(1..=SLOTS as i64).contains(&av) {
                    self.err(a.span(), format!("fixture {id}: address {av} must be in 1..512"));
                    ok = false;
                }
                ok.then_some((uv as u16, av as u16))
            }
            (None, None) => None,
            (Some(u), None) => {
                self.err(u.span(), format!("fixture {id}: give both universe and address, or neither"));
                None
            }
            (None, Some(a)) => {
                self.err(a.span(), format!("fixture {id}: give both universe and address, or neither"));
                None
            }
        }
    }

    /// The orientation: the light frame (beam −Z) of a conventional fixture,
    /// the body mount of a moving head (identity hangs it).
    fn orientation(&mut self, f: &FixtureFile, id: u32, line: usize, position: Vec3, head: bool) -> Quat {
        match (&f.aim, &f.rotation) {
            (Some(_), Some(r)) => {
                self.err(r.span(), format!("fixture {id}: give either aim or rotation, not both"));
                Quat::IDENTITY
            }
            (None, None) if head => Quat::IDENTITY,
            (None, None) => {
                self.err_line(line, format!("fixture {id}: needs an aim point or a rotation"));
                Quat::IDENTITY
            }
            (Some(aim_key), None) => {
                let aim = Vec3::from(*aim_key.get_ref());
                if !aim.is_finite() || aim.distance(position) < 1e-6 {
                    self.err(aim_key.span(), format!("fixture {id}: aim must be finite and differ from position"));
                    return Quat::IDENTITY;
                }
                if head {
                    mount_aimed(position, aim)
                } else {
                    Quat::from_rotation_arc(Vec3::NEG_Z, (aim - position).normalize())
                }
            }
            (None, Some(key)) => {
                let q = Quat::from_array(*key.get_ref());
                if !q.is_finite() || q.length() < 1e-6 {
                    self.err(
                        key.span(),
                        format!("fixture {id}: rotation must be a non-zero finite quaternion [x, y, z, w]"),
                    );
                    return Quat::IDENTITY;
                }
                q.normalize()
            }
        }
    }

    fn builtin(&mut self, f: &FixtureFile, id: u32, line: usize, position: Vec3) -> Option<Made> {
        let typed_only = [
            ("zoom", f.zoom.as_ref().map(|v| v.span())),
            ("focus", f.focus.as_ref().map(|v| v.span())),
            ("iris", f.iris.as_ref().map(|v| v.span())),
            ("pan", f.pan.as_ref().map(|v| v.span())),
            ("tilt", f.tilt.as_ref().map(|v| v.span())),
            ("frames", f.frames.as_ref().map(|v| v.span())),
        ];
        for (key, span) in typed_only {
            if let Some(span) = span {
                self.err(span, format!("fixture {id}: the built-in spot has no {key}; use a fixture type for it"));
            }
        }
        if let Some(m) = &f.mode
            && !m.get_ref().eq_ignore_ascii_case("dimmer")
        {
            let msg =
                format!("fixture {id}: unknown mode {:?}; the built-in spot has one mode, \"dimmer\"", m.get_ref());
            self.err(m.span(), msg);
        }
        let rotation = self.orientation(f, id, line, position, false);
        let beam_angle = f.beam_angle.as_ref().map_or(25.0, |v| *v.get_ref());
        let field = f.field_angle.as_ref().map_or(beam_angle + 10.0, |v| *v.get_ref());
        if !(beam_angle > 0.0 && beam_angle <= 360.0 && field >= beam_angle && field <= 360.0) {
            // Blame the key that is out of range (the field angle when only the pair is inconsistent).
            let beam_ok = beam_angle > 0.0 && beam_angle <= 360.0;
            let span = match (&f.beam_angle, &f.field_angle) {
                (Some(b), _) if !beam_ok => b.span(),
                (_, Some(fa)) => fa.span(),
                (Some(b), None) => b.span(),
                (None, None) => line_span(self.text, line),
            };
            self.err(
                span,
                format!(
                    "fixture {id}: beam_angle {beam_angle} and field_angle {field} \
                     must satisfy 0 < beam <= field <= 360"
                ),
            );
        }
        let Some(intensity_key) = &f.intensity else {
            self.err_line(line, format!("fixture {id}: the built-in spot needs intensity (Î in candela)"));
            return None;
        };
        let intensity = *intensity_key.get_ref();
        if !(intensity.is_finite() && intensity >= 0.0) {
            self.err(
                intensity_key.span(),
                format!("fixture {id}: intensity {intensity} cd must be a finite number >= 0"),
            );
        }
        let mut colour = Vec3::from(f.colour.as_ref().map_or([1.0; 3], |c| *c.get_ref()));
        if let Some(c) = &f.colour
            && (!colour.is_finite() || colour.min_element() < 0.0)
        {
            self.err(c.span(), format!("fixture {id}: colour must be three finite numbers >= 0"));
        }
        let level = f.level.as_ref().map_or(1.0, |l| *l.get_ref());
        if let Some(l) = &f.level
            && !(0.0..=1.0).contains(&level)
        {
            self.err(l.span(), format!("fixture {id}: level {level} must be in 0..1"));
        }
        if let Some(g) = &f.gel
            && let Some(lib) = self.gels(g.span())
        {
            match lib.find(g.get_ref()) {
                // The gel filters the stand-in colour as it filters 3200 K tungsten (c_F of eq. 4).
                Some(gid) => colour *= footlight_photometry::filter_factor(&Lamp::tungsten(), 1.0, lib.get(gid)),
                None => {
                    let p = lib.path.display().to_string();
                    self.err(g.span(), format!("fixture {id}: unknown gel {:?}; the ids are in {p}", g.get_ref()))
                }
            }
        }
        let beam = SpotBeam::from_beam_field(beam_angle, field);
        let local = vec![(level.clamp(0.0, 1.0) * 255.0).round() as u8];
        Some(Made {
            model: FixtureModel::Builtin(BuiltinSpot { beam, intensity, colour }),
            rotation,
            level: Some(level),
            local,
        })
    }

    fn typed(&mut self, f: &FixtureFile, id: u32, line: usize, position: Vec3) -> Option<Made> {
        let kind = f.kind.get_ref().trim().to_string();
        let ty = self.fixture_type(&f.kind)?;
        let builtin_only = [
            ("beam_angle", f.beam_angle.as_ref().map(|v| v.span())),
            ("field_angle", f.field_angle.as_ref().map(|v| v.span())),
            ("intensity", f.intensity.as_ref().map(|v| v.span())),
            ("colour", f.colour.as_ref().map(|v| v.span())),
            ("level", f.level.as_ref().map(|v| v.span())),
        ];
        for (key, span) in builtin_only {
            if let Some(span) = span {
                self.err(
                    span,
                    format!(
                        "fixture {id}: type {kind:?} takes {key} from its type file or the [look]; remove {key} here"
                    ),
                );
            }
        }
        let names = || ty.modes.iter().map(|m| format!("{:?}", m.name)).collect::<Vec<_>>().join(", ");
        let mode = match &f.mode {
            Some(m) => match ty.mode(m.get_ref()) {
                Some(i) => i,
                None => {
                    self.err(
                        m.span(),
                        format!("fixture {id}: type {kind:?} has no mode {:?}; its modes: {}", m.get_ref(), names()),
                    );
                    return None;
                }
            },
            None if ty.modes.len() == 1 || f.address.is_none() => 0,
            None => {
                self.err(
                    f.kind.span(),
                    format!("fixture {id}: type {kind:?} has several modes ({}); give mode = \"…\"", names()),
                );
                return None;
            }
        };
        let m = &ty.modes[mode];
        let rotation = self.orientation(f, id, line, position, ty.movement.is_some());
        let scroller_channel = m.channel(Attribute::Scroller).is_some();
        let mut scroller: Option<Scroller> = m.channel(Attribute::Scroller).and_then(|c| c.scroller.clone());
        let mut gels = None;
        if let Some(fr) = &f.frames {
            if !scroller_channel {
                self.err(
                    fr.span(),
                    format!("fixture {id}: mode {:?} has no scroller channel, so frames would never show", m.name),
                );
            } else if let Some(lib) = self.gels(fr.span()) {
                let mut frames = Vec::new();
                for n in fr.get_ref() {
                    if n.eq_ignore_ascii_case("open") {
                        frames.push(None);
                    } else if let Some(g) = lib.find(n) {
                        frames.push(Some(g));
                    } else {
                        self.err(
                            fr.span(),
                            format!("fixture {id}: unknown gel {n:?} in frames; the ids are in {}", lib.path.display()),
                        );
                    }
                }
                if frames.is_empty() {
                    self.err(
                        fr.span(),
                        format!("fixture {id}: frames must list at least one gel (\"open\" for an open frame)"),
                    );
                }
                scroller = Some(Scroller { frames });
            }
        }
        if scroller.as_ref().is_some_and(|s| s.frames.iter().any(Option::is_some)) {
            gels = self.gels(f.kind.span());
        }
        let mut gel = None;
        if let Some(g) = &f.gel {
            if scroller_channel {
                self.err(
                    g.span(),
                    format!(
                        "fixture {id}: mode {:?} has a colour scroller; give either a fixed gel or the scroller frames",
                        m.name
                    ),
                );
            } else if let Some(lib) = self.gels(g.span()) {
                match lib.find(g.get_ref()) {
                    Some(gid) => {
                        gel = Some(gid);
                        gels = Some(lib);
                    }
                    None => {
                        let p = lib.path.display().to_string();
                        self.err(g.span(), format!("fixture {id}: unknown gel {:?}; the ids are in {p}", g.get_ref()));
                    }
                }
            }
        }
        let manual = self.manual(f, id, &ty, mode);
        let mut local = vec![0u8; usize::from(m.footprint)];
        for c in &m.channels {
            for (o, v) in c.slots_for(c.default) {
                local[usize::from(o)] = v;
            }
        }
        let model = FixtureModel::Typed(TypedFixture {
            fixture_type: ty.clone(),
            mode,
            position,
            rotation,
            gel,
            scroller,
            gels,
            manual,
            breaks: Vec::new(),
        });
        Some(Made { model, rotation, level: None, local })
    }

    /// Hand-set zoom/focus/iris/pan/tilt: only for attributes the fixture has and the mode leaves off DMX.
    fn manual(&mut self, f: &FixtureFile, id: u32, ty: &FixtureType, mode: usize) -> Manual {
        let m = &ty.modes[mode];
        let spot = match &ty.optics {
            Optics::Spot(s) => Some(s.clone()),
            _ => None,
        };
        let half = |r: f32| (-r / 2.0, r / 2.0);
        let entries: [ManualEntry; 5] = [
            (
                "zoom",
                &f.zoom,
                Attribute::Zoom,
                spot.as_ref().filter(|s| s.zoom[0] != s.zoom[1]).map(|s| s.field_range()),
            ),
            ("focus", &f.focus, Attribute::Focus, (!matches!(ty.optics, Optics::Measured(_))).then_some((0.0, 1.0))),
            ("iris", &f.iris, Attribute::Iris, spot.as_ref().and_then(|s| s.iris_min).map(|lo| (lo, 1.0))),
            ("pan", &f.pan, Attribute::Pan, ty.movement.map(|mv| half(mv.pan))),
            ("tilt", &f.tilt, Attribute::Tilt, ty.movement.map(|mv| half(mv.tilt))),
        ];
        let mut out = Manual::default();
        for (key, value, attribute, range) in entries {
            let Some(v) = value else { continue };
            let x = *v.get_ref();
            let Some((lo, hi)) = range else {
                self.err(v.span(), format!("fixture {id}: type {:?} has no {key}", ty.name));
                continue;
            };
            if let Some(c) = m.channel(attribute) {
                let (name, line) = (&m.name, c.line);
                let msg = format!(
                    "fixture {id}: {key} is on DMX in mode {name:?} (type file line {line}); \
                     set it from the desk or the [look] instead"
                );
                self.err(v.span(), msg);
                continue;
            }
            if !(x.is_finite() && x >= lo && x <= hi) {
                self.err(v.span(), format!("fixture {id}: {key} {x} must be in {lo}..{hi}"));
                continue;
            }
            match attribute {
                Attribute::Zoom => out.zoom = Some(x),
                Attribute::Focus => out.focus = Some(x),
                Attribute::Iris => out.iris = Some(x),
                Attribute::Pan => out.pan = Some(x),
                _ => out.tilt = Some(x),
            }
        }
        out
    }

    /// Footprints inside the universe, and no two fixtures on one slot.
    /// One warning for the fixtures without a universe and address: a desk
    /// cannot reach them, they stay at their look.
    fn unaddressed(&mut self, built: &[Built]) {
        let none: Vec<&Fixture> = built.iter().map(|b| &b.fixture).filter(|f| f.dmx.is_none()).collect();
        let Some(first) = none.first() else { return };
        let ids: Vec<String> = none.iter().take(12).map(|f| f.id.to_string()).collect();
        let more = if none.len() > ids.len() { format!(" and {} more", none.len() - ids.len()) } else { String::new() };
        self.warnings.push(PatchError::new(
            self.path,
            first.line,
            format!(
                "warning: {} fixture(s) have no universe and address (id {}{more}): a desk cannot control \
                 them, they stay at their [look]; add `universe` and `address` to each",
                none.len(),
                ids.join(", ")
            ),
        ));
    }

    fn addresses(&mut self, built: &[Built]) {
        for (i, b) in built.iter().enumerate() {
            let Some((u, a)) = b.fixture.dmx else { continue };
            let (id, fp) = (b.fixture.id, b.fixture.footprint());
            let span = b.address_span.clone().unwrap_or(0..0);
            let end = u32::from(a) + u32::from(fp) - 1;
            if end > SLOTS as u32 {
                let last = SLOTS as u32 + 1 - u32::from(fp);
                let msg = format!(
                    "fixture {id}: its {fp} slots from address {a} run past slot 512; \
                     the last address that fits is {last}"
                );
                self.err(span.clone(), msg);
                continue;
            }
            let overlap = built[..i].iter().find(|o| match o.fixture.dmx {
                Some((ou, oa)) if ou == u => {
                    let oe = u32::from(oa) + u32::from(o.fixture.footprint()) - 1;
                    u32::from(a) <= oe && u32::from(oa) <= end
                }
                _ => false,
            });
            if let Some(o) = overlap {
                let (ou, oa) = o.fixture.dmx.unwrap_or((u, a));
                let oe = oa + o.fixture.footprint() - 1;
                let free = first_free(built, i, u, fp)
                    .map_or(format!("universe {u} has no {fp} free slots left; use another universe"), |s| {
                        format!("the first free address with {fp} slots in universe {u} is {s}")
                    });
                self.err(
                    span,
                    format!(
                        "fixture {id}: slots {a}..{end} in universe {u} overlap fixture {} \
                         (line {}, slots {oa}..{oe}); {free}",
                        o.fixture.id, o.fixture.line
                    ),
                );
                let _ = ou;
            }
        }
    }

    /// The `[look]` over the channel defaults: frames for patched universes
    /// and each fixture's default-look state and light.
    fn look(&mut self, file: &PatchFile, built: &mut [Built]) -> Universes {
        let mut raw: Vec<(u16, u16, u8)> = Vec::new();
        let mut overridden = vec![false; built.len()];
        if let Some(look) = &file.look {
            for (key, value) in look.get_ref() {
                let span = value.span();
                if key.contains('/') {
                    self.look_slots(key, value, &mut raw);
                    continue;
                }
                let Some(i) =
                    key.trim().parse::<u32>().ok().and_then(|id| built.iter().position(|b| b.fixture.id == id))
                else {
                    self.err(
                        span,
                        format!(
                            "[look] {key:?}: no fixture with that id; keys are fixture ids or \"universe/address\""
                        ),
                    );
                    continue;
                };
                let Some(table) = value.get_ref().as_table() else {
                    self.err(
                        span,
                        format!("[look] {key}: give attribute = DMX value pairs, e.g. {key} = {{ dimmer = 255 }}"),
                    );
                    continue;
                };
                for (attr, v) in table {
                    if self.look_value(&mut built[i], attr, v, span.clone()) {
                        overridden[i] = true;
                    }
                }
            }
        }
        let mut frames = Universes::new();
        for b in built.iter() {
            if let Some((u, a)) = b.fixture.dmx {
                for (o, v) in b.local.iter().enumerate() {
                    frames.set_slot(u, a + o as u16, *v);
                }
            }
        }
        for &(u, a, v) in &raw {
            frames.set_slot(u, a, v);
            for (i, b) in built.iter().enumerate() {
                if let Some((bu, ba)) = b.fixture.dmx
                    && bu == u
                    && a >= ba
                    && a < ba + b.fixture.footprint()
                {
                    overridden[i] = true;
                }
            }
        }
        for (i, b) in built.iter_mut().enumerate() {
            let f = &mut b.fixture;
            f.look = match (f.dmx.and_then(|(u, _)| frames.get(u)), &f.model) {
                // The built-in spot keeps its exact level unless the look moved its slot.
                (_, FixtureModel::Builtin(_)) if !overridden[i] => {
                    FixtureState { v: b.level.unwrap_or(1.0), ..FixtureState::default() }
                }
                (Some(slots), _) => f.decode(slots),
                (None, _) => f.decode_with(&|o| b.local.get(usize::from(o)).copied().unwrap_or(0)),
            };
            f.light = f.light_of(&f.look);
        }
        frames
    }

    /// `"U/ADDR" = value` or `= [values…]` (consecutive slots).
    fn look_slots(&mut self, key: &str, value: &Spanned<toml::Value>, raw: &mut Vec<(u16, u16, u8)>) {
        let span = value.span();
        let parsed =
            key.split_once('/').and_then(|(u, a)| Some((u.trim().parse::<i64>().ok()?, a.trim().parse::<i64>().ok()?)));
        let Some((u, a)) = parsed.filter(|(u, a)| (1..=MAX_UNIVERSE).contains(u) && (1..=SLOTS as i64).contains(a))
        else {
            self.err(
                span,
                format!(
                    "[look] {key:?}: write \"universe/address\" with universe 1..{MAX_UNIVERSE} and address 1..512"
                ),
            );
            return;
        };
        let values: Vec<Option<i64>> = match value.get_ref() {
            toml::Value::Integer(v) => vec![Some(*v)],
            toml::Value::Array(vs) => vs.iter().map(|v| v.as_integer()).collect(),
            _ => vec![None],
        };
        if values.is_empty() || values.iter().any(|v| !matches!(v, Some(0..=255))) {
            self.err(span, format!("[look] {key:?}: give a DMX value 0..255 or a list of them for consecutive slots"));
            return;
        }
        if a + values.len() as i64 - 1 > SLOTS as i64 {
            self.err(span, format!("[look] {key:?}: {} values from address {a} run past slot 512", values.len()));
            return;
        }
        for (k, v) in values.into_iter().enumerate() {
            raw.push((u as u16, a as u16 + k as u16, v.unwrap_or(0) as u8));
        }
    }

    /// One `attribute = value` of a fixture's look entry; true when applied.
    fn look_value(&mut self, b: &mut Built, attr: &str, v: &toml::Value, span: Range<usize>) -> bool {
        let id = b.fixture.id;
        let Some(value) = v.as_integer() else {
            self.err(span, format!("[look] fixture {id}: {attr} must be a whole DMX value"));
            return false;
        };
        match &b.fixture.model {
            FixtureModel::Builtin(_) => {
                if !attr.eq_ignore_ascii_case("dimmer") {
                    self.err(span, format!("[look] fixture {id}: the built-in spot has only a dimmer"));
                    return false;
                }
                if !(0..=255).contains(&value) {
                    self.err(span, format!("[look] fixture {id}: dimmer {value} must be in 0..255"));
                    return false;
                }
                b.level = Some(value as f32 / 255.0);
                b.local[0] = value as u8;
                true
            }
            FixtureModel::Typed(t) => {
                let mode = &t.fixture_type.modes[t.mode];
                let Some(c) = mode.channel_named(attr) else {
                    let has: Vec<&str> = mode
                        .channels
                        .iter()
                        .filter(|c| c.attribute != Attribute::Other)
                        .map(|c| c.name.as_str())
                        .collect();
                    let name = &mode.name;
                    let manual = ["zoom", "focus", "iris", "pan", "tilt"].contains(&attr);
                    let hint = if manual {
                        format!("; without a channel, set {attr} = … on the fixture itself")
                    } else {
                        String::new()
                    };
                    self.err(
                        span,
                        format!(
                            "[look] fixture {id}: mode {name:?} has no {attr} channel; it has {}{hint}",
                            has.join(", ")
                        ),
                    );
                    return false;
                };
                let full = i64::from(c.full_scale());
                if !(0..=full).contains(&value) {
                    let bits = if full == 255 { 8 } else { 16 };
                    self.err(
                        span,
                        format!("[look] fixture {id}: {attr} {value} must be in 0..{full} ({bits}-bit channel)"),
                    );
                    return false;
                }
                for (o, x) in c.slots_for(value as u16) {
                    b.local[usize::from(o)] = x;
                }
                true
            }
        }
    }

    fn inputs(&mut self, inputs: &[Spanned<InputFile>]) -> Vec<InputRoute> {
        let mut out: Vec<InputRoute> = Vec::new();
        for i in inputs {
            let line = line_of(self.text, i.span().start);
            let d = i.get_ref();
            let (protocol, max, min) = match d.protocol.get_ref().to_ascii_lowercase().as_str() {
                "sacn" | "e131" | "e1.31" => (InputProtocol::Sacn, 63999, 1),
                "artnet" | "art-net" => (InputProtocol::ArtNet, 32767, 0),
                "usbpro" | "usb-pro" => (InputProtocol::UsbPro, 255, 0),
                other => {
                    self.err(
                        d.protocol.span(),
                        format!("unknown input protocol {other:?}; use \"sacn\", \"artnet\" or \"usbpro\""),
                    );
                    continue;
                }
            };
            let u = *d.universe.get_ref();
            if !(min..=max).contains(&u) {
                let what = match protocol {
                    InputProtocol::Sacn => "sACN universe",
                    InputProtocol::ArtNet => "Art-Net Port-Address",
                    InputProtocol::UsbPro => "USB Pro widget index",
                };
                self.err(d.universe.span(), format!("{what} {u} must be in {min}..{max}"));
                continue;
            }
            let patch_universe = match (&d.patch_universe, d.block) {
                (Some(p), false) if (1..=MAX_UNIVERSE).contains(p.get_ref()) => Some(*p.get_ref() as u16),
                (Some(p), false) => {
                    self.err(p.span(), format!("patch_universe {} must be in 1..{MAX_UNIVERSE}", p.get_ref()));
                    continue;
                }
                (None, true) => None,
                _ => {
                    self.err_line(line, "give patch_universe = N, or block = true to ignore this input");
                    continue;
                }
            };
            if let Some(o) = out.iter().find(|o| o.protocol == protocol && o.universe == u as u16) {
                self.err(d.universe.span(), format!("this input is already routed on line {}", o.line));
                continue;
            }
            out.push(InputRoute { protocol, universe: u as u16, patch_universe, line });
        }
        out
    }
}

/// The byte range of 1-based `line` in `text` (for errors about a key that is absent).
fn line_span(text: &str, line: usize) -> Range<usize> {
    let start: usize = text.split_inclusive('\n').take(line.saturating_sub(1)).map(str::len).sum();
    start..start
}

/// A manual-value key: its name, value, attribute and allowed range (`None`: the type lacks it).
type ManualEntry<'f> = (&'static str, &'f Option<Spanned<f32>>, Attribute, Option<(f32, f32)>);

/// What building one fixture gives.
struct Made {
    model: FixtureModel,
    /// Light frame (conventional) or body mount (moving head).
    rotation: Quat,
    /// Built-in spot: its exact default level.
    level: Option<f32>,
    /// Channel defaults relative to the start address.
    local: Vec<u8>,
}

/// The first start address in universe `u` where `fp` slots are free of
/// every fixture but `skip`.
fn first_free(built: &[Built], skip: usize, u: u16, fp: u16) -> Option<u16> {
    let taken: Vec<(u16, u16)> = built
        .iter()
        .enumerate()
        .filter(|(j, _)| *j != skip)
        .filter_map(|(_, b)| match b.fixture.dmx {
            Some((bu, ba)) if bu == u => Some((ba, ba + b.fixture.footprint() - 1)),
            _ => None,
        })
        .collect();
    (1..=(SLOTS as u16 + 1).saturating_sub(fp)).find(|&s| taken.iter().all(|&(a, e)| s + fp - 1 < a || s > e))
}
