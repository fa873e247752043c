//! glTF 2.0 import (`.gltf` with external or embedded buffers, and `.glb`).
//!
//! Walks every node of the default scene (or the first scene) with its world
//! transform, turns triangle primitives (lists, strips and fans) into scene
//! triangles, maps materials with [`Material::from_pbr`] (base colour,
//! metallic, roughness, `KHR_materials_transmission`, `KHR_materials_ior`),
//! and takes the first perspective camera. What the renderer cannot use
//! (textures, points/lines, punctual lights: lights come from the patch) is
//! reported once with `tracing::warn!`, never silently.

use super::{Camera, Material, Scene, SceneBuilder};
use glam::{Mat3, Mat4, Vec3};
use std::path::{Path, PathBuf};

/// Why a scene file could not be loaded. Always names the file.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read or parsed as glTF (the gltf crate's message says where).
    #[error("{path}: not a valid glTF 2.0 file: {source}")]
    Gltf {
        /// The scene file.
        path: PathBuf,
        /// What the gltf crate reported.
        source: gltf::Error,
    },
    /// The gltf crate panicked while validating the file (gltf-json 1.4.1
    /// indexes accessors unchecked in its POSITION min/max hook).
    #[error("{path}: malformed glTF (the validator failed: {message}); check accessor and buffer indices")]
    Malformed {
        /// The scene file.
        path: PathBuf,
        /// The panic message.
        message: String,
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

/// Loads a glTF/GLB file into a [`Scene`] with its BVH.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    // gltf-json 1.4.1 panics on some out-of-range indices during validation
    // (mesh.rs indexes `root.accessors[...]` before checking it). A broken
    // file must be an error, not a crash, so the import runs under
    // catch_unwind; nothing shared is mutated inside, so unwinding is safe.
    let imported = std::panic::catch_unwind(|| gltf::import(path)).map_err(|panic| SceneError::Malformed {
        path: path.to_path_buf(),
        message: panic
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_else(|| "unknown panic".into()),
    })?;
    let (doc, buffers, _images) = imported.map_err(|source| SceneError::Gltf { path: path.to_path_buf(), source })?;
    let mut builder = SceneBuilder::new();

    // Material table: glTF material i -> our index (0 is the default grey).
    let mut material_index = Vec::new();
    let mut textured = 0usize;
    for m in doc.materials() {
        let pbr = m.pbr_metallic_roughness();
        if pbr.base_color_texture().is_some() || pbr.metallic_roughness_texture().is_some() {
            textured += 1;
        }
        let [r, g, b, _a] = pbr.base_color_factor();
        let transmission = m.transmission().map(|t| t.transmission_factor()).unwrap_or(0.0);
        let ior = m.ior().unwrap_or(1.5);
        let name = m.name().map(str::to_string).unwrap_or_else(|| format!("material {}", m.index().unwrap_or(0)));
        let mat = Material::from_pbr(
            &name,
            Vec3::new(r, g, b),
            pbr.metallic_factor(),
            pbr.roughness_factor(),
            transmission,
            ior,
        );
        material_index.push(builder.add_material(mat));
    }
    if textured > 0 {
        tracing::warn!("{}: {textured} material(s) use textures; only their constant factors are used", path.display());
    }

    let scene = doc.default_scene().or_else(|| doc.scenes().next());
    let mut skipped_modes = 0usize;
    let mut camera: Option<Camera> = None;
    if let Some(scene) = scene {
        let mut stack: Vec<(gltf::Node, Mat4)> = scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect();
        while let Some((node, parent)) = stack.pop() {
            let local = Mat4::from_cols_array_2d(&node.transform().matrix());
            let world = parent * local;
            for child in node.children() {
                stack.push((child, world));
            }
            if camera.is_none()
                && let Some(cam) = node.camera()
                && let gltf::camera::Projection::Perspective(p) = cam.projection()
            {
                let (_s, rotation, translation) = world.to_scale_rotation_translation();
                camera = Some(Camera::from_rotation(translation, rotation, p.yfov()));
            }
            let Some(mesh) = node.mesh() else { continue };
            let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
            let flip = Mat3::from_mat4(world).determinant() < 0.0;
            for (pi, prim) in mesh.primitives().enumerate() {
                let bad = |what: String| SceneError::BadPrimitive {
                    path: path.to_path_buf(),
                    mesh: mesh.name().map(str::to_string).unwrap_or_else(|| mesh.index().to_string()),
                    primitive: pi,
                    what,
                };
                use gltf::mesh::Mode;
                let mode = prim.mode();
                if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
                    skipped_modes += 1;
                    continue;
                }
                let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
                let Some(pos_iter) = reader.read_positions() else {
                    return Err(bad("has no POSITION attribute".into()));
                };
                let positions: Vec<Vec3> = pos_iter.map(|p| world.transform_point3(Vec3::from(p))).collect();
                let normals: Option<Vec<Vec3>> = reader
                    .read_normals()
                    .map(|it| it.map(|n| (normal_matrix * Vec3::from(n)).normalize_or_zero()).collect());
                if let Some(n) = &normals
                    && n.len() != positions.len()
                {
                    return Err(bad(format!("{} normals for {} positions", n.len(), positions.len())));
                }
                let indices: Vec<u32> = match reader.read_indices() {
                    Some(ix) => ix.into_u32().collect(),
                    None => (0..positions.len() as u32).collect(),
                };
                if let Some(&bad_index) = indices.iter().find(|&&i| i as usize >= positions.len()) {
                    return Err(bad(format!("index {bad_index} past the {} vertices", positions.len())));
                }
                let material = prim.material().index().map(|i| material_index[i]).unwrap_or(0);
                for [a, b, c] in triangle_list(mode, &indices) {
                    let (b, c) = if flip { (c, b) } else { (b, c) };
                    let p = [positions[a as usize], positions[b as usize], positions[c as usize]];
                    let n = normals.as_ref().map(|n| [n[a as usize], n[b as usize], n[c as usize]]);
                    builder.add_triangle(p, n, material);
                }
            }
        }
    }
    if skipped_modes > 0 {
        tracing::warn!("{}: skipped {skipped_modes} point/line primitive(s)", path.display());
    }
    if let Some(cam) = camera {
        builder.set_camera(cam);
    }
    let scene = builder.build();
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
        assert!(err.contains("broken.gltf"), "{err}");
        std::fs::write(&path, b"not json").unwrap();
        let err = load(&path).err().unwrap().to_string();
        assert!(err.contains("broken.gltf"), "{err}");
    }
}
