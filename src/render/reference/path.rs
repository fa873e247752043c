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
//! With a medium ([`PathReference::with_medium`], issue 34 item 5) the
//! same paths fly through homogeneous haze. On every segment the light
//! scattered once toward the segment's start is sampled equiangularly
//! about each lamp (Kulla and Fajardo 2012; the Henyey-Greenstein phase,
//! the beam pattern, a shadow ray and the transmittance e^(−σ_t ℓ) of the
//! ℓ metres of haze toward the lamp): unlike next-event estimation at
//! free-flight vertices, whose 1/r² has infinite variance near a lamp, it
//! stays finite where a segment passes one. Every segment inside the haze
//! box also draws a free-flight distance s ~ σ_t e^(−σ_t s): a collision
//! before the surface is a volume vertex, where the walk goes on in a
//! direction drawn from the phase function, surviving with the albedo
//! σ_s/σ_t; else the ray reaches the surface, whose light term is dimmed by
//! the transmittance toward each lamp. All orders of
//! surface and volume scattering, in any sequence: the whole hazy picture
//! the renderer's beam, volume photons and surface terms approximate.
//! Surfaces reached after a volume vertex reflect ρ_d/π, as after a
//! diffuse bounce.
//!
//! Pixel positions follow a (0,2)-sequence (the first two Sobol dimensions)
//! shifted per pixel by a seeded random offset (Cranley-Patterson
//! rotation): any prefix of a power of two samples is stratified over the
//! pixel, so hard beam and shadow edges converge at O(N^-3/4) rather than
//! O(N^-1/2), and the estimate stays unbiased. Bounces use a seeded PCG per
//! pixel and pass.

use super::{Lit, light_term};
use crate::fixture::Light;
use crate::render::media::Medium;
use crate::render::media::medium::hg;
use crate::render::media::reference::sample_hg;
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
    /// Haze the paths fly through (at the density to render), if any.
    medium: Option<Medium>,
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
        Self { camera, width, height, seed, indirect, medium: None, sum: vec![DVec3::ZERO; n], shift, samples: 0 }
    }

    /// The same picture in the haze `medium`, taken at face value (at the
    /// density to render: [`Medium::at_density`]; `multiple` is ignored,
    /// every path sees σ_t): module docs. A clear medium is no medium.
    pub fn with_medium(mut self, medium: Medium) -> Self {
        self.medium = (!medium.is_clear()).then_some(medium);
        self
    }

    /// Adds `spp` samples to every pixel of `lights` with weights `k`.
    pub fn add(&mut self, scene: &Scene, lights: &[Light], k: &[Vec3], spp: u32) {
        let (w, h) = (self.width, self.height);
        let (first, camera, seed, indirect) = (self.samples, self.camera, self.seed, self.indirect);
        let medium = self.medium.as_ref();
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
                    *px += path(scene, lights, k, medium, camera.position, dir, &mut rng, indirect).as_dvec3();
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

/// Where the ray `o + t·d` first collides in the haze `m` before `t_hit`
/// (free flight s ~ σ_t e^(−σ_t s) from where it enters the box), or
/// `None` when it reaches `t_hit` (probability e^(−σ_t ℓ), ℓ the metres of
/// haze on the way).
fn collision(m: &Medium, o: Vec3, d: Vec3, t_hit: f32, rng: &mut Pcg64Mcg) -> Option<Vec3> {
    let (t0, t1) = m.clip(o, d, t_hit)?;
    let s = -(1.0 - rng.random::<f64>()).ln() / f64::from(m.sigma_t());
    (f64::from(t0) + s < f64::from(t1)).then(|| o + d * (t0 + s as f32))
}

/// Single scattering of `light` (1 cd) toward `o` along the ray `o + t·d`
/// up to `t_hit`, one sample: t drawn equiangularly about the lamp (Kulla
/// and Fajardo 2012: θ uniform between the ends' angles seen from the
/// lamp, pdf D / ((θ_b − θ_a) r²) for D the lamp's distance from the line),
/// so the 1/r² of the integrand cancels:
/// σ_s T_cam · p f g T_light · (θ_b − θ_a) / D.
fn equiangular_single(scene: &Scene, m: &Medium, light: &Light, o: Vec3, d: Vec3, t_hit: f32, u: f32) -> f32 {
    let Some((t0, t1)) = m.clip(o, d, t_hit) else { return 0.0 };
    let delta = (light.position - o).dot(d);
    let dist = (light.position - o - d * delta).length();
    if dist <= 1e-6 || !dist.is_finite() {
        return 0.0;
    }
    let (a, b) = (((t0 - delta) / dist).atan(), ((t1 - delta) / dist).atan());
    let t = delta + dist * (a + (b - a) * u).tan();
    if t.is_nan() || t < t0 || t > t1 {
        return 0.0;
    }
    let x = o + d * t;
    let to_x = x - light.position;
    let r = to_x.length();
    if r <= 1e-6 {
        return 0.0;
    }
    let w_in = to_x / r;
    let f = light.pattern_toward(w_in);
    if f.is_nan() || f <= 0.0 || scene.accel.occluded(x, -w_in, r * (1.0 - 1e-5)) {
        return 0.0;
    }
    let transmittance = (-m.sigma_t() * ((t - t0) + m.length_inside(x, light.position))).exp();
    m.sigma_s * hg(m.g, w_in.dot(-d)) * f * transmittance * (b - a) / dist
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
#[allow(clippy::too_many_arguments)]
fn path(
    scene: &Scene,
    lights: &[Light],
    k: &[Vec3],
    medium: Option<&Medium>,
    origin: Vec3,
    dir: Vec3,
    rng: &mut Pcg64Mcg,
    indirect: bool,
) -> Vec3 {
    let (mut o, mut d) = (origin, dir);
    let (mut beta, mut total, mut after_diffuse) = (Vec3::ONE, Vec3::ZERO, false);
    // Transmittance of the haze between `x` and a lamp at `p`.
    let transmittance = |x: Vec3, p: Vec3| medium.map_or(1.0, |m| (-m.sigma_t() * m.length_inside(x, p)).exp());
    for _ in 0..MAX_VERTICES {
        let hit = scene.accel.intersect(o, d, f32::INFINITY);
        let t_hit = hit.as_ref().map_or(f32::INFINITY, |h| h.t);
        if let Some(m) = medium {
            // Light scattered once on this segment toward its start, sampled
            // equiangularly about each lamp: finite variance where a
            // segment passes close to a lamp, whose 1/r² next-event
            // estimation at free-flight vertices would not have.
            for (light, k) in lights.iter().zip(k) {
                if *k != Vec3::ZERO {
                    total += beta * *k * equiangular_single(scene, m, light, o, d, t_hit, rng.random());
                }
            }
            if let Some(x) = collision(m, o, d, t_hit, rng) {
                // A volume vertex carries the walk on (its light was sampled
                // along the segment), surviving with the albedo σ_s/σ_t.
                if !indirect || rng.random::<f32>() >= m.sigma_s / m.sigma_t() {
                    break;
                }
                // Light arriving along w_in (HG about −d) came from −w_in.
                d = -sample_hg(m.g, -d, rng.random(), rng.random());
                o = x;
                after_diffuse = true;
                continue;
            }
        }
        let Some(hit) = hit else { break };
        let s = scene.surface(&hit);
        let m = &scene.materials[s.material as usize];
        let Facing { front, geometric: ng, shading: ns } = s.facing(d);
        let rho = scene.diffuse_at(&s);
        if rho.max_element() > 0.0 || (!after_diffuse && m.specular.max_element() > 0.0) {
            let at = Lit { position: s.position, ns, ng, wo: -d, material: m, rho_d: rho, lambert_only: after_diffuse };
            for (light, k) in lights.iter().zip(k) {
                if *k != Vec3::ZERO {
                    total += beta * *k * light_term(scene, light, &at) * transmittance(s.position, light.position);
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

    /// Pure absorption (σ_s = 0): the hazy picture is the clear one times
    /// e^(−σ_a ℓ), ℓ the metres of haze from the surface to the camera and
    /// to the lamp (closed form, taken along each pixel's centre ray).
    #[test]
    fn an_absorbing_haze_dims_by_beer_lambert() {
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::lambert("floor", Vec3::splat(0.5)));
        b.add_quad(
            Vec3::new(-6.0, 0.0, -6.0),
            Vec3::new(-6.0, 0.0, 6.0),
            Vec3::new(6.0, 0.0, 6.0),
            Vec3::new(6.0, 0.0, -6.0),
            m,
        );
        let scene = b.build();
        let light =
            Light::aimed(Vec3::new(0.0, 4.0, 0.0), Vec3::ZERO, Beam::Spot(SpotBeam::from_beam_field(80.0, 90.0)));
        let camera = Camera::look_at(Vec3::new(0.0, 3.0, 3.0), Vec3::ZERO, 50f32.to_radians());
        let (w, h) = (24, 16);
        let haze = Medium::new(0.0, 0.1, 0.0, Vec3::splat(-10.0), Vec3::splat(10.0)).unwrap();
        let lights = std::slice::from_ref(&light);
        let mut clear = PathReference::new(camera, w, h, 3, false);
        clear.add(&scene, lights, &[Vec3::ONE], 64);
        let mut hazy = PathReference::new(camera, w, h, 3, false).with_medium(haze);
        hazy.add(&scene, lights, &[Vec3::ONE], 64);
        let (clear, hazy) = (clear.mean(), hazy.mean());
        let (mut got, mut want) = (0.0f64, 0.0f64);
        for (i, (c, v)) in clear.iter().zip(&hazy).enumerate() {
            let dir = camera.direction((i % w as usize) as f32 + 0.5, (i / w as usize) as f32 + 0.5, w, h);
            let t = -camera.position.y / dir.y;
            if t.is_nan() || t <= 0.0 {
                continue;
            }
            let p = camera.position + dir * t;
            let l = haze.length_inside(camera.position, p) + haze.length_inside(p, light.position);
            want += f64::from(c.y * (-0.1 * l).exp());
            got += f64::from(v.y);
        }
        assert!(want > 0.0);
        assert!((got / want - 1.0).abs() < 0.01, "hazy {got:.5} against Beer-Lambert {want:.5}");
    }

    /// A pixel a fraction of a degree wide is one camera ray: its value in
    /// an empty haze box must match the per-ray volume path tracer
    /// ([`crate::render::media::reference::path_traced_ray`], another
    /// estimator: a forced first collision and walks toward the light),
    /// all orders, within their standard errors.
    #[test]
    fn a_thin_pixel_in_haze_matches_the_per_ray_path_tracer() {
        let scene = SceneBuilder::new().build();
        let medium = Medium::new(0.3, 0.01, 0.8, Vec3::new(-4.0, 0.0, -4.0), Vec3::new(4.0, 6.0, 4.0)).unwrap();
        let light = Light::aimed(
            Vec3::new(0.0, 5.5, 0.0),
            Vec3::new(0.0, 4.5, 0.0),
            Beam::Spot(SpotBeam::from_beam_field(20.0, 30.0)),
        );
        let origin = Vec3::new(-3.5, 3.0, 0.0);
        let camera = Camera::look_at(origin, Vec3::new(3.5, 3.0, 0.0), 0.01f32.to_radians());
        let n = 40_000;
        let mut pixel = PathReference::new(camera, 1, 1, 11, true).with_medium(medium);
        pixel.add(&scene, std::slice::from_ref(&light), &[Vec3::ONE], n);
        let ours = f64::from(pixel.mean()[0].x);
        let dir = camera.direction(0.5, 0.5, 1, 1);
        let theirs = crate::render::media::reference::path_traced_ray(
            &medium,
            &light,
            origin,
            dir,
            f32::INFINITY,
            n as usize,
            64,
            5,
        );
        // Our own spread: the same pixel in 8 independent parts.
        let parts: Vec<f64> = (0..8)
            .map(|s| {
                let mut p = PathReference::new(camera, 1, 1, 100 + s, true).with_medium(medium);
                p.add(&scene, std::slice::from_ref(&light), &[Vec3::ONE], n / 8);
                f64::from(p.mean()[0].x)
            })
            .collect();
        let mean = parts.iter().sum::<f64>() / 8.0;
        let ours_se = (parts.iter().map(|p| (p - mean).powi(2)).sum::<f64>() / 7.0 / 8.0).sqrt() / 2f64.sqrt();
        let se = (ours_se * ours_se + theirs.std_error * theirs.std_error).sqrt();
        assert!(theirs.all > 0.0 && ours > 0.0);
        assert!(
            (ours - theirs.all).abs() < 4.0 * se,
            "pixel {ours:.4e} against the per-ray path tracer {:.4e} ± {se:.2e}",
            theirs.all
        );
    }
}
