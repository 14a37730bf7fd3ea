//! A point light's [`Incidence`] at four points at once: the f64 arithmetic of
//! [`super::incidence`], each operation one IEEE operation per lane in the same order (no FMA;
//! division and square root are correctly rounded in every SIMD instruction set), so each lane
//! is the scalar result bit for bit.

use super::Incidence;
use glam::{DVec3, Vec3};
use wide::f64x4;

/// [`super::incidence`] of the point light at `position` with `intensity` at each of `points`.
#[inline]
pub(super) fn point_incidences4(
    position: DVec3,
    intensity: [f32; 3],
    points: [Vec3; 4],
) -> [Option<Incidence>; 4] {
    let axis = |a: usize| f64x4::splat(position[a]) - f64x4::from(points.map(|p| f64::from(p[a])));
    let (vx, vy, vz) = (axis(0), axis(1), axis(2));
    // As `DVec3::length_squared`: (x·x + y·y) + z·z.
    let r2 = vx * vx + vy * vy + vz * vz;
    let length = r2.sqrt();
    let (wx, wy, wz) = (
        (vx / length).to_array(),
        (vy / length).to_array(),
        (vz / length).to_array(),
    );
    // Grey lights (equal channel bits) divide once, as the scalar path does.
    let e0 = (f64x4::splat(f64::from(intensity[0])) / r2).to_array();
    let channel = |k: usize| {
        if intensity[k].to_bits() == intensity[0].to_bits() {
            e0
        } else {
            (f64x4::splat(f64::from(intensity[k])) / r2).to_array()
        }
    };
    let (e1, e2) = (channel(1), channel(2));
    let r2 = r2.to_array();
    std::array::from_fn(|k| {
        if r2[k] <= 0.0 {
            None
        } else {
            Some(Incidence {
                to_light: Vec3::new(wx[k] as f32, wy[k] as f32, wz[k] as f32),
                irradiance: [e0[k] as f32, e1[k] as f32, e2[k] as f32],
            })
        }
    })
}
