//! An MVR file's geometry as the stage (issue 14 item 4): every scene
//! object, truss, support, video screen and projector with its 3D files from
//! the archive, placed by its world matrix (layers, group objects and
//! symdef/symbol instancing already composed by `footlight_mvr::mvr`).
//!
//! Units and axes are converted once, here (DIN SPEC 15800, "Geometry3D",
//! as BlenderDMX reads it too):
//! * **glTF/GLB** models are glTF's own convention (metres, Y up). MVR's
//!   world is millimetres, Z up, so in MVR space a model is scaled by 1000 and
//!   turned Y up → Z up; the MVR → stage conversion (`mvr::stage_matrix`:
//!   mm → m, Z up → Y up) undoes exactly that, so a GLB vertex goes through
//!   `stage_matrix(world)` unchanged.
//! * **3DS** models are in the MVR frame (millimetres, Z up): each vertex is
//!   converted like a world point, `C · p / 1000` (C: Z up → Y up, −90°
//!   about X), then placed by `stage_matrix(world)`. The vertices of a 3DS
//!   file are stored in its world frame (its mesh matrix only records how
//!   they were placed), so the mesh matrix is not applied again. Their
//!   materials ([`ds3_materials`]: diffuse colour, diffuse texture map) become
//!   Lambert materials, made once per file; a map is looked up in the archive
//!   beside the `.3ds`, then at its root. Each face takes the material of its
//!   face group (`MSH_MAT_GROUP`), else the mesh's, else a grey stand-in.
//! * A model the archive does not hold, or cannot be read, becomes a
//!   primitive stand-in: a 0.5 m grey cube at the object's origin
//!   (estimated size; MVR gives no dimensions for a scene object), with a
//!   warning naming the object and the file.
//!
//! The whole import shares one triangle budget ([`ImportLimits`]), counted
//! over every instance of every model.

pub mod ds3_materials;

use super::{ImportLimits, Material, Scene, SceneBuilder, SceneError, Texture};
use footlight_mvr::mvr::{Mvr, ObjectKind, stage_matrix};
use glam::{DMat4, Mat4, Vec2, Vec3};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Edge of the stand-in cube for a missing model, metres (estimated: the
/// size of a flight case; MVR gives no dimensions for a scene object).
pub const STAND_IN_EDGE: f32 = 0.5;

/// The MVR's scene geometry, and the warnings of its import.
pub struct MvrScene {
    /// The stage built from the MVR's 3D files.
    pub scene: Scene,
    /// Problems that did not stop the import (missing or unreadable models:
    /// stand-ins), each naming the MVR entry and the object.
    pub warnings: Vec<String>,
    /// Scene objects read, with a model or a stand-in.
    pub objects: usize,
}

/// Loads the geometry of the MVR file at `path` under the default limits.
pub fn load_mvr_scene(path: &Path) -> Result<MvrScene, SceneError> {
    load_mvr_scene_with(path, &ImportLimits::default())
}

/// [`load_mvr_scene`] under explicit limits (the triangle budget covers
/// every instance of every model together).
pub fn load_mvr_scene_with(path: &Path, limits: &ImportLimits) -> Result<MvrScene, SceneError> {
    let mvr = Mvr::open(path).map_err(|e| SceneError::Read { path: path.to_path_buf(), what: e.to_string() })?;
    let mut builder = SceneBuilder::new();
    let stand_in = builder.add_material(Material::lambert("MVR stand-in (missing model)", Vec3::splat(0.5)));
    // The scene description's own warnings (bad matrices…) come with the patch (`load_mvr`).
    let mut warnings: Vec<String> = Vec::new();
    // 3DS files are parsed once, however often they are instanced.
    // Their materials too: shared by every instance of the file.
    let mut parsed_3ds: BTreeMap<String, Result<(ds3::Scene3ds, Materials3ds), String>> = BTreeMap::new();
    let mut non_finite_normals = 0usize;
    let mut objects = 0usize;
    // Stand-ins by problem (a missing model named by 300 seats is one line).
    let mut stand_ins = StandIns::default();
    for object in &mvr.scene.objects {
        objects += 1;
        let what = format!("{} {:?}", kind_name(object.kind), object.name);
        if object.geometries.is_empty() {
            stand_ins.add(format!("{}: no Geometry3D or Symbol", path.display()), what);
            add_stand_in(&mut builder, object.world, stand_in);
            continue;
        }
        for (file, world) in &object.geometries {
            let label = mvr.archive.label(file);
            let budget =
                ImportLimits { max_triangles: limits.max_triangles.saturating_sub(builder.triangle_count() as u64) };
            let Some(bytes) = mvr.archive.get(file) else {
                stand_ins.add(format!("{}: the model {file:?} is not in the archive", path.display()), what.clone());
                add_stand_in(&mut builder, *world, stand_in);
                continue;
            };
            let lower = file.to_ascii_lowercase();
            let result = if lower.ends_with(".glb") || lower.ends_with(".gltf") {
                let placement = stage_matrix(*world).as_mat4();
                // Its buffers and images may be other files of the archive (issue 36 item 4).
                super::gltf_import::import_archive_entry(&mvr.archive, file, bytes, &mut builder, placement, &budget)
                    .map(|n| non_finite_normals += n)
                    .map_err(|e| match e {
                        // Over budget stops the whole import: a stand-in would hide it.
                        e @ (SceneError::Budget { .. } | SceneError::VertexBudget { .. }) => Err(e),
                        e => Ok(e.to_string()),
                    })
            } else if lower.ends_with(".3ds") {
                let parsed = parsed_3ds.entry(file.clone()).or_insert_with(|| {
                    parse_3ds(&label, bytes).map(|model| {
                        let grey = builder.add_material(Material::lambert(
                            &format!("{file} (3DS mesh without a material)"),
                            Vec3::splat(0.6),
                        ));
                        let materials =
                            materials_3ds(&label, file, bytes, &model, &mvr.archive, grey, &mut builder, &mut warnings);
                        (model, materials)
                    })
                });
                match parsed {
                    Ok((model, materials)) => {
                        add_3ds(&label, model, *world, materials, &mut builder, &budget).map_err(|e| match e {
                            e @ SceneError::Budget { .. } => Err(e),
                            e => Ok(e.to_string()),
                        })
                    }
                    Err(e) => Err(Ok(e.clone())),
                }
            } else {
                Err(Ok(format!("{}: not a glTF/GLB or 3DS model (by its extension)", label.display())))
            };
            match result {
                Ok(()) => {}
                Err(Err(fatal)) => return Err(fatal),
                Err(Ok(why)) => {
                    stand_ins.add(why, what.clone());
                    add_stand_in(&mut builder, *world, stand_in);
                }
            }
        }
    }
    warnings.extend(stand_ins.into_warnings());
    let mut scene = builder.build();
    scene.report.non_finite_normals = non_finite_normals;
    if scene.triangle_count() == 0 {
        warnings.push(format!("{}: the MVR has no scene geometry; renders will be black", path.display()));
    }
    Ok(MvrScene { scene, warnings, objects })
}

/// Objects drawn as stand-in cubes, by problem, in the order first seen:
/// one warning per problem naming a few objects and counting them.
#[derive(Default)]
struct StandIns {
    problems: Vec<(String, Vec<String>, usize)>,
}

impl StandIns {
    /// Names shown per problem before `and N more`.
    const SHOWN: usize = 4;

    fn add(&mut self, problem: String, what: String) {
        match self.problems.iter_mut().find(|(p, _, _)| *p == problem) {
            Some((_, names, n)) => {
                *n += 1;
                if names.len() < Self::SHOWN && !names.contains(&what) {
                    names.push(what);
                }
            }
            None => self.problems.push((problem, vec![what], 1)),
        }
    }

    fn into_warnings(self) -> Vec<String> {
        self.problems
            .into_iter()
            .map(|(problem, names, n)| {
                let more = n.saturating_sub(names.len());
                let who = if more > 0 { format!("{} and {more} more", names.join(", ")) } else { names.join(", ") };
                let cubes = if n == 1 { "a stand-in cube".to_string() } else { format!("{n} stand-in cubes") };
                format!("{problem}; {cubes}: {who}")
            })
            .collect()
    }
}

fn kind_name(kind: ObjectKind) -> &'static str {
    match kind {
        ObjectKind::SceneObject => "SceneObject",
        ObjectKind::Truss => "Truss",
        ObjectKind::Support => "Support",
        ObjectKind::VideoScreen => "VideoScreen",
        ObjectKind::Projector => "Projector",
    }
}

/// MVR space (Z up) → stage space (Y up), as a rotation only: −90° about X.
fn z_up_to_y_up() -> Mat4 {
    Mat4::from_rotation_x(-std::f32::consts::FRAC_PI_2)
}

/// Parses a 3DS file (`label` names it in the message) with the `ds3` crate.
pub fn parse_3ds(label: &Path, bytes: &[u8]) -> Result<ds3::Scene3ds, String> {
    ds3::parse(bytes).map_err(|e| format!("{}: not a readable 3DS file: {e}", label.display()))
}

/// The scene materials of one 3DS file's materials, made once per file and
/// shared by all its instances ([`materials_3ds`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Materials3ds {
    /// For a mesh without a material, or naming one the file does not
    /// define: the grey stand-in.
    pub fallback: u32,
    /// By 3DS material name: the scene material, and whether it has a
    /// base-colour texture (then the mesh's texture coordinates are passed).
    pub by_name: BTreeMap<String, (u32, bool)>,
    /// Per mesh (`ds3`'s order): its face groups, which take precedence over
    /// `Mesh3ds::material` face by face.
    pub face_groups: Vec<Vec<ds3_materials::FaceGroup>>,
}

impl Materials3ds {
    /// Every mesh in `material`, untextured.
    pub fn uniform(material: u32) -> Self {
        Self { fallback: material, by_name: BTreeMap::new(), face_groups: Vec::new() }
    }

    fn of(&self, name: Option<&str>) -> (u32, bool) {
        name.and_then(|n| self.by_name.get(n)).copied().unwrap_or((self.fallback, false))
    }

    /// Mesh `index`'s material per face: its face groups, else the mesh's
    /// material (`ds3`), else the fallback.
    fn per_face(&self, index: usize, mesh: &ds3::Mesh3ds) -> Vec<(u32, bool)> {
        let mut out = vec![self.of(mesh.material.as_deref()); mesh.faces.len()];
        for g in self.face_groups.get(index).into_iter().flatten() {
            let m = self.of(Some(&g.material));
            for &f in &g.faces {
                if let Some(slot) = out.get_mut(usize::from(f)) {
                    *slot = m;
                }
            }
        }
        out
    }
}

/// The materials of the 3DS file `file` (bytes `bytes`, parsed as `model`;
/// `label` names it in messages) as Lambert scene materials in `builder`:
/// each with its diffuse colour ([`ds3_materials`]; grey 0.6 without one),
/// or, when its diffuse texture map is in `archive` (beside the `.3ds`, else
/// at the archive's root; PNG or JPEG), white × that texture: the map
/// replaces the colour, as in 3ds Max at the map's default 100 % amount (the
/// amount is not read). A map the archive lacks or cannot decode, unreadable
/// material chunks, and a textured mesh without texture coordinates each
/// add one warning to `warnings`; `fallback` is the grey stand-in for meshes
/// without a material.
#[allow(clippy::too_many_arguments)]
pub fn materials_3ds(
    label: &Path,
    file: &str,
    bytes: &[u8],
    model: &ds3::Scene3ds,
    archive: &footlight_mvr::archive::Archive,
    fallback: u32,
    builder: &mut SceneBuilder,
    warnings: &mut Vec<String>,
) -> Materials3ds {
    let mut out = Materials3ds::uniform(fallback);
    let chunks = match ds3_materials::read_materials(bytes) {
        Ok(m) => m,
        Err(e) => {
            warnings
                .push(format!("{}: its material chunks are unreadable ({e}); its meshes are grey", label.display()));
            return out;
        }
    };
    let folder = file.rfind('/').map_or("", |i| &file[..=i]);
    out.face_groups = chunks.face_groups;
    for m in chunks.materials {
        if out.by_name.contains_key(&m.name) {
            continue;
        }
        let colour = m.diffuse.map_or(Vec3::splat(0.6), Vec3::from);
        let mut material = Material::lambert(&format!("{file}: {}", m.name), colour);
        if let Some(map) = &m.texture_map {
            let name = map.replace('\\', "/");
            let found = archive.get(&format!("{folder}{name}")).or_else(|| archive.get(&name));
            match found.map(|b| Texture::decode_image(map, b)) {
                Some(Ok(t)) => {
                    material.diffuse = Vec3::ONE;
                    material.base_texture = Some(Arc::new(t));
                }
                Some(Err(e)) => warnings.push(format!(
                    "{}: material {:?}: its texture map {map:?} is {e}; its diffuse colour is used",
                    label.display(),
                    m.name
                )),
                None => warnings.push(format!(
                    "{}: material {:?} names the texture map {map:?}, which the archive does not contain; its \
                     diffuse colour is used",
                    label.display(),
                    m.name
                )),
            }
        }
        let textured = material.base_texture.is_some();
        out.by_name.insert(m.name, (builder.add_material(material), textured));
    }
    let bare: Vec<&str> = model
        .meshes
        .iter()
        .enumerate()
        .filter(|(i, mesh)| mesh.uvs.len() != mesh.vertices.len() && out.per_face(*i, mesh).iter().any(|m| m.1))
        .map(|(_, mesh)| mesh.name.as_str())
        .collect();
    if !bare.is_empty() {
        warnings.push(format!(
            "{}: textured mesh(es) {bare:?} have no texture coordinates; they read texel (0, 0)",
            label.display()
        ));
    }
    out
}

/// A 3DS model's triangles (MVR frame: millimetres, Z up) placed by the MVR
/// world matrix `world` (millimetres), each face in its material from
/// `materials` (with its texture coordinates when that material is
/// textured: 3DS puts v = 0 at the image's bottom, the scene's textures at
/// its top, so v becomes 1 − v); face indices are checked here (an index
/// past the vertices is an error naming the mesh and face).
pub fn add_3ds(
    label: &Path,
    model: &ds3::Scene3ds,
    world: DMat4,
    materials: &Materials3ds,
    builder: &mut SceneBuilder,
    budget: &ImportLimits,
) -> Result<(), SceneError> {
    let triangles: u64 = model.meshes.iter().map(|m| m.faces.len() as u64).sum();
    if triangles > budget.max_triangles {
        return Err(SceneError::Budget { path: label.to_path_buf(), triangles, limit: budget.max_triangles });
    }
    let placement = stage_matrix(world).as_mat4() * z_up_to_y_up() * Mat4::from_scale(Vec3::splat(1e-3));
    let flip = glam::Mat3::from_mat4(placement).determinant() < 0.0;
    for (mi, mesh) in model.meshes.iter().enumerate() {
        let per_face = materials.per_face(mi, mesh);
        let vertices: Vec<Vec3> = mesh.vertices.iter().map(|&v| placement.transform_point3(Vec3::from(v))).collect();
        let uvs: Option<Vec<Vec2>> = (mesh.uvs.len() == vertices.len() && per_face.iter().any(|m| m.1))
            .then(|| mesh.uvs.iter().map(|&[u, v]| Vec2::new(u, 1.0 - v)).collect());
        for (fi, face) in mesh.faces.iter().enumerate() {
            let [a, b, c] = face.map(usize::from);
            let (Some(&pa), Some(&pb), Some(&pc)) = (vertices.get(a), vertices.get(b), vertices.get(c)) else {
                return Err(SceneError::Invalid {
                    path: label.to_path_buf(),
                    what: format!(
                        "mesh {:?} face {fi}: an index past its {} vertices",
                        mesh.name.chars().take(60).collect::<String>(),
                        vertices.len()
                    ),
                });
            };
            let (material, textured) = per_face[fi];
            // Same length as the vertices, so the indices are in range.
            let [ta, tb, tc] = match &uvs {
                Some(t) if textured => [t[a], t[b], t[c]],
                _ => [Vec2::ZERO; 3],
            };
            let (p, uv) = if flip { ([pa, pc, pb], [ta, tc, tb]) } else { ([pa, pb, pc], [ta, tb, tc]) };
            builder.add_triangle_uv(p, None, uv, material);
        }
    }
    Ok(())
}

/// The stand-in cube ([`STAND_IN_EDGE`]) sitting on the object's origin.
fn add_stand_in(builder: &mut SceneBuilder, world: DMat4, material: u32) {
    let m = stage_matrix(world).as_mat4();
    let h = STAND_IN_EDGE / 2.0;
    let p = |x: f32, y: f32, z: f32| m.transform_point3(Vec3::new(x * h, (y + 1.0) * h, z * h));
    add_box(builder, p, material);
}

/// The 12 triangles of the box with corners `p(±1, ±1, ±1)`, wound outward
/// when `p` keeps handedness.
pub(crate) fn add_box(builder: &mut SceneBuilder, p: impl Fn(f32, f32, f32) -> Vec3, material: u32) {
    let faces: [[(f32, f32, f32); 4]; 6] = [
        [(1., -1., -1.), (1., 1., -1.), (1., 1., 1.), (1., -1., 1.)],
        [(-1., -1., 1.), (-1., 1., 1.), (-1., 1., -1.), (-1., -1., -1.)],
        [(-1., 1., -1.), (-1., 1., 1.), (1., 1., 1.), (1., 1., -1.)],
        [(-1., -1., 1.), (-1., -1., -1.), (1., -1., -1.), (1., -1., 1.)],
        [(-1., -1., 1.), (1., -1., 1.), (1., 1., 1.), (-1., 1., 1.)],
        [(1., -1., -1.), (-1., -1., -1.), (-1., 1., -1.), (1., 1., -1.)],
    ];
    for f in faces {
        let [a, b, c, d] = f.map(|(x, y, z)| p(x, y, z));
        builder.add_quad(a, b, c, d, material);
    }
}

/// Where the scene of a show comes from: `--scene` when given, else the
/// geometry of the patch's MVR show (the `.mvr` itself, or the one a TOML
/// patch names with `show = …`: [`footlight_mvr::show_of`]), else the
/// bundled stage.
pub fn scene_source(scene_flag: Option<&Path>, patch: &Path, default_scene: &Path) -> SceneSource {
    match scene_flag {
        Some(s) => SceneSource::Gltf(s.to_path_buf()),
        None => match footlight_mvr::show_of(patch) {
            Some(show) => SceneSource::Mvr(show),
            None => SceneSource::Gltf(default_scene.to_path_buf()),
        },
    }
}

/// A scene file to load ([`scene_source`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SceneSource {
    /// A glTF/GLB file.
    Gltf(PathBuf),
    /// The 3D files of an MVR show.
    Mvr(PathBuf),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scene_comes_from_the_flag_then_the_mvr_then_the_default() {
        let d = Path::new("scenes/stage.glb");
        assert_eq!(scene_source(Some(Path::new("a.glb")), Path::new("show.mvr"), d), SceneSource::Gltf("a.glb".into()));
        assert_eq!(scene_source(None, Path::new("show.MVR"), d), SceneSource::Mvr("show.MVR".into()));
        assert_eq!(scene_source(None, Path::new("rig.toml"), d), SceneSource::Gltf(d.into()));
    }
}
