//! Ray queries against the scene's triangles through an `obvhs` compressed
//! wide BVH (CWBVH, Ylitie et al. 2017).
//!
//! obvhs's own triangle test is not watertight on back-side hits, so the
//! callers offset secondary-ray origins along the geometric normal (see
//! [`offset_origin`]) and the test here is two-sided.

use glam::{Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    cwbvh::{CwBvh, builder::build_cwbvh_from_tris},
    ray::{Ray, RayHit},
    triangle::Triangle,
};
use std::time::Duration;

/// A closest-hit result: which triangle, how far, and where on it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Index into the scene's triangle list.
    pub triangle: u32,
    /// Distance along the (unit) ray direction.
    pub t: f32,
    /// Barycentric coordinates (u, v) of the hit: p = (1-u-v)·v0 + u·v1 + v·v2.
    pub u: f32,
    /// See `u`.
    pub v: f32,
}

/// Acceleration structure over a triangle soup. Empty scenes have no BVH and
/// every query misses.
pub struct Accel {
    bvh: Option<CwBvh>,
    /// Triangles in BVH order, so a leaf's primitive id indexes them directly.
    ordered: Vec<Triangle>,
    /// Maps BVH primitive order back to the scene's triangle index.
    original: Vec<u32>,
}

impl Accel {
    /// Builds the BVH (PLOC + CWBVH conversion, obvhs "medium" preset).
    pub fn build(triangles: &[[Vec3; 3]]) -> Self {
        if triangles.is_empty() {
            return Self { bvh: None, ordered: Vec::new(), original: Vec::new() };
        }
        let tris: Vec<Triangle> =
            triangles.iter().map(|t| Triangle { v0: t[0].into(), v1: t[1].into(), v2: t[2].into() }).collect();
        let bvh = build_cwbvh_from_tris(&tris, BvhBuildParams::medium_build(), &mut Duration::default());
        let original = bvh.primitive_indices.clone();
        let ordered = original.iter().map(|&i| tris[i as usize]).collect();
        Self { bvh: Some(bvh), ordered, original }
    }

    /// Closest hit along `origin + t·dir` for t in (0, `t_max`); `dir` must be unit.
    pub fn intersect(&self, origin: Vec3, dir: Vec3, t_max: f32) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        if !origin.is_finite() || !dir.is_finite() {
            return None;
        }
        // −0.0 components make the CWBVH traversal miss (found by the haze
        // shadow rays, issue 15); adding +0.0 turns them into +0.0.
        let dir = dir + Vec3::ZERO;
        let ray = Ray::new(origin.into(), dir.into(), 0.0, t_max);
        let mut hit = RayHit::none();
        if !bvh.ray_traverse(ray, &mut hit, |ray, id| self.ordered[id].intersect(ray)) {
            return None;
        }
        let id = hit.primitive_id as usize;
        let tri = &self.ordered[id];
        let (u, v) = barycentric(tri, origin.into(), dir.into());
        Some(Hit { triangle: self.original[id], t: hit.t, u, v })
    }

    /// True when anything blocks the segment `origin + t·dir`, t in (0, `t_max`).
    pub fn occluded(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        let Some((bvh, ray)) = self.shadow_ray(origin, dir, t_max) else { return false };
        !bvh.ray_traverse_miss(ray, |ray, id| self.ordered[id].intersect(ray))
    }

    /// The BVH and the ray of a shadow segment, `None` when nothing can
    /// block it (an empty scene, a non-finite ray, no length).
    #[inline(always)]
    fn shadow_ray(&self, origin: Vec3, dir: Vec3, t_max: f32) -> Option<(&CwBvh, Ray)> {
        let bvh = self.bvh.as_ref()?;
        if !origin.is_finite() || !dir.is_finite() || t_max <= 0.0 {
            return None;
        }
        let dir = dir + Vec3::ZERO; // −0.0 → +0.0, as in `intersect`
        Some((bvh, Ray::new(origin.into(), dir.into(), 0.0, t_max)))
    }

    /// [`Accel::occluded`], testing first the triangle that blocked the last
    /// segment tested with `hint`, and remembering the one that blocks this
    /// one. Neighbouring shadow rays toward one light (the 9 samples of a
    /// re-shaded pixel) are often blocked by the same triangle: then no
    /// traversal runs. The same answer as [`Accel::occluded`]: the hinted
    /// triangle is tested with the traversal's own ray and triangle test,
    /// and it answers only when it blocks the segment, which then crosses
    /// the triangle's (conservative) leaf box, so the traversal would find
    /// it blocked too.
    pub fn occluded_hinted(&self, origin: Vec3, dir: Vec3, t_max: f32, hint: &mut OccluderHint) -> bool {
        let Some((bvh, ray)) = self.shadow_ray(origin, dir, t_max) else { return false };
        if hint.0.is_some_and(|id| self.ordered[id as usize].intersect(&ray) < t_max) {
            return true;
        }
        let mut found = None;
        let missed = bvh.ray_traverse_miss(ray, |ray, id| {
            let t = self.ordered[id].intersect(ray);
            if t < ray.tmax {
                found = Some(id as u32);
            }
            t
        });
        if !missed {
            hint.0 = found;
        }
        !missed
    }
}

/// The triangle that blocked the last shadow segment tested with it
/// ([`Accel::occluded_hinted`]); the default knows none.
#[derive(Clone, Copy, Debug, Default)]
pub struct OccluderHint(Option<u32>);

/// Barycentrics of the ray's hit on the triangle's plane (Möller–Trumbore,
/// same orientation as obvhs: p = (1-u-v)·v0 + u·v1 + v·v2), clamped into the
/// triangle so float noise on an edge stays on the triangle.
fn barycentric(tri: &Triangle, origin: Vec3A, dir: Vec3A) -> (f32, f32) {
    let e1 = tri.v1 - tri.v0;
    let e2 = tri.v2 - tri.v0;
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < f32::MIN_POSITIVE {
        return (1.0 / 3.0, 1.0 / 3.0);
    }
    let inv = 1.0 / det;
    let s = origin - tri.v0;
    let u = s.dot(p) * inv;
    let q = s.cross(e1);
    let v = dir.dot(q) * inv;
    let u = if u.is_finite() { u.clamp(0.0, 1.0) } else { 1.0 / 3.0 };
    let v = if v.is_finite() { v.clamp(0.0, 1.0 - u) } else { 1.0 / 3.0 };
    (u, v)
}

/// Moves a ray origin off a surface along the geometric normal `n_g` (facing
/// the side the new ray leaves from), scaled with the coordinates' magnitude
/// so it works from millimetre models to kilometre ones.
pub fn offset_origin(p: Vec3, n_g: Vec3) -> Vec3 {
    let scale = p.abs().max_element().max(1e-3);
    p + n_g * (scale * 2e-5 + 1e-6)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> Vec<[Vec3; 3]> {
        let a = Vec3::new(-1.0, 0.0, -1.0);
        let b = Vec3::new(1.0, 0.0, -1.0);
        let c = Vec3::new(1.0, 0.0, 1.0);
        let d = Vec3::new(-1.0, 0.0, 1.0);
        vec![[a, c, b], [a, d, c]]
    }

    #[test]
    fn hits_both_sides_and_reports_position() {
        let accel = Accel::build(&quad());
        let from_above = accel.intersect(Vec3::new(0.3, 2.0, 0.2), Vec3::NEG_Y, f32::INFINITY).unwrap();
        assert!((from_above.t - 2.0).abs() < 1e-5);
        let from_below = accel.intersect(Vec3::new(0.3, -2.0, 0.2), Vec3::Y, f32::INFINITY).unwrap();
        assert!((from_below.t - 2.0).abs() < 1e-5);
        assert!(accel.occluded(Vec3::new(0.0, 1.0, 0.0), Vec3::NEG_Y, 2.0));
        assert!(!accel.occluded(Vec3::new(0.0, 1.0, 0.0), Vec3::NEG_Y, 0.5));
    }

    #[test]
    fn hinted_shadow_tests_answer_as_the_traversal_does() {
        // 300 small random cards between a 60×60 grid of points on the floor
        // and a light above: every segment, tested in scan order with one
        // hint carried along, gets the plain traversal's answer, and the
        // hint holds a triangle that blocks the last blocked segment.
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(7);
        let mut next = || rng.random::<f32>();
        let mut cards = Vec::new();
        for _ in 0..300 {
            let c = Vec3::new(4.0 * next() - 2.0, 0.5 + 2.0 * next(), 4.0 * next() - 2.0);
            let (u, v) = (Vec3::new(0.4 * next(), 0.05 * next(), 0.0), Vec3::new(0.0, 0.05 * next(), 0.4 * next()));
            cards.push([c, c + u, c + v]);
        }
        let accel = Accel::build(&cards);
        let light = Vec3::new(0.3, 4.0, -0.2);
        let mut hint = OccluderHint::default();
        let (mut blocked, mut from_hint) = (0, 0);
        for k in 0..3600 {
            let p = Vec3::new(-2.0 + 4.0 * (k % 60) as f32 / 59.0, 0.0, -2.0 + 4.0 * (k / 60) as f32 / 59.0);
            let (dir, len) = ((light - p).normalize(), (light - p).length());
            let ray = Ray::new(p.into(), dir.into(), 0.0, len);
            from_hint += usize::from(hint.0.is_some_and(|id| accel.ordered[id as usize].intersect(&ray) < len));
            let hinted = accel.occluded_hinted(p, dir, len, &mut hint);
            assert_eq!(hinted, accel.occluded(p, dir, len), "segment {k}");
            if hinted {
                blocked += 1;
                let id = hint.0.expect("a blocked segment leaves its occluder") as usize;
                assert!(accel.ordered[id].intersect(&ray) < len, "segment {k}: the hint does not block it");
            }
        }
        assert!(blocked > 300 && blocked < 3300, "{blocked} of 3600 segments blocked");
        assert!(from_hint > blocked / 3, "only {from_hint} of {blocked} blocked segments answered by the hint");
    }

    #[test]
    fn empty_scene_misses() {
        let accel = Accel::build(&[]);
        assert!(accel.intersect(Vec3::ZERO, Vec3::Z, f32::INFINITY).is_none());
        assert!(!accel.occluded(Vec3::ZERO, Vec3::Z, 1.0));
    }

    #[test]
    fn barycentrics_reconstruct_the_hit() {
        let tris = quad();
        let accel = Accel::build(&tris);
        let o = Vec3::new(0.25, 3.0, -0.5);
        let h = accel.intersect(o, Vec3::NEG_Y, f32::INFINITY).unwrap();
        let t = tris[h.triangle as usize];
        let p = t[0] * (1.0 - h.u - h.v) + t[1] * h.u + t[2] * h.v;
        assert!((p - Vec3::new(0.25, 0.0, -0.5)).length() < 1e-5, "{p}");
    }
}
