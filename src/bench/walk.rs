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

use crate::live::{Daemon, DmxSource, Show};
use crate::output::{CameraControl, Phase, Stage};
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
    /// Median time to render one preview frame, ms, over the published
    /// frames that are moving previews with a new picture (NaN: none).
    pub preview_ms: f64,
    /// Moving-preview pictures the median is over.
    pub preview_frames: usize,
    /// The haze density the previews were rendered in (`None`: no haze in the patch).
    pub haze_density: Option<f32>,
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
    /// The picture at full quality against the finished one (every SPPM
    /// pass done), on the 8-bit display values.
    pub full_quality_error: PictureError,
    /// One view change stage by stage ([`profile`]).
    pub profile: Option<ViewProfile>,
    /// With a `[haze]` patch: the moving preview alone on the start view,
    /// clear and in the haze ([`preview_cost`]).
    pub haze_preview: Option<PreviewCost>,
}

/// The moving preview's own cost, without and with haze (same view, same
/// lights, every light at k = 1000 cd, the daemon stopped).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PreviewCost {
    /// Runs of each.
    pub runs: usize,
    /// Clear preview: median, min and max, ms.
    pub clear_ms: [f64; 3],
    /// In the patch's haze at its density: median, min and max, ms.
    pub haze_ms: [f64; 3],
    /// The density.
    pub density: f32,
}

/// Times [`crate::live::views::preview_in_haze`] `runs` times without and
/// with `patch`'s haze on `camera` (`None` without a `[haze]`).
pub fn preview_cost(
    scene: &Scene,
    patch: &crate::Patch,
    camera: &Camera,
    (width, height): (u32, u32),
    runs: usize,
) -> Option<PreviewCost> {
    use crate::live::views::preview_in_haze;
    let spec = patch.haze.as_ref()?;
    let medium = crate::render::media::Medium::from_spec(spec, scene)?;
    let lights: Vec<(&crate::Light, glam::Vec3)> =
        patch.fixtures.iter().map(|f| (&f.light, glam::Vec3::splat(1000.0))).collect();
    let scale = crate::live::views::ViewSettings::default().preview_scale;
    let time = |haze: Option<(&crate::render::media::Medium, f32)>| {
        let mut t: Vec<f64> = (0..runs.max(1))
            .map(|_| {
                let t0 = Instant::now();
                std::hint::black_box(preview_in_haze(scene, camera, width, height, scale, &lights, haze));
                t0.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        t.sort_by(f64::total_cmp);
        [t[t.len() / 2], t[0], t[t.len() - 1]]
    };
    let clear_ms = time(None);
    let haze_ms = time(Some((&medium, spec.density)));
    Some(PreviewCost { runs: runs.max(1), clear_ms, haze_ms, density: spec.density })
}

impl PreviewCost {
    /// One Markdown sentence.
    pub fn markdown(&self) -> String {
        let [c, c0, c1] = self.clear_ms;
        let [h, h0, h1] = self.haze_ms;
        format!(
            "\nThe moving preview alone on the start view ({} runs, median [min-max]): clear {c:.1} ms [{c0:.1}-{c1:.1}], \
             **in haze at density {:.2}: {h:.1} ms [{h0:.1}-{h1:.1}]** (+{:.0} %; beams on a 1/8 grid, {} samples).\n",
            self.runs,
            self.density,
            100.0 * (h / c - 1.0),
            crate::live::views::PREVIEW_HAZE_SAMPLES,
        )
    }
}

/// How far one displayed picture is from another (8-bit sRGB, all channels).
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct PictureError {
    /// Root mean square difference, in 8-bit levels.
    pub rms: f64,
    /// Share of pixels with some channel more than 8 levels off.
    pub over_8: f64,
    /// Largest difference, levels.
    pub max: u8,
}

impl PictureError {
    /// `a` against the reference `b` (same size, RGB bytes).
    pub fn between(a: &[u8], b: &[u8]) -> Self {
        let n = a.len().min(b.len());
        if n == 0 {
            return Self::default();
        }
        let sq: f64 = a.iter().zip(b).map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2)).sum();
        let max = a.iter().zip(b).map(|(x, y)| x.abs_diff(*y)).max().unwrap_or(0);
        let pixels = n / 3;
        let over =
            a.chunks(3).zip(b.chunks(3)).filter(|(p, q)| p.iter().zip(*q).any(|(x, y)| x.abs_diff(*y) > 8)).count();
        Self { rms: (sq / n as f64).sqrt(), over_8: over as f64 / pixels.max(1) as f64, max }
    }
}

impl WalkReport {
    /// The report's Markdown section.
    pub fn markdown(&self) -> String {
        format!(
            "\n## Walking the stage (issue 16)\n\n{} lights at {}×{}. Moving camera (30° orbit, a write every 1/30 s): \
             **{:.1} new pictures per second**, preview {:.2} ms per frame (median of {} previews{}; target ≥ 15 fps). Camera stops → new view on \
             screen {:.0} ms, **full quality (every light past Whitted) {:.0} ms** (target < 3000 ms), every light \
             finished {:.0} ms (settle time 200 ms included). Return to a cached view: **{:.1} ms** with {} of {} \
             lights restored (target < one frame, {:.1} ms). The picture at full quality against the finished one: \
             RMS {:.2} of 255 levels, {:.2} % of pixels more than 8 levels off, at most {} levels.\n{}",
            self.lights,
            self.width,
            self.height,
            self.moving_fps,
            self.preview_ms,
            self.preview_frames,
            self.haze_density.map(|d| format!(", in haze at density {d:.2}")).unwrap_or_default(),
            self.view_on_screen_ms,
            self.full_quality_ms,
            self.converged_ms,
            self.cached_return_ms,
            self.cached_restored,
            self.lights,
            self.frame_ms,
            self.full_quality_error.rms,
            self.full_quality_error.over_8 * 100.0,
            self.full_quality_error.max,
            self.profile.as_ref().map(ViewProfile::markdown).unwrap_or_default()
        ) + &self.haze_preview.map(|p| p.markdown()).unwrap_or_default()
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
    let profile = profile(scene, patch, camera, (width, height), photons)?;
    let show = Arc::new(Show::new(patch.clone()).map_err(|e| e.to_string())?);
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

    // Orbit: a write every 1/30 s about the start view's target, the
    // stage centre (as the page orbits; each write confined to the stage).
    let orbit = (handle.status)().view.current;
    let mut frames = handle.frames.clone();
    frames.borrow_and_update();
    let t0 = Instant::now();
    let mut step = 0u32;
    let mut preview = Vec::new();
    let (mut new_pictures, mut haze_density) = (0usize, None);
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
                    // Only a moving preview's time is the preview's (a
                    // composite frame takes microseconds). A frame showing
                    // the last preview again carries that preview's time
                    // (clock.rs): after a slow tick the clock catches up at
                    // once and this loop sees only the reused frame, which
                    // made the median read 0.0 ms before.
                    if f.preview {
                        preview.push(f.composite_time.as_secs_f64() * 1e3);
                        haze_density = f.haze_density;
                    }
                    new_pictures += 1;
                    last_rgb = Some(f.rgb.clone());
                }
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    let moving_s = t0.elapsed().as_secs_f64();
    let moved_frames = new_pictures;
    let stopped = Instant::now();
    let on_screen = || (handle.status)().view.phase == Phase::Still && stages().is_none_or(|s| s >= 1);
    wait(&on_screen, Duration::from_secs(600))?;
    let view_on_screen_ms = stopped.elapsed().as_secs_f64() * 1e3;
    wait(&|| stages().is_none_or(|s| s >= 3), Duration::from_secs(600))?;
    let full_quality_ms = stopped.elapsed().as_secs_f64() * 1e3;
    // The picture on screen then: the next composite after the stage landed.
    std::thread::sleep(Duration::from_secs_f64(2.0 * frame_ms / 1e3));
    let at_full = handle.frames.borrow().rgb.clone();
    wait(&ready, Duration::from_secs(600))?;
    let converged_ms = stopped.elapsed().as_secs_f64() * 1e3;
    std::thread::sleep(Duration::from_secs_f64(2.0 * frame_ms / 1e3));
    let finished = handle.frames.borrow().rgb.clone();
    let full_quality_error = PictureError::between(&at_full, &finished);

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
    let haze_preview = preview_cost(scene, patch, &camera, (width, height), 7);
    preview.sort_by(f64::total_cmp);
    Ok(WalkReport {
        width,
        height,
        lights,
        moving_fps: moved_frames as f64 / moving_s,
        preview_ms: preview.get(preview.len() / 2).copied().unwrap_or(f64::NAN),
        preview_frames: preview.len(),
        haze_density,
        view_on_screen_ms,
        full_quality_ms,
        converged_ms,
        cached_return_ms,
        cached_restored,
        frame_ms,
        full_quality_error,
        profile: Some(profile),
        haze_preview,
    })
}

/// One light's share of a view change (see [`ViewProfile`]).
#[derive(Clone, Debug, Serialize)]
pub struct LightProfile {
    /// Footprint-culled direct stage (what the daemon shows first), ms.
    pub direct_ms: f64,
    /// Whitted direct term on the base (binned) sample set, ms.
    pub shade_ms: f64,
    /// Adaptive anti-aliasing: gradient flags plus 9-sample re-shading, ms.
    pub aa_ms: f64,
    /// Pixels re-shaded by anti-aliasing.
    pub reshaded: usize,
    /// Photon tracing (done once per light geometry, *not* on a camera move), ms.
    pub trace_ms: f64,
    /// Irradiance lookups from the kept maps at every shading vertex, ms.
    pub irradiance_ms: f64,
    /// Indirect buffer from the per-vertex values plus the D + A sum, ms.
    pub indirect_ms: f64,
    /// The coarse first estimate the live tracer publishes instead of the
    /// exact lookups ([`crate::render::View::coarse_vertex_irradiance_until`]), ms.
    pub coarse_ms: f64,
    /// Share of vertices the coarse estimate interpolated.
    pub interpolated: f64,
}

/// Per-stage times of one camera move (the start view orbited 30°), each
/// stage run alone on the build pool (2 threads on the bench VM): what the
/// daemon does between the camera stopping and the full-quality picture.
#[derive(Clone, Debug, Serialize)]
pub struct ViewProfile {
    /// Threads of the pool the stages ran on.
    pub threads: usize,
    /// 9-sample G-buffer, ms.
    pub gbuffer_ms: f64,
    /// Camera-path expansion through mirrors and glass, ms.
    pub expand_ms: f64,
    /// Shading vertices of the base sample set.
    pub vertices: usize,
    /// Per light, in patch order.
    pub lights: Vec<LightProfile>,
}

impl ViewProfile {
    /// Sum over lights of one field.
    fn sum(&self, f: impl Fn(&LightProfile) -> f64) -> f64 {
        self.lights.iter().map(f).sum()
    }

    /// What a view change costs before every light is at full quality
    /// (view + every light's direct, Whitted + AA and indirect lookups), ms;
    /// with `coarse`, the coarse first estimate instead of the exact lookups.
    pub fn view_change_ms(&self, coarse: bool) -> f64 {
        self.gbuffer_ms
            + self.expand_ms
            + self.sum(|l| {
                l.direct_ms + l.shade_ms + l.aa_ms + if coarse { l.coarse_ms } else { l.irradiance_ms } + l.indirect_ms
            })
    }

    /// The profile as a Markdown table.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "\nOne view change, stage by stage ({} threads, {} shading vertices): G-buffer {:.0} ms, path expansion \
             {:.0} ms.\n\n| light | direct stage | Whitted (base) | AA (re-shaded px) | irradiance lookups | coarse \
             estimate (interpolated) | indirect buffer | photon trace (not redone) |\n|---|---|---|---|---|---|---|---|\n",
            self.threads, self.vertices, self.gbuffer_ms, self.expand_ms
        );
        for (i, l) in self.lights.iter().enumerate() {
            s += &format!(
                "| {} | {:.0} | {:.0} | {:.0} ({}) | {:.0} | {:.0} ({:.0} %) | {:.0} | {:.0} |\n",
                i + 1,
                l.direct_ms,
                l.shade_ms,
                l.aa_ms,
                l.reshaded,
                l.irradiance_ms,
                l.coarse_ms,
                l.interpolated * 100.0,
                l.indirect_ms,
                l.trace_ms
            );
        }
        s += &format!(
            "| **all** | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} |\n\nSum of the per-view stages: **{:.0} ms** \
             with exact lookups, **{:.0} ms** with the coarse first estimate.\n",
            self.sum(|l| l.direct_ms),
            self.sum(|l| l.shade_ms),
            self.sum(|l| l.aa_ms),
            self.sum(|l| l.irradiance_ms),
            self.sum(|l| l.coarse_ms),
            self.sum(|l| l.indirect_ms),
            self.sum(|l| l.trace_ms),
            self.view_change_ms(false),
            self.view_change_ms(true)
        );
        s
    }
}

/// Profiles one view change (module docs, [`ViewProfile`]): photon maps are
/// traced first (as the daemon holds them), then the orbited view and every
/// light's per-view stages are timed one by one.
pub fn profile(
    scene: &Scene,
    patch: &crate::Patch,
    camera: Camera,
    (width, height): (u32, u32),
    photons: usize,
) -> Result<ViewProfile, String> {
    use crate::render::build::light_seed;
    use crate::render::footprint::{DirectQuality, primary_direct};
    use crate::render::gbuffer::GBuffer;
    use crate::render::photon::trace_photons;
    use crate::render::{AaParams, RecursionLimits, Sampling, View};
    let threads = std::thread::available_parallelism().map_or(2, |n| n.get());
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| e.to_string())?;
    let ms = |t: Instant| t.elapsed().as_secs_f64() * 1e3;
    let settings = crate::render::build::BuildSettings::default();
    let moved = crate::output::Pose::focused(scene, &camera).orbit(30f32.to_radians(), 0.0).camera()?;
    pool.install(|| {
        let t = Instant::now();
        let gbuffer = GBuffer::build(scene, moved, width, height);
        let gbuffer_ms = ms(t);
        let t = Instant::now();
        let view = View::from_gbuffer(scene, gbuffer, Sampling::Adaptive, RecursionLimits::default());
        let expand_ms = ms(t);
        let mut lights = Vec::new();
        for (i, f) in patch.fixtures.iter().enumerate() {
            let light = &f.light;
            let t = Instant::now();
            let _ = primary_direct(scene, &view, view.tile_bounds(), light, DirectQuality::Full);
            let direct_ms = ms(t);
            let t = Instant::now();
            let (mut dense, _) = view.render_direct(scene, light, None);
            let shade_ms = ms(t);
            let t = Instant::now();
            let decision = view.aa_decision(scene, light, &dense, AaParams::new(settings.aa_threshold));
            let reshaded = view.reshade(scene, light, &mut dense, decision.reshading());
            let aa_ms = ms(t);
            let (mut trace_ms, mut irradiance_ms, mut indirect_ms, mut coarse_ms, mut interpolated) =
                (0.0, 0.0, 0.0, 0.0, 0.0);
            if photons > 0 {
                let ps = PhotonSettings { stored: photons, ..PhotonSettings::default() };
                let t = Instant::now();
                let maps = trace_photons(scene, light, &PhotonSettings { seed: light_seed(ps.seed, i), ..ps });
                trace_ms = ms(t);
                let t = Instant::now();
                let e = view.vertex_irradiance(scene, &maps);
                irradiance_ms = ms(t);
                let t = Instant::now();
                let a = view.render_vertex_irradiance(scene, &e);
                let sum: Vec<glam::Vec3> = dense.iter().zip(&a).map(|(d, a)| *d + *a).collect();
                std::hint::black_box(&sum);
                indirect_ms = ms(t);
                let step = crate::live::TracerSettings::default().coarse_indirect;
                let t = Instant::now();
                if let Some((_, exact)) = view.coarse_vertex_irradiance_until(scene, &maps, step, &|| false) {
                    interpolated = exact.iter().filter(|e| !**e).count() as f64 / exact.len().max(1) as f64;
                }
                coarse_ms = ms(t);
            }
            lights.push(LightProfile {
                direct_ms,
                shade_ms,
                aa_ms,
                reshaded,
                trace_ms,
                irradiance_ms,
                indirect_ms,
                coarse_ms,
                interpolated,
            });
        }
        Ok(ViewProfile { threads, gbuffer_ms, expand_ms, vertices: view.shading.vertex_count(), lights })
    })
}
