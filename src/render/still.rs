//! One still image through the whole pipeline: view (G-buffer + camera
//! paths), one unit-intensity buffer per light, composite (eq. 5), display.
//! `footlight render` and the benchmarks use this; the live daemon uses the
//! same pieces with a scheduler in between.

use super::RenderSettings;
use super::buffer::LightBuffer;
use super::build::{BuildError, BuildSettings, Cancel, Haze, LightBuild};
use super::composite::composite;
use super::media::{HazeQuality, HazeView, Medium};
use super::view::View;
use crate::fixture::Light;
use crate::scene::{Camera, Scene};
use glam::Vec3;
use std::time::{Duration, Instant};

/// A light to render: its geometry, k_i at dimmer 1 (for anti-aliasing
/// decisions) and its current k_i (for the composite).
#[derive(Clone, Debug)]
pub struct LightJob {
    /// Tracer geometry and pattern.
    pub light: Light,
    /// k_i with the dimmer at full.
    pub k_full: Vec3,
    /// k_i now (eq. 4).
    pub k: Vec3,
}

/// A light's build failed: a NaN/Inf in its buffer (a bug, reported with
/// the light and pixel), or a cancelled build.
#[derive(Debug, thiserror::Error)]
#[error("light {light}: {source}")]
pub struct RenderError {
    /// Index of the light in the job list.
    pub light: usize,
    /// Where and what.
    pub source: BuildError,
}

/// Timings of the stages of a still render.
#[derive(Clone, Debug, Default)]
pub struct StillTimings {
    /// G-buffer and camera-path expansion.
    pub view: Duration,
    /// All light buffers (direct and Whitted terms).
    pub lights: Duration,
    /// Photon tracing and indirect estimates.
    pub photons: Duration,
    /// Haze: in-scattering and density re-weighting.
    pub haze: Duration,
    /// Composite.
    pub composite: Duration,
}

/// The result of a still render.
pub struct Still {
    /// Camera-dependent state (reusable).
    pub view: View,
    /// One buffer per light, in job order.
    pub buffers: Vec<LightBuffer>,
    /// Linear composite in cd/m².
    pub linear: Vec<Vec3>,
    /// Pixels re-shaded by adaptive anti-aliasing, summed over lights.
    pub reshaded: usize,
    /// Stage timings.
    pub timings: StillTimings,
}

pub use super::build::light_seed;

/// Haze for a still: the medium at 100 % density and the density now.
#[derive(Clone, Copy, Debug)]
pub struct StillHaze {
    /// The patch's `[haze]` at 100 %.
    pub medium: Medium,
    /// Density 0-1 (the hazer channel or the patch's default).
    pub density: f32,
    /// Beam sampling.
    pub quality: HazeQuality,
}

/// Renders `jobs` over `scene` from `camera`.
pub fn render_still(
    scene: &Scene,
    camera: Camera,
    jobs: &[LightJob],
    settings: &RenderSettings,
) -> Result<Still, RenderError> {
    render_still_hazy(scene, camera, jobs, settings, None)
}

/// As [`render_still`], in haze when `haze` is given: each light's buffer
/// is its surface buffer re-weighted with its beam at the density
/// ([`LightBuild::haze`]).
pub fn render_still_hazy(
    scene: &Scene,
    camera: Camera,
    jobs: &[LightJob],
    settings: &RenderSettings,
    haze: Option<&StillHaze>,
) -> Result<Still, RenderError> {
    let t0 = Instant::now();
    let view = View::build(scene, camera, settings.width, settings.height, settings.sampling, settings.limits);
    let haze = haze.map(|h| Haze {
        medium: h.medium,
        view: HazeView::new(scene, &view.gbuffer),
        density: h.density,
        quality: h.quality,
    });
    let mut haze_time = Duration::ZERO;
    let t1 = Instant::now();
    let mut buffers = Vec::with_capacity(jobs.len());
    let mut reshaded = 0;
    let mut photon_time = Duration::ZERO;
    let build_settings = BuildSettings {
        aa_threshold: settings.aa_threshold,
        photons: settings.photons,
        refine_passes: settings.refine_passes,
    };
    for (i, job) in jobs.iter().enumerate() {
        // Only what the look lights is built: a dark light adds exactly 0 to
        // eq. 5. Lit lights keep their index, so their photon seeds are the
        // daemon's.
        if job.k == Vec3::ZERO {
            buffers.push(LightBuffer::empty(settings.width.max(1), settings.height.max(1)));
            continue;
        }
        let mut build = LightBuild::new(job.light.clone(), i, build_settings, Cancel::never());
        let mut buffer = build.whitted(scene, &view).and_then(|b| {
            if build.has_photons() {
                let tp = Instant::now();
                let b = build.photons(scene, &view);
                photon_time += tp.elapsed();
                b
            } else {
                Ok(b)
            }
        });
        reshaded += build.reshaded();
        // `--refine N`: N progressive passes, each blended with the photon map.
        if buffer.is_ok() && build.will_refine() {
            let tp = Instant::now();
            let light = build.light().clone();
            if let Some(mut refine) = build.into_refinement(scene, &view) {
                while !refine.finished() && buffer.is_ok() {
                    buffer = refine.pass(scene, &view);
                }
            }
            build = LightBuild::new(light, i, build_settings, Cancel::never());
            photon_time += tp.elapsed();
        }
        let buffer = buffer.and_then(|b| match &haze {
            Some(h) => {
                let th = Instant::now();
                let hazy = build.haze(scene, h, &b);
                haze_time += th.elapsed();
                hazy
            }
            None => Ok(b),
        });
        let buffer = buffer.map_err(|source| RenderError { light: i, source })?;
        buffers.push(buffer);
    }
    let t2 = Instant::now();
    let refs: Vec<&LightBuffer> = buffers.iter().collect();
    let k: Vec<Vec3> = jobs.iter().map(|j| j.k).collect();
    let linear = composite(&refs, &k, settings.width.max(1), settings.height.max(1));
    let t3 = Instant::now();
    Ok(Still {
        view,
        buffers,
        linear,
        reshaded,
        timings: StillTimings {
            view: t1 - t0,
            lights: t2 - t1 - photon_time - haze_time,
            haze: haze_time,
            photons: photon_time,
            composite: t3 - t2,
        },
    })
}
