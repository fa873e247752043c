//! One still image through the whole pipeline: view (G-buffer + camera
//! paths), one unit-intensity buffer per light, composite (eq. 5), display.
//! `footlight render` and the benchmarks use this; the live daemon uses the
//! same pieces with a scheduler in between.

use super::RenderSettings;
use super::buffer::{BadValue, LightBuffer};
use super::composite::composite;
use super::photon::{PhotonSettings, trace_photons};
use super::view::{AaParams, View};
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

/// A NaN/Inf in a light's buffer: a bug, reported with the light and pixel.
#[derive(Debug, thiserror::Error)]
#[error("light {light}: {source}")]
pub struct RenderError {
    /// Index of the light in the job list.
    pub light: usize,
    /// Where and what.
    pub source: BadValue,
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

/// Photon seed of light `index`: distinct, reproducible streams per light.
pub fn light_seed(seed: u64, index: usize) -> u64 {
    seed ^ (index as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// Renders `jobs` over `scene` from `camera`.
pub fn render_still(
    scene: &Scene,
    camera: Camera,
    jobs: &[LightJob],
    settings: &RenderSettings,
) -> Result<Still, RenderError> {
    let t0 = Instant::now();
    let view = View::build(scene, camera, settings.width, settings.height, settings.sampling, settings.limits);
    let t1 = Instant::now();
    let mut buffers = Vec::with_capacity(jobs.len());
    let mut reshaded = 0;
    let mut photon_time = Duration::ZERO;
    for (i, job) in jobs.iter().enumerate() {
        let aa = AaParams::new(settings.aa_threshold);
        let (mut dense, n) = view.render_direct(scene, &job.light, Some(aa));
        if let Some(photons) = &settings.photons {
            let tp = Instant::now();
            let light_settings = PhotonSettings { seed: light_seed(photons.seed, i), ..*photons };
            let maps = trace_photons(scene, &job.light, &light_settings);
            let indirect = view.render_indirect(scene, &maps);
            for (d, a) in dense.iter_mut().zip(&indirect) {
                *d += *a; // buffer_i = D_i + A_i, both scaled by k_i (eq. 5)
            }
            photon_time += tp.elapsed();
        }
        let buffer = LightBuffer::from_dense(view.width(), view.height(), &dense);
        buffer.check().map_err(|source| RenderError { light: i, source })?;
        reshaded += n;
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
            lights: t2 - t1 - photon_time,
            photons: photon_time,
            composite: t3 - t2,
        },
    })
}
