//! Photon storage and radiance estimates.
//!
//! Photons live in a kiddo `ImmutableKdTree` (a static, cache-friendly k-d
//! tree; maps are rebuilt whole, never edited). The kNN estimate of
//! irradiance at x with normal n from the k nearest photons is
//!
//!   E(x) = Σ_{p<k} w_p Φ_p / (c_cone · π r²),   w_p = 1 − d_p/r,  c_cone = 1 − 2/3
//!
//! (Jensen 2001, cone filter with k_cone = 1), where r is the distance to
//! the k-th photon. The k-th photon only fixes the radius and is left out of
//! the sum: the classic kNN density estimator's bias correction ((k−1)
//! photons inside the ball, Fukunaga & Hostetler). Photons arriving from
//! behind the surface, or farther than r/4 from its tangent plane, are
//! skipped (they belong to another surface: corners, thin walls).

use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use std::num::NonZero;

/// Cone filter normalisation for k_cone = 1: 1 − 2/(3 k_cone).
const CONE_NORM: f32 = 1.0 / 3.0;

/// A k-d tree over `positions`, or none when there are none (kiddo needs
/// at least one point).
fn kd_tree(positions: impl Iterator<Item = Vec3>) -> Option<ImmutableKdTree<f32, 3>> {
    let points: Vec<[f32; 3]> = positions.map(|p| p.to_array()).collect();
    (!points.is_empty()).then(|| ImmutableKdTree::new_from_slice(&points))
}

/// One stored photon.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Photon {
    /// Where it landed.
    pub position: Vec3,
    /// Power (lm for the 1 cd source), RGB after surface colours.
    pub power: Vec3,
    /// Unit direction of travel when it arrived.
    pub dir: Vec3,
    /// Surface normal at the hit, facing the side the photon came from.
    pub normal: Vec3,
}

/// A set of photons with its k-d tree.
pub struct PhotonMap {
    /// The photons.
    pub photons: Vec<Photon>,
    tree: Option<ImmutableKdTree<f32, 3>>,
}

/// An irradiance estimate and the radius it used.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Irradiance (lx per cd of the source), RGB.
    pub irradiance: Vec3,
    /// Radius of the gather ball.
    pub radius: f32,
    /// Photons that contributed.
    pub count: usize,
}

impl PhotonMap {
    /// Builds the map's k-d tree (none for an empty map).
    pub fn new(photons: Vec<Photon>) -> Self {
        let tree = kd_tree(photons.iter().map(|p| p.position));
        Self { photons, tree }
    }

    /// Number of photons.
    pub fn len(&self) -> usize {
        self.photons.len()
    }

    /// True when the map holds no photons.
    pub fn is_empty(&self) -> bool {
        self.photons.is_empty()
    }

    /// kNN irradiance estimate at `x` (surface normal `n`, facing the side
    /// light arrives on) from up to `k` photons within `max_radius`.
    pub fn estimate(&self, x: Vec3, n: Vec3, k: usize, max_radius: f32) -> Estimate {
        let empty = Estimate { irradiance: Vec3::ZERO, radius: 0.0, count: 0 };
        let Some(tree) = &self.tree else { return empty };
        let Some(k) = NonZero::new(k.max(2)) else { return empty };
        let found = tree.nearest_n_within::<SquaredEuclidean>(&x.to_array(), max_radius * max_radius, k, true);
        if found.len() < 2 {
            return empty;
        }
        // A full set: r is the k-th photon's distance and that photon is left
        // out; fewer found: the search radius bounds the ball.
        let (r2, used) = if found.len() == k.get() {
            (found[found.len() - 1].distance, &found[..found.len() - 1])
        } else {
            (max_radius * max_radius, &found[..])
        };
        let r = r2.sqrt();
        if r.is_nan() || r <= 0.0 || r.is_infinite() {
            return empty;
        }
        let mut sum = Vec3::ZERO;
        let mut count = 0;
        for nb in used {
            let p = &self.photons[nb.item as usize];
            if p.dir.dot(n) >= 0.0 || (p.position - x).dot(n).abs() > 0.25 * r {
                continue;
            }
            let w = 1.0 - nb.distance.sqrt() / r;
            sum += p.power * w;
            count += 1;
        }
        Estimate { irradiance: sum / (CONE_NORM * std::f32::consts::PI * r2), radius: r, count }
    }

    /// Distance to the nearest photon (infinite for an empty map): a cheap
    /// test before a k-nearest gather.
    pub fn nearest_distance(&self, x: Vec3) -> f32 {
        match &self.tree {
            None => f32::INFINITY,
            Some(tree) => tree.nearest_one::<SquaredEuclidean>(&x.to_array()).distance.sqrt(),
        }
    }

    /// Photons within `radius` of `x` arriving on the front of `n`:
    /// Σ power (for progressive photon mapping).
    pub fn gather(&self, x: Vec3, n: Vec3, radius2: f32) -> (Vec3, usize) {
        let Some(tree) = &self.tree else { return (Vec3::ZERO, 0) };
        let mut sum = Vec3::ZERO;
        let mut count = 0;
        let r = radius2.sqrt();
        for nb in tree.within_unsorted::<SquaredEuclidean>(&x.to_array(), radius2) {
            let p = &self.photons[nb.item as usize];
            if p.dir.dot(n) >= 0.0 || (p.position - x).dot(n).abs() > 0.25 * r {
                continue;
            }
            sum += p.power;
            count += 1;
        }
        (sum, count)
    }
}

/// Irradiance precomputed at a subset of global photons (Christensen 1999,
/// "Faster photon map global illumination"): a shading point then needs a
/// few nearest-neighbour lookups instead of a 150-photon gather.
pub struct IrradianceCache {
    points: Vec<CachePoint>,
    tree: Option<ImmutableKdTree<f32, 3>>,
}

#[derive(Clone, Copy, Debug)]
struct CachePoint {
    position: Vec3,
    normal: Vec3,
    irradiance: Vec3,
    radius: f32,
}

/// Cache points consulted per lookup.
const CACHE_NEIGHBOURS: usize = 4;

impl IrradianceCache {
    /// Estimates irradiance at every `stride`-th photon of `map` from its
    /// `k` nearest photons, about the surface normal where it landed.
    pub fn build(map: &PhotonMap, k: usize, stride: usize, max_radius: f32) -> Self {
        let empty = PhotonMap::new(Vec::new());
        Self::build_with_caustics(map, &empty, (k, stride, max_radius), (1, 1, max_radius))
    }

    /// One cache for both maps: cache points at every `stride`-th global and
    /// caustic photon, each holding global + caustic irradiance there, so a
    /// shading point needs one lookup for all indirect light. Each argument
    /// triple is (k, stride, gather radius limit) of its map.
    pub fn build_with_caustics(
        global: &PhotonMap,
        caustic: &PhotonMap,
        (k, stride, max_radius): (usize, usize, f32),
        (kc, stride_c, radius_c): (usize, usize, f32),
    ) -> Self {
        let at = |p: &Photon| {
            let g = global.estimate(p.position, p.normal, k, max_radius);
            // Most points are nowhere near a caustic: a nearest-neighbour test first.
            let c = if !caustic.is_empty() && caustic.nearest_distance(p.position) < radius_c {
                caustic.estimate(p.position, p.normal, kc, radius_c)
            } else {
                Estimate { irradiance: Vec3::ZERO, radius: 0.0, count: 0 }
            };
            // The acceptance radius is the finer of the two gathers that found photons.
            let radius = match (g.count > 0, c.count > 0) {
                (true, true) => g.radius.min(c.radius),
                (true, false) => g.radius,
                (false, true) => c.radius,
                (false, false) => return None,
            };
            let irradiance = g.irradiance + c.irradiance;
            irradiance.is_finite().then_some(CachePoint { position: p.position, normal: p.normal, irradiance, radius })
        };
        let mut points: Vec<CachePoint> = global.photons.par_iter().step_by(stride.max(1)).filter_map(at).collect();
        points.extend(caustic.photons.par_iter().step_by(stride_c.max(1)).filter_map(at).collect::<Vec<_>>());
        let tree = kd_tree(points.iter().map(|p| p.position));
        Self { points, tree }
    }

    /// Number of cache points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when nothing was cached (no indirect light).
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Gather radius of the cache point nearest to `x`, if any: the local
    /// photon spacing, used to start progressive photon mapping.
    pub fn radius_near(&self, x: Vec3) -> Option<f32> {
        let tree = self.tree.as_ref()?;
        let nb = tree.nearest_one::<SquaredEuclidean>(&x.to_array());
        Some(self.points[nb.item as usize].radius)
    }

    /// Irradiance at `x` with normal `n`: cone-weighted mean of the nearest
    /// cache points whose normals agree and whose gather balls reach `x`.
    pub fn lookup(&self, x: Vec3, n: Vec3) -> Vec3 {
        let Some(tree) = &self.tree else { return Vec3::ZERO };
        let k = NonZero::new(CACHE_NEIGHBOURS).expect("non-zero");
        let mut sum = Vec3::ZERO;
        let mut weights = 0.0;
        for nb in tree.nearest_n::<SquaredEuclidean>(&x.to_array(), k) {
            let c = &self.points[nb.item as usize];
            let d = nb.distance.sqrt();
            if c.normal.dot(n) < 0.7 || d >= c.radius {
                continue;
            }
            let w = 1.0 - d / c.radius;
            sum += c.irradiance * w;
            weights += w;
        }
        if weights > 0.0 { sum / weights } else { Vec3::ZERO }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform photons on the unit square z = 0 arriving straight down:
    /// irradiance = total power / area.
    fn uniform(n_side: usize, total: f32) -> PhotonMap {
        let mut v = Vec::new();
        for i in 0..n_side {
            for j in 0..n_side {
                // Jittered grid (deterministic).
                let jx = ((i * 7 + j * 13) % 17) as f32 / 17.0;
                let jy = ((i * 11 + j * 5) % 19) as f32 / 19.0;
                let p = Vec3::new((i as f32 + jx) / n_side as f32, (j as f32 + jy) / n_side as f32, 0.0);
                v.push(Photon {
                    position: p,
                    power: Vec3::splat(total / (n_side * n_side) as f32),
                    dir: Vec3::NEG_Z,
                    normal: Vec3::Z,
                });
            }
        }
        PhotonMap::new(v)
    }

    #[test]
    fn uniform_density_gives_exact_irradiance() {
        let m = uniform(200, 10.0);
        for x in [Vec3::new(0.5, 0.5, 0.0), Vec3::new(0.3, 0.6, 0.0)] {
            let e = m.estimate(x, Vec3::Z, 150, 1.0);
            assert!((e.irradiance.x - 10.0).abs() < 0.05 * 10.0, "{e:?}");
            let c = IrradianceCache::build(&m, 150, 4, 1.0);
            assert!((c.lookup(x, Vec3::Z).x - 10.0).abs() < 0.05 * 10.0);
        }
        // Photons arriving from behind do not count.
        assert_eq!(m.estimate(Vec3::splat(0.5), Vec3::NEG_Z, 150, 1.0).count, 0);
    }

    #[test]
    fn empty_and_coincident_maps_are_finite() {
        let empty = PhotonMap::new(Vec::new());
        assert_eq!(empty.estimate(Vec3::ZERO, Vec3::Z, 150, 1.0).irradiance, Vec3::ZERO);
        assert!(IrradianceCache::build(&empty, 150, 1, 1.0).is_empty());
        let same =
            PhotonMap::new(vec![
                Photon { position: Vec3::ONE, power: Vec3::ONE, dir: Vec3::NEG_Z, normal: Vec3::Z };
                500
            ]);
        let e = same.estimate(Vec3::ONE, Vec3::Z, 150, 1.0);
        assert!(e.irradiance.is_finite());
        let c = IrradianceCache::build(&same, 150, 1, 1.0);
        assert!(c.lookup(Vec3::ONE, Vec3::Z).is_finite());
        let (sum, n) = same.gather(Vec3::ONE, Vec3::Z, 0.01);
        assert_eq!((sum, n), (Vec3::splat(500.0), 500));
    }
}
