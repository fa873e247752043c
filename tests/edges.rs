//! Edge pixels resolved to the box filter (issue 34, items 1 and 2): a
//! hard-edged spot on a box standing on a floor (beam rim, shadow and
//! geometry edges, silhouettes), a framing-shutter cut and a gobo, each
//! against a box-filtered reference computed here from first principles
//! (16×16 jittered samples per pixel, f64: the camera ray meets the floor
//! or the box by a slab test, the shadow ray is tested against the box,
//! E = I·f(ω)·cos/d² and the pixel shows ρ/π·E). The only renderer code
//! the reference calls is the beam's own pattern `Light::pattern_toward`
//! (what is tested is how a pixel integrates it, not the pattern).
//!
//! The Whitted stage (adaptive 9-sample anti-aliasing) is measured, then
//! the refinement's edge supersampling ([`EdgeSamples`]) after 2 and 4
//! passes: it must reach issue 34's refined target (1e-4) on every set-up
//! and cut the edge pixels' error.

use crate::common::*;
use footlight::fixture::beam::{Blade, Gate, GoboImage, ShapedBeam};
use footlight::fixture::{Beam, Light, SpotBeam};
use footlight::render::buffer::LightBuffer;
use footlight::render::view::{AA_THRESHOLD, AaParams, EdgeSamples, Sampling};
use footlight::scene::{Camera, Scene, SceneBuilder};
use glam::{DVec3, Vec3};
use std::sync::Arc;

const W: u32 = 160;
const H: u32 = 100;
/// Reference strata per pixel side.
const REF_SIDE: usize = 16;
const RHO_FLOOR: f64 = 0.6;
const RHO_BOX: f64 = 0.7;
const FLOOR_HALF: f64 = 8.0;

/// One set-up: a light, a camera, and whether the box stands on the floor.
struct Setup {
    name: &'static str,
    light: Light,
    camera: Camera,
    cube: Option<(DVec3, DVec3)>,
}

fn hard_spot(half_deg: f32) -> SpotBeam {
    let half = half_deg.to_radians();
    SpotBeam::from_half_angles(half, half)
}

fn setups() -> Vec<Setup> {
    let look = |eye: Vec3, at: Vec3| Camera::look_at(eye, at, 50f32.to_radians());
    let shutter = Gate {
        blades: [
            Blade { a: 0.35, b: 0.2, rot: 0.0 },
            Blade { a: 0.25, b: 0.25, rot: 10.0 },
            Blade::default(),
            Blade::default(),
        ],
        ..Gate::default()
    };
    // A 64×64 image of an 8×8 checker: 32 open squares, each 8 texels wide
    // (the gate samples texels bilinearly: a ramp one texel wide at each cut).
    let checker: Vec<u8> = (0..64 * 64).map(|i| if ((i % 64) / 8 + (i / 64) / 8) % 2 == 0 { 255 } else { 0 }).collect();
    let gobo = Gate {
        gobo: Some(Arc::new(GoboImage::from_luma8("checker", 64, 64, &checker).expect("64×64 gobo"))),
        ..Gate::default()
    };
    vec![
        Setup {
            name: "hard spot on a box",
            light: Light::aimed(Vec3::new(-2.0, 4.0, 1.5), Vec3::new(0.0, 0.5, 0.0), Beam::Spot(hard_spot(25.0))),
            camera: look(Vec3::new(0.5, 3.0, 6.0), Vec3::new(0.0, 0.4, 0.0)),
            cube: Some((DVec3::new(-0.5, 0.0, -0.5), DVec3::new(0.5, 1.0, 0.5))),
        },
        Setup {
            name: "shutter cut",
            light: Light::aimed(
                Vec3::new(0.3, 3.5, 2.0),
                Vec3::ZERO,
                Beam::Shaped(Box::new(ShapedBeam::new(hard_spot(18.0), shutter))),
            ),
            camera: look(Vec3::new(0.0, 4.0, 5.0), Vec3::ZERO),
            cube: None,
        },
        Setup {
            name: "gobo",
            light: Light::aimed(
                Vec3::new(-0.4, 4.0, 1.0),
                Vec3::new(0.1, 0.0, 0.0),
                Beam::Shaped(Box::new(ShapedBeam::new(hard_spot(24.0), gobo))),
            ),
            camera: look(Vec3::new(0.0, 4.0, 5.0), Vec3::ZERO),
            cube: None,
        },
    ]
}

fn scene(s: &Setup) -> Scene {
    let mut b = SceneBuilder::new();
    let f = lambert(&mut b, RHO_FLOOR as f32);
    floor(&mut b, FLOOR_HALF as f32, 0.0, f);
    if let Some((min, max)) = s.cube {
        let m = lambert(&mut b, RHO_BOX as f32);
        cube(&mut b, min.as_vec3(), max.as_vec3(), m);
    }
    b.build()
}

/// Entry and exit distances of a ray through an axis-aligned box, and the
/// axis of the entry face (slab test).
fn slab(o: DVec3, d: DVec3, min: DVec3, max: DVec3) -> Option<(f64, f64, usize)> {
    let (mut near, mut far, mut axis) = (f64::NEG_INFINITY, f64::INFINITY, 0);
    for a in 0..3 {
        let inv = 1.0 / d[a];
        let (t0, t1) = ((min[a] - o[a]) * inv, (max[a] - o[a]) * inv);
        let (t0, t1) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
        if t0 > near {
            near = t0;
            axis = a;
        }
        far = far.min(t1);
    }
    (near <= far && far > 0.0).then_some((near, far, axis))
}

/// The box-filtered direct term (green: every material is grey) of every
/// pixel, and whether the pixel is an edge pixel of the reference: its
/// samples disagree on the surface they see, or their values differ by
/// more than a tenth of the largest (a rim, cut or shadow crosses it).
fn reference(s: &Setup) -> (Vec<f64>, Vec<bool>) {
    let camera = &s.camera;
    let eye = camera.position.as_dvec3();
    let (right, up, back) =
        (camera.basis.x_axis.as_dvec3(), camera.basis.y_axis.as_dvec3(), camera.basis.z_axis.as_dvec3());
    let tan_half = (f64::from(camera.yfov) * 0.5).tan();
    let aspect = f64::from(W) / f64::from(H);
    let light = s.light.position.as_dvec3();
    let mut rng = Rng(0x5EED_E06E);
    let n = (W * H) as usize;
    let (mut value, mut edge) = (vec![0.0; n], vec![false; n]);
    for y in 0..H as usize {
        for x in 0..W as usize {
            let mut sum = 0.0;
            let (mut seen, mut low, mut high): (Option<u8>, f64, f64) = (None, f64::INFINITY, 0.0);
            for j in 0..REF_SIDE {
                for i in 0..REF_SIDE {
                    let px = x as f64 + (i as f64 + f64::from(rng.next_f32())) / REF_SIDE as f64;
                    let py = y as f64 + (j as f64 + f64::from(rng.next_f32())) / REF_SIDE as f64;
                    let nx = (2.0 * px / f64::from(W) - 1.0) * tan_half * aspect;
                    let ny = (1.0 - 2.0 * py / f64::from(H)) * tan_half;
                    let dir = (right * nx + up * ny - back).normalize();
                    // The nearest of the floor and the box.
                    let mut hit: Option<(f64, DVec3, f64, u8)> = None;
                    if dir.y < 0.0 {
                        let t = -eye.y / dir.y;
                        let p = eye + dir * t;
                        if p.x.abs() <= FLOOR_HALF && p.z.abs() <= FLOOR_HALF {
                            hit = Some((t, DVec3::Y, RHO_FLOOR, 1));
                        }
                    }
                    if let Some((min, max)) = s.cube
                        && let Some((t, _, axis)) = slab(eye, dir, min, max)
                        && t > 0.0
                        && hit.is_none_or(|h| t < h.0)
                    {
                        let mut normal = DVec3::ZERO;
                        normal[axis] = -dir[axis].signum();
                        hit = Some((t, normal, RHO_BOX, 2 + axis as u8));
                    }
                    let Some((t, normal, rho, surface)) = hit else {
                        edge[y * W as usize + x] |= seen.is_some_and(|s| s != 0);
                        seen.get_or_insert(0);
                        low = 0.0;
                        continue;
                    };
                    let p = eye + dir * t;
                    let to = light - p;
                    let d2 = to.length_squared();
                    let wi = to / d2.sqrt();
                    let cos = normal.dot(wi);
                    let shadowed = s.cube.is_some_and(|(min, max)| {
                        slab(p + normal * 1e-9, wi, min, max).is_some_and(|(t0, _, _)| t0 > 1e-9 && t0 < d2.sqrt())
                    });
                    let f =
                        if cos > 0.0 && !shadowed { f64::from(s.light.pattern_toward((-wi).as_vec3())) } else { 0.0 };
                    let at = y * W as usize + x;
                    edge[at] |= seen.is_some_and(|s| s != surface);
                    seen.get_or_insert(surface);
                    let v = rho / std::f64::consts::PI * f * cos.max(0.0) / d2;
                    (low, high) = (low.min(v), high.max(v));
                    sum += v;
                }
            }
            let at = y * W as usize + x;
            edge[at] |= high > 0.0 && high - low > 0.1 * high;
            value[at] = sum / (REF_SIDE * REF_SIDE) as f64;
        }
    }
    (value, edge)
}

#[test]
fn edge_supersampling_converges_rims_cuts_gobos_and_geometry_edges_to_the_box_filter() {
    for s in setups() {
        let scene = scene(&s);
        let (reference, edge) = reference(&s);
        let edges = (0..edge.len()).filter(|&i| edge[i] && reference[i] > 0.0).count();
        let lit = reference.iter().filter(|&&r| r > 0.0).count();
        assert!(edges > 100 && lit > edges + edges / 2, "{}: {edges} edge pixels, {lit} lit", s.name);
        let view = view(&scene, s.camera, W, H, Sampling::Adaptive, 0);
        let (first, _) = view.render_direct(&scene, &s.light, Some(AaParams::new(AA_THRESHOLD)));
        assert_finite(&first, s.name);
        let buffer = LightBuffer::from_dense(W, H, &first);
        let mut samples = EdgeSamples::select(&scene, &view, &s.light, &buffer, 0xED6E);
        // The picker finds the reference's edges: every edge pixel with
        // light in it or beside it, bar a few whose jump is below 1 %.
        let picked: std::collections::HashSet<u32> = samples.pixels().iter().copied().collect();
        let missed: Vec<usize> =
            (0..edge.len()).filter(|&i| edge[i] && reference[i] > 0.0 && !picked.contains(&(i as u32))).collect();
        let missed_error = green_rel_mse(&first, &reference, |i| missed.contains(&i));
        let error =
            |img: &[Vec3]| (green_rel_mse(img, &reference, |_| true), green_rel_mse(img, &reference, |i| edge[i]));
        let at_first = error(&first);
        let mut rows = vec![("Whitted stage".to_string(), at_first)];
        for pass in 1..=4 {
            assert!(samples.pass_until(&scene, &view, &s.light, &|| false));
            if pass % 2 == 0 {
                let mut refined = first.clone();
                samples.replace_in(&mut refined, &buffer);
                assert_finite(&refined, s.name);
                rows.push((format!("{} samples", samples.samples()), error(&refined)));
            }
        }
        eprintln!(
            "{}: {edges} lit reference edge pixels, {} picked, {} lit edge pixels missed (their error {missed_error:.2e}); \
             rel. MSE whole / edges: {}",
            s.name,
            samples.len(),
            missed.len(),
            rows.iter().map(|(l, (a, b))| format!("{l} {a:.2e} / {b:.2e}")).collect::<Vec<_>>().join(", ")
        );
        // Measured: whole 2.7e-5 / 5.1e-5 / 6.4e-5 at 32 samples (what the
        // photon stage publishes), 1.5e-5 / 2.5e-5 / 2.3e-5 at 64; the edge
        // pixels 18-370× better than the Whitted stage's.
        let (whole, edges_error) = rows[2].1;
        assert!(rows[1].1.0 <= 1e-4, "{}: whole picture {:.2e} after 32 samples, over 1e-4", s.name, rows[1].1.0);
        assert!(whole <= 1e-4, "{}: whole picture {whole:.2e} after 64 samples, over issue 34's 1e-4", s.name);
        assert!(
            edges_error * 8.0 <= at_first.1,
            "{}: edge pixels {edges_error:.2e} after 64 samples against {:.2e} at the Whitted stage",
            s.name,
            at_first.1
        );
        assert!(whole <= rows[1].1.0, "{}: 64 samples no better than 32: {rows:?}", s.name);
    }
}
