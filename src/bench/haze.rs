//! Haze rows of `footlight bench` (issue 15): time against error for the
//! beam (samples per ray, beam-buffer scale, edge refinement), the cost of
//! a moved beam's first (coarse) stage, the density re-weighting error
//! against an exact rebuild and its cost, the multiple-scattering
//! approximation against the Monte Carlo volume path tracer, and haze on the
//! 600-fixture rig; for the live daemon (`footlight bench --haze-only`): the
//! density-knot re-weighting a hazer change costs (weights only) against an
//! exact rebuild, and a moved beam through the live tracer (request → the
//! light's direct stage with its coarse beam published).
//!
//! Errors are on the in-scattered radiance image of one light at 100 %
//! density against every pixel traced with 256 samples per ray.

use super::time_ms;
use crate::fixture::Light;
use crate::render::LightBuffer;
use crate::render::gbuffer::GBuffer;
use crate::render::media::multiple::{
    MultipleSettings, anchored, multiple_along_ray, render_multiple, render_surface_glow, trace_haze_photons,
    trace_volume_photons,
};
use crate::render::media::reference::path_traced_ray;
use crate::render::media::single::radiance_at_full;
use crate::render::media::{HazeQuality, HazeView, Medium, integrate_ray, render_inscatter, resolve};
use crate::scene::{Camera, Scene, SceneBuilder};
use glam::Vec3;
use serde::Serialize;

/// One beam setting and what it costs and misses.
#[derive(Clone, Debug, Serialize)]
pub struct BeamPoint {
    /// The sampling.
    pub quality: HazeQuality,
    /// Median wall time for one light, ms.
    pub ms: f64,
    /// Σ|L − L_ref| / Σ L_ref over the image.
    pub rel_l1: f64,
    /// Largest |L − L_ref| / peak(L_ref).
    pub max_err_of_peak: f64,
}

/// Density re-weighting against a rebuild at that density.
#[derive(Clone, Debug, Serialize)]
pub struct DensityPoint {
    /// Density 0-1.
    pub density: f32,
    /// Σ|re-weighted − rebuilt| / Σ rebuilt over the light's buffer.
    pub rel_l1: f64,
    /// Largest |re-weighted − rebuilt| / peak(rebuilt).
    pub max_err_of_peak: f64,
}

/// Multiple scattering along one ray: renderer vs path tracer.
#[derive(Clone, Debug, Serialize)]
pub struct MultiplePoint {
    /// Height of the camera ray crossing the beam, m.
    pub height: f32,
    /// Path tracer, all orders (per 1 cd).
    pub path_traced: f64,
    /// Its standard error.
    pub std_error: f64,
    /// Renderer, single scattering only.
    pub single: f64,
    /// Renderer with the similarity relation.
    pub similarity: f64,
}

/// Multiple scattering by volume photons ([`crate::render::media::multiple`])
/// against the path tracer, for one medium: summed over the rays.
#[derive(Clone, Debug, Serialize)]
pub struct VolumePoint {
    /// σ_s per metre.
    pub sigma_s: f32,
    /// Henyey-Greenstein g.
    pub g: f32,
    /// Photons emitted.
    pub photons: usize,
    /// Path tracer, orders ≥ 2 (all minus order 1), summed over the rays.
    pub reference: f64,
    /// Its standard error (of the all-orders sum).
    pub std_error: f64,
    /// Volume photons, orders ≥ 2, summed over the rays.
    pub estimate: f64,
    /// Path tracer, all orders, summed.
    pub all: f64,
    /// Renderer: single scattering (σ_t on light paths) + volume photons.
    pub total: f64,
    /// Renderer: the similarity relation (the term before), summed.
    pub similarity: f64,
    /// Largest |total − all| / all over the rays.
    pub max_ray_error: f64,
    /// Photon tracing for one light, ms.
    pub trace_ms: f64,
    /// The screen term at the bench size (scale 8), ms.
    pub render_ms: f64,
}

/// The multiple-scattering term at density d from its value at 100 %
/// (m d² e^((1 − d) κ)) against photons traced at d, summed over the rays.
#[derive(Clone, Debug, Serialize)]
pub struct VolumeDensityPoint {
    /// Density 0-1.
    pub density: f32,
    /// |Σ re-weighted − Σ rebuilt| / Σ rebuilt over the bench's rays (at
    /// d = 1 the noise floor: two photon seeds): photons traced at 100 %,
    /// their paths re-weighted to the density
    /// ([`crate::render::media::multiple::VolumePhotons::at_density`]: what
    /// `render` and the live knots use), against photons traced at it.
    pub rel_error: f64,
    /// The same for the term at 100 % scaled by d² e^((1 − d) κ) (before).
    pub law_error: f64,
    /// The live daemon between its knots: hat weights of the re-weighted
    /// term at 0, ½ and 1, against photons traced at the density.
    pub live_error: f64,
}

/// Haze on the 600-fixture rig.
#[derive(Clone, Debug, Serialize)]
pub struct RigHaze {
    /// Lights.
    pub lights: usize,
    /// Picture size.
    pub width: u32,
    /// Picture size.
    pub height: u32,
    /// Coarse haze buffers of all lights, s.
    pub coarse_all_s: f64,
    /// Resolving every light's knot buffers (½ and 1; once per build, not
    /// per density change), ms.
    pub density_change_ms: f64,
    /// Beam (haze buffer) memory of all lights, MiB.
    pub haze_mib: f64,
    /// Knot-buffer memory of all lights (haze part only: surfaces empty), MiB.
    pub knot_mib: f64,
    /// Tiles of the picture, per light.
    pub tiles: usize,
    /// Tiles the beams fill, mean per light.
    pub beam_tiles: f64,
    /// Where the coarse beams' time goes: all lights at 1 sample per ray
    /// (cone tests, the bounds, upsampling, tiles), s.
    pub one_sample_s: f64,
    /// Tiles inside the screen bounds the beams are computed over (with the
    /// upsampling margin), mean per light.
    pub bounds_tiles: f64,
    /// Coarse rays traced (inside the bounds), mean per light.
    pub coarse_rays: f64,
    /// Of those, rays that meet the cone inside the haze box, mean per light.
    pub cone_rays: f64,
    /// Tail culling measured: for a threshold τ (share of the light's own
    /// peak), the knot-buffer MiB left if the haze-only tiles whose largest
    /// value is below τ · peak were dropped, and the composite's
    /// (rel. L1, max/peak) error at knot 1 (all lights at k = 1).
    pub tail: Vec<(f32, f64, f64, f64)>,
    /// The density between knots the rig is rebuilt at ([`RIG_DENSITY`]).
    pub density: f32,
    /// One full composite of every light's two non-zero knot buffers at a
    /// density between ½ and 1 (all faders changed at once: the CPU
    /// compositor's worst frame in haze), ms; and the same without haze
    /// (each light's knot 1 alone standing in for its surface buffer).
    pub composite_ms: (f64, f64),
    /// A hazer change on the CPU compositor with every light's knots kept
    /// as layers ([`crate::render::composite::Compositor::update_layers`]:
    /// new weights, the kept sums recombined and encoded), ms (median of 5,
    /// the density moving between ½ and 1).
    pub hazer_change_ms: f64,
    /// Every fader changed at once on the same compositor (k of every light
    /// in every layer, weights kept: both kept sums recomposed, then
    /// recombined and encoded), ms (median of 3).
    pub layered_faders_ms: f64,
    /// The live composite at that density (knot weights only) against an
    /// exact rebuild of every beam there, all lights at k = 1: (rel. L1,
    /// max/peak) with the daemon's knot weights, then with
    /// [`quadratic_weights`].
    pub reweighting_error: [(f64, f64); 2],
}

/// The density the rig is rebuilt at: between the knots 0 and ½, where
/// the interpolation error is largest in the single-light rows.
pub const RIG_DENSITY: f32 = 0.25;

/// A moved beam through the live tracer ([`crate::live::Tracer`]).
#[derive(Clone, Debug, Serialize)]
pub struct MovedBeam {
    /// Picture size.
    pub width: u32,
    /// Picture size.
    pub height: u32,
    /// Build threads.
    pub threads: usize,
    /// Moves measured.
    pub moves: usize,
    /// Request → direct stage with its coarse beam published, median ms.
    pub median_ms: f64,
    /// The same, worst, ms.
    pub max_ms: f64,
    /// The coarse beam against the refined one: Σ|L − L_ref| / Σ L_ref.
    pub coarse_rel_l1: f64,
    /// Largest |L − L_ref| / peak(L_ref).
    pub coarse_max_err_of_peak: f64,
}

/// All haze rows.
#[derive(Clone, Debug, Serialize)]
pub struct HazeReport {
    /// The medium measured (stage bounds, 100 %).
    pub sigma_s: f32,
    /// σ_a.
    pub sigma_a: f32,
    /// g.
    pub g: f32,
    /// Picture size.
    pub width: u32,
    /// Picture size.
    pub height: u32,
    /// Beam time against error.
    pub beam: Vec<BeamPoint>,
    /// Density re-weighting errors.
    pub density: Vec<DensityPoint>,
    /// One light's re-weighting (a hazer change), ms.
    pub density_change_ms: f64,
    /// Multiple scattering against the path tracer.
    pub multiple: Vec<MultiplePoint>,
    /// Multiple scattering by volume photons against the path tracer.
    pub volume: Vec<VolumePoint>,
    /// The volume-photon term re-weighted to a density against a rebuild.
    pub volume_density: Vec<VolumeDensityPoint>,
    /// Photons (air and surfaces) of the bench light on the stage: tracing +
    /// screen terms at the live knots, ms.
    pub volume_stage_ms: f64,
    /// The live daemon's density knots (0, ½, 1) re-weighted for a hazer
    /// change against an exact rebuild at that density.
    pub density_live: Vec<DensityPoint>,
    /// The same with [`quadratic_weights`] (not used live: negative weights).
    pub density_live_quadratic: Vec<DensityPoint>,
    /// A moved beam through the live tracer (`--haze-only` and full runs).
    pub moved: Option<MovedBeam>,
    /// The 600-fixture rig (full runs only).
    pub rig: Option<RigHaze>,
    /// The whole hazy picture against the volume path tracer
    /// (`--haze-only` and full runs; [`super::haze_whole`]).
    pub whole: Option<super::haze_whole::WholeHaze>,
}

impl HazeReport {
    /// Lines for the terminal summary and report.md.
    pub fn lines(&self) -> String {
        let mut s = format!(
            "  haze (σ_s {} /m, σ_a {} /m, g {}, {}×{}):\n",
            self.sigma_s, self.sigma_a, self.g, self.width, self.height
        );
        for p in &self.beam {
            let q = p.quality;
            s += &format!(
                "    beam scale {} samples {:>3} refine {:<5}  {:>8.1} ms  rel. L1 {:.4}  max/peak {:.4}\n",
                q.scale, q.samples, q.refine_edges, p.ms, p.rel_l1, p.max_err_of_peak
            );
        }
        for p in &self.density {
            s += &format!(
                "    density {:>4.0} % re-weighted vs rebuilt: rel. L1 {:.2e}  max/peak {:.2e}\n",
                p.density * 100.0,
                p.rel_l1,
                p.max_err_of_peak
            );
        }
        s += &format!("    density change (one light, re-weighting only): {:.2} ms\n", self.density_change_ms);
        for (p, quad) in self.density_live.iter().zip(&self.density_live_quadratic) {
            s += &format!(
                "    live: density {:>4.0} % from knots 0/50/100 % (weights only) vs rebuilt: rel. L1 {:.2e}  max/peak {:.2e} (quadratic weights would give {:.2e}, {:.2e})\n",
                p.density * 100.0,
                p.rel_l1,
                p.max_err_of_peak,
                quad.rel_l1,
                quad.max_err_of_peak
            );
        }
        if let Some(m) = &self.moved {
            s += &format!(
                "    live: moved beam {}×{} on {} threads, request → direct stage + coarse beam published: median {:.1} ms, max {:.1} ms over {} moves; coarse vs refined beam rel. L1 {:.4}, max/peak {:.4}\n",
                m.width, m.height, m.threads, m.median_ms, m.max_ms, m.moves, m.coarse_rel_l1, m.coarse_max_err_of_peak
            );
        }
        for p in &self.multiple {
            s += &format!(
                "    multiple scattering at y {:.1} m: path-traced {:.3e} ± {:.1e}, single {:.3e} ({:+.1} %), similarity {:.3e} ({:+.1} %)\n",
                p.height,
                p.path_traced,
                p.std_error,
                p.single,
                (p.single / p.path_traced - 1.0) * 100.0,
                p.similarity,
                (p.similarity / p.path_traced - 1.0) * 100.0
            );
        }
        s += "    multiple scattering by volume photons (orders ≥ 2; 30° spot, 8×6×8 m box, rays at y 4, 2.5, 1 m, sums over the rays):\n";
        for p in &self.volume {
            s += &format!(
                "      σ_s {:.2} g {:.1} {:>6} photons: captured {:>5.1} % of orders ≥ 2 ({:.3e} of {:.3e}); single + photons {:+.1} % of all orders (worst ray {:.1} %), similarity before {:+.1} %; {:.0} ms trace + {:.0} ms screen {}×{}\n",
                p.sigma_s,
                p.g,
                p.photons,
                p.estimate / p.reference * 100.0,
                p.estimate,
                p.reference,
                (p.total / p.all - 1.0) * 100.0,
                p.max_ray_error * 100.0,
                (p.similarity / p.all - 1.0) * 100.0,
                p.trace_ms,
                p.render_ms,
                self.width,
                self.height
            );
        }
        for p in &self.volume_density {
            s += &format!(
                "      density {:>3.0} % (100,000 photons, summed over the rays): against photons traced at the density, photon paths re-weighted from 100 % rel. error {:.1} % (before: d² e^((1 − d) κ) {:.1} %); live knots 0, ½, 1 with hat weights {:.1} %\n",
                p.density * 100.0,
                p.rel_error * 100.0,
                p.law_error * 100.0,
                p.live_error * 100.0
            );
        }
        s += &format!(
            "      bench light on the stage: photons traced (air and surfaces) + screen terms at the knots ½ and 1 {:.0} ms\n",
            self.volume_stage_ms
        );
        if let Some(r) = &self.rig {
            s += &format!(
                "    600-fixture rig {}×{}: coarse beams of all {} lights {:.1} s ({:.0} of {} tiles per beam), beam buffers {:.0} MiB; knot buffers ½, 1: {:.0} ms to resolve, {:.0} MiB\n",
                r.width,
                r.height,
                r.lights,
                r.coarse_all_s,
                r.beam_tiles,
                r.tiles,
                r.haze_mib,
                r.density_change_ms,
                r.knot_mib
            );
            s += "    600-fixture rig live memory: beams are resolved into the knots as they are made and not kept (before: all beams kept, the MiB above); per light its surface buffer and the two knot buffers\n";
            s += &format!(
                "    600-fixture rig beam time: {:.1} s at 8 samples, {:.1} s at 1 sample per ray; per beam {:.0} tiles in its bounds, {:.0} coarse rays, {:.0} meeting the cone\n",
                r.coarse_all_s, r.one_sample_s, r.bounds_tiles, r.coarse_rays, r.cone_rays
            );
            s += &format!(
                "    600-fixture rig density {:.0} % from the knots (weights only) vs every beam rebuilt, all lights at k = 1 (beams only): rel. L1 {:.2e} max/peak {:.2e} (quadratic weights would give {:.2e}, {:.2e})\n",
                r.density * 100.0,
                r.reweighting_error[0].0,
                r.reweighting_error[0].1,
                r.reweighting_error[1].0,
                r.reweighting_error[1].1
            );
            s += &format!(
                "    600-fixture rig full composite (every fader changed) at {}×{}: {:.0} ms in haze (two knot buffers per light, {:.1} Hz), {:.0} ms with one buffer per light ({:.1} Hz)\n",
                r.width,
                r.height,
                r.composite_ms.0,
                1e3 / r.composite_ms.0.max(1e-9),
                r.composite_ms.1,
                1e3 / r.composite_ms.1.max(1e-9)
            );
            s += &format!(
                "    600-fixture rig hazer change on the CPU compositor (knots kept as layers, weights only) at {}×{}: {:.0} ms ({:.1} Hz); every fader changed on it: {:.0} ms ({:.1} Hz)\n",
                r.width,
                r.height,
                r.hazer_change_ms,
                1e3 / r.hazer_change_ms.max(1e-9),
                r.layered_faders_ms,
                1e3 / r.layered_faders_ms.max(1e-9)
            );
            for (tau, mib, rel, max) in &r.tail {
                s += &format!(
                    "    600-fixture rig knot tails below {tau:.0e} of each light's peak dropped: {mib:.0} MiB of knots, knot 1 composite rel. L1 {rel:.2e} max/peak {max:.2e}\n"
                );
            }
        }
        if let Some(w) = &self.whole {
            s += &w.lines();
        }
        s
    }
}

/// The medium the bench measures: the stage's bounds, a light haze.
pub fn bench_medium(scene: &Scene) -> Option<Medium> {
    let (lo, hi) = crate::render::media::medium::scene_bounds(scene)?;
    Medium::new(0.03, 0.003, 0.7, lo, hi).ok()
}

fn errors(got: &[f32], reference: &[f32]) -> (f64, f64) {
    let peak = reference.iter().fold(0.0f32, |a, &b| a.max(b)) as f64;
    let (mut num, mut den, mut max) = (0.0f64, 0.0f64, 0.0f64);
    for (a, b) in got.iter().zip(reference) {
        let e = f64::from((a - b).abs());
        num += e;
        den += f64::from(*b);
        max = max.max(e);
    }
    (num / den.max(1e-30), max / peak.max(1e-30))
}

fn luminance(b: &LightBuffer) -> Vec<f32> {
    b.to_dense().iter().map(|v| v.x).collect()
}

/// Runs the haze rows for `light` over `scene` from `camera` at `w`×`h`;
/// `rig` adds the 600-fixture rig at 1920×1080.
#[allow(clippy::too_many_arguments)]
pub fn run(
    scene: &Scene,
    camera: Camera,
    w: u32,
    h: u32,
    light: &Light,
    repeats: usize,
    paths: usize,
    rig: Option<&[Light]>,
) -> Option<HazeReport> {
    let medium = bench_medium(scene)?;
    let gbuffer = GBuffer::build(scene, camera, w, h);
    let hv = HazeView::new(scene, &gbuffer);
    // Reference: every pixel, 256 samples.
    let full = HazeQuality { scale: 1, samples: 256, refine_edges: false };
    let reference = radiance_at_full(&render_inscatter(scene, &hv, light, &medium, full), &medium);
    let mut beam = Vec::new();
    let settings = [
        HazeQuality { scale: 4, samples: 8, refine_edges: false },
        HazeQuality { scale: 4, samples: 16, refine_edges: false },
        HazeQuality { scale: 2, samples: 16, refine_edges: false },
        HazeQuality { scale: 4, samples: 32, refine_edges: true },
        HazeQuality { scale: 2, samples: 32, refine_edges: true },
        HazeQuality { scale: 1, samples: 8, refine_edges: false },
        HazeQuality { scale: 1, samples: 16, refine_edges: false },
        HazeQuality { scale: 1, samples: 32, refine_edges: false },
        HazeQuality { scale: 1, samples: 64, refine_edges: false },
    ];
    for q in settings {
        let (ms, buf) = time_ms(repeats, || render_inscatter(scene, &hv, light, &medium, q));
        let (rel_l1, max_err_of_peak) = errors(&radiance_at_full(&buf, &medium), &reference);
        beam.push(BeamPoint { quality: q, ms, rel_l1, max_err_of_peak });
    }
    // Density: re-weighting vs a rebuild at that density (surface included).
    let view = crate::render::View::from_gbuffer(
        scene,
        gbuffer,
        crate::render::Sampling::One,
        crate::render::RecursionLimits { max_depth: 0, ..Default::default() },
    );
    let (surface, _) = view.render_light(scene, light, None);
    let q = HazeQuality { scale: 1, samples: 32, refine_edges: false };
    let haze = render_inscatter(scene, &hv, light, &medium, q);
    let mut density = Vec::new();
    for d in [0.1f32, 0.25, 0.5, 0.75] {
        let re = resolve(&hv, &medium, light.position, &surface, Some(&haze), d);
        let thin = medium.at_density(d);
        let rebuilt =
            resolve(&hv, &thin, light.position, &surface, Some(&render_inscatter(scene, &hv, light, &thin, q)), 1.0);
        let (rel_l1, max_err_of_peak) = errors(&luminance(&re), &luminance(&rebuilt));
        density.push(DensityPoint { density: d, rel_l1, max_err_of_peak });
    }
    let (density_change_ms, _) =
        time_ms(repeats.max(5), || resolve(&hv, &medium, light.position, &surface, Some(&haze), 0.4));
    // Multiple scattering: dense forward haze, a 30° beam, rays at 3 heights.
    let empty = SceneBuilder::new().build();
    let mut dense = Medium::new(0.3, 0.01, 0.8, Vec3::new(-4.0, 0.0, -4.0), Vec3::new(4.0, 6.0, 4.0)).ok()?;
    let spot = Light::aimed(
        Vec3::new(0.0, 5.5, 0.0),
        Vec3::new(0.0, 4.5, 0.0),
        crate::fixture::Beam::Spot(crate::fixture::SpotBeam::from_beam_field(20.0, 30.0)),
    );
    let mut multiple = Vec::new();
    for (k, y) in [4.0f32, 2.5, 1.0].into_iter().enumerate() {
        let (o, d) = (Vec3::new(0.4, y, 10.0), Vec3::NEG_Z);
        let mc = path_traced_ray(&dense, &spot, o, d, f32::INFINITY, paths, 64, 0x4A2E + k as u64);
        dense.multiple = false;
        let single = f64::from(dense.sigma_s * integrate_ray(&empty, &dense, &spot, o, d, f32::INFINITY, 128).a1());
        dense.multiple = true;
        let similarity = f64::from(dense.sigma_s * integrate_ray(&empty, &dense, &spot, o, d, f32::INFINITY, 128).a1());
        multiple.push(MultiplePoint { height: y, path_traced: mc.all, std_error: mc.std_error, single, similarity });
    }
    let (volume, volume_density) = run_volume(paths, (w, h), repeats);
    let settings = MultipleSettings::default();
    let (volume_stage_ms, _) = time_ms(repeats, || {
        // As the live refined stage: traced once (air and surfaces),
        // rendered at the knots ½ and 1.
        let photons = trace_haze_photons(scene, light, &medium, &settings);
        let knots = &crate::render::media::KNOTS[1..];
        let glows = render_surface_glow(scene, &hv, &medium, &photons.surface, knots);
        knots
            .iter()
            .zip(glows)
            .map(|(&d, glow)| {
                let air = render_multiple(&hv, &medium.at_density(d), &photons.volume.at_density(d), settings.scale);
                air.iter().zip(&glow).map(|(a, g)| *a + *g).collect::<Vec<_>>()
            })
            .collect::<Vec<_>>()
    });
    // The live daemon's knots: weights only, against a rebuild at d.
    let knots = crate::render::media::knot_buffers(&hv, &medium, light.position, &surface, Some(&haze));
    let knot_dense: Vec<Vec<Vec3>> = [surface.to_dense(), knots[0].to_dense(), knots[1].to_dense()].into();
    let (mut density_live, mut density_live_quadratic) = (Vec::new(), Vec::new());
    for d in [0.1f32, 0.25, 0.4, 0.6, 0.75, 0.9] {
        let thin = medium.at_density(d);
        let rebuilt =
            resolve(&hv, &thin, light.position, &surface, Some(&render_inscatter(scene, &hv, light, &thin, q)), 1.0);
        let rebuilt = luminance(&rebuilt);
        let weights = [crate::render::media::knot_weights(d), quadratic_weights(d)];
        for (wj, into) in weights.iter().zip([&mut density_live, &mut density_live_quadratic]) {
            let live: Vec<f32> =
                (0..knot_dense[0].len()).map(|i| (0..3).map(|j| wj[j] * knot_dense[j][i].x).sum::<f32>()).collect();
            let (rel_l1, max_err_of_peak) = errors(&live, &rebuilt);
            into.push(DensityPoint { density: d, rel_l1, max_err_of_peak });
        }
    }
    let rig = rig.map(|lights| run_rig(scene, camera, lights, &medium));
    Some(HazeReport {
        sigma_s: medium.sigma_s,
        sigma_a: medium.sigma_a,
        g: medium.g,
        width: w,
        height: h,
        beam,
        density,
        density_change_ms,
        multiple,
        volume,
        volume_density,
        volume_stage_ms,
        density_live,
        density_live_quadratic,
        moved: None,
        rig,
        whole: None,
    })
}

/// Quadratic Lagrange weights of the knots 0, ½, 1 for density `d`: an
/// alternative to the daemon's hat weights measured by the bench. They
/// match the surface term e^(−d κ) to second order in κ and the haze term
/// d e^(−d κ) to first (hats: first and zeroth), but go negative (down to
/// −⅛), which the GPU compositor refuses as a bad weight; non-negative
/// weights exact at κ = 0 cannot do better than hats (Jensen).
pub fn quadratic_weights(d: f32) -> [f32; 3] {
    let d = crate::render::media::medium::clean_density(d);
    [2.0 * (d - 0.5) * (d - 1.0), 4.0 * d * (1.0 - d), d * (2.0 * d - 1.0)]
}

/// Tail thresholds measured on the rig (share of a light's own peak).
const TAILS: [f32; 3] = [1e-4, 1e-3, 1e-2];

/// Volume photons against the path tracer (`paths` per ray) in the
/// multiple-scattering box at three densities and two g, with the screen
/// term timed at `size`; and the density re-weighting of the term.
pub fn run_volume(paths: usize, size: (u32, u32), repeats: usize) -> (Vec<VolumePoint>, Vec<VolumeDensityPoint>) {
    let empty = SceneBuilder::new().build();
    let (lo, hi) = (Vec3::new(-4.0, 0.0, -4.0), Vec3::new(4.0, 6.0, 4.0));
    let spot = Light::aimed(
        Vec3::new(0.0, 5.5, 0.0),
        Vec3::new(0.0, 4.5, 0.0),
        crate::fixture::Beam::Spot(crate::fixture::SpotBeam::from_beam_field(20.0, 30.0)),
    );
    let rays: Vec<(Vec3, Vec3)> = [4.0f32, 2.5, 1.0].iter().map(|&y| (Vec3::new(0.4, y, 10.0), Vec3::NEG_Z)).collect();
    let camera = Camera::look_at(Vec3::new(0.0, 3.0, 12.0), Vec3::new(0.0, 3.0, 0.0), 50f32.to_radians());
    let hv = HazeView::new(&empty, &GBuffer::build(&empty, camera, size.0, size.1));
    let settings = MultipleSettings::default();
    let mut points = Vec::new();
    for (sigma_s, g) in [(0.03f32, 0.8f32), (0.1, 0.8), (0.3, 0.8), (0.3, 0.5)] {
        let Ok(mut m) = Medium::new(sigma_s, 0.01 * sigma_s / 0.3, g, lo, hi) else { continue };
        let (trace_ms, photons) = time_ms(repeats, || trace_volume_photons(&empty, &spot, &m, &settings));
        let (render_ms, _) = time_ms(repeats, || render_multiple(&hv, &m, &photons, settings.scale));
        let mut p = VolumePoint {
            sigma_s,
            g,
            photons: settings.photons,
            reference: 0.0,
            std_error: 0.0,
            estimate: 0.0,
            all: 0.0,
            total: 0.0,
            similarity: 0.0,
            max_ray_error: 0.0,
            trace_ms,
            render_ms,
        };
        let mut var = 0.0;
        for (k, &(o, d)) in rays.iter().enumerate() {
            let mc = path_traced_ray(&m, &spot, o, d, f32::INFINITY, paths, 64, 0x7A11 + k as u64);
            m.multiple = false;
            let single = f64::from(m.sigma_s * integrate_ray(&empty, &m, &spot, o, d, f32::INFINITY, 128).a1());
            m.multiple = true;
            let similarity = f64::from(m.sigma_s * integrate_ray(&empty, &m, &spot, o, d, f32::INFINITY, 128).a1());
            m.multiple = false;
            // Grey: no surface tints these photons (an empty scene).
            let est = f64::from(multiple_along_ray(&m, &photons, o, d, f32::INFINITY).x);
            p.reference += mc.all - mc.single;
            p.estimate += est;
            p.all += mc.all;
            p.total += single + est;
            p.similarity += similarity;
            p.max_ray_error = p.max_ray_error.max(((single + est) / mc.all - 1.0).abs());
            var += mc.std_error * mc.std_error;
        }
        p.std_error = var.sqrt();
        points.push(p);
    }
    // Density: the term at d from photons traced at 100 % (paths
    // re-weighted; before: scaled by a law) and between the live knots,
    // against photons traced at d (another seed: the difference includes
    // both estimates' noise).
    let mut density = Vec::new();
    if let Ok(m) = Medium::new(0.3, 0.01, 0.8, lo, hi) {
        // 5× the live photon count: the rows compare estimates, not noise.
        let settings = MultipleSettings { photons: 100_000, ..settings };
        let full = trace_volume_photons(&empty, &spot, &m, &settings);
        let half = (m.at_density(0.5), full.at_density(0.5));
        for d in [0.1f32, 0.25, 0.5, 0.75, 1.0] {
            let thin = m.at_density(d);
            let other = MultipleSettings { seed: settings.seed ^ 0xD0D0, ..settings };
            let rebuilt = trace_volume_photons(&empty, &spot, &thin, &other);
            let reweighted = full.at_density(d);
            let hats = crate::render::media::knot_weights(d);
            // Sums over the rays (one ray alone is noisy at 20,000 photons).
            let (mut num, mut law, mut live, mut den) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            for &(o, dir) in &rays {
                let kappa = integrate_ray(&empty, &m, &spot, o, dir, f32::INFINITY, 128).kappa();
                let at = |med: &Medium, ph| multiple_along_ray(med, ph, o, dir, f32::INFINITY).x;
                let exact = at(&thin, &rebuilt);
                let re = at(&thin, &reweighted);
                let scaled = anchored(at(&m, &full), kappa, 1.0, d);
                let knots = hats[1] * at(&half.0, &half.1) + hats[2] * at(&m, &full);
                num += f64::from(re);
                law += f64::from(scaled);
                live += f64::from(knots);
                den += f64::from(exact);
            }
            let den = den.max(1e-30);
            density.push(VolumeDensityPoint {
                density: d,
                rel_error: (num - den).abs() / den,
                law_error: (law - den).abs() / den,
                live_error: (live - den).abs() / den,
            });
        }
    }
    (points, density)
}

/// Coarse haze buffers for every light of the rig at 1920×1080, and a
/// density change (re-weighting all of them; surface buffers stand in as
/// empty) and its error against rebuilding every beam at a density between
/// the knots; where the beam time goes; what dropping knot tails would save
/// and cost.
fn run_rig(scene: &Scene, camera: Camera, lights: &[Light], medium: &Medium) -> RigHaze {
    use crate::render::buffer::TILE;
    let (w, h) = (1920, 1080);
    let hv = HazeView::new(scene, &GBuffer::build(scene, camera, w, h));
    let t = std::time::Instant::now();
    let buffers: Vec<_> = lights.iter().map(|l| render_inscatter(scene, &hv, l, medium, HazeQuality::COARSE)).collect();
    let coarse_all_s = t.elapsed().as_secs_f64();
    let one = HazeQuality { samples: 1, ..HazeQuality::COARSE };
    let t = std::time::Instant::now();
    for l in lights {
        std::hint::black_box(render_inscatter(scene, &hv, l, medium, one));
    }
    let one_sample_s = t.elapsed().as_secs_f64();
    // The rays the coarse stage traces: every 4th pixel inside the bounds.
    let (mut bounds_tiles, mut coarse_rays, mut cone_rays) = (0usize, 0usize, 0usize);
    let s = HazeQuality::COARSE.scale as usize;
    for l in lights {
        let Some((x0, y0, x1, y1)) = crate::render::media::single::beam_screen_bounds(&hv, l, medium) else { continue };
        let (ex0, ey0) = (x0.saturating_sub(s) / TILE, y0.saturating_sub(s) / TILE);
        let (ex1, ey1) = ((x1 + s).min(w as usize).div_ceil(TILE), (y1 + s).min(h as usize).div_ceil(TILE));
        bounds_tiles += (ex1 - ex0) * (ey1 - ey0);
        for y in (s / 2..h as usize).step_by(s).filter(|y| (y0..y1).contains(y)) {
            for x in (s / 2..w as usize).step_by(s).filter(|x| (x0..x1).contains(x)) {
                coarse_rays += 1;
                let i = y * w as usize + x;
                let (o, d) = (hv.camera.position, hv.dir(i));
                let meets = medium.clip(o, d, hv.t_hit(i)).and_then(|(a, b)| {
                    crate::render::media::single::cone_interval(l.position, l.axis(), l.beam.cos_cutoff(), o, d, a, b)
                });
                cone_rays += usize::from(meets.is_some());
            }
        }
    }
    let empty = LightBuffer::empty(w, h);
    let mib = |bytes: usize| bytes as f64 / (1 << 20) as f64;
    let n = (w * h) as usize;
    // Composites at k = 1 of the knots, of an exact rebuild at RIG_DENSITY, and
    // of what each tail threshold drops from knot 1.
    let mut sum = [vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]];
    let mut dropped = vec![vec![Vec3::ZERO; n]; TAILS.len()];
    let mut tail_bytes = [0usize; TAILS.len()];
    let (mut density_change_ms, mut knot_bytes) = (0.0, 0usize);
    let thin = medium.at_density(RIG_DENSITY);
    let mut rebuilt = vec![Vec3::ZERO; n];
    let add = |into: &mut [Vec3], b: &LightBuffer, only: Option<&[(usize, usize)]>| {
        let tiles = only.map_or_else(|| b.occupied(), <[_]>::to_vec);
        for (tx, ty) in tiles {
            let Some(tile) = b.tile(tx, ty) else { continue };
            for r in 0..TILE.min(h as usize - ty * TILE) {
                for c in 0..TILE.min(w as usize - tx * TILE) {
                    into[(ty * TILE + r) * w as usize + tx * TILE + c] += tile[r * TILE + c];
                }
            }
        }
    };
    let mut kept = Vec::with_capacity(lights.len());
    for (l, b) in lights.iter().zip(&buffers) {
        let t = std::time::Instant::now();
        let knots = crate::render::media::knot_buffers(&hv, medium, l.position, &empty, Some(b));
        density_change_ms += t.elapsed().as_secs_f64() * 1e3;
        knot_bytes += knots.iter().map(LightBuffer::bytes).sum::<usize>();
        for j in 0..2 {
            add(&mut sum[j], &knots[j], None);
        }
        let beam = render_inscatter(scene, &hv, l, &thin, HazeQuality::COARSE);
        add(&mut rebuilt, &resolve(&hv, &thin, l.position, &empty, Some(&beam), 1.0), None);
        // Tails: per-tile largest value of either knot against the light's peak.
        let tiles = knots[1].occupied();
        let tile_max = |tx: usize, ty: usize| {
            knots
                .iter()
                .filter_map(|k| k.tile(tx, ty))
                .flat_map(|t| t.into_owned())
                .map(|v| v.max_element())
                .fold(0.0f32, f32::max)
        };
        let maxes: Vec<f32> = tiles.iter().map(|&(tx, ty)| tile_max(tx, ty)).collect();
        let peak = maxes.iter().copied().fold(0.0f32, f32::max);
        let per_tile = knots.iter().map(|k| k.bytes()).sum::<usize>() as f64 / tiles.len().max(1) as f64;
        for (k, tau) in TAILS.iter().enumerate() {
            let drop: Vec<(usize, usize)> =
                tiles.iter().zip(&maxes).filter(|(_, m)| **m < tau * peak).map(|(t, _)| *t).collect();
            tail_bytes[k] += ((tiles.len() - drop.len()) as f64 * per_tile) as usize;
            add(&mut dropped[k], &knots[1], Some(&drop));
        }
        kept.push(knots);
    }
    // The compositor's worst frame in haze: every light's k changed, two
    // knot buffers each (hat weights at d = 0.75), against one buffer each.
    let hats = crate::render::media::knot_weights(0.75);
    let refs: Vec<&LightBuffer> = kept.iter().flat_map(|k| [&k[0], &k[1]]).collect();
    let ks: Vec<Vec3> = kept.iter().flat_map(|_| [Vec3::splat(hats[1]), Vec3::splat(hats[2])]).collect();
    let (hazy_ms, _) = super::time_ms(3, || crate::render::composite::composite(&refs, &ks, w, h));
    let ones: Vec<&LightBuffer> = kept.iter().map(|k| &k[1]).collect();
    let (clear_ms, _) = super::time_ms(3, || crate::render::composite::composite(&ones, &ks[..ones.len()], w, h));
    // The daemon's way (`live::clock::FrameEntries`): the knots as layers
    // of the CPU compositor, a hazer change re-weights the kept sums.
    let empty_surface = LightBuffer::empty(w, h);
    let surface = &empty_surface;
    let layers_at = |level: f32| -> Vec<_> {
        (0..3)
            .flat_map(|j| {
                kept.iter().map(move |k| crate::render::composite::CompositeInput {
                    buffer: if j == 0 { surface } else { &k[j - 1] },
                    generation: 0,
                    k: Vec3::splat(level),
                })
            })
            .collect()
    };
    let layers = layers_at(1.0);
    let mut compositor = crate::render::composite::Compositor::new(w, h, crate::render::Display::default());
    compositor.update_layers(&layers, &crate::render::media::knot_weights(0.75));
    let mut step = 0;
    let (hazer_change_ms, _) = super::time_ms(5, || {
        step += 1;
        let d = if step % 2 == 0 { 0.7 } else { 0.8 };
        compositor.update_layers(&layers, &crate::render::media::knot_weights(d))
    });
    let faded = layers_at(0.9);
    let weights = crate::render::media::knot_weights(0.75);
    let (layered_faders_ms, _) = super::time_ms(3, || {
        step += 1;
        compositor.update_layers(if step % 2 == 0 { &layers } else { &faded }, &weights)
    });
    drop((layers, faded));
    drop(kept);
    let grey = |v: &[Vec3]| v.iter().map(|p| p.x).collect::<Vec<f32>>();
    // Surfaces are empty: the knot 0 adds nothing, whatever its weight.
    let live = |wj: [f32; 3]| sum[0].iter().zip(&sum[1]).map(|(a, b)| wj[1] * a.x + wj[2] * b.x).collect::<Vec<f32>>();
    let rebuilt = grey(&rebuilt);
    let reweighting_error = [
        errors(&live(crate::render::media::knot_weights(RIG_DENSITY)), &rebuilt),
        errors(&live(quadratic_weights(RIG_DENSITY)), &rebuilt),
    ];
    let full = grey(&sum[1]);
    let tail = TAILS
        .iter()
        .enumerate()
        .map(|(k, &tau)| {
            let kept: Vec<f32> = full.iter().zip(&dropped[k]).map(|(a, d)| a - d.x).collect();
            let (rel, max) = errors(&kept, &full);
            (tau, mib(tail_bytes[k]), rel, max)
        })
        .collect();
    let count = lights.len().max(1) as f64;
    RigHaze {
        lights: lights.len(),
        width: w,
        height: h,
        coarse_all_s,
        density_change_ms,
        haze_mib: mib(buffers.iter().map(|b| b.bytes()).sum()),
        knot_mib: mib(knot_bytes),
        tiles: empty.total_tiles(),
        beam_tiles: buffers.iter().map(|b| b.occupied_tiles()).sum::<usize>() as f64 / count,
        one_sample_s,
        bounds_tiles: bounds_tiles as f64 / count,
        coarse_rays: coarse_rays as f64 / count,
        cone_rays: cone_rays as f64 / count,
        tail,
        density: RIG_DENSITY,
        composite_ms: (hazy_ms, clear_ms),
        hazer_change_ms,
        layered_faders_ms,
        reweighting_error,
    }
}

/// The 600-fixture rig's lights (`scale::rig_patch`), for the rig rows.
pub fn rig_lights() -> Vec<Light> {
    let root = match crate::bundled::root_of("patch/fixtures") {
        Ok(root) => root.to_string_lossy().into_owned(),
        Err(e) => {
            tracing::error!("the 600-fixture rig: {e}");
            return Vec::new();
        }
    };
    crate::Patch::parse(std::path::Path::new("generated-600-rig.toml"), &super::scale::rig_patch(&root))
        .map(|p| p.lights())
        .unwrap_or_default()
}

/// A moved beam through the live tracer at `w`×`h` on `threads` build
/// threads: `moves` pan steps of `light` (15° about the vertical), each
/// timed from the request to its direct stage, coarse beam included, being
/// published (what the frame clock composites next); the tracer finishes
/// each light (Whitted, refined beam) before the next move. Photons off:
/// they run only on a settled light and do not delay the first stage.
pub fn moved_beam(
    scene: &std::sync::Arc<Scene>,
    camera: Camera,
    (w, h): (u32, u32),
    threads: usize,
    light: &Light,
    moves: usize,
) -> Option<MovedBeam> {
    use crate::live::{Tracer, TracerSettings};
    use crate::output::Stage;
    use std::time::{Duration, Instant};
    let medium = bench_medium(scene)?;
    let view = crate::render::View::build(
        scene,
        camera,
        w,
        h,
        crate::render::Sampling::Adaptive,
        crate::render::RecursionLimits::default(),
    );
    let hv = HazeView::new(scene, &view.gbuffer);
    let mut settings = TracerSettings { threads, ..TracerSettings::default() };
    settings.build.photons = None;
    let tracer = Tracer::with_haze(scene.clone(), std::sync::Arc::new(view), 1, settings, Some(medium));
    let wait = |what: &dyn Fn(Stage) -> bool| {
        let t = Instant::now();
        while !what(tracer.published(0).stage) && t.elapsed() < Duration::from_secs(120) {
            std::thread::sleep(Duration::from_micros(200));
        }
    };
    let moved = |k: usize| {
        let turn = glam::Quat::from_rotation_y((15.0 * k as f32).to_radians());
        Light { rotation: turn * light.rotation, ..light.clone() }
    };
    tracer.request(0, moved(0), 1.0);
    wait(&|s| s == Stage::Ready);
    let mut times = Vec::new();
    for k in 1..=moves.max(1) {
        let generation = tracer.published(0).generation;
        let t = Instant::now();
        tracer.request(0, moved(k), 1.0);
        while tracer.published(0).generation == generation && t.elapsed() < Duration::from_secs(120) {
            std::thread::sleep(Duration::from_micros(100));
        }
        times.push(t.elapsed().as_secs_f64() * 1e3);
        wait(&|s| s == Stage::Ready);
    }
    drop(tracer);
    times.sort_by(f64::total_cmp);
    let refined = radiance_at_full(&render_inscatter(scene, &hv, light, &medium, HazeQuality::REFINED), &medium);
    let coarse = radiance_at_full(&render_inscatter(scene, &hv, light, &medium, HazeQuality::COARSE), &medium);
    let (coarse_rel_l1, coarse_max_err_of_peak) = errors(&coarse, &refined);
    Some(MovedBeam {
        width: w,
        height: h,
        threads,
        moves: times.len(),
        median_ms: times[times.len() / 2],
        max_ms: times[times.len() - 1],
        coarse_rel_l1,
        coarse_max_err_of_peak,
    })
}
