//! GPU frames against the CPU reference (support.rs): ≤ 1 code value per
//! channel, exactly 0 where nothing lights a pixel, and the linear sum to
//! f32 rounding.

use crate::support::{self, TestLight, cpu_composite, cpu_srgb8, cpu_srgb8_table, device_or_skip, max_code_diff};
use footlight_gpu::{CompositorOptions, DisplayParams, GpuCompositor, GpuContext, TILE};

/// Uploads `lights`, composites with `k`, and checks the frame and the
/// linear image against the reference. Returns the compositor for more checks.
pub fn check(
    ctx: &GpuContext,
    width: u32,
    height: u32,
    lights: &[TestLight],
    k: &[[f32; 3]],
    display: &DisplayParams,
    options: CompositorOptions,
) -> GpuCompositor {
    let mut gpu = GpuCompositor::new(ctx.device(), ctx.queue(), width, height, options).unwrap();
    for (i, l) in lights.iter().enumerate() {
        gpu.set_light(i, l.view()).unwrap();
    }
    let frame = gpu.composite(k, display).unwrap();
    assert_eq!((frame.width, frame.height, frame.rgba8.len()), (width, height, (width * height * 4) as usize));
    let reference = cpu_composite(lights, k, width, height);
    let exact = cpu_srgb8(&reference, display);
    let what = format!("{width}x{height}, {} lights", lights.len());
    assert!(max_code_diff(&frame.rgba8, &exact) <= 1, "{what}: GPU vs exact sRGB");
    assert!(max_code_diff(&frame.rgba8, &cpu_srgb8_table(&reference, display)) <= 1, "{what}: GPU vs table");
    for (i, v) in reference.iter().enumerate() {
        if *v == [0.0; 3] {
            assert_eq!(&frame.rgba8[i * 4..i * 4 + 3], &[0, 0, 0], "{what}: unlit pixel {i} must be exactly black");
        }
    }
    let linear = gpu.composite_linear(k).unwrap();
    assert_eq!(linear.len(), reference.len());
    for (i, (g, c)) in linear.iter().zip(&reference).enumerate() {
        for ch in 0..3 {
            // Only the order of additions (pages) and fused multiply-adds differ.
            let tol = 1e-5 * c[ch].abs().max(1e-3);
            assert!((g[ch] - c[ch]).abs() <= tol, "{what}: pixel {i} channel {ch}: GPU {} CPU {}", g[ch], c[ch]);
        }
        if *c == [0.0; 3] {
            assert_eq!(*g, [0.0; 3], "{what}: pixel {i} exactly 0");
        }
    }
    gpu
}

#[test]
fn matches_cpu_for_light_counts_and_odd_sizes() {
    let ctx = device_or_skip!();
    let display = DisplayParams { exposure: 0.8, white_balance: [1.1, 1.0, 0.85], rolloff: None };
    let mut seed = 1;
    for (w, h) in [(1, 1), (17, 9), (35, 19), (64, 32), (129, 70)] {
        for n in [0usize, 1, 2, 7, 33] {
            seed += 1;
            let mut rng = support::rng(seed);
            let lights: Vec<TestLight> = (0..n).map(|_| support::random_light(&mut rng, w, h, 0.6, 1.0)).collect();
            // Sums span black to well past white, so clipping is tested too.
            let k = support::random_k(&mut rng, n, 3.0 / (n.max(1) as f32).sqrt(), 0.25);
            check(ctx, w, h, &lights, &k, &display, CompositorOptions::default());
        }
    }
}

#[test]
fn edge_tiles_cover_the_last_row_and_column() {
    let ctx = device_or_skip!();
    let (w, h) = (33u32, 17u32); // 3×2 tiles, the last column and row 1 pixel wide
    let mut light = TestLight::empty(w, h);
    let tiles_x = w.div_ceil(TILE);
    // Only the bottom-right tile, pixel value = its position (distinct everywhere).
    light.slots[(tiles_x + 2) as usize] = 0;
    light.tiles = (0..256u32).map(|p| [(p % 16) as f32 * 0.01 + 0.001, (p / 16) as f32 * 0.01, 0.5]).collect();
    let display = DisplayParams { exposure: 1.0, white_balance: [1.0; 3], rolloff: None };
    let gpu = check(ctx, w, h, &[light], &[[1.0, 2.0, 0.5]], &display, CompositorOptions::default());
    assert_eq!(gpu.pool_stats().used_tiles, 1);
}

#[test]
fn several_pool_pages_match_the_reference() {
    let ctx = device_or_skip!();
    let (w, h) = (75u32, 50u32); // 5×4 tiles
    let mut rng = support::rng(77);
    let lights: Vec<TestLight> = (0..12).map(|_| support::random_light(&mut rng, w, h, 0.5, 1.0)).collect();
    let k = support::random_k(&mut rng, lights.len(), 0.8, 0.2);
    let display = DisplayParams::for_white_lux(std::f32::consts::PI);
    // Pages of 7 tiles: every light spans pages, every page is its own pass.
    let options = CompositorOptions { max_page_bytes: Some(7 * 3072), ..Default::default() };
    let mut gpu = check(ctx, w, h, &lights, &k, &display, options);
    let stats = gpu.pool_stats();
    assert_eq!(stats.max_page_tiles, 7);
    assert!(stats.pages >= 10, "{stats:?}");
    assert_eq!(stats.used_tiles, lights.iter().map(|l| l.occupied() as u64).sum::<u64>());

    // Dark lights cost nothing: only the pages holding lit lights are dispatched.
    let mut one_on = vec![[0.0; 3]; lights.len()];
    one_on[3] = [1.0, 0.5, 0.25];
    gpu.composite(&one_on, &display).unwrap();
    let f = gpu.last_frame_stats();
    assert_eq!((f.active_lights, f.tiles_read), (1, lights[3].occupied() as u64));
    assert!(f.passes <= lights[3].occupied().div_ceil(7) + 1 && f.passes < stats.pages, "{f:?} {stats:?}");
    gpu.composite(&vec![[0.0; 3]; lights.len()], &display).unwrap();
    assert_eq!(gpu.last_frame_stats(), footlight_gpu::FrameStats { active_lights: 0, tiles_read: 0, passes: 1 });
}
