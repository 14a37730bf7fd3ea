//! Camera rays on x86-64 hosts with AVX2 or AVX-512 (the kernel widths `Eight` and
//! `Sixteen`): `lanes.rs`'s array loops compiled for the host's widest registers. The
//! operations are the same in every build (no FMA; square root and division are correctly
//! rounded; the f32 conversion rounds to nearest as `as f32` does), so every ray is the same
//! bits.

#![allow(unsafe_code)]

use super::Camera;
use crate::triangle::Ray;

impl Camera {
    /// [`Camera::pixels_samples_rays`] compiled for AVX2 (`Camera::pixels_rays_lanes`).
    ///
    /// # Safety
    /// Only on hosts with AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn pixels_rays_avx2(
        &self,
        pixels: &[u64],
        samples: (&[u32], u32),
        out: &mut Vec<Ray>,
    ) {
        self.pixels_rays_lanes(pixels, samples, out);
    }

    /// `Camera::pixels_rays_lanes` compiled for AVX-512 (sixteen samples of a pixel in one
    /// register of integers, two of f64).
    ///
    /// # Safety
    /// Only on hosts with AVX-512F (which implies AVX2).
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn pixels_rays_avx512(
        &self,
        pixels: &[u64],
        samples: (&[u32], u32),
        out: &mut Vec<Ray>,
    ) {
        self.pixels_rays_lanes(pixels, samples, out);
    }
}
