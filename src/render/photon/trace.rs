//! Photon tracing for one light (Jensen 2001, chapter 5), with the unit
//! replacement source of Vierjahn 2010, eq. 4-5.
//!
//! Photons leave the light's position with directions importance-sampled
//! from its beam pattern ([`BeamSampler`]); all of them together carry the
//! flux ∫ f_ε dω of the 1 cd source, so the indirect buffer is in the same
//! units as the direct one. At each surface Russian roulette picks diffuse
//! reflection (cosine-weighted), mirror reflection (k_R) or transmission
//! (k_T, Snell) with probabilities equal to their mean coefficients, so
//! photon powers stay near constant. Photons are stored on diffuse surfaces
//! after at least one bounce: direct light comes from the ray tracer.
//!
//! Determinism: photons are emitted in fixed-size chunks, each with its own
//! PCG RNG seeded from (seed, chunk index), so the maps do not depend on the
//! thread count.

use super::PhotonSettings;
use super::map::{IrradianceCache, Photon, PhotonMap};
use crate::fixture::{BeamSampler, Light};
use crate::render::whitted::{reflect, refract};
use crate::scene::{Facing, Scene, bvh::offset_origin};
use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;

/// Caustic gathers are limited to this share of the global gather radius
/// (caustics are sharp).
const CAUSTIC_RADIUS_SHARE: f32 = 0.25;

/// Cache points consulted when the 4 nearest do not fit, before a kNN
/// gather ([`PhotonMaps::irradiance`]).
pub const WIDE_LOOKUP: usize = 16;

/// Photons emitted per RNG chunk.
const CHUNK: usize = 2048;
/// Chunks traced per round before the stored count is checked.
const CHUNKS_PER_ROUND: usize = 8;

/// A light's photon maps and the estimate structures built from them.
pub struct PhotonMaps {
    /// Photons whose path had a diffuse bounce (L D (S|D)* D).
    pub global: PhotonMap,
    /// Photons after specular bounces only (L S+ D).
    pub caustic: PhotonMap,
    /// Precomputed irradiance over the global map.
    pub irradiance: IrradianceCache,
    /// Photons emitted (the power normalisation).
    pub emitted: u64,
    /// ∫ f_ε dω of the light's pattern (lm at 1 cd).
    pub flux: f32,
    /// Gather radius limit used for estimates (scene-scaled).
    pub max_radius: f32,
    /// Settings used.
    pub settings: PhotonSettings,
    /// Where the trace's time went (profiled in `footlight bench
    /// --accuracy-only --accuracy-part converge`).
    pub times: TraceTimes,
}

/// Wall-clock time of the stages of [`trace_photons_until`], ms.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct TraceTimes {
    /// Emitting and tracing photons.
    pub trace_ms: f64,
    /// Building the global and caustic k-d trees.
    pub tree_ms: f64,
    /// Precomputing the irradiance cache (its k-d tree included).
    pub cache_ms: f64,
}

impl PhotonMaps {
    /// Maps of a light that reaches nothing (no tracing was done).
    pub fn empty(settings: PhotonSettings, max_radius: f32) -> Self {
        Self {
            global: PhotonMap::new(Vec::new()),
            caustic: PhotonMap::new(Vec::new()),
            irradiance: IrradianceCache::build(&PhotonMap::new(Vec::new()), 1, 1, 1.0),
            emitted: 0,
            flux: 0.0,
            max_radius,
            settings,
            times: TraceTimes::default(),
        }
    }

    /// Indirect irradiance (global + caustic) at a diffuse point, from the
    /// precomputed irradiance cache; where no cache point fits (their normals
    /// disagree or their gather balls do not reach: box corners, thin parts),
    /// from the direct kNN estimates of both maps, so a lit region never
    /// reads zero.
    ///
    /// Before the kNN fallback, the [`WIDE_LOOKUP`] nearest cache points are
    /// consulted: on a surface next to a more densely lit one (a wall beside
    /// the spot's pool, a riser's face under its lit top) the 4 nearest
    /// cache points often belong to the other surface while this surface's
    /// own points, whose gather balls reach `x`, are a little farther. On
    /// the bundled stage 41 % of the diffuse vertices missed the 4 nearest
    /// and paid a 150-photon gather each (issue 13: the photon stage's
    /// largest cost, `footlight bench --accuracy-only --accuracy-part profile`).
    pub fn irradiance(&self, x: Vec3, n: Vec3) -> Vec3 {
        self.irradiance
            .lookup(x, n)
            .or_else(|| self.irradiance.lookup_among(x, n, WIDE_LOOKUP))
            .unwrap_or_else(|| self.direct_estimate(x, n))
    }

    /// The estimate before the wide lookup (4 cache points, then the kNN
    /// gather): kept for the bench's before/after rows.
    pub fn irradiance_narrow(&self, x: Vec3, n: Vec3) -> Vec3 {
        self.irradiance.lookup(x, n).unwrap_or_else(|| self.direct_estimate(x, n))
    }

    /// Global + caustic irradiance at `x` from kNN gathers in the maps (no
    /// cache). The global gather reaches at most twice the nearest cache
    /// point's radius (the local photon spacing at k photons): a point far
    /// from every photon of its own surface (the floor under a closed box)
    /// must not collect the photons of a nearby parallel one.
    pub fn direct_estimate(&self, x: Vec3, n: Vec3) -> Vec3 {
        let reach = self.irradiance.radius_near(x).map_or(self.max_radius, |r| (2.0 * r).min(self.max_radius));
        let g = self.global.estimate(x, n, self.settings.estimate, reach).irradiance;
        let c = if !self.caustic.is_empty() && self.caustic.nearest_distance(x) < self.caustic_radius() {
            self.caustic.estimate(x, n, self.settings.caustic_estimate, self.caustic_radius()).irradiance
        } else {
            Vec3::ZERO
        };
        g + c
    }

    /// Gather radius limit of caustic estimates.
    pub fn caustic_radius(&self) -> f32 {
        self.max_radius * CAUSTIC_RADIUS_SHARE
    }
}

/// Scene-scaled gather radius limit: 5 % of the bounding-box diagonal.
pub fn max_gather_radius(scene: &Scene) -> f32 {
    let (lo, hi) = scene_bounds(scene);
    ((hi - lo).length() * 0.05).max(1e-4)
}

fn scene_bounds(scene: &Scene) -> (Vec3, Vec3) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for t in &scene.positions {
        for v in t {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
    }
    if lo.x > hi.x { (Vec3::ZERO, Vec3::ZERO) } else { (lo, hi) }
}

/// True when the light's cone provably misses the scene's bounding sphere
/// (so tracing would find nothing).
fn beam_misses_scene(scene: &Scene, light: &Light) -> bool {
    if scene.positions.is_empty() {
        return true;
    }
    let (lo, hi) = scene_bounds(scene);
    let centre = (lo + hi) * 0.5;
    let radius = (hi - lo).length() * 0.5;
    let to_centre = centre - light.position;
    let d = to_centre.length();
    if d <= radius {
        return false;
    }
    let cone = light.beam.cos_cutoff().clamp(-1.0, 1.0).acos();
    let angle_to_centre = (to_centre / d).dot(light.axis()).clamp(-1.0, 1.0).acos();
    angle_to_centre > cone + (radius / d).clamp(-1.0, 1.0).asin()
}

/// Traces `light`'s photons until `settings.stored` indirect photons are
/// stored (or the emission cap is reached) and builds its maps.
pub fn trace_photons(scene: &Scene, light: &Light, settings: &PhotonSettings) -> PhotonMaps {
    trace_photons_until(scene, light, settings, &|| false)
        .unwrap_or_else(|| PhotonMaps::empty(*settings, max_gather_radius(scene)))
}

/// As [`trace_photons`], abandoned (`None`) as soon as `stop` returns true:
/// it is checked before every 2048-photon chunk and before the irradiance
/// cache is built, so a cancelled build stops within a few milliseconds.
pub fn trace_photons_until(
    scene: &Scene,
    light: &Light,
    settings: &PhotonSettings,
    stop: &(dyn Fn() -> bool + Sync),
) -> Option<PhotonMaps> {
    let max_radius = max_gather_radius(scene);
    let sampler = BeamSampler::new(&light.beam);
    if settings.stored == 0 || sampler.flux() <= 0.0 || beam_misses_scene(scene, light) {
        return Some(PhotonMaps::empty(*settings, max_radius));
    }
    let t0 = std::time::Instant::now();
    let ms = |t: std::time::Instant| t.elapsed().as_secs_f64() * 1e3;
    let cap = (settings.stored.saturating_mul(settings.max_emitted_factor.max(1))).max(CHUNK);
    let mut global = Vec::new();
    let mut caustic = Vec::new();
    let mut emitted = 0usize;
    let mut chunk = 0u64;
    while global.len() + caustic.len() < settings.stored && emitted < cap {
        let results: Vec<(Vec<Photon>, Vec<Photon>)> = (chunk..chunk + CHUNKS_PER_ROUND as u64)
            .into_par_iter()
            .map(|c| if stop() { (Vec::new(), Vec::new()) } else { trace_chunk(scene, light, &sampler, settings, c) })
            .collect();
        if stop() {
            return None;
        }
        for (g, c) in results {
            global.extend(g);
            caustic.extend(c);
        }
        chunk += CHUNKS_PER_ROUND as u64;
        emitted += CHUNKS_PER_ROUND * CHUNK;
    }
    // Photon powers so far are f_ε/pdf per photon; divide by the emission count.
    let norm = 1.0 / emitted as f32;
    for p in global.iter_mut().chain(caustic.iter_mut()) {
        p.power *= norm;
    }
    if stop() {
        return None;
    }
    let mut times = TraceTimes { trace_ms: ms(t0), ..TraceTimes::default() };
    let t1 = std::time::Instant::now();
    let open = scene.open_edges();
    let global = PhotonMap::new(global)
        .with_boundary(settings.boundary)
        .with_filter(settings.filter)
        .with_open_edges(open.clone());
    let caustic = PhotonMap::new(caustic).with_boundary(settings.boundary).with_open_edges(open);
    times.tree_ms = ms(t1);
    let t2 = std::time::Instant::now();
    let irradiance = IrradianceCache::build_with_caustics(
        &global,
        &caustic,
        (settings.estimate, settings.irradiance_stride, max_radius),
        (settings.caustic_estimate, 2, max_radius * CAUSTIC_RADIUS_SHARE),
    );
    times.cache_ms = ms(t2);
    Some(PhotonMaps {
        global,
        caustic,
        irradiance,
        emitted: emitted as u64,
        flux: sampler.flux(),
        max_radius,
        settings: *settings,
        times,
    })
}

/// Traces one chunk of photons with its own RNG; returns (global, caustic).
pub(crate) fn trace_chunk(
    scene: &Scene,
    light: &Light,
    sampler: &BeamSampler,
    settings: &PhotonSettings,
    chunk: u64,
) -> (Vec<Photon>, Vec<Photon>) {
    let mut rng = Pcg64Mcg::seed_from_u64(settings.seed ^ chunk.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let mut global = Vec::new();
    let mut caustic = Vec::new();
    for _ in 0..CHUNK {
        let Some(s) = sampler.sample(rng.random(), rng.random()) else { continue };
        let f = light.beam.pattern(s.dir);
        if f <= 0.0 {
            continue;
        }
        let mut power = Vec3::splat(f / s.pdf);
        let mut origin = light.position;
        let mut dir = (light.rotation * s.dir).normalize();
        let mut specular_only = true;
        for bounce in 0..=settings.max_bounces {
            let Some(hit) = scene.accel.intersect(origin, dir, f32::INFINITY) else { break };
            let sp = scene.surface(&hit);
            let m = &scene.materials[sp.material as usize];
            let rho = scene.diffuse_at(&sp);
            let Facing { front, geometric: ng, shading: ns } = sp.facing(dir);
            if bounce > 0 && rho.max_element() > 0.0 {
                let photon = Photon { position: sp.position, power, dir, normal: ns };
                if specular_only { caustic.push(photon) } else { global.push(photon) }
            }
            // Russian roulette over diffuse / mirror / transmission.
            let (pd, pr, pt) = scatter_probabilities(rho, m);
            let u: f32 = rng.random();
            if u < pd {
                power *= rho / pd;
                dir = cosine_hemisphere(ns, rng.random(), rng.random());
                if dir.dot(ng) <= 0.0 {
                    break;
                }
                origin = offset_origin(sp.position, ng);
                specular_only = false;
            } else if u < pd + pr {
                power *= m.k_r / pr;
                dir = reflect(dir, ns);
                if dir.dot(ng) <= 0.0 {
                    dir = reflect(dir, ng);
                }
                origin = offset_origin(sp.position, ng);
            } else if u < pd + pr + pt {
                power *= m.k_t / pt;
                let eta = if front { 1.0 / m.ior } else { m.ior };
                match refract(dir, ns, eta) {
                    Some(t) if t.dot(ng) < 0.0 => {
                        dir = t;
                        origin = offset_origin(sp.position, -ng);
                    }
                    _ => {
                        dir = reflect(dir, ns);
                        origin = offset_origin(sp.position, ng);
                    }
                }
            } else {
                break;
            }
            if !power.is_finite() || power.max_element() <= 0.0 {
                break;
            }
        }
    }
    (global, caustic)
}

/// The probabilities of a diffuse bounce, a mirror reflection and a
/// transmission at a surface of diffuse albedo `rho` and material `m`
/// (Russian roulette, Jensen 2001 §5.2): their mean coefficients, scaled
/// down together when they sum past 1. The photon tracer and the
/// reference path tracer ([`crate::render::reference::path`]) choose alike.
pub fn scatter_probabilities(rho: Vec3, m: &crate::scene::Material) -> (f32, f32, f32) {
    let (pd, pr, pt) = (rho.element_sum() / 3.0, m.k_r.element_sum() / 3.0, m.k_t.element_sum() / 3.0);
    let scale = (pd + pr + pt).max(1.0).recip();
    (pd * scale, pr * scale, pt * scale)
}

/// Cosine-weighted direction about unit normal `n`.
pub fn cosine_hemisphere(n: Vec3, u1: f32, u2: f32) -> Vec3 {
    let r = u1.sqrt();
    let phi = std::f32::consts::TAU * u2;
    let (t, b) = n.any_orthonormal_pair();
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt()).normalize_or(n)
}
