//! f16 tile storage: the error it adds, measured against the f32 reference.
//!
//! A half float keeps 11 significant bits, so each stored value is within a
//! relative 2⁻¹¹ (4.9e-4) of the f32 one and the weighted sum of
//! non-negative terms is too. At 8 bits that is at most one code value
//! (sRGB's steepest slope, 12.92 × 255 per unit at black, times 4.9e-4 of a
//! value below 0.0031 is 0.005 codes; near white it is 0.05).

use crate::support::{self, TestLight, cpu_composite, cpu_srgb8, device_or_skip, max_code_diff};
use footlight_gpu::{CompositorOptions, DisplayParams, GpuCompositor, TileFormat};

fn half_options() -> CompositorOptions {
    CompositorOptions { tile_format: TileFormat::F16, ..Default::default() }
}

#[test]
fn half_tiles_stay_within_one_code_value_and_2e_minus_11() {
    let ctx = device_or_skip!();
    let mut worst_rel = 0.0f32;
    for (seed, (w, h, n)) in [(41, 33, 3usize), (97, 64, 20), (130, 75, 40)].into_iter().enumerate() {
        let mut rng = support::rng(100 + seed as u64);
        let lights: Vec<TestLight> = (0..n).map(|_| support::random_light(&mut rng, w, h, 0.6, 1.0)).collect();
        let k = support::random_k(&mut rng, n, 3.0 / (n as f32).sqrt(), 0.2);
        let display = DisplayParams { exposure: 0.9, white_balance: [1.0, 0.95, 1.1], rolloff: None };
        let mut gpu = GpuCompositor::new(ctx.device(), ctx.queue(), w, h, half_options()).unwrap();
        for (i, l) in lights.iter().enumerate() {
            gpu.set_light(i, l.view()).unwrap();
        }
        let reference = cpu_composite(&lights, &k, w, h);
        let linear = gpu.composite_linear(&k).unwrap();
        for (g, c) in linear.iter().zip(&reference) {
            for ch in 0..3 {
                // Relative 2⁻¹¹ for normal halves, plus an absolute floor for
                // values below f16's normal range (6.1e-5, spacing 6e-8).
                let err = (g[ch] - c[ch]).abs();
                assert!(err <= c[ch] / 2048.0 + 1e-6, "{w}x{h}: GPU {} CPU {}", g[ch], c[ch]);
                if c[ch] == 0.0 {
                    assert_eq!(g[ch], 0.0, "zero stays exactly zero");
                } else if c[ch] > 1e-2 {
                    worst_rel = worst_rel.max(err / c[ch]);
                }
            }
        }
        let frame = gpu.composite(&k, &display).unwrap();
        let codes = max_code_diff(&frame.rgba8, &cpu_srgb8(&reference, &display));
        assert!(codes <= 1, "{w}x{h} {n} lights: {codes} code values");
    }
    eprintln!("f16 tiles: worst relative error of the linear sum {worst_rel:.2e} (bound 2^-11 = 4.9e-4)");
    assert!(worst_rel <= 4.9e-4 + 1e-5, "{worst_rel}");
}

#[test]
fn half_tiles_saturate_at_65504_instead_of_becoming_infinite() {
    let ctx = device_or_skip!();
    let (w, h) = (16u32, 16u32);
    let mut light = TestLight::empty(w, h);
    light.slots[0] = 0;
    light.tiles = vec![[1.0e6, 65504.0, 1.0e-9]; 256];
    let mut gpu = GpuCompositor::new(ctx.device(), ctx.queue(), w, h, half_options()).unwrap();
    gpu.set_light(0, light.view()).unwrap();
    let linear = gpu.composite_linear(&[[1.0, 1.0, 1.0]]).unwrap();
    // 1e-9 is below f16's smallest subnormal (6e-8) and flushes to 0.
    assert!(linear.iter().all(|v| *v == [65504.0, 65504.0, 0.0]), "{:?}", linear[0]);
    // A channel with k = 0 stays 0 (0 × 65504, not 0 × ∞ = NaN).
    let linear = gpu.composite_linear(&[[0.0, 2.0, 1.0]]).unwrap();
    assert!(linear.iter().all(|v| *v == [0.0, 131008.0, 0.0]), "{:?}", linear[0]);
}
