//! The indirect term's error at the paper's settings (issue 13): 50,000
//! photons, 150 in the estimate, against a converged reference, split into
//! variance and bias and by region.
//!
//! Per shading vertex of a 1-sample view, E_a and E_b are the photon-map
//! irradiance (what the photons stage shows) from two photon seeds, E_ref
//! the mean of two independent path-traced estimates
//! ([`crate::render::photon::pathtrace`], unbiased; an SPPM reference is
//! itself biased low at edges while its radius is large). The reference's
//! own noise, Σ (R₁ − R₂)²/4, is measured and taken out. Over a region,
//! with S = Σ E_ref²:
//!
//! * relative MSE = (Σ (E_a − E_ref)² − ref. noise) / S,
//! * variance     = Σ (E_a − E_b)² / 2 / S (two independent seeds),
//! * bias²        = (Σ ((E_a + E_b)/2 − E_ref)² − ref. noise) / S − variance / 2
//!   (the mean of two seeds keeps half the variance).
//!
//! Regions: "boundary" vertices have another surface's photons (normal more
//! than 45° off) inside their 150-photon gather ball: walls meeting the
//! floor, corners, objects standing on the floor; "open" vertices do not.
//! Channels are summed (R+G+B).

use crate::Light;
use crate::render::photon::pathtrace::indirect_irradiance;
use crate::render::photon::{BoundaryMode, Filter, PhotonSettings, trace_photons};
use crate::render::{RecursionLimits, Sampling, View};
use crate::scene::{Camera, Material, Scene, SceneBuilder};
use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;

/// Error of one region.
#[derive(Clone, Debug, Serialize)]
pub struct RegionError {
    /// "boundary", "open" or "all".
    pub region: String,
    /// Share of the lit diffuse vertices in the region.
    pub share: f64,
    /// Relative MSE against the reference (this region's Σ E_ref²).
    pub rel_mse: f64,
    /// Its variance part (two seeds).
    pub variance: f64,
    /// Its bias² part (vs the reference).
    pub bias2: f64,
    /// Mean signed relative error Σ (mean − ref) / Σ ref: the bias's sign.
    pub mean_rel_error: f64,
}

/// One scene at one estimator setting.
#[derive(Clone, Debug, Serialize)]
pub struct IndirectRow {
    /// The scene.
    pub scene: String,
    /// Estimator ("before" / "after").
    pub estimator: String,
    /// Errors: all, boundary, open.
    pub regions: Vec<RegionError>,
    /// Path-traced samples per vertex behind each of the two references.
    pub reference_samples: usize,
    /// The reference's own noise (relative, over all vertices).
    pub reference_noise: f64,
}

/// The small Lambert box of the tests: a closed 4 m box of albedo 0.6 with
/// a spot inside, and a camera looking at a floor corner.
pub fn lambert_box() -> (Scene, Light, Camera) {
    use crate::fixture::{Beam, SpotBeam};
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::lambert("lambert", Vec3::splat(0.6)));
    let (lo, hi) = (Vec3::splat(-2.0), Vec3::splat(2.0));
    let p = |x: bool, y: bool, z: bool| {
        Vec3::new(if x { hi.x } else { lo.x }, if y { hi.y } else { lo.y }, if z { hi.z } else { lo.z })
    };
    b.add_quad(p(false, false, true), p(true, false, true), p(true, true, true), p(false, true, true), m);
    b.add_quad(p(true, false, false), p(false, false, false), p(false, true, false), p(true, true, false), m);
    b.add_quad(p(true, false, true), p(true, false, false), p(true, true, false), p(true, true, true), m);
    b.add_quad(p(false, false, false), p(false, false, true), p(false, true, true), p(false, true, false), m);
    b.add_quad(p(false, true, true), p(true, true, true), p(true, true, false), p(false, true, false), m);
    b.add_quad(p(false, false, false), p(true, false, false), p(true, false, true), p(false, false, true), m);
    let light = Light::aimed(
        Vec3::new(0.0, 1.5, 0.0),
        Vec3::new(0.5, -2.0, 0.0),
        Beam::Spot(SpotBeam::from_beam_field(50.0, 70.0)),
    );
    let camera = Camera::look_at(Vec3::new(-1.5, 1.2, 1.8), Vec3::new(1.6, -1.8, -1.8), 75f32.to_radians());
    (b.build(), light, camera)
}

/// The Lambert box with a tessellated Lambert sphere (radius 0.8 m, 24×16
/// facets, smooth vertex normals) resting on the floor in the spot's pool,
/// seen from the same camera: a curved surface meeting a flat one, where
/// boundary clipping of the gather disk has to work on facets.
pub fn lambert_box_with_sphere() -> (Scene, Light, Camera) {
    let (boxed, light, camera) = lambert_box();
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::lambert("lambert", Vec3::splat(0.6)));
    for (i, p) in boxed.positions.iter().enumerate() {
        b.add_triangle(*p, Some(boxed.normals[i]), m);
    }
    let (centre, r) = (Vec3::new(0.6, -1.2, -0.6), 0.8);
    let (nu, nv) = (24, 16);
    let at = |i: usize, j: usize| {
        let (phi, theta) = (i as f32 / nu as f32 * std::f32::consts::TAU, j as f32 / nv as f32 * std::f32::consts::PI);
        Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin())
    };
    for i in 0..nu {
        for j in 0..nv {
            let n = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
            let p = n.map(|n| centre + n * r);
            b.add_triangle([p[0], p[1], p[2]], Some([n[0], n[1], n[2]]), m);
            b.add_triangle([p[0], p[2], p[3]], Some([n[0], n[2], n[3]]), m);
        }
    }
    (b.build(), light, camera)
}

/// `scene` with every material made Lambert: albedo ρ_d + ρ_s + k_R + k_T
/// per channel (at most 0.9), no mirror, glass or Phong lobe. The path
/// tracer reference cannot see a point light through glass or in a mirror
/// (delta paths: caustics), so on the bundled stage both the photon maps
/// and the reference run on this variant: same geometry, same light, every
/// path the reference can find.
pub fn all_lambert(mut scene: Scene) -> Scene {
    for m in &mut scene.materials {
        let rho = (m.diffuse + m.specular + m.k_r + m.k_t).min(Vec3::splat(0.9));
        *m = Material::lambert(&m.name, rho);
    }
    scene
}

/// Measures the indirect error of `light` in `scene` from `camera` at
/// `w`×`h` (one vertex per pixel), before and after the boundary correction,
/// against path tracing with `reference_samples` paths per vertex (twice).
#[allow(clippy::too_many_arguments)]
pub fn measure(
    name: &str,
    scene: &Scene,
    light: &Light,
    camera: Camera,
    (w, h): (u32, u32),
    photons: PhotonSettings,
    reference_samples: usize,
) -> Vec<IndirectRow> {
    let view = View::build(scene, camera, w, h, Sampling::One, RecursionLimits { max_depth: 0, min_weight: 0.0 });
    let vertices = view.shading.vertices();
    let reference_maps = trace_photons(scene, light, &PhotonSettings { seed: photons.seed ^ 0xBEEF_0001, ..photons });
    let traced = |salt: u64| -> Vec<f64> {
        vertices
            .par_iter()
            .enumerate()
            .map(|(i, v)| {
                let e = indirect_irradiance(
                    scene,
                    light,
                    v.position,
                    v.normal,
                    reference_samples,
                    salt ^ (i as u64 * 7919),
                );
                f64::from(e.element_sum())
            })
            .collect()
    };
    let (r1, r2) = (traced(0x1234_5678), traced(0x8765_4321));
    let reference: Vec<f64> = r1.iter().zip(&r2).map(|(a, b)| (a + b) / 2.0).collect();
    let noise: Vec<f64> = r1.iter().zip(&r2).map(|(a, b)| (a - b).powi(2) / 4.0).collect();
    let boundary: Vec<bool> = vertices
        .iter()
        .map(|v| reference_maps.global.other_surface_near(v.position, v.normal, photons.estimate))
        .collect();
    let diffuse: Vec<bool> =
        vertices.iter().map(|v| scene.materials[v.material as usize].diffuse.max_element() > 0.0).collect();
    let mut rows = Vec::new();
    for (estimator, mode, filter) in [
        ("before: cone filter, full gather disk", BoundaryMode::None, Filter::Cone),
        ("cone filter, disk clipped at boundaries", BoundaryMode::Clip, Filter::Cone),
        ("after: uniform disk, full gather disk", BoundaryMode::None, Filter::Disk),
        ("uniform disk, clipped at boundaries", BoundaryMode::Clip, Filter::Disk),
        ("cone filter, measured cuts", BoundaryMode::Measured, Filter::Cone),
        ("uniform disk, measured cuts", BoundaryMode::Measured, Filter::Disk),
    ] {
        let at = |seed: u64| -> Vec<f64> {
            let maps = trace_photons(scene, light, &PhotonSettings { seed, boundary: mode, filter, ..photons });
            view.vertex_irradiance(scene, &maps).iter().map(|e| f64::from(e.element_sum())).collect()
        };
        let (a, b) = (at(photons.seed ^ 0xA), at(photons.seed ^ 0xB));
        let region = |label: &str, keep: &dyn Fn(usize) -> bool| {
            let idx: Vec<usize> =
                (0..vertices.len()).filter(|&i| diffuse[i] && reference[i] > 0.0 && keep(i)).collect();
            let lit = (0..vertices.len()).filter(|&i| diffuse[i] && reference[i] > 0.0).count().max(1);
            let s: f64 = idx.iter().map(|&i| reference[i] * reference[i]).sum::<f64>().max(f64::MIN_POSITIVE);
            let sum_ref: f64 = idx.iter().map(|&i| reference[i]).sum::<f64>().max(f64::MIN_POSITIVE);
            let ref_noise: f64 = idx.iter().map(|&i| noise[i]).sum::<f64>();
            let mse: f64 = (idx.iter().map(|&i| (a[i] - reference[i]).powi(2)).sum::<f64>() - ref_noise) / s;
            let variance: f64 = idx.iter().map(|&i| (a[i] - b[i]).powi(2) / 2.0).sum::<f64>() / s;
            let mean_err: f64 =
                (idx.iter().map(|&i| ((a[i] + b[i]) / 2.0 - reference[i]).powi(2)).sum::<f64>() - ref_noise) / s;
            let signed: f64 = idx.iter().map(|&i| (a[i] + b[i]) / 2.0 - reference[i]).sum::<f64>() / sum_ref;
            RegionError {
                region: label.into(),
                share: idx.len() as f64 / lit as f64,
                rel_mse: mse,
                variance,
                bias2: mean_err - variance / 2.0,
                mean_rel_error: signed,
            }
        };
        let regions = vec![
            region("all", &|_| true),
            region("boundary (walls, corners)", &|i| boundary[i]),
            region("open", &|i| !boundary[i]),
        ];
        let total: f64 = reference.iter().map(|r| r * r).sum::<f64>().max(f64::MIN_POSITIVE);
        rows.push(IndirectRow {
            scene: name.into(),
            estimator: estimator.into(),
            regions,
            reference_samples,
            reference_noise: noise.iter().sum::<f64>() / total,
        });
    }
    rows
}

/// Markdown table of the rows.
pub fn markdown(rows: &[IndirectRow]) -> String {
    let mut s = String::from(
        "| scene | estimator | region | share | rel. MSE | variance | bias² | mean rel. error |\n|---|---|---|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        for g in &r.regions {
            s += &format!(
                "| {} | {} | {} | {:.0} % | {:.2e} | {:.2e} | {:.2e} | {:+.3} |\n",
                r.scene,
                r.estimator,
                g.region,
                g.share * 100.0,
                g.rel_mse,
                g.variance,
                g.bias2,
                g.mean_rel_error
            );
        }
    }
    s
}
