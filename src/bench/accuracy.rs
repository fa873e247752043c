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
}

/// Everything the section measured (empty where a part was not run).
#[derive(Clone, Debug, Serialize)]
pub struct AccuracyReport {
    /// Picture size.
    pub size: (u32, u32),
    /// AA cost and error per sampling variant.
    pub aa: Vec<sweeps::AaCostRow>,
    /// Where the adaptive cost goes, before and after.
    pub breakdowns: Vec<(String, sweeps::AaBreakdown)>,
    /// A moved light's published pictures over time, with their error.
    pub converge: Vec<ConvergeRow>,
    /// Passes behind the converged reference.
    pub reference_passes: u32,
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

/// A moved light at the paper's settings on the bench's thread pool: the
/// view stays (the camera did not move), the light's build runs stage by
/// stage as the daemon's tracer runs it (direct, Whitted + AA, photon map,
/// 16 blended SPPM passes), each picture timed from the change and compared
/// with a converged reference: the same light built with another photon
/// seed and refined for `reference_passes` passes.
pub fn converge(
    scene: &Scene,
    light: &Light,
    k_full: Vec3,
    camera: Camera,
    size: (u32, u32),
    reference_passes: u32,
) -> Vec<ConvergeRow> {
    use crate::render::build::{BuildSettings, Cancel, LightBuild};
    use crate::render::footprint::DirectQuality;
    use crate::render::{Sampling, View};
    use std::time::Instant;
    let display = Display::default();
    let view = View::build(scene, camera, size.0, size.1, Sampling::Adaptive, RecursionLimits::default());
    let settings = BuildSettings { refine_passes: 16, ..BuildSettings::default() };
    let reference = {
        let mut b = LightBuild::new(
            light.clone(),
            7,
            BuildSettings { refine_passes: reference_passes, ..settings },
            Cancel::never(),
        );
        let mut last = b.photons(scene, &view).ok().map(|x| x.to_dense());
        if let Some(mut r) = b.into_refinement(scene, &view) {
            while !r.finished() {
                match r.pass(scene, &view) {
                    Ok(buf) => last = Some(buf.to_dense()),
                    Err(_) => break,
                }
            }
        }
        last.unwrap_or_default().iter().map(|v| *v * k_full).collect::<Vec<Vec3>>()
    };
    let err = |dense: Vec<Vec3>| {
        let shown: Vec<Vec3> = dense.iter().map(|v| *v * k_full).collect();
        super::mse_display(&shown, &reference, &display)
    };
    let mut rows = Vec::new();
    let t0 = Instant::now();
    let ms = || t0.elapsed().as_secs_f64() * 1e3;
    let mut b = LightBuild::new(light.clone(), 0, settings, Cancel::never());
    if let Ok((buf, _)) = b.direct(scene, &view, DirectQuality::Full) {
        let t = ms();
        rows.push(ConvergeRow { stage: "direct (seen directly)".into(), ms: t, mse: err(buf.to_dense()) });
    }
    if let Ok(buf) = b.whitted(scene, &view) {
        let t = ms();
        rows.push(ConvergeRow { stage: "Whitted + AA".into(), ms: t, mse: err(buf.to_dense()) });
    }
    if let Ok(buf) = b.photons(scene, &view) {
        let t = ms();
        rows.push(ConvergeRow { stage: "photon map (paper's settings)".into(), ms: t, mse: err(buf.to_dense()) });
    }
    if let Some(mut r) = b.into_refinement(scene, &view) {
        while !r.finished() {
            let Ok(buf) = r.pass(scene, &view) else { break };
            let t = ms();
            let done = r.done();
            if done.is_power_of_two() {
                rows.push(ConvergeRow {
                    stage: format!("SPPM pass {done} (blended)"),
                    ms: t,
                    mse: err(buf.to_dense()),
                });
            }
        }
    }
    rows
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
    let threshold = crate::render::RenderSettings::default().aa_threshold;
    let gbuffer = GBuffer::build(scene, camera, size.0, size.1);
    let (mut aa, mut breakdowns) = (Vec::new(), Vec::new());
    if wants(Part::Aa) {
        aa = sweeps::aa_cost(scene, &gbuffer, light, k_full, &display, limits, threshold, repeats);
        let bd = |set| sweeps::aa_breakdown_with_set(scene, &gbuffer, light, limits, threshold, repeats, set);
        breakdowns.push((
            "before (triangle-ID bins, whole-path re-shading)".to_string(),
            bd(crate::render::SampleSet::TriangleBins),
        ));
        breakdowns.push(("after (surface bins)".to_string(), bd(crate::render::SampleSet::Binned)));
    }
    let reference_passes = if size.0 < 400 { 16 } else { 48 };
    let converge =
        if wants(Part::Converge) { converge(scene, light, k_full, camera, size, reference_passes) } else { Vec::new() };
    let indirect =
        if wants(Part::Indirect) { indirect_rows(scene_path, light, camera, size.0 < 400)? } else { Vec::new() };
    Ok(AccuracyReport { size, aa, breakdowns, converge, reference_passes, indirect })
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
             Cost = expansion + shading (+ re-shading) / 1-sample expansion + shading; error = display-space MSE \
             against 81 samples per pixel (9-sample renderer at 3× size, box-filtered).\n\n",
            self.size.0, self.size.1
        );
        s += &sweeps::aa_cost_markdown(&self.aa);
        for (label, b) in &self.breakdowns {
            s += &b.sentence(label);
        }
        s += &format!(
            "\n## Moved light: time to the converged picture (issue 13)\n\n{}×{}, paper's settings (50,000 photons, 150 \
             in the estimate, depth 5), the bench's thread pool; the view is kept (only the light moved). Error: display \
             MSE of the light at full against the same light with another photon seed refined for {} passes.\n\n\
             | picture | ms after the change | MSE R | G | B |\n|---|---:|---:|---:|---:|\n",
            self.size.0, self.size.1, self.reference_passes
        );
        for r in &self.converge {
            s += &format!("| {} | {:.0} | {:.2e} | {:.2e} | {:.2e} |\n", r.stage, r.ms, r.mse[0], r.mse[1], r.mse[2]);
        }
        s += "\n## Indirect term at the paper's settings vs path tracing (issue 13)\n\n\
              The bundled stage is measured with every material made Lambert ([`indirect::all_lambert`]) in both the \
              photon maps and the reference: the path tracer cannot see the light through glass or in a mirror.\n\n";
        s += &super::indirect::markdown(&self.indirect);
        s
    }
}
