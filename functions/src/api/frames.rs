//! The frames of `POST /renders` (`frames`, `frame`, `orbit`): which frames of which camera
//! path one job renders, checked against the scene before anything is started, with the rules
//! and limits of `hort render --frames/--frame/--orbit`.

use super::RequestScene;
use super::error::ApiError;
use super::request::RenderRequest;
use hort_core::animation::MAX_FRAMES;
use hort_core::camera::Camera;
use hort_core::error::SceneError;
use hort_core::pipeline::{FrameChoice, FrameRequest, FrameRequestError};
use hort_core::predict::check_combine_time;
use hort_core::scene::{Scene, animation_from};

/// The frames `request` asks of `scene` at `width` x `height`: every frame on its path, every
/// frame's camera able to form a view, and all within what one job's Combine task assembles.
/// Errors name the field at fault.
pub(super) fn frame_choice(
    request: &RenderRequest,
    scene: &Scene,
    width: u32,
    height: u32,
) -> Result<FrameChoice, ApiError> {
    if let Some(n) = request.frames
        && !(1..=MAX_FRAMES).contains(&n)
    {
        return Err(ApiError::invalid_field(
            "frames",
            format!("frames: {n} is out of range: must be 1 to {MAX_FRAMES}"),
        ));
    }
    let asked = FrameRequest {
        frames: request.frames.map(|n| 0..n),
        frame: request.frame,
        orbit: request.orbit,
    };
    let frames = asked.resolve(Some(scene)).map_err(|e| match e {
        FrameRequestError::OrbitNotFinite(degrees) => ApiError::invalid_field(
            "orbit",
            format!("orbit: {degrees} is not a finite number of degrees"),
        ),
        FrameRequestError::OrbitWithoutFrames => {
            ApiError::invalid_field("frames", "frames: an orbit needs its number of frames")
        }
        FrameRequestError::NoAnimation => ApiError::invalid_field(
            "frames",
            "frames: the scene has no animation; give orbit, or an \"animation\" in its \
                 manifest",
        ),
        FrameRequestError::OutsideAnimation {
            by_frame,
            last,
            total,
        } => {
            let field = if by_frame { "frame" } else { "frames" };
            ApiError::invalid_field(
                field,
                format!(
                    "{field}: frame {last} is outside the animation's {total} frames (0 to {})",
                    total - 1
                ),
            )
        }
    })?;
    check_combine_time(width, height, frames.count())
        .map_err(|e| ApiError::invalid_field("frames", format!("frames: {e}")))?;
    let choice = frames.job_choice();
    for frame in choice.frames() {
        choice
            .at(frame)
            .camera(scene, width, height)
            .and_then(|camera| Camera::new(&camera, width, height))
            .map_err(|e| ApiError::invalid_scene(format!("frame {frame}: {e}")))?;
    }
    Ok(choice)
}

/// Puts the request's `animation` (keyframes in world coordinates, as a manifest's) into the
/// scene given inline, in its local frame, replacing the scene's own: the binary scene the job
/// uploads then carries it. A scene given by key takes its animation from its manifest only
/// (the Plan function loads it), and an `animation` with an `orbit` is two camera paths.
pub(super) fn take_request_animation(
    request: &RenderRequest,
    loaded: &mut RequestScene,
) -> Result<(), ApiError> {
    let Some(animation) = &request.animation else {
        return Ok(());
    };
    if request.orbit.is_some() {
        return Err(ApiError::invalid_field(
            "animation",
            "animation: give one camera path, an orbit or keyframes",
        ));
    }
    let RequestScene::Loaded(loaded) = loaded else {
        return Err(ApiError::invalid_field(
            "animation",
            "animation: a scene given by key takes its animation from its manifest; give the \
             scene inline to animate it from the request",
        ));
    };
    let scene = &mut loaded.scene;
    let path = std::path::Path::new("request");
    scene.animation = Some(
        animation_from(animation, scene.origin, path).map_err(|e| match e {
            SceneError::Manifest { field, detail, .. } => {
                ApiError::invalid_field(field.clone(), format!("{field}: {detail}"))
            }
            other => ApiError::invalid_field("animation", format!("animation: {other}")),
        })?,
    );
    Ok(())
}
