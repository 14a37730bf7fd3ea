//! Which frame of which camera path one render shows: the one place a render's camera is
//! chosen, for the monolithic renderer and the planned job alike, so frame K of an animation
//! is the same image whichever way it is rendered.

use crate::animation::{Animation, CameraPath};
use crate::error::SceneError;
use crate::scene::{CameraSpec, Scene};
use serde::{Deserialize, Serialize};

/// The frame a render shows: its index, and the turntable it belongs to, if any. A request
/// without one (`FrameChoice::STILL`) renders the scene's camera with a still image's samples.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameChoice {
    /// The (first) frame's index; its sample streams ([`crate::camera::Camera::with_frame`]).
    #[serde(default)]
    pub index: u32,
    /// How many frames from `index` one job renders (1: one image, absent from the JSON).
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub count: u32,
    /// A turntable (`--orbit`); `None` follows the scene's own animation, if it has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orbit: Option<Orbit>,
}

/// A turntable: the eye turns `degrees` about the vertical axis through the framing target
/// over `frames` frames ([`CameraPath::Orbit`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Orbit {
    /// The whole turn, degrees.
    pub degrees: f64,
    /// Frames in the whole turn.
    pub frames: u32,
}

impl FrameChoice {
    /// A still image: frame 0, no camera path.
    pub const STILL: FrameChoice = FrameChoice {
        index: 0,
        count: 1,
        orbit: None,
    };

    /// Frame `index` of the turntable `orbit`, or of the scene's own animation when `None`.
    pub fn new(index: u32, orbit: Option<Orbit>) -> FrameChoice {
        FrameChoice {
            index,
            count: 1,
            orbit,
        }
    }

    /// Frames `frames` (one job renders them all) of the turntable `orbit`, or of the scene's
    /// own animation when `None`.
    pub fn range(frames: std::ops::Range<u32>, orbit: Option<Orbit>) -> FrameChoice {
        FrameChoice {
            index: frames.start,
            count: frames.end.saturating_sub(frames.start).max(1),
            orbit,
        }
    }

    /// The frames this choice renders, ascending.
    pub fn frames(&self) -> std::ops::Range<u32> {
        self.index..self.index.saturating_add(self.count.max(1))
    }

    /// Frame `frame` alone, on the same path.
    pub fn at(&self, frame: u32) -> FrameChoice {
        FrameChoice::new(frame, self.orbit)
    }

    /// True for [`FrameChoice::STILL`] (left out of the job request's JSON).
    pub fn is_still(&self) -> bool {
        *self == FrameChoice::STILL
    }

    /// The camera path this choice follows in `scene`: the turntable, else the scene's own
    /// animation, else none.
    pub fn animation(&self, scene: &Scene) -> Option<Animation> {
        match self.orbit {
            Some(orbit) => Some(Animation {
                frames: orbit.frames,
                path: CameraPath::Orbit {
                    degrees: orbit.degrees,
                },
            }),
            None => scene_animation(scene),
        }
    }

    /// The camera of this choice's (first) frame for a `width` x `height` image of `scene`:
    /// the scene's camera for that size ([`Scene::camera_for`]) moved along the camera path.
    /// Errors when the frame is not one of the path's, or, without a path, is not frame 0.
    pub fn camera(&self, scene: &Scene, width: u32, height: u32) -> Result<CameraSpec, SceneError> {
        let base = scene.camera_for(width, height);
        match self.animation(scene) {
            Some(animation) => {
                animation.validate()?;
                animation.camera(&base, self.index)
            }
            None if self.index == 0 => Ok(base),
            None => Err(SceneError::Animation {
                detail: format!(
                    "frame {} asked of a scene without an animation (give an orbit, or a \
                     manifest \"animation\")",
                    self.index
                ),
            }),
        }
    }
}

impl Default for FrameChoice {
    fn default() -> Self {
        FrameChoice::STILL
    }
}

fn one() -> u32 {
    1
}

fn is_one(v: &u32) -> bool {
    *v == 1
}

/// The scene's own camera path (a manifest's `animation`).
fn scene_animation(scene: &Scene) -> Option<Animation> {
    scene.animation.clone()
}
