//! Emitter groups stored by what differs (issue 38 item 3; DESIGN.md
//! "Storage by what differs").
//!
//! The cells of one fixture hang centimetres apart and light nearly the
//! same footprint, so per 16×16 tile their unit buffers B_c (eq. 5) are
//! nearly proportional. [`GroupBuffer`] keeps, per tile, either
//!
//! * a **low-rank form** B_c ≈ Σ_j a_cj U_j with r ≤ [`MAX_RANK`] basis
//!   tiles U_j (orthonormal, 256 RGB pixels each) and r coefficients per
//!   cell. U_1 is the cells' sum Σ_c B_c (normalised), further U_j are the
//!   leading singular vectors of what the earlier ones leave (power
//!   iteration on the cells' m×m Gram matrix), and a_cj = ⟨B_c, U_j⟩, so
//!   each cell's tile is its orthogonal projection on span(U_1…U_r). As the
//!   span holds Σ_c B_c, Σ_c a_cj U_j sums to Σ_c B_c exactly: a group whose
//!   cells share one k (a bar at one colour) composites exactly (to f32);
//! * or, where no rank ≤ [`MAX_RANK`] meets the bound (near field, shadows
//!   of the cells' own bodies, lens glow), the **cells' own tiles**, exact.
//!
//! **The bound.** With E_c the energy Σ|B_c|² of cell c over the picture
//! and T_c its occupied tiles, a tile is kept low-rank only if for every
//! cell ‖B_c − Σ_j a_cj U_j‖² ≤ τ (‖B_c‖²_tile + E_c / T_c). Summed over the
//! tiles, each cell's relative squared error over the picture (its rel.
//! MSE alone at k = 1) is at most 2τ. A picture mixes cells with k_c ≥ 0;
//! its error is at most the cells' errors added in amplitude, and in
//! practice (the errors of neighbouring cells cancel: they sum to 0 per
//! tile) near τ: `tests/groups.rs` measures both.
//!
//! **The composite** ([`GroupBuffer::accumulate_tile`]): per low-rank tile
//! w_j = Σ_c k_c a_cj (RGB, since k is RGB) and tile += Σ_j w_j ⊙ U_j: the
//! cost is m·r + 256·r multiply-adds instead of m·256, and the memory
//! r·256 + m·r values instead of m·256. The bytes are
//! [`GroupBuffer::bytes`].

use super::buffer::{LightBuffer, TILE};
use glam::Vec3;
use rayon::prelude::*;

const TILE_PIXELS: usize = TILE * TILE;
/// Values of one tile (RGB).
const TILE_VALUES: usize = TILE_PIXELS * 3;
const EMPTY: u32 = u32::MAX;

/// The highest rank a tile is kept at before it falls back to the cells'
/// own tiles.
pub const MAX_RANK: usize = 3;

/// How a group's storage is built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroupSettings {
    /// τ of the bound: each cell's relative squared error over the
    /// picture is at most 2τ.
    pub tolerance: f32,
    /// Highest rank per tile (1 to [`MAX_RANK`]); 0 keeps every tile exact.
    pub max_rank: usize,
}

impl Default for GroupSettings {
    /// τ = 1e-4 (each cell within 2e-4; issue 38's bound is 1e-3), rank ≤ 3.
    fn default() -> Self {
        Self { tolerance: 1e-4, max_rank: MAX_RANK }
    }
}

/// How one tile of a group is stored.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Form {
    /// `rank` basis tiles from `basis` (in tiles) and `cells × rank`
    /// coefficients from `coeffs`, cell-major.
    LowRank { rank: u32, basis: u32, coeffs: u32 },
    /// `count` cell tiles from `first` in `exact`.
    Exact { first: u32, count: u32 },
}

/// What a tile became while building.
enum Built {
    LowRank { rank: usize, basis: Vec<Vec3>, coeffs: Vec<f32> },
    Exact(Vec<(u32, Vec<Vec3>)>),
}

/// A group's cell buffers, per tile low-rank or exact (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct GroupBuffer {
    width: u32,
    height: u32,
    tiles_x: usize,
    cells: usize,
    /// Per tile: index into `forms`, or EMPTY (no cell reaches it).
    slot: Vec<u32>,
    forms: Vec<Form>,
    /// Basis tiles U_j, TILE×TILE row-major each, unit norm.
    basis: Vec<Vec3>,
    /// Per low-rank tile, a_cj at `c * rank + j`.
    coeffs: Vec<f32>,
    /// Exact tiles: (cell, index in tiles into `exact_data`).
    exact: Vec<(u32, u32)>,
    exact_data: Vec<Vec3>,
    /// Cell tiles the cells' own buffers held.
    cell_tiles: usize,
}

/// How a group's tiles are stored, for the bench and the status.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct GroupStats {
    /// Tiles any cell reaches.
    pub tiles: usize,
    /// Of those, tiles kept at rank 1, 2 and 3.
    pub rank_tiles: [usize; MAX_RANK],
    /// Tiles kept as the cells' own tiles.
    pub exact_tiles: usize,
    /// Cell tiles held by the exact tiles.
    pub exact_cell_tiles: usize,
    /// Cell tiles the cells' own buffers hold (what per-cell storage costs).
    pub cell_tiles: usize,
}

impl GroupBuffer {
    /// Builds the storage of a group from its cells' unit buffers (all of
    /// the same size), parallel over tiles.
    ///
    /// # Panics
    /// If `cells` is empty or the buffers differ in size.
    pub fn build(cells: &[&LightBuffer], settings: GroupSettings) -> Self {
        assert!(!cells.is_empty(), "a group has at least one cell");
        let (width, height) = (cells[0].width, cells[0].height);
        assert!(cells.iter().all(|b| b.width == width && b.height == height), "cells of one size");
        let tiles_x = (width as usize).div_ceil(TILE);
        let n_tiles = cells[0].total_tiles();
        // Per cell: E_c / T_c, its mean squared tile energy (the floor of its
        // per-tile budget, so the bound sums to 2τ over the picture).
        let floor: Vec<f64> = cells
            .iter()
            .map(|b| {
                let energy: f64 = b.values().map(|v| f64::from(v.length_squared())).sum();
                energy / b.occupied_tiles().max(1) as f64
            })
            .collect();
        let built: Vec<(usize, Built)> = (0..n_tiles)
            .into_par_iter()
            .filter_map(|t| {
                let (tx, ty) = (t % tiles_x, t / tiles_x);
                let tiles: Vec<(u32, std::borrow::Cow<[Vec3]>)> =
                    cells.iter().enumerate().filter_map(|(c, b)| b.tile(tx, ty).map(|s| (c as u32, s))).collect();
                let present: Vec<(u32, &[Vec3])> = tiles.iter().map(|(c, t)| (*c, &t[..])).collect();
                (!present.is_empty()).then(|| (t, build_tile(&present, cells.len(), &floor, settings)))
            })
            .collect();
        let mut g = Self {
            width,
            height,
            tiles_x,
            cells: cells.len(),
            slot: vec![EMPTY; n_tiles],
            forms: Vec::with_capacity(built.len()),
            basis: Vec::new(),
            coeffs: Vec::new(),
            exact: Vec::new(),
            exact_data: Vec::new(),
            cell_tiles: cells.iter().map(|b| b.occupied_tiles()).sum(),
        };
        for (t, b) in built {
            g.slot[t] = g.forms.len() as u32;
            match b {
                Built::LowRank { rank, basis, coeffs } => {
                    g.forms.push(Form::LowRank {
                        rank: rank as u32,
                        basis: (g.basis.len() / TILE_PIXELS) as u32,
                        coeffs: g.coeffs.len() as u32,
                    });
                    g.basis.extend(basis);
                    g.coeffs.extend(coeffs);
                }
                Built::Exact(tiles) => {
                    g.forms.push(Form::Exact { first: g.exact.len() as u32, count: tiles.len() as u32 });
                    for (c, data) in tiles {
                        g.exact.push((c, (g.exact_data.len() / TILE_PIXELS) as u32));
                        g.exact_data.extend(data);
                    }
                }
            }
        }
        g
    }

    /// A storage of no cells (a group whose storage is not built yet: it
    /// is never current, so its cells composite per light).
    pub fn empty(width: u32, height: u32) -> Self {
        let tiles_x = (width as usize).div_ceil(TILE);
        let n_tiles = tiles_x * (height as usize).div_ceil(TILE);
        Self {
            width,
            height,
            tiles_x,
            cells: 0,
            slot: vec![EMPTY; n_tiles],
            forms: Vec::new(),
            basis: Vec::new(),
            coeffs: Vec::new(),
            exact: Vec::new(),
            exact_data: Vec::new(),
            cell_tiles: 0,
        }
    }

    /// Image width.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Image height.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Number of cells (the k a composite takes).
    pub fn cells(&self) -> usize {
        self.cells
    }

    /// Bytes held: basis tiles, coefficients, exact tiles, the tile table.
    pub fn bytes(&self) -> usize {
        (self.basis.len() + self.exact_data.len()) * std::mem::size_of::<Vec3>()
            + self.coeffs.len() * 4
            + self.exact.len() * 8
            + self.forms.len() * std::mem::size_of::<Form>()
            + self.slot.len() * 4
    }

    /// How the tiles are stored.
    pub fn stats(&self) -> GroupStats {
        let mut s = GroupStats { tiles: self.forms.len(), cell_tiles: self.cell_tiles, ..Default::default() };
        for f in &self.forms {
            match *f {
                Form::LowRank { rank, .. } => s.rank_tiles[rank as usize - 1] += 1,
                Form::Exact { count, .. } => {
                    s.exact_tiles += 1;
                    s.exact_cell_tiles += count as usize;
                }
            }
        }
        s
    }

    /// Tile indices (row-major over the tile grid) any cell reaches.
    pub fn covered(&self) -> Vec<u32> {
        (0..self.slot.len() as u32).filter(|&t| self.slot[t as usize] != EMPTY).collect()
    }

    /// Whether tile (tx, ty) is kept as the cells' own tiles (exact).
    pub fn is_exact(&self, tx: usize, ty: usize) -> bool {
        matches!(self.slot[ty * self.tiles_x + tx], s if s != EMPTY && matches!(self.forms[s as usize], Form::Exact { .. }))
    }

    /// Cell `c`'s buffer as this storage reproduces it (for tests and the
    /// bench's error measurement).
    pub fn cell(&self, c: usize) -> LightBuffer {
        let mut k = vec![Vec3::ZERO; self.cells];
        k[c] = Vec3::ONE;
        let tiles: Vec<(usize, Vec<Vec3>)> = self
            .covered()
            .into_iter()
            .map(|t| {
                let t = t as usize;
                let (tx, ty) = (t % self.tiles_x, t / self.tiles_x);
                let mut band = vec![Vec3::ZERO; TILE_PIXELS];
                self.accumulate_tile_at(&k, tx, ty, TILE, TILE, 0, &mut band);
                (t, band)
            })
            .collect();
        LightBuffer::from_tile_list(self.width, self.height, tiles)
    }

    /// Adds Σ_c k_c ⊙ B_c of tile (tx, ty) into `band`, the image rows of
    /// tile row ty, `w` pixels wide (the layout of the compositor's bands).
    /// `k` holds one weight per cell.
    pub fn accumulate_tile(&self, k: &[Vec3], tx: usize, ty: usize, w: usize, band: &mut [Vec3]) {
        let rows = band.len() / w.max(1);
        let x0 = tx * TILE;
        self.accumulate_tile_at(k, tx, ty, w, rows, x0, band);
    }

    /// [`Self::accumulate_tile`] with the band's width, rows and the
    /// tile's first column given.
    #[allow(clippy::too_many_arguments)]
    fn accumulate_tile_at(
        &self,
        k: &[Vec3],
        tx: usize,
        ty: usize,
        w: usize,
        rows: usize,
        x0: usize,
        band: &mut [Vec3],
    ) {
        debug_assert_eq!(k.len(), self.cells, "one k per cell");
        let s = self.slot[ty * self.tiles_x + tx];
        if s == EMPTY {
            return;
        }
        let cols = TILE.min(self.width as usize - tx * TILE).min(w - x0);
        match self.forms[s as usize] {
            Form::LowRank { rank, basis, coeffs } => {
                let rank = rank as usize;
                let a = &self.coeffs[coeffs as usize..coeffs as usize + self.cells * rank];
                for j in 0..rank {
                    // w_j = Σ_c k_c a_cj: the cells' weights folded into one RGB weight.
                    let wj = k.iter().enumerate().fold(Vec3::ZERO, |acc, (c, kc)| acc + *kc * a[c * rank + j]);
                    if wj == Vec3::ZERO {
                        continue;
                    }
                    let u = &self.basis[(basis as usize + j) * TILE_PIXELS..(basis as usize + j + 1) * TILE_PIXELS];
                    add_scaled(u, wj, w, rows, x0, cols, band);
                }
            }
            Form::Exact { first, count } => {
                for &(c, d) in &self.exact[first as usize..(first + count) as usize] {
                    let kc = k[c as usize];
                    if kc == Vec3::ZERO {
                        continue;
                    }
                    add_scaled(
                        &self.exact_data[d as usize * TILE_PIXELS..(d as usize + 1) * TILE_PIXELS],
                        kc,
                        w,
                        rows,
                        x0,
                        cols,
                        band,
                    );
                }
            }
        }
    }
}

/// The groups of a rig from one key per light (a light's fixture id):
/// each run of two or more consecutive lights with the same `Some` key is
/// a group (a fixture's cells), as indices into the lights.
pub fn runs_of<T: PartialEq>(keys: &[Option<T>]) -> Vec<Vec<usize>> {
    let mut runs: Vec<Vec<usize>> = Vec::new();
    for (i, key) in keys.iter().enumerate() {
        match runs.last_mut() {
            Some(run) if key.is_some() && keys[run[0]] == *key => run.push(i),
            _ => runs.push(vec![i]),
        }
    }
    runs.retain(|r| r.len() > 1 && keys[r[0]].is_some());
    runs
}

/// band[r·w + x0 + x] += k ⊙ tile[r·TILE + x] over `rows` × `cols`, as
/// a plain f32 multiply-add the compiler vectorises (as in the compositor).
fn add_scaled(tile: &[Vec3], k: Vec3, w: usize, rows: usize, x0: usize, cols: usize, band: &mut [Vec3]) {
    let kk: [f32; 3 * TILE] = std::array::from_fn(|i| k[i % 3]);
    for r in 0..rows {
        let dst: &mut [f32] = bytemuck::cast_slice_mut(&mut band[r * w + x0..r * w + x0 + cols]);
        let src: &[f32] = bytemuck::cast_slice(&tile[r * TILE..r * TILE + cols]);
        for ((d, s), k) in dst.iter_mut().zip(src).zip(&kk) {
            *d += k * s; // Vierjahn 2010, eq. (5), through the group's storage
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// One tile's storage from the `present` cells' tiles (cell index, tile);
/// `cells` in the group, `floor` per cell (E_c / T_c).
fn build_tile(present: &[(u32, &[Vec3])], cells: usize, floor: &[f64], settings: GroupSettings) -> Built {
    let m = present.len();
    let exact = || Built::Exact(present.iter().map(|(c, t)| (*c, t.to_vec())).collect());
    // A rank as high as the cells present stores no less than they do.
    let max_rank = settings.max_rank.min(MAX_RANK).min(m.saturating_sub(1));
    if max_rank == 0 {
        return exact();
    }
    // Each present cell's tile as 768 f64 values; R_c starts as B_c.
    let b: Vec<Vec<f64>> = present
        .iter()
        .map(|(_, t)| bytemuck::cast_slice::<Vec3, f32>(t).iter().map(|&v| f64::from(v)).collect())
        .collect();
    let tol = f64::from(settings.tolerance);
    let budget: Vec<f64> =
        present.iter().zip(&b).map(|((c, _), bc)| tol * (dot(bc, bc) + floor[*c as usize])).collect();
    let mut r = b.clone();
    let mut basis: Vec<Vec<f64>> = Vec::new();
    let mut a: Vec<Vec<f64>> = vec![Vec::new(); m]; // a[i][j], i over present cells
    for j in 0..max_rank {
        // U_1 = Σ_c B_c; later U_j: the leading singular vector of the residuals.
        let mut u = vec![0.0f64; TILE_VALUES];
        if j == 0 {
            for bc in &b {
                u.iter_mut().zip(bc).for_each(|(u, v)| *u += v);
            }
        } else {
            let v = leading_eigenvector(&r);
            for (vi, ri) in v.iter().zip(&r) {
                u.iter_mut().zip(ri).for_each(|(u, x)| *u += vi * x);
            }
            // Re-orthogonalise against the earlier basis (rounding).
            for q in &basis {
                let d = dot(&u, q);
                u.iter_mut().zip(q).for_each(|(u, q)| *u -= d * q);
            }
        }
        let norm = dot(&u, &u).sqrt();
        if !(norm > 0.0 && norm.is_finite()) {
            break;
        }
        u.iter_mut().for_each(|x| *x /= norm);
        for (i, ri) in r.iter_mut().enumerate() {
            let aij = dot(ri, &u);
            ri.iter_mut().zip(&u).for_each(|(x, q)| *x -= aij * q);
            a[i].push(aij);
        }
        basis.push(u);
        if r.iter().zip(&budget).all(|(ri, bud)| dot(ri, ri) <= *bud) {
            let rank = basis.len();
            let mut coeffs = vec![0.0f32; cells * rank];
            for ((c, _), ai) in present.iter().zip(&a) {
                for (jj, v) in ai.iter().enumerate() {
                    coeffs[*c as usize * rank + jj] = *v as f32;
                }
            }
            let basis: Vec<Vec3> = basis
                .iter()
                .flat_map(|u| u.chunks_exact(3).map(|p| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32)))
                .collect();
            return Built::LowRank { rank, basis, coeffs };
        }
    }
    exact()
}

/// The leading eigenvector of the residuals' Gram matrix G_ik = ⟨R_i, R_k⟩
/// (m×m), by power iteration from the residual norms; unit length.
fn leading_eigenvector(r: &[Vec<f64>]) -> Vec<f64> {
    let m = r.len();
    let mut g = vec![0.0f64; m * m];
    for i in 0..m {
        for k in i..m {
            let d = dot(&r[i], &r[k]);
            g[i * m + k] = d;
            g[k * m + i] = d;
        }
    }
    // Start from the residual norms plus a ramp over the cells (a shifted
    // footprint's first-order term), so the start is never orthogonal to
    // the answer in the cases that matter.
    let mut v: Vec<f64> = (0..m).map(|i| g[i * m + i].sqrt() + 1e-3 * (i as f64 + 1.0)).collect();
    for _ in 0..40 {
        let next: Vec<f64> = (0..m).map(|i| dot(&g[i * m..(i + 1) * m], &v)).collect();
        let n = dot(&next, &next).sqrt();
        if !(n > 0.0 && n.is_finite()) {
            break;
        }
        v = next.into_iter().map(|x| x / n).collect();
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    fn buffer(w: u32, h: u32, f: impl Fn(u32, u32) -> Vec3) -> LightBuffer {
        let dense: Vec<Vec3> = (0..w * h).map(|i| f(i % w, i / w)).collect();
        LightBuffer::from_dense(w, h, &dense)
    }

    fn dense_composite(g: &GroupBuffer, k: &[Vec3]) -> Vec<Vec3> {
        let w = g.width() as usize;
        let mut out = vec![Vec3::ZERO; w * g.height() as usize];
        for (ty, band) in out.chunks_mut(w * TILE).enumerate() {
            for tx in 0..w.div_ceil(TILE) {
                g.accumulate_tile(k, tx, ty, w, band);
            }
        }
        out
    }

    #[test]
    fn runs_are_consecutive_cells_of_one_fixture() {
        let keys = [Some(1), Some(1), None, None, Some(2), Some(3), Some(3), Some(3), Some(1)];
        assert_eq!(runs_of(&keys), vec![vec![0, 1], vec![5, 6, 7]]);
    }

    /// Proportional cells are one basis tile; the composite is Σ k_c B_c.
    #[test]
    fn proportional_cells_are_rank_one_and_composite_exactly() {
        let (w, h) = (40u32, 20u32);
        let shape = |x: u32, y: u32| Vec3::new(1.0 + x as f32, 0.5 + y as f32, 0.25) * 0.01;
        let cells: Vec<LightBuffer> = (0..4).map(|c| buffer(w, h, |x, y| shape(x, y) * (c + 1) as f32)).collect();
        let refs: Vec<&LightBuffer> = cells.iter().collect();
        let g = GroupBuffer::build(&refs, GroupSettings::default());
        let s = g.stats();
        assert_eq!(s.tiles, 3 * 2);
        assert_eq!(s.rank_tiles[0], 6, "{s:?}");
        let k = [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0), Vec3::ZERO, Vec3::new(0.3, 0.3, 3.0)];
        let got = dense_composite(&g, &k);
        let want = crate::render::composite(&refs, &k, w, h);
        for (a, b) in got.iter().zip(&want) {
            assert!((*a - *b).abs().max_element() <= 1e-5 * b.max_element().max(1e-3), "{a} vs {b}");
        }
        assert!(g.bytes() < refs.iter().map(|b| b.bytes()).sum::<usize>() / 2);
    }

    /// A shifted bump: rank 1 does not fit, a higher rank does within the
    /// bound; cells that share nothing stay exact; each cell's error over
    /// the picture is within 2τ.
    #[test]
    fn shifted_cells_take_a_higher_rank_and_disjoint_cells_stay_exact() {
        let (w, h) = (64u32, 32u32);
        let bump = |x: u32, y: u32, cx: f32| {
            // A smooth bump of radius 14 px: (1 − r²/R²)³.
            let d = ((x as f32 - cx).powi(2) + (y as f32 - 16.0).powi(2)) / 196.0;
            Vec3::new(1.0, 0.8, 0.6) * (1.0 - d).max(0.0).powi(3)
        };
        let mut cells: Vec<LightBuffer> =
            (0..6).map(|c| buffer(w, h, |x, y| bump(x, y, 30.0 + 0.4 * c as f32))).collect();
        // A cell that lights only one far tile, alone there.
        cells.push(buffer(w, h, |x, y| if x >= 48 && y < 16 { Vec3::ONE } else { Vec3::ZERO }));
        let refs: Vec<&LightBuffer> = cells.iter().collect();
        let settings = GroupSettings { tolerance: 1e-5, max_rank: 3 };
        let g = GroupBuffer::build(&refs, settings);
        let s = g.stats();
        assert!(s.rank_tiles[1] + s.rank_tiles[2] > 0, "{s:?}");
        for (c, b) in refs.iter().enumerate() {
            let (got, want) = (g.cell(c).to_dense(), b.to_dense());
            let err: f64 = got.iter().zip(&want).map(|(a, b)| f64::from((*a - *b).length_squared())).sum();
            let energy: f64 = want.iter().map(|b| f64::from(b.length_squared())).sum();
            assert!(err <= 2.0 * 1e-5 * energy * 1.01, "cell {c}: {err} vs {energy}");
        }
        // The one-cell tile is stored exactly.
        assert!(g.is_exact(3, 0));
        assert_eq!(g.cell(6).to_dense(), cells[6].to_dense());
        // Uniform k is exact: the basis spans the cells' sum.
        let k = vec![Vec3::new(0.2, 0.7, 1.3); 7];
        let got = dense_composite(&g, &k);
        let want = crate::render::composite(&refs, &k, w, h);
        for (a, b) in got.iter().zip(&want) {
            assert!((*a - *b).abs().max_element() <= 1e-5 * b.max_element().max(1e-3), "{a} vs {b}");
        }
    }
}
