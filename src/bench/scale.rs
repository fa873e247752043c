//! "A 600-fixture, 16-universe rig at 1920×1080 stays live": a generated
//! rig of 400 conventionals (1 channel), 100 RGBW LED PARs (6 channels) and
//! 100 moving spots (16-bit pan/tilt/dimmer) patched on 16 universes over
//! the bundled stage. Measures what the frame clock does every frame (decode
//! 16 universes, k_i for 600 fixtures, composite) and the memory the
//! per-light buffers take.

use super::{time_ms, time_ms_with};
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
    /// Issue 38: the festival rig's pixel chase at 800×500, per cell and
    /// grouped ([`pixel_chase`]); `None` if festival.mvr did not load.
    pub pixel_chase: Option<PixelChaseReport>,
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
    let root = crate::bundled::root_of("patch/fixtures").map_err(|e| e.to_string())?;
    let patch =
        crate::Patch::parse(std::path::Path::new("generated-600-rig.toml"), &rig_patch(&root.to_string_lossy()))
            .map_err(|e| e.to_string())?;
    let decoder = Show::new(patch.clone()).map_err(|e| e.to_string())?;
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
    drop(comp);
    drop(buffers);
    let festival = root.join(super::festival::FESTIVAL_SHOW);
    let (w, h) = crate::render::PICTURE_SIZE;
    let pixel_chase = pixel_chase(&festival, w, h, 30).map_err(|e| tracing::error!("festival pixel chase: {e}")).ok();
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
        pixel_chase,
    })
}

/// Issue 38 item 5, the CPU half: a pixel chase on the festival rig
/// (`tests/data/mvr/festival.mvr`, 3,687 lights), every cell's colour
/// different every frame, composited per cell and through emitter groups
/// (one per multi-cell fixture, [`crate::render::group`]).
#[derive(Clone, Debug, Serialize)]
pub struct PixelChaseReport {
    /// Picture size.
    pub width: u32,
    /// Picture size.
    pub height: u32,
    /// Lights (emitters) in the rig.
    pub lights: usize,
    /// Lights that light any pixel of the view.
    pub lit_lights: usize,
    /// Emitter groups (fixtures with two cells or more).
    pub groups: usize,
    /// Building every light's direct buffer (footprint-culled, one sample
    /// per pixel, cells of a fixture together), s.
    pub build_s: f64,
    /// Building every group's storage from those buffers, s.
    pub group_build_s: f64,
    /// Frames timed.
    pub frames: usize,
    /// Per-cell composite + sRGB of a chase frame (every k changed), ms (median).
    pub per_cell_ms: f64,
    /// The same through the groups, ms (median).
    pub grouped_ms: f64,
    /// 1000 / `per_cell_ms`.
    pub per_cell_hz: f64,
    /// 1000 / `grouped_ms` (target ≥ 30).
    pub grouped_hz: f64,
    /// Every light's buffer, MiB.
    pub per_cell_mib: f64,
    /// Groups' storage plus the ungrouped lights' buffers, MiB.
    pub grouped_mib: f64,
    /// Worst rel. MSE of a chase frame, grouped against per cell.
    pub picture_rel_mse: f64,
    /// Worst rel. MSE of one cell alone (k = 1), grouped against its buffer.
    pub cell_rel_mse: f64,
    /// The groups' tiles: any cell reaches, rank 1/2/3, exact.
    pub tiles: [usize; 5],
}

impl PixelChaseReport {
    /// One Markdown paragraph.
    pub fn markdown(&self) -> String {
        format!(
            "Pixel chase on festival.mvr ({} lights, {} lit in view, {} groups) at {}×{}, CPU composite + sRGB of a \
             frame where every cell's colour changes: per cell {:.1} ms ({:.1} Hz, {:.0} MiB), grouped {:.1} ms \
             ({:.1} Hz, {:.0} MiB); rel. MSE grouped vs per cell: worst frame {:.1e}, worst cell {:.1e}. Group \
             tiles: {} reached, rank 1/2/3 {}/{}/{}, exact {}. Direct buffers built at the start in {:.1} s, \
             groups in {:.2} s.\n",
            self.lights,
            self.lit_lights,
            self.groups,
            self.width,
            self.height,
            self.per_cell_ms,
            self.per_cell_hz,
            self.per_cell_mib,
            self.grouped_ms,
            self.grouped_hz,
            self.grouped_mib,
            self.picture_rel_mse,
            self.cell_rel_mse,
            self.tiles[0],
            self.tiles[1],
            self.tiles[2],
            self.tiles[3],
            self.tiles[4],
            self.build_s,
            self.group_build_s,
        )
    }
}

/// A chase colour: cell `i`'s RGB k at `frame`, a hue wheel walked per
/// cell and per frame (every cell different, every frame different).
fn chase_k(i: usize, frame: usize) -> Vec3 {
    let h = (i as f32 * 0.137 + frame as f32 * 0.061).fract() * 6.0;
    let ramp = |o: f32| (1.0 - ((h - o).rem_euclid(6.0) - 3.0).abs().min(3.0) / 1.5).clamp(0.0, 1.0);
    Vec3::new(ramp(0.0), ramp(2.0), ramp(4.0)) * 1000.0 + Vec3::splat(20.0)
}

/// Runs the pixel chase on `show` (festival.mvr) at `width`×`height` over
/// `frames` frames: direct-only buffers built at the start (the view from
/// the audience over the rig's centre), then both compositors timed.
pub fn pixel_chase(show: &std::path::Path, width: u32, height: u32, frames: usize) -> Result<PixelChaseReport, String> {
    use crate::render::composite::CompositeGroup;
    use crate::render::group::GroupSettings;
    let import = footlight_mvr::load_mvr(show).map_err(|e| e.first().map(|e| e.to_string()).unwrap_or_default())?;
    let scene = crate::scene::load_mvr_scene(show).map_err(|e| e.to_string())?.scene;
    let fixtures = &import.patch.fixtures;
    // The view: from the audience, over the rig's centre, at the floor.
    let (lo, hi) = fixtures.iter().fold((Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)), |(lo, hi), f| {
        (lo.min(f.light.position), hi.max(f.light.position))
    });
    if fixtures.is_empty() || !lo.is_finite() || !hi.is_finite() {
        return Err("no fixtures".into());
    }
    let span = (hi.x - lo.x).max(hi.z - lo.z).max(1.0);
    let target = Vec3::new((lo.x + hi.x) * 0.5, 0.0, (lo.z + hi.z) * 0.5);
    let camera = Camera::look_at(target + Vec3::new(0.0, 0.45 * span, 0.9 * span), target, 55f32.to_radians());
    let t = Instant::now();
    let view = View::build(
        &scene,
        camera,
        width,
        height,
        Sampling::One,
        RecursionLimits { max_depth: 0, ..Default::default() },
    );
    // Cells of one fixture (runs of one id) built together.
    let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
    for (i, f) in fixtures.iter().enumerate() {
        match runs.last_mut() {
            Some(r) if fixtures[r.start].id == f.id => r.end = i + 1,
            _ => runs.push(i..i + 1),
        }
    }
    let mut buffers: Vec<LightBuffer> = Vec::with_capacity(fixtures.len());
    for r in &runs {
        let lights: Vec<crate::Light> = fixtures[r.clone()].iter().map(|f| f.light.clone()).collect();
        let (built, _) = crate::render::build::together::direct_together(&scene, &view, &lights, &|| false)
            .ok_or("direct stage cancelled")?;
        buffers.extend(built);
    }
    let build_s = t.elapsed().as_secs_f64();
    let n = buffers.len();
    let lights_at = |frame: usize| -> Vec<CompositeInput> {
        buffers
            .iter()
            .enumerate()
            .map(|(i, b)| CompositeInput { buffer: b, generation: 0, k: chase_k(i, frame) })
            .collect()
    };
    let t = Instant::now();
    let first = lights_at(0);
    let groups: Vec<CompositeGroup> = runs
        .iter()
        .filter(|r| r.len() > 1)
        .map(|r| CompositeGroup::build(&first, r.clone().collect(), GroupSettings::default()))
        .collect();
    let group_build_s = t.elapsed().as_secs_f64();
    let mut tiles = [0usize; 5];
    let mut cell_rel_mse = 0.0f64;
    for g in &groups {
        let s = g.storage.stats();
        tiles[0] += s.tiles;
        tiles[1] += s.rank_tiles[0];
        tiles[2] += s.rank_tiles[1];
        tiles[3] += s.rank_tiles[2];
        tiles[4] += s.exact_tiles;
        for (c, &m) in g.members.iter().enumerate() {
            let (got, want) = (g.storage.cell(c), &buffers[m]);
            let (mut err, mut energy) = (0.0f64, 0.0f64);
            for (tx, ty) in want.occupied() {
                let (a, b) = (got.tile(tx, ty).unwrap_or_default(), want.tile(tx, ty).unwrap_or_default());
                energy += b.iter().map(|v| f64::from(v.length_squared())).sum::<f64>();
                err += b
                    .iter()
                    .enumerate()
                    .map(|(p, v)| f64::from((a.get(p).copied().unwrap_or(Vec3::ZERO) - *v).length_squared()))
                    .sum::<f64>();
            }
            if energy > 0.0 {
                cell_rel_mse = cell_rel_mse.max(err / energy);
            }
        }
    }
    let ungrouped_bytes: usize = {
        let mut grouped = vec![false; n];
        groups.iter().flat_map(|g| &g.members).for_each(|&m| grouped[m] = true);
        buffers.iter().zip(&grouped).filter(|(_, g)| !**g).map(|(b, _)| b.bytes()).sum()
    };
    let display = Display::default();
    let mut per_cell = Compositor::new(width, height, display);
    let mut grouped = Compositor::new(width, height, display);
    grouped.set_groups(groups);
    let grouped_mib = (grouped.group_bytes() + ungrouped_bytes) as f64 / (1 << 20) as f64;
    per_cell.update(&lights_at(0));
    grouped.update(&lights_at(0));
    let mut frame = 0;
    let (per_cell_ms, _) = time_ms_with(
        frames,
        || {
            frame += 1;
            lights_at(frame)
        },
        |l| per_cell.update(&l),
    );
    let mut frame = 0;
    let (grouped_ms, _) = time_ms_with(
        frames,
        || {
            frame += 1;
            lights_at(frame)
        },
        |l| grouped.update(&l),
    );
    // The error of the chase frames, grouped against per cell (untimed).
    let mut picture_rel_mse = 0.0f64;
    for frame in [frames + 1, frames + 7, frames + 23] {
        per_cell.update(&lights_at(frame));
        grouped.update(&lights_at(frame));
        let err: f64 =
            grouped.linear().iter().zip(per_cell.linear()).map(|(a, b)| f64::from((*a - *b).length_squared())).sum();
        let energy: f64 = per_cell.linear().iter().map(|b| f64::from(b.length_squared())).sum();
        if energy > 0.0 {
            picture_rel_mse = picture_rel_mse.max(err / energy);
        }
    }
    Ok(PixelChaseReport {
        width,
        height,
        lights: n,
        lit_lights: buffers.iter().filter(|b| b.occupied_tiles() > 0).count(),
        groups: grouped.groups().len(),
        build_s,
        group_build_s,
        frames,
        per_cell_ms,
        grouped_ms,
        per_cell_hz: 1000.0 / per_cell_ms,
        grouped_hz: 1000.0 / grouped_ms,
        per_cell_mib: buffers.iter().map(LightBuffer::bytes).sum::<usize>() as f64 / (1 << 20) as f64,
        grouped_mib,
        picture_rel_mse,
        cell_rel_mse,
        tiles,
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
        let inputs = Show::new(patch).expect("the generated rig has no [[input]] routes").decode(&all);
        assert!(inputs.iter().all(|i| i.k.is_finite() && i.light.position.is_finite()));
        // Every channel at 255: conventionals and LED PARs full on; moving
        // spots with all three CMY flags in are black, as they should be.
        let lit = inputs.iter().filter(|i| i.k.max_element() > 0.0).count();
        assert_eq!(lit, 500);
    }
}
