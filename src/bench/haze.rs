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
    MultipleSettings, at_density, multiple_along_ray, render_multiple, trace_volume_photons,
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
    /// Σ|re-weighted − rebuilt| / Σ rebuilt.
    pub rel_error: f64,
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
}

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
    /// Volume photons of the bench light on the stage: tracing + screen, ms.
    pub volume_stage_ms: f64,
    /// The live daemon's density knots (0, ½, 1) re-weighted for a hazer
    /// change against an exact rebuild at that density.
    pub density_live: Vec<DensityPoint>,
    /// A moved beam through the live tracer (`--haze-only` and full runs).
    pub moved: Option<MovedBeam>,
    /// The 600-fixture rig (full runs only).
    pub rig: Option<RigHaze>,
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
        for p in &self.density_live {
            s += &format!(
                "    live: density {:>4.0} % from knots 0/50/100 % (weights only) vs rebuilt: rel. L1 {:.2e}  max/peak {:.2e}\n",
                p.density * 100.0,
                p.rel_l1,
                p.max_err_of_peak
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
                "      density {:>3.0} %: photons re-weighted from 100 % vs traced at the density: rel. error {:.1} %\n",
                p.density * 100.0,
                p.rel_error * 100.0
            );
        }
        s += &format!(
            "      bench light on the stage: volume photons traced + screen term {:.0} ms\n",
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
        let single = f64::from(dense.sigma_s * integrate_ray(&empty, &dense, &spot, o, d, f32::INFINITY, 128).a1);
        dense.multiple = true;
        let similarity = f64::from(dense.sigma_s * integrate_ray(&empty, &dense, &spot, o, d, f32::INFINITY, 128).a1);
        multiple.push(MultiplePoint { height: y, path_traced: mc.all, std_error: mc.std_error, single, similarity });
    }
    let (volume, volume_density) = run_volume(paths, (w, h), repeats);
    let settings = MultipleSettings::default();
    let (volume_stage_ms, _) = time_ms(repeats, || {
        let photons = trace_volume_photons(scene, light, &medium, &settings);
        render_multiple(&hv, &medium, &photons, settings.scale)
    });
    // The live daemon's knots: weights only, against a rebuild at d.
    let knots = crate::render::media::knot_buffers(&hv, &medium, light.position, &surface, Some(&haze));
    let knot_dense: Vec<Vec<Vec3>> = [surface.to_dense(), knots[0].to_dense(), knots[1].to_dense()].into();
    let mut density_live = Vec::new();
    for d in [0.1f32, 0.25, 0.4, 0.6, 0.75, 0.9] {
        let wj = crate::render::media::knot_weights(d);
        let live: Vec<f32> =
            (0..knot_dense[0].len()).map(|i| (0..3).map(|j| wj[j] * knot_dense[j][i].x).sum::<f32>()).collect();
        let thin = medium.at_density(d);
        let rebuilt =
            resolve(&hv, &thin, light.position, &surface, Some(&render_inscatter(scene, &hv, light, &thin, q)), 1.0);
        let (rel_l1, max_err_of_peak) = errors(&live, &luminance(&rebuilt));
        density_live.push(DensityPoint { density: d, rel_l1, max_err_of_peak });
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
        moved: None,
        rig,
    })
}

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
            let single = f64::from(m.sigma_s * integrate_ray(&empty, &m, &spot, o, d, f32::INFINITY, 128).a1);
            m.multiple = true;
            let similarity = f64::from(m.sigma_s * integrate_ray(&empty, &m, &spot, o, d, f32::INFINITY, 128).a1);
            m.multiple = false;
            let est = f64::from(multiple_along_ray(&m, &photons, o, d, f32::INFINITY));
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
    // Density: the term at 100 % re-weighted against photons traced at d.
    let mut density = Vec::new();
    if let Ok(m) = Medium::new(0.3, 0.01, 0.8, lo, hi) {
        let full = trace_volume_photons(&empty, &spot, &m, &settings);
        for d in [0.1f32, 0.25, 0.5, 0.75] {
            let thin = m.at_density(d);
            let rebuilt = trace_volume_photons(&empty, &spot, &thin, &settings);
            let (mut num, mut den) = (0.0f64, 0.0f64);
            for &(o, dir) in &rays {
                let kappa = integrate_ray(&empty, &m, &spot, o, dir, f32::INFINITY, 128).kappa();
                let re = at_density(multiple_along_ray(&m, &full, o, dir, f32::INFINITY), kappa, d);
                let exact = multiple_along_ray(&thin, &rebuilt, o, dir, f32::INFINITY);
                num += f64::from((re - exact).abs());
                den += f64::from(exact);
            }
            density.push(VolumeDensityPoint { density: d, rel_error: num / den.max(1e-30) });
        }
    }
    (points, density)
}

/// Coarse haze buffers for every light of the rig at 1920×1080, and a
/// density change (re-weighting all of them; surface buffers stand in as empty).
fn run_rig(scene: &Scene, camera: Camera, lights: &[Light], medium: &Medium) -> RigHaze {
    let (w, h) = (1920, 1080);
    let hv = HazeView::new(scene, &GBuffer::build(scene, camera, w, h));
    let t = std::time::Instant::now();
    let buffers: Vec<_> = lights.iter().map(|l| render_inscatter(scene, &hv, l, medium, HazeQuality::COARSE)).collect();
    let coarse_all_s = t.elapsed().as_secs_f64();
    let empty = LightBuffer::empty(w, h);
    let t = std::time::Instant::now();
    let knots: Vec<[LightBuffer; 2]> = lights
        .iter()
        .zip(&buffers)
        .map(|(l, b)| crate::render::media::knot_buffers(&hv, medium, l.position, &empty, Some(b)))
        .collect();
    let density_change_ms = t.elapsed().as_secs_f64() * 1e3;
    let mib = |bytes: usize| bytes as f64 / (1 << 20) as f64;
    RigHaze {
        lights: lights.len(),
        width: w,
        height: h,
        coarse_all_s,
        density_change_ms,
        haze_mib: mib(buffers.iter().map(|b| b.bytes()).sum()),
        knot_mib: mib(knots.iter().flatten().map(|b| b.bytes()).sum()),
        tiles: empty.total_tiles(),
        beam_tiles: buffers.iter().map(|b| b.occupied_tiles()).sum::<usize>() as f64 / lights.len().max(1) as f64,
    }
}

/// The 600-fixture rig's lights (`scale::rig_patch`), for the rig rows.
pub fn rig_lights() -> Vec<Light> {
    let root = env!("CARGO_MANIFEST_DIR");
    crate::Patch::parse(std::path::Path::new("generated-600-rig.toml"), &super::scale::rig_patch(root))
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
    use crate::live::{Stage, Tracer, TracerSettings};
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
