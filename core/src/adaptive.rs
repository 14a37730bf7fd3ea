//! The adaptive sampler: a first pass of `base_spp` samples in every pixel, then a second pass
//! up to `max_spp` samples only in the pixels whose first-pass error estimate is above a
//! threshold, and only if any pixel needs it.
//!
//! Guarantees:
//! - **Deterministic and local.** A pixel's decision ([`decide`]) depends only on its own
//!   first-pass sample radiances and hits, so it does not depend on threads, spans or splits;
//!   the monolithic renderer and the pipeline make the same decisions from the same samples.
//! - **One sequence.** A pixel's sample of rank `r` is sample `r` of the uniform sampler
//!   ([`crate::sampling`]): the first pass (ranks `0..base_spp`) is exactly a uniform render's
//!   `base_spp` samples, and the second pass continues the same sequence (ranks
//!   `base_spp..max_spp`), so first and second pass together are stratified like one render of
//!   `max_spp` samples, for any base and maximum count.
//! - **The pixel** is the in-order f32 sum ([`crate::sampling::PixelSum`]) of its samples in
//!   rank order divided by the number of samples it got (`base_spp` or `max_spp`); the hit
//!   buffer keeps the hit of rank 0.

use crate::error::SceneError;
use crate::sampling::PixelSum;
use serde::{Deserialize, Serialize};

mod render;
pub use render::render_adaptive;
pub(crate) use render::{RefinementOrder, adaptive_run};

/// The adaptive sampler's settings; recorded in the plan and the report.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdaptiveSettings {
    /// Samples of the first pass in every pixel: at least 2 (a pixel's error estimate needs
    /// two), below `max_spp`.
    pub base_spp: u32,
    /// Samples of a pixel that needs more: above `base_spp`, at most 65536.
    pub max_spp: u32,
    /// A pixel gets the second pass when the standard error of its first-pass mean (the
    /// largest over R, G, B, in linear radiance) is above this; finite and positive.
    pub threshold: f64,
}

/// Settings are checked finite ([`AdaptiveSettings::check`]), so equality is an equivalence.
impl Eq for AdaptiveSettings {}

/// Largest `max_spp` (the image limit on spp).
const MAX_SPP: u32 = 65_536;

impl AdaptiveSettings {
    /// Checks the settings; the error names the bad value and the limit it breaks, as
    /// [`crate::scene::check_image_size`] does for the image size.
    pub fn check(&self) -> Result<(), SceneError> {
        if !(2..MAX_SPP).contains(&self.base_spp) {
            return Err(SceneError::OutOfRange {
                what: "adaptive base spp",
                value: self.base_spp.to_string(),
                limit: format!(
                    "must be from 2 (a pixel's error estimate needs two samples) to {}",
                    MAX_SPP - 1
                ),
            });
        }
        if self.max_spp <= self.base_spp || self.max_spp > MAX_SPP {
            return Err(SceneError::OutOfRange {
                what: "adaptive max spp",
                value: self.max_spp.to_string(),
                limit: format!(
                    "must be above the base spp {} and at most {MAX_SPP}",
                    self.base_spp
                ),
            });
        }
        if !(self.threshold.is_finite() && self.threshold > 0.0) {
            return Err(SceneError::OutOfRange {
                what: "adaptive threshold",
                value: self.threshold.to_string(),
                limit: "must be a finite number above 0".into(),
            });
        }
        Ok(())
    }
}

/// What the first pass decided for one pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decision {
    /// Every first-pass sample missed: the pixel sees only background; no extra samples.
    Background,
    /// The error estimate is at or below the threshold; no extra samples.
    Converged,
    /// The error estimate is above the threshold: ranks `base_spp..max_spp` are traced.
    Refine,
}

/// The decision for a pixel from its first-pass sample radiances `colours` (rank order) and
/// whether any of them hit a surface. The estimate is, per channel, the unbiased sample
/// variance over `colours.len()` samples divided by their count (the squared standard error of
/// the mean), computed in f64 from the f32 radiances; the pixel is refined when the largest
/// channel's is above `threshold^2`.
pub fn decide(colours: &[[f32; 3]], any_hit: bool, threshold: f64) -> Decision {
    if !any_hit {
        return Decision::Background;
    }
    let n = colours.len() as f64;
    if colours.len() < 2 {
        return Decision::Converged;
    }
    let mut worst = 0.0f64;
    for c in 0..3 {
        let mean = colours.iter().map(|s| f64::from(s[c])).sum::<f64>() / n;
        let squares: f64 = colours
            .iter()
            .map(|s| {
                let d = f64::from(s[c]) - mean;
                d * d
            })
            .sum();
        worst = worst.max(squares / (n - 1.0) / n);
    }
    if worst > threshold * threshold {
        Decision::Refine
    } else {
        Decision::Converged
    }
}

/// Counts of what the adaptive sampler did, for the report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct AdaptiveCounts {
    /// Pixels that got the second pass (`max_spp` samples).
    pub refined_pixels: u64,
    /// Pixels whose first-pass samples all missed: no extra samples (a skip).
    pub background_pixels: u64,
    /// Pixels whose estimate was at or below the threshold.
    pub converged_pixels: u64,
    /// Camera samples traced in all: first and second pass.
    pub samples: u64,
}

impl AdaptiveCounts {
    /// Counts one pixel's decision, given the settings it was made under.
    pub fn add(&mut self, decision: Decision, settings: &AdaptiveSettings) {
        self.samples += u64::from(settings.base_spp);
        match decision {
            Decision::Background => self.background_pixels += 1,
            Decision::Converged => self.converged_pixels += 1,
            Decision::Refine => {
                self.refined_pixels += 1;
                self.samples += u64::from(settings.max_spp - settings.base_spp);
            }
        }
    }
}

impl std::ops::AddAssign for AdaptiveCounts {
    fn add_assign(&mut self, o: AdaptiveCounts) {
        self.refined_pixels += o.refined_pixels;
        self.background_pixels += o.background_pixels;
        self.converged_pixels += o.converged_pixels;
        self.samples += o.samples;
    }
}

/// A pixel from its first-pass sample radiances and, when it was refined, its second-pass
/// ones (both in rank order): their in-order f32 sum divided by their count, as
/// [`PixelSum`] computes it.
pub fn pixel_value(first: &[[f32; 3]], second: &[[f32; 3]]) -> [f32; 3] {
    let mut sum = PixelSum::default();
    for &c in first.iter().chain(second) {
        sum.add(c);
    }
    sum.mean((first.len() + second.len()) as u32)
}

#[cfg(test)]
mod tests;
