//! Whitted recursion against closed forms: a mirror shows the lit floor
//! scaled by k_R, a glass pane shows it scaled by k_T, and two facing
//! mirrors stop at the depth limit with the truncated geometric series.

use crate::common::*;
use footlight::fixture::{Beam, Light, SpotBeam};
use footlight::render::gbuffer::CENTRE_SAMPLE;
use footlight::render::view::Sampling;
use footlight::scene::{Camera, Material, SceneBuilder};
use glam::Vec3;
use std::f32::consts::PI;

const RHO: f32 = 0.7;

/// Floor luminance from a 1 cd omni light (closed form).
fn floor_luminance(light: Vec3, q: Vec3) -> f32 {
    let d = light - q;
    RHO / PI * (d.y / d.length()) / d.length_squared()
}

/// Camera path through a flat specular quad at z = z0, continued in a
/// straight line (glass, ior 1) or mirrored (mirror), to the floor y = 0.
fn check_through(kind: &str, material: Material, k: f32) {
    let mut b = SceneBuilder::new();
    let m_floor = lambert(&mut b, RHO);
    floor(&mut b, 30.0, 0.0, m_floor);
    let m = b.add_material(material);
    let z0 = if kind == "mirror" { -2.0 } else { 1.5 };
    // Vertical quad facing +Z, 4 m wide, 0.05..3 m high.
    b.add_quad(
        Vec3::new(-2.0, 0.05, z0),
        Vec3::new(2.0, 0.05, z0),
        Vec3::new(2.0, 3.0, z0),
        Vec3::new(-2.0, 3.0, z0),
        m,
    );
    let scene = b.build();
    let light_pos = Vec3::new(0.0, 3.0, 0.0);
    let light = omni(light_pos);
    let cam_pos = Vec3::new(0.0, 1.2, 4.0);
    let cam = Camera::look_at(cam_pos, Vec3::new(0.0, 0.8, 0.0), 50f32.to_radians());
    let (w, h) = (60, 40);
    let v = view(&scene, cam, w, h, Sampling::One, 5);
    let (buf, _) = v.render_light(&scene, &light, None);
    let mut checked = 0;
    for y in 0..h {
        for x in 0..w {
            let s = v.gbuffer.samples[(y * w + x) as usize][CENTRE_SAMPLE];
            if s.triangle == footlight::render::gbuffer::NO_HIT || scene.material_of[s.triangle as usize] != m {
                continue;
            }
            let p = scene.point_on(s.triangle, s.u, s.v);
            let mut d = (p - cam_pos).normalize();
            if kind == "mirror" {
                d.z = -d.z;
            }
            if d.y >= -1e-3 {
                continue;
            }
            let q = p + d * (-p.y / d.y);
            // Skip floor points the quad itself shadows or that lie behind it.
            if (kind == "mirror" && q.z < z0) || (kind == "glass" && q.z > z0) || q.x.abs().max(q.z.abs()) > 29.0 {
                continue;
            }
            let expected = k * floor_luminance(light_pos, q);
            let got = buf.get(x, y).x;
            assert!(
                (got - expected).abs() <= 0.01 * expected + 1e-7,
                "{kind} ({x},{y}) floor {q}: {got} vs {expected}"
            );
            checked += 1;
        }
    }
    assert!(checked > 100, "{kind}: only {checked} pixels checked");
}

#[test]
fn mirror_shows_the_lit_floor_scaled_by_k_r() {
    let mirror = Material { k_r: Vec3::splat(0.8), ..Material::lambert("mirror", Vec3::ZERO) };
    check_through("mirror", mirror, 0.8);
}

#[test]
fn glass_pane_transmits_the_lit_floor_scaled_by_k_t() {
    // ior 1: the ray goes straight through; no diffuse or Phong term.
    let glass = Material { k_t: Vec3::splat(0.6), ior: 1.0, ..Material::lambert("glass", Vec3::ZERO) };
    check_through("glass", glass, 0.6);
}

#[test]
fn recursion_stops_at_the_depth_limit() {
    // Two facing planes (ρ = 0.5 Lambert + k_R = 0.5 mirror) at z = ±1, a
    // 1 cd omni light at the origin, a 1×1 image looking down -Z from the
    // origin: L = D · Σ_{j=0..N} k_R^j with D = ρ/π.
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material { k_r: Vec3::splat(0.5), ..Material::lambert("semi-mirror", Vec3::splat(0.5)) });
    b.add_quad(
        Vec3::new(-5.0, -5.0, -1.0),
        Vec3::new(5.0, -5.0, -1.0),
        Vec3::new(5.0, 5.0, -1.0),
        Vec3::new(-5.0, 5.0, -1.0),
        m,
    );
    b.add_quad(
        Vec3::new(-5.0, -5.0, 1.0),
        Vec3::new(-5.0, 5.0, 1.0),
        Vec3::new(5.0, 5.0, 1.0),
        Vec3::new(5.0, -5.0, 1.0),
        m,
    );
    let scene = b.build();
    let light = omni(Vec3::ZERO);
    let cam = Camera::look_at(Vec3::ZERO, Vec3::NEG_Z, 1f32.to_radians());
    let d = 0.5 / PI;
    for depth in 0..=6 {
        let v = view(&scene, cam, 1, 1, Sampling::One, depth);
        let got = v.render_light(&scene, &light, None).0.get(0, 0).x;
        let expected: f32 = (0..=depth).map(|j| d * 0.5f32.powi(j as i32)).sum();
        assert!((got - expected).abs() <= 1e-4 * expected, "depth {depth}: {got} vs {expected}");
    }
}

#[test]
fn glass_sphere_refracts_and_stays_finite_at_grazing_angles() {
    // A glass sphere (ior 1.5) over a lit floor: total internal reflection
    // and grazing refraction must keep every pixel finite.
    let mut b = SceneBuilder::new();
    let m_floor = lambert(&mut b, 0.5);
    floor(&mut b, 10.0, 0.0, m_floor);
    let glass = b.add_material(Material::from_pbr("glass", Vec3::ONE, 0.0, 0.0, 0.9, 1.5));
    let (rings, segs) = (24, 48);
    let c = Vec3::new(0.0, 1.0, 0.0);
    let pt = |i: usize, j: usize| {
        let th = PI * i as f32 / rings as f32;
        let ph = 2.0 * PI * j as f32 / segs as f32;
        c + Vec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin())
    };
    for i in 0..rings {
        for j in 0..segs {
            let (a, b2, c2, d) = (pt(i, j), pt(i + 1, j), pt(i + 1, j + 1), pt(i, j + 1));
            b.add_triangle([a, d, c2], Some([(a - c).normalize(), (d - c).normalize(), (c2 - c).normalize()]), glass);
            b.add_triangle([a, c2, b2], Some([(a - c).normalize(), (c2 - c).normalize(), (b2 - c).normalize()]), glass);
        }
    }
    let scene = b.build();
    let light = Light::aimed(Vec3::new(0.0, 4.0, 0.5), Vec3::ZERO, Beam::Spot(SpotBeam::from_beam_field(60.0, 80.0)));
    let cam = Camera::look_at(Vec3::new(0.0, 1.5, 4.0), c, 40f32.to_radians());
    let v = view(&scene, cam, 80, 60, Sampling::Nine, 5);
    let (buf, _) = v.render_light(&scene, &light, None);
    buf.check().expect("finite");
    // Looking through the sphere's centre we see the (lit) floor behind it.
    assert!(buf.get(40, 38).max_element() > 0.0);
}
