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

use super::clock::LightInput;
use crate::fixture::Light;
use crate::render::Display;
use crate::render::bodies::{Body, BodyLayer, BodyModel, Rect};
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
                    update.pixels_tested += layer.redraw(&self.scene, camera, &self.bodies, b);
                    update.moved += 1;
                }
            }
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
        let Some((_, camera, layer)) = &self.layer else { return (composite, update) };
        let lights: Vec<Light> = inputs.iter().map(|i| i.light.clone()).collect();
        let mut rgb = composite.as_ref().clone();
        layer.overlay_srgb8(camera, &self.bodies, &lights, &k, display, &mut rgb);
        let out = Arc::new(rgb);
        self.last = Some((composite, k, out.clone()));
        (out, update)
    }
}
