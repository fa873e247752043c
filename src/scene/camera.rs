//! Pinhole camera: turns a pixel and a sub-pixel offset into a primary ray.
//!
//! The camera comes from the glTF file (its first perspective camera node)
//! or from the patch's `[camera]` table; both follow glTF's convention of
//! looking along local −Z with +Y up.

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

    #[test]
    fn straight_down_is_not_degenerate() {
        let cam = Camera::look_at(Vec3::new(0.0, 5.0, 0.0), Vec3::ZERO, 0.7);
        assert!(cam.basis.is_finite());
        assert!((cam.direction(50.0, 50.0, 100, 100) - Vec3::NEG_Y).length() < 1e-5);
    }
}
