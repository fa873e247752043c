//! Multiple scattering in haze by photons (issue 15, item 5; surfaces:
//! issue 34, item 5).
//!
//! The single-scattered beam ([`super::single`]) is light that scattered
//! once, on the camera ray. Everything else the haze does is estimated
//! here, per light at unit intensity, so it stays linear in the light
//! (eq. 5): light scattered two or more times (the *glow* around and
//! between beams, and the forward-scattered light that stays in the beam),
//! light surfaces reflect into the haze, and haze light reaching surfaces.
//!
//! # Volume photons (Jensen and Christensen 1998)
//! Photons leave the light inside its cut-off cone (uniform in the cap,
//! power f_ε(ω) Ω / N for Ω the cap's solid angle: 1 cd, the light's own
//! pattern). The first segment, to the first surface (the scene's BVH)
//! within the haze box, is split: the part 1 − e^(−σ_t L) collides in it
//! (a *forced collision*: free-flight distance from σ_t e^(−σ_t s)
//! truncated to the segment, so thin haze costs no more photons than thick
//! haze); that first collision is the analytic beam's and is not stored.
//! The rest, e^(−σ_t L), reaches the surface unscattered. Both walk on:
//! on each later segment a photon collides with probability
//! q = max(1 − e^(−σ_t L), ½) (forced, q = 1, where no surface is in the
//! way), its power weighted by the ratio of the true probability to q; a
//! collision multiplies the power by the albedo σ_s / σ_t and draws the
//! new direction from Henyey-Greenstein ([`super::reference::sample_hg`]);
//! a diffuse surface reflects it (cosine-weighted, Russian roulette on the
//! largest channel's albedo p, power × ρ_d / p: surfaces tint it, so
//! powers are RGB, and no channel grows).
//! Russian roulette ends weak paths. Stored:
//!
//! * *volume photons* at every collision after the first event of the
//!   path: orders ≥ 2, and light a surface reflected into the haze
//!   (order 1 after a bounce);
//! * *surface photons* where light that collided in the haze at least once
//!   lands on a diffuse surface (haze light reaching surfaces). Light that
//!   never met the haze is the surface photon maps' (clear air, dimmed by
//!   [`super::resolve`]).
//!
//! The stored volume powers sum, in expectation, to σ_t L⁽ⁿ⁾ per unit volume and
//! solid angle (collision density), so the in-scattered source toward −ω is
//!
//!   S(x, ω) = (σ_s / σ_t) Σ_{|x_p − x| < r} p(ω_p · −ω) Φ_p / (4/3 π r³)
//!
//! and the camera ray collects L = ∫ e^(−σ_t τ_cam(t)) S(x(t)) dt, taken by
//! ray marching with steps of about r through the box (the photons sit in a
//! uniform grid of cell r, so one step reads 27 cells). Multiple scattering
//! is smooth, so the screen is traced on a coarse grid (every `scale`-th
//! pixel) and upsampled bilinearly with depth-aware weights. The surface
//! photons give the irradiance E = Σ Φ K over the disc of radius r (same
//! grid, same side of the surface; K the Epanechnikov kernel
//! 2 (1 − ρ²/r²) / (π r²), soft at the rim), reflected as ρ_d/π E and dimmed
//! along the camera ray ([`render_surface_glow`], every pixel whose
//! neighbourhood holds a photon).
//!
//! # Left out
//! Mirrors and glass for these photons (a photon ends at a surface that
//! only reflects specularly or transmits), secondary camera segments
//! (mirrors, glass), the blur of the kernel radius r (edges of the glow are
//! r wide), and the boundary bias of the disc at surface edges and
//! corners. Measured against the volume path tracer
//! ([`super::reference::path_traced_ray`], one ray) in `footlight bench
//! --haze-only` ("multiple scattering" rows) and in `tests/haze.rs`, and
//! the whole picture against [`crate::render::reference::path::PathReference`]
//! in a medium ([`crate::bench::haze_whole`]).
//!
//! # Density
//! Photons are traced once, at 100 %, and each keeps its scattering order
//! k and the optical depth τ of its path; at density d its power is
//! multiplied by d^k e^((1 − d) τ), the ratio of the path's contribution at
//! the two densities ([`VolumePhotons::at_density`]): unbiased, the same as
//! tracing at d in expectation. The term is rendered at the densities the
//! caller needs and kept next to the beam ([`HazeBuffer::with_multiple`]):
//! `render` at its own density, the live tracer at its knots ½ and 1, so
//! [`super::resolve`] reads it exactly there. The bench reports the
//! re-weighting against photons traced at d, and what the live knots'
//! interpolation leaves.

use super::medium::{Medium, hg};
use super::reference::sample_hg;
use super::single::HazeView;
use crate::fixture::Light;
use crate::render::buffer::{HazeBuffer, LightBuffer, TILE};
use crate::render::photon::trace::cosine_hemisphere;
use crate::scene::Scene;
use crate::scene::bvh::{Hit, offset_origin};
use glam::Vec3;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

/// How many volume photons, how wide the kernel, how coarse the screen grid.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MultipleSettings {
    /// Photons emitted per light.
    pub photons: usize,
    /// Kernel radius as a fraction of the haze box's largest side.
    pub radius_frac: f32,
    /// Screen grid: trace every `scale`-th pixel in x and y.
    pub scale: u32,
    /// Scattering events followed per photon at most.
    pub max_order: u32,
    /// RNG seed (photon chunk k uses `seed + k`).
    pub seed: u64,
}

impl Default for MultipleSettings {
    fn default() -> Self {
        Self { photons: 20_000, radius_frac: 0.05, scale: 8, max_order: 64, seed: 0x5EED_0D15 }
    }
}

/// Photons per rayon chunk (each chunk has its own seeded RNG, so the
/// result does not depend on the thread count).
const CHUNK: usize = 1024;

/// Largest grid size per axis.
const MAX_CELLS: usize = 128;

/// The stored volume photons of one light, in a uniform grid.
pub struct VolumePhotons {
    /// Photon positions, sorted by cell.
    pos: Vec<Vec3>,
    /// Propagation directions (unit), arriving at the position.
    dir: Vec<Vec3>,
    /// Powers per channel (per 1 cd of the light; surfaces tint them).
    power: Vec<Vec3>,
    /// Scattering order of the collision each photon is stored at (≥ 2).
    order: Vec<u16>,
    /// Optical depth (at the traced medium's density) of the photon's path
    /// from the light to where it is stored.
    tau: Vec<f32>,
    /// Kernel radius r = grid cell size, metres.
    radius: f32,
    /// Grid origin (the box's minimum).
    origin: Vec3,
    /// Cells per axis.
    dims: [usize; 3],
    /// `start[c]..start[c + 1]` are the photons of cell c.
    start: Vec<u32>,
}

impl VolumePhotons {
    /// Photons stored.
    pub fn len(&self) -> usize {
        self.pos.len()
    }

    /// True when no photon was stored.
    pub fn is_empty(&self) -> bool {
        self.pos.is_empty()
    }

    /// The kernel radius in metres.
    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// These photons re-weighted from the density they were traced at to
    /// `d` times it (0-1; clamped, NaN → 0): each photon's path is kept and
    /// its power multiplied by the ratio of the path's contribution at the
    /// two densities, d^k e^((1 − d) τ) for a photon stored at its k-th
    /// collision after optical depth τ (every collision density and every
    /// σ_s scales by d, every transmittance e^(−σ_t s) becomes
    /// e^(−d σ_t s); the albedo does not change). Unbiased at any d, the
    /// same as tracing at d in expectation: ray-march the result through
    /// the medium at d ([`Medium::at_density`]).
    pub fn at_density(&self, d: f32) -> VolumePhotons {
        let d = super::medium::clean_density(d);
        let power = self
            .power
            .iter()
            .zip(&self.order)
            .zip(&self.tau)
            .map(
                |((&p, &k), &tau)| {
                    if d > 0.0 { p * (d.powi(i32::from(k)) * ((1.0 - d) * tau).exp()) } else { Vec3::ZERO }
                },
            )
            .collect();
        VolumePhotons {
            pos: self.pos.clone(),
            dir: self.dir.clone(),
            power,
            order: self.order.clone(),
            tau: self.tau.clone(),
            radius: self.radius,
            origin: self.origin,
            dims: self.dims,
            start: self.start.clone(),
        }
    }

    fn cell_of(&self, p: Vec3) -> [usize; 3] {
        let c = (p - self.origin) / self.radius;
        [0, 1, 2].map(|a| (c[a].max(0.0) as usize).min(self.dims[a] - 1))
    }

    /// Σ p(ω_p · w_out) Φ_p over the photons within r of `x`.
    fn gather(&self, x: Vec3, w_out: Vec3, g: f32) -> Vec3 {
        let mut sum = Vec3::ZERO;
        self.for_each_near(x, |i| sum += hg(g, self.dir[i].dot(w_out)) * self.power[i]);
        sum
    }

    /// True when some photon is in the 3×3×3 cells around `x`.
    fn any_near(&self, x: Vec3) -> bool {
        let c = self.cell_of(x);
        (c[2].saturating_sub(1)..(c[2] + 2).min(self.dims[2])).any(|z| {
            (c[1].saturating_sub(1)..(c[1] + 2).min(self.dims[1])).any(|y| {
                let row = (z * self.dims[1] + y) * self.dims[0];
                self.start[row + (c[0] + 2).min(self.dims[0])] > self.start[row + c[0].saturating_sub(1)]
            })
        })
    }

    /// Calls `f` with every photon within r of `x`.
    fn for_each_near(&self, x: Vec3, mut f: impl FnMut(usize)) {
        let c = self.cell_of(x);
        let r2 = self.radius * self.radius;
        for z in c[2].saturating_sub(1)..(c[2] + 2).min(self.dims[2]) {
            for y in c[1].saturating_sub(1)..(c[1] + 2).min(self.dims[1]) {
                let row = (z * self.dims[1] + y) * self.dims[0];
                let x0 = row + c[0].saturating_sub(1);
                let x1 = row + (c[0] + 2).min(self.dims[0]);
                for i in self.start[x0] as usize..self.start[x1] as usize {
                    if (self.pos[i] - x).length_squared() < r2 {
                        f(i);
                    }
                }
            }
        }
    }
}

/// A surface photon counts toward a pixel when its normal and the pixel's
/// are within ~45°.
const SAME_SURFACE: f32 = 0.7;

/// One stored photon before gridding.
#[derive(Clone, Copy)]
struct Stored {
    pos: Vec3,
    dir: Vec3,
    power: Vec3,
    order: u16,
    tau: f32,
}

/// Traces `settings.photons` photons of `light` (1 cd) through `medium`
/// and keeps the volume photons ([`trace_haze_photons`]'s `volume`).
/// Seeded, deterministic.
pub fn trace_volume_photons(
    scene: &Scene,
    light: &Light,
    medium: &Medium,
    settings: &MultipleSettings,
) -> VolumePhotons {
    trace_haze_photons(scene, light, medium, settings).volume
}

/// A light's photons in haze: in the air and on the surfaces.
pub struct HazePhotons {
    /// Stored at collisions in the haze, except the light's own first
    /// collision (the analytic beam): orders ≥ 2, and light a surface
    /// reflected into the haze (order 1 after a bounce).
    pub volume: VolumePhotons,
    /// Stored where light that scattered in the haze at least once lands
    /// on a diffuse surface (haze light reaching surfaces); `dir` holds the
    /// surface's normal on the side the photon arrived from.
    pub surface: VolumePhotons,
}

/// Traces `settings.photons` photons of `light` (1 cd) through `medium`
/// and the scene's diffuse surfaces (module doc): every emitted photon
/// splits at its first segment into the part that collides in the haze
/// (forced collision, power × (1 − e^(−σ_t L))) and the part that reaches
/// the first surface (power × e^(−σ_t L)); both walk on, colliding or
/// reaching the next surface (forced where no surface is in the way),
/// reflecting diffusely (Russian roulette on the mean albedo), scattering
/// by Henyey-Greenstein. Seeded, deterministic.
pub fn trace_haze_photons(scene: &Scene, light: &Light, medium: &Medium, settings: &MultipleSettings) -> HazePhotons {
    let extent = medium.max - medium.min;
    let radius = (settings.radius_frac.max(1e-3) * extent.max_element()).max(extent.max_element() / MAX_CELLS as f32);
    let dims = [0, 1, 2].map(|a| ((extent[a] / radius).ceil() as usize).clamp(1, MAX_CELLS));
    let empty = || VolumePhotons {
        pos: Vec::new(),
        dir: Vec::new(),
        power: Vec::new(),
        order: Vec::new(),
        tau: Vec::new(),
        radius,
        origin: medium.min,
        dims,
        start: vec![0; dims[0] * dims[1] * dims[2] + 1],
    };
    let sigma_t = medium.sigma_t();
    if !(sigma_t > 0.0) || !(medium.sigma_s > 0.0) || settings.photons == 0 {
        return HazePhotons { volume: empty(), surface: empty() };
    }
    let cos_cut = light.beam.cos_cutoff().clamp(-1.0, 1.0);
    let solid = std::f32::consts::TAU * (1.0 - cos_cut);
    let axis = light.axis();
    let (b1, b2) = axis.any_orthonormal_pair();
    let n = settings.photons;
    let per_photon = solid / n as f32;
    let chunks = n.div_ceil(CHUNK);
    let walker = Walker { scene, medium, albedo: medium.sigma_s / sigma_t, max_order: settings.max_order };
    let stored: Vec<(Vec<Stored>, Vec<Stored>)> = (0..chunks)
        .into_par_iter()
        .map(|k| {
            let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(settings.seed.wrapping_add(k as u64));
            let mut out = (Vec::new(), Vec::new());
            for _ in k * CHUNK..((k + 1) * CHUNK).min(n) {
                // Uniform in the cap cos θ ≥ cos_cut around the axis.
                let cos = 1.0 - rng.random::<f32>() * (1.0 - cos_cut);
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                let phi = std::f32::consts::TAU * rng.random::<f32>();
                let w = (axis * cos + b1 * (sin * phi.cos()) + b2 * (sin * phi.sin())).normalize_or(axis);
                let f = light.pattern_toward(w);
                if !(f > 0.0) {
                    continue;
                }
                walker.emit(light.position, w, f * per_photon, &mut rng, &mut out);
            }
            out
        })
        .collect();
    let (mut volume, mut surface) = (Vec::new(), Vec::new());
    for (v, s) in stored {
        volume.extend(v);
        surface.extend(s);
    }
    HazePhotons { volume: grid(volume, empty()), surface: grid(surface, empty()) }
}

/// What one photon's walk needs (module doc).
struct Walker<'a> {
    scene: &'a Scene,
    medium: &'a Medium,
    /// σ_s / σ_t.
    albedo: f32,
    /// Events (collisions and bounces) followed at most.
    max_order: u32,
}

/// Where a photon is, where it goes, what it carries.
#[derive(Clone, Copy)]
struct Walk {
    x: Vec3,
    w: Vec3,
    /// Power per 1 cd, per channel (surfaces tint it).
    power: Vec3,
    /// Collisions in the haze so far (the density law's k).
    order: u32,
    /// Optical depth of the path so far, at the traced density.
    tau: f32,
    /// Events so far.
    events: u32,
    /// The emitted power (the Russian roulette's scale).
    start: f32,
}

/// Volume photons and surface photons stored by one chunk.
type Stores = (Vec<Stored>, Vec<Stored>);

impl Walker<'_> {
    /// One photon leaving the light at `x` along `w` with `power`: its
    /// first segment split between a collision (the beam's own, order 1:
    /// not stored) and the first surface (module doc), both followed.
    fn emit(&self, x: Vec3, w: Vec3, power: f32, rng: &mut rand_pcg::Pcg64Mcg, out: &mut Stores) {
        let sigma_t = self.medium.sigma_t();
        let hit = self.scene.accel.intersect(x, w, f32::INFINITY);
        let t_surface = hit.as_ref().map_or(f32::INFINITY, |h| h.t);
        let clip = self.medium.clip(x, w, t_surface);
        let p_seg = clip.map_or(0.0, |(t0, t1)| 1.0 - (-sigma_t * (t1 - t0)).exp());
        let start = power;
        if p_seg > 0.0
            && let Some((t0, t1)) = clip
        {
            let u: f32 = rng.random();
            let s = (-(1.0 - u * p_seg).ln() / sigma_t).min(t1 - t0);
            let mut walk = Walk {
                x: x + w * (t0 + s),
                w,
                power: Vec3::splat(power * p_seg * self.albedo),
                order: 1,
                tau: sigma_t * s,
                events: 1,
                start,
            };
            if self.roulette(&mut walk, rng) {
                walk.w = sample_hg(self.medium.g, w, rng.random(), rng.random());
                self.follow(walk, rng, out);
            }
        }
        if let Some(hit) = hit
            && p_seg < 1.0
        {
            let tau = clip.map_or(0.0, |(t0, t1)| sigma_t * (t1 - t0));
            let walk = Walk { x, w, power: Vec3::splat(power * (1.0 - p_seg)), order: 0, tau, events: 0, start };
            if let Some(walk) = self.bounce(walk, &hit, rng, out) {
                self.follow(walk, rng, out);
            }
        }
    }

    /// Walks on from `walk` until the photon leaves, is absorbed or has
    /// had `max_order` events.
    fn follow(&self, mut walk: Walk, rng: &mut rand_pcg::Pcg64Mcg, out: &mut Stores) {
        let sigma_t = self.medium.sigma_t();
        while walk.events < self.max_order {
            let hit = self.scene.accel.intersect(walk.x, walk.w, f32::INFINITY);
            let t_surface = hit.as_ref().map_or(f32::INFINITY, |h| h.t);
            if let Some((t0, t1)) = self.medium.clip(walk.x, walk.w, t_surface) {
                let p_seg = 1.0 - (-sigma_t * (t1 - t0)).exp();
                // Collide with probability q: forced (q = 1) where no surface
                // is in the way, at least ½ otherwise (thin haze keeps its
                // volume photons); the weights keep it unbiased.
                let q = if hit.is_some() { p_seg.max(0.5) } else { 1.0 };
                let collide = q >= 1.0 || rng.random::<f32>() < q;
                if collide && p_seg > 0.0 {
                    let u: f32 = rng.random();
                    let s = (-(1.0 - u * p_seg).ln() / sigma_t).min(t1 - t0);
                    walk.x += walk.w * (t0 + s);
                    walk.power *= p_seg / q;
                    walk.tau += sigma_t * s;
                    walk.order += 1;
                    walk.events += 1;
                    out.0.push(Stored {
                        pos: walk.x,
                        dir: walk.w,
                        power: walk.power,
                        order: walk.order.min(u32::from(u16::MAX)) as u16,
                        tau: walk.tau,
                    });
                    walk.power *= self.albedo;
                    if !self.roulette(&mut walk, rng) {
                        return;
                    }
                    walk.w = sample_hg(self.medium.g, walk.w, rng.random(), rng.random());
                    continue;
                }
                if q >= 1.0 {
                    return;
                }
                walk.power *= (1.0 - p_seg) / (1.0 - q);
                walk.tau += sigma_t * (t1 - t0);
            }
            let Some(hit) = hit else { return };
            match self.bounce(walk, &hit, rng, out) {
                Some(next) => walk = next,
                None => return,
            }
        }
    }

    /// The photon `walk` arriving at `hit`: stored there if it scattered in
    /// the haze before (order ≥ 1) on a diffuse surface, then reflected
    /// diffusely (Russian roulette on the largest channel's albedo), or `None`.
    fn bounce(&self, mut walk: Walk, hit: &Hit, rng: &mut rand_pcg::Pcg64Mcg, out: &mut Stores) -> Option<Walk> {
        let s = self.scene.surface(hit);
        let facing = s.facing(walk.w);
        let rho = self.scene.diffuse_at(&s);
        if walk.order >= 1 && rho.max_element() > 0.0 {
            out.1.push(Stored {
                pos: s.position,
                dir: facing.geometric,
                power: walk.power,
                order: walk.order.min(u32::from(u16::MAX)) as u16,
                tau: walk.tau,
            });
        }
        // Survival with the largest channel's albedo: a saturated surface
        // (a red curtain) keeps every channel's power at most what arrived
        // instead of multiplying its one strong channel (the mean's law).
        let pd = rho.max_element().min(1.0);
        if !(pd > 0.0) || rng.random::<f32>() >= pd {
            return None;
        }
        walk.power *= rho / pd;
        walk.w = cosine_hemisphere(facing.shading, rng.random(), rng.random());
        if walk.w.dot(facing.geometric) <= 0.0 {
            return None;
        }
        walk.x = offset_origin(s.position, facing.geometric);
        walk.events += 1;
        self.roulette(&mut walk, rng).then_some(walk)
    }

    /// Russian roulette below 1 % of the emitted power: false ends the walk.
    fn roulette(&self, walk: &mut Walk, rng: &mut rand_pcg::Pcg64Mcg) -> bool {
        if walk.power.max_element() < 0.01 * walk.start {
            if rng.random::<f32>() < 0.5 {
                return false;
            }
            walk.power *= 2.0;
        }
        true
    }
}

/// Sorts `stored` into the grid of `grid` (a counting sort by cell).
fn grid(stored: Vec<Stored>, mut grid: VolumePhotons) -> VolumePhotons {
    let ncells = grid.start.len() - 1;
    let cells: Vec<usize> = stored
        .iter()
        .map(|s| {
            let c = grid.cell_of(s.pos);
            (c[2] * grid.dims[1] + c[1]) * grid.dims[0] + c[0]
        })
        .collect();
    let mut count = vec![0u32; ncells + 1];
    for &c in &cells {
        count[c + 1] += 1;
    }
    for c in 0..ncells {
        count[c + 1] += count[c];
    }
    grid.start = count.clone();
    let mut next = count;
    let mut order = vec![0usize; stored.len()];
    for (i, &c) in cells.iter().enumerate() {
        order[next[c] as usize] = i;
        next[c] += 1;
    }
    grid.pos = order.iter().map(|&i| stored[i].pos).collect();
    grid.dir = order.iter().map(|&i| stored[i].dir).collect();
    grid.power = order.iter().map(|&i| stored[i].power).collect();
    grid.order = order.iter().map(|&i| stored[i].order).collect();
    grid.tau = order.iter().map(|&i| stored[i].tau).collect();
    grid
}

/// Multiply scattered radiance (orders ≥ 2, per 1 cd, at `medium`'s
/// density) reaching `origin` along the ray `origin + t·dir` (unit), t up to
/// `t_surface` (∞: none): a ray march through the photons (module doc).
pub fn multiple_along_ray(medium: &Medium, photons: &VolumePhotons, origin: Vec3, dir: Vec3, t_surface: f32) -> Vec3 {
    if photons.is_empty() {
        return Vec3::ZERO;
    }
    let Some((t0, t1)) = medium.clip(origin, dir, t_surface) else { return Vec3::ZERO };
    let r = photons.radius;
    let steps = ((t1 - t0) / r).ceil().clamp(1.0, 4096.0) as usize;
    let step = (t1 - t0) / steps as f32;
    let sigma_t = medium.sigma_t();
    let mut sum = Vec3::ZERO;
    for k in 0..steps {
        let tau = (k as f32 + 0.5) * step;
        let s = photons.gather(origin + dir * (t0 + tau), -dir, medium.g);
        if s != Vec3::ZERO {
            sum += s * (-sigma_t * tau).exp();
        }
    }
    let volume = 4.0 / 3.0 * std::f32::consts::PI * r * r * r;
    sum * step * medium.sigma_s / sigma_t / volume
}

/// Renders the multiply scattered radiance of the light whose `photons`
/// these are for the view `hv` (per 1 cd, at `medium`'s density): dense,
/// row-major, traced every `scale`-th pixel and upsampled with depth-aware
/// bilinear weights.
pub fn render_multiple(hv: &HazeView, medium: &Medium, photons: &VolumePhotons, scale: u32) -> Vec<Vec3> {
    let (w, h) = (hv.width as usize, hv.height as usize);
    if photons.is_empty() || w == 0 || h == 0 {
        return vec![Vec3::ZERO; w * h];
    }
    let s = scale.max(1) as usize;
    let (cw, ch) = (w.div_ceil(s), h.div_ceil(s));
    let rep = |c: usize, n: usize| (c * s + s / 2).min(n - 1);
    let cam = hv.camera.position;
    let trace = |i: usize| multiple_along_ray(medium, photons, cam, hv.dir(i), hv.t_hit(i));
    let coarse: Vec<Vec3> = (0..cw * ch).into_par_iter().map(|k| trace(rep(k / cw, h) * w + rep(k % cw, w))).collect();
    if s == 1 {
        return coarse;
    }
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let t_here = hv.t_hit(i);
            let mut sum = Vec3::ZERO;
            let mut wsum = 0.0;
            for (cx, cy, wb) in bilinear_corners(i % w, i / w, s, (cw, ch), (w, h)) {
                let wt = wb * depth_weight(t_here, hv.t_hit(rep(cy, h) * w + rep(cx, w)));
                sum += wt * coarse[cy * cw + cx];
                wsum += wt;
            }
            if wsum > 1e-3 { sum / wsum } else { trace(i) }
        })
        .collect()
}

/// Haze light reaching the surfaces, seen by the camera (per 1 cd; dense,
/// row-major), at each of `densities` (0-1 of `medium`'s, the one the
/// `photons` were traced in at 100 %): at the surface each pixel's centre
/// ray hits, the surface photons' irradiance E = Σ Φ_p K(|x_p − x|) over
/// those within the kernel radius r that arrived on the pixel's side of the
/// surface (normals within ~45°: a corner's other wall, the back of a flat,
/// is another surface), with the Epanechnikov kernel
/// K(ρ) = 2 (1 − ρ²/r²) / (π r²), which integrates to 1 over the disc and
/// fades to 0 at its rim (a sparse photon shows as a soft spot, not a
/// hard-edged disc); each photon re-weighted to the density as
/// [`VolumePhotons::at_density`] does. E is gathered on every
/// [`GLOW_SCALE`]-th pixel and interpolated between neighbours at the same
/// depth facing the same way (a pixel with none is gathered itself), then
/// reflected by each pixel's Lambert ρ_d/π and dimmed by the haze on its
/// camera ray. One pass for all the densities; pixels with no photon
/// nearby cost one grid lookup.
pub fn render_surface_glow(
    scene: &Scene,
    hv: &HazeView,
    medium: &Medium,
    photons: &VolumePhotons,
    densities: &[f32],
) -> Vec<Vec<Vec3>> {
    let (w, h) = (hv.width as usize, hv.height as usize);
    let ds: Vec<f32> = densities.iter().map(|&d| super::medium::clean_density(d)).collect();
    let nd = ds.len();
    if photons.is_empty() || nd == 0 || w == 0 || h == 0 {
        return vec![vec![Vec3::ZERO; w * h]; nd];
    }
    let cam = hv.camera.position;
    let r2 = photons.radius * photons.radius;
    let norm = 2.0 / (std::f32::consts::PI * r2);
    // The surface point and normal of pixel i's centre ray.
    let surface = |i: usize| {
        let p = hv.hit_point(i)?;
        if !photons.any_near(p) {
            return None;
        }
        let s = scene.surface(&hv.centre_hit(scene, i)?);
        Some((s, s.facing(hv.dir(i)).geometric))
    };
    // Irradiance at a surface point with normal n, one per density, into `e`.
    let irradiance = |x: Vec3, n: Vec3, e: &mut [Vec3]| {
        photons.for_each_near(x, |p| {
            if photons.dir[p].dot(n) > SAME_SURFACE {
                let kernel = norm * (1.0 - (photons.pos[p] - x).length_squared() / r2);
                let (k, tau) = (i32::from(photons.order[p]), photons.tau[p]);
                for (sum, &d) in e.iter_mut().zip(&ds) {
                    if d > 0.0 {
                        *sum += photons.power[p] * (kernel * d.powi(k) * ((1.0 - d) * tau).exp());
                    }
                }
            }
        });
    };
    // E varies over the kernel radius, not from pixel to pixel: it is
    // gathered on every GLOW_SCALE-th pixel and interpolated (bilinear
    // weights, only neighbours at the same depth and facing the same way).
    // Coarse pixel c holds its normal and depth, and E at c·nd + j.
    let g = GLOW_SCALE;
    let (cw, ch) = (w.div_ceil(g), h.div_ceil(g));
    let rep = |c: usize, n: usize| (c * g + g / 2).min(n - 1);
    let mut coarse_e = vec![Vec3::ZERO; cw * ch * nd];
    let coarse: Vec<Option<(Vec3, f32)>> = coarse_e
        .par_chunks_mut(nd)
        .enumerate()
        .map(|(c, e)| {
            let i = rep(c / cw, h) * w + rep(c % cw, w);
            let (s, n) = surface(i)?;
            irradiance(s.position, n, e);
            Some((n, hv.t_hit(i)))
        })
        .collect();
    // Pixel i's value at density j at i·nd + j.
    let mut flat = vec![Vec3::ZERO; w * h * nd];
    flat.par_chunks_mut(nd).enumerate().for_each(|(i, out)| {
        let Some((s, n)) = surface(i) else { return };
        let t_here = hv.t_hit(i);
        let mut wsum = 0.0;
        for (cx, cy, wb) in bilinear_corners(i % w, i / w, g, (cw, ch), (w, h)) {
            let c = cy * cw + cx;
            if let Some((nc, tc)) = coarse[c]
                && nc.dot(n) > SAME_SURFACE
            {
                let wt = wb * depth_weight(t_here, tc);
                for (o, e) in out.iter_mut().zip(&coarse_e[c * nd..(c + 1) * nd]) {
                    *o += *e * wt;
                }
                wsum += wt;
            }
        }
        if wsum > 1e-3 {
            out.iter_mut().for_each(|o| *o /= wsum);
        } else {
            out.fill(Vec3::ZERO);
            irradiance(s.position, n, out);
        }
        let rho = scene.diffuse_at(&s) * std::f32::consts::FRAC_1_PI;
        let cam_depth = medium.sigma_t() * medium.length_inside(cam, s.position);
        for (o, &d) in out.iter_mut().zip(&ds) {
            *o = rho * *o * (-d * cam_depth).exp();
        }
    });
    (0..nd).map(|j| flat.iter().skip(j).step_by(nd).copied().collect()).collect()
}

/// The surface glow's irradiance is gathered on every `GLOW_SCALE`-th
/// pixel in x and y and interpolated ([`render_surface_glow`]).
const GLOW_SCALE: usize = 4;

/// The four coarse cells around full pixel (x, y) of a `full`-sized picture
/// traced on every `s`-th pixel (`coarse` cells per axis), with their
/// bilinear weights.
fn bilinear_corners(
    x: usize,
    y: usize,
    s: usize,
    coarse: (usize, usize),
    full: (usize, usize),
) -> [(usize, usize, f32); 4] {
    let (cx0, fx) = cell(x, s, coarse.0, full.0);
    let (cy0, fy) = cell(y, s, coarse.1, full.1);
    let (cx1, cy1) = ((cx0 + 1).min(coarse.0 - 1), (cy0 + 1).min(coarse.1 - 1));
    [(cx0, cy0, (1.0 - fx) * (1.0 - fy)), (cx1, cy0, fx * (1.0 - fy)), (cx0, cy1, (1.0 - fx) * fy), (cx1, cy1, fx * fy)]
}

/// The coarse cell left of / above full pixel `p` and the bilinear fraction.
fn cell(p: usize, s: usize, n: usize, full: usize) -> (usize, f32) {
    let centre = |c: usize| (c * s + s / 2).min(full - 1) as f32;
    let c0 = (p.saturating_sub(s / 2) / s).min(n - 1);
    let c1 = (c0 + 1).min(n - 1);
    if c1 == c0 {
        return (c0, 0.0);
    }
    (c0, ((p as f32 - centre(c0)) / (centre(c1) - centre(c0)).max(1.0)).clamp(0.0, 1.0))
}

/// Depth weight of a coarse neighbour: 1 at the same depth, ~0 beyond 10 %
/// relative difference; a miss and a hit do not mix.
fn depth_weight(a: f32, b: f32) -> f32 {
    match (a.is_finite(), b.is_finite()) {
        (false, false) => 1.0,
        (true, true) => (-((a - b).abs() / a.min(b).max(1e-3) / 0.05).powi(2)).exp(),
        _ => 0.0,
    }
}

/// Tiles whose largest value is below this fraction of the image's peak
/// are dropped from the haze buffer (the glow fades smoothly; the bench's
/// captured fraction includes what this drops).
pub const TILE_CUTOFF: f32 = 1e-3;

/// The photons' radiance `multiple` (dense, row-major, RGB: from
/// [`render_multiple`] and [`render_surface_glow`]) as a tile-sparse buffer
/// ([`HazeBuffer::with_multiple`]): tiles whose largest value is at least
/// [`TILE_CUTOFF`] of the peak are kept, plus the tiles in `keep` (the
/// beam's, so the glow inside the beam is never cut). Non-finite or
/// negative values are stored as they are: the buffer check reports them.
pub fn multiple_buffer(width: u32, height: u32, multiple: &[Vec3], keep: &[(usize, usize)]) -> LightBuffer {
    let (w, h) = (width as usize, height as usize);
    if multiple.len() != w * h {
        return LightBuffer::empty(width, height);
    }
    let peak = multiple.iter().fold(0.0f32, |a, m| if m.is_finite() { a.max(m.max_element()) } else { a });
    let mut tiles = keep.to_vec();
    for ty in 0..h.div_ceil(TILE) {
        for tx in 0..w.div_ceil(TILE) {
            let lit = (ty * TILE..((ty + 1) * TILE).min(h)).any(|y| {
                (tx * TILE..((tx + 1) * TILE).min(w)).any(|x| !(multiple[y * w + x].max_element() < TILE_CUTOFF * peak))
            });
            if peak > 0.0 && lit {
                tiles.push((tx, ty));
            }
        }
    }
    tiles.sort_unstable();
    tiles.dedup();
    LightBuffer::from_tiles(width, height, &tiles, |tx, ty, tile| {
        for r in 0..TILE.min(h - ty * TILE) {
            for c in 0..TILE.min(w - tx * TILE) {
                tile[r * TILE + c] = multiple[(ty * TILE + r) * w + tx * TILE + c];
            }
        }
    })
}

/// A light's haze buffer with multiple scattering: the single-scattered
/// beam at `quality` with σ_t on the light paths (the photons carry what
/// the similarity relation approximated, so it is not used in the air),
/// plus the photons' term (volume photons ray-marched, surface photons
/// gathered: module doc) rendered at each of `densities` (0-1 of
/// `medium`'s) from one set of photons traced at 100 % and re-weighted
/// ([`VolumePhotons::at_density`]): `render` asks for its own density, the
/// live tracer for its knots ½ and 1, so [`super::resolve`] finds the term
/// exactly where it resolves. [`super::resolve`] dims the surfaces with
/// σ_t on both paths (the light the haze takes from them comes back here).
pub fn render_beam_with_multiple(
    scene: &Scene,
    hv: &HazeView,
    light: &Light,
    medium: &Medium,
    quality: super::single::HazeQuality,
    settings: &MultipleSettings,
    densities: &[f32],
) -> HazeBuffer {
    let air = Medium { multiple: false, ..*medium };
    let beam = super::single::render_inscatter(scene, hv, light, &air, quality);
    let photons = trace_haze_photons(scene, light, &air, settings);
    let keep = beam.as_light_buffer().occupied();
    let (w, h) = (beam.width(), beam.height());
    let densities: Vec<f32> = densities.iter().map(|&d| super::medium::clean_density(d)).filter(|&d| d > 0.0).collect();
    let glows = render_surface_glow(scene, hv, &air, &photons.surface, &densities);
    densities.iter().zip(glows).fold(beam, |haze, (&d, glow)| {
        let mut term = render_multiple(hv, &air.at_density(d), &photons.volume.at_density(d), settings.scale);
        term.iter_mut().zip(&glow).for_each(|(t, g)| *t += *g);
        haze.with_multiple(d, multiple_buffer(w, h, &term, &keep))
    })
}

/// The multiply scattered radiance at density `to` from its value `m` at
/// density `from` (`from` > 0) and the pixel's beam optical depth `kappa`
/// at 100 %: m · (to/from)² · e^((from − to) κ) (order 2 grows as the
/// square of the density, its extinction as the beam's). Only used between
/// the densities a haze buffer holds the term at; exact at `from`.
pub fn anchored(m: f32, kappa: f32, from: f32, to: f32) -> f32 {
    if m > 0.0 && from > 0.0 {
        let r = to / from;
        m * r * r * ((from - to) * kappa).exp()
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::SceneBuilder;

    #[test]
    fn photons_are_seeded_and_the_grid_holds_them_all() {
        let scene = SceneBuilder::new().build();
        let m = Medium::new(0.3, 0.01, 0.8, Vec3::new(-4.0, 0.0, -4.0), Vec3::new(4.0, 6.0, 4.0)).unwrap();
        let light = Light::aimed(
            Vec3::new(0.0, 5.5, 0.0),
            Vec3::new(0.0, 4.5, 0.0),
            crate::fixture::Beam::Spot(crate::fixture::SpotBeam::from_beam_field(20.0, 30.0)),
        );
        let s = MultipleSettings { photons: 3000, ..Default::default() };
        let a = trace_volume_photons(&scene, &light, &m, &s);
        let b = trace_volume_photons(&scene, &light, &m, &s);
        assert!(a.len() > 1000, "{}", a.len());
        assert_eq!(a.pos, b.pos);
        assert_eq!(*a.start.last().unwrap() as usize, a.len());
        // Every photon is in its own cell.
        for c in 0..a.start.len() - 1 {
            for i in a.start[c] as usize..a.start[c + 1] as usize {
                let k = a.cell_of(a.pos[i]);
                assert_eq!((k[2] * a.dims[1] + k[1]) * a.dims[0] + k[0], c);
            }
        }
        // Clear haze stores nothing.
        assert!(trace_volume_photons(&scene, &light, &m.at_density(0.0), &s).is_empty());
    }
}
