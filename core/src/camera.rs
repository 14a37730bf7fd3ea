//! The pinhole camera of the default scene contract (docs/ARCHITECTURE.md). Ray directions are
//! computed in f64 and rounded once to f32:
//! for pixel position (px, py) (pixel centre at x + 0.5), with tan = tan(vfov / 2),
//! dir = normalize(f + ((2·px/W - 1)·tan·W/H)·r + ((1 - 2·py/H)·tan)·u), row 0 at the top,
//! evaluated as f + (px·2tan/H - tan·W/H)·r + (tan - py·2tan/H)·u with the constants computed
//! once, and scaled by the reciprocal of its length: one division and one square root per ray.
//! (The f64 results differ from the formula's by a few units in the last place, far below the
//! f32 rounding.)
//!
//! [`Camera::sample_ray`] is the one camera-sample path: the monolithic renderer and CastMap
//! both take their rays from it, so they trace the same rays bit for bit.
//! [`Camera::pixels_rays`] gives pixels' sample rays with the same operations in lanes:
//! sixteen samples of a pixel (or, below sixteen samples a pixel, sixteen (pixel, sample)
//! pairs) at a time in plain arrays (`lanes.rs`, compiled for AVX-512 or AVX2 where the kernel
//! width is `Sixteen` or `Eight`, `avx.rs`).

#[cfg(target_arch = "x86_64")]
mod avx;
mod lanes;

#[cfg(target_arch = "x86_64")]
use crate::bvh::{KernelWidth, kernel_width};
use crate::error::SceneError;
use crate::sampling::{PixelSamples, TraceOrder};
use crate::scene::CameraSpec;
use crate::triangle::Ray;
use glam::DVec3;

/// A camera ready to generate rays for a `width` x `height` image.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    eye: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    tan_half: f64,
    width: f64,
    height: f64,
    /// The image-plane coordinates' constants: sx = px·`pixel_scale` - `x_edge`,
    /// sy = `tan_half` - py·`pixel_scale`.
    pixel_scale: f64,
    x_edge: f64,
    /// The image width in pixels, to split row-major pixel indices into (x, y).
    columns: u64,
    /// The animation frame whose sample streams the rays follow (0 for a still image).
    frame: u32,
}

impl Camera {
    /// Errors when the eye is at the target or `up` is parallel to the view direction.
    pub fn new(spec: &CameraSpec, width: u32, height: u32) -> Result<Camera, SceneError> {
        let view = spec.look_at - spec.eye;
        if view.length() <= 0.0 {
            return Err(SceneError::Camera {
                detail: "eye and look_at are the same point".into(),
            });
        }
        let forward = view / view.length();
        let side = forward.cross(spec.up);
        if side.length() <= 1e-12 * spec.up.length() || !side.is_finite() {
            return Err(SceneError::Camera {
                detail: "up is parallel to the view direction (or zero)".into(),
            });
        }
        let right = side / side.length();
        let up = right.cross(forward);
        let half = spec.vfov_degrees * (std::f64::consts::PI / 180.0) / 2.0;
        let tan_half = libm::tan(half);
        let (w, h) = (f64::from(width), f64::from(height));
        Ok(Camera {
            eye: spec.eye,
            forward,
            right,
            up,
            tan_half,
            width: w,
            height: h,
            pixel_scale: 2.0 * tan_half / h,
            x_edge: tan_half * w / h,
            columns: u64::from(width),
            frame: 0,
        })
    }

    /// This camera with the sample streams of animation frame `frame`
    /// ([`PixelSamples::of_frame`]); frame 0's are a still image's.
    pub fn with_frame(self, frame: u32) -> Camera {
        Camera { frame, ..self }
    }

    /// The eye position.
    pub fn eye(&self) -> DVec3 {
        self.eye
    }

    /// The (not normalized) direction through image position (px, py), in f64.
    #[inline]
    pub fn direction(&self, px: f64, py: f64) -> DVec3 {
        let sx = px * self.pixel_scale - self.x_edge;
        let sy = self.tan_half - py * self.pixel_scale;
        self.forward + sx * self.right + sy * self.up
    }

    /// The point `p` in the camera's frame: its offset from the eye along (right, up, forward).
    pub fn to_view(&self, p: DVec3) -> DVec3 {
        let d = p - self.eye;
        DVec3::new(d.dot(self.right), d.dot(self.up), d.dot(self.forward))
    }

    /// The image position (px, py), in pixel units, that a point `v` of the camera's frame
    /// ([`Camera::to_view`]) in front of the eye (`v.z > 0`) projects to: the inverse of
    /// [`Camera::direction`] (in exact arithmetic).
    pub fn view_to_image(&self, v: DVec3) -> (f64, f64) {
        let (sx, sy) = (v.x / v.z, v.y / v.z);
        let px = (sx / (self.tan_half * self.width / self.height) + 1.0) * self.width / 2.0;
        let py = (1.0 - sy / self.tan_half) * self.height / 2.0;
        (px, py)
    }

    /// The ray through image position (px, py) in pixel units (pixel x's centre is x + 0.5).
    #[inline]
    pub fn ray(&self, px: f64, py: f64) -> Ray {
        let d = self.direction(px, py);
        let d = d * (1.0 / (d.x * d.x + d.y * d.y + d.z * d.z).sqrt());
        Ray {
            origin: self.eye.as_vec3(),
            dir: d.as_vec3(),
        }
    }

    /// The ray of sample `sample` of `spp` in pixel `pixel` (row-major index from the top-left,
    /// x = pixel % width, y = pixel / width): [`Camera::ray`] through (x + ox, y + oy), where
    /// (ox, oy) is [`crate::sampling::sample_offset`]`(pixel, sample, spp)` (in frame 0; the camera's frame's
    /// [`PixelSamples::of_frame`] offset otherwise). A pure function of its arguments and the
    /// camera. Panics if the camera was made for an image of width 0 (it has no pixels).
    #[inline]
    pub fn sample_ray(&self, pixel: u64, sample: u32, spp: u32) -> Ray {
        let (ox, oy) = PixelSamples::of_frame(pixel, spp, self.frame).offset(sample);
        let (x, y) = self.pixel_xy(pixel);
        self.ray(x + ox, y + oy)
    }

    /// The column and row of pixel `pixel` (row-major index from the top-left), as f64: x <
    /// 2^32 and, for a pixel of the image, y < height, so both convert exactly.
    #[inline(always)]
    fn pixel_xy(&self, pixel: u64) -> (f64, f64) {
        ((pixel % self.columns) as f64, (pixel / self.columns) as f64)
    }

    /// Appends the rays of each of `pixels`' samples to `out`, pixel by pixel, each pixel's in
    /// `order` (a [`TraceOrder`] of the pixels' sample count): exactly
    /// [`Camera::sample_ray`]`(pixel, sample, spp)` for each pixel and each sample of
    /// `order.samples()`, with the per-pixel work (the pixel's coordinates and sample pattern)
    /// done once and the ray arithmetic in SIMD lanes: sixteen samples of a pixel at a time
    /// (`lanes.rs`, a shorter rest in sixteen lanes too); below sixteen samples a pixel,
    /// sixteen consecutive (pixel, sample) pairs at a time (one pixel's samples would leave
    /// lanes idle).
    #[inline]
    pub fn pixels_rays(&self, pixels: &[u64], order: &TraceOrder, out: &mut Vec<Ray>) {
        let samples = order.samples();
        self.pixels_samples_rays(pixels, (samples, samples.len() as u32), out);
    }

    /// [`Camera::pixels_rays`] of the samples `samples` of `spp` (a sample of a pixel whose
    /// sequence has `spp` samples, in any order): [`Camera::sample_ray`]`(pixel, sample, spp)`
    /// for each pixel and each of `samples`, pixel by pixel. (The adaptive sampler traces the
    /// samples `base..max` of its refined pixels, of a sequence of `max`.)
    #[inline]
    pub fn pixels_samples_rays(&self, pixels: &[u64], samples: (&[u32], u32), out: &mut Vec<Ray>) {
        #[cfg(target_arch = "x86_64")]
        match kernel_width() {
            // SAFETY: the width `Sixteen` is offered only on hosts with AVX-512F, `Eight` only
            // on hosts with AVX2 (`bvh::dispatch`).
            #[allow(unsafe_code)]
            KernelWidth::Sixteen => {
                return unsafe { self.pixels_rays_avx512(pixels, samples, out) };
            }
            #[allow(unsafe_code)]
            KernelWidth::Eight => return unsafe { self.pixels_rays_avx2(pixels, samples, out) },
            KernelWidth::Four => {}
        }
        self.pixels_rays_lanes(pixels, samples, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::sample_offset;

    #[test]
    fn centre_ray_looks_at_target_and_rows_go_down() {
        let spec = CameraSpec {
            eye: DVec3::new(0.0, 0.0, 5.0),
            look_at: DVec3::ZERO,
            up: DVec3::Y,
            vfov_degrees: 45.0,
        };
        let cam = Camera::new(&spec, 4, 2).unwrap();
        assert_eq!(cam.ray(2.0, 1.0).dir, glam::Vec3::new(0.0, 0.0, -1.0));
        assert!(cam.ray(0.5, 0.5).dir.y > 0.0, "row 0 is the top");
        assert!(cam.ray(0.5, 0.5).dir.x < 0.0, "column 0 is the left");
    }

    /// Sample rays are the rays through the pixel corner plus the sample offset, with the pixel
    /// index split row-major (first and last column, later rows, one and several samples).
    #[test]
    fn sample_rays_go_through_their_pixel_and_offset() {
        let spec = CameraSpec {
            eye: DVec3::new(0.5, 1.0, 5.0),
            look_at: DVec3::new(0.0, 0.25, 0.0),
            up: DVec3::Y,
            vfov_degrees: 40.0,
        };
        let (width, height) = (7u32, 5u32);
        let cam = Camera::new(&spec, width, height).unwrap();
        for spp in [1u32, 4, 9] {
            for (x, y) in [(0u32, 0u32), (6, 0), (0, 1), (3, 2), (6, 4)] {
                let pixel = u64::from(y) * u64::from(width) + u64::from(x);
                for sample in 0..spp {
                    let (ox, oy) = sample_offset(pixel, sample, spp);
                    let expected = cam.ray(f64::from(x) + ox, f64::from(y) + oy);
                    let got = cam.sample_ray(pixel, sample, spp);
                    assert_eq!(got.origin.to_array(), expected.origin.to_array());
                    assert_eq!(
                        got.dir.to_array().map(f32::to_bits),
                        expected.dir.to_array().map(f32::to_bits),
                        "pixel ({x}, {y}) sample {sample} of {spp}"
                    );
                }
            }
        }
    }

    /// Pixels' batch of rays is their sample rays one by one, bit for bit, pixel by pixel in
    /// trace order, on every path: one sample (pixel centres), below sixteen samples a pixel
    /// (lanes across pixels, the last group partly filled), runs of sixteen samples of a pixel
    /// with and without a shorter rest (20, 35 and 64 samples); one pixel, several, none; a
    /// still camera and a frame of an animation. The same for samples from the tail of a
    /// longer sequence (the adaptive sampler's second pass: samples `spp / 4..spp` of `spp`,
    /// and one sample alone).
    #[test]
    fn pixels_rays_are_the_sample_rays_in_order() {
        let spec = CameraSpec {
            eye: DVec3::new(-0.5, 2.0, 7.0),
            look_at: DVec3::new(0.25, 0.5, 0.0),
            up: DVec3::Y,
            vfov_degrees: 50.0,
        };
        let bits = |r: &Ray| (r.origin.to_array(), r.dir.to_array().map(f32::to_bits));
        // The dispatched path, the portable lanes, and AVX2's registers where the host has it.
        type PixelsRays = fn(&Camera, &[u64], (&[u32], u32), &mut Vec<Ray>);
        #[cfg_attr(not(target_arch = "x86_64"), allow(unused_mut))]
        let mut paths: Vec<(&str, PixelsRays)> = vec![
            ("dispatched", Camera::pixels_samples_rays),
            ("portable", Camera::pixels_rays_lanes),
        ];
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the host has AVX2.
            #[allow(unsafe_code)]
            paths.push(("avx2", |c, pixels, samples, out| unsafe {
                c.pixels_rays_avx2(pixels, samples, out)
            }));
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the host has AVX-512F.
            #[allow(unsafe_code)]
            paths.push(("avx512", |c, pixels, samples, out| unsafe {
                c.pixels_rays_avx512(pixels, samples, out)
            }));
        }
        for frame in [0, 3] {
            let cam = Camera::new(&spec, 9, 4).unwrap().with_frame(frame);
            for (path, pixels_rays) in &paths {
                for spp in [1u32, 2, 3, 4, 5, 7, 16, 20, 35, 64] {
                    let order = TraceOrder::new(spp);
                    let tail: Vec<u32> = (spp / 4..spp).collect();
                    let lists = [order.samples(), &tail, &[spp - 1]];
                    for (samples, pixels) in lists.into_iter().flat_map(|samples| {
                        [&[0u64, 8, 9, 22, 35][..], &[4, 5, 6], &[7], &[]]
                            .map(|pixels| (samples, pixels))
                    }) {
                        // A ray already there stays first: the batch is appended.
                        let mut got = vec![cam.sample_ray(0, 0, 1)];
                        pixels_rays(&cam, pixels, (samples, spp), &mut got);
                        let mut expected = vec![cam.sample_ray(0, 0, 1)];
                        for &pixel in pixels {
                            let sample_ray = |&sample| cam.sample_ray(pixel, sample, spp);
                            expected.extend(samples.iter().map(sample_ray));
                        }
                        let at = format!(
                            "{path}: frame {frame}, samples {samples:?} of {spp}, pixels {pixels:?}"
                        );
                        assert_eq!(got.len(), expected.len(), "{at}");
                        for (g, e) in got.iter().zip(&expected) {
                            assert_eq!(bits(g), bits(e), "{at}");
                        }
                    }
                }
            }
        }
    }

    /// Frame 0's rays are a still camera's; another frame keeps the pixel centre at one sample
    /// and scrambles the samples differently above, each still inside its pixel, and a frame's
    /// batch of rays is its sample rays one by one.
    #[test]
    fn each_frame_has_its_own_sample_streams() {
        let spec = CameraSpec {
            eye: DVec3::new(0.5, 1.0, 5.0),
            look_at: DVec3::ZERO,
            up: DVec3::Y,
            vfov_degrees: 40.0,
        };
        let still = Camera::new(&spec, 8, 6).unwrap();
        let bits = |r: Ray| r.dir.to_array().map(f32::to_bits);
        let frame0 = still.with_frame(0);
        let frame3 = still.with_frame(3);
        for pixel in [0u64, 9, 47] {
            assert_eq!(
                bits(frame3.sample_ray(pixel, 0, 1)),
                bits(still.sample_ray(pixel, 0, 1))
            );
            let mut differ = 0;
            for sample in 0..16 {
                assert_eq!(
                    bits(frame0.sample_ray(pixel, sample, 16)),
                    bits(still.sample_ray(pixel, sample, 16))
                );
                let other = frame3.sample_ray(pixel, sample, 16);
                differ += usize::from(bits(other) != bits(still.sample_ray(pixel, sample, 16)));
                let (ox, oy) = PixelSamples::of_frame(pixel, 16, 3).offset(sample);
                assert!((0.0..1.0).contains(&ox) && (0.0..1.0).contains(&oy));
            }
            assert!(
                differ >= 15,
                "pixel {pixel}: only {differ} of 16 samples moved"
            );
            let mut batch = Vec::new();
            let order = TraceOrder::new(16);
            frame3.pixels_rays(&[pixel], &order, &mut batch);
            assert_eq!(batch.len(), 16);
            for (&sample, ray) in order.samples().iter().zip(batch) {
                assert_eq!(bits(ray), bits(frame3.sample_ray(pixel, sample, 16)));
            }
        }
    }

    #[test]
    fn degenerate_cameras_are_errors() {
        let mut spec = CameraSpec {
            eye: DVec3::ONE,
            look_at: DVec3::ONE,
            up: DVec3::Y,
            vfov_degrees: 45.0,
        };
        let e = Camera::new(&spec, 4, 2).unwrap_err().to_string();
        assert_eq!(e, "invalid camera: eye and look_at are the same point");
        spec.look_at = DVec3::new(1.0, 5.0, 1.0);
        let e = Camera::new(&spec, 4, 2).unwrap_err().to_string();
        assert_eq!(
            e,
            "invalid camera: up is parallel to the view direction (or zero)"
        );
    }
}
