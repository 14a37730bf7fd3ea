//! What a caller asks of a camera path (`hort render --frames/--frame/--orbit`, `POST /renders`
//! `frames`/`frame`/`orbit`), resolved against the scene in one place, so that both front ends
//! accept the same requests and refuse the same ones; each words the refusal with its own
//! names for the fields.

use super::frame_choice::{FrameChoice, Orbit};
use crate::scene::Scene;
use std::ops::Range;

/// The frames a caller asks for, before they are checked against the scene.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameRequest {
    /// Frames `A..B` (a count N is `0..N`); with `orbit`, its end is the turn's frame count.
    pub frames: Option<Range<u32>>,
    /// Frame K alone (of `frames`' turn, with an orbit).
    pub frame: Option<u32>,
    /// A turntable of this many degrees over the frames.
    pub orbit: Option<f64>,
}

/// The frames one run renders and the camera path they follow.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameSelection {
    /// The frames, ascending.
    pub frames: Range<u32>,
    /// The turntable, if asked; else the scene's own animation (or none).
    pub orbit: Option<Orbit>,
    /// Whether the request names frames at all: a single frame of an animated run is still
    /// reported as a frame.
    pub animated: bool,
}

/// Why a [`FrameRequest`] cannot be rendered.
#[derive(Clone, Debug, PartialEq)]
pub enum FrameRequestError {
    /// The turn is NaN or infinite.
    OrbitNotFinite(f64),
    /// A turn without `frames`, which give its frame count.
    OrbitWithoutFrames,
    /// Frames asked of a scene that has no camera path.
    NoAnimation,
    /// A frame past the path's end.
    OutsideAnimation {
        /// Whether `frame` (rather than `frames`) asked for it.
        by_frame: bool,
        /// The last frame asked for.
        last: u32,
        /// The path's frame count.
        total: u32,
    },
}

impl FrameRequest {
    /// The frames this request asks of `scene` (`None`: a scene not loaded by the caller,
    /// which must then be a still image or an orbit), checked before any work: the orbit is
    /// finite and has its frame count, and every frame lies on its path.
    pub fn resolve(&self, scene: Option<&Scene>) -> Result<FrameSelection, FrameRequestError> {
        let orbit = match self.orbit {
            None => None,
            Some(degrees) if !degrees.is_finite() => {
                return Err(FrameRequestError::OrbitNotFinite(degrees));
            }
            Some(degrees) => {
                let frames = self
                    .frames
                    .as_ref()
                    .ok_or(FrameRequestError::OrbitWithoutFrames)?;
                Some(Orbit {
                    degrees,
                    frames: frames.end,
                })
            }
        };
        let total = match orbit {
            Some(o) => Some(o.frames),
            None => scene
                .and_then(|s| FrameChoice::STILL.animation(s))
                .map(|a| a.frames),
        };
        let animated = self.frames.is_some() || self.frame.is_some() || orbit.is_some();
        let frames = match (self.frame, &self.frames) {
            (Some(k), _) => k..k.saturating_add(1),
            (None, Some(range)) => range.clone(),
            (None, None) => 0..1,
        };
        match total {
            Some(total) if frames.end > total => Err(FrameRequestError::OutsideAnimation {
                by_frame: self.frame.is_some(),
                last: frames.end - 1,
                total,
            }),
            None if animated && scene.is_some() => Err(FrameRequestError::NoAnimation),
            _ => Ok(FrameSelection {
                frames,
                orbit,
                animated,
            }),
        }
    }
}

impl FrameSelection {
    /// Frame `index` alone, along this selection's path.
    pub fn choice(&self, index: u32) -> FrameChoice {
        FrameChoice::new(index, self.orbit)
    }

    /// All the frames, as one job renders them.
    pub fn job_choice(&self) -> FrameChoice {
        FrameChoice::range(self.frames.clone(), self.orbit)
    }

    /// How many frames the run renders (at least 1).
    pub fn count(&self) -> u32 {
        self.frames.end - self.frames.start
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::animation::{Animation, CameraPath};
    use crate::terminator::sphere_scene;

    fn request(frames: Option<Range<u32>>, frame: Option<u32>, orbit: Option<f64>) -> FrameRequest {
        FrameRequest {
            frames,
            frame,
            orbit,
        }
    }

    /// A scene whose own path is a 5-frame turn.
    fn animated() -> Scene {
        Scene {
            animation: Some(Animation {
                frames: 5,
                path: CameraPath::Orbit { degrees: 30.0 },
            }),
            ..sphere_scene(4, 8)
        }
    }

    #[test]
    fn a_request_without_frames_is_one_still_frame() {
        let still = request(None, None, None).resolve(Some(&sphere_scene(4, 8)));
        let want = FrameSelection {
            frames: 0..1,
            orbit: None,
            animated: false,
        };
        assert_eq!(still, Ok(want.clone()));
        assert_eq!(want.job_choice(), FrameChoice::STILL);
    }

    #[test]
    fn frames_follow_the_orbit_or_else_the_scene_path() {
        let orbit = request(Some(2..6), None, Some(90.0)).resolve(None).unwrap();
        assert_eq!(orbit.frames, 2..6);
        assert_eq!(
            orbit.orbit,
            Some(Orbit {
                degrees: 90.0,
                frames: 6
            })
        );
        assert_eq!(orbit.count(), 4);
        assert_eq!(orbit.job_choice(), FrameChoice::range(2..6, orbit.orbit));
        let own = request(None, Some(4), None)
            .resolve(Some(&animated()))
            .unwrap();
        assert_eq!((own.frames, own.orbit, own.animated), (4..5, None, true));
        // A scene the caller did not load: frames are taken as asked (the plan checks them).
        let unloaded = request(Some(0..3), None, None).resolve(None).unwrap();
        assert_eq!(unloaded.frames, 0..3);
    }

    #[test]
    fn each_refusal_names_what_is_wrong() {
        let still = sphere_scene(4, 8);
        assert!(matches!(
            request(Some(0..4), None, Some(f64::NAN)).resolve(Some(&still)),
            Err(FrameRequestError::OrbitNotFinite(d)) if d.is_nan()
        ));
        assert_eq!(
            request(Some(0..4), None, Some(f64::INFINITY)).resolve(Some(&still)),
            Err(FrameRequestError::OrbitNotFinite(f64::INFINITY))
        );
        assert_eq!(
            request(None, Some(1), Some(45.0)).resolve(Some(&still)),
            Err(FrameRequestError::OrbitWithoutFrames)
        );
        assert_eq!(
            request(Some(0..3), None, None).resolve(Some(&still)),
            Err(FrameRequestError::NoAnimation)
        );
        assert_eq!(
            request(None, Some(0), None).resolve(Some(&still)),
            Err(FrameRequestError::NoAnimation)
        );
        assert_eq!(
            request(Some(0..4), Some(4), Some(90.0)).resolve(Some(&still)),
            Err(FrameRequestError::OutsideAnimation {
                by_frame: true,
                last: 4,
                total: 4
            })
        );
        assert_eq!(
            request(Some(3..7), None, None).resolve(Some(&animated())),
            Err(FrameRequestError::OutsideAnimation {
                by_frame: false,
                last: 6,
                total: 5
            })
        );
    }
}
