//! The pinhole camera of a scene: pixel `(x, y)` with `y = 0` the top row, box filter.

use crate::TracerError;
use glam::{DVec3, Vec3};
use prt_scene::Camera;

/// Precomputed pinhole camera (`fov_y_deg` is the full vertical field of view).
#[derive(Clone, Copy, Debug)]
pub struct PinholeCamera {
    eye: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    tan_half_y: f64,
    aspect: f64,
    width: u32,
    height: u32,
}

impl PinholeCamera {
    /// Checks and prepares a camera.
    ///
    /// # Errors
    /// When the image is empty, the field of view is not in `(0°, 180°)`, the eye equals the
    /// target, `up` is parallel to the view direction, or a value is not finite.
    pub fn new(camera: &Camera) -> Result<Self, TracerError> {
        let bad = |s: &str| Err(TracerError::InvalidSettings(format!("camera: {s}")));
        if camera.width == 0 || camera.height == 0 {
            return bad("image size must be at least 1×1");
        }
        if !(camera.fov_y_deg > 0.0 && camera.fov_y_deg < 180.0) {
            return bad("fov_y must be strictly between 0 and 180 degrees");
        }
        if !(camera.eye.is_finite() && camera.target.is_finite() && camera.up.is_finite()) {
            return bad("eye, target and up must be finite");
        }
        let forward = (camera.target - camera.eye).normalize_or_zero();
        if forward == DVec3::ZERO {
            return bad("eye and target coincide");
        }
        let right = forward.cross(camera.up).normalize_or_zero();
        if right == DVec3::ZERO || forward.cross(camera.up.normalize()).length() < 1e-9 {
            return bad("up is parallel to the view direction");
        }
        let up = right.cross(forward);
        Ok(Self {
            eye: camera.eye,
            forward,
            right,
            up,
            tan_half_y: (camera.fov_y_deg.to_radians() * 0.5).tan(),
            aspect: f64::from(camera.width) / f64::from(camera.height),
            width: camera.width,
            height: camera.height,
        })
    }

    /// Image width in pixels.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Image height in pixels.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Eye position.
    #[must_use]
    pub fn eye(&self) -> Vec3 {
        self.eye.as_vec3()
    }

    /// Unit direction through image-plane position `(x, y)` in pixels (`(0, 0)` the top-left
    /// corner of the top-left pixel; a pixel's box filter is `x + jitter`, jitter in `[0, 1)`).
    #[must_use]
    pub fn direction(&self, x: f64, y: f64) -> Vec3 {
        let sx = (2.0 * x / f64::from(self.width) - 1.0) * self.tan_half_y * self.aspect;
        let sy = (1.0 - 2.0 * y / f64::from(self.height)) * self.tan_half_y;
        (self.forward + self.right * sx + self.up * sy)
            .normalize()
            .as_vec3()
    }
}
