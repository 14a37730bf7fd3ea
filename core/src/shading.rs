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
use wide::f32x4;

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

/// Four hits' shading inputs, one lane per hit, for [`surface_points4`].
#[derive(Clone, Copy, Debug)]
pub struct SurfaceInputs4 {
    /// Triangle corners per lane.
    pub corners: [[Vec3; 3]; 4],
    /// Barycentrics per lane.
    pub b: [[f32; 3]; 4],
    /// Direction of the ray that found the hit, per lane.
    pub ray_dir: [Vec3; 4],
    /// Vertex normals per lane, if the mesh has them.
    pub normals: [Option<[Vec3; 3]>; 4],
    /// Diffuse reflectance per lane.
    pub kd: [[f32; 3]; 4],
}

/// Three coordinates of four points, one lane per point.
type Lanes3 = [f32x4; 3];

/// Lane `i` holds `v(i)[axis]` for each axis.
#[inline(always)]
fn lanes3(v: impl Fn(usize) -> Vec3) -> Lanes3 {
    let [a, b, c, d] = [v(0), v(1), v(2), v(3)];
    [
        f32x4::from([a.x, b.x, c.x, d.x]),
        f32x4::from([a.y, b.y, c.y, d.y]),
        f32x4::from([a.z, b.z, c.z, d.z]),
    ]
}

/// `Vec3::dot` per lane, in its order: `(x·x' + y·y') + z·z'`.
#[inline(always)]
fn dot4(a: &Lanes3, b: &Lanes3) -> f32x4 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `b0·p0 + b1·p1 + b2·p2` per lane, as `surface_point` sums it.
#[inline(always)]
fn interpolate4(b: &[f32x4; 3], v: &[Lanes3; 3]) -> Lanes3 {
    std::array::from_fn(|a| b[0] * v[0][a] + b[1] * v[1][a] + b[2] * v[2][a])
}

/// `Vec3::normalize_or_zero` per lane: `v · (1 / sqrt(v·v))` where that reciprocal is finite
/// and positive, else +0 (SIMD division and square root are correctly rounded, as scalar ones).
#[inline(always)]
fn normalize_or_zero4(v: &Lanes3) -> Lanes3 {
    let rcp = f32x4::ONE / dot4(v, v).sqrt();
    let ok = rcp.simd_gt(f32x4::ZERO) & rcp.simd_lt(f32x4::splat(f32::INFINITY));
    v.map(|c| ok.select(c * rcp, f32x4::ZERO))
}

/// Flips the sign bit of the lanes set in `mask` (an exact negation, as `-v`).
#[inline(always)]
fn negate_where(mask: f32x4, v: &Lanes3) -> Lanes3 {
    let sign = mask & f32x4::splat(-0.0);
    v.map(|c| c ^ sign)
}

/// Four [`surface_point`]s at once in SIMD lanes: lane `i` of the result is
/// `surface_point(corners[i], b[i], ray_dir[i], normals[i], kd[i])` bit for bit (the same IEEE
/// operations in the same order per lane, no FMA, selects instead of branches).
#[inline]
pub fn surface_points4(s: &SurfaceInputs4) -> [SurfacePoint; 4] {
    let corner = |c: usize| lanes3(|i| s.corners[i][c]);
    let p = [corner(0), corner(1), corner(2)];
    let b: [f32x4; 3] = std::array::from_fn(|k| f32x4::from(s.b.map(|b| b[k])));
    let pos = interpolate4(&b, &p);
    let g7 = f32x4::splat(gamma(7.0));
    let p_error: Lanes3 = std::array::from_fn(|a| {
        g7 * ((b[0] * p[0][a]).abs() + (b[1] * p[1][a]).abs() + (b[2] * p[2][a]).abs())
    });
    let e1: Lanes3 = std::array::from_fn(|a| p[1][a] - p[0][a]);
    let e2: Lanes3 = std::array::from_fn(|a| p[2][a] - p[0][a]);
    let cross = [
        e1[1] * e2[2] - e2[1] * e1[2],
        e1[2] * e2[0] - e2[2] * e1[0],
        e1[0] * e2[1] - e2[0] * e1[1],
    ];
    let n = normalize_or_zero4(&cross);
    let dir = lanes3(|i| s.ray_dir[i]);
    let n_geo = negate_where(dot4(&n, &dir).simd_gt(f32x4::ZERO), &n);
    let n_shade = if s.normals.iter().any(Option::is_some) {
        // Lanes without vertex normals interpolate zeros and take `n_geo` below.
        let vn = |c: usize| lanes3(|i| s.normals[i].map_or(Vec3::ZERO, |n| n[c]));
        let ns = normalize_or_zero4(&interpolate4(&b, &[vn(0), vn(1), vn(2)]));
        // (Zero normals normalize to zero whatever the barycentrics: NaN and infinite
        // lengths fail the reciprocal's test.)
        let zero = f32x4::ZERO;
        let is_zero = ns[0].simd_eq(zero) & ns[1].simd_eq(zero) & ns[2].simd_eq(zero);
        let flipped = negate_where(dot4(&ns, &n_geo).simd_lt(zero), &ns);
        std::array::from_fn(|a| is_zero.select(n_geo[a], flipped[a]))
    } else {
        n_geo
    };
    let out = |v: &Lanes3| {
        let [x, y, z] = v.map(f32x4::to_array);
        std::array::from_fn::<Vec3, 4, _>(|i| Vec3::new(x[i], y[i], z[i]))
    };
    let (pos, p_error, n_geo, n_shade) = (out(&pos), out(&p_error), out(&n_geo), out(&n_shade));
    std::array::from_fn(|i| SurfacePoint {
        p: pos[i],
        p_error: p_error[i],
        n_geo: n_geo[i],
        n_shade: n_shade[i],
        kd: s.kd[i],
    })
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

    /// Ordinary values mostly, sometimes exact zeros of both signs, repeats and extremes.
    fn coord(rng: &mut crate::bvh::tests::Rng) -> f32 {
        const SPECIAL: [f32; 8] = [0.0, -0.0, 1.0, -1.0, 1e-30, -1e-30, 1e30, f32::NAN];
        match rng.next() % 10 {
            0 => SPECIAL[(rng.next() % 8) as usize],
            1 => (rng.next() % 3) as f32 - 1.0,
            _ => rng.unit() * 4.0 - 2.0,
        }
    }

    fn any_vec(rng: &mut crate::bvh::tests::Rng) -> Vec3 {
        Vec3::new(coord(rng), coord(rng), coord(rng))
    }

    fn bits(sp: &SurfacePoint) -> [u32; 15] {
        let v = [sp.p, sp.p_error, sp.n_geo, sp.n_shade].map(|v| v.to_array());
        let mut out = [0; 15];
        for (i, x) in v.iter().flatten().chain(&sp.kd).enumerate() {
            out[i] = x.to_bits();
        }
        out
    }

    /// Every lane of `surface_points4` is `surface_point` bit for bit: 400k random lanes with
    /// degenerate triangles (repeated corners), zero and NaN coordinates, rays along either
    /// side, and lanes with, without and with zero vertex normals mixed in one call.
    #[test]
    fn four_lanes_are_the_scalar_surface_points() {
        let mut rng = crate::bvh::tests::Rng(7);
        let (mut flipped, mut shaded) = (0, 0);
        for _ in 0..100_000 {
            let lane = |rng: &mut crate::bvh::tests::Rng| {
                let a = any_vec(rng);
                let b = if rng.next() % 8 == 0 { a } else { any_vec(rng) };
                let corners = [a, b, any_vec(rng)];
                let (u, v) = (rng.unit(), rng.unit() * 0.5);
                let bary = if rng.next() % 16 == 0 {
                    [coord(rng), coord(rng), coord(rng)]
                } else {
                    [1.0 - u - v, u, v]
                };
                let normals = match rng.next() % 4 {
                    0 => None,
                    1 => Some([Vec3::ZERO; 3]),
                    _ => Some([any_vec(rng), any_vec(rng), any_vec(rng)]),
                };
                let kd = [rng.unit(), rng.unit(), rng.unit()];
                (corners, bary, any_vec(rng), normals, kd)
            };
            let lanes: [_; 4] = std::array::from_fn(|_| lane(&mut rng));
            let four = surface_points4(&SurfaceInputs4 {
                corners: lanes.map(|l| l.0),
                b: lanes.map(|l| l.1),
                ray_dir: lanes.map(|l| l.2),
                normals: lanes.map(|l| l.3),
                kd: lanes.map(|l| l.4),
            });
            for (i, (corners, b, dir, normals, kd)) in lanes.into_iter().enumerate() {
                let one = surface_point(corners, b, dir, normals, kd);
                assert_eq!(bits(&four[i]), bits(&one), "lane {i}: {:?}", lanes[i]);
                let n = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
                flipped += usize::from(n.dot(dir) > 0.0 && one.n_geo != Vec3::ZERO);
                shaded += usize::from(normals.is_some() && one.n_shade != one.n_geo);
            }
        }
        assert!(flipped > 50_000, "flipped geometric normals: {flipped}");
        assert!(shaded > 50_000, "interpolated shading normals: {shaded}");
    }
}
