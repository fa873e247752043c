//! Gate measurements (issue 14: gobos, framing shutters, prism, frost):
//! what a light with something in its gate costs when it is rebuilt. For
//! each spot of `tests/data/gate-patch.toml` (five GDTF spots, each with a
//! different gate), at the bench's picture size: the flux normalisation (2-D
//! quadrature, once per distinct gate: prism and frost only), the photon
//! sampler's table, and the direct-light render of the shaped light against
//! the same light with its gate open. Run with `footlight bench --gate-only`.

use crate::fixture::{Beam, BeamSampler, Light};
use crate::render::{RecursionLimits, Sampling, View};
use crate::scene::{Camera, Scene};
use std::path::Path;
use std::time::Instant;

/// One spot's costs, ms.
#[derive(Clone, Debug)]
pub struct GateRow {
    /// The fixture's name in the patch.
    pub name: String,
    /// First pattern evaluation (the flux normalisation for prism/frost; 0 otherwise).
    pub first_eval_ms: f64,
    /// Photon sampler table.
    pub sampler_ms: f64,
    /// Direct light of the shaped light (the rebuild's first stage).
    pub direct_ms: f64,
    /// Direct light of the same light with the gate open.
    pub open_ms: f64,
}

/// Measures every spot of the gate patch at `(w, h)` with `camera`.
pub fn run(scene: &Scene, camera: Camera, (w, h): (u32, u32), patch: &Path) -> Result<Vec<GateRow>, String> {
    let patch = footlight_mvr::load_patch(patch).map_err(|e| e.to_string())?;
    let view = View::build(scene, camera, w, h, Sampling::Geometry, RecursionLimits::default());
    let mut rows = Vec::new();
    for f in &patch.fixtures {
        let shaped = f.light_of(&f.look);
        let open = match &shaped.beam {
            Beam::Shaped(s) => Light { beam: Beam::Spot(s.spot.clone()), ..shaped.clone() },
            _ => shaped.clone(),
        };
        let t = Instant::now();
        let fresh = f.light_of(&f.look);
        let _ = fresh.beam.pattern(glam::Vec3::NEG_Z);
        let first_eval_ms = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let _ = BeamSampler::new(&fresh.beam);
        let sampler_ms = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let _ = view.render_light(scene, &fresh, None);
        let direct_ms = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let _ = view.render_light(scene, &open, None);
        let open_ms = t.elapsed().as_secs_f64() * 1e3;
        rows.push(GateRow { name: f.name.clone(), first_eval_ms, sampler_ms, direct_ms, open_ms });
    }
    Ok(rows)
}

/// The rows as a Markdown table.
pub fn markdown(rows: &[GateRow], (w, h): (u32, u32)) -> String {
    let mut s = format!(
        "| spot ({w}×{h}) | first pattern eval (flux norm) ms | photon sampler ms | direct light ms | same, gate open ms |\n|---|---|---|---|---|\n"
    );
    for r in rows {
        s += &format!(
            "| {} | {:.1} | {:.1} | {:.1} | {:.1} |\n",
            r.name, r.first_eval_ms, r.sampler_ms, r.direct_ms, r.open_ms
        );
    }
    s
}
