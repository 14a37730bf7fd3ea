//! The two-dimensional Sobol sequence, Owen scrambled by hashing: the points every sample
//! position comes from.
//!
//! Point `i` is (van der Corput of `i`, the second Sobol dimension of `i`), each coordinate a
//! 32-bit binary fraction, scrambled by Laine and Karras's hash-based nested scrambling as
//! Burley ("Practical Hash-based Owen Scrambling", 2020) gives it. The sequence is a
//! (0, 2)-sequence in base 2: every block of `2^m` consecutive points starting at a multiple of
//! `2^m` is a (0, m, 2)-net (one point in each of the `2^m` dyadic boxes of any shape
//! `2^-a x 2^-(m-a)`), and any nested scrambling keeps that. So every prefix of the sequence is
//! well stratified: at a power of two exactly, in between as the union of such nets.
//!
//! Everything here is wrapping integer arithmetic and bit reversal, identical on every target;
//! the versions in lanes perform the same operations per lane.

/// Scrambled coordinates `(x, y)` of point `index`, as 32-bit binary fractions (bit 31 is
/// 1/2), for the scrambling seeds `seed_x` and `seed_y`.
#[inline(always)]
pub(super) fn point(index: u32, seed_x: u32, seed_y: u32) -> (u32, u32) {
    // In reversed bit order, van der Corput's fraction of `index` is `index` itself, so the
    // scrambling (which works on reversed bits) starts from it directly.
    let x = laine_karras(index, seed_x).reverse_bits();
    let y = laine_karras(second_dimension_reversed(index), seed_y).reverse_bits();
    (x, y)
}

/// Which dyadic cell of the pixel point `index` lies in, at every level up to `levels`, up to
/// a relabelling fixed per pixel: the top `levels` bits of both coordinates before scrambling,
/// interleaved with the coarsest level most significant (x's bit, then y's). Nested
/// scrambling changes each bit by a function of the seed and the bits above it only, so two
/// points of one pixel share their top `l` bits of both coordinates exactly when they share
/// those bits here: they lie in the same `2^-l x 2^-l` square. The key ignores the seeds, so
/// it is the same for every pixel and frame.
pub(super) fn cell_key(index: u32, levels: u32) -> u32 {
    let y = second_dimension_reversed(index);
    let mut key = 0;
    for level in 0..levels {
        key = key << 2 | ((index >> level) & 1) << 1 | ((y >> level) & 1);
    }
    key
}

/// [`point`] of `N` indices, one per lane: the same wrapping operations per lane as plain
/// array loops, which the compiler turns into vector instructions of the calling function's
/// instruction set (sixteen lanes are one AVX-512 register).
///
/// `second` is [`second_dimensions`] of `index`: it depends on the indices only, so a caller
/// that scrambles the same indices for many pixels computes it once.
#[inline(always)]
pub(super) fn points_lanes<const N: usize>(
    (index, second): ([u32; N], [u32; N]),
    seed_x: u32,
    seed_y: u32,
) -> ([u32; N], [u32; N]) {
    points_lanes_seeded((index, second), ([seed_x; N], [seed_y; N]))
}

/// [`points_lanes`] with a seed per lane: lane k is [`point`]`(index[k], seed_x[k],
/// seed_y[k])` (samples of different pixels side by side).
#[inline(always)]
pub(super) fn points_lanes_seeded<const N: usize>(
    (index, second): ([u32; N], [u32; N]),
    (seed_x, seed_y): ([u32; N], [u32; N]),
) -> ([u32; N], [u32; N]) {
    let x = reverse_bits_lanes(laine_karras_lanes(index, seed_x));
    let y = reverse_bits_lanes(laine_karras_lanes(second, seed_y));
    (x, y)
}

/// The second Sobol dimension of `index` in reversed bit order (bit 0 is 1/2). Its generator
/// matrix is Pascal's triangle mod 2: column `k` is `v_k` with `v_0 = 1/2` and
/// `v_(k+1) = v_k ^ (v_k >> 1)` as a fraction, that is `v_(k+1) = v_k ^ (v_k << 1)` reversed.
/// Indices below [`SMALL_INDICES`] (every sample of a pixel up to that many) are read from a
/// table of the same function.
#[inline(always)]
fn second_dimension_reversed(index: u32) -> u32 {
    match SECOND_DIMENSION_REVERSED.get(index as usize) {
        Some(&out) => out,
        None => second_dimension_reversed_by_columns(index),
    }
}

/// [`second_dimension_reversed`], column by column.
#[inline(always)]
const fn second_dimension_reversed_by_columns(mut index: u32) -> u32 {
    let (mut v, mut out) = (1u32, 0u32);
    while index != 0 {
        if index & 1 != 0 {
            out ^= v;
        }
        index >>= 1;
        v ^= v << 1;
    }
    out
}

/// Indices whose second dimension [`SECOND_DIMENSION_REVERSED`] holds.
const SMALL_INDICES: usize = 256;

/// [`second_dimension_reversed_by_columns`] of `0..SMALL_INDICES`, made at compile time.
const SECOND_DIMENSION_REVERSED: [u32; SMALL_INDICES] = {
    let mut table = [0u32; SMALL_INDICES];
    let mut i = 0;
    while i < SMALL_INDICES {
        table[i] = second_dimension_reversed_by_columns(i as u32);
        i += 1;
    }
    table
};

/// [`second_dimension_reversed`] of each of `N` indices, what [`points_lanes`] takes: from the
/// table when every index is in it, else the same columns, each added where the lane's bit is
/// set, for as many bits as the largest index has.
#[inline(always)]
pub(super) fn second_dimensions<const N: usize>(index: [u32; N]) -> [u32; N] {
    let largest = index.iter().fold(0, |a, &b| a.max(b));
    let mut out = [0u32; N];
    if (largest as usize) < SMALL_INDICES {
        for (out, &i) in out.iter_mut().zip(&index) {
            *out = SECOND_DIMENSION_REVERSED[i as usize % SMALL_INDICES];
        }
        return out;
    }
    let mut v = 1u32;
    for bit in 0..32 - largest.leading_zeros() {
        for (out, &i) in out.iter_mut().zip(&index) {
            // All ones where the lane's bit is set: 0 - 1 wraps to u32::MAX.
            *out ^= 0u32.wrapping_sub((i >> bit) & 1) & v;
        }
        v ^= v << 1;
    }
    out
}

/// Laine and Karras's permutation of a bit-reversed fraction: every bit is changed by a
/// function of the seed and the less significant bits only (the more significant ones of the
/// fraction), so each dyadic interval maps onto one of the same size: a nested (Owen)
/// scrambling.
#[inline(always)]
fn laine_karras(mut v: u32, seed: u32) -> u32 {
    v = v.wrapping_add(seed);
    v ^= v.wrapping_mul(0x6c50_b47c);
    v ^= v.wrapping_mul(0xb82f_1e52);
    v ^= v.wrapping_mul(0xc7af_e638);
    v ^= v.wrapping_mul(0x8d22_f6e6);
    v
}

/// [`laine_karras`] of `N` values, one per lane, each with its lane's seed.
#[inline(always)]
fn laine_karras_lanes<const N: usize>(mut v: [u32; N], seed: [u32; N]) -> [u32; N] {
    for (v, seed) in v.iter_mut().zip(seed) {
        *v = laine_karras(*v, seed);
    }
    v
}

/// `u32::reverse_bits` of `N` values: swaps of halves, bytes, nibbles, pairs and bits.
#[inline(always)]
fn reverse_bits_lanes<const N: usize>(mut v: [u32; N]) -> [u32; N] {
    for v in &mut v {
        let mut x = v.rotate_left(16);
        x = ((x >> 8) & 0x00ff_00ff) | ((x & 0x00ff_00ff) << 8);
        x = ((x >> 4) & 0x0f0f_0f0f) | ((x & 0x0f0f_0f0f) << 4);
        x = ((x >> 2) & 0x3333_3333) | ((x & 0x3333_3333) << 2);
        *v = ((x >> 1) & 0x5555_5555) | ((x & 0x5555_5555) << 1);
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The second dimension as first written (on fractions, bit 31 is 1/2). Its direction
    /// numbers are Sobol's for the second dimension (as in Burley 2020's table): 1/2, 3/4,
    /// 5/8, 15/16, 17/32, ...; in index order (no Gray code) the first eight points are 0, 1/2,
    /// 3/4, 1/4, 5/8, 1/8, 3/8, 7/8.
    fn second_dimension(mut i: u32) -> u32 {
        let (mut v, mut out) = (1u32 << 31, 0u32);
        while i != 0 {
            if i & 1 != 0 {
                out ^= v;
            }
            i >>= 1;
            v ^= v >> 1;
        }
        out
    }

    #[test]
    fn the_second_dimension_is_sobols() {
        let eighths: Vec<u32> = (0..8).map(|i| second_dimension(i) >> 29).collect();
        assert_eq!(eighths, [0, 4, 6, 2, 5, 1, 3, 7]);
        let directions: Vec<u32> = (0..5).map(|k| second_dimension(1 << k)).collect();
        assert_eq!(
            directions,
            [
                0x8000_0000,
                0xc000_0000,
                0xa000_0000,
                0xf000_0000,
                0x8800_0000
            ]
        );
        for i in (0..70_000u32).chain([u32::MAX - 3, u32::MAX]) {
            assert_eq!(
                second_dimension_reversed(i).reverse_bits(),
                second_dimension(i)
            );
        }
    }

    /// Lanes compute the scalar bits: indices around powers of two, large ones, mixed lanes.
    #[test]
    fn points_in_lanes_are_the_single_points() {
        let seeds = [(0u32, 0u32), (0xdead_beef, 0x1234_5678), (u32::MAX, 1)];
        let mut starts: Vec<u32> = (0..300).collect();
        starts.extend((1..32).map(|k| (1u32 << k) - 2));
        starts.extend([u32::MAX - 3, 0x8000_0000, 12_345_678]);
        for (sx, sy) in seeds {
            for &first in &starts {
                let lanes = [0u32, 1, 2, 3].map(|k| first.wrapping_add(k * 7));
                let (x, y) = points_lanes((lanes, second_dimensions(lanes)), sx, sy);
                for k in 0..4 {
                    assert_eq!((x[k], y[k]), point(lanes[k], sx, sy), "index {}", lanes[k]);
                }
                let lanes: [u32; 16] = std::array::from_fn(|k| first.wrapping_add(k as u32 * 5));
                let (x, y) = points_lanes((lanes, second_dimensions(lanes)), sx, sy);
                for k in 0..16 {
                    assert_eq!((x[k], y[k]), point(lanes[k], sx, sy), "index {}", lanes[k]);
                }
            }
        }
    }

    /// Nested scrambling keeps nets: for every m up to 10, each aligned block of 2^m points
    /// has one point in each dyadic box 2^-a x 2^-(m-a), whatever the seeds.
    #[test]
    fn aligned_blocks_are_nets_after_scrambling() {
        for (sx, sy) in [(0u32, 0u32), (0x9e37_79b9, 0x7f4a_7c15), (7, u32::MAX)] {
            for m in 0..=10u32 {
                let n = 1u32 << m;
                for block in [0u32, 1, 5] {
                    for a in 0..=m {
                        let mut boxes: Vec<u32> = (block * n..(block + 1) * n)
                            .map(|i| {
                                let (x, y) = point(i, sx, sy);
                                let bx = if a == 0 { 0 } else { x >> (32 - a) };
                                let by = if m == a { 0 } else { y >> (32 - (m - a)) };
                                (bx << (m - a)) | by
                            })
                            .collect();
                        boxes.sort_unstable();
                        assert_eq!(boxes, (0..n).collect::<Vec<_>>(), "m {m} a {a}");
                    }
                }
            }
        }
    }
}
