//! MVR/GDTF measurements (issue 14's benchmark): the import time of the
//! 150-fixture show (`tests/data/mvr/show150.mvr`, written by
//! `tools/gen_gdtf_mvr.py`), and the composite cost per frame with 50
//! fixtures strobing: the strobe is a factor on k_i evaluated on the frame
//! clock ([`crate::fixture::FixtureState::shutter_at`]), so it costs an
//! incremental composite of the lights that flipped, never a rebuild.
//!
//! The pixel-bar rig ([`pixels`], `footlight bench --pixels-only`): the
//! show's 24 bars × 8 cells, each cell its own light (GDTF
//! `GeometryReference`s, `footlight_mvr::show::cells`). It measures the
//! rig's build (each cell's footprint-culled direct stage and settled
//! Whitted stage, and the fixed cost of a light that reaches no tile: what
//! a cell pays beyond its footprint) and the composite per 60 Hz frame with
//! every fader moving and with one fader moving (the composite is
//! tile-sparse: it redoes only the tiles of the lights whose k_i changed).
//! The same cells are then built together ([`crate::render::build::together`]: each
//! bar's cells in one pass over the union of their footprints, and the
//! whole rig in one pass), timed against one by one, with the largest
//! difference to the cells built alone next to each time. Last, the same
//! through the live tracer ([`through_tracer`]): the time from start-up to
//! every cell's settled Whitted stage on screen with the tracer building a
//! bar's cells together ([`crate::live::TracerSettings::batch_cells`]) and
//! one by one, the largest difference between the two pictures, and the
//! first picture of every light of the whole show (the direct stages).

use crate::fixture::FixtureState;
use crate::live::daemon::median;
use crate::render::composite::{CompositeInput, Compositor};
use crate::render::{Display, LightBuffer, RecursionLimits, Sampling, View};
use crate::scene::{Camera, Scene};
use glam::Vec3;
use serde::Serialize;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

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
    /// The pixel-bar rig ([`pixels`]); `None` if the show did not load.
    pub pixels: Option<PixelReport>,
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
        ) + &self.pixels.as_ref().map(PixelReport::lines).unwrap_or_default()
    }
}

/// Runs the MVR measurements: import `show` `repeats` times, then 120
/// frames of `strobing` lights strobing at rates spread over 1-25 Hz.
pub fn run(
    scene: &Arc<Scene>,
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
        pixels: pixels(scene, camera, (w, h), show).map_err(|e| tracing::error!("pixel bars: {e}")).ok(),
    }
}

/// What the pixel-bar section measured.
#[derive(Clone, Debug, Serialize)]
pub struct PixelReport {
    /// Pixel bars in the show.
    pub bars: usize,
    /// Cells (lights) of those bars.
    pub cells: usize,
    /// Picture size.
    pub size: (u32, u32),
    /// Tiles of the picture.
    pub tiles: usize,
    /// Import of the show (every cell built into the patch), ms.
    pub import_ms: f64,
    /// Every cell's footprint-culled direct stage, one after another, ms in all.
    pub direct_build_ms: f64,
    /// Every cell's settled Whitted stage (anti-aliased), ms in all.
    pub whitted_build_ms: f64,
    /// The cells built together ([`crate::render::build::together`]): each bar's cells in one pass.
    pub together: Together,
    /// Tiles a cell's cone reaches, mean.
    pub tiles_per_cell: f64,
    /// Direct stage of a light whose cone reaches no tile, ms (median of 20):
    /// the fixed cost every cell pays beyond its footprint.
    pub empty_light_ms: f64,
    /// Composite per 60 Hz frame with every cell's k_i changing, ms (median of 120 frames).
    pub all_faders_ms: f64,
    /// Tiles recomposited per frame with every fader moving, mean.
    pub all_faders_tiles: f64,
    /// Composite per 60 Hz frame with one cell's k_i changing (the cell whose
    /// cone reaches the most tiles), ms (median of 120 frames).
    pub one_fader_ms: f64,
    /// Tiles recomposited per frame with one fader moving, mean.
    pub one_fader_tiles: f64,
    /// The rig and the show through the live tracer ([`through_tracer`]).
    pub live: Live,
}

/// The pixel rig and the whole show through the live tracer, the cells of
/// each fixture built together (batched) and one by one (alone). Photons
/// off (the later stages are per cell either way), settle time 0, every
/// light requested at once as at start-up.
#[derive(Clone, Debug, Serialize)]
pub struct Live {
    /// Start to every cell of the rig at its Whitted stage, cells alone, ms (faster of two runs).
    pub rig_alone_ms: f64,
    /// The same, each bar's cells together, ms.
    pub rig_batched_ms: f64,
    /// Batched passes the tracer ran for the rig (direct and Whitted).
    pub rig_passes: u64,
    /// Largest |batched − alone| of the cells' published buffers, relative to the cell's peak.
    pub rig_err: f64,
    /// Lights of the whole show.
    pub show_lights: usize,
    /// Start to a first picture (direct stage) of every light of the show, alone, ms.
    pub show_first_alone_ms: f64,
    /// The same, each fixture's cells together, ms.
    pub show_first_batched_ms: f64,
    /// Largest |batched − alone| of the show's first pictures, relative to the light's peak.
    pub show_first_err: f64,
}

impl Live {
    fn lines(&self) -> String {
        format!(
            "    through the live tracer (photons off, every light requested at start-up; build threads at the lowest OS \
             priority):\n      \
             rig to every cell at Whitted: alone {:.1} ms, cells together {:.1} ms ({} batched passes; \
             max difference {:.1e} of the cell's peak)\n      \
             whole show ({} lights) to a first picture of every light: alone {:.1} ms, cells together {:.1} ms \
             (max difference {:.1e})\n",
            self.rig_alone_ms,
            self.rig_batched_ms,
            self.rig_passes,
            self.rig_err,
            self.show_lights,
            self.show_first_alone_ms,
            self.show_first_batched_ms,
            self.show_first_err
        )
    }
}

/// Lights `lights` through a live tracer over `view`, grouped by `fixture`
/// ([`crate::live::Tracer::set_groups`]), every light requested at once:
/// the time from start to every light at its Whitted stage (`first_only`:
/// at its first picture), the published buffers and the batched passes run.
/// Photons off, settle time 0. NaN time if it takes over 10 minutes.
pub fn through_tracer(
    scene: &Arc<Scene>,
    view: &Arc<View>,
    lights: &[crate::Light],
    fixture: &[Option<u32>],
    batch: bool,
    first_only: bool,
) -> (f64, Vec<LightBuffer>, u64) {
    use crate::live::{Tracer, TracerSettings};
    use crate::output::Stage;
    let mut settings = TracerSettings { batch_cells: batch, settle: Duration::ZERO, ..TracerSettings::default() };
    settings.build.photons = None;
    settings.build.refine_passes = 0;
    let tracer = Tracer::new(scene.clone(), view.clone(), lights.len(), settings);
    tracer.set_groups(fixture);
    tracer.set_paused(true);
    for (i, l) in lights.iter().enumerate() {
        tracer.request(i, l.clone(), 1.0);
    }
    let done = |s: Stage| if first_only { s != Stage::Queued } else { s == Stage::Ready };
    let t = Instant::now();
    tracer.set_paused(false);
    let mut ms = f64::NAN;
    while t.elapsed() < Duration::from_secs(600) {
        if (0..lights.len()).all(|i| done(tracer.published(i).stage)) {
            ms = t.elapsed().as_secs_f64() * 1e3;
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let buffers = (0..lights.len()).map(|i| (*tracer.published(i).buffer).clone()).collect();
    let passes = tracer.batched_builds();
    tracer.shutdown(Duration::from_secs(60));
    (ms, buffers, passes)
}

/// [`Live`]: the rig (`lights`, grouped by `bar_of`) to Whitted and the
/// whole show (`show`) to a first picture, batched and alone, each the
/// faster of two runs.
fn live(
    scene: &Arc<Scene>,
    view: &Arc<View>,
    lights: &[crate::Light],
    bar_of: &[u32],
    show: &[&crate::fixture::Fixture],
) -> Live {
    let bars: Vec<Option<u32>> = bar_of.iter().map(|b| Some(*b)).collect();
    let show_lights: Vec<crate::Light> = show.iter().map(|f| f.light.clone()).collect();
    let ids: Vec<Option<u32>> = show.iter().map(|f| Some(f.id)).collect();
    // Each twice, in the order alone, together, together, alone (the load of
    // a shared machine drifts), the faster of the two kept.
    let twice = |lights: &[crate::Light], ids: &[Option<u32>], first_only: bool| {
        let a = through_tracer(scene, view, lights, ids, false, first_only);
        let b = through_tracer(scene, view, lights, ids, true, first_only);
        let b2 = through_tracer(scene, view, lights, ids, true, first_only);
        let a2 = through_tracer(scene, view, lights, ids, false, first_only);
        (a.0.min(a2.0), a.1, b.0.min(b2.0), b.1, b.2)
    };
    let (rig_alone_ms, alone, rig_batched_ms, batched, rig_passes) = twice(lights, &bars, false);
    let (show_first_alone_ms, first_alone, show_first_batched_ms, first_batched, _) = twice(&show_lights, &ids, true);
    Live {
        rig_alone_ms,
        rig_batched_ms,
        rig_passes,
        rig_err: max_difference(&alone, &batched),
        show_lights: show_lights.len(),
        show_first_alone_ms,
        show_first_batched_ms,
        show_first_err: max_difference(&first_alone, &first_batched),
    }
}

impl PixelReport {
    /// Lines for the summary and the report.
    pub fn lines(&self) -> String {
        format!(
            "  pixel bars: {} bars × {} cells = {} lights, {}×{} ({} tiles); import {:.1} ms\n    \
             build: direct stages {:.1} ms in all ({:.3} ms per cell, {:.1} tiles per cell; a light reaching no tile {:.3} ms), \
             Whitted stages {:.1} ms in all\n    \
             composite per 60 Hz frame: all faders moving {:.3} ms ({:.0} tiles), one fader {:.3} ms ({:.1} tiles)\n",
            self.bars,
            self.cells / self.bars.max(1),
            self.cells,
            self.size.0,
            self.size.1,
            self.tiles,
            self.import_ms,
            self.direct_build_ms,
            self.direct_build_ms / self.cells.max(1) as f64,
            self.tiles_per_cell,
            self.empty_light_ms,
            self.whitted_build_ms,
            self.all_faders_ms,
            self.all_faders_tiles,
            self.one_fader_ms,
            self.one_fader_tiles
        ) + &self.together.lines(self.direct_build_ms, self.whitted_build_ms)
            + &self.live.lines()
    }
}

/// The pixel cells built together ([`crate::render::build::together`]) against one
/// by one: times and the largest difference to the cells built alone.
#[derive(Clone, Debug, Serialize)]
pub struct Together {
    /// Path bounds of the view ([`crate::render::footprint::TileBounds::paths`]), once per view, ms.
    pub bounds_ms: f64,
    /// Every bar's direct stage, its cells together, ms in all.
    pub direct_ms: f64,
    /// Largest |together − alone| over the direct stages, relative to the cell's peak.
    pub direct_err: f64,
    /// Every bar's Whitted stage, its cells together, ms in all.
    pub whitted_ms: f64,
    /// Largest |together − alone| over the Whitted stages, relative to the cell's peak.
    pub whitted_err: f64,
    /// The Whitted stage of every cell of the rig in one pass, ms.
    pub rig_whitted_ms: f64,
    /// Largest |together − alone| of the one-pass rig, relative to the cell's peak.
    pub rig_whitted_err: f64,
    /// Union of the bars' footprints (tiles shaded once per bar), summed over bars.
    pub union_tiles: usize,
    /// Tiles the cells' cones reach, summed over cells (what one by one shades).
    pub cell_tiles: usize,
}

impl Together {
    fn lines(&self, direct_alone: f64, whitted_alone: f64) -> String {
        format!(
            "    cells built together (one pass per bar over the union of its cells' footprints, {} tiles vs {} cell tiles):\n      \
             direct stages {:.1} ms (alone {:.1} ms; max difference {:.1e} of the cell's peak)\n      \
             Whitted stages {:.1} ms + path bounds {:.1} ms once per view (alone {:.1} ms; max difference {:.1e}); \
             the whole rig in one pass {:.1} ms (max difference {:.1e})\n      \
             first picture of every cell (direct + Whitted): alone {:.1} ms, together {:.1} ms\n",
            self.union_tiles,
            self.cell_tiles,
            self.direct_ms,
            direct_alone,
            self.direct_err,
            self.whitted_ms,
            self.bounds_ms,
            whitted_alone,
            self.whitted_err,
            self.rig_whitted_ms,
            self.rig_whitted_err,
            direct_alone + whitted_alone,
            self.direct_ms + self.whitted_ms + self.bounds_ms
        )
    }
}

/// Largest |b − a| over every pixel, relative to the peak of `a`, over pairs of buffers.
fn max_difference(alone: &[LightBuffer], together: &[LightBuffer]) -> f64 {
    alone
        .iter()
        .zip(together)
        .map(|(a, b)| {
            let (a, b) = (a.to_dense(), b.to_dense());
            let peak = a.iter().map(|p| p.max_element()).fold(0.0f32, f32::max);
            let diff = a.iter().zip(&b).map(|(x, y)| (*x - *y).abs().max_element()).fold(0.0f32, f32::max);
            if peak > 0.0 { f64::from(diff / peak) } else { f64::from(diff) }
        })
        .fold(0.0, f64::max)
}

/// Builds the cells together, bar by bar (`bar_of[i]`: cell i's bar), and
/// the whole rig in one pass; compares with `direct` and `whitted` (the
/// cells' buffers built alone).
fn together(
    scene: &Scene,
    view: &View,
    lights: &[crate::Light],
    bar_of: &[u32],
    direct: &[LightBuffer],
    whitted: &[LightBuffer],
) -> Result<Together, String> {
    use crate::render::build::together::{direct_together, whitted_together};
    use crate::render::footprint::TileBounds;
    let aa = Some(crate::render::AaParams::new(crate::render::BuildSettings::default().aa_threshold));
    let t = Instant::now();
    let bounds = TileBounds::paths(view);
    let bounds_ms = t.elapsed().as_secs_f64() * 1e3;
    let mut bars: std::collections::BTreeMap<u32, Vec<usize>> = std::collections::BTreeMap::new();
    for (i, b) in bar_of.iter().enumerate() {
        bars.entry(*b).or_default().push(i);
    }
    let never = || false;
    let (mut d, mut wb) = (vec![None; lights.len()], vec![None; lights.len()]);
    let (mut direct_ms, mut whitted_ms, mut union_tiles, mut cell_tiles) = (0.0, 0.0, 0, 0);
    for cells in bars.values() {
        let group: Vec<crate::Light> = cells.iter().map(|&i| lights[i].clone()).collect();
        let t = Instant::now();
        let (bufs, _) = direct_together(scene, view, &group, &never).ok_or("cancelled")?;
        direct_ms += t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let (built, stats) = whitted_together(scene, view, &bounds, &group, aa, &never).ok_or("cancelled")?;
        whitted_ms += t.elapsed().as_secs_f64() * 1e3;
        union_tiles += stats.union_tiles;
        cell_tiles += stats.light_tiles;
        for ((&i, b), (w, _)) in cells.iter().zip(bufs).zip(built) {
            d[i] = Some(b);
            wb[i] = Some(w);
        }
    }
    let d: Vec<LightBuffer> = d.into_iter().flatten().collect();
    let wb: Vec<LightBuffer> = wb.into_iter().flatten().collect();
    let t = Instant::now();
    let (rig, _) = whitted_together(scene, view, &bounds, lights, aa, &never).ok_or("cancelled")?;
    let rig_whitted_ms = t.elapsed().as_secs_f64() * 1e3;
    let rig: Vec<LightBuffer> = rig.into_iter().map(|(b, _)| b).collect();
    Ok(Together {
        bounds_ms,
        direct_ms,
        direct_err: max_difference(direct, &d),
        whitted_ms,
        whitted_err: max_difference(whitted, &wb),
        rig_whitted_ms,
        rig_whitted_err: max_difference(whitted, &rig),
        union_tiles,
        cell_tiles,
    })
}

/// Runs the pixel-bar measurements on `show` (its LED fixtures that became
/// several lights: the cells of their GDTF `GeometryReference`s) over
/// `scene` from `camera`.
pub fn pixels(scene: &Arc<Scene>, camera: Camera, (w, h): (u32, u32), show: &Path) -> Result<PixelReport, String> {
    use crate::render::build::{BuildSettings, Cancel, LightBuild};
    use crate::render::footprint::DirectQuality;
    let t = Instant::now();
    let import = footlight_mvr::load_mvr(show).map_err(|e| e.first().map(|e| e.to_string()).unwrap_or_default())?;
    let import_ms = t.elapsed().as_secs_f64() * 1e3;
    // Pixel cells: LED fixtures sharing an id with another (one MVR fixture
    // became several lights); the blinders' tungsten lamps are left out.
    let led = |f: &&crate::fixture::Fixture| match &f.model {
        crate::fixture::FixtureModel::Typed(t) => matches!(t.fixture_type.lamp, footlight_photometry::Lamp::Led { .. }),
        crate::fixture::FixtureModel::Builtin(_) => false,
    };
    let mut per_id: std::collections::BTreeMap<u32, usize> = std::collections::BTreeMap::new();
    for f in import.patch.fixtures.iter().filter(led) {
        *per_id.entry(f.id).or_default() += 1;
    }
    let cells: Vec<_> = import.patch.fixtures.iter().filter(led).filter(|f| per_id[&f.id] > 1).collect();
    let bars = per_id.values().filter(|n| **n > 1).count();
    if cells.is_empty() {
        return Err(format!("{}: no pixel cells", show.display()));
    }
    let view = Arc::new(View::build(scene, camera, w, h, Sampling::Adaptive, RecursionLimits::default()));
    let tiles = view.tile_bounds().len();
    let build =
        |light: &crate::Light, i: usize| LightBuild::new(light.clone(), i, BuildSettings::default(), Cancel::never());
    // Direct stages, one cell after another (as the tracer serves them).
    let t = Instant::now();
    let mut in_beam = Vec::with_capacity(cells.len());
    let mut buffers: Vec<LightBuffer> = Vec::with_capacity(cells.len());
    for (i, f) in cells.iter().enumerate() {
        let (b, stats) = build(&f.light, i).direct(scene, &view, DirectQuality::Full).map_err(|e| e.to_string())?;
        in_beam.push(stats.tiles_in_beam);
        buffers.push(b);
    }
    let direct_build_ms = t.elapsed().as_secs_f64() * 1e3;
    let direct_alone = buffers.clone();
    let t = Instant::now();
    for (i, f) in cells.iter().enumerate() {
        buffers[i] = build(&f.light, i).whitted(scene, &view).map_err(|e| e.to_string())?;
    }
    let whitted_build_ms = t.elapsed().as_secs_f64() * 1e3;
    let lights: Vec<crate::Light> = cells.iter().map(|f| f.light.clone()).collect();
    let bar_of: Vec<u32> = cells.iter().map(|f| f.id).collect();
    let together = together(scene, &view, &lights, &bar_of, &direct_alone, &buffers)?;
    // A light aimed away from everything the camera sees: its direct stage tests every tile and shades none.
    let forward = camera.direction(w as f32 / 2.0, h as f32 / 2.0, w, h);
    let away = crate::Light::aimed(camera.position, camera.position - forward, cells[0].light.beam.clone());
    let empty_light_ms = median(
        (0..20)
            .map(|i| {
                let t = Instant::now();
                let _ = build(&away, i).direct(scene, &view, DirectQuality::Full);
                t.elapsed().as_secs_f64() * 1e3
            })
            .collect(),
    );
    // Composite: 120 frames at 60 Hz, every fader moving, then one.
    // The cells' own k_full is 0 in the default look (colour channels at 0): a white level instead.
    let k_full = vec![Vec3::splat(1000.0); cells.len()];
    let level = |i: usize, t: f64| (0.5 + 0.5 * (std::f64::consts::TAU * (0.5 * t + i as f64 / 24.0)).sin()) as f32;
    let frame = |moving: &dyn Fn(usize) -> bool| {
        let mut comp = Compositor::new(w, h, Display::default());
        let inputs = |t: f64| -> Vec<CompositeInput> {
            buffers
                .iter()
                .enumerate()
                .map(|(i, b)| CompositeInput {
                    buffer: b,
                    generation: 0,
                    k: k_full[i] * if moving(i) { level(i, t) } else { 0.5 },
                })
                .collect()
        };
        comp.update(&inputs(0.0));
        let (mut times, mut touched) = (Vec::new(), 0usize);
        for f in 1..=120 {
            let inputs = inputs(f64::from(f) / 60.0);
            let t = Instant::now();
            let stats = comp.update(&inputs);
            times.push(t.elapsed().as_secs_f64() * 1e3);
            touched += stats.tiles;
        }
        (median(times), touched as f64 / 120.0)
    };
    let (all_faders_ms, all_faders_tiles) = frame(&|_| true);
    // The one fader: the cell whose cone reaches the most tiles (the worst single fader).
    let widest = (0..cells.len()).max_by_key(|i| in_beam[*i]).unwrap_or(0);
    let (one_fader_ms, one_fader_tiles) = frame(&|i| i == widest);
    let show: Vec<&crate::fixture::Fixture> = import.patch.fixtures.iter().collect();
    let live = live(scene, &view, &lights, &bar_of, &show);
    Ok(PixelReport {
        bars,
        cells: cells.len(),
        size: (w, h),
        tiles,
        import_ms,
        direct_build_ms,
        whitted_build_ms,
        together,
        tiles_per_cell: in_beam.iter().sum::<usize>() as f64 / cells.len() as f64,
        empty_light_ms,
        all_faders_ms,
        all_faders_tiles,
        one_fader_ms,
        one_fader_tiles,
        live,
    })
}
