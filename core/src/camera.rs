//! The pinhole camera of DESIGN.md. Ray directions are computed in f64 and rounded once to f32:
//! for pixel position (px, py) (pixel centre at x + 0.5), with tan = tan(vfov / 2),
//! dir = normalize(f + ((2·px/W - 1)·tan·W/H)·r + ((1 - 2·py/H)·tan)·u), row 0 at the top.

use crate::error::SceneError;
use crate::scene::CameraSpec;
use crate::triangle::Ray;
use glam::DVec3;

/// A camera ready to generate rays for a `width` x `height` image.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    eye: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    tan_half: f64,
    width: f64,
    height: f64,
}

impl Camera {
    /// Errors when the eye is at the target or `up` is parallel to the view direction.
    pub fn new(spec: &CameraSpec, width: u32, height: u32) -> Result<Camera, SceneError> {
        let view = spec.look_at - spec.eye;
        if view.length() <= 0.0 {
            return Err(SceneError::Camera {
                detail: "eye and look_at are the same point".into(),
            });
        }
        let forward = view / view.length();
        let side = forward.cross(spec.up);
        if side.length() <= 1e-12 * spec.up.length() || !side.is_finite() {
            return Err(SceneError::Camera {
                detail: "up is parallel to the view direction (or zero)".into(),
            });
        }
        let right = side / side.length();
        let up = right.cross(forward);
        let half = spec.vfov_degrees * (std::f64::consts::PI / 180.0) / 2.0;
        Ok(Camera {
            eye: spec.eye,
            forward,
            right,
            up,
            tan_half: libm::tan(half),
            width: f64::from(width),
            height: f64::from(height),
        })
    }

    /// The eye position.
    pub fn eye(&self) -> DVec3 {
        self.eye
    }

    /// The (not normalized) direction through image position (px, py), in f64.
    #[inline]
    pub fn direction(&self, px: f64, py: f64) -> DVec3 {
        let sx = (2.0 * px / self.width - 1.0) * self.tan_half * self.width / self.height;
        let sy = (1.0 - 2.0 * py / self.height) * self.tan_half;
        self.forward + sx * self.right + sy * self.up
    }

    /// The ray through image position (px, py) in pixel units (pixel x's centre is x + 0.5).
    #[inline]
    pub fn ray(&self, px: f64, py: f64) -> Ray {
        let d = self.direction(px, py);
        let d = d / (d.x * d.x + d.y * d.y + d.z * d.z).sqrt();
        Ray {
            origin: self.eye.as_vec3(),
            dir: d.as_vec3(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_looks_at_target_and_rows_go_down() {
        let spec = CameraSpec {
            eye: DVec3::new(0.0, 0.0, 5.0),
            look_at: DVec3::ZERO,
            up: DVec3::Y,
            vfov_degrees: 45.0,
        };
        let cam = Camera::new(&spec, 4, 2).unwrap();
        assert_eq!(cam.ray(2.0, 1.0).dir, glam::Vec3::new(0.0, 0.0, -1.0));
        assert!(cam.ray(0.5, 0.5).dir.y > 0.0, "row 0 is the top");
        assert!(cam.ray(0.5, 0.5).dir.x < 0.0, "column 0 is the left");
    }

    #[test]
    fn degenerate_cameras_are_errors() {
        let mut spec = CameraSpec {
            eye: DVec3::ONE,
            look_at: DVec3::ONE,
            up: DVec3::Y,
            vfov_degrees: 45.0,
        };
        let e = Camera::new(&spec, 4, 2).unwrap_err().to_string();
        assert_eq!(e, "invalid camera: eye and look_at are the same point");
        spec.look_at = DVec3::new(1.0, 5.0, 1.0);
        let e = Camera::new(&spec, 4, 2).unwrap_err().to_string();
        assert_eq!(
            e,
            "invalid camera: up is parallel to the view direction (or zero)"
        );
    }
}
