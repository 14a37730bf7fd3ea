//! Camera rays sixteen samples of a pixel at a time, in plain arrays: each lane does
//! [`Camera::ray`]'s IEEE operations in its order (no FMA; square root and division correctly
//! rounded; the f32 conversion to nearest), as loops the compiler turns into vector
//! instructions of the calling function's instruction set (`avx.rs` compiles them for AVX-512
//! at the kernel width `Sixteen`, eight f64 or sixteen u32 lanes a register, and for AVX2 at
//! `Eight`). The part of the sample positions that is the same in every pixel is computed once
//! per batch ([`SampleRun`]). Every ray is [`Camera::sample_ray`]'s bits.

use super::Camera;
use crate::sampling::{PixelSamples, SamplePairs, SampleRun};
use crate::triangle::Ray;
use glam::Vec3;
use std::borrow::Borrow;

/// The samples of one pixel whose rays are made together.
const LANES: usize = 16;

impl Camera {
    /// [`Camera::pixels_samples_rays`] with the rays of each run of [`LANES`] samples of a
    /// pixel made together ([`Camera::rays_lanes`]); a pixel's shorter rest is one more run,
    /// whose unused lanes repeat its last sample and whose rays there are not kept. Below
    /// [`LANES`] samples a pixel, [`LANES`] consecutive (pixel, sample) pairs together. For
    /// several pixels the runs' shared part is made once; for one (the adaptive rounds' calls)
    /// on the way.
    #[inline(always)]
    pub(super) fn pixels_rays_lanes(
        &self,
        pixels: &[u64],
        (samples, spp): (&[u32], u32),
        out: &mut Vec<Ray>,
    ) {
        if samples.len() < LANES {
            self.pairs_rays_lanes(pixels, (samples, spp), out);
            return;
        }
        out.reserve(pixels.len() * samples.len());
        let (runs, unused) = sample_runs(samples);
        if let [pixel] = pixels {
            self.pixel_runs_rays(*pixel, runs, (unused, spp), out);
            return;
        }
        // What the runs' sample positions share in every pixel, once.
        let runs: Vec<SampleRun<LANES>> = runs.collect();
        for &pixel in pixels {
            self.pixel_runs_rays(pixel, &runs, (unused, spp), out);
        }
    }

    /// The rays of one pixel's samples, each of `runs` made together, without the last run's
    /// `unused` lanes.
    #[inline(always)]
    fn pixel_runs_rays(
        &self,
        pixel: u64,
        runs: impl IntoIterator<Item = impl Borrow<SampleRun<LANES>>>,
        (unused, spp): (usize, u32),
        out: &mut Vec<Ray>,
    ) {
        let offsets = PixelSamples::of_frame(pixel, spp, self.frame);
        let (x, y) = self.pixel_xy(pixel);
        for run in runs {
            let (mut px, mut py) = offsets.offsets_lanes(run.borrow());
            for k in 0..LANES {
                // `x + ox` lane by lane (addition commutes bit for bit).
                px[k] += x;
                py[k] += y;
            }
            self.rays_lanes(px, py, out);
        }
        out.truncate(out.len() - unused);
    }

    /// The rays of `samples` of each of `pixels`, pixel by pixel, made [`LANES`] consecutive
    /// (pixel, sample) pairs at a time: the image positions and their offsets in lanes
    /// ([`SamplePairs`]), then the rays in lanes (a pixel's few samples alone would leave lanes
    /// idle). The last group's unused lanes repeat its last pair, and their rays are not kept.
    /// `samples` has fewer than [`LANES`] samples.
    #[inline(always)]
    fn pairs_rays_lanes(&self, pixels: &[u64], (samples, spp): (&[u32], u32), out: &mut Vec<Ray>) {
        out.reserve(pixels.len() * samples.len());
        let Some(&last) = samples.last() else {
            return;
        };
        // The samples' shared part (their second dimension), once.
        let mut run = [last; LANES];
        run[..samples.len()].copy_from_slice(samples);
        let run = SampleRun::new(run);
        let mut pairs = SamplePairs::<LANES>::default();
        let (mut px, mut py, mut filled) = ([0.0f64; LANES], [0.0f64; LANES], 0);
        for &pixel in pixels {
            let offsets = PixelSamples::of_frame(pixel, spp, self.frame);
            let (x, y) = self.pixel_xy(pixel);
            for j in 0..samples.len() {
                pairs.set(filled, &offsets, &run, j);
                (px[filled], py[filled]) = (x, y);
                filled += 1;
                if filled == LANES {
                    self.pairs_rays(&pairs, (px, py), out);
                    filled = 0;
                }
            }
        }
        if filled > 0 {
            for k in filled..LANES {
                pairs.copy_lane(k, filled - 1);
                (px[k], py[k]) = (px[filled - 1], py[filled - 1]);
            }
            self.pairs_rays(&pairs, (px, py), out);
            out.truncate(out.len() - (LANES - filled));
        }
    }

    /// Appends the rays of `pairs` whose pixels' corners are `(x, y)`, lane by lane.
    #[inline(always)]
    fn pairs_rays(
        &self,
        pairs: &SamplePairs<LANES>,
        (mut x, mut y): ([f64; LANES], [f64; LANES]),
        out: &mut Vec<Ray>,
    ) {
        let (ox, oy) = pairs.offsets_lanes();
        for k in 0..LANES {
            // `x + ox` as `Camera::sample_ray` adds them.
            x[k] += ox[k];
            y[k] += oy[k];
        }
        self.rays_lanes(x, y, out);
    }

    /// Appends [`Camera::ray`] of [`LANES`] image positions, one per lane, in lane order.
    #[inline(always)]
    fn rays_lanes(&self, px: [f64; LANES], py: [f64; LANES], out: &mut Vec<Ray>) {
        let (f, r, u) = (self.forward, self.right, self.up);
        let mut dir = [[0.0f32; LANES]; 3];
        for k in 0..LANES {
            // As `direction`: px·scale - x_edge and tan - py·scale, then
            // forward + sx·right + sy·up axis by axis.
            let sx = px[k] * self.pixel_scale - self.x_edge;
            let sy = self.tan_half - py[k] * self.pixel_scale;
            let dx = f.x + sx * r.x + sy * u.x;
            let dy = f.y + sx * r.y + sy * u.y;
            let dz = f.z + sx * r.z + sy * u.z;
            let inverse = 1.0 / (dx * dx + dy * dy + dz * dz).sqrt();
            dir[0][k] = (dx * inverse) as f32;
            dir[1][k] = (dy * inverse) as f32;
            dir[2][k] = (dz * inverse) as f32;
        }
        let origin = self.eye.as_vec3();
        let rays: [Ray; LANES] = std::array::from_fn(|k| Ray {
            origin,
            dir: Vec3::new(dir[0][k], dir[1][k], dir[2][k]),
        });
        out.extend_from_slice(&rays);
    }
}

/// `samples` in runs of [`LANES`] (made with [`SampleRun::new`]), the last one's unused lanes
/// repeating its last sample, and how many lanes are unused.
#[inline(always)]
fn sample_runs(samples: &[u32]) -> (impl Iterator<Item = SampleRun<LANES>>, usize) {
    let (runs, rest) = samples.as_chunks::<LANES>();
    let (last, unused) = match rest {
        [.., sample] => {
            let mut lanes = [*sample; LANES];
            lanes[..rest.len()].copy_from_slice(rest);
            (Some(lanes), LANES - rest.len())
        }
        [] => (None, 0),
    };
    (runs.iter().copied().chain(last).map(SampleRun::new), unused)
}
