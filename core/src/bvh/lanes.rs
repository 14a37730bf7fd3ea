//! The lane operations of the triangle tests, at any SIMD width: four lanes ([`f32x4`] of the
//! `wide` crate: SSE4.1 on x86-64, NEON on aarch64) everywhere, and eight ([`F32x8`], AVX) on
//! x86-64 hosts that have AVX2, chosen at run time (`dispatch.rs`).
//!
//! Guarantee: each operation is one IEEE operation per lane (add, subtract, multiply and
//! divide correctly rounded, never fused), comparisons are ordered (false when a lane holds a
//! NaN) and masks are whole lanes, so a lane computes the same bits at any width and on any
//! machine. Code written once over [`Lanes`] therefore gives the same answers at every width.

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
    // Only the 8-wide leaves (x86-64) select through the trait.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    fn select(self, if_true: Self, if_false: Self) -> Self;
    /// Bit i set when lane i of the mask is set.
    fn bitmask(self) -> u32;
    /// Per lane `if self > other { self } else { other }` (so `other` when either is NaN).
    fn greater(self, other: Self) -> Self;
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
}

#[cfg(target_arch = "x86_64")]
pub(super) use avx::F32x8;

// `std::arch`'s AVX intrinsics are unsafe to call outside code compiled for AVX; this module
// is the only place in the crate that calls them.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod avx {
    use super::Lanes;
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, BitOr, BitXor, Div, Mul, Not, Sub};

    /// Eight `f32` lanes in one AVX register.
    ///
    /// Only code compiled with AVX2 enabled (a `#[target_feature(enable = "avx2")]` function,
    /// entered after `dispatch.rs` found AVX2 on the host) may make or use one: every method
    /// is inlined into its caller, where the AVX instructions are then allowed.
    #[derive(Clone, Copy)]
    pub(in crate::bvh) struct F32x8(__m256);

    impl F32x8 {
        #[inline(always)]
        pub fn from_array(x: [f32; 8]) -> Self {
            // SAFETY: AVX is available (see the type's contract); the array holds 8 floats.
            F32x8(unsafe { _mm256_loadu_ps(x.as_ptr()) })
        }

        /// Lanes holding the bit patterns `x`.
        #[inline(always)]
        pub fn from_bits(x: [u32; 8]) -> Self {
            // SAFETY: AVX is available (see the type's contract); the array holds 8 words.
            F32x8(unsafe { _mm256_castsi256_ps(_mm256_loadu_si256(x.as_ptr().cast())) })
        }

        /// The lanes' bit patterns.
        #[inline(always)]
        pub fn to_bits(self) -> [u32; 8] {
            let mut out = [0u32; 8];
            // SAFETY: AVX is available; `out` holds 8 words.
            unsafe { _mm256_storeu_si256(out.as_mut_ptr().cast(), _mm256_castps_si256(self.0)) };
            out
        }

        /// All ones in the lanes whose bit is set in `bits`.
        #[inline(always)]
        pub fn lane_mask(bits: u32) -> Self {
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

        /// Lanes (holding `u32` bit patterns) whose value is above `x`, unsigned.
        #[inline(always)]
        pub fn u32_above(self, x: u32) -> Self {
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
        pub fn to_array(self) -> [f32; 8] {
            let mut out = [0.0f32; 8];
            // SAFETY: AVX is available; `out` holds 8 floats.
            unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) };
            out
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
    }
}
