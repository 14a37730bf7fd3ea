//! Four hits shaded at once: their [`super::surface_point`]s and every light's
//! [`super::shadow_test`], the f32 arithmetic in f32x4 lanes, handed over light by light as
//! lanes ([`TestLanes`]). [`flat_test_lanes`] takes hits on flat (no vertex normals),
//! untextured triangles; [`smooth_test_lanes`] any hits, with their triangles' vertex normals
//! (zeros for a flat one) and their reflectances at the hits (a texture is looked up per hit
//! before): the shading normal and Hanika's shadow point (`smooth_lanes`) are lanes too. Each
//! lane performs the scalar code's IEEE operations in its order (glam's
//! `dot`, `cross` and `normalize_or_zero` spelled out; no FMA; square root and division are
//! correctly rounded in every SIMD instruction set; negation flips the sign bit), so each
//! lane's test is the scalar test bit for bit. What branches per lane runs in lanes too: the
//! rounding of the shadow origin away from the surface is integer arithmetic on the bits
//! (`lanes::round_away_lanes`), and a light's side and incidence become lane masks. The tests
//! leave in lanes too: the renderer stores a light's four segments a coordinate at a time
//! ([`crate::bvh::SegmentColumns::push_lanes`]).

use super::lanes::{narrow, point_incidence_lanes, round_away_lanes, widen};
use super::{incidence, shadow_ray};
use crate::bvh::CornerLanes;
use crate::scene::Light;
use crate::triangle::gamma;
use glam::Vec3;
use wide::{f32x4, f64x4};

/// What [`flat_test_lanes`] needs of one hit: the triangle's corners, the hit's
/// barycentrics, the ray's direction and the diffuse reflectance.
/// (References, not copies: the lanes read each value where the hit and the ray keep it.)
#[derive(Clone, Copy, Debug)]
pub struct FlatHit<'a> {
    /// The triangle's corners.
    pub corners: CornerLanes<'a>,
    /// The hit's barycentrics.
    pub b: &'a [f32; 3],
    /// The ray's direction.
    pub dir: &'a Vec3,
    /// Diffuse reflectance.
    pub kd: [f32; 3],
}

/// Three axes of four lanes: glam's `Vec3` operations lane by lane, in glam's order.
#[derive(Clone, Copy)]
struct Vec3x4 {
    x: f32x4,
    y: f32x4,
    z: f32x4,
}

impl Vec3x4 {
    #[inline(always)]
    fn of(v: [Vec3; 4]) -> Self {
        Vec3x4 {
            x: f32x4::from([v[0].x, v[1].x, v[2].x, v[3].x]),
            y: f32x4::from([v[0].y, v[1].y, v[2].y, v[3].y]),
            z: f32x4::from([v[0].z, v[1].z, v[2].z, v[3].z]),
        }
    }

    /// `v` in every lane.
    #[inline(always)]
    fn splat(v: Vec3) -> Self {
        Vec3x4 {
            x: f32x4::splat(v.x),
            y: f32x4::splat(v.y),
            z: f32x4::splat(v.z),
        }
    }

    /// `s * v` (each axis times its lane of `s`).
    #[inline(always)]
    fn scale(self, s: f32x4) -> Self {
        Vec3x4 {
            x: s * self.x,
            y: s * self.y,
            z: s * self.z,
        }
    }

    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Vec3x4 {
            x: self.x + o.x,
            y: self.y + o.y,
            z: self.z + o.z,
        }
    }

    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Vec3x4 {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }

    #[inline(always)]
    fn abs(self) -> Self {
        Vec3x4 {
            x: self.x.abs(),
            y: self.y.abs(),
            z: self.z.abs(),
        }
    }

    /// glam's `dot`: `(x·x' + y·y') + z·z'`.
    #[inline(always)]
    fn dot(self, o: Self) -> f32x4 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// glam's `cross`.
    #[inline(always)]
    fn cross(self, o: Self) -> Self {
        Vec3x4 {
            x: self.y * o.z - o.y * self.z,
            y: self.z * o.x - o.z * self.x,
            z: self.x * o.y - o.x * self.y,
        }
    }

    /// glam's `normalize_or_zero`: `v · (1 / sqrt(v·v))` where that reciprocal is finite and
    /// positive, else zero.
    #[inline(always)]
    fn normalize_or_zero(self) -> Self {
        let rcp = f32x4::ONE / self.dot(self).sqrt();
        let ok = rcp.simd_gt(f32x4::ZERO) & rcp.simd_lt(f32x4::splat(f32::INFINITY));
        let n = self.scale(rcp);
        Vec3x4 {
            x: ok & n.x,
            y: ok & n.y,
            z: ok & n.z,
        }
    }

    /// All ones in the lanes where every axis is zero (either sign), as `v == Vec3::ZERO`.
    #[inline(always)]
    fn is_zero(&self) -> f32x4 {
        let zero = f32x4::ZERO;
        self.x.simd_eq(zero) & self.y.simd_eq(zero) & self.z.simd_eq(zero)
    }

    /// `v` where `mask` is all ones, +0 elsewhere.
    #[inline(always)]
    fn keep(self, mask: f32x4) -> Self {
        Vec3x4 {
            x: mask & self.x,
            y: mask & self.y,
            z: mask & self.z,
        }
    }

    /// `a` where `mask` is all ones, else `b`.
    #[inline(always)]
    fn choose(mask: f32x4, a: Self, b: Self) -> Self {
        Vec3x4 {
            x: mask.select(a.x, b.x),
            y: mask.select(a.y, b.y),
            z: mask.select(a.z, b.z),
        }
    }

    /// `-v` where `flip` is all ones (the sign bit flipped, as scalar negation does).
    #[inline(always)]
    fn negate_where(self, flip: f32x4) -> Self {
        let sign = flip & f32x4::splat(-0.0);
        Vec3x4 {
            x: self.x ^ sign,
            y: self.y ^ sign,
            z: self.z ^ sign,
        }
    }
}

/// One light's shadow tests at four hits, lane by lane: in `lit` bit k whether hit k has a
/// test (an incidence, and the light on the normal's side); lane k of the others is hit k's
/// test, when it has one: its segment's origin and direction, and the radiance it adds when
/// unblocked. Every segment ends at `t_max`.
#[derive(Clone, Copy, Debug)]
pub struct TestLanes {
    /// Bit k: hit k has a test.
    pub lit: u32,
    /// The segments' origins, axis by axis.
    pub origin: [f32x4; 3],
    /// The segments' directions, axis by axis.
    pub dir: [f32x4; 3],
    /// Where every segment ends.
    pub t_max: f32,
    /// The radiance of each test when unblocked, channel by channel.
    pub unoccluded: [f32x4; 3],
}

impl TestLanes {
    /// As [`super::shadow_test_at`] of a flat surface point, lane by lane: the light's
    /// incidence at `p`, the cosine with the normal `n`, the segment from `origin` and the
    /// radiance with reflectances `kd` (channel by channel).
    #[inline(always)]
    fn new(light: &Light, p: &Vec3x4, n: &Vec3x4, origin: &Vec3x4, kd: &[f32x4; 3]) -> Self {
        let (to_light, irradiance, valid) = match *light {
            Light::Point {
                position,
                intensity,
            } => {
                let i = point_incidence_lanes(position, intensity, [p.x, p.y, p.z]);
                let [x, y, z] = i.to_light;
                (Vec3x4 { x, y, z }, i.irradiance, i.valid)
            }
            Light::Directional { .. } => {
                // The same incidence at every point.
                let i = incidence(Vec3::ZERO, light).expect("a directional light reaches all");
                let e = i.irradiance;
                (
                    Vec3x4::splat(i.to_light),
                    [f32x4::splat(e[0]), f32x4::splat(e[1]), f32x4::splat(e[2])],
                    0xf,
                )
            }
        };
        let cos = n.dot(to_light);
        // `cos <= 0` has no test; a NaN has one, as in the scalar test.
        let lit = valid & !cos.simd_le(f32x4::ZERO).to_bitmask() & 0xf;
        let (dir, t_max) = shadow_rays(light, origin);
        // As `unoccluded_radiance`: kd · (cos/pi) · E.
        let f = f32x4::splat(std::f32::consts::FRAC_1_PI) * cos;
        let radiance = |c: usize| kd[c] * f * irradiance[c];
        TestLanes {
            lit,
            origin: [origin.x, origin.y, origin.z],
            dir: [dir.x, dir.y, dir.z],
            t_max,
            unoccluded: [radiance(0), radiance(1), radiance(2)],
        }
    }

    /// Hit `k`'s radiance when its segment is unblocked (when bit k of `lit` is set).
    #[inline(always)]
    pub fn unoccluded(&self, k: usize) -> [f32; 3] {
        self.unoccluded.map(|c| c.to_array()[k])
    }
}

/// [`shadow_ray`]'s direction and `t_max` from each of the four `origins`, lane by lane.
#[inline(always)]
fn shadow_rays(light: &Light, origins: &Vec3x4) -> (Vec3x4, f32) {
    // The segment from the origin: the same `t_max` from every origin.
    let (from_origin, t_max) = shadow_ray(light, Vec3::ZERO);
    let dir = match *light {
        Light::Point { position, .. } => {
            // As `(position - origin.as_dvec3()).as_vec3()`: exact widening, one f64
            // subtraction, one rounding.
            let axis = |a: usize, o: f32x4| narrow(f64x4::splat(position[a]) - widen(o));
            Vec3x4 {
                x: axis(0, origins.x),
                y: axis(1, origins.y),
                z: axis(2, origins.z),
            }
        }
        Light::Directional { .. } => Vec3x4::splat(from_origin.dir),
    };
    (dir, t_max)
}

/// Every light's [`super::shadow_test`] at the [`super::surface_point`] of each of four flat,
/// untextured hits, handed to `visit(light, tests)` light by light, in light order: lane k of
/// `tests` is hit k's test where its bit of `tests.lit` is set, exactly the test
/// [`super::shadow_tests`] gives that surface point and light.
#[inline]
pub fn flat_test_lanes(
    hits: &[FlatHit<'_>; 4],
    lights: &[Light],
    visit: impl FnMut(usize, &TestLanes),
) {
    test_lanes(hits, None, lights, visit);
}

/// [`flat_test_lanes`] of four hits on triangles with vertex normals (`normals[k]`, the
/// corners' normals of hit k's triangle, as the mesh has them); each hit's `kd` is its
/// reflectance at the hit (textured or not).
#[inline]
pub fn smooth_test_lanes(
    hits: &[FlatHit<'_>; 4],
    normals: &[[Vec3; 3]; 4],
    lights: &[Light],
    visit: impl FnMut(usize, &TestLanes),
) {
    test_lanes(hits, Some(normals), lights, visit);
}

#[inline(always)]
fn test_lanes(
    hits: &[FlatHit<'_>; 4],
    normals: Option<&[[Vec3; 3]; 4]>,
    lights: &[Light],
    mut visit: impl FnMut(usize, &TestLanes),
) {
    let corner = |c: usize| {
        let at = |k: usize| hits[k].corners.corner(c);
        Vec3x4::of([at(0), at(1), at(2), at(3)])
    };
    let corners = [corner(0), corner(1), corner(2)];
    let [p0, p1, p2] = corners;
    let weight = |c: usize| f32x4::from([hits[0].b[c], hits[1].b[c], hits[2].b[c], hits[3].b[c]]);
    let b = [weight(0), weight(1), weight(2)];
    let (w0, w1, w2) = (p0.scale(b[0]), p1.scale(b[1]), p2.scale(b[2]));
    // As `surface_point`: p, its error bound, and the geometric normal facing the ray.
    let p = w0.add(w1).add(w2);
    let p_error = w0
        .abs()
        .add(w1.abs())
        .add(w2.abs())
        .scale(f32x4::splat(gamma(7.0)));
    let n_geo = p1.sub(p0).cross(p2.sub(p0)).normalize_or_zero();
    let dir = Vec3x4::of([*hits[0].dir, *hits[1].dir, *hits[2].dir, *hits[3].dir]);
    let n = n_geo.negate_where(n_geo.dot(dir).simd_gt(f32x4::ZERO));
    // The shading normal and where shadow rays start: on a flat triangle the geometric
    // normal and p.
    let (n_shade, p_shadow, p_shadow_error) = match normals {
        None => (n, p, p_error),
        Some(normals) => {
            let at = |c: usize| Vec3x4::of(std::array::from_fn(|k| normals[k][c]));
            smooth_lanes([at(0), at(1), at(2)], (corners, b), n, (p, p_error))
        }
    };
    // As `offset_origin(p_shadow, p_shadow_error, n, n)`: n·n is never below zero, so the
    // offset keeps its side, and the origin is rounded away from the surface along it.
    let offset = n.scale(n.abs().dot(p_shadow_error));
    let moved = p_shadow.add(offset);
    let origin = Vec3x4 {
        x: round_away_lanes(moved.x, offset.x),
        y: round_away_lanes(moved.y, offset.y),
        z: round_away_lanes(moved.z, offset.z),
    };
    let kd = |c: usize| f32x4::from([hits[0].kd[c], hits[1].kd[c], hits[2].kd[c], hits[3].kd[c]]);
    let kd = [kd(0), kd(1), kd(2)];
    for (l, light) in lights.iter().enumerate() {
        visit(l, &TestLanes::new(light, &p, &n_shade, &origin, &kd));
    }
}

/// As the vertex-normal branch of [`super::surface_point_on`], lane by lane: the shading
/// normal (the barycentric blend of the vertex `normals`, normalised and turned to the side of
/// `n_geo`, the geometric normal facing the ray) and Hanika's shadow point with its error
/// bound ([`super::shadow_point`]), from the triangles' `corners`, the barycentrics `b` and the
/// hit point `p` with its bound. Lanes whose blended normal is zero keep `(n_geo, p, p_error)`.
#[inline(always)]
fn smooth_lanes(
    normals: [Vec3x4; 3],
    (corners, b): ([Vec3x4; 3], [f32x4; 3]),
    n_geo: Vec3x4,
    (p, p_error): (Vec3x4, Vec3x4),
) -> (Vec3x4, Vec3x4, Vec3x4) {
    let zero = f32x4::ZERO;
    let [n0, n1, n2] = normals;
    let n = n0
        .scale(b[0])
        .add(n1.scale(b[1]))
        .add(n2.scale(b[2]))
        .normalize_or_zero();
    let none = n.is_zero();
    // The normal and the vertex normals turned to n_geo's side (a negated unit vector is the
    // unit vector of the negated one, bit for bit).
    let flip = n.dot(n_geo).simd_lt(zero);
    let n = n.negate_where(flip);
    let units = normals.map(|v| v.normalize_or_zero().negate_where(flip));
    // As `shadow_point_unit`: each vertex plane above p (its normal not within
    // MIN_NORMAL_COS of the triangle's plane) lifts p by its weight; where a term is not
    // taken, +0 is added, which leaves a sum that starts at +0 as it is.
    let (mut offset, mut magnitude) = (Vec3x4::splat(Vec3::ZERO), Vec3x4::splat(Vec3::ZERO));
    for (i, unit) in units.iter().enumerate() {
        let facing = unit.dot(n_geo).simd_ge(f32x4::splat(super::MIN_NORMAL_COS));
        let height = p.sub(corners[i]).dot(*unit);
        let below = height.simd_lt(zero);
        // `b.max(0.0)`: zero for a NaN (the sign of a zero weight never reaches the sums).
        let weight = b[i].simd_gt(zero).select(b[i], zero);
        let term = unit.scale(weight * -height);
        let take = facing & below;
        offset = offset.add(term.keep(take));
        magnitude = magnitude.add(term.abs().keep(take));
    }
    let q = p.add(offset);
    let error = p_error
        .add(q.abs().scale(f32x4::splat(gamma(2.0))))
        .add(magnitude.scale(f32x4::splat(gamma(4.0))))
        .scale(f32x4::splat(1.0 + gamma(4.0)));
    let lifted = !magnitude.is_zero() & !none;
    (
        Vec3x4::choose(none, n_geo, n),
        Vec3x4::choose(lifted, q, p),
        Vec3x4::choose(lifted, error, p_error),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shading::tests::rng;
    use crate::shading::{ShadowTest, shadow_test, surface_point};
    use crate::triangle::Ray;
    use glam::DVec3;

    /// Hit `k`'s test in `lanes` (when bit k of `lit` is set).
    fn test_of(lanes: &TestLanes, k: usize) -> ShadowTest {
        let at =
            |v: &[f32x4; 3]| Vec3::new(v[0].to_array()[k], v[1].to_array()[k], v[2].to_array()[k]);
        ShadowTest {
            ray: Ray {
                origin: at(&lanes.origin),
                dir: at(&lanes.dir),
            },
            t_max: lanes.t_max,
            unoccluded: lanes.unoccluded(k),
        }
    }

    /// The lanes' tests as (hit, light, test bits), hit by hit, then light by light: the order
    /// of [`crate::shading::shadow_tests`].
    fn expand(lanes: &[(usize, TestLanes)]) -> Vec<(usize, usize, Vec<u32>)> {
        let mut tests = Vec::new();
        for k in 0..4 {
            for (l, lanes) in lanes {
                if lanes.lit & (1 << k) != 0 {
                    tests.push((k, *l, bits(&test_of(lanes, k))));
                }
            }
        }
        tests
    }

    /// Each test's bits: origin, direction, t_max, radiance.
    fn bits(t: &ShadowTest) -> Vec<u32> {
        let mut b = t.ray.origin.to_array().to_vec();
        b.extend(t.ray.dir.to_array());
        b.push(t.t_max);
        b.extend(t.unoccluded);
        b.into_iter().map(f32::to_bits).collect()
    }

    /// The corners of four triangles in the lanes of one array, as a BVH keeps them.
    fn in_lanes(corners: &[[Vec3; 3]; 4]) -> [[[f32; 4]; 3]; 3] {
        let mut v = [[[0.0f32; 4]; 3]; 3];
        for (k, tri) in corners.iter().enumerate() {
            for (c, corner) in tri.iter().enumerate() {
                for a in 0..3 {
                    v[c][a][k] = corner[a];
                }
            }
        }
        v
    }

    /// Hit k of four on triangle k of `v` ([`in_lanes`]), at barycentrics `b[k]`, along
    /// `dir[k]`, with reflectance `kd[k]`.
    fn lane_hits<'a>(
        v: &'a [[[f32; 4]; 3]; 3],
        b: &'a [[f32; 3]; 4],
        dir: &'a [Vec3; 4],
        kd: [[f32; 3]; 4],
    ) -> [FlatHit<'a>; 4] {
        std::array::from_fn(|k| FlatHit {
            corners: CornerLanes::new(v, k),
            b: &b[k],
            dir: &dir[k],
            kd: kd[k],
        })
    }

    /// The tests of light `l` among `expected` (hit, light, test bits), as the tests of a
    /// scene with that light alone.
    fn alone(expected: &[(usize, usize, Vec<u32>)], l: usize) -> Vec<(usize, usize, Vec<u32>)> {
        let of_l = expected.iter().filter(|(_, light, _)| *light == l);
        of_l.map(|(k, _, t)| (*k, 0, t.clone())).collect()
    }

    /// Two point lights (one grey, one coloured) at `scale` and a directional light.
    fn three_lights(scale: f32) -> [Light; 3] {
        [
            Light::Point {
                position: DVec3::new(0.3, 4.0, -0.2) * f64::from(scale),
                intensity: [5.0; 3],
            },
            Light::Directional {
                direction: DVec3::new(0.1, -1.0, 0.2).normalize(),
                irradiance: [0.5, 1.0, 2.0],
            },
            Light::Point {
                position: DVec3::new(-1.7, -2.5, 1.1) * f64::from(scale),
                intensity: [3.0, 7.0, 3.0],
            },
        ]
    }

    /// The lanes give, hit by hit and light by light, the scalar surface point's shadow tests
    /// bit for bit: random triangles at several scales seen from either side, degenerate ones
    /// (no normal), hits on a corner, point lights (one at a hit point, grey and coloured)
    /// and a directional light.
    #[test]
    fn four_flat_hits_in_lanes_are_the_scalar_tests() {
        let mut r = rng(11);
        let mut checked = 0;
        for round in 0..400 {
            let scale = [1e-3f32, 1.0, 3e3][round % 3];
            let mut v = || Vec3::new(r() * 4.0 - 2.0, r() * 2.0 - 1.0, r() * 4.0 - 2.0) * scale;
            let mut corners: [[Vec3; 3]; 4] = std::array::from_fn(|_| [v(), v(), v()]);
            let mut b = [[0.0f32; 3]; 4];
            let mut dir = [Vec3::ZERO; 4];
            let mut kd = [[0.0f32; 3]; 4];
            for k in 0..4 {
                if (round + k) % 7 == 0 {
                    // Collinear corners: no geometric normal.
                    corners[k][2] = corners[k][0] + (corners[k][1] - corners[k][0]) * 0.5;
                }
                b[k] = if (round + k) % 5 == 0 {
                    [0.0, 1.0, 0.0]
                } else {
                    let (b1, b2) = (r() * 0.5, r() * 0.5);
                    [1.0 - b1 - b2, b1, b2]
                };
                dir[k] = Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5);
                kd[k] = [r(), r(), r()];
            }
            let v = in_lanes(&corners);
            let hits = lane_hits(&v, &b, &dir, kd);
            let first = surface_point(corners[0], b[0], dir[0], None, [1.0; 3]);
            let mut lights = three_lights(scale).to_vec();
            // At the first hit's point exactly (no incidence there).
            lights.push(Light::Point {
                position: first.p.as_dvec3(),
                intensity: [1.0; 3],
            });
            let mut expected = Vec::new();
            for (k, h) in hits.iter().enumerate() {
                let sp = surface_point(h.corners.corners(), *h.b, *h.dir, None, h.kd);
                for (l, light) in lights.iter().enumerate() {
                    if let Some(t) = shadow_test(&sp, light) {
                        expected.push((k, l, bits(&t)));
                    }
                }
            }
            let mut lanes = Vec::new();
            flat_test_lanes(&hits, &lights, |l, t| lanes.push((l, *t)));
            let lanes = expand(&lanes);
            assert_eq!(lanes, expected, "round {round}");
            assert!(!lanes.iter().any(|&(k, l, _)| k == 0 && l == 3));
            // Each light alone (the one-light path).
            for (l, light) in lights.iter().enumerate() {
                let mut lanes = Vec::new();
                flat_test_lanes(&hits, std::slice::from_ref(light), |l, t| {
                    lanes.push((l, *t))
                });
                assert_eq!(
                    expand(&lanes),
                    alone(&expected, l),
                    "round {round}, light {l} alone"
                );
            }
            checked += expected.len();
        }
        assert!(checked > 2000, "{checked} tests");
    }

    /// Four hits on triangles with vertex normals, in lanes, are the scalar surface points'
    /// shadow tests bit for bit: normals toward either side of the triangle, of any length,
    /// zero (no shading normal), nearly in the triangle's plane (the shadow point's cutoff) and
    /// one the others cancel; hits on a corner and on an edge; point and directional lights.
    #[test]
    fn four_smooth_hits_in_lanes_are_the_scalar_tests() {
        let mut r = rng(23);
        let (mut checked, mut lifted) = (0, 0);
        for round in 0..600 {
            let scale = [1e-3f32, 1.0, 3e3][round % 3];
            let mut v = || Vec3::new(r() * 4.0 - 2.0, r() * 2.0 - 1.0, r() * 4.0 - 2.0) * scale;
            let corners: [[Vec3; 3]; 4] = std::array::from_fn(|_| [v(), v(), v()]);
            let mut b = [[0.0f32; 3]; 4];
            let mut dir = [Vec3::ZERO; 4];
            let mut kd = [[0.0f32; 3]; 4];
            let mut normals = [[Vec3::ZERO; 3]; 4];
            for k in 0..4 {
                b[k] = match (round + k) % 6 {
                    0 => [0.0, 1.0, 0.0],
                    1 => [0.5, 0.0, 0.5],
                    _ => {
                        let (b1, b2) = (r() * 0.5, r() * 0.5);
                        [1.0 - b1 - b2, b1, b2]
                    }
                };
                dir[k] = Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5);
                kd[k] = [r(), r(), r()];
                let [p0, p1, p2] = corners[k];
                let n_geo = (p1 - p0).cross(p2 - p0).normalize_or_zero();
                let mut jitter = || Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5);
                normals[k] = match (round + 2 * k) % 7 {
                    // No shading normal: the flat point.
                    0 => [Vec3::ZERO; 3],
                    // Cancelling: the blend is zero at the centroid-ish hit or nearly.
                    1 => [n_geo, -n_geo, Vec3::ZERO],
                    // Nearly in the plane: below and above MIN_NORMAL_COS.
                    2 => {
                        let t = (p1 - p0).normalize_or_zero();
                        [t + n_geo * 5e-4, t + n_geo * 2e-3, n_geo]
                    }
                    // Toward the far side, long.
                    3 => [
                        -n_geo * 3.0 + jitter() * 0.5,
                        -n_geo + jitter(),
                        -n_geo * 7.0,
                    ],
                    // Smooth, bulging: tilted outward, as a coarse sphere's.
                    _ => [
                        (n_geo + jitter() * 0.8) * 2.0,
                        n_geo + jitter() * 0.8,
                        (n_geo + jitter() * 0.8) * 0.3,
                    ],
                };
            }
            let v = in_lanes(&corners);
            let hits = lane_hits(&v, &b, &dir, kd);
            let lights = three_lights(scale);
            let mut expected = Vec::new();
            for (k, h) in hits.iter().enumerate() {
                let sp = surface_point(h.corners.corners(), *h.b, *h.dir, Some(normals[k]), h.kd);
                lifted += usize::from(sp.p_shadow != sp.p);
                for (l, light) in lights.iter().enumerate() {
                    if let Some(t) = shadow_test(&sp, light) {
                        expected.push((k, l, bits(&t)));
                    }
                }
            }
            let mut lanes = Vec::new();
            smooth_test_lanes(&hits, &normals, &lights, |l, t| lanes.push((l, *t)));
            assert_eq!(expand(&lanes), expected, "round {round}");
            for (l, light) in lights.iter().enumerate() {
                let mut lanes = Vec::new();
                let light = std::slice::from_ref(light);
                smooth_test_lanes(&hits, &normals, light, |l, t| lanes.push((l, *t)));
                assert_eq!(
                    expand(&lanes),
                    alone(&expected, l),
                    "round {round}, light {l} alone"
                );
            }
            checked += expected.len();
        }
        assert!(checked > 3000, "{checked} tests");
        assert!(lifted > 300, "shadow points moved off the facet: {lifted}");
    }
}
