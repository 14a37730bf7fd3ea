//! The lane operations of the triangle tests, at any SIMD width: four lanes ([`f32x4`] of the
//! `wide` crate: SSE4.1 on x86-64, NEON on aarch64) everywhere, eight ([`F32x8`], AVX) on
//! x86-64 hosts that have AVX2 and sixteen ([`F32x16`], AVX-512) on those that have AVX-512F,
//! chosen at run time (`dispatch.rs`).
//!
//! Guarantee: each operation is one IEEE operation per lane (add, subtract, multiply and
//! divide correctly rounded, never fused), comparisons are ordered (false when a lane holds a
//! NaN) and masks are whole lanes, so a lane computes the same bits at any width and on any
//! machine. Code written once over [`Lanes`] therefore gives the same answers at every width.

use super::ray_packet::RAY_PACKET;
use std::ops::{Add, BitAnd, BitOr, BitXor, Div, Mul, Not, Sub};
use wide::f32x4;

/// Lanes of `f32` and lane masks (all ones or all zeros) of the same shape.
pub(super) trait Lanes:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + BitAnd<Output = Self>
    + BitOr<Output = Self>
    + BitXor<Output = Self>
    + Not<Output = Self>
{
    fn splat(x: f32) -> Self;
    /// Clears the sign bit.
    fn abs(self) -> Self;
    fn cmp_eq(self, other: Self) -> Self;
    fn cmp_lt(self, other: Self) -> Self;
    fn cmp_le(self, other: Self) -> Self;
    fn cmp_gt(self, other: Self) -> Self;
    /// Per lane of the mask `self`: `if_true` where it is set, else `if_false`.
    fn select(self, if_true: Self, if_false: Self) -> Self;
    /// Bit i set when lane i of the mask is set.
    fn bitmask(self) -> u32;
    /// Per lane `if self > other { self } else { other }` (so `other` when either is NaN).
    fn greater(self, other: Self) -> Self;
    /// Per lane `if self < other { self } else { other }` (so `other` when either is NaN).
    fn lesser(self, other: Self) -> Self;
}

/// [`Lanes::greater`] of 4 lanes: on x86-64 one `maxps`, which computes exactly this
/// (the second operand when either is NaN or both are zeros), elsewhere a compare and select
/// (NEON's `fmax` propagates NaN instead, so it is not used).
#[inline(always)]
pub(super) fn greater4(a: f32x4, b: f32x4) -> f32x4 {
    #[cfg(target_arch = "x86_64")]
    {
        a.fast_max(b)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        a.simd_gt(b).select(a, b)
    }
}

/// Per lane `if a < b { a } else { b }`: on x86-64 one `minps` (exactly this), elsewhere a
/// compare and select.
#[inline(always)]
pub(super) fn lesser4(a: f32x4, b: f32x4) -> f32x4 {
    #[cfg(target_arch = "x86_64")]
    {
        a.fast_min(b)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        a.simd_lt(b).select(a, b)
    }
}

impl Lanes for f32x4 {
    #[inline(always)]
    fn splat(x: f32) -> Self {
        f32x4::splat(x)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32x4::abs(self)
    }
    #[inline(always)]
    fn cmp_eq(self, other: Self) -> Self {
        self.simd_eq(other)
    }
    #[inline(always)]
    fn cmp_lt(self, other: Self) -> Self {
        self.simd_lt(other)
    }
    #[inline(always)]
    fn cmp_le(self, other: Self) -> Self {
        self.simd_le(other)
    }
    #[inline(always)]
    fn cmp_gt(self, other: Self) -> Self {
        self.simd_gt(other)
    }
    #[inline(always)]
    fn select(self, if_true: Self, if_false: Self) -> Self {
        f32x4::select(self, if_true, if_false)
    }
    #[inline(always)]
    fn bitmask(self) -> u32 {
        self.to_bitmask()
    }
    #[inline(always)]
    fn greater(self, other: Self) -> Self {
        greater4(self, other)
    }
    #[inline(always)]
    fn lesser(self, other: Self) -> Self {
        lesser4(self, other)
    }
}

#[cfg(target_arch = "x86_64")]
pub(super) use avx::F32x8;
#[cfg(target_arch = "x86_64")]
pub(super) use avx512::F32x16;

/// Lanes that hold one ray of a packet's group each at the leaves (`leaf_lanes.rs`): four
/// ([`f32x4`], every host), eight ([`F32x8`]) or sixteen ([`F32x16`]). Values move through
/// a packet's arrays ([`RAY_PACKET`] places), of which [`RayGroupLanes::LANES`] from a group's
/// first ray are the lanes.
/// Only code compiled with the type's instruction set may make or use one (see each type).
pub(super) trait RayGroupLanes: Lanes {
    /// Lanes, and rays of a group: 4, 8 or 16.
    const LANES: usize;
    /// Lanes from the first [`Self::LANES`] values of `x`.
    #[inline(always)]
    fn load(x: &[f32; RAY_PACKET]) -> Self {
        Self::load_at(x, 0)
    }
    /// The lanes, then zeros.
    #[cfg(test)]
    #[inline(always)]
    fn store(self) -> [f32; RAY_PACKET] {
        let mut out = [0.0f32; RAY_PACKET];
        self.store_at(&mut out, 0);
        out
    }
    /// The lanes' bit patterns, then zeros.
    #[cfg(test)]
    #[inline(always)]
    fn store_bits(self) -> [u32; RAY_PACKET] {
        let mut out = [0u32; RAY_PACKET];
        self.store_bits_at(&mut out, 0);
        out
    }
    /// Lanes from `x[from..from + LANES]`. Panics unless `from + LANES <= RAY_PACKET`.
    fn load_at(x: &[f32; RAY_PACKET], from: usize) -> Self;
    /// Lanes holding the bit patterns of `x[from..from + LANES]`. Panics unless
    /// `from + LANES <= RAY_PACKET`.
    fn load_bits_at(x: &[u32; RAY_PACKET], from: usize) -> Self;
    /// Writes the lanes to `x[from..from + LANES]`. Panics unless `from + LANES <= RAY_PACKET`.
    fn store_at(self, x: &mut [f32; RAY_PACKET], from: usize);
    /// Writes the lanes' bit patterns to `x[from..from + LANES]`. Panics unless
    /// `from + LANES <= RAY_PACKET`.
    fn store_bits_at(self, x: &mut [u32; RAY_PACKET], from: usize);
    /// All ones in the lanes whose bit is set in `bits`.
    fn lane_mask(bits: u32) -> Self;
    /// Lanes (holding `u32` bit patterns) whose value is above `x`, unsigned.
    fn u32_above(self, x: u32) -> Self;
    /// The least lane, when no lane is NaN (of a +0 and a -0, either).
    fn lowest(self) -> f32;
}

/// `LANE_MASKS[bits]`: all ones in the four lanes whose bit is set (the ray packets' groups
/// and the four-lane leaves read them).
const LANE_MASKS: [[u32; 4]; 16] = {
    let mut t = [[0u32; 4]; 16];
    let mut bits = 0;
    while bits < 16 {
        let mut l = 0;
        while l < 4 {
            if bits & (1 << l) != 0 {
                t[bits][l] = u32::MAX;
            }
            l += 1;
        }
        bits += 1;
    }
    t
};

impl RayGroupLanes for f32x4 {
    const LANES: usize = 4;

    #[inline(always)]
    fn load_at(x: &[f32; RAY_PACKET], from: usize) -> Self {
        let four: [f32; 4] = x[from..from + 4].try_into().expect("four lanes");
        f32x4::from(four)
    }

    #[inline(always)]
    fn load_bits_at(x: &[u32; RAY_PACKET], from: usize) -> Self {
        let four: [u32; 4] = x[from..from + 4].try_into().expect("four lanes");
        wide::bytemuck::cast(four)
    }

    #[inline(always)]
    fn store_at(self, x: &mut [f32; RAY_PACKET], from: usize) {
        x[from..from + 4].copy_from_slice(&self.to_array());
    }

    #[inline(always)]
    fn store_bits_at(self, x: &mut [u32; RAY_PACKET], from: usize) {
        let four: [u32; 4] = wide::bytemuck::cast(self);
        x[from..from + 4].copy_from_slice(&four);
    }

    #[inline(always)]
    fn lane_mask(bits: u32) -> Self {
        wide::bytemuck::cast(LANE_MASKS[(bits & 0xf) as usize])
    }

    #[inline(always)]
    fn u32_above(self, x: u32) -> Self {
        let lanes: wide::u32x4 = wide::bytemuck::cast(self);
        wide::bytemuck::cast(lanes.simd_gt(wide::u32x4::splat(x)))
    }

    #[inline(always)]
    fn lowest(self) -> f32 {
        lowest4(self)
    }
}

/// The smallest lane of `x` (no NaN lanes), in two vector steps: `f32::min`'s NaN handling
/// made the scalar chain a measurable part of every packet's setup and inner node.
#[inline(always)]
pub(super) fn lowest4(x: f32x4) -> f32 {
    // [min(x0, x2), _, min(x1, x3), _], then the least of its lanes 0 and 2.
    let m = lesser4(x.unpack_lo(x), x.unpack_hi(x));
    lesser4(m, m.unpack_hi(m)).to_array()[0]
}

// `std::arch`'s AVX intrinsics are unsafe to call outside code compiled for AVX; this module
// is the only place in the crate that calls them.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod avx {
    use super::{Lanes, RAY_PACKET, RayGroupLanes};
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, BitOr, BitXor, Div, Mul, Not, Sub};

    /// Eight `f32` lanes in one AVX register.
    ///
    /// Only code compiled with AVX2 enabled (a `#[target_feature(enable = "avx2")]` function,
    /// entered after `dispatch.rs` found AVX2 on the host) may make or use one: every method
    /// is inlined into its caller, where the AVX instructions are then allowed.
    #[derive(Clone, Copy)]
    pub(in crate::bvh) struct F32x8(__m256);

    impl RayGroupLanes for F32x8 {
        const LANES: usize = 8;

        #[inline(always)]
        fn load_at(x: &[f32; RAY_PACKET], from: usize) -> Self {
            assert!(
                from + 8 <= RAY_PACKET,
                "eight lanes from {from} of {RAY_PACKET}"
            );
            // SAFETY: AVX is available (see the type's contract); `x[from..]` holds at least 8
            // floats.
            F32x8(unsafe { _mm256_loadu_ps(x.as_ptr().add(from)) })
        }

        #[inline(always)]
        fn load_bits_at(x: &[u32; RAY_PACKET], from: usize) -> Self {
            assert!(
                from + 8 <= RAY_PACKET,
                "eight lanes from {from} of {RAY_PACKET}"
            );
            // SAFETY: AVX is available (see the type's contract); `x[from..]` holds at least 8
            // words.
            F32x8(unsafe { _mm256_castsi256_ps(_mm256_loadu_si256(x.as_ptr().add(from).cast())) })
        }

        #[inline(always)]
        fn store_at(self, x: &mut [f32; RAY_PACKET], from: usize) {
            assert!(
                from + 8 <= RAY_PACKET,
                "eight lanes from {from} of {RAY_PACKET}"
            );
            // SAFETY: AVX is available; `x[from..]` holds at least 8 floats.
            unsafe { _mm256_storeu_ps(x.as_mut_ptr().add(from), self.0) };
        }

        #[inline(always)]
        fn store_bits_at(self, x: &mut [u32; RAY_PACKET], from: usize) {
            assert!(
                from + 8 <= RAY_PACKET,
                "eight lanes from {from} of {RAY_PACKET}"
            );
            // SAFETY: AVX is available; `x[from..]` holds at least 8 words.
            unsafe {
                _mm256_storeu_si256(x.as_mut_ptr().add(from).cast(), _mm256_castps_si256(self.0))
            };
        }

        #[inline(always)]
        fn lane_mask(bits: u32) -> Self {
            let lane = |i: u32| if bits & (1 << i) != 0 { -1 } else { 0 };
            // SAFETY: AVX is available (the type's contract).
            F32x8(unsafe {
                _mm256_castsi256_ps(_mm256_setr_epi32(
                    lane(0),
                    lane(1),
                    lane(2),
                    lane(3),
                    lane(4),
                    lane(5),
                    lane(6),
                    lane(7),
                ))
            })
        }

        #[inline(always)]
        fn u32_above(self, x: u32) -> Self {
            // SAFETY: AVX2 is available (the type's contract). Flipping the top bit maps the
            // unsigned order onto the signed one that `cmpgt` compares.
            F32x8(unsafe {
                let flip = _mm256_set1_epi32(i32::MIN);
                let lanes = _mm256_xor_si256(_mm256_castps_si256(self.0), flip);
                let x = _mm256_xor_si256(_mm256_set1_epi32(x as i32), flip);
                _mm256_castsi256_ps(_mm256_cmpgt_epi32(lanes, x))
            })
        }

        #[inline(always)]
        fn lowest(self) -> f32 {
            // SAFETY: AVX2 is available (the type's contract). `minps` keeps the least of
            // every pair (no NaN lanes): halves, then quarters, then the last two lanes.
            unsafe {
                let m = _mm_min_ps(
                    _mm256_castps256_ps128(self.0),
                    _mm256_extractf128_ps::<1>(self.0),
                );
                let m = _mm_min_ps(m, _mm_movehl_ps(m, m));
                _mm_cvtss_f32(_mm_min_ss(m, _mm_shuffle_ps::<1>(m, m)))
            }
        }
    }

    macro_rules! binary {
        ($trait:ident, $method:ident, $intrinsic:ident) => {
            impl $trait for F32x8 {
                type Output = F32x8;
                #[inline(always)]
                fn $method(self, other: F32x8) -> F32x8 {
                    // SAFETY: AVX is available (the type's contract).
                    F32x8(unsafe { $intrinsic(self.0, other.0) })
                }
            }
        };
    }
    binary!(Add, add, _mm256_add_ps);
    binary!(Sub, sub, _mm256_sub_ps);
    binary!(Mul, mul, _mm256_mul_ps);
    binary!(Div, div, _mm256_div_ps);
    binary!(BitAnd, bitand, _mm256_and_ps);
    binary!(BitOr, bitor, _mm256_or_ps);
    binary!(BitXor, bitxor, _mm256_xor_ps);

    impl Not for F32x8 {
        type Output = F32x8;
        #[inline(always)]
        fn not(self) -> F32x8 {
            // SAFETY: AVX is available (the type's contract).
            unsafe {
                let ones = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
                F32x8(_mm256_xor_ps(self.0, ones))
            }
        }
    }

    /// An ordered, quiet comparison (false with a NaN), as SSE's `cmpltps` and friends.
    macro_rules! compare {
        ($method:ident, $predicate:ident) => {
            #[inline(always)]
            fn $method(self, other: F32x8) -> F32x8 {
                // SAFETY: AVX is available (the type's contract).
                F32x8(unsafe { _mm256_cmp_ps::<$predicate>(self.0, other.0) })
            }
        };
    }

    impl Lanes for F32x8 {
        #[inline(always)]
        fn splat(x: f32) -> Self {
            // SAFETY: AVX is available (the type's contract).
            F32x8(unsafe { _mm256_set1_ps(x) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            // SAFETY: AVX is available (the type's contract).
            F32x8(unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0) })
        }
        compare!(cmp_eq, _CMP_EQ_OQ);
        compare!(cmp_lt, _CMP_LT_OQ);
        compare!(cmp_le, _CMP_LE_OQ);
        compare!(cmp_gt, _CMP_GT_OQ);
        #[inline(always)]
        fn select(self, if_true: Self, if_false: Self) -> Self {
            // SAFETY: AVX is available (the type's contract). Masks are whole lanes, so the
            // sign bit `blendv` reads decides as the whole lane would.
            F32x8(unsafe { _mm256_blendv_ps(if_false.0, if_true.0, self.0) })
        }
        #[inline(always)]
        fn bitmask(self) -> u32 {
            // SAFETY: AVX is available (the type's contract).
            unsafe { _mm256_movemask_ps(self.0) as u32 }
        }
        #[inline(always)]
        fn greater(self, other: Self) -> Self {
            // SAFETY: AVX is available (the type's contract). `maxps` gives the second
            // operand unless the first is greater: exactly `Lanes::greater`.
            F32x8(unsafe { _mm256_max_ps(self.0, other.0) })
        }
        #[inline(always)]
        fn lesser(self, other: Self) -> Self {
            // SAFETY: AVX is available (the type's contract). `minps` gives the second
            // operand unless the first is less: exactly `Lanes::lesser`.
            F32x8(unsafe { _mm256_min_ps(self.0, other.0) })
        }
    }
}

// `std::arch`'s AVX-512 intrinsics are unsafe to call outside code compiled for AVX-512F; this
// module is the only place in the crate that calls them.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod avx512 {
    use super::{Lanes, RAY_PACKET, RayGroupLanes};
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, BitOr, BitXor, Div, Mul, Not, Sub};

    /// Sixteen `f32` lanes in one AVX-512 register; masks are whole lanes (all ones or all
    /// zeros), as at the other widths, made from and read into AVX-512's mask registers.
    ///
    /// Only code compiled with AVX-512F enabled (a `#[target_feature(enable = "avx512f")]`
    /// function, entered after `dispatch.rs` found AVX-512F on the host) may make or use one:
    /// every method is inlined into its caller, where the AVX-512 instructions are then allowed.
    #[derive(Clone, Copy)]
    pub(in crate::bvh) struct F32x16(__m512);

    /// The whole-lane mask of the mask register `k`.
    #[inline(always)]
    fn lanes_of(k: __mmask16) -> F32x16 {
        // SAFETY: AVX-512F is available (the type's contract).
        F32x16(unsafe { _mm512_castsi512_ps(_mm512_maskz_set1_epi32(k, -1)) })
    }

    impl F32x16 {
        /// The mask register of the whole-lane mask `self` (a lane is set when any bit is).
        #[inline(always)]
        fn mask(self) -> __mmask16 {
            // SAFETY: AVX-512F is available (the type's contract).
            unsafe {
                let bits = _mm512_castps_si512(self.0);
                _mm512_test_epi32_mask(bits, bits)
            }
        }

        #[inline(always)]
        fn bits(self) -> __m512i {
            // SAFETY: AVX-512F is available (the type's contract).
            unsafe { _mm512_castps_si512(self.0) }
        }

        #[inline(always)]
        fn from_bits(x: __m512i) -> Self {
            // SAFETY: AVX-512F is available (the type's contract).
            F32x16(unsafe { _mm512_castsi512_ps(x) })
        }
    }

    impl RayGroupLanes for F32x16 {
        const LANES: usize = 16;

        #[inline(always)]
        fn load_at(x: &[f32; RAY_PACKET], from: usize) -> Self {
            assert!(
                from + 16 <= RAY_PACKET,
                "sixteen lanes from {from} of {RAY_PACKET}"
            );
            // SAFETY: AVX-512F is available (see the type's contract); `x[from..]` holds at
            // least 16 floats (asserted).
            F32x16(unsafe { _mm512_loadu_ps(x.as_ptr().add(from)) })
        }

        #[inline(always)]
        fn load_bits_at(x: &[u32; RAY_PACKET], from: usize) -> Self {
            assert!(
                from + 16 <= RAY_PACKET,
                "sixteen lanes from {from} of {RAY_PACKET}"
            );
            // SAFETY: AVX-512F is available (see the type's contract); `x[from..]` holds at
            // least 16 words (asserted).
            Self::from_bits(unsafe { _mm512_loadu_si512(x.as_ptr().add(from).cast()) })
        }

        #[inline(always)]
        fn store_at(self, x: &mut [f32; RAY_PACKET], from: usize) {
            assert!(
                from + 16 <= RAY_PACKET,
                "sixteen lanes from {from} of {RAY_PACKET}"
            );
            // SAFETY: AVX-512F is available; `x[from..]` holds at least 16 floats (asserted).
            unsafe { _mm512_storeu_ps(x.as_mut_ptr().add(from), self.0) };
        }

        #[inline(always)]
        fn store_bits_at(self, x: &mut [u32; RAY_PACKET], from: usize) {
            assert!(
                from + 16 <= RAY_PACKET,
                "sixteen lanes from {from} of {RAY_PACKET}"
            );
            // SAFETY: AVX-512F is available; `x[from..]` holds at least 16 words (asserted).
            unsafe { _mm512_storeu_si512(x.as_mut_ptr().add(from).cast(), self.bits()) };
        }

        #[inline(always)]
        fn lane_mask(bits: u32) -> Self {
            lanes_of(bits as __mmask16)
        }

        #[inline(always)]
        fn u32_above(self, x: u32) -> Self {
            // SAFETY: AVX-512F is available (the type's contract); the compare is unsigned.
            lanes_of(unsafe { _mm512_cmpgt_epu32_mask(self.bits(), _mm512_set1_epi32(x as i32)) })
        }

        #[inline(always)]
        fn lowest(self) -> f32 {
            // SAFETY: AVX-512F is available (the type's contract).
            unsafe { _mm512_reduce_min_ps(self.0) }
        }
    }

    macro_rules! arithmetic {
        ($trait:ident, $method:ident, $intrinsic:ident) => {
            impl $trait for F32x16 {
                type Output = F32x16;
                #[inline(always)]
                fn $method(self, other: F32x16) -> F32x16 {
                    // SAFETY: AVX-512F is available (the type's contract).
                    F32x16(unsafe { $intrinsic(self.0, other.0) })
                }
            }
        };
    }
    arithmetic!(Add, add, _mm512_add_ps);
    arithmetic!(Sub, sub, _mm512_sub_ps);
    arithmetic!(Mul, mul, _mm512_mul_ps);
    arithmetic!(Div, div, _mm512_div_ps);

    /// Bitwise operations on the lanes' bits (AVX-512F has them on integer lanes only).
    macro_rules! bitwise {
        ($trait:ident, $method:ident, $intrinsic:ident) => {
            impl $trait for F32x16 {
                type Output = F32x16;
                #[inline(always)]
                fn $method(self, other: F32x16) -> F32x16 {
                    // SAFETY: AVX-512F is available (the type's contract).
                    F32x16::from_bits(unsafe { $intrinsic(self.bits(), other.bits()) })
                }
            }
        };
    }
    bitwise!(BitAnd, bitand, _mm512_and_si512);
    bitwise!(BitOr, bitor, _mm512_or_si512);
    bitwise!(BitXor, bitxor, _mm512_xor_si512);

    impl Not for F32x16 {
        type Output = F32x16;
        #[inline(always)]
        fn not(self) -> F32x16 {
            // SAFETY: AVX-512F is available (the type's contract).
            F32x16::from_bits(unsafe { _mm512_xor_si512(self.bits(), _mm512_set1_epi32(-1)) })
        }
    }

    /// An ordered, quiet comparison (false with a NaN), as SSE's `cmpltps` and friends.
    macro_rules! compare {
        ($method:ident, $predicate:ident) => {
            #[inline(always)]
            fn $method(self, other: F32x16) -> F32x16 {
                // SAFETY: AVX-512F is available (the type's contract).
                lanes_of(unsafe { _mm512_cmp_ps_mask::<$predicate>(self.0, other.0) })
            }
        };
    }

    impl Lanes for F32x16 {
        #[inline(always)]
        fn splat(x: f32) -> Self {
            // SAFETY: AVX-512F is available (the type's contract).
            F32x16(unsafe { _mm512_set1_ps(x) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            // SAFETY: AVX-512F is available (the type's contract).
            F32x16::from_bits(unsafe { _mm512_and_si512(self.bits(), _mm512_set1_epi32(i32::MAX)) })
        }
        compare!(cmp_eq, _CMP_EQ_OQ);
        compare!(cmp_lt, _CMP_LT_OQ);
        compare!(cmp_le, _CMP_LE_OQ);
        compare!(cmp_gt, _CMP_GT_OQ);
        #[inline(always)]
        fn select(self, if_true: Self, if_false: Self) -> Self {
            // SAFETY: AVX-512F is available (the type's contract).
            F32x16(unsafe { _mm512_mask_blend_ps(self.mask(), if_false.0, if_true.0) })
        }
        #[inline(always)]
        fn bitmask(self) -> u32 {
            u32::from(self.mask())
        }
        #[inline(always)]
        fn greater(self, other: Self) -> Self {
            // SAFETY: AVX-512F is available (the type's contract). `vmaxps` gives the second
            // operand unless the first is greater, as `maxps` does: exactly `Lanes::greater`.
            F32x16(unsafe { _mm512_max_ps(self.0, other.0) })
        }
        #[inline(always)]
        fn lesser(self, other: Self) -> Self {
            // SAFETY: AVX-512F is available (the type's contract). `vminps` gives the second
            // operand unless the first is less: exactly `Lanes::lesser`.
            F32x16(unsafe { _mm512_min_ps(self.0, other.0) })
        }
    }
}
