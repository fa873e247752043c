//! Light lifecycle: a dark light adds nothing, re-uploading replaces,
//! removal, pool growth keeps earlier lights, and bad input is an error
//! naming the light (and pixel), never a panic or a silently wrong frame.

use crate::support::{self, TestLight, cpu_composite, cpu_srgb8, device_or_skip, max_code_diff};
use footlight_gpu::{CompositorOptions, DisplayParams, GpuCompositor, GpuError, MAX_LIGHTS, TILE_PIXELS};

const W: u32 = 50;
const H: u32 = 37;

fn compositor(ctx: &footlight_gpu::GpuContext) -> GpuCompositor {
    GpuCompositor::new(ctx.device(), ctx.queue(), W, H, CompositorOptions::default()).unwrap()
}

#[test]
fn a_dark_light_adds_exactly_nothing() {
    let ctx = device_or_skip!();
    let mut rng = support::rng(5);
    let a = support::random_light(&mut rng, W, H, 0.7, 1.0);
    let b = support::random_light(&mut rng, W, H, 0.7, 1.0);
    let display = DisplayParams { exposure: 0.5, white_balance: [1.0; 3], rolloff: None };
    let mut only_a = compositor(ctx);
    only_a.set_light(0, a.view()).unwrap();
    let mut both = compositor(ctx);
    both.set_light(0, a.view()).unwrap();
    both.set_light(1, b.view()).unwrap();
    let ka = [0.7, 1.3, 0.2];
    assert_eq!(
        both.composite(&[ka, [0.0; 3]], &display).unwrap().rgba8,
        only_a.composite(&[ka], &display).unwrap().rgba8
    );
    assert_eq!(both.composite_linear(&[ka, [0.0; 3]]).unwrap(), only_a.composite_linear(&[ka]).unwrap());
    // All dark: black, exactly.
    let black = both.composite(&[[0.0; 3]; 2], &display).unwrap();
    assert!(black.rgba8.chunks_exact(4).all(|p| p == [0, 0, 0, 255]));
    assert!(both.composite_linear(&[[0.0; 3]; 2]).unwrap().iter().all(|v| *v == [0.0; 3]));
}

#[test]
fn uploading_again_replaces_and_removing_clears() {
    let ctx = device_or_skip!();
    let mut rng = support::rng(6);
    let display = DisplayParams::for_white_lux(2.0);
    let first = support::random_light(&mut rng, W, H, 0.3, 1.0);
    let second = support::random_light(&mut rng, W, H, 0.9, 1.0);
    let other = support::random_light(&mut rng, W, H, 0.5, 1.0);
    let k = [[1.0, 0.5, 0.25], [0.3, 0.3, 0.3]];
    let mut gpu = compositor(ctx);
    gpu.set_light(0, first.view()).unwrap();
    gpu.set_light(1, other.view()).unwrap();
    gpu.composite(&k, &display).unwrap();
    gpu.set_light(0, second.view()).unwrap();
    let expect = |lights: &[TestLight]| cpu_srgb8(&cpu_composite(lights, &k, W, H), &display);
    let frame = gpu.composite(&k, &display).unwrap();
    assert!(max_code_diff(&frame.rgba8, &expect(&[second.clone(), other.clone()])) <= 1);
    assert_eq!(gpu.pool_stats().used_tiles, (second.occupied() + other.occupied()) as u64);

    assert!(gpu.remove_light(0));
    assert!(!gpu.remove_light(0), "already gone");
    assert!(!gpu.remove_light(99), "never set");
    assert_eq!(gpu.light_count(), 2, "indices stay valid");
    let frame = gpu.composite(&k, &display).unwrap();
    assert!(max_code_diff(&frame.rgba8, &expect(&[TestLight::empty(W, H), other.clone()])) <= 1);
    assert_eq!(gpu.pool_stats().used_tiles, other.occupied() as u64);

    // Freed space is reused: the pool does not grow for a same-size light.
    let capacity = gpu.pool_stats().capacity_tiles;
    gpu.set_light(0, second.view()).unwrap();
    assert_eq!(gpu.pool_stats().capacity_tiles, capacity);
    assert!(max_code_diff(&gpu.composite(&k, &display).unwrap().rgba8, &expect(&[second, other])) <= 1);
}

#[test]
fn the_pool_grows_and_keeps_earlier_lights() {
    let ctx = device_or_skip!();
    let (w, h) = (160u32, 96u32); // 60 tiles
    let mut rng = support::rng(8);
    let mut gpu = GpuCompositor::new(ctx.device(), ctx.queue(), w, h, CompositorOptions::default()).unwrap();
    let initial = gpu.pool_stats().capacity_tiles;
    let lights: Vec<TestLight> = (0..20).map(|_| support::random_light(&mut rng, w, h, 0.8, 1.0)).collect();
    for (i, l) in lights.iter().enumerate() {
        gpu.set_light(i, l.view()).unwrap();
    }
    let stats = gpu.pool_stats();
    assert!(stats.capacity_tiles > initial, "{stats:?}");
    assert_eq!(stats.pages, 1, "grown in place, not split: {stats:?}");
    let k = support::random_k(&mut rng, lights.len(), 0.2, 0.1);
    let display = DisplayParams { exposure: 1.0, white_balance: [1.0; 3], rolloff: None };
    let frame = gpu.composite(&k, &display).unwrap();
    assert!(max_code_diff(&frame.rgba8, &cpu_srgb8(&cpu_composite(&lights, &k, w, h), &display)) <= 1);
}

#[test]
fn lights_may_be_set_out_of_order_and_need_a_weight_each() {
    let ctx = device_or_skip!();
    let mut rng = support::rng(9);
    let l = support::random_light(&mut rng, W, H, 0.5, 1.0);
    let mut gpu = compositor(ctx);
    gpu.set_light(5, l.view()).unwrap();
    assert_eq!(gpu.light_count(), 6);
    let display = DisplayParams::default();
    assert!(matches!(gpu.composite(&[[1.0; 3]; 5], &display), Err(GpuError::WeightCount { lights: 6, got: 5 })));
    // Extra weights belong to lights without buffers: fine.
    let k = [[0.0; 3], [1.0; 3], [1.0; 3], [1.0; 3], [1.0; 3], [500.0; 3], [7.0; 3]];
    let mut lights = vec![TestLight::empty(W, H); 5];
    lights.push(l);
    let frame = gpu.composite(&k, &display).unwrap();
    assert!(max_code_diff(&frame.rgba8, &cpu_srgb8(&cpu_composite(&lights, &k, W, H), &display)) <= 1);
}

#[test]
fn bad_input_is_an_error_that_changes_nothing() {
    let ctx = device_or_skip!();
    let mut rng = support::rng(10);
    let good = support::random_light(&mut rng, W, H, 0.5, 1.0);
    let display = DisplayParams::default();
    let k = [[900.0, 800.0, 700.0]];
    let mut gpu = compositor(ctx);
    gpu.set_light(0, good.view()).unwrap();
    let before = gpu.composite(&k, &display).unwrap().rgba8;

    let mut bad = good.clone();
    bad.slots.pop();
    assert!(matches!(
        gpu.set_light(0, bad.view()),
        Err(GpuError::SlotTableLength { light: 0, got: 11, expected: 12, .. })
    ));

    let mut bad = good.clone();
    bad.tiles.pop();
    assert!(matches!(gpu.set_light(0, bad.view()), Err(GpuError::TileDataLength { light: 0, .. })));

    let mut bad = good.clone();
    let t = bad.slots.iter().position(|s| *s != u32::MAX).unwrap();
    bad.slots[t] = bad.occupied() as u32;
    assert!(matches!(gpu.set_light(0, bad.view()), Err(GpuError::BadSlot { light: 0, .. })));

    let mut bad = good.clone();
    let used: Vec<usize> = (0..bad.slots.len()).filter(|&t| bad.slots[t] != u32::MAX).collect();
    bad.slots[used[1]] = bad.slots[used[0]];
    assert!(matches!(gpu.set_light(0, bad.view()), Err(GpuError::BadSlot { light: 0, .. })), "a tile used twice");

    // A NaN at pixel (x, y) is reported there.
    let mut bad = good.clone();
    let tiles_x = W.div_ceil(16) as usize;
    let (x, y) = ((t % tiles_x) as u32 * 16 + 3, (t / tiles_x) as u32 * 16 + 5);
    bad.tiles[bad.slots[t] as usize * TILE_PIXELS + 5 * 16 + 3] = [0.0, f32::NAN, 0.0];
    match gpu.set_light(0, bad.view()) {
        Err(GpuError::BadValue { light: 0, x: bx, y: by, value }) => {
            assert_eq!((bx, by), (x, y));
            assert!(value[1].is_nan());
        }
        other => panic!("expected BadValue, got {other:?}"),
    }
    let mut bad = good.clone();
    bad.tiles[bad.slots[t] as usize * TILE_PIXELS] = [-1.0, 0.0, 0.0];
    assert!(matches!(gpu.set_light(0, bad.view()), Err(GpuError::BadValue { light: 0, .. })));
    assert!(matches!(gpu.set_light(MAX_LIGHTS, good.view()), Err(GpuError::LightIndex { .. })));

    assert!(matches!(gpu.composite(&[[f32::NAN, 0.0, 0.0]], &display), Err(GpuError::BadWeight { light: 0, .. })));
    assert!(matches!(gpu.composite(&[[-1.0, 0.0, 0.0]], &display), Err(GpuError::BadWeight { light: 0, .. })));
    let nan_display = DisplayParams { exposure: f32::NAN, white_balance: [1.0; 3], rolloff: None };
    assert!(matches!(gpu.composite(&k, &nan_display), Err(GpuError::BadDisplay(_))));
    let negative_wb = DisplayParams { exposure: 1.0, white_balance: [1.0, -1.0, 1.0], rolloff: None };
    assert!(matches!(gpu.composite(&k, &negative_wb), Err(GpuError::BadDisplay(_))));
    // A roll-off whose knee is not below white (or not finite) is refused too.
    for rolloff in [[1.0, 16.0], [0.6, 1.0], [f32::NAN, 16.0], [0.6, f32::INFINITY], [-0.1, 4.0]] {
        let bad = DisplayParams { rolloff: Some(rolloff), ..display };
        assert!(matches!(gpu.composite(&k, &bad), Err(GpuError::BadDisplay(_))), "{rolloff:?}");
    }

    // None of it touched light 0.
    assert_eq!(gpu.composite(&k, &display).unwrap().rgba8, before);
    assert!(matches!(
        GpuCompositor::new(ctx.device(), ctx.queue(), 0, 10, CompositorOptions::default()),
        Err(GpuError::BadSize { width: 0, .. })
    ));
}
