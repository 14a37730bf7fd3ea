//! A pixel's running sum of sample radiances: the one pixel-mean path of the monolithic
//! renderer, TraceReduce and the adaptive sampler, so all write the same bits.

/// One pixel's running sum of sample radiances (linear RGB, f32). The guarantee: [`mean`]
/// returns exactly `(((0 + c_0) + c_1) + ... + c_n-1) / spp` per channel, the samples summed in
/// the order they were added, in f32 without fused operations, then one correctly rounded
/// division by `spp as f32`.
///
/// [`mean`]: PixelSum::mean
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PixelSum {
    sum: [f32; 3],
}

impl PixelSum {
    /// Adds the next sample's radiance.
    #[inline]
    pub fn add(&mut self, colour: [f32; 3]) {
        for (sum, c) in self.sum.iter_mut().zip(colour) {
            *sum += c;
        }
    }

    /// A sum that continues from `sum`, the value [`PixelSum::sum`] gave (bit for bit the same
    /// as having added those samples here).
    pub fn from_sum(sum: [f32; 3]) -> Self {
        PixelSum { sum }
    }

    /// The in-order sum of the samples added so far.
    pub fn sum(&self) -> [f32; 3] {
        self.sum
    }

    /// The pixel: the sum divided by the pixel's sample count `spp` (not by the number of
    /// samples added; callers add exactly `spp`).
    #[inline]
    pub fn mean(self, spp: u32) -> [f32; 3] {
        let spp = spp as f32;
        self.sum.map(|v| v / spp)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mean is the in-order f32 sum divided once by spp: order matters in f32, and this
    /// order is the one both renderers have always used.
    #[test]
    fn pixel_sum_is_the_in_order_sum_over_spp() {
        let samples = [[1e8f32, 0.1, -0.0], [1.0, 0.2, -0.0], [-1e8, 0.3, -0.0]];
        let mut film = PixelSum::default();
        for s in samples {
            film.add(s);
        }
        let mean = film.mean(3);
        assert_eq!(
            mean[0], 0.0,
            "1e8 + 1 rounds to 1e8 in f32, so the 1 is lost"
        );
        assert_eq!(mean[1].to_bits(), (((0.1f32 + 0.2) + 0.3) / 3.0).to_bits());
        assert_eq!(mean[2].to_bits(), 0.0f32.to_bits(), "0 + -0 is +0");
        assert_eq!(PixelSum::default().mean(4), [0.0; 3]);
    }
}
