//! Density changes without rebuilds: a light's surface buffer and haze
//! buffer, both rendered once at 100 % density, give its buffer at any
//! density d by re-weighting each pixel (DESIGN.md "Haze"):
//!
//!   buffer_i(d) = S_i · e^(−d κ_s) + d σ_s a0 e^(−d κ_h)
//!
//! S_i is the light's surface buffer without haze (direct + indirect, what
//! Footlight rendered before haze existed), κ_s = σ_t τ_cam + σ_t' τ_light
//! (σ_t' = σ_t where the haze buffer carries the photons' term, else the
//! medium's light-path rule: [`surface_medium`]) the optical depth from the pixel's surface point to the camera and to
//! the light (computed here from the view: no ray is traced), and (a0, κ_h)
//! the haze buffer ([`super::single`]). A haze buffer with multiple
//! scattering carries that term rendered at one or more densities
//! ([`crate::render::buffer::HazeBuffer::multiple`]); it is added as it is
//! where d is one of them, else from the nearest one above (or the
//! highest) by [`super::multiple::anchored`]. Every term is linear in the
//! light's intensity, so the composite stays I = Σ k_i buffer_i(d) (eq. 5).
//!
//! Exact: at d = 0 (S_i unchanged, bit for bit), at d = 1, and for the
//! surface term of a pixel with one visible surface at any d. The haze term
//! between is a one-exponential fit of ∫ e^(−d τ(t)) over the beam; the
//! bench reports its error against a rebuild at the new density.
//!
//! Left out of the surface extinction: secondary camera segments (haze seen
//! in mirrors and through glass is attenuated as the first surface is), and
//! the spread of optical depth inside one pixel (geometry edges use the
//! centre ray's).

use super::medium::{Medium, clean_density};
use super::single::HazeView;
use crate::render::buffer::{HazeBuffer, LightBuffer, TILE};
use glam::Vec3;

/// One light's buffer at haze density `density` (0-1, NaN → 0): see the
/// module doc. `medium` is the haze at 100 %, the one `haze` was rendered
/// with; `light_position` is the light's source point. Touches only the
/// tiles `surface` or `haze` occupy.
pub fn resolve(
    hv: &HazeView,
    medium: &Medium,
    light_position: Vec3,
    surface: &LightBuffer,
    haze: Option<&HazeBuffer>,
    density: f32,
) -> LightBuffer {
    let d = clean_density(density);
    if d == 0.0 || medium.is_clear() {
        // No haze: today's buffer exactly.
        return surface.clone();
    }
    let mut candidates = surface.occupied();
    if let Some(h) = haze {
        candidates.extend(h.occupied());
        candidates.sort_unstable();
        candidates.dedup();
    }
    // The multiple-scattering term to read: held at d, else the nearest
    // density above d, else the highest.
    let multiple = haze.and_then(|b| {
        let terms = b.multiple();
        terms.iter().find(|(at, _)| *at >= d).or(terms.last())
    });
    let (w, h) = (hv.width as usize, hv.height as usize);
    let sigma_s = medium.sigma_s;
    let surfaces = surface_medium(medium, haze);
    LightBuffer::from_tiles(hv.width, hv.height, &candidates, |tx, ty, tile| {
        let (src, hz) = (surface.tile(tx, ty), haze.and_then(|b| b.as_light_buffer().tile(tx, ty)));
        let mt = multiple.and_then(|(at, m)| m.tile(tx, ty).map(|t| (*at, t)));
        let (src, hz, mt) = (src.as_deref(), hz.as_deref(), mt.as_ref().map(|(at, t)| (*at, &t[..])));
        for r in 0..TILE.min(h - ty * TILE) {
            for c in 0..TILE.min(w - tx * TILE) {
                let k = r * TILE + c;
                let i = (ty * TILE + r) * w + tx * TILE + c;
                let mut v = Vec3::ZERO;
                if let Some(s) = src
                    && s[k] != Vec3::ZERO
                {
                    v = s[k] * (-d * surface_depth(hv, &surfaces, light_position, i)).exp();
                }
                let kappa = hz.map_or(0.0, |hz| hz[k].y);
                if let Some(hz) = hz {
                    let a0 = hz[k].x;
                    if a0 > 0.0 {
                        v += Vec3::splat(d * sigma_s * a0 * (-d * kappa).exp());
                    }
                }
                if let Some((at, m)) = mt {
                    let m = m[k];
                    v += if at == d { m } else { m.map(|m| super::multiple::anchored(m, kappa, at, d)) };
                }
                tile[k] = v;
            }
        }
    })
}

/// The surface optical depth κ_s = σ_t τ_cam + σ_t' τ_light at density 1 of
/// pixel `i` for a light at `light_position` (0 where the centre ray hits
/// nothing): [`resolve`] multiplies the surface buffer by e^(−d κ_s).
/// σ_t' is `medium`'s [`Medium::sigma_t_light`]: pass the medium of
/// [`surface_medium`], which takes the whole σ_t where the photons bring
/// back the light the haze scatters out of the light path.
pub fn surface_depth(hv: &HazeView, medium: &Medium, light_position: Vec3, i: usize) -> f32 {
    match hv.hit_point(i) {
        Some(p) => {
            medium.sigma_t() * medium.length_inside(hv.camera.position, p)
                + medium.sigma_t_light() * medium.length_inside(p, light_position)
        }
        None => 0.0,
    }
}

/// The medium whose extinction dims a light's surfaces next to its haze
/// buffer `haze`: where the buffer carries the photons' term (`multiple`'s
/// refined stage and `render`), the light the haze scatters out of a
/// surface's light path comes back as the surface photons' glow, so the
/// light path takes the whole σ_t (the similarity relation's σ_t* would
/// count it twice); without photons (single scattering, the live coarse
/// stage) `medium` as it is (with `multiple`: σ_t*, standing in for it).
pub fn surface_medium(medium: &Medium, haze: Option<&HazeBuffer>) -> Medium {
    if haze.is_some_and(|h| !h.multiple().is_empty()) { Medium { multiple: false, ..*medium } } else { *medium }
}

/// The surface transmittance e^(−κ_s) at density 1 of pixel `i` for a light
/// at `light_position` (1 where the centre ray hits nothing): what
/// [`resolve`] multiplies the surface buffer by.
pub fn surface_transmittance(hv: &HazeView, medium: &Medium, light_position: Vec3, i: usize) -> f32 {
    (-surface_depth(hv, medium, light_position, i)).exp()
}
