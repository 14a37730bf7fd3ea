//! Camera paths over the frames of a job: a turntable ([`CameraPath::Orbit`]) or keyframes from
//! a scene manifest's `animation` ([`CameraPath::Keyframes`]). [`Animation::camera`] gives frame
//! `k`'s camera; it is a pure function of its inputs in IEEE f64 (`libm` for trigonometry), so
//! every machine renders the same frames.

use crate::error::SceneError;
use crate::scene::CameraSpec;
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// The most frames one job may have.
pub const MAX_FRAMES: u32 = 100_000;

/// How the camera moves over the frames.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum CameraPath {
    /// A turntable: frame `k` of `n` turns the eye of the base camera by `degrees * k / n` about
    /// the vertical axis (+y) through the base camera's `look_at`; frame 0 is the base camera.
    Orbit {
        /// The turn over all `n` frames (360: a loop whose frame `n` would be frame 0).
        degrees: f64,
    },
    /// Keyframes, in increasing frame order, interpolated between (positions along a
    /// centripetal Catmull-Rom spline that never leaves the bounds of the two keys of a segment,
    /// field of view linearly); before the first key and after the last the camera holds.
    Keyframes {
        /// At least one.
        keys: Vec<CameraKey>,
    },
}

/// The camera at one frame of a keyframed path, in the scene's local frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraKey {
    /// The frame this key holds at.
    pub frame: u32,
    /// The camera at that frame.
    pub camera: CameraSpec,
}

/// A job's frames and how its camera moves over them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Animation {
    /// Frames in the whole animation, 1 to [`MAX_FRAMES`].
    pub frames: u32,
    /// How the camera moves.
    pub path: CameraPath,
}

impl Animation {
    /// Checks what can be checked before any frame is rendered.
    pub fn validate(&self) -> Result<(), SceneError> {
        if self.frames == 0 || self.frames > MAX_FRAMES {
            return Err(SceneError::Camera {
                detail: format!(
                    "an animation has 1 to {MAX_FRAMES} frames, not {}",
                    self.frames
                ),
            });
        }
        match &self.path {
            CameraPath::Orbit { degrees } if !degrees.is_finite() => Err(SceneError::Camera {
                detail: format!("an orbit of {degrees} degrees"),
            }),
            _ => Ok(()),
        }
    }

    /// Frame `frame`'s camera. `base` is the scene's camera for the image size
    /// ([`crate::scene::Scene::camera_for`]): what an orbit turns. Errors when `frame` is not
    /// below `frames`, or when the frame's camera cannot form a view (naming the frame).
    pub fn camera(&self, base: &CameraSpec, frame: u32) -> Result<CameraSpec, SceneError> {
        if frame >= self.frames {
            return Err(SceneError::Camera {
                detail: format!(
                    "frame {frame} is outside the animation's {} frames (0 to {})",
                    self.frames,
                    self.frames.saturating_sub(1)
                ),
            });
        }
        match &self.path {
            CameraPath::Orbit { degrees } => Ok(orbit(
                base,
                degrees * f64::from(frame) / f64::from(self.frames),
            )),
            CameraPath::Keyframes { .. } => Err(SceneError::Camera {
                detail: "keyframed camera paths are not rendered yet".into(),
            }),
        }
    }
}

/// `base` with its eye turned by `degrees` about the vertical axis (+y) through its `look_at`,
/// counter-clockwise seen from above; `base` itself, bit for bit, at 0 degrees.
fn orbit(base: &CameraSpec, degrees: f64) -> CameraSpec {
    if degrees == 0.0 {
        return *base;
    }
    let angle = degrees * (std::f64::consts::PI / 180.0);
    let (sin, cos) = (libm::sin(angle), libm::cos(angle));
    let offset = base.eye - base.look_at;
    // Counter-clockwise from above (+y): x' = x cos + z sin, z' = -x sin + z cos.
    let turned = DVec3::new(
        offset.x * cos + offset.z * sin,
        offset.y,
        offset.z * cos - offset.x * sin,
    );
    CameraSpec {
        eye: base.look_at + turned,
        ..*base
    }
}
