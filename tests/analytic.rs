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

/// Writes a glTF 2.0 file (JSON + external .bin) with one 40 m square at
/// y = 0 facing +Y, using material `material` (a glTF material object), and
/// returns its path. Built here byte by byte, independent of the importer.
pub fn gltf_plane(name: &str, material: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("footlight-gltf-plane-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let h = 20.0f32;
    let positions = [[-h, 0.0, h], [h, 0.0, h], [h, 0.0, -h], [-h, 0.0, -h]];
    let mut bin = Vec::new();
    for p in positions {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    for _ in 0..4 {
        for c in [0.0f32, 1.0, 0.0] {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    std::fs::write(dir.join("plane.bin"), &bin).unwrap();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1}},"indices":2,"material":0}}]}}],
"materials":[{material}],
"buffers":[{{"uri":"plane.bin","byteLength":{len}}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":48}},{{"buffer":0,"byteOffset":96,"byteLength":12}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-20,0,-20],"max":[20,0,20]}},
{{"bufferView":1,"componentType":5126,"count":4,"type":"VEC3"}},
{{"bufferView":2,"componentType":5123,"count":6,"type":"SCALAR"}}]}}"#,
        len = bin.len()
    );
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, json).unwrap();
    path
}

#[test]
fn matte_gltf_plane_is_lambert_through_the_importer() {
    // Issue 13.1: a white (and a grey) matte glTF material, read by the
    // importer, must give L = ρ/π · E for every light/view direction, E the
    // irradiance of a 1 cd point light: cos θ / d².
    for (rho, roughness) in [(1.0f32, 1.0f32), (0.5, 0.5), (0.8, 0.75)] {
        let material = format!(
            r#"{{"name":"matte","pbrMetallicRoughness":{{"baseColorFactor":[{rho},{rho},{rho},1],"metallicFactor":0,"roughnessFactor":{roughness}}}}}"#
        );
        let scene = footlight::scene::load(&gltf_plane(&format!("matte-{roughness}"), &material)).unwrap();
        let light_pos = Vec3::new(0.3, 2.0, -0.2);
        let light = omni(light_pos);
        // A grazing camera too: a Phong lobe would show most there.
        for cam in [
            Camera::look_at(Vec3::new(0.0, 6.0, 0.01), Vec3::ZERO, 60f32.to_radians()),
            Camera::look_at(Vec3::new(-9.0, 0.4, 3.0), Vec3::new(2.0, 0.0, -1.0), 50f32.to_radians()),
        ] {
            let (w, h) = (40, 30);
            let v = view(&scene, cam, w, h, Sampling::One, 0);
            let (buf, _) = v.render_light(&scene, &light, None);
            let mut checked = 0;
            for y in 0..h {
                for x in 0..w {
                    let s = v.gbuffer.samples[(y * w + x) as usize][footlight::render::gbuffer::CENTRE_SAMPLE];
                    let Some(p) = v.gbuffer.position(&scene, &s) else { continue };
                    let d = light_pos - p;
                    let irradiance = d.y / d.length() / d.length_squared();
                    let got = buf.get(x, y);
                    let per_irradiance = got / irradiance;
                    let want = rho / std::f32::consts::PI;
                    assert!(
                        (per_irradiance - Vec3::splat(want)).abs().max_element() <= 1e-4 * want,
                        "ρ {rho} roughness {roughness} ({x},{y}): L/E = {per_irradiance}, want {want}"
                    );
                    checked += 1;
                }
            }
            assert!(checked > 300, "{checked}");
        }
    }
}
