//! Four-wide box and triangle tests over [`Node4`] and [`Triangle4`] (the `wide` crate: SSE on
//! x86-64, NEON on aarch64, plain arrays elsewhere). Every lane computes the same IEEE
//! operations in the same order as the scalar code (no FMA, comparisons and selects instead of
//! min/max), so results are the same bits on every machine:
//! - [`BoxTester::test`] is [`SlabRay::entry`](super::traverse) on each child box;
//! - [`triangle_any_hit`] (shadow rays) claims a hit or a miss only where
//!   [`crate::triangle::intersect`] computes the same values and decides the same; the rest
//!   go through `intersect` itself;
//! - [`triangle_hits`] (closest hit) gives `intersect`'s exact t and barycentrics wherever the
//!   scalar test takes no other path (no edge function exactly 0, no NaN input), and leaves
//!   the other lanes to `intersect`.

use super::lanes::{Lanes, greater4, lesser4};
use super::node4::{Node4, Triangle4};
use crate::triangle::{Ray, RayPrep, gamma};
use wide::f32x4;

/// `[f(0), f(1), f(2)]`, always inlined (`array::map` is not, and per-ray setup showed it).
#[inline(always)]
pub(super) fn each3<T>(f: impl Fn(usize) -> T) -> [T; 3] {
    [f(0), f(1), f(2)]
}

/// `[f(0), f(1), f(2), f(3)]`, always inlined.
#[inline(always)]
pub(super) fn each4<T>(f: impl Fn(usize) -> T) -> [T; 4] {
    [f(0), f(1), f(2), f(3)]
}

/// Per-ray constants of the 4-wide slab test.
pub(super) struct BoxTester {
    origin: [f32x4; 3],
    inv_dir: [f32x4; 3],
    /// Per axis: the near plane is the box's `hi` (the direction's sign bit is set).
    near_hi: [bool; 3],
}

impl BoxTester {
    pub fn new(ray: &Ray) -> Self {
        let inv = glam::Vec3::ONE / ray.dir;
        BoxTester {
            origin: each3(|a| f32x4::splat(ray.origin[a])),
            inv_dir: each3(|a| f32x4::splat(inv[a])),
            near_hi: each3(|a| inv[a].is_sign_negative()),
        }
    }

    /// For each child slot of `node`: bit set when the ray enters its box at or before `t_max`
    /// (scaled far distances, as the scalar test), and the entry distances.
    #[inline(always)]
    pub fn test(&self, node: &Node4, t_max: f32) -> (u32, [f32; 4]) {
        let mut t0 = f32x4::ZERO;
        let mut t1 = f32x4::splat(t_max);
        let scale = f32x4::splat(super::traverse::FAR_SCALE);
        for axis in 0..3 {
            let (near_plane, far_plane) = if self.near_hi[axis] {
                (node.hi[axis], node.lo[axis])
            } else {
                (node.lo[axis], node.hi[axis])
            };
            let near = (f32x4::from(near_plane) - self.origin[axis]) * self.inv_dir[axis];
            let far = (f32x4::from(far_plane) - self.origin[axis]) * self.inv_dir[axis] * scale;
            // A NaN never passes a comparison, so it leaves the interval unchanged.
            t0 = greater4(near, t0);
            t1 = lesser4(far, t1);
        }
        let miss = t0.simd_gt(t1).to_bitmask();
        (!miss & 0xf, t0.to_array())
    }
}

/// Per-ray constants of the 4-wide triangle tests: the permuted origin and the shear, kept as
/// scalars (small to copy into a search; the tests broadcast them to lanes).
#[derive(Clone, Copy)]
pub(super) struct TriangleTester {
    axes: [usize; 3],
    origin: [f32; 3],
    shear: [f32; 3],
}

impl TriangleTester {
    pub fn new(prep: &RayPrep) -> Self {
        let (axes, shear) = prep.shear();
        TriangleTester {
            axes,
            origin: each3(|k| prep.origin[axes[k]]),
            shear,
        }
    }
}

/// The watertight test's intermediate values for a set of (ray, triangle) pairs, one per lane,
/// computed exactly as [`crate::triangle::intersect`] computes them (before its f64 fallback).
pub(super) struct Edges<L> {
    x: [L; 3],
    y: [L; 3],
    zs: [L; 3],
    pub u: L,
    pub v: L,
    pub w: L,
    pub inv_det: L,
    pub t: L,
    /// Lanes with an edge function exactly 0 (the scalar test recomputes them in f64).
    any_zero: L,
    /// Lanes the scalar test rejects before its error bound: mixed edge signs, zero or
    /// non-finite determinant, t of the wrong sign, NaN or infinite t. Valid where !any_zero.
    rejected: L,
    /// Lanes where no input of the error bound is NaN, so lane maxima equal `f32::max`.
    clean: L,
}

/// The first half of [`Edges`]: the sheared corners and the edge functions, enough to see the
/// lanes the scalar test rejects first (mixed signs).
pub(super) struct EdgeFunctions<L> {
    x: [L; 3],
    y: [L; 3],
    z: [L; 3],
    u: L,
    v: L,
    w: L,
    /// Lanes with an edge function exactly 0 (the scalar test recomputes them in f64).
    any_zero: L,
    /// Lanes whose edge functions have mixed signs (one below zero, one above).
    mixed: L,
}

/// The edge functions of each lane's pair: `origin[k]` and `shear[k]` are the ray's origin on
/// its permuted axis k (kx, ky, kz) and its shear ([`RayPrep::shear`]), `corners[c][k]` corner
/// c of the triangle on that axis. Four triangles against one ray ([`Triangle4`]) or one
/// triangle against a ray per lane (`leaf_lanes.rs`) alike.
///
/// No closures here or in what it calls: a closure is compiled on its own, without the SIMD
/// features of the function it is meant to be inlined into, unless the compiler inlines it.
#[inline(always)]
fn edge_functions<L: Lanes>(
    origin: &[L; 3],
    shear: &[L; 3],
    corners: &[[L; 3]; 3],
) -> EdgeFunctions<L> {
    #[inline(always)]
    fn sheared<L: Lanes>(origin: &[L; 3], shear: &[L; 3], corner: &[L; 3]) -> (L, L, L) {
        let x = corner[0] - origin[0];
        let y = corner[1] - origin[1];
        let z = corner[2] - origin[2];
        (x - shear[0] * z, y - shear[1] * z, z)
    }
    let (ax, ay, az) = sheared(origin, shear, &corners[0]);
    let (bx, by, bz) = sheared(origin, shear, &corners[1]);
    let (cx, cy, cz) = sheared(origin, shear, &corners[2]);
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    let zero = L::splat(0.0);
    let any_neg = u.cmp_lt(zero) | v.cmp_lt(zero) | w.cmp_lt(zero);
    let any_pos = u.cmp_gt(zero) | v.cmp_gt(zero) | w.cmp_gt(zero);
    EdgeFunctions {
        x: [ax, bx, cx],
        y: [ay, by, cy],
        z: [az, bz, cz],
        u,
        v,
        w,
        any_zero: u.cmp_eq(zero) | v.cmp_eq(zero) | w.cmp_eq(zero),
        mixed: any_neg & any_pos,
    }
}

impl<L: Lanes> EdgeFunctions<L> {
    /// Whether every lane of `valid` (bit i = lane i) misses for the scalar test: its edge
    /// functions have mixed signs and none is exactly 0, where `intersect` returns `None`
    /// before anything else (NaN elsewhere in the lane included). A lane with an edge function
    /// of 0 is left to the whole test: `intersect` recomputes the three in f64 there, and an
    /// f32 edge function that is not 0 may come out 0 (its exact value below the smallest
    /// subnormal), so the signs may no longer be mixed.
    #[inline(always)]
    fn all_outside(&self, valid: u32) -> bool {
        !(self.mixed & !self.any_zero).bitmask() & valid == 0
    }

    /// The rest of the test's values, with the ray's shear `sz` of its z axis.
    #[inline(always)]
    fn finish(self, sz: L) -> Edges<L> {
        let EdgeFunctions { u, v, w, .. } = self;
        let [ax, bx, cx] = self.x;
        let [ay, by, cy] = self.y;
        let zero = L::splat(0.0);
        let det = u + v + w;
        let [az, bz, cz] = self.z;
        let (zs0, zs1, zs2) = (sz * az, sz * bz, sz * cz);
        let t_scaled = u * zs0 + v * zs1 + w * zs2;
        let inv_det = L::splat(1.0) / det;
        let t = t_scaled * inv_det;
        let inf = L::splat(f32::INFINITY);
        let det_bad = det.cmp_eq(zero) | !det.abs().cmp_lt(inf);
        let wrong_side = det.cmp_lt(zero) ^ t_scaled.cmp_lt(zero);
        let rejected = self.mixed | det_bad | wrong_side | !t.cmp_lt(inf);
        let sum = ax + ay + bx + by + cx + cy + zs0 + zs1 + zs2 + u + v + w;
        Edges {
            x: self.x,
            y: self.y,
            zs: [zs0, zs1, zs2],
            u,
            v,
            w,
            inv_det,
            t,
            any_zero: self.any_zero,
            rejected,
            clean: sum.cmp_eq(sum),
        }
    }
}

/// All of the test's values for each lane's pair ([`edge_functions`], then the rest).
#[inline(always)]
pub(super) fn edges<L: Lanes>(origin: &[L; 3], shear: &[L; 3], corners: &[[L; 3]; 3]) -> Edges<L> {
    edge_functions(origin, shear, corners).finish(shear[2])
}

/// All of the test's values for each lane's pair ([`edge_functions`], then the rest), or `None`
/// when every lane of `valid` (bit i = lane i) has mixed edge signs and no edge function of 0:
/// those lanes miss ([`EdgeFunctions::all_outside`]), and the rest of the test (its division
/// among it) is left out. Most pairs of a leaf test end here.
#[inline(always)]
pub(super) fn edges_unless_outside<L: Lanes>(
    origin: &[L; 3],
    shear: &[L; 3],
    corners: &[[L; 3]; 3],
    valid: u32,
) -> Option<Edges<L>> {
    let f = edge_functions(origin, shear, corners);
    if f.all_outside(valid) {
        return None;
    }
    Some(f.finish(shear[2]))
}

/// Lanes the scalar test rejects by its conservative t > 0 bound (pbrt-v4 6.8.6), computed in
/// its order of operations. Only `clean` lanes are claimed: there the maxima are of
/// non-negative non-NaN values, where `select(a > b, a, b)` equals `f32::max`.
#[inline(always)]
fn too_close<L: Lanes>(e: &Edges<L>) -> L {
    #[inline(always)]
    fn max<L: Lanes>(a: L, b: L) -> L {
        a.greater(b)
    }
    #[inline(always)]
    fn max3<L: Lanes>([a, b, c]: [L; 3]) -> L {
        max(max(a.abs(), b.abs()), c.abs())
    }
    let max_zt = max3(e.zs);
    let max_xt = max3(e.x);
    let max_yt = max3(e.y);
    let (g2, g3, g5) = (
        L::splat(gamma(2.0)),
        L::splat(gamma(3.0)),
        L::splat(gamma(5.0)),
    );
    let delta_z = g3 * max_zt;
    let delta_x = g5 * (max_xt + max_zt);
    let delta_y = g5 * (max_yt + max_zt);
    let delta_e = L::splat(2.0) * (g2 * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = max3([e.u, e.v, e.w]);
    let delta_t = L::splat(3.0)
        * (g3 * max_e * max_zt + delta_e * max_zt + delta_z * max_e)
        * e.inv_det.abs();
    e.t.cmp_le(delta_t) & e.clean
}

/// The 4 triangles of `p` against the ray of `r`, as [`edges`] takes them: the ray's origin
/// and shear and the corners, in lanes.
#[inline(always)]
fn triangle4_lanes(r: &TriangleTester, p: &Triangle4) -> TestLanes<f32x4> {
    let corners = each3(|c| each3(|k| f32x4::from(p.v[c][r.axes[k]])));
    let origin = each3(|k| f32x4::splat(r.origin[k]));
    let shear = each3(|k| f32x4::splat(r.shear[k]));
    (origin, shear, corners)
}

/// A triangle test's inputs in lanes: the rays' origins and shears, and the corners.
type TestLanes<L> = ([L; 3], [L; 3], [[L; 3]; 3]);

/// The any-hit verdict of each lane of `e` among the `valid` ones, against
/// `intersect(prep, .., t_max)` for that lane's pair: (`hit`, `unsure`). `hit` lanes are hits
/// with `t < t_max` (the scalar test computes the same values and accepts them); `unsure` lanes
/// are those only the scalar test can decide; every other lane is a miss.
#[inline(always)]
pub(super) fn any_hit_verdict<L: Lanes>(e: &Edges<L>, valid: u32, t_max: L) -> (u32, u32) {
    let reject = e.rejected | !e.t.cmp_lt(t_max);
    let keep = !(reject & !e.any_zero).bitmask() & valid;
    // Shadow rays meet the triangle they start on, which only the error bound rejects.
    if keep == 0 {
        return (0, 0);
    }
    let keep = keep & !(too_close(e) & !e.any_zero).bitmask();
    let unsure = keep & (e.any_zero | !e.clean).bitmask();
    (keep & !unsure, unsure)
}

/// [`any_hit_verdict`] of the 4 triangles of `p` (bit i = lane i, only lanes < `p.lanes`)
/// against the ray of `r`: the whole test, without [`triangle_hits`]' stop at the edge signs
/// (measured slower for single shadow rays: the bvh README's "Triangle tests").
#[inline(always)]
pub(super) fn triangle_any_hit(r: &TriangleTester, p: &Triangle4, t_max: f32) -> (u32, u32) {
    let (origin, shear, corners) = triangle4_lanes(r, p);
    let e = edges(&origin, &shear, &corners);
    any_hit_verdict(&e, p.valid(), f32x4::splat(t_max))
}

/// The closest-hit verdict of each lane of `e` among the `valid` ones (bit i = lane i), against
/// `intersect(prep, .., +inf)` for that lane's pair: (`exact`, `scalar`). `exact` lanes are
/// hits with exactly `e.t` and barycentrics `e.u, e.v, e.w` times `e.inv_det`, with t <= the
/// lane's `t_max` (farther hits are left out); `scalar` lanes are those only the scalar test
/// can decide (an edge function is 0, or a NaN input). Every other lane is a miss or farther.
#[inline(always)]
pub(super) fn closest_verdict<L: Lanes>(e: &Edges<L>, valid: u32, t_max: L) -> (u32, u32) {
    let unsure = e.any_zero | !e.clean;
    let scalar = unsure.bitmask() & valid;
    let miss = e.rejected | !e.t.cmp_le(t_max);
    let mut exact = !(miss | unsure).bitmask() & valid;
    if exact != 0 {
        exact &= !too_close(e).bitmask();
    }
    (exact, scalar)
}

/// The 4-wide closest-hit test of one [`Triangle4`] against `intersect(prep, .., +inf)`.
pub(super) struct Triangle4Hits {
    /// Lanes whose scalar result is a hit with exactly `t[lane]` and barycentrics
    /// `b[..][lane]`, with t <= the `t_max` given (farther hits are left out).
    pub exact: u32,
    /// Lanes only the scalar test can decide (an edge function is 0, or a NaN input).
    pub scalar: u32,
    pub t: [f32; 4],
    pub b: [[f32; 4]; 3],
}

/// The 4-wide closest-hit test of `p` against the ray of `r`; `None` when every triangle of `p`
/// is outside ([`edges_unless_outside`]).
#[inline(always)]
pub(super) fn triangle_hits(
    r: &TriangleTester,
    p: &Triangle4,
    t_max: f32,
) -> Option<Triangle4Hits> {
    let (origin, shear, corners) = triangle4_lanes(r, p);
    let e = edges_unless_outside(&origin, &shear, &corners, p.valid())?;
    let (exact, scalar) = closest_verdict(&e, p.valid(), f32x4::splat(t_max));
    Some(Triangle4Hits {
        exact,
        scalar,
        t: e.t.to_array(),
        b: [
            (e.u * e.inv_det).to_array(),
            (e.v * e.inv_det).to_array(),
            (e.w * e.inv_det).to_array(),
        ],
    })
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::triangle::intersect;
    use glam::Vec3;

    use crate::bvh::tests::Rng;

    /// Mostly ordinary values, often exact grid values, zeros of both signs, extremes.
    pub(in crate::bvh) fn coord(rng: &mut Rng) -> f32 {
        const SPECIAL: [f32; 10] = [0.0, -0.0, 1.0, -1.0, 0.5, 2.0, 1e-30, -1e-30, 1e30, -1e30];
        match rng.next() % 8 {
            0 => SPECIAL[(rng.next() % 10) as usize],
            1 => (rng.next() % 5) as f32 - 2.0,
            _ => rng.unit() * 4.0 - 2.0,
        }
    }

    pub(in crate::bvh) fn any_vec(rng: &mut Rng) -> Vec3 {
        Vec3::new(coord(rng), coord(rng), coord(rng))
    }

    fn triangle4(tris: &[[Vec3; 3]; 4]) -> Triangle4 {
        let mut v = [[[0.0f32; 4]; 3]; 3];
        for (lane, t) in tris.iter().enumerate() {
            for (c, p) in t.iter().enumerate() {
                for a in 0..3 {
                    v[c][a][lane] = p[a];
                }
            }
        }
        Triangle4 {
            v,
            first: 0,
            lanes: 4,
        }
    }

    /// The 4-wide any-hit test decides every lane it claims (hit or miss) as the scalar test
    /// does, and the 4-wide closest-hit test gives the scalar test's exact bits on every lane
    /// it decides: 4 million ray/triangle pairs, random and degenerate (shared vertices,
    /// axis-parallel rays, signed zeros, huge and tiny coordinates, origins on vertices and on
    /// triangles).
    #[test]
    fn four_wide_tests_agree_with_the_scalar_test() {
        let mut rng = Rng(42);
        let (mut hits, mut exact_hits) = (0, 0);
        for _ in 0..1_000_000 {
            let shared = any_vec(&mut rng);
            let tris: [[Vec3; 3]; 4] = std::array::from_fn(|_| {
                let a = if rng.next().is_multiple_of(4) {
                    shared
                } else {
                    any_vec(&mut rng)
                };
                [a, any_vec(&mut rng), any_vec(&mut rng)]
            });
            let origin = match rng.next() % 4 {
                0 => tris[(rng.next() % 4) as usize][(rng.next() % 3) as usize],
                1 => {
                    // On (or next to) a triangle's surface, as shadow rays start.
                    let [p0, p1, p2] = tris[(rng.next() % 4) as usize];
                    let (b1, b2) = (rng.unit() * 0.5, rng.unit() * 0.5);
                    p0 * (1.0 - b1 - b2) + p1 * b1 + p2 * b2
                }
                _ => any_vec(&mut rng) * 3.0,
            };
            let dir = match rng.next() % 3 {
                0 => any_vec(&mut rng),
                _ => tris[(rng.next() % 4) as usize][(rng.next() % 3) as usize] - origin,
            };
            if dir == Vec3::ZERO || !dir.is_finite() {
                continue;
            }
            let ray = Ray { origin, dir };
            let prep = RayPrep::new(&ray);
            let tester = TriangleTester::new(&prep);
            let p = triangle4(&tris);
            let t_max = [f32::INFINITY, rng.unit() * 4.0][(rng.next() % 2) as usize];
            let (any_hit, unsure) = triangle_any_hit(&tester, &p, t_max);
            let exact = triangle_hits(&tester, &p, t_max).unwrap_or(Triangle4Hits {
                exact: 0,
                scalar: 0,
                t: [f32::NAN; 4],
                b: [[f32::NAN; 4]; 3],
            });
            assert_eq!(exact.exact & exact.scalar, 0);
            exact_hits += exact.exact.count_ones();
            for (lane, [p0, p1, p2]) in tris.iter().enumerate() {
                let bit = 1 << lane;
                let any = intersect(&prep, *p0, *p1, *p2, t_max).is_some();
                hits += usize::from(any);
                assert_eq!(any_hit & unsure, 0);
                if any_hit & bit != 0 {
                    assert!(
                        any,
                        "a claimed hit the scalar test misses: {ray:?} {:?}",
                        tris[lane]
                    );
                } else if unsure & bit == 0 {
                    assert!(
                        !any,
                        "a claimed miss the scalar test hits: {ray:?} {:?}",
                        tris[lane]
                    );
                }
                let scalar = intersect(&prep, *p0, *p1, *p2, f32::INFINITY);
                if exact.scalar & bit != 0 {
                    continue;
                }
                let wide = (exact.exact & bit != 0)
                    .then(|| (exact.t[lane].to_bits(), exact.b.map(|b| b[lane].to_bits())));
                let expected = scalar
                    .filter(|h| h.t <= t_max)
                    .map(|h| (h.t.to_bits(), h.b.map(f32::to_bits)));
                assert_eq!(wide, expected, "{ray:?} {:?}", tris[lane]);
            }
        }
        assert!(hits > 100_000, "the test should exercise hits ({hits})");
        assert!(exact_hits > 100_000, "and 4-wide exact hits ({exact_hits})");
    }
}
