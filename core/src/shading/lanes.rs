//! Shading arithmetic of four points at once, one point per lane: a point light's
//! [`Incidence`] (the f64 arithmetic of [`super::incidence`]) and the one-ulp rounding of a
//! shadow origin ([`super::round_away`]). Each lane performs the scalar code's IEEE operations
//! in its order (no FMA; division and square root are correctly rounded in every SIMD
//! instruction set; the rounding is integer arithmetic on the bits), so each lane is the
//! scalar result bit for bit.

use super::Incidence;
use glam::{DVec3, Vec3};
use wide::{f32x4, f64x4, i32x4};

/// A point light's incidence at four points: unit directions toward the light and irradiance
/// per channel, lane by lane, and in `valid` bit k whether point k has an incidence at all
/// (not at the light's position).
pub(super) struct IncidenceLanes {
    pub to_light: [f32x4; 3],
    pub irradiance: [f32x4; 3],
    pub valid: u32,
}

/// [`super::incidence`] of the point light at `position` with `intensity` at the points whose
/// coordinates are `p` (axis by axis, point k in lane k).
#[inline(always)]
pub(super) fn point_incidence_lanes(
    position: DVec3,
    intensity: [f32; 3],
    p: [f32x4; 3],
) -> IncidenceLanes {
    let axis = |a: usize| f64x4::splat(position[a]) - widen(p[a]);
    let (vx, vy, vz) = (axis(0), axis(1), axis(2));
    // As `DVec3::length_squared`: (x·x + y·y) + z·z.
    let r2 = vx * vx + vy * vy + vz * vz;
    let length = r2.sqrt();
    // Grey lights (equal channel bits) divide once, as the scalar path does.
    let e0 = narrow(f64x4::splat(f64::from(intensity[0])) / r2);
    let channel = |k: usize| {
        if intensity[k].to_bits() == intensity[0].to_bits() {
            e0
        } else {
            narrow(f64x4::splat(f64::from(intensity[k])) / r2)
        }
    };
    IncidenceLanes {
        to_light: [
            narrow(vx / length),
            narrow(vy / length),
            narrow(vz / length),
        ],
        irradiance: [e0, channel(1), channel(2)],
        // `r2 <= 0` has no incidence; a NaN has one, as in the scalar test.
        valid: !r2.simd_le(f64x4::ZERO).to_bitmask() & 0xf,
    }
}

/// [`super::incidence`] of the point light at `position` with `intensity` at each of `points`.
#[inline]
pub(super) fn point_incidences4(
    position: DVec3,
    intensity: [f32; 3],
    points: [Vec3; 4],
) -> [Option<Incidence>; 4] {
    let axis = |a: usize| f32x4::from([points[0][a], points[1][a], points[2][a], points[3][a]]);
    let lanes = point_incidence_lanes(position, intensity, [axis(0), axis(1), axis(2)]);
    let [wx, wy, wz] = lanes.to_light;
    let (wx, wy, wz) = (wx.to_array(), wy.to_array(), wz.to_array());
    let [e0, e1, e2] = lanes.irradiance;
    let (e0, e1, e2) = (e0.to_array(), e1.to_array(), e2.to_array());
    let at = |k: usize| {
        (lanes.valid & (1 << k) != 0).then(|| Incidence {
            to_light: Vec3::new(wx[k], wy[k], wz[k]),
            irradiance: [e0[k], e1[k], e2[k]],
        })
    };
    [at(0), at(1), at(2), at(3)]
}

/// [`super::round_away`] of one axis, lane by lane: `po` one ulp further along the sign of
/// `offset` (`f32::next_up` where it is above zero, `f32::next_down` where below), unchanged
/// where it is zero or NaN.
#[inline(always)]
pub(super) fn round_away_lanes(po: f32x4, offset: f32x4) -> f32x4 {
    let zero = f32x4::ZERO;
    let (up, down) = (offset.simd_gt(zero), offset.simd_lt(zero));
    let (up, down): (i32x4, i32x4) = (wide::bytemuck::cast(up), wide::bytemuck::cast(down));
    let bits: i32x4 = wide::bytemuck::cast(po);
    let magnitude = bits & i32x4::splat(i32::MAX);
    let negative = bits.simd_lt(i32x4::ZERO);
    // Away from zero (the magnitude grows by one ulp) where the sign and the direction agree,
    // else toward it; from a zero of either sign, to the smallest subnormal on the direction's
    // side.
    let away = !(negative ^ down);
    let moved = away.select(bits + i32x4::ONE, bits - i32x4::ONE);
    let from_zero = (down & i32x4::splat(i32::MIN)) | i32x4::ONE;
    let moved = magnitude.simd_eq(i32x4::ZERO).select(from_zero, moved);
    // NaN stays NaN; an infinity stays where it moves away from zero (+inf up, -inf down).
    let infinity = i32x4::splat(0x7f80_0000);
    let stays = magnitude.simd_gt(infinity) | (magnitude.simd_eq(infinity) & away);
    let moves = (up | down) & !stays;
    wide::bytemuck::cast(moves.select(moved, bits))
}

/// The f64 value of each lane (exact).
#[inline(always)]
pub(super) fn widen(x: f32x4) -> f64x4 {
    let x = x.to_array();
    f64x4::from([
        f64::from(x[0]),
        f64::from(x[1]),
        f64::from(x[2]),
        f64::from(x[3]),
    ])
}

/// Each lane rounded to f32 (as `as f32`).
#[inline(always)]
pub(super) fn narrow(x: f64x4) -> f32x4 {
    let x = x.to_array();
    f32x4::from([x[0] as f32, x[1] as f32, x[2] as f32, x[3] as f32])
}

#[cfg(test)]
mod tests {
    use super::*;

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
        ];
        let offsets = [1e-6f32, -1e-6, 0.0, -0.0, f32::NAN, f32::INFINITY];
        let mut checked = 0;
        for &offset in &offsets {
            for four in values.chunks(4) {
                let at = |k: usize| four.get(k).copied().unwrap_or(four[0]);
                let po = [at(0), at(1), at(2), at(3)];
                let got = round_away_lanes(f32x4::from(po), f32x4::splat(offset)).to_array();
                for k in 0..4 {
                    let expected =
                        super::super::round_away(Vec3::splat(po[k]), Vec3::splat(offset)).x;
                    assert_eq!(
                        got[k].to_bits(),
                        expected.to_bits(),
                        "{} moved along {offset}",
                        po[k]
                    );
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, offsets.len() * 16);
    }
}
