//! Pipelined readback: frames submitted ahead come back newest first, older
//! finished ones are dropped, and a full ring waits instead of growing.

use crate::support::{self, TestLight, cpu_composite, cpu_srgb8, device_or_skip, max_code_diff};
use footlight_gpu::{CompositorOptions, DisplayParams, FrameId, GpuCompositor};
use std::time::{Duration, Instant};

#[test]
fn frames_submitted_ahead_come_back_newest_first() {
    let ctx = device_or_skip!();
    let (w, h) = (70u32, 45u32);
    let mut rng = support::rng(21);
    let lights: Vec<TestLight> = (0..4).map(|_| support::random_light(&mut rng, w, h, 0.7, 1.0)).collect();
    // Two staging buffers for five frames: submit has to recycle and wait.
    let options = CompositorOptions { readback_slots: 2, ..Default::default() };
    let mut gpu = GpuCompositor::new(ctx.device(), ctx.queue(), w, h, options).unwrap();
    for (i, l) in lights.iter().enumerate() {
        gpu.set_light(i, l.view()).unwrap();
    }
    let display = DisplayParams { exposure: 1.0, white_balance: [1.0; 3], rolloff: None };
    let k_at = |step: usize| vec![[0.1 * step as f32, 0.2, 0.3]; 4];
    for step in 0..5 {
        assert_eq!(gpu.submit(&k_at(step), &display).unwrap(), FrameId(step as u64));
    }
    let frame = gpu.wait_frame().unwrap().expect("a frame in flight");
    assert_eq!(frame.id, FrameId(4), "the newest frame, older ones dropped");
    let expect = cpu_srgb8(&cpu_composite(&lights, &k_at(4), w, h), &display);
    assert!(max_code_diff(&frame.rgba8, &expect) <= 1);
    assert_eq!(frame.rgb8().len(), (w * h * 3) as usize);
    assert!(gpu.try_frame().unwrap().is_none(), "nothing left");
    assert!(gpu.wait_frame().unwrap().is_none(), "nothing in flight");
}

#[test]
fn try_frame_does_not_block_and_delivers() {
    let ctx = device_or_skip!();
    let (w, h) = (33u32, 20u32);
    let mut rng = support::rng(22);
    let light = support::random_light(&mut rng, w, h, 1.0, 1.0);
    let mut gpu = GpuCompositor::new(ctx.device(), ctx.queue(), w, h, CompositorOptions::default()).unwrap();
    gpu.set_light(0, light.view()).unwrap();
    let display = DisplayParams { exposure: 1.0, white_balance: [1.0; 3], rolloff: None };
    let id = gpu.submit(&[[0.5; 3]], &display).unwrap();
    let start = Instant::now();
    let frame = loop {
        if let Some(f) = gpu.try_frame().unwrap() {
            break f;
        }
        assert!(start.elapsed() < Duration::from_secs(30), "frame never arrived");
        std::thread::sleep(Duration::from_millis(1));
    };
    assert_eq!(frame.id, id);
    let expect = cpu_srgb8(&cpu_composite(&[light], &[[0.5; 3]], w, h), &display);
    assert!(max_code_diff(&frame.rgba8, &expect) <= 1);
}
