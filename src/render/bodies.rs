//! Fixture bodies in the picture (issue 14 item 5), as a separate layer.
//!
//! Bodies never enter the light buffers' geometry: a moving head that moved
//! would otherwise change the scene every light is traced against and
//! rebuild all of them. Instead each body is ray-cast against the view into
//! a per-view [`BodyLayer`] (depth, normal, body index, lens or housing),
//! depth-tested against the stage's primary hit along the same pixel ray,
//! and shaded on its own:
//!
//! * the housing: a fixed dim work light, L = ρ_body/π · E_work
//!   ([`BODY_ALBEDO`], [`WORK_LIGHT_LUX`], both estimated), so bodies are
//!   visible in a dark rig;
//! * the lens face: it emits the fixture's own light, L = k_i · f(θ) /
//!   (π r² · cos θ_lens): the intensity toward the camera (k_i · f, cd)
//!   over the lens disc's apparent area (cos θ_lens floored at 0.05, a lens
//!   seen edge-on). k_i is the light's current composite factor (eq. 4), so
//!   dimmer/colour/strobe changes stay a composite-only update of the layer.
//!
//! Bodies cast no shadows and receive no stage light (they are not in the
//! scene the lights are traced against). Each body is a box ([`Body::size`];
//! `render --bodies` uses the estimated [`BODY_SIZE`]: the GDTF model's own
//! dimensions and mesh are not read yet), its lens at the light's position on the beam axis,
//! the housing behind it, posed by the light's current rotation (pan/tilt).
//!
//! Cost: a body touches only the pixels inside the screen rectangle of its
//! bounding sphere ([`BodyLayer::redraw`] re-tests that rectangle, old and
//! new, against the bodies overlapping it), so a moving head costs its own
//! footprint, not a rebuild of any light buffer. Built for stills
//! (`footlight render --bodies`); the live daemon, the GPU compositor and the
//! browser stream do not show the layer yet.

use crate::fixture::Light;
use crate::scene::{Camera, Scene};
use glam::{Vec3, Vec3Swizzles};

/// Body box, metres: width (light-local x), height (local y), length behind
/// the lens (local +z; the beam leaves along −z). Estimated: a mid-size
/// moving head's head.
pub const BODY_SIZE: Vec3 = Vec3::new(0.35, 0.35, 0.45);

/// Lens radius, metres (estimated: the test GDTF types' BeamRadius is 0.075 m).
pub const LENS_RADIUS: f32 = 0.075;

/// Housing albedo (estimated: matte black paint).
pub const BODY_ALBEDO: f32 = 0.05;

/// Illuminance of the fixed work light on every housing face, lux (estimated).
pub const WORK_LIGHT_LUX: f32 = 20.0;

/// One fixture body: the light it belongs to, its current k_i and its box.
#[derive(Clone, Debug)]
pub struct Body {
    /// The light (position = lens centre, rotation = current pan/tilt).
    pub light: Light,
    /// k_i now (eq. 4): the lens glow's colour and level.
    pub k: Vec3,
    /// Box size: width (light-local x), height (y), length behind the lens (+z), metres.
    pub size: Vec3,
    /// Lens disc radius, metres.
    pub lens_radius: f32,
}

impl Body {
    /// The estimated primitive body ([`BODY_SIZE`], [`LENS_RADIUS`]) of a light.
    pub fn primitive(light: Light, k: Vec3) -> Self {
        Self { light, k, size: BODY_SIZE, lens_radius: LENS_RADIUS }
    }
}

/// What a pixel of the body layer sees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyHit {
    /// Distance along the pixel ray, metres.
    pub depth: f32,
    /// World normal of the face hit (toward the camera).
    pub normal: Vec3,
    /// Index of the body.
    pub body: u32,
    /// True on the lens disc.
    pub lens: bool,
}

/// The per-view body layer: one optional hit per pixel (pixel centres).
pub struct BodyLayer {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Row-major hits, nearest body in front of the stage.
    pub hits: Vec<Option<BodyHit>>,
    /// Each body's pixel rectangle (x0, y0, x1, y1), exclusive ends.
    rects: Vec<(u32, u32, u32, u32)>,
}

impl BodyLayer {
    /// Ray-casts every body into an empty layer.
    pub fn build(scene: &Scene, camera: &Camera, width: u32, height: u32, bodies: &[Body]) -> Self {
        let mut layer = Self { width, height, hits: vec![None; (width * height) as usize], rects: Vec::new() };
        layer.rects = bodies.iter().map(|b| footprint(camera, width, height, b)).collect();
        for i in 0..bodies.len() {
            let r = layer.rects[i];
            layer.retest(scene, camera, bodies, r);
        }
        layer
    }

    /// Body `i` moved (its light's rotation or position changed): only the
    /// pixels of its old and new rectangles are tested again.
    pub fn redraw(&mut self, scene: &Scene, camera: &Camera, bodies: &[Body], i: usize) {
        let Some(&old) = self.rects.get(i) else { return };
        let new = footprint(camera, self.width, self.height, &bodies[i]);
        self.rects[i] = new;
        self.retest(scene, camera, bodies, old);
        self.retest(scene, camera, bodies, new);
    }

    /// Pixels tested by the last build or redraw of body `i` (its rectangle's area).
    pub fn footprint_pixels(&self, i: usize) -> u64 {
        self.rects.get(i).map_or(0, |&(x0, y0, x1, y1)| u64::from(x1 - x0) * u64::from(y1 - y0))
    }

    fn retest(&mut self, scene: &Scene, camera: &Camera, bodies: &[Body], r: (u32, u32, u32, u32)) {
        let overlapping: Vec<usize> = (0..bodies.len()).filter(|&j| overlaps(self.rects[j], r)).collect();
        for y in r.1..r.3 {
            for x in r.0..r.2 {
                let dir = camera.direction(x as f32 + 0.5, y as f32 + 0.5, self.width, self.height);
                let stage = scene.accel.intersect(camera.position, dir, f32::INFINITY).map_or(f32::INFINITY, |h| h.t);
                let mut best: Option<BodyHit> = None;
                for &j in &overlapping {
                    if let Some(hit) = cast(&bodies[j], camera.position, dir)
                        && hit.0 < stage
                        && best.is_none_or(|b| hit.0 < b.depth)
                    {
                        best = Some(BodyHit { depth: hit.0, normal: hit.1, body: j as u32, lens: hit.2 });
                    }
                }
                self.hits[(y * self.width + x) as usize] = best;
            }
        }
    }

    /// Radiance of every body pixel (cd/m², linear RGB), `None` where the
    /// stage shows: housing work light plus the lens glow with each body's k_i.
    pub fn shade(&self, camera: &Camera, bodies: &[Body]) -> Vec<Option<Vec3>> {
        let housing = Vec3::splat(BODY_ALBEDO * std::f32::consts::FRAC_1_PI * WORK_LIGHT_LUX);
        let mut out = Vec::with_capacity(self.hits.len());
        for (i, hit) in self.hits.iter().enumerate() {
            let Some(h) = hit else {
                out.push(None);
                continue;
            };
            let b = &bodies[h.body as usize];
            let mut l = housing;
            if h.lens {
                let (x, y) = (i as u32 % self.width, i as u32 / self.width);
                let to_camera = -camera.direction(x as f32 + 0.5, y as f32 + 0.5, self.width, self.height);
                let cos_lens = to_camera.dot(b.light.axis()).max(0.05);
                let intensity = b.k * b.light.pattern_toward(to_camera);
                l += intensity / (std::f32::consts::PI * b.lens_radius * b.lens_radius * cos_lens);
            }
            out.push(Some(l));
        }
        out
    }

    /// Overwrites the body pixels of a linear picture (`width × height`).
    pub fn overlay(&self, camera: &Camera, bodies: &[Body], linear: &mut [Vec3]) {
        for (px, l) in linear.iter_mut().zip(self.shade(camera, bodies)) {
            if let Some(l) = l {
                *px = l;
            }
        }
    }
}

fn overlaps(a: (u32, u32, u32, u32), b: (u32, u32, u32, u32)) -> bool {
    a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3
}

/// The body's box in light-local coordinates: x, y ±half size, z from 0 (lens) to the length.
fn local_box(size: Vec3) -> (Vec3, Vec3) {
    let h = size.xy() * 0.5;
    (Vec3::new(-h.x, -h.y, 0.0), Vec3::new(h.x, h.y, size.z))
}

/// Nearest hit of a ray with a body: (t, world normal, lens?).
fn cast(body: &Body, origin: Vec3, dir: Vec3) -> Option<(f32, Vec3, bool)> {
    let light = &body.light;
    let inv = light.rotation.inverse();
    let o = inv * (origin - light.position);
    let d = inv * dir;
    let (lo, hi) = local_box(body.size);
    let (mut t0, mut t1, mut axis) = (0.0f32, f32::INFINITY, usize::MAX);
    for k in 0..3 {
        if d[k].abs() < 1e-12 {
            if o[k] < lo[k] || o[k] > hi[k] {
                return None;
            }
            continue;
        }
        let (a, b) = ((lo[k] - o[k]) / d[k], (hi[k] - o[k]) / d[k]);
        let (near, far) = if a < b { (a, b) } else { (b, a) };
        if near > t0 {
            t0 = near;
            axis = k;
        }
        t1 = t1.min(far);
        if t0 > t1 {
            return None;
        }
    }
    if axis == usize::MAX || !t0.is_finite() {
        return None; // the camera is inside the body
    }
    let mut n = Vec3::ZERO;
    n[axis] = -d[axis].signum();
    let p = o + d * t0;
    // The lens: the z = 0 face (facing −z, the beam side), inside the lens radius.
    let lens = axis == 2 && n.z < 0.0 && p.xy().length() <= body.lens_radius;
    Some((t0, light.rotation * n, lens))
}

/// A conservative pixel rectangle around the body's bounding sphere (the
/// whole image when the sphere reaches behind the camera).
fn footprint(camera: &Camera, width: u32, height: u32, body: &Body) -> (u32, u32, u32, u32) {
    let light = &body.light;
    let centre = light.position + light.rotation * Vec3::new(0.0, 0.0, body.size.z * 0.5);
    let radius = (body.size * 0.5).length() + 1e-3;
    let rel = camera.basis.transpose() * (centre - camera.position);
    let depth = -rel.z;
    let all = (0, 0, width, height);
    if depth <= radius * 1.01 || !depth.is_finite() {
        return all;
    }
    let tan_half = (camera.yfov * 0.5).tan();
    let aspect = width as f32 / height.max(1) as f32;
    let ndc = |v: f32, scale: f32| v / (depth * tan_half * scale);
    let cx = (ndc(rel.x, aspect) + 1.0) * 0.5 * width as f32;
    let cy = (1.0 - ndc(rel.y, 1.0)) * 0.5 * height as f32;
    // Angular radius of the sphere, as pixels at the image centre's scale, with margin for the off-axis stretch.
    let ang = (radius / depth).asin();
    let pr = ang.tan() / tan_half * 0.5 * height as f32 * 1.5 + 2.0;
    let cl = |v: f32, n: u32| v.clamp(0.0, n as f32) as u32;
    let r = (cl(cx - pr, width), cl(cy - pr, height), cl(cx + pr + 1.0, width), cl(cy + pr + 1.0, height));
    if r.0 >= r.2 || r.1 >= r.3 { (0, 0, 0, 0) } else { r }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixture::{Beam, SpotBeam};
    use crate::scene::{Material, SceneBuilder};

    fn floor_scene() -> Scene {
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::lambert("floor", Vec3::splat(0.5)));
        b.add_quad(
            Vec3::new(-20.0, 0.0, 20.0),
            Vec3::new(20.0, 0.0, 20.0),
            Vec3::new(20.0, 0.0, -20.0),
            Vec3::new(-20.0, 0.0, -20.0),
            m,
        );
        b.build()
    }

    #[test]
    fn a_head_facing_the_camera_shows_its_lens_and_housing() {
        let scene = floor_scene();
        let cam = Camera::look_at(Vec3::new(0.0, 3.0, 6.0), Vec3::new(0.0, 3.0, 0.0), 30f32.to_radians());
        // A 20°/30° spot at (0, 3, 0) aimed at the camera: the lens faces it.
        let light =
            Light::aimed(Vec3::new(0.0, 3.0, 0.0), cam.position, Beam::Spot(SpotBeam::from_beam_field(20.0, 30.0)));
        let bodies = [Body::primitive(light, Vec3::new(100.0, 50.0, 25.0))];
        let (w, h) = (101, 101);
        let layer = BodyLayer::build(&scene, &cam, w, h, &bodies);
        let centre = layer.hits[(50 * w + 50) as usize].expect("the lens at the image centre");
        assert!(centre.lens && (centre.depth - 6.0).abs() < 1e-4, "{centre:?}");
        // On axis: L = k / (π r²) plus the housing term, per channel.
        let shaded = layer.shade(&cam, &bodies)[(50 * w + 50) as usize].unwrap();
        let housing = BODY_ALBEDO / std::f32::consts::PI * WORK_LIGHT_LUX;
        let want = bodies[0].k / (std::f32::consts::PI * LENS_RADIUS * LENS_RADIUS) + Vec3::splat(housing);
        assert!((shaded - want).abs().max_element() <= 1e-3 * want.max_element(), "{shaded} vs {want}");
        // The box's apparent half width: 0.175 m at 6 m with a 30° field over 101 px.
        let px_per_m = 101.0 / (2.0 * 6.0 * (15f32.to_radians()).tan());
        let half = (0.175 * px_per_m) as u32;
        assert!(layer.hits[(50 * w + 50 + half - 1) as usize].is_some_and(|h| !h.lens));
        assert!(layer.hits[(50 * w + 50 + half + 2) as usize].is_none());
        // Only the body's own rectangle was tested.
        assert!(layer.footprint_pixels(0) < u64::from(w * h) / 4, "{}", layer.footprint_pixels(0));
    }

    #[test]
    fn bodies_behind_the_stage_are_hidden_and_a_redraw_follows_the_move() {
        let scene = floor_scene();
        let cam = Camera::look_at(Vec3::new(0.0, 5.0, 8.0), Vec3::ZERO, 40f32.to_radians());
        let beam = Beam::Spot(SpotBeam::from_beam_field(20.0, 30.0));
        // One body under the floor (hidden by the depth test), one above it.
        let mut bodies = vec![
            Body::primitive(Light::aimed(Vec3::new(0.0, -1.0, 0.0), Vec3::ZERO, beam.clone()), Vec3::ONE),
            Body::primitive(Light::aimed(Vec3::new(2.0, 1.0, 0.0), Vec3::new(2.0, 0.0, 0.0), beam), Vec3::ONE),
        ];
        let (w, h) = (120, 80);
        let mut layer = BodyLayer::build(&scene, &cam, w, h, &bodies);
        assert!(layer.hits.iter().flatten().all(|h| h.body == 1));
        let count = |l: &BodyLayer| l.hits.iter().flatten().count();
        let before = count(&layer);
        assert!(before > 10, "{before}");
        // Move body 1 across the stage: a redraw of body 1 alone equals a full rebuild.
        bodies[1].light.position = Vec3::new(-2.0, 1.0, 1.0);
        layer.redraw(&scene, &cam, &bodies, 1);
        let fresh = BodyLayer::build(&scene, &cam, w, h, &bodies);
        assert_eq!(layer.hits, fresh.hits);
        assert!(count(&layer) > 10);
    }
}
