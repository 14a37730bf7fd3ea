//! Camera paths over the frames of a job: a turntable ([`CameraPath::Orbit`]) or keyframes from
//! a scene manifest's `animation` ([`CameraPath::Keyframes`]). [`Animation::camera`] gives frame
//! `k`'s camera; it is a pure function of its inputs in IEEE f64 (`libm` for trigonometry), so
//! every machine renders the same frames.

mod spline;

use crate::camera::Camera;
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
    /// Frame `frame`'s camera. `base` is the scene's camera for the image size
    /// ([`crate::scene::Scene::camera_for`]): what an orbit turns. Errors when `frame` is not
    /// below `frames`, or when the frame's camera cannot form a view (naming the frame).
    ///
    /// The animation is checked first ([`Animation::validate`]), so an invalid one is an error
    /// at every frame. An orbit's frame 0, and every frame of an orbit by 0 degrees, is `base`
    /// bit for bit; a keyframed path's camera at a key's frame is that key's camera bit for bit.
    pub fn camera(&self, base: &CameraSpec, frame: u32) -> Result<CameraSpec, SceneError> {
        self.validate()?;
        if frame >= self.frames {
            return Err(SceneError::Animation {
                detail: format!(
                    "frame {frame} is outside the animation's {} (0 to {})",
                    plural_frames(self.frames),
                    self.frames - 1
                ),
            });
        }
        let spec = match &self.path {
            CameraPath::Orbit { degrees } => orbit(base, *degrees, frame, self.frames),
            CameraPath::Keyframes { keys } => keyframed(keys, frame),
        };
        // An orbit by a huge angle overflows (a finite `degrees * frame` beyond f64).
        let finite = spec.eye.is_finite() && spec.look_at.is_finite();
        let problem = if finite {
            view_problem(&spec)
        } else {
            Some("the camera's position is not finite".into())
        };
        problem.map_or(Ok(spec), |detail| {
            Err(SceneError::Animation {
                detail: format!("animation frame {frame}: {detail}"),
            })
        })
    }

    /// Checks everything that can be checked without a base camera: `frames` is 1 to
    /// [`MAX_FRAMES`]; an orbit's `degrees` is finite; a keyframed path has at least one key,
    /// the keys' frames increase strictly and are below `frames`, and every key's camera is
    /// finite and forms a view (eye not at look_at, up not parallel to the view, the test of
    /// [`crate::camera::Camera::new`]) with a field of view between 0 and 180 degrees. The
    /// error names the keyframe by its index and frame.
    pub fn validate(&self) -> Result<(), SceneError> {
        self.problem().map_or(Ok(()), |p| {
            Err(SceneError::Animation {
                detail: p.to_string(),
            })
        })
    }

    /// The first problem [`Animation::validate`] reports, with where it lies.
    pub(crate) fn problem(&self) -> Option<Problem> {
        if self.frames == 0 || self.frames > MAX_FRAMES {
            return Some(Problem {
                at: Where::Frames,
                detail: format!("{} is not between 1 and {MAX_FRAMES}", self.frames),
            });
        }
        match &self.path {
            CameraPath::Orbit { degrees } => (!degrees.is_finite()).then(|| Problem {
                at: Where::Degrees,
                detail: format!("{degrees} is not a finite number"),
            }),
            CameraPath::Keyframes { keys } => {
                if keys.is_empty() {
                    return Some(Problem {
                        at: Where::Keys,
                        detail: "lists no keyframes (at least one is needed)".into(),
                    });
                }
                keys.iter().enumerate().find_map(|(index, key)| {
                    let previous = index.checked_sub(1).map(|i| (i, keys[i].frame));
                    key_problem(key, previous, self.frames).map(|detail| Problem {
                        at: Where::Key {
                            index,
                            frame: key.frame,
                        },
                        detail,
                    })
                })
            }
        }
    }
}

/// Where in an [`Animation`] a [`Problem`] lies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Where {
    /// `frames`.
    Frames,
    /// An orbit's `degrees`.
    Degrees,
    /// The list of keyframes as a whole.
    Keys,
    /// Keyframe `index`, at frame `frame`.
    Key { index: usize, frame: u32 },
}

/// Why an animation is invalid: where, and what is wrong there (a phrase without the place).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Problem {
    pub(crate) at: Where,
    pub(crate) detail: String,
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.at {
            Where::Frames => write!(f, "animation frames: {}", self.detail),
            Where::Degrees => write!(f, "animation orbit degrees: {}", self.detail),
            Where::Keys => write!(f, "animation {}", self.detail),
            Where::Key { index, frame } => write!(
                f,
                "animation keyframe {index} (frame {frame}): {}",
                self.detail
            ),
        }
    }
}

/// `n frames`, or `1 frame`.
fn plural_frames(n: u32) -> String {
    if n == 1 {
        "1 frame".into()
    } else {
        format!("{n} frames")
    }
}

/// What is wrong with `key` (the keyframe after `previous`, index and frame, if any) of an
/// animation of `frames` frames, if anything.
fn key_problem(key: &CameraKey, previous: Option<(usize, u32)>, frames: u32) -> Option<String> {
    if let Some((index, frame)) = previous
        && key.frame <= frame
    {
        return Some(format!(
            "frames must increase strictly, but keyframe {index} is at frame {frame}"
        ));
    }
    if key.frame >= frames {
        return Some(format!(
            "frame {} is outside the animation's {} (0 to {})",
            key.frame,
            plural_frames(frames),
            frames - 1
        ));
    }
    let c = &key.camera;
    for (name, v) in [("eye", c.eye), ("look_at", c.look_at), ("up", c.up)] {
        if !v.is_finite() {
            return Some(format!("{name} must be finite numbers"));
        }
    }
    let vfov = c.vfov_degrees;
    if !(vfov > 0.0 && vfov < 180.0) {
        return Some(format!("vfov {vfov} is not between 0 and 180 degrees"));
    }
    view_problem(c)
}

/// Why `spec` cannot form a view, by the test [`Camera::new`] applies (its message), if it
/// cannot.
fn view_problem(spec: &CameraSpec) -> Option<String> {
    match Camera::new(spec, 1, 1) {
        Ok(_) => None,
        Err(SceneError::Camera { detail }) => Some(detail),
        Err(other) => Some(other.to_string()),
    }
}

/// Frame `frame` of `frames` of a turn by `degrees` about the vertical axis through
/// `base.look_at`: counter-clockwise seen from above for positive degrees.
fn orbit(base: &CameraSpec, degrees: f64, frame: u32, frames: u32) -> CameraSpec {
    let turn = degrees * f64::from(frame) / f64::from(frames);
    if turn == 0.0 {
        return *base;
    }
    let angle = turn * (std::f64::consts::PI / 180.0);
    let (sin, cos) = (libm::sin(angle), libm::cos(angle));
    let (c, e) = (base.look_at, base.eye);
    let (dx, dz) = (e.x - c.x, e.z - c.z);
    // The right-handed turn about +y: x' = x cos + z sin, z' = z cos - x sin; the eye's height
    // is kept as it is, bit for bit.
    CameraSpec {
        eye: DVec3::new(
            c.x + (dx * cos + dz * sin),
            e.y,
            c.z + (dz * cos - dx * sin),
        ),
        ..*base
    }
}

/// The keyframed camera at `frame` (`keys` valid: non-empty, frames strictly increasing).
fn keyframed(keys: &[CameraKey], frame: u32) -> CameraSpec {
    let first = &keys[0];
    let last = &keys[keys.len() - 1];
    if frame <= first.frame {
        return first.camera;
    }
    if frame >= last.frame {
        return last.camera;
    }
    // The first key after `frame`; `frame` lies between keys i and i + 1, or at key i + 1.
    let next = keys.partition_point(|k| k.frame <= frame);
    let i = next - 1;
    let (a, b) = (&keys[i], &keys[next]);
    if a.frame == frame {
        return a.camera;
    }
    let u = f64::from(frame - a.frame) / f64::from(b.frame - a.frame);
    let neighbour = |j: Option<usize>| j.and_then(|j| keys.get(j));
    let before = neighbour(i.checked_sub(1));
    let after = neighbour(Some(next + 1));
    let path = |get: fn(&CameraSpec) -> DVec3| {
        spline::clamped_segment(
            before.map(|k| get(&k.camera)),
            get(&a.camera),
            get(&b.camera),
            after.map(|k| get(&k.camera)),
            u,
        )
    };
    let up = lerp(a.camera.up, b.camera.up, u);
    let up_length = up.length();
    let vfov = a.camera.vfov_degrees + (b.camera.vfov_degrees - a.camera.vfov_degrees) * u;
    let (vlo, vhi) = (
        a.camera.vfov_degrees.min(b.camera.vfov_degrees),
        a.camera.vfov_degrees.max(b.camera.vfov_degrees),
    );
    CameraSpec {
        eye: path(|c| c.eye),
        look_at: path(|c| c.look_at),
        // A zero `up` (opposite keys halfway) stays zero, for the view check to refuse.
        up: if up_length > 0.0 { up / up_length } else { up },
        vfov_degrees: vfov.max(vlo).min(vhi),
    }
}

/// `a + (b - a) u`, per coordinate: exactly `a` where `a == b`.
fn lerp(a: DVec3, b: DVec3, u: f64) -> DVec3 {
    a + (b - a) * u
}

#[cfg(test)]
mod tests;
