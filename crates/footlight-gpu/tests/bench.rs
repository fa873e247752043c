//! Composite timings on whatever adapter is here (lavapipe in CI). Ignored:
//! speed is reported, never asserted (README). Run with
//! `cargo test -p footlight-gpu --release -- --ignored --nocapture bench`.

use crate::support::{self, TestLight, device_or_skip};
use footlight_gpu::{CompositorOptions, DisplayParams, GpuCompositor, TileFormat};
use std::time::{Duration, Instant};

struct Scenario {
    name: &'static str,
    width: u32,
    height: u32,
    lights: usize,
    /// Beam radius in tiles.
    radius: f32,
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

#[test]
#[ignore]
fn bench_composite() {
    let ctx = device_or_skip!();
    let info = ctx.adapter_info();
    println!("adapter: {} ({:?}, {:?}), driver {}", info.name, info.backend, info.device_type, info.driver_info);
    let scenarios = [
        Scenario { name: "32 lights 800x500", width: 800, height: 500, lights: 32, radius: 8.0 },
        Scenario { name: "600 sparse lights 1920x1080", width: 1920, height: 1080, lights: 600, radius: 11.0 },
    ];
    let display = DisplayParams::default();
    for s in &scenarios {
        let mut rng = support::rng(2010);
        let lights: Vec<TestLight> =
            (0..s.lights).map(|_| support::beam_light(&mut rng, s.width, s.height, s.radius)).collect();
        let tiles: usize = lights.iter().map(TestLight::occupied).sum();
        let screen = (s.width.div_ceil(16) * s.height.div_ceil(16)) as usize;
        println!(
            "\n{}: {} occupied tiles, {:.1} % of the frame per light on average",
            s.name,
            tiles,
            100.0 * tiles as f64 / (s.lights * screen) as f64
        );
        // Same-run baseline: composite.rs's loop (tile by tile, active lights
        // only) plus the sRGB table, on one thread (footlight's CPU compositor
        // splits tile rows over rayon's threads).
        let all_on = vec![[40.0, 38.0, 30.0]; s.lights];
        let mut out = vec![[0.0f32; 3]; (s.width * s.height) as usize];
        let cpu = median(
            (0..3)
                .map(|_| {
                    timed(|| {
                        cpu_tiles(&lights, &all_on, s.width, s.height, &mut out);
                        drop(support::cpu_srgb8_table(&out, &display));
                    })
                })
                .collect(),
        );
        println!("  CPU, 1 thread (composite.rs loop + sRGB table): {:.1} ms", ms(cpu));
        for format in [TileFormat::F32, TileFormat::F16] {
            let options = CompositorOptions { tile_format: format, ..Default::default() };
            let mut gpu = GpuCompositor::new(ctx.device(), ctx.queue(), s.width, s.height, options).unwrap();
            let t = Instant::now();
            for (i, l) in lights.iter().enumerate() {
                gpu.set_light(i, l.view()).unwrap();
            }
            let upload = t.elapsed();
            let t = Instant::now();
            gpu.composite(&all_on, &display).unwrap(); // builds the index
            let first = t.elapsed();
            let runs = 7;
            let blocking =
                median((0..runs).map(|_| timed(|| drop(gpu.composite(&all_on, &display).unwrap()))).collect());
            let half_on: Vec<[f32; 3]> =
                all_on.iter().enumerate().map(|(i, k)| if i % 2 == 0 { *k } else { [0.0; 3] }).collect();
            let half_dark =
                median((0..runs).map(|_| timed(|| drop(gpu.composite(&half_on, &display).unwrap()))).collect());
            let all_dark = vec![[0.0; 3]; s.lights];
            let dark = median((0..runs).map(|_| timed(|| drop(gpu.composite(&all_dark, &display).unwrap()))).collect());
            // Pipelined: submit ahead, take what is ready (as the live loop does).
            let frames = 10;
            let t = Instant::now();
            let mut got = 0;
            for _ in 0..frames {
                gpu.submit(&all_on, &display).unwrap();
                got += usize::from(gpu.try_frame().unwrap().is_some());
            }
            got += usize::from(gpu.wait_frame().unwrap().is_some());
            let pipelined = t.elapsed() / frames;
            // One light rebuilt: its upload, the index rebuild and a frame.
            let rebuilt = median(
                (0..runs)
                    .map(|_| {
                        timed(|| {
                            gpu.set_light(0, lights[0].view()).unwrap();
                            drop(gpu.composite(&all_on, &display).unwrap());
                        })
                    })
                    .collect(),
            );
            let stats = gpu.pool_stats();
            println!(
                "  {format:?}: upload {:.0} ms total, first frame {:.1} ms; composite+readback median {:.1} ms \
                 (half the lights dark {:.1} ms, all dark {:.1} ms); pipelined {:.1} ms/frame ({got} of {frames} \
                 frames taken); one light rebuilt + frame {:.1} ms; pool {} page(s), {:.0} MiB, max page {} tiles",
                ms(upload),
                ms(first),
                ms(blocking),
                ms(half_dark),
                ms(dark),
                ms(pipelined),
                ms(rebuilt),
                stats.pages,
                stats.bytes as f64 / (1 << 20) as f64,
                stats.max_page_tiles,
            );
        }
    }
}

fn timed(f: impl FnOnce()) -> Duration {
    let t = Instant::now();
    f();
    t.elapsed()
}

/// footlight's `composite_into` without rayon: per tile, add every active
/// light's tile row by row.
fn cpu_tiles(lights: &[TestLight], k: &[[f32; 3]], width: u32, height: u32, out: &mut [[f32; 3]]) {
    let (w, h) = (width as usize, height as usize);
    let tiles_x = w.div_ceil(16);
    out.fill([0.0; 3]);
    let active: Vec<(&TestLight, [f32; 3])> =
        lights.iter().zip(k).filter(|(l, k)| **k != [0.0; 3] && l.occupied() > 0).map(|(l, k)| (l, *k)).collect();
    for ty in 0..h.div_ceil(16) {
        for tx in 0..tiles_x {
            let (x0, y0) = (tx * 16, ty * 16);
            let (cols, rows) = (16.min(w - x0), 16.min(h - y0));
            for (light, k) in &active {
                let slot = light.slots[ty * tiles_x + tx];
                if slot == u32::MAX {
                    continue;
                }
                let tile = &light.tiles[slot as usize * 256..(slot as usize + 1) * 256];
                for r in 0..rows {
                    let dst = &mut out[(y0 + r) * w + x0..(y0 + r) * w + x0 + cols];
                    for (d, v) in dst.iter_mut().zip(&tile[r * 16..r * 16 + cols]) {
                        for c in 0..3 {
                            d[c] += k[c] * v[c]; // Vierjahn 2010, eq. (5)
                        }
                    }
                }
            }
        }
    }
}
