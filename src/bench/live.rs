//! Daemon-side measurements (issue 7's benchmark): composite frame time
//! for 1, 8, 32 and 128 lights at two picture sizes on the CPU (full and
//! incremental) and the GPU, and the time from a geometry change to the
//! first direct-light frame and to the converged frame.

use crate::Light;
use crate::live::daemon::median;
use crate::live::{Tracer, TracerSettings};
use crate::output::Stage;
use crate::render::composite::{CompositeInput, Compositor, composite_into};
use crate::render::photon::PhotonSettings;
use crate::render::{Display, LightBuffer, RecursionLimits, Sampling, View};
use crate::scene::{Camera, Scene};
use glam::Vec3;
use serde::Serialize;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Composite timings for one light count and picture size.
#[derive(Clone, Debug, Serialize)]
pub struct CompositeRow {
    /// Lights composited.
    pub lights: usize,
    /// Picture width.
    pub width: u32,
    /// Picture height.
    pub height: u32,
    /// Full CPU composite + sRGB, ms.
    pub cpu_full_ms: f64,
    /// Incremental CPU update after one fader move, ms.
    pub cpu_one_fader_ms: f64,
    /// GPU composite + readback, ms (None without an adapter).
    pub gpu_ms: Option<f64>,
}

/// Geometry change latency for one light.
#[derive(Clone, Debug, Serialize)]
pub struct Latency {
    /// Request to the first published (direct) stage, ms.
    pub first_direct_ms: f64,
    /// Request to the Whitted stage (mirrors, glass, anti-aliasing), ms.
    pub whitted_ms: f64,
    /// Request to the photon-mapped stage, ms.
    pub photons_ms: f64,
    /// Request to the last of the daemon's progressive passes, ms (a pass
    /// count; the error-judged time to the converged picture is
    /// `bench::accuracy`'s `converge` part).
    pub converged_ms: f64,
    /// Progressive passes counted as converged.
    pub refine_passes: u32,
}

/// Daemon measurements.
#[derive(Clone, Debug, Serialize)]
pub struct LiveReport {
    /// Adapter the GPU timings ran on (software rasterisers included).
    pub gpu_adapter: Option<String>,
    /// Composite timings.
    pub composite: Vec<CompositeRow>,
    /// Geometry change latency at the bench picture size.
    pub latency: Latency,
}

/// Runs the daemon measurements.
pub fn run(
    scene: &Arc<Scene>,
    camera: Camera,
    sizes: &[(u32, u32)],
    counts: &[usize],
    bench_size: (u32, u32),
    (light, k_full): (&Light, Vec3),
    refine_passes: u32,
) -> LiveReport {
    let display = Display::default();
    let mut rows = Vec::new();
    let mut adapter = None;
    for &(w, h) in sizes {
        let view = View::build(scene, camera, w, h, Sampling::Geometry, RecursionLimits::default());
        let max = counts.iter().copied().max().unwrap_or(1);
        let rig = super::many_lights(max);
        let buffers: Vec<LightBuffer> = rig.iter().map(|l| view.render_light(scene, l, None).0).collect();
        let mut gpu = crate::gpu::GpuFrames::open(crate::gpu::CompositorChoice::Gpu, w, h, display).ok().flatten();
        if let Some(g) = &gpu {
            adapter = Some(g.adapter().to_string());
        }
        for &n in counts {
            let refs: Vec<&LightBuffer> = buffers[..n].iter().collect();
            let k: Vec<Vec3> = (0..n).map(|i| k_full * (0.3 + 0.7 * (i as f32 * 0.37).fract())).collect();
            let mut frame = vec![Vec3::ZERO; (w * h) as usize];
            let mut srgb = vec![0u8; (w * h * 3) as usize];
            let reps = 15;
            let cpu_full_ms = median(
                (0..reps)
                    .map(|_| {
                        let t = Instant::now();
                        composite_into(&refs, &k, w, h, &mut frame);
                        display.to_srgb8_into(&frame, &mut srgb);
                        t.elapsed().as_secs_f64() * 1e3
                    })
                    .collect(),
            );
            let mut comp = Compositor::new(w, h, display);
            let inputs = |step: u32| -> Vec<CompositeInput> {
                refs.iter()
                    .zip(&k)
                    .enumerate()
                    .map(|(i, (b, k))| CompositeInput {
                        buffer: b,
                        generation: 0,
                        k: if i == 0 { *k * (0.2 + 0.2 * (step % 4) as f32) } else { *k },
                    })
                    .collect()
            };
            comp.update(&inputs(0));
            let cpu_one_fader_ms = median(
                (1..=reps as u32)
                    .map(|s| {
                        let t = Instant::now();
                        comp.update(&inputs(s));
                        t.elapsed().as_secs_f64() * 1e3
                    })
                    .collect(),
            );
            let gpu_ms = gpu.as_mut().and_then(|g| {
                let inputs = inputs(0);
                g.frame(&inputs).ok()?; // uploads, once
                let times: Vec<f64> = (0..reps)
                    .filter_map(|_| {
                        let t = Instant::now();
                        g.frame(&inputs).ok()?;
                        Some(t.elapsed().as_secs_f64() * 1e3)
                    })
                    .collect();
                (!times.is_empty()).then(|| median(times))
            });
            rows.push(CompositeRow { lights: n, width: w, height: h, cpu_full_ms, cpu_one_fader_ms, gpu_ms });
        }
    }

    // Latency: a light moves; time each published stage.
    let (w, h) = bench_size;
    let view = Arc::new(View::build(scene, camera, w, h, Sampling::Adaptive, RecursionLimits::default()));
    let settings = TracerSettings {
        build: crate::render::BuildSettings {
            photons: Some(PhotonSettings::default()),
            refine_passes,
            ..crate::render::BuildSettings::default()
        },
        ..TracerSettings::default()
    };
    let tracer = Tracer::new(scene.clone(), view, 1, settings);
    let t0 = Instant::now();
    tracer.request(0, light.clone(), 1.0);
    let mut seen = [None::<f64>; 4];
    while t0.elapsed() < Duration::from_secs(300) {
        let stage = tracer.published(0).stage;
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        let idx = match stage {
            Stage::Queued => None,
            Stage::Direct => Some(0),
            Stage::Whitted => Some(1),
            Stage::Photons | Stage::Refining(_) => Some(2),
            Stage::Ready => Some(3),
        };
        if let Some(i) = idx {
            for s in seen.iter_mut().take(i + 1) {
                s.get_or_insert(ms);
            }
            if i == 3 {
                break;
            }
        }
        std::thread::sleep(Duration::from_micros(200));
    }
    tracer.shutdown(Duration::from_secs(60));
    let at = |i: usize| seen[i].unwrap_or(f64::NAN);
    LiveReport {
        gpu_adapter: adapter,
        composite: rows,
        latency: Latency {
            first_direct_ms: at(0),
            whitted_ms: at(1),
            photons_ms: at(2),
            converged_ms: at(3),
            refine_passes,
        },
    }
}
