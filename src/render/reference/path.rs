//! The converged reference of a whole picture: box-filtered path tracing
//! (issue 34, item 3). What `footlight bench --converge-only` measures the
//! renderer's error against, and the curve it is raced against.
//!
//! Every pixel is the mean of camera rays through uniformly spread points
//! of its square (the box filter: the true pixel a display shows). A ray's
//! radiance follows the model the renderer approximates:
//!
//! * at every surface, eq. 1's light term of every light (next-event
//!   estimation, [`super::light_term`]: Phong at the first diffuse vertex,
//!   ρ_d/π after a diffuse bounce, as the photon model carries light on);
//! * mirror (k_R) and transmission (k_T, with Snell and total internal
//!   reflection) as in eq. 1, and diffuse bounces with the cosine-weighted
//!   density (the indirect term the photon maps estimate), chosen by
//!   Russian roulette with the photon tracer's probabilities (mean of the
//!   channels), so the estimate is unbiased.
//!
//! A point light seen only through a mirror or glass onto a diffuse surface
//! (a caustic) is a delta path next-event estimation cannot find, so this
//! is a reference for scenes without such paths (as
//! [`crate::render::photon::pathtrace`]). It shares with the renderer only
//! the camera model, the BVH queries, the surface queries and the beam
//! pattern, each with closed-form tests of its own.
//!
//! Pixel positions follow a (0,2)-sequence (the first two Sobol dimensions)
//! shifted per pixel by a seeded random offset (Cranley-Patterson
//! rotation): any prefix of a power of two samples is stratified over the
//! pixel, so hard beam and shadow edges converge at O(N^-3/4) rather than
//! O(N^-1/2), and the estimate stays unbiased. Bounces use a seeded PCG per
//! pixel and pass.

use super::{Lit, light_term};
use crate::fixture::Light;
use crate::render::photon::trace::{cosine_hemisphere, scatter_probabilities};
use crate::render::whitted::{reflect, refract};
use crate::scene::{Camera, Facing, Scene, bvh::offset_origin};
use glam::{DVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;

/// Vertices a path may have at most (Russian roulette ends it long before).
const MAX_VERTICES: usize = 64;

/// A progressively refined box-filtered path-traced picture.
pub struct PathReference {
    camera: Camera,
    width: u32,
    height: u32,
    seed: u64,
    /// Follow diffuse bounces (the whole picture); `false`: the direct term
    /// (eq. 1's light term through mirrors and glass) alone.
    indirect: bool,
    /// Per pixel: the sum of its samples, in f64 (thousands of samples).
    sum: Vec<DVec3>,
    /// Per pixel: its Cranley-Patterson shift of the pixel sequence.
    shift: Vec<(f64, f64)>,
    /// Samples per pixel so far.
    samples: u32,
}

impl PathReference {
    /// An empty picture of `width`×`height` from `camera`; `seed` sets every
    /// random choice; `indirect = false` renders the direct term alone.
    pub fn new(camera: Camera, width: u32, height: u32, seed: u64, indirect: bool) -> Self {
        let n = (width as usize) * (height as usize);
        let mut rng = Pcg64Mcg::seed_from_u64(seed ^ 0x5EED_5EED_0000_0034);
        let shift = (0..n).map(|_| (rng.random::<f64>(), rng.random::<f64>())).collect();
        Self { camera, width, height, seed, indirect, sum: vec![DVec3::ZERO; n], shift, samples: 0 }
    }

    /// Adds `spp` samples to every pixel of `lights` with weights `k`.
    pub fn add(&mut self, scene: &Scene, lights: &[Light], k: &[Vec3], spp: u32) {
        let (w, h) = (self.width, self.height);
        let (first, camera, seed, indirect) = (self.samples, self.camera, self.seed, self.indirect);
        let shift = &self.shift;
        self.sum.par_chunks_mut(w as usize).enumerate().for_each(|(y, row)| {
            for (x, px) in row.iter_mut().enumerate() {
                let i = y * w as usize + x;
                let mut rng = Pcg64Mcg::seed_from_u64(
                    seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
                        ^ u64::from(first).wrapping_mul(0xD1B5_4A32_D192_ED03),
                );
                for n in first..first + spp {
                    let (sx, sy) = sobol_02(n);
                    let (jx, jy) = ((sx + shift[i].0).fract(), (sy + shift[i].1).fract());
                    let dir = camera.direction(x as f32 + jx as f32, y as f32 + jy as f32, w, h);
                    *px += path(scene, lights, k, camera.position, dir, &mut rng, indirect).as_dvec3();
                }
            }
        });
        self.samples += spp;
    }

    /// Samples per pixel so far.
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// The picture: each pixel's mean, row-major linear RGB (zero before
    /// any sample).
    pub fn mean(&self) -> Vec<Vec3> {
        let n = f64::from(self.samples.max(1));
        self.sum.iter().map(|s| (*s / n).as_vec3()).collect()
    }
}

/// Point `n` of the (0,2)-sequence in base 2: the radical inverse of `n`
/// and the second Sobol dimension (direction numbers v_k = v_(k-1) ^ v_(k-1)/2;
/// Kollig and Keller 2002, "Efficient multidimensional sampling").
pub fn sobol_02(n: u32) -> (f64, f64) {
    let x = n.reverse_bits();
    let (mut y, mut v, mut i) = (0u32, 1u32 << 31, n);
    while i != 0 {
        if i & 1 != 0 {
            y ^= v;
        }
        i >>= 1;
        v ^= v >> 1;
    }
    let scale = 1.0 / 4_294_967_296.0;
    (f64::from(x) * scale, f64::from(y) * scale)
}

/// The radiance arriving at `origin` from direction `dir` (unit): one path
/// with next-event estimation at every vertex (module docs).
fn path(
    scene: &Scene,
    lights: &[Light],
    k: &[Vec3],
    origin: Vec3,
    dir: Vec3,
    rng: &mut Pcg64Mcg,
    indirect: bool,
) -> Vec3 {
    let (mut o, mut d) = (origin, dir);
    let (mut beta, mut total, mut after_diffuse) = (Vec3::ONE, Vec3::ZERO, false);
    for _ in 0..MAX_VERTICES {
        let Some(hit) = scene.accel.intersect(o, d, f32::INFINITY) else { break };
        let s = scene.surface(&hit);
        let m = &scene.materials[s.material as usize];
        let Facing { front, geometric: ng, shading: ns } = s.facing(d);
        let rho = scene.diffuse_at(&s);
        if rho.max_element() > 0.0 || (!after_diffuse && m.specular.max_element() > 0.0) {
            let at = Lit { position: s.position, ns, ng, wo: -d, material: m, rho_d: rho, lambert_only: after_diffuse };
            for (light, k) in lights.iter().zip(k) {
                if *k != Vec3::ZERO {
                    total += beta * *k * light_term(scene, light, &at);
                }
            }
        }
        // Russian roulette over diffuse / mirror / transmission, as the
        // photon tracer chooses.
        // Without the indirect term, no diffuse bounce.
        let (pd, pr, pt) = scatter_probabilities(if indirect { rho } else { Vec3::ZERO }, m);
        let u: f32 = rng.random();
        if u < pd {
            beta *= rho / pd;
            d = cosine_hemisphere(ns, rng.random(), rng.random());
            if d.dot(ng) <= 0.0 {
                break;
            }
            o = offset_origin(s.position, ng);
            after_diffuse = true;
        } else if u < pd + pr {
            beta *= m.k_r / pr;
            let r = reflect(d, ns);
            d = if r.dot(ng) <= 0.0 { reflect(d, ng) } else { r };
            o = offset_origin(s.position, ng);
        } else if u < pd + pr + pt {
            beta *= m.k_t / pt;
            let eta = if front { 1.0 / m.ior } else { m.ior };
            match refract(d, ns, eta) {
                Some(t) if t.dot(ng) < 0.0 => {
                    d = t;
                    o = offset_origin(s.position, -ng);
                }
                _ => {
                    let r = reflect(d, ns);
                    d = if r.dot(ng) <= 0.0 { reflect(d, ng) } else { r };
                    o = offset_origin(s.position, ng);
                }
            }
        } else {
            break;
        }
        if !beta.is_finite() || beta.max_element() <= 0.0 {
            break;
        }
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixture::{Beam, SpotBeam};
    use crate::scene::{Material, SceneBuilder};

    #[test]
    fn the_pixel_sequence_is_stratified_at_every_power_of_two() {
        for log in 0..8u32 {
            let n = 1u32 << log;
            // Every elementary interval of area 1/n (2^a × 2^b cells, a + b = log) holds one point.
            for a in 0..=log {
                let (cx, cy) = (1u32 << a, 1u32 << (log - a));
                let mut seen = vec![false; n as usize];
                for i in 0..n {
                    let (x, y) = sobol_02(i);
                    let cell = (y * f64::from(cy)) as u32 * cx + (x * f64::from(cx)) as u32;
                    assert!(!seen[cell as usize], "n {n}: two points in cell {cell} of {cx}x{cy}");
                    seen[cell as usize] = true;
                }
            }
        }
    }

    /// A closed sphere of albedo ρ around a point light: a sphere's form
    /// factor from any point to a patch is the patch's share of the area,
    /// so every bounce spreads the reflected power evenly, and the indirect
    /// irradiance is ρ Φ / (A (1 − ρ)) everywhere (Φ = 4π I, A = 4π R²),
    /// whatever the light's position. The path reference's indirect part
    /// (whole minus direct, same seed) must match it.
    #[test]
    fn a_sphere_furnace_gets_the_closed_form_indirect_light() {
        let (radius, rho) = (2.0f32, 0.5f32);
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::lambert("wall", Vec3::splat(rho)));
        b.add_uv_sphere(Vec3::ZERO, radius, 48, 96, m);
        let scene = b.build();
        let omni = Beam::Spot(SpotBeam::from_beam_field(360.0, 360.0));
        let light = Light::aimed(Vec3::new(0.3, -0.4, 0.2), Vec3::new(0.3, -1.4, 0.2), omni);
        let camera = Camera::look_at(Vec3::new(-0.5, 0.3, 0.4), Vec3::new(1.0, -0.2, -1.0), 70f32.to_radians());
        let (w, h) = (24, 16);
        let k = [Vec3::ONE];
        let mut whole = PathReference::new(camera, w, h, 7, true);
        whole.add(&scene, std::slice::from_ref(&light), &k, 256);
        let mut direct = PathReference::new(camera, w, h, 7, false);
        direct.add(&scene, std::slice::from_ref(&light), &k, 16);
        let (whole, direct) = (whole.mean(), direct.mean());
        // L_indirect = ρ/π · E_ind on a Lambert wall, E_ind = ρ I / (R² (1 − ρ)).
        let expected = rho / std::f32::consts::PI * rho / (radius * radius * (1.0 - rho));
        let n = whole.len() as f64;
        let mean: f64 = whole.iter().zip(&direct).map(|(a, b)| f64::from(a.y - b.y)).sum::<f64>() / n;
        let rel = (mean / f64::from(expected) - 1.0).abs();
        assert!(rel < 0.01, "indirect {mean:.6} against {expected:.6} ({:.2} %)", rel * 100.0);
        assert!(whole.iter().all(|v| v.is_finite() && v.min_element() >= 0.0));
    }
}
