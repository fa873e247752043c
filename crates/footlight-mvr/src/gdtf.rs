//! Reading a GDTF file (GDTF 1.0-1.2, DIN SPEC 15800:2022): `description.xml`
//! in a zip, with the wheel images in `wheels/`.
//!
//! The `gdtf` crate (0.3, MIT) deserialises `description.xml` into an object
//! model that follows the 1.2 schema closely (attribute definitions, wheels
//! with slots and prism facets, physical descriptions with emitters,
//! filters, measurements and DMX profiles, models, the geometry tree with
//! every 1.2 geometry kind, DMX modes, relations, macros); this module
//! checks the archive ([`crate::archive`]) and the XML ([`crate::xml`],
//! for line and column) first, and then expands one DMX mode the way a
//! desk patches it ([`Gdtf::layout`]):
//!
//! * the geometry tree is walked **from the mode's `Geometry` attribute, by
//!   reference**, never by names like Base/Yoke/Head; a `GeometryReference`
//!   instantiates its top-level geometry again (a pixel cell), with its own
//!   position and DMX offsets;
//! * every `DMXChannel` is bound to the geometry instances it names: once in
//!   the plain tree, once per `GeometryReference` whose referenced subtree
//!   holds it, shifted by the reference's `Break` (`DMXOffset − 1` for the
//!   channel's break, or the last break for `DMXBreak="Overwrite"`);
//! * channel functions get their DMX range, physical range, wheel, emitter,
//!   filter, mode master, DMX profile and channel sets. A function's range
//!   runs from its `DMXFrom` to the next `DMXFrom − 1` **among the functions
//!   of its logical channel under the same mode master** (`ModeMaster`,
//!   `ModeFrom`, `ModeTo`: functions of different modes overlap, each mode
//!   tiling the channel), as pygdtf computes it; the mode master's range is
//!   read at the master channel's resolution.
//!
//! Two things the `gdtf` crate does not give are filled in here: its
//! `Matrix` has no accessor (it is read back through its own serialiser,
//! [`matrix`]), and `DmxValue::to` can shift by more than 63 bits on a
//! hostile `N/255` value (so [`dmx`] rescales with checked shifts).

use crate::archive::Archive;
use crate::xml;
use footlight_fixture::PatchError;
use gdtf::dmx_mode::{DmxBreak, DmxChannel, DmxMode, ModeMaster};
use gdtf::geometry::AnyGeometry;
use gdtf::geometry::{BeamGeometry, Geometry};
use gdtf::values::{DmxValue, Matrix};
use glam::{DMat4, DVec4};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub use gdtf::geometry::{BeamType, LampType};

/// Deepest geometry nesting followed (GeometryReferences included).
const MAX_DEPTH: usize = 32;
/// Deepest element nesting of a `description.xml`, checked before the `gdtf`
/// crate parses it ([`crate::xml::well_formed`]). Real files nest about 15
/// deep (`GDTF/FixtureType/Geometries` + a geometry tree under 10 deep, or
/// `DMXModes/…/ChannelSet` at 9). The crate recurses once per geometry level
/// with about 7 KiB of stack each in a debug build: a 2 MiB thread stack
/// (a tokio blocking thread: `footlight run` loads there) survives ~250
/// levels, so 64 keeps a 4× margin.
pub const MAX_XML_DEPTH: usize = 64;
/// Most geometry instances one mode may expand to.
const MAX_NODES: usize = 100_000;
/// Most channel instances one mode may bind (a channel on a referenced
/// geometry counts once per reference): 128 DMX breaks of 512 slots.
pub const MAX_CHANNELS: usize = 128 * 512;

/// One parsed GDTF file.
#[derive(Clone, Debug)]
pub struct Gdtf {
    /// The file (or `show.mvr/x.gdtf` inside an MVR), for messages.
    pub label: PathBuf,
    /// `DataVersion` of the `<GDTF>` root (e.g. "1.2").
    pub data_version: String,
    /// The fixture type as the `gdtf` crate reads it.
    pub ft: gdtf::fixture_type::FixtureType,
    /// The archive's files under `wheels/` (gobo and colour-slot images), by entry name.
    media: BTreeMap<String, Vec<u8>>,
    /// The archive's 3D model files under `models/` (glb, 3ds), by entry name.
    model_files: BTreeMap<String, Vec<u8>>,
    /// Where named elements of `description.xml` start (for the line of a warning).
    pub lines: xml::LineIndex,
}

/// A `<Model>` of the fixture type (issue 14 item 5: fixture bodies).
#[derive(Clone, Debug, PartialEq)]
pub struct ModelInfo {
    /// `Name`.
    pub name: String,
    /// `Length` (along the geometry's X), `Width` (Y), `Height` (Z), metres.
    pub dimensions: [f64; 3],
    /// `PrimitiveType` as written in the file (`Cube`, `Cylinder`, `Base`…).
    pub primitive: String,
    /// `File`: the model file's name, without folder and extension.
    pub file: Option<String>,
}

/// Largest model side drawn, metres (a model larger than a stage is a broken file).
pub const MAX_MODEL_SIZE: f64 = 1000.0;

impl ModelInfo {
    /// The dimensions to draw: each side as written when it is a finite
    /// size from 0 to [`MAX_MODEL_SIZE`] m, else 0 (NaN, infinite or
    /// negative: that side is drawn flat).
    pub fn drawn_dimensions(&self) -> [f64; 3] {
        self.dimensions.map(|d| if (0.0..=MAX_MODEL_SIZE).contains(&d) { d } else { 0.0 })
    }

    /// What is wrong with the dimensions (`Length NaN, Height -0.4`), if anything.
    pub fn bad_dimensions(&self) -> Option<String> {
        let bad: Vec<String> = ["Length", "Width", "Height"]
            .iter()
            .zip(self.dimensions)
            .filter(|(_, d)| !(0.0..=MAX_MODEL_SIZE).contains(d))
            .map(|(n, d)| format!("{n} {d}"))
            .collect();
        (!bad.is_empty()).then(|| bad.join(", "))
    }

    /// The warning for [`ModelInfo::bad_dimensions`], naming the model.
    pub fn dimension_warning(&self) -> Option<String> {
        self.bad_dimensions().map(|bad| {
            format!(
                "model {:?}: {bad} is not a size from 0 to {MAX_MODEL_SIZE} m; drawn as 0 there \
                 (the fixture body is estimated)",
                self.name
            )
        })
    }
}

/// A model's 3D file from the GDTF archive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// `models/gltf/<File>.glb` (glTF 2.0 binary; glTF axes, Y up).
    Glb,
    /// `models/3ds/<File>.3ds` (Z up).
    Max3ds,
}

/// A DMX mode expanded to its geometry instances and patched channels.
#[derive(Clone, Debug)]
pub struct Layout {
    /// The mode's name.
    pub mode: String,
    /// The geometry tree from the mode's root geometry, references instantiated.
    pub root: GeometryNode,
    /// Channels in file order; a channel on a referenced geometry appears once per reference.
    pub channels: Vec<ChannelInfo>,
    /// Slots used per DMX break (break number → highest offset).
    pub footprints: BTreeMap<u16, u16>,
    /// Relations (virtual dimmers and overrides) as written.
    pub relations: Vec<RelationInfo>,
}

/// One geometry instance.
#[derive(Clone, Debug)]
pub struct GeometryNode {
    /// Instance name: the geometry's name, or `Reference` / `Reference.Child`
    /// inside a GeometryReference.
    pub name: String,
    /// The geometry's own name in the file (the template name inside a reference).
    pub template: String,
    /// What kind of geometry it is.
    pub kind: GeometryKind,
    /// Transform from this geometry to the fixture (GDTF axes: metres, Z up).
    pub to_fixture: DMat4,
    /// The geometry's `Model`, if any.
    pub model: Option<String>,
    /// Child instances.
    pub children: Vec<GeometryNode>,
}

/// The GDTF geometry kinds Footlight distinguishes.
#[derive(Clone, Debug, PartialEq)]
pub enum GeometryKind {
    /// `<Geometry>`.
    Generic,
    /// `<Axis>`: pan or tilt rotates about it.
    Axis,
    /// `<Beam>`: a light source.
    Beam(BeamInfo),
    /// `<FilterBeam>`.
    FilterBeam,
    /// `<FilterColor>`.
    FilterColor,
    /// `<FilterGobo>`.
    FilterGobo,
    /// `<FilterShaper>`.
    FilterShaper,
    /// `<GeometryReference>` to a top-level geometry (its instance is the only child).
    Reference(String),
    /// Any other kind (media server, laser, wiring, structure…), by element name.
    Other(&'static str),
}

/// A `<Beam>` geometry's photometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamInfo {
    /// Wash, Spot, None, Rectangle, PC, Fresnel or Glow.
    pub beam_type: BeamType,
    /// Discharge, Tungsten, Halogen or LED.
    pub lamp_type: LampType,
    /// Power consumption, W.
    pub power_w: f64,
    /// Luminous flux of the beam, lm.
    pub flux_lm: f64,
    /// Colour temperature, K.
    pub cct_k: f64,
    /// Full angle at 50 % of peak, degrees.
    pub beam_angle: f64,
    /// Full angle at 10 % of peak, degrees.
    pub field_angle: f64,
    /// Radius of the light output, m.
    pub beam_radius_m: f64,
    /// Colour rendering index.
    pub cri: u32,
}

/// One DMX channel of a mode, bound to a geometry instance.
#[derive(Clone, Debug)]
pub struct ChannelInfo {
    /// The geometry instance it controls.
    pub geometry: String,
    /// The geometry named in the file.
    pub template: String,
    /// Attribute of the first logical channel (e.g. "Pan", "ColorAdd_R").
    pub attribute: String,
    /// DMX break (1-based).
    pub dmx_break: u16,
    /// Slots from the break's start address, 1-based, coarse first; empty for a virtual channel.
    pub offsets: Vec<u16>,
    /// Default raw value at the channel's resolution (from its initial function).
    pub default: u64,
    /// Channel functions of all logical channels, in file order.
    pub functions: Vec<FunctionInfo>,
}

impl ChannelInfo {
    /// Bytes of resolution (1 = 8-bit, 2 = 16-bit, 3 = 24-bit); 0 for a virtual channel.
    pub fn bytes(&self) -> u8 {
        self.offsets.len().min(4) as u8
    }

    /// Largest raw value at the channel's resolution.
    pub fn max(&self) -> u64 {
        max_raw(self.bytes().max(1))
    }
}

/// One channel function, its DMX range resolved.
#[derive(Clone, Debug)]
pub struct FunctionInfo {
    /// Its name.
    pub name: String,
    /// The attribute it controls.
    pub attribute: String,
    /// First raw DMX value (the channel's resolution).
    pub dmx_from: u64,
    /// Last raw DMX value.
    pub dmx_to: u64,
    /// Physical value at `dmx_from`.
    pub physical_from: f64,
    /// Physical value at `dmx_to`.
    pub physical_to: f64,
    /// Linked wheel.
    pub wheel: Option<String>,
    /// Linked emitter.
    pub emitter: Option<String>,
    /// Linked filter.
    pub filter: Option<String>,
    /// Linked DMX profile.
    pub dmx_profile: Option<String>,
    /// Mode master: the master's node text (a DMX channel, `Geometry_Attribute`,
    /// or a channel function below it) and the raw range of the master
    /// channel that selects this function, at the master's resolution.
    pub mode_master: Option<(String, u64, u64)>,
    /// Channel sets, DMX ranges resolved.
    pub sets: Vec<SetInfo>,
}

/// One channel set.
#[derive(Clone, Debug)]
pub struct SetInfo {
    /// Its name.
    pub name: String,
    /// First raw DMX value.
    pub dmx_from: u64,
    /// Last raw DMX value.
    pub dmx_to: u64,
    /// Wheel slot index as the file writes it (1-based; the `gdtf` crate stores it 0-based).
    pub wheel_slot: Option<i32>,
}

/// A relation between two channels.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RelationInfo {
    /// Its name.
    pub name: String,
    /// Master channel (node text).
    pub master: String,
    /// Follower channel function (node text).
    pub follower: String,
    /// "Multiply" (virtual dimmer) or "Override".
    pub kind: String,
}

impl Gdtf {
    /// Reads the GDTF file at `path`.
    pub fn open(path: &Path) -> Result<Self, PatchError> {
        let archive = Archive::open(path)?;
        Self::from_archive(&archive)
    }

    /// Reads a GDTF held in memory; `label` names it in messages.
    pub fn from_bytes(label: &Path, bytes: Vec<u8>) -> Result<Self, PatchError> {
        let archive = Archive::from_bytes(label, bytes, Default::default())?;
        Self::from_archive(&archive)
    }

    /// Reads a GDTF from a checked archive.
    pub fn from_archive(archive: &Archive) -> Result<Self, PatchError> {
        let label = archive.path.clone();
        let Some(bytes) = archive.get("description.xml") else {
            return Err(PatchError::new(&label, 0, "no description.xml in the archive; not a GDTF file"));
        };
        let desc_label = archive.label("description.xml");
        let text = xml::utf8(&desc_label, bytes)?;
        xml::well_formed(&desc_label, text, "GDTF", MAX_XML_DEPTH)?;
        let description = gdtf::Description::from_reader(text.as_bytes())
            .map_err(|e| PatchError::new(&desc_label, 0, format!("not a GDTF description: {e}")))?;
        let data_version = format!("{}.{}", description.data_version.major, description.data_version.minor);
        let Some(ft) = description.fixture_types.into_iter().next() else {
            return Err(PatchError::new(&desc_label, 0, "no <FixtureType> in the description"));
        };
        let media = archive
            .names()
            .filter(|n| n.starts_with("wheels/"))
            .filter_map(|n| archive.get(n).map(|d| (n.to_string(), d.to_vec())))
            .collect();
        let model_files = archive
            .names()
            .filter(|n| n.starts_with("models/"))
            .filter_map(|n| archive.get(n).map(|d| (n.to_string(), d.to_vec())))
            .collect();
        let lines = xml::LineIndex::new(text, &["Name", "Attribute", "MediaFileName"]);
        Ok(Self { label, data_version, ft, media, model_files, lines })
    }

    /// `description.xml` of this file, as warnings name it.
    pub fn description_label(&self) -> PathBuf {
        self.label.join("description.xml")
    }

    /// Line of the `<FixtureType>` element (a warning about the whole type).
    pub fn type_line(&self) -> usize {
        self.lines.element("FixtureType").unwrap_or(0)
    }

    /// Line where attribute `attribute` is used: its first `<LogicalChannel
    /// Attribute=…>`, else its first `<ChannelFunction Attribute=…>`, else its
    /// `<Attribute Name=…>` definition, else the fixture type's.
    pub fn attribute_line(&self, attribute: &str) -> usize {
        self.lines
            .line("LogicalChannel", "Attribute", attribute)
            .or_else(|| self.lines.line("ChannelFunction", "Attribute", attribute))
            .or_else(|| self.lines.line("Attribute", "Name", attribute))
            .unwrap_or_else(|| self.type_line())
    }

    /// Line of the first `<element Name="name">` (`DMXMode`, `Wheel`, `Model`,
    /// `Beam`…), else the fixture type's.
    pub fn named_line(&self, element: &str, name: &str) -> usize {
        self.lines.line(element, "Name", name).unwrap_or_else(|| self.type_line())
    }

    /// Gives a line to warnings about this file that have none (line 0), from
    /// what they name: `Attr: …` (an attribute's channel), `mode "M"`,
    /// `wheel "W"`, `model "X"`, `gobo image "I"`, else the first word that
    /// is a channel's attribute; else the fixture type's line.
    pub fn locate(&self, warnings: &mut [PatchError]) {
        let label = self.description_label();
        for w in warnings.iter_mut().filter(|w| w.line == 0 && (w.path == label || w.path == self.label)) {
            w.path = label.clone();
            w.line = self.line_named_in(&w.message);
        }
    }

    fn line_named_in(&self, message: &str) -> usize {
        let quoted = |after: &str| {
            let rest = message.split(after).nth(1)?.strip_prefix('"')?;
            rest.split('"').next()
        };
        if let Some((head, _)) = message.split_once(": ")
            && !head.contains(' ')
            && let Some(line) = self
                .lines
                .line("LogicalChannel", "Attribute", head)
                .or_else(|| self.lines.line("Attribute", "Name", head))
        {
            return line;
        }
        let kinds = [("mode ", "DMXMode"), ("wheel ", "Wheel"), ("model ", "Model"), ("beam ", "Beam")];
        for (word, element) in kinds {
            if let Some(line) = quoted(word).and_then(|n| self.lines.line(element, "Name", n)) {
                return line;
            }
        }
        if let Some(line) = quoted("image ").and_then(|n| self.lines.line("Slot", "MediaFileName", n)) {
            return line;
        }
        // Else the first word that is an attribute with a channel (`ColorAdd_R/G/B/W: …`).
        message
            .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .find_map(|word| self.lines.line("LogicalChannel", "Attribute", word))
            .unwrap_or_else(|| self.type_line())
    }

    /// The fixture type's name (`Name`, else `ShortName`).
    pub fn name(&self) -> String {
        self.ft.name.as_deref().map(str::to_string).unwrap_or_else(|| self.ft.short_name.clone())
    }

    /// Names of the DMX modes, in file order.
    pub fn mode_names(&self) -> Vec<String> {
        self.ft.dmx_modes.iter().map(|m| m.name.as_deref().unwrap_or("").to_string()).collect()
    }

    /// The DMX mode named `name` (exact, then ignoring ASCII case).
    pub fn mode(&self, name: &str) -> Option<&DmxMode> {
        let named = |m: &&DmxMode| m.name.as_deref() == Some(name);
        let loose = |m: &&DmxMode| m.name.as_deref().is_some_and(|n| n.eq_ignore_ascii_case(name));
        self.ft.dmx_modes.iter().find(named).or_else(|| self.ft.dmx_modes.iter().find(loose))
    }

    /// A wheel image by its `MediaFileName` (`wheels/<name>.png`, `.jpg`,
    /// `.jpeg`, or the name with its extension).
    pub fn wheel_image(&self, media_name: &str) -> Option<&[u8]> {
        let candidates = [
            format!("wheels/{media_name}.png"),
            format!("wheels/{media_name}.jpg"),
            format!("wheels/{media_name}.jpeg"),
            format!("wheels/{media_name}"),
        ];
        candidates
            .iter()
            .find_map(|c| {
                self.media.get(c).or_else(|| self.media.iter().find(|(k, _)| k.eq_ignore_ascii_case(c)).map(|(_, v)| v))
            })
            .map(Vec::as_slice)
    }

    /// The `<Model>` named `name`.
    pub fn model(&self, name: &str) -> Option<ModelInfo> {
        let m = self.ft.models.iter().find(|m| m.name.as_deref() == Some(name))?;
        Some(ModelInfo {
            name: name.to_string(),
            dimensions: [m.length, m.width, m.height],
            primitive: format!("{:?}", m.primitive_type),
            file: m.file.clone(),
        })
    }

    /// One warning per `<Model>` whose `Length`, `Width` or `Height` is
    /// not a finite size from 0 to [`MAX_MODEL_SIZE`] m, naming the file and the model.
    pub fn model_warnings(&self) -> Vec<PatchError> {
        let label = self.label.join("description.xml");
        self.ft
            .models
            .iter()
            .filter_map(|m| self.model(m.name.as_deref()?))
            .filter_map(|m| Some((self.named_line("Model", &m.name), m.dimension_warning()?)))
            .map(|(line, w)| PatchError::new(&label, line, w))
            .collect()
    }

    /// A model's 3D file: `models/gltf/<file>.glb` first, else
    /// `models/3ds/<file>.3ds` (GDTF 1.2 "Model"; exact name, then ignoring
    /// ASCII case). `None` when the archive holds neither.
    pub fn model_mesh(&self, file: &str) -> Option<(MeshFormat, &str, &[u8])> {
        let candidates = [
            (MeshFormat::Glb, format!("models/gltf/{file}.glb")),
            (MeshFormat::Max3ds, format!("models/3ds/{file}.3ds")),
        ];
        candidates.iter().find_map(|(format, c)| {
            self.model_files
                .get_key_value(c.as_str())
                .or_else(|| self.model_files.iter().find(|(k, _)| k.eq_ignore_ascii_case(c)))
                .map(|(k, v)| (*format, k.as_str(), v.as_slice()))
        })
    }

    /// Number of slots of the wheel named `name`.
    pub fn wheel_slots(&self, name: &str) -> Option<usize> {
        self.ft.wheels.iter().find(|w| w.name.as_deref() == Some(name)).map(|w| w.slots.len())
    }

    /// Expands the DMX mode `mode` (see the module doc).
    pub fn layout(&self, mode: &str) -> Result<Layout, PatchError> {
        let Some(m) = self.mode(mode) else {
            let line = self.lines.element("DMXModes").unwrap_or_else(|| self.type_line());
            return Err(PatchError::new(
                &self.description_label(),
                line,
                format!("no DMX mode {mode:?}; the modes are {:?}", self.mode_names()),
            ));
        };
        let mode_line = self.named_line("DMXMode", m.name.as_deref().unwrap_or(""));
        let at = |m: String| PatchError::new(&self.label.join("description.xml"), mode_line, m);
        let mode_name = m.name.as_deref().unwrap_or("").to_string();
        let root_name = m.geometry.as_deref().unwrap_or("");
        let root = self.ft.root_geometry(root_name).or(match self.ft.geometries.as_slice() {
            [only] => Some(only),
            _ => None,
        });
        let Some(root) = root else {
            return Err(at(format!(
                "DMX mode {mode_name:?} names geometry {root_name:?}, which is not a top-level geometry"
            )));
        };
        let mut count = 0usize;
        let tree = self.instantiate(root, DMat4::IDENTITY, None, 0, &mut count).map_err(at)?;
        // Where each file geometry occurs: (instance name, the breaks of the reference it sits in).
        let mut occurrences: Occurrences = BTreeMap::new();
        collect(&tree, None, &reference_breaks(&self.ft), &mut occurrences);
        // Each DMX channel is bound once per instance of its geometry: count
        // before building (references multiply channels).
        let instances: usize =
            m.dmx_channels.iter().map(|c| occurrences.get(&c.geometry.to_string()).map_or(1, Vec::len)).sum();
        if instances > MAX_CHANNELS {
            return Err(at(format!(
                "DMX mode {mode_name:?} binds {instances} channel instances (its channels times the \
                 references to their geometries), more than {MAX_CHANNELS}"
            )));
        }
        let mut channels = Vec::new();
        for c in &m.dmx_channels {
            let template = c.geometry.to_string();
            let places = occurrences.get(&template).cloned().unwrap_or_else(|| vec![(template.clone(), None)]);
            for (instance, breaks) in places {
                channels.push(channel(c, &template, &instance, breaks.as_deref(), m));
            }
        }
        let mut footprints = BTreeMap::new();
        for c in &channels {
            if let Some(&hi) = c.offsets.iter().max() {
                let e = footprints.entry(c.dmx_break).or_insert(0u16);
                *e = (*e).max(hi);
            }
        }
        let relations = m
            .relations
            .iter()
            .map(|r| RelationInfo {
                name: r.name.as_deref().unwrap_or("").to_string(),
                master: r.master.to_string(),
                follower: r.follower.to_string(),
                kind: format!("{:?}", r.type_),
            })
            .collect();
        Ok(Layout { mode: mode_name, root: tree, channels, footprints, relations })
    }

    fn instantiate(
        &self,
        g: &Geometry,
        parent: DMat4,
        prefix: Option<&str>,
        depth: usize,
        count: &mut usize,
    ) -> Result<GeometryNode, String> {
        *count += 1;
        if depth > MAX_DEPTH || *count > MAX_NODES {
            return Err(format!(
                "the geometry tree is deeper than {MAX_DEPTH} or larger than {MAX_NODES} instances (a reference loop?)"
            ));
        }
        let template = g.name().map(|n| n.to_string()).unwrap_or_default();
        let name = match prefix {
            Some(p) => format!("{p}.{template}"),
            None => template.clone(),
        };
        let to_fixture = parent * position(g).map(matrix).unwrap_or(DMat4::IDENTITY);
        let model = g.model_name().map(|n| n.to_string());
        let (kind, children) = match g {
            Geometry::Reference(r) => {
                let target = r.geometry.as_deref().unwrap_or("");
                let Some(top) = self.ft.root_geometry(target) else {
                    return Err(format!("GeometryReference {template:?} names {target:?}, not a top-level geometry"));
                };
                // The referenced geometry's own position is replaced by the reference's.
                let base = to_fixture * position(top).map(matrix).unwrap_or(DMat4::IDENTITY).inverse();
                let mut inner = self.instantiate(top, base, Some(&template), depth + 1, count)?;
                inner.name = template.clone();
                (GeometryKind::Reference(target.to_string()), vec![inner])
            }
            _ => {
                let mut kids = Vec::new();
                for c in g.children() {
                    kids.push(self.instantiate(c, to_fixture, prefix, depth + 1, count)?);
                }
                (kind_of(g), kids)
            }
        };
        Ok(GeometryNode { name, template, kind, to_fixture, model, children })
    }
}

fn kind_of(g: &Geometry) -> GeometryKind {
    match g {
        Geometry::Generic(_) => GeometryKind::Generic,
        Geometry::Axis(_) => GeometryKind::Axis,
        Geometry::Beam(b) => GeometryKind::Beam(beam_info(b)),
        Geometry::FilterBeam(_) => GeometryKind::FilterBeam,
        Geometry::FilterColor(_) => GeometryKind::FilterColor,
        Geometry::FilterGobo(_) => GeometryKind::FilterGobo,
        Geometry::FilterShaper(_) => GeometryKind::FilterShaper,
        Geometry::Reference(_) => GeometryKind::Reference(String::new()),
        Geometry::MediaServerLayer(_) => GeometryKind::Other("MediaServerLayer"),
        Geometry::MediaServerCamera(_) => GeometryKind::Other("MediaServerCamera"),
        Geometry::MediaServerMaster(_) => GeometryKind::Other("MediaServerMaster"),
        Geometry::Display(_) => GeometryKind::Other("Display"),
        Geometry::Laser(_) => GeometryKind::Other("Laser"),
        Geometry::WiringObject(_) => GeometryKind::Other("WiringObject"),
        Geometry::Inventory(_) => GeometryKind::Other("Inventory"),
        Geometry::Structure(_) => GeometryKind::Other("Structure"),
        Geometry::Support(_) => GeometryKind::Other("Support"),
        Geometry::Magnet(_) => GeometryKind::Other("Magnet"),
    }
}

fn beam_info(b: &BeamGeometry) -> BeamInfo {
    BeamInfo {
        beam_type: b.beam_type,
        lamp_type: b.lamp_type,
        power_w: b.power_consumption,
        flux_lm: b.luminous_flux,
        cct_k: b.color_temperature,
        beam_angle: b.beam_angle,
        field_angle: b.field_angle,
        beam_radius_m: b.beam_radius,
        cri: b.color_rendering_index,
    }
}

fn position(g: &Geometry) -> Option<&Matrix> {
    Some(match g {
        Geometry::Generic(x) => &x.position,
        Geometry::Axis(x) => &x.position,
        Geometry::FilterBeam(x) => &x.position,
        Geometry::FilterColor(x) => &x.position,
        Geometry::FilterGobo(x) => &x.position,
        Geometry::FilterShaper(x) => &x.position,
        Geometry::Beam(x) => &x.position,
        Geometry::MediaServerLayer(x) => &x.position,
        Geometry::MediaServerCamera(x) => &x.position,
        Geometry::MediaServerMaster(x) => &x.position,
        Geometry::Display(x) => &x.position,
        Geometry::Reference(x) => &x.position,
        Geometry::Laser(x) => &x.position,
        Geometry::WiringObject(x) => &x.position,
        Geometry::Inventory(x) => &x.position,
        Geometry::Structure(x) => &x.position,
        Geometry::Support(x) => &x.position,
        Geometry::Magnet(x) => &x.position,
    })
}

/// A GDTF `Matrix` (`{u1,v1,w1,o1}{u2,v2,w2,o2}{u3,v3,w3,o3}{0,0,0,1}`: rows,
/// translation in the fourth column, metres) as a glam matrix. The `gdtf`
/// crate keeps the numbers private, so they are read back from its own
/// serialiser; a non-finite result is the identity.
pub fn matrix(m: &Matrix) -> DMat4 {
    let text = quick_xml::se::to_string_with_root("m", m).unwrap_or_default();
    let inner = text.trim_start_matches("<m>").trim_end_matches("</m>");
    let nums: Vec<f64> =
        inner.split(['{', '}', ',']).filter(|s| !s.trim().is_empty()).filter_map(|s| s.trim().parse().ok()).collect();
    if nums.len() != 16 || nums.iter().any(|x| !x.is_finite()) {
        return DMat4::IDENTITY;
    }
    let row = |r: usize| DVec4::new(nums[4 * r], nums[4 * r + 1], nums[4 * r + 2], nums[4 * r + 3]);
    DMat4::from_cols(row(0), row(1), row(2), row(3)).transpose()
}

/// Largest raw value of a `bytes`-byte channel.
pub fn max_raw(bytes: u8) -> u64 {
    if bytes >= 8 { u64::MAX } else { (1u64 << (8 * u32::from(bytes))) - 1 }
}

/// A `DmxValue` at `bytes` bytes of resolution: a wider value keeps its top
/// bytes, a narrower one is scaled up by repeating its bytes (GDTF's
/// non-shifting rule: 255/1 is 65535/2) or by shifting (`…/Ns` values).
pub fn dmx(v: DmxValue, bytes: u8) -> u64 {
    let (mine, value) = (u32::from(v.bytes().get()), v.value());
    let want = u32::from(bytes.clamp(1, 8));
    if mine == want {
        return value.min(max_raw(want as u8));
    }
    if mine > want {
        let shift = 8 * (mine - want);
        return value.checked_shr(shift).unwrap_or(0).min(max_raw(want as u8));
    }
    let shift = 8 * (want - mine);
    let mut out = value.checked_shl(shift).unwrap_or(0);
    if !v.shifting() {
        let mut s = shift as i64 - 8 * mine as i64;
        while s > -(8 * mine as i64) {
            out |= if s >= 0 { value.checked_shl(s as u32).unwrap_or(0) } else { value >> ((-s) as u32).min(63) };
            s -= 8 * mine as i64;
        }
    }
    out.min(max_raw(want as u8))
}

/// File geometry name → its instances and the `(DMXBreak, DMXOffset)`
/// pairs of the reference each sits in (`None` outside references).
type Occurrences = BTreeMap<String, Vec<(String, Option<Vec<(u16, u16)>>)>>;

/// Records, for each file geometry name, the instances it has and the
/// breaks of the reference they sit in (`refs`: [`reference_breaks`]).
fn collect(node: &GeometryNode, breaks: Option<&[(u16, u16)]>, refs: &ReferenceBreaks, out: &mut Occurrences) {
    if let GeometryKind::Reference(_) = node.kind {
        let own = refs.get(node.template.as_str()).cloned().unwrap_or_default();
        for c in &node.children {
            // The referenced root is bound under the reference's name (pygdtf does the same).
            out.entry(c.template.clone()).or_default().push((node.name.clone(), Some(own.clone())));
            for gc in &c.children {
                collect(gc, Some(&own), refs, out);
            }
        }
        return;
    }
    out.entry(node.template.clone()).or_default().push((node.name.clone(), breaks.map(<[_]>::to_vec)));
    for c in &node.children {
        collect(c, breaks, refs, out);
    }
}

/// GeometryReference name → its `(DMXBreak, DMXOffset)` pairs.
type ReferenceBreaks<'a> = BTreeMap<&'a str, Vec<(u16, u16)>>;

/// The `(DMXBreak, DMXOffset)` pairs of every GeometryReference in the
/// file, by name (the first in document order wins a repeated name). Made
/// once per layout, without recursion: a lookup per reference instance
/// used to walk the whole tree again (quadratic in a big pixel matrix).
fn reference_breaks(ft: &gdtf::fixture_type::FixtureType) -> ReferenceBreaks<'_> {
    let mut out = BTreeMap::new();
    let mut stack: Vec<&Geometry> = ft.geometries.iter().rev().collect();
    while let Some(g) = stack.pop() {
        if let Geometry::Reference(r) = g
            && let Some(name) = r.name.as_deref()
        {
            out.entry(name).or_insert_with(|| {
                r.breaks
                    .iter()
                    .map(|b| (u16::from(b.dmx_break), b.dmx_offset.absolute().min(u32::from(u16::MAX)) as u16))
                    .collect()
            });
        }
        stack.extend(g.children().iter().rev());
    }
    out
}

fn channel(
    c: &DmxChannel,
    template: &str,
    instance: &str,
    breaks: Option<&[(u16, u16)]>,
    mode: &DmxMode,
) -> ChannelInfo {
    let (mut dmx_break, overwrite) = match c.dmx_break {
        DmxBreak::Value(v) => (v.clamp(1, i32::from(u16::MAX)) as u16, false),
        DmxBreak::Overwrite => (1, true),
    };
    let mut shift: u32 = 0;
    if let Some(bs) = breaks {
        let hit = if overwrite { bs.last() } else { bs.iter().find(|(b, _)| *b == dmx_break) };
        if let Some(&(b, off)) = hit {
            dmx_break = b.max(1);
            shift = u32::from(off.max(1) - 1);
        }
    }
    let offsets: Vec<u16> = c
        .offset
        .as_deref()
        .unwrap_or(&[])
        .iter()
        .map(|&o| (i64::from(o).max(1) + i64::from(shift)).min(i64::from(u16::MAX)) as u16)
        .collect();
    let bytes = offsets.len().clamp(1, 4) as u8;
    let max = max_raw(bytes);
    let mut functions = Vec::new();
    for lc in &c.logical_channels {
        for f in &lc.channel_functions {
            let from = dmx(f.dmx_from, bytes);
            // The function ends where the next one under the same mode master begins.
            let to = lc
                .channel_functions
                .iter()
                .filter(|g| g.mode_master == f.mode_master)
                .map(|g| dmx(g.dmx_from, bytes))
                .filter(|&g| g > from)
                .min()
                .map_or(max, |next| next - 1);
            let mut sets = Vec::new();
            for (j, s) in f.channel_sets.iter().enumerate() {
                let sf = dmx(s.dmx_from, bytes);
                let st =
                    f.channel_sets.get(j + 1).map(|x| dmx(x.dmx_from, bytes).saturating_sub(1).max(sf)).unwrap_or(to);
                sets.push(SetInfo {
                    name: s.name.as_deref().unwrap_or("").to_string(),
                    dmx_from: sf,
                    dmx_to: st,
                    wheel_slot: s.wheel_slot_index.map(|i| i.saturating_add(1)),
                });
            }
            functions.push(FunctionInfo {
                name: f.name.as_deref().unwrap_or("").to_string(),
                attribute: f.attribute.to_string(),
                dmx_from: from,
                dmx_to: to,
                physical_from: f.physical_from,
                physical_to: f.physical_to,
                wheel: f.wheel.as_ref().map(|w| w.to_string()),
                emitter: f.emitter.as_ref().map(|w| w.to_string()),
                filter: f.filter.as_ref().map(|w| w.to_string()),
                dmx_profile: f.dmx_profile.as_ref().map(|w| w.to_string()),
                mode_master: f.mode_master.as_ref().map(|mm| {
                    let master = match mm.mode_master(mode) {
                        Some(ModeMaster::DmxChannel(ch) | ModeMaster::ChannelFunction(ch, _, _)) => {
                            ch.offset.as_ref().map_or(1, Vec::len)
                        }
                        None => 1,
                    };
                    let master = master.clamp(1, 4) as u8;
                    (mm.node.to_string(), dmx(mm.from, master), dmx(mm.to, master))
                }),
                sets,
            });
        }
    }
    let attribute =
        c.logical_channels.first().and_then(|l| l.attribute.first()).map(|a| a.to_string()).unwrap_or_default();
    // The default comes from the initial function (else the first function).
    let initial = c.initial_function.as_ref().and_then(|node| node.last()).map(|n| n.to_string());
    let default = c
        .logical_channels
        .iter()
        .flat_map(|l| &l.channel_functions)
        .find(|f| initial.as_deref().is_some_and(|i| f.name.as_deref() == Some(i)))
        .or_else(|| c.logical_channels.first().and_then(|l| l.channel_functions.first()))
        .map(|f| dmx(f.default, bytes))
        .unwrap_or(0);
    ChannelInfo {
        geometry: instance.to_string(),
        template: template.to_string(),
        attribute,
        dmx_break,
        offsets,
        default,
        functions,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::num::NonZeroU8;

    #[test]
    fn dmx_values_rescale() {
        let v = |x, b| DmxValue::new(x, NonZeroU8::new(b).unwrap(), false).unwrap();
        assert_eq!(dmx(v(255, 1), 2), 65535);
        assert_eq!(dmx(v(128, 1), 2), 0x8080);
        assert_eq!(dmx(v(32768, 2), 1), 128);
        assert_eq!(dmx(v(1, 1), 3), 0x010101);
        assert_eq!(dmx(v(0, 1), 4), 0);
        let s = DmxValue::new(1, NonZeroU8::new(1).unwrap(), true).unwrap();
        assert_eq!(dmx(s, 2), 256);
        // A hostile 255-byte value neither panics nor overflows.
        if let Some(h) = DmxValue::new(7, NonZeroU8::new(255).unwrap(), false) {
            assert_eq!(dmx(h, 1), 0);
        }
    }
}
