//! A point light's [`Incidence`] at `N` points at once, one point per lane (the f64
//! arithmetic of [`super::incidence`], in [`super::array_lanes`]): for the hit lanes
//! (`hit_lanes.rs`) and, four points at a time, for [`super::ShadowTester`]. Each lane performs
//! the scalar code's IEEE operations in its order (no FMA; division and square root are
//! correctly rounded in every SIMD instruction set), so each lane is the scalar result bit for
//! bit.

use super::Incidence;
use super::array_lanes::{F32s, F64s};
use crate::bvh::first_bits;
use glam::{DVec3, Vec3};

/// A point light's incidence at `N` points: unit directions toward the light and irradiance
/// per channel, lane by lane, and in `valid` bit k whether point k has an incidence at all
/// (not at the light's position).
pub(super) struct IncidenceLanes<const N: usize> {
    pub to_light: [F32s<N>; 3],
    pub irradiance: [F32s<N>; 3],
    pub valid: u32,
}

/// [`super::incidence`] of the point light at `position` with `intensity` at the points whose
/// coordinates are `p` (axis by axis, point k in lane k).
#[inline(always)]
pub(super) fn point_incidence_lanes<const N: usize>(
    position: DVec3,
    intensity: [f32; 3],
    p: [F32s<N>; 3],
) -> IncidenceLanes<N> {
    let axis = |a: usize| F64s::splat(position[a]) - p[a].widen();
    let (vx, vy, vz) = (axis(0), axis(1), axis(2));
    // As `DVec3::length_squared`: (x·x + y·y) + z·z.
    let r2 = vx * vx + vy * vy + vz * vz;
    let length = r2.sqrt();
    // Grey lights (equal channel bits) divide once, as the scalar path does.
    let e0 = (F64s::splat(f64::from(intensity[0])) / r2).narrow();
    let channel = |k: usize| {
        if intensity[k].to_bits() == intensity[0].to_bits() {
            e0
        } else {
            (F64s::splat(f64::from(intensity[k])) / r2).narrow()
        }
    };
    IncidenceLanes {
        to_light: [
            (vx / length).narrow(),
            (vy / length).narrow(),
            (vz / length).narrow(),
        ],
        irradiance: [e0, channel(1), channel(2)],
        // `r2 <= 0` has no incidence; a NaN has one, as in the scalar test.
        valid: !r2.le(F64s::splat(0.0)).to_bits() & first_bits(N),
    }
}

/// [`super::incidence`] of the point light at `position` with `intensity` at each of `points`.
#[inline]
pub(super) fn point_incidences4(
    position: DVec3,
    intensity: [f32; 3],
    points: [Vec3; 4],
) -> [Option<Incidence>; 4] {
    let axis = |a: usize| F32s([points[0][a], points[1][a], points[2][a], points[3][a]]);
    let lanes = point_incidence_lanes(position, intensity, [axis(0), axis(1), axis(2)]);
    let [wx, wy, wz] = lanes.to_light.map(|w| w.0);
    let [e0, e1, e2] = lanes.irradiance.map(|e| e.0);
    let at = |k: usize| {
        (lanes.valid & (1 << k) != 0).then(|| Incidence {
            to_light: Vec3::new(wx[k], wy[k], wz[k]),
            irradiance: [e0[k], e1[k], e2[k]],
        })
    };
    [at(0), at(1), at(2), at(3)]
}
