//! Degenerate input never yields NaN/Inf or a panic: every buffer is checked.

use crate::common::*;
use footlight::render::composite;
use footlight::render::view::Sampling;
use footlight::scene::{Camera, SceneBuilder};
use glam::Vec3;

fn render_all(scene: &footlight::Scene, cam: Camera, lights: &[footlight::Light]) -> Vec<Vec3> {
    let v = view(scene, cam, 40, 25, Sampling::Nine, 5);
    let bufs: Vec<_> = lights.iter().map(|l| v.render_light(scene, l, None).0).collect();
    for b in &bufs {
        b.check().expect("finite buffer");
    }
    let refs: Vec<_> = bufs.iter().collect();
    let img = composite(&refs, &vec![Vec3::splat(1e4); lights.len()], 40, 25);
    assert_finite(&img, "composite");
    img
}

#[test]
fn nan_vertices_and_zero_area_triangles_are_dropped() {
    let mut b = SceneBuilder::new();
    let m = lambert(&mut b, 0.5);
    floor(&mut b, 5.0, 0.0, m);
    b.add_triangle([Vec3::ZERO, Vec3::X, Vec3::new(0.0, f32::NAN, 1.0)], None, m);
    b.add_triangle([Vec3::ZERO, Vec3::X, Vec3::new(f32::INFINITY, 0.0, 1.0)], None, m);
    b.add_triangle([Vec3::ZERO, Vec3::X, Vec3::X * 3.0], None, m); // collinear
    b.add_triangle([Vec3::Y, Vec3::Y, Vec3::Y], None, m); // a point
    b.add_triangle([Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 1e-12, 0.0)], None, m); // sliver
    let scene = b.build();
    assert_eq!(scene.report.non_finite, 2);
    assert_eq!(scene.report.degenerate, 3);
    let img = render_all(
        &scene,
        Camera::look_at(Vec3::new(0.0, 3.0, 3.0), Vec3::ZERO, 0.8),
        &[omni(Vec3::new(0.0, 2.0, 0.0))],
    );
    assert!(img.iter().any(|p| p.max_element() > 0.0));
}

#[test]
fn empty_scene_renders_black() {
    let scene = SceneBuilder::new().build();
    let img = render_all(&scene, Camera::look_at(Vec3::Z, Vec3::ZERO, 0.8), &[omni(Vec3::ZERO)]);
    assert!(img.iter().all(|p| *p == Vec3::ZERO));
}

#[test]
fn light_inside_a_closed_box_lights_only_the_inside() {
    let mut b = SceneBuilder::new();
    let m = lambert(&mut b, 0.9);
    floor(&mut b, 10.0, 0.0, m);
    cube(&mut b, Vec3::new(-0.5, 0.5, -0.5), Vec3::new(0.5, 1.5, 0.5), m);
    let scene = b.build();
    let img = render_all(
        &scene,
        Camera::look_at(Vec3::new(0.0, 3.0, 4.0), Vec3::ONE * 0.5, 0.8),
        &[omni(Vec3::new(0.0, 1.0, 0.0))],
    );
    assert!(img.iter().all(|p| *p == Vec3::ZERO), "light leaks out of the box");
}

#[test]
fn camera_inside_geometry_and_lights_on_surfaces_stay_finite() {
    let mut b = SceneBuilder::new();
    let m = lambert(&mut b, 0.9);
    let mirror = b.add_material(footlight::scene::Material::from_pbr("chrome", Vec3::splat(0.9), 1.0, 0.0, 0.0, 1.5));
    cube(&mut b, Vec3::splat(-1.0), Vec3::splat(1.0), m);
    cube(&mut b, Vec3::splat(-0.2), Vec3::splat(0.2), mirror);
    let scene = b.build();
    // Camera inside the big box, one light on a wall, one exactly at a corner,
    // one inside the small mirror box, one at the camera.
    let lights =
        [omni(Vec3::new(0.0, 1.0, 0.0)), omni(Vec3::splat(1.0)), omni(Vec3::ZERO), omni(Vec3::new(0.5, 0.0, 0.9))];
    let img = render_all(&scene, Camera::look_at(Vec3::new(0.5, 0.0, 0.9), Vec3::ZERO, 1.2), &lights);
    assert!(img.iter().any(|p| p.max_element() > 0.0));
}

#[test]
fn huge_and_tiny_scene_scales_stay_finite() {
    for scale in [1e-3f32, 1e3] {
        let mut b = SceneBuilder::new();
        let m = lambert(&mut b, 0.5);
        floor(&mut b, 5.0 * scale, 0.0, m);
        cube(&mut b, Vec3::new(-scale, 0.0, -scale), Vec3::splat(scale), m);
        let scene = b.build();
        let img = render_all(
            &scene,
            Camera::look_at(Vec3::new(0.0, 3.0, 4.0) * scale, Vec3::ZERO, 0.8),
            &[omni(Vec3::new(1.5, 2.5, 1.0) * scale)],
        );
        assert!(img.iter().any(|p| p.max_element() > 0.0), "scale {scale}");
    }
}
