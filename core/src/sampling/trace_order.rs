//! The order a pixel's samples are traced in: square by square, so a ray packet's rays
//! ([`crate::bvh::RAY_PACKET`], 64 neighbours in trace order) leave from as small a part of
//! the pixel as the sample count allows. Tracing order never changes a bit of the image: a
//! pixel is still the mean of its samples in sample order ([`TraceOrder::position`]).
//!
//! Why it pays: consecutive samples of the sequence are spread over the whole pixel (every
//! aligned block of 16 is a net covering it), so at 256 samples a pixel's four packets each
//! spanned the pixel; in trace order each covers one quarter. On a mesh with several
//! triangles per pixel a packet then meets fewer leaves, and its shadow rays leave from closer
//! points.

use super::sobol::cell_key;

/// Levels of squares the order follows: down to `2^-8 x 2^-8` of a pixel, one square per
/// sample at the largest sample count (65536).
const LEVELS: u32 = 8;

/// The trace order of the samples of a pixel at one sample count: the same for every pixel and
/// frame (the sequence's scrambling only relabels the squares).
///
/// Guarantee: a permutation of `0..spp`. Samples are sorted by the nested squares of the pixel
/// they lie in, coarsest first (quadrants, then their quarters, ...), ties by sample index; so
/// when `spp` is a power of two and `spp / n` a power of four, every aligned run of `n` traced
/// samples is the `n` samples of one square of side `sqrt(n / spp)` (the sequence puts exactly
/// `n` in each).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TraceOrder {
    /// Trace position -> sample index.
    samples: Vec<u32>,
    /// Sample index -> trace position.
    positions: Vec<u32>,
}

impl TraceOrder {
    /// The trace order at `spp` samples per pixel (sample order when `spp <= 1`).
    pub fn new(spp: u32) -> TraceOrder {
        let mut samples: Vec<u32> = (0..spp).collect();
        if spp > 1 {
            samples.sort_by_key(|&i| (cell_key(i, LEVELS), i));
        }
        let mut positions = vec![0u32; samples.len()];
        for (position, &sample) in samples.iter().enumerate() {
            positions[sample as usize] = position as u32;
        }
        TraceOrder { samples, positions }
    }

    /// The samples in trace order.
    pub fn samples(&self) -> &[u32] {
        &self.samples
    }

    /// Where sample `sample` is traced: `samples()[position(s)] == s`. Panics past the count.
    #[inline]
    pub fn position(&self, sample: u32) -> usize {
        self.positions[sample as usize] as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::PixelSamples;

    /// Every aligned run of 16 traced samples lies in one square of the pixel holding 16
    /// samples (a quarter at 64 spp, a sixteenth at 256, the pixel at 16), whatever the pixel;
    /// and the order is a permutation with its inverse.
    #[test]
    fn runs_of_sixteen_lie_in_one_square() {
        for (spp, side) in [(16u32, 1.0f64), (64, 0.5), (256, 0.25), (1024, 0.125)] {
            let order = TraceOrder::new(spp);
            let mut seen = vec![false; spp as usize];
            for (position, &s) in order.samples().iter().enumerate() {
                assert!(!seen[s as usize], "spp {spp}: sample {s} twice");
                seen[s as usize] = true;
                assert_eq!(order.position(s), position);
            }
            for pixel in [0u64, 1, 77, 123_456_789, u64::MAX] {
                for frame in [0u32, 3] {
                    let samples = PixelSamples::of_frame(pixel, spp, frame);
                    for run in order.samples().chunks(16) {
                        let square = |s: u32| {
                            let (x, y) = samples.offset(s);
                            ((x / side) as u32, (y / side) as u32)
                        };
                        let first = square(run[0]);
                        assert!(
                            run.iter().all(|&s| square(s) == first),
                            "spp {spp}, pixel {pixel}, frame {frame}: {run:?}"
                        );
                    }
                }
            }
        }
    }

    /// Sample order where there is nothing to order, and every count gets a permutation.
    #[test]
    fn small_and_odd_counts() {
        assert_eq!(TraceOrder::new(0).samples(), &[] as &[u32]);
        assert_eq!(TraceOrder::new(1).samples(), &[0]);
        for spp in [2u32, 3, 5, 17, 100, 1000] {
            let mut sorted = TraceOrder::new(spp).samples().to_vec();
            sorted.sort_unstable();
            assert_eq!(sorted, (0..spp).collect::<Vec<_>>(), "spp {spp}");
        }
    }
}
