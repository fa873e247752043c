//! Pinhole camera: turns a pixel and a sub-pixel offset into a primary ray;
//! and where a walked camera may go (issue 37: a camera that stays on the
//! stage).
//!
//! The camera comes from the glTF file (its first perspective camera node)
//! or from the patch's `[camera]` table; both follow glTF's convention of
//! looking along local −Z with +Y up.
//!
//! **Staying on the stage** ([`StageLimits`]). The page and the window move
//! the camera freely (orbit about its target, pan, dolly); every written
//! pose is then confined:
//!
//! 1. eye and target are clamped into the *room*: the scene's bounds, less
//!    [`WALL_MARGIN`] on every side, with at least [`StageLimits::headroom`]
//!    above the floor for a scene with no walls or roof, grown to hold the
//!    named views' eyes (the start camera sits in the audience, outside an
//!    open-fronted set);
//! 2. the eye's distance to the target is kept within
//!    [`MIN_DISTANCE`] and the room's diagonal (the dolly's range);
//! 3. the segment from the stage centre (the pivot) to the eye is traced
//!    through the BVH ([`behind_wall`]): when the eye went behind a wall (a
//!    surface seen from its back, or into something not come out of; glass
//!    does not count) it is pulled in along the segment to [`WALL_MARGIN`]
//!    in front of that wall. A column or a sculpture wholly between the
//!    pivot and the eye does not stop it.
//!
//! The pivot ([`stage_centre`]) is where the rig points: the mean plan
//! position of the beams' focus points (each beam axis's first opaque
//! hit), at [`FOCUS_HEIGHT`] above their median height (most beams land on
//! the deck; the median ignores the few on the cyc). Without a rig it is
//! the scene's bounds' plan centre, [`FOCUS_HEIGHT`] above the first
//! surface below the bounds' centre. A pivot inside a closed prop is raised
//! out of it.
//!
//! **Framing** ([`frame_distance`], [`fov_to_fit`]): the eye distance at
//! which a set of points fits a frustum, in closed form.

use super::Scene;
use glam::{Mat3, Vec3};

/// A perspective pinhole camera in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position (metres).
    pub position: Vec3,
    /// Orthonormal basis: columns are right, up, and backward (+Z local).
    pub basis: Mat3,
    /// Vertical field of view in radians.
    pub yfov: f32,
}

impl Camera {
    /// A camera at `position` looking at `target` with world +Y up. Falls back
    /// to +Z as up when looking straight up or down, so the basis never
    /// degenerates.
    pub fn look_at(position: Vec3, target: Vec3, yfov: f32) -> Self {
        let forward = (target - position).try_normalize().unwrap_or(Vec3::NEG_Z);
        let mut right = forward.cross(Vec3::Y);
        if right.length_squared() < 1e-8 {
            right = forward.cross(Vec3::Z);
        }
        let right = right.normalize();
        let up = right.cross(forward);
        Self { position, basis: Mat3::from_cols(right, up, -forward), yfov: sanitize_fov(yfov) }
    }

    /// A camera from a world transform's translation and rotation (glTF node).
    pub fn from_rotation(position: Vec3, rotation: glam::Quat, yfov: f32) -> Self {
        let rotation = if rotation.is_finite() && rotation.length_squared() > 1e-12 {
            rotation.normalize()
        } else {
            glam::Quat::IDENTITY
        };
        Self { position, basis: Mat3::from_quat(rotation), yfov: sanitize_fov(yfov) }
    }

    /// Direction (unit) of the ray through image point (`x`, `y`) in pixels,
    /// measured from the top-left corner, for an image `width`×`height`.
    pub fn direction(&self, x: f32, y: f32, width: u32, height: u32) -> Vec3 {
        let aspect = width as f32 / height.max(1) as f32;
        let tan_half = (self.yfov * 0.5).tan();
        let ndc_x = (2.0 * x / width.max(1) as f32 - 1.0) * tan_half * aspect;
        let ndc_y = (1.0 - 2.0 * y / height.max(1) as f32) * tan_half;
        (self.basis.x_axis * ndc_x + self.basis.y_axis * ndc_y - self.basis.z_axis).normalize()
    }
}

/// An axis-aligned box, metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Lowest corner.
    pub min: Vec3,
    /// Highest corner.
    pub max: Vec3,
}

impl Bounds {
    /// The smallest box holding every finite point of `points`; `None` when
    /// there is none.
    pub fn around(points: impl IntoIterator<Item = Vec3>) -> Option<Self> {
        points
            .into_iter()
            .filter(|p| p.is_finite())
            .fold(None, |b: Option<Self>, p| Some(b.map_or(Self { min: p, max: p }, |b| b.with(p))))
    }

    /// The bounds of every vertex of `scene` (`None`: an empty scene).
    pub fn of_scene(scene: &Scene) -> Option<Self> {
        Self::around(scene.positions.iter().flatten().copied())
    }

    /// This box grown to hold `p` (a non-finite `p` is ignored).
    pub fn with(self, p: Vec3) -> Self {
        if p.is_finite() { Self { min: self.min.min(p), max: self.max.max(p) } } else { self }
    }

    /// This box moved in by `d` on every side; an axis narrower than 2`d`
    /// collapses to its middle.
    pub fn shrunk(self, d: f32) -> Self {
        let (min, max) = (self.min + Vec3::splat(d), self.max - Vec3::splat(d));
        let mid = (self.min + self.max) * 0.5;
        let inverted = min.cmpgt(max);
        Self { min: Vec3::select(inverted, mid, min), max: Vec3::select(inverted, mid, max) }
    }

    /// The point of the box nearest `p`.
    pub fn clamp(&self, p: Vec3) -> Vec3 {
        p.clamp(self.min, self.max)
    }

    /// True when `p` lies in the box grown by `eps`.
    pub fn contains(&self, p: Vec3, eps: f32) -> bool {
        p.cmpge(self.min - Vec3::splat(eps)).all() && p.cmple(self.max + Vec3::splat(eps)).all()
    }

    /// The middle of the box.
    pub fn centre(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Length of the box's diagonal.
    pub fn diagonal(&self) -> f32 {
        (self.max - self.min).length()
    }
}

/// Nearest a confined eye comes to its target (m): the dolly's lower limit.
pub const MIN_DISTANCE: f32 = 0.5;
/// How far a confined eye stays inside the scene's bounds and in front of
/// the wall it was pulled back from (m).
pub const WALL_MARGIN: f32 = 0.25;
/// Height of the stage centre above the floor the rig lights (m): about a
/// performer's chest, so an orbit keeps the deck and the people on it in
/// view.
pub const FOCUS_HEIGHT: f32 = 1.0;

/// The first opaque surface along `origin + t·dir` for t in (0, `t_max`):
/// its distance. Transmissive surfaces (glass: k_T > 0) are passed through;
/// `dir` must be unit.
pub fn first_opaque(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32) -> Option<f32> {
    let mut start = 0.0f32;
    // A ray through more than 16 panes of glass stops at the 17th surface.
    for _ in 0..16 {
        let hit = scene.accel.intersect(origin + dir * start, dir, t_max - start)?;
        let t = start + hit.t;
        let material = scene.material_of.get(hit.triangle as usize).and_then(|&m| scene.materials.get(m as usize));
        if !material.is_some_and(|m| m.k_t.max_element() > 0.0) {
            return Some(t);
        }
        start = t + 1e-4;
        if start >= t_max {
            return None;
        }
    }
    Some(start)
}

/// Whether `to` is behind a wall seen from `from` (a point in the open):
/// the distance from `from` of the wall, or `None` when `to` is in the
/// open too. The opaque surfaces on the segment are counted as a ray
/// crosses them (glass is passed through): a face met from its front
/// (its face normal against the ray) goes into something, one met from
/// its back comes out. `to` is behind a wall when the segment ends inside
/// (the wall is where it went in for the last time), or when it meets a
/// face from its back while in the open (a one-sided wall or set piece
/// seen from behind). A closed, outward-facing prop wholly on the segment
/// (a column, a sculpture) is gone into and come out of: the eye behind it
/// stays where it is, rather than jumping in front of every column an
/// orbit passes behind.
pub fn behind_wall(scene: &Scene, from: Vec3, to: Vec3) -> Option<f32> {
    let length = from.distance(to);
    let unit = (to - from).try_normalize()?;
    let (mut depth, mut entry, mut start) = (0u32, 0.0f32, 0.0f32);
    // At most 64 surfaces are counted; a segment through more ends where
    // the count stands.
    for _ in 0..64 {
        let Some(hit) = scene.accel.intersect(from + unit * start, unit, length - start) else { break };
        let t = start + hit.t;
        start = t + 1e-4;
        let i = hit.triangle as usize;
        let material = scene.material_of.get(i).and_then(|&m| scene.materials.get(m as usize));
        if material.is_some_and(|m| m.k_t.max_element() > 0.0) {
            continue;
        }
        let facing = scene.face_normals.get(i).map_or(-1.0, |n| n.dot(unit));
        if facing < 0.0 {
            if depth == 0 {
                entry = t;
            }
            depth += 1;
        } else if depth > 0 {
            depth -= 1;
        } else {
            return Some(t);
        }
        if start >= length {
            break;
        }
    }
    (depth > 0).then_some(entry)
}

/// Where a beam is focused: the first opaque surface along its axis from
/// `position` (`None`: the beam points into the void).
pub fn focus_point(scene: &Scene, position: Vec3, axis: Vec3) -> Option<Vec3> {
    let axis = axis.try_normalize()?;
    first_opaque(scene, position, axis, f32::INFINITY).filter(|t| t.is_finite()).map(|t| position + axis * t)
}

/// True when `p` is inside a closed object: the surface straight above is
/// seen from its back (its face normal points away from `p`), and so is
/// every surface met straight out to the four sides. Not below: a prop's
/// bottom often lies on the deck, and the ray may meet the deck first. In
/// a room, under an open sky or beside a wall facing it, it is not.
fn enclosed(scene: &Scene, p: Vec3) -> bool {
    let back = |dir: Vec3| {
        scene
            .accel
            .intersect(p, dir, f32::INFINITY)
            .map(|h| scene.face_normals.get(h.triangle as usize).is_some_and(|n| n.dot(dir) > 0.0))
    };
    // Slightly off the axes: a ray along one would meet a modelled box's
    // faces on their diagonals, where a hit may slip between the triangles.
    let (a, b) = (0.0131, 0.0077);
    let up = Vec3::new(a, 1.0, b).normalize();
    let sides = [Vec3::new(1.0, a, b), Vec3::new(-1.0, b, a), Vec3::new(b, a, 1.0), Vec3::new(a, b, -1.0)];
    back(up) == Some(true) && sides.into_iter().all(|d| back(d.normalize()) != Some(false))
}

/// The stage centre (see the module doc): from the rig's focus points
/// when there are any, else from the scene's `bounds`; lifted out of a
/// closed prop (0.5 m steps, at most to the room's top: the bounds' top or
/// [`StageLimits::headroom`] above their floor).
pub fn stage_centre(scene: &Scene, bounds: &Bounds, focus: &[Vec3]) -> Vec3 {
    let focus: Vec<Vec3> = focus.iter().copied().filter(|p| p.is_finite()).collect();
    let mut pivot = if focus.is_empty() {
        let c = bounds.centre();
        let floor = first_opaque(scene, c, Vec3::NEG_Y, f32::INFINITY).map_or(bounds.min.y, |t| c.y - t);
        Vec3::new(c.x, floor + FOCUS_HEIGHT, c.z)
    } else {
        let n = focus.len() as f32;
        let plan = focus.iter().fold(Vec3::ZERO, |a, p| a + *p) / n;
        let mut heights: Vec<f32> = focus.iter().map(|p| p.y).collect();
        heights.sort_by(f32::total_cmp);
        Vec3::new(plan.x, heights[heights.len() / 2] + FOCUS_HEIGHT, plan.z)
    };
    pivot = bounds.clamp(pivot);
    let top = bounds.max.y.max(bounds.min.y + StageLimits::headroom(bounds));
    while enclosed(scene, pivot) && pivot.y + 0.5 <= top {
        pivot.y += 0.5;
    }
    pivot
}

/// Where a walked camera may go (see the module doc): the room's box, the
/// stage centre and the range of the eye's distance to its target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StageLimits {
    /// The box eye and target stay in.
    pub room: Bounds,
    /// The stage centre: the start view's orbit pivot and the origin of
    /// the wall test.
    pub pivot: Vec3,
    /// Nearest the eye comes to the target (m).
    pub min_distance: f32,
    /// Farthest the eye goes from the target (m): the room's diagonal.
    pub max_distance: f32,
}

impl StageLimits {
    /// The least height of the room above the floor of `bounds`: half its
    /// larger plan extent (a set with no walls or roof, a bare deck, still
    /// has room to look down on it; a roof lower than that is a wall).
    pub fn headroom(bounds: &Bounds) -> f32 {
        let size = bounds.max - bounds.min;
        0.5 * size.x.max(size.z)
    }

    /// The limits of a scene with these `bounds` (the scene's own), whose
    /// named views have their eyes at `eyes`, orbiting `pivot`.
    pub fn new(bounds: Bounds, eyes: &[Vec3], pivot: Vec3) -> Self {
        let mut high = bounds;
        high.max.y = high.max.y.max(high.min.y + Self::headroom(&bounds));
        let room = eyes.iter().fold(high.shrunk(WALL_MARGIN).with(pivot), |r, e| r.with(*e));
        Self { room, pivot, min_distance: MIN_DISTANCE, max_distance: room.diagonal().max(2.0 * MIN_DISTANCE) }
    }

    /// `eye` and `target` confined (see the module doc): both in the room,
    /// the eye within the distance range of the target and in front of
    /// every opaque surface between the pivot and it. A pose already
    /// inside is returned unchanged. Non-finite input is returned as is
    /// (the pose check refuses it).
    pub fn confine(&self, scene: &Scene, eye: Vec3, target: Vec3) -> Confined {
        if !eye.is_finite() || !target.is_finite() {
            return Confined { eye, target, moved: false };
        }
        // 1. Both in the room (the target may lie on its walls: a view
        // looks at a surface).
        let target_in = self.room.shrunk(-WALL_MARGIN).clamp(target);
        let mut e = self.room.clamp(eye);
        // 2. The dolly's range, along the line from the target.
        let off = e - target_in;
        let d = off.length();
        // (An eye on its target steps out towards the pivot.)
        let dir = off.try_normalize().or_else(|| (self.pivot - target_in).try_normalize()).unwrap_or(Vec3::Z);
        if d > self.max_distance || d < self.min_distance {
            e = self.room.clamp(target_in + dir * d.clamp(self.min_distance, self.max_distance));
        }
        // 3. Never behind a wall, seen from the pivot.
        if let Some(unit) = (e - self.pivot).try_normalize()
            && let Some(t) = behind_wall(scene, self.pivot, e)
        {
            e = self.pivot + unit * (t - WALL_MARGIN).max(0.0);
        }
        // A target the eye was pulled onto: step back towards the pivot.
        if e.distance(target_in) < 1e-3 {
            let back = (self.pivot - target_in).try_normalize().unwrap_or(Vec3::Z);
            e = target_in + back * self.min_distance.min(self.pivot.distance(target_in).max(1e-2));
        }
        let moved = e != eye || target_in != target;
        Confined { eye: e, target: target_in, moved }
    }
}

/// A confined eye and target ([`StageLimits::confine`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Confined {
    /// The eye.
    pub eye: Vec3,
    /// The target.
    pub target: Vec3,
    /// True when either was moved.
    pub moved: bool,
}

/// The camera basis (right, up) of a level camera looking along `forward`.
fn level_axes(forward: Vec3) -> (Vec3, Vec3) {
    let c = Camera::look_at(Vec3::ZERO, forward, 1.0);
    (c.basis.x_axis, c.basis.y_axis)
}

/// The eye distance s from `centre`, backwards along `forward` (unit), at
/// which every one of `points` lies inside a level camera's frustum of
/// vertical field `yfov` and width/height `aspect`, shrunk by `fill` (0-1:
/// a point sits at most at `fill` of the way from the picture's centre to
/// its edge). In closed form: a point at q = p − centre has camera
/// coordinates x = q·right, y = q·up and depth q·forward + s, and fits when
/// s ≥ |x| / (fill·tan(hx)) − q·forward and s ≥ |y| / (fill·tan(hy)) −
/// q·forward, with tan(hy) = tan(yfov/2) and tan(hx) = aspect·tan(hy);
/// the answer is the largest of these (at least 0).
pub fn frame_distance(points: &[Vec3], centre: Vec3, forward: Vec3, yfov: f32, aspect: f32, fill: f32) -> f32 {
    let forward = forward.try_normalize().unwrap_or(Vec3::NEG_Z);
    let (right, up) = level_axes(forward);
    let ty = fill * (0.5 * yfov).tan();
    let tx = ty * aspect;
    points
        .iter()
        .filter(|p| p.is_finite())
        .map(|p| {
            let q = *p - centre;
            let depth = q.dot(forward);
            (q.dot(right).abs() / tx).max(q.dot(up).abs() / ty) - depth
        })
        .fold(0.0f32, f32::max)
}

/// The vertical field of view (radians) at which a level camera at `eye`
/// looking at `target` sees every one of `points` in front of it at most
/// `fill` of the way to the picture's edge, for width/height `aspect`: the
/// largest of atan(|y|/(fill·z)) and atan(|x|/(fill·z·aspect)), doubled.
/// Points behind the eye are left out.
pub fn fov_to_fit(points: &[Vec3], eye: Vec3, target: Vec3, aspect: f32, fill: f32) -> f32 {
    let forward = (target - eye).try_normalize().unwrap_or(Vec3::NEG_Z);
    let (right, up) = level_axes(forward);
    let half = points
        .iter()
        .filter(|p| p.is_finite())
        .filter_map(|p| {
            let q = *p - eye;
            let z = q.dot(forward);
            (z > 1e-3).then(|| (q.dot(up).abs() / (fill * z)).max(q.dot(right).abs() / (fill * z * aspect)))
        })
        .fold(0.0f32, f32::max);
    2.0 * half.atan()
}

/// Keeps the field of view inside (0.1°, 179°); non-finite input becomes 40°.
fn sanitize_fov(yfov: f32) -> f32 {
    if yfov.is_finite() { yfov.clamp(0.1f32.to_radians(), 179f32.to_radians()) } else { 40f32.to_radians() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_points_at_target() {
        let cam = Camera::look_at(Vec3::new(0.0, 2.0, 10.0), Vec3::new(0.0, 2.0, 0.0), 0.7);
        let d = cam.direction(400.0, 250.0, 800, 500);
        assert!((d - Vec3::NEG_Z).length() < 1e-6);
        // Right half of the image is +X (stage left) when looking upstage.
        assert!(cam.direction(700.0, 250.0, 800, 500).x > 0.0);
        assert!(cam.direction(400.0, 10.0, 800, 500).y > 0.0);
    }

    use crate::scene::{Material, SceneBuilder};

    /// A closed axis-aligned box, faces counter-clockwise seen from outside.
    fn add_box(b: &mut SceneBuilder, min: Vec3, max: Vec3, material: u32) {
        let p = |x: bool, y: bool, z: bool| {
            Vec3::new(if x { max.x } else { min.x }, if y { max.y } else { min.y }, if z { max.z } else { min.z })
        };
        let f = false;
        let t = true;
        b.add_quad(p(f, f, t), p(t, f, t), p(t, t, t), p(f, t, t), material);
        b.add_quad(p(t, f, f), p(f, f, f), p(f, t, f), p(t, t, f), material);
        b.add_quad(p(t, f, t), p(t, f, f), p(t, t, f), p(t, t, t), material);
        b.add_quad(p(f, f, f), p(f, f, t), p(f, t, t), p(f, t, f), material);
        b.add_quad(p(f, t, t), p(t, t, t), p(t, t, f), p(f, t, f), material);
        b.add_quad(p(f, f, f), p(t, f, f), p(t, f, t), p(f, f, t), material);
    }

    /// A 10 m × 5 m × 10 m room (x, z in ±5, y in 0..5: floor, roof and
    /// four walls facing in), a closed pillar x 2..3, z ±0.5, 4 m high, a
    /// glass pane at z = −2 across x −4..4, a one-sided flat at x = −3
    /// facing the middle (+X), and one at z = 3 (x ±1) facing away (+Z).
    fn room() -> Scene {
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::lambert("grey", Vec3::splat(0.5)));
        let glass = b.add_material(Material { k_t: Vec3::splat(0.9), ..Material::lambert("glass", Vec3::ZERO) });
        let (lo, hi) = (Vec3::new(-5.0, 0.0, -5.0), Vec3::new(5.0, 5.0, 5.0));
        // The room's faces seen from inside: a box's faces, wound the other way.
        let p = |x: bool, y: bool, z: bool| {
            Vec3::new(if x { hi.x } else { lo.x }, if y { hi.y } else { lo.y }, if z { hi.z } else { lo.z })
        };
        let (f, t) = (false, true);
        for [a, bb, c, d] in [
            [p(f, f, t), p(t, f, t), p(t, t, t), p(f, t, t)],
            [p(t, f, f), p(f, f, f), p(f, t, f), p(t, t, f)],
            [p(t, f, t), p(t, f, f), p(t, t, f), p(t, t, t)],
            [p(f, f, f), p(f, f, t), p(f, t, t), p(f, t, f)],
            [p(f, t, t), p(t, t, t), p(t, t, f), p(f, t, f)],
            [p(f, f, f), p(t, f, f), p(t, f, t), p(f, f, t)],
        ] {
            b.add_quad(d, c, bb, a, m);
        }
        add_box(&mut b, Vec3::new(2.0, 0.0, -0.5), Vec3::new(3.0, 4.0, 0.5), m);
        b.add_quad(
            Vec3::new(-3.0, 0.0, 4.0),
            Vec3::new(-3.0, 0.0, -4.0),
            Vec3::new(-3.0, 3.0, -4.0),
            Vec3::new(-3.0, 3.0, 4.0),
            m,
        );
        b.add_quad(
            Vec3::new(-1.0, 0.0, 3.0),
            Vec3::new(1.0, 0.0, 3.0),
            Vec3::new(1.0, 3.0, 3.0),
            Vec3::new(-1.0, 3.0, 3.0),
            m,
        );
        b.add_quad(
            Vec3::new(-4.0, 0.0, -2.0),
            Vec3::new(4.0, 0.0, -2.0),
            Vec3::new(4.0, 5.0, -2.0),
            Vec3::new(-4.0, 5.0, -2.0),
            glass,
        );
        b.build()
    }

    fn limits(scene: &Scene) -> StageLimits {
        StageLimits::new(Bounds::of_scene(scene).unwrap(), &[], Vec3::new(0.0, 1.0, 0.0))
    }

    #[test]
    fn bounds_hold_their_points_and_shrink_to_the_middle() {
        let b = Bounds::around([Vec3::new(1.0, 2.0, 3.0), Vec3::new(-1.0, 0.0, 5.0), Vec3::NAN]).unwrap();
        assert_eq!((b.min, b.max), (Vec3::new(-1.0, 0.0, 3.0), Vec3::new(1.0, 2.0, 5.0)));
        assert!(Bounds::around([Vec3::NAN]).is_none());
        let s = b.shrunk(0.75);
        assert_eq!((s.min, s.max), (Vec3::new(-0.25, 0.75, 3.75), Vec3::new(0.25, 1.25, 4.25)));
        // Narrower than twice the margin: the axis collapses to its middle.
        let thin = b.shrunk(1.5);
        assert_eq!((thin.min.x, thin.max.x, thin.min.y, thin.max.y), (0.0, 0.0, 1.0, 1.0));
        assert_eq!(b.clamp(Vec3::new(9.0, -9.0, 4.0)), Vec3::new(1.0, 0.0, 4.0));
        assert!(b.contains(Vec3::new(1.05, 1.0, 4.0), 0.1) && !b.contains(Vec3::new(1.2, 1.0, 4.0), 0.1));
        assert!((b.diagonal() - 12f32.sqrt()).abs() < 1e-6);
    }

    #[test]
    fn the_room_is_the_scene_less_the_margin_with_headroom_and_the_named_eyes() {
        let scene = room();
        let l = limits(&scene);
        let m = WALL_MARGIN;
        assert!(l.room.min.abs_diff_eq(Vec3::new(-5.0 + m, m, -5.0 + m), 1e-6), "{:?}", l.room);
        assert!(l.room.max.abs_diff_eq(Vec3::new(5.0 - m, 5.0 - m, 5.0 - m), 1e-6), "{:?}", l.room);
        assert!((l.max_distance - l.room.diagonal()).abs() < 1e-6 && l.min_distance == MIN_DISTANCE);
        // A bare 20 m deck: half its width above it; an audience eye widens the room.
        let flat = Bounds { min: Vec3::new(-10.0, 0.0, -10.0), max: Vec3::new(10.0, 0.0, 10.0) };
        let l = StageLimits::new(flat, &[Vec3::new(0.0, 2.0, 14.0)], Vec3::Y);
        assert!((l.room.min.y - m).abs() < 1e-6 && (l.room.max.y - (10.0 - m)).abs() < 1e-6, "{:?}", l.room);
        assert_eq!(l.room.max.z, 14.0, "{:?}", l.room);
    }

    #[test]
    fn confine_pulls_the_eye_in_front_of_the_wall_it_went_behind_and_keeps_the_dolly_in_range() {
        let scene = room();
        let l = limits(&scene);
        let target = Vec3::new(0.0, 1.0, 0.0);
        // Inside and clear: untouched.
        let free = l.confine(&scene, Vec3::new(-2.0, 2.0, 2.0), target);
        assert_eq!((free.eye, free.target, free.moved), (Vec3::new(-2.0, 2.0, 2.0), target, false));
        // Behind the flat at x = −3 (seen from the pivot (0, 1, 0) it faces
        // the pivot): pulled in along the segment, WALL_MARGIN short of it.
        let c = l.confine(&scene, Vec3::new(-4.0, 1.0, 0.0), target);
        assert!(c.moved && c.eye.abs_diff_eq(Vec3::new(-3.0 + WALL_MARGIN, 1.0, 0.0), 1e-4), "{c:?}");
        assert_eq!(behind_wall(&scene, target, Vec3::new(-4.0, 1.0, 0.0)), Some(3.0));
        // Behind the flat at z = 3 that faces away (met from its back).
        let c = l.confine(&scene, Vec3::new(0.0, 1.0, 4.0), target);
        assert!(c.eye.abs_diff_eq(Vec3::new(0.0, 1.0, 3.0 - WALL_MARGIN), 1e-4), "{c:?}");
        // Behind the closed pillar: gone into and come out of, so the eye stays…
        assert!(!l.confine(&scene, Vec3::new(4.0, 1.0, 0.0), target).moved);
        // …but inside it, it comes out in front of it.
        let c = l.confine(&scene, Vec3::new(2.5, 1.0, 0.0), target);
        assert!(c.eye.abs_diff_eq(Vec3::new(2.0 - WALL_MARGIN, 1.0, 0.0), 1e-4), "{c:?}");
        // Through the wall into the void: back to the room's face (x = 4.75).
        let c = l.confine(&scene, Vec3::new(30.0, 1.0, 3.0), target);
        assert!(c.eye.abs_diff_eq(Vec3::new(5.0 - WALL_MARGIN, 1.0, 3.0), 1e-4), "{c:?}");
        // Above the roof: under it.
        let c = l.confine(&scene, Vec3::new(0.0, 5.2, 0.0), target);
        assert!(c.eye.abs_diff_eq(Vec3::new(0.0, 5.0 - WALL_MARGIN, 0.0), 1e-4), "{c:?}");
        // Glass does not count: the eye beyond the pane stays.
        assert!(!l.confine(&scene, Vec3::new(0.0, 1.0, -4.0), target).moved);
        // The dolly's range: at least MIN_DISTANCE, at most the room's
        // diagonal (here a smaller one, to reach it inside the room).
        let near = l.confine(&scene, Vec3::new(0.0, 1.0, 0.1), target);
        assert!(near.eye.abs_diff_eq(Vec3::new(0.0, 1.0, MIN_DISTANCE), 1e-5), "{near:?}");
        let on = l.confine(&scene, target, target);
        assert!((on.eye.distance(target) - MIN_DISTANCE).abs() < 1e-5, "{on:?}");
        let small = StageLimits { max_distance: 3.0, ..l };
        let far = small.confine(&scene, Vec3::new(0.0, 1.0, -4.0), target);
        assert!(far.eye.abs_diff_eq(Vec3::new(0.0, 1.0, -3.0), 1e-5), "{far:?}");
        // A target outside the scene is brought back (to the room grown by
        // the margin: a target on a wall stays); non-finite input passes through.
        let c = l.confine(&scene, Vec3::new(-1.0, 2.0, 1.0), Vec3::new(0.0, 9.0, 0.0));
        assert!(c.target.abs_diff_eq(Vec3::new(0.0, 5.0, 0.0), 1e-6), "{c:?}");
        assert!(!l.confine(&scene, Vec3::new(-1.0, 2.0, 1.0), Vec3::new(0.0, 0.0, -5.0)).moved);
        assert!(!l.confine(&scene, Vec3::NAN, target).moved);
        // Confining twice changes nothing more.
        for eye in [Vec3::new(-4.0, 1.0, 0.0), Vec3::new(30.0, 7.0, -30.0), Vec3::new(-9.0, -3.0, 2.0)] {
            let once = l.confine(&scene, eye, target);
            let twice = l.confine(&scene, once.eye, once.target);
            assert!(once.moved && !twice.moved, "{eye}: {once:?} then {twice:?}");
        }
    }

    #[test]
    fn the_stage_centre_is_where_the_rig_points_at_focus_height() {
        let scene = room();
        let bounds = Bounds::of_scene(&scene).unwrap();
        // Three beams on the deck, one on the back wall at 3 m: the plan
        // mean, at the median height (the deck's) plus FOCUS_HEIGHT.
        let focus =
            [Vec3::new(1.0, 0.0, 1.0), Vec3::new(-3.0, 0.0, 1.0), Vec3::new(0.0, 0.0, 3.0), Vec3::new(-2.0, 3.0, -5.0)];
        let p = stage_centre(&scene, &bounds, &focus);
        assert!(p.abs_diff_eq(Vec3::new(-1.0, FOCUS_HEIGHT, 0.0), 1e-6), "{p}");
        // No rig: the bounds' plan centre, FOCUS_HEIGHT above the floor below it.
        let p = stage_centre(&scene, &bounds, &[]);
        assert!(p.abs_diff_eq(Vec3::new(0.0, FOCUS_HEIGHT, 0.0), 1e-5), "{p}");
        // A focus inside the 4 m pillar: lifted in 0.5 m steps until out of it.
        let p = stage_centre(&scene, &bounds, &[Vec3::new(2.5, 0.0, 0.0)]);
        assert!(p.y >= 4.0 && p.y <= 4.5 && p.x == 2.5, "{p}");
        // A closed 2 m crate: the pivot leaves it.
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::lambert("grey", Vec3::splat(0.5)));
        add_box(&mut b, Vec3::new(-10.0, -0.1, -10.0), Vec3::new(10.0, 0.0, 10.0), m);
        add_box(&mut b, Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 2.0, 1.0), m);
        add_box(&mut b, Vec3::new(-0.1, 6.0, -0.1), Vec3::new(0.1, 6.1, 0.1), m);
        let crate_scene = b.build();
        let bounds = Bounds::of_scene(&crate_scene).unwrap();
        let p = stage_centre(&crate_scene, &bounds, &[Vec3::new(0.0, 0.0, 0.0)]);
        assert!(p.abs_diff_eq(Vec3::new(0.0, 2.0, 0.0), 1e-5), "{p}");
        let hit = focus_point(&crate_scene, Vec3::new(0.0, 5.0, 0.0), Vec3::NEG_Y).unwrap();
        assert!(hit.abs_diff_eq(Vec3::new(0.0, 2.0, 0.0), 1e-5), "{hit}");
        assert_eq!(focus_point(&crate_scene, Vec3::new(0.0, 5.0, 0.0), Vec3::X), None);
    }

    #[test]
    fn framing_fits_every_point_with_one_on_the_border() {
        // One point to the right of the centre: s = a / (fill · aspect · tan(fov/2)).
        let (fov, aspect, fill) = (50f32.to_radians(), 1.6, 0.9);
        let s = frame_distance(&[Vec3::new(2.0, 0.0, 0.0)], Vec3::ZERO, Vec3::NEG_Z, fov, aspect, fill);
        assert!((s - 2.0 / (fill * aspect * (fov / 2.0).tan())).abs() < 1e-5, "{s}");
        // Many points, looking down: each projects within the border, one on it.
        let forward = Vec3::new(0.3, -0.4, -1.0).normalize();
        let centre = Vec3::new(0.5, 1.0, -2.0);
        let points = [
            Vec3::new(-6.0, 0.0, -8.0),
            Vec3::new(6.0, 7.0, -8.0),
            Vec3::new(5.0, 0.0, 1.0),
            Vec3::new(-4.0, 6.5, 2.0),
            Vec3::new(0.0, 3.0, -3.0),
        ];
        let s = frame_distance(&points, centre, forward, fov, aspect, fill);
        let cam = Camera::look_at(centre - forward * s, centre, fov);
        let (w, h) = (1600.0, 1000.0);
        let mut worst = 0.0f32;
        for p in points {
            let local = cam.basis.transpose() * (p - cam.position);
            let depth = -local.z;
            assert!(depth > 0.0);
            let (u, v) = (local.x / depth / ((fov / 2.0).tan() * aspect), local.y / depth / (fov / 2.0).tan());
            worst = worst.max(u.abs()).max(v.abs());
            assert!(u.abs() <= fill + 1e-4 && v.abs() <= fill + 1e-4, "{p}: ({u}, {v})");
            // …and the camera's own ray through that pixel points at it.
            let px = (u + 1.0) * w / 2.0;
            let py = (1.0 - v) * h / 2.0;
            assert!(cam.direction(px, py, w as u32, h as u32).abs_diff_eq((p - cam.position).normalize(), 1e-4));
        }
        assert!((worst - fill).abs() < 1e-4, "tight: the outermost point sits on the border ({worst})");
        // fov_to_fit from the same eye gives the same field back.
        let back = fov_to_fit(&points, cam.position, centre, aspect, fill);
        assert!((back - fov).abs() < 1e-4, "{} vs {}", back.to_degrees(), fov.to_degrees());
        // A point straight up at depth z, height y: 2 atan(y / (fill z)).
        let f = fov_to_fit(&[Vec3::new(0.0, 3.0, -4.0)], Vec3::ZERO, Vec3::NEG_Z, 1.0, 1.0);
        assert!((f - 2.0 * 0.75f32.atan()).abs() < 1e-6);
        assert_eq!(fov_to_fit(&[Vec3::new(0.0, 3.0, 4.0)], Vec3::ZERO, Vec3::NEG_Z, 1.0, 1.0), 0.0, "behind the eye");
    }

    #[test]
    fn straight_down_is_not_degenerate() {
        let cam = Camera::look_at(Vec3::new(0.0, 5.0, 0.0), Vec3::ZERO, 0.7);
        assert!(cam.basis.is_finite());
        assert!((cam.direction(50.0, 50.0, 100, 100) - Vec3::NEG_Y).length() < 1e-5);
    }
}
