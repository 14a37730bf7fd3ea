//! Deterministic pixel sample positions, and the one pixel-mean path ([`PixelSum`]).
//!
//! One sample per pixel is the pixel centre (the image contract's camera rays). With more,
//! sample `i` of a pixel is point `i` of the two-dimensional Sobol sequence, Owen scrambled per
//! pixel ([`sobol`]): its position does not depend on the pixel's sample count, so the first
//! `n` samples of any count above 1 are the same `n` samples (the adaptive sampler continues
//! the sequence of its first pass), and every prefix is well stratified: at `2^m` samples
//! exactly one in each dyadic box of area `2^-m` (columns, rows, squares and every shape in
//! between), at other counts the union of such nets. More samples therefore always cover the
//! pixel more evenly, at any count (docs/perf/sampling.md has the measurements).
//!
//! Pure integer hashing and exact float conversions: identical on every machine.

mod pixel_sum;
mod sobol;
mod trace_order;

pub use pixel_sum::PixelSum;
pub use trace_order::TraceOrder;

/// The offset in [0, 1)^2 inside pixel `pixel` (row-major index) of sample `sample` of `spp`:
/// the pixel centre when `spp <= 1`, else the pixel's point `sample` of the sequence (the same
/// for every `spp > 1`).
pub fn sample_offset(pixel: u64, sample: u32, spp: u32) -> (f64, f64) {
    PixelSamples::new(pixel, spp).offset(sample)
}

/// The sample positions of one pixel: [`sample_offset`] with the pixel's scrambling seeds
/// computed once. Guarantee: `PixelSamples::new(pixel, spp).offset(sample)` is exactly
/// `sample_offset(pixel, sample, spp)`.
#[derive(Clone, Copy, Debug)]
pub struct PixelSamples {
    /// One sample at the pixel centre.
    centre: bool,
    seed_x: u32,
    seed_y: u32,
}

impl PixelSamples {
    /// The sample pattern of pixel `pixel` (row-major index) at `spp` samples: frame 0's
    /// ([`PixelSamples::of_frame`]).
    #[inline]
    pub fn new(pixel: u64, spp: u32) -> Self {
        Self::of_frame(pixel, spp, 0)
    }

    /// The sample pattern of pixel `pixel` at `spp` samples in frame `frame` of an animation.
    /// Each frame scrambles the sequence with its own seeds, so noise does not stick to the
    /// screen from frame to frame; frame 0's seeds are those of a still image.
    #[inline]
    pub fn of_frame(pixel: u64, spp: u32, frame: u32) -> Self {
        if spp <= 1 {
            // The pixel centre: no seeds needed.
            return PixelSamples {
                centre: true,
                seed_x: 0,
                seed_y: 0,
            };
        }
        let seed = hash64(pixel) ^ frame_salt(frame);
        PixelSamples {
            centre: false,
            seed_x: seed as u32,
            seed_y: hash32((seed >> 32) as u32 ^ 0x68bc_21eb),
        }
    }

    /// The offset in [0, 1)^2 of sample `sample`.
    #[inline(always)]
    pub fn offset(&self, sample: u32) -> (f64, f64) {
        if self.centre {
            return (0.5, 0.5);
        }
        let (x, y) = sobol::point(sample, self.seed_x, self.seed_y);
        (unit_float(x), unit_float(y))
    }

    /// The offsets of the samples of `run`, x and y in `N` lanes of plain arrays: lane k holds
    /// `self.offset(run.samples()[k])`, with the same exact operations per lane (for code
    /// compiled for a wide instruction set: sixteen lanes are one AVX-512 register).
    #[inline(always)]
    pub fn offsets_lanes<const N: usize>(&self, run: &SampleRun<N>) -> ([f64; N], [f64; N]) {
        if self.centre {
            return ([0.5; N], [0.5; N]);
        }
        let (x, y) = sobol::points_lanes((run.samples, run.second), self.seed_x, self.seed_y);
        unit_floats_lanes(x, y)
    }
}

/// `N` samples of any pixels, one per lane (a few samples each of neighbouring pixels), with
/// what their offsets need: lane k's offset is `PixelSamples::offset` of its pixel and sample,
/// with the same exact operations per lane ([`SamplePairs::offsets_lanes`]).
#[derive(Clone, Copy, Debug)]
pub struct SamplePairs<const N: usize> {
    centre: bool,
    samples: [u32; N],
    second: [u32; N],
    seed_x: [u32; N],
    seed_y: [u32; N],
}

impl<const N: usize> Default for SamplePairs<N> {
    fn default() -> Self {
        SamplePairs {
            centre: false,
            samples: [0; N],
            second: [0; N],
            seed_x: [0; N],
            seed_y: [0; N],
        }
    }
}

impl<const N: usize> SamplePairs<N> {
    /// Lane `k` takes the sample in lane `j` of `run` of the pixel whose pattern is `pixel`.
    /// Every lane's pattern must be of the same sample count (all pixel centres or none).
    /// Panics unless `k < N` and `j < M`.
    #[inline(always)]
    pub fn set<const M: usize>(
        &mut self,
        k: usize,
        pixel: &PixelSamples,
        run: &SampleRun<M>,
        j: usize,
    ) {
        self.centre = pixel.centre;
        self.samples[k] = run.samples[j];
        self.second[k] = run.second[j];
        self.seed_x[k] = pixel.seed_x;
        self.seed_y[k] = pixel.seed_y;
    }

    /// Lane `k` takes what lane `from` holds. Panics unless both are below `N`.
    #[inline(always)]
    pub fn copy_lane(&mut self, k: usize, from: usize) {
        self.samples[k] = self.samples[from];
        self.second[k] = self.second[from];
        self.seed_x[k] = self.seed_x[from];
        self.seed_y[k] = self.seed_y[from];
    }

    /// Each lane's offset, x and y in plain arrays ([`PixelSamples::offsets_lanes`]'s
    /// operations, with each lane's own seeds).
    #[inline(always)]
    pub fn offsets_lanes(&self) -> ([f64; N], [f64; N]) {
        if self.centre {
            return ([0.5; N], [0.5; N]);
        }
        let (x, y) =
            sobol::points_lanes_seeded((self.samples, self.second), (self.seed_x, self.seed_y));
        unit_floats_lanes(x, y)
    }
}

/// `N` sample indices with the part of their sequence points that is the same in every pixel
/// (the second dimension before scrambling) computed once: what
/// [`PixelSamples::offsets_lanes`] scrambles per pixel.
#[derive(Clone, Copy, Debug)]
pub struct SampleRun<const N: usize> {
    samples: [u32; N],
    second: [u32; N],
}

impl<const N: usize> SampleRun<N> {
    /// The run of samples `samples` (any indices, one per lane).
    #[inline(always)]
    pub fn new(samples: [u32; N]) -> Self {
        SampleRun {
            samples,
            second: sobol::second_dimensions(samples),
        }
    }

    /// The sample indices, one per lane.
    pub fn samples(&self) -> [u32; N] {
        self.samples
    }
}

/// What frame `frame` mixes into each pixel's seed: 0 for frame 0, so a still image and frame 0
/// of an animation have the same samples.
#[inline]
fn frame_salt(frame: u32) -> u64 {
    if frame == 0 {
        0
    } else {
        hash64(0xf4a3_e5ee_d000_0000 ^ u64::from(frame))
    }
}

/// `2^-24`: 24 bits of a binary fraction times it are that fraction exactly.
const UNIT: f64 = 1.0 / (1u32 << 24) as f64;

pub(crate) fn hash32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

pub(crate) fn hash64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

/// The top 24 bits of a binary fraction as a float in [0, 1) (exactly representable).
fn unit_float(h: u32) -> f64 {
    f64::from(h >> 8) * UNIT
}

/// [`unit_float`] of `N` x and `N` y fractions, lane by lane.
#[inline(always)]
fn unit_floats_lanes<const N: usize>(x: [u32; N], y: [u32; N]) -> ([f64; N], [f64; N]) {
    let mut out = ([0.0; N], [0.0; N]);
    for k in 0..N {
        // The top 24 bits fit an i32, whose conversion to f64 is exact (as `f64::from`).
        out.0[k] = f64::from((x[k] >> 8) as i32) * UNIT;
        out.1[k] = f64::from((y[k] >> 8) as i32) * UNIT;
    }
    out
}

#[cfg(test)]
mod tests;
