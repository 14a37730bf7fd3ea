//! The adaptive sampler: a first pass of `base_spp` samples in every pixel, then a second pass
//! up to `max_spp` samples only in the pixels whose first-pass error estimate is above a
//! threshold, and only if any pixel needs it.
//!
//! Guarantees:
//! - **Deterministic and local.** A pixel's decision ([`decide`]) depends only on its own
//!   first-pass sample radiances and hits, so it does not depend on threads, spans or splits;
//!   the monolithic renderer and the pipeline make the same decisions from the same samples.
//! - **Nested stratification.** Sample positions ([`adaptive_offset`]) are the cells of a
//!   `g x g` grid (`g = sqrt(max_spp)`), visited in a base-4 order whose every prefix of `4^j`
//!   samples puts exactly one sample in each cell of the `2^j x 2^j` grid, Owen-scrambled per
//!   pixel and jittered inside the cell. So the first pass (ranks `0..base_spp`) is stratified
//!   like a uniform render of `base_spp` samples, and first and second pass together (ranks
//!   `0..max_spp`) are stratified like one of `max_spp` samples: error falls as it should.
//! - **The pixel** is the in-order f32 sum ([`crate::sampling::PixelSum`]) of its samples in
//!   rank order divided by the number of samples it got (`base_spp` or `max_spp`); the hit
//!   buffer keeps the hit of rank 0.

use crate::camera::Camera;
use crate::error::SceneError;
use crate::sampling::{ONE_MINUS_ULP, PixelSum, hash32, hash64, unit_float};
use crate::triangle::Ray;
use serde::{Deserialize, Serialize};

mod render;
pub use render::render_adaptive;

/// The adaptive sampler's settings; recorded in the plan and the report.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdaptiveSettings {
    /// Samples of the first pass in every pixel: a power of 4, at least 4.
    pub base_spp: u32,
    /// Samples of a pixel that needs more: a power of 4 above `base_spp`, at most 65536.
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
        let power_of_4 = |v: u32| v.is_power_of_two() && v.trailing_zeros().is_multiple_of(2);
        if !power_of_4(self.base_spp) || self.base_spp < 4 || self.base_spp >= MAX_SPP {
            return Err(SceneError::OutOfRange {
                what: "adaptive base spp",
                value: self.base_spp.to_string(),
                limit: "must be a power of 4 from 4 to 16384 (4, 16, 64, 256, ...)".into(),
            });
        }
        if !power_of_4(self.max_spp) || self.max_spp <= self.base_spp || self.max_spp > MAX_SPP {
            return Err(SceneError::OutOfRange {
                what: "adaptive max spp",
                value: self.max_spp.to_string(),
                limit: format!(
                    "must be a power of 4 above the base spp {} and at most {MAX_SPP}",
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

/// The camera ray of the sample of rank `rank` of pixel `pixel` (row-major in an image
/// `width` pixels wide) in the adaptive pattern for `max_spp`: the one ray path of the
/// monolithic renderer and the pipeline.
pub fn adaptive_ray(camera: &Camera, width: u32, pixel: u64, rank: u32, max_spp: u32) -> Ray {
    let (ox, oy) = adaptive_offset(pixel, rank, max_spp);
    // x < 2^32 and y < 2^32: both convert to f64 exactly.
    let x = (pixel % u64::from(width)) as f64;
    let y = (pixel / u64::from(width)) as f64;
    camera.ray(x + ox, y + oy)
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

/// The offset in [0, 1)^2 inside pixel `pixel` (row-major index) of the sample of rank `rank`
/// (`0..max_spp`) of the adaptive pattern for `max_spp` (a power of 4): point `rank` of the
/// two-dimensional Sobol sequence (van der Corput in x, the second Sobol dimension in y), Owen
/// scrambled per pixel and per dimension (the hash-based nested scrambling of Laine and Karras,
/// as Burley 2020 gives it). The first `2^m` points of that sequence are a (0, m, 2)-net, and
/// scrambling keeps that: every prefix of `4^j` ranks has one sample in each cell of the
/// `2^j x 2^j` grid and one in each of the `4^j` columns and rows. Pure integer hashing and
/// exact conversions, as [`crate::sampling::sample_offset`].
pub fn adaptive_offset(pixel: u64, rank: u32, max_spp: u32) -> (f64, f64) {
    let rank = rank & (max_spp.max(1) - 1);
    let seed = hash64(pixel);
    let x = nested_scramble(rank.reverse_bits(), seed as u32);
    let y = nested_scramble(
        sobol_second(rank),
        hash32((seed >> 32) as u32 ^ 0x68bc_21eb),
    );
    (
        unit_float(x).min(ONE_MINUS_ULP),
        unit_float(y).min(ONE_MINUS_ULP),
    )
}

/// Point `i` of the second dimension of the Sobol sequence, as a 32-bit binary fraction (its
/// generator matrix is Pascal's triangle mod 2: direction `v_{k+1} = v_k ^ (v_k >> 1)`).
fn sobol_second(mut i: u32) -> u32 {
    let mut v = 1u32 << 31;
    let mut out = 0;
    while i != 0 {
        if i & 1 != 0 {
            out ^= v;
        }
        i >>= 1;
        v ^= v >> 1;
    }
    out
}

/// Owen scrambling of a 32-bit binary fraction by hashing: every bit is flipped by a function
/// of the seed and the bits above it only (Laine and Karras's permutation on the reversed
/// bits), so every dyadic interval maps onto one of the same size and nets stay nets.
fn nested_scramble(x: u32, seed: u32) -> u32 {
    let mut v = x.reverse_bits();
    v = v.wrapping_add(seed);
    v ^= v.wrapping_mul(0x6c50_b47c);
    v ^= v.wrapping_mul(0xb82f_1e52);
    v ^= v.wrapping_mul(0xc7af_e638);
    v ^= v.wrapping_mul(0x8d22_f6e6);
    v.reverse_bits()
}

#[cfg(test)]
mod tests;
