//! Direct light in proportion to the beam's footprint (issue 18).
//!
//! A moving head's direct stage used to shade every directly seen vertex of
//! the frame, although a narrow beam reaches a few percent of them. Here
//! the view's directly seen (depth-0) shading vertices are bounded per
//! 16×16 buffer tile by a sphere, once per view ([`TileBounds`]); a light
//! tests each tile's sphere against its cone (the beam's cutoff angle) and
//! shades only the tiles that can be lit, writing them straight into the
//! sparse [`LightBuffer`] (no dense frame-sized buffer, no scan of it).
//! The cost of a direct stage is then one cone test per tile plus the
//! vertices of the tiles in the beam.
//!
//! While a light moves, [`DirectQuality::Moving`] shades one pixel in each
//! 2×2 block and repeats it (a quarter of the shadow rays); the light's
//! settled build replaces it with full resolution and the Whitted stage.
//! Its error against the settled direct stage is measured in `footlight
//! bench`.

use super::buffer::{LightBuffer, TILE};
use super::view::View;
use super::whitted::direct;
use crate::fixture::Light;
use crate::scene::Scene;
use glam::Vec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Bounding sphere of the shading vertices of each 16×16 buffer tile, the
/// one cone cull of the renderer: [`TileBounds::build`] bounds the directly
/// seen (depth-0) vertices, what a direct stage shades;
/// [`TileBounds::paths`] bounds every camera-path vertex (any depth: seen
/// directly, through mirrors or through glass), what a Whitted stage
/// shades. Built once per view and kept by its owner.
pub struct TileBounds {
    pub(crate) tiles_x: usize,
    tiles_y: usize,
    /// Per tile: centre and radius, or `None` when no vertex is in it.
    spheres: Vec<Option<(Vec3, f32)>>,
    /// A tile holds a vertex at a non-finite position: never culled
    /// ([`TileBounds::paths`] only; the direct stage skips such vertices).
    unbounded: Vec<bool>,
}

impl TileBounds {
    /// Bounds of `view`'s depth-0 shading vertices, tile by tile.
    pub fn build(view: &View) -> Self {
        Self::of(view, true)
    }

    /// Bounds of every camera-path vertex of `view` (any depth), tile by tile.
    pub fn paths(view: &View) -> Self {
        Self::of(view, false)
    }

    fn of(view: &View, primary_only: bool) -> Self {
        let (w, h) = (view.width() as usize, view.height() as usize);
        let (tiles_x, tiles_y) = (w.div_ceil(TILE), h.div_ceil(TILE));
        let (spheres, unbounded) = (0..tiles_x * tiles_y)
            .into_par_iter()
            .map(|t| {
                let (tx, ty) = (t % tiles_x, t / tiles_x);
                let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
                let mut bad = false;
                for y in ty * TILE..((ty + 1) * TILE).min(h) {
                    for x in tx * TILE..((tx + 1) * TILE).min(w) {
                        for v in view.shading.pixel(y * w + x).iter().filter(|v| !primary_only || v.depth == 0) {
                            if v.position.is_finite() {
                                lo = lo.min(v.position);
                                hi = hi.max(v.position);
                            } else {
                                bad |= !primary_only;
                            }
                        }
                    }
                }
                ((lo.x <= hi.x).then(|| ((lo + hi) * 0.5, (hi - lo).length() * 0.5)), bad)
            })
            .unzip();
        Self { tiles_x, tiles_y, spheres, unbounded }
    }

    /// Number of tiles.
    pub fn len(&self) -> usize {
        self.spheres.len()
    }

    /// True for an empty view.
    pub fn is_empty(&self) -> bool {
        self.spheres.is_empty()
    }

    /// Tiles whose vertices may lie inside `light`'s cone (half-angle
    /// `acos(cos_cutoff)`, where its pattern is zero beyond). Conservative:
    /// a tile is left out only when its bounding sphere lies wholly outside
    /// the cone.
    pub fn tiles_in_beam(&self, light: &Light) -> Vec<usize> {
        let axis = light.axis();
        let cutoff = light.beam.cos_cutoff().clamp(-1.0, 1.0).acos();
        (0..self.spheres.len())
            .filter(|&t| {
                if self.unbounded[t] {
                    return true;
                }
                let Some((centre, radius)) = self.spheres[t] else { return false };
                sphere_may_meet_cone(centre, radius, light.position, axis, cutoff)
            })
            .collect()
    }
}

/// Whether the sphere (`centre`, `radius`) may reach into the cone of
/// half-angle `cutoff` (radians) from `apex` along `axis`: false only when
/// the sphere lies wholly outside it (angle to the axis beyond the cut-off
/// plus the sphere's angular radius); true for a sphere around the apex or
/// any non-finite input (conservative).
pub(crate) fn sphere_may_meet_cone(centre: Vec3, radius: f32, apex: Vec3, axis: Vec3, cutoff: f32) -> bool {
    let d = centre - apex;
    let dist = d.length();
    if !dist.is_finite() || dist <= radius || !axis.is_finite() {
        return true;
    }
    let angle = (d.dot(axis) / dist).clamp(-1.0, 1.0).acos();
    let widen = (radius / dist).clamp(0.0, 1.0).asin();
    angle <= cutoff + widen + 1e-4
}

/// How finely a direct stage is shaded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DirectQuality {
    /// Every pixel's directly seen vertices (the settled direct stage).
    Full,
    /// One pixel per 2×2 block, repeated (a light in motion).
    Moving,
}

/// What a footprint-culled direct stage did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FootprintStats {
    /// Tiles tested against the cone.
    pub tiles: usize,
    /// Tiles inside the cone (shaded).
    pub tiles_in_beam: usize,
    /// Shading vertices evaluated (shadow rays at most).
    pub vertices: usize,
}

/// Direct light at the directly seen surfaces of the tiles `light`'s cone
/// reaches (no mirrors, glass or anti-aliasing): the cheapest picture of a
/// moved light, in proportion to its footprint.
pub fn primary_direct(
    scene: &Scene,
    view: &View,
    bounds: &TileBounds,
    light: &Light,
    quality: DirectQuality,
) -> (LightBuffer, FootprintStats) {
    let (w, h) = (view.width() as usize, view.height() as usize);
    let tiles = bounds.tiles_in_beam(light);
    let evaluated = AtomicUsize::new(0);
    let step = match quality {
        DirectQuality::Full => 1,
        DirectQuality::Moving => 2,
    };
    let shaded: Vec<(usize, Vec<Vec3>)> = tiles
        .par_iter()
        .map(|&t| {
            let (tx, ty) = (t % bounds.tiles_x, t / bounds.tiles_x);
            let mut tile = vec![Vec3::ZERO; TILE * TILE];
            let mut count = 0;
            let (x1, y1) = (((tx + 1) * TILE).min(w), ((ty + 1) * TILE).min(h));
            for y in (ty * TILE..y1).step_by(step) {
                for x in (tx * TILE..x1).step_by(step) {
                    let vertices = view.shading.pixel(y * w + x);
                    let mut value = Vec3::ZERO;
                    for v in vertices.iter().filter(|v| v.depth == 0) {
                        value += v.weight * direct(scene, light, v);
                        count += 1;
                    }
                    for yy in y..(y + step).min(y1) {
                        for xx in x..(x + step).min(x1) {
                            tile[(yy - ty * TILE) * TILE + (xx - tx * TILE)] = value;
                        }
                    }
                }
            }
            evaluated.fetch_add(count, Ordering::Relaxed);
            (t, tile)
        })
        .collect();
    let stats =
        FootprintStats { tiles: bounds.len(), tiles_in_beam: tiles.len(), vertices: evaluated.load(Ordering::Relaxed) };
    debug_assert_eq!(bounds.tiles_y * bounds.tiles_x, bounds.len());
    (LightBuffer::from_tile_list(view.width(), view.height(), shaded), stats)
}
