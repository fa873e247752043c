//! Fixture bodies in the picture (issue 14 item 5), as a separate layer.
//!
//! Bodies never enter the light buffers' geometry: a moving head that moved
//! would otherwise change the scene every light is traced against and
//! rebuild all of them. Instead each body is ray-cast against the view into
//! a per-view [`BodyLayer`] (depth, normal, body, part, lens or housing),
//! depth-tested against the stage's primary hit along the same pixel ray,
//! and shaded on its own:
//!
//! * the housing: a fixed dim work light, L = ρ_body/π · E_work
//!   ([`BODY_ALBEDO`], [`WORK_LIGHT_LUX`], both estimated), so bodies are
//!   visible in a dark rig;
//! * a lens part: it emits its light's own k_i, L = k_i · f(θ) /
//!   (π r² · cos θ_lens): the intensity toward the camera (k_i · f, cd)
//!   over the lens disc's apparent area (cos θ_lens floored at 0.05, a lens
//!   seen edge-on). k_i is the light's current composite factor (eq. 4), so
//!   dimmer/colour/strobe changes stay a composite-only update of the layer.
//!
//! Where the shapes come from ([`BodyModel`], [`body_models`]):
//! * an MVR fixture: its GDTF model ([`footlight_mvr::body`]): every
//!   geometry with a `<Model>` is a part, its glb (through the scene's glTF
//!   importer, glTF Y up turned to GDTF Z up) or 3ds (the `ds3` crate) mesh
//!   scaled to the model's Length × Width × Height, else its primitive
//!   (box, cylinder, ellipsoid) at those dimensions; each part posed by the
//!   fixture's pan/tilt through the Axis geometries; a `<Beam>` is a lens;
//! * a TOML fixture type, or an MVR fixture whose GDTF is missing: the
//!   **estimated** box [`BODY_SIZE`] with a lens disc [`LENS_RADIUS`],
//!   posed by the light's rotation.
//!
//! Bodies cast no shadows and receive no stage light (they are not in the
//! scene the lights are traced against).
//!
//! Cost: a body touches only the pixels inside the screen rectangle of its
//! parts' bounding spheres ([`BodyLayer::redraw`] re-tests that rectangle,
//! old and new, against the bodies overlapping it; the stage depth of a
//! pixel is cast once per view and kept), so a moving head costs its own
//! footprint, not a rebuild of any light buffer. Stills: `footlight render
//! --bodies`; live: [`LiveBodies`] in the frame clock.

use crate::fixture::Light;
use crate::scene::{Camera, ImportLimits, Scene, SceneBuilder};
use footlight_mvr::body::{FixtureBodySpec, Shape as SpecShape};
use footlight_mvr::gdtf::MeshFormat;
use glam::{Mat4, Vec3, Vec3Swizzles};
use std::path::Path;
use std::sync::Arc;

/// Estimated body box, metres: width (light-local x), height (local y),
/// length behind the lens (local +z; the beam leaves along −z): a mid-size
/// moving head's head. For TOML fixture types (no model dimensions).
pub const BODY_SIZE: Vec3 = Vec3::new(0.35, 0.35, 0.45);

/// Estimated lens radius, metres (the test GDTF types' BeamRadius is 0.075 m).
pub const LENS_RADIUS: f32 = 0.075;

/// Housing albedo (estimated: matte black paint).
pub const BODY_ALBEDO: f32 = 0.05;

/// Illuminance of the fixed work light on every housing face, lux (estimated).
pub const WORK_LIGHT_LUX: f32 = 20.0;

/// Segments around a primitive cylinder or ellipsoid.
const SEGMENTS: usize = 24;

/// Triangles at most in one model file (GDTF asks for at most 1200 vertices per device).
const MAX_MODEL_TRIANGLES: u64 = 200_000;

/// A part's triangles in its own frame, with their BVH and bounds.
pub struct Shape {
    /// The triangles (materials unused).
    pub mesh: Scene,
    /// Bounds, part frame.
    pub lo: Vec3,
    /// See `lo`.
    pub hi: Vec3,
}

impl Shape {
    fn from_builder(b: SceneBuilder) -> Self {
        let mesh = b.build();
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for t in &mesh.positions {
            for p in t {
                lo = lo.min(*p);
                hi = hi.max(*p);
            }
        }
        if mesh.positions.is_empty() {
            (lo, hi) = (Vec3::ZERO, Vec3::ZERO);
        }
        Self { mesh, lo, hi }
    }

    /// The axis-aligned box `lo..hi`.
    pub fn cuboid(lo: Vec3, hi: Vec3) -> Self {
        let mut b = SceneBuilder::new();
        let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z) * (hi - lo) * 0.5 + (hi + lo) * 0.5;
        crate::scene::mvr_scene::add_box(&mut b, p, 0);
        Self::from_builder(b)
    }

    /// A cylinder along z: elliptic section of radii `r.x`, `r.y`, from `z0` to `z1`.
    pub fn cylinder(r: glam::Vec2, z0: f32, z1: f32) -> Self {
        let mut b = SceneBuilder::new();
        let ring = |k: usize, z: f32| {
            let a = k as f32 / SEGMENTS as f32 * std::f32::consts::TAU;
            Vec3::new(r.x * a.cos(), r.y * a.sin(), z)
        };
        for k in 0..SEGMENTS {
            let (a0, a1, b0, b1) = (ring(k, z0), ring(k + 1, z0), ring(k, z1), ring(k + 1, z1));
            b.add_quad(a0, a1, b1, b0, 0);
            b.add_triangle([Vec3::new(0.0, 0.0, z0), a1, a0], None, 0);
            b.add_triangle([Vec3::new(0.0, 0.0, z1), b0, b1], None, 0);
        }
        Self::from_builder(b)
    }

    /// An ellipsoid of semi-axes `r` about the origin.
    pub fn ellipsoid(r: Vec3) -> Self {
        let mut b = SceneBuilder::new();
        let rings = SEGMENTS / 2;
        let p = |i: usize, k: usize| {
            let th = i as f32 / rings as f32 * std::f32::consts::PI;
            let ph = k as f32 / SEGMENTS as f32 * std::f32::consts::TAU;
            Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()) * r
        };
        for i in 0..rings {
            for k in 0..SEGMENTS {
                let (a, bb, c, d) = (p(i, k), p(i + 1, k), p(i + 1, k + 1), p(i, k + 1));
                b.add_triangle([a, bb, c], None, 0);
                b.add_triangle([a, c, d], None, 0);
            }
        }
        Self::from_builder(b)
    }

    /// A GDTF model part: its mesh (glb/3ds) scaled to `dims` (Length along
    /// X, Width Y, Height Z, about the file's origin), else the primitive.
    pub fn from_spec(shape: &SpecShape, dims: Vec3) -> Result<Self, String> {
        let half = dims * 0.5;
        match shape {
            SpecShape::Box => Ok(Self::cuboid(-half, half)),
            SpecShape::Cylinder => Ok(Self::cylinder(half.xy(), -half.z, half.z)),
            SpecShape::Sphere => Ok(Self::ellipsoid(half)),
            SpecShape::Mesh { format, entry, bytes } => {
                let label = Path::new(entry);
                let limits = ImportLimits { max_triangles: MAX_MODEL_TRIANGLES };
                let mut raw = SceneBuilder::new();
                match format {
                    // glTF is Y up; GDTF is Z up: +90° about X takes glTF y to z.
                    MeshFormat::Glb => {
                        let turn = Mat4::from_rotation_x(std::f32::consts::FRAC_PI_2);
                        crate::scene::gltf_import::import_bytes_into(label, bytes, &mut raw, turn, &limits)
                            .map_err(|e| e.to_string())?;
                    }
                    MeshFormat::Max3ds => {
                        let model = crate::scene::mvr_scene::parse_3ds(label, bytes)?;
                        for mesh in &model.meshes {
                            for face in &mesh.faces {
                                let [a, b, c] = face.map(|i| mesh.vertices.get(usize::from(i)).copied());
                                let (Some(a), Some(b), Some(c)) = (a, b, c) else {
                                    return Err(format!("{entry}: a face index past its vertices"));
                                };
                                raw.add_triangle([a.into(), b.into(), c.into()], None, 0);
                            }
                        }
                    }
                }
                let raw = Self::from_builder(raw);
                if raw.mesh.positions.is_empty() {
                    return Err(format!("{entry}: no triangles"));
                }
                let extent = raw.hi - raw.lo;
                let scale = Vec3::select(extent.cmpgt(Vec3::splat(1e-9)), dims / extent, Vec3::ONE);
                let mut b = SceneBuilder::new();
                for t in &raw.mesh.positions {
                    b.add_triangle(t.map(|p| p * scale), None, 0);
                }
                Ok(Self::from_builder(b))
            }
        }
    }
}

/// One posed part of a body.
#[derive(Clone)]
pub struct Part {
    /// Its triangles (shared by every fixture of the type).
    pub shape: Arc<Shape>,
    /// Part frame → stage (rigid).
    pub to_world: Mat4,
    /// Stage → part frame.
    pub from_world: Mat4,
    /// A lens: the light (index into the frame's lights) whose k_i it shows, and its radius.
    pub glow: Option<(usize, f32)>,
}

impl Part {
    /// A part at `to_world` (rigid).
    pub fn new(shape: Arc<Shape>, to_world: Mat4, glow: Option<(usize, f32)>) -> Self {
        Self { shape, to_world, from_world: to_world.inverse(), glow }
    }
}

/// One fixture body, posed.
#[derive(Clone)]
pub struct Body {
    /// Its parts.
    pub parts: Vec<Part>,
}

/// How to draw one fixture's body at any pan/tilt.
pub struct BodyModel {
    /// The fixture's name (messages).
    pub name: String,
    /// The light whose pan/tilt pose the body (its first light).
    pub driver: usize,
    kind: ModelKind,
}

enum ModelKind {
    /// From the GDTF model: the spec, one shape per part, each part's lens light.
    Gdtf { spec: FixtureBodySpec, shapes: Vec<Arc<Shape>>, glow: Vec<Option<(usize, f32)>> },
    /// The estimated box and lens disc in the light's frame.
    Estimated { housing: Arc<Shape>, lens: Arc<Shape> },
}

impl BodyModel {
    /// The estimated body of light `index` (TOML fixture types).
    pub fn estimated(name: &str, index: usize) -> Self {
        let h = BODY_SIZE.xy() * 0.5;
        let housing = Arc::new(Shape::cuboid(Vec3::new(-h.x, -h.y, 0.0), Vec3::new(h.x, h.y, BODY_SIZE.z)));
        let lens = Arc::new(Shape::cylinder(glam::Vec2::splat(LENS_RADIUS), -1e-3, 0.0));
        Self { name: name.to_string(), driver: index, kind: ModelKind::Estimated { housing, lens } }
    }

    /// True for the estimated box (no GDTF model).
    pub fn is_estimated(&self) -> bool {
        matches!(self.kind, ModelKind::Estimated { .. })
    }

    /// The body at the driver light's current `light` (estimated box) or
    /// `pan_deg`/`tilt_deg` (GDTF model).
    pub fn pose(&self, light: &Light, pan_deg: f32, tilt_deg: f32) -> Body {
        match &self.kind {
            ModelKind::Estimated { housing, lens } => {
                let m = Mat4::from_rotation_translation(light.rotation, light.position);
                Body {
                    parts: vec![
                        Part::new(housing.clone(), m, None),
                        Part::new(lens.clone(), m, Some((self.driver, LENS_RADIUS))),
                    ],
                }
            }
            ModelKind::Gdtf { spec, shapes, glow } => {
                let poses = spec.pose(pan_deg, tilt_deg);
                let parts =
                    poses.into_iter().zip(shapes).zip(glow).map(|((m, s), g)| Part::new(s.clone(), m, *g)).collect();
                Body { parts }
            }
        }
    }
}

/// The body models of a show: from the GDTF models when `patch` is an MVR
/// (lights matched to MVR fixtures by id and name, `"<fixture> / <cell>"`
/// for cells), the estimated box for every other light. `names[i]` and
/// `ids[i]` are light i's fixture name and id. Returns the warnings too
/// (unreadable model files: the primitive is drawn).
pub fn body_models(patch: &Path, names: &[String], ids: &[u32]) -> (Vec<BodyModel>, Vec<String>) {
    let mut warnings = Vec::new();
    let mut covered = vec![false; names.len()];
    let mut models = Vec::new();
    if let Some(show) = footlight_mvr::show_of(patch) {
        match footlight_mvr::body::fixture_bodies(&show) {
            Err(e) => warnings.push(format!("fixture bodies: {e}; estimated boxes drawn")),
            Ok((specs, w)) => {
                warnings.extend(w);
                let mut cache: std::collections::BTreeMap<(String, String, u32), Arc<Shape>> = Default::default();
                for spec in specs {
                    let prefix = format!("{} / ", spec.name);
                    let lights: Vec<usize> = (0..names.len())
                        .filter(|&j| ids[j] == spec.id && (names[j] == spec.name || names[j].starts_with(&prefix)))
                        .collect();
                    let Some(&driver) = lights.first() else { continue };
                    let mut shapes = Vec::new();
                    let mut glow = Vec::new();
                    for p in &spec.parts {
                        let key =
                            (spec.type_name.clone(), p.geometry.clone() + "/" + &p.model, p.dimensions.x.to_bits());
                        let shape = match cache.get(&key) {
                            Some(s) => s.clone(),
                            None => {
                                let s = Arc::new(Shape::from_spec(&p.shape, p.dimensions).unwrap_or_else(|e| {
                                    warnings.push(format!("{e}; a box of the model's dimensions is drawn"));
                                    Shape::cuboid(-p.dimensions * 0.5, p.dimensions * 0.5)
                                }));
                                cache.insert(key, s.clone());
                                s
                            }
                        };
                        shapes.push(shape);
                        let light = p
                            .cell
                            .as_ref()
                            .and_then(|c| {
                                let full = format!("{prefix}{c}");
                                lights.iter().copied().find(|&j| names[j] == full)
                            })
                            .unwrap_or(driver);
                        glow.push(p.lens.map(|r| (light, r)));
                    }
                    for &j in &lights {
                        covered[j] = true;
                    }
                    models.push(BodyModel {
                        name: spec.name.clone(),
                        driver,
                        kind: ModelKind::Gdtf { spec, shapes, glow },
                    });
                }
            }
        }
    }
    for (j, name) in names.iter().enumerate() {
        if !covered[j] {
            models.push(BodyModel::estimated(name, j));
        }
    }
    models.sort_by_key(|m| m.driver);
    (models, warnings)
}

/// What a pixel of the body layer sees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyHit {
    /// Distance along the pixel ray, metres.
    pub depth: f32,
    /// World normal of the face hit (toward the camera).
    pub normal: Vec3,
    /// Index of the body.
    pub body: u32,
    /// Index of the part in the body.
    pub part: u32,
    /// True on a lens.
    pub lens: bool,
}

/// A body pixel with the lens glow's k_i left out: radiance (cd/m², linear
/// RGB) = `base` (grey) + k_`light` · `glow` (eq. 4's k_i, cd). The browser
/// stream sends this and multiplies by the frame's k_i itself, so a dimmer
/// change needs no body message (docs/stream.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyPixel {
    /// The housing under the fixed work light, cd/m² (grey).
    pub base: f32,
    /// The lens glow per unit k_i, cd/m² per cd (0 on the housing).
    pub glow: f32,
    /// The light whose k_i the glow uses (0 when `glow` is 0).
    pub light: u32,
}

impl BodyPixel {
    /// The radiance with the frame's k (light order): base + k_light · glow.
    pub fn radiance(&self, k: &[Vec3]) -> Vec3 {
        let glow = match k.get(self.light as usize) {
            Some(k) if self.glow != 0.0 => *k * self.glow,
            _ => Vec3::ZERO,
        };
        Vec3::splat(self.base) + glow
    }
}

/// A pixel rectangle (x0, y0, x1, y1), exclusive ends.
pub type Rect = (u32, u32, u32, u32);

/// The per-view body layer: one optional hit per pixel (pixel centres).
pub struct BodyLayer {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Row-major hits, nearest body in front of the stage.
    pub hits: Vec<Option<BodyHit>>,
    /// Each body's pixel rectangle.
    rects: Vec<Rect>,
    /// The stage's first-hit distance per pixel (NaN: not cast yet); the camera is fixed for a layer.
    stage: Vec<f32>,
}

impl BodyLayer {
    /// Ray-casts every body into an empty layer.
    pub fn build(scene: &Scene, camera: &Camera, width: u32, height: u32, bodies: &[Body]) -> Self {
        let n = (width * height) as usize;
        let mut layer = Self { width, height, hits: vec![None; n], rects: Vec::new(), stage: vec![f32::NAN; n] };
        layer.rects = bodies.iter().map(|b| footprint(camera, width, height, b)).collect();
        for i in 0..bodies.len() {
            let r = layer.rects[i];
            layer.retest(scene, camera, bodies, r);
        }
        layer
    }

    /// Body `i` moved (its pose changed): only the pixels of its old and new
    /// rectangles are tested again. Returns the pixels tested.
    pub fn redraw(&mut self, scene: &Scene, camera: &Camera, bodies: &[Body], i: usize) -> u64 {
        let Some(&old) = self.rects.get(i) else { return 0 };
        let new = footprint(camera, self.width, self.height, &bodies[i]);
        self.rects[i] = new;
        self.retest(scene, camera, bodies, old);
        self.retest(scene, camera, bodies, new);
        area(old) + area(new)
    }

    /// Pixels of body `i`'s current rectangle.
    pub fn footprint_pixels(&self, i: usize) -> u64 {
        self.rects.get(i).map_or(0, |&r| area(r))
    }

    /// Body `i`'s current pixel rectangle.
    pub fn rect(&self, i: usize) -> Option<Rect> {
        self.rects.get(i).copied()
    }

    fn retest(&mut self, scene: &Scene, camera: &Camera, bodies: &[Body], r: Rect) {
        let overlapping: Vec<usize> = (0..bodies.len()).filter(|&j| overlaps(self.rects[j], r)).collect();
        for y in r.1..r.3 {
            for x in r.0..r.2 {
                let idx = (y * self.width + x) as usize;
                let dir = camera.direction(x as f32 + 0.5, y as f32 + 0.5, self.width, self.height);
                let mut best: Option<BodyHit> = None;
                for &j in &overlapping {
                    let limit = best.map_or(f32::INFINITY, |b| b.depth);
                    if let Some((t, normal, part)) = cast(&bodies[j], camera.position, dir, limit) {
                        let lens = bodies[j].parts[part].glow.is_some();
                        best = Some(BodyHit { depth: t, normal, body: j as u32, part: part as u32, lens });
                    }
                }
                if let Some(b) = best {
                    if self.stage[idx].is_nan() {
                        self.stage[idx] =
                            scene.accel.intersect(camera.position, dir, f32::INFINITY).map_or(f32::INFINITY, |h| h.t);
                    }
                    if b.depth >= self.stage[idx] {
                        best = None;
                    }
                }
                self.hits[idx] = best;
            }
        }
    }

    /// Body pixel `index` split as the browser stream sends it
    /// ([`BodyPixel`]): radiance = base + k_light · glow; `None` where the
    /// stage shows. [`BodyLayer::radiance`] is this with the frame's k_i, so
    /// the server's picture and the stream's agree by construction.
    pub fn pixel(&self, index: usize, camera: &Camera, bodies: &[Body], lights: &[Light]) -> Option<BodyPixel> {
        let h = self.hits.get(index).copied().flatten()?;
        let mut p = BodyPixel { base: BODY_ALBEDO * std::f32::consts::FRAC_1_PI * WORK_LIGHT_LUX, glow: 0.0, light: 0 };
        if let Some((light_index, radius)) =
            bodies.get(h.body as usize).and_then(|b| b.parts.get(h.part as usize)?.glow)
            && let Some(light) = lights.get(light_index)
        {
            let (x, y) = (index as u32 % self.width, index as u32 / self.width);
            let to_camera = -camera.direction(x as f32 + 0.5, y as f32 + 0.5, self.width, self.height);
            let cos_lens = to_camera.dot(light.axis()).max(0.05);
            p.glow = light.pattern_toward(to_camera) / (std::f32::consts::PI * radius * radius * cos_lens);
            p.light = light_index as u32;
        }
        Some(p)
    }

    /// Radiance of body pixel `index` (cd/m², linear RGB), `None` where the
    /// stage shows: housing work light plus the lens glow with its light's
    /// k_i (`lights[i]`, `k[i]` in light order).
    pub fn radiance(
        &self,
        index: usize,
        camera: &Camera,
        bodies: &[Body],
        lights: &[Light],
        k: &[Vec3],
    ) -> Option<Vec3> {
        self.pixel(index, camera, bodies, lights).map(|p| p.radiance(k))
    }

    /// Radiance of every body pixel ([`BodyLayer::radiance`]).
    pub fn shade(&self, camera: &Camera, bodies: &[Body], lights: &[Light], k: &[Vec3]) -> Vec<Option<Vec3>> {
        (0..self.hits.len()).map(|i| self.radiance(i, camera, bodies, lights, k)).collect()
    }

    /// Overwrites the body pixels of a linear picture (`width × height`).
    pub fn overlay(&self, camera: &Camera, bodies: &[Body], lights: &[Light], k: &[Vec3], linear: &mut [Vec3]) {
        for (i, px) in linear.iter_mut().enumerate() {
            if let Some(l) = self.radiance(i, camera, bodies, lights, k) {
                *px = l;
            }
        }
    }

    /// Overwrites the body pixels of an 8-bit sRGB picture through `display`
    /// (the live compositors' output); returns the pixels written.
    pub fn overlay_srgb8(
        &self,
        camera: &Camera,
        bodies: &[Body],
        lights: &[Light],
        k: &[Vec3],
        display: &crate::render::Display,
        rgb: &mut [u8],
    ) -> usize {
        // One batch through the display's own encoding (whatever curve it has).
        let (at, linear): (Vec<usize>, Vec<Vec3>) = (0..self.hits.len())
            .filter(|&i| 3 * i + 3 <= rgb.len())
            .filter_map(|i| Some((i, self.radiance(i, camera, bodies, lights, k)?)))
            .unzip();
        let encoded = display.to_srgb8(&linear);
        for (&i, px) in at.iter().zip(encoded.chunks_exact(3)) {
            rgb[3 * i..3 * i + 3].copy_from_slice(px);
        }
        at.len()
    }
}

fn area(r: Rect) -> u64 {
    u64::from(r.2.saturating_sub(r.0)) * u64::from(r.3.saturating_sub(r.1))
}

fn overlaps(a: Rect, b: Rect) -> bool {
    a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3
}

/// Nearest hit of a ray with a body closer than `limit`: (t, world normal toward the ray, part).
fn cast(body: &Body, origin: Vec3, dir: Vec3, limit: f32) -> Option<(f32, Vec3, usize)> {
    let mut best: Option<(f32, Vec3, usize)> = None;
    for (pi, part) in body.parts.iter().enumerate() {
        let o = part.from_world.transform_point3(origin);
        let d = part.from_world.transform_vector3(dir);
        let t_max = best.map_or(limit, |b| b.0);
        if !slab(o, d, part.shape.lo, part.shape.hi, t_max) {
            continue;
        }
        if let Some(h) = part.shape.mesh.accel.intersect(o, d, t_max) {
            let n = part.to_world.transform_vector3(part.shape.mesh.face_normals[h.triangle as usize]);
            let n = if n.dot(dir) > 0.0 { -n } else { n };
            best = Some((h.t, n, pi));
        }
    }
    best
}

/// Whether the ray `o + t d`, 0 < t < t_max, meets the box `lo..hi`.
fn slab(o: Vec3, d: Vec3, lo: Vec3, hi: Vec3, t_max: f32) -> bool {
    let inv = d.recip();
    let (a, b) = ((lo - o) * inv, (hi - o) * inv);
    let (near, far) = (a.min(b), a.max(b));
    let t0 = near.max_element().max(0.0);
    let t1 = far.min_element().min(t_max);
    // NaN (a zero direction component on a slab face) counts as a hit: the BVH decides.
    t0.partial_cmp(&t1) != Some(std::cmp::Ordering::Greater)
}

/// A conservative pixel rectangle around the parts' bounding boxes: the
/// projected corners of each part's box (the box's projection lies in their
/// hull, a pixel centre inside it lies in their bounding rectangle), with a
/// pixel of margin; a part with a corner at or behind the camera plane falls
/// back to its bounding sphere (the whole image when it reaches behind).
fn footprint(camera: &Camera, width: u32, height: u32, body: &Body) -> Rect {
    let mut r: Option<Rect> = None;
    for part in &body.parts {
        let pr = box_rect(camera, width, height, part).unwrap_or_else(|| {
            let centre = part.to_world.transform_point3((part.shape.lo + part.shape.hi) * 0.5);
            let radius = (part.shape.hi - part.shape.lo).length() * 0.5 + 1e-3;
            sphere_rect(camera, width, height, centre, radius)
        });
        if pr.0 >= pr.2 || pr.1 >= pr.3 {
            continue;
        }
        r = Some(match r {
            None => pr,
            Some(q) => (q.0.min(pr.0), q.1.min(pr.1), q.2.max(pr.2), q.3.max(pr.3)),
        });
    }
    r.unwrap_or((0, 0, 0, 0))
}

/// The pixel rectangle of a part's projected box corners (1e-3 m padding, 1 px
/// margin); `None` when a corner is not in front of the camera.
fn box_rect(camera: &Camera, width: u32, height: u32, part: &Part) -> Option<Rect> {
    let (lo, hi) = (part.shape.lo - Vec3::splat(1e-3), part.shape.hi + Vec3::splat(1e-3));
    let tan_half = (camera.yfov * 0.5).tan();
    let aspect = width as f32 / height.max(1) as f32;
    let (mut x0, mut y0, mut x1, mut y1) = (f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY);
    for i in 0..8 {
        let c = Vec3::new([lo.x, hi.x][i & 1], [lo.y, hi.y][(i >> 1) & 1], [lo.z, hi.z][(i >> 2) & 1]);
        let rel = camera.basis.transpose() * (part.to_world.transform_point3(c) - camera.position);
        let depth = -rel.z;
        if depth.is_nan() || depth <= 1e-3 {
            return None;
        }
        let x = (rel.x / (depth * tan_half * aspect) + 1.0) * 0.5 * width as f32;
        let y = (1.0 - rel.y / (depth * tan_half)) * 0.5 * height as f32;
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
    }
    if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite()) {
        return None;
    }
    let cl = |v: f32, n: u32| v.clamp(0.0, n as f32) as u32;
    let r = (
        cl(x0.floor() - 1.0, width),
        cl(y0.floor() - 1.0, height),
        cl(x1.ceil() + 1.0, width),
        cl(y1.ceil() + 1.0, height),
    );
    Some(if r.0 >= r.2 || r.1 >= r.3 { (0, 0, 0, 0) } else { r })
}

fn sphere_rect(camera: &Camera, width: u32, height: u32, centre: Vec3, radius: f32) -> Rect {
    let rel = camera.basis.transpose() * (centre - camera.position);
    let depth = -rel.z;
    let all = (0, 0, width, height);
    if depth <= radius * 1.01 || !depth.is_finite() {
        return all;
    }
    let tan_half = (camera.yfov * 0.5).tan();
    let aspect = width as f32 / height.max(1) as f32;
    let ndc = |v: f32, scale: f32| v / (depth * tan_half * scale);
    let cx = (ndc(rel.x, aspect) + 1.0) * 0.5 * width as f32;
    let cy = (1.0 - ndc(rel.y, 1.0)) * 0.5 * height as f32;
    // Angular radius of the sphere, as pixels at the image centre's scale, with margin for the off-axis stretch.
    let ang = (radius / depth).asin();
    let pr = ang.tan() / tan_half * 0.5 * height as f32 * 1.5 + 2.0;
    let cl = |v: f32, n: u32| v.clamp(0.0, n as f32) as u32;
    let r = (cl(cx - pr, width), cl(cy - pr, height), cl(cx + pr + 1.0, width), cl(cy + pr + 1.0, height));
    if r.0 >= r.2 || r.1 >= r.3 { (0, 0, 0, 0) } else { r }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixture::{Beam, SpotBeam};
    use crate::scene::{Material, SceneBuilder};

    fn floor_scene() -> Scene {
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::lambert("floor", Vec3::splat(0.5)));
        b.add_quad(
            Vec3::new(-20.0, 0.0, 20.0),
            Vec3::new(20.0, 0.0, 20.0),
            Vec3::new(20.0, 0.0, -20.0),
            Vec3::new(-20.0, 0.0, -20.0),
            m,
        );
        b.build()
    }

    #[test]
    fn an_estimated_head_facing_the_camera_glows_with_its_k() {
        let scene = floor_scene();
        let cam = Camera::look_at(Vec3::new(0.0, 3.0, 6.0), Vec3::new(0.0, 3.0, 0.0), 30f32.to_radians());
        let light =
            Light::aimed(Vec3::new(0.0, 3.0, 0.0), cam.position, Beam::Spot(SpotBeam::from_beam_field(20.0, 30.0)));
        let k = [Vec3::new(100.0, 50.0, 25.0)];
        let body = BodyModel::estimated("head", 0).pose(&light, 0.0, 0.0);
        let (w, h) = (101, 101);
        let layer = BodyLayer::build(&scene, &cam, w, h, std::slice::from_ref(&body));
        let centre = layer.hits[(50 * w + 50) as usize].expect("the lens at the image centre");
        // The lens disc's front face is 1 mm in front of the light's position.
        assert!(centre.lens && (centre.depth - 5.999).abs() < 1e-4, "{centre:?}");
        // On axis: L = k / (π r²) plus the housing term, per channel.
        let shaded = layer.radiance((50 * w + 50) as usize, &cam, &[body], &[light], &k).unwrap();
        let housing = BODY_ALBEDO / std::f32::consts::PI * WORK_LIGHT_LUX;
        let want = k[0] / (std::f32::consts::PI * LENS_RADIUS * LENS_RADIUS) + Vec3::splat(housing);
        assert!((shaded - want).abs().max_element() <= 1e-3 * want.max_element(), "{shaded} vs {want}");
        // The box's apparent half width: 0.175 m at 6 m with a 30° field over 101 px.
        let px_per_m = 101.0 / (2.0 * 6.0 * (15f32.to_radians()).tan());
        let half = (0.175 * px_per_m) as u32;
        assert!(layer.hits[(50 * w + 50 + half - 1) as usize].is_some_and(|h| !h.lens));
        assert!(layer.hits[(50 * w + 50 + half + 2) as usize].is_none());
        assert!(layer.footprint_pixels(0) < u64::from(w * h) / 4, "{}", layer.footprint_pixels(0));
    }

    #[test]
    fn bodies_behind_the_stage_are_hidden_and_a_redraw_equals_a_rebuild() {
        let scene = floor_scene();
        let cam = Camera::look_at(Vec3::new(0.0, 5.0, 8.0), Vec3::ZERO, 40f32.to_radians());
        let beam = Beam::Spot(SpotBeam::from_beam_field(20.0, 30.0));
        let under = Light::aimed(Vec3::new(0.0, -1.0, 0.0), Vec3::ZERO, beam.clone());
        let above = Light::aimed(Vec3::new(2.0, 1.0, 0.0), Vec3::new(2.0, 0.0, 0.0), beam);
        let models = [BodyModel::estimated("under", 0), BodyModel::estimated("above", 1)];
        let mut bodies = vec![models[0].pose(&under, 0.0, 0.0), models[1].pose(&above, 0.0, 0.0)];
        let (w, h) = (120, 80);
        let mut layer = BodyLayer::build(&scene, &cam, w, h, &bodies);
        assert!(layer.hits.iter().flatten().all(|h| h.body == 1));
        let count = |l: &BodyLayer| l.hits.iter().flatten().count();
        assert!(count(&layer) > 10, "{}", count(&layer));
        let mut moved = above.clone();
        moved.position = Vec3::new(-2.0, 1.0, 1.0);
        bodies[1] = models[1].pose(&moved, 0.0, 0.0);
        layer.redraw(&scene, &cam, &bodies, 1);
        let fresh = BodyLayer::build(&scene, &cam, w, h, &bodies);
        assert_eq!(layer.hits, fresh.hits);
        assert!(count(&layer) > 10);
    }

    #[test]
    fn the_box_footprints_miss_no_pixel_of_a_brute_force_cast() {
        let scene = floor_scene();
        let cam = Camera::look_at(Vec3::new(1.0, 2.5, 6.0), Vec3::new(0.0, 2.0, 0.0), 60f32.to_radians());
        let beam = Beam::Spot(SpotBeam::from_beam_field(20.0, 30.0));
        let (w, h) = (96, 64);
        let mut bodies = Vec::new();
        for k in 0..12 {
            let a = k as f32 * 0.7;
            let at = Vec3::new(-3.0 + 0.55 * k as f32, 1.0 + 0.3 * (k % 4) as f32, -1.0 + 0.9 * (k % 3) as f32);
            let light = Light::aimed(at, at + Vec3::new(a.cos(), -0.5 - a.sin().abs(), a.sin()), beam.clone());
            bodies.push(BodyModel::estimated("b", 0).pose(&light, 0.0, 0.0));
        }
        let layer = BodyLayer::build(&scene, &cam, w, h, &bodies);
        let mut hit = 0;
        for y in 0..h {
            for x in 0..w {
                let dir = cam.direction(x as f32 + 0.5, y as f32 + 0.5, w, h);
                let stage = scene.accel.intersect(cam.position, dir, f32::INFINITY).map_or(f32::INFINITY, |h| h.t);
                let mut best: Option<(f32, usize)> = None;
                for (j, b) in bodies.iter().enumerate() {
                    if let Some((t, _, _)) = cast(b, cam.position, dir, best.map_or(f32::INFINITY, |b| b.0)) {
                        best = Some((t, j));
                    }
                }
                let want = best.filter(|b| b.0 < stage).map(|b| b.1 as u32);
                assert_eq!(layer.hits[(y * w + x) as usize].map(|h| h.body), want, "pixel ({x}, {y})");
                hit += usize::from(want.is_some());
            }
        }
        assert!(hit > 200, "{hit} body pixels");
    }
}
