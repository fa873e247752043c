//! The whole hazy picture against the volume path tracer (issue 34,
//! item 5): `footlight bench --haze-only` (and full runs).
//!
//! The stage is the error-time section's box stage
//! ([`super::error_time::box_stage`]) filled with haze (σ_s 0.05 /m,
//! σ_a 0.002 /m, g 0.7 over the scene's bounds, 100 % density). Our
//! pictures are `footlight render`'s ([`render_still_hazy`]): single
//! scattering only, and the whole model (`multiple = true`: the beam, volume
//! photons, surface light into the haze and haze light onto surfaces). The
//! reference is [`crate::render::reference::path::PathReference`] with the
//! medium: every order of surface and volume scattering, box-filtered,
//! traced as two independent halves so its own noise is reported and taken
//! off. Reported per picture: energy, relative MSE, fitted scale, and the
//! energy of three regions: the air (pixels that see no surface), lit
//! surfaces (the clear stage's direct light reaches them) and unlit ones.

use super::error_time::{box_stage, fitted_scale, reference, rel_mse};
use crate::render::media::medium::scene_bounds;
use crate::render::media::{HazeQuality, Medium};
use crate::render::reference::path::PathReference;
use crate::render::still::{LightJob, RenderError, StillHaze, render_still_hazy};
use crate::render::{RenderSettings, Sampling};
use glam::Vec3;
use serde::Serialize;
use std::time::Instant;

/// The medium of the section (issue 34 item 5's).
pub const SIGMA_S: f32 = 0.05;
/// σ_a, /m.
pub const SIGMA_A: f32 = 0.002;
/// Henyey-Greenstein g.
pub const G: f32 = 0.7;

/// Size and reference samples.
#[derive(Clone, Copy, Debug)]
pub struct WholeHazeConfig {
    /// Picture size.
    pub size: (u32, u32),
    /// Reference samples per pixel (two halves).
    pub reference_spp: u32,
}

impl WholeHazeConfig {
    /// 160×100 with 256 samples (`--quick`), else 320×200 with 1024.
    pub fn new(quick: bool) -> Self {
        if quick {
            Self { size: (160, 100), reference_spp: 256 }
        } else {
            Self { size: (320, 200), reference_spp: 1024 }
        }
    }
}

/// Which pixels a region holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Region {
    /// The centre ray sees no surface: haze only.
    Air,
    /// A surface the clear stage's direct light reaches.
    Lit,
    /// A surface it does not reach.
    Unlit,
}

/// One of our pictures against the reference.
#[derive(Clone, Debug, Serialize)]
pub struct WholeHazeRow {
    /// What was rendered.
    pub label: String,
    /// Seconds for the picture (`render`'s stages, all lights).
    pub seconds: f64,
    /// Σ ours / Σ reference (luminance-free: all channels).
    pub energy: f64,
    /// Relative MSE against the reference.
    pub rel_mse: f64,
    /// The same less the reference's own noise.
    pub rel_mse_corrected: f64,
    /// Σ ours·ref / Σ ref·ref.
    pub fitted_scale: f64,
    /// Σ ours / Σ reference per region (air, lit, unlit).
    pub regions: [f64; 3],
    /// Share of the squared error per region (air, lit, unlit).
    pub error_share: [f64; 3],
}

/// The section's figures.
#[derive(Clone, Debug, Serialize)]
pub struct WholeHaze {
    /// Picture size.
    pub size: (u32, u32),
    /// σ_s, σ_a, g.
    pub medium: (f32, f32, f32),
    /// Reference samples per pixel.
    pub reference_spp: u32,
    /// Reference seconds.
    pub reference_s: f64,
    /// The reference's own relative MSE (two halves).
    pub reference_noise: f64,
    /// Share of the reference's energy per region (air, lit, unlit).
    pub region_share: [f64; 3],
    /// Share of the pixels per region.
    pub region_pixels: [f64; 3],
    /// Our pictures.
    pub rows: Vec<WholeHazeRow>,
}

/// The section's medium over `scene`'s bounds.
pub fn stage_medium(scene: &crate::scene::Scene) -> Option<Medium> {
    let (lo, hi) = scene_bounds(scene)?;
    Medium::new(SIGMA_S, SIGMA_A, G, lo, hi).ok().map(|m| Medium { multiple: true, ..m })
}

/// Runs the section.
pub fn run(cfg: &WholeHazeConfig) -> Result<WholeHaze, RenderError> {
    let (scene, lights, camera) = box_stage();
    let Some(medium) = stage_medium(&scene) else {
        unreachable!("the box stage has bounds");
    };
    let k = vec![Vec3::ONE; lights.len()];
    let (w, h) = cfg.size;
    tracing::info!("whole haze: {w}×{h}; the reference first ({} samples per pixel)", cfg.reference_spp);
    let (reference_img, reference_noise, reference_s) =
        reference(&scene, &lights, &k, camera, cfg.size, cfg.reference_spp, true, Some(medium));
    // Regions from the clear stage's direct light (the reference's, 4 samples).
    let mut clear = PathReference::new(camera, w, h, 0xC1EA, false);
    clear.add(&scene, &lights, &k, 4);
    let clear = clear.mean();
    let lit_level = {
        let mut v: Vec<f32> = clear.iter().map(|c| c.element_sum()).filter(|&c| c > 0.0).collect();
        v.sort_by(f32::total_cmp);
        v.get(v.len() * 99 / 100).copied().unwrap_or(0.0) * 0.01
    };
    let regions: Vec<Region> = (0..(w * h) as usize)
        .map(|i| {
            let dir = camera.direction((i % w as usize) as f32 + 0.5, (i / w as usize) as f32 + 0.5, w, h);
            if scene.accel.intersect(camera.position, dir, f32::INFINITY).is_none() {
                Region::Air
            } else if clear[i].element_sum() > lit_level {
                Region::Lit
            } else {
                Region::Unlit
            }
        })
        .collect();
    let index = |r: Region| match r {
        Region::Air => 0,
        Region::Lit => 1,
        Region::Unlit => 2,
    };
    let sums = |img: &[Vec3]| {
        let mut s = [0.0f64; 3];
        for (v, r) in img.iter().zip(&regions) {
            s[index(*r)] += f64::from(v.element_sum());
        }
        s
    };
    let reference_sums = sums(&reference_img);
    let total: f64 = reference_sums.iter().sum();
    let mut region_pixels = [0.0f64; 3];
    for r in &regions {
        region_pixels[index(*r)] += 1.0 / regions.len() as f64;
    }
    let jobs: Vec<LightJob> =
        lights.iter().map(|l| LightJob { light: l.clone(), k_full: Vec3::ONE, k: Vec3::ONE, fixture: None }).collect();
    let settings = RenderSettings { width: w, height: h, sampling: Sampling::Adaptive, ..Default::default() };
    let mut rows = Vec::new();
    for (label, multiple) in
        [("single scattering only", false), ("whole: beam + volume and surface photons (multiple = true)", true)]
    {
        let t = Instant::now();
        let haze = StillHaze { medium: Medium { multiple, ..medium }, density: 1.0, quality: HazeQuality::REFINED };
        let still = render_still_hazy(&scene, camera, &jobs, &settings, Some(&haze))?;
        let seconds = t.elapsed().as_secs_f64();
        let img = still.linear;
        let ours = sums(&img);
        let energy = ours.iter().sum::<f64>() / total.max(1e-30);
        let rel = rel_mse(&img, &reference_img);
        let mut error = [0.0f64; 3];
        for ((a, b), r) in img.iter().zip(&reference_img).zip(&regions) {
            error[index(*r)] += f64::from((*a - *b).length_squared());
        }
        let error_total: f64 = error.iter().sum();
        rows.push(WholeHazeRow {
            label: label.into(),
            seconds,
            energy,
            rel_mse: rel,
            rel_mse_corrected: (rel - reference_noise).max(0.0),
            fitted_scale: fitted_scale(&img, &reference_img),
            regions: [0, 1, 2].map(|r| ours[r] / reference_sums[r].max(1e-30)),
            error_share: error.map(|e| e / error_total.max(1e-30)),
        });
    }
    Ok(WholeHaze {
        size: cfg.size,
        medium: (SIGMA_S, SIGMA_A, G),
        reference_spp: cfg.reference_spp,
        reference_s,
        reference_noise,
        region_share: reference_sums.map(|s| s / total.max(1e-30)),
        region_pixels,
        rows,
    })
}

impl WholeHaze {
    /// Lines for the terminal summary and report.md.
    pub fn lines(&self) -> String {
        let (sigma_s, sigma_a, g) = self.medium;
        let mut s = format!(
            "  whole hazy picture vs the volume path tracer (box stage {}×{}, σ_s {sigma_s} /m, σ_a {sigma_a} /m, g {g}):\n",
            self.size.0, self.size.1
        );
        s += &format!(
            "    reference {} spp in {:.1} s, own rel. MSE {:.2e}; energy share air / lit / unlit {:.3} / {:.3} / {:.3} (pixels {:.2} / {:.2} / {:.2})\n",
            self.reference_spp,
            self.reference_s,
            self.reference_noise,
            self.region_share[0],
            self.region_share[1],
            self.region_share[2],
            self.region_pixels[0],
            self.region_pixels[1],
            self.region_pixels[2]
        );
        for r in &self.rows {
            s += &format!(
                "    {:<60} {:>6.2} s  energy {:.4}  rel. MSE {:.2e} (corrected {:.2e})  scale {:.4}  air / lit / unlit {:.3} / {:.3} / {:.3}, share of the error {:.2} / {:.2} / {:.2}\n",
                r.label,
                r.seconds,
                r.energy,
                r.rel_mse,
                r.rel_mse_corrected,
                r.fitted_scale,
                r.regions[0],
                r.regions[1],
                r.regions[2],
                r.error_share[0],
                r.error_share[1],
                r.error_share[2]
            );
        }
        s
    }
}
