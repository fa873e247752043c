//! Adaptive anti-aliasing (Vierjahn 2010, section 3.4) against 9× oversampling.

use crate::common::*;
use footlight::bench::mse_display;
use footlight::render::display::Display;
use footlight::render::view::{AaParams, Sampling};
use glam::Vec3;

#[test]
fn adaptive_aa_beats_one_sample_against_nine_times_oversampling() {
    let scene = stage();
    let patch = default_patch();
    let cam = scene.camera.unwrap();
    let display = Display::default();
    let (w, h) = (200, 125);
    let mut total = [[0f64; 3]; 3];
    for f in &patch.fixtures[..2] {
        let k_full = f.k_full();
        let aa = AaParams::new(20.0);
        let mut imgs = Vec::new();
        for sampling in [Sampling::One, Sampling::Adaptive, Sampling::Nine] {
            let v = view(&scene, cam, w, h, sampling, 5);
            let (buf, reshaded) = v.render_light(&scene, &f.light, Some(aa));
            if sampling == Sampling::Adaptive {
                assert!(reshaded > 0 && reshaded < (w * h) as usize, "adaptive re-shaded {reshaded} pixels");
            }
            imgs.push(buf.to_dense().iter().map(|v| *v * k_full).collect::<Vec<Vec3>>());
        }
        for (i, img) in imgs.iter().enumerate() {
            let m = mse_display(img, &imgs[2], &display);
            for c in 0..3 {
                total[i][c] += m[c];
            }
        }
    }
    let (one, adaptive) = (total[0], total[1]);
    for c in 0..3 {
        assert!(adaptive[c] < 0.5 * one[c], "channel {c}: adaptive MSE {} vs one-sample {}", adaptive[c], one[c]);
    }
    assert!(one.iter().sum::<f64>() > 0.0);
}

#[test]
fn reshaded_pixels_do_not_depend_on_exposure_or_dimmer() {
    // Issue 13.5: the decision is the light's own relative gradient, so the
    // set of re-shaded pixels is the same for the buffer at any scale
    // (exposure ×0.01 and ×100, any dimmer or k_i).
    let scene = stage();
    let patch = default_patch();
    let cam = scene.camera.unwrap();
    let v = view(&scene, cam, 160, 100, Sampling::Adaptive, 5);
    let aa = AaParams::new(20.0);
    for f in &patch.fixtures[..2] {
        let (dense, _) = v.render_direct(&scene, &f.light, None);
        let at = |s: f32| v.gradient_flags(&scene, &dense.iter().map(|x| *x * s).collect::<Vec<_>>(), aa);
        let base = at(1.0);
        let n = base.iter().filter(|&&b| b).count();
        assert!(n > 0 && n < base.len() / 4, "{}: {n} pixels flagged", f.name);
        assert_eq!(at(0.01), base, "{}: exposure ×0.01 changed the re-shaded set", f.name);
        assert_eq!(at(100.0), base, "{}: exposure ×100 changed the re-shaded set", f.name);
        // The renderer's own count agrees.
        assert_eq!(v.render_direct(&scene, &f.light, Some(aa)).1, n);
    }
}
