//! Radiometry: two-sided Lambertian surfaces lit by point and directional lights, hard shadows,
//! and an optional constant ambient term.
//!
//! Outgoing radiance toward the camera at a hit with diffuse reflectance kd (per channel):
//!   L = sum over visible lights of kd/pi · E_light  +  kd · ambient,
//! with E = I·cos(theta)/r^2 for a point light of radiant intensity I at distance r, and
//! E = E_dir·cos(theta) for a directional light, theta measured from the shading normal. A
//! light contributes only when it is on the viewer's side of the surface (two-sided BSDF) and no
//! triangle lies on the shadow segment. This is Mitsuba 3's `direct` integrator with a
//! `twosided(diffuse)` BSDF and `point`/`directional` emitters, so both converge to one image.
//!
//! Shadow rays start at the hit point moved off the surface by its floating-point error bound
//! (pbrt-v4, "Robust Spawned Ray Origins"): the offset scales with the coordinates' magnitudes,
//! so it works for scenes of any scale, unlike a fixed epsilon.

use crate::scene::Light;
use crate::triangle::{Ray, gamma};
use glam::{DVec3, Vec3};

/// Fraction of a point light's distance not tested for occluders, at the light's end
/// (pbrt-v4's ShadowEpsilon): nothing can sit exactly on a point light.
pub const SHADOW_EPSILON: f32 = 1e-4;

/// What shading needs of a hit, computed once where the hit is found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// Hit position interpolated from the corners with the barycentrics.
    pub p: Vec3,
    /// Conservative absolute error bound of `p` per axis.
    pub p_error: Vec3,
    /// Unit geometric normal, flipped to face the incoming ray.
    pub n_geo: Vec3,
    /// Unit shading normal (interpolated vertex normals, else `n_geo`), in `n_geo`'s hemisphere.
    pub n_shade: Vec3,
    /// Diffuse reflectance.
    pub kd: [f32; 3],
}

/// One light's shadow test for a surface point: the segment to test and the radiance the light
/// adds when nothing blocks it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowTest {
    /// From the offset hit point toward the light, as [`shadow_ray`] builds it: reaching a
    /// point light at t = 1, or along the unit direction to a directional light.
    pub ray: Ray,
    /// Occluders count for `0 < t < t_max` along `ray`.
    pub t_max: f32,
    /// Radiance per RGB channel the light adds toward the viewer if unblocked: kd/pi · E.
    pub unoccluded: [f32; 3],
}

/// Builds the surface point of a hit on triangle `corners` at barycentrics `b`, seen along
/// `ray_dir`; `normals` are the corners' vertex normals if the mesh has them.
#[inline]
pub fn surface_point(
    corners: [Vec3; 3],
    b: [f32; 3],
    ray_dir: Vec3,
    normals: Option<[Vec3; 3]>,
    kd: [f32; 3],
) -> SurfacePoint {
    let [p0, p1, p2] = corners;
    let p = b[0] * p0 + b[1] * p1 + b[2] * p2;
    let p_error = gamma(7.0) * ((b[0] * p0).abs() + (b[1] * p1).abs() + (b[2] * p2).abs());
    let mut n_geo = (p1 - p0).cross(p2 - p0).normalize_or_zero();
    if n_geo.dot(ray_dir) > 0.0 {
        n_geo = -n_geo;
    }
    let n_shade = match normals {
        Some([n0, n1, n2]) => {
            let n = (b[0] * n0 + b[1] * n1 + b[2] * n2).normalize_or_zero();
            if n == Vec3::ZERO {
                n_geo
            } else if n.dot(n_geo) < 0.0 {
                -n
            } else {
                n
            }
        }
        None => n_geo,
    };
    SurfacePoint {
        p,
        p_error,
        n_geo,
        n_shade,
        kd,
    }
}

/// The shadow test of `light` at `sp`, or `None` when the light cannot contribute (behind the
/// surface as seen by the viewer, or at grazing angle), so no ray is needed.
#[inline]
pub fn shadow_test(sp: &SurfacePoint, light: &Light) -> Option<ShadowTest> {
    let (to_light, irradiance) = match *light {
        Light::Point {
            position,
            intensity,
        } => {
            let v: DVec3 = position - sp.p.as_dvec3();
            let r2 = v.length_squared();
            if r2 <= 0.0 {
                return None;
            }
            let wi = (v / r2.sqrt()).as_vec3();
            // Grey lights (equal channel bits) divide once: the same operation on the same
            // operands, so the same bits.
            let e0 = (f64::from(intensity[0]) / r2) as f32;
            let e = |k: usize| {
                if intensity[k].to_bits() == intensity[0].to_bits() {
                    e0
                } else {
                    (f64::from(intensity[k]) / r2) as f32
                }
            };
            (wi, [e0, e(1), e(2)])
        }
        Light::Directional {
            direction,
            irradiance,
        } => ((-direction).as_vec3(), irradiance),
    };
    let cos_geo = sp.n_geo.dot(to_light);
    let cos = sp.n_shade.dot(to_light);
    if cos_geo <= 0.0 || cos <= 0.0 {
        return None;
    }
    let origin = offset_origin(sp.p, sp.p_error, sp.n_geo, to_light);
    let (ray, t_max) = shadow_ray(light, origin);
    let f = std::f32::consts::FRAC_1_PI * cos;
    Some(ShadowTest {
        ray,
        t_max,
        unoccluded: [
            sp.kd[0] * f * irradiance[0],
            sp.kd[1] * f * irradiance[1],
            sp.kd[2] * f * irradiance[2],
        ],
    })
}

/// The shadow segment from `origin` to `light`: toward a point light, the ray reaches the light
/// at t = 1 and occluders count for t < 1 - [`SHADOW_EPSILON`]; toward a directional light, the
/// ray is unbounded. A pure function of (light, origin), so stages that carry only the origin
/// rebuild the identical ray.
#[inline]
pub fn shadow_ray(light: &Light, origin: Vec3) -> (Ray, f32) {
    match *light {
        Light::Point { position, .. } => {
            let dir = (position - origin.as_dvec3()).as_vec3();
            (Ray { origin, dir }, 1.0 - SHADOW_EPSILON)
        }
        Light::Directional { direction, .. } => {
            let dir = (-direction).as_vec3();
            (Ray { origin, dir }, f32::INFINITY)
        }
    }
}

/// The final radiance of a hit: the unblocked lights' contributions summed in light order,
/// then `kd · ambient`. Every renderer path sums in this order, so results match bit for bit.
#[inline]
pub fn combine(
    kd: [f32; 3],
    contributions: impl Iterator<Item = [f32; 3]>,
    ambient: [f32; 3],
) -> [f32; 3] {
    let mut sum = [0.0f32; 3];
    for c in contributions {
        for k in 0..3 {
            sum[k] += c[k];
        }
    }
    [
        sum[0] + kd[0] * ambient[0],
        sum[1] + kd[1] * ambient[1],
        sum[2] + kd[2] * ambient[2],
    ]
}

/// Moves `p` off the surface by its error bound along `n`, to the side of `w`, and rounds away
/// (pbrt-v4 `OffsetRayOrigin`).
#[inline]
fn offset_origin(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.abs().dot(p_error);
    let mut offset = d * n;
    if w.dot(n) < 0.0 {
        offset = -offset;
    }
    let mut po = p + offset;
    for i in 0..3 {
        if offset[i] > 0.0 {
            po[i] = po[i].next_up();
        } else if offset[i] < 0.0 {
            po[i] = po[i].next_down();
        }
    }
    po
}

#[cfg(test)]
mod tests {
    use super::*;

    fn facing_up(kd: f32) -> SurfacePoint {
        surface_point(
            [Vec3::ZERO, Vec3::Z, Vec3::X],
            [1.0 / 3.0; 3],
            Vec3::new(0.0, -1.0, 0.0),
            None,
            [kd; 3],
        )
    }

    #[test]
    fn white_surface_facing_default_light_has_radiance_one() {
        let sp = facing_up(1.0);
        let c = sp.p.as_dvec3();
        let position = c + DVec3::new(0.0, 2.0, 0.0);
        let intensity = (std::f64::consts::PI * 4.0) as f32;
        let light = Light::Point {
            position,
            intensity: [intensity; 3],
        };
        let t = shadow_test(&sp, &light).expect("light is above");
        for v in t.unoccluded {
            assert!((v - 1.0).abs() < 1e-6, "{v}");
        }
    }

    #[test]
    fn light_behind_the_surface_contributes_nothing() {
        let sp = facing_up(1.0);
        let light = Light::Point {
            position: DVec3::new(0.3, -2.0, 0.3),
            intensity: [10.0; 3],
        };
        assert!(shadow_test(&sp, &light).is_none());
    }

    #[test]
    fn normal_faces_the_viewer_from_either_side() {
        let from_above = facing_up(0.5);
        assert_eq!(from_above.n_geo, Vec3::Y);
        let from_below = surface_point(
            [Vec3::ZERO, Vec3::Z, Vec3::X],
            [1.0 / 3.0; 3],
            Vec3::Y,
            None,
            [0.5; 3],
        );
        assert_eq!(from_below.n_geo, -Vec3::Y);
    }

    #[test]
    fn shadow_origin_is_off_the_surface_at_any_scale() {
        for scale in [1e-4f32, 1.0, 1e4] {
            let corners = [Vec3::ZERO, Vec3::Z * scale, Vec3::X * scale]
                .map(|v| v + Vec3::splat(3.0 * scale));
            let sp = surface_point(corners, [0.2, 0.3, 0.5], -Vec3::Y, None, [1.0; 3]);
            let light = Light::Directional {
                direction: DVec3::new(0.0, -1.0, 0.0),
                irradiance: [1.0; 3],
            };
            let t = shadow_test(&sp, &light).unwrap();
            assert!(
                t.ray.origin.y > corners[0].y,
                "scale {scale}: origin not above the plane"
            );
            assert!(t.ray.origin.y - corners[0].y < 1e-5 * scale.max(1.0) * 10.0);
        }
    }
}
