//! Run time against error (issue 8): sweeps of the anti-aliasing threshold
//! and the recursion depth, the "skip what the scene does not need"
//! measurements, and the paper's section 4.1 accuracy over ten renders.

use super::{CurvePoint, Ratio, mse_display, time_ms};
use crate::Light;
use crate::render::buffer::LightBuffer;
use crate::render::composite::composite_into;
use crate::render::gbuffer::GBuffer;
use crate::render::photon::{PhotonSettings, trace_photons};
use crate::render::view::AaMarking;
use crate::render::{AaParams, Display, RecursionLimits, Sampling, View};
use crate::scene::Scene;
use glam::Vec3;
use serde::Serialize;

/// A run-time-versus-error curve over one setting.
#[derive(Clone, Debug, Serialize)]
pub struct Curve {
    /// What is swept.
    pub name: String,
    /// Unit/label of the setting.
    pub setting: String,
    /// The paper's operating point on this axis.
    pub paper_setting: f64,
    /// Measured points.
    pub points: Vec<CurvePoint>,
    /// Settings that dominate the paper's point: no slower and no less accurate.
    pub dominating: Vec<f64>,
}

impl Curve {
    /// Builds a curve and finds the points dominating the paper's one.
    pub fn new(name: &str, setting: &str, paper_setting: f64, points: Vec<CurvePoint>) -> Self {
        let total = |p: &CurvePoint| p.mse.iter().sum::<f64>();
        let paper = points.iter().find(|p| p.setting == paper_setting).cloned();
        let dominating = match &paper {
            Some(pp) => points
                .iter()
                .filter(|p| p.setting != paper_setting && p.ms <= pp.ms && total(p) <= total(pp))
                .map(|p| p.setting)
                .collect(),
            None => Vec::new(),
        };
        Self { name: name.into(), setting: setting.into(), paper_setting, points, dominating }
    }
}

/// k_full-scaled copy of a unit buffer, for display-space errors.
fn shown(dense: &[Vec3], k: Vec3) -> Vec<Vec3> {
    dense.iter().map(|v| *v * k).collect()
}

/// Shading time and error against 9× oversampling over the AA threshold.
pub fn aa_threshold_curve(
    scene: &Scene,
    gbuffer: &GBuffer,
    light: &Light,
    k_full: Vec3,
    display: &Display,
    limits: RecursionLimits,
    repeats: usize,
) -> Curve {
    let nine = View::from_gbuffer(scene, gbuffer.clone(), Sampling::Nine, limits);
    let reference = shown(&nine.render_direct(scene, light, None).0, k_full);
    let mut points = Vec::new();
    for threshold in [5.0f32, 10.0, 15.0, 20.0, 25.0, 40.0, 80.0, 256.0] {
        let aa = AaParams::new(threshold);
        // Each run on a fresh copy of the view: the 9-sample cache starts cold.
        let (ms, (dense, _)) = super::time_ms_with(
            repeats,
            || View::from_gbuffer(scene, gbuffer.clone(), Sampling::Adaptive, limits),
            |v| v.render_direct(scene, light, Some(aa)),
        );
        points.push(CurvePoint {
            setting: threshold as f64,
            ms,
            mse: mse_display(&shown(&dense, k_full), &reference, display),
        });
    }
    Curve::new("anti-aliasing threshold (direct light)", "threshold (0-255; 256 = geometry AA only)", 20.0, points)
}

/// Expansion + shading time and error against depth 8 over the recursion depth.
pub fn depth_curve(
    scene: &Scene,
    gbuffer: &GBuffer,
    light: &Light,
    k_full: Vec3,
    display: &Display,
    repeats: usize,
) -> Curve {
    let aa = AaParams::new(20.0);
    let limits = |d: u32| RecursionLimits { max_depth: d, ..RecursionLimits::default() };
    let deep = View::from_gbuffer(scene, gbuffer.clone(), Sampling::Adaptive, limits(8));
    let reference = shown(&deep.render_direct(scene, light, Some(aa)).0, k_full);
    let mut points = Vec::new();
    for depth in 0..=6u32 {
        let (ms, (dense, _)) = super::time_ms_with(
            repeats,
            || gbuffer.clone(),
            |g| View::from_gbuffer(scene, g, Sampling::Adaptive, limits(depth)).render_direct(scene, light, Some(aa)),
        );
        points.push(CurvePoint {
            setting: depth as f64,
            ms,
            mse: mse_display(&shown(&dense, k_full), &reference, display),
        });
    }
    Curve::new("recursion depth (direct light, mirrors and glass)", "depth", 5.0, points)
}

/// Time saved by skipping work a scene does not need, as same-run ratios.
#[allow(clippy::too_many_arguments)]
pub fn skips(
    scene: &Scene,
    plain: &Scene,
    gbuffer: &GBuffer,
    lights: &[Light],
    aa: AaParams,
    k_full: Vec3,
    limits: RecursionLimits,
    repeats: usize,
) -> Vec<Ratio> {
    let (w, h) = (gbuffer.width, gbuffer.height);
    let view = View::from_gbuffer(scene, gbuffer.clone(), Sampling::Adaptive, limits);
    let buffers: Vec<LightBuffer> = lights.iter().map(|l| view.render_light(scene, l, Some(aa)).0).collect();
    let refs: Vec<&LightBuffer> = buffers.iter().collect();
    let mut frame = vec![Vec3::ZERO; (w * h) as usize];
    let reps = repeats.max(1) * 10;
    let mut out = Vec::new();

    // Dark lights: half the rig at dimmer 0 (skipped) vs the same lights at a
    // vanishing but non-zero level (composited).
    let k_dark: Vec<Vec3> = (0..lights.len()).map(|i| if i % 2 == 0 { k_full } else { Vec3::ZERO }).collect();
    let k_dim: Vec<Vec3> = (0..lights.len()).map(|i| if i % 2 == 0 { k_full } else { Vec3::splat(1e-20) }).collect();
    let (t_dark, _) = time_ms(reps, || composite_into(&refs, &k_dark, w, h, &mut frame));
    let (t_dim, _) = time_ms(reps, || composite_into(&refs, &k_dim, w, h, &mut frame));
    out.push(Ratio {
        name: "skip dark lights: composite time without / with skipping".into(),
        ours: t_dim / t_dark,
        paper: None,
        note: format!("{} lights, half at dimmer 0", lights.len()),
    });

    // Sparse tiles vs every tile stored.
    let dense_bufs: Vec<LightBuffer> = buffers
        .iter()
        .map(|b| {
            LightBuffer::from_dense(
                w,
                h,
                &b.to_dense().iter().map(|v| v.max(Vec3::splat(f32::MIN_POSITIVE))).collect::<Vec<_>>(),
            )
        })
        .collect();
    let dense_refs: Vec<&LightBuffer> = dense_bufs.iter().collect();
    let k_all = vec![k_full; lights.len()];
    let (t_sparse, _) = time_ms(reps, || composite_into(&refs, &k_all, w, h, &mut frame));
    let (t_dense, _) = time_ms(reps, || composite_into(&dense_refs, &k_all, w, h, &mut frame));
    let bytes_sparse: usize = buffers.iter().map(LightBuffer::bytes).sum();
    let bytes_dense: usize = dense_bufs.iter().map(LightBuffer::bytes).sum();
    out.push(Ratio {
        name: "sparse tiles: composite time dense / sparse".into(),
        ours: t_dense / t_sparse,
        paper: None,
        note: format!("memory dense / sparse = {:.2}", bytes_dense as f64 / bytes_sparse.max(1) as f64),
    });

    // No specular surfaces: secondary rays skipped entirely.
    let (t_spec, _) = time_ms(repeats, || View::expand_all(scene, gbuffer, Sampling::Adaptive.base_set(), limits));
    let g_plain = GBuffer::build(plain, gbuffer.camera, w, h);
    let (t_plain, _) = time_ms(repeats, || View::expand_all(plain, &g_plain, Sampling::Adaptive.base_set(), limits));
    out.push(Ratio {
        name: "no specular surfaces: camera-path expansion with / without mirrors and glass".into(),
        ours: t_spec / t_plain,
        paper: None,
        note: "same stage with every material made matte".into(),
    });

    // Reused G-buffer and camera paths: moved light re-render vs from scratch.
    let (t_scratch, _) = time_ms(repeats, || {
        View::build(scene, gbuffer.camera, w, h, Sampling::Adaptive, limits).render_light(scene, &lights[0], Some(aa))
    });
    let (t_reuse, _) = time_ms(repeats, || view.render_light(scene, &lights[0], Some(aa)));
    out.push(Ratio {
        name: "reused G-buffer: re-render from scratch / with the cached view".into(),
        ours: t_scratch / t_reuse,
        paper: Some(1.5),
        note: "paper: full re-render / illumination only".into(),
    });
    out
}

/// Section 4.1 of the paper over ten renders: MSE of adaptive AA against
/// 9× oversampling (same photon maps), and the baseline between two 9×
/// renders whose photon maps differ only in the seed.
#[derive(Clone, Debug, Serialize)]
pub struct Accuracy {
    /// Renders averaged.
    pub renders: usize,
    /// Mean MSE (R, G, B) adaptive vs 9×.
    pub adaptive_vs_nine: [f64; 3],
    /// Mean MSE (R, G, B) between two 9× renders with different photon seeds.
    pub nine_seed_baseline: [f64; 3],
}

/// Ten lights, each rendered with photon maps: adaptive and 9× (same maps), and 9× with other maps.
pub fn accuracy(
    scene: &Scene,
    gbuffer: &GBuffer,
    lights: &[Light],
    k_full: Vec3,
    display: &Display,
    limits: RecursionLimits,
    photons: PhotonSettings,
) -> Accuracy {
    let adaptive = View::from_gbuffer(scene, gbuffer.clone(), Sampling::Adaptive, limits);
    let nine = View::from_gbuffer(scene, gbuffer.clone(), Sampling::Nine, limits);
    let aa = AaParams::new(20.0);
    let mut a = [0f64; 3];
    let mut b = [0f64; 3];
    for (i, light) in lights.iter().enumerate() {
        let maps = trace_photons(scene, light, &PhotonSettings { seed: 1000 + i as u64, ..photons });
        let other = trace_photons(scene, light, &PhotonSettings { seed: 5000 + i as u64, ..photons });
        let full = |v: &View, m: &crate::render::photon::PhotonMaps, aa: Option<AaParams>| {
            let (d, _) = v.render_direct(scene, light, aa);
            let ind = v.render_indirect(scene, m);
            d.iter().zip(&ind).map(|(x, y)| (*x + *y) * k_full).collect::<Vec<Vec3>>()
        };
        let img_a = full(&adaptive, &maps, Some(aa));
        let img_n = full(&nine, &maps, None);
        let img_n2 = full(&nine, &other, None);
        let m1 = mse_display(&img_a, &img_n, display);
        let m2 = mse_display(&img_n, &img_n2, display);
        for c in 0..3 {
            a[c] += m1[c] / lights.len() as f64;
            b[c] += m2[c] / lights.len() as f64;
        }
    }
    Accuracy { renders: lights.len(), adaptive_vs_nine: a, nine_seed_baseline: b }
}

/// One anti-aliasing decision rule measured on one light (issue 13.5).
#[derive(Clone, Debug, Serialize)]
pub struct AaRule {
    /// Which rule.
    pub rule: String,
    /// Expansion + shading time with this rule / 1-sample expansion + shading, %.
    pub cost_percent: f64,
    /// Display-space MSE (R, G, B) against 9× oversampling, light at full.
    pub mse_vs_nine: [f64; 3],
    /// Share of pixels re-shaded.
    pub reshaded_share: f64,
}

/// The pixels the pre-issue-13 rule re-shaded: the displayed 0-255 value
/// (k_i at full · exposure · white balance, sRGB) against the threshold,
/// across every neighbour pair. Kept here as the "before" of the bench.
pub fn display_rule_flags(dense: &[Vec3], w: usize, h: usize, display_scale: Vec3, threshold: f32) -> Vec<bool> {
    let shown: Vec<Vec3> = dense
        .iter()
        .map(|&l| Vec3::from_array(crate::render::display::srgb8(l * display_scale).map(f32::from)))
        .collect();
    use crate::render::view::{AaMarking, mark_gradients_with};
    mark_gradients_with(&shown, w, h, threshold, |_, _| true, AaMarking::Dilated)
}

/// Cost and error of the old display-value rule (at the bench light's own
/// k_i and at 0.1× and 10× exposure) and of the light-relative rule.
#[allow(clippy::too_many_arguments)]
pub fn aa_rules(
    scene: &Scene,
    gbuffer: &GBuffer,
    light: &Light,
    k_full: Vec3,
    display: &Display,
    limits: RecursionLimits,
    threshold: f32,
    repeats: usize,
) -> Vec<AaRule> {
    let (w, h) = (gbuffer.width as usize, gbuffer.height as usize);
    let nine = View::from_gbuffer(scene, gbuffer.clone(), Sampling::Nine, limits);
    let reference = shown(&nine.render_direct(scene, light, None).0, k_full);
    let (t_one, _) = super::time_ms_with(
        repeats,
        || gbuffer.clone(),
        |g| View::from_gbuffer(scene, g, Sampling::One, limits).render_direct(scene, light, None),
    );
    let mut out = Vec::new();
    let mut measure = |rule: String, flags: &dyn Fn(&View, &[Vec3]) -> Vec<bool>| {
        let (ms, (dense, n)) = super::time_ms_with(
            repeats,
            || gbuffer.clone(),
            |g| {
                let v = View::from_gbuffer(scene, g, Sampling::Adaptive, limits);
                let (mut dense, _) = v.render_direct(scene, light, None);
                let f = flags(&v, &dense);
                // Every rule of this table re-shades its pixels whole (as
                // the rule before issue 13 did), so the rows differ only in the decision.
                let how = crate::render::view::Reshading {
                    flags: &f,
                    whole: &[],
                    corners_first: None,
                    facing: &[],
                    reconstruct: false,
                    rim: &[],
                    rim_nine: &[],
                    edge: None,
                };
                let n = v.reshade(scene, light, &mut dense, how);
                (dense, n)
            },
        );
        out.push(AaRule {
            rule,
            cost_percent: ms / t_one * 100.0,
            mse_vs_nine: mse_display(&shown(&dense, k_full), &reference, display),
            reshaded_share: n as f64 / (w * h) as f64,
        });
    };
    for (name, factor) in [
        ("before: displayed value, this light at full", 1.0f32),
        ("before: displayed value, exposure ×10", 10.0),
        ("before: displayed value, exposure ×0.1", 0.1),
    ] {
        let scale = k_full * display.scale() * factor;
        measure(name.into(), &|_, dense| display_rule_flags(dense, w, h, scale, threshold));
    }
    measure("after: light-relative gradient, same surface (any exposure)".into(), &|v, dense| {
        v.gradient_flags(scene, dense, AaParams::new(threshold))
    });
    measure("geometry bins only (no re-shading)".into(), &|_, _| vec![false; w * h]);
    out
}

/// Rounds the anti-aliasing timings take for `repeats` (8 × `repeats` + 1),
/// of which the fastest is kept: on the 2-core VM one of the two worker
/// threads loses its core to other work in about a third of the runs
/// (the 1-sample pass then takes ~1.5× as long), and a median of 7 rounds
/// landed in either mode from run to run (1-sample 24-32 ms, ratios ±25
/// points); the fastest is each variant's undisturbed cost. 13 rounds
/// (4 × `repeats` + 1, before 2026-12-01's second session) still moved
/// single rows by up to 10 points from run to run.
pub fn aa_rounds(repeats: usize) -> usize {
    8 * repeats.max(1) + 1
}

/// Anti-aliasing cost and error of one sampling variant (issue 13, accuracy
/// round): expansion + shading time against 1-sample expansion + shading,
/// and display-space MSE against an 81-sample reference.
#[derive(Clone, Debug, Serialize)]
pub struct AaCostRow {
    /// Which variant.
    pub variant: String,
    /// Expansion + shading + re-shading time, ms (fastest of [`aa_rounds`]).
    pub ms: f64,
    /// `ms` / 1-sample expansion + shading, %.
    pub cost_percent: f64,
    /// The same ratio round by round (this variant's time over the 1-sample
    /// time of the same round, %): first quartile, median, third quartile
    /// over the [`aa_rounds`]. The spread is how far one run's
    /// `cost_percent` can move with the load of a shared machine.
    pub per_round_percent: [f64; 3],
    /// Display-space MSE (R, G, B) against the 81-sample reference.
    pub mse_vs_81: [f64; 3],
    /// Share of pixels re-shaded.
    pub reshaded_share: f64,
}

/// First quartile, median and third quartile of `values` (nearest rank,
/// [`crate::live::daemon::percentile`]; NaN for an empty slice).
fn quartiles(values: &[f64]) -> [f64; 3] {
    if values.is_empty() {
        return [f64::NAN; 3];
    }
    [0.25, 0.5, 0.75].map(|q| crate::live::daemon::percentile(values.iter().copied(), q))
}

/// The 81-sample reference of one light's direct buffer: the 9-sample
/// renderer at 3w×3h (a 9×9 sample grid per pixel), box-filtered down.
pub fn reference_81(scene: &Scene, gbuffer: &GBuffer, light: &Light, limits: RecursionLimits) -> Vec<Vec3> {
    let big = view_81(scene, gbuffer, limits);
    box_down_3x(&big.render_direct(scene, light, None).0, gbuffer.width as usize, gbuffer.height as usize)
}

/// The 9-sample view at 3× the size of `gbuffer` (81 samples per pixel
/// once box-filtered down with [`box_down_3x`]).
fn view_81(scene: &Scene, gbuffer: &GBuffer, limits: RecursionLimits) -> View {
    View::build(scene, gbuffer.camera, 3 * gbuffer.width, 3 * gbuffer.height, Sampling::Nine, limits)
}

/// A 3w×3h image box-filtered down to w×h (each pixel the mean of its 3×3).
fn box_down_3x(dense: &[Vec3], w: usize, h: usize) -> Vec<Vec3> {
    let mut out = vec![Vec3::ZERO; w * h];
    for (i, o) in out.iter_mut().enumerate() {
        let (x, y) = (i % w, i / w);
        for j in 0..9 {
            *o += dense[(3 * y + j / 3) * 3 * w + 3 * x + j % 3] / 9.0;
        }
    }
    out
}

/// Cost and error of 1 sample, 9 samples, and the binned and adaptive
/// variants before (one bin per triangle ID) and after (one bin per smooth
/// surface, [`crate::render::gbuffer::surface_bins`]) for `light`.
#[allow(clippy::too_many_arguments)]
pub fn aa_cost(
    scene: &Scene,
    gbuffer: &GBuffer,
    light: &Light,
    k_full: Vec3,
    display: &Display,
    limits: RecursionLimits,
    threshold: f32,
    repeats: usize,
) -> Vec<AaCostRow> {
    use crate::render::SampleSet;
    let (w, h) = (gbuffer.width as usize, gbuffer.height as usize);
    let reference = shown(&reference_81(scene, gbuffer, light, limits), k_full);
    let mut variants: Vec<(String, Sampling, SampleSet, Option<AaParams>)> = vec![
        ("1 sample".into(), Sampling::One, SampleSet::Centre, None),
        ("9 samples everywhere".into(), Sampling::Nine, SampleSet::All, None),
        ("before: triangle-ID bins only".into(), Sampling::Geometry, SampleSet::TriangleBins, None),
        ("surface bins only".into(), Sampling::Geometry, SampleSet::Binned, None),
    ];
    // Without bins: one sample per pixel, every neighbour pair compared
    // (geometry edges too), 9-sample re-shading (the floor of the cost
    // analysis in docs/rendering.md).
    for t in NO_BINS_THRESHOLDS {
        variants.push((
            format!("no bins: 1 sample + 9-sample re-shading of every pair (geometry edges too), pair marks + highlight pixels, threshold {t}"),
            Sampling::Adaptive,
            SampleSet::Centre,
            Some(AaParams::new(t)),
        ));
    }
    // Before the reconstruction (the second session of 2026-12-02's
    // shipped rule): a pair's pixel whose probed corners disagree takes
    // all 9 samples.
    for t in [AA_THRESHOLD_BEFORE, threshold] {
        variants.push((
            format!("before: marks: pair + highlight pixels, corners first, else all 9 samples, threshold {t}"),
            Sampling::Adaptive,
            SampleSet::Binned,
            Some(AaParams { reconstruct: false, ..AaParams::new(t) }),
        ));
    }
    for (marking, name) in [(AaMarking::Across, "pair and the pixel beyond each"), (AaMarking::Pair, "pair")] {
        for t in AA_CURVE_THRESHOLDS {
            let aa = AaParams { marking, ..AaParams::new(t) };
            let shipped = aa == AaParams::new(threshold);
            variants.push((
                format!(
                    "{}marks: {name} + highlight pixels, threshold {t}",
                    if shipped { "after (shipped): " } else { "" }
                ),
                Sampling::Adaptive,
                SampleSet::Binned,
                Some(aa),
            ));
        }
    }
    // Interleaved: every round times every variant once, so a change of
    // load on the shared machine hits all of them alike; the fastest of
    // [`aa_rounds`] rounds is kept (the View is dropped outside the clock).
    let rounds = aa_rounds(repeats);
    let mut times = vec![Vec::with_capacity(rounds); variants.len()];
    let mut outs: Vec<(Vec<Vec3>, usize)> = vec![(Vec::new(), 0); variants.len()];
    for _ in 0..rounds {
        for (k, (_, sampling, set, aa)) in variants.iter().enumerate() {
            let g = gbuffer.clone();
            let t = std::time::Instant::now();
            let v = View::from_gbuffer_with_set(scene, g, *sampling, *set, limits);
            let out = v.render_direct(scene, light, *aa);
            times[k].push(t.elapsed().as_secs_f64() * 1e3);
            drop(v);
            outs[k] = out;
        }
    }
    let one_sample = times[0].clone();
    let mut rows: Vec<AaCostRow> = Vec::new();
    for ((name, ..), (mut t, (dense, n))) in variants.into_iter().zip(times.into_iter().zip(outs)) {
        let per_round: Vec<f64> = t.iter().zip(&one_sample).map(|(x, one)| x / one * 100.0).collect();
        t.sort_by(f64::total_cmp);
        let ms = t[0];
        let one_ms = rows.first().map_or(ms, |r| r.ms);
        rows.push(AaCostRow {
            variant: name,
            ms,
            cost_percent: ms / one_ms * 100.0,
            per_round_percent: quartiles(&per_round),
            mse_vs_81: mse_display(&shown(&dense, k_full), &reference, display),
            reshaded_share: n as f64 / (w * h) as f64,
        });
    }
    rows
}

/// Error of the whole picture of one light (direct + indirect, one set of
/// photon maps) with and without the surface bins (issue 13, AA cost): the
/// indirect term is evaluated on the base sample set only, so a base
/// without bins leaves its geometry edges aliased.
#[derive(Clone, Debug, Serialize)]
pub struct AaPictureRow {
    /// Which variant.
    pub variant: String,
    /// Share of pixels re-shaded.
    pub reshaded_share: f64,
    /// Display-space MSE (R) of the direct term against 81 samples.
    pub direct_mse: f64,
    /// Display-space MSE (R) of the indirect term against 81 samples.
    pub indirect_mse: f64,
    /// Display-space MSE (R) of direct + indirect against 81 samples.
    pub picture_mse: f64,
}

/// [`AaPictureRow`]s for `light`: the shipped sampling (surface bins,
/// threshold `threshold`), the 1-sample base with every pair re-shaded at
/// `threshold` and 60, and 9 samples everywhere, against the 81-sample
/// direct and indirect terms (the 9-sample renderer at 3× size,
/// box-filtered), all with the same photon maps (paper's settings, seeded).
#[allow(clippy::too_many_arguments)]
pub fn aa_picture(
    scene: &Scene,
    gbuffer: &GBuffer,
    light: &Light,
    k_full: Vec3,
    display: &Display,
    limits: RecursionLimits,
    threshold: f32,
) -> Vec<AaPictureRow> {
    use crate::render::SampleSet;
    let (w, h) = (gbuffer.width as usize, gbuffer.height as usize);
    let maps = trace_photons(scene, light, &PhotonSettings::default());
    let big = view_81(scene, gbuffer, limits);
    let ref_direct = shown(&box_down_3x(&big.render_direct(scene, light, None).0, w, h), k_full);
    let ref_indirect = shown(&box_down_3x(&big.render_indirect(scene, &maps), w, h), k_full);
    drop(big);
    let sum = |a: &[Vec3], b: &[Vec3]| -> Vec<Vec3> { a.iter().zip(b).map(|(x, y)| *x + *y).collect() };
    let ref_picture = sum(&ref_direct, &ref_indirect);
    let variants = [
        (
            format!("after (shipped): surface bins, pair marks + highlight pixels, threshold {threshold}"),
            SampleSet::Binned,
            threshold,
        ),
        (format!("no bins: 1 sample, every pair re-shaded, threshold {threshold}"), SampleSet::Centre, threshold),
        ("no bins: 1 sample, every pair re-shaded, threshold 60".to_string(), SampleSet::Centre, 60.0),
        ("9 samples everywhere".to_string(), SampleSet::All, threshold),
    ];
    variants
        .into_iter()
        .map(|(variant, set, t)| {
            let sampling = if set == SampleSet::All { Sampling::Nine } else { Sampling::Adaptive };
            let v = View::from_gbuffer_with_set(scene, gbuffer.clone(), sampling, set, limits);
            let (direct, n) = v.render_direct(scene, light, Some(AaParams::new(t)));
            let direct = shown(&direct, k_full);
            let indirect = shown(&v.render_indirect(scene, &maps), k_full);
            let picture = sum(&direct, &indirect);
            AaPictureRow {
                variant,
                reshaded_share: n as f64 / (w * h) as f64,
                direct_mse: mse_display(&direct, &ref_direct, display)[0],
                indirect_mse: mse_display(&indirect, &ref_indirect, display)[0],
                picture_mse: mse_display(&picture, &ref_picture, display)[0],
            }
        })
        .collect()
}

/// Markdown table of [`aa_picture`] rows.
pub fn aa_picture_markdown(rows: &[AaPictureRow]) -> String {
    let mut s = String::from(
        "| sampling | re-shaded | direct MSE (R) | indirect MSE (R) | picture MSE (R) |\n|---|---:|---:|---:|---:|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {:.2} % | {:.2e} | {:.2e} | {:.2e} |\n",
            r.variant,
            r.reshaded_share * 100.0,
            r.direct_mse,
            r.indirect_mse,
            r.picture_mse
        );
    }
    s
}

/// The renderer's threshold before the reconstruction of one-bin pixels
/// from their probed corners ([`crate::render::view::aa`]), for the
/// bench's "before" rows.
pub const AA_THRESHOLD_BEFORE: f32 = 100.0;

/// Thresholds of the bench's "no bins" rows (1-sample base, every pair
/// re-shaded with 9 samples).
pub const NO_BINS_THRESHOLDS: [f32; 3] = [20.0, 60.0, 100.0];

/// Thresholds of the bench's error-versus-cost curve of adaptive
/// anti-aliasing (relative 0-255 codes).
pub const AA_CURVE_THRESHOLDS: [f32; 6] = [20.0, 40.0, 60.0, 100.0, 120.0, 150.0];

/// Markdown table of [`aa_cost`] rows.
pub fn aa_cost_markdown(rows: &[AaCostRow]) -> String {
    let mut s = String::from(
        "| sampling | ms | cost / 1 sample | round by round: median (quartiles) | MSE vs 81 samples R | G | B | re-shaded |\n|---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        let [q1, median, q3] = r.per_round_percent;
        s += &format!(
            "| {} | {:.1} | {:.0} % | {median:.0} % ({q1:.0}-{q3:.0}) | {:.2e} | {:.2e} | {:.2e} | {:.2} % |\n",
            r.variant,
            r.ms,
            r.cost_percent,
            r.mse_vs_81[0],
            r.mse_vs_81[1],
            r.mse_vs_81[2],
            r.reshaded_share * 100.0
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::quartiles;

    #[test]
    fn quartiles_are_nearest_rank_order_statistics() {
        assert_eq!(quartiles(&[5.0, 1.0, 3.0, 2.0, 4.0]), [2.0, 3.0, 4.0]);
        assert_eq!(quartiles(&[7.0]), [7.0, 7.0, 7.0]);
        assert!(quartiles(&[]).iter().all(|q| q.is_nan()));
    }
}
