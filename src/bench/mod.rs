//! `footlight bench`: the paper's figure 6 and section 4.1 as same-run
//! ratios and errors on the bundled stage.
//!
//! Every speed figure is a ratio of two timings taken in this run on this
//! machine (median of `repeats`), printed beside the paper's; every quality
//! figure is an MSE against the 9× oversampled render of the same state.
//! Writes `report.md` and `report.json` into the output folder.

pub mod accuracy;
pub mod bodies;
pub mod chase;
pub mod clients;
pub mod error_time;
pub mod festival;
pub mod gate;
pub mod harness;
pub mod haze;
pub mod haze_whole;
pub mod indirect;
pub mod live;
pub mod mvr;
pub mod plots;
pub mod scale;
pub mod stream;
pub mod stress;
pub mod sweeps;
pub mod walk;

use crate::Patch;
use crate::render::buffer::LightBuffer;
use crate::render::buffer::TILE;
use crate::render::composite::{CompositeInput, Compositor, composite_into};
use crate::render::display::Display;
use crate::render::gbuffer::GBuffer;
use crate::render::view::{AaParams, Sampling, View};
use crate::render::{PICTURE_SIZE, QUICK_SIZE};
use crate::render::{RecursionLimits, RenderSettings};
use crate::scene::{Camera, Scene};
use glam::Vec3;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// The 150-fixture MVR show of the MVR and pixel-bar sections, relative to
/// the bundled files ([`crate::bundled`]).
pub const SHOW150: &str = "tests/data/mvr/show150.mvr";

/// What to measure and at what size.
#[derive(Clone, Debug)]
pub struct BenchConfig {
    /// Image width (paper: 800).
    pub width: u32,
    /// Image height (paper: 500).
    pub height: u32,
    /// Repetitions per timing (median reported).
    pub repeats: usize,
    /// Lights in the synthetic many-light composite (target: 32).
    pub composite_lights: usize,
    /// Recursion limits (paper: depth 5).
    pub limits: RecursionLimits,
    /// AA threshold (0-255).
    pub aa_threshold: f32,
    /// Shrunk settings for CI.
    pub quick: bool,
    /// The scene file (re-loaded for the no-specular comparison).
    pub scene_path: PathBuf,
}

impl BenchConfig {
    /// The paper's settings, or CI-sized ones with `quick`.
    pub fn new(quick: bool, scene_path: PathBuf) -> Self {
        let s = RenderSettings::default();
        Self {
            width: if quick { QUICK_SIZE.0 } else { s.width },
            height: if quick { QUICK_SIZE.1 } else { s.height },
            repeats: if quick { 1 } else { 3 },
            composite_lights: 32,
            limits: s.limits,
            aa_threshold: s.build.aa_threshold,
            quick,
            scene_path,
        }
    }
}

/// One measured ratio with the paper's value beside it.
#[derive(Clone, Debug, Serialize)]
pub struct Ratio {
    /// What is compared.
    pub name: String,
    /// Our value (same-run ratio).
    pub ours: f64,
    /// The paper's value, where it reports one.
    pub paper: Option<f64>,
    /// How to read it.
    pub note: String,
}

/// Everything the bench measured.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Scene triangles.
    pub triangles: usize,
    /// Share of specular triangles.
    pub specular_fraction: f32,
    /// Threads in the default pool.
    pub threads: usize,
    /// Raw timings in milliseconds by name.
    pub timings_ms: Vec<(String, f64)>,
    /// Ratios against the paper's figure 6.
    pub ratios: Vec<Ratio>,
    /// MSE per RGB channel against the 9× render, by sampling mode.
    pub mse_vs_nine: Vec<(String, [f64; 3])>,
    /// Pixels re-shaded by adaptive AA, as a share of the image.
    pub adaptive_reshaded_share: f64,
    /// Issue 13.5: the anti-aliasing decision before (displayed value) and
    /// after (light-relative gradient): cost, error, re-shaded share.
    pub aa_rules: Vec<sweeps::AaRule>,
    /// Indirect term at the paper's settings vs path tracing: relative MSE,
    /// variance and bias by region, before/after the edge clipping.
    pub indirect: Vec<indirect::IndirectRow>,
    /// Composite linearity check: max relative difference between the
    /// composite of per-light buffers and their eq. 1 single-pass render.
    pub linearity_max_rel_error: f64,
    /// Photon maps: timings and errors against the converged reference.
    pub photons: PhotonReport,
    /// Run time against error: photon count, SPPM passes, AA threshold, depth.
    pub curves: Vec<sweeps::Curve>,
    /// Work skipped when a scene does not need it, as same-run ratios.
    pub skips: Vec<Ratio>,
    /// Section 4.1: adaptive AA vs 9×, and the photon-seed baseline, over ten renders.
    pub accuracy: sweeps::Accuracy,
    /// The numerical stress matrix.
    pub stress: Vec<stress::StressCase>,
    /// Daemon: composite frame times by light count and size, geometry latency.
    pub live: live::LiveReport,
    /// The 600-fixture, 16-universe rig at 1920×1080 (full runs only).
    pub scale: Option<scale::ScaleReport>,
    /// Haze: beam time vs error, density re-weighting, multiple scattering, rig cost.
    pub haze: Option<haze::HazeReport>,
    /// Issue 18: 44 moving heads in a chase through the daemon.
    pub chase: Option<chase::ChaseReport>,
    /// Issues 12/17: the frame clock under N preview clients.
    pub clients: Vec<clients::ClientsRow>,
    /// MVR import time and strobe composite cost (issue 14).
    pub mvr: mvr::MvrReport,
    /// Issue 17: the browser stream against PNG pictures and polling, and its picture size.
    pub stream: (Vec<stream::StreamRow>, (u32, u32)),
    /// Issue 16: moving the camera, settling, returning to a cached view.
    pub walk: Option<walk::WalkReport>,
    /// Issue 38: the festival-scale show's targets (full runs only).
    pub festival: Option<festival::FestivalReport>,
}

/// One point of a run-time-versus-error curve.
#[derive(Clone, Debug, Serialize)]
pub struct CurvePoint {
    /// The swept setting's value (photons stored, or SPPM passes).
    pub setting: f64,
    /// Wall time to produce the estimate, ms.
    pub ms: f64,
    /// Display-space MSE per RGB channel against the converged reference.
    pub mse: [f64; 3],
}

/// Photon-map measurements for one light.
#[derive(Clone, Debug, Serialize)]
pub struct PhotonReport {
    /// Photons stored per map (paper: 50,000) and in the estimate (paper: 150).
    pub stored: usize,
    /// k of the kNN estimate.
    pub estimate: usize,
    /// Tracing + map build (incl. precomputed irradiance) for one light, ms.
    pub trace_and_build_ms: f64,
    /// Evaluating the indirect buffer at the view's vertices, ms.
    pub indirect_buffer_ms: f64,
    /// SPPM passes behind the converged reference.
    pub reference_passes: u32,
    /// Baseline: MSE between two renders differing only in the photon seed
    /// (paper: 0.005, 0.003, 0.003 for two 9× renders).
    pub seed_to_seed_mse: [f64; 3],
}

impl Report {
    /// A plain-text table for the terminal.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "footlight bench: {}×{}, {} triangles, {} threads\n",
            self.width, self.height, self.triangles, self.threads
        );
        for r in &self.ratios {
            let paper = r.paper.map(|p| format!("{p:.2}")).unwrap_or_else(|| "-".into());
            s += &format!("  {:<58} ours {:>9.2}   paper {:>7}\n", r.name, r.ours, paper);
        }
        for (name, m) in &self.mse_vs_nine {
            s += &format!("  MSE vs 9x, {name:<10} R {:.5} G {:.5} B {:.5}\n", m[0], m[1], m[2]);
        }
        for r in &self.aa_rules {
            s += &format!(
                "  AA {:<62} cost {:>5.0} %  MSE {:.2e}  re-shaded {:.2} %\n",
                r.rule,
                r.cost_percent,
                r.mse_vs_nine.iter().sum::<f64>(),
                r.reshaded_share * 100.0
            );
        }
        s += &format!("  linearity (composite vs eq. 1 render): max rel. error {:.2e}\n", self.linearity_max_rel_error);
        if let Some(h) = &self.haze {
            s += &h.lines();
        }
        if let Some(c) = &self.chase {
            s += &c.lines();
        }
        if let Some(f) = &self.festival {
            s += &f.lines();
        }
        s += &self.mvr.lines();
        s
    }

    fn markdown(&self) -> String {
        let mut s = String::from("# footlight bench report\n\n");
        s += &format!(
            "Command: `{}` (footlight {}, {} build).\n\n",
            std::env::args().collect::<Vec<_>>().join(" "),
            env!("CARGO_PKG_VERSION"),
            if cfg!(debug_assertions) { "debug" } else { "release" }
        );
        s += &format!(
            "Scene: {} triangles ({:.1} % specular), {}×{}, depth 5, {} threads. Timings are medians; every ratio is taken within this run.\n\n",
            self.triangles,
            self.specular_fraction * 100.0,
            self.width,
            self.height,
            self.threads
        );
        s += "| comparison | ours | paper | note |\n|---|---:|---:|---|\n";
        for r in &self.ratios {
            let paper = r.paper.map(|p| format!("{p:.2}")).unwrap_or_else(|| "–".into());
            s += &format!("| {} | {:.2} | {} | {} |\n", r.name, r.ours, paper, r.note);
        }
        s += "\n## Anti-aliasing error (MSE of display RGB in [0,1] against 9× oversampling)\n\n| sampling | R | G | B |\n|---|---:|---:|---:|\n";
        for (name, m) in &self.mse_vs_nine {
            s += &format!("| {name} | {:.6} | {:.6} | {:.6} |\n", m[0], m[1], m[2]);
        }
        s += "| paper, adaptive | 0.006 | 0.004 | 0.0004 |\n";
        s += &format!(
            "\nAdaptive AA re-shaded {:.1} % of the pixels.\nLinearity: composite of per-light buffers vs single-pass eq. 1 render, max relative error {:.2e}.\n",
            self.adaptive_reshaded_share * 100.0,
            self.linearity_max_rel_error
        );
        s += "\n## Anti-aliasing decision (issue 13.5): before and after\n\n| rule | cost / 1 sample (%) | MSE vs 9× R | G | B | re-shaded |\n|---|---:|---:|---:|---:|---:|\n";
        for r in &self.aa_rules {
            s += &format!(
                "| {} | {:.0} | {:.2e} | {:.2e} | {:.2e} | {:.2} % |\n",
                r.rule,
                r.cost_percent,
                r.mse_vs_nine[0],
                r.mse_vs_nine[1],
                r.mse_vs_nine[2],
                r.reshaded_share * 100.0
            );
        }
        s += "| paper (adaptive) | 119 | 0.006 | 0.004 | 0.0004 | |\n";
        s += "\n## Indirect term at the paper's settings vs path tracing (issue 13)\n\n";
        s += &indirect::markdown(&self.indirect);
        let p = &self.photons;
        s += &format!(
            "\n## Photon maps (one light, {} stored, {} in the estimate)\n\nTrace + build {:.1} ms, indirect buffer {:.1} ms. \
             Reference: the first estimate refined by {} SPPM passes. Seed-to-seed MSE (same settings, other photon seed): \
             R {:.6} G {:.6} B {:.6} (paper, two 9× renders: 0.005 0.003 0.003).\n",
            p.stored,
            p.estimate,
            p.trace_and_build_ms,
            p.indirect_buffer_ms,
            p.reference_passes,
            p.seed_to_seed_mse[0],
            p.seed_to_seed_mse[1],
            p.seed_to_seed_mse[2]
        );
        for c in &self.curves {
            s += &format!(
                "\n### Error vs time: {}\n\nPaper's operating point: {} = {}. Settings that dominate it (no slower, no \
                 less accurate): {}.\n\n| {} | ms | MSE R | MSE G | MSE B |\n|---:|---:|---:|---:|---:|\n",
                c.name,
                c.setting,
                c.paper_setting,
                if c.dominating.is_empty() {
                    "none".to_string()
                } else {
                    c.dominating.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ")
                },
                c.setting
            );
            for p in &c.points {
                let mark = if p.setting == c.paper_setting { " (paper)" } else { "" };
                s += &format!(
                    "| {}{mark} | {:.1} | {:.3e} | {:.3e} | {:.3e} |\n",
                    p.setting, p.ms, p.mse[0], p.mse[1], p.mse[2]
                );
            }
        }
        let a = &self.accuracy;
        s += &format!(
            "\n## Accuracy over {} renders (paper section 4.1)\n\n| MSE | R | G | B |\n|---|---:|---:|---:|\n\
             | adaptive vs 9× (ours) | {:.2e} | {:.2e} | {:.2e} |\n| adaptive vs 9× (paper) | 0.006 | 0.004 | 0.0004 |\n\
             | 9× vs 9×, other photon seed (ours) | {:.2e} | {:.2e} | {:.2e} |\n| 9× vs 9×, other photon seed (paper) | 0.005 | 0.003 | 0.003 |\n",
            a.renders,
            a.adaptive_vs_nine[0],
            a.adaptive_vs_nine[1],
            a.adaptive_vs_nine[2],
            a.nine_seed_baseline[0],
            a.nine_seed_baseline[1],
            a.nine_seed_baseline[2]
        );
        s += "\n## Skipping what the scene does not need\n\n| measurement | ratio | note |\n|---|---:|---|\n";
        for r in &self.skips {
            s += &format!("| {} | {:.2} | {} |\n", r.name, r.ours, r.note);
        }
        s += "\n## Numerical stress matrix\n\n| case | result | max (cd/m²) | bound | detail |\n|---|---|---:|---:|---|\n";
        for c in &self.stress {
            let bound = c.bound.map(|b| format!("{b:.3e}")).unwrap_or_else(|| "–".into());
            s += &format!(
                "| {} | {} | {:.3e} | {} | {} |\n",
                c.name,
                if c.ok { "ok" } else { "FAIL" },
                c.max_value,
                bound,
                c.detail
            );
        }
        let l = &self.live;
        s += &format!(
            "\n## Daemon\n\nGeometry change of one light at {}×{}: first direct-light frame after {:.0} ms, mirrors/glass/AA \
             after {:.0} ms, photon-mapped after {:.0} ms, all {} progressive passes done after {:.0} ms (the time to the \
             converged picture, judged by its error, is the accuracy section's: `--accuracy-part converge`).\n\n\
             Composite per frame (GPU: {}):\n\n| lights | size | CPU full (ms) | CPU one fader (ms) | GPU (ms) |\n|---:|---|---:|---:|---:|\n",
            self.width,
            self.height,
            l.latency.first_direct_ms,
            l.latency.whitted_ms,
            l.latency.photons_ms,
            l.latency.refine_passes,
            l.latency.converged_ms,
            l.gpu_adapter.as_deref().unwrap_or("no adapter")
        );
        for r in &l.composite {
            let gpu = r.gpu_ms.map(|g| format!("{g:.2}")).unwrap_or_else(|| "–".into());
            s += &format!(
                "| {} | {}×{} | {:.2} | {:.3} | {} |\n",
                r.lights, r.width, r.height, r.cpu_full_ms, r.cpu_one_fader_ms, gpu
            );
        }
        if let Some(r) = &self.scale {
            s += &format!(
                "\n## A {}-fixture rig on {} universes at {}×{}\n\nPer frame: decoding all universes into lights and k_i \
                 {:.2} ms; full composite + sRGB {:.2} ms; incremental update after one fader {:.3} ms, after all \
                 dimmers at once {:.2} ms. Buffers: {:.0} MiB sparse ({:.0} MiB as dense RGB f32). Building every \
                 light's direct buffer once: {:.1} s.\n",
                r.fixtures,
                r.universes,
                r.width,
                r.height,
                r.decode_ms,
                r.composite_full_ms,
                r.composite_one_fader_ms,
                r.composite_all_faders_ms,
                r.buffers_mib,
                r.dense_mib,
                r.build_s
            );
            if let Some(p) = &r.pixel_chase {
                s += &format!("\n{}", p.markdown());
            }
        }
        if let Some(h) = &self.haze {
            s += &format!("\n## Haze (issue 15)\n\n```text\n{}```\n", h.lines());
        }
        if !self.clients.is_empty() {
            s += &clients::markdown(&self.clients);
        }
        if !self.stream.0.is_empty() {
            s += &stream::markdown(&self.stream.0, self.stream.1);
        }
        if let Some(w) = &self.walk {
            s += &w.markdown();
        }
        if let Some(c) = &self.chase {
            s += &c.markdown();
        }
        if let Some(f) = &self.festival {
            s += &f.markdown();
        }
        s += &format!("\n## MVR and GDTF (issue 14)\n\n```text\n{}```\n", self.mvr.lines());
        s += "\n## Raw timings (ms)\n\n| stage | ms |\n|---|---:|\n";
        for (n, t) in &self.timings_ms {
            s += &format!("| {n} | {t:.3} |\n");
        }
        s
    }
}

/// Default output folder: `bench/runs/<date>-<host>/`.
pub fn default_out_dir() -> PathBuf {
    let host = std::fs::read_to_string("/etc/hostname").map(|h| h.trim().to_string()).unwrap_or_else(|_| "host".into());
    let days =
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_secs() / 86_400).unwrap_or(0)
            as i64;
    let (y, m, d) = civil_from_days(days);
    PathBuf::from(format!("bench/runs/{y:04}-{m:02}-{d:02}-{host}"))
}

/// Gregorian date from days since 1970-01-01 (H. Hinnant's algorithm);
/// written out to avoid a date-time dependency for one folder name.
fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    (yoe + era * 400 + i64::from(m <= 2), m, d)
}

/// Median wall time of `f` over `n` runs, in milliseconds; returns the last result.
fn time_ms<T>(n: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    time_ms_with(n, || (), |()| f())
}

/// As [`time_ms`], with an untimed `setup` before each run.
fn time_ms_with<S, T>(n: usize, mut setup: impl FnMut() -> S, mut f: impl FnMut(S) -> T) -> (f64, T) {
    let mut times = Vec::with_capacity(n.max(1));
    let mut last = None;
    for _ in 0..n.max(1) {
        let input = setup();
        let t = Instant::now();
        last = Some(f(input));
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], last.expect("at least one run"))
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool")
}

/// Number of composite tiles in a `w`×`h` image.
fn tile_count(w: u32, h: u32) -> usize {
    (w as usize).div_ceil(TILE) * (h as usize).div_ceil(TILE)
}

/// A generated rig of `n` spots on three trusses over the stage, aimed at
/// spread-out points on the floor (distinct, realistic sparse buffers).
pub fn many_lights(n: usize) -> Vec<crate::Light> {
    use crate::fixture::{Beam, Light, SpotBeam};
    (0..n)
        .map(|i| {
            let row = i % 3;
            let col = i / 3;
            let cols = n.div_ceil(3).max(1);
            let x = -5.0 + 10.0 * (col as f32 + 0.5) / cols as f32;
            let z = [5.0, 0.0, -5.0][row];
            let aim = Vec3::new(x * 0.7 + (i as f32 * 0.61).sin(), 0.0, -3.0 + 5.0 * (i as f32 * 0.29).fract());
            let beam = 15.0 + 20.0 * (i as f32 * 0.43).fract();
            Light::aimed(Vec3::new(x, 6.5, z), aim, Beam::Spot(SpotBeam::from_beam_field(beam, beam + 10.0)))
        })
        .collect()
}

/// Display-space MSE per channel between two linear images.
pub fn mse_display(a: &[Vec3], b: &[Vec3], display: &Display) -> [f64; 3] {
    let s = display.scale();
    let mut acc = [0f64; 3];
    for (x, y) in a.iter().zip(b) {
        let d = crate::render::display::srgb_encode(*x * s) - crate::render::display::srgb_encode(*y * s);
        for (c, v) in acc.iter_mut().zip(d.to_array()) {
            *c += (v as f64) * (v as f64);
        }
    }
    acc.map(|c| c / a.len().max(1) as f64)
}

/// Photon maps for `light` over `view`: timings at the paper's settings, the
/// seed-to-seed baseline, and error-vs-time curves against an SPPM-converged
/// reference (all in display space of the light at full, direct included).
fn photon_section(
    scene: &Scene,
    view: &View,
    light: &crate::Light,
    k_full: Vec3,
    display: &Display,
    cfg: &BenchConfig,
) -> (PhotonReport, Vec<sweeps::Curve>) {
    use crate::render::photon::{PhotonSettings, Progressive, trace_photons};
    let paper = PhotonSettings::default();
    let (direct, _) = view.render_direct(scene, light, None);
    let shown =
        |indirect: &[Vec3]| -> Vec<Vec3> { direct.iter().zip(indirect).map(|(d, a)| (*d + *a) * k_full).collect() };
    let (t_trace, maps) = time_ms(cfg.repeats, || trace_photons(scene, light, &paper));
    let (t_indirect, first) = time_ms(cfg.repeats, || view.render_indirect(scene, &maps));
    let other = trace_photons(scene, light, &PhotonSettings { seed: paper.seed ^ 0xDEAD_BEEF, ..paper });
    let seed_to_seed_mse = mse_display(&shown(&first), &shown(&view.render_indirect(scene, &other)), display);

    // Converged reference: the first estimate refined by many SPPM passes.
    let reference_passes = if cfg.quick { 24 } else { 64 };
    let mut reference = Progressive::new(scene, view, &maps);
    for _ in 0..reference_passes {
        reference.pass(scene, view, light);
    }
    let reference_img = shown(&view.render_progressive(scene, &reference));

    let mut photon_count_curve = Vec::new();
    for factor in [0.125, 0.25, 0.5, 1.0, 2.0] {
        let settings =
            PhotonSettings { stored: (paper.stored as f64 * factor) as usize, seed: paper.seed ^ 0x5151, ..paper };
        let t = Instant::now();
        let m = trace_photons(scene, light, &settings);
        let img = view.render_indirect(scene, &m);
        let ms = t.elapsed().as_secs_f64() * 1e3;
        photon_count_curve.push(CurvePoint {
            setting: settings.stored as f64,
            ms,
            mse: mse_display(&shown(&img), &reference_img, display),
        });
    }
    let mut sppm_curve = Vec::new();
    let other_seed = PhotonSettings { seed: paper.seed ^ 0x7777, ..paper };
    let t0 = Instant::now();
    let start = trace_photons(scene, light, &other_seed);
    let mut sppm = Progressive::new(scene, view, &start);
    for target in [1u32, 2, 4, 8, 16] {
        while sppm.passes() < target {
            sppm.pass(scene, view, light);
        }
        let img = view.render_progressive(scene, &sppm);
        sppm_curve.push(CurvePoint {
            setting: target as f64,
            ms: t0.elapsed().as_secs_f64() * 1e3,
            mse: mse_display(&shown(&img), &reference_img, display),
        });
    }
    // Issue 13.4: the same passes blended with the first estimate (what is shown now).
    let mut blended_curve = Vec::new();
    let t0 = Instant::now();
    let start = trace_photons(scene, light, &other_seed);
    let at_vertices = view.vertex_irradiance(scene, &start);
    blended_curve.push(CurvePoint {
        setting: 0.0,
        ms: t0.elapsed().as_secs_f64() * 1e3,
        mse: mse_display(&shown(&view.render_vertex_irradiance(scene, &at_vertices)), &reference_img, display),
    });
    let mut sppm = Progressive::new(scene, view, &start).starting_from(at_vertices, paper.estimate as f32);
    for target in [1u32, 2, 4, 8, 16] {
        while sppm.passes() < target {
            sppm.pass(scene, view, light);
        }
        let img = view.render_progressive(scene, &sppm);
        blended_curve.push(CurvePoint {
            setting: target as f64,
            ms: t0.elapsed().as_secs_f64() * 1e3,
            mse: mse_display(&shown(&img), &reference_img, display),
        });
    }
    let report = PhotonReport {
        stored: paper.stored,
        estimate: paper.estimate,
        trace_and_build_ms: t_trace,
        indirect_buffer_ms: t_indirect,
        reference_passes,
        seed_to_seed_mse,
    };
    let curves = vec![
        sweeps::Curve::new("photons stored (first estimate)", "photons", paper.stored as f64, photon_count_curve),
        sweeps::Curve::new("before: SPPM passes alone after the first estimate", "passes", 0.0, sppm_curve),
        sweeps::Curve::new("after: SPPM passes blended with the first estimate (0 = it)", "passes", 0.0, blended_curve),
    ];
    (report, curves)
}

/// Runs the benchmark and writes the report into `out`.
pub fn run(scene: &Scene, patch: &Patch, camera: Camera, cfg: &BenchConfig, out: &Path) -> std::io::Result<Report> {
    std::fs::create_dir_all(out)?;
    let display = Display::default();
    let (w, h) = (cfg.width, cfg.height);
    let n = cfg.repeats;
    let mut timings = Vec::new();
    let mut ratios = Vec::new();
    let fixture =
        patch.fixtures.first().ok_or_else(|| std::io::Error::other("the patch has no fixtures to benchmark"))?;
    let light = &fixture.light;
    let k_full = fixture.k_full();
    let aa = AaParams::new(cfg.aa_threshold);
    let progress = indicatif::ProgressBar::new(7).with_style(
        indicatif::ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    progress.enable_steady_tick(std::time::Duration::from_millis(200));
    progress.set_message("primary intersections and illumination");

    // Primary intersections: single-sample ray casting vs the 9-sample G-buffer.
    let (t_single, _) = time_ms(n, || GBuffer::trace_centre_only(scene, camera, w, h));
    let (t_gbuf, gbuffer) = time_ms(n, || GBuffer::build(scene, camera, w, h));
    timings.push(("primary: 1 ray/pixel".into(), t_single));
    timings.push(("primary: 9-sample G-buffer".into(), t_gbuf));
    ratios.push(Ratio {
        name: "primary: 9-sample G-buffer time / 1-sample ray casting".into(),
        ours: t_gbuf / t_single,
        paper: Some(0.5),
        note: "paper rasterised its G-buffer on the GPU (2× faster than 1-sample ray casting); ours is CPU BVH, 9 rays"
            .into(),
    });

    // Illumination for one light: path expansion + shading, per sampling mode.
    let mut illum = Vec::new();
    let mut images = Vec::new();
    for sampling in [Sampling::One, Sampling::Adaptive, Sampling::Nine] {
        // The G-buffer clone is outside the timed region; only expansion and shading count.
        let (t, (buffer, reshaded)) = time_ms_with(
            n,
            || gbuffer.clone(),
            |g| {
                let view = View::from_gbuffer(scene, g, sampling, cfg.limits);
                view.render_light(scene, light, Some(aa))
            },
        );
        timings.push((format!("illumination, {sampling:?} (expand + shade)"), t));
        illum.push(t);
        images.push((sampling, buffer.to_dense(), reshaded));
    }
    ratios.push(Ratio {
        name: "illumination: adaptive AA / 1 sample (%)".into(),
        ours: illum[1] / illum[0] * 100.0,
        paper: Some(119.0),
        note: "".into(),
    });
    ratios.push(Ratio {
        name: "illumination: 9× / 1 sample (%)".into(),
        ours: illum[2] / illum[0] * 100.0,
        paper: Some(900.0),
        note: "".into(),
    });

    // Shading only, views prebuilt: 1 sample vs adaptive with its 9-sample
    // cache warm (every light after the first, and every rebuild of a moved light).
    let one_view = View::from_gbuffer(scene, gbuffer.clone(), Sampling::One, cfg.limits);
    let (t_shade_one, _) = time_ms(n, || one_view.render_light(scene, light, Some(aa)));
    let warm_view = View::from_gbuffer(scene, gbuffer.clone(), Sampling::Adaptive, cfg.limits);
    warm_view.render_light(scene, light, Some(aa));
    let (t_shade_warm, _) = time_ms(n, || warm_view.render_light(scene, light, Some(aa)));
    timings.push(("shade only, 1 sample".into(), t_shade_one));
    timings.push(("shade only, adaptive, warm 9-sample cache".into(), t_shade_warm));
    ratios.push(Ratio {
        name: "shading only: adaptive (warm cache) / 1 sample (%)".into(),
        ours: t_shade_warm / t_shade_one * 100.0,
        paper: Some(119.0),
        note: "camera paths prebuilt; the cache holds 9-sample paths of re-shaded pixels".into(),
    });

    // Threads: adaptive illumination on 1 and 2 threads.
    let adaptive_view = View::build(scene, camera, w, h, Sampling::Adaptive, cfg.limits);
    let (t1, _) = time_ms(n, || pool(1).install(|| adaptive_view.render_light(scene, light, Some(aa))));
    let (t2, _) = time_ms(n, || pool(2).install(|| adaptive_view.render_light(scene, light, Some(aa))));
    timings.push(("shade one light, 1 thread".into(), t1));
    timings.push(("shade one light, 2 threads".into(), t2));
    ratios.push(Ratio {
        name: "threads: 1-thread time / 2-thread time".into(),
        ours: t1 / t2,
        paper: Some(1.4),
        note: "".into(),
    });

    progress.set_message("updates and composites");
    progress.inc(1);
    // Updates: full re-render of one light, illumination-only, composite.
    let (t_full, _) = time_ms(n, || {
        let v = View::build(scene, camera, w, h, Sampling::Adaptive, cfg.limits);
        v.render_light(scene, light, Some(aa))
    });
    let (t_relight, _) = time_ms(n, || adaptive_view.render_light(scene, light, Some(aa)));
    let buffers: Vec<LightBuffer> = patch
        .fixtures
        .iter()
        .map(|f| adaptive_view.render_light(scene, &f.light, Some(AaParams::new(cfg.aa_threshold))).0)
        .collect();
    let refs: Vec<&LightBuffer> = buffers.iter().collect();
    let k: Vec<Vec3> = patch.fixtures.iter().map(|f| f.k()).collect();
    let mut frame = vec![Vec3::ZERO; (w * h) as usize];
    let mut srgb = vec![0u8; (w * h * 3) as usize];
    let reps = if cfg.quick { 20 } else { 100 };
    let (t_comp, _) = time_ms(reps, || {
        composite_into(&refs, &k, w, h, &mut frame);
        display.to_srgb8_into(&frame, &mut srgb);
    });
    // Incremental: the first fixture's fader moves every frame; only its tiles are recomposed.
    let mut compositor = Compositor::new(w, h, display);
    let inputs = |k0: Vec3| -> Vec<CompositeInput> {
        refs.iter()
            .zip(&k)
            .enumerate()
            .map(|(i, (b, k))| CompositeInput { buffer: b, generation: 0, k: if i == 0 { k0 } else { *k } })
            .collect()
    };
    compositor.update(&inputs(k[0]));
    let mut step = 0u32;
    let (t_update, stats) = time_ms(reps, || {
        step += 1;
        compositor.update(&inputs(k[0] * (0.2 + 0.8 * (step % 5) as f32 / 4.0)))
    });
    // Many lights: distinct buffers from a generated rig of spots over the stage.
    let rig = many_lights(cfg.composite_lights);
    let rig_buffers: Vec<LightBuffer> = rig.iter().map(|l| adaptive_view.render_light(scene, l, Some(aa)).0).collect();
    let rig_refs: Vec<&LightBuffer> = rig_buffers.iter().collect();
    let rig_k: Vec<Vec3> = (0..rig.len()).map(|i| k_full * (0.2 + 0.8 * (i as f32 * 0.37).fract())).collect();
    let (t_comp_many, _) = time_ms(reps, || {
        composite_into(&rig_refs, &rig_k, w, h, &mut frame);
        display.to_srgb8_into(&frame, &mut srgb);
    });
    timings.push(("full re-render of one light (G-buffer + expand + shade)".into(), t_full));
    timings.push(("illumination-only re-render of one light (shade)".into(), t_relight));
    timings.push((format!("full composite + sRGB, {} patch lights", refs.len()), t_comp));
    timings.push((format!("incremental update, one fader ({} of {} tiles)", stats.tiles, tile_count(w, h)), t_update));
    timings.push((format!("full composite + sRGB, {} distinct lights", rig.len()), t_comp_many));
    ratios.push(Ratio {
        name: "update: full re-render / illumination-only re-render".into(),
        ours: t_full / t_relight,
        paper: Some(1.5),
        note: "moved light: camera paths are reused".into(),
    });
    ratios.push(Ratio {
        name: "update: full re-render / full composite (colour change)".into(),
        ours: t_full / t_comp,
        paper: Some(125.0),
        note: format!("composite + sRGB of all {} patch lights", refs.len()),
    });
    ratios.push(Ratio {
        name: "update: full re-render / incremental update (one fader)".into(),
        ours: t_full / t_update,
        paper: Some(125.0),
        note: "target >= 1000; recomposes only the tiles the light covers".into(),
    });
    ratios.push(Ratio {
        name: "update: illumination-only / full composite".into(),
        ours: t_relight / t_comp,
        paper: Some(83.0),
        note: "".into(),
    });
    ratios.push(Ratio {
        name: format!("full composite of {} lights: ms per frame", rig.len()),
        ours: t_comp_many,
        paper: None,
        note: "target: < 16.7 ms (one 60 Hz frame) at 800×500 on 2 cores".into(),
    });

    // Quality: display-space MSE against 9× for the same light at its look.
    let k0 = fixture.k();
    let scaled = |img: &Vec<Vec3>| img.iter().map(|v| *v * k0).collect::<Vec<_>>();
    let nine = scaled(&images[2].1);
    let mse_vs_nine = vec![
        ("1 sample".to_string(), mse_display(&scaled(&images[0].1), &nine, &display)),
        ("adaptive".to_string(), mse_display(&scaled(&images[1].1), &nine, &display)),
    ];
    let adaptive_reshaded_share = images[1].2 as f64 / (w * h) as f64;

    // Linearity: composite of per-light buffers (binned) vs eq. 1 single pass.
    let lights: Vec<_> = patch.fixtures.iter().map(|f| f.light.clone()).collect();
    let geo_view = View::from_gbuffer(scene, adaptive_view.gbuffer.clone(), Sampling::Geometry, cfg.limits);
    let geo_buffers: Vec<LightBuffer> = lights.iter().map(|l| geo_view.render_light(scene, l, None).0).collect();
    let geo_refs: Vec<&LightBuffer> = geo_buffers.iter().collect();
    let comp = crate::render::composite(&geo_refs, &k, w, h);
    let eq1 = crate::render::reference::render_eq1(
        scene,
        &geo_view.gbuffer,
        &lights,
        &k,
        Sampling::Geometry.base_set(),
        cfg.limits,
    );
    let linearity_max_rel_error = comp
        .iter()
        .zip(&eq1)
        .map(|(a, b)| ((*a - *b).abs().max_element() / b.abs().max_element().max(1e-3)) as f64)
        .fold(0.0, f64::max);

    let aa_rules = sweeps::aa_rules(scene, &gbuffer, light, k_full, &display, cfg.limits, cfg.aa_threshold, n);
    progress.set_message("indirect error vs path tracing");
    let indirect = {
        let paper = crate::render::photon::PhotonSettings::default();
        let (bs, bl, bc) = indirect::lambert_box();
        if cfg.quick {
            let few = crate::render::photon::PhotonSettings { stored: 5_000, ..paper };
            indirect::measure("Lambert box (5,000 photons)", &bs, &bl, bc, (32, 20), few, 32)
        } else {
            let mut rows = indirect::measure("Lambert box", &bs, &bl, bc, (80, 50), paper, 256);
            rows.extend(indirect::measure("bundled stage", scene, light, camera, (80, 50), paper, 256));
            rows
        }
    };

    progress.set_message("photon maps and SPPM");
    progress.inc(1);
    let (photons, mut curves) = photon_section(scene, &adaptive_view, light, k_full, &display, cfg);
    progress.set_message("AA threshold and depth sweeps");
    progress.inc(1);
    curves.push(sweeps::aa_threshold_curve(scene, &gbuffer, light, k_full, &display, cfg.limits, n));
    curves.push(sweeps::depth_curve(scene, &gbuffer, light, k_full, &display, n));
    progress.set_message("skip measurements");
    progress.inc(1);
    let mut plain = crate::scene::load(&cfg.scene_path).map_err(std::io::Error::other)?;
    for m in &mut plain.materials {
        *m = crate::scene::Material::lambert(&m.name, m.diffuse + m.k_r + m.k_t);
    }
    let skip_lights = many_lights(16);
    let skips = sweeps::skips(scene, &plain, &gbuffer, &skip_lights, aa, k_full, cfg.limits, n);
    progress.set_message("accuracy over ten renders");
    progress.inc(1);
    let accuracy_photons = if cfg.quick {
        crate::render::photon::PhotonSettings { stored: 5_000, ..Default::default() }
    } else {
        crate::render::photon::PhotonSettings::default()
    };
    let accuracy = sweeps::accuracy(scene, &gbuffer, &many_lights(10), k_full, &display, cfg.limits, accuracy_photons);
    progress.set_message("stress matrix");
    progress.inc(1);
    let stress = stress::run_matrix(if cfg.quick { 2_000 } else { 20_000 });
    progress.set_message("daemon: composite scaling and geometry latency");
    let scene_arc = Arc::new(crate::scene::load(&cfg.scene_path).map_err(std::io::Error::other)?);
    let (sizes, counts): (Vec<(u32, u32)>, Vec<usize>) = if cfg.quick {
        (vec![QUICK_SIZE], vec![1, 8, 32])
    } else {
        (vec![PICTURE_SIZE, (1920, 1080)], vec![1, 8, 32, 128])
    };
    let live = live::run(&scene_arc, camera, &sizes, &counts, (w, h), (light, k_full), if cfg.quick { 4 } else { 16 });
    let scale = if cfg.quick {
        None
    } else {
        progress.set_message("600-fixture rig at 1920×1080");
        match scale::run(&scene_arc, camera, 1920, 1080) {
            Ok(r) => Some(r),
            Err(e) => {
                tracing::error!("large rig: {e}");
                None
            }
        }
    };
    progress.set_message("haze");
    let rig_lights = (!cfg.quick).then(haze::rig_lights);
    let mut haze = haze::run(
        scene,
        camera,
        w,
        h,
        light,
        cfg.repeats,
        if cfg.quick { 20_000 } else { 200_000 },
        rig_lights.as_deref(),
    );
    if let Some(report) = &mut haze {
        report.moved = haze::moved_beam(&scene_arc, camera, (w, h), 2, light, if cfg.quick { 2 } else { 10 });
        report.whole = haze_whole::run(&haze_whole::WholeHazeConfig::new(cfg.quick))
            .map_err(|e| tracing::error!("whole haze: {e}"))
            .ok();
    }
    progress.set_message("44 moving heads in a chase");
    let chase = if cfg.quick {
        chase::run(&scene_arc, camera, QUICK_SIZE, 2.0, 0)
    } else {
        chase::run(&scene_arc, camera, PICTURE_SIZE, 10.0, crate::render::photon::PhotonSettings::default().stored)
    };
    let chase = chase.map_err(|e| tracing::error!("chase: {e}")).ok();
    progress.set_message("preview clients");
    let clients = if cfg.quick {
        clients::run(&scene_arc, patch, camera, QUICK_SIZE, &[0, 20], 1.0)
    } else {
        clients::run(&scene_arc, patch, camera, PICTURE_SIZE, &[0, 20, 200], 10.0)
    };
    let clients = clients.map_err(|e| tracing::error!("preview clients: {e}")).unwrap_or_default();
    progress.set_message("MVR import and strobe");
    let show150 = crate::bundled::resolve(Path::new(SHOW150));
    let mvr = mvr::run(&scene_arc, camera, (w, h), &show150, cfg.repeats, 50);
    progress.set_message("browser stream");
    use stream::Viewer::{Buffers, None as NoViewers, Pictures, Polling, Switching};
    let (stream_size, stream_seconds) = if cfg.quick { (QUICK_SIZE, 2.0) } else { (PICTURE_SIZE, 12.0) };
    // (Switching, 20): a storm of stream mode switches, rate-limited per client (issue 35).
    let levels = [(NoViewers, 0), (Buffers, 20), (Pictures, 20), (Polling, 20), (Buffers, 60), (Switching, 20)];
    let stream_rows = stream::run(&scene_arc, patch, camera, stream_size, &levels, stream_seconds);
    let stream = (stream_rows.map_err(|e| tracing::error!("browser stream: {e}")).unwrap_or_default(), stream_size);
    progress.set_message("walking the stage");
    let walk = if cfg.quick {
        walk::run(&scene_arc, patch, camera, QUICK_SIZE, 1.0, 0)
    } else {
        walk::run(&scene_arc, patch, camera, PICTURE_SIZE, 5.0, crate::render::photon::PhotonSettings::default().stored)
    };
    let walk = walk.map_err(|e| tracing::error!("walking the stage: {e}")).ok();
    let festival = (!cfg.quick).then(|| {
        progress.set_message("festival-scale show (issue 38)");
        festival::run(&festival::FestivalConfig::new(false)).map_err(|e| tracing::error!("festival: {e}")).ok()
    });
    let festival = festival.flatten();
    progress.finish_and_clear();

    let report = Report {
        width: w,
        height: h,
        triangles: scene.triangle_count(),
        specular_fraction: scene.specular_fraction(),
        threads: rayon::current_num_threads(),
        timings_ms: timings,
        ratios,
        mse_vs_nine,
        adaptive_reshaded_share,
        aa_rules,
        indirect,
        linearity_max_rel_error,
        photons,
        curves,
        skips,
        accuracy,
        stress,
        live,
        scale,
        haze,
        chase,
        clients,
        mvr,
        stream,
        walk,
        festival,
    };
    plots::write(&report, out)?;
    if let Some(f) = &report.festival {
        std::fs::write(out.join("festival-ready.svg"), f.ready_svg())?;
    }
    std::fs::write(out.join("report.md"), report.markdown())?;
    std::fs::write(out.join("report.json"), serde_json::to_string_pretty(&report).map_err(std::io::Error::other)?)?;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn civil_dates() {
        assert_eq!(civil_from_days(0), (1970, 1, 1));
        assert_eq!(civil_from_days(20_418), (2025, 11, 26));
    }
}
