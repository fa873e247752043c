//! Error against time (issue 34, item 3): the renderer's picture, stage by
//! stage, and the reference path tracer's, sample count by sample count,
//! both as relative MSE against one converged box-filtered reference, and
//! the speed ratio at equal error. Run alone with
//! `footlight bench --converge-only` (report.md, report.json and
//! error-time.svg in `--out`).
//!
//! The stage is built here (`box_stage`): a Lambert floor, back and side
//! walls and two boxes standing on the floor, lit by a hard-edged spot, a
//! soft raking spot and a front wash: beam rims, shadow edges, the faces of
//! boxes on a floor and wall corners, the places issue 34 found the error.
//! Every surface is Lambert, so the path tracer sees every path the photon
//! maps carry (no caustic through a mirror or glass).
//!
//! The reference is [`PathReference`] at many samples per pixel, traced as
//! two independent halves A and B: it is their mean, and its own error is
//! estimated as Σ|A − B|² / 4 (for independent unbiased halves E|A − B|² is
//! twice a half's variance, and the mean has half of that). Every figure is
//! given as measured and with that noise taken off (`corrected`): for an
//! estimate X independent of the reference R, E|X − R|² = |X − T|² + E|R − T|².

use crate::fixture::{Beam, Light, SpotBeam};
use crate::render::buffer::LightBuffer;
use crate::render::build::{BuildSettings, Cancel, LightBuild, NextStage, light_seed};
use crate::render::composite::composite;
use crate::render::photon::PhotonSettings;
use crate::render::reference::path::PathReference;
use crate::render::view::{EDGE_SAMPLES_PER_PASS, EdgeSamples, Sampling, View};
use crate::render::{RecursionLimits, RenderSettings};
use crate::scene::{Camera, Material, Scene, SceneBuilder};
use glam::Vec3;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// What the section runs.
#[derive(Clone, Copy, Debug)]
pub struct ErrorTimeConfig {
    /// Picture size.
    pub size: (u32, u32),
    /// Samples per pixel of the whole-picture reference (two halves).
    pub reference_spp: u32,
    /// Samples per pixel of the direct-term reference (two halves).
    pub direct_spp: u32,
    /// The renderer's refinement passes (`--refine N`).
    pub refine: u32,
}

impl ErrorTimeConfig {
    /// The 320×200 with 32 refinement passes; `quick`: 160×100, 8 passes, a short reference.
    pub fn new(quick: bool) -> Self {
        if quick {
            Self { size: (160, 100), reference_spp: 256, direct_spp: 64, refine: 8 }
        } else {
            Self { size: (320, 200), reference_spp: 4096, direct_spp: 512, refine: 32 }
        }
    }
}

/// One picture on a curve.
#[derive(Clone, Debug, Serialize)]
pub struct Point {
    /// What the picture is (a stage, a sample count).
    pub label: String,
    /// Seconds from the start to this picture (the renderer: view and
    /// build stages; the path tracer: its samples).
    pub seconds: f64,
    /// Σ|x − r|² / Σ|r|² against the reference, as measured.
    pub rel_mse: f64,
    /// The same less the reference's own noise (module docs); ≤ 0: below
    /// what the reference can tell.
    pub corrected: f64,
    /// The least-squares scale of the picture against the reference,
    /// Σ x·r / Σ r·r (1: no bias in total).
    pub scale: f64,
}

/// A picture of ours and the path tracer's time to the same error.
#[derive(Clone, Debug, Serialize)]
pub struct Ratio {
    /// Our picture.
    pub label: String,
    /// Its seconds.
    pub ours: f64,
    /// The path tracer's seconds to the same corrected error (log-log
    /// interpolated between its pictures; beyond its last, extrapolated at
    /// the Monte Carlo rate error ∝ 1/time); `None` when not comparable.
    pub path: Option<f64>,
    /// `path` came from the extrapolation.
    pub extrapolated: bool,
}

/// Everything the section measured.
#[derive(Clone, Debug, Serialize)]
pub struct ErrorTimeReport {
    /// Picture size.
    pub size: (u32, u32),
    /// Lights on the stage.
    pub lights: usize,
    /// Samples per pixel of the reference, and its seconds.
    pub reference_spp: u32,
    /// Seconds the reference took (both halves).
    pub reference_seconds: f64,
    /// The reference's own relative MSE, estimated from its halves.
    pub reference_noise: f64,
    /// The direct-term reference's samples and noise.
    pub direct_spp: u32,
    /// The direct-term reference's own relative MSE.
    pub direct_noise: f64,
    /// Our direct term at its first build (the Whitted stage) against the
    /// direct-term reference.
    pub direct: Point,
    /// The share of the direct term's squared error on the 5 % of pixels
    /// where the direct reference's gradient is highest (edges).
    pub direct_edge_share: f64,
    /// The direct term's worst pixels: (x, y, ours, reference), green channel.
    pub worst: Vec<(u32, u32, f32, f32)>,
    /// The direct term under each sampling rule (view and Whitted stage
    /// seconds) against the direct-term reference.
    pub direct_by_sampling: Vec<Point>,
    /// The direct term (adaptive sampling) after 1, 2, 4, … refinement
    /// passes of edge supersampling ([`crate::render::view::EdgeSamples`]):
    /// view, Whitted stage and passes, seconds; the edge pixels' share of
    /// the picture in the label.
    pub direct_refined: Vec<Point>,
    /// Our indirect term against the reference's, region by region.
    pub indirect_by_region: Vec<IndirectRegion>,
    /// Our whole picture stage by stage.
    pub ours: Vec<Point>,
    /// The path tracer's picture by samples per pixel.
    pub path: Vec<Point>,
    /// Speed ratios at equal error.
    pub ratios: Vec<Ratio>,
}

/// Our indirect term in one region of the picture (green channel):
/// Σ(picture − converged direct term) / Σ(reference − direct-only
/// reference) over the pixels whose centre sample lies there.
#[derive(Clone, Debug, Serialize)]
pub struct IndirectRegion {
    /// The region ([`REGIONS`]).
    pub name: String,
    /// Its pixels.
    pub pixels: usize,
    /// Ours / reference at the photon-map estimate.
    pub photon_estimate: f64,
    /// Ours / reference after the last refinement pass.
    pub refined: f64,
}

/// The regions of [`IndirectRegion`], bit r of a pixel's mask for region r.
pub const REGIONS: [&str; 6] = [
    "whole picture",
    "box faces (vertical)",
    "floor within 0.3 m of a box",
    "within 0.15 m of a wall corner",
    "within 0.3 m of an open edge",
    "the rest of the floor and walls",
];

/// The walls' and floor's extent of [`box_stage`] (m): floor x0..x1 ×
/// z0..z1, back wall at z0 and side wall at x0, both up to `top`.
struct StageExtent {
    x0: f32,
    x1: f32,
    z0: f32,
    z1: f32,
    top: f32,
}

/// [`box_stage`]'s extent.
const STAGE: StageExtent = StageExtent { x0: -6.0, x1: 6.0, z0: -4.0, z1: 4.0, top: 5.0 };

/// [`box_stage`]'s boxes (min, max corners): the tall one, the low one.
const BOXES: [(Vec3, Vec3); 2] =
    [(Vec3::new(-1.0, 0.0, -1.5), Vec3::new(0.0, 1.0, -0.5)), (Vec3::new(1.0, 0.0, -0.5), Vec3::new(3.0, 0.4, 0.5))];

/// Each pixel's region mask ([`REGIONS`]) from its centre sample on
/// [`box_stage`] ([`STAGE`], [`BOXES`]).
fn regions(scene: &Scene, view: &View) -> Vec<u8> {
    use crate::render::gbuffer::{CENTRE_SAMPLE, NO_HIT};
    use crate::scene::Hit;
    let StageExtent { x0, x1, z0, z1, top } = STAGE;
    let boxes = BOXES;
    view.gbuffer
        .samples
        .iter()
        .map(|px| {
            let s = px[CENTRE_SAMPLE];
            if s.triangle == NO_HIT {
                return 0;
            }
            let sp = scene.surface(&Hit { triangle: s.triangle, t: 0.0, u: s.u, v: s.v });
            let p = sp.position;
            let mut mask = 1u8;
            let on_box = boxes.iter().any(|(lo, hi)| p.cmpge(*lo - 1e-3).all() && p.cmple(*hi + 1e-3).all());
            if on_box && sp.geometric_normal.y.abs() < 0.5 {
                mask |= 2;
            }
            let floor = p.y.abs() < 1e-3 && !on_box;
            let near_box = boxes.iter().any(|(lo, hi)| {
                let d = (*lo - p).max(p - *hi).max(Vec3::ZERO);
                Vec3::new(d.x, 0.0, d.z).length() < 0.3
            });
            if floor && near_box {
                mask |= 4;
            }
            let near = |d: f32| d < 0.15;
            let corners = [near(p.y) && near(p.x - x0), near(p.y) && near(p.z - z0), near(p.x - x0) && near(p.z - z0)];
            if !on_box && corners.iter().any(|&c| c) {
                mask |= 8;
            }
            // The open edges: the floor's front and right edges, the walls'
            // tops and free ends (nothing beyond them to mark a cut).
            if !on_box && (p.x > x1 - 0.3 || p.z > z1 - 0.3 || p.y > top - 0.3) {
                mask |= 16;
            }
            if !on_box && mask & (4 | 8 | 16) == 0 {
                mask |= 32;
            }
            mask
        })
        .collect()
}

/// The section's stage: Lambert floor (ρ 0.5), back wall (0.6), a red-ish
/// side wall, a 1 m box (0.7) and a low wide box (0.3) on the floor; a hard
/// 12° spot on the tall box, a soft raking spot (10-20°) and a front wash
/// (20-35°); the camera in front at eye height above the stage.
pub fn box_stage() -> (Scene, Vec<Light>, Camera) {
    let mut b = SceneBuilder::new();
    let grey = |b: &mut SceneBuilder, name: &str, rho: f32| b.add_material(Material::lambert(name, Vec3::splat(rho)));
    let floor = grey(&mut b, "floor", 0.5);
    let back = grey(&mut b, "back wall", 0.6);
    let side = b.add_material(Material::lambert("side wall", Vec3::new(0.6, 0.3, 0.25)));
    let tall = grey(&mut b, "tall box", 0.7);
    let low = grey(&mut b, "low box", 0.3);
    let StageExtent { x0, x1, z0, z1, top } = STAGE;
    b.add_quad(Vec3::new(x0, 0.0, z1), Vec3::new(x1, 0.0, z1), Vec3::new(x1, 0.0, z0), Vec3::new(x0, 0.0, z0), floor);
    b.add_quad(Vec3::new(x0, 0.0, z0), Vec3::new(x1, 0.0, z0), Vec3::new(x1, top, z0), Vec3::new(x0, top, z0), back);
    b.add_quad(Vec3::new(x0, 0.0, z1), Vec3::new(x0, 0.0, z0), Vec3::new(x0, top, z0), Vec3::new(x0, top, z1), side);
    add_box(&mut b, BOXES[0].0, BOXES[0].1, tall);
    add_box(&mut b, BOXES[1].0, BOXES[1].1, low);
    let spot = |inner: f32, outer: f32| Beam::Spot(SpotBeam::from_half_angles(inner.to_radians(), outer.to_radians()));
    let lights = vec![
        Light::aimed(Vec3::new(-1.5, 4.5, 0.5), Vec3::new(-0.4, 0.5, -1.0), spot(12.0, 12.0)),
        Light::aimed(Vec3::new(-5.0, 2.5, 1.0), Vec3::new(1.5, 0.0, -0.5), spot(10.0, 20.0)),
        Light::aimed(Vec3::new(0.5, 4.0, 6.0), Vec3::new(0.5, 0.0, -1.0), spot(20.0, 35.0)),
    ];
    let camera = Camera::look_at(Vec3::new(1.0, 2.8, 7.5), Vec3::new(0.0, 0.7, -1.0), 55f32.to_radians());
    (b.build(), lights, camera)
}

/// An axis-aligned box standing on its base (five faces, outward).
fn add_box(b: &mut SceneBuilder, min: Vec3, max: Vec3, material: u32) {
    let p = |x: bool, y: bool, z: bool| {
        Vec3::new(if x { max.x } else { min.x }, if y { max.y } else { min.y }, if z { max.z } else { min.z })
    };
    b.add_quad(p(false, false, true), p(true, false, true), p(true, true, true), p(false, true, true), material);
    b.add_quad(p(true, false, false), p(false, false, false), p(false, true, false), p(true, true, false), material);
    b.add_quad(p(true, false, true), p(true, false, false), p(true, true, false), p(true, true, true), material);
    b.add_quad(p(false, false, false), p(false, false, true), p(false, true, true), p(false, true, false), material);
    b.add_quad(p(false, true, true), p(true, true, true), p(true, true, false), p(false, true, false), material);
}

/// Σ|a − b|² / Σ|b|².
pub fn rel_mse(a: &[Vec3], b: &[Vec3]) -> f64 {
    let err: f64 = a.iter().zip(b).map(|(a, b)| f64::from((*a - *b).length_squared())).sum();
    let energy: f64 = b.iter().map(|b| f64::from(b.length_squared())).sum();
    if energy > 0.0 { err / energy } else { 0.0 }
}

/// The `n` pixels of `img` furthest from `reference` (squared error):
/// (x, y, green of `img`, green of `reference`).
fn worst_pixels(img: &[Vec3], reference: &[Vec3], w: u32, n: usize) -> Vec<(u32, u32, f32, f32)> {
    let mut by_error: Vec<usize> = (0..img.len()).collect();
    let err = |i: usize| (img[i] - reference[i]).length_squared();
    by_error.sort_by(|a, b| err(*b).total_cmp(&err(*a)));
    by_error.into_iter().take(n).map(|i| (i as u32 % w, i as u32 / w, img[i].y, reference[i].y)).collect()
}

/// The share of Σ|img − reference|² on the 5 % of pixels with the highest
/// gradient of the reference (|Δx| + |Δy| of its green channel).
fn edge_share(img: &[Vec3], reference: &[Vec3], w: u32, h: u32) -> f64 {
    let (w, h) = (w as usize, h as usize);
    let g = |i: usize| reference[i].y;
    let gradient: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let dx = if x + 1 < w { (g(i + 1) - g(i)).abs() } else { 0.0 };
            let dy = if y + 1 < h { (g(i + w) - g(i)).abs() } else { 0.0 };
            dx + dy
        })
        .collect();
    let mut sorted = gradient.clone();
    sorted.sort_by(f32::total_cmp);
    let threshold = sorted[(sorted.len() * 95 / 100).min(sorted.len().saturating_sub(1))];
    let err = |i: usize| f64::from((img[i] - reference[i]).length_squared());
    let total: f64 = (0..w * h).map(err).sum();
    let edges: f64 = (0..w * h).filter(|&i| gradient[i] >= threshold).map(err).sum();
    if total > 0.0 { edges / total } else { 0.0 }
}

/// A converged reference from two independent halves of `spp` / 2 samples
/// each, in `medium` if given: (mean, its own relative MSE, seconds).
#[allow(clippy::too_many_arguments)]
pub(crate) fn reference(
    scene: &Scene,
    lights: &[Light],
    k: &[Vec3],
    camera: Camera,
    size: (u32, u32),
    spp: u32,
    indirect: bool,
    medium: Option<crate::render::media::Medium>,
) -> (Vec<Vec3>, f64, f64) {
    let t = Instant::now();
    let half = (spp / 2).max(1);
    let mut a = PathReference::new(camera, size.0, size.1, 0xA11CE, indirect);
    let mut b = PathReference::new(camera, size.0, size.1, 0xB0B, indirect);
    if let Some(m) = medium {
        (a, b) = (a.with_medium(m), b.with_medium(m));
    }
    // In rounds, so that a long reference shows progress in the log.
    let round = half.min(64);
    while a.samples() < half {
        let n = round.min(half - a.samples());
        a.add(scene, lights, k, n);
        b.add(scene, lights, k, n);
        tracing::debug!("reference: {} of {half} samples per half", a.samples());
    }
    let (a, b) = (a.mean(), b.mean());
    let mean: Vec<Vec3> = a.iter().zip(&b).map(|(a, b)| (*a + *b) * 0.5).collect();
    let noise = rel_mse(&a, &b) * rel_energy(&b, &mean) / 4.0;
    (mean, noise, t.elapsed().as_secs_f64())
}

/// Σ a·b / Σ b·b: the scale that best fits `a` to `b`.
pub fn fitted_scale(a: &[Vec3], b: &[Vec3]) -> f64 {
    let dot: f64 = a.iter().zip(b).map(|(a, b)| f64::from(a.dot(*b))).sum();
    let energy: f64 = b.iter().map(|b| f64::from(b.length_squared())).sum();
    if energy > 0.0 { dot / energy } else { 1.0 }
}

/// Σ|b|² / Σ|m|²: turns a relative MSE against `b` into one against `m`.
pub(crate) fn rel_energy(b: &[Vec3], m: &[Vec3]) -> f64 {
    let eb: f64 = b.iter().map(|v| f64::from(v.length_squared())).sum();
    let em: f64 = m.iter().map(|v| f64::from(v.length_squared())).sum();
    if em > 0.0 { eb / em } else { 1.0 }
}

/// Runs the section.
pub fn run(cfg: &ErrorTimeConfig) -> Result<ErrorTimeReport, crate::render::build::BuildError> {
    let (scene, lights, camera) = box_stage();
    let k = vec![Vec3::ONE; lights.len()];
    let (w, h) = cfg.size;
    tracing::info!("error against time: {w}×{h}, {} lights; the reference first", lights.len());
    let (reference_img, reference_noise, reference_seconds) =
        reference(&scene, &lights, &k, camera, cfg.size, cfg.reference_spp, true, None);
    let (direct_img, direct_noise, _) = reference(&scene, &lights, &k, camera, cfg.size, cfg.direct_spp, false, None);
    let point = |label: String, seconds: f64, img: &[Vec3], reference: &[Vec3], noise: f64| {
        let rel_mse = rel_mse(img, reference);
        Point { label, seconds, rel_mse, corrected: rel_mse - noise, scale: fitted_scale(img, reference) }
    };
    // Ours: `footlight render --refine N` stage by stage, every light one stage a round.
    tracing::info!("error against time: the renderer");
    let defaults = RenderSettings::default();
    let settings = BuildSettings {
        aa_threshold: defaults.build.aa_threshold,
        photons: Some(PhotonSettings::default()),
        refine_passes: cfg.refine,
        edge_samples: true,
        compact: false,
    };
    let t = Instant::now();
    let view = View::build(&scene, camera, w, h, defaults.sampling, RecursionLimits::default());
    let mut seconds = t.elapsed().as_secs_f64();
    let mut builds: Vec<LightBuild> =
        lights.iter().enumerate().map(|(i, l)| LightBuild::new(l.clone(), i, settings, Cancel::never())).collect();
    let mut latest: Vec<LightBuffer> = vec![LightBuffer::empty(w, h); lights.len()];
    let (mut ours, mut direct, mut pass) = (Vec::new(), None, 0);
    let (mut worst, mut direct_edge_share) = (Vec::new(), 0.0);
    let (mut photon_img, mut last_img) = (Vec::new(), Vec::new());
    loop {
        let mut stage = None;
        for (i, b) in builds.iter_mut().enumerate() {
            let Some(next) = b.next_stage() else { continue };
            let t = Instant::now();
            let step = b.next(&scene, &view)?;
            seconds += t.elapsed().as_secs_f64();
            if let Some(step) = step {
                latest[i] = step.buffer;
            }
            stage = Some(next);
        }
        let Some(stage) = stage else { break };
        let refs: Vec<&LightBuffer> = latest.iter().collect();
        let img = composite(&refs, &k, w, h);
        let label = match stage {
            NextStage::Direct(_) | NextStage::Whitted => "direct (Whitted stage)".to_string(),
            NextStage::Photons => "photon-map estimate".to_string(),
            NextStage::Refine => {
                pass += 1;
                format!("refinement pass {pass}")
            }
        };
        if direct.is_none() {
            worst = worst_pixels(&img, &direct_img, w, 10);
            direct_edge_share = edge_share(&img, &direct_img, w, h);
            direct = Some(point(label.clone(), seconds, &img, &direct_img, direct_noise));
        }
        if stage == NextStage::Photons {
            photon_img = img.clone();
        }
        last_img = img.clone();
        ours.push(point(label, seconds, &img, &reference_img, reference_noise));
    }
    // The path tracer, its own seed, sample counts doubling until it has run
    // four times our time or reached the reference's samples.
    tracing::info!("error against time: the path tracer");
    let limit = 4.0 * seconds;
    let mut pt = PathReference::new(camera, w, h, 0xC0FFEE, true);
    let (mut path, mut pt_seconds) = (Vec::new(), 0.0);
    while pt_seconds < limit && pt.samples() < cfg.reference_spp {
        let n = pt.samples().max(1);
        let t = Instant::now();
        pt.add(&scene, &lights, &k, n);
        pt_seconds += t.elapsed().as_secs_f64();
        path.push(point(format!("{} spp", pt.samples()), pt_seconds, &pt.mean(), &reference_img, reference_noise));
    }
    let ratios = ours.iter().map(|p| ratio(p, &path)).collect();
    // The direct term under each sampling rule (adaptive must not be worse than nine).
    let (mut direct_by_sampling, mut direct_refined, mut direct_best) = (Vec::new(), Vec::new(), Vec::new());
    for sampling in [Sampling::One, Sampling::Geometry, Sampling::Adaptive, Sampling::Nine] {
        let t = Instant::now();
        let view = View::build(&scene, camera, w, h, sampling, RecursionLimits::default());
        let mut buffers = Vec::new();
        for (i, l) in lights.iter().enumerate() {
            let direct_only = BuildSettings { photons: None, refine_passes: 0, ..settings };
            buffers.push(LightBuild::new(l.clone(), i, direct_only, Cancel::never()).whitted(&scene, &view)?);
        }
        let seconds = t.elapsed().as_secs_f64();
        let img = composite(&buffers.iter().collect::<Vec<_>>(), &k, w, h);
        direct_by_sampling.push(point(format!("{sampling:?}"), seconds, &img, &direct_img, direct_noise));
        if sampling != Sampling::Adaptive {
            continue;
        }
        // The refinement passes' edge supersampling on this direct term.
        let t = Instant::now();
        let mut edges: Vec<EdgeSamples> = buffers
            .iter()
            .zip(&lights)
            .enumerate()
            .map(|(i, (b, l))| EdgeSamples::select(&scene, &view, l, b, light_seed(0xED6E, i)))
            .collect();
        let mut spent = seconds + t.elapsed().as_secs_f64();
        let share = edges.iter().map(EdgeSamples::len).sum::<usize>() as f64 / (lights.len() * (w * h) as usize) as f64;
        for pass in 1..=cfg.refine {
            let t = Instant::now();
            for (e, l) in edges.iter_mut().zip(&lights) {
                e.pass_until(&scene, &view, l, &|| false);
            }
            spent += t.elapsed().as_secs_f64();
            if pass.is_power_of_two() || pass == cfg.refine {
                let refined: Vec<LightBuffer> = buffers
                    .iter()
                    .zip(&edges)
                    .map(|(b, e)| {
                        let mut dense = b.to_dense();
                        e.replace_in(&mut dense, b);
                        LightBuffer::from_dense(w, h, &dense)
                    })
                    .collect();
                let img = composite(&refined.iter().collect::<Vec<_>>(), &k, w, h);
                let label = format!(
                    "{pass} pass{} ({} samples in {:.1} % of pixels)",
                    if pass == 1 { "" } else { "es" },
                    pass * EDGE_SAMPLES_PER_PASS,
                    share * 100.0
                );
                direct_refined.push(point(label, spent, &img, &direct_img, direct_noise));
                direct_best = img;
            }
        }
    }
    // The indirect term by region: ours (picture less the converged direct
    // term) against the reference's (full less direct-only).
    let regions = regions(&scene, &view);
    let indirect = |img: &[Vec3], direct: &[Vec3]| -> Vec<f64> {
        img.iter().zip(direct).map(|(a, d)| f64::from(a.y) - f64::from(d.y)).collect()
    };
    let reference_indirect = indirect(&reference_img, &direct_img);
    let (photon_indirect, last_indirect) = (indirect(&photon_img, &direct_best), indirect(&last_img, &direct_best));
    let indirect_by_region = REGIONS
        .iter()
        .enumerate()
        .map(|(r, name)| {
            let sum = |v: &[f64]| -> f64 { (0..v.len()).filter(|&i| regions[i] & (1 << r) != 0).map(|i| v[i]).sum() };
            let reference = sum(&reference_indirect);
            let pixels = regions.iter().filter(|&&m| m & (1 << r) != 0).count();
            let ratio = |v: &[f64]| if reference > 0.0 { sum(v) / reference } else { f64::NAN };
            IndirectRegion {
                name: (*name).to_string(),
                pixels,
                photon_estimate: ratio(&photon_indirect),
                refined: ratio(&last_indirect),
            }
        })
        .collect();
    Ok(ErrorTimeReport {
        size: cfg.size,
        lights: lights.len(),
        reference_spp: cfg.reference_spp,
        reference_seconds,
        reference_noise,
        direct_spp: cfg.direct_spp,
        direct_noise,
        direct: direct.expect("the first stage ran"),
        direct_edge_share,
        worst,
        direct_by_sampling,
        direct_refined,
        indirect_by_region,
        ours,
        path,
        ratios,
    })
}

/// The path tracer's time to `ours`' corrected error (module docs of [`Ratio`]).
fn ratio(ours: &Point, path: &[Point]) -> Ratio {
    let none = Ratio { label: ours.label.clone(), ours: ours.seconds, path: None, extrapolated: false };
    let e = ours.corrected;
    let usable: Vec<&Point> = path.iter().filter(|p| p.corrected > 0.0).collect();
    if e.is_nan() || e <= 0.0 || usable.is_empty() {
        return none;
    }
    if e >= usable[0].corrected {
        return none; // worse than the path tracer's first picture
    }
    for pair in usable.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        if e <= a.corrected && e >= b.corrected {
            let f = (e.ln() - a.corrected.ln()) / (b.corrected.ln() - a.corrected.ln());
            let t = (a.seconds.ln() + f * (b.seconds.ln() - a.seconds.ln())).exp();
            return Ratio { path: Some(t), ..none };
        }
    }
    let last = usable[usable.len() - 1];
    Ratio { path: Some(last.seconds * last.corrected / e), extrapolated: true, ..none }
}

impl ErrorTimeReport {
    /// The report as Markdown.
    pub fn markdown(&self) -> String {
        let (w, h) = self.size;
        let mut s = format!(
            "## Error against time (issue 34)\n\n`bench::error_time::box_stage`: Lambert floor, walls and two boxes \
             on the floor, {} lights (hard 12° spot, soft raking spot, front wash), {w}×{h}, box-filtered pixels, \
             linear RGB. Relative MSE Σ|x − r|²/Σ|r|² against the reference path tracer at {} samples per pixel \
             ({:.0} s), whose own noise, from its two halves, is **{:.2e}** (\"corrected\" takes it off). Both \
             renderers run on the same thread pool.\n\n",
            self.lights, self.reference_spp, self.reference_seconds, self.reference_noise
        );
        s += &format!(
            "**Direct term at first build** ({}): rel. MSE {:.2e} (corrected {:.2e}) against the direct-only \
             reference at {} spp (noise {:.2e}), at {:.2} s; {:.0} % of its squared error lies on the 5 % of pixels \
             with the highest gradient. Its worst pixels (x, y: ours / reference, green): {}.\n\n",
            self.direct.label,
            self.direct.rel_mse,
            self.direct.corrected,
            self.direct_spp,
            self.direct_noise,
            self.direct.seconds,
            self.direct_edge_share * 100.0,
            self.worst.iter().map(|(x, y, a, r)| format!("({x}, {y}: {a:.4} / {r:.4})")).collect::<Vec<_>>().join(", ")
        );
        s += "| direct term, sampling | s (view + Whitted) | rel. MSE | corrected | scale |\n|---|---:|---:|---:|---:|\n";
        for p in &self.direct_by_sampling {
            s += &format!(
                "| {} | {:.3} | {:.2e} | {:.2e} | {:.4} |\n",
                p.label, p.seconds, p.rel_mse, p.corrected, p.scale
            );
        }
        s += &format!(
            "\nEdge supersampling (`render::view::EdgeSamples`) of the adaptive direct term, batch after batch of \
             {EDGE_SAMPLES_PER_PASS} stratified samples in each edge pixel. The photon stage runs the first {} \
             before it publishes (the first full picture's direct term is the \"{} passes\" row); refinement adds \
             one at passes 1, 2, 4, 8, ….\n",
            crate::render::build::EDGE_PASSES_AT_PHOTONS,
            crate::render::build::EDGE_PASSES_AT_PHOTONS
        );
        s += "\n| direct term, edge supersampling | s (view + Whitted + passes) | rel. MSE | corrected | scale |\n\
              |---|---:|---:|---:|---:|\n";
        for p in &self.direct_refined {
            s += &format!(
                "| {} | {:.3} | {:.2e} | {:.2e} | {:.4} |\n",
                p.label, p.seconds, p.rel_mse, p.corrected, p.scale
            );
        }
        s += "\nOur indirect term against the reference's, by region (green channel; Σ ours / Σ reference over the \
              pixels whose centre sample lies there; ours is the picture less the converged direct term, the \
              reference's its full picture less the direct-only one):\n\n\
              | region | pixels | photon-map estimate | after the last pass |\n|---|---:|---:|---:|\n";
        for r in &self.indirect_by_region {
            s += &format!("| {} | {} | {:.4} | {:.4} |\n", r.name, r.pixels, r.photon_estimate, r.refined);
        }
        s += "\n| our picture | s | rel. MSE | corrected | scale | path tracer to the same error, s | ratio |\n\
              |---|---:|---:|---:|---:|---:|---:|\n";
        for (p, r) in self.ours.iter().zip(&self.ratios) {
            let (pt, ratio) = match r.path {
                Some(t) => (
                    format!("{t:.2}{}", if r.extrapolated { " (extrapolated)" } else { "" }),
                    format!("{:.1}×", t / r.ours),
                ),
                None => ("—".to_string(), "—".to_string()),
            };
            s += &format!(
                "| {} | {:.2} | {:.2e} | {:.2e} | {:.4} | {pt} | {ratio} |\n",
                p.label, p.seconds, p.rel_mse, p.corrected, p.scale
            );
        }
        s += "\n| path tracer | s | rel. MSE | corrected | scale |\n|---|---:|---:|---:|---:|\n";
        for p in &self.path {
            s += &format!(
                "| {} | {:.2} | {:.2e} | {:.2e} | {:.4} |\n",
                p.label, p.seconds, p.rel_mse, p.corrected, p.scale
            );
        }
        s
    }

    /// The curves as an SVG (log time against log error).
    pub fn svg(&self) -> String {
        use super::plots::{Series, log_log_svg};
        let line = |name: &str, colour: &str, points: &[Point]| Series {
            name: name.to_string(),
            colour: colour.to_string(),
            points: points.iter().filter(|p| p.corrected > 0.0).map(|p| (p.seconds, p.corrected)).collect(),
        };
        log_log_svg(
            "Error against time: ours vs the reference path tracer",
            "seconds",
            "rel. MSE (reference noise taken off)",
            Some(3e-4),
            &[
                line("footlight (stages, refinement passes)", "#c03", &self.ours),
                line("path tracer", "#06c", &self.path),
            ],
        )
    }

    /// Writes report.md, report.json and error-time.svg into `out`.
    pub fn write(&self, out: &Path) -> std::io::Result<()> {
        std::fs::create_dir_all(out)?;
        std::fs::write(out.join("report.md"), format!("# footlight bench: error against time\n\n{}", self.markdown()))?;
        std::fs::write(out.join("report.json"), serde_json::to_string_pretty(self).map_err(std::io::Error::other)?)?;
        std::fs::write(out.join("error-time.svg"), self.svg())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(seconds: f64, corrected: f64) -> Point {
        Point { label: String::new(), seconds, rel_mse: corrected, corrected, scale: 1.0 }
    }

    #[test]
    fn the_ratio_interpolates_in_log_log_and_extrapolates_at_the_monte_carlo_rate() {
        let path = [p(1.0, 1e-2), p(4.0, 2.5e-3), p(16.0, 6.25e-4)];
        // On the 1/t line between the points: 5e-3 at 2 s.
        let r = ratio(&p(0.5, 5e-3), &path);
        assert!((r.path.unwrap() - 2.0).abs() < 1e-9 && !r.extrapolated);
        // Beyond the last point: 1/t goes on.
        let r = ratio(&p(3.0, 1e-4), &path);
        assert!((r.path.unwrap() - 100.0).abs() < 1e-9 && r.extrapolated);
        // Worse than the first picture, or below the reference's noise: none.
        assert!(ratio(&p(0.1, 2e-2), &path).path.is_none());
        assert!(ratio(&p(0.1, -1e-6), &path).path.is_none());
    }
}
