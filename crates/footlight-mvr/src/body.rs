//! Fixture bodies from the GDTF model (issue 14 item 5): what each MVR
//! fixture's body is made of and how its parts move with pan and tilt.
//!
//! For every fixture of an MVR, the geometry tree of its DMX mode
//! ([`crate::gdtf::Layout`], walked by reference, never by names) gives one
//! [`PartSpec`] per geometry that names a `<Model>`, plus a lens disc for
//! every `<Beam>` without one. A part's shape is, in this order:
//! * the model's 3D file from the GDTF archive: `models/gltf/<File>.glb`,
//!   else `models/3ds/<File>.3ds` ([`Shape::Mesh`], read by the main crate's
//!   glTF importer or the `ds3` crate and scaled to the model's dimensions);
//! * else its `PrimitiveType`: `Cube` a box, `Cylinder` a cylinder along
//!   the geometry's Z, `Sphere` an ellipsoid, each spanning `Length` (X) ×
//!   `Width` (Y) × `Height` (Z) metres about the geometry's origin; the
//!   GDTF 1.0 shapes (`Base`, `Yoke`, `Head`, `Conventional`, `Scanner`,
//!   `Pigtail`…) and `Undefined` are drawn as that box (estimated: their
//!   meshes belong to the GDTF reference software, not to the file).
//!
//! Posing ([`FixtureBodySpec::pose`]): GDTF axes are metres, Z up; an `Axis`
//! bound to a `Pan` channel turns about its Z, one bound to `Tilt` about its
//! X (the frame `show.rs` maps pan/tilt onto, so the beam part's −Z is the
//! light's axis), and the fixture's MVR matrix places the whole in stage
//! axes (`mvr::stage_pose`, GDTF → stage: −90° about X, as the beam frame).

use crate::gdtf::{Gdtf, GeometryKind, GeometryNode, MeshFormat};
use crate::mvr::{Mvr, stage_pose};
use footlight_fixture::PatchError;
use glam::{DMat4, DQuat, DVec3, Mat4, Quat, Vec3};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// Thickness of the lens disc drawn for a `<Beam>` without a model, metres
/// (estimated: a front lens).
pub const LENS_THICKNESS: f32 = 0.002;

/// The shape of one body part, in the part's own GDTF frame (metres, Z up).
#[derive(Clone, Debug)]
pub enum Shape {
    /// A 3D file from the GDTF archive, scaled so its bounds span the model's dimensions.
    Mesh {
        /// glb or 3ds.
        format: MeshFormat,
        /// The archive entry (`models/gltf/head.glb`), for messages.
        entry: String,
        /// The file's bytes (shared by every fixture of the type).
        bytes: Arc<Vec<u8>>,
    },
    /// A box centred on the geometry's origin.
    Box,
    /// A cylinder along the geometry's Z, centred on its origin.
    Cylinder,
    /// An ellipsoid centred on the geometry's origin.
    Sphere,
}

/// One drawn part of a fixture body.
#[derive(Clone, Debug)]
pub struct PartSpec {
    /// The geometry instance it belongs to.
    pub geometry: String,
    /// The model's name (`lens` for the disc of a beam without a model).
    pub model: String,
    /// What is drawn.
    pub shape: Shape,
    /// Length (X), width (Y), height (Z), metres.
    pub dimensions: Vec3,
    /// True when the shape stands in for something the file does not give
    /// (a GDTF 1.0 primitive drawn as a box, a model file missing from the archive).
    pub estimated: bool,
    /// The lens radius when the part is a `<Beam>`'s (it glows with the light's k_i).
    pub lens: Option<f32>,
    /// The emitting cell the part belongs to: the enclosing
    /// `GeometryReference`'s name, else the beam's own name (multi-lamp
    /// fixtures), matching the patch's `"<fixture> / <cell>"` lights.
    pub cell: Option<String>,
    /// Index of its geometry in [`FixtureBodySpec::nodes`].
    pub node: usize,
}

/// How a geometry moves relative to its parent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Joint {
    /// Fixed.
    Fixed,
    /// An `Axis` bound to `Pan`: turns about its Z.
    Pan,
    /// An `Axis` bound to `Tilt`: turns about its X.
    Tilt,
}

/// One geometry instance of the posing chain.
#[derive(Clone, Debug)]
pub struct Node {
    /// Parent index (`None` for the root).
    pub parent: Option<usize>,
    /// Transform from this geometry to its parent (GDTF `Position`, metres).
    pub local: DMat4,
    /// Pan, tilt or fixed.
    pub joint: Joint,
}

/// A fixture's body: where it hangs and its parts.
#[derive(Clone, Debug)]
pub struct FixtureBodySpec {
    /// Desk fixture id (as `show.rs` numbers the patch's fixtures).
    pub id: u32,
    /// The MVR fixture's name (its lights are `name` or `name / cell`).
    pub name: String,
    /// The GDTF type's name.
    pub type_name: String,
    /// Mount position, stage metres.
    pub position: Vec3,
    /// Mount orientation, stage axes (the fixture's GDTF frame is `mount · R_x(−90°)`).
    pub mount: Quat,
    /// Geometry instances in tree order (parents first).
    pub nodes: Vec<Node>,
    /// The drawn parts.
    pub parts: Vec<PartSpec>,
}

impl FixtureBodySpec {
    /// Each part's transform from its GDTF frame to the stage at `pan_deg`,
    /// `tilt_deg` (rigid: the dimensions are in the part's shape).
    pub fn pose(&self, pan_deg: f32, tilt_deg: f32) -> Vec<Mat4> {
        let finite = |a: f32| if a.is_finite() { f64::from(a).to_radians() } else { 0.0 };
        let (pan, tilt) = (finite(pan_deg), finite(tilt_deg));
        let mut posed: Vec<DMat4> = Vec::with_capacity(self.nodes.len());
        for n in &self.nodes {
            let parent = n.parent.map_or(DMat4::IDENTITY, |p| posed[p]);
            let joint = match n.joint {
                Joint::Fixed => DMat4::IDENTITY,
                Joint::Pan => DMat4::from_rotation_z(pan),
                Joint::Tilt => DMat4::from_rotation_x(tilt),
            };
            posed.push(parent * n.local * joint);
        }
        let stage = Mat4::from_rotation_translation(self.mount, self.position)
            * Mat4::from_rotation_x(-std::f32::consts::FRAC_PI_2);
        self.parts.iter().map(|p| stage * posed[p.node].as_mat4()).collect()
    }
}

/// Every fixture body of the MVR at `path`, with warnings (models whose file
/// is missing: one line per GDTF and file, with the parts and fixtures it
/// concerns, not one per part). Fixtures whose GDTF is missing or
/// unreadable get no spec (the caller draws an estimated box).
pub fn fixture_bodies(path: &Path) -> Result<(Vec<FixtureBodySpec>, Vec<String>), PatchError> {
    let m = Mvr::open(path)?;
    let mut warnings = Vec::new();
    let mut types: BTreeMap<String, Option<Gdtf>> = BTreeMap::new();
    let mut meshes: BTreeMap<(String, String), Arc<Vec<u8>>> = BTreeMap::new();
    let mut missing = MissingFiles::new();
    let mut out = Vec::new();
    for (n, f) in m.scene.fixtures.iter().enumerate() {
        let id = f.fixture_id_numeric.or_else(|| f.fixture_id.parse().ok()).unwrap_or(n as u32 + 1);
        let g = types.entry(f.gdtf_spec.clone()).or_insert_with(|| {
            let g = m
                .archive
                .get(&f.gdtf_spec)
                .and_then(|b| Gdtf::from_bytes(&m.archive.label(&f.gdtf_spec), b.to_vec()).ok());
            // Once per type: models whose size is not drawable (NaN, negative…).
            warnings.extend(g.iter().flat_map(Gdtf::model_warnings).map(|w| w.to_string()));
            g
        });
        let Some(g) = g.as_ref() else { continue };
        let mode = if g.mode(&f.gdtf_mode).is_some() { f.gdtf_mode.clone() } else { g.mode_names()[0].clone() };
        let Ok(layout) = g.layout(&mode) else { continue };
        let mut joints: BTreeMap<&str, Joint> = BTreeMap::new();
        for c in &layout.channels {
            match c.attribute.as_str() {
                "Pan" => joints.entry(&c.geometry).or_insert(Joint::Pan),
                "Tilt" => joints.entry(&c.geometry).or_insert(Joint::Tilt),
                _ => continue,
            };
        }
        let (p, q): (DVec3, DQuat) = stage_pose(f.world);
        let mut spec = FixtureBodySpec {
            id,
            name: f.name.clone(),
            type_name: g.name(),
            position: p.as_vec3(),
            mount: q.as_quat(),
            nodes: Vec::new(),
            parts: Vec::new(),
        };
        let mut walk = Walk { g, joints: &joints, spec: &mut spec, meshes: &mut meshes, missing: &mut missing };
        walk.node(&layout.root, None, DMat4::IDENTITY, None);
        out.push(spec);
    }
    for ((label, file, primitive), (parts, fixtures)) in missing {
        let fixtures = crate::report::plural(fixtures.len(), "fixture");
        let parts = crate::report::plural(parts, "part");
        warnings.push(format!(
            "{label}: model file {file:?} is in neither models/gltf nor models/3ds; its primitive {primitive} is \
             drawn ({parts} of {fixtures})"
        ));
    }
    Ok((out, warnings))
}

/// Model files a GDTF names but lacks, by (GDTF, file, primitive): the parts drawn as
/// the primitive instead, and the fixtures (ids) they belong to.
type MissingFiles = BTreeMap<(String, String, String), (usize, std::collections::BTreeSet<u32>)>;

struct Walk<'a> {
    g: &'a Gdtf,
    joints: &'a BTreeMap<&'a str, Joint>,
    spec: &'a mut FixtureBodySpec,
    meshes: &'a mut BTreeMap<(String, String), Arc<Vec<u8>>>,
    missing: &'a mut MissingFiles,
}

impl Walk<'_> {
    fn node(&mut self, n: &GeometryNode, parent: Option<usize>, parent_to_fixture: DMat4, cell: Option<&str>) {
        let joint = match n.kind {
            GeometryKind::Axis => self.joints.get(n.name.as_str()).copied().unwrap_or(Joint::Fixed),
            _ => Joint::Fixed,
        };
        let local = parent_to_fixture.inverse() * n.to_fixture;
        let index = self.spec.nodes.len();
        self.spec.nodes.push(Node { parent, local, joint });
        let beam = match &n.kind {
            // A radius that is not a drawable size (NaN, infinite, negative) is none.
            GeometryKind::Beam(b) => Some(b.beam_radius_m as f32).map(|r| if r.is_finite() { r.max(0.0) } else { 0.0 }),
            _ => None,
        };
        let cell = match (&n.kind, cell) {
            (GeometryKind::Reference(_), _) => Some(n.name.as_str()),
            (GeometryKind::Beam(_), None) => Some(n.name.as_str()),
            (_, c) => c,
        };
        let model = n.model.as_deref().and_then(|name| self.g.model(name));
        match model {
            Some(model) => {
                let [l, w, h] = model.drawn_dimensions();
                let dims = Vec3::new(l as f32, w as f32, h as f32);
                let (shape, estimated) = self.shape(&model.primitive, model.file.as_deref());
                let estimated = estimated || model.bad_dimensions().is_some();
                let lens = beam.map(|r| if r > 0.0 { r } else { 0.5 * dims.x.min(dims.y).max(1e-3) });
                self.spec.parts.push(PartSpec {
                    geometry: n.name.clone(),
                    model: model.name.clone(),
                    shape,
                    dimensions: dims,
                    estimated,
                    lens,
                    cell: cell.map(str::to_string),
                    node: index,
                });
            }
            None => {
                if let Some(r) = beam.filter(|r| *r > 0.0) {
                    self.spec.parts.push(PartSpec {
                        geometry: n.name.clone(),
                        model: "lens".into(),
                        shape: Shape::Cylinder,
                        dimensions: Vec3::new(2.0 * r, 2.0 * r, LENS_THICKNESS),
                        estimated: true,
                        lens: Some(r),
                        cell: cell.map(str::to_string),
                        node: index,
                    });
                }
            }
        }
        for c in &n.children {
            self.node(c, Some(index), n.to_fixture, cell);
        }
    }

    /// The model's file when the archive has it, else its primitive.
    fn shape(&mut self, primitive: &str, file: Option<&str>) -> (Shape, bool) {
        if let Some(file) = file {
            match self.g.model_mesh(file) {
                Some((format, entry, bytes)) => {
                    let key = (self.spec.type_name.clone(), entry.to_string());
                    let bytes = self.meshes.entry(key).or_insert_with(|| Arc::new(bytes.to_vec())).clone();
                    return (Shape::Mesh { format, entry: entry.to_string(), bytes }, false);
                }
                None => {
                    let key = (self.g.label.display().to_string(), file.to_string(), primitive.to_string());
                    let e = self.missing.entry(key).or_default();
                    e.0 += 1;
                    e.1.insert(self.spec.id);
                }
            }
        }
        match primitive {
            "Cube" => (Shape::Box, false),
            "Cylinder" => (Shape::Cylinder, false),
            "Sphere" => (Shape::Sphere, false),
            _ => (Shape::Box, true),
        }
    }
}
