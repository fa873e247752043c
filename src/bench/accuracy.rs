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

/// Everything the section measured.
#[derive(Clone, Debug, Serialize)]
pub struct AccuracyReport {
    /// Picture size.
    pub size: (u32, u32),
    /// AA cost and error per sampling variant.
    pub aa: Vec<sweeps::AaCostRow>,
    /// Where the adaptive cost goes, before (triangle-ID bins).
    pub breakdown_before: sweeps::AaBreakdown,
    /// Where the adaptive cost goes, after (surface bins).
    pub breakdown_after: sweeps::AaBreakdown,
}

/// Runs the section for the patch's first fixture at `size`.
pub fn run(scene: &Scene, patch: &Patch, camera: Camera, size: (u32, u32), repeats: usize) -> std::io::Result<AccuracyReport> {
    let fixture =
        patch.fixtures.first().ok_or_else(|| std::io::Error::other("the patch has no fixtures to benchmark"))?;
    let light: &Light = &fixture.light;
    let k_full: Vec3 = fixture.k_full();
    let display = Display::default();
    let limits = RecursionLimits::default();
    let threshold = crate::render::RenderSettings::default().aa_threshold;
    let gbuffer = GBuffer::build(scene, camera, size.0, size.1);
    let aa = sweeps::aa_cost(scene, &gbuffer, light, k_full, &display, limits, threshold, repeats);
    let bd = |set| sweeps::aa_breakdown_with_set(scene, &gbuffer, light, limits, threshold, repeats, set);
    let breakdown_before = bd(crate::render::SampleSet::TriangleBins);
    let breakdown_after = bd(crate::render::SampleSet::Binned);
    Ok(AccuracyReport { size, aa, breakdown_before, breakdown_after })
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
        for (label, b) in [("before (triangle-ID bins)", &self.breakdown_before), ("after (surface bins)", &self.breakdown_after)] {
            s += &format!(
                "\nWhere the adaptive cost goes, {label} (% of 1-sample expansion + shading = {:.1} ms): expansion {:.0} %, \
                 shading {:.0} %, gradient decision {:.0} %, 9-sample re-shading {:.0} %. Vertices: {} (1 sample) vs {} \
                 (bins); {:.1} % of pixels hold more than one bin, {:.2} % re-shaded.\n",
                b.one_sample_ms,
                b.expand_percent,
                b.shade_percent,
                b.decide_percent,
                b.reshade_percent,
                b.one_sample_vertices,
                b.base_vertices,
                b.multi_bin_share * 100.0,
                b.reshaded_share * 100.0
            );
        }
        s
    }
}
