//! Lights built together (issue 14: pixel cells). An LED bar's cells are
//! lights of their own (one unit buffer I_h,ε_i each, eq. 5), but they hang
//! a few centimetres apart and light the same part of the picture; built
//! one by one, each cell's Whitted stage walks every shading vertex of the
//! frame (the bench measured 36 ms per cell at 800×500).
//!
//! [`whitted_together`] builds a set of lights in one pass: the tiles of
//! the picture are bounded once ([`TileBounds`]: every camera-path vertex
//! of a tile, mirrors and glass included, in one sphere), each light keeps
//! the tiles its cone reaches, and one parallel pass over the **union** of
//! those tiles evaluates, at every vertex, the direct light of each light
//! whose cone reaches the tile ([`crate::render::whitted::direct`]: its own shadow
//! ray). Each light then gets the same adaptive anti-aliasing as alone
//! ([`View::reshade`] of the pixels its own relative gradient flags, §3.4),
//! decided on a window around its lit tiles instead of the whole frame, and
//! is stored in its own tile-sparse [`LightBuffer`]: eq. 5 is unchanged.
//!
//! The result equals [`super::LightBuild::whitted`] of each light
//! alone (same vertices, same sums in the same order; a culled tile is one
//! where every term is zero): `tests/pixels.rs` checks it to 1e-6, and
//! `footlight bench --pixels-only` times both.

use crate::fixture::Light;
use crate::render::buffer::{LightBuffer, TILE};
use crate::render::footprint::{DirectQuality, TileBounds};
use crate::render::view::{
    AA_REFERENCE_PERCENTILE, AaParams, BeamEdge, BeamRim, LitWindow, Reshading, Sampling, View, facing_corners,
    mark_highlights_into, mark_pairs_into, mark_rim_into, row_spans,
};
use crate::render::whitted::direct;
use crate::scene::Scene;
use glam::Vec3;
use rayon::prelude::*;

/// What [`whitted_together`] did, for the bench.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TogetherStats {
    /// Tiles of the picture.
    pub tiles: usize,
    /// Tiles in the union of the lights' cones (shaded once).
    pub union_tiles: usize,
    /// Sum over lights of the tiles their cone reaches.
    pub light_tiles: usize,
    /// Pixels re-shaded by anti-aliasing, all lights together.
    pub reshaded: usize,
}

/// The Whitted stage (eq. 1 direct term with adaptive anti-aliasing, §3.4)
/// of every light of `lights`, built together: one pass over the union of
/// their footprints, every vertex evaluating each light's direct light (one
/// shadow ray per light), each light in its own unit buffer (eq. 5).
/// Equal to [`super::LightBuild::whitted`] of each light alone.
/// `bounds` must be [`TileBounds::paths`] of `view`. Returns `None` once
/// `stop` returns true (checked per tile and per light).
pub fn whitted_together(
    scene: &Scene,
    view: &View,
    bounds: &TileBounds,
    lights: &[Light],
    aa: Option<AaParams>,
    stop: &(dyn Fn() -> bool + Sync),
) -> Option<(Vec<(LightBuffer, usize)>, TogetherStats)> {
    let (w, h) = (view.width() as usize, view.height() as usize);
    let n = bounds.len();
    let lists: Vec<Vec<usize>> = lights.iter().map(|l| bounds.tiles_in_beam(l)).collect();
    let (per_light, union_tiles, light_tiles) =
        shade_union(scene, view, bounds.tiles_x, n, lights, &lists, false, 1, stop)?;
    let adaptive = matches!(view.sampling, Sampling::Adaptive) && aa.is_some();
    // Scratch for anti-aliasing, shared by the lights one after another.
    let mut dense = if adaptive { vec![Vec3::ZERO; w * h] } else { Vec::new() };
    let mut flags = if adaptive { vec![false; w * h] } else { Vec::new() };
    let mut out = Vec::with_capacity(lights.len());
    let mut reshaded_all = 0;
    for (light, tiles) in lights.iter().zip(per_light) {
        if stop() {
            return None;
        }
        let (Some(aa), false) = (aa.filter(|_| adaptive), tiles.is_empty()) else {
            out.push((LightBuffer::from_tile_list(w as u32, h as u32, tiles), 0));
            continue;
        };
        let (buffer, reshaded) = anti_alias(scene, view, bounds.tiles_x, light, tiles, aa, &mut dense, &mut flags);
        reshaded_all += reshaded;
        out.push((buffer, reshaded));
    }
    let stats = TogetherStats { tiles: n, union_tiles, light_tiles, reshaded: reshaded_all };
    Some((out, stats))
}

/// The direct stage ([`crate::render::footprint::primary_direct`] at
/// [`crate::render::footprint::DirectQuality::Full`]: directly seen surfaces only,
/// no anti-aliasing) of every light of `lights`, built together over the
/// union of their footprints ([`View::tile_bounds`]); equal to each light's
/// own direct stage. `None` once `stop` returns true.
pub fn direct_together(
    scene: &Scene,
    view: &View,
    lights: &[Light],
    stop: &(dyn Fn() -> bool + Sync),
) -> Option<(Vec<LightBuffer>, TogetherStats)> {
    direct_together_at(scene, view, lights, DirectQuality::Full, stop)
}

/// [`direct_together`] at `quality`: with [`DirectQuality::Moving`] (lights
/// in motion) one pixel per 2×2 block is shaded and repeated over the
/// block, as [`crate::render::footprint::primary_direct`] does for one light; equal
/// to each light's own direct stage at that quality.
pub fn direct_together_at(
    scene: &Scene,
    view: &View,
    lights: &[Light],
    quality: DirectQuality,
    stop: &(dyn Fn() -> bool + Sync),
) -> Option<(Vec<LightBuffer>, TogetherStats)> {
    let step = match quality {
        DirectQuality::Full => 1,
        DirectQuality::Moving => 2,
    };
    let (w, h) = (view.width(), view.height());
    let bounds = view.tile_bounds();
    let tiles_x = (w as usize).div_ceil(TILE);
    let lists: Vec<Vec<usize>> = lights.iter().map(|l| bounds.tiles_in_beam(l)).collect();
    let (per_light, union_tiles, light_tiles) =
        shade_union(scene, view, tiles_x, bounds.len(), lights, &lists, true, step, stop)?;
    let out = per_light.into_iter().map(|tiles| LightBuffer::from_tile_list(w, h, tiles)).collect();
    Some((out, TogetherStats { tiles: bounds.len(), union_tiles, light_tiles, reshaded: 0 }))
}

/// Per light, its non-zero tiles; the union's size; the sum of the lists'
/// sizes. One parallel pass over the union of `lists` (light i's tiles):
/// every vertex of a tile (only the directly seen ones with `primary`)
/// evaluates the direct light of each light whose list holds the tile,
/// summed per pixel in vertex order (the sum a light alone makes). With
/// `step` 2 only the first pixel of each 2×2 block is shaded and its value
/// fills the block (moving quality).
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn shade_union(
    scene: &Scene,
    view: &View,
    tiles_x: usize,
    n: usize,
    lights: &[Light],
    lists: &[Vec<usize>],
    primary: bool,
    step: usize,
    stop: &(dyn Fn() -> bool + Sync),
) -> Option<(Vec<Vec<(usize, Vec<Vec3>)>>, usize, usize)> {
    let (w, h) = (view.width() as usize, view.height() as usize);
    // Which lights reach each tile.
    let mut reach: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut light_tiles = 0;
    for (i, list) in lists.iter().enumerate() {
        for &t in list {
            reach[t].push(i as u32);
            light_tiles += 1;
        }
    }
    let union: Vec<usize> = (0..n).filter(|&t| !reach[t].is_empty()).collect();
    // One pass over the union: per tile, one TILE×TILE block per light reaching it.
    let shaded: Vec<(usize, Vec<Vec<Vec3>>)> = union
        .par_iter()
        .map(|&t| {
            let who = &reach[t];
            let mut blocks = vec![vec![Vec3::ZERO; TILE * TILE]; who.len()];
            if stop() {
                return (t, blocks);
            }
            let (tx, ty) = (t % tiles_x, t / tiles_x);
            let mut sums = vec![Vec3::ZERO; who.len()];
            let (x1, y1) = (((tx + 1) * TILE).min(w), ((ty + 1) * TILE).min(h));
            for y in (ty * TILE..y1).step_by(step) {
                for x in (tx * TILE..x1).step_by(step) {
                    sums.iter_mut().for_each(|s| *s = Vec3::ZERO);
                    // The same sum as the light alone: vertex after vertex.
                    for v in view.shading.pixel(y * w + x).iter().filter(|v| !primary || v.depth == 0) {
                        for (s, &i) in sums.iter_mut().zip(who) {
                            *s += v.weight * direct(scene, &lights[i as usize], v);
                        }
                    }
                    for yy in y..(y + step).min(y1) {
                        for xx in x..(x + step).min(x1) {
                            let p = (yy - ty * TILE) * TILE + (xx - tx * TILE);
                            for (b, s) in blocks.iter_mut().zip(&sums) {
                                b[p] = *s;
                            }
                        }
                    }
                }
            }
            (t, blocks)
        })
        .collect();
    if stop() {
        return None;
    }
    // Hand each light its blocks.
    let mut per_light: Vec<Vec<(usize, Vec<Vec3>)>> = vec![Vec::new(); lights.len()];
    for (t, blocks) in shaded {
        for (&i, b) in reach[t].iter().zip(blocks) {
            if b.iter().any(|p| *p != Vec3::ZERO) {
                per_light[i as usize].push((t, b));
            }
        }
    }
    Some((per_light, union.len(), light_tiles))
}

/// One light's adaptive anti-aliasing from its shaded tiles: the pixels
/// [`View::aa_flags`] would flag on the whole frame (neighbour pairs and
/// sub-pixel highlights), found on the window of its lit tiles and
/// highlights grown by 2 pixels (outside it every value is 0, so no
/// gradient), then [`View::reshade`]. `dense` and `flags` are
/// frame-sized scratch, all zero / false on entry and on return.
#[allow(clippy::too_many_arguments)]
fn anti_alias(
    scene: &Scene,
    view: &View,
    tiles_x: usize,
    light: &Light,
    tiles: Vec<(usize, Vec<Vec3>)>,
    aa: AaParams,
    dense: &mut [Vec3],
    flags: &mut [bool],
) -> (LightBuffer, usize) {
    let (w, h) = (view.width() as usize, view.height() as usize);
    let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
    for (t, block) in &tiles {
        let (tx, ty) = (t % tiles_x, t / tiles_x);
        for y in ty * TILE..((ty + 1) * TILE).min(h) {
            for x in tx * TILE..((tx + 1) * TILE).min(w) {
                dense[y * w + x] = block[(y - ty * TILE) * TILE + (x - tx * TILE)];
            }
        }
        (x0, y0) = (x0.min(tx * TILE), y0.min(ty * TILE));
        (x1, y1) = (x1.max(((tx + 1) * TILE).min(w)), y1.max(((ty + 1) * TILE).min(h)));
    }
    // The light's reference level (99th percentile of its lit pixels): the
    // lit pixels are all in its tiles.
    let mut lit: Vec<f32> = tiles
        .iter()
        .flat_map(|(_, b)| b.iter().map(|v| v.max_element()))
        .filter(|&m| m > 0.0 && m.is_finite())
        .collect();
    let mut reshaded = 0;
    let mut window = (x0.saturating_sub(2), y0.saturating_sub(2), (x1 + 2).min(w), (y1 + 2).min(h));
    if !lit.is_empty() {
        let k = ((lit.len() - 1) as f32 * AA_REFERENCE_PERCENTILE) as usize;
        let (_, level, _) = lit.select_nth_unstable_by(k, f32::total_cmp);
        let level = *level;
        // Sub-pixel highlights ([`View::glint_pixels`]) may lie where the
        // base shows nothing, outside the lit tiles: the window takes them in.
        let glints = if aa.glints { view.glint_pixels(scene, light, dense, level, aa.threshold) } else { Vec::new() };
        for &i in &glints {
            let (x, y) = (i % w, i / w);
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
        }
        // The window: lit tiles and glints plus 2 pixels (a mark reaches
        // past an edge; outside it every value is 0, so no gradient).
        let (x0, y0, x1, y1) = (x0.saturating_sub(2), y0.saturating_sub(2), (x1 + 2).min(w), (y1 + 2).min(h));
        let pairs = view.pairs_over(scene, dense, level, aa.threshold, &LitWindow { x0, x1, y0, y1 }.spans(h));
        mark_pairs_into(flags, &pairs, w, h, aa.marking);
        mark_highlights_into(flags, &glints, w, h, aa.marking);
        let facing = if aa.corners_first { facing_corners(&pairs, w) } else { Vec::new() };
        // A hard beam edge's rim ([`View::beam_rim`]), looked for around
        // the rows' lit spans as for a light alone (the same pixels: the
        // rim lies within a pixel of a lit one, inside the window). Only a
        // light with a hard edge pays the pass over the frame.
        let lit = LitWindow { x0, x1, y0, y1 };
        let rim = if aa.rim && BeamEdge::of(light).is_some() {
            view.beam_rim(scene, light, &row_spans(dense, w)).within(lit, w)
        } else {
            BeamRim::default()
        };
        mark_rim_into(flags, &rim);
        let how = Reshading {
            flags,
            whole: &glints,
            corners_first: aa.corners_first.then_some(level),
            facing: &facing,
            reconstruct: aa.reconstruct,
            rim: &rim.cover,
            rim_nine: &rim.nine,
            edge: rim.edge,
        };
        reshaded = view.reshade(scene, light, dense, how);
        window = (x0, y0, x1, y1);
    }
    // Pack the window (re-shading may light a pixel of a neighbouring tile),
    // and leave the scratch clean.
    let (x0, y0, x1, y1) = window;
    let (tx0, ty0, tx1, ty1) = (x0 / TILE, y0 / TILE, x1.div_ceil(TILE), y1.div_ceil(TILE));
    let mut list = Vec::new();
    for ty in ty0..ty1 {
        for tx in tx0..tx1 {
            let mut block = vec![Vec3::ZERO; TILE * TILE];
            for y in ty * TILE..((ty + 1) * TILE).min(h) {
                for x in tx * TILE..((tx + 1) * TILE).min(w) {
                    block[(y - ty * TILE) * TILE + (x - tx * TILE)] = dense[y * w + x];
                    dense[y * w + x] = Vec3::ZERO;
                    flags[y * w + x] = false;
                }
            }
            list.push((ty * tiles_x + tx, block));
        }
    }
    (LightBuffer::from_tile_list(w as u32, h as u32, list), reshaded)
}
