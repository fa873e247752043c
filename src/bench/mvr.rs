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
        )
    }
}

/// Runs the pixel-bar measurements on `show` (its LED fixtures that became
/// several lights: the cells of their GDTF `GeometryReference`s) over
/// `scene` from `camera`.
pub fn pixels(scene: &Scene, camera: Camera, (w, h): (u32, u32), show: &Path) -> Result<PixelReport, String> {
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
    let view = View::build(scene, camera, w, h, Sampling::Adaptive, RecursionLimits::default());
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
    let t = Instant::now();
    for (i, f) in cells.iter().enumerate() {
        buffers[i] = build(&f.light, i).whitted(scene, &view).map_err(|e| e.to_string())?;
    }
    let whitted_build_ms = t.elapsed().as_secs_f64() * 1e3;
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
    Ok(PixelReport {
        bars,
        cells: cells.len(),
        size: (w, h),
        tiles,
        import_ms,
        direct_build_ms,
        whitted_build_ms,
        tiles_per_cell: in_beam.iter().sum::<usize>() as f64 / cells.len() as f64,
        empty_light_ms,
        all_faders_ms,
        all_faders_tiles,
        one_fader_ms,
        one_fader_tiles,
    })
}
