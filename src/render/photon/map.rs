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
//! behind the surface, landing on a surface whose normal is more than 45°
//! off, or farther than r/4 from its tangent plane, are skipped (they belong
//! to another surface: corners, thin walls).
//!
//! The irradiance cache ([`IrradianceCache`]) holds estimates at every
//! stride-th photon, each made from the *other* photons, so cache values do
//! not depend on where the cache points are (no self-counting, no crowding
//! bias); a lookup that finds no fitting cache point returns `None` and the
//! caller falls back to the kNN estimate (no black holes).

use crate::scene::open_edges::OpenEdges;
use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use std::num::NonZero;
use std::sync::Arc;

/// Cone filter normalisation for k_cone = 1: 1 − 2/(3 k_cone).
const CONE_NORM: f32 = 1.0 / 3.0;

/// Normals of a photon's surface and a gather point closer than this (cos)
/// belong to different surfaces (the irradiance cache uses the same bound).
const SAME_SURFACE_COS: f32 = 0.7;

/// True when photon `p` lit the surface at `x` with normal `n` (gather
/// radius `r`): it arrived from the front of `n`, landed on a surface facing
/// the same way, and lies within r/4 of the tangent plane. Photons from
/// behind a thin wall or from the other face of a corner fail one of these.
fn same_surface(p: &Photon, x: Vec3, n: Vec3, r: f32) -> bool {
    p.dir.dot(n) < 0.0 && p.normal.dot(n) >= SAME_SURFACE_COS && (p.position - x).dot(n).abs() <= 0.25 * r
}

/// Records the edge that photon `p` of another surface marks for a gather
/// at `x` (normal `n`): the line where `p`'s plane meets the tangent plane,
/// at in-plane distance |(x − p)·n_p| / sin θ. Only surfaces 45-135° off
/// cut the disk (a parallel one is a thin wall's back, not an edge); the
/// nearest cut per surface orientation is kept, for at most two.
fn note_cut(cuts: &mut [Option<(Vec3, f32)>; 2], p: &Photon, x: Vec3, n: Vec3) {
    let c = p.normal.dot(n);
    if c.abs() > SAME_SURFACE_COS {
        return;
    }
    let d = (x - p.position).dot(p.normal).abs() / (1.0 - c * c).sqrt();
    merge_cut(cuts, p.normal, d);
}

/// Keeps a cut of the gather disk at in-plane distance `d`, `m` the normal
/// of the surface beyond it (facing back toward the centre): the nearest
/// cut per orientation, for at most two orientations.
fn merge_cut(cuts: &mut [Option<(Vec3, f32)>; 2], m: Vec3, d: f32) {
    for slot in cuts.iter_mut() {
        match slot {
            Some((seen, best)) if seen.dot(m) >= 0.9 => {
                *best = best.min(d);
                return;
            }
            Some(_) => {}
            None => {
                *slot = Some((m, d));
                return;
            }
        }
    }
}

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
    /// How estimates treat a gather disk that crosses the surface's edge.
    boundary: BoundaryMode,
    /// The estimate's kernel.
    filter: Filter,
    /// The scene's open edges, cuts no photon marks ([`OpenEdges`]).
    open: Option<Arc<OpenEdges>>,
}

/// The kernel of a kNN irradiance estimate (issue 13: the indirect term's
/// error at the paper's settings is mostly variance, see `footlight bench
/// --accuracy-only`).
///
/// For photons spread evenly over the disk the relative variance of a
/// k-photon estimate is (1/k)·E[w²]/E[w]²: 1/k for the uniform disk and
/// 1.5/k for the cone 1 − s/r (E[w] = 1/3, E[w²] = 1/6 over the unit disk).
/// The cone blurs less (weighted E[s²] = 0.3 r² against 0.5 r²), which only
/// matters where the irradiance curves within the gather disk.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Filter {
    /// Cone filter w = 1 − s/r (Jensen 2001), normalised by π r²/3: sharper,
    /// 1.5× the variance of [`Filter::Disk`] at the same k.
    #[default]
    Cone,
    /// Uniform disk w = 1, normalised by π r² (the plain kNN density estimate).
    Disk,
}

impl Filter {
    /// Weight of a photon at distance `s` in a disk of radius `r`.
    fn weight(self, s: f32, r: f32) -> f32 {
        match self {
            Filter::Cone => 1.0 - s / r,
            Filter::Disk => 1.0,
        }
    }

    /// ∫ w over the unit disk / π.
    fn norm(self) -> f32 {
        match self {
            Filter::Cone => CONE_NORM,
            Filter::Disk => 1.0,
        }
    }

    /// Share of the kernel's weight beyond a straight cut `delta` radii
    /// from the centre.
    fn beyond(self, delta: f32) -> f32 {
        match self {
            Filter::Cone => cone_weight_beyond(delta),
            Filter::Disk => disk_share_beyond(delta),
        }
    }
}

/// Share of the unit disk's area beyond a straight cut at distance `delta`
/// from the centre (circular segment: (acos δ − δ √(1 − δ²)) / π).
pub fn disk_share_beyond(delta: f32) -> f32 {
    let d = delta.clamp(0.0, 1.0);
    (d.acos() - d * (1.0 - d * d).max(0.0).sqrt()) / std::f32::consts::PI
}

/// How a kNN estimate normalises a gather disk that reaches past the edge
/// of the gathering surface (a floor meeting a wall, a box corner, the top
/// edge of a riser). The photons of the other surface are not counted
/// ([`same_surface`]), so dividing by the full disk's area reads low there.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BoundaryMode {
    /// Divide by the whole disk (Jensen 2001): biased low at edges and
    /// corners (−16 % mean at the test box's walls and corners).
    None,
    /// Divide by the part of the disk on this surface: each other surface
    /// whose photons are in the ball (normal 45-135° off) cuts the disk
    /// along the line where its plane meets the tangent plane; the cone
    /// filter's weight beyond that line ([`cone_weight_beyond`]) is taken out
    /// of the normalisation (two cuts: the product of both kept shares).
    Clip,
    /// As `Clip`, with each cut's distance measured from the photons of
    /// this surface: their mean offset toward the other surface, against
    /// the mean offset of a uniformly covered disk cut at δ
    /// ([`kept_centroid`]), gives δ; the cut is never put nearer than the
    /// plane-intersection line of `Clip`. A wall plane that does not reach
    /// across the whole disk (a column, a truss, a chair leg, a facet of a
    /// curved object) leaves this surface's photons on both sides of its
    /// line, so the measured cut moves out and the disk keeps its area,
    /// where `Clip` over-corrects (issue 13: +10 % on the bundled stage).
    /// The default: the lowest indirect error of the three on the box, the
    /// box with a tessellated sphere and the bundled stage (`footlight bench
    /// --accuracy-only`).
    #[default]
    Measured,
}

/// Mean offset (in radii) of a uniformly covered unit disk cut at `delta`,
/// away from the cut: (2/3)(1 − δ²)^{3/2} / (π (1 − segment share)),
/// 4/(3π) ≈ 0.424 at δ = 0 (a half disk), 0 at δ = 1.
pub fn kept_centroid(delta: f32) -> f32 {
    let d = delta.clamp(0.0, 1.0);
    let kept = 1.0 - disk_share_beyond(d);
    (2.0 / 3.0) * (1.0 - d * d).max(0.0).powf(1.5) / (std::f32::consts::PI * kept)
}

/// The cut distance δ whose [`kept_centroid`] is `offset` (bisection;
/// 1 for no offset, 0 past a half disk's).
fn cut_from_centroid(offset: f32) -> f32 {
    if offset.is_nan() || offset <= 0.0 {
        return 1.0;
    }
    let (mut lo, mut hi) = (0.0f32, 1.0f32);
    for _ in 0..20 {
        let mid = 0.5 * (lo + hi);
        if kept_centroid(mid) > offset { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

/// Share of the cone filter's weight (1 − s/r over the unit disk) lying
/// beyond a straight cut at distance `delta` (in radii) from the centre:
/// 1/2 at δ = 0, 0 at δ ≥ 1. Integrated numerically once (Simpson in x of
/// the closed-form inner integral) and interpolated from a 129-entry table.
pub fn cone_weight_beyond(delta: f32) -> f32 {
    const N: usize = 128;
    static TABLE: std::sync::OnceLock<[f32; N + 1]> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        // ∫_{-h}^{h} (1 − √(x² + y²)) dy with h = √(1 − x²), in closed form.
        let strip = |x: f64| {
            let h = (1.0 - x * x).max(0.0).sqrt();
            if h == 0.0 {
                return 0.0;
            }
            // ∫_{-h}^{h} √(x²+y²) dy = h·1 + x² ln((h + 1)/|x|) (with √(x²+h²) = 1).
            let root = if x.abs() < 1e-12 { h * h } else { h + x * x * ((h + 1.0) / x.abs()).ln() };
            2.0 * h - root
        };
        let total = std::f64::consts::PI / 3.0;
        let mut t = [0f32; N + 1];
        for (i, out) in t.iter_mut().enumerate() {
            let d = i as f64 / N as f64;
            let m = 2000;
            let step = (1.0 - d) / m as f64;
            let mut sum = strip(d) + strip(1.0);
            for j in 1..m {
                sum += strip(d + j as f64 * step) * if j % 2 == 1 { 4.0 } else { 2.0 };
            }
            *out = (sum * step / 3.0 / total) as f32;
        }
        t
    });
    if delta.is_nan() || delta >= 1.0 {
        return 0.0;
    }
    let x = delta.max(0.0) * N as f32;
    let i = (x as usize).min(N - 1);
    let f = x - i as f32;
    table[i] * (1.0 - f) + table[i + 1] * f
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
        Self { photons, tree, boundary: BoundaryMode::default(), filter: Filter::default(), open: None }
    }

    /// The same map with estimates weighting photons by `filter`.
    pub fn with_filter(mut self, filter: Filter) -> Self {
        self.filter = filter;
        self
    }

    /// Takes the scene's open edges ([`OpenEdges`]) as cuts of the gather
    /// disk too (with any [`BoundaryMode`] but `None`): past a floor's lip
    /// no photon lands to mark one.
    pub fn with_open_edges(mut self, open: Arc<OpenEdges>) -> Self {
        self.open = Some(open);
        self
    }

    /// The cuts of the scene's open edges in the disk of radius `r` about
    /// `x` (normal `n`), added to `cuts` ([`merge_cut`]).
    fn note_open_edges(&self, cuts: &mut [Option<(Vec3, f32)>; 2], x: Vec3, n: Vec3, r: f32) {
        if self.boundary == BoundaryMode::None {
            return;
        }
        if let Some(open) = &self.open {
            for (toward, d) in open.near(x, n, r) {
                // As a wall there would: its normal faces back toward x.
                merge_cut(cuts, -toward, d);
            }
        }
    }

    /// The same map with estimates treating edges as `mode` says.
    pub fn with_boundary(mut self, mode: BoundaryMode) -> Self {
        self.boundary = mode;
        self
    }

    /// True when another surface's photons (normal more than 45° off `n`)
    /// are among the `k` nearest to `x`: `x` is near an edge or a corner.
    pub fn other_surface_near(&self, x: Vec3, n: Vec3, k: usize) -> bool {
        let (Some(tree), Some(k)) = (&self.tree, NonZero::new(k)) else { return false };
        tree.nearest_n::<SquaredEuclidean>(&x.to_array(), k)
            .iter()
            .any(|nb| self.photons[nb.item as usize].normal.dot(n) < SAME_SURFACE_COS)
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
        self.estimate_without(x, n, k, max_radius, None)
    }

    /// As [`PhotonMap::estimate`], leaving photon `skip` out (leave-one-out):
    /// an estimate *at* a stored photon must not count that photon, whose
    /// presence there is what put the estimate there. Counting it adds one
    /// photon at full cone weight: a relative bias of about 3/k (+3.5 % at
    /// k = 50 on a uniform field). For a Poisson field the other photons seen
    /// from a photon are again a Poisson field of the same density (Palm
    /// distribution), so the leave-one-out estimate is as unbiased as the
    /// plain kNN estimate at an arbitrary point.
    pub fn estimate_without(&self, x: Vec3, n: Vec3, k: usize, max_radius: f32, skip: Option<usize>) -> Estimate {
        let empty = Estimate { irradiance: Vec3::ZERO, radius: 0.0, count: 0 };
        let Some(tree) = &self.tree else { return empty };
        let k = k.max(2);
        let Some(k_search) = NonZero::new(k + usize::from(skip.is_some())) else { return empty };
        let mut found =
            tree.nearest_n_within::<SquaredEuclidean>(&x.to_array(), max_radius * max_radius, k_search, true);
        if let Some(skip) = skip {
            match found.iter().position(|nb| nb.item as usize == skip) {
                Some(i) => {
                    found.remove(i);
                }
                None => found.truncate(k),
            }
        }
        if found.len() < 2 {
            return empty;
        }
        // A full set: r is the k-th photon's distance and that photon is left
        // out; fewer found: the search radius bounds the ball.
        let (r2, used) = if found.len() == k {
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
        // Sum of this surface's photon offsets from x (for `Measured`).
        let mut offsets = Vec3::ZERO;
        // Up to two other surfaces cutting the disk: (their normal, cut distance).
        let mut cuts: [Option<(Vec3, f32)>; 2] = [None; 2];
        for nb in used {
            let p = &self.photons[nb.item as usize];
            if !same_surface(p, x, n, r) {
                if self.boundary != BoundaryMode::None {
                    note_cut(&mut cuts, p, x, n);
                }
                continue;
            }
            let w = self.filter.weight(nb.distance.sqrt(), r);
            sum += p.power * w;
            offsets += p.position - x;
            count += 1;
        }
        self.note_open_edges(&mut cuts, x, n, r);
        let kept = self.kept_share(cuts, offsets, count, n, r, self.filter);
        let area = self.filter.norm() * std::f32::consts::PI * r2 * kept;
        Estimate { irradiance: sum / area, radius: r, count }
    }

    /// The photons that are *not* every `stride`-th one (index % stride ≠ 0),
    /// with power scaled by stride/(stride − 1) so they estimate the same
    /// irradiance; `None` for stride < 2 or when nothing would be left.
    pub fn thinned_complement(&self, stride: usize) -> Option<PhotonMap> {
        if stride < 2 || self.photons.len() < 2 {
            return None;
        }
        let scale = stride as f32 / (stride - 1) as f32;
        let rest: Vec<Photon> = self
            .photons
            .iter()
            .enumerate()
            .filter(|(i, _)| i % stride != 0)
            .map(|(_, p)| Photon { power: p.power * scale, ..*p })
            .collect();
        (!rest.is_empty()).then(|| PhotonMap {
            open: self.open.clone(),
            ..PhotonMap::new(rest).with_boundary(self.boundary).with_filter(self.filter)
        })
    }

    /// Distance to the nearest photon (infinite for an empty map): a cheap
    /// test before a k-nearest gather.
    pub fn nearest_distance(&self, x: Vec3) -> f32 {
        match &self.tree {
            None => f32::INFINITY,
            Some(tree) => tree.nearest_one::<SquaredEuclidean>(&x.to_array()).distance.sqrt(),
        }
    }

    /// Photons within `radius` of `x` on the gathering surface ([`same_surface`]):
    /// their Σ power, divided by the share of the disk on that surface
    /// where other surfaces cut it ([`BoundaryMode`], uniform weights), and
    /// their count (for progressive photon mapping).
    pub fn gather(&self, x: Vec3, n: Vec3, radius2: f32) -> (Vec3, usize) {
        let Some(tree) = &self.tree else { return (Vec3::ZERO, 0) };
        let mut sum = Vec3::ZERO;
        let mut count = 0;
        let r = radius2.sqrt();
        let mut offsets = Vec3::ZERO;
        let mut cuts: [Option<(Vec3, f32)>; 2] = [None; 2];
        for nb in tree.within_unsorted::<SquaredEuclidean>(&x.to_array(), radius2) {
            let p = &self.photons[nb.item as usize];
            if !same_surface(p, x, n, r) {
                if self.boundary != BoundaryMode::None {
                    note_cut(&mut cuts, p, x, n);
                }
                continue;
            }
            sum += p.power;
            offsets += p.position - x;
            count += 1;
        }
        if count == 0 || r.is_nan() || r <= 0.0 {
            return (sum, count);
        }
        // Per whole disk: the photons on this surface stand for the part
        // of the disk it covers (issue 34 item 4: without this, SPPM's
        // passes read low at every edge and corner and pull the photon-map
        // estimate's boundary correction back down as they take over).
        self.note_open_edges(&mut cuts, x, n, r);
        (sum / self.kept_share(cuts, offsets, count, n, r, Filter::Disk), count)
    }

    /// The share of a gather disk's kernel weight (`filter`) that lies on
    /// the gathering surface ([`BoundaryMode`]): 1 without cuts, at least
    /// 1/4. `cuts` are the other surfaces' lines ([`note_cut`]), `offsets`
    /// the sum of this surface's `count` photon offsets from the centre
    /// (for [`BoundaryMode::Measured`]), `n` the normal, `r` the radius.
    fn kept_share(
        &self,
        mut cuts: [Option<(Vec3, f32)>; 2],
        offsets: Vec3,
        count: usize,
        n: Vec3,
        r: f32,
        filter: Filter,
    ) -> f32 {
        if self.boundary == BoundaryMode::Measured && count > 0 {
            for (m, d) in cuts.iter_mut().flatten() {
                // Toward the other surface, in the tangent plane: against
                // its normal (which faces the lit side, toward x).
                let Some(u) = (-(*m - m.dot(n) * n)).try_normalize() else { continue };
                let away = -offsets.dot(u) / (count as f32 * r);
                *d = d.max(cut_from_centroid(away) * r);
            }
        }
        let kept: f32 = cuts.iter().flatten().map(|(_, d)| 1.0 - filter.beyond(d / r)).product();
        kept.max(0.25)
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
        // Cache points sit at every stride-th photon. Their estimates come from
        // the *other* photons of that map (power scaled for the thinning), so
        // where a cache point is does not depend on the photons that set its
        // value. Estimating from photons that include the point's own (or its
        // fellow cache points') biases the cache: its own photon at full cone
        // weight adds ~3/k, and cache points crowd where photons crowd, so a
        // normalised interpolation favours their high values (+3.5 % together
        // at k = 50 on a uniform field, issue 13). With stride 1 every photon
        // is a cache point and the estimate leaves just its own photon out.
        let rest_global = global.thinned_complement(stride);
        let rest_caustic = caustic.thinned_complement(stride_c);
        let at = |p: &Photon, index: usize, in_global: bool| {
            let g = match (&rest_global, in_global) {
                (Some(rest), true) => rest.estimate(p.position, p.normal, k, max_radius),
                (None, true) => global.estimate_without(p.position, p.normal, k, max_radius, Some(index)),
                (_, false) => global.estimate(p.position, p.normal, k, max_radius),
            };
            // Most points are nowhere near a caustic: a nearest-neighbour test first.
            let c = if !caustic.is_empty() && caustic.nearest_distance(p.position) < radius_c {
                match (&rest_caustic, in_global) {
                    (Some(rest), false) => rest.estimate(p.position, p.normal, kc, radius_c),
                    (None, false) => caustic.estimate_without(p.position, p.normal, kc, radius_c, Some(index)),
                    (_, true) => caustic.estimate(p.position, p.normal, kc, radius_c),
                }
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
        let mut points: Vec<CachePoint> =
            global.photons.par_iter().enumerate().step_by(stride.max(1)).filter_map(|(i, p)| at(p, i, true)).collect();
        points.extend(
            caustic
                .photons
                .par_iter()
                .enumerate()
                .step_by(stride_c.max(1))
                .filter_map(|(i, p)| at(p, i, false))
                .collect::<Vec<_>>(),
        );
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
    /// cache points whose normals agree and whose gather balls reach `x`;
    /// `None` when none of them fits (corners, thin parts, sparse regions),
    /// so the caller can fall back to a direct estimate instead of showing
    /// a black hole.
    pub fn lookup(&self, x: Vec3, n: Vec3) -> Option<Vec3> {
        self.lookup_among(x, n, CACHE_NEIGHBOURS)
    }

    /// As [`IrradianceCache::lookup`], consulting the `neighbours` nearest
    /// cache points (at least 1).
    pub fn lookup_among(&self, x: Vec3, n: Vec3, neighbours: usize) -> Option<Vec3> {
        let tree = self.tree.as_ref()?;
        let k = NonZero::new(neighbours.max(1)).expect("non-zero");
        let found = tree.nearest_n::<SquaredEuclidean>(&x.to_array(), k);
        let fits = |c: &CachePoint, d: f32| c.normal.dot(n) >= SAME_SURFACE_COS && d < c.radius;
        let (mut reach, mut fitting) = (0.0f32, 0usize);
        for nb in &found {
            let c = &self.points[nb.item as usize];
            if fits(c, nb.distance.sqrt()) {
                reach += c.radius;
                fitting += 1;
            }
        }
        if fitting == 0 {
            return None;
        }
        reach /= fitting as f32;
        let mut sum = Vec3::ZERO;
        let mut weights = 0.0;
        for nb in &found {
            let c = &self.points[nb.item as usize];
            let d = nb.distance.sqrt();
            if fits(c, d) && d < reach {
                let w = 1.0 - d / reach;
                sum += c.irradiance * w;
                weights += w;
            }
        }
        (weights > 0.0).then(|| sum / weights)
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

    /// The unit square z = 0 as a scene: every edge of it open.
    fn unit_square_scene() -> crate::scene::Scene {
        let mut b = crate::scene::SceneBuilder::new();
        let m = b.add_material(crate::scene::Material::lambert("floor", Vec3::splat(0.5)));
        b.add_quad(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            m,
        );
        b.build()
    }

    #[test]
    fn an_open_edge_cuts_the_gather_disk() {
        // Uniform photons on a square with nothing beyond its edges: near
        // an edge a kNN or SPPM gather reads low unless the edge cuts the
        // disk (issue 34 item 4: 0.78-0.82 at the box stage's open edges).
        let plain = uniform(200, 10.0);
        let open = uniform(200, 10.0).with_open_edges(unit_square_scene().open_edges());
        for x in [Vec3::new(0.995, 0.5, 0.0), Vec3::new(0.5, 0.004, 0.0), Vec3::new(0.003, 0.996, 0.0)] {
            let (without, with) = (plain.estimate(x, Vec3::Z, 150, 1.0), open.estimate(x, Vec3::Z, 150, 1.0));
            assert!(without.irradiance.x < 0.85 * 10.0, "{x}: without the edge {without:?}");
            assert!((with.irradiance.x - 10.0).abs() < 0.06 * 10.0, "{x}: with the edge {with:?}");
            let r2 = 0.05f32 * 0.05;
            let (phi, n) = open.gather(x, Vec3::Z, r2);
            let e = phi.x / (std::f32::consts::PI * r2);
            assert!(n > 0 && (e - 10.0).abs() < 0.1 * 10.0, "{x}: SPPM gather {e} from {n} photons");
        }
        // Far from every edge nothing changes.
        let x = Vec3::new(0.5, 0.5, 0.0);
        assert_eq!(plain.estimate(x, Vec3::Z, 150, 1.0).irradiance, open.estimate(x, Vec3::Z, 150, 1.0).irradiance);
    }

    #[test]
    fn uniform_density_gives_exact_irradiance() {
        let m = uniform(200, 10.0);
        for x in [Vec3::new(0.5, 0.5, 0.0), Vec3::new(0.3, 0.6, 0.0)] {
            let e = m.estimate(x, Vec3::Z, 150, 1.0);
            assert!((e.irradiance.x - 10.0).abs() < 0.05 * 10.0, "{e:?}");
            let c = IrradianceCache::build(&m, 150, 4, 1.0);
            assert!((c.lookup(x, Vec3::Z).unwrap().x - 10.0).abs() < 0.05 * 10.0);
        }
        // Photons arriving from behind do not count.
        assert_eq!(m.estimate(Vec3::splat(0.5), Vec3::NEG_Z, 150, 1.0).count, 0);
    }

    /// A uniform (binomial, i.e. Poisson-like) photon field: `n` photons at
    /// seeded random spots on the unit square, arriving straight down.
    fn random_field(n: usize, power: f32, seed: u64) -> PhotonMap {
        use rand::SeedableRng;
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
        PhotonMap::new(floor_photons(&mut rng, n, power))
    }

    /// `n` photons of `power` at random spots on the unit square of the
    /// floor z = 0, arriving straight down, drawn from `rng`.
    fn floor_photons(rng: &mut impl rand::Rng, n: usize, power: f32) -> Vec<Photon> {
        (0..n)
            .map(|_| Photon {
                position: Vec3::new(rng.random(), rng.random(), 0.0),
                power: Vec3::splat(power),
                dir: Vec3::NEG_Z,
                normal: Vec3::Z,
            })
            .collect()
    }

    /// Mean of `f` over a 80×80 grid in the square [0.2, 0.8]², and the
    /// exact mean irradiance there: the power of the photons inside / area
    /// (so the photons' own sampling noise cancels out of the comparison).
    fn interior_mean(m: &PhotonMap, f: impl Fn(Vec3) -> f32) -> (f32, f32) {
        let n = 80;
        let mut sum = 0.0f64;
        for i in 0..n {
            for j in 0..n {
                let x =
                    Vec3::new(0.2 + 0.6 * (i as f32 + 0.5) / n as f32, 0.2 + 0.6 * (j as f32 + 0.5) / n as f32, 0.0);
                sum += f64::from(f(x));
            }
        }
        let inside = |p: &Photon| (0.2..0.8).contains(&p.position.x) && (0.2..0.8).contains(&p.position.y);
        let power: f64 = m.photons.iter().filter(|p| inside(p)).map(|p| f64::from(p.power.x)).sum();
        ((sum / (n * n) as f64) as f32, (power / 0.36) as f32)
    }

    #[test]
    fn cache_does_not_count_its_own_photon() {
        // Issue 13.2: cache points sit on photons; counting that photon at full
        // cone weight biased the cache upward (+3.5 % at k = 50).
        let m = random_field(200_000, 1e-4, 7);
        for k in [50, 150] {
            let c = IrradianceCache::build(&m, k, 4, 1.0);
            let (cache, exact) = interior_mean(&m, |x| c.lookup(x, Vec3::Z).expect("cache covers the interior").x);
            let (knn, _) = interior_mean(&m, |x| m.estimate(x, Vec3::Z, k, 1.0).irradiance.x);
            eprintln!("k {k}: exact {exact}, cache {cache}, kNN {knn}");
            assert!((cache - exact).abs() < 0.005 * exact, "k {k}: cache mean {cache}, exact {exact}");
            assert!((knn - exact).abs() < 0.005 * exact, "k {k}: kNN mean {knn}, exact {exact}");
        }
    }

    #[test]
    fn lookup_without_a_fitting_cache_point_is_none() {
        let m = uniform(50, 1.0);
        let c = IrradianceCache::build(&m, 50, 1, 1.0);
        // A normal no cache point shares (a wall standing on the field).
        assert_eq!(c.lookup(Vec3::new(0.5, 0.5, 0.0), Vec3::X), None);
        assert!(c.lookup(Vec3::new(0.5, 0.5, 0.0), Vec3::Z).is_some());
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
        assert!(c.lookup(Vec3::ONE, Vec3::Z).is_none_or(|e| e.is_finite()));
        let (sum, n) = same.gather(Vec3::ONE, Vec3::Z, 0.01);
        assert_eq!((sum, n), (Vec3::splat(500.0), 500));
    }

    #[test]
    fn cone_weight_beyond_a_cut_matches_quadrature() {
        // Midpoint quadrature of (1 − s) over the unit disk on a 2000² grid.
        let m = 2000;
        let mut beyond = [0f64; 5];
        let mut total = 0f64;
        let cuts = [0.0, 0.25, 0.5, 0.75, 0.95];
        for i in 0..m {
            for j in 0..m {
                let (x, y) = (-1.0 + (i as f64 + 0.5) * 2.0 / m as f64, -1.0 + (j as f64 + 0.5) * 2.0 / m as f64);
                let s = (x * x + y * y).sqrt();
                if s < 1.0 {
                    total += 1.0 - s;
                    for (b, c) in beyond.iter_mut().zip(cuts) {
                        if x > c {
                            *b += 1.0 - s;
                        }
                    }
                }
            }
        }
        for (b, c) in beyond.iter().zip(cuts) {
            let got = cone_weight_beyond(c as f32);
            assert!((got as f64 - b / total).abs() < 1e-3, "cut {c}: {got} vs {}", b / total);
        }
        assert_eq!(cone_weight_beyond(1.0), 0.0);
        assert_eq!(cone_weight_beyond(f32::NAN), 0.0);
    }

    #[test]
    fn estimate_next_to_a_wall_is_not_biased_low() {
        // A uniform photon field on the floor z = 0, x in [0, 1], meeting a
        // wall x = 1 (photons there have normal −X): within a gather radius
        // of the wall, the full-disk estimate divides by area that is not
        // floor; the clipped one does not.
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
        let n = 200_000;
        let mut v = floor_photons(&mut rng, n, 1.0 / n as f32);
        v.extend((0..n).map(|_| Photon {
            position: Vec3::new(1.0, rng.random(), rng.random()),
            power: Vec3::splat(1.0 / n as f32),
            dir: Vec3::X,
            normal: Vec3::NEG_X,
        }));
        let clipped = PhotonMap::new(v.clone()).with_boundary(BoundaryMode::Clip);
        let clipped_disk = PhotonMap::new(v.clone()).with_boundary(BoundaryMode::Clip).with_filter(Filter::Disk);
        let measured = PhotonMap::new(v.clone()).with_boundary(BoundaryMode::Measured).with_filter(Filter::Disk);
        let plain = PhotonMap::new(v).with_boundary(BoundaryMode::None);
        let mean = |m: &PhotonMap, x: f32| {
            (0..40)
                .map(|j| m.estimate(Vec3::new(x, 0.3 + 0.01 * j as f32, 0.0), Vec3::Z, 150, 1.0).irradiance.x)
                .sum::<f32>()
                / 40.0
        };
        // Exact floor irradiance: 1 (unit power on unit area).
        // The gather radius here is about 0.015.
        for (x, low) in [(0.999, 0.7), (0.997, 0.75), (0.995, 0.85)] {
            let (c, p) = (mean(&clipped, x), mean(&plain, x));
            eprintln!("x {x}: clipped {c}, full disk {p}");
            assert!((c - 1.0).abs() < 0.05, "clipped estimate {c} at x = {x}");
            let cd = mean(&clipped_disk, x);
            assert!((cd - 1.0).abs() < 0.05, "clipped uniform-disk estimate {cd} at x = {x}");
            let me = mean(&measured, x);
            assert!((me - 1.0).abs() < 0.05, "measured-cut estimate {me} at x = {x}");
            assert!(p < low, "the full-disk estimate should read low at the wall: {p} at x = {x}");
        }
        // Away from the wall both agree.
        assert!((mean(&clipped, 0.5) - mean(&plain, 0.5)).abs() < 1e-6);
    }

    #[test]
    fn disk_share_beyond_a_cut_matches_counting() {
        // Share of a 4000² grid over the unit square inside the unit disk
        // with x > δ, against the circular-segment closed form.
        let m = 4000;
        for d in [0.0f32, 0.3, 0.6, 0.9] {
            let (mut inside, mut beyond) = (0u64, 0u64);
            for i in 0..m {
                for j in 0..m {
                    let x = -1.0 + 2.0 * (i as f64 + 0.5) / m as f64;
                    let y = -1.0 + 2.0 * (j as f64 + 0.5) / m as f64;
                    if x * x + y * y <= 1.0 {
                        inside += 1;
                        beyond += u64::from(x > f64::from(d));
                    }
                }
            }
            let want = beyond as f64 / inside as f64;
            assert!(
                (f64::from(disk_share_beyond(d)) - want).abs() < 1e-3,
                "cut {d}: {} vs {want}",
                disk_share_beyond(d)
            );
        }
        assert_eq!(disk_share_beyond(1.0), 0.0);
        assert!((disk_share_beyond(0.0) - 0.5).abs() < 1e-6);
    }

    #[test]
    fn disk_filter_is_unbiased_with_two_thirds_of_the_cone_variance() {
        // Issue 13 (indirect error): on a uniform random field both kernels
        // are unbiased; the uniform disk's relative variance is 1/k, the
        // cone's 1.5/k (E[w²]/E[w]² = (1/6)/(1/9) over the unit disk).
        let k = 150;
        let (mut cone, mut disk) = (Vec::new(), Vec::new());
        for seed in 0..6 {
            let m = random_field(100_000, 1e-5, 100 + seed);
            let d = PhotonMap::new(m.photons.clone()).with_filter(Filter::Disk);
            for i in 0..60 {
                // Points far apart (gather radius ≈ 0.022): independent estimates.
                let x = Vec3::new(
                    0.1 + 0.8 * ((i % 10) as f32 + 0.5) / 10.0,
                    0.1 + 0.8 * ((i / 10) as f32 + 0.5) / 6.0,
                    0.0,
                );
                cone.push(f64::from(m.estimate(x, Vec3::Z, k, 1.0).irradiance.x));
                disk.push(f64::from(d.estimate(x, Vec3::Z, k, 1.0).irradiance.x));
            }
        }
        let stats = |v: &[f64]| {
            let mean = v.iter().sum::<f64>() / v.len() as f64;
            (mean, v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (v.len() - 1) as f64 / (mean * mean))
        };
        let ((mc, vc), (md, vd)) = (stats(&cone), stats(&disk));
        eprintln!(
            "cone: mean {mc}, rel. variance {vc} (1.5/k = {}); disk: mean {md}, rel. variance {vd} (1/k = {})",
            1.5 / k as f64,
            1.0 / k as f64
        );
        // Exact irradiance 1 (unit total power on the unit square); 360 samples.
        assert!((md - 1.0).abs() < 0.01 && (mc - 1.0).abs() < 0.01, "means {md}, {mc}");
        assert!((vd * k as f64 - 1.0).abs() < 0.3, "disk relative variance {vd}");
        assert!((vc * k as f64 - 1.5).abs() < 0.45, "cone relative variance {vc}");
        assert!(vd < 0.85 * vc, "disk {vd} vs cone {vc}");
    }

    #[test]
    fn kept_centroid_matches_counting_and_inverts() {
        // Mean x of a 2000² grid over the unit disk with x < δ, against the
        // closed form; and the bisection gets δ back.
        let m = 2000;
        for d in [0.0f32, 0.4, 0.8] {
            let (mut n, mut sum) = (0u64, 0f64);
            for i in 0..m {
                for j in 0..m {
                    let x = -1.0 + 2.0 * (i as f64 + 0.5) / m as f64;
                    let y = -1.0 + 2.0 * (j as f64 + 0.5) / m as f64;
                    if x * x + y * y <= 1.0 && x < f64::from(d) {
                        n += 1;
                        sum += x;
                    }
                }
            }
            let want = -sum / n as f64;
            assert!((f64::from(kept_centroid(d)) - want).abs() < 2e-3, "δ {d}: {} vs {want}", kept_centroid(d));
            assert!((cut_from_centroid(kept_centroid(d)) - d).abs() < 1e-3);
        }
        assert_eq!(cut_from_centroid(0.0), 1.0);
        assert_eq!(cut_from_centroid(f32::NAN), 1.0);
    }

    #[test]
    fn measured_cut_ignores_a_post_standing_on_the_floor() {
        // A thin post (0.004 wide, well inside one gather disk, r ≈ 0.015)
        // stands on a uniformly lit floor: its photons mark a cut plane, but
        // the floor continues around it. `Clip` removes half the disk there
        // and reads high; `Measured` sees floor photons on both sides.
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
        let n = 200_000;
        let mut v = floor_photons(&mut rng, n, 1.0 / n as f32);
        // The post's face x = 0.5, y in [0.498, 0.502], facing −X, densely lit.
        v.extend((0..100).map(|_| Photon {
            position: Vec3::new(0.5, 0.498 + 0.004 * rng.random::<f32>(), 0.01 * rng.random::<f32>()),
            power: Vec3::splat(1.0 / n as f32),
            dir: Vec3::X,
            normal: Vec3::NEG_X,
        }));
        let est = |mode| {
            let m = PhotonMap::new(v.clone()).with_boundary(mode).with_filter(Filter::Disk);
            (0..20)
                .map(|j| m.estimate(Vec3::new(0.4999 - 0.00002 * j as f32, 0.5, 0.0), Vec3::Z, 150, 1.0).irradiance.x)
                .sum::<f32>()
                / 20.0
        };
        let (clip, measured) = (est(BoundaryMode::Clip), est(BoundaryMode::Measured));
        eprintln!("next to a post: clip {clip}, measured {measured} (exact 1)");
        assert!(clip > 1.5, "clip should over-correct next to the post: {clip}");
        // The centroid's noise (150 photons) leaves a few % either way; the
        // cut's own over-correction is gone.
        assert!((measured - 1.0).abs() < 0.2 && (measured - 1.0).abs() < 0.25 * (clip - 1.0), "measured {measured}");
    }
}
