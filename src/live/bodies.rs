//! Fixture bodies in the live picture (issue 14 item 5): the body layer
//! ([`crate::render::bodies`]) over each frame's composite Σ k_i · buffer_i,
//! in the CPU and the GPU compositor alike (it is written over the frame's
//! 8-bit sRGB through the same display encoding).
//!
//! Per frame ([`LiveBodies::apply`]):
//! * a body whose driver light moved (position, rotation, pan or tilt
//!   changed) is re-posed and [`BodyLayer::redraw`] re-tests only its old and
//!   new pixel rectangles; no light is rebuilt (bodies are not in the traced
//!   scene), so a moving head costs its own footprint;
//! * a camera change (a new view generation) re-casts the whole layer;
//! * the layer's pixels are then shaded with this frame's k_i (lens glow) and
//!   written over a copy of the composite; when neither the composite, the
//!   k_i nor any body changed, the last picture is shared again.
//!
//! The moving-camera preview shows no bodies (it is not a composite).
//!
//! For the browser stream the layer is also kept as 16×16 tiles of
//! [`BodyPixel`]s ([`BodyTiles`], shared with every [`crate::output::Frame`]): each
//! pixel's housing radiance and lens glow per unit k_i, so the browser
//! multiplies by the frame's k_i itself (a dimmer change sends no body
//! bytes). A tile gets a new revision only when its pixels changed: a moved
//! body's old and new rectangles, a body whose lens light changed beam
//! (zoom, gobo: the glow's pattern toward the camera), or the whole layer
//! after a camera change. The stream sends the tiles whose revision a client
//! has not seen (docs/stream.md, message type 6).

use super::clock::LightInput;
use crate::fixture::Light;
use crate::output::{BodyTile, BodyTiles};
use crate::render::Display;
use crate::render::bodies::{Body, BodyLayer, BodyModel, Rect};
use crate::render::buffer::TILE;
use crate::scene::{Camera, Scene};
use glam::{Quat, Vec3};
use std::sync::Arc;

/// What one frame's body pass did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BodyUpdate {
    /// Bodies re-posed and redrawn this frame.
    pub moved: usize,
    /// Pixels ray-tested this frame (old and new rectangles of the moved bodies).
    pub pixels_tested: u64,
    /// True when the whole layer was cast again (first frame, camera change).
    pub rebuilt: bool,
}

/// The last composite in, the k_i it was shaded with, the picture out.
type LastPicture = (Arc<Vec<u8>>, Vec<Vec3>, Arc<Vec<u8>>);

/// A driver light's pose: what moves a body.
type PoseKey = (Vec3, Quat, f32, f32);

/// The live body layer and what it was drawn from.
pub struct LiveBodies {
    models: Vec<BodyModel>,
    scene: Arc<Scene>,
    bodies: Vec<Body>,
    keys: Vec<PoseKey>,
    layer: Option<(u64, Camera, BodyLayer)>,
    /// The last composite in, the k_i shaded with, and the picture out.
    last: Option<LastPicture>,
    /// Totals since start: bodies redrawn, pixels tested.
    pub totals: BodyUpdate,
    /// The layer as stream tiles, and the last revision handed out.
    tiles: Option<Arc<BodyTiles>>,
    revision: u64,
    /// Each light as the tiles' glow was computed with.
    glow_lights: Vec<Light>,
}

impl LiveBodies {
    /// Bodies of `models` (one per fixture, [`crate::render::bodies::body_models`]) on `scene`.
    pub fn new(models: Vec<BodyModel>, scene: Arc<Scene>) -> Self {
        Self {
            models,
            scene,
            bodies: Vec::new(),
            keys: Vec::new(),
            layer: None,
            last: None,
            totals: BodyUpdate::default(),
            tiles: None,
            revision: 0,
            glow_lights: Vec::new(),
        }
    }

    /// Number of bodies.
    pub fn len(&self) -> usize {
        self.models.len()
    }

    /// True without bodies.
    pub fn is_empty(&self) -> bool {
        self.models.is_empty()
    }

    /// Body `i`'s pixel rectangle in the current layer.
    pub fn rect(&self, i: usize) -> Option<Rect> {
        self.layer.as_ref().and_then(|(_, _, l)| l.rect(i))
    }

    /// The layer as stream tiles after the last [`LiveBodies::apply`]
    /// (`None` before the first); a new `Arc` whenever a tile changed.
    pub fn tiles(&self) -> Option<Arc<BodyTiles>> {
        self.tiles.clone()
    }

    /// Recomputes the stream tiles overlapping `dirty` (all of them when
    /// `all`); a tile whose pixels came out the same keeps its revision.
    fn update_tiles(&mut self, lights: &[Light], dirty: &[Rect], all: bool) {
        let Some((_, camera, layer)) = &self.layer else { return };
        let (w, h) = (layer.width, layer.height);
        let (tx, ty) = ((w as usize).div_ceil(TILE), (h as usize).div_ceil(TILE));
        let reset = self.tiles.as_ref().is_none_or(|t| t.width != w || t.height != h);
        let mut tiles = match &self.tiles {
            Some(t) if !reset => t.tiles.clone(),
            _ => {
                // One shared empty tile: tiles are replaced, never changed in place.
                let empty = Arc::new(BodyTile { revision: 0, pixels: vec![None; TILE * TILE] });
                std::iter::repeat_n(empty, tx * ty).collect()
            }
        };
        let mut todo = vec![reset || all; tx * ty];
        for r in dirty {
            let t = TILE as u32;
            for y in r.1 / t..r.3.div_ceil(t).min(ty as u32) {
                for x in r.0 / t..r.2.div_ceil(t).min(tx as u32) {
                    todo[y as usize * tx + x as usize] = true;
                }
            }
        }
        let mut changed = false;
        for (i, _) in todo.iter().enumerate().filter(|(_, d)| **d) {
            let (x0, y0) = ((i % tx * TILE) as u32, (i / tx * TILE) as u32);
            let mut pixels = vec![None; TILE * TILE];
            for (j, p) in pixels.iter_mut().enumerate() {
                let (x, y) = (x0 + (j % TILE) as u32, y0 + (j / TILE) as u32);
                if x < w && y < h {
                    *p = layer.pixel((y * w + x) as usize, camera, &self.bodies, lights);
                }
            }
            if pixels != tiles[i].pixels {
                self.revision += 1;
                tiles[i] = Arc::new(BodyTile { revision: self.revision, pixels });
                changed = true;
            }
        }
        if changed || self.tiles.is_none() {
            self.tiles = Some(Arc::new(BodyTiles { width: w, height: h, lights: lights.len() as u32, tiles }));
        }
        self.glow_lights = lights.to_vec();
    }

    fn key(input: &LightInput) -> PoseKey {
        (input.light.position, input.light.rotation, input.state.pan, input.state.tilt)
    }

    /// Updates the layer for this frame's lights (camera `camera` of view
    /// generation `generation`, `width × height`) and writes it over
    /// `composite` (8-bit sRGB from `display`). Returns the picture and what
    /// was done.
    #[allow(clippy::too_many_arguments)]
    pub fn apply(
        &mut self,
        camera: &Camera,
        generation: u64,
        width: u32,
        height: u32,
        inputs: &[LightInput],
        composite: Arc<Vec<u8>>,
        display: &Display,
    ) -> (Arc<Vec<u8>>, BodyUpdate) {
        let mut update = BodyUpdate::default();
        let pose = |m: &BodyModel| {
            let i = &inputs[m.driver.min(inputs.len().saturating_sub(1))];
            (Self::key(i), m.pose(&i.light, i.state.pan, i.state.tilt))
        };
        if inputs.is_empty() || self.models.iter().any(|m| m.driver >= inputs.len()) {
            return (composite, update);
        }
        let mut dirty: Vec<Rect> = Vec::new();
        let stale =
            !matches!(&self.layer, Some((g, _, l)) if *g == generation && l.width == width && l.height == height);
        if stale {
            (self.keys, self.bodies) = self.models.iter().map(pose).unzip();
            let layer = BodyLayer::build(&self.scene, camera, width, height, &self.bodies);
            update.pixels_tested = (0..self.bodies.len()).map(|i| layer.footprint_pixels(i)).sum();
            update.moved = self.bodies.len();
            update.rebuilt = true;
            self.layer = Some((generation, *camera, layer));
            self.last = None;
        } else if let Some((_, camera, layer)) = &mut self.layer {
            for (b, m) in self.models.iter().enumerate() {
                let key = Self::key(&inputs[m.driver]);
                if key != self.keys[b] {
                    self.keys[b] = key;
                    self.bodies[b] = m.pose(&inputs[m.driver].light, key.2, key.3);
                    dirty.extend(layer.rect(b));
                    update.pixels_tested += layer.redraw(&self.scene, camera, &self.bodies, b);
                    dirty.extend(layer.rect(b));
                    update.moved += 1;
                }
            }
        }
        let lights: Vec<Light> = inputs.iter().map(|i| i.light.clone()).collect();
        // A lens whose light changed beam (zoom, gobo) without moving: its glow tiles again.
        if !update.rebuilt && self.glow_lights.len() == lights.len() {
            for (b, body) in self.bodies.iter().enumerate() {
                let beam_changed = body
                    .parts
                    .iter()
                    .filter_map(|p| p.glow)
                    .any(|(l, _)| l < lights.len() && lights[l] != self.glow_lights[l]);
                if beam_changed && let Some(r) = self.rect(b) {
                    dirty.push(r);
                }
            }
        }
        if update.rebuilt || !dirty.is_empty() || self.glow_lights.len() != lights.len() {
            self.update_tiles(&lights, &dirty, update.rebuilt);
        }
        self.totals.moved += update.moved;
        self.totals.pixels_tested += update.pixels_tested;
        let k: Vec<Vec3> = inputs.iter().map(|i| i.k).collect();
        if update.moved == 0
            && let Some((c, last_k, out)) = &self.last
            && Arc::ptr_eq(c, &composite)
            && *last_k == k
        {
            return (out.clone(), update);
        }
        let Some(tiles) = &self.tiles else { return (composite, update) };
        let mut rgb = composite.as_ref().clone();
        overlay_tiles(tiles, &k, display, &mut rgb);
        let out = Arc::new(rgb);
        self.last = Some((composite, k, out.clone()));
        (out, update)
    }
}

/// Overwrites the body pixels of an 8-bit sRGB picture with the layer's
/// stream tiles at this frame's k_i (base + k_light · glow per pixel,
/// [`crate::render::bodies::BodyPixel::radiance`]), through `display`.
/// The tiles hold each body pixel's base and glow, worked out when a body
/// moved or its beam changed ([`LiveBodies::update_tiles`]), so a frame
/// costs one multiply-add per body pixel instead of casting the camera ray
/// and the lens pattern again (equal to [`BodyLayer::overlay_srgb8`]: the
/// same pixels, the same k; the festival show's 146 bodies took 10 % of the
/// daemon's CPU that way while strobing lights changed k every frame).
/// Returns the pixels written.
fn overlay_tiles(tiles: &BodyTiles, k: &[Vec3], display: &Display, rgb: &mut [u8]) -> usize {
    let (w, h) = (tiles.width as usize, tiles.height as usize);
    let tiles_x = w.div_ceil(TILE);
    let (at, linear): (Vec<usize>, Vec<Vec3>) = tiles
        .tiles
        .iter()
        .enumerate()
        .filter(|(_, tile)| !tile.is_empty())
        .flat_map(|(t, tile)| {
            let (x0, y0) = (t % tiles_x * TILE, t / tiles_x * TILE);
            tile.pixels.iter().enumerate().filter_map(move |(j, p)| {
                let (x, y) = (x0 + j % TILE, y0 + j / TILE);
                let p = p.as_ref().filter(|_| x < w && y < h)?;
                Some((y * w + x, p.radiance(k)))
            })
        })
        .filter(|(i, _)| 3 * i + 3 <= rgb.len())
        .unzip();
    let encoded = display.to_srgb8(&linear);
    for (&i, px) in at.iter().zip(encoded.chunks_exact(3)) {
        rgb[3 * i..3 * i + 3].copy_from_slice(px);
    }
    at.len()
}
