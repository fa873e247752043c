//! What sits in a profile spot's gate: a gobo, four framing-shutter blades,
//! a prism and a frost filter (issue 14, GDTF `Gobo1…`, `Blade…`,
//! `ShaperRot`, `Prism1…`, `Frost1`), as a [`ShapedBeam`] around a
//! [`SpotBeam`].
//!
//! # Gate coordinates
//! A local direction `d` (beam along −Z) meets the gate plane at
//! `p = (d.x, d.y) / (−d.z) / tan(outer)`, where `outer` is the open spot's
//! cut-off half-angle: the spot's cone is the unit disc `|p| ≤ 1`, gate +x
//! is the light's local +X and gate +y its local +Y. The mapping is the
//! ideal pin-hole projection, so a straight edge in the gate is a plane
//! through the light, and on a flat floor a straight line. The image is not
//! mirrored by a lens: everything is described as seen looking along the
//! beam.
//!
//! * **Gobo** ([`GoboImage`]): the slot's greyscale image (GDTF `wheels/`,
//!   255 = light passes) spans the square `[−1, 1]²` (row 0 at gate +y),
//!   sampled bilinearly, clamped to its border; `gobo_angle` (degrees)
//!   turns it counter-clockwise about the axis.
//! * **More image layers** ([`GoboLayer`]: a second gobo wheel, an
//!   animation wheel): each is sampled like the gobo at its own angle and
//!   the transmissions multiply (two discs in series). An animation wheel
//!   is approximated as such a layer centred on the axis (a real one sits
//!   off-axis near a focal plane and slides across the gate as it turns).
//! * **Blades** ([`Blade`]): blade 1 enters from gate +y, 2 from +x, 3 from
//!   −y, 4 from −x. Insertion `a` and `b` (fractions of the gate diameter,
//!   0 = at the rim, 1 = across to the opposite rim) place the blade's two
//!   ends (`a` on the counter-clockwise side); `rot` (degrees) turns the edge
//!   about its midpoint; the whole assembly turns by `shaper_rot`. Light on
//!   the blade's side of its edge is cut: `f_ε = 0` exactly.
//! * **Prism** ([`Facet`]): each facet images the whole gate (gobo and
//!   blades included) turned by the facet's angle and shifted by its
//!   offset (gate units); `prism_angle` turns the set. The facets share the
//!   light: the pattern is the facets' mean, scaled so that the flux
//!   ∫f_ε dω equals the un-prismed gate's (a prism moves light, it does not
//!   absorb it).
//! * **Frost** (0..1): widens the spot's penumbra (outer half-angle × (1 +
//!   [`FROST_WIDEN`] · frost), core × (1 − [`FROST_WIDEN`] · frost)) and
//!   blurs the gobo (box blur of [`FROST_BLUR`] · frost gate radii); the
//!   pattern is scaled so the flux equals the un-frosted gate's. The blade
//!   cuts stay hard (estimated simplification: real frost softens them too).
//!
//! Gobo and blades absorb light, so the flux ∫f_ε dω ([`ShapedBeam::solid_angle`])
//! drops with them at the same Î: photon emission and direct light agree
//! because both read [`ShapedBeam::pattern`]. The flux normalisation and
//! the blurred gobo are computed on first use (2-D quadrature, a few ms)
//! and cached, so building a [`ShapedBeam`] per frame (the daemon decodes
//! every fixture every frame) costs nothing until a light is rebuilt.

use super::SpotBeam;
use glam::{Vec2, Vec3};
use std::sync::{Arc, OnceLock};

/// Penumbra widening at full frost (estimated: a light frost roughly
/// doubles the soft edge of a profile; GDTF gives no frost optics).
pub const FROST_WIDEN: f32 = 0.5;
/// Gobo blur radius at full frost, in gate radii (estimated).
pub const FROST_BLUR: f32 = 0.12;
/// Offset of a facet whose GDTF matrix has no translation, in gate radii
/// along the facet's rotated +x (estimated: most real files give rotation
/// only, and visualisers choose their own spread).
pub const PRISM_SPREAD: f32 = 0.7;
/// A gate's key ([`ShapedBeam`]'s parameters as bits) and its (scale, flux).
type NormEntry = (Vec<u32>, (f32, f32));
/// Distinct gates whose flux normalisation is kept process-wide.
const NORM_CACHE: usize = 64;
/// Widest open cone a gate is applied to (half-angle, radians): the gate
/// mapping uses tan of the half-angle.
pub const MAX_GATE_HALF_ANGLE: f32 = 1.45;

/// A gobo: transmission 0..1 on a `width` × `height` grid (row 0 at gate +y).
#[derive(Clone, Debug, PartialEq)]
pub struct GoboImage {
    /// The slot or media name, for messages.
    pub name: String,
    width: usize,
    height: usize,
    texels: Vec<f32>,
}

impl GoboImage {
    /// From 8-bit luminance rows (255 = light passes); `None` for an empty
    /// image or a size that does not match the data.
    pub fn from_luma8(name: impl Into<String>, width: usize, height: usize, luma: &[u8]) -> Option<Self> {
        if width == 0 || height == 0 || width.checked_mul(height)? != luma.len() {
            return None;
        }
        let texels = luma.iter().map(|&v| f32::from(v) / 255.0).collect();
        Some(Self { name: name.into(), width, height, texels })
    }

    /// Width and height in texels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn texel(&self, x: isize, y: isize) -> f32 {
        let x = x.clamp(0, self.width as isize - 1) as usize;
        let y = y.clamp(0, self.height as isize - 1) as usize;
        self.texels[y * self.width + x]
    }

    /// Transmission at gate point `p` (the image spans [−1, 1]²), bilinear,
    /// clamped to the border.
    pub fn sample(&self, p: Vec2) -> f32 {
        if !p.is_finite() {
            return 0.0;
        }
        let fx = (p.x.clamp(-2.0, 2.0) + 1.0) * 0.5 * self.width as f32 - 0.5;
        let fy = (1.0 - p.y.clamp(-2.0, 2.0)) * 0.5 * self.height as f32 - 0.5;
        let (x0, y0) = (fx.floor(), fy.floor());
        let (tx, ty) = (fx - x0, fy - y0);
        let (x0, y0) = (x0 as isize, y0 as isize);
        let top = self.texel(x0, y0) * (1.0 - tx) + self.texel(x0 + 1, y0) * tx;
        let bottom = self.texel(x0, y0 + 1) * (1.0 - tx) + self.texel(x0 + 1, y0 + 1) * tx;
        top * (1.0 - ty) + bottom * ty
    }

    /// The image box-blurred (separable, clamped border) by `radius` gate radii.
    pub fn blurred(&self, radius: f32) -> Self {
        let rx = (radius * 0.5 * self.width as f32).round() as isize;
        let ry = (radius * 0.5 * self.height as f32).round() as isize;
        if !(rx > 0 || ry > 0) {
            return self.clone();
        }
        let (w, h) = (self.width as isize, self.height as isize);
        let mut pass = vec![0.0; self.texels.len()];
        for y in 0..h {
            for x in 0..w {
                let sum: f32 = (-rx..=rx).map(|d| self.texel(x + d, y)).sum();
                pass[(y * w + x) as usize] = sum / (2 * rx + 1) as f32;
            }
        }
        let first = Self { texels: pass, ..self.clone() };
        let mut out = vec![0.0; self.texels.len()];
        for y in 0..h {
            for x in 0..w {
                let sum: f32 = (-ry..=ry).map(|d| first.texel(x, y + d)).sum();
                out[(y * w + x) as usize] = sum / (2 * ry + 1) as f32;
            }
        }
        Self { texels: out, ..self.clone() }
    }
}

/// One framing-shutter blade (see the module doc for the frame).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Blade {
    /// Insertion of the counter-clockwise end, fraction of the gate diameter (0 out).
    pub a: f32,
    /// Insertion of the clockwise end.
    pub b: f32,
    /// Turn of the edge about its midpoint, degrees.
    pub rot: f32,
}

/// One prism facet: the gate's image turned by `rotation` (radians) and
/// shifted by `offset` (gate radii).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Facet {
    /// Turn of the facet's image about the axis, radians.
    pub rotation: f32,
    /// Shift of the facet's image in the gate plane, gate radii.
    pub offset: Vec2,
}

impl Facet {
    /// A facet from a GDTF `Rotation` matrix (rows as written): the turn
    /// from its first column, the shift from its third column; a matrix
    /// with no shift gets [`PRISM_SPREAD`] along the turned +x.
    pub fn from_gdtf(rows: [[f64; 3]; 3]) -> Self {
        let rotation = (rows[1][0] as f32).atan2(rows[0][0] as f32);
        let rotation = if rotation.is_finite() { rotation } else { 0.0 };
        let shift = Vec2::new(rows[0][2] as f32, rows[1][2] as f32);
        let offset =
            if shift.is_finite() && shift.length() > 1e-6 { shift } else { Vec2::from_angle(rotation) * PRISM_SPREAD };
        Self { rotation, offset }
    }
}

/// Everything in the gate, in real units (see the module doc).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Gate {
    /// The gobo in the beam (`None`: open slot).
    pub gobo: Option<Arc<GoboImage>>,
    /// Gobo rotation, degrees counter-clockwise.
    pub gobo_angle: f32,
    /// The four blades (1: +y, 2: +x, 3: −y, 4: −x).
    pub blades: [Blade; 4],
    /// Rotation of the blade assembly, degrees.
    pub shaper_rot: f32,
    /// Prism facets (empty: no prism in the beam).
    pub facets: Vec<Facet>,
    /// Prism rotation, degrees.
    pub prism_angle: f32,
    /// Frost 0 (none) .. 1 (full).
    pub frost: f32,
    /// Further image layers in series with the gobo (a second gobo wheel,
    /// an animation wheel): their transmissions multiply.
    pub layers: Vec<GoboLayer>,
}

/// One more image in the gate (see the module doc): sampled like the gobo.
#[derive(Clone, Debug, PartialEq)]
pub struct GoboLayer {
    /// The image (255 = light passes).
    pub image: Arc<GoboImage>,
    /// Rotation, degrees counter-clockwise.
    pub angle: f32,
}

impl Gate {
    /// True when the gate changes nothing (open gobo, blades out, no prism, no frost).
    pub fn is_open(&self) -> bool {
        self.gobo.is_none()
            && self.layers.is_empty()
            && self.blades.iter().all(|b| !(b.a > 0.0) && !(b.b > 0.0))
            && self.facets.is_empty()
            && !(self.frost > 0.0)
    }
}

/// A half-plane cut in gate coordinates: blocked where `(p − point)·normal > 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Cut {
    point: Vec2,
    normal: Vec2,
}

/// A spot shaped by its gate (see the module doc).
#[derive(Clone, Debug)]
pub struct ShapedBeam {
    /// The open spot (zoom, focus, iris applied; no frost).
    pub spot: SpotBeam,
    /// The gate's contents.
    pub gate: Gate,
    /// The spot with the frost's wider penumbra.
    soft: SpotBeam,
    /// tan of the open spot's outer half-angle: gate radius 1.
    tan_outer: f32,
    /// Blade cuts in gate coordinates.
    cuts: Vec<Cut>,
    /// Facet (turn cos/sin, offset), prism rotation applied.
    facets: Vec<(Vec2, Vec2)>,
    /// cos of the widest angle any facet reaches.
    cos_cut: f32,
    /// Gobo as seen through the frost.
    frosted: OnceLock<Option<Arc<GoboImage>>>,
    /// The further layers as seen through the frost.
    frosted_layers: OnceLock<Vec<Arc<GoboImage>>>,
    /// Flux scale for prism and frost, and the flux ∫f dω.
    flux: OnceLock<(f32, f32)>,
}

impl PartialEq for ShapedBeam {
    fn eq(&self, other: &Self) -> bool {
        self.spot == other.spot && self.gate == other.gate
    }
}

impl ShapedBeam {
    /// `spot` shaped by `gate`. Cheap: the flux normalisation is computed on first use.
    pub fn new(spot: SpotBeam, gate: Gate) -> Self {
        let outer = spot.outer.min(MAX_GATE_HALF_ANGLE);
        let tan_outer = outer.tan().max(1e-6);
        let frost = if gate.frost.is_finite() { gate.frost.clamp(0.0, 1.0) } else { 0.0 };
        let soft = if frost > 0.0 {
            SpotBeam::from_half_angles(
                spot.inner * (1.0 - FROST_WIDEN * frost),
                (spot.outer * (1.0 + FROST_WIDEN * frost)).min(MAX_GATE_HALF_ANGLE),
            )
        } else {
            spot.clone()
        };
        let finite = |a: f32| if a.is_finite() { a.to_radians() } else { 0.0 };
        let shaper = Vec2::from_angle(finite(gate.shaper_rot));
        let mut cuts = Vec::new();
        for (k, b) in gate.blades.iter().enumerate() {
            let ins = |x: f32| if x.is_finite() { x.clamp(0.0, 1.0) } else { 0.0 };
            let (a, bb) = (ins(b.a), ins(b.b));
            if a <= 0.0 && bb <= 0.0 {
                continue;
            }
            // Home direction u (1: +y, 2: +x, 3: −y, 4: −x) and t, u turned 90° counter-clockwise.
            let u = Vec2::from_angle(std::f32::consts::FRAC_PI_2 - k as f32 * std::f32::consts::FRAC_PI_2);
            let t = u.perp();
            let (pa, pb) = (t + u * (1.0 - 2.0 * a), -t + u * (1.0 - 2.0 * bb));
            let mid = (pa + pb) * 0.5;
            let edge = Vec2::from_angle(finite(b.rot)).rotate(pb - pa);
            let mut normal = edge.perp().normalize_or_zero();
            if normal.dot(u) < 0.0 {
                normal = -normal;
            }
            cuts.push(Cut { point: shaper.rotate(mid), normal: shaper.rotate(normal) });
        }
        let prism = Vec2::from_angle(finite(gate.prism_angle));
        let facets: Vec<(Vec2, Vec2)> = gate
            .facets
            .iter()
            .map(|f| {
                let r = if f.rotation.is_finite() { f.rotation } else { 0.0 };
                let o = if f.offset.is_finite() { f.offset } else { Vec2::ZERO };
                (prism.rotate(Vec2::from_angle(r)), prism.rotate(o))
            })
            .collect();
        // Widest reach: the soft cone's gate radius plus the largest facet shift.
        let reach = soft.outer.min(MAX_GATE_HALF_ANGLE).tan() / tan_outer
            + facets.iter().map(|f| f.1.length()).fold(0.0, f32::max);
        let theta_cut = if facets.is_empty() { soft.outer } else { (reach * tan_outer).atan() };
        let cos_cut = if theta_cut >= std::f32::consts::PI { -1.0 } else { theta_cut.cos() };
        Self {
            spot,
            gate,
            soft,
            tan_outer,
            cuts,
            facets,
            cos_cut,
            frosted: OnceLock::new(),
            frosted_layers: OnceLock::new(),
            flux: OnceLock::new(),
        }
    }

    /// cos of the widest angle with light.
    pub fn cos_cutoff(&self) -> f32 {
        self.cos_cut
    }

    /// The gate point of a local direction (`None` behind the light).
    pub fn gate_point(&self, dir: Vec3) -> Option<Vec2> {
        if !(-dir.z > 0.0) {
            return None;
        }
        Some(Vec2::new(dir.x, dir.y) / (-dir.z * self.tan_outer))
    }

    /// The un-prismed gate's transmission × spot at gate point `q` (at
    /// angle `theta` from the axis when known, else from `q`): `soft`
    /// selects the frosted spot and gobo.
    fn through_gate(&self, q: Vec2, theta: Option<f32>, soft: bool) -> f32 {
        let spot = if soft { &self.soft } else { &self.spot };
        let v = spot.at_angle(theta.unwrap_or_else(|| (q.length() * self.tan_outer).atan()));
        if v <= 0.0 || self.cuts.iter().any(|c| (q - c.point).dot(c.normal) > 0.0) {
            return 0.0;
        }
        let gobo = if soft { self.frosted_gobo() } else { self.gate.gobo.as_ref() };
        let sample = |g: &GoboImage, angle: f32| {
            let turn = Vec2::from_angle(-angle.to_radians());
            let turn = if turn.is_finite() { turn } else { Vec2::X };
            g.sample(turn.rotate(q))
        };
        let mut t = match gobo {
            Some(g) => v * sample(g, self.gate.gobo_angle),
            None => v,
        };
        if !self.gate.layers.is_empty() {
            let frosted = if soft { Some(self.frosted_layers()) } else { None };
            for (k, layer) in self.gate.layers.iter().enumerate() {
                let img = frosted.and_then(|f| f.get(k)).unwrap_or(&layer.image);
                t *= sample(img, layer.angle);
            }
        }
        t
    }

    fn frosted_layers(&self) -> &[Arc<GoboImage>] {
        self.frosted_layers.get_or_init(|| {
            let frost = if self.gate.frost.is_finite() { self.gate.frost.clamp(0.0, 1.0) } else { 0.0 };
            self.gate
                .layers
                .iter()
                .map(|l| if frost > 0.0 { Arc::new(l.image.blurred(FROST_BLUR * frost)) } else { l.image.clone() })
                .collect()
        })
    }

    fn frosted_gobo(&self) -> Option<&Arc<GoboImage>> {
        self.frosted
            .get_or_init(|| {
                let frost = if self.gate.frost.is_finite() { self.gate.frost.clamp(0.0, 1.0) } else { 0.0 };
                self.gate
                    .gobo
                    .as_ref()
                    .map(|g| if frost > 0.0 { Arc::new(g.blurred(FROST_BLUR * frost)) } else { g.clone() })
            })
            .as_ref()
    }

    /// The pattern before the flux scale.
    fn raw(&self, dir: Vec3) -> f32 {
        let Some(p) = self.gate_point(dir) else { return 0.0 };
        let soft = self.gate.frost > 0.0;
        if self.facets.is_empty() {
            // The spot's own angle: exactly the open spot where nothing cuts.
            return self.through_gate(p, Some(super::axis_angle(dir)), soft);
        }
        let sum: f32 = self
            .facets
            .iter()
            .map(|(turn, off)| self.through_gate(Vec2::new(turn.x, -turn.y).rotate(p - *off), None, soft))
            .sum();
        sum / self.facets.len() as f32
    }

    /// A key of everything the flux depends on (bit patterns; the gobo by
    /// its name, size and texel sum).
    fn key(&self) -> Vec<u32> {
        let g = &self.gate;
        let mut k = vec![self.spot.inner.to_bits(), self.spot.outer.to_bits(), g.gobo_angle.to_bits()];
        if let Some(img) = &g.gobo {
            let sum: f32 = img.texels.iter().sum();
            k.extend([img.width as u32, img.height as u32, sum.to_bits()]);
            k.extend(img.name.bytes().map(u32::from));
        }
        k.extend(g.blades.iter().flat_map(|b| [b.a.to_bits(), b.b.to_bits(), b.rot.to_bits()]));
        k.extend([g.shaper_rot.to_bits(), g.prism_angle.to_bits(), g.frost.to_bits()]);
        k.extend(g.facets.iter().flat_map(|f| [f.rotation.to_bits(), f.offset.x.to_bits(), f.offset.y.to_bits()]));
        for l in &g.layers {
            let sum: f32 = l.image.texels.iter().sum();
            k.extend([u32::MAX, l.angle.to_bits(), l.image.width as u32, l.image.height as u32, sum.to_bits()]);
            k.extend(l.image.name.bytes().map(u32::from));
        }
        k
    }

    /// (scale, flux): flux of the unscaled pattern vs the plain gate's.
    /// Cached per beam and in a small process-wide table: the daemon makes
    /// a new beam per fixture per frame, and a moving preview camera
    /// evaluates it, so the quadrature runs once per distinct gate.
    fn norm(&self) -> (f32, f32) {
        *self.flux.get_or_init(|| {
            static CACHE: std::sync::Mutex<Vec<NormEntry>> = std::sync::Mutex::new(Vec::new());
            let key = self.key();
            if let Ok(c) = CACHE.lock()
                && let Some((_, v)) = c.iter().find(|(k, _)| *k == key)
            {
                return *v;
            }
            let v = self.integrate_norm();
            if let Ok(mut c) = CACHE.lock() {
                if c.len() >= NORM_CACHE {
                    c.remove(0);
                }
                c.push((key, v));
            }
            v
        })
    }

    fn integrate_norm(&self) -> (f32, f32) {
        {
            let plain = integrate(self.spot.outer, |d| {
                self.gate_point(d).map_or(0.0, |p| self.through_gate(p, Some(super::axis_angle(d)), false))
            });
            if self.facets.is_empty() && !(self.gate.frost > 0.0) {
                return (1.0, plain as f32);
            }
            let raw = integrate(self.cos_cut.clamp(-1.0, 1.0).acos(), |d| self.raw(d));
            if raw > 0.0 { ((plain / raw) as f32, plain as f32) } else { (0.0, 0.0) }
        }
    }

    /// f_ε for a unit local direction.
    pub fn pattern(&self, dir: Vec3) -> f32 {
        let len = dir.length();
        if !(len > 0.0) || !len.is_finite() || -dir.z / len < self.cos_cut {
            return 0.0;
        }
        let raw = self.raw(dir);
        if raw <= 0.0 {
            0.0
        } else if self.facets.is_empty() && !(self.gate.frost > 0.0) {
            raw // gobo and blades only absorb: no flux scale to compute
        } else {
            raw * self.norm().0
        }
    }

    /// ∫ f_ε dω (steradians): the flux through the gobo and blades at 1 cd
    /// peak; prism and frost keep it.
    pub fn solid_angle(&self) -> f32 {
        self.norm().1
    }
}

/// ∫ f dω over the cap of half-angle `theta_max` by the midpoint rule in
/// θ (256 steps) and φ (384 steps): fine enough for 1024-texel gobos over
/// the gate (each texel spans several nodes).
fn integrate(theta_max: f32, f: impl Fn(Vec3) -> f32) -> f64 {
    let theta_max = f64::from(theta_max).clamp(0.0, std::f64::consts::PI);
    let (nt, np) = (256, 384);
    let (dt, dp) = (theta_max / nt as f64, std::f64::consts::TAU / np as f64);
    let mut sum = 0.0;
    for i in 0..nt {
        let th = (i as f64 + 0.5) * dt;
        let (s, c) = th.sin_cos();
        let mut ring = 0.0;
        for j in 0..np {
            let ph = (j as f64 + 0.5) * dp;
            ring += f64::from(f(Vec3::new((s * ph.cos()) as f32, (s * ph.sin()) as f32, -c as f32)));
        }
        sum += ring * s;
    }
    sum * dt * dp
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::beam::{Beam, BeamSampler};

    const N: usize = 64;

    /// The generator's ring gobo (tools/gen_gdtf_mvr.py `gobo_ring`): light passes for 0.5 ≤ r ≤ 0.9.
    fn ring() -> Arc<GoboImage> {
        let c = (N as f32 - 1.0) / 2.0;
        let luma: Vec<u8> = (0..N * N)
            .map(|i| {
                let (x, y) = ((i % N) as f32, (i / N) as f32);
                let r = (x - c).hypot(y - c) / (N as f32 / 2.0);
                if (0.5..=0.9).contains(&r) { 255 } else { 0 }
            })
            .collect();
        Arc::new(GoboImage::from_luma8("ring", N, N, &luma).unwrap())
    }

    /// Four vertical bars (`gobo_bars`): columns 0-7, 16-23, … pass.
    fn bars() -> Arc<GoboImage> {
        let luma: Vec<u8> = (0..N * N).map(|i| if (i % N / 8).is_multiple_of(2) { 255 } else { 0 }).collect();
        Arc::new(GoboImage::from_luma8("bars", N, N, &luma).unwrap())
    }

    fn dir(theta: f64, phi: f64) -> Vec3 {
        Vec3::new((theta.sin() * phi.cos()) as f32, (theta.sin() * phi.sin()) as f32, -(theta.cos() as f32))
    }

    /// ∫ f dω by a product rule the beam does not use: 4-point Gauss–Legendre
    /// on 300 θ panels × 700 φ midpoints.
    fn flux(beam: &Beam) -> f64 {
        let top = f64::from(beam.cos_cutoff().clamp(-1.0, 1.0)).acos();
        let (x, w) = (
            [-0.861_136_311_6, -0.339_981_043_6, 0.339_981_043_6, 0.861_136_311_6],
            [0.347_854_845_1, 0.652_145_154_9, 0.652_145_154_9, 0.347_854_845_1],
        );
        let (nt, np) = (300, 700);
        let h = top / nt as f64;
        let mut sum = 0.0;
        for i in 0..nt {
            let mid = (i as f64 + 0.5) * h;
            for (xk, wk) in x.iter().zip(w) {
                let th = mid + 0.5 * h * xk;
                let ring: f64 = (0..np)
                    .map(|j| f64::from(beam.pattern(dir(th, std::f64::consts::TAU * (j as f64 + 0.5) / np as f64))))
                    .sum();
                sum += wk * 0.5 * h * th.sin() * ring * std::f64::consts::TAU / np as f64;
            }
        }
        sum
    }

    fn shaped(spot: &SpotBeam, gate: Gate) -> Beam {
        Beam::Shaped(Box::new(ShapedBeam::new(spot.clone(), gate)))
    }

    #[test]
    fn ring_gobo_flux_matches_the_closed_form_and_the_photon_sampler() {
        // A hard-edged 30° spot: the ring passes tan θ / tan 15° in [0.5, 0.9].
        let spot = SpotBeam::from_beam_field(30.0, 30.0);
        let beam = shaped(&spot, Gate { gobo: Some(ring()), ..Gate::default() });
        let t = spot.outer.tan() as f64;
        let closed = std::f64::consts::TAU * ((0.5 * t).atan().cos() - (0.9 * t).atan().cos());
        let quad = flux(&beam);
        assert!((quad / closed - 1.0).abs() < 0.03, "quadrature {quad} vs closed form {closed}");
        assert!(
            (f64::from(beam.solid_angle()) / quad - 1.0).abs() < 5e-3,
            "solid_angle {} vs {quad}",
            beam.solid_angle()
        );
        // Photon emission: the sampler's table and the unbiased estimate mean(f/pdf).
        let s = BeamSampler::new(&beam);
        assert!((f64::from(s.flux()) / quad - 1.0).abs() < 0.01, "sampler flux {} vs {quad}", s.flux());
        let m = 200_000;
        let mut est = 0.0;
        for i in 0..m {
            let smp = s.sample((i as f32 + 0.5) / m as f32, (i as f32 * 0.618_034).fract()).unwrap();
            est += f64::from(beam.pattern(smp.dir) / smp.pdf);
        }
        est /= m as f64;
        assert!((est / quad - 1.0).abs() < 0.01, "photon estimate {est} vs {quad}");
        // Light passes only through the ring.
        assert_eq!(beam.pattern(dir(0.0, 0.0)), 0.0, "the ring's centre is opaque");
        assert!(beam.pattern(dir((0.7 * t).atan(), 1.0)) > 0.99);
    }

    #[test]
    fn bars_gobo_rotation_turns_the_pattern_and_keeps_the_flux() {
        let spot = SpotBeam::from_beam_field(20.0, 26.0);
        let at = |angle: f32| shaped(&spot, Gate { gobo: Some(bars()), gobo_angle: angle, ..Gate::default() });
        let (still, turned) = (at(0.0), at(37.0));
        for k in 0..200 {
            let (th, ph) = (0.002 * k as f64, 0.31 * k as f64);
            let (a, b) = (still.pattern(dir(th, ph)), turned.pattern(dir(th, ph + 37f64.to_radians())));
            assert!((a - b).abs() < 2e-3, "{k}: {a} vs {b}");
        }
        let (fs, ft) = (flux(&still), flux(&turned));
        assert!((fs / ft - 1.0).abs() < 0.01, "{fs} vs {ft}");
        assert!((f64::from(still.solid_angle()) / fs - 1.0).abs() < 5e-3);
        // Half the gate's columns pass: about half the open spot's flux.
        let open = f64::from(spot.solid_angle());
        assert!((fs / open - 0.5).abs() < 0.06, "{fs} of {open}");
    }

    #[test]
    fn a_blade_cuts_exactly_along_its_edge() {
        let spot = SpotBeam::from_beam_field(24.0, 30.0);
        let t = spot.outer.tan();
        // Blade 2 (from +x) in halfway on both ends: cuts gate x > 0, i.e. local x > 0.
        let mut gate = Gate::default();
        gate.blades[1] = Blade { a: 0.5, b: 0.5, rot: 0.0 };
        let beam = shaped(&spot, gate.clone());
        for k in 0..400 {
            let (th, ph) = (f64::from(spot.outer) * (k as f64 / 400.0), 0.77 * k as f64);
            let d = dir(th, ph);
            let want = if d.x > 0.0 { 0.0 } else { spot.pattern(d) };
            assert_eq!(beam.pattern(d), want, "{th} {ph}");
        }
        // Turned by the shaper 90°: blade 2's cut moves to gate +y.
        gate.shaper_rot = 90.0;
        let turned = shaped(&spot, gate.clone());
        assert_eq!(turned.pattern(Vec3::new(0.0, 0.2 * t, -1.0).normalize()), 0.0);
        assert!(turned.pattern(Vec3::new(0.2 * t, 0.0, -1.0).normalize()) > 0.99);
        // A tilted edge (A in 0.2, B in 0.6 of the diameter): blade 2's A end
        // sits on the gate +y side at (1 − 2·0.2, 1), its B end at (1 − 2·0.6, −1).
        gate.shaper_rot = 0.0;
        gate.blades[1] = Blade { a: 0.2, b: 0.6, rot: 0.0 };
        let tilted = shaped(&spot, gate);
        let (pa, pb) = (Vec2::new(0.6, 1.0), Vec2::new(-0.2, -1.0));
        for k in 0..300 {
            let p = Vec2::new(-1.0 + 2.0 * (k % 20) as f32 / 19.0, -1.0 + 2.0 * (k / 20) as f32 / 14.0) * 0.95;
            let d = Vec3::new(p.x * t, p.y * t, -1.0).normalize();
            let side = (pb - pa).perp_dot(p - pa); // > 0: right of A→B, the blade's (+x) side
            if side > 1e-3 {
                assert_eq!(tilted.pattern(d), 0.0, "{p}");
            } else if side < -1e-3 {
                assert_eq!(tilted.pattern(d), spot.pattern(d), "{p}");
            }
        }
    }

    #[test]
    fn prism_and_frost_move_light_without_losing_it() {
        let spot = SpotBeam::from_beam_field(12.0, 16.0);
        let plain = shaped(&spot, Gate { gobo: Some(ring()), ..Gate::default() });
        let reference = flux(&plain);
        let facets: Vec<Facet> = (0..3)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 3.0;
                Facet::from_gdtf([[a.cos(), -a.sin(), 0.0], [a.sin(), a.cos(), 0.0], [0.0, 0.0, 1.0]])
            })
            .collect();
        assert!((facets[1].offset - Vec2::from_angle(std::f32::consts::TAU / 3.0) * PRISM_SPREAD).length() < 1e-5);
        let prism =
            shaped(&spot, Gate { gobo: Some(ring()), facets: facets.clone(), prism_angle: 20.0, ..Gate::default() });
        let fp = flux(&prism);
        assert!((fp / reference - 1.0).abs() < 0.01, "prism {fp} vs {reference}");
        assert!(prism.cos_cutoff() < plain.cos_cutoff(), "facets reach wider");
        // Three images: light off the axis where the plain beam has none.
        let t = spot.outer.tan();
        let facet0 = Vec2::from_angle(20f32.to_radians()) * PRISM_SPREAD + Vec2::new(0.7, 0.0);
        assert!(prism.pattern(Vec3::new(facet0.x * t, facet0.y * t, -1.0).normalize()) > 0.1);
        let frosted = shaped(&spot, Gate { gobo: Some(ring()), frost: 1.0, ..Gate::default() });
        let ff = flux(&frosted);
        assert!((ff / reference - 1.0).abs() < 0.01, "frost {ff} vs {reference}");
        // A softer edge: light beyond the open cone, and the sampler still agrees.
        let past = dir(f64::from(spot.outer) * 1.1, 0.3);
        assert_eq!(plain.pattern(past), 0.0);
        let open_frost = shaped(&spot, Gate { frost: 1.0, ..Gate::default() });
        assert!(open_frost.pattern(past) > 0.0);
        for b in [&prism, &frosted] {
            let s = BeamSampler::new(b);
            assert!((f64::from(s.flux()) / reference - 1.0).abs() < 0.015, "sampler {}", s.flux());
        }
    }

    #[test]
    fn a_second_image_layer_multiplies_the_gobo() {
        // Two discs in series: the pattern is the spot times both transmissions,
        // each at its own angle (the bars as a gobo alone at 30° give the second factor).
        let spot = SpotBeam::from_beam_field(20.0, 30.0);
        let ring_only = shaped(&spot, Gate { gobo: Some(ring()), ..Gate::default() });
        let bars_only = shaped(&spot, Gate { gobo: Some(bars()), gobo_angle: 30.0, ..Gate::default() });
        let layered = ShapedBeam::new(
            spot.clone(),
            Gate { gobo: Some(ring()), layers: vec![GoboLayer { image: bars(), angle: 30.0 }], ..Gate::default() },
        );
        assert!(!Gate { layers: vec![GoboLayer { image: bars(), angle: 0.0 }], ..Gate::default() }.is_open());
        let mut lit = 0;
        for k in 0..400 {
            let d = dir(0.0065 * (k % 40) as f64, 0.37 * k as f64);
            let v = spot.pattern(d);
            if v <= 0.0 {
                continue;
            }
            let want = ring_only.pattern(d) * bars_only.pattern(d) / v;
            assert!((layered.pattern(d) - want).abs() < 1e-5, "{d}: {} vs {want}", layered.pattern(d));
            lit += usize::from(want > 0.0);
        }
        assert!(lit > 20, "{lit}");
        // It absorbs: less flux than the ring alone.
        assert!(layered.solid_angle() < ring_only.solid_angle());
    }

    #[test]
    fn garbage_is_finite_and_the_open_gate_is_the_spot() {
        let spot = SpotBeam::from_beam_field(20.0, 30.0);
        assert!(Gate::default().is_open());
        let open = ShapedBeam::new(spot.clone(), Gate { gobo_angle: 45.0, ..Gate::default() });
        for k in 0..100 {
            let d = dir(0.01 * k as f64, 0.5 * k as f64);
            assert_eq!(open.pattern(d), spot.pattern(d));
        }
        let junk = ShapedBeam::new(
            spot,
            Gate {
                gobo: Some(ring()),
                gobo_angle: f32::NAN,
                blades: [Blade { a: f32::NAN, b: 2.0, rot: f32::INFINITY }; 4],
                shaper_rot: f32::NAN,
                facets: vec![Facet { rotation: f32::NAN, offset: Vec2::NAN }],
                prism_angle: f32::INFINITY,
                frost: f32::NAN,
                layers: vec![GoboLayer { image: bars(), angle: f32::NAN }],
            },
        );
        for d in [Vec3::NEG_Z, Vec3::Z, Vec3::X, Vec3::ZERO, Vec3::NAN, dir(0.1, 0.2)] {
            let v = junk.pattern(d);
            assert!(v.is_finite() && v >= 0.0, "{d}: {v}");
        }
        assert!(junk.solid_angle().is_finite());
        assert!(GoboImage::from_luma8("x", 2, 2, &[0; 3]).is_none());
    }
}
