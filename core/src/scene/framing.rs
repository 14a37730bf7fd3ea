//! The documented defaults (docs/ARCHITECTURE.md, "Default scene"): a camera that frames the
//! scene's bounding box and one point light above it.

use super::mesh::Mesh;
use super::{CameraSpec, Light};
use crate::error::SceneError;
use glam::DVec3;
use std::path::Path;

/// Axis-aligned bounds (min, max) of the vertices used by triangles, in f64.
/// Errors when the scene has no triangles or no extent.
pub fn scene_bounds(mesh: &Mesh, path: &Path) -> Result<(DVec3, DVec3), SceneError> {
    if mesh.triangles.is_empty() {
        return Err(SceneError::Empty {
            path: path.to_path_buf(),
        });
    }
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for tri in &mesh.triangles {
        for &i in tri {
            let p = mesh.positions[i as usize].as_dvec3();
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    if (hi - lo).length() <= 0.0 {
        return Err(SceneError::NoExtent {
            path: path.to_path_buf(),
        });
    }
    Ok((lo, hi))
}

/// With c the bounds' centre and D their diagonal length: eye = c + (0, 0.5, 1.25)·D, looking at
/// c, up +y, vertical field of view 45 degrees. The bounding sphere (radius D/2) fits the vertical
/// field of view, and so the horizontal one of any landscape or square image; see
/// [`framed_camera`] for the camera of a given image size.
pub fn default_camera(lo: DVec3, hi: DVec3) -> CameraSpec {
    let c = (lo + hi) * 0.5;
    let d = (hi - lo).length();
    CameraSpec {
        eye: c + DVec3::new(0.0, 0.5, 1.25) * d,
        look_at: c,
        up: DVec3::Y,
        vfov_degrees: 45.0,
    }
}

/// The automatic camera for a `width` x `height` image. Landscape and square images
/// (`width >= height`) get [`default_camera`] unchanged. For portrait images the eye moves back
/// from c along the same direction until the bounding sphere (centre c, radius D/2) also fits the
/// horizontal field of view: its distance from c becomes (D/2) / sin(h), with h the horizontal
/// half angle, atan(tan(22.5 degrees)·W/H), when that is farther than the default distance.
pub fn framed_camera(lo: DVec3, hi: DVec3, width: u32, height: u32) -> CameraSpec {
    let camera = default_camera(lo, hi);
    if width >= height || width == 0 {
        return camera;
    }
    let c = camera.look_at;
    let offset = camera.eye - c;
    let distance = offset.length();
    let radius = (hi - lo).length() / 2.0;
    let half = camera.vfov_degrees * (std::f64::consts::PI / 180.0) / 2.0;
    let tan_h = libm::tan(half) * f64::from(width) / f64::from(height);
    let sin_h = tan_h / (1.0 + tan_h * tan_h).sqrt();
    let needed = radius / sin_h;
    if needed <= distance {
        return camera;
    }
    CameraSpec {
        eye: c + offset * (needed / distance),
        ..camera
    }
}

/// One white point light at c + (0.5, 1.0, 0.8)·D with radiant intensity pi·|light - c|^2, so a
/// white surface at c facing the light has radiance 1.
pub fn default_light(lo: DVec3, hi: DVec3) -> Light {
    let c = (lo + hi) * 0.5;
    let d = (hi - lo).length();
    let position = c + DVec3::new(0.5, 1.0, 0.8) * d;
    let intensity = (std::f64::consts::PI * (position - c).length_squared()) as f32;
    Light::Point {
        position,
        intensity: [intensity; 3],
    }
}
