//! Primary intersections (Vierjahn 2010, section 3.4): 9 samples per pixel
//! on a 3×3 grid, binned by triangle ID.
//!
//! The G-buffer depends only on the camera and the geometry, so it is built
//! once and reused for every light and every rebuild while the camera stays
//! still. Each pixel's samples are grouped by the triangle they hit; a bin is
//! shaded once at the mean of its samples (mean barycentrics on one triangle
//! = mean position), weighted by its share of the 9 samples. Pixel-edge
//! geometry is anti-aliased this way at the cost of one shade per triangle.

use super::view::is_sharp;
use crate::scene::{Camera, Scene};
use glam::Vec3;
use rayon::prelude::*;

/// Samples per pixel (3×3 grid).
pub const SAMPLES_PER_PIXEL: usize = 9;
/// Index of the pixel-centre sample (the one-sample-per-pixel mode uses it).
pub const CENTRE_SAMPLE: usize = 4;
/// Triangle id of a sample that hit nothing (background).
pub const NO_HIT: u32 = u32::MAX;

/// Sub-pixel offset of sample `s` inside its pixel, in pixel units.
pub fn sample_offset(s: usize) -> (f32, f32) {
    (((s % 3) as f32 + 0.5) / 3.0, ((s / 3) as f32 + 0.5) / 3.0)
}

/// One primary sample: the triangle it hit and where (barycentrics).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrimarySample {
    /// Triangle id, or [`NO_HIT`].
    pub triangle: u32,
    /// Barycentric u.
    pub u: f32,
    /// Barycentric v.
    pub v: f32,
}

impl PrimarySample {
    const MISS: Self = Self { triangle: NO_HIT, u: 0.0, v: 0.0 };
}

/// A triangle-ID bin of one pixel: shaded once, weighted by `weight`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bin {
    /// Triangle id, or [`NO_HIT`] for the background.
    pub triangle: u32,
    /// Share of the pixel's samples in this bin (count / 9).
    pub weight: f32,
    /// Mean barycentric u of the bin's samples.
    pub u: f32,
    /// Mean barycentric v of the bin's samples.
    pub v: f32,
}

/// The bins of one pixel (at most 9).
#[derive(Clone, Copy, Debug)]
pub struct Bins {
    items: [Bin; SAMPLES_PER_PIXEL],
    len: usize,
}

impl Bins {
    /// The bins as a slice.
    pub fn as_slice(&self) -> &[Bin] {
        &self.items[..self.len]
    }
}

/// The one bin of a pixel whose 9 samples all hit one triangle (most
/// pixels), or `None`: the same bin [`bin_samples`] and [`surface_bins`]
/// return for it (same sums in the same order), without building the
/// 9-slot [`Bins`] (copying it cost as much as expanding the pixel's path).
#[inline]
pub fn single_bin(samples: &[PrimarySample; SAMPLES_PER_PIXEL]) -> Option<Bin> {
    let first = samples[0].triangle;
    if !samples.iter().all(|s| s.triangle == first) {
        return None;
    }
    let (mut u, mut v) = (0.0f32, 0.0f32);
    for s in samples {
        u += s.u;
        v += s.v;
    }
    let n = SAMPLES_PER_PIXEL as f32;
    // weight 9 / 9 = 1 exactly, as the general loop computes it.
    Some(Bin { triangle: first, weight: 1.0, u: u / n, v: v / n })
}

/// Groups 9 samples by triangle id (order of first appearance).
pub fn bin_samples(samples: &[PrimarySample; SAMPLES_PER_PIXEL]) -> Bins {
    let empty = Bin { triangle: NO_HIT, weight: 0.0, u: 0.0, v: 0.0 };
    let mut items = [empty; SAMPLES_PER_PIXEL];
    // Fast path: most pixels see one triangle only (the general loop below
    // cost as much as expanding the pixel's path; same sums, same order).
    if let Some(bin) = single_bin(samples) {
        items[0] = bin;
        return Bins { items, len: 1 };
    }
    let mut counts = [0u32; SAMPLES_PER_PIXEL];
    let mut len = 0;
    for s in samples {
        let slot = match items[..len].iter().position(|b| b.triangle == s.triangle) {
            Some(i) => i,
            None => {
                items[len] = Bin { triangle: s.triangle, ..empty };
                len += 1;
                len - 1
            }
        };
        counts[slot] += 1;
        items[slot].u += s.u;
        items[slot].v += s.v;
    }
    for (b, &c) in items[..len].iter_mut().zip(&counts) {
        b.u /= c as f32;
        b.v /= c as f32;
        b.weight = c as f32 / SAMPLES_PER_PIXEL as f32;
    }
    Bins { items, len }
}

/// Cosine of the largest shading-normal difference between two bins still
/// taken as one smooth surface (about 8°; also the anti-aliasing decision's
/// "same surface" test).
pub const SAME_SURFACE_COS: f32 = 0.99;

/// Largest distance of one bin's point from the other bin's tangent plane,
/// relative to the distance between the points, for the two to be one
/// surface: adjacent facets of a tessellated curve within 8° stay under
/// sin 8° ≈ 0.14; an object in front of another of the same material is far
/// off the plane.
const SAME_SURFACE_PLANE: f32 = 0.2;

/// The bins a pixel is shaded with (issue 13.5, "cheaper bins"): the
/// triangle-ID bins of [`bin_samples`], with bins that lie on one smooth
/// surface merged into one. Two bins are one surface when they have the
/// same material, shading normals within ~8° ([`SAME_SURFACE_COS`]) and each
/// point lies near the other's tangent plane: a tessellation edge inside a
/// curved or flat surface, not an edge of the geometry. Triangle-ID bins
/// anti-alias geometry edges; a tessellation edge is none, and splitting a
/// pixel there only multiplies the camera paths (on the bundled stage 21 %
/// of the pixels held several triangle bins). Bins of one Lambert material
/// whose triangles share a smooth vertex (`shares_smooth_vertex`) are one
/// surface too, however far their normals turn inside the pixel (the
/// stage's pleated velvet turns ~17° a pixel: 334,240 → 311,320 vertices); the
/// groups are the connected components of those links. A merged group is
/// shaded once with the summed weight, at the centre sample when the group
/// holds it (the pixel centre, as in 1-sample rendering), else at its
/// largest bin's mean point: it gives up the surface's curvature inside the
/// pixel, an error second order in the normals' spread. Pixels whose bins
/// are all different surfaces keep them; a crease (a flat-shaded edge)
/// keeps its bins.
pub fn surface_bins(scene: &Scene, samples: &[PrimarySample; SAMPLES_PER_PIXEL]) -> Bins {
    let bins = bin_samples(samples);
    if bins.len <= 1 {
        return bins;
    }
    // Fixed arrays, not Vecs: this runs for every pixel on an edge (a
    // fifth of them). Only bins of one material can merge: a bin's surface
    // is looked up only when another bin shares its material (object
    // outlines between two materials cost no look-up), and a pixel without
    // such a pair keeps its bins at once. The surfaces are kept as three
    // plain vector arrays: nine `Option<SurfacePoint>`s cost more to
    // build and copy than the look-ups themselves.
    let items = bins.as_slice();
    let n = items.len();
    let mut material = [NO_HIT; SAMPLES_PER_PIXEL];
    for (m, b) in material.iter_mut().zip(items) {
        if b.triangle != NO_HIT {
            *m = scene.material_of[b.triangle as usize];
        }
    }
    let paired = |i: usize| material[i] != NO_HIT && (0..n).any(|j| j != i && material[j] == material[i]);
    if !(0..n).any(paired) {
        return bins;
    }
    let (mut position, mut shading, mut geometric) =
        ([Vec3::ZERO; SAMPLES_PER_PIXEL], [Vec3::ZERO; SAMPLES_PER_PIXEL], [Vec3::ZERO; SAMPLES_PER_PIXEL]);
    let mut looked_up = [false; SAMPLES_PER_PIXEL];
    for i in (0..n).filter(|&i| paired(i)) {
        let b = items[i];
        let sp = scene.surface(&crate::scene::Hit { triangle: b.triangle, t: 0.0, u: b.u, v: b.v });
        (position[i], shading[i], geometric[i], looked_up[i]) =
            (sp.position, sp.shading_normal, sp.geometric_normal, true);
    }
    let same = |a: usize, b: usize| {
        if !(looked_up[a] && looked_up[b]) {
            return false;
        }
        let d = position[b] - position[a];
        let len = d.length();
        material[a] == material[b]
            && shading[a].dot(shading[b]) >= SAME_SURFACE_COS
            && geometric[a].dot(d).abs() <= SAME_SURFACE_PLANE * len
            && geometric[b].dot(d).abs() <= SAME_SURFACE_PLANE * len
    };
    // Group leader of every bin (the first bin of its group).
    let mut leader = [0usize; SAMPLES_PER_PIXEL];
    for i in 0..n {
        leader[i] = (0..i).find(|&j| leader[j] == j && same(i, j)).unwrap_or(i);
    }
    // Lambert bins on one smooth surface form one group however far their
    // normals turn: the connected components of the smooth links (a pixel
    // across three cells of a pleat links the outer two through the middle).
    let mut lambert = [false; SAMPLES_PER_PIXEL];
    for i in (0..n).filter(|&i| paired(i)) {
        lambert[i] = is_lambert(&scene.materials[material[i] as usize]);
    }
    let smooth = |a: usize, b: usize| {
        material[a] == material[b] && lambert[a] && shares_smooth_vertex(scene, items[a].triangle, items[b].triangle)
    };
    let mut linked = true;
    while linked {
        linked = false;
        for i in 0..n {
            for j in 0..i {
                if leader[i] != leader[j] && smooth(i, j) {
                    let (keep, drop) = (leader[i].min(leader[j]), leader[i].max(leader[j]));
                    leader.iter_mut().filter(|l| **l == drop).for_each(|l| *l = keep);
                    linked = true;
                }
            }
        }
    }
    if (0..n).all(|i| leader[i] == i) {
        return bins;
    }
    let centre = samples[CENTRE_SAMPLE];
    let empty = Bin { triangle: NO_HIT, weight: 0.0, u: 0.0, v: 0.0 };
    let mut items = [empty; SAMPLES_PER_PIXEL];
    let mut len = 0;
    for g in (0..n).filter(|&i| leader[i] == i) {
        let members = || (0..n).filter(move |&i| leader[i] == g);
        let weight: f32 = members().map(|i| bins.items[i].weight).sum();
        let single = members().count() == 1;
        let at = if single {
            bins.items[g]
        } else if members().any(|i| bins.items[i].triangle == centre.triangle) {
            Bin { triangle: centre.triangle, weight, u: centre.u, v: centre.v }
        } else {
            let largest = members().max_by(|&a, &b| bins.items[a].weight.total_cmp(&bins.items[b].weight)).unwrap_or(g);
            bins.items[largest]
        };
        items[len] = Bin { weight, ..at };
        len += 1;
    }
    Bins { items, len }
}

/// A purely diffuse (Lambert) material: no specular lobe, no mirror, no
/// transmission. Its direct light, ρ_d/π · n·l, is linear in the shading
/// normal while the light is in front of the surface, so one shade at a
/// smooth group's point stands for the group as one shade at a single
/// triangle's mean point does.
fn is_lambert(m: &crate::scene::Material) -> bool {
    m.specular == Vec3::ZERO && m.k_r == Vec3::ZERO && m.k_t == Vec3::ZERO
}

/// Whether triangles `a` and `b` share a vertex with the same position and
/// the same shading normal (bit for bit: one vertex of an indexed,
/// smooth-shaded mesh): their surface and its normal field are continuous
/// there, so the edge between them is a tessellation edge of one smooth
/// surface, however strongly it curves. A crease (vertices duplicated with
/// different normals) or two objects that only touch share no such vertex
/// with the same normal.
fn shares_smooth_vertex(scene: &Scene, a: u32, b: u32) -> bool {
    let (pa, na) = (&scene.positions[a as usize], &scene.normals[a as usize]);
    let (pb, nb) = (&scene.positions[b as usize], &scene.normals[b as usize]);
    (0..3).any(|i| (0..3).any(|j| pa[i] == pb[j] && na[i] == nb[j]))
}

/// Where a pixel's samples on sharp specular surfaces can show a light's
/// highlight, independent of the light: the samples lie within `radius` of
/// `centre`, their mirror directions (the view ray reflected about the
/// shading normal) within `spread` radians of `mirror`, and no sample's
/// Phong lobe reaches further than `lobe` radians from its mirror
/// direction (cos^n α ≥ e^-40, the cut of [`crate::render::View::glint_pixels`], with the
/// smallest exponent of the pixel's samples).
#[derive(Clone, Copy, Debug)]
pub(crate) struct GlintBound {
    centre: Vec3,
    radius: f32,
    mirror: Vec3,
    spread: f32,
    lobe: f32,
}

/// Angle added to [`GlintBound`]'s test for the rounding of the f32 dot
/// products and arc cosines behind it (their error near cos = 1 is ~5e-4
/// rad); a pixel is skipped only when it misses by more.
const GLINT_BOUND_MARGIN: f32 = 0.01;

impl GlintBound {
    /// Whether no sample of the pixel can be within its lobe of the
    /// direction to a light at `light`: the direction from any sample to
    /// the light is within asin(radius / distance) of the one from
    /// `centre`, each mirror direction within `spread` of `mirror`, so every
    /// sample's angle α is at least the centre's angle less both.
    pub(crate) fn misses(&self, light: Vec3) -> bool {
        let to = light - self.centre;
        let d = to.length();
        // Inside the samples' ball (or NaN): no bound.
        if d.is_nan() || d <= self.radius {
            return false;
        }
        let theta = (to / d).dot(self.mirror).clamp(-1.0, 1.0).acos();
        theta - (self.radius / d).asin() - self.spread - self.lobe > GLINT_BOUND_MARGIN
    }
}

/// The surface points of a pixel's samples on sharp specular materials
/// ([`is_sharp`]), with their materials: what the highlight bounds and the
/// highlight test of adaptive anti-aliasing look at.
pub(crate) fn sharp_samples<'s>(
    scene: &'s Scene,
    samples: &'s [PrimarySample; SAMPLES_PER_PIXEL],
) -> impl Iterator<Item = (crate::scene::SurfacePoint, &'s crate::scene::Material)> + 's {
    samples.iter().filter(|s| s.triangle != NO_HIT).filter_map(move |s| {
        let m = &scene.materials[scene.material_of[s.triangle as usize] as usize];
        is_sharp(m).then(|| (scene.surface(&crate::scene::Hit { triangle: s.triangle, t: 0.0, u: s.u, v: s.v }), m))
    })
}

/// The [`GlintBound`] of one pixel's samples on sharp specular materials
/// seen from `eye`: `None` when no sample is on one; a bound that never
/// misses when a sample gives no usable direction.
fn glint_bound(scene: &Scene, eye: Vec3, samples: &[PrimarySample; SAMPLES_PER_PIXEL]) -> Option<GlintBound> {
    let never = GlintBound { centre: eye, radius: f32::INFINITY, mirror: Vec3::Z, spread: 0.0, lobe: 0.0 };
    let mut points = [(Vec3::ZERO, Vec3::ZERO); SAMPLES_PER_PIXEL];
    let (mut n, mut lowest, mut usable, mut any) = (0, f32::INFINITY, true, false);
    for (sp, m) in sharp_samples(scene, samples) {
        any = true;
        let Some(dir) = (sp.position - eye).try_normalize() else {
            usable = false;
            continue;
        };
        let f = sp.facing(dir);
        // The view ray mirrored about the shading normal: a highlight's
        // cos α is the light direction's cosine to it.
        let mirror = (dir - 2.0 * dir.dot(f.shading) * f.shading).normalize_or_zero();
        usable &= mirror.is_finite() && mirror != Vec3::ZERO && sp.position.is_finite();
        points[n] = (sp.position, mirror);
        n += 1;
        lowest = lowest.min(m.exponent);
    }
    if !any {
        return None;
    }
    let points = &points[..n];
    Some(match points.iter().map(|p| p.1).sum::<Vec3>().try_normalize() {
        Some(mirror) if usable && n > 0 => {
            let centre = points.iter().map(|p| p.0).sum::<Vec3>() / n as f32;
            let radius = points.iter().map(|p| p.0.distance(centre)).fold(0.0f32, f32::max);
            let nearest = points.iter().map(|p| p.1.dot(mirror)).fold(1.0f32, f32::min);
            // cos^n α ≥ e^-40 ⟺ α ≤ acos(1 − 40/n), widest for the lowest n.
            let lobe = (1.0 - 40.0 / lowest).clamp(-1.0, 1.0).acos();
            GlintBound { centre, radius, mirror, spread: nearest.clamp(-1.0, 1.0).acos(), lobe }
        }
        _ => never,
    })
}

/// The 9 primary samples of every pixel for one camera.
#[derive(Clone)]
pub struct GBuffer {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// The camera the samples were traced from.
    pub camera: Camera,
    /// Row-major, 9 samples per pixel.
    pub samples: Vec<[PrimarySample; SAMPLES_PER_PIXEL]>,
    /// Every pixel's [`surface_bins`], found once with the samples: the
    /// paper's preprocessing of the intersection buffer (section 3.4, "for
    /// each pixel, intersections are binned"; section 4.2 counts it with the
    /// primary intersections). Pixel i owns `bins[bin_start[i]..bin_start[i + 1]]`.
    bins: Vec<Bin>,
    bin_start: Vec<u32>,
    /// The pixels with a sample on a sharp specular material ([`is_sharp`]),
    /// ascending, each with its [`GlintBound`]: preprocessing of the
    /// intersection buffer like the bins (light-free), so that the
    /// highlight test of adaptive anti-aliasing
    /// ([`crate::render::View::glint_pixels`]) evaluates a light only where
    /// a pixel's bound does not rule it out, from the first light on.
    glint_bounds: Vec<(u32, GlintBound)>,
}

impl GBuffer {
    /// Traces the 9 primary rays of every pixel (parallel over rows).
    pub fn build(scene: &Scene, camera: Camera, width: u32, height: u32) -> Self {
        let (w, h) = (width.max(1), height.max(1));
        let mut samples = vec![[PrimarySample::MISS; SAMPLES_PER_PIXEL]; (w * h) as usize];
        let any_sharp = scene.materials.iter().any(is_sharp);
        // Each row's bins and highlight bounds are found right after its
        // samples (still in cache).
        // Per row: bin counts per pixel, the bins, the sharp pixels' bounds.
        type Row = (Vec<u32>, Vec<Bin>, Vec<(u32, GlintBound)>);
        let rows: Vec<Row> = samples
            .par_chunks_mut(w as usize)
            .enumerate()
            .map(|(y, row)| {
                let (mut counts, mut bins) = (Vec::with_capacity(row.len()), Vec::with_capacity(row.len()));
                let mut glints = Vec::new();
                for (x, px) in row.iter_mut().enumerate() {
                    for (s, out) in px.iter_mut().enumerate() {
                        let (ox, oy) = sample_offset(s);
                        let dir = camera.direction(x as f32 + ox, y as f32 + oy, w, h);
                        if let Some(hit) = scene.accel.intersect(camera.position, dir, f32::INFINITY) {
                            *out = PrimarySample { triangle: hit.triangle, u: hit.u, v: hit.v };
                        }
                    }
                    let before = bins.len();
                    match single_bin(px) {
                        Some(b) => bins.push(b),
                        None => bins.extend_from_slice(surface_bins(scene, px).as_slice()),
                    }
                    counts.push((bins.len() - before) as u32);
                    if any_sharp && let Some(bound) = glint_bound(scene, camera.position, px) {
                        glints.push(((y * w as usize + x) as u32, bound));
                    }
                }
                (counts, bins, glints)
            })
            .collect();
        let mut bin_start = Vec::with_capacity(samples.len() + 1);
        let mut bins = Vec::with_capacity(rows.iter().map(|r| r.1.len()).sum());
        let mut glint_bounds = Vec::new();
        bin_start.push(0u32);
        for (counts, row_bins, glints) in rows {
            glint_bounds.extend(glints);
            for c in counts {
                let last = *bin_start.last().unwrap_or(&0);
                bin_start.push(last + c);
            }
            bins.extend(row_bins);
        }
        Self { width: w, height: h, camera, samples, bins, bin_start, glint_bounds }
    }

    /// Memory held by the samples, the bins and the highlight bounds.
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(&self.samples[..])
            + std::mem::size_of_val(&self.bins[..])
            + std::mem::size_of_val(&self.bin_start[..])
            + std::mem::size_of_val(&self.glint_bounds[..])
    }

    /// The pixels with a sample on a sharp specular material
    /// ([`is_sharp`]), ascending, each with its [`GlintBound`]: the only
    /// pixels the highlight test of adaptive anti-aliasing looks at.
    pub(crate) fn highlight_bounds(&self) -> &[(u32, GlintBound)] {
        &self.glint_bounds
    }

    /// Finds the highlight bounds again from the samples, in parallel, and
    /// returns how many pixels hold one: what [`GBuffer::build`] spends on
    /// them, for the bench to time (build finds them row by row with the
    /// bins).
    pub fn find_highlight_bounds(&self, scene: &Scene) -> usize {
        let eye = self.camera.position;
        self.samples.par_iter().filter_map(|px| glint_bound(scene, eye, px)).count()
    }

    /// The bins pixel `index` is shaded with ([`surface_bins`] of its
    /// samples, found by [`GBuffer::build`]).
    #[inline]
    pub fn bins(&self, index: usize) -> &[Bin] {
        &self.bins[self.bin_start[index] as usize..self.bin_start[index + 1] as usize]
    }

    /// The bins of row `y`'s pixels, left to right: [`GBuffer::bins`] of
    /// each, walked with one cursor through the row's contiguous bins (the
    /// binned expansion runs this for every pixel of every view).
    pub fn row_bins(&self, y: usize) -> impl Iterator<Item = &[Bin]> + '_ {
        let w = self.width as usize;
        let starts = &self.bin_start[y * w..=(y + 1) * w];
        let mut rest = &self.bins[starts[0] as usize..starts[w] as usize];
        starts.windows(2).map(move |s| {
            let (mine, tail) = rest.split_at((s[1] - s[0]) as usize);
            rest = tail;
            mine
        })
    }

    /// Traces only the centre sample of every pixel: the single-sample ray
    /// casting baseline the paper compares its intersection buffer against.
    pub fn trace_centre_only(scene: &Scene, camera: Camera, width: u32, height: u32) -> Vec<PrimarySample> {
        let (w, h) = (width.max(1), height.max(1));
        let mut out = vec![PrimarySample::MISS; (w * h) as usize];
        out.par_chunks_mut(w as usize).enumerate().for_each(|(y, row)| {
            let (ox, oy) = sample_offset(CENTRE_SAMPLE);
            for (x, px) in row.iter_mut().enumerate() {
                let dir = camera.direction(x as f32 + ox, y as f32 + oy, w, h);
                if let Some(hit) = scene.accel.intersect(camera.position, dir, f32::INFINITY) {
                    *px = PrimarySample { triangle: hit.triangle, u: hit.u, v: hit.v };
                }
            }
        });
        out
    }

    /// World position of a sample, or `None` for a miss.
    pub fn position(&self, scene: &Scene, s: &PrimarySample) -> Option<Vec3> {
        (s.triangle != NO_HIT).then(|| scene.point_on(s.triangle, s.u, s.v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_group_by_triangle_with_weights() {
        let a = PrimarySample { triangle: 3, u: 0.1, v: 0.2 };
        let b = PrimarySample { triangle: 3, u: 0.3, v: 0.4 };
        let c = PrimarySample { triangle: 7, u: 0.5, v: 0.5 };
        let m = PrimarySample::MISS;
        let bins = bin_samples(&[a, b, c, m, m, a, a, b, c]);
        let s = bins.as_slice();
        assert_eq!(s.len(), 3);
        assert_eq!(s[0].triangle, 3);
        assert!((s[0].weight - 5.0 / 9.0).abs() < 1e-6);
        assert!((s[0].u - (0.1 * 3.0 + 0.3 * 2.0) / 5.0).abs() < 1e-6);
        assert_eq!(s[2].triangle, NO_HIT);
        let total: f32 = s.iter().map(|b| b.weight).sum();
        assert!((total - 1.0).abs() < 1e-6);
    }

    #[test]
    fn one_triangle_pixel_is_one_bin_at_the_mean() {
        // The single-triangle fast path: weight 1, the mean of the 9
        // barycentrics summed in sample order, as the general loop sums them.
        let s: [PrimarySample; SAMPLES_PER_PIXEL] = std::array::from_fn(|i| PrimarySample {
            triangle: 5,
            u: 0.1 + 0.013 * i as f32,
            v: 0.3 - 0.007 * i as f32,
        });
        let bins = bin_samples(&s);
        assert_eq!(bins.as_slice().len(), 1);
        let b = bins.as_slice()[0];
        let (mut u, mut v) = (0.0f32, 0.0f32);
        for x in &s {
            u += x.u;
            v += x.v;
        }
        assert_eq!((b.triangle, b.weight, b.u, b.v), (5, 1.0, u / 9.0, v / 9.0));
        // One sample on another triangle: the general path, two bins.
        let mut t = s;
        t[8].triangle = 6;
        assert_eq!(bin_samples(&t).as_slice().len(), 2);
    }

    #[test]
    fn offsets_form_a_centred_grid() {
        assert_eq!(sample_offset(CENTRE_SAMPLE), (0.5, 0.5));
        assert_eq!(sample_offset(0), (1.0 / 6.0, 1.0 / 6.0));
        assert_eq!(sample_offset(8), (5.0 / 6.0, 5.0 / 6.0));
    }
}
