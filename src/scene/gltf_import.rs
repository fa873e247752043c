//! glTF 2.0 import (`.gltf` with external or embedded buffers, and `.glb`).
//!
//! Walks every node of the default scene (or the first scene) with its world
//! transform, turns triangle primitives (lists, strips and fans) into scene
//! triangles, maps materials with [`Material::from_pbr`] (base colour,
//! metallic, roughness, `KHR_materials_transmission`, `KHR_materials_ior`),
//! base-colour textures (PNG, with TEXCOORD_0; [`super::texture`]), and
//! takes the first perspective camera. What the renderer cannot use
//! (metallic-roughness, normal and other textures, JPEG images, texture sets
//! other than TEXCOORD_0, points/lines, punctual lights: lights come from
//! the patch) is reported once with `tracing::warn!`, never silently.
//!
//! [`import_bytes_into`] reads a file given as bytes (a fixture body's
//! model) and [`import_archive_entry`] an MVR archive's model (its URIs
//! resolved in the archive) into a shared [`SceneBuilder`] under a
//! placement matrix.
//!
//! A scene file is untrusted input (issue 12 items 2, 3 and 10), so
//! everything is checked before it is used, in this order, and every error
//! names the file and the element:
//!
//! 1. The file must be a regular file. gltf-json parses it *without* its
//!    validator first, because the validator's POSITION hook indexes
//!    `accessors[i]` unchecked (gltf-json 1.4.1) and panics on a bad index;
//!    those indices are checked here, then the validator runs and cannot panic.
//! 2. Cameras (`yfov` in (0, π), finite `znear`/`aspectRatio`), node
//!    transforms (finite) and material factors (finite: an error; outside
//!    their glTF range: a warning, then [`Material::from_pbr`] clamps).
//! 3. The node graph of the scene: each node may be reached once. A cycle or
//!    a node reached twice (a shared subtree, which glTF forbids and which
//!    could instance a mesh 2^40 times) is an error naming the node.
//! 4. Every accessor a primitive uses: its type, count × stride inside its
//!    buffer view, the view inside its buffer's `byteLength`, sparse parts
//!    likewise. This module reads accessors itself (the gltf crate's reader
//!    returns `None` for every kind of problem, and its sparse iterator
//!    unwraps), so a bad count names the accessor and the bound.
//! 5. The budget ([`ImportLimits`]): instances × triangles and instances ×
//!    vertices (at most 3 per triangle allowed), summed from the declared
//!    counts before anything is allocated.
//! 6. Buffers: `data:` URIs (base64), the GLB binary chunk, or a *relative*
//!    path that, canonicalised, stays inside the scene's folder and is a
//!    regular file; at most `byteLength` bytes are read, and a shorter file is
//!    an error. `file:` and other schemes, absolute paths, `..` escapes and
//!    devices are refused. A model inside an MVR archive
//!    ([`import_archive_entry`]) reads a relative path as another file of
//!    the same archive instead, never outside it (no `..`, no absolute
//!    path). Base-colour images are read the same way (or
//!    from a bufferView), the whole file up to [`MAX_IMAGE_BYTES`], decoded
//!    with at most [`super::texture::MAX_TEXTURE_SIDE`] texels a side; one
//!    that cannot be read leaves the constant factor, with a warning.
//! 7. Index values below the vertex count; non-finite normals are replaced
//!    by the face normal and counted (a warning), non-finite or zero-area
//!    triangles are dropped and counted (a warning).

use super::texture::{Texture, Wrap};
use super::{Camera, Material, Scene, SceneBuilder};
use glam::{Mat3, Mat4, Vec2, Vec3};
use gltf::json;
use gltf::json::validation::Checked;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Why a scene file could not be loaded. Always names the file.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file itself could not be read.
    #[error("{path}: {what}")]
    Read {
        /// The scene file.
        path: PathBuf,
        /// What went wrong.
        what: String,
    },
    /// The file could not be parsed or validated as glTF (the gltf crate's message says where).
    #[error("{path}: not a valid glTF 2.0 file: {source}")]
    Gltf {
        /// The scene file.
        path: PathBuf,
        /// What the gltf crate reported.
        source: gltf::Error,
    },
    /// An element of the file is unusable or unsafe (an accessor past its
    /// buffer, a node cycle, a buffer URI outside the scene folder, …).
    #[error("{path}: {what}")]
    Invalid {
        /// The scene file.
        path: PathBuf,
        /// The element and what is wrong with it.
        what: String,
    },
    /// The scene is larger than the import budget.
    #[error(
        "{path}: the scene has {triangles} triangles (mesh instances × triangles per mesh), \
         over the limit of {limit}; simplify or decimate the scene"
    )]
    Budget {
        /// The scene file.
        path: PathBuf,
        /// Triangles the file declares.
        triangles: u64,
        /// The limit.
        limit: u64,
    },
    /// The scene's mesh instances read more vertices than the budget allows
    /// (each instance reads its mesh's vertices again).
    #[error(
        "{path}: the scene reads {vertices} vertices (mesh instances × vertices per mesh), \
         over the limit of {limit}; simplify or decimate the scene"
    )]
    VertexBudget {
        /// The scene file.
        path: PathBuf,
        /// Vertices the file declares, summed over instances.
        vertices: u64,
        /// The limit (3 × [`ImportLimits::max_triangles`]).
        limit: u64,
    },
    /// A mesh primitive's data is inconsistent (e.g. an index past the vertex count).
    #[error("{path}: mesh {mesh:?} primitive {primitive}: {what}")]
    BadPrimitive {
        /// The scene file.
        path: PathBuf,
        /// Mesh name or index.
        mesh: String,
        /// Primitive index inside the mesh.
        primitive: usize,
        /// What is wrong.
        what: String,
    },
}

/// Limits of one import.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImportLimits {
    /// Triangles at most, counted as declared (instances × triangles of
    /// their mesh), before degenerate ones are dropped.
    pub max_triangles: u64,
}

impl ImportLimits {
    /// Default [`ImportLimits::max_triangles`]: 20 million. A kept triangle
    /// costs about 90 bytes in the scene and about as much again in the BVH
    /// and the view, so 20 M triangles is roughly 4 GB: beyond any stage set
    /// we expect (the bundled stage has a few thousand), still loadable.
    pub const MAX_TRIANGLES: u64 = 20_000_000;
}

impl Default for ImportLimits {
    fn default() -> Self {
        Self { max_triangles: Self::MAX_TRIANGLES }
    }
}

/// Elements at most in an accessor without a bufferView (read as zeros,
/// usually under sparse values): 2^20. Such an accessor has no buffer that
/// bounds its count, so without this one line of JSON could ask for gigabytes.
pub const MAX_ZERO_ELEMENTS: u64 = 1 << 20;

/// Loads a glTF/GLB file into a [`Scene`] with its BVH, under the default [`ImportLimits`].
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    load_with(path, &ImportLimits::default())
}

/// [`load`] under explicit limits.
pub fn load_with(path: &Path, limits: &ImportLimits) -> Result<Scene, SceneError> {
    Importer { path, limits, within: Within::Folder }.load()
}

struct Importer<'a> {
    path: &'a Path,
    limits: &'a ImportLimits,
    /// Where the file's URIs resolve.
    within: Within<'a>,
}

/// Where a glTF file's buffer and image URIs (other than `data:`) resolve.
#[derive(Clone, Copy)]
enum Within<'a> {
    /// A file on disk: relative paths inside its folder.
    Folder,
    /// Bytes with nothing around them (a fixture body's model): `path` is a
    /// label, so only `data:` URIs and the GLB chunk can be read.
    Nothing,
    /// An entry of an archive (an MVR's model): relative paths from the
    /// entry's folder, inside the archive and nowhere else.
    Archive { archive: &'a footlight_mvr::archive::Archive, entry: &'a str },
}

/// Adds a glTF/GLB file given as bytes (named `label` in messages) to
/// `builder`, every vertex placed by `placement` after the file's node
/// transforms. External URIs are refused (there is nothing to resolve them
/// in); `data:` URIs and the GLB binary chunk are read. Returns the count of
/// NaN/Inf vertex normals (replaced).
pub fn import_bytes_into(
    label: &Path,
    bytes: &[u8],
    builder: &mut SceneBuilder,
    placement: Mat4,
    limits: &ImportLimits,
) -> Result<usize, SceneError> {
    Importer { path: label, limits, within: Within::Nothing }.import_into(bytes, builder, placement)
}

/// [`import_bytes_into`] for the model `entry` of an MVR archive (its
/// bytes `bytes`): a buffer or image URI relative to the entry's folder
/// reads that file **of the archive** (a `.gltf` with its `.bin`, a GLB
/// whose texture is a PNG beside it; issue 36 item 4), confined to it: no
/// scheme, no absolute path, no `..` component; a buffer reads exactly its
/// `byteLength` (a shorter entry is an error), an image at most
/// [`MAX_IMAGE_BYTES`]; the archive's own limits (sizes, ratios) were
/// checked when it was opened.
pub fn import_archive_entry(
    archive: &footlight_mvr::archive::Archive,
    entry: &str,
    bytes: &[u8],
    builder: &mut SceneBuilder,
    placement: Mat4,
    limits: &ImportLimits,
) -> Result<usize, SceneError> {
    let label = archive.label(entry);
    Importer { path: &label, limits, within: Within::Archive { archive, entry } }.import_into(bytes, builder, placement)
}

/// What a checked accessor reads as.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Want {
    /// VEC3 of FLOAT (POSITION, NORMAL).
    Vec3,
    /// SCALAR of UNSIGNED_BYTE/SHORT/INT (indices).
    Index,
    /// VEC2 of FLOAT (TEXCOORD_0).
    Vec2,
}

/// Bytes at most read for one image file beside the scene (256 MiB).
pub const MAX_IMAGE_BYTES: u64 = 256 << 20;

/// An accessor whose every byte range was checked against its buffer.
#[derive(Clone, Debug)]
struct Span {
    /// Buffer index and the byte offset of the first element in it.
    base: Option<(usize, u64)>,
    stride: u64,
    count: u64,
    /// Bytes per component (1, 2 or 4).
    component: u64,
    sparse: Option<SparseSpan>,
}

#[derive(Clone, Debug)]
struct SparseSpan {
    count: u64,
    indices: (usize, u64),
    index_size: u64,
    values: (usize, u64),
}

impl Importer<'_> {
    fn invalid(&self, what: impl Into<String>) -> SceneError {
        SceneError::Invalid { path: self.path.to_path_buf(), what: what.into() }
    }

    fn load(&self) -> Result<Scene, SceneError> {
        let path = self.path;
        let bytes = self.read_scene_file()?;
        let mut builder = SceneBuilder::new();
        let non_finite_normals = self.import_into(&bytes, &mut builder, Mat4::IDENTITY)?;
        drop(bytes);
        let mut scene = builder.build();
        scene.report.non_finite_normals = non_finite_normals;
        let r = scene.report;
        if r.non_finite + r.degenerate > 0 {
            tracing::warn!(
                "{}: dropped {} triangle(s) with NaN/Inf vertices and {} with zero area",
                path.display(),
                r.non_finite,
                r.degenerate
            );
        }
        if scene.triangle_count() == 0 {
            tracing::warn!("{}: the scene has no triangles; renders will be black", path.display());
        }
        Ok(scene)
    }

    /// Adds the file's triangles (placed by `placement` after their node
    /// transforms), materials and first camera to `builder`; returns how
    /// many vertex normals were NaN/Inf.
    fn import_into(&self, bytes: &[u8], builder: &mut SceneBuilder, placement: Mat4) -> Result<usize, SceneError> {
        let path = self.path;
        let gltf::Gltf { document, blob } = gltf::Gltf::from_slice_without_validation(bytes)
            .map_err(|source| SceneError::Gltf { path: path.to_path_buf(), source })?;
        let root = document.into_json();
        self.check_validator_preconditions(&root)?;
        let doc =
            gltf::Document::from_json(root).map_err(|source| SceneError::Gltf { path: path.to_path_buf(), source })?;
        let root = doc.as_json();

        self.check_cameras(root)?;
        let material_index = self.materials(&doc)?;
        let instances = self.walk_nodes(&doc)?;

        // Accessors and the budget, from declared sizes only (nothing allocated yet).
        let (mut triangles, mut vertices): (u64, u64) = (0, 0);
        for &(node, _) in &instances {
            let Some(mesh) = root.nodes[node].mesh else { continue };
            for (pi, prim) in root.meshes[mesh.value()].primitives.iter().enumerate() {
                let Some(mode) = triangle_mode(prim) else { continue };
                let (positions, _normals, indices) = self.primitive_spans(root, mesh.value(), pi, prim)?;
                let n = indices.as_ref().map_or(positions.count, |i| i.count);
                triangles = triangles.saturating_add(triangle_count(mode, n));
                vertices = vertices.saturating_add(positions.count);
            }
        }
        if triangles > self.limits.max_triangles {
            return Err(SceneError::Budget { path: path.to_path_buf(), triangles, limit: self.limits.max_triangles });
        }
        let vertex_limit = self.limits.max_triangles.saturating_mul(3);
        if vertices > vertex_limit {
            return Err(SceneError::VertexBudget { path: path.to_path_buf(), vertices, limit: vertex_limit });
        }

        let buffers = self.buffers(root, blob)?;
        let mut material_index = material_index;
        self.attach_textures(&doc, &buffers, &mut material_index);
        let textured: Vec<bool> = material_index.iter().map(|m| m.base_texture.is_some()).collect();
        let mut bad_texcoords = 0usize;
        // glTF material i is builder material `first_material + i`; no material: the default grey 0.
        let first_material = builder.material_count() as u32;
        for m in material_index {
            builder.add_material(m);
        }
        let mut skipped_modes = 0usize;
        let mut non_finite_normals = 0usize;
        let mut camera: Option<Camera> = None;
        for &(node, world) in &instances {
            let world = placement * world;
            let n = &root.nodes[node];
            if camera.is_none()
                && let Some(c) = n.camera
                && let Some(p) = &root.cameras[c.value()].perspective
            {
                let (_s, rotation, translation) = world.to_scale_rotation_translation();
                camera = Some(Camera::from_rotation(translation, rotation, p.yfov));
            }
            let Some(mesh_index) = n.mesh else { continue };
            let mesh = &root.meshes[mesh_index.value()];
            let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
            let flip = Mat3::from_mat4(world).determinant() < 0.0;
            for (pi, prim) in mesh.primitives.iter().enumerate() {
                let bad = |what: String| SceneError::BadPrimitive {
                    path: path.to_path_buf(),
                    mesh: mesh.name.clone().unwrap_or_else(|| mesh_index.value().to_string()),
                    primitive: pi,
                    what,
                };
                let Some(mode) = triangle_mode(prim) else {
                    skipped_modes += 1;
                    continue;
                };
                let (pos_span, normal_span, index_span) = self.primitive_spans(root, mesh_index.value(), pi, prim)?;
                let positions: Vec<Vec3> = read_vec3(&pos_span, &buffers)
                    .map_err(|e| bad(format!("POSITION: {e}")))?
                    .into_iter()
                    .map(|p| world.transform_point3(Vec3::from(p)))
                    .collect();
                let normals: Option<Vec<Vec3>> = match &normal_span {
                    Some(s) => Some(
                        read_vec3(s, &buffers)
                            .map_err(|e| bad(format!("NORMAL: {e}")))?
                            .into_iter()
                            .map(|n| {
                                let n = Vec3::from(n);
                                if !n.is_finite() {
                                    non_finite_normals += 1;
                                }
                                (normal_matrix * n).normalize_or_zero()
                            })
                            .collect(),
                    ),
                    None => None,
                };
                let indices: Vec<u32> = match &index_span {
                    Some(s) => read_indices(s, &buffers).map_err(|e| bad(format!("indices: {e}")))?,
                    None => (0..positions.len() as u32).collect(),
                };
                if let Some(&bad_index) = indices.iter().find(|&&i| i as usize >= positions.len()) {
                    return Err(bad(format!("index {bad_index} past the {} vertices", positions.len())));
                }
                let material = prim.material.map_or(0, |m| m.value() as u32 + first_material);
                // Texture coordinates, read only where a base-colour texture uses them.
                let uvs: Option<Vec<Vec2>> = match prim.material {
                    Some(m) if textured.get(m.value()).copied().unwrap_or(false) => {
                        match self.texcoords(root, prim, pos_span.count, &buffers) {
                            Ok(uv) => uv,
                            Err(e) => {
                                tracing::warn!("{}: {}", path.display(), bad(e).to_string());
                                bad_texcoords += 1;
                                None
                            }
                        }
                    }
                    _ => None,
                };
                for [a, b, c] in triangle_list(mode, &indices) {
                    let (b, c) = if flip { (c, b) } else { (b, c) };
                    let p = [positions[a as usize], positions[b as usize], positions[c as usize]];
                    let n = normals.as_ref().map(|n| [n[a as usize], n[b as usize], n[c as usize]]);
                    let uv = uvs.as_ref().map_or([Vec2::ZERO; 3], |t| [t[a as usize], t[b as usize], t[c as usize]]);
                    builder.add_triangle_uv(p, n, uv, material);
                }
            }
        }
        if bad_texcoords > 0 {
            tracing::warn!(
                "{}: {bad_texcoords} textured primitive(s) without usable TEXCOORD_0 read texel (0, 0)",
                path.display()
            );
        }
        if skipped_modes > 0 {
            tracing::warn!("{}: skipped {skipped_modes} point/line primitive(s)", path.display());
        }
        if non_finite_normals > 0 {
            tracing::warn!(
                "{}: {non_finite_normals} vertex normal(s) were NaN/Inf; those vertices use their face normal",
                path.display()
            );
        }
        if let Some(cam) = camera
            && !builder.has_camera()
        {
            builder.set_camera(cam);
        }
        Ok(non_finite_normals)
    }

    /// The scene file's bytes; it must be a regular file.
    fn read_scene_file(&self) -> Result<Vec<u8>, SceneError> {
        let err = |what: String| SceneError::Read { path: self.path.to_path_buf(), what };
        // Checked before opening: opening a FIFO for reading blocks until a writer comes.
        match std::fs::metadata(self.path) {
            Ok(m) if !m.is_file() => return Err(err("not a regular file".into())),
            Ok(_) => {}
            Err(e) => return Err(err(format!("cannot open: {e}"))),
        }
        let mut file = std::fs::File::open(self.path).map_err(|e| err(format!("cannot open: {e}")))?;
        let meta = file.metadata().map_err(|e| err(format!("cannot read: {e}")))?;
        if !meta.is_file() {
            return Err(err("not a regular file".into()));
        }
        let mut bytes = Vec::with_capacity(meta.len().min(1 << 30) as usize);
        file.read_to_end(&mut bytes).map_err(|e| err(format!("cannot read: {e}")))?;
        Ok(bytes)
    }

    /// What gltf-json's validator indexes without checking (it would panic).
    fn check_validator_preconditions(&self, root: &json::Root) -> Result<(), SceneError> {
        for (mi, mesh) in root.meshes.iter().enumerate() {
            for (pi, prim) in mesh.primitives.iter().enumerate() {
                for (semantic, accessor) in &prim.attributes {
                    if accessor.value() >= root.accessors.len() {
                        let name = match semantic {
                            Checked::Valid(s) => s.to_string(),
                            Checked::Invalid => "an attribute".into(),
                        };
                        return Err(self.invalid(format!(
                            "mesh {mi} primitive {pi}: {name} names accessor {}, but the file has {} accessor(s)",
                            accessor.value(),
                            root.accessors.len()
                        )));
                    }
                }
            }
        }
        Ok(())
    }

    fn check_cameras(&self, root: &json::Root) -> Result<(), SceneError> {
        for (i, c) in root.cameras.iter().enumerate() {
            let Some(p) = &c.perspective else { continue };
            let name = named("camera", i, c.name.as_deref());
            if !(p.yfov.is_finite() && p.yfov > 0.0 && p.yfov < std::f32::consts::PI) {
                return Err(self.invalid(format!(
                    "{name}: yfov {} rad must be between 0 and π (exclusive); it is the vertical field of view",
                    p.yfov
                )));
            }
            if !(p.znear.is_finite() && p.znear > 0.0) {
                return Err(self.invalid(format!("{name}: znear {} must be a finite number > 0", p.znear)));
            }
            if let Some(a) = p.aspect_ratio
                && !(a.is_finite() && a > 0.0)
            {
                return Err(self.invalid(format!("{name}: aspectRatio {a} must be a finite number > 0")));
            }
        }
        Ok(())
    }

    /// The material table (glTF material i is scene material i + 1). A
    /// non-finite factor is an error; one outside its glTF range is clamped
    /// by [`Material::from_pbr`] after a warning.
    fn materials(&self, doc: &gltf::Document) -> Result<Vec<Material>, SceneError> {
        let mut out = Vec::new();
        for (i, m) in doc.materials().enumerate() {
            let name = m.name().map(str::to_string).unwrap_or_else(|| format!("material {i}"));
            let label = named("material", i, m.name());
            let pbr = m.pbr_metallic_roughness();
            let [r, g, b, a] = pbr.base_color_factor();
            let transmission = m.transmission().map(|t| t.transmission_factor()).unwrap_or(0.0);
            let ior = m.ior().unwrap_or(1.5);
            let factors = [
                ("baseColorFactor[0]", r, 0.0, 1.0),
                ("baseColorFactor[1]", g, 0.0, 1.0),
                ("baseColorFactor[2]", b, 0.0, 1.0),
                ("baseColorFactor[3]", a, 0.0, 1.0),
                ("metallicFactor", pbr.metallic_factor(), 0.0, 1.0),
                ("roughnessFactor", pbr.roughness_factor(), 0.0, 1.0),
                ("transmissionFactor", transmission, 0.0, 1.0),
                ("ior", ior, 1.0, f32::INFINITY),
            ];
            for (key, v, lo, hi) in factors {
                if !v.is_finite() {
                    return Err(self.invalid(format!("{label}: {key} is {v}; give a finite number in {lo}..{hi}")));
                }
                if v < lo || v > hi {
                    tracing::warn!(
                        "{}: {label}: {key} {v} is outside its glTF range {lo}..{hi}; it is clamped",
                        self.path.display()
                    );
                }
            }
            out.push(Material::from_pbr(
                &name,
                Vec3::new(r, g, b),
                pbr.metallic_factor(),
                pbr.roughness_factor(),
                transmission,
                ior,
            ));
        }
        Ok(out)
    }

    /// The scene's nodes with their world transforms, each reached exactly
    /// once (a cycle or a shared subtree is an error naming the node).
    fn walk_nodes(&self, doc: &gltf::Document) -> Result<Vec<(usize, Mat4)>, SceneError> {
        let root = doc.as_json();
        let gnodes: Vec<gltf::Node> = doc.nodes().collect();
        let scene = root.scene.map(|s| s.value()).or(if root.scenes.is_empty() { None } else { Some(0) });
        let Some(scene) = scene else { return Ok(Vec::new()) };
        let nodes = &root.nodes;
        let node_name = |i: usize| named("node", i, nodes[i].name.as_deref());
        // parent[i]: None = not reached yet; Some(None) = a scene root; Some(Some(p)) = child of p.
        let mut parent: Vec<Option<Option<usize>>> = vec![None; nodes.len()];
        let mut out = Vec::new();
        // Depth first, last child first (the order of earlier versions, so
        // triangle ids and the first camera stay as they were).
        let mut stack: Vec<(usize, Option<usize>, Mat4)> =
            root.scenes[scene].nodes.iter().map(|n| (n.value(), None, Mat4::IDENTITY)).collect();
        while let Some((i, from, parent_world)) = stack.pop() {
            if let Some(first) = parent[i] {
                // A cycle if `i` is an ancestor of the node that reached it again.
                let mut a = from;
                let mut depth = 0;
                while let Some(x) = a {
                    if x == i {
                        let via = from.map_or("the scene".to_string(), node_name);
                        return Err(self.invalid(format!(
                            "{}: the node hierarchy has a cycle ({via} lists it as a child, but it is \
                             {via}'s ancestor); glTF nodes must form trees",
                            node_name(i)
                        )));
                    }
                    a = parent[x].flatten();
                    depth += 1;
                    if depth > nodes.len() {
                        break;
                    }
                }
                let hint =
                    "glTF nodes must form trees (to place a mesh several times, give several nodes the same mesh)";
                let again = from.map_or("the scene".to_string(), node_name);
                if first == from {
                    return Err(self.invalid(format!("{again} lists {} twice; {hint}", node_name(i))));
                }
                let first = first.map_or("the scene".to_string(), node_name);
                return Err(
                    self.invalid(format!("{} is reached twice (from {first} and from {again}); {hint}", node_name(i)))
                );
            }
            parent[i] = Some(from);
            let n = &nodes[i];
            let local = self.node_transform(&gnodes[i])?;
            let world = parent_world * local;
            out.push((i, world));
            for c in n.children.iter().flatten() {
                stack.push((c.value(), Some(i), world));
            }
        }
        Ok(out)
    }

    /// The node's local matrix (the gltf crate's TRS composition, as
    /// before); it must be finite.
    fn node_transform(&self, node: &gltf::Node) -> Result<Mat4, SceneError> {
        let m = Mat4::from_cols_array_2d(&node.transform().matrix());
        if !m.is_finite() {
            return Err(self.invalid(format!(
                "{}: its transform (matrix or translation/rotation/scale) is not finite",
                named("node", node.index(), node.name())
            )));
        }
        Ok(m)
    }

    /// Base-colour textures (PNG, see [`super::texture`]) onto their
    /// materials; each texture is decoded once. A texture that cannot be
    /// used leaves the constant factor, with a warning naming it.
    fn attach_textures(&self, doc: &gltf::Document, buffers: &[Vec<u8>], materials: &mut [Material]) {
        let root = doc.as_json();
        let mut cache: std::collections::HashMap<usize, Option<Arc<Texture>>> = Default::default();
        let mut metallic_roughness = 0usize;
        for (i, m) in doc.materials().enumerate() {
            let pbr = m.pbr_metallic_roughness();
            if pbr.metallic_roughness_texture().is_some() {
                metallic_roughness += 1;
            }
            let Some(info) = pbr.base_color_texture() else { continue };
            let label = named("material", i, m.name());
            if info.tex_coord() != 0 {
                tracing::warn!(
                    "{}: {label}: its baseColorTexture reads TEXCOORD_{}; only TEXCOORD_0 is read, so its constant \
                     factor is used",
                    self.path.display(),
                    info.tex_coord()
                );
                continue;
            }
            let texture = info.texture();
            let decoded = cache
                .entry(texture.index())
                .or_insert_with(|| {
                    let image = texture.source();
                    let name = named("image", image.index(), image.name());
                    let bytes = match image.source() {
                        gltf::image::Source::View { view, .. } => self
                            .view(root, view.index())
                            .ok()
                            .and_then(|(b, start, len, _)| {
                                buffers.get(b)?.get(usize::try_from(start).ok()?..usize::try_from(start + len).ok()?)
                            })
                            .map(<[u8]>::to_vec)
                            .ok_or_else(|| "its bufferView is outside its buffer".to_string()),
                        gltf::image::Source::Uri { uri, .. } => {
                            self.read_uri(&name, uri, None).map_err(|e| e.to_string())
                        }
                    };
                    match bytes.and_then(|b| Texture::decode_image(&name, &b)) {
                        Ok(mut t) => {
                            let sampler = texture.sampler();
                            t.nearest = sampler.mag_filter() == Some(gltf::texture::MagFilter::Nearest);
                            let wrap = |w: gltf::texture::WrappingMode| match w {
                                gltf::texture::WrappingMode::ClampToEdge => Wrap::Clamp,
                                gltf::texture::WrappingMode::MirroredRepeat => Wrap::Mirror,
                                gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
                            };
                            t.wrap_u = wrap(sampler.wrap_s());
                            t.wrap_v = wrap(sampler.wrap_t());
                            Some(Arc::new(t))
                        }
                        Err(e) => {
                            tracing::warn!(
                                "{}: {name}: {e}; materials using it keep their constant base colour",
                                self.path.display()
                            );
                            None
                        }
                    }
                })
                .clone();
            if let Some(slot) = materials.get_mut(i) {
                slot.base_texture = decoded;
            }
        }
        if metallic_roughness > 0 {
            tracing::warn!(
                "{}: {metallic_roughness} material(s) use metallic-roughness textures; only their constant \
                 factors are used",
                self.path.display()
            );
        }
    }

    /// A primitive's TEXCOORD_0 as VEC2 FLOAT, one per position; `None`
    /// when it has none. The error says why they cannot be used.
    fn texcoords(
        &self,
        root: &json::Root,
        prim: &json::mesh::Primitive,
        positions: u64,
        buffers: &[Vec<u8>],
    ) -> Result<Option<Vec<Vec2>>, String> {
        let Some(i) = prim.attributes.get(&Checked::Valid(json::mesh::Semantic::TexCoords(0))) else {
            return Ok(None);
        };
        let span = self.accessor_span(root, i.value(), Want::Vec2).map_err(|e| format!("TEXCOORD_0: {e}"))?;
        if span.count != positions {
            return Err(format!("TEXCOORD_0 has {} elements for {positions} positions", span.count));
        }
        Ok(Some(read_vec2(&span, buffers).map_err(|e| format!("TEXCOORD_0: {e}"))?))
    }

    /// The checked spans of a triangle primitive's POSITION, NORMAL and indices.
    fn primitive_spans(
        &self,
        root: &json::Root,
        mesh: usize,
        pi: usize,
        prim: &json::mesh::Primitive,
    ) -> Result<(Span, Option<Span>, Option<Span>), SceneError> {
        let mesh_name = root.meshes[mesh].name.clone().unwrap_or_else(|| mesh.to_string());
        let bad = |what: String| SceneError::BadPrimitive {
            path: self.path.to_path_buf(),
            mesh: mesh_name.clone(),
            primitive: pi,
            what,
        };
        let attr = |s: json::mesh::Semantic| prim.attributes.get(&Checked::Valid(s)).map(|i| i.value());
        let Some(pos) = attr(json::mesh::Semantic::Positions) else {
            return Err(bad("has no POSITION attribute".into()));
        };
        let positions = self.accessor_span(root, pos, Want::Vec3)?;
        let normals = match attr(json::mesh::Semantic::Normals) {
            Some(n) => {
                let s = self.accessor_span(root, n, Want::Vec3)?;
                if s.count != positions.count {
                    return Err(bad(format!(
                        "NORMAL (accessor {n}) has {} elements for {} positions (accessor {pos})",
                        s.count, positions.count
                    )));
                }
                Some(s)
            }
            None => None,
        };
        let indices = match prim.indices {
            Some(i) => Some(self.accessor_span(root, i.value(), Want::Index)?),
            None => None,
        };
        Ok((positions, normals, indices))
    }

    /// Checks accessor `i` for `want` against its view and buffer (declared
    /// `byteLength`s; the buffers are later read to exactly that length).
    fn accessor_span(&self, root: &json::Root, i: usize, want: Want) -> Result<Span, SceneError> {
        let a = &root.accessors[i];
        let label = named("accessor", i, a.name.as_deref());
        let fail = |what: String| self.invalid(format!("{label}: {what}"));
        let (ty, component) = match (&a.type_, &a.component_type) {
            (Checked::Valid(t), Checked::Valid(c)) => (*t, c.0),
            _ => return Err(fail("invalid type or componentType".into())),
        };
        use json::accessor::{ComponentType as C, Type as T};
        let component_size: u64 = match (want, ty, component) {
            (Want::Vec3, T::Vec3, C::F32) => 4,
            (Want::Vec2, T::Vec2, C::F32) => 4,
            (Want::Vec2, ..) => {
                return Err(fail(format!("is {ty:?} of {component:?}; texture coordinates are read as VEC2 of FLOAT")));
            }
            (Want::Index, T::Scalar, C::U8) => 1,
            (Want::Index, T::Scalar, C::U16) => 2,
            (Want::Index, T::Scalar, C::U32) => 4,
            (Want::Vec3, ..) => {
                return Err(fail(format!("is {ty:?} of {component:?}; positions and normals must be VEC3 of FLOAT")));
            }
            (Want::Index, ..) => {
                return Err(fail(format!(
                    "is {ty:?} of {component:?}; indices must be SCALAR of UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT"
                )));
            }
        };
        if a.normalized {
            return Err(fail("is normalized; positions, normals and indices must not be".into()));
        }
        let elem = component_size
            * match want {
                Want::Vec3 => 3,
                Want::Vec2 => 2,
                Want::Index => 1,
            };
        let count = a.count.0;
        if count == 0 {
            return Err(fail("count is 0 (glTF requires at least 1)".into()));
        }
        let (base, stride) = match a.buffer_view {
            Some(v) => {
                let (buffer, start, len, stride) = self.view(root, v.value())?;
                let stride = stride.unwrap_or(elem);
                if stride < elem {
                    return Err(fail(format!(
                        "bufferView {} has byteStride {stride}, less than the {elem}-byte element",
                        v.value()
                    )));
                }
                let offset = a.byte_offset.map_or(0, |o| o.0);
                let need = (count - 1)
                    .checked_mul(stride)
                    .and_then(|x| x.checked_add(offset))
                    .and_then(|x| x.checked_add(elem));
                match need {
                    Some(n) if n <= len => {}
                    _ => {
                        let need = need.map_or("more than 2^64".to_string(), |n| n.to_string());
                        return Err(fail(format!(
                            "count {count} × stride {stride} from byteOffset {offset} needs {need} bytes, \
                             but bufferView {} has {len}",
                            v.value()
                        )));
                    }
                }
                (Some((buffer, start + offset)), stride)
            }
            None => {
                // All zeros (then usually sparse): no buffer bounds the count, so a fixed limit does.
                if count > MAX_ZERO_ELEMENTS {
                    return Err(fail(format!(
                        "count {count} without a bufferView is over the limit of {MAX_ZERO_ELEMENTS} elements"
                    )));
                }
                (None, elem)
            }
        };
        let sparse = match &a.sparse {
            None => None,
            Some(s) => {
                let n = s.count.0;
                if n == 0 || n > count {
                    return Err(fail(format!("sparse count {n} must be in 1..{count}")));
                }
                let index_size: u64 = match &s.indices.component_type {
                    Checked::Valid(c) => match c.0 {
                        C::U8 => 1,
                        C::U16 => 2,
                        C::U32 => 4,
                        other => return Err(fail(format!("sparse indices of {other:?}"))),
                    },
                    Checked::Invalid => return Err(fail("sparse indices have an invalid componentType".into())),
                };
                let part = |what: &str, view: usize, offset: u64, size: u64| -> Result<(usize, u64), SceneError> {
                    let (buffer, start, len, _) = self.view(root, view)?;
                    match n.checked_mul(size).and_then(|x| x.checked_add(offset)) {
                        Some(need) if need <= len => Ok((buffer, start + offset)),
                        _ => Err(fail(format!(
                            "sparse {what}: {n} × {size} bytes from byteOffset {offset} do not fit the {len} bytes of bufferView {view}"
                        ))),
                    }
                };
                let indices = part("indices", s.indices.buffer_view.value(), s.indices.byte_offset.0, index_size)?;
                let values = part("values", s.values.buffer_view.value(), s.values.byte_offset.0, elem)?;
                Some(SparseSpan { count: n, indices, index_size, values })
            }
        };
        Ok(Span { base, stride, count, component: component_size, sparse })
    }

    /// Buffer view `v`: its buffer, start, length and stride, checked
    /// against the buffer's declared `byteLength`.
    fn view(&self, root: &json::Root, v: usize) -> Result<(usize, u64, u64, Option<u64>), SceneError> {
        let view = &root.buffer_views[v];
        let b = view.buffer.value();
        let buffer_len = root.buffers[b].byte_length.0;
        let start = view.byte_offset.map_or(0, |o| o.0);
        let len = view.byte_length.0;
        if start.checked_add(len).is_none_or(|end| end > buffer_len) {
            return Err(self.invalid(format!(
                "{}: byteOffset {start} + byteLength {len} run past the {buffer_len} bytes of buffer {b}",
                named("bufferView", v, view.name.as_deref())
            )));
        }
        Ok((b, start, len, view.byte_stride.map(|s| s.0 as u64)))
    }

    /// Every buffer's bytes, exactly `byteLength` long.
    fn buffers(&self, root: &json::Root, mut blob: Option<Vec<u8>>) -> Result<Vec<Vec<u8>>, SceneError> {
        let mut out = Vec::with_capacity(root.buffers.len());
        for (i, b) in root.buffers.iter().enumerate() {
            let label = named("buffer", i, b.name.as_deref());
            let want = b.byte_length.0;
            let mut data = match &b.uri {
                None => blob.take().ok_or_else(|| {
                    self.invalid(format!("{label} has no uri and there is no (further) GLB binary chunk"))
                })?,
                Some(uri) => self.read_uri(&label, uri, Some(want))?,
            };
            if (data.len() as u64) < want {
                return Err(
                    self.invalid(format!("{label}: byteLength is {want}, but its data has only {} bytes", data.len()))
                );
            }
            data.truncate(want as usize);
            out.push(data);
        }
        Ok(out)
    }

    /// A buffer's or image's URI: base64 `data:`, or a relative path inside
    /// the scene's folder (see the module docs); exactly `want` bytes are
    /// read (a shorter file is an error), or with `None` the whole file up
    /// to [`MAX_IMAGE_BYTES`].
    fn read_uri(&self, label: &str, uri: &str, want: Option<u64>) -> Result<Vec<u8>, SceneError> {
        let shown: String = uri.chars().take(80).collect();
        let refuse = |why: &str| self.invalid(format!("{label}: uri {shown:?} refused: {why}"));
        if let Some(rest) = uri.strip_prefix("data:") {
            let Some((_, payload)) = rest.split_once(";base64,") else {
                return Err(refuse("only base64 data URIs are supported"));
            };
            return base64::decode(payload).map_err(|e| refuse(&format!("bad base64 ({e})")));
        }
        let decoded = urlencoding::decode(uri).map_err(|_| refuse("its %-escapes are not UTF-8"))?;
        match self.within {
            Within::Folder => {}
            Within::Nothing => {
                return Err(refuse("a model given without its folder can only use data: URIs or the GLB binary chunk"));
            }
            Within::Archive { archive, entry } => return self.read_archive_uri(label, &decoded, want, archive, entry),
        }
        let rel = Path::new(decoded.as_ref());
        let scheme = decoded
            .split_once(':')
            .is_some_and(|(s, _)| !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c)));
        if scheme {
            return Err(refuse("only data: URIs and paths relative to the scene file are allowed"));
        }
        if decoded.is_empty() || rel.is_absolute() || decoded.starts_with(['/', '\\']) {
            return Err(refuse("absolute paths are not allowed; give a path relative to the scene file"));
        }
        let dir = self.path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
        let dir = dir.canonicalize().map_err(|e| refuse(&format!("the scene folder cannot be resolved ({e})")))?;
        let target = dir.join(rel).canonicalize().map_err(|e| refuse(&format!("cannot open ({e})")))?;
        if !target.starts_with(&dir) {
            return Err(refuse(&format!("it resolves outside the scene folder {}", dir.display())));
        }
        // Checked before opening: opening a FIFO for reading blocks until a writer comes.
        if !std::fs::metadata(&target).is_ok_and(|m| m.is_file()) {
            return Err(refuse("not a regular file"));
        }
        let file = std::fs::File::open(&target).map_err(|e| refuse(&format!("cannot open ({e})")))?;
        let meta = file.metadata().map_err(|e| refuse(&format!("cannot read ({e})")))?;
        if !meta.is_file() {
            return Err(refuse("not a regular file"));
        }
        let want = want.unwrap_or(meta.len().min(MAX_IMAGE_BYTES));
        if meta.len() < want {
            return Err(self.invalid(format!(
                "{label}: byteLength is {want}, but {} has only {} bytes",
                target.display(),
                meta.len()
            )));
        }
        let mut data = Vec::with_capacity(want as usize);
        file.take(want).read_to_end(&mut data).map_err(|e| refuse(&format!("cannot read ({e})")))?;
        Ok(data)
    }
}

impl Importer<'_> {
    /// A relative URI (`decoded`: its %-escapes already decoded) of a model
    /// that is entry `entry` of `archive`: the archive's file at the entry's
    /// folder joined with it (`\` read as `/`, `.` dropped); a scheme, an
    /// absolute path or a `..` component is refused, so it never leaves the
    /// archive (see [`import_archive_entry`]).
    fn read_archive_uri(
        &self,
        label: &str,
        decoded: &str,
        want: Option<u64>,
        archive: &footlight_mvr::archive::Archive,
        entry: &str,
    ) -> Result<Vec<u8>, SceneError> {
        let shown: String = decoded.chars().take(80).collect();
        let refuse = |why: &str| self.invalid(format!("{label}: uri {shown:?} refused: {why}"));
        let name = decoded.replace('\\', "/");
        let scheme = name
            .split_once(':')
            .is_some_and(|(s, _)| !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c)));
        if footlight_mvr::archive::unsafe_name(&name).is_some() || name.starts_with('/') {
            return Err(refuse("absolute paths, `..` components and NUL bytes are not allowed inside an MVR archive"));
        }
        if scheme {
            return Err(refuse("only data: URIs and paths relative to the model inside the MVR archive are allowed"));
        }
        let folder = entry.rfind(['/', '\\']).map_or("", |i| &entry[..i]);
        let parts: Vec<&str> =
            folder.split(['/', '\\']).chain(name.split('/')).filter(|c| !c.is_empty() && *c != ".").collect();
        if parts.is_empty() {
            return Err(refuse("it names no file"));
        }
        let joined = parts.join("/");
        let Some(data) = archive.get(&joined) else {
            return Err(refuse(&format!("{joined:?} is not in the archive {}", archive.path.display())));
        };
        match want {
            Some(want) if (data.len() as u64) < want => Err(self.invalid(format!(
                "{label}: byteLength is {want}, but {joined:?} in the archive has only {} bytes",
                data.len()
            ))),
            Some(want) => Ok(data[..want as usize].to_vec()),
            None if data.len() as u64 > MAX_IMAGE_BYTES => {
                Err(refuse(&format!("{joined:?} is larger than {MAX_IMAGE_BYTES} bytes")))
            }
            None => Ok(data.to_vec()),
        }
    }
}

/// `kind i "name"` for messages.
fn named(kind: &str, i: usize, name: Option<&str>) -> String {
    match name {
        Some(n) => format!("{kind} {i} {:?}", n.chars().take(60).collect::<String>()),
        None => format!("{kind} {i}"),
    }
}

/// The primitive's mode when it is made of triangles.
fn triangle_mode(prim: &json::mesh::Primitive) -> Option<gltf::mesh::Mode> {
    use gltf::mesh::Mode;
    match prim.mode {
        Checked::Valid(m @ (Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan)) => Some(m),
        _ => None,
    }
}

/// Triangles from `n` indices (or vertices) in `mode` (glTF 2.0 §3.7.2.1).
fn triangle_count(mode: gltf::mesh::Mode, n: u64) -> u64 {
    match mode {
        gltf::mesh::Mode::Triangles => n / 3,
        _ => n.saturating_sub(2),
    }
}

/// Element `k` of a checked span: its bytes.
fn element(buffers: &[Vec<u8>], at: (usize, u64), stride: u64, k: u64, size: u64) -> Option<&[u8]> {
    let start = usize::try_from(at.1 + k * stride).ok()?;
    buffers.get(at.0)?.get(start..start + size as usize)
}

/// Reads a checked VEC3/FLOAT span (sparse substitution included).
fn read_vec3(s: &Span, buffers: &[Vec<u8>]) -> Result<Vec<[f32; 3]>, String> {
    let f = |b: &[u8]| -> [f32; 3] {
        let c = |j: usize| f32::from_le_bytes([b[4 * j], b[4 * j + 1], b[4 * j + 2], b[4 * j + 3]]);
        [c(0), c(1), c(2)]
    };
    let mut out = match s.base {
        Some(at) => (0..s.count)
            .map(|k| element(buffers, at, s.stride, k, 12).map(f).ok_or("element past its buffer"))
            .collect::<Result<Vec<_>, _>>()?,
        None => vec![[0.0; 3]; s.count as usize],
    };
    if let Some(sp) = &s.sparse {
        for (k, i) in sparse_indices(sp, s.count, buffers)?.into_iter().enumerate() {
            let v = element(buffers, sp.values, 12, k as u64, 12).map(f).ok_or("sparse value past its buffer")?;
            out[i as usize] = v;
        }
    }
    Ok(out)
}

/// Reads a checked VEC2/FLOAT span (sparse substitution included).
fn read_vec2(s: &Span, buffers: &[Vec<u8>]) -> Result<Vec<Vec2>, String> {
    let f = |b: &[u8]| -> Vec2 {
        let c = |j: usize| f32::from_le_bytes([b[4 * j], b[4 * j + 1], b[4 * j + 2], b[4 * j + 3]]);
        Vec2::new(c(0), c(1))
    };
    let mut out = match s.base {
        Some(at) => (0..s.count)
            .map(|k| element(buffers, at, s.stride, k, 8).map(f).ok_or("element past its buffer"))
            .collect::<Result<Vec<_>, _>>()?,
        None => vec![Vec2::ZERO; s.count as usize],
    };
    if let Some(sp) = &s.sparse {
        for (k, i) in sparse_indices(sp, s.count, buffers)?.into_iter().enumerate() {
            out[i as usize] =
                element(buffers, sp.values, 8, k as u64, 8).map(f).ok_or("sparse value past its buffer")?;
        }
    }
    Ok(out)
}

/// Reads a checked SCALAR index span.
fn read_indices(s: &Span, buffers: &[Vec<u8>]) -> Result<Vec<u32>, String> {
    let size = s.component;
    let f = |b: &[u8]| -> u32 {
        match size {
            1 => u32::from(b[0]),
            2 => u32::from(u16::from_le_bytes([b[0], b[1]])),
            _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        }
    };
    let mut out = match s.base {
        Some(at) => (0..s.count)
            .map(|k| element(buffers, at, s.stride, k, size).map(f).ok_or("element past its buffer"))
            .collect::<Result<Vec<_>, _>>()?,
        None => vec![0; s.count as usize],
    };
    if let Some(sp) = &s.sparse {
        for (k, i) in sparse_indices(sp, s.count, buffers)?.into_iter().enumerate() {
            out[i as usize] =
                element(buffers, sp.values, size, k as u64, size).map(f).ok_or("sparse value past its buffer")?;
        }
    }
    Ok(out)
}

/// A sparse accessor's indices: strictly increasing, below `count`.
fn sparse_indices(sp: &SparseSpan, count: u64, buffers: &[Vec<u8>]) -> Result<Vec<u32>, String> {
    let mut out = Vec::with_capacity(sp.count as usize);
    for k in 0..sp.count {
        let b = element(buffers, sp.indices, sp.index_size, k, sp.index_size).ok_or("sparse index past its buffer")?;
        let i = match sp.index_size {
            1 => u32::from(b[0]),
            2 => u32::from(u16::from_le_bytes([b[0], b[1]])),
            _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        };
        if u64::from(i) >= count {
            return Err(format!("sparse index {i} past the {count} elements"));
        }
        if out.last().is_some_and(|&p| p >= i) {
            return Err(format!(
                "sparse indices must strictly increase ({i} after {})",
                out.last().copied().unwrap_or(0)
            ));
        }
        out.push(i);
    }
    Ok(out)
}

/// Expands strip and fan index sequences into triangles (glTF 2.0 §3.7.2.1).
fn triangle_list(mode: gltf::mesh::Mode, idx: &[u32]) -> Vec<[u32; 3]> {
    use gltf::mesh::Mode;
    match mode {
        Mode::Triangles => idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        Mode::TriangleStrip => (2..idx.len())
            .map(|i| if i % 2 == 0 { [idx[i - 2], idx[i - 1], idx[i]] } else { [idx[i - 1], idx[i - 2], idx[i]] })
            .collect(),
        Mode::TriangleFan => (2..idx.len()).map(|i| [idx[0], idx[i - 1], idx[i]]).collect(),
        _ => Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans_expand() {
        use gltf::mesh::Mode;
        assert_eq!(triangle_list(Mode::TriangleStrip, &[0, 1, 2, 3]), vec![[0, 1, 2], [2, 1, 3]]);
        assert_eq!(triangle_list(Mode::TriangleFan, &[0, 1, 2, 3]), vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(triangle_list(Mode::Triangles, &[0, 1, 2, 3]), vec![[0, 1, 2]]);
        assert_eq!(triangle_count(Mode::Triangles, 4), 1);
        assert_eq!(triangle_count(Mode::TriangleStrip, 4), 2);
        assert_eq!(triangle_count(Mode::TriangleFan, 1), 0);
    }

    #[test]
    fn broken_file_names_the_file() {
        let dir = std::env::temp_dir().join(format!("footlight-gltf-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("broken.gltf");
        std::fs::write(&path, b"{ \"asset\": { \"version\": \"2.0\" }, \"meshes\": [ { \"primitives\": [ { \"attributes\": { \"POSITION\": 7 } } ] } ] }").unwrap();
        let err = match load(&path) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("broken file loaded"),
        };
        assert!(err.contains("broken.gltf") && err.contains("accessor 7"), "{err}");
        std::fs::write(&path, b"not json").unwrap();
        let err = load(&path).err().unwrap().to_string();
        assert!(err.contains("broken.gltf"), "{err}");
    }
}
