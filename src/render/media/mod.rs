//! Haze: beams in the air, per light, still re-lit by a weighted sum
//! (issue 15; the paper's future work, Vierjahn 2010, section 5).
//!
//! Single scattering in a homogeneous medium is linear in a light's
//! intensity, so it fits eq. 5 unchanged: each light gets a haze buffer at
//! unit intensity next to its surface buffer, and dimmer and colour
//! changes stay one composite. Data flow:
//!
//! ```text
//! patch [haze] ─> Medium (100 % density)        View's G-buffer ─> HazeView (centre rays)
//!                      │                                  │
//!  moved light ─> render_inscatter(scene, hv, light, medium, HazeQuality::COARSE)  → HazeBuffer
//!                 then HazeQuality::REFINED                                         (a0, κ per pixel)
//!                      │
//!  surface buffer S_i ─┴─> resolve(hv, medium, light.position, S_i, haze_i, density) → LightBuffer
//!  (direct + indirect)        (hazer channel change: only this runs)          → composite (eq. 5)
//! ```
//!
//! # Layout
//! * [`medium`]: coefficients, Henyey-Greenstein phase, the haze box.
//! * [`single`]: per-light single scattering along camera rays
//!   (equiangular, shadowed, coarse-then-refined): the stage function.
//! * [`multiple`]: multiple scattering by volume photons (orders ≥ 2),
//!   kept in the third channel of the light's haze buffer.
//! * [`resolve`]: the composite-time density re-weighting and the
//!   extinction of the surface terms.
//! * [`live`]: the daemon's buffers per light at densities 0, ½, 1 and
//!   their composite weights (a hazer change re-weights, never rebuilds).
//! * [`reference`]: the single-pass haze reference and a Monte Carlo
//!   volume path tracer (multiple scattering).
//!
//! * [`multiple`]: multiple scattering (orders ≥ 2) by volume photons, in
//!   `render` and the live refined stage; the live coarse stage uses the
//!   similarity relation on light paths ([`Medium::sigma_t_light`]). What
//!   is left out is listed in `docs/rendering.md` ("Haze").

// `!(x > 0.0)` rejects NaN along with out-of-range values: deliberate.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod live;
pub mod medium;
pub mod multiple;
pub mod reference;
pub mod resolve;
pub mod single;

pub use live::{KNOTS, knot_buffers, knot_weights, update_knots};
pub use medium::{Medium, MediumError};
pub use resolve::resolve;
pub use single::{HazeQuality, HazeView, InScatter, integrate_ray, render_inscatter};
