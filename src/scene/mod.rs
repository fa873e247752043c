//! The stage: triangles, materials, a camera and the BVH over them.
//!
//! Data comes from a glTF 2.0 file ([`gltf_import`]), an MVR show's 3D files
//! ([`mvr_scene`]) or is built in code
//! ([`SceneBuilder`], used by tests). Every triangle is checked once on the
//! way in: triangles with non-finite vertices or (near) zero area are dropped
//! and counted, so the ray loops never meet NaN geometry.

pub mod bvh;
pub mod camera;
pub mod gltf_import;
pub mod material;
pub mod mvr_scene;
pub mod open_edges;
pub mod texture;

pub use bvh::{Accel, Hit};
pub use camera::Camera;
pub use gltf_import::{ImportLimits, SceneError, load, load_with};
pub use material::Material;
pub use mvr_scene::{MvrScene, load_mvr_scene};
pub use texture::Texture;

use glam::{Vec2, Vec3};

/// A surface point found by a ray, with everything shading needs.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    /// World position.
    pub position: Vec3,
    /// Geometric (face) normal, unit, as wound in the file (not flipped).
    pub geometric_normal: Vec3,
    /// Interpolated vertex normal, unit, on the same side as `geometric_normal`.
    pub shading_normal: Vec3,
    /// Index into [`Scene::materials`].
    pub material: u32,
    /// Triangle index (the paper's triangle ID).
    pub triangle: u32,
    /// Texture coordinates (glTF TEXCOORD_0), interpolated; zero without them.
    pub uv: Vec2,
}

/// A surface point's normals turned toward the side a ray arrives from
/// (every surface is two-sided), and which side that was.
#[derive(Clone, Copy, Debug)]
pub struct Facing {
    /// True when the ray hit the side the winding calls the front.
    pub front: bool,
    /// Geometric normal on the arriving side.
    pub geometric: Vec3,
    /// Shading normal on the arriving side.
    pub shading: Vec3,
}

impl SurfacePoint {
    /// Normals facing a ray arriving along `dir`.
    pub fn facing(&self, dir: Vec3) -> Facing {
        let front = self.geometric_normal.dot(dir) < 0.0;
        let sign = if front { 1.0 } else { -1.0 };
        Facing { front, geometric: self.geometric_normal * sign, shading: self.shading_normal * sign }
    }
}

/// Counts of what the importer had to drop, reported to the user.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ImportReport {
    /// Triangles dropped because a vertex was NaN/Inf.
    pub non_finite: usize,
    /// Triangles dropped because their area was (numerically) zero.
    pub degenerate: usize,
    /// Vertex normals that were NaN/Inf in the file (the face normal is used instead).
    pub non_finite_normals: usize,
    /// Exact copies of an earlier triangle (same three vertices), dropped:
    /// hundreds of coincident triangles would make the BVH deeper than its
    /// traversal stack (obvhs), and a copy adds nothing to the picture.
    pub duplicate: usize,
}

/// Triangle mesh scene with materials, an optional camera and its BVH.
pub struct Scene {
    /// Vertex positions per triangle.
    pub positions: Vec<[Vec3; 3]>,
    /// Vertex normals per triangle (unit; equal to the face normal when the file had none).
    pub normals: Vec<[Vec3; 3]>,
    /// Face normal per triangle (unit, from the winding).
    pub face_normals: Vec<Vec3>,
    /// Material index per triangle.
    pub material_of: Vec<u32>,
    /// Texture coordinates per triangle vertex (zero when the file had
    /// none); empty when no material has a texture (24 bytes a triangle saved).
    pub uvs: Vec<[Vec2; 3]>,
    /// Material table; index 0 always exists (a neutral grey default).
    pub materials: Vec<Material>,
    /// Camera from the file, if it had one.
    pub camera: Option<Camera>,
    /// What the importer dropped.
    pub report: ImportReport,
    /// Ray queries.
    pub accel: Accel,
    /// The open edges, found on first use ([`Scene::open_edges`]).
    open_edges: std::sync::OnceLock<std::sync::Arc<open_edges::OpenEdges>>,
}

impl Scene {
    /// Number of triangles kept.
    pub fn triangle_count(&self) -> usize {
        self.positions.len()
    }

    /// The scene's open edges ([`open_edges::OpenEdges`]), found on first
    /// use with points every 1/80 of the scene's diagonal (a quarter of the
    /// photon maps' largest gather radius).
    pub fn open_edges(&self) -> std::sync::Arc<open_edges::OpenEdges> {
        self.open_edges
            .get_or_init(|| {
                let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
                for v in self.positions.iter().flatten().filter(|v| v.is_finite()) {
                    lo = lo.min(*v);
                    hi = hi.max(*v);
                }
                let spacing = if lo.x <= hi.x { (hi - lo).length() / 80.0 } else { 1.0 };
                std::sync::Arc::new(open_edges::OpenEdges::find(self, spacing))
            })
            .clone()
    }

    /// Resolves a BVH hit into a full surface point.
    pub fn surface(&self, hit: &Hit) -> SurfacePoint {
        let i = hit.triangle as usize;
        let [a, b, c] = self.positions[i];
        let w = 1.0 - hit.u - hit.v;
        let position = a * w + b * hit.u + c * hit.v;
        let ng = self.face_normals[i];
        let [na, nb, nc] = self.normals[i];
        let mut ns = (na * w + nb * hit.u + nc * hit.v).normalize_or_zero();
        if ns == Vec3::ZERO {
            ns = ng;
        } else if ns.dot(ng) < 0.0 {
            // Normals pointing against the winding: trust the winding's side.
            ns = -ns;
        }
        SurfacePoint {
            position,
            geometric_normal: ng,
            shading_normal: ns,
            material: self.material_of[i],
            triangle: hit.triangle,
            uv: self.uvs.get(i).map_or(Vec2::ZERO, |&[ta, tb, tc]| ta * w + tb * hit.u + tc * hit.v),
        }
    }

    /// The diffuse albedo ρ_d at a surface point: the material's, times its
    /// base-colour texture sampled at the point's texture coordinates.
    pub fn diffuse_at(&self, s: &SurfacePoint) -> Vec3 {
        let m = &self.materials[s.material as usize];
        match &m.base_texture {
            Some(t) => m.diffuse * t.sample(s.uv),
            None => m.diffuse,
        }
    }

    /// Position at barycentrics (u, v) on triangle `tri`.
    pub fn point_on(&self, tri: u32, u: f32, v: f32) -> Vec3 {
        let [a, b, c] = self.positions[tri as usize];
        a * (1.0 - u - v) + b * u + c * v
    }

    /// Share of triangles whose material spawns secondary rays (the paper's
    /// "specular" share: 24 % in its test scene).
    pub fn specular_fraction(&self) -> f32 {
        if self.material_of.is_empty() {
            return 0.0;
        }
        let n = self.material_of.iter().filter(|&&m| self.materials[m as usize].is_specular()).count();
        n as f32 / self.material_of.len() as f32
    }

    /// True when any material needs secondary rays; scenes without can skip them.
    pub fn has_specular(&self) -> bool {
        self.materials.iter().any(Material::is_specular)
    }
}

/// Collects triangles and materials, validating each triangle, then builds
/// the BVH. Used by the glTF importer and by tests that build scenes in code.
pub struct SceneBuilder {
    positions: Vec<[Vec3; 3]>,
    normals: Vec<[Vec3; 3]>,
    face_normals: Vec<Vec3>,
    material_of: Vec<u32>,
    uvs: Vec<[Vec2; 3]>,
    materials: Vec<Material>,
    camera: Option<Camera>,
    report: ImportReport,
}

impl Default for SceneBuilder {
    fn default() -> Self {
        Self::new()
    }
}

impl SceneBuilder {
    /// An empty builder whose material 0 is a neutral 50 % grey Lambert.
    pub fn new() -> Self {
        Self {
            positions: Vec::new(),
            normals: Vec::new(),
            face_normals: Vec::new(),
            material_of: Vec::new(),
            uvs: Vec::new(),
            materials: vec![Material::lambert("default grey", Vec3::splat(0.5))],
            camera: None,
            report: ImportReport::default(),
        }
    }

    /// Adds a material and returns its index.
    pub fn add_material(&mut self, m: Material) -> u32 {
        self.materials.push(m);
        (self.materials.len() - 1) as u32
    }

    /// Materials so far (index of the next one added).
    pub fn material_count(&self) -> usize {
        self.materials.len()
    }

    /// Triangles kept so far.
    pub fn triangle_count(&self) -> usize {
        self.positions.len()
    }

    /// True when a camera was set.
    pub fn has_camera(&self) -> bool {
        self.camera.is_some()
    }

    /// Sets the scene camera.
    pub fn set_camera(&mut self, camera: Camera) {
        self.camera = Some(camera);
    }

    /// Adds one triangle; `normals` may be `None` for flat shading. Returns
    /// false (and counts why) when the triangle was dropped.
    pub fn add_triangle(&mut self, p: [Vec3; 3], normals: Option<[Vec3; 3]>, material: u32) -> bool {
        self.add_triangle_uv(p, normals, [Vec2::ZERO; 3], material)
    }

    /// [`SceneBuilder::add_triangle`] with texture coordinates per vertex
    /// (non-finite ones read as zero).
    pub fn add_triangle_uv(&mut self, p: [Vec3; 3], normals: Option<[Vec3; 3]>, uv: [Vec2; 3], material: u32) -> bool {
        if !p.iter().all(|v| v.is_finite()) {
            self.report.non_finite += 1;
            return false;
        }
        let cross = (p[1] - p[0]).cross(p[2] - p[0]);
        let scale = (p[1] - p[0]).length().max((p[2] - p[0]).length()).max((p[2] - p[1]).length());
        // Relative test: an area below (1e-7 · longest edge)² is a sliver that
        // has no usable normal in f32.
        let area2 = cross.length();
        if area2.is_nan() || area2 <= 1e-7 * scale * scale || scale == 0.0 {
            self.report.degenerate += 1;
            return false;
        }
        let ng = cross.normalize();
        let ns = normals.map(|n| n.map(|v| if v.is_finite() { v.normalize_or(ng) } else { ng })).unwrap_or([ng; 3]);
        let material = if (material as usize) < self.materials.len() { material } else { 0 };
        self.positions.push(p);
        self.normals.push(ns);
        self.face_normals.push(ng);
        self.material_of.push(material);
        self.uvs.push(uv.map(|t| if t.is_finite() { t } else { Vec2::ZERO }));
        true
    }

    /// Adds an axis-free quad a-b-c-d (counter-clockwise seen from its front) as two triangles.
    pub fn add_quad(&mut self, a: Vec3, b: Vec3, c: Vec3, d: Vec3, material: u32) {
        self.add_triangle([a, b, c], None, material);
        self.add_triangle([a, c, d], None, material);
    }

    /// Adds a UV sphere of `rings` × `segments` quads (two triangles each,
    /// pole quads degenerate into one) with smooth normals, the poles on
    /// the y axis.
    pub fn add_uv_sphere(&mut self, centre: Vec3, radius: f32, rings: usize, segments: usize, material: u32) {
        let at = |i: usize, j: usize| {
            let theta = std::f32::consts::PI * i as f32 / rings as f32;
            let phi = std::f32::consts::TAU * j as f32 / segments as f32;
            Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin())
        };
        for i in 0..rings {
            for j in 0..segments {
                let n = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                let p = n.map(|x| centre + x * radius);
                self.add_triangle([p[0], p[1], p[2]], Some([n[0], n[1], n[2]]), material);
                self.add_triangle([p[0], p[2], p[3]], Some([n[0], n[2], n[3]]), material);
            }
        }
    }

    /// Drops every triangle whose three vertices (in any order) equal an
    /// earlier triangle's, bit for bit; keeps the first one's material.
    fn drop_duplicates(&mut self) {
        let key = |t: &[Vec3; 3]| {
            let mut k = t.map(|v| v.to_array().map(f32::to_bits));
            k.sort_unstable();
            k
        };
        let mut seen = std::collections::HashSet::with_capacity(self.positions.len());
        let keep: Vec<bool> = self.positions.iter().map(|t| seen.insert(key(t))).collect();
        let dropped = keep.iter().filter(|k| !**k).count();
        if dropped == 0 {
            return;
        }
        self.report.duplicate += dropped;
        fn retain_marked<T>(v: &mut Vec<T>, keep: &[bool]) {
            let mut marks = keep.iter();
            v.retain(|_| marks.next().copied().unwrap_or(true));
        }
        retain_marked(&mut self.positions, &keep);
        retain_marked(&mut self.normals, &keep);
        retain_marked(&mut self.face_normals, &keep);
        retain_marked(&mut self.material_of, &keep);
        retain_marked(&mut self.uvs, &keep);
    }

    /// Builds the BVH and returns the finished scene.
    pub fn build(mut self) -> Scene {
        self.drop_duplicates();
        if self.materials.iter().all(|m| m.base_texture.is_none()) {
            self.uvs = Vec::new();
        }
        let accel = Accel::build(&self.positions);
        Scene {
            positions: self.positions,
            normals: self.normals,
            face_normals: self.face_normals,
            material_of: self.material_of,
            uvs: self.uvs,
            materials: self.materials,
            camera: self.camera,
            report: self.report,
            accel,
            open_edges: std::sync::OnceLock::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drops_exact_duplicates_so_coincident_stacks_cannot_overflow_the_bvh() {
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::lambert("grey", Vec3::splat(0.5)));
        let t = [Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 1.0)];
        for i in 0..600 {
            // The same triangle, its vertices listed in rotating order.
            let r = i % 3;
            b.add_triangle([t[r], t[(r + 1) % 3], t[(r + 2) % 3]], None, m);
        }
        b.add_triangle([Vec3::new(-5.0, -1.0, -5.0), Vec3::new(5.0, -1.0, -5.0), Vec3::new(0.0, -1.0, 5.0)], None, m);
        let s = b.build();
        assert_eq!(s.triangle_count(), 2);
        assert_eq!(s.report.duplicate, 599);
        // Rays still find both surfaces (in a debug build obvhs asserts on
        // a traversal stack overflow, which 600 coincident triangles caused).
        let down = Vec3::NEG_Y;
        let hit = s.accel.intersect(Vec3::new(0.0, 1.0, 0.0), down, f32::INFINITY).expect("the triangle");
        assert!((hit.t - 1.0).abs() < 1e-5);
        let hit = s.accel.intersect(Vec3::new(1.5, 1.0, 0.0), down, f32::INFINITY).expect("the floor");
        assert!((hit.t - 2.0).abs() < 1e-5);
    }

    #[test]
    fn drops_nan_and_zero_area_triangles() {
        let mut b = SceneBuilder::new();
        assert!(!b.add_triangle([Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 0.0, 0.0)], None, 0));
        assert!(!b.add_triangle([Vec3::ZERO, Vec3::X, Vec3::X * 2.0], None, 0));
        assert!(!b.add_triangle([Vec3::ONE; 3], None, 0));
        assert!(b.add_triangle([Vec3::ZERO, Vec3::X, Vec3::Y], Some([Vec3::NAN, Vec3::Z, Vec3::ZERO]), 99));
        let s = b.build();
        assert_eq!(s.report, ImportReport { non_finite: 1, degenerate: 2, non_finite_normals: 0, duplicate: 0 });
        assert_eq!(s.triangle_count(), 1);
        assert_eq!(s.material_of[0], 0);
        assert!(s.normals[0].iter().all(|n| (n.length() - 1.0).abs() < 1e-5));
    }
}
