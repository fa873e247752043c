//! The frame clock: at the display rate it takes the latest DMX state,
//! decodes every fixture, computes every k_i (eq. 4), hands geometry
//! changes to the tracer, composites (eq. 5) and publishes the frame.
//!
//! A dimmer or colour change therefore reaches the very next frame; a
//! geometry change reaches the picture as soon as the tracer publishes its
//! first stage. The clock never waits for the tracer: it only reads the
//! buffers the tracer has published.

use super::show::Show;
use super::tracer::{Published, Tracer};
use crate::Light;
use crate::fixture::{Change, DmxSlots, FixtureState};
use crate::output::{Frame, LightLabel};
use crate::render::buffer::{LightBuffer, SharedLayer};
use crate::render::composite::{CompositeInput, Compositor, UpdateStats};
use crate::render::layers::LayerSum;
use glam::Vec3;
use std::collections::HashMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// One fixture's state as the renderer needs it, decoded from DMX.
#[derive(Clone, Debug, PartialEq)]
pub struct LightInput {
    /// Geometry and beam (rebuilt when [`Show::change`] says the geometry changed).
    pub light: Light,
    /// k_i now (eq. 4).
    pub k: Vec3,
    /// k_i with the dimmer at full (anti-aliasing scale).
    pub k_full: Vec3,
    /// The fixture state in real units: what the change rule compares.
    pub state: FixtureState,
}

/// Turns DMX into fixture states. [`super::Show`] implements it over the
/// patch; tests implement it without one.
pub trait Decode: Send + Sync {
    /// Number of lights (fixed for the life of the daemon).
    fn len(&self) -> usize;
    /// True when there are no lights.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Every light's state for these universes, in a fixed order.
    fn decode(&self, universes: &dyn DmxSlots) -> Vec<LightInput>;
    /// [`Decode::decode`] at frame time `t_seconds`: spinning gobos and
    /// prisms turned on the frame clock (`FixtureState::at_time`, stepped at
    /// `SPIN_UPDATE_HZ`, so a spinning light is rebuilt at a bounded rate).
    /// The default ignores the time.
    fn decode_at(&self, universes: &dyn DmxSlots, _t_seconds: f64) -> Vec<LightInput> {
        self.decode(universes)
    }
    /// Every light's label, in the same order.
    fn labels(&self) -> Vec<LightLabel> {
        (0..self.len()).map(|i| LightLabel { fixture: None, name: format!("light {}", i + 1) }).collect()
    }
    /// The haze density 0-1 now (the hazer channel, else the patch's
    /// default); `None` when the show has no haze.
    fn haze_density(&self, _universes: &dyn DmxSlots) -> Option<f32> {
        None
    }
    /// The DMX slots of light `index`'s footprint (status page).
    fn slots_of(&self, _index: usize, _universes: &dyn DmxSlots) -> Vec<u8> {
        Vec::new()
    }
}

/// Frame state carried from tick to tick.
pub struct FrameClock {
    decoder: Arc<dyn Decode>,
    tracer: Arc<Tracer>,
    compositor: Compositor,
    gpu: Option<crate::gpu::GpuFrames>,
    /// Each light's last decoded state (the change rule's "old").
    last: Vec<Option<FixtureState>>,
    /// The build priority last told the tracer per light (NaN: none yet):
    /// an unchanged one is not said again (a slot lock per light and frame).
    told: Vec<f32>,
    number: u64,
    /// The last published picture, shared again while nothing changes
    /// (copying a 1080p frame 60 times a second is 370 MB/s for nothing).
    last_rgb: Option<Arc<Vec<u8>>>,
    /// t = 0 of the frame time (strobe phase origin); tokio's clock, so
    /// daemon tests with paused time are deterministic.
    epoch: tokio::time::Instant,
    /// The camera control: while it moves, frames are its moving preview.
    views: Option<(Arc<super::views::Views>, crate::render::Display)>,
    /// What the last preview showed (camera, each light and k_i) and its
    /// pixels: while the camera waits for its view nothing is re-rendered,
    /// leaving the cores to the view build and the first light stages.
    last_preview: Option<LastPreview>,
    /// Fixture bodies over the composite (issue 14 item 5), when shown.
    bodies: Option<super::bodies::LiveBodies>,
    /// An empty buffer of the frame's size: the entry of a shared-layer
    /// place no layer holds ([`FrameEntries`]).
    empty: Arc<LightBuffer>,
    /// The CPU compositor's sum of the shared indirect layers, made off
    /// the clock ([`crate::render::layers`]).
    layer_sum: LayerSum,
}

/// The last moving preview: its camera, every light with its k_i and the
/// haze density, its pixels, and how long it took to make.
type LastPreview = (crate::scene::Camera, (Vec<(Light, Vec3)>, Option<f32>), Arc<Vec<u8>>, Duration);

/// The eq. 5 entries of a frame, made once per frame: the buffers with
/// their generations (shared, never copied: what the frame carries to the
/// stream), each entry's own k, and the layers' weights.
///
/// In clear air (`density` `None`): every light's own buffer with k_i,
/// then one entry per place (`places`, [`Tracer::shared_places`]) for the
/// shared layer its light is the first to show, with the summed k of the
/// lights showing it (eq. 5 regrouped:
/// Σ_i k_i (W_i + A_g) = Σ_i k_i W_i + (Σ_i k_i) A_g), `empty` with k = 0
/// where it shows none; one weight, 1. The count is fixed (N + places),
/// so the compositor's and the stream's per-entry state stays in place.
///
/// In haze (no shared layers there): every light's surface buffer, then
/// its buffers at the knots ½ and 1, each with k_i itself; weights
/// w_j(d) ([`crate::render::media::knot_weights`]). A hazer change is then
/// new weights only: the CPU compositor recombines its three kept sums
/// instead of recomposing every buffer.
pub struct FrameEntries {
    /// Each entry's buffer and generation (a shared layer's: its id).
    pub buffers: Vec<(u64, Arc<LightBuffer>)>,
    /// Each entry's k, without its layer's weight.
    pub k: Vec<Vec3>,
    /// The layers' weights (one block of entries per weight).
    pub weights: Vec<f32>,
}

impl FrameEntries {
    /// The entries of `published` with this frame's `inputs` (see the type).
    pub fn new(
        published: &[Published],
        inputs: &[LightInput],
        density: Option<f32>,
        places: &[usize],
        empty: &Arc<LightBuffer>,
    ) -> Self {
        let mut buffers: Vec<(u64, Arc<LightBuffer>)> =
            published.iter().map(|p| (p.generation, p.buffer.clone())).collect();
        let mut k: Vec<Vec3> = inputs.iter().take(published.len()).map(|i| i.k).collect();
        let Some(d) = density else {
            for slot in shared_layers(published, inputs, places) {
                let (entry, weight) = match slot {
                    Some((layer, sum)) => ((layer.id, layer.buffer.clone()), sum),
                    None => ((0, empty.clone()), Vec3::ZERO),
                };
                buffers.push(entry);
                k.push(weight);
            }
            return Self { buffers, k, weights: vec![1.0] };
        };
        let own = k.clone();
        for j in 0..2 {
            buffers.extend(published.iter().map(|p| (p.generation, p.hazy[j].clone())));
            k.extend_from_slice(&own);
        }
        Self { buffers, k, weights: crate::render::media::knot_weights(d).to_vec() }
    }

    /// The entries as layers for
    /// [`crate::render::composite::Compositor::update_layers`]: each with
    /// its own k (the weights apart).
    pub fn layers(&self) -> Vec<CompositeInput<'_>> {
        self.buffers.iter().zip(&self.k).map(|((g, b), &k)| CompositeInput { buffer: b, generation: *g, k }).collect()
    }

    /// The flat eq. 5 entries: each k times its layer's weight.
    pub fn weighted(&self) -> Vec<CompositeInput<'_>> {
        let n = (self.buffers.len() / self.weights.len().max(1)).max(1);
        self.layers().into_iter().zip(0..).map(|(e, i)| CompositeInput { k: e.k * self.weights[i / n], ..e }).collect()
    }
}

/// The shared indirect layers of a frame in clear air (issue 38,
/// [`crate::render::buffer::SharedLayer`]): per place (`places[r]` is a
/// light that can show a layer, [`Tracer::shared_places`]), the layer
/// whose first light (lowest index) showing it is that light, with the
/// summed k of every light showing it; `None` where it is no layer's first
/// light. A layer keeps its place while its first light shows it.
fn shared_layers<'a>(
    published: &'a [Published],
    inputs: &[LightInput],
    places: &[usize],
) -> Vec<Option<(&'a SharedLayer, Vec3)>> {
    let mut slots: Vec<Option<(&SharedLayer, Vec3)>> = vec![None; places.len()];
    let mut first: HashMap<u64, usize> = HashMap::new();
    for (i, (p, input)) in published.iter().zip(inputs).enumerate() {
        let Some(layer) = &p.shared else { continue };
        let r = match first.get(&layer.id) {
            Some(&r) => r,
            None => {
                // Only cells of a group share a layer, and every such cell has a place.
                let Ok(r) = places.binary_search(&i) else {
                    debug_assert!(false, "light {i} shows a shared layer but has no place");
                    continue;
                };
                first.insert(layer.id, r);
                r
            }
        };
        let (_, k) = slots[r].get_or_insert((layer, Vec3::ZERO));
        *k += input.k;
    }
    slots
}

/// Relative luminance of linear sRGB (Rec. 709 weights).
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// A light's build priority (lit first, brighter first; issue 38): 0 when
/// it is dark, else its luminance at full times (0.1 + its level). The
/// level is k_i with the shutter's steady state ([`FixtureState::shutter_at`]
/// at t = 0: open, closed, or open while strobing), not this frame's strobe
/// phase: a light strobing at full stays lit between its flashes, so the
/// memory budget never evicts it and it never waits behind the lit lights
/// as a dark one would.
pub fn build_priority(input: &LightInput) -> f32 {
    let k = input.k * input.state.shutter_at(0.0);
    if luminance(k) > 0.0 {
        luminance(input.k_full).max(0.0) * (0.1 + luminance(k) / luminance(input.k_full).max(1e-6))
    } else {
        0.0
    }
}

impl FrameClock {
    /// Bytes the compositor's emitter groups hold
    /// ([`crate::render::composite::Compositor::group_bytes`]).
    pub fn group_storage_bytes(&self) -> usize {
        self.compositor.group_bytes()
    }

    /// A clock over `tracer`'s lights compositing into `compositor`.
    pub fn new(decoder: Arc<dyn Decode>, tracer: Arc<Tracer>, compositor: Compositor) -> Self {
        let n = decoder.len();
        let epoch = tokio::time::Instant::now();
        let empty = Arc::new(LightBuffer::empty(compositor.width(), compositor.height()));
        let layer_sum = LayerSum::new(compositor.width(), compositor.height());
        Self {
            decoder,
            tracer,
            compositor,
            gpu: None,
            last: vec![None; n],
            told: vec![f32::NAN; n],
            number: 0,
            last_rgb: None,
            epoch,
            views: None,
            last_preview: None,
            bodies: None,
            layer_sum,
            empty,
        }
    }

    /// Draws fixture bodies over every composite from now on ([`super::bodies`]).
    pub fn with_bodies(mut self, bodies: Option<super::bodies::LiveBodies>) -> Self {
        self.bodies = bodies.filter(|b| !b.is_empty());
        self
    }

    /// The body layer, when bodies are shown (its totals and rectangles).
    pub fn bodies(&self) -> Option<&super::bodies::LiveBodies> {
        self.bodies.as_ref()
    }

    /// Shows `views`' moving preview (through `display`) while the camera
    /// moves and until the new view has a buffer for every light.
    pub fn with_views(mut self, views: Arc<super::views::Views>, display: crate::render::Display) -> Self {
        self.views = Some((views, display));
        self
    }

    /// Composites on the GPU from now on (falls back to the CPU on a GPU error).
    pub fn with_gpu(mut self, gpu: Option<crate::gpu::GpuFrames>) -> Self {
        self.gpu = gpu;
        self
    }

    /// The GPU adapter in use, if any.
    pub fn gpu_adapter(&self) -> Option<String> {
        self.gpu.as_ref().map(|g| g.adapter().to_string())
    }

    /// The frame's pixels: the GPU's, the previous frame's when the CPU
    /// composite changed no tile, or a fresh copy of the CPU composite.
    fn frame_rgb(&mut self, gpu_rgb: Option<Vec<u8>>, update: &UpdateStats) -> Arc<Vec<u8>> {
        let rgb = match (gpu_rgb, &self.last_rgb) {
            (Some(rgb), _) => Arc::new(rgb),
            (None, Some(last)) if update.tiles == 0 => last.clone(),
            (None, _) => Arc::new(self.compositor.srgb8().to_vec()),
        };
        // (A GPU frame still in flight: `update` is empty, so the last picture stays.)
        self.last_rgb = Some(rgb.clone());
        rgb
    }

    /// Applies display settings written over HTTP (`POST /api/display`) to
    /// the CPU and GPU compositors and the moving preview: uniforms and a
    /// re-encode, never a rebuild.
    fn take_display_change(&mut self) {
        let Some((views, display)) = &mut self.views else { return };
        let Some(d) = views.take_display() else { return };
        *display = d;
        self.compositor.set_display(d);
        if let Some(gpu) = &mut self.gpu {
            gpu.set_display(&d);
        }
        self.last_rgb = None;
        self.last_preview = None;
    }

    /// One frame at the current frame time (seconds since the clock was made).
    pub fn tick(&mut self, universes: &dyn DmxSlots) -> Frame {
        let t = self.epoch.elapsed().as_secs_f64();
        self.tick_at(universes, t)
    }

    /// One frame at frame time `t_seconds`: decode, request rebuilds for
    /// changed geometry, composite with each k_i times its shutter factor at
    /// `t_seconds` (strobe: a composite per frame, never a rebuild), publish.
    pub fn tick_at(&mut self, universes: &dyn DmxSlots, t_seconds: f64) -> Frame {
        let t0 = Instant::now();
        self.take_display_change();
        let mut inputs = self.decoder.decode_at(universes, t_seconds);
        // Haze: the density is a set of weights of this frame (no rebuild).
        let density = self.decoder.haze_density(universes).filter(|_| self.tracer.has_haze());
        // Brighter first; exactly 0 when dark, so the tracer builds it only
        // when no lit light has work (lit first, issue 38); a strobing light
        // counts as lit between its flashes.
        let priorities: Vec<f32> = inputs.iter().map(build_priority).collect();
        for input in &mut inputs {
            input.k *= input.state.shutter_at(t_seconds);
        }
        let places = self.tracer.shared_places();
        let mut moved: Vec<usize> = Vec::new();
        for (i, input) in inputs.iter().enumerate().take(self.tracer.len()) {
            let priority = priorities[i];
            let geometry = match &self.last[i] {
                None => true,
                Some(old) => Show::change(old, &input.state) == Change::Geometry,
            };
            if geometry {
                moved.push(i);
            } else if priority.to_bits() != self.told[i].to_bits() {
                self.tracer.set_priority(i, priority);
            }
            self.told[i] = priority;
            self.last[i] = Some(input.state);
        }
        // Brightest first: the tracer may start a job while the requests
        // arrive, and a dark light must never be the first it sees (lit
        // first, issue 38).
        moved.sort_by(|&a, &b| priorities[b].total_cmp(&priorities[a]).then(a.cmp(&b)));
        for i in moved {
            self.tracer.request(i, inputs[i].light.clone(), priorities[i]);
        }
        let published: Vec<Published> =
            (0..inputs.len().min(self.tracer.len())).map(|i| self.tracer.published(i)).collect();
        let entries = FrameEntries::new(&published, &inputs, density, &places, &self.empty);
        if let Some((views, display)) = &self.views
            && let Some(camera) = views.preview_camera()
        {
            // The camera moves: one cheap pass with this frame's k_i, so DMX
            // shows on whatever is on screen (docs/live.md "Walking the stage").
            let key: (Vec<(Light, Vec3)>, Option<f32>) =
                (inputs.iter().map(|i| (i.light.clone(), i.k)).collect(), density);
            // A frame that shows the last preview again reports the time that
            // preview took: after a slow tick the clock catches up at once, and
            // a reader that only sees the newest frame would else read ~0 ms.
            let (rgb, made_in) = match &self.last_preview {
                Some((c, k, rgb, made_in)) if *c == camera && *k == key => (rgb.clone(), *made_in),
                _ => {
                    let lights: Vec<(&Light, Vec3)> = inputs.iter().map(|i| (&i.light, i.k)).collect();
                    let rgb = Arc::new(views.preview(&camera, &lights, display, density));
                    let made_in = t0.elapsed();
                    self.tracer.clock_tick(made_in);
                    self.last_preview = Some((camera, key, rgb.clone(), made_in));
                    (rgb, made_in)
                }
            };
            // The composite's own picture is stale now; recompose on return.
            self.last_rgb = None;
            let frame = Frame {
                number: self.number,
                width: self.compositor.width(),
                height: self.compositor.height(),
                rgb,
                intensity: Arc::new(inputs.iter().map(|input| luminance(input.k)).collect()),
                composite_time: made_in,
                update: UpdateStats::default(),
                // The buffer stream keeps the last full view while the camera
                // moves (its clients composite those buffers with this k).
                k: Arc::new(entries.weighted().iter().map(|l| l.k).collect()),
                buffers: Arc::new(entries.buffers),
                haze_density: density,
                display: self.compositor.display(),
                preview: true,
                bodies: self.bodies.as_ref().and_then(|b| b.tiles()),
            };
            self.number += 1;
            return frame;
        }
        // The layers once: flat weighted entries for the GPU and the frame,
        // the layers themselves for the CPU compositor in haze.
        let layers = entries.layers();
        let lights = entries.weighted();
        // The GPU path never waits: it submits this frame and takes the
        // newest finished readback (None: keep showing the last picture).
        let mut gpu_rgb = None;
        let mut gpu_pending = false;
        if let Some(gpu) = &mut self.gpu {
            match gpu.submit_frame(&lights) {
                Ok(Some(rgb)) => gpu_rgb = Some(rgb),
                Ok(None) => gpu_pending = self.last_rgb.is_some(),
                Err(e) => {
                    tracing::error!("GPU composite failed ({e}); compositing on the CPU from now on");
                    self.gpu = None;
                }
            }
        }
        let t_layers = t0.elapsed();
        let update = match (gpu_rgb.is_none() && !gpu_pending, density) {
            (false, _) => UpdateStats::default(),
            (true, None) if !places.is_empty() => {
                // The lights' own buffers tile by tile; the shared layers'
                // sum (dense, every tile) made off the clock and added
                // before encoding (`render::layers`).
                let n = published.len();
                let shared: Vec<(Vec3, u64, &Arc<LightBuffer>)> =
                    lights[n..].iter().zip(&entries.buffers[n..]).map(|(l, (g, b))| (l.k, *g, b)).collect();
                let overlay = self.layer_sum.update(&shared);
                self.compositor.set_overlay(overlay);
                self.compositor.update_sharing(&lights[..n], &entries.buffers)
            }
            (true, None) => self.compositor.update_sharing(&lights, &entries.buffers),
            // In haze the knots are layers: a hazer change recombines them.
            (true, Some(_)) => self.compositor.update_layers(&layers, &entries.weights),
        };
        let intensity = inputs.iter().map(|input| luminance(input.k)).collect();
        let k = Arc::new(lights.iter().map(|l| l.k).collect());
        drop((layers, lights));
        let buffers = Arc::new(entries.buffers);
        let t_composite = t0.elapsed();
        let mut rgb = self.frame_rgb(gpu_rgb, &update);
        if let Some(bodies) = &mut self.bodies {
            // The body layer after Σ k_i buffer_i (CPU or GPU picture alike).
            let view = self.tracer.view();
            let (w, h) = (self.compositor.width(), self.compositor.height());
            let generation = self.tracer.view_generation();
            let display = self.compositor.display();
            rgb = bodies.apply(&view.gbuffer.camera, generation, w, h, &inputs, rgb, &display).0;
        }
        let body_tiles = self.bodies.as_ref().and_then(|b| b.tiles());
        let frame = Frame {
            number: self.number,
            width: self.compositor.width(),
            height: self.compositor.height(),
            rgb,
            intensity: Arc::new(intensity),
            composite_time: {
                let total = t0.elapsed();
                // A long tick keeps the build pool off the clock's core.
                self.tracer.clock_tick(total);
                if total > Duration::from_millis(20) {
                    tracing::debug!(
                        "slow frame {}: {:.1} ms (decode and entries {:.1}, composite {:.1}: {} tiles, {} changed)",
                        self.number,
                        total.as_secs_f64() * 1e3,
                        t_layers.as_secs_f64() * 1e3,
                        (t_composite - t_layers).as_secs_f64() * 1e3,
                        update.tiles,
                        update.changed_lights
                    );
                }
                total
            },
            update,
            k,
            buffers,
            haze_density: density,
            display: self.compositor.display(),
            preview: false,
            bodies: body_tiles,
        };
        self.number += 1;
        frame
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A light strobing at full keeps its build priority between flashes
    /// (its k_i is 0 then, but it is not dark); a closed shutter or a
    /// dimmer at 0 is dark.
    #[test]
    fn a_strobing_light_stays_lit_between_flashes() {
        let light = crate::Light::aimed(
            Vec3::new(0.0, 5.0, 0.0),
            Vec3::ZERO,
            crate::Beam::Spot(crate::fixture::SpotBeam::from_beam_field(20.0, 30.0)),
        );
        let input = |v: f32, shutter: f32, strobe: f32| LightInput {
            light: light.clone(),
            k: Vec3::splat(1000.0 * v),
            k_full: Vec3::splat(1000.0),
            state: FixtureState { v, shutter, strobe, ..FixtureState::default() },
        };
        let strobing = input(1.0, 1.0, 10.0);
        // 10 Hz: at t = 0.09 s the flash of the period is over.
        assert_eq!(strobing.state.shutter_at(0.09), 0.0, "between flashes");
        let steady = build_priority(&input(1.0, 1.0, 0.0));
        assert!(steady > 0.0);
        assert_eq!(build_priority(&strobing), steady, "strobing at full is as lit as steady at full");
        assert_eq!(build_priority(&input(1.0, 0.0, 0.0)), 0.0, "shutter closed: dark");
        assert_eq!(build_priority(&input(0.0, 1.0, 10.0)), 0.0, "dimmer at 0: dark");
        assert!(build_priority(&input(0.5, 1.0, 0.0)) < steady, "brighter first");
    }
}
