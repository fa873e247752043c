//! Haze rows of `footlight bench` (issue 15): time against error for the
//! beam (samples per ray, beam-buffer scale, edge refinement), the cost of
//! a moved beam's first (coarse) stage, the density re-weighting error
//! against an exact rebuild and its cost, the multiple-scattering
//! approximation against the Monte Carlo volume path tracer, and haze on the
//! 600-fixture rig.
//!
//! Errors are on the in-scattered radiance image of one light at 100 %
//! density against every pixel traced with 256 samples per ray.

use super::time_ms;
use crate::fixture::Light;
use crate::render::LightBuffer;
use crate::render::gbuffer::GBuffer;
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
    /// Re-weighting all lights for a density change, ms.
    pub density_change_ms: f64,
    /// Haze buffer memory, MiB.
    pub haze_mib: f64,
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
        if let Some(r) = &self.rig {
            s += &format!(
                "    600-fixture rig {}×{}: coarse haze of all {} lights {:.1} s, density change {:.0} ms, haze buffers {:.0} MiB\n",
                r.width, r.height, r.lights, r.coarse_all_s, r.density_change_ms, r.haze_mib
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
        rig,
    })
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
    let resolved: Vec<LightBuffer> =
        lights.iter().zip(&buffers).map(|(l, b)| resolve(&hv, medium, l.position, &empty, Some(b), 0.6)).collect();
    let density_change_ms = t.elapsed().as_secs_f64() * 1e3;
    drop(resolved);
    RigHaze {
        lights: lights.len(),
        width: w,
        height: h,
        coarse_all_s,
        density_change_ms,
        haze_mib: buffers.iter().map(|b| b.bytes()).sum::<usize>() as f64 / (1 << 20) as f64,
    }
}
