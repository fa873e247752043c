//! The accuracy round's bench section (issue 13, remaining items): anti-
//! aliasing cost and error before/after the surface bins, a moved light's
//! time to its converged picture, and the indirect term's error. Run alone
//! with `footlight bench --accuracy-only` (printed as Markdown).

use super::sweeps;
use crate::render::gbuffer::GBuffer;
use crate::render::{Display, RecursionLimits};
use crate::scene::{Camera, Scene};
use crate::{Light, Patch};
use glam::Vec3;
use serde::Serialize;

/// A part of the section (`--accuracy-part`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Part {
    /// Anti-aliasing cost and error.
    Aa,
    /// A moved light's time to the converged picture.
    Converge,
    /// The indirect term's error.
    Indirect,
    /// Where a moved light's time goes, stage by stage (also run by `converge`).
    Profile,
}

/// Everything the section measured (empty where a part was not run).
#[derive(Clone, Debug, Serialize)]
pub struct AccuracyReport {
    /// Picture size.
    pub size: (u32, u32),
    /// AA cost and error per sampling variant.
    pub aa: Vec<sweeps::AaCostRow>,
    /// The whole picture's error (direct + indirect) with and without bins.
    pub picture: Vec<sweeps::AaPictureRow>,
    /// Interleaved rounds behind each AA time ([`sweeps::aa_rounds`]).
    pub aa_rounds: usize,
    /// Per camera, outside the cost (the paper's intersection buffer,
    /// section 3.4): the G-buffer's build (9 primary rays per pixel, the
    /// bins and the highlight bounds), ms, median of 3; `None` when the
    /// AA part was not run.
    pub gbuffer_ms: Option<f64>,
    /// Of it, finding the highlight bounds again alone, ms (median of 3),
    /// and how many pixels hold one.
    pub highlight_bounds: Option<(f64, usize)>,
    /// A moved light's published pictures over time, with their error.
    pub converge: Vec<ConvergeRow>,
    /// Passes behind the converged reference.
    pub reference_passes: u32,
    /// Where the moved light's time goes, stage by stage.
    pub profile: Option<ConvergeProfile>,
    /// Indirect error at the paper's settings: Lambert box, box with a
    /// tessellated sphere, bundled stage made all-Lambert.
    pub indirect: Vec<super::indirect::IndirectRow>,
}

/// One published picture of a moved light (issue 13: moved-light convergence).
#[derive(Clone, Debug, Serialize)]
pub struct ConvergeRow {
    /// The build stage.
    pub stage: String,
    /// Time from the pan/tilt change to this picture, ms.
    pub ms: f64,
    /// Display-space MSE (R, G, B) of the light at full against the converged reference.
    pub mse: [f64; 3],
}

/// How a moved light's build is run in [`converge`].
#[derive(Clone, Copy, Debug)]
pub struct Pipeline {
    /// Row label prefix.
    pub label: &'static str,
    /// Coarse first indirect estimate every this many pixels (0: exact).
    pub coarse: u32,
    /// SPPM starts from the coarse estimate (no exact fill).
    pub from_coarse: bool,
    /// Photons emitted per SPPM pass (0: as many as stored).
    pub pass_emitted: usize,
    /// SPPM passes.
    pub passes: u32,
}

impl Pipeline {
    /// Round 3's moved light: exact photon-map estimate, 16 passes.
    pub fn before() -> Self {
        Self { label: "before", coarse: 0, from_coarse: false, pass_emitted: 0, passes: 16 }
    }

    /// The live tracer's moved light today ([`crate::live::tracer::TracerSettings`]
    /// and [`BuildSettings`] defaults).
    pub fn shipped() -> Self {
        let t = crate::live::tracer::TracerSettings::default();
        let b = crate::render::build::BuildSettings::default();
        Self {
            label: "after",
            coarse: t.coarse_indirect,
            from_coarse: t.refine_from_coarse,
            pass_emitted: b.photons.map_or(0, |p| p.pass_emitted),
            passes: b.refine_passes,
        }
    }
}

/// A moved light at the paper's settings on the bench's thread pool: the
/// view stays (the camera did not move), the light's build runs stage by
/// stage as the daemon's tracer runs it (direct, Whitted + AA, photon map,
/// blended SPPM passes), each picture timed from the change and compared
/// with a converged reference: the same light built with another photon
/// seed and refined for `reference_passes` passes. Every pipeline in
/// `pipelines` is run in turn; `every_pass` lists every pass (else powers
/// of two and the last).
pub fn converge(
    scene: &Scene,
    light: &Light,
    k_full: Vec3,
    camera: Camera,
    size: (u32, u32),
    reference_passes: u32,
    pipelines: &[Pipeline],
) -> Vec<ConvergeRow> {
    use crate::render::build::{BuildSettings, Cancel, LightBuild, NextStage, Stage};
    use crate::render::footprint::DirectQuality;
    use crate::render::{Sampling, View};
    use std::time::Instant;
    let display = Display::default();
    let view = View::build(scene, camera, size.0, size.1, Sampling::Adaptive, RecursionLimits::default());
    let reference = {
        let settings = BuildSettings { refine_passes: reference_passes, ..BuildSettings::default() };
        let mut b = LightBuild::new(light.clone(), 7, settings, Cancel::never());
        let last = b.run_to_end(scene, &view).ok().flatten().map(|x| x.to_dense());
        last.unwrap_or_default().iter().map(|v| *v * k_full).collect::<Vec<Vec3>>()
    };
    let err = |dense: Vec<Vec3>| {
        let shown: Vec<Vec3> = dense.iter().map(|v| *v * k_full).collect();
        super::mse_display(&shown, &reference, &display)
    };
    let mut rows = Vec::new();
    for p in pipelines {
        let photons = BuildSettings::default()
            .photons
            .map(|s| crate::render::photon::PhotonSettings { pass_emitted: p.pass_emitted, ..s });
        let settings = BuildSettings { refine_passes: p.passes, photons, ..BuildSettings::default() };
        let row =
            |stage: String, ms: f64, mse: [f64; 3]| ConvergeRow { stage: format!("{}: {stage}", p.label), ms, mse };
        let t0 = Instant::now();
        let ms = || t0.elapsed().as_secs_f64() * 1e3;
        let mut b = LightBuild::new(light.clone(), 0, settings, Cancel::never())
            .with_coarse_indirect(p.coarse)
            .with_refinement_from_coarse(p.from_coarse)
            .with_direct_first(DirectQuality::Full);
        let mut stage = b.next_stage();
        while let Ok(Some(step)) = b.next(scene, &view) {
            let t = ms();
            let what = match stage {
                Some(NextStage::Direct(_)) => "direct (seen directly)".into(),
                Some(NextStage::Whitted) => "Whitted + AA".into(),
                Some(NextStage::Photons) if p.coarse > 1 => "photon map, coarse".into(),
                Some(NextStage::Photons) => "photon map".into(),
                _ => {
                    let done = if let Stage::Refining(n) = step.stage { n } else { p.passes };
                    format!("SPPM pass {done} (blended)")
                }
            };
            rows.push(row(what, t, err(step.buffer.to_dense())));
            stage = b.next_stage();
        }
    }
    rows
}

/// Mean of the three channels' MSE.
fn mean_mse(m: &[f64; 3]) -> f64 {
    m.iter().sum::<f64>() / 3.0
}

/// The convergence criterion (docs/rendering.md): a picture of a moved
/// light is converged once its display MSE against the reference (mean of
/// R, G, B) is at most this factor times what round 3's refinement reached
/// after its 16 passes (the `before` pipeline's last pass, same run).
pub const CONVERGED_FACTOR: f64 = 1.05;

/// Time of the first row with `prefix` whose error meets `bound`, and that
/// row's stage.
pub fn converged_at(rows: &[ConvergeRow], prefix: &str, bound: f64) -> Option<(f64, String)> {
    rows.iter()
        .filter(|r| r.stage.starts_with(prefix))
        .find(|r| mean_mse(&r.mse) <= bound)
        .map(|r| (r.ms, r.stage.clone()))
}

/// Where a moved light's time goes, stage by stage (issue 13: profile
/// before speeding up): the photon stage's trace, k-d trees, irradiance
/// cache and per-vertex lookups, then every SPPM pass's trace, tree,
/// gather and blend. Measured with the same functions the build calls, with
/// a clock between them.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ConvergeProfile {
    /// Shading vertices of the view (the gather points).
    pub vertices: usize,
    /// Of them, diffuse ones (those with an indirect term).
    pub diffuse: usize,
    /// Global + caustic photons stored.
    pub stored: usize,
    /// Diffuse vertices whose 4 nearest cache points do not fit.
    pub narrow_misses: usize,
    /// Of them, those the 16 nearest cache points do not fit either (kNN gather).
    pub wide_misses: usize,
    /// Of those, the ones whose kNN gather reads exactly zero.
    pub zero_gathers: usize,
    /// Stage name and ms, in order.
    pub stages: Vec<(String, f64)>,
    /// Per pass: its stages and the blend + render of its picture, ms.
    pub passes: Vec<(crate::render::photon::PassTimes, f64)>,
    /// Photons emitted per pass and the mean stages of 3 such passes.
    pub pass_sizes: Vec<(usize, crate::render::photon::PassTimes)>,
}

/// Profiles a moved light's stages at `size` (see [`ConvergeProfile`]).
pub fn converge_profile(
    scene: &Scene,
    light: &Light,
    camera: Camera,
    size: (u32, u32),
    passes: u32,
    coarse_step: u32,
) -> ConvergeProfile {
    use crate::render::build::light_seed;
    use crate::render::photon::{PhotonSettings, Progressive, WIDE_LOOKUP, trace_photons};
    use crate::render::{AaParams, Sampling, View};
    use rayon::prelude::*;
    use std::time::Instant;
    let ms = |t: Instant| t.elapsed().as_secs_f64() * 1e3;
    let view = View::build(scene, camera, size.0, size.1, Sampling::Adaptive, RecursionLimits::default());
    let mut p = ConvergeProfile { vertices: view.shading.vertex_count(), ..ConvergeProfile::default() };
    let diffuse: Vec<_> = view
        .shading
        .vertices()
        .iter()
        .filter(|v| scene.materials[v.material as usize].diffuse.max_element() > 0.0)
        .collect();
    p.diffuse = diffuse.len();
    let t = Instant::now();
    let _ = view.render_direct(scene, light, Some(AaParams::new(20.0)));
    p.stages.push(("Whitted + AA".into(), ms(t)));
    let settings = PhotonSettings::default();
    let maps = trace_photons(scene, light, &PhotonSettings { seed: light_seed(settings.seed, 0), ..settings });
    p.stored = maps.global.len() + maps.caustic.len();
    p.stages.push(("photon trace".into(), maps.times.trace_ms));
    p.stages.push(("photon k-d trees".into(), maps.times.tree_ms));
    p.stages.push(("irradiance cache".into(), maps.times.cache_ms));
    let t = Instant::now();
    let _: Vec<Vec3> = diffuse.par_iter().map(|v| maps.irradiance_narrow(v.position, v.normal)).collect();
    p.stages.push(("before: per-vertex lookups, exact (4 cache points, else kNN)".into(), ms(t)));
    let t = Instant::now();
    let exact = view.vertex_irradiance(scene, &maps);
    p.stages.push(("per-vertex lookups, exact".into(), ms(t)));
    let miss: Vec<_> = diffuse.iter().filter(|v| maps.irradiance.lookup(v.position, v.normal).is_none()).collect();
    p.narrow_misses = miss.len();
    let wide: Vec<_> =
        miss.iter().filter(|v| maps.irradiance.lookup_among(v.position, v.normal, WIDE_LOOKUP).is_none()).collect();
    p.wide_misses = wide.len();
    p.zero_gathers = wide.iter().filter(|v| maps.direct_estimate(v.position, v.normal) == Vec3::ZERO).count();
    let t = Instant::now();
    if let Some((mut e, known)) = view.coarse_vertex_irradiance_until(scene, &maps, coarse_step, &|| false) {
        p.stages.push((format!("per-vertex lookups, coarse (every {coarse_step}th pixel)"), ms(t)));
        let t = Instant::now();
        let _ = view.fill_vertex_irradiance_until(scene, &maps, &mut e, &known, &|| false);
        p.stages.push(("finishing the coarse lookups".into(), ms(t)));
    }
    let t = Instant::now();
    let _ = view.render_vertex_irradiance(scene, &exact);
    p.stages.push(("shading the per-vertex irradiance".into(), ms(t)));
    let t = Instant::now();
    let mut sppm = Progressive::new(scene, &view, &maps).starting_from(exact.clone(), maps.settings.estimate as f32);
    p.stages.push(("SPPM set-up (initial radii)".into(), ms(t)));
    for _ in 0..passes {
        sppm.pass(scene, &view, light);
        let t = Instant::now();
        let _ = view.render_progressive(scene, &sppm);
        p.passes.push((sppm.last_times(), ms(t)));
    }
    // Pass size: from the same start, 3 passes emitting 1, 2 and 4 times as
    // many photons as stored.
    for factor in [1, 2, 4] {
        let emitted = maps.settings.stored * factor;
        let mut sppm = Progressive::new(scene, &view, &maps)
            .starting_from(exact.clone(), maps.settings.estimate as f32)
            .with_pass_emitted(emitted);
        let mut sum = crate::render::photon::PassTimes::default();
        for _ in 0..3 {
            sppm.pass(scene, &view, light);
            let l = sppm.last_times();
            sum.trace_ms += l.trace_ms / 3.0;
            sum.tree_ms += l.tree_ms / 3.0;
            sum.gather_ms += l.gather_ms / 3.0;
            sum.photons += l.photons / 3;
        }
        p.pass_sizes.push((emitted, sum));
    }
    p
}

impl ConvergeProfile {
    /// The profile as Markdown.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "\n### Where a moved light's time goes\n\n{} shading vertices ({} diffuse); {} photons stored. \
             Cache lookups: {} diffuse vertices miss the 4 nearest cache points, {} of them the 16 nearest too \
             (a kNN gather each), {} of which read zero.\n\n| stage | ms |\n|---|---:|\n",
            self.vertices, self.diffuse, self.stored, self.narrow_misses, self.wide_misses, self.zero_gathers
        );
        for (stage, ms) in &self.stages {
            s += &format!("| {stage} | {ms:.1} |\n");
        }
        if !self.passes.is_empty() {
            let n = self.passes.len() as f64;
            let mean = |f: &dyn Fn(&(crate::render::photon::PassTimes, f64)) -> f64| {
                self.passes.iter().map(f).sum::<f64>() / n
            };
            s += &format!(
                "| SPPM pass (mean of {}): photon trace | {:.1} |\n| SPPM pass: k-d tree ({:.0} photons) | {:.1} |\n\
                 | SPPM pass: gather at every vertex | {:.1} |\n| SPPM pass: blend + shade | {:.1} |\n",
                self.passes.len(),
                mean(&|p| p.0.trace_ms),
                mean(&|p| p.0.photons as f64),
                mean(&|p| p.0.tree_ms),
                mean(&|p| p.0.gather_ms),
                mean(&|p| p.1),
            );
        }
        if !self.pass_sizes.is_empty() {
            s += "\n| photons emitted per pass | stored | trace ms | tree ms | gather ms | ms per 1000 stored |\n\
                  |---:|---:|---:|---:|---:|---:|\n";
            for (emitted, t) in &self.pass_sizes {
                let total = t.trace_ms + t.tree_ms + t.gather_ms;
                s += &format!(
                    "| {emitted} | {} | {:.1} | {:.1} | {:.1} | {:.2} |\n",
                    t.photons,
                    t.trace_ms,
                    t.tree_ms,
                    t.gather_ms,
                    total * 1000.0 / t.photons.max(1) as f64
                );
            }
        }
        s
    }
}

/// Runs the section for the patch's first fixture at `size`.
pub fn run(
    scene: &Scene,
    scene_path: &std::path::Path,
    patch: &Patch,
    camera: Camera,
    size: (u32, u32),
    repeats: usize,
    parts: &[Part],
) -> std::io::Result<AccuracyReport> {
    let wants = |p: Part| parts.is_empty() || parts.contains(&p);
    let fixture =
        patch.fixtures.first().ok_or_else(|| std::io::Error::other("the patch has no fixtures to benchmark"))?;
    let light: &Light = &fixture.light;
    let k_full: Vec3 = fixture.k_full();
    let display = Display::default();
    let limits = RecursionLimits::default();
    let threshold = crate::render::RenderSettings::default().build.aa_threshold;
    let gbuffer = GBuffer::build(scene, camera, size.0, size.1);
    let (mut aa, mut picture) = (Vec::new(), Vec::new());
    let (mut gbuffer_ms, mut highlight_bounds) = (None, None);
    if wants(Part::Aa) {
        gbuffer_ms = Some(super::time_ms(3, || GBuffer::build(scene, camera, size.0, size.1)).0);
        let (ms, n) = super::time_ms(3, || gbuffer.find_highlight_bounds(scene));
        highlight_bounds = Some((ms, n));
        aa = sweeps::aa_cost(scene, &gbuffer, light, k_full, &display, limits, threshold, repeats);
        picture = sweeps::aa_picture(scene, &gbuffer, light, k_full, &display, limits, threshold);
    }
    let reference_passes = if size.0 < 400 { 16 } else { 48 };
    let profile = (wants(Part::Converge) || parts.contains(&Part::Profile)).then(|| {
        let step = crate::live::tracer::TracerSettings::default().coarse_indirect;
        converge_profile(scene, light, camera, size, 16, step)
    });
    let converge = if wants(Part::Converge) {
        let shipped = Pipeline::shipped();
        let stored = crate::render::photon::PhotonSettings::default().stored;
        // Half as many passes of twice the photons: the same photon budget.
        let bigger = Pipeline {
            label: "variant, 2× photons per pass",
            pass_emitted: 2 * shipped.pass_emitted.max(stored),
            passes: shipped.passes / 2,
            ..shipped
        };
        converge(scene, light, k_full, camera, size, reference_passes, &[Pipeline::before(), shipped, bigger])
    } else {
        Vec::new()
    };
    let indirect =
        if wants(Part::Indirect) { indirect_rows(scene_path, light, camera, size.0 < 400)? } else { Vec::new() };
    Ok(AccuracyReport {
        size,
        aa,
        picture,
        aa_rounds: sweeps::aa_rounds(repeats),
        gbuffer_ms,
        highlight_bounds,
        converge,
        reference_passes,
        profile,
        indirect,
    })
}

/// The indirect term's error at the paper's settings (CI-sized with `quick`).
fn indirect_rows(
    scene_path: &std::path::Path,
    light: &Light,
    camera: Camera,
    quick: bool,
) -> std::io::Result<Vec<super::indirect::IndirectRow>> {
    use super::indirect::{all_lambert, lambert_box, lambert_box_with_sphere, measure};
    use crate::render::photon::PhotonSettings;
    let (photons, size, samples) = if quick {
        (PhotonSettings { stored: 5000, estimate: 50, ..PhotonSettings::default() }, (32, 20), 32)
    } else {
        (PhotonSettings::default(), (80, 50), 256)
    };
    let mut rows = Vec::new();
    let (s, l, c) = lambert_box();
    rows.extend(measure("Lambert box", &s, &l, c, size, photons, samples));
    let (s, l, c) = lambert_box_with_sphere();
    rows.extend(measure("Lambert box + tessellated sphere", &s, &l, c, size, photons, samples));
    let stage =
        crate::scene::load(scene_path).map_err(|e| std::io::Error::other(format!("{}: {e}", scene_path.display())))?;
    rows.extend(measure("bundled stage, all Lambert", &all_lambert(stage), light, camera, size, photons, samples));
    Ok(rows)
}

impl AccuracyReport {
    /// The report as Markdown.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "## Accuracy round (issue 13): anti-aliasing cost and error\n\n{}×{}, first patch light, depth 5. \
             Cost = expansion + shading (+ re-shading) / 1-sample expansion + shading, the fastest of {} interleaved \
             rounds (and, round by round, over the same round's 1-sample time: the median and quartiles show \
             how far the load of the machine moves one run's figure); error = display-space MSE against 81 \
             samples per pixel (9-sample renderer at 3× size, box-filtered).\n\n",
            self.size.0, self.size.1, self.aa_rounds
        );
        s += &sweeps::aa_cost_markdown(&self.aa);
        if let (Some(g), Some((b, n))) = (self.gbuffer_ms, self.highlight_bounds) {
            s += &format!(
                "\nPer camera, outside the cost (the paper's intersection buffer, section 3.4; every light on the \
                 view shares it): the G-buffer, 9 primary rays per pixel with the surface bins and the highlight \
                 bounds, {g:.1} ms; of it the highlight bounds of the {n} pixels that see a sharp specular surface \
                 {b:.1} ms.\n"
            );
        }
        if !self.picture.is_empty() {
            s += "\nThe whole picture of the light (direct + indirect, the same photon maps, paper's settings) against \
                  81 samples per pixel: the indirect term is evaluated on the base sample set, so without bins its \
                  geometry edges stay aliased.\n\n";
            s += &sweeps::aa_picture_markdown(&self.picture);
        }
        s += &format!(
            "\n## Moved light: time to the converged picture (issue 13)\n\n{}×{}, paper's settings (50,000 photons, 150 \
             in the estimate, depth 5), the bench's thread pool; the view is kept (only the light moved). Error: display \
             MSE of the light at full against the same light with another photon seed refined for {} passes.\n\n\
             | picture | ms after the change | MSE R | G | B |\n|---|---:|---:|---:|---:|\n",
            self.size.0, self.size.1, self.reference_passes
        );
        let before_last = self.converge.iter().rev().find(|r| r.stage.starts_with("before: SPPM"));
        for r in &self.converge {
            let show = !r.stage.starts_with("before: SPPM pass")
                || r.stage.contains("pass 1 ")
                || r.stage.contains("pass 2 ")
                || r.stage.contains("pass 4 ")
                || r.stage.contains("pass 8 ")
                || std::ptr::eq(r, before_last.unwrap_or(r));
            if show {
                s += &format!(
                    "| {} | {:.0} | {:.2e} | {:.2e} | {:.2e} |\n",
                    r.stage, r.ms, r.mse[0], r.mse[1], r.mse[2]
                );
            }
        }
        if let Some(last) = before_last {
            let bound = CONVERGED_FACTOR * mean_mse(&last.mse);
            let at = |prefix: &str| {
                converged_at(&self.converge, prefix, bound)
                    .map_or("not reached".to_string(), |(ms, stage)| format!("**{ms:.0} ms** ({stage})"))
            };
            s += &format!(
                "\nConverged (docs/rendering.md): mean display MSE ≤ {CONVERGED_FACTOR} × that of round 3's 16th pass \
                 ({:.3e}) = {bound:.3e}. Before: {}; after: {}.\n",
                mean_mse(&last.mse),
                at("before: "),
                at("after: ")
            );
        }
        if let Some(p) = &self.profile {
            s += &p.markdown();
        }
        s += "\n## Indirect term at the paper's settings vs path tracing (issue 13)\n\n\
              The bundled stage is measured with every material made Lambert ([`indirect::all_lambert`]) in both the \
              photon maps and the reference: the path tracer cannot see the light through glass or in a mirror.\n\n";
        s += &super::indirect::markdown(&self.indirect);
        s
    }
}
