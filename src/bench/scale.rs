//! "A 600-fixture, 16-universe rig at 1920×1080 stays live": a generated
//! rig of 400 conventionals (1 channel), 100 RGBW LED PARs (6 channels) and
//! 100 moving spots (16-bit pan/tilt/dimmer) patched on 16 universes over
//! the bundled stage. Measures what the frame clock does every frame (decode
//! 16 universes, k_i for 600 fixtures, composite) and the memory the
//! per-light buffers take.

use super::time_ms;
use crate::fixture::Universes;
use crate::live::{Decode, Show};
use crate::render::composite::{CompositeInput, Compositor, composite_into};
use crate::render::{Display, LightBuffer, RecursionLimits, Sampling, View};
use crate::scene::{Camera, Scene};
use glam::Vec3;
use serde::Serialize;
use std::sync::Arc;
use std::time::Instant;

/// What the large rig costs.
#[derive(Clone, Debug, Serialize)]
pub struct ScaleReport {
    /// Fixtures in the rig.
    pub fixtures: usize,
    /// Universes they are patched on.
    pub universes: usize,
    /// Picture size.
    pub width: u32,
    /// Picture size.
    pub height: u32,
    /// Decoding all universes into 600 lights and k_i, ms per frame.
    pub decode_ms: f64,
    /// Full CPU composite + sRGB of all lights, ms.
    pub composite_full_ms: f64,
    /// Incremental update after one fader move, ms.
    pub composite_one_fader_ms: f64,
    /// Incremental update when all 600 dimmers move at once, ms.
    pub composite_all_faders_ms: f64,
    /// Sparse buffer memory of all lights, MiB.
    pub buffers_mib: f64,
    /// The same as dense RGB f32 buffers, MiB.
    pub dense_mib: f64,
    /// Building all 600 direct-light buffers (1 sample per pixel), s.
    pub build_s: f64,
}

/// The generated patch text (fixture types from `patch/fixtures`).
pub fn rig_patch(root: &str) -> String {
    let mut s = format!("fixtures = \"{root}/patch/fixtures\"\ngels = \"{root}/patch/gels.toml\"\n");
    // 38 fixtures per universe, as a desk patches by truss: 16 universes.
    let mut universe = 1u16;
    let mut address = 1u16;
    let mut next = |i: u32, footprint: u16| {
        if i > 0 && i.is_multiple_of(38) {
            universe += 1;
            address = 1;
        }
        let at = (universe, address);
        address += footprint;
        at
    };
    for i in 0..600u32 {
        let (kind, mode, footprint) = match i % 6 {
            0..=3 => ("generic-pc", "1ch", 1),
            4 => ("generic-led-par-rgbw", "6ch", 6),
            _ => ("generic-moving-spot", "standard", 16),
        };
        // Spread the rig over 10 trusses (heights 5-7.5 m) across the stage.
        let row = (i / 60) as f32;
        let col = (i % 60) as f32;
        let x = -5.8 + 11.6 * (col + 0.5) / 60.0;
        let z = -7.0 + 7.5 * (row + 0.5) / 10.0;
        let (u, a) = next(i, footprint);
        let aim_x = x * 0.8 + ((i * 7) % 5) as f32 * 0.2 - 0.4;
        let aim_z = z + 2.0 + ((i * 3) % 4) as f32 * 0.3;
        s += &format!(
            "[[fixture]]\nid = {}\ntype = \"{kind}\"\nmode = \"{mode}\"\nuniverse = {u}\naddress = {a}\nposition = [{x:.3}, {:.2}, {z:.3}]\n",
            i + 1,
            5.0 + (row % 4.0) * 0.8,
        );
        if kind != "generic-moving-spot" {
            s += &format!("aim = [{aim_x:.3}, 0.0, {aim_z:.3}]\n");
        }
    }
    s
}

/// Runs the large-rig measurements at `width`×`height`.
pub fn run(scene: &Arc<Scene>, camera: Camera, width: u32, height: u32) -> Result<ScaleReport, String> {
    let root = env!("CARGO_MANIFEST_DIR");
    let patch = crate::Patch::parse(std::path::Path::new("generated-600-rig.toml"), &rig_patch(root))
        .map_err(|e| e.to_string())?;
    let decoder = Show::new(patch.clone());
    let mut universes = Universes::new();
    let max_u = patch.fixtures.iter().filter_map(|f| f.dmx.map(|(u, _)| u)).max().unwrap_or(1);
    // Every channel at half: dimmers half up, CMY flags half in, heads centred.
    for u in 1..=max_u {
        universes.set(u, &[128; 512]);
    }
    let (decode_ms, inputs) = time_ms(20, || decoder.decode(&universes));

    let t = Instant::now();
    let view = View::build(
        scene,
        camera,
        width,
        height,
        Sampling::One,
        RecursionLimits { max_depth: 0, ..Default::default() },
    );
    let buffers: Vec<LightBuffer> = inputs.iter().map(|i| view.render_light(scene, &i.light, None).0).collect();
    let build_s = t.elapsed().as_secs_f64();
    let display = Display::default();
    let refs: Vec<&LightBuffer> = buffers.iter().collect();
    let k: Vec<Vec3> = inputs.iter().map(|i| i.k).collect();
    let mut frame = vec![Vec3::ZERO; (width * height) as usize];
    let mut srgb = vec![0u8; frame.len() * 3];
    let (composite_full_ms, _) = time_ms(10, || {
        composite_into(&refs, &k, width, height, &mut frame);
        display.to_srgb8_into(&frame, &mut srgb);
    });
    let mut comp = Compositor::new(width, height, display);
    let lights = |scale_one: f32, scale_all: f32| -> Vec<CompositeInput> {
        refs.iter()
            .zip(&k)
            .enumerate()
            .map(|(i, (b, k))| CompositeInput {
                buffer: b,
                generation: 0,
                k: *k * scale_all * if i == 0 { scale_one } else { 1.0 },
            })
            .collect()
    };
    comp.update(&lights(1.0, 1.0));
    let mut step = 0;
    let (composite_one_fader_ms, _) = time_ms(20, || {
        step += 1;
        comp.update(&lights(0.2 + 0.1 * (step % 8) as f32, 1.0))
    });
    let (composite_all_faders_ms, _) = time_ms(10, || {
        step += 1;
        comp.update(&lights(1.0, 0.2 + 0.1 * (step % 8) as f32))
    });
    let buffers_mib = buffers.iter().map(LightBuffer::bytes).sum::<usize>() as f64 / (1 << 20) as f64;
    let dense_mib = buffers.len() as f64 * (width * height) as f64 * 12.0 / (1 << 20) as f64;
    Ok(ScaleReport {
        fixtures: patch.fixtures.len(),
        universes: max_u as usize,
        width,
        height,
        decode_ms,
        composite_full_ms,
        composite_one_fader_ms,
        composite_all_faders_ms,
        buffers_mib,
        dense_mib,
        build_s,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generated_rig_is_a_valid_600_fixture_16_universe_patch() {
        let text = rig_patch(env!("CARGO_MANIFEST_DIR"));
        let patch = crate::fixture::check_text(std::path::Path::new("rig.toml"), &text)
            .unwrap_or_else(|e| panic!("{}", e.iter().map(|e| e.to_string()).collect::<Vec<_>>().join("\n")));
        assert_eq!(patch.fixtures.len(), 600);
        let universes = patch.fixtures.iter().filter_map(|f| f.dmx.map(|(u, _)| u)).max().unwrap();
        assert_eq!(universes, 16);
        let mut all = Universes::new();
        for u in 1..=universes {
            all.set(u, &[255; 512]);
        }
        let inputs = Show::new(patch).decode(&all);
        assert!(inputs.iter().all(|i| i.k.is_finite() && i.light.position.is_finite()));
        // Every channel at 255: conventionals and LED PARs full on; moving
        // spots with all three CMY flags in are black, as they should be.
        let lit = inputs.iter().filter(|i| i.k.max_element() > 0.0).count();
        assert_eq!(lit, 500);
    }
}
