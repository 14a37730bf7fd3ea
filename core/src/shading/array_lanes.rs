//! Lanes of any count `N` kept in plain arrays: [`F32s`] of `f32`, [`F64s`] of `f64` and
//! [`Mask`]s of whole lanes. Each operation is a loop that does one IEEE operation per lane
//! (add, subtract, multiply, divide and square root correctly rounded, never fused; widening
//! exact, narrowing to nearest; comparisons ordered, false with a NaN), which the compiler
//! turns into vector instructions of the instruction set the calling function is compiled
//! for: sixteen `f32` lanes take one AVX-512 register, two AVX ones, or four SSE4.1 or NEON
//! ones (`render/batch.rs` compiles its shading for each and enters the one the host has). No
//! instruction set changes a lane's bits, so code written once over these types gives the
//! same answers at every lane count and on every machine.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// `N` lanes of `f32`.
#[derive(Clone, Copy, Debug)]
pub(super) struct F32s<const N: usize>(pub [f32; N]);

/// `N` lanes of `f64`.
#[derive(Clone, Copy, Debug)]
pub(super) struct F64s<const N: usize>(pub [f64; N]);

/// `N` lane masks: all ones where set, zeros elsewhere.
#[derive(Clone, Copy, Debug)]
pub(super) struct Mask<const N: usize>([u32; N]);

/// `[f(a[0]), f(a[1]), f(a[2])]`: `array::map` spelled out, since `map` is not always
/// inlined, and then runs apart from the lanes' instruction set (a call per element,
/// compiled for the baseline).
#[inline(always)]
pub(super) fn three<A, B>(a: [A; 3], f: impl Fn(A) -> B) -> [B; 3] {
    let [a0, a1, a2] = a;
    [f(a0), f(a1), f(a2)]
}

/// `[f(a[k]) for each k]`.
#[inline(always)]
fn each<A: Copy, B: Copy + Default, const N: usize>(a: [A; N], f: impl Fn(A) -> B) -> [B; N] {
    let mut out = [B::default(); N];
    for k in 0..N {
        out[k] = f(a[k]);
    }
    out
}

/// `[f(a[k], b[k]) for each k]`.
#[inline(always)]
fn pairs<A: Copy, B: Copy, C: Copy + Default, const N: usize>(
    a: [A; N],
    b: [B; N],
    f: impl Fn(A, B) -> C,
) -> [C; N] {
    let mut out = [C::default(); N];
    for k in 0..N {
        out[k] = f(a[k], b[k]);
    }
    out
}

/// All ones for `true`.
#[inline(always)]
fn whole(set: bool) -> u32 {
    0u32.wrapping_sub(u32::from(set))
}

macro_rules! arithmetic {
    ($lanes:ident, $trait:ident, $method:ident, $op:tt) => {
        impl<const N: usize> $trait for $lanes<N> {
            type Output = Self;
            #[inline(always)]
            fn $method(self, o: Self) -> Self {
                $lanes(pairs(self.0, o.0, |a, b| a $op b))
            }
        }
    };
}
arithmetic!(F32s, Add, add, +);
arithmetic!(F32s, Sub, sub, -);
arithmetic!(F32s, Mul, mul, *);
arithmetic!(F32s, Div, div, /);
arithmetic!(F64s, Add, add, +);
arithmetic!(F64s, Sub, sub, -);
arithmetic!(F64s, Mul, mul, *);
arithmetic!(F64s, Div, div, /);

impl<const N: usize> Neg for F32s<N> {
    type Output = Self;
    /// The sign bit flipped, as scalar negation does.
    #[inline(always)]
    fn neg(self) -> Self {
        F32s(each(self.0, |a: f32| -a))
    }
}

impl<const N: usize> F32s<N> {
    pub const ZERO: Self = F32s([0.0; N]);

    #[inline(always)]
    pub fn splat(x: f32) -> Self {
        F32s([x; N])
    }

    #[inline(always)]
    pub fn sqrt(self) -> Self {
        F32s(each(self.0, f32::sqrt))
    }

    /// The sign bit cleared.
    #[inline(always)]
    pub fn abs(self) -> Self {
        F32s(each(self.0, f32::abs))
    }

    /// Each lane exactly in `f64`.
    #[inline(always)]
    pub fn widen(self) -> F64s<N> {
        F64s(each(self.0, f64::from))
    }

    #[inline(always)]
    pub fn gt(self, o: Self) -> Mask<N> {
        Mask(pairs(self.0, o.0, |a, b| whole(a > b)))
    }

    #[inline(always)]
    pub fn lt(self, o: Self) -> Mask<N> {
        Mask(pairs(self.0, o.0, |a, b| whole(a < b)))
    }

    #[inline(always)]
    pub fn le(self, o: Self) -> Mask<N> {
        Mask(pairs(self.0, o.0, |a, b| whole(a <= b)))
    }

    #[inline(always)]
    pub fn ge(self, o: Self) -> Mask<N> {
        Mask(pairs(self.0, o.0, |a, b| whole(a >= b)))
    }

    #[inline(always)]
    pub fn eq(self, o: Self) -> Mask<N> {
        Mask(pairs(self.0, o.0, |a, b| whole(a == b)))
    }

    /// The sign bit flipped where `flip` is set.
    #[inline(always)]
    pub fn negate_where(self, flip: Mask<N>) -> Self {
        F32s(pairs(self.0, flip.0, |a, m| {
            f32::from_bits(a.to_bits() ^ (m & 0x8000_0000))
        }))
    }

    /// Each lane's bit pattern as an integer.
    #[inline(always)]
    pub fn bits(self) -> [u32; N] {
        each(self.0, f32::to_bits)
    }

    /// Set where the lane is above zero and finite (`x > 0 && x < inf`), decided on the bits:
    /// those are exactly the lanes whose bits lie in `1..=0x7f7f_ffff`, so whose bits less one
    /// (wrapping) are below `0x7f7f_ffff`; +0, +inf, NaNs and negative values all fall
    /// outside. Written as two float comparisons, the compiler turned the pair into a class
    /// test that it then ran lane by lane in scalar code (a quarter of the AVX-512 shading
    /// function's instructions).
    #[inline(always)]
    pub fn positive_finite(self) -> Mask<N> {
        Mask(each(self.bits(), |b: u32| {
            whole(b.wrapping_sub(1) < 0x7f7f_ffff)
        }))
    }

    /// `self` one ulp further along the sign of `offset` (`f32::next_up` where it is above
    /// zero, `f32::next_down` where below), unchanged where it is zero or NaN: the rounding of
    /// [`super::round_away`], lane by lane, as integer arithmetic on the bits.
    #[inline(always)]
    pub fn round_away(self, offset: Self) -> Self {
        let mut out = [0.0; N];
        for (k, out) in out.iter_mut().enumerate() {
            let (bits, offset) = (self.0[k].to_bits(), offset.0[k]);
            let (up, down) = (offset > 0.0, offset < 0.0);
            let magnitude = bits & 0x7fff_ffff;
            let negative = (bits as i32) < 0;
            // Away from zero (the magnitude grows by one ulp) where the sign and the
            // direction agree, else toward it; from a zero of either sign, to the smallest
            // subnormal on the direction's side.
            let away = negative == down;
            let moved = if magnitude == 0 {
                (u32::from(down) << 31) | 1
            } else if away {
                bits.wrapping_add(1)
            } else {
                bits.wrapping_sub(1)
            };
            // NaN stays NaN; an infinity stays where it moves away from zero.
            let infinity = 0x7f80_0000;
            let stays = (magnitude > infinity) | ((magnitude == infinity) & away);
            let moves = (up | down) & !stays;
            *out = f32::from_bits(if moves { moved } else { bits });
        }
        F32s(out)
    }
}

impl<const N: usize> F64s<N> {
    #[inline(always)]
    pub fn splat(x: f64) -> Self {
        F64s([x; N])
    }

    #[inline(always)]
    pub fn sqrt(self) -> Self {
        F64s(each(self.0, f64::sqrt))
    }

    /// Each lane rounded to `f32` (as `as f32`).
    #[inline(always)]
    pub fn narrow(self) -> F32s<N> {
        F32s(each(self.0, |x| x as f32))
    }

    #[inline(always)]
    pub fn le(self, o: Self) -> Mask<N> {
        Mask(pairs(self.0, o.0, |a, b| whole(a <= b)))
    }
}

impl<const N: usize> Mask<N> {
    /// Bit k set where lane k is.
    #[inline(always)]
    pub fn to_bits(self) -> u32 {
        let mut bits = 0;
        for (k, m) in self.0.iter().enumerate() {
            bits |= (m & 1) << k;
        }
        bits
    }

    #[inline(always)]
    pub fn and(self, o: Self) -> Self {
        Mask(pairs(self.0, o.0, |a, b| a & b))
    }

    #[inline(always)]
    pub fn not(self) -> Self {
        Mask(each(self.0, |a: u32| !a))
    }

    /// `a` where set, else `b`.
    #[inline(always)]
    pub fn select(self, a: F32s<N>, b: F32s<N>) -> F32s<N> {
        let (a, b) = (a.bits(), b.bits());
        let mut out = [0.0; N];
        for k in 0..N {
            out[k] = f32::from_bits((a[k] & self.0[k]) | (b[k] & !self.0[k]));
        }
        F32s(out)
    }

    /// `a` where set, +0 elsewhere.
    #[inline(always)]
    pub fn keep(self, a: F32s<N>) -> F32s<N> {
        F32s(pairs(self.0, a.0, |m, a| f32::from_bits(a.to_bits() & m)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// Every pair of special and ordinary values, rounded in lanes, is `round_away`'s scalar
    /// rounding bit for bit: zeros of both signs, subnormals, the largest finite values,
    /// infinities, NaN, and offsets of every sign.
    #[test]
    fn rounding_in_lanes_is_the_scalar_rounding() {
        let values = [
            0.0f32,
            -0.0,
            f32::from_bits(1),
            -f32::from_bits(1),
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            1.0,
            -1.0,
            3.5e-7,
            -2.25e5,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
        ];
        let offsets = [1e-6f32, -1e-6, 0.0, -0.0, f32::NAN, f32::INFINITY];
        let mut checked = 0;
        for &offset in &offsets {
            let got = F32s(values).round_away(F32s::splat(offset));
            for (k, &po) in values.iter().enumerate() {
                let expected = super::super::round_away(Vec3::splat(po), Vec3::splat(offset)).x;
                assert_eq!(
                    got.0[k].to_bits(),
                    expected.to_bits(),
                    "{po} moved along {offset}"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, offsets.len() * 16);
    }
}
