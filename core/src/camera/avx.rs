//! Camera rays on x86-64 hosts with AVX2 (the kernel widths `Eight` and `Sixteen`): each
//! coordinate of four rays' f64 arithmetic in one 256-bit register, where the portable lanes
//! (`wide::f64x4` in an x86-64-v2 build) take two 128-bit registers and two instructions per
//! operation. The operations are `Camera::rays4`'s in its order (no FMA; square root and
//! division are correctly rounded; the f32 conversion rounds to nearest as `as f32` does), so
//! every ray is the same bits.

#![allow(unsafe_code)]

use super::Camera;
use crate::triangle::Ray;
use glam::Vec3;
use std::arch::x86_64::{
    __m256d, _mm_storeu_ps, _mm256_add_pd, _mm256_cvtpd_ps, _mm256_div_pd, _mm256_loadu_pd,
    _mm256_mul_pd, _mm256_set1_pd, _mm256_sqrt_pd, _mm256_sub_pd,
};
use wide::f64x4;

impl Camera {
    /// [`Camera::pixels_samples_rays`] compiled for AVX2 (`Camera::pixels_rays_lanes`), with
    /// [`Camera::rays4_avx`] for runs shorter than sixteen samples.
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
        self.pixels_rays_lanes::<true>(pixels, samples, out);
    }

    /// `Camera::pixels_rays_lanes` compiled for AVX-512 (sixteen samples of a pixel in one
    /// register of integers, two of f64), with [`Camera::rays4_avx`] for the rest.
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
        self.pixels_rays_lanes::<true>(pixels, samples, out);
    }

    /// `Camera::rays4` in 256-bit registers.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn rays4_avx(&self, px: f64x4, py: f64x4) -> [Ray; 4] {
        let (px, py) = (load(px), load(py));
        // As `direction`: px·scale - x_edge and tan - py·scale.
        let scale = _mm256_set1_pd(self.pixel_scale);
        let sx = _mm256_sub_pd(_mm256_mul_pd(px, scale), _mm256_set1_pd(self.x_edge));
        let sy = _mm256_sub_pd(_mm256_set1_pd(self.tan_half), _mm256_mul_pd(py, scale));
        // forward + sx·right + sy·up, axis by axis.
        let (f, r, u) = (self.forward, self.right, self.up);
        let [dx, dy, dz] = [(f.x, r.x, u.x), (f.y, r.y, u.y), (f.z, r.z, u.z)].map(|(f, r, u)| {
            let along = _mm256_add_pd(_mm256_set1_pd(f), _mm256_mul_pd(sx, _mm256_set1_pd(r)));
            _mm256_add_pd(along, _mm256_mul_pd(sy, _mm256_set1_pd(u)))
        });
        let squares = _mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy));
        let length2 = _mm256_add_pd(squares, _mm256_mul_pd(dz, dz));
        let inverse = _mm256_div_pd(_mm256_set1_pd(1.0), _mm256_sqrt_pd(length2));
        let [x, y, z] = [dx, dy, dz].map(|d| {
            let mut f = [0.0f32; 4];
            // SAFETY: `f` holds four floats.
            unsafe { _mm_storeu_ps(f.as_mut_ptr(), _mm256_cvtpd_ps(_mm256_mul_pd(d, inverse))) };
            f
        });
        let origin = self.eye.as_vec3();
        let ray = |k: usize| Ray {
            origin,
            dir: Vec3::new(x[k], y[k], z[k]),
        };
        [ray(0), ray(1), ray(2), ray(3)]
    }
}

/// `v`'s lanes in one register.
#[target_feature(enable = "avx2")]
#[inline]
fn load(v: f64x4) -> __m256d {
    let lanes = v.to_array();
    // SAFETY: `lanes` holds four f64.
    unsafe { _mm256_loadu_pd(lanes.as_ptr()) }
}
