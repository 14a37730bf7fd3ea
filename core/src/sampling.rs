//! Deterministic pixel sample positions: one sample is the pixel centre; several samples are
//! correlated multi-jittered (Kensler, "Correlated Multi-Jittered Sampling", 2013), stratified
//! in 2D and in each 1D projection, jittered by a hash of (pixel, sample). Pure integer hashing
//! and exact float conversions: identical on every machine.
//!
//! [`PixelSum`] turns a pixel's sample radiances into the pixel: the one pixel-mean path of the
//! monolithic renderer and TraceReduce, so both write the same bits.

/// The offset in [0, 1)^2 inside pixel `pixel` (row-major index) of sample `sample` of `spp`.
pub fn sample_offset(pixel: u64, sample: u32, spp: u32) -> (f64, f64) {
    if spp <= 1 {
        return (0.5, 0.5);
    }
    let m = isqrt(spp).max(1);
    let n = spp.div_ceil(m);
    let pattern = hash64(pixel) as u32;
    let s = sample % (m * n);
    let sx = permute(s % m, m, pattern.wrapping_mul(0xa511_e9b3));
    let sy = permute(s / m, n, pattern.wrapping_mul(0x63d8_3595));
    let jx = unit_float(hash32(s ^ pattern.wrapping_mul(0xa399_d265)));
    let jy = unit_float(hash32(s ^ pattern.wrapping_mul(0x711a_d6a5)));
    let x = (f64::from(s % m) + (f64::from(sy) + jx) / f64::from(n)) / f64::from(m);
    let y = (f64::from(s / m) + (f64::from(sx) + jy) / f64::from(m)) / f64::from(n);
    (x.min(ONE_MINUS_ULP), y.min(ONE_MINUS_ULP))
}

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

    /// The pixel: the sum divided by the pixel's sample count `spp` (not by the number of
    /// samples added; callers add exactly `spp`).
    #[inline]
    pub fn mean(self, spp: u32) -> [f32; 3] {
        let spp = spp as f32;
        self.sum.map(|v| v / spp)
    }
}

pub(crate) const ONE_MINUS_ULP: f64 = 1.0 - f64::EPSILON / 2.0;

fn isqrt(v: u32) -> u32 {
    let mut r = (f64::from(v)).sqrt() as u32;
    while r * r > v {
        r -= 1;
    }
    while (r + 1) * (r + 1) <= v {
        r += 1;
    }
    r
}

/// A hash-driven bijection of [0, len): a bijective mix on the next power of two, with
/// cycle-walking until the value falls inside [0, len).
fn permute(mut i: u32, len: u32, seed: u32) -> u32 {
    if len <= 1 {
        return 0;
    }
    let bits = 32 - (len - 1).leading_zeros();
    let mask = if bits == 32 {
        u32::MAX
    } else {
        (1 << bits) - 1
    };
    loop {
        i ^= seed;
        i = i.wrapping_mul(0xe170_893d) & mask;
        i ^= i >> (bits / 2).max(1);
        i = i.wrapping_add(seed >> 16) & mask;
        i = i.wrapping_mul(0x0929_eb3f) & mask;
        i ^= i >> (bits / 3).max(1);
        i = (i.wrapping_mul(0x6935_fa69) ^ (seed >> 8)) & mask;
        i = i.wrapping_mul(0x74dc_b303) & mask;
        i ^= i >> (bits / 2).max(1);
        if i < len {
            return i;
        }
    }
}

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

/// A float in [0, 1) with 24 random bits (exactly representable).
pub(crate) fn unit_float(h: u32) -> f64 {
    f64::from(h >> 8) / f64::from(1u32 << 24)
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

    #[test]
    fn one_sample_is_the_pixel_centre() {
        assert_eq!(sample_offset(7, 0, 1), (0.5, 0.5));
    }

    #[test]
    fn permute_is_a_bijection() {
        for len in [1u32, 2, 3, 5, 8, 13, 64, 100] {
            let mut seen: Vec<u32> = (0..len).map(|i| permute(i, len, 0xdead_beef)).collect();
            seen.sort_unstable();
            assert_eq!(seen, (0..len).collect::<Vec<_>>(), "len {len}");
        }
    }

    #[test]
    fn samples_are_stratified_in_each_dimension() {
        for spp in [4u32, 9, 16] {
            let m = isqrt(spp);
            for pixel in 0..50u64 {
                let pts: Vec<_> = (0..spp).map(|s| sample_offset(pixel, s, spp)).collect();
                let mut xs: Vec<u32> = pts.iter().map(|p| (p.0 * f64::from(spp)) as u32).collect();
                xs.sort_unstable();
                assert_eq!(xs, (0..spp).collect::<Vec<_>>(), "x strata, spp {spp}");
                let mut cells: Vec<u32> = pts
                    .iter()
                    .map(|p| (p.1 * f64::from(m)) as u32 * m + (p.0 * f64::from(m)) as u32)
                    .collect();
                cells.sort_unstable();
                assert_eq!(cells, (0..spp).collect::<Vec<_>>(), "2D strata, spp {spp}");
                assert!(
                    pts.iter()
                        .all(|p| (0.0..1.0).contains(&p.0) && (0.0..1.0).contains(&p.1))
                );
            }
        }
    }
}
