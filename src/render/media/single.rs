//! Single scattering of one light at unit intensity (1 cd) along camera
//! rays, the in-scattered term of the light's haze buffer.
//!
//! Along a camera ray x(t) = o + t·ω the light scattered toward the camera is
//!
//!   L = σ_s ∫ p(cos θ) f_ε(x → from P) / r² · g(x) · T_cam(t) · T_light(x) dt
//!
//! over the part of the ray inside the haze box, in front of the first
//! surface, and inside the beam's cut-off cone (`notes/productions.md`;
//! Kulla and Fajardo 2012). r = |x − P|, g is a shadow ray from x to the
//! light (so geometry cuts dark wedges out of the beam),
//! T_cam = exp(−σ_t τ_cam) and T_light = exp(−σ_t* τ_light) with τ the
//! metres of haze on each path ([`super::Medium::sigma_t_light`]).
//!
//! # Sampling
//! The ray is cut to the cone analytically ([`cone_interval`]): a ray that
//! misses the cone costs that one test and stores nothing. Inside, the
//! integral is taken in the equiangular variable θ (Kulla and Fajardo 2012,
//! eq. 7): t = Δ + D tan θ, with D the light's distance from the ray and Δ
//! its foot point, turns dt / r² into dθ / D, so the 1/r² peak near the lamp
//! is flat in θ. Samples are the midpoints of `n` equal θ strata: no noise,
//! no seed, exact for the unshadowed part to O(n⁻²).
//!
//! # What is stored per pixel
//! a0 = ∫ p f g / r² dt (no extinction) and the effective optical depth
//! κ = −ln(a1 / a0) with a1 the same integral with T_cam T_light at this
//! medium. The in-scattered radiance at density d is then
//! d σ_s a0 exp(−d κ): exact at d = 0 and d = 1, a one-exponential fit in
//! between ([`super::resolve`]). Both are per unit σ_s and grey (the haze is
//! grey; the light's colour is in k_i), so a buffer holds (a0, κ, 0).
//!
//! # Coarse first, then refined
//! [`HazeQuality`] sets a beam-buffer scale: rays are traced at every
//! `scale`-th pixel and upsampled with depth-aware weights (joint
//! bilateral: a neighbour whose surface is at a different depth gets no
//! weight). With `refine_edges`, full-resolution pixels whose four coarse
//! neighbours disagree (a beam or shadow edge, a depth edge) are traced
//! exactly (Engelhardt and Dachsbacher 2010 refine the same way along
//! epipolar lines). Without `refine_edges` (the coarse stage), tiles whose
//! coarse samples all miss the beam are skipped, not upsampled.

use super::medium::Medium;
use crate::fixture::Light;
use crate::render::buffer::{HazeBuffer, LightBuffer, TILE};
use crate::render::gbuffer::{CENTRE_SAMPLE, GBuffer, NO_HIT, PrimarySample};
use crate::scene::{Camera, Scene};
use glam::Vec3;
use rayon::prelude::*;

/// How finely a light's beam is sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct HazeQuality {
    /// Beam-buffer scale: trace every `scale`-th pixel in x and y (1 = all).
    pub scale: u32,
    /// Equiangular samples per ray inside the cone.
    pub samples: u32,
    /// Trace pixels at beam, shadow and depth edges at full resolution.
    pub refine_edges: bool,
}

impl HazeQuality {
    /// The first, fast stage after a beam moved: quarter resolution, 8 samples.
    pub const COARSE: Self = Self { scale: 4, samples: 8, refine_edges: false };
    /// The refined stage: quarter-resolution interior, edges traced at full
    /// resolution, 32 samples.
    pub const REFINED: Self = Self { scale: 4, samples: 32, refine_edges: true };
    /// Every pixel traced with 64 samples (the reference of the bench).
    pub const FULL: Self = Self { scale: 1, samples: 64, refine_edges: false };
}

/// Light-independent per-pixel data of the haze for one camera: the centre
/// ray of every pixel (the G-buffer's centre sample) and where it ends.
pub struct HazeView {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// The camera.
    pub camera: Camera,
    /// Per pixel: unit ray direction.
    dirs: Vec<Vec3>,
    /// Per pixel: distance to the first surface (∞ for a miss).
    t_hit: Vec<f32>,
    /// Per pixel: the surface the centre ray hits (from the G-buffer; empty
    /// for a view made from rays).
    centre: Vec<PrimarySample>,
}

impl HazeView {
    /// From a view's G-buffer (its centre samples; no new rays).
    pub fn new(scene: &Scene, gbuffer: &GBuffer) -> Self {
        let (w, h) = (gbuffer.width, gbuffer.height);
        let camera = gbuffer.camera;
        let mut dirs = Vec::with_capacity((w * h) as usize);
        let mut t_hit = Vec::with_capacity((w * h) as usize);
        let mut centre = Vec::with_capacity((w * h) as usize);
        for y in 0..h {
            for x in 0..w {
                let samples = &gbuffer.samples[(y * w + x) as usize];
                let d = camera.direction(x as f32 + 0.5, y as f32 + 0.5, w, h);
                let depth = |s: &PrimarySample| {
                    (s.triangle != NO_HIT).then(|| scene.point_on(s.triangle, s.u, s.v).distance(camera.position))
                };
                // A silhouette pixel whose centre ray misses but whose other
                // samples hit (their light is in the surface buffer) takes
                // the nearest of their depths, so that light is extinguished
                // like its neighbours' instead of passing the haze untouched.
                let t = depth(&samples[CENTRE_SAMPLE])
                    .or_else(|| samples.iter().filter_map(depth).reduce(f32::min))
                    .unwrap_or(f32::INFINITY);
                dirs.push(d);
                t_hit.push(t);
                centre.push(samples[CENTRE_SAMPLE]);
            }
        }
        Self { width: w, height: h, camera, dirs, t_hit, centre }
    }

    /// A view from rays already traced (`dirs` unit, `t_hit` ∞ for a miss,
    /// both row-major over `width`×`height`): the moving-camera preview's
    /// reduced picture (src/live/views.rs), which has no G-buffer.
    pub fn from_rays(camera: Camera, width: u32, height: u32, dirs: Vec<Vec3>, t_hit: Vec<f32>) -> Self {
        assert_eq!((dirs.len(), t_hit.len()), ((width * height) as usize, (width * height) as usize), "rays");
        Self { width, height, camera, dirs, t_hit, centre: Vec::new() }
    }

    /// Centre-ray direction of pixel `i` (row-major).
    pub fn dir(&self, i: usize) -> Vec3 {
        self.dirs[i]
    }

    /// Distance to the surface the centre ray of pixel `i` hits (∞: none).
    pub fn t_hit(&self, i: usize) -> f32 {
        self.t_hit[i]
    }

    /// The surface the centre ray of pixel `i` hits: the G-buffer's centre
    /// sample, or for a view made from rays a ray traced now (`None`: it
    /// misses, or a silhouette pixel whose depth came from another sample).
    pub fn centre_hit(&self, scene: &Scene, i: usize) -> Option<crate::scene::bvh::Hit> {
        match self.centre.get(i) {
            Some(s) if s.triangle != NO_HIT => {
                Some(crate::scene::bvh::Hit { triangle: s.triangle, t: self.t_hit[i], u: s.u, v: s.v })
            }
            Some(_) => None,
            None => scene.accel.intersect(self.camera.position, self.dirs[i], f32::INFINITY),
        }
    }

    /// Point the centre ray of pixel `i` hits, if any.
    pub fn hit_point(&self, i: usize) -> Option<Vec3> {
        let t = self.t_hit[i];
        t.is_finite().then(|| self.camera.position + self.dirs[i] * t)
    }
}

/// The in-scattered light of one camera ray at unit intensity, per unit σ_s.
///
/// The extinguished integral a1 is kept as its optical depth κ = ln(a0 / a1)
/// rather than as a1 itself: at optical depths past ~87 (σ_s 5 /m across a
/// stage) a1 underflows in f32, and a κ computed from an underflowed a1 was
/// 0 (the beam shown unattenuated, 10⁵ times too bright at σ_s 10 /m).
/// [`integrate_ray`] sums a1 relative to its least-extinguished sample
/// (log-sum-exp), so κ stays exact to any depth; a1 is only formed on demand.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct InScatter {
    /// ∫ p f_ε g / r² dt without extinction.
    pub a0: f32,
    /// Effective optical depth κ = ln(a0 / a1) ≥ 0, a1 the same integral with
    /// T_cam · T_light at the medium's density; [`KAPPA_OPAQUE`] when no
    /// light gets through. 0 when a0 = 0.
    pub kappa: f32,
}

/// κ of a ray whose every sample is extinguished past f32 (τ = ∞): finite,
/// so d·κ stays a number for every density d ≤ 1 and exp(−d κ) is 0 for
/// any d > 1e-28, and exactly 1 at d = 0 (no haze, no extinction).
pub const KAPPA_OPAQUE: f32 = 1e30;

impl InScatter {
    /// The integral with extinction, a1 = a0 exp(−κ) (0 where it underflows).
    pub fn a1(&self) -> f32 {
        if self.a0 > 0.0 { self.a0 * (-self.kappa).exp() } else { 0.0 }
    }

    /// Effective optical depth κ (0 when a0 = 0).
    pub fn kappa(&self) -> f32 {
        if self.a0 > 0.0 { self.kappa } else { 0.0 }
    }

    /// The stored pixel (a0, κ, 0).
    pub fn pixel(&self) -> Vec3 {
        if self.a0 > 0.0 && self.a0.is_finite() { Vec3::new(self.a0, self.kappa(), 0.0) } else { Vec3::ZERO }
    }

    /// The weighted mean of `parts` (weight, value): a0 averages linearly,
    /// a1 too, taken relative to the smallest κ so that it never underflows.
    fn mean(parts: &[(f32, InScatter)]) -> InScatter {
        let lit = || parts.iter().filter(|(w, c)| *w > 0.0 && c.a0 > 0.0);
        let Some(m) = lit().map(|(_, c)| c.kappa).reduce(f32::min) else { return InScatter::default() };
        let wsum: f32 = parts.iter().map(|(w, _)| *w).sum();
        let (a0, a1_rel) =
            lit().fold((0.0f32, 0.0f32), |(a, b), (w, c)| (a + w * c.a0, b + w * c.a0 * (-(c.kappa - m)).exp()));
        if !(wsum > 0.0) || !(a0 > 0.0) {
            return InScatter::default();
        }
        let kappa = if a1_rel > 0.0 { ((a0 / a1_rel).ln() + m).clamp(0.0, KAPPA_OPAQUE) } else { KAPPA_OPAQUE };
        InScatter { a0: a0 / wsum, kappa }
    }
}

/// Margin on the cut-off angle for the analytic cone test (radians), so
/// rounding never drops a sample the pattern would light.
const CONE_MARGIN: f32 = 1e-3;

/// The interval of t in [t_lo, t_hi] where `origin + t·dir` (unit dir) is
/// inside the cone of half-angle acos(`cos_cut`) around `axis` (unit) with
/// apex `apex`; `None` when the ray misses it. Cones of 90° or wider are
/// not convex: the whole interval is returned (the pattern decides).
pub fn cone_interval(
    apex: Vec3,
    axis: Vec3,
    cos_cut: f32,
    origin: Vec3,
    dir: Vec3,
    t_lo: f32,
    t_hi: f32,
) -> Option<(f32, f32)> {
    if !(t_hi > t_lo) {
        return None;
    }
    let angle = cos_cut.clamp(-1.0, 1.0).acos() + CONE_MARGIN;
    if angle >= std::f32::consts::FRAC_PI_2 - 1e-3 {
        return Some((t_lo, t_hi));
    }
    let c2 = angle.cos().powi(2);
    let co = origin - apex;
    let (da, ca) = (dir.dot(axis), co.dot(axis));
    // f(t) = (x·a)² − c² |x|² ≥ 0 with x = co + t·dir: the double cone.
    let a = da * da - c2;
    let b = 2.0 * (da * ca - c2 * dir.dot(co));
    let c = ca * ca - c2 * co.length_squared();
    let mut pieces: [(f32, f32); 2] = [(f32::NAN, f32::NAN); 2];
    if a.abs() < 1e-9 {
        // Ray parallel to a cone generator: f is linear.
        if b.abs() < 1e-12 {
            if c >= 0.0 {
                pieces[0] = (f32::NEG_INFINITY, f32::INFINITY);
            }
        } else {
            let r = -c / b;
            pieces[0] = if b > 0.0 { (r, f32::INFINITY) } else { (f32::NEG_INFINITY, r) };
        }
    } else {
        let disc = b * b - 4.0 * a * c;
        if disc < 0.0 {
            if a > 0.0 {
                pieces[0] = (f32::NEG_INFINITY, f32::INFINITY);
            }
        } else {
            // Numerically stable roots.
            let q = -0.5 * (b + b.signum() * disc.sqrt());
            let (r1, r2) = (q / a, if q != 0.0 { c / q } else { 0.0 });
            let (r1, r2) = (r1.min(r2), r1.max(r2));
            if a > 0.0 {
                pieces = [(f32::NEG_INFINITY, r1), (r2, f32::INFINITY)];
            } else {
                pieces[0] = (r1, r2);
            }
        }
    }
    // Keep the forward nappe: (co + t·dir)·a ≥ 0.
    let (h_lo, h_hi) = if da.abs() < 1e-12 {
        if ca >= 0.0 { (f32::NEG_INFINITY, f32::INFINITY) } else { return None }
    } else if da > 0.0 {
        (-ca / da, f32::INFINITY)
    } else {
        (f32::NEG_INFINITY, -ca / da)
    };
    let mut out: Option<(f32, f32)> = None;
    for (p0, p1) in pieces {
        if p0.is_nan() {
            continue;
        }
        let lo = p0.max(h_lo).max(t_lo);
        let hi = p1.min(h_hi).min(t_hi);
        if hi > lo {
            out = Some(out.map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))));
        }
    }
    out
}

/// The optical depth whose transmittance is the mean of e^(−e) over a
/// stratum where e runs linearly from `near` to `far`:
/// e^(−min) (1 − e^(−Δ)) / Δ, as a depth (so it never underflows).
fn stratum_depth(near: f32, far: f32) -> f32 {
    let (lo, span) = (near.min(far), (far - near).abs());
    if span < 1e-3 {
        0.5 * (near + far)
    } else if span.is_finite() {
        lo - (-(-span).exp_m1() / span).ln()
    } else {
        lo + f32::MAX.ln()
    }
}

/// Single scattering of `light` (1 cd) along one camera ray: `origin` +
/// t·`dir` (unit), t from 0 to `t_surface` (∞: no surface), with `samples`
/// equiangular strata inside the cone: pattern, phase and occlusion at each
/// stratum's midpoint, the transmittance averaged over the stratum (optical
/// depth linear across it), so a stratum many mean free paths long is
/// weighted by what light gets through it, not by its midpoint.
pub fn integrate_ray(
    scene: &Scene,
    medium: &Medium,
    light: &Light,
    origin: Vec3,
    dir: Vec3,
    t_surface: f32,
    samples: u32,
) -> InScatter {
    let Some((tb0, tb1)) = medium.clip(origin, dir, t_surface) else { return InScatter::default() };
    let Some((t0, t1)) = cone_interval(light.position, light.axis(), light.beam.cos_cutoff(), origin, dir, tb0, tb1)
    else {
        return InScatter::default();
    };
    let n = samples.max(1);
    // Equiangular parameterisation (Kulla and Fajardo 2012, eq. 7).
    let delta = (light.position - origin).dot(dir);
    let d = (light.position - origin - dir * delta).length().max(1e-4);
    let (th0, th1) = (((t0 - delta) / d).atan(), ((t1 - delta) / d).atan());
    let step = (th1 - th0) / n as f32;
    if !(step > 0.0) || !step.is_finite() {
        return InScatter::default();
    }
    let (sigma_t, sigma_tl) = (medium.sigma_t(), medium.sigma_t_light());
    // Optical depth (camera side + light side) at t.
    let depth_at = |t: f32| {
        let x = origin + dir * t;
        sigma_t * (t.clamp(tb0, tb1) - tb0) + sigma_tl * medium.length_inside(x, light.position)
    };
    // A sliver of haze (the ray grazes the box or the cone, or meets a
    // surface on the box's face): the θ strata would collapse onto a few
    // representable t and lose the depth across them, so it is one stratum
    // in t: a0 = h Δt / r², the transmittance averaged over Δt. As σ_t → ∞
    // this tends to the optically thick skin's σ_s/σ_t · h / r², not ∞.
    if t1 - t0 <= 16.0 * n as f32 * f32::EPSILON * t0.abs().max(t1.abs()).max(1.0) {
        let t = 0.5 * (t0 + t1);
        let x = origin + dir * t;
        let to_x = x - light.position;
        let r = to_x.length();
        if !(r > 1e-6) || !r.is_finite() || !(t1 > t0) {
            return InScatter::default();
        }
        let w_in = to_x / r;
        let f = light.pattern_toward(w_in);
        if f <= 0.0 || scene.accel.occluded(x, -w_in, r * (1.0 - 1e-4)) {
            return InScatter::default();
        }
        let a0 = medium.phase(w_in.dot(-dir)) * f * (t1 - t0) / (r * r);
        let kappa = stratum_depth(depth_at(t0), depth_at(t1));
        return if a0 > 0.0 && a0.is_finite() {
            InScatter { a0, kappa: kappa.clamp(0.0, KAPPA_OPAQUE) }
        } else {
            InScatter::default()
        };
    }
    // a1 = exp(−shift) · a1_rel: shift is the least optical depth so far, so
    // the largest term is h·1 and nothing underflows (log-sum-exp).
    let (mut a0, mut a1_rel, mut shift) = (0.0f32, 0.0f32, f32::INFINITY);
    let mut depth_lo = depth_at(t0);
    for k in 0..n {
        let th = th0 + (k as f32 + 0.5) * step;
        let t = delta + d * th.tan();
        // The stratum's far end: its depth is the next stratum's near end.
        let depth_hi =
            if k + 1 == n { depth_at(t1) } else { depth_at(delta + d * (th0 + (k + 1) as f32 * step).tan()) };
        let depth_near = std::mem::replace(&mut depth_lo, depth_hi);
        let x = origin + dir * t;
        let to_x = x - light.position;
        let r = to_x.length();
        if !(r > 1e-6) || !r.is_finite() {
            continue;
        }
        let w_in = to_x / r;
        let f = light.pattern_toward(w_in);
        if f <= 0.0 {
            continue;
        }
        // Light propagates along w_in, then toward the camera along −dir.
        let h = medium.phase(w_in.dot(-dir)) * f;
        if scene.accel.occluded(x, -w_in, r * (1.0 - 1e-4)) {
            continue;
        }
        a0 += h;
        // The transmittance averaged over the stratum with the optical depth
        // linear across it ([`stratum_depth`]): a stratum many mean free
        // paths long is weighted by the light that gets out of its near end
        // (the midpoint value would miss it by e^(−Δ/2)·Δ).
        let depth = stratum_depth(depth_near, depth_hi);
        if depth.is_finite() {
            if depth < shift {
                a1_rel = if shift.is_finite() { a1_rel * (-(shift - depth)).exp() } else { 0.0 };
                shift = depth;
            }
            a1_rel += h * (-(depth - shift)).exp();
        }
    }
    if !(a0 > 0.0) {
        return InScatter::default();
    }
    // κ = ln(a0 / a1) = ln(a0 / a1_rel) + shift; dt / r² = dθ / D scales a0.
    let kappa = if a1_rel > 0.0 { ((a0 / a1_rel).ln() + shift).clamp(0.0, KAPPA_OPAQUE) } else { KAPPA_OPAQUE };
    InScatter { a0: a0 * (step / d), kappa }
}

/// Renders `light`'s haze buffer (a0, κ per pixel, tile-sparse) for the
/// view `hv` at `quality`. The stage function for a moved light: call it
/// with [`HazeQuality::COARSE`] first, then [`HazeQuality::REFINED`].
///
/// Cost in proportion to the beam's footprint: only the pixels inside the
/// screen bounds of the cone's part in the haze box ([`beam_screen_bounds`])
/// are traced (a ray there that misses the cone costs one cone test), only
/// the tiles they cover are filled, and the result is written straight into
/// sparse tiles (no frame-sized buffer). Pixels outside the bounds cannot
/// see the beam, so the result is the same as tracing every pixel.
pub fn render_inscatter(
    scene: &Scene,
    hv: &HazeView,
    light: &Light,
    medium: &Medium,
    quality: HazeQuality,
) -> HazeBuffer {
    let (w, h) = (hv.width as usize, hv.height as usize);
    if medium.is_clear() || medium.sigma_s <= 0.0 || w == 0 || h == 0 {
        return HazeBuffer::empty(hv.width, hv.height);
    }
    let Some((bx0, by0, bx1, by1)) = beam_screen_bounds(hv, light, medium) else {
        return HazeBuffer::empty(hv.width, hv.height);
    };
    let trace =
        |i: usize| integrate_ray(scene, medium, light, hv.camera.position, hv.dirs[i], hv.t_hit[i], quality.samples);
    let tiles: Vec<(usize, usize)> = (by0 / TILE..by1.div_ceil(TILE))
        .flat_map(|ty| (bx0 / TILE..bx1.div_ceil(TILE)).map(move |tx| (tx, ty)))
        .collect();
    let in_bounds = |x: usize, y: usize| x >= bx0 && x < bx1 && y >= by0 && y < by1;
    let s = quality.scale.max(1) as usize;
    if s == 1 {
        let buffer = LightBuffer::from_tiles(hv.width, hv.height, &tiles, |tx, ty, tile| {
            for r in 0..TILE.min(h - ty * TILE) {
                for c in 0..TILE.min(w - tx * TILE) {
                    let (x, y) = (tx * TILE + c, ty * TILE + r);
                    if in_bounds(x, y) {
                        tile[r * TILE + c] = trace(y * w + x).pixel();
                    }
                }
            }
        });
        return HazeBuffer::from_light_buffer(buffer);
    }
    // Coarse grid: coarse pixel (cx, cy) is full pixel (rep(cx), rep(cy));
    // traced only inside the bounds (outside, the beam is not in the ray).
    let (cw, ch) = (w.div_ceil(s), h.div_ceil(s));
    let rep = |c: usize, n: usize| (c * s + s / 2).min(n - 1);
    let (cx0, cx1) = ((bx0 / s).saturating_sub(1), (bx1 / s + 2).min(cw));
    let (cy0, cy1) = ((by0 / s).saturating_sub(1), (by1 / s + 2).min(ch));
    let mut coarse = vec![InScatter::default(); (cx1 - cx0) * (cy1 - cy0)];
    coarse.par_chunks_mut(cx1 - cx0).enumerate().for_each(|(row, px)| {
        let cy = cy0 + row;
        for (k, p) in px.iter_mut().enumerate() {
            let (x, y) = (rep(cx0 + k, w), rep(cy, h));
            if in_bounds(x, y) {
                *p = trace(y * w + x);
            }
        }
    });
    let coarse_at = |cx: usize, cy: usize| {
        if (cx0..cx1).contains(&cx) && (cy0..cy1).contains(&cy) {
            coarse[(cy - cy0) * (cx1 - cx0) + cx - cx0]
        } else {
            InScatter::default()
        }
    };
    let pixel = |x: usize, y: usize| -> Vec3 {
        let (cy_a, cy_b, fy) = neighbours(y, s, ch, h);
        let (cx_a, cx_b, fx) = neighbours(x, s, cw, w);
        let i = y * w + x;
        let t_here = hv.t_hit[i];
        let corners = [
            (cx_a, cy_a, (1.0 - fx) * (1.0 - fy)),
            (cx_b, cy_a, fx * (1.0 - fy)),
            (cx_a, cy_b, (1.0 - fx) * fy),
            (cx_b, cy_b, fx * fy),
        ];
        let mut parts = [(0.0f32, InScatter::default()); 4];
        let mut wsum = 0.0;
        let (mut lo, mut hi, mut a0_max) = (f32::INFINITY, 0.0f32, 0.0f32);
        let mut depth_edge = false;
        for (part, (cx, cy, wb)) in parts.iter_mut().zip(corners) {
            let c = coarse_at(cx, cy);
            let wd = depth_weight(t_here, hv.t_hit[rep(cy, h) * w + rep(cx, w)]);
            depth_edge |= wd < 0.5;
            lo = lo.min(c.a1());
            hi = hi.max(c.a1());
            a0_max = a0_max.max(c.a0);
            let wt = wb * wd;
            *part = (wt, c);
            wsum += wt;
        }
        if a0_max <= 0.0 && !in_bounds(x, y) {
            return Vec3::ZERO;
        }
        // Edge: neighbours differ by over 20 % (beam or shadow edge), or
        // a depth discontinuity the weights cannot bridge.
        let edge = depth_edge || hi > 1.25 * lo + 1e-12;
        if quality.refine_edges && edge {
            trace(i).pixel()
        } else if wsum > 1e-6 {
            InScatter::mean(&parts).pixel()
        } else if in_bounds(x, y) {
            // No neighbour at this depth (a thin object): trace it.
            trace(i).pixel()
        } else {
            Vec3::ZERO
        }
    };
    // Upsampled values reach up to one coarse step past the bounds.
    let (ex0, ey0) = (bx0.saturating_sub(s) / TILE, by0.saturating_sub(s) / TILE);
    let (ex1, ey1) = ((bx1 + s).min(w).div_ceil(TILE), (by1 + s).min(h).div_ceil(TILE));
    let mut tiles: Vec<(usize, usize)> = (ey0..ey1).flat_map(|ty| (ex0..ex1).map(move |tx| (tx, ty))).collect();
    if !quality.refine_edges {
        // A tile none of whose coarse samples (the two around every pixel,
        // per axis) meets the beam is all zero after upsampling; only a
        // pixel at a depth unlike all four neighbours (a beam seen through
        // a gap) would be traced on its own. The coarse stage skips such
        // tiles without upsampling; the refined stage traces depth edges.
        let live = |tx: usize, ty: usize| {
            let range = |t: usize, n: usize, full: usize| {
                let (p0, p1) = (t * TILE, ((t + 1) * TILE).min(full) - 1);
                (p0.saturating_sub(s / 2) / s, (p1.saturating_sub(s / 2) / s + 1).min(n - 1))
            };
            let ((xa, xb), (ya, yb)) = (range(tx, cw, w), range(ty, ch, h));
            (ya..=yb).any(|cy| (xa..=xb).any(|cx| coarse_at(cx, cy).a0 > 0.0))
        };
        tiles.retain(|&(tx, ty)| live(tx, ty));
    }
    let buffer = LightBuffer::from_tiles(hv.width, hv.height, &tiles, |tx, ty, tile| {
        for r in 0..TILE.min(h - ty * TILE) {
            for c in 0..TILE.min(w - tx * TILE) {
                tile[r * TILE + c] = pixel(tx * TILE + c, ty * TILE + r);
            }
        }
    });
    HazeBuffer::from_light_buffer(buffer)
}

/// The pixel rectangle [x0, x1) × [y0, y1) outside which no centre ray of
/// `hv` can meet `light`'s cone inside the haze box: the projection of a
/// convex hull of the cone cut where the box ends along the beam axis (the
/// apex plus a 16-gon circumscribing the cone's disk at the largest axial
/// distance of a box corner). A hull reaching behind the camera is clipped
/// at a near plane 1 mm in front of it (its points there project far out,
/// widening the rectangle toward that side). The whole picture when the
/// cone is 80° or wider; `None` when the hull is off screen or behind.
pub fn beam_screen_bounds(hv: &HazeView, light: &Light, medium: &Medium) -> Option<(usize, usize, usize, usize)> {
    let (w, h) = (hv.width as usize, hv.height as usize);
    let full = Some((0, 0, w, h));
    let angle = light.beam.cos_cutoff().clamp(-1.0, 1.0).acos() + CONE_MARGIN;
    if !(angle < 80f32.to_radians()) {
        return full;
    }
    let (apex, axis) = (light.position, light.axis());
    let corners = (0..8).map(|k| {
        Vec3::new(
            if k & 1 == 0 { medium.min.x } else { medium.max.x },
            if k & 2 == 0 { medium.min.y } else { medium.max.y },
            if k & 4 == 0 { medium.min.z } else { medium.max.z },
        )
    });
    let reach = corners.map(|c| (c - apex).dot(axis)).fold(0.0f32, f32::max);
    if !reach.is_finite() || !apex.is_finite() || !axis.is_finite() {
        return full;
    }
    if reach <= 0.0 {
        return None; // the box is wholly behind the lamp
    }
    const SIDES: usize = 16;
    let radius = reach * angle.tan() / (std::f32::consts::PI / SIDES as f32).cos();
    let (u, v) = axis.any_orthonormal_pair();
    let centre = apex + axis * reach;
    let cam = hv.camera;
    let aspect = w as f32 / h.max(1) as f32;
    let tan_half = (cam.yfov * 0.5).tan();
    const NEAR: f32 = 1e-3;
    let hull: Vec<Vec3> = (0..=SIDES)
        .map(|k| {
            if k == SIDES {
                apex
            } else {
                let phi = k as f32 * std::f32::consts::TAU / SIDES as f32;
                centre + (u * phi.cos() + v * phi.sin()) * radius
            }
        })
        .collect();
    let depth = |p: Vec3| -(p - cam.position).dot(cam.basis.z_axis);
    // The hull clipped at the near plane: its points in front, and where
    // every segment between a point in front and one behind crosses the plane.
    let mut front: Vec<Vec3> = hull.iter().copied().filter(|p| depth(*p) >= NEAR).collect();
    if front.is_empty() {
        return None;
    }
    for a in hull.iter().filter(|p| depth(**p) >= NEAR) {
        for b in hull.iter().filter(|p| depth(**p) < NEAR) {
            let (da, db) = (depth(*a), depth(*b));
            front.push(*a + (*b - *a) * ((da - NEAR) / (da - db)));
        }
    }
    let (mut lo, mut hi) = (glam::Vec2::splat(f32::INFINITY), glam::Vec2::splat(f32::NEG_INFINITY));
    for p in front {
        let rel = p - cam.position;
        let z = depth(p).max(NEAR);
        let nx = rel.dot(cam.basis.x_axis) / (z * tan_half * aspect);
        let ny = rel.dot(cam.basis.y_axis) / (z * tan_half);
        let px = glam::Vec2::new((nx + 1.0) * 0.5 * w as f32, (1.0 - ny) * 0.5 * h as f32);
        if !px.is_finite() {
            return full;
        }
        lo = lo.min(px);
        hi = hi.max(px);
    }
    // One pixel of margin for the centre-ray offset and rounding.
    let clamp = |v: f32, n: usize| v.clamp(0.0, n as f32) as usize;
    let (x0, y0) = (clamp((lo.x - 1.0).floor(), w), clamp((lo.y - 1.0).floor(), h));
    let (x1, y1) = (clamp((hi.x + 2.0).ceil(), w), clamp((hi.y + 2.0).ceil(), h));
    (x1 > x0 && y1 > y0).then_some((x0, y0, x1, y1))
}

/// The two coarse samples around full pixel `p` (coarse scale `s`, `n`
/// coarse and `full` full pixels on the axis) and the weight of the second.
fn neighbours(p: usize, s: usize, n: usize, full: usize) -> (usize, usize, f32) {
    let centre = |c: usize| (c * s + s / 2).min(full - 1) as f32;
    let c0 = (p.saturating_sub(s / 2) / s).min(n - 1);
    let c1 = (c0 + 1).min(n - 1);
    if c1 == c0 {
        return (c0, c1, 0.0);
    }
    let f = ((p as f32 - centre(c0)) / (centre(c1) - centre(c0)).max(1.0)).clamp(0.0, 1.0);
    (c0, c1, f)
}

/// Joint-bilateral depth weight: 1 at the same depth, falling to ~0 at 10 %
/// relative depth difference; two misses match, a miss and a hit do not.
fn depth_weight(a: f32, b: f32) -> f32 {
    match (a.is_finite(), b.is_finite()) {
        (false, false) => 1.0,
        (true, true) => {
            let rel = (a - b).abs() / a.min(b).max(1e-3);
            (-(rel / 0.05).powi(2)).exp()
        }
        _ => 0.0,
    }
}

/// A dense in-scatter buffer in radiance at density 1 (σ_s a1): for tests
/// and the bench, which compare it with references pixel by pixel.
pub fn radiance_at_full(buffer: &HazeBuffer, medium: &Medium) -> Vec<f32> {
    buffer.as_light_buffer().to_dense().iter().map(|v| medium.sigma_s * v.x * (-v.y).exp()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cone_interval_matches_a_direct_test() {
        let apex = Vec3::new(0.0, 5.0, 0.0);
        let axis = Vec3::NEG_Y;
        let cos_cut = 15f32.to_radians().cos();
        let inside = |x: Vec3| (x - apex).normalize().dot(axis) >= cos_cut;
        let mut rng = 1u64;
        let mut next = || {
            rng = rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((rng >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        };
        for _ in 0..500 {
            let o = Vec3::new(next() * 6.0, next() * 6.0 + 3.0, next() * 6.0 + 8.0);
            let d = Vec3::new(next(), next(), next() - 0.5).normalize();
            let got = cone_interval(apex, axis, cos_cut, o, d, 0.0, 30.0);
            // March and compare membership away from the boundary.
            for k in 0..600 {
                let t = k as f32 * 0.05;
                let x = o + d * t;
                let c = (x - apex).normalize().dot(axis);
                if (c - cos_cut).abs() < 2e-3 {
                    continue;
                }
                let in_interval = got.is_some_and(|(a, b)| t >= a && t <= b);
                assert_eq!(in_interval, inside(x), "o {o} d {d} t {t} got {got:?}");
            }
        }
    }
}
