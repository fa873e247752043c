//! Reading an MVR file (MVR 1.4-1.6, DIN SPEC 15800:2022 annex): a zip with
//! `GeneralSceneDescription.xml`, the GDTF files it names and the 3D files.
//!
//! quick-xml's serde deserialiser fills plain structs (first stage); they
//! are then flattened ([`Scene`]): every fixture and scene object with its
//! layer, class, group path and **world** matrix (the product of the
//! layer's, groups' and its own `Matrix`), symbols resolved through their
//! `Symdef` (instancing, nested symbols followed to a fixed depth).
//!
//! Limits, so a hostile file costs an error or a warning, never the process
//! (issue 35): the XML nests at most [`MAX_XML_DEPTH`] elements (checked
//! before serde, which recurses once per level: a stack overflow aborts);
//! groups and nested fixtures are followed [`MAX_DEPTH`] deep, the rest
//! skipped with a warning; symbols [`MAX_DEPTH`] deep and
//! [`MAX_SYMBOL_INSTANCES`] instances per scene.
//!
//! Units and axes: MVR is millimetres, right-handed, Z up; the stage is
//! metres, Y up, +Z toward the audience. [`stage_matrix`] converts once,
//! at import: x_stage = x, y_stage = z_mvr, z_stage = −y_mvr (a −90°
//! rotation about X, so MVR's +Y upstage becomes −Z) and mm → m.

use crate::archive::Archive;
use crate::xml;
use footlight_fixture::PatchError;
use glam::{DMat3, DMat4, DQuat, DVec3};
use serde::Deserialize;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Deepest symbol/group nesting followed.
const MAX_DEPTH: usize = 32;
/// Deepest element nesting of a `GeneralSceneDescription.xml`, checked
/// before serde reads it ([`crate::xml::well_formed`]). Real files nest
/// under 50 deep (`GeneralSceneDescription/Scene/Layers/Layer/ChildList`,
/// two levels per group object, under 20 groups, then
/// `Fixture/Addresses/Address`); groups past [`MAX_DEPTH`] are skipped with
/// a warning anyway. serde recurses once per level with up to about 3 KiB
/// of stack each in a debug build (nested `Fixture`s, the largest): a 2 MiB
/// thread stack survives ~600 levels, so 128 keeps a 4× margin.
pub const MAX_XML_DEPTH: usize = 128;
/// Most symbol instances one scene expands: `Symbol`s followed plus the
/// `Geometry3D`s reached through them. Symbols nest (up to [`MAX_DEPTH`]),
/// so two symbols of the next symdef per symdef would otherwise expand to
/// 2^32 placed files from a few kilobytes; a 2,000-seat house of symbol
/// chairs with ten parts each is 22,000.
pub const MAX_SYMBOL_INSTANCES: usize = 250_000;

/// The scene of one MVR file, flattened.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// `verMajor.verMinor`.
    pub version: String,
    /// The exporting application.
    pub provider: String,
    /// Layers (name, uuid) in file order.
    pub layers: Vec<(String, String)>,
    /// Classes: uuid → name.
    pub classes: BTreeMap<String, String>,
    /// Fixtures in document order (layers, then depth-first through groups).
    pub fixtures: Vec<MvrFixture>,
    /// Scene objects, truss, supports, video screens and projectors.
    pub objects: Vec<SceneObject>,
    /// Focus points: uuid → (name, world matrix in MVR millimetres).
    pub focus_points: BTreeMap<String, (String, DMat4)>,
    /// Symbol definitions: uuid → name.
    pub symdefs: BTreeMap<String, String>,
}

/// One `<Fixture>`.
#[derive(Clone, Debug)]
pub struct MvrFixture {
    /// `name`.
    pub name: String,
    /// `uuid`.
    pub uuid: String,
    /// The layer it is in.
    pub layer: String,
    /// Group objects it is nested in, outermost first.
    pub groups: Vec<String>,
    /// Its class name (from `Classing`).
    pub class: Option<String>,
    /// `GDTFSpec`: the GDTF file name in the archive.
    pub gdtf_spec: String,
    /// `GDTFMode`.
    pub gdtf_mode: String,
    /// DMX addresses, one per break.
    pub addresses: Vec<MvrAddress>,
    /// `FixtureID` as written.
    pub fixture_id: String,
    /// `FixtureIDNumeric`.
    pub fixture_id_numeric: Option<u32>,
    /// `UnitNumber`.
    pub unit_number: Option<u32>,
    /// World matrix in MVR units (millimetres, Z up).
    pub world: DMat4,
    /// `Focus`: uuid of a focus point.
    pub focus: Option<String>,
    /// `Color`: CIE x, y, Y.
    pub color: Option<[f64; 3]>,
    /// `Gobo`: image name and rotation in degrees.
    pub gobo: Option<(String, f64)>,
    /// `CastShadow`.
    pub cast_shadow: bool,
}

/// One `<Address>`: break (0-based, as MVR writes it), universe and address (1-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MvrAddress {
    /// DMX break, 0-based (the GDTF break is this + 1).
    pub dmx_break: u16,
    /// Universe, from 1.
    pub universe: u16,
    /// Address 1-512.
    pub address: u16,
}

/// What kind of scene object.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ObjectKind {
    /// `<SceneObject>`.
    SceneObject,
    /// `<Truss>`.
    Truss,
    /// `<Support>`.
    Support,
    /// `<VideoScreen>`.
    VideoScreen,
    /// `<Projector>`.
    Projector,
}

/// A scene object with its geometry files placed in the world.
#[derive(Clone, Debug)]
pub struct SceneObject {
    /// Kind.
    pub kind: ObjectKind,
    /// `name`.
    pub name: String,
    /// `uuid`.
    pub uuid: String,
    /// Layer.
    pub layer: String,
    /// Class name.
    pub class: Option<String>,
    /// World matrix (MVR millimetres).
    pub world: DMat4,
    /// 3D files (archive entry name) with their world matrices (MVR millimetres),
    /// symbols resolved.
    pub geometries: Vec<(String, DMat4)>,
}

/// The MVR → stage transform of a world matrix: millimetres → metres, Z up → Y up.
pub fn stage_matrix(mvr: DMat4) -> DMat4 {
    let c = DMat4::from_rotation_x(-std::f64::consts::FRAC_PI_2);
    let mut m = mvr;
    m.w_axis.x /= 1000.0;
    m.w_axis.y /= 1000.0;
    m.w_axis.z /= 1000.0;
    c * m * c.inverse()
}

/// Position (metres) and orientation of an MVR world matrix in stage axes;
/// the rotation is orthonormalised (scale and shear dropped).
pub fn stage_pose(mvr: DMat4) -> (DVec3, DQuat) {
    let s = stage_matrix(mvr);
    let r = DMat3::from_mat4(s);
    let (x, y) = (r.x_axis.normalize_or(DVec3::X), r.y_axis);
    let z = x.cross(y).normalize_or(DVec3::Z);
    let y = z.cross(x);
    (s.w_axis.truncate(), DQuat::from_mat3(&DMat3::from_cols(x, y, z)).normalize())
}

/// Parses an MVR matrix `{u1,u2,u3}{v1,v2,v3}{w1,w2,w3}{o1,o2,o3}` (columns:
/// the images of the axes, then the offset in mm). `None` when malformed.
pub fn parse_matrix(text: &str) -> Option<DMat4> {
    let nums: Vec<f64> = text
        .split(['{', '}', ','])
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<f64>().ok().filter(|x| x.is_finite()))
        .collect::<Option<Vec<_>>>()?;
    if nums.len() != 12 {
        return None;
    }
    let col =
        |i: usize| glam::DVec4::new(nums[3 * i], nums[3 * i + 1], nums[3 * i + 2], if i == 3 { 1.0 } else { 0.0 });
    Some(DMat4::from_cols(col(0), col(1), col(2), col(3)))
}

// --- first stage: the XML as written ------------------------------------------

#[derive(Deserialize, Default)]
struct GsdX {
    #[serde(rename = "@verMajor", default)]
    ver_major: String,
    #[serde(rename = "@verMinor", default)]
    ver_minor: String,
    #[serde(rename = "@provider", default)]
    provider: String,
    #[serde(rename = "Scene", default)]
    scene: Option<SceneX>,
}

#[derive(Deserialize, Default)]
struct SceneX {
    #[serde(rename = "AUXData", default)]
    aux: Option<AuxX>,
    #[serde(rename = "Layers", default)]
    layers: Option<LayersX>,
}

#[derive(Deserialize, Default)]
struct AuxX {
    #[serde(rename = "Class", default)]
    classes: Vec<NamedX>,
    #[serde(rename = "Symdef", default)]
    symdefs: Vec<SymdefX>,
}

#[derive(Deserialize, Default)]
struct NamedX {
    #[serde(rename = "@name", default)]
    name: String,
    #[serde(rename = "@uuid", default)]
    uuid: String,
}

#[derive(Deserialize, Default)]
struct SymdefX {
    #[serde(rename = "@name", default)]
    name: String,
    #[serde(rename = "@uuid", default)]
    uuid: String,
    #[serde(rename = "ChildList", default)]
    child_list: Option<GeometriesX>,
}

#[derive(Deserialize, Default)]
struct LayersX {
    #[serde(rename = "Layer", default)]
    layers: Vec<LayerX>,
}

#[derive(Deserialize, Default)]
struct LayerX {
    #[serde(rename = "@name", default)]
    name: String,
    #[serde(rename = "@uuid", default)]
    uuid: String,
    #[serde(rename = "Matrix", default)]
    matrix: Option<String>,
    #[serde(rename = "ChildList", default)]
    child_list: Option<ChildListX>,
}

#[derive(Deserialize, Default)]
struct ChildListX {
    #[serde(rename = "Fixture", default)]
    fixtures: Vec<FixtureX>,
    #[serde(rename = "GroupObject", default)]
    groups: Vec<GroupX>,
    #[serde(rename = "FocusPoint", default)]
    focus_points: Vec<ObjectX>,
    #[serde(rename = "SceneObject", default)]
    scene_objects: Vec<ObjectX>,
    #[serde(rename = "Truss", default)]
    trusses: Vec<ObjectX>,
    #[serde(rename = "Support", default)]
    supports: Vec<ObjectX>,
    #[serde(rename = "VideoScreen", default)]
    screens: Vec<ObjectX>,
    #[serde(rename = "Projector", default)]
    projectors: Vec<ObjectX>,
}

#[derive(Deserialize, Default)]
struct GroupX {
    #[serde(rename = "@name", default)]
    name: String,
    #[serde(rename = "Matrix", default)]
    matrix: Option<String>,
    #[serde(rename = "ChildList", default)]
    child_list: Option<ChildListX>,
}

#[derive(Deserialize, Default)]
struct ObjectX {
    #[serde(rename = "@name", default)]
    name: String,
    #[serde(rename = "@uuid", default)]
    uuid: String,
    #[serde(rename = "Matrix", default)]
    matrix: Option<String>,
    #[serde(rename = "Classing", default)]
    classing: Option<String>,
    #[serde(rename = "Geometries", default)]
    geometries: Option<GeometriesX>,
    #[serde(rename = "ChildList", default)]
    child_list: Option<ChildListX>,
}

#[derive(Deserialize, Default)]
struct GeometriesX {
    #[serde(rename = "Geometry3D", default)]
    geometry3d: Vec<Geometry3dX>,
    #[serde(rename = "Symbol", default)]
    symbols: Vec<SymbolX>,
}

#[derive(Deserialize, Default)]
struct Geometry3dX {
    #[serde(rename = "@fileName", default)]
    file_name: String,
    #[serde(rename = "Matrix", default)]
    matrix: Option<String>,
}

#[derive(Deserialize, Default)]
struct SymbolX {
    #[serde(rename = "@symdef", default)]
    symdef: String,
    #[serde(rename = "Matrix", default)]
    matrix: Option<String>,
}

#[derive(Deserialize, Default)]
struct FixtureX {
    #[serde(rename = "@name", default)]
    name: String,
    #[serde(rename = "@uuid", default)]
    uuid: String,
    #[serde(rename = "Matrix", default)]
    matrix: Option<String>,
    #[serde(rename = "Classing", default)]
    classing: Option<String>,
    #[serde(rename = "GDTFSpec", default)]
    gdtf_spec: Option<String>,
    #[serde(rename = "GDTFMode", default)]
    gdtf_mode: Option<String>,
    #[serde(rename = "Focus", default)]
    focus: Option<String>,
    #[serde(rename = "CastShadow", default)]
    cast_shadow: Option<String>,
    #[serde(rename = "Addresses", default)]
    addresses: Option<AddressesX>,
    #[serde(rename = "FixtureID", default)]
    fixture_id: Option<String>,
    #[serde(rename = "FixtureIDNumeric", default)]
    fixture_id_numeric: Option<String>,
    #[serde(rename = "UnitNumber", default)]
    unit_number: Option<String>,
    #[serde(rename = "Color", default)]
    color: Option<String>,
    #[serde(rename = "Gobo", default)]
    gobo: Option<GoboX>,
    #[serde(rename = "ChildList", default)]
    child_list: Option<ChildListX>,
}

#[derive(Deserialize, Default)]
struct AddressesX {
    #[serde(rename = "Address", default)]
    addresses: Vec<AddressX>,
}

#[derive(Deserialize, Default)]
struct AddressX {
    #[serde(rename = "@break", default)]
    dmx_break: Option<String>,
    #[serde(rename = "$text", default)]
    text: String,
}

#[derive(Deserialize, Default)]
struct GoboX {
    #[serde(rename = "@rotation", default)]
    rotation: Option<String>,
    #[serde(rename = "$text", default)]
    text: String,
}

// --- second stage: flatten ------------------------------------------------------

/// The MVR archive and its scene.
#[derive(Clone, Debug)]
pub struct Mvr {
    /// The archive (its GDTF and 3D files).
    pub archive: Archive,
    /// The scene.
    pub scene: Scene,
    /// Problems that do not stop the import (bad matrices, addresses), at
    /// the line of the element concerned.
    pub warnings: Vec<PatchError>,
    /// How names were read that are not what the file says (a `GDTFSpec`
    /// without `.gdtf`, resolved in the archive: [`Mvr::resolve_specs`]).
    pub notes: Vec<PatchError>,
    /// Where the scene description's elements start, by `uuid` and `name`.
    pub lines: xml::LineIndex,
}

impl Mvr {
    /// Reads the MVR file at `path`.
    pub fn open(path: &std::path::Path) -> Result<Self, PatchError> {
        Self::from_archive(Archive::open(path)?)
    }

    /// Reads the scene of a checked archive.
    pub fn from_archive(archive: Archive) -> Result<Self, PatchError> {
        let label = archive.label("GeneralSceneDescription.xml");
        let Some(bytes) = archive.get("GeneralSceneDescription.xml") else {
            return Err(PatchError::new(
                &archive.path,
                0,
                "no GeneralSceneDescription.xml in the archive; not an MVR file",
            ));
        };
        let text = xml::utf8(&label, bytes)?;
        xml::well_formed(&label, text, "GeneralSceneDescription", MAX_XML_DEPTH)?;
        let gsd: GsdX = quick_xml::de::from_str(text)
            .map_err(|e| PatchError::new(&label, 0, format!("not an MVR scene description: {e}")))?;
        let lines = xml::LineIndex::new(text, &["uuid", "name"]);
        let mut b = Flatten {
            label: label.clone(),
            lines: &lines,
            out: Scene::default(),
            warnings: Vec::new(),
            symdefs: BTreeMap::new(),
            symbol_budget: MAX_SYMBOL_INSTANCES,
            warned: BTreeSet::new(),
        };
        b.out.version = format!("{}.{}", gsd.ver_major, gsd.ver_minor);
        b.out.provider = gsd.provider;
        let scene = gsd.scene.unwrap_or_default();
        if let Some(aux) = scene.aux {
            for c in aux.classes {
                b.out.classes.insert(c.uuid, c.name);
            }
            for s in aux.symdefs {
                b.out.symdefs.insert(s.uuid.clone(), s.name.clone());
                b.symdefs.insert(s.uuid, s.child_list.unwrap_or_default());
            }
        }
        for layer in scene.layers.unwrap_or_default().layers {
            b.out.layers.push((layer.name.clone(), layer.uuid.clone()));
            let m = b.matrix(layer.matrix.as_deref(), &layer.name);
            if let Some(cl) = &layer.child_list {
                b.child_list(cl, m, &layer.name, &mut Vec::new(), 0);
            }
        }
        let (scene, warnings) = (b.out, b.warnings);
        let mut mvr = Self { archive, scene, warnings, notes: Vec::new(), lines };
        mvr.resolve_specs();
        Ok(mvr)
    }

    /// Line of the `<Fixture>` (or any element) with this `uuid` in the scene description; 0 if none.
    pub fn fixture_line(&self, uuid: &str) -> usize {
        self.lines.line("Fixture", "uuid", uuid).or_else(|| self.lines.any("uuid", uuid)).unwrap_or(0)
    }

    /// Reads a `GDTFSpec` the archive does not hold as written: without its
    /// extension (`"Cluster S2"`, as some exporters write it) as the
    /// archive's `Cluster S2.gdtf`; else (with or without `.gdtf`) as the
    /// archive's GDTF whose `FixtureType` `Name` is `Cluster S2` (ASCII
    /// case ignored). [`MvrFixture::gdtf_spec`] is rewritten so every
    /// reader after this one finds the file; one note per spec, at its
    /// first fixture's line, with the fixtures it concerns. A spec found as
    /// written, or not found at all, is left as it is (a missing file is
    /// the patch's warning).
    pub fn resolve_specs(&mut self) {
        let label = self.archive.label("GeneralSceneDescription.xml");
        // FixtureType names of the archive's GDTF files, read only when needed.
        let mut names: Option<Vec<(String, String)>> = None;
        let mut resolved: BTreeMap<String, Option<(String, String)>> = BTreeMap::new();
        let mut first: BTreeMap<String, (usize, usize)> = BTreeMap::new();
        for i in 0..self.scene.fixtures.len() {
            let spec = self.scene.fixtures[i].gdtf_spec.clone();
            if spec.is_empty() || self.archive.get(&spec).is_some() {
                continue;
            }
            let found = resolved.entry(spec.clone()).or_insert_with(|| {
                let bare = match spec.len().checked_sub(5) {
                    Some(i) if spec.is_char_boundary(i) && spec[i..].eq_ignore_ascii_case(".gdtf") => &spec[..i],
                    _ => {
                        let with = format!("{spec}.gdtf");
                        if self.archive.get(&with).is_some() {
                            return Some((with, "its name with .gdtf".to_string()));
                        }
                        spec.as_str()
                    }
                };
                let names = names.get_or_insert_with(|| gdtf_type_names(&self.archive));
                names
                    .iter()
                    .find(|(_, name)| name.trim().eq_ignore_ascii_case(bare.trim()))
                    .map(|(entry, name)| (entry.clone(), format!("the GDTF whose FixtureType Name is {name:?}")))
            });
            if let Some((entry, _)) = found {
                let uuid = self.scene.fixtures[i].uuid.clone();
                let line = self.fixture_line(&uuid);
                first.entry(spec).or_insert((line, 0)).1 += 1;
                self.scene.fixtures[i].gdtf_spec = entry.clone();
            }
        }
        for (spec, (line, count)) in first {
            let Some(Some((entry, how))) = resolved.get(&spec) else { continue };
            let fixtures = crate::report::plural(count, "fixture");
            let why = if Path::new(&spec).extension().is_some_and(|e| e.eq_ignore_ascii_case("gdtf")) {
                "is not in the archive"
            } else {
                "has no .gdtf extension"
            };
            self.notes.push(PatchError::new(
                &label,
                line,
                format!("GDTFSpec {spec:?} {why}; read as {entry:?}, {how} ({fixtures})"),
            ));
        }
    }
}

/// `(entry, FixtureType Name)` of every `.gdtf` entry of an MVR archive whose
/// `description.xml` can be read (an unreadable one is skipped here; the
/// patch reports it when a fixture names it).
fn gdtf_type_names(archive: &Archive) -> Vec<(String, String)> {
    archive
        .names()
        .filter(|n| Path::new(n).extension().is_some_and(|e| e.eq_ignore_ascii_case("gdtf")))
        .filter_map(|n| {
            let inner = Archive::from_bytes(&archive.label(n), archive.get(n)?.to_vec(), Default::default()).ok()?;
            let text = std::str::from_utf8(inner.get("description.xml")?).ok()?;
            Some((n.to_string(), xml::first_attribute(text, "FixtureType", "Name")?))
        })
        .collect()
}

struct Flatten<'a> {
    label: PathBuf,
    lines: &'a xml::LineIndex,
    out: Scene,
    warnings: Vec<PatchError>,
    symdefs: BTreeMap<String, GeometriesX>,
    /// Symbol instances left to expand ([`MAX_SYMBOL_INSTANCES`]); at 0 the
    /// rest are skipped, with one warning.
    symbol_budget: usize,
    /// Keys of the warnings given once per scene (see `warn_once`).
    warned: BTreeSet<String>,
}

impl Flatten<'_> {
    fn warn(&mut self, m: String) {
        self.warnings.push(PatchError::new(&self.label, 0, m));
    }

    /// A warning at the line of the element with this `uuid` (or `name`).
    fn warn_at(&mut self, uuid: &str, name: &str, m: String) {
        let line = self.lines.any("uuid", uuid).or_else(|| self.lines.any("name", name)).unwrap_or(0);
        self.warnings.push(PatchError::new(&self.label, line, m));
    }

    fn matrix(&mut self, text: Option<&str>, owner: &str) -> DMat4 {
        match text {
            None => DMat4::IDENTITY,
            Some(t) => parse_matrix(t).unwrap_or_else(|| {
                let line = self.lines.any("name", owner).unwrap_or(0);
                let m = format!("{owner}: Matrix {t:?} is not {{u}}{{v}}{{w}}{{o}} with 12 numbers; identity used");
                self.warnings.push(PatchError::new(&self.label, line, m));
                DMat4::IDENTITY
            }),
        }
    }

    fn class(&self, uuid: &Option<String>) -> Option<String> {
        uuid.as_ref().map(|u| self.out.classes.get(u.trim()).cloned().unwrap_or_else(|| u.trim().to_string()))
    }

    fn child_list(&mut self, cl: &ChildListX, parent: DMat4, layer: &str, groups: &mut Vec<String>, depth: usize) {
        if depth > MAX_DEPTH {
            self.warn(format!("layer {layer}: groups nested deeper than {MAX_DEPTH}; the rest is skipped"));
            return;
        }
        for f in &cl.fixtures {
            let world = parent * self.matrix(f.matrix.as_deref(), &f.name);
            let fixture = self.fixture(f, world, layer, groups);
            self.out.fixtures.push(fixture);
            if let Some(kids) = &f.child_list {
                self.child_list(kids, world, layer, groups, depth + 1);
            }
        }
        for g in &cl.groups {
            let world = parent * self.matrix(g.matrix.as_deref(), &g.name);
            groups.push(g.name.clone());
            if let Some(kids) = &g.child_list {
                self.child_list(kids, world, layer, groups, depth + 1);
            }
            groups.pop();
        }
        for p in &cl.focus_points {
            let world = parent * self.matrix(p.matrix.as_deref(), &p.name);
            self.out.focus_points.insert(p.uuid.clone(), (p.name.clone(), world));
        }
        let kinds = [
            (ObjectKind::SceneObject, &cl.scene_objects),
            (ObjectKind::Truss, &cl.trusses),
            (ObjectKind::Support, &cl.supports),
            (ObjectKind::VideoScreen, &cl.screens),
            (ObjectKind::Projector, &cl.projectors),
        ];
        for (kind, list) in kinds {
            for o in list {
                let world = parent * self.matrix(o.matrix.as_deref(), &o.name);
                let mut geometries = Vec::new();
                if let Some(g) = &o.geometries {
                    self.geometries(g, world, &mut geometries, 0);
                }
                let class = self.class(&o.classing);
                self.out.objects.push(SceneObject {
                    kind,
                    name: o.name.clone(),
                    uuid: o.uuid.clone(),
                    layer: layer.to_string(),
                    class,
                    world,
                    geometries,
                });
                if let Some(kids) = &o.child_list {
                    self.child_list(kids, world, layer, groups, depth + 1);
                }
            }
        }
    }

    /// Takes one symbol instance from the budget; false (and one warning
    /// per scene) once it is spent.
    fn spend_symbol(&mut self) -> bool {
        if self.symbol_budget > 0 {
            self.symbol_budget -= 1;
            return true;
        }
        self.warn_once(
            "budget".into(),
            format!(
                "more than {MAX_SYMBOL_INSTANCES} symbol instances (Symbols followed and the Geometry3D they \
                 reach); the rest are skipped (symbols that instance each other many times over?)"
            ),
        );
        false
    }

    /// A warning given once per `key` (symbol problems repeat at every instance).
    fn warn_once(&mut self, key: String, m: String) {
        if self.warned.insert(key) {
            self.warn(m);
        }
    }

    fn geometries(&mut self, g: &GeometriesX, world: DMat4, out: &mut Vec<(String, DMat4)>, depth: usize) {
        for f in &g.geometry3d {
            // An object's own files are bounded by the file's size; those
            // reached through symbols count against the budget.
            if depth > 0 && !self.spend_symbol() {
                return;
            }
            let m = self.matrix(f.matrix.as_deref(), &f.file_name);
            out.push((f.file_name.clone(), world * m));
        }
        for s in &g.symbols {
            if !self.spend_symbol() {
                return;
            }
            let m = world * self.matrix(s.matrix.as_deref(), "Symbol");
            if depth >= MAX_DEPTH {
                self.warn_once(
                    format!("deep {}", s.symdef),
                    format!("symbol {}: symbols nested deeper than {MAX_DEPTH}; skipped", s.symdef),
                );
                continue;
            }
            match self.symdefs.remove(&s.symdef) {
                Some(def) => {
                    self.geometries(&def, m, out, depth + 1);
                    self.symdefs.insert(s.symdef.clone(), def);
                }
                None => self.warn_once(
                    format!("missing {}", s.symdef),
                    format!("Symbol names Symdef {:?}, which AUXData does not define (or a symbol loop)", s.symdef),
                ),
            }
        }
    }

    fn fixture(&mut self, f: &FixtureX, world: DMat4, layer: &str, groups: &[String]) -> MvrFixture {
        let mut addresses = Vec::new();
        for a in f.addresses.as_ref().map(|a| a.addresses.as_slice()).unwrap_or(&[]) {
            let brk = a.dmx_break.as_deref().map(str::trim).unwrap_or("0");
            let Ok(dmx_break) = brk.parse::<u16>() else {
                self.warn_at(
                    &f.uuid,
                    &f.name,
                    format!("fixture {:?}: Address break {brk:?} is not a number; ignored", f.name),
                );
                continue;
            };
            match parse_address(&a.text) {
                Some((universe, address)) => addresses.push(MvrAddress { dmx_break, universe, address }),
                None => self.warn_at(
                    &f.uuid,
                    &f.name,
                    format!(
                        "fixture {:?}: Address {:?} is neither an absolute address ((universe − 1)·512 + address) \
                         nor universe.address; ignored",
                        f.name, a.text
                    ),
                ),
            }
        }
        let num = |s: &Option<String>| s.as_deref().and_then(|t| t.trim().parse::<u32>().ok());
        let color = f.color.as_deref().and_then(|c| {
            let v: Vec<f64> = c.split(',').filter_map(|x| x.trim().parse().ok()).collect();
            (v.len() == 3 && v.iter().all(|x| x.is_finite())).then(|| [v[0], v[1], v[2]])
        });
        let gobo = f.gobo.as_ref().map(|g| {
            (g.text.trim().to_string(), g.rotation.as_deref().and_then(|r| r.trim().parse().ok()).unwrap_or(0.0))
        });
        MvrFixture {
            name: f.name.clone(),
            uuid: f.uuid.clone(),
            layer: layer.to_string(),
            groups: groups.to_vec(),
            class: self.class(&f.classing),
            gdtf_spec: f.gdtf_spec.as_deref().unwrap_or("").trim().to_string(),
            gdtf_mode: f.gdtf_mode.as_deref().unwrap_or("").trim().to_string(),
            addresses,
            fixture_id: f.fixture_id.as_deref().unwrap_or("").trim().to_string(),
            fixture_id_numeric: num(&f.fixture_id_numeric),
            unit_number: num(&f.unit_number),
            world,
            focus: f.focus.as_deref().map(|s| s.trim().to_string()),
            color,
            gobo,
            cast_shadow: f.cast_shadow.as_deref().is_some_and(|s| s.trim().eq_ignore_ascii_case("true")),
        }
    }
}

/// An MVR address: absolute `(universe − 1)·512 + address`, or `universe.address`.
pub fn parse_address(text: &str) -> Option<(u16, u16)> {
    let t = text.trim();
    let (u, a) = match t.split_once('.') {
        Some((u, a)) => (u.trim().parse::<u32>().ok()?, a.trim().parse::<u32>().ok()?),
        None => {
            let n = t.parse::<u64>().ok()?;
            if n == 0 {
                return None;
            }
            (((n - 1) / 512 + 1).try_into().ok()?, ((n - 1) % 512 + 1) as u32)
        }
    };
    if !(1..=63999).contains(&u) || !(1..=512).contains(&a) {
        return None;
    }
    Some((u as u16, a as u16))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matrices_and_axes() {
        let m = parse_matrix("{1,0,0}{0,1,0}{0,0,1}{1000,2000,7000}").unwrap();
        let s = stage_matrix(m);
        // x stays, MVR z (up) becomes stage y, MVR +y (upstage) becomes stage −z, mm → m.
        assert!((s.w_axis.truncate() - DVec3::new(1.0, 7.0, -2.0)).length() < 1e-12, "{s}");
        // A fixture rotated 90° about MVR Z turns about stage Y.
        let r = parse_matrix("{0,1,0}{-1,0,0}{0,0,1}{0,0,0}").unwrap();
        let (_, q) = stage_pose(r);
        assert!((q * DVec3::X - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12, "{q}");
        // The GDTF rest beam (−Z local) of an unrotated fixture points down on stage.
        let (_, q) = stage_pose(DMat4::IDENTITY);
        let c = DQuat::from_rotation_x(-std::f64::consts::FRAC_PI_2);
        assert!(((q * c) * DVec3::NEG_Z - DVec3::NEG_Y).length() < 1e-12);
        assert!(parse_matrix("{1,0}{0,1,0}{0,0,1}{0,0,0}").is_none());
        assert!(parse_matrix("{1,0,0}{0,1,0}{0,0,1}{0,0,nan}").is_none());
    }

    #[test]
    fn addresses() {
        assert_eq!(parse_address("1"), Some((1, 1)));
        assert_eq!(parse_address("513"), Some((2, 1)));
        assert_eq!(parse_address("1024"), Some((2, 512)));
        assert_eq!(parse_address("3.17"), Some((3, 17)));
        assert_eq!(parse_address("0"), None);
        assert_eq!(parse_address("1.513"), None);
        assert_eq!(parse_address("x"), None);
    }
}
