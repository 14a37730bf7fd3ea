//! A point light's [`Incidence`] at four points at once, one point per lane (the f64
//! arithmetic of [`super::incidence`]), for [`super::ShadowTester`]. Each lane performs the
//! scalar code's IEEE operations in its order (no FMA; division and square root are correctly
//! rounded in every SIMD instruction set), so each lane is the scalar result bit for bit.

use super::Incidence;
use glam::{DVec3, Vec3};
use wide::{f32x4, f64x4};

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
