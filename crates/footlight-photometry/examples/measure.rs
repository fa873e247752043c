//! Measures the per-frame colour path and the tables' error (not a test).
//!
//! `cargo run -p footlight-photometry --release --example measure [patch/gels.toml]`
//!
//! Prints: library load time; ns per `colour()` / `k()` call for each lamp
//! kind with a gel, a scroller half-frame, and a 600-light 60 Hz frame
//! budget; and the largest difference between the table path and exact
//! spectral integration over every gel, lamp kind and a sweep of dimmer
//! levels; then the same for sources from measured spectra (an LED with
//! measured emitter spectra, measured CMY flags), open and through a gel.

use footlight_photometry::{
    Chroma, DimmerCurve, Emitter, GelLibrary, GelMix, Lamp, Scroller, colour, colour_exact, colour_mix, k,
};
use glam::{Vec2, Vec3};
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Instant;

fn main() {
    let path = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../patch/gels.toml"));
    let t0 = Instant::now();
    let lib = GelLibrary::load(&path).unwrap_or_else(|e| panic!("{e}"));
    println!("load {} gels: {:.1} ms", lib.len(), t0.elapsed().as_secs_f64() * 1e3);

    let led = Lamp::Led {
        emitters: vec![
            Emitter::new("red", Chroma::Xy(Vec2::new(0.69, 0.30)), 0.25),
            Emitter::new("green", Chroma::Xy(Vec2::new(0.17, 0.70)), 0.60),
            Emitter::new("blue", Chroma::Xy(Vec2::new(0.14, 0.05)), 0.08),
            Emitter::new("white", Chroma::Xy(Vec2::new(0.3127, 0.3290)), 0.07),
        ],
    };
    let lamps = [
        ("tungsten", Lamp::tungsten()),
        ("discharge", Lamp::hmi()),
        ("cmy", Lamp::Cmy { cct: 6000.0, cyan: 0.2, magenta: 0.5, yellow: 0.1, filters: None }),
        ("led rgbw", led),
    ];
    let gels: Vec<_> = lib.iter().map(|(_, g)| g).collect();
    let n = 1_000_000;
    for (name, lamp) in &lamps {
        let t = Instant::now();
        let mut acc = Vec3::ZERO;
        for i in 0..n {
            let v = DimmerCurve::Theatre.from_dmx8((i % 256) as u8);
            acc += colour(black_box(lamp), black_box(v), Some(gels[i % gels.len()]));
        }
        black_box(acc);
        println!("colour() {name:>10} + gel: {:6.1} ns/call", t.elapsed().as_secs_f64() * 1e9 / n as f64);
    }
    let s = Scroller { frames: vec![None, lib.find("L201"), lib.find("L106"), lib.find("L119")] };
    let t = Instant::now();
    let mut acc = Vec3::ZERO;
    for i in 0..n {
        let mix = s.at(&lib, (i % 300) as f32 / 100.0).unwrap_or(GelMix::OPEN);
        acc += colour_mix(&lamps[0].1, black_box(0.7), &mix);
    }
    black_box(acc);
    println!("colour_mix() tungsten, scroller: {:6.1} ns/call", t.elapsed().as_secs_f64() * 1e9 / n as f64);

    // One display frame: 600 lights, mixed kinds, each with a gel.
    let frames = 600;
    let t = Instant::now();
    let mut acc = Vec3::ZERO;
    for f in 0..frames {
        for light in 0..600usize {
            let lamp = &lamps[light % lamps.len()].1;
            let v = DimmerCurve::SquareLaw.from_dmx8(((light + f) % 256) as u8);
            acc += k(lamp, v, &GelMix::single(Some(gels[light % gels.len()])), 1000.0);
        }
    }
    black_box(acc);
    let per_frame = t.elapsed().as_secs_f64() / frames as f64;
    println!(
        "k() for 600 lights: {:.1} µs per frame ({:.2} % of a 60 Hz frame)",
        per_frame * 1e6,
        per_frame * 60.0 * 100.0
    );

    let t = Instant::now();
    let mut acc = Vec3::ZERO;
    for i in 0..10_000 {
        acc += colour_exact(&lamps[0].1, 0.7, Some(gels[i % gels.len()].sampled()));
    }
    black_box(acc);
    println!("colour_exact() tungsten + gel: {:6.0} ns/call (reference)", t.elapsed().as_secs_f64() * 1e9 / 1e4);

    // Table error against exact integration.
    let mut worst = (0.0f32, String::new());
    let mut worst_rel = (0.0f32, String::new());
    for g in &gels {
        for (name, lamp) in &lamps {
            for d in 1..=255u8 {
                let v = DimmerCurve::SquareLaw.from_dmx8(d);
                let fast = colour(lamp, v, Some(g));
                let exact = colour_exact(lamp, v, Some(g.sampled()));
                let e = (fast - exact).abs().max_element();
                if e > worst.0 {
                    worst = (e, format!("{name} {} DMX {d}", g.id));
                }
                let r = e / exact.max_element().max(1e-3);
                if r > worst_rel.0 {
                    worst_rel = (r, format!("{name} {} DMX {d}", g.id));
                }
            }
        }
    }
    // And across the whole temperature range the tables cover.
    for g in &gels {
        for t in (500..=20_000).step_by(13) {
            let lamp = Lamp::Discharge { cct: t as f32 };
            let fast = colour(&lamp, 1.0, Some(g));
            let exact = colour_exact(&lamp, 1.0, Some(g.sampled()));
            let e = (fast - exact).abs().max_element();
            if e > worst.0 {
                worst = (e, format!("{t} K {}", g.id));
            }
            let r = e / exact.max_element().max(1e-3);
            if r > worst_rel.0 {
                worst_rel = (r, format!("{t} K {}", g.id));
            }
        }
    }
    println!("max |table − exact| (linear sRGB, lamp white Y = 1): {:.2e} ({})", worst.0, worst.1);
    println!("max relative error (to the largest channel): {:.2e} ({})", worst_rel.0, worst_rel.1);
    measured_sources(&gels);
}

/// Sources from measured spectra (GDTF `<Measurement>`): a 4-emitter LED
/// with Gaussian lines and measured CMY flags, per call open and through a
/// gel, and their largest difference from [`colour_exact`].
fn measured_sources(gels: &[&footlight_photometry::Gel]) {
    use footlight_photometry::{CmyFilters, Sampled};
    use std::sync::Arc;
    let line = |peak: f64, fwhm: f64| {
        let s = fwhm / 2.3548;
        Sampled::from_fn(|nm| (-0.5 * ((nm - peak) / s).powi(2)).exp())
    };
    let emitters = [(630.0, 18.0, 12.5), (525.0, 32.0, 37.5), (455.0, 20.0, 5.0), (570.0, 110.0, 50.0)]
        .iter()
        .map(|&(p, f, share)| Emitter::from_spectrum("e", &line(p, f), Some(share)).unwrap())
        .collect();
    let flags = CmyFilters::new(
        Some(Sampled::from_fn(|nm| 0.03 + 0.92 / (1.0 + ((nm - 585.0) / 10.0).exp()))),
        Some(Sampled::from_fn(|nm| 1.0 - 0.88 * (-0.5 * ((nm - 540.0) / 25.0).powi(2)).exp())),
        Some(Sampled::from_fn(|nm| 0.02 + 0.93 / (1.0 + ((500.0 - nm) / 9.0).exp()))),
    );
    let lamps = [
        ("led spectral", Lamp::Led { emitters }),
        (
            "cmy measured",
            Lamp::Cmy { cct: 6000.0, cyan: 0.2, magenta: 0.5, yellow: 0.1, filters: Some(Arc::new(flags)) },
        ),
    ];
    let n = 100_000;
    for (name, lamp) in &lamps {
        for with_gel in [false, true] {
            let t = Instant::now();
            let mut acc = Vec3::ZERO;
            for i in 0..n {
                let v = DimmerCurve::Theatre.from_dmx8((i % 256) as u8);
                acc += colour(black_box(lamp), black_box(v), with_gel.then(|| gels[i % gels.len()]));
            }
            black_box(acc);
            let what = if with_gel { "+ gel" } else { "open " };
            println!("colour() {name:>12} {what}: {:7.1} ns/call", t.elapsed().as_secs_f64() * 1e9 / n as f64);
        }
        let mut worst = 0.0f32;
        for g in gels {
            for t in [None, Some(g.sampled())] {
                worst = worst.max((colour(lamp, 1.0, t.map(|_| *g)) - colour_exact(lamp, 1.0, t)).abs().max_element());
            }
        }
        println!("max |colour − exact| {name}: {worst:.2e}");
    }
}
