//! Fixture bodies from the GDTF model (issue 14 item 5): the drawn
//! silhouettes of `tests/data/mvr/bodies.mvr` (a glb head on a moving head,
//! a 3ds can, a primitives-only par; tools/gen_gdtf_mvr.py) against the
//! projection of the dimensions written in the generator, posed here by
//! hand from the GDTF rules (pan about the Axis' Z, tilt about X, GDTF Z up
//! → stage Y up).

use footlight::render::bodies::{Body, BodyLayer, body_models};
use footlight::scene::{Camera, SceneBuilder};
use glam::{Mat3, Vec3};
use std::path::Path;

const W: u32 = 400;
const H: u32 = 250;

/// GDTF fixture frame → stage for an unrotated MVR fixture: (X, Y, Z) → (X, Z, −Y).
fn gdtf_to_stage(p: Vec3) -> Vec3 {
    Vec3::new(p.x, p.z, -p.y)
}

/// Pinhole projection of a stage point to continuous pixel coordinates.
fn project(cam: &Camera, p: Vec3) -> (f32, f32) {
    let rel = cam.basis.transpose() * (p - cam.position);
    let t = (cam.yfov * 0.5).tan();
    let aspect = W as f32 / H as f32;
    let x = (rel.x / (-rel.z * t * aspect) + 1.0) * 0.5 * W as f32;
    let y = (1.0 - rel.y / (-rel.z * t)) * 0.5 * H as f32;
    (x, y)
}

/// Outline samples of a box `lo..hi` (its corners) in GDTF coordinates.
fn box_points(lo: Vec3, hi: Vec3) -> Vec<Vec3> {
    (0..8).map(|i| Vec3::new([lo.x, hi.x][i & 1], [lo.y, hi.y][(i >> 1) & 1], [lo.z, hi.z][(i >> 2) & 1])).collect()
}

/// Outline samples of a cylinder along Z (rims, 720 points each).
fn cylinder_points(r: f32, z0: f32, z1: f32) -> Vec<Vec3> {
    (0..720)
        .flat_map(|k| {
            let a = k as f32 / 720.0 * std::f32::consts::TAU;
            [Vec3::new(r * a.cos(), r * a.sin(), z0), Vec3::new(r * a.cos(), r * a.sin(), z1)]
        })
        .collect()
}

/// The pixel-centre extent (x0, y0, x1, y1 inclusive) the points' hull should cover.
fn expected_extent(cam: &Camera, stage_points: &[Vec3]) -> (f32, f32, f32, f32) {
    let mut e = (f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY);
    for &p in stage_points {
        let (x, y) = project(cam, p);
        e = (e.0.min(x), e.1.min(y), e.2.max(x), e.3.max(y));
    }
    // Pixel centres at i + 0.5 inside [min, max].
    ((e.0 - 0.5).ceil(), (e.1 - 0.5).ceil(), (e.2 - 0.5).floor(), (e.3 - 0.5).floor())
}

fn drawn_extent(layer: &BodyLayer, body: u32) -> (f32, f32, f32, f32) {
    let mut e = (f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY);
    for (i, h) in layer.hits.iter().enumerate() {
        if h.is_some_and(|h| h.body == body) {
            let (x, y) = ((i as u32 % W) as f32, (i as u32 / W) as f32);
            e = (e.0.min(x), e.1.min(y), e.2.max(x), e.3.max(y));
        }
    }
    e
}

fn close(a: (f32, f32, f32, f32), b: (f32, f32, f32, f32)) -> bool {
    [(a.0, b.0), (a.1, b.1), (a.2, b.2), (a.3, b.3)].iter().all(|(x, y)| (x - y).abs() <= 1.0)
}

#[test]
fn glb_3ds_and_primitive_bodies_span_their_model_dimensions_at_any_pan_tilt() {
    let path = Path::new("tests/data/mvr/bodies.mvr");
    let import = footlight_mvr::load_mvr(path).expect("bodies.mvr loads");
    let fixtures = &import.patch.fixtures;
    let names: Vec<String> = fixtures.iter().map(|f| f.name.clone()).collect();
    let ids: Vec<u32> = fixtures.iter().map(|f| f.id).collect();
    let (models, warnings) = body_models(path, &names, &ids);
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(models.len(), 3);
    assert!(models.iter().all(|m| !m.is_estimated()), "every body from its GDTF model");
    let scene = SceneBuilder::new().build(); // nothing hides a body
    let cam = Camera::look_at(Vec3::new(0.0, 3.0, 9.0), Vec3::new(0.0, 4.0, 0.0), 35f32.to_radians());
    let (pan, tilt) = (90.0f32, 60.0f32);
    let bodies: Vec<Body> = models
        .iter()
        .map(|m| {
            let f = &fixtures[m.driver];
            let mut state = f.look;
            state.pan = pan;
            state.tilt = tilt;
            m.pose(&f.light_of(&state), pan, tilt)
        })
        .collect();
    let layer = BodyLayer::build(&scene, &cam, W, H, &bodies);

    // Head glb at stage (-2, 4, 0): Foot cube 0.4 x 0.4 x 0.2; the Lantern
    // (0, 0, -0.3) under pan (Z) and tilt (X); its glb box scaled to
    // X [0, 0.3], Y [-0.2, 0], Z [0, 0.5]; the lens disc r 0.08 at z -0.1.
    let at = Vec3::new(-2.0, 4.0, 0.0);
    let (rz, rx) = (Mat3::from_rotation_z(pan.to_radians()), Mat3::from_rotation_x(tilt.to_radians()));
    let head = |p: Vec3| at + gdtf_to_stage(rz * (rx * p + Vec3::new(0.0, 0.0, -0.3)));
    let mut pts: Vec<Vec3> = box_points(Vec3::new(-0.2, -0.2, -0.1), Vec3::new(0.2, 0.2, 0.1))
        .into_iter()
        .map(|p| at + gdtf_to_stage(p))
        .collect();
    pts.extend(box_points(Vec3::new(0.0, -0.2, 0.0), Vec3::new(0.3, 0.0, 0.5)).into_iter().map(head));
    pts.extend(cylinder_points(0.08, -0.101, -0.099).into_iter().map(head));
    let (want, got) = (expected_extent(&cam, &pts), drawn_extent(&layer, 0));
    assert!(close(want, got), "glb head: drawn {got:?}, projected {want:?}");
    // The lens faces where the light points: the posed disc's normal is the light's axis.
    let light = fixtures[models[0].driver].light_of(&{
        let mut s = fixtures[models[0].driver].look;
        s.pan = pan;
        s.tilt = tilt;
        s
    });
    let lens_axis = gdtf_to_stage(rz * rx * Vec3::NEG_Z);
    assert!((lens_axis - light.axis()).length() < 1e-4, "{lens_axis} vs {}", light.axis());

    // Can 3ds at (0, 4, 0): X, Y ±0.125, Z [0, 0.4]; lens r 0.1 at the origin.
    let at = Vec3::new(0.0, 4.0, 0.0);
    let mut pts: Vec<Vec3> = box_points(Vec3::new(-0.125, -0.125, 0.0), Vec3::new(0.125, 0.125, 0.4));
    pts.extend(cylinder_points(0.1, -0.001, 0.001));
    let pts: Vec<Vec3> = pts.into_iter().map(|p| at + gdtf_to_stage(p)).collect();
    let (want, got) = (expected_extent(&cam, &pts), drawn_extent(&layer, 1));
    assert!(close(want, got), "3ds can: drawn {got:?}, projected {want:?}");

    // Par (primitives) at (2, 4, 0): cylinder r 0.15, Z ±0.2; lens cylinder r 0.12 at z -0.2, 0.01 high.
    let at = Vec3::new(2.0, 4.0, 0.0);
    let mut pts = cylinder_points(0.15, -0.2, 0.2);
    pts.extend(cylinder_points(0.12, -0.205, -0.195));
    let pts: Vec<Vec3> = pts.into_iter().map(|p| at + gdtf_to_stage(p)).collect();
    let (want, got) = (expected_extent(&cam, &pts), drawn_extent(&layer, 2));
    assert!(close(want, got), "primitive par: drawn {got:?}, projected {want:?}");

    // Pan/tilt move the glb head: at rest the drawn extent differs.
    let rest: Vec<Body> = models.iter().map(|m| m.pose(&fixtures[m.driver].light, 0.0, 0.0)).collect();
    let rest_layer = BodyLayer::build(&scene, &cam, W, H, &rest);
    assert_ne!(drawn_extent(&rest_layer, 0), got_extent_of(&layer, 0));
    assert_eq!(drawn_extent(&rest_layer, 1), drawn_extent(&layer, 1), "a fixed can does not move");
}

fn got_extent_of(layer: &BodyLayer, body: u32) -> (f32, f32, f32, f32) {
    drawn_extent(layer, body)
}
