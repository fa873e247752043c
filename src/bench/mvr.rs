//! MVR/GDTF measurements (issue 14's benchmark): the import time of the
//! 150-fixture show (`tests/data/mvr/show150.mvr`, written by
//! `tools/gen_gdtf_mvr.py`), and the composite cost per frame with 50
//! fixtures strobing: the strobe is a factor on k_i evaluated on the frame
//! clock ([`crate::fixture::FixtureState::shutter_at`]), so it costs an
//! incremental composite of the lights that flipped, never a rebuild.

use crate::fixture::FixtureState;
use crate::render::composite::{CompositeInput, Compositor};
use crate::render::{Display, LightBuffer, RecursionLimits, Sampling, View};
use crate::scene::{Camera, Scene};
use glam::Vec3;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// What the MVR section measured.
#[derive(Clone, Debug, Serialize)]
pub struct MvrReport {
    /// Wall time of `footlight_mvr::load_mvr` on show150.mvr, ms (median); NaN if it failed.
    pub import_ms: f64,
    /// Fixtures (lights) the import produced.
    pub fixtures: usize,
    /// Strobing fixtures composited.
    pub strobing: usize,
    /// Picture size of the strobe composite.
    pub size: (u32, u32),
    /// Incremental composite per 60 Hz frame with every fixture strobing (1-25 Hz), ms (median).
    pub strobe_frame_ms: f64,
    /// Lights whose k_i flipped per frame, mean.
    pub strobe_changed_per_frame: f64,
}

impl MvrReport {
    /// Lines for the summary and the report.
    pub fn lines(&self) -> String {
        format!(
            "  MVR import, show150.mvr ({} lights): {:.1} ms (target < 2000 ms)\n  strobe: {} fixtures at 1-25 Hz, {}×{}: \
             {:.3} ms composite per 60 Hz frame, {:.1} lights flip per frame (no rebuilds)\n",
            self.fixtures,
            self.import_ms,
            self.strobing,
            self.size.0,
            self.size.1,
            self.strobe_frame_ms,
            self.strobe_changed_per_frame
        )
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Runs the MVR measurements: import `show` `repeats` times, then 120
/// frames of `strobing` lights strobing at rates spread over 1-25 Hz.
pub fn run(
    scene: &Scene,
    camera: Camera,
    (w, h): (u32, u32),
    show: &Path,
    repeats: usize,
    strobing: usize,
) -> MvrReport {
    let mut fixtures = 0;
    let import_ms = median(
        (0..repeats.max(1))
            .map(|_| {
                let t = Instant::now();
                match footlight_mvr::load_mvr(show) {
                    Ok(i) => {
                        fixtures = i.patch.fixtures.len();
                        t.elapsed().as_secs_f64() * 1e3
                    }
                    Err(e) => {
                        tracing::error!("MVR bench: {}", e.first().map(|e| e.to_string()).unwrap_or_default());
                        f64::NAN
                    }
                }
            })
            .collect(),
    );
    let view = View::build(scene, camera, w, h, Sampling::Geometry, RecursionLimits::default());
    let rig = super::many_lights(strobing);
    let buffers: Vec<LightBuffer> = rig.iter().map(|l| view.render_light(scene, l, None).0).collect();
    let states: Vec<FixtureState> = (0..strobing)
        .map(|i| FixtureState { v: 1.0, strobe: 1.0 + 24.0 * (i as f32 * 0.618).fract(), ..FixtureState::default() })
        .collect();
    let k_full = Vec3::splat(1000.0);
    let mut comp = Compositor::new(w, h, Display::default());
    let inputs = |t: f64| -> Vec<CompositeInput> {
        buffers
            .iter()
            .zip(&states)
            .map(|(b, s)| CompositeInput { buffer: b, generation: 0, k: k_full * s.shutter_at(t) })
            .collect()
    };
    comp.update(&inputs(0.0));
    let mut times = Vec::new();
    let mut changed = 0usize;
    let frames = 120;
    for f in 1..=frames {
        let t = f64::from(f) / 60.0;
        let before = Instant::now();
        let stats = comp.update(&inputs(t));
        times.push(before.elapsed().as_secs_f64() * 1e3);
        changed += stats.changed_lights;
    }
    MvrReport {
        import_ms,
        fixtures,
        strobing,
        size: (w, h),
        strobe_frame_ms: median(times),
        strobe_changed_per_frame: changed as f64 / f64::from(frames),
    }
}
