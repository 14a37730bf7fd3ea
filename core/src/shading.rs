//! Radiometry: two-sided Lambertian surfaces lit by point and directional lights, hard shadows,
//! and an optional constant ambient term.
//!
//! Outgoing radiance toward the camera at a hit with diffuse reflectance kd (per channel):
//!   L = sum over visible lights of kd/pi · E_light  +  kd · ambient,
//! with E = I·cos(theta)/r^2 for a point light of radiant intensity I at distance r, and
//! E = E_dir·cos(theta) for a directional light, theta measured from the shading normal. A
//! light contributes only when it is on the viewer's side of the surface (two-sided BSDF: the
//! side of the shading normal, turned to face the viewer) and no triangle lies on the shadow
//! segment. This is Mitsuba 3's `direct` integrator with a `twosided(diffuse)` BSDF and
//! `point`/`directional` emitters, so both converge to one image (on flat triangles; at the
//! terminator of a coarse smooth mesh, see below, Mitsuba's shadow rays hit the facets).
//!
//! Shadow rays start at the hit point moved off the surface by its floating-point error bound
//! (pbrt-v4, "Robust Spawned Ray Origins"): the offset scales with the coordinates' magnitudes,
//! so it works for scenes of any scale, unlike a fixed epsilon.
//!
//! **The shadow terminator.** On a triangle with vertex normals, the light side is decided by
//! the shading normal alone, and the shadow ray starts from the hit point moved onto the
//! vertices' tangent planes where it lies below them (Hanika, "Hacking the Shadow Terminator",
//! Ray Tracing Gems II, ch. 4, 2021), with that point's own error bound; flat triangles keep
//! the hit point, so their bytes are unchanged. A coarse smooth sphere then keeps the smooth
//! normals' terminator instead of its facets' (docs/perf/terminator.md).

use crate::scene::Light;
use crate::triangle::{Ray, gamma};
use glam::{DVec3, Vec3};

mod array_lanes;
mod frame;
mod hit_lanes;
mod lanes;

pub use frame::{LastFrame, TriangleFrame};
pub use hit_lanes::{HitLanes, TestLanes, flat_test_lanes, smooth_test_lanes};

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
    /// Where shadow rays start before the robust offset: on a triangle with vertex normals,
    /// [`shadow_point`] of the hit; else `p` itself.
    pub p_shadow: Vec3,
    /// Conservative absolute error bound of `p_shadow` per axis (`p_error` when it is `p`).
    pub p_shadow_error: Vec3,
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
    let frame = TriangleFrame::new(corners, normals);
    surface_point_on(&frame, corners, b, ray_dir, normals, kd)
}

/// [`surface_point`] given the triangle's `frame` ([`TriangleFrame::new`] of `corners` and
/// `normals`): the same bits.
#[inline]
pub fn surface_point_on(
    frame: &TriangleFrame,
    corners: [Vec3; 3],
    b: [f32; 3],
    ray_dir: Vec3,
    normals: Option<[Vec3; 3]>,
    kd: [f32; 3],
) -> SurfacePoint {
    let [p0, p1, p2] = corners;
    let p = b[0] * p0 + b[1] * p1 + b[2] * p2;
    let p_error = gamma(7.0) * ((b[0] * p0).abs() + (b[1] * p1).abs() + (b[2] * p2).abs());
    let mut n_geo = frame.n_geo;
    if n_geo.dot(ray_dir) > 0.0 {
        n_geo = -n_geo;
    }
    let (n_shade, p_shadow, p_shadow_error) = match (normals, frame.unit_normals) {
        (Some([n0, n1, n2]), Some(units)) => {
            let n = (b[0] * n0 + b[1] * n1 + b[2] * n2).normalize_or_zero();
            if n == Vec3::ZERO {
                (n_geo, p, p_error)
            } else {
                // The vertex normals turned with the shading normal, to n_geo's side.
                // (Normalising a negated vector gives the negated unit vector bit for bit;
                // a zero one, +0 or -0, never moves the shadow point.)
                let (n, unit_normals) = if n.dot(n_geo) < 0.0 {
                    (-n, units.map(|u| -u))
                } else {
                    (n, units)
                };
                let (q, q_error) = shadow_point(corners, b, unit_normals, n_geo, p, p_error);
                (n, q, q_error)
            }
        }
        _ => (n_geo, p, p_error),
    };
    SurfacePoint {
        p,
        p_error,
        n_geo,
        n_shade,
        p_shadow,
        p_shadow_error,
        kd,
    }
}

/// Smallest cosine between a vertex normal and the geometric normal for the vertex to move the
/// shadow point: the move then has a positive component along the true plane normal despite
/// rounding (a normal nearly in the triangle's plane would move the point along the surface).
const MIN_NORMAL_COS: f32 = 1e-3;

/// Hanika's shadow-ray origin for the hit `p` (error bound `p_error`) at barycentrics `b` of a
/// triangle with corners `corners` and unit vertex normals `unit_normals` (each the mesh's
/// normal after `normalize_or_zero`, turned to the side of the unit geometric normal `n_geo`):
///
///   p' = p + sum_i b_i · max(0, (A_i - p)·n_i) · n_i,
///
/// p projected onto each vertex's tangent plane where it lies below it, blended with the
/// barycentrics ("Hacking the Shadow Terminator", Ray Tracing Gems II, ch. 4, 2021). On a convex
/// patch of a coarse mesh p' lies about where the smooth surface the normals describe would be,
/// so a shadow ray from it toward a light the shading normal faces clears the facets; on a
/// concave or flat patch no vertex plane is above p and p' = p bit for bit.
///
/// Returns p' with a conservative error bound: each term `w_i · n_i` (w_i the computed weight,
/// an exact input from here on) is rounded once per axis, the three terms are summed and added
/// to p, so |computed - exact| <= p_error + gamma(2)·|p'| + gamma(4)·sum_i |w_i · n_i| (pbrt-v4
/// style, in terms of the computed values); the bound is scaled by 1 + gamma(4) to cover its own
/// rounding. Vertices whose normal is within [`MIN_NORMAL_COS`] of the plane (or behind it) do
/// not move the point, so the exact p' lies on n_geo's side of the plane or on it, and the
/// robust spawn along n_geo by this bound starts the ray strictly on that side.
#[inline]
pub fn shadow_point(
    corners: [Vec3; 3],
    b: [f32; 3],
    unit_normals: [Vec3; 3],
    n_geo: Vec3,
    p: Vec3,
    p_error: Vec3,
) -> (Vec3, Vec3) {
    let mut offset = Vec3::ZERO;
    let mut magnitude = Vec3::ZERO;
    for (i, &n) in unit_normals.iter().enumerate() {
        // (Both tests are false for NaN.)
        if n.dot(n_geo) >= MIN_NORMAL_COS {
            let height = (p - corners[i]).dot(n);
            if height < 0.0 {
                let term = (b[i].max(0.0) * -height) * n;
                offset += term;
                magnitude += term.abs();
            }
        }
    }
    if magnitude == Vec3::ZERO {
        return (p, p_error);
    }
    let q = p + offset;
    let error = (p_error + gamma(2.0) * q.abs() + gamma(4.0) * magnitude) * (1.0 + gamma(4.0));
    (q, error)
}

/// Where a light is seen from a point, and what it gives there: the unit direction toward it,
/// and the irradiance per channel on a surface facing it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Incidence {
    /// Unit direction from the point toward the light.
    pub to_light: Vec3,
    /// Irradiance per RGB channel on a surface facing the light.
    pub irradiance: [f32; 3],
}

/// The light's [`Incidence`] at `p`, or `None` when `p` is at a point light's position.
#[inline]
pub fn incidence(p: Vec3, light: &Light) -> Option<Incidence> {
    match *light {
        Light::Point {
            position,
            intensity,
        } => {
            let v: DVec3 = position - p.as_dvec3();
            let r2 = v.length_squared();
            if r2 <= 0.0 {
                return None;
            }
            let to_light = (v / r2.sqrt()).as_vec3();
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
            Some(Incidence {
                to_light,
                irradiance: [e0, e(1), e(2)],
            })
        }
        Light::Directional {
            direction,
            irradiance,
        } => Some(Incidence {
            to_light: (-direction).as_vec3(),
            irradiance,
        }),
    }
}

/// The shadow test of `light` at `sp`, or `None` when the light cannot contribute (behind the
/// shading normal as seen by the viewer, or at grazing angle), so no ray is needed. The ray
/// starts at `sp.p_shadow` pushed off the triangle along `n_geo` by `sp.p_shadow_error`.
#[inline]
pub fn shadow_test(sp: &SurfacePoint, light: &Light) -> Option<ShadowTest> {
    shadow_test_at(sp, light, incidence(sp.p, light)?)
}

/// [`shadow_test`] given the light's [`incidence`] at `sp.p` (computed one point at a time or
/// four at a time, [`shadow_tests`]: the same bits).
#[inline]
fn shadow_test_at(sp: &SurfacePoint, light: &Light, incidence: Incidence) -> Option<ShadowTest> {
    let Incidence {
        to_light,
        irradiance,
    } = incidence;
    // The shading normal decides the light's side. On a flat triangle it is the geometric
    // normal. On a smooth one, a light behind the flat triangle but in front of the shading
    // normal (the terminator of a coarse mesh) gets a shadow ray from the shadow point, which
    // may clear the triangle or hit it: the geometry decides, not a cutoff at the facet.
    let cos = sp.n_shade.dot(to_light);
    if cos <= 0.0 {
        return None;
    }
    // Off the surface on the viewer's (n_geo's) side, whichever side the light is on: for a
    // flat triangle that is the light's side, as the spawn toward the light would give.
    let origin = offset_origin(sp.p_shadow, sp.p_shadow_error, sp.n_geo, sp.n_geo);
    let (ray, t_max) = shadow_ray(light, origin);
    Some(ShadowTest {
        ray,
        t_max,
        unoccluded: unoccluded_radiance(sp.kd, cos, irradiance),
    })
}

/// The radiance per channel a light adds toward the viewer when unblocked: kd/pi · E at
/// cosine `cos`, evaluated as `kd · (cos/pi) · E`.
#[inline(always)]
fn unoccluded_radiance(kd: [f32; 3], cos: f32, irradiance: [f32; 3]) -> [f32; 3] {
    let f = std::f32::consts::FRAC_1_PI * cos;
    [
        kd[0] * f * irradiance[0],
        kd[1] * f * irradiance[1],
        kd[2] * f * irradiance[2],
    ]
}

/// Every light's [`shadow_test`] at every point of `points`, handed to `visit(point, light,
/// test)` in order of point, then light: the tests and order of calling [`shadow_test`] pair by
/// pair, bit for bit. A point light's incidence, two divisions and a square root in f64 per
/// point whose results the rest waits on, is computed for four points at a time in lanes
/// ([`lanes::point_incidences4`]). ([`ShadowTester`] does the same, keeping its scratch space
/// from call to call.)
pub fn shadow_tests(
    points: &[SurfacePoint],
    lights: &[Light],
    visit: impl FnMut(usize, usize, ShadowTest),
) {
    ShadowTester::default().shadow_tests(points, lights, visit);
}

/// [`shadow_tests`] with the lights' incidences at four points kept from call to call, for
/// callers that test a few points at a time.
#[derive(Default)]
pub struct ShadowTester {
    incidences: Vec<[Option<Incidence>; 4]>,
}

impl ShadowTester {
    /// [`shadow_tests`].
    pub fn shadow_tests(
        &mut self,
        points: &[SurfacePoint],
        lights: &[Light],
        mut visit: impl FnMut(usize, usize, ShadowTest),
    ) {
        let incidences = &mut self.incidences;
        for (group, four) in points.chunks(4).enumerate() {
            // Lanes past the group's end repeat its first point; their results are not used.
            let at = |k: usize| four.get(k).unwrap_or(&four[0]).p;
            let positions = [at(0), at(1), at(2), at(3)];
            incidences.clear();
            incidences.extend(lights.iter().map(|light| match *light {
                Light::Point {
                    position,
                    intensity,
                } => lanes::point_incidences4(position, intensity, positions),
                Light::Directional { .. } => [incidence(positions[0], light); 4],
            }));
            for (k, sp) in four.iter().enumerate() {
                for (l, (light, lit)) in lights.iter().zip(incidences.iter()).enumerate() {
                    if let Some(test) = lit[k].and_then(|i| shadow_test_at(sp, light, i)) {
                        visit(group * 4 + k, l, test);
                    }
                }
            }
        }
    }
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
/// then `kd · ambient`. Every renderer path sums in this order, so results match bit for bit
/// (a path that sums as it goes starts from `[0.0; 3]`, adds with [`add_light`] in light order
/// and ends with [`add_ambient`]).
#[inline]
pub fn combine(
    kd: [f32; 3],
    contributions: impl Iterator<Item = [f32; 3]>,
    ambient: [f32; 3],
) -> [f32; 3] {
    let mut sum = [0.0f32; 3];
    for c in contributions {
        add_light(&mut sum, c);
    }
    add_ambient(sum, kd, ambient)
}

/// One unblocked light's contribution added to a hit's sum ([`combine`]).
#[inline(always)]
pub fn add_light(sum: &mut [f32; 3], contribution: [f32; 3]) {
    for k in 0..3 {
        sum[k] += contribution[k];
    }
}

/// A hit's final radiance from the sum of its lights ([`combine`]): `sum + kd · ambient`.
#[inline(always)]
pub fn add_ambient(sum: [f32; 3], kd: [f32; 3], ambient: [f32; 3]) -> [f32; 3] {
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
    round_away(p + offset, offset)
}

/// `po` moved one ulp further along `offset`'s sign on each axis (none where it is zero), so
/// the rounding of `p + offset` cannot bring the point back toward the surface.
#[inline(always)]
fn round_away(mut po: Vec3, offset: Vec3) -> Vec3 {
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

    /// A small deterministic generator (xorshift) for the randomised tests.
    pub(super) fn rng(seed: u64) -> impl FnMut() -> f32 {
        let mut x = seed;
        move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// Flat triangles (no vertex normals) shoot from the hit point with its own bound, the
    /// test's previous origin: their bits are unchanged.
    #[test]
    fn flat_triangles_keep_the_hit_point_and_its_bound() {
        let mut r = rng(7);
        let light = Light::Point {
            position: DVec3::new(0.3, 4.0, -0.2),
            intensity: [5.0; 3],
        };
        for _ in 0..1000 {
            let mut v = || Vec3::new(r() * 4.0 - 2.0, r() * 0.5, r() * 4.0 - 2.0);
            let corners = [v(), v(), v()];
            let (b1, b2) = (r() * 0.5, r() * 0.5);
            let b = [1.0 - b1 - b2, b1, b2];
            let sp = surface_point(corners, b, Vec3::new(0.1, -1.0, 0.05), None, [0.5; 3]);
            assert_eq!(sp.p_shadow.to_array(), sp.p.to_array());
            assert_eq!(sp.p_shadow_error.to_array(), sp.p_error.to_array());
            if let Some(t) = shadow_test(&sp, &light) {
                let to_light = (light_position(&light) - sp.p.as_dvec3())
                    .normalize()
                    .as_vec3();
                let before = offset_origin(sp.p, sp.p_error, sp.n_geo, to_light);
                assert_eq!(
                    t.ray.origin.to_array().map(f32::to_bits),
                    before.to_array().map(f32::to_bits)
                );
            }
        }
    }

    fn light_position(light: &Light) -> DVec3 {
        match *light {
            Light::Point { position, .. } => position,
            Light::Directional { .. } => unreachable!(),
        }
    }

    /// Hanika's point, recomputed exactly (f64 from the same f32 inputs and weights), lies on
    /// the geometric normal's side of the triangle's plane and within the returned bound of the
    /// computed point; so the robust spawn starts every shadow ray strictly on that side.
    #[test]
    fn the_shadow_point_is_above_the_plane_within_its_bound() {
        let mut r = rng(11);
        let mut moved = 0;
        for case in 0..4000 {
            let scale = [1e-3f32, 1.0, 1e3][case % 3];
            let centre = Vec3::splat(scale * (r() * 20.0 - 10.0));
            let mut v = || centre + scale * Vec3::new(r() - 0.5, (r() - 0.5) * 0.2, r() - 0.5);
            let corners = [v(), v(), v()];
            // Vertex normals bent outward from the plane, as on a convex patch, unnormalised.
            let plane = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
            let centroid = (corners[0] + corners[1] + corners[2]) / 3.0;
            let normals = corners.map(|c| {
                let n = plane.normalize() + (c - centroid) / scale * r() * 1.5;
                n * (0.5 + r() * 3.0)
            });
            let (b1, b2) = (r(), r());
            let (b1, b2) = if b1 + b2 > 1.0 {
                (1.0 - b1, 1.0 - b2)
            } else {
                (b1, b2)
            };
            let b = [1.0 - b1 - b2, b1, b2];
            let eye_side = if case % 2 == 0 { -plane } else { plane };
            let sp = surface_point(corners, b, eye_side, Some(normals), [1.0; 3]);
            if sp.p_shadow == sp.p {
                continue;
            }
            moved += 1;
            // The exact point from the same weights.
            let n_geo = sp.n_geo.as_dvec3();
            let sign = if (b[0] * normals[0] + b[1] * normals[1] + b[2] * normals[2])
                .normalize()
                .dot(sp.n_geo)
                < 0.0
            {
                -1.0
            } else {
                1.0
            };
            let p_exact = (0..3).fold(DVec3::ZERO, |a, i| {
                a + f64::from(b[i]) * corners[i].as_dvec3()
            });
            let mut q_exact = p_exact;
            for i in 0..3 {
                let n = (sign * normals[i]).normalize_or_zero();
                let height = (sp.p - corners[i]).dot(n);
                if n.dot(sp.n_geo) >= MIN_NORMAL_COS && height < 0.0 {
                    q_exact += f64::from(b[i].max(0.0) * -height) * n.as_dvec3();
                }
            }
            let err = (sp.p_shadow.as_dvec3() - q_exact).abs();
            let bound = sp.p_shadow_error.as_dvec3();
            assert!(
                err.cmple(bound).all(),
                "case {case}: error {err} over bound {bound}"
            );
            // Above the exact plane (through the corners, normal from f64 arithmetic).
            let [a, b_, c] = corners.map(|c| c.as_dvec3());
            let plane = (b_ - a).cross(c - a);
            let up = if plane.dot(n_geo) > 0.0 {
                plane
            } else {
                -plane
            };
            assert!((q_exact - a).dot(up) >= 0.0, "case {case}: below the plane");
            // The spawned origin is strictly above it.
            let light = Light::Directional {
                direction: -sp.n_shade.as_dvec3(),
                irradiance: [1.0; 3],
            };
            let t = shadow_test(&sp, &light).expect("the light faces the shading normal");
            assert!(
                (t.ray.origin.as_dvec3() - a).dot(up) > 0.0,
                "case {case}: origin"
            );
        }
        assert!(moved > 1000, "{moved} of the cases moved the point");
    }

    /// The batch path (four points' point-light incidences in lanes) gives every pair's
    /// [`shadow_test`] bit for bit, in order of point then light: grey, coloured and
    /// directional lights, a light at a point's position, and groups that do not fill four lanes.
    #[test]
    fn batched_shadow_tests_are_the_tests_one_by_one() {
        let mut r = rng(5);
        let lights = [
            Light::Point {
                position: DVec3::new(0.3, 4.0, -0.2),
                intensity: [5.0; 3],
            },
            Light::Directional {
                direction: DVec3::new(0.1, -1.0, 0.2).normalize(),
                irradiance: [0.5, 1.0, 2.0],
            },
            Light::Point {
                position: DVec3::new(-1.7, 2.5, 1.1),
                intensity: [3.0, 7.0, 3.0],
            },
            // At the first point's position exactly (no incidence there).
            Light::Point {
                position: DVec3::new(0.25, 0.0, 0.5),
                intensity: [1.0; 3],
            },
        ];
        for count in [1, 3, 4, 5, 8, 11, 200] {
            let points: Vec<SurfacePoint> = (0..count)
                .map(|i| {
                    let mut v = || Vec3::new(r() * 4.0 - 2.0, r() * 0.5, r() * 4.0 - 2.0);
                    let corners = if i == 0 {
                        [
                            Vec3::ZERO,
                            Vec3::new(0.5, 0.0, 0.0),
                            Vec3::new(0.0, 0.0, 1.0),
                        ]
                    } else {
                        [v(), v(), v()]
                    };
                    let b = if i == 0 {
                        [0.0, 0.5, 0.5]
                    } else {
                        let (b1, b2) = (r() * 0.5, r() * 0.5);
                        [1.0 - b1 - b2, b1, b2]
                    };
                    let dir = Vec3::new(r() - 0.5, -1.0, r() - 0.5);
                    surface_point(corners, b, dir, None, [r(), r(), r()])
                })
                .collect();
            assert_eq!(points[0].p, Vec3::new(0.25, 0.0, 0.5));
            let mut expected = Vec::new();
            for (k, sp) in points.iter().enumerate() {
                for (l, light) in lights.iter().enumerate() {
                    if let Some(t) = shadow_test(sp, light) {
                        expected.push((k, l, t));
                    }
                }
            }
            let mut batched = Vec::new();
            shadow_tests(&points, &lights, |k, l, t| batched.push((k, l, t)));
            let bits = |v: &[(usize, usize, ShadowTest)]| -> Vec<(usize, usize, Vec<u32>)> {
                v.iter()
                    .map(|&(k, l, t)| {
                        let mut b = t.ray.origin.to_array().to_vec();
                        b.extend(t.ray.dir.to_array());
                        b.push(t.t_max);
                        b.extend(t.unoccluded);
                        (k, l, b.into_iter().map(f32::to_bits).collect())
                    })
                    .collect()
            };
            assert_eq!(bits(&batched), bits(&expected), "{count} points");
            assert!(!expected.iter().any(|&(k, l, _)| k == 0 && l == 3));
        }
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
