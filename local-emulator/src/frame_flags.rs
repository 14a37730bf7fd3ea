//! The animation flags of `hort render` (`--frames`, `--frame`, `--orbit`): which frames of
//! which camera path a run renders, resolved against the scene before any work.

use anyhow::{Result, anyhow, bail};
use clap::Args;
use hort_core::animation::MAX_FRAMES;
use hort_core::pipeline::{FrameChoice, Orbit};
use hort_core::predict::check_combine_time;
use hort_core::scene::Scene;
use std::ops::Range;
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

/// What a run renders: the frames, and the camera path they follow.
#[derive(Clone, Debug, PartialEq)]
pub struct FramePlan {
    /// The frames, ascending.
    pub frames: Range<u32>,
    /// The turntable, if `--orbit`; else the scene's own animation (or none).
    pub orbit: Option<Orbit>,
    /// Whether the run names frames at all (any of the flags): a single frame of an animated
    /// run is still reported as a frame.
    pub animated: bool,
}

impl FramePlan {
    /// The choice of frame `index` along this plan's path.
    pub fn choice(&self, index: u32) -> FrameChoice {
        FrameChoice::new(index, self.orbit)
    }

    /// How many frames the run renders.
    pub fn len(&self) -> u32 {
        self.frames.end - self.frames.start
    }
}

impl FrameFlags {
    /// The frames these flags ask of `scene` (`None`: a scene not loaded here, which must then
    /// be a still image or an orbit), checked before any work: every frame exists on its path.
    pub fn plan(&self, scene: Option<&Scene>) -> Result<FramePlan> {
        let orbit = match self.orbit {
            Some(degrees) if !degrees.is_finite() => {
                bail!("--orbit {degrees}: the turn must be a finite number of degrees")
            }
            Some(degrees) => {
                let (_, end) = self
                    .frames
                    .expect("clap: --orbit requires --frames")
                    .bounds();
                Some(Orbit {
                    degrees,
                    frames: end,
                })
            }
            None => None,
        };
        let total = match orbit {
            Some(o) => Some(o.frames),
            None => scene
                .and_then(|s| FrameChoice::STILL.animation(s))
                .map(|a| a.frames),
        };
        let animated = self.frames.is_some() || self.frame.is_some() || orbit.is_some();
        let frames = match (self.frame, self.frames) {
            (Some(k), _) => k..k + 1,
            (None, Some(span)) => {
                let (a, b) = span.bounds();
                a..b
            }
            (None, None) => 0..1,
        };
        match total {
            Some(total) if frames.end > total => bail!(
                "--frames/--frame: frame {} is outside the animation's {total} frames (0 to {})",
                frames.end - 1,
                total - 1
            ),
            None if animated && scene.is_some() => bail!(
                "--frames/--frame: the scene has no animation; give --orbit DEGREES, or an \
                 \"animation\" in its manifest"
            ),
            _ => {}
        }
        Ok(FramePlan {
            frames,
            orbit,
            animated,
        })
    }
}

impl FramePlan {
    /// Checks that one job can render these frames at `width` x `height` (its Combine task
    /// assembles them all within the state machine's timeout), before any work. A monolithic
    /// run has no such limit.
    pub fn check_one_job(&self, width: u32, height: u32) -> Result<()> {
        check_combine_time(width, height, self.len()).map_err(|e| anyhow!("--frames: {e}"))
    }
}
