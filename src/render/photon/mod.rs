//! Per-light photon maps: the indirect term I_h,ε_A,i of Vierjahn 2010,
//! eq. 3 and 5.
//!
//! Each light gets its own photon maps, traced from a unit-intensity source
//! with the light's emission pattern, so its indirect buffer is scaled by
//! the same k_i as its direct buffer (the composite is Σ k_i (A_i + D_i)).
//!
//! # Layout
//! * [`trace`]: emission importance-sampled from the beam, Russian-roulette
//!   diffuse bounces, k_R/k_T specular bounces; photons stored on diffuse
//!   surfaces after at least one bounce (direct light is ray traced): a
//!   global map (paths with a diffuse bounce) and a caustic map (specular-only
//!   paths), Jensen's split.
//! * [`map`]: k-d trees (kiddo) and radiance estimates: kNN with a cone
//!   filter and the kNN bias correction; global illumination through
//!   precomputed irradiance at photon positions (Christensen 1999).
//! * [`sppm`]: stochastic progressive photon mapping (Hachisuka & Jensen
//!   2009) at the view's shading vertices, for refinement while idle.
//! * [`pathtrace`]: a brute-force path tracer for the indirect term of
//!   diffuse scenes: the independent reference in tests and benchmarks.

pub mod map;
pub mod pathtrace;
pub mod sppm;
pub mod trace;

pub use map::{BoundaryMode, Filter, IrradianceCache, Photon, PhotonMap};
pub use sppm::{PassTimes, Progressive};
pub use trace::{PhotonMaps, TraceTimes, WIDE_LOOKUP, trace_photons, trace_photons_until};

/// Photon-mapping settings (paper, section 4: 50,000 photons stored per
/// map, 150 in the estimate).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhotonSettings {
    /// Indirect photons to store per light (global + caustic).
    pub stored: usize,
    /// Photons in a global-map radiance estimate (k of the kNN).
    pub estimate: usize,
    /// Photons in a caustic-map radiance estimate.
    pub caustic_estimate: usize,
    /// Emission stops after `stored · max_emitted_factor` photons even if
    /// fewer were stored (beams that mostly leave the scene).
    pub max_emitted_factor: usize,
    /// Bounce limit (Russian roulette ends most paths earlier).
    pub max_bounces: u32,
    /// Precompute irradiance at every n-th global photon (Christensen 1999).
    pub irradiance_stride: usize,
    /// Seed of the light's photon RNG (combined with the light index).
    pub seed: u64,
    /// Gather disks at edges and corners ([`BoundaryMode::Measured`] by
    /// default; all three measured in `footlight bench --accuracy-only`).
    pub boundary: BoundaryMode,
    /// Kernel of the global map's estimates (the caustic map keeps the
    /// sharper cone). [`Filter::Disk`] has 2/3 of the cone's variance at the
    /// same k and halves the error in the test boxes, but blurs the bundled
    /// stage's spot pools and corners more (relative MSE 6.8e-2 → 7.9e-2
    /// with measured cuts), so the cone stays the default (issue 13,
    /// `footlight bench --accuracy-only`).
    pub filter: Filter,
    /// Photons emitted per SPPM pass ([`Progressive`]), rounded up to whole
    /// 2048-photon chunks; 0: as many as `stored`.
    pub pass_emitted: usize,
}

impl Default for PhotonSettings {
    fn default() -> Self {
        Self {
            stored: 50_000,
            estimate: 150,
            caustic_estimate: 60,
            max_emitted_factor: 20,
            max_bounces: 16,
            irradiance_stride: 4,
            seed: 0x00F0_07B1_6B75,
            boundary: BoundaryMode::Measured,
            filter: Filter::Cone,
            pass_emitted: 0,
        }
    }
}
