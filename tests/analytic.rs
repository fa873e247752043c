//! Closed forms: a point light over a Lambert plane gives
//! L = ρ/π · I · cos θ / d² (Lambert's cosine law and the inverse square law).

use crate::common::*;
use footlight::fixture::{Beam, Light, SpotBeam};
use footlight::render::composite;
use footlight::render::display::Display;
use footlight::render::view::Sampling;
use footlight::scene::{Camera, SceneBuilder};
use glam::Vec3;

#[test]
fn point_light_over_lambert_plane_matches_closed_form() {
    let rho = 0.6;
    let mut b = SceneBuilder::new();
    let m = lambert(&mut b, rho);
    floor(&mut b, 20.0, 0.0, m);
    let scene = b.build();
    let light_pos = Vec3::new(0.3, 2.0, -0.2);
    let light = omni(light_pos);
    let cam = Camera::look_at(Vec3::new(0.0, 6.0, 0.01), Vec3::ZERO, 60f32.to_radians());
    let (w, h) = (64, 48);
    let v = view(&scene, cam, w, h, Sampling::One, 0);
    let (buf, _) = v.render_light(&scene, &light, None);
    let mut checked = 0;
    for y in (0..h).step_by(5) {
        for x in (0..w).step_by(5) {
            let s = v.gbuffer.samples[(y * w + x) as usize][footlight::render::gbuffer::CENTRE_SAMPLE];
            let p = v.gbuffer.position(&scene, &s).expect("plane fills the view");
            let d = light_pos - p;
            let cos = d.y / d.length();
            let expected = rho / std::f32::consts::PI * cos / d.length_squared();
            let got = buf.get(x, y);
            assert!((got.x - expected).abs() <= 0.01 * expected, "({x},{y}) at {p}: got {got}, expected {expected}");
            assert_eq!(got.x, got.y);
            checked += 1;
        }
    }
    assert!(checked > 80);
}

#[test]
fn spot_pattern_shapes_the_pool_of_light() {
    // A 20°/30° spot straight down from 3 m: values follow the smoothstep
    // pattern computed here from its definition.
    let mut b = SceneBuilder::new();
    let m = lambert(&mut b, 1.0);
    floor(&mut b, 20.0, 0.0, m);
    let scene = b.build();
    let light = Light::aimed(Vec3::new(0.0, 3.0, 0.0), Vec3::ZERO, Beam::Spot(SpotBeam::from_beam_field(20.0, 30.0)));
    let cam = Camera::look_at(Vec3::new(0.0, 5.0, 0.01), Vec3::ZERO, 50f32.to_radians());
    let (w, h) = (80, 80);
    let v = view(&scene, cam, w, h, Sampling::One, 0);
    let (buf, _) = v.render_light(&scene, &light, None);
    // Independent pattern: 1 - smoothstep over [inner, outer] with beam 10°
    // at 50 % and field 15° at 10 % -> p = 5° / 0.3041995, inner = 10° - p/2.
    let p = 5f32.to_radians() / 0.304_199_5;
    let inner = 10f32.to_radians() - p / 2.0;
    for y in 0..h {
        for x in 0..w {
            let s = v.gbuffer.samples[(y * w + x) as usize][footlight::render::gbuffer::CENTRE_SAMPLE];
            let pt = v.gbuffer.position(&scene, &s).unwrap();
            let d = Vec3::new(0.0, 3.0, 0.0) - pt;
            let theta = (d.y / d.length()).acos();
            let t = ((theta - inner) / p).clamp(0.0, 1.0);
            let pattern = 1.0 - t * t * (3.0 - 2.0 * t);
            let cos = d.y / d.length();
            let expected = pattern / std::f32::consts::PI * cos / d.length_squared();
            let got = buf.get(x, y).x;
            assert!(
                (got - expected).abs() <= 0.01 * expected + 1e-6,
                "({x},{y}) θ={}°: {got} vs {expected}",
                theta.to_degrees()
            );
        }
    }
}

#[test]
fn thousand_candela_at_five_metres_is_forty_lux_end_to_end() {
    // White Lambert plane, 1000 cd straight down from 5 m: E = 40 lx,
    // L = 40/π cd/m²; with display white at 1000 lx the pixel is 4 % linear.
    let mut b = SceneBuilder::new();
    let m = lambert(&mut b, 1.0);
    floor(&mut b, 50.0, 0.0, m);
    let scene = b.build();
    let light = omni(Vec3::new(0.0, 5.0, 0.0));
    let cam = Camera::look_at(Vec3::new(0.0, 4.0, 0.001), Vec3::ZERO, 1f32.to_radians());
    let v = view(&scene, cam, 1, 1, Sampling::One, 0);
    let (buf, _) = v.render_light(&scene, &light, None);
    let img = composite(&[&buf], &[Vec3::splat(1000.0)], 1, 1);
    let lux = img[0].x * std::f32::consts::PI;
    assert!((lux - 40.0).abs() < 0.01, "{lux} lx");
    let display = Display::default();
    assert!((img[0].x * display.exposure - 0.04).abs() < 1e-5);
}

#[test]
fn light_behind_a_surface_does_not_light_its_front() {
    let mut b = SceneBuilder::new();
    let m = lambert(&mut b, 0.8);
    floor(&mut b, 5.0, 0.0, m);
    let scene = b.build();
    let light = omni(Vec3::new(0.0, -1.0, 0.0));
    let cam = Camera::look_at(Vec3::new(0.0, 4.0, 0.01), Vec3::ZERO, 40f32.to_radians());
    let v = view(&scene, cam, 32, 32, Sampling::Geometry, 5);
    let (buf, _) = v.render_light(&scene, &light, None);
    assert_eq!(buf.occupied_tiles(), 0, "light below the floor leaks through it");
}
