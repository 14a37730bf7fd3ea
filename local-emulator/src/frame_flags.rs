//! The animation flags of `hort render` (`--frames`, `--frame`, `--orbit`): which frames of
//! which camera path a run renders, resolved against the scene before any work.

use anyhow::{Result, anyhow};
use clap::Args;
use hort_core::animation::MAX_FRAMES;
use hort_core::pipeline::{FrameRequest, FrameRequestError, FrameSelection};
use hort_core::predict::check_combine_time;
use hort_core::scene::Scene;
use std::str::FromStr;

/// The animation flags.
#[derive(Args, Clone, Debug, Default)]
pub struct FrameFlags {
    /// Frames to render: N (frames 0 to N-1; with --orbit, the turn's frame count) or A..B
    /// (frames A to B-1 of the scene's animation, or of an --orbit turn of B frames). Several
    /// frames need a `#` run in --out (and --hits), which each frame's number replaces,
    /// zero-padded: --out 'shots/turn_####.png'.
    #[arg(long, value_name = "N|A..B")]
    pub frames: Option<FrameSpan>,
    /// Render frame K alone (with --orbit, of the --frames N turn): the same image as frame K
    /// of a run of all the frames.
    #[arg(long, value_name = "K", allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(0..i64::from(MAX_FRAMES)))]
    pub frame: Option<u32>,
    /// A turntable: the eye turns DEGREES about the vertical axis through the framed target
    /// over the frames (needs --frames).
    #[arg(
        long,
        value_name = "DEGREES",
        allow_negative_numbers = true,
        requires = "frames"
    )]
    pub orbit: Option<f64>,
}

/// `--frames`: a count, or a half-open range of frame indices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameSpan {
    /// `N`: frames `0..N`.
    Count(u32),
    /// `A..B`: frames `A..B`.
    Range(u32, u32),
}

impl FromStr for FrameSpan {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        let number = |t: &str| {
            t.trim()
                .parse::<u32>()
                .map_err(|_| format!("`{text}` is not N or A..B (frame numbers from 0)"))
        };
        let span = match text.split_once("..") {
            Some((a, b)) => FrameSpan::Range(number(a)?, number(b)?),
            None => FrameSpan::Count(number(text)?),
        };
        let (start, end) = span.bounds();
        if start >= end {
            return Err(format!("`{text}` holds no frame"));
        }
        if end > MAX_FRAMES {
            return Err(format!("`{text}`: at most {MAX_FRAMES} frames"));
        }
        Ok(span)
    }
}

impl FrameSpan {
    fn bounds(self) -> (u32, u32) {
        match self {
            FrameSpan::Count(n) => (0, n),
            FrameSpan::Range(a, b) => (a, b),
        }
    }
}

impl FrameFlags {
    /// The frames these flags ask of `scene` (`None`: a scene not loaded here, which must then
    /// be a still image or an orbit), checked before any work: every frame exists on its path.
    pub fn plan(&self, scene: Option<&Scene>) -> Result<FrameSelection> {
        let request = FrameRequest {
            frames: self.frames.map(|span| {
                let (a, b) = span.bounds();
                a..b
            }),
            frame: self.frame,
            orbit: self.orbit,
        };
        request.resolve(scene).map_err(|e| match e {
            FrameRequestError::OrbitNotFinite(degrees) => {
                anyhow!("--orbit {degrees}: the turn must be a finite number of degrees")
            }
            FrameRequestError::OrbitWithoutFrames => {
                anyhow!("--orbit: the turn needs its number of frames (--frames N)")
            }
            FrameRequestError::NoAnimation => anyhow!(
                "--frames/--frame: the scene has no animation; give --orbit DEGREES, or an \
                 \"animation\" in its manifest"
            ),
            FrameRequestError::OutsideAnimation { last, total, .. } => anyhow!(
                "--frames/--frame: frame {last} is outside the animation's {total} frames (0 to {})",
                total - 1
            ),
        })
    }
}

/// Checks that one job can render `frames` at `width` x `height` (its Combine task assembles
/// them all within the state machine's timeout), before any work. A monolithic run has no
/// such limit.
pub fn check_one_job(frames: &FrameSelection, width: u32, height: u32) -> Result<()> {
    check_combine_time(width, height, frames.count()).map_err(|e| anyhow!("--frames: {e}"))
}
