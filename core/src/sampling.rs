//! Deterministic pixel sample positions: one sample is the pixel centre; several samples are
//! correlated multi-jittered (Kensler, "Correlated Multi-Jittered Sampling", 2013), stratified
//! in 2D and in each 1D projection, jittered by a hash of (pixel, sample). Pure integer hashing
//! and exact float conversions: identical on every machine.
//!
//! [`PixelSum`] turns a pixel's sample radiances into the pixel: the one pixel-mean path of the
//! monolithic renderer and TraceReduce, so both write the same bits.

use wide::{f64x4, u32x4};

/// The offset in [0, 1)^2 inside pixel `pixel` (row-major index) of sample `sample` of `spp`.
pub fn sample_offset(pixel: u64, sample: u32, spp: u32) -> (f64, f64) {
    PixelSamples::new(pixel, spp).offset(sample)
}

/// The sample positions of one pixel: [`sample_offset`] with the work that depends only on
/// (pixel, spp) done once. Guarantee: `PixelSamples::new(pixel, spp).offset(sample)` is
/// exactly `sample_offset(pixel, sample, spp)` (the same operations in the same order).
#[derive(Clone, Copy, Debug)]
pub struct PixelSamples {
    /// Strata: `m` columns by `n` rows (`m = 0` marks the one-sample pixel centre).
    m: u32,
    n: u32,
    /// `1 / m` and `1 / n` when they are powers of two (then `v / m == v * (1 / m)` exactly,
    /// both being the correctly rounded `v · 2^-k`), else 0 (divide).
    inv_m: f64,
    inv_n: f64,
    /// `log2(m)` when `m` is a power of two (then `s % m` and `s / m` are a mask and a
    /// shift), else `u32::MAX`.
    m_log2: u32,
    /// The column and row permutations (lengths `m` and `n`).
    perm_x: Permutation,
    perm_y: Permutation,
    jitter_x: u32,
    jitter_y: u32,
}

impl PixelSamples {
    /// The sample pattern of pixel `pixel` (row-major index) at `spp` samples.
    #[inline]
    pub fn new(pixel: u64, spp: u32) -> Self {
        if spp <= 1 {
            return PixelSamples {
                m: 0,
                n: 0,
                inv_m: 0.0,
                inv_n: 0.0,
                m_log2: u32::MAX,
                perm_x: Permutation::new(1, 0),
                perm_y: Permutation::new(1, 0),
                jitter_x: 0,
                jitter_y: 0,
            };
        }
        let m = isqrt(spp).max(1);
        let n = spp.div_ceil(m);
        let pattern = hash64(pixel) as u32;
        let inverse = |d: u32| {
            if d.is_power_of_two() {
                1.0 / f64::from(d)
            } else {
                0.0
            }
        };
        PixelSamples {
            m,
            n,
            inv_m: inverse(m),
            inv_n: inverse(n),
            m_log2: if m.is_power_of_two() {
                m.trailing_zeros()
            } else {
                u32::MAX
            },
            perm_x: Permutation::new(m, pattern.wrapping_mul(0xa511_e9b3)),
            perm_y: Permutation::new(n, pattern.wrapping_mul(0x63d8_3595)),
            jitter_x: pattern.wrapping_mul(0xa399_d265),
            jitter_y: pattern.wrapping_mul(0x711a_d6a5),
        }
    }

    /// The offset in [0, 1)^2 of sample `sample`.
    #[inline(always)]
    pub fn offset(&self, sample: u32) -> (f64, f64) {
        let (m, n) = (self.m, self.n);
        if m == 0 {
            return (0.5, 0.5);
        }
        let s = if sample < m * n {
            sample
        } else {
            sample % (m * n)
        };
        let (column, row) = if self.m_log2 != u32::MAX {
            (s & (m - 1), s >> self.m_log2)
        } else {
            (s % m, s / m)
        };
        let sx = self.perm_x.apply(column);
        let sy = self.perm_y.apply(row);
        let jx = unit_float(hash32(s ^ self.jitter_x));
        let jy = unit_float(hash32(s ^ self.jitter_y));
        let (over_m, over_n) = (
            |v: f64| divide(v, m, self.inv_m),
            |v: f64| divide(v, n, self.inv_n),
        );
        let x = over_m(f64::from(column) + over_n(f64::from(sy) + jx));
        let y = over_n(f64::from(row) + over_m(f64::from(sx) + jy));
        (x.min(ONE_MINUS_ULP), y.min(ONE_MINUS_ULP))
    }

    /// The offsets of samples `first..first + 4` (wrapping): `[self.offset(first), ..,
    /// self.offset(first + 3)]`. With power-of-two strata (64 spp: 8 x 8) and no wrap-around,
    /// the four are computed in u32x4 and f64x4 lanes: the same wrapping integer operations
    /// (the permutations never cycle-walk there: their length is their mask plus one) and the
    /// same correctly rounded float operations per lane.
    #[inline(always)]
    pub fn offsets4(&self, first: u32) -> [(f64, f64); 4] {
        let (m, n) = (self.m, self.n);
        let powers_of_two = self.m_log2 != u32::MAX && self.inv_n != 0.0;
        let no_wrap = first.checked_add(3).is_some_and(|last| last < m * n);
        if !(powers_of_two && no_wrap) {
            return [0, 1, 2, 3].map(|k| self.offset(first.wrapping_add(k)));
        }
        let s = u32x4::splat(first) + u32x4::from([0, 1, 2, 3]);
        let column = s & u32x4::splat(m - 1);
        let row = s >> self.m_log2;
        let sx = self.perm_x.apply4(column);
        let sy = self.perm_y.apply4(row);
        let unit = |h: u32x4| {
            let h = (h >> 8u32).to_array().map(f64::from);
            f64x4::from(h) / f64x4::splat(f64::from(1u32 << 24))
        };
        let jx = unit(hash32x4(s ^ u32x4::splat(self.jitter_x)));
        let jy = unit(hash32x4(s ^ u32x4::splat(self.jitter_y)));
        let float = |v: u32x4| f64x4::from(v.to_array().map(f64::from));
        let (inv_m, inv_n) = (f64x4::splat(self.inv_m), f64x4::splat(self.inv_n));
        let x = (float(column) + (float(sy) + jx) * inv_n) * inv_m;
        let y = (float(row) + (float(sx) + jy) * inv_m) * inv_n;
        // `f64::min` of non-NaN values: the smaller (equal values have equal bits here, as
        // neither side is a zero of the other sign).
        let cap = f64x4::splat(ONE_MINUS_ULP);
        let (x, y) = (
            x.simd_lt(cap).select(x, cap).to_array(),
            y.simd_lt(cap).select(y, cap).to_array(),
        );
        [0, 1, 2, 3].map(|k| (x[k], y[k]))
    }
}

/// `v / d`, as `v * inv` when `inv` is the exact `1 / d` of a power of two (the same bits).
#[inline(always)]
fn divide(v: f64, d: u32, inv: f64) -> f64 {
    if inv != 0.0 {
        v * inv
    } else {
        v / f64::from(d)
    }
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
#[cfg(test)]
fn permute(i: u32, len: u32, seed: u32) -> u32 {
    Permutation::new(len, seed).apply(i)
}

/// [`permute`] for one (len, seed), with its constants (mask, shifts, seed parts) computed once.
#[derive(Clone, Copy, Debug)]
struct Permutation {
    len: u32,
    mask: u32,
    /// `(bits / 2).max(1)` and `(bits / 3).max(1)`, `bits` the width of the mask.
    half: u32,
    third: u32,
    seed: u32,
}

impl Permutation {
    fn new(len: u32, seed: u32) -> Self {
        let bits = 32 - len.saturating_sub(1).leading_zeros();
        let mask = if bits == 32 {
            u32::MAX
        } else {
            (1 << bits) - 1
        };
        Permutation {
            len,
            mask,
            half: (bits / 2).max(1),
            third: (bits / 3).max(1),
            seed,
        }
    }

    #[inline(always)]
    fn apply(&self, mut i: u32) -> u32 {
        let Permutation {
            len,
            mask,
            half,
            third,
            seed,
        } = *self;
        if len <= 1 {
            return 0;
        }
        loop {
            i ^= seed;
            i = i.wrapping_mul(0xe170_893d) & mask;
            i ^= i >> half;
            i = i.wrapping_add(seed >> 16) & mask;
            i = i.wrapping_mul(0x0929_eb3f) & mask;
            i ^= i >> third;
            i = (i.wrapping_mul(0x6935_fa69) ^ (seed >> 8)) & mask;
            i = i.wrapping_mul(0x74dc_b303) & mask;
            i ^= i >> half;
            if i < len {
                return i;
            }
        }
    }

    /// [`Permutation::apply`] of four indices, one per lane, for a length that is a power of
    /// two or 1 (its mask plus one, or mask 0): one round, never a cycle walk.
    #[inline(always)]
    fn apply4(&self, mut i: u32x4) -> u32x4 {
        let Permutation {
            mask,
            half,
            third,
            seed,
            ..
        } = *self;
        let (mask, splat) = (u32x4::splat(mask), u32x4::splat);
        i ^= splat(seed);
        i = (i * splat(0xe170_893d)) & mask;
        i ^= i >> half;
        i = (i + splat(seed >> 16)) & mask;
        i = (i * splat(0x0929_eb3f)) & mask;
        i ^= i >> third;
        i = ((i * splat(0x6935_fa69)) ^ splat(seed >> 8)) & mask;
        i = (i * splat(0x74dc_b303)) & mask;
        i ^ (i >> half)
    }
}

/// [`hash32`] of four values, one per lane (wrapping multiplies and shifts, as scalar).
#[inline(always)]
fn hash32x4(mut x: u32x4) -> u32x4 {
    x ^= x >> 16u32;
    x *= u32x4::splat(0x7feb_352d);
    x ^= x >> 15u32;
    x *= u32x4::splat(0x846c_a68b);
    x ^ (x >> 16u32)
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

    /// The permutation as first written (constants recomputed on every call): the reference
    /// that `Permutation` must equal.
    fn reference_permute(mut i: u32, len: u32, seed: u32) -> u32 {
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

    /// The reference formula, dividing always, with the permutation as first written: the offsets of `PixelSamples` (which multiply by
    /// exact reciprocals for power-of-two strata) are its bits, for square and non-square,
    /// power-of-two and other strata.
    #[test]
    fn offsets_are_the_dividing_formula_bit_for_bit() {
        for spp in [2u32, 3, 4, 8, 12, 16, 32, 35, 64, 128, 256, 1000] {
            let m = isqrt(spp).max(1);
            let n = spp.div_ceil(m);
            for pixel in [0u64, 1, 77, 12_345, u64::MAX] {
                let pattern = hash64(pixel) as u32;
                for sample in 0..spp {
                    let s = sample % (m * n);
                    let sx = reference_permute(s % m, m, pattern.wrapping_mul(0xa511_e9b3));
                    let sy = reference_permute(s / m, n, pattern.wrapping_mul(0x63d8_3595));
                    let jx = unit_float(hash32(s ^ pattern.wrapping_mul(0xa399_d265)));
                    let jy = unit_float(hash32(s ^ pattern.wrapping_mul(0x711a_d6a5)));
                    let x = (f64::from(s % m) + (f64::from(sy) + jx) / f64::from(n)) / f64::from(m);
                    let y = (f64::from(s / m) + (f64::from(sx) + jy) / f64::from(m)) / f64::from(n);
                    let expected = (
                        x.min(ONE_MINUS_ULP).to_bits(),
                        y.min(ONE_MINUS_ULP).to_bits(),
                    );
                    let (gx, gy) = sample_offset(pixel, sample, spp);
                    assert_eq!(
                        (gx.to_bits(), gy.to_bits()),
                        expected,
                        "spp {spp} pixel {pixel} sample {sample}"
                    );
                }
            }
        }
    }

    /// Four offsets at once are the four single offsets bit for bit: power-of-two strata (in
    /// lanes), other strata and samples past `m * n` (the scalar path), and starts near the
    /// end of the u32 range.
    #[test]
    fn four_offsets_are_the_single_offsets() {
        let mut lanes = 0;
        for spp in [2u32, 3, 4, 8, 12, 16, 32, 35, 64, 128, 256, 1000, 4096] {
            for pixel in [0u64, 1, 77, 12_345, u64::MAX] {
                let samples = PixelSamples::new(pixel, spp);
                let starts = (0..spp + 8).chain([u32::MAX - 5, u32::MAX - 3, u32::MAX]);
                for first in starts {
                    let four = samples.offsets4(first);
                    for (k, (x, y)) in four.into_iter().enumerate() {
                        let (ex, ey) = samples.offset(first.wrapping_add(k as u32));
                        assert_eq!(
                            (x.to_bits(), y.to_bits()),
                            (ex.to_bits(), ey.to_bits()),
                            "spp {spp} pixel {pixel} sample {first} + {k}"
                        );
                    }
                    lanes += usize::from(first.checked_add(4).is_some_and(|end| end <= spp));
                }
            }
        }
        assert!(
            lanes > 20_000,
            "the lane path should be exercised ({lanes})"
        );
    }

    #[test]
    fn one_sample_is_the_pixel_centre() {
        assert_eq!(sample_offset(7, 0, 1), (0.5, 0.5));
    }

    #[test]
    fn permutation_is_the_reference_permute() {
        for len in [0u32, 1, 2, 3, 5, 8, 13, 64, 100, 1 << 20, u32::MAX] {
            for seed in [0u32, 1, 0xdead_beef, u32::MAX] {
                for i in [0u32, 1, 2, 7, len / 2, len.saturating_sub(1)] {
                    if i < len.max(1) {
                        assert_eq!(permute(i, len, seed), reference_permute(i, len, seed));
                    }
                }
            }
        }
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
