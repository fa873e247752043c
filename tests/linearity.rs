//! Eq. 5 against eq. 1: the composite of unit-intensity per-light buffers
//! weighted by k_i equals a single-pass render of all lights together
//! (independent recursion in `render::reference`), on the bundled stage with
//! its mirrors and glass, for random RGB k_i.

use crate::common::*;
use footlight::render::RecursionLimits;
use footlight::render::buffer::LightBuffer;
use footlight::render::composite;
use footlight::render::reference::render_eq1;
use footlight::render::view::Sampling;
use glam::Vec3;

#[test]
fn composite_equals_single_pass_eq1_render() {
    let scene = stage();
    let patch = paper_patch();
    let cam = scene.camera.expect("stage has a camera");
    let lights = patch.lights();
    let mut rng = Rng(0x5EED_0005);
    for sampling in [Sampling::Geometry, Sampling::Nine] {
        let v = view(&scene, cam, 160, 100, sampling, 5);
        let buffers: Vec<LightBuffer> = lights.iter().map(|l| v.render_light(&scene, l, None).0).collect();
        let refs: Vec<&LightBuffer> = buffers.iter().collect();
        for _trial in 0..3 {
            let k: Vec<Vec3> =
                lights.iter().map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 1e5).collect();
            let comp = composite(&refs, &k, 160, 100);
            let eq1 = render_eq1(
                &scene,
                &v.gbuffer,
                &lights,
                &k,
                sampling.base_set(),
                RecursionLimits { max_depth: 5, min_weight: 0.0 },
            );
            assert_finite(&comp, "composite");
            let peak = eq1.iter().map(|p| p.max_element()).fold(0.0f32, f32::max);
            assert!(peak > 0.0, "the rig lights the stage");
            let mut lit = 0;
            for (i, (a, b)) in comp.iter().zip(&eq1).enumerate() {
                let scale = b.max_element().max(peak * 1e-6);
                let rel = (*a - *b).abs().max_element() / scale;
                assert!(rel <= 1e-5, "{sampling:?} pixel {i}: composite {a} vs eq.1 {b} (rel {rel:e})");
                lit += usize::from(b.max_element() > 0.0);
            }
            assert!(lit > 1000, "only {lit} lit pixels");
        }
    }
}

#[test]
fn composite_scales_exactly_with_k() {
    let scene = stage();
    let patch = paper_patch();
    let v = view(&scene, scene.camera.unwrap(), 80, 50, Sampling::Geometry, 5);
    let (buf, _) = v.render_light(&scene, &patch.fixtures[0].light, None);
    let one = composite(&[&buf], &[Vec3::ONE], 80, 50);
    let k = Vec3::new(3.0, 0.5, 2.0);
    let scaled = composite(&[&buf], &[k], 80, 50);
    for (a, b) in one.iter().zip(&scaled) {
        assert_eq!(*a * k, *b);
    }
}
