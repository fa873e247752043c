//! "Walk the stage" (issue 16), measured through the real daemon on the
//! bench's scene and patch (the paper rig):
//!
//! * **moving preview**: the camera orbits 30° around what the start view
//!   centres on (a write every 1/30 s, as a dragging mouse sends) for a few
//!   seconds; frames published per second
//!   while moving and the preview's time per frame (target ≥ 15 fps at
//!   800×500 on 2 cores);
//! * **camera stops**: from the last write to the new view on screen (every
//!   light has a buffer for it: the moving preview is gone), to every light
//!   past its Whitted stage (full-quality direct light, mirrors, glass, AA),
//!   and to every light finished (target for the full-quality view < 3 s;
//!   before issue 16 it took a restart);
//! * **return to a cached view**: from the named-view write to its kept
//!   buffers on screen (target < one frame).

use crate::live::views::Phase;
use crate::live::{Daemon, DmxSource, Show, Stage};
use crate::render::photon::PhotonSettings;
use crate::scene::{Camera, Scene};
use serde::Serialize;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// What the walk measured.
#[derive(Clone, Debug, Serialize)]
pub struct WalkReport {
    /// Picture size.
    pub width: u32,
    /// Picture size.
    pub height: u32,
    /// Lights in the patch.
    pub lights: usize,
    /// New pictures per second published while the camera moved.
    pub moving_fps: f64,
    /// Median time to render one preview frame, ms.
    pub preview_ms: f64,
    /// Last camera write → the new view on screen (no light left without a buffer), ms.
    pub view_on_screen_ms: f64,
    /// Last camera write → every light at least at its Whitted stage, ms.
    pub full_quality_ms: f64,
    /// Last camera write → every light finished, ms.
    pub converged_ms: f64,
    /// Named-view write → its cached buffers on screen, ms.
    pub cached_return_ms: f64,
    /// Lights restored from the cache on that return.
    pub cached_restored: usize,
    /// Frame period of the clock, ms (the cached-return target).
    pub frame_ms: f64,
}

impl WalkReport {
    /// The report's Markdown section.
    pub fn markdown(&self) -> String {
        format!(
            "\n## Walking the stage (issue 16)\n\n{} lights at {}×{}. Moving camera (30° orbit, a write every 1/30 s): \
             **{:.1} new pictures per second**, preview {:.1} ms per frame (target ≥ 15 fps). Camera stops → new view on \
             screen {:.0} ms, **full quality (every light past Whitted) {:.0} ms** (target < 3000 ms), every light \
             finished {:.0} ms (settle time 200 ms included). Return to a cached view: **{:.1} ms** with {} of {} \
             lights restored (target < one frame, {:.1} ms).\n",
            self.lights,
            self.width,
            self.height,
            self.moving_fps,
            self.preview_ms,
            self.view_on_screen_ms,
            self.full_quality_ms,
            self.converged_ms,
            self.cached_return_ms,
            self.cached_restored,
            self.lights,
            self.frame_ms
        )
    }
}

fn rank(s: Stage) -> u32 {
    match s {
        Stage::Queued => 0,
        Stage::Direct => 1,
        Stage::Whitted => 2,
        Stage::Photons | Stage::Refining(_) => 3,
        Stage::Ready => 4,
    }
}

/// Runs the walk: the daemon over `scene` and `patch` from `camera`.
pub fn run(
    scene: &Arc<Scene>,
    patch: &crate::Patch,
    camera: Camera,
    (width, height): (u32, u32),
    seconds: f64,
    photons: usize,
) -> Result<WalkReport, String> {
    let show = Arc::new(Show::new(patch.clone()));
    let lights = patch.fixtures.len();
    let mut config = super::harness::config(width, height);
    config.tracer.build.photons =
        (photons > 0).then(|| PhotonSettings { stored: photons, ..PhotonSettings::default() });
    let frame_ms = 1e3 / config.fps;
    let rt = super::harness::runtime()?;
    let daemon = Daemon::new(scene.clone(), show, camera, config).input(DmxSource::None);
    let running = super::harness::Running::start(rt, daemon)?;
    let handle = running.handle.clone();
    let stages = || (handle.status)().lights.iter().map(|l| l.build.as_ref().map_or(0, |b| rank(b.stage))).min();
    let wait = |what: &dyn Fn() -> bool, limit: Duration| -> Result<f64, String> {
        let t = Instant::now();
        while !what() {
            if t.elapsed() > limit {
                return Err("timed out".into());
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        Ok(t.elapsed().as_secs_f64() * 1e3)
    };
    let ready = || stages().is_none_or(|s| s >= 4);
    wait(&ready, Duration::from_secs(600))?;

    // Orbit: a write every 1/30 s around what the start view centres on.
    let orbit = crate::live::views::Pose::focused(scene, &camera);
    let mut frames = handle.frames.clone();
    frames.borrow_and_update();
    let t0 = Instant::now();
    let mut step = 0u32;
    let mut preview = Vec::new();
    let mut last_rgb: Option<Arc<Vec<u8>>> = None;
    while t0.elapsed().as_secs_f64() < seconds {
        step += 1;
        // 30° around the stage over the run: a designer walking to another seat.
        let pose = orbit.orbit(30f32.to_radians() * (f64::from(step) / (seconds * 30.0)).min(1.0) as f32, 0.0);
        handle.views.move_to_pose(pose)?;
        let next = Duration::from_secs_f64(f64::from(step) / 30.0);
        // Every published frame until the next write; a new picture is one
        // whose pixels are not the previous frame's (the clock reuses the
        // preview while nothing it shows changed).
        while t0.elapsed() < next {
            if frames.has_changed().unwrap_or(false) {
                let f = frames.borrow_and_update().clone();
                if last_rgb.as_ref().is_none_or(|l| !Arc::ptr_eq(l, &f.rgb)) {
                    preview.push(f.composite_time.as_secs_f64() * 1e3);
                    last_rgb = Some(f.rgb.clone());
                }
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    let moving_s = t0.elapsed().as_secs_f64();
    let moved_frames = preview.len();
    let stopped = Instant::now();
    let on_screen = || (handle.status)().view.phase == Phase::Still && stages().is_none_or(|s| s >= 1);
    wait(&on_screen, Duration::from_secs(600))?;
    let view_on_screen_ms = stopped.elapsed().as_secs_f64() * 1e3;
    wait(&|| stages().is_none_or(|s| s >= 3), Duration::from_secs(600))?;
    let full_quality_ms = stopped.elapsed().as_secs_f64() * 1e3;
    wait(&ready, Duration::from_secs(600))?;
    let converged_ms = stopped.elapsed().as_secs_f64() * 1e3;

    // Back to the start view by name: from the cache.
    let hits = (handle.status)().view.cache.hits;
    let back = Instant::now();
    handle.views.go_to("start")?;
    let restored = || {
        let v = (handle.status)().view;
        v.phase == Phase::Still && v.cache.hits > hits
    };
    wait(&restored, Duration::from_secs(60))?;
    let cached_return_ms = back.elapsed().as_secs_f64() * 1e3;
    let cached_restored = (handle.status)().view.last_restored;

    running.stop()?;
    preview.sort_by(f64::total_cmp);
    Ok(WalkReport {
        width,
        height,
        lights,
        moving_fps: moved_frames as f64 / moving_s,
        preview_ms: preview.get(preview.len() / 2).copied().unwrap_or(0.0),
        view_on_screen_ms,
        full_quality_ms,
        converged_ms,
        cached_return_ms,
        cached_restored,
        frame_ms,
    })
}
