//! The rim of a hard-edged beam on a Lambert floor (issue 34, item 1):
//! the direct term of `Sampling::Nine` and of the default adaptive
//! anti-aliasing at several thresholds against an independent box-filtered
//! reference, computed here from first principles (32×32 jittered samples
//! per pixel, E = I(θ)·cos/d² · ρ/π with the cone's cut-off; no renderer
//! shading code).

use crate::common::*;
use footlight::fixture::{Beam, Light, SpotBeam};
use footlight::render::view::{AaParams, Sampling};
use footlight::scene::{Camera, Scene, SceneBuilder};
use glam::Vec3;

/// Floor reflectance.
const RHO: f32 = 0.6;
/// Half-size of the square floor (m).
const FLOOR_HALF: f32 = 8.0;
/// Picture size.
const W: u32 = 160;
const H: u32 = 100;
/// Reference samples per pixel side (32×32 jittered).
const REF_SIDE: usize = 32;

/// One set-up: a hard spot (half-angle `half_deg`) at `position` aimed at
/// `target`, seen by a camera at `eye` looking at `look`.
struct Setup {
    name: &'static str,
    position: Vec3,
    target: Vec3,
    half_deg: f32,
    eye: Vec3,
    look: Vec3,
}

const SETUPS: [Setup; 3] = [
    Setup {
        name: "overhead 12°",
        position: Vec3::new(-0.5, 4.0, 0.5),
        target: Vec3::new(0.2, 0.0, 0.0),
        half_deg: 12.0,
        eye: Vec3::new(0.0, 4.0, 5.0),
        look: Vec3::new(0.0, 0.0, 0.0),
    },
    Setup {
        name: "raking 8°",
        position: Vec3::new(-4.0, 2.5, 1.0),
        target: Vec3::new(0.5, 0.0, -0.3),
        half_deg: 8.0,
        eye: Vec3::new(0.5, 5.0, 4.0),
        look: Vec3::new(0.3, 0.0, -0.5),
    },
    Setup {
        name: "front 20°",
        position: Vec3::new(0.3, 3.0, 4.0),
        target: Vec3::new(-0.2, 0.0, -0.4),
        half_deg: 20.0,
        eye: Vec3::new(-1.0, 2.5, 6.0),
        look: Vec3::new(0.0, 0.0, 0.0),
    },
];

fn scene() -> Scene {
    let mut b = SceneBuilder::new();
    let m = lambert(&mut b, RHO);
    floor(&mut b, FLOOR_HALF, 0.0, m);
    b.build()
}

fn light(s: &Setup) -> Light {
    let half = s.half_deg.to_radians();
    Light::aimed(s.position, s.target, Beam::Spot(SpotBeam::from_half_angles(half, half)))
}

/// The box-filtered direct term of every pixel and the share of each
/// pixel's reference samples inside the cone, from first principles: the
/// camera ray (the renderer's pinhole model) meets the plane y = 0; inside
/// the cone (angle to the axis below the half-angle) E = 1 cd · cos/d²
/// and the pixel shows ρ/π · E. f64 throughout; jittered 32×32 strata,
/// seeded.
fn reference(s: &Setup, camera: &Camera) -> (Vec<f64>, Vec<f64>) {
    let pos = s.position.as_dvec3();
    let axis = (s.target.as_dvec3() - pos).normalize();
    let cos_cut = f64::from(s.half_deg).to_radians().cos();
    let eye = camera.position.as_dvec3();
    let (right, up, back) =
        (camera.basis.x_axis.as_dvec3(), camera.basis.y_axis.as_dvec3(), camera.basis.z_axis.as_dvec3());
    let tan_half = (f64::from(camera.yfov) * 0.5).tan();
    let aspect = f64::from(W) / f64::from(H);
    let mut rng = Rng(0x5EED_0034);
    let (mut value, mut cover) = (vec![0.0; (W * H) as usize], vec![0.0; (W * H) as usize]);
    for y in 0..H as usize {
        for x in 0..W as usize {
            let (mut sum, mut inside) = (0.0, 0usize);
            for j in 0..REF_SIDE {
                for i in 0..REF_SIDE {
                    let px = x as f64 + (i as f64 + f64::from(rng.next_f32())) / REF_SIDE as f64;
                    let py = y as f64 + (j as f64 + f64::from(rng.next_f32())) / REF_SIDE as f64;
                    let nx = (2.0 * px / f64::from(W) - 1.0) * tan_half * aspect;
                    let ny = (1.0 - 2.0 * py / f64::from(H)) * tan_half;
                    let dir = (right * nx + up * ny - back).normalize();
                    if dir.y >= 0.0 {
                        continue;
                    }
                    let p = eye + dir * (-eye.y / dir.y);
                    if p.x.abs() > f64::from(FLOOR_HALF) || p.z.abs() > f64::from(FLOOR_HALF) {
                        continue;
                    }
                    let to = pos - p;
                    let d2 = to.length_squared();
                    let wi = to / d2.sqrt();
                    if (-wi).dot(axis) < cos_cut || wi.y <= 0.0 {
                        continue;
                    }
                    inside += 1;
                    sum += f64::from(RHO) / std::f64::consts::PI * wi.y / d2;
                }
            }
            let n = (REF_SIDE * REF_SIDE) as f64;
            value[y * W as usize + x] = sum / n;
            cover[y * W as usize + x] = inside as f64 / n;
        }
    }
    (value, cover)
}

/// Per set-up: (name, [nine, adaptive 20, 60, 120] × (whole, rim)).
fn measure() -> Vec<(&'static str, [(f64, f64); 4])> {
    let scene = scene();
    SETUPS
        .iter()
        .map(|s| {
            let camera = Camera::look_at(s.eye, s.look, 50f32.to_radians());
            let light = light(s);
            let (reference, cover) = reference(s, &camera);
            let rim = |i: usize| cover[i] > 0.0 && cover[i] < 1.0;
            let rim_pixels = (0..cover.len()).filter(|&i| rim(i)).count();
            let lit = cover.iter().filter(|&&c| c > 0.0).count();
            assert!(rim_pixels > 50 && lit > 10 * rim_pixels / 4, "{}: rim {rim_pixels}, lit {lit}", s.name);
            let nine = view(&scene, camera, W, H, Sampling::Nine, 0).render_direct(&scene, &light, None).0;
            assert_finite(&nine, s.name);
            let adaptive = view(&scene, camera, W, H, Sampling::Adaptive, 0);
            let mut rows = [(green_rel_mse(&nine, &reference, |_| true), green_rel_mse(&nine, &reference, rim)); 4];
            let base = adaptive.render_direct(&scene, &light, None).0;
            for (k, t) in [20.0, 60.0, 120.0].into_iter().enumerate() {
                let (img, reshaded) = adaptive.render_direct(&scene, &light, Some(AaParams::new(t)));
                assert_finite(&img, s.name);
                rows[k + 1] = (green_rel_mse(&img, &reference, |_| true), green_rel_mse(&img, &reference, rim));
                // Why the gradient pairs alone fall short: the rim pixels
                // no pair marks (the edge crosses them at a corner, or its
                // jump to each 4-neighbour is under the threshold).
                let flags = adaptive.gradient_flags(&scene, &base, AaParams::new(t));
                let missed = (0..cover.len()).filter(|&i| rim(i) && !flags[i]).count();
                let missed_error = green_rel_mse(&base, &reference, |i| rim(i) && !flags[i]);
                eprintln!(
                    "{}: threshold {t}: {reshaded} pixels re-shaded, {rim_pixels} rim pixels, {missed} of them in no \
                     gradient pair (their 1-sample rel. MSE {missed_error:.3e} of their own energy)",
                    s.name
                );
            }
            eprintln!(
                "{}: rel. MSE whole / rim: nine {:.3e} / {:.3e}; adaptive 20 {:.3e} / {:.3e}, 60 {:.3e} / {:.3e}, \
                 120 {:.3e} / {:.3e}",
                s.name, rows[0].0, rows[0].1, rows[1].0, rows[1].1, rows[2].0, rows[2].1, rows[3].0, rows[3].1
            );
            (s.name, rows)
        })
        .collect()
}

#[test]
fn adaptive_is_never_worse_than_nine_on_a_hard_beam_rim() {
    for (name, rows) in measure() {
        let nine = rows[0];
        for (k, t) in [20, 60, 120].into_iter().enumerate() {
            let (whole, rim) = rows[k + 1];
            assert!(whole <= nine.0, "{name}: threshold {t}: whole picture {whole:.3e} against nine's {:.3e}", nine.0);
            assert!(rim <= nine.1, "{name}: threshold {t}: rim {rim:.3e} against nine's {:.3e}", nine.1);
            // Beyond nine samples: the first build's direct term within
            // issue 34's targets of the box-filtered reference (3e-4 for
            // the first build, 1e-4 after refinement: met at once, the
            // rim pixels shaded by cell coverage), the rim itself 20×
            // better than nine samples.
            assert!(whole <= 1e-4, "{name}: threshold {t}: whole picture {whole:.3e} over 1e-4");
            assert!(rim * 20.0 <= nine.1, "{name}: threshold {t}: rim {rim:.3e} against nine's {:.3e}", nine.1);
        }
    }
}

#[test]
fn hard_rims_built_together_equal_rims_built_alone() {
    // Cells built together (`render::build::together`) find a hard beam's
    // rim in their lit window as a light alone finds it on the whole frame:
    // same pixels re-shaded, same buffers (1e-6 of the peak). A block on
    // the floor puts rim pixels on two surfaces (all 9 samples) and a
    // shadow edge across the rim.
    use footlight::render::build::BuildSettings;
    let mut b = SceneBuilder::new();
    let m = lambert(&mut b, RHO);
    floor(&mut b, FLOOR_HALF, 0.0, m);
    cube(&mut b, Vec3::new(-0.3, 0.0, -0.3), Vec3::new(0.3, 0.5, 0.3), m);
    let scene = b.build();
    let s = &SETUPS[0];
    let camera = Camera::look_at(s.eye, s.look, 50f32.to_radians());
    let hard = |position: Vec3, target: Vec3, half_deg: f32| {
        let half = f32::to_radians(half_deg);
        Light::aimed(position, target, Beam::Spot(SpotBeam::from_half_angles(half, half)))
    };
    let lights =
        vec![light(s), hard(Vec3::new(2.0, 3.0, 1.0), Vec3::new(0.1, 0.0, 0.2), 10.0), omni(Vec3::new(-1.2, 2.5, 1.5))];
    let v = view(&scene, camera, W, H, Sampling::Adaptive, 2);
    let settings = BuildSettings { photons: None, ..BuildSettings::default() };
    let aa = AaParams::new(settings.aa_threshold);
    let (mut cover, mut nine) = (0, 0);
    for l in &lights[..2] {
        let (base, _) = v.render_direct(&scene, l, None);
        let decision = v.aa_decision(&scene, l, &base, aa);
        cover += decision.rim.cover.len();
        nine += decision.rim.nine.len();
    }
    eprintln!("rim pixels: {cover} by cell coverage, {nine} with 9 samples");
    assert!(cover > 100 && nine > 0, "rim pixels: {cover} by coverage, {nine} with 9 samples");
    crate::common::assert_together_equals_alone(&scene, &v, &lights, settings);
}
