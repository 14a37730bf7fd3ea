//! Watertight ray/triangle intersection (Woop, Benthin, Wald, "Watertight Ray/Triangle
//! Intersection", JCGT 2013), as in pbrt-v4: rays through shared edges and vertices of a closed
//! mesh never pass between its triangles.
//!
//! Guarantees: the result is a pure function of the ray and the three vertices (no dependence on
//! traversal order or on other triangles), so the closest hit over any grouping of triangles is
//! the same bits. No fused multiply-add, no platform maths: identical on x86-64 and aarch64.

use glam::Vec3;

/// A ray; `dir` need not be unit length (t is measured in units of `dir`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point (t = 0), world coordinates.
    pub origin: Vec3,
    /// Direction; the point at parameter t is `origin + t * dir`.
    pub dir: Vec3,
}

/// Per-ray constants of the watertight test: the axis permutation and shear.
#[derive(Clone, Copy, Debug)]
pub struct RayPrep {
    /// The ray's origin, unchanged; triangles are translated by it before the shear.
    pub origin: Vec3,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
}

/// A hit on one triangle: parameter `t` along the ray and barycentrics `b = (b0, b1, b2)` of the
/// corners (b0 + b1 + b2 = 1 up to rounding, each >= 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Ray parameter, in units of `dir`: above its rounding error bound and below `t_max`.
    pub t: f32,
    /// Barycentric weights of corners p0, p1, p2: the hit point is `b0·p0 + b1·p1 + b2·p2`.
    pub b: [f32; 3],
}

impl RayPrep {
    /// The permutation `[kx, ky, kz]` (indices into x, y, z) and shear `[sx, sy, sz]`, for
    /// vectorised copies of [`intersect`] that must compute the same bits.
    pub(crate) fn shear(&self) -> ([usize; 3], [f32; 3]) {
        ([self.kx, self.ky, self.kz], [self.sx, self.sy, self.sz])
    }

    /// Precomputes the permutation (largest |dir| axis becomes z) and shear of `ray`.
    pub fn new(ray: &Ray) -> Self {
        let d = ray.dir.abs();
        let kz = if d.x > d.y {
            if d.x > d.z { 0 } else { 2 }
        } else if d.y > d.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if ray.dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let dz = ray.dir[kz];
        RayPrep {
            origin: ray.origin,
            kx,
            ky,
            kz,
            sx: ray.dir[kx] / dz,
            sy: ray.dir[ky] / dz,
            sz: 1.0 / dz,
        }
    }
}

/// Intersects the prepared ray with triangle (p0, p1, p2) for `0 < t < t_max`.
/// Returns `None` on a miss, a degenerate triangle or a ray parallel to the triangle's plane.
#[inline]
pub fn intersect(r: &RayPrep, p0: Vec3, p1: Vec3, p2: Vec3, t_max: f32) -> Option<TriangleHit> {
    // Translate to the ray origin, permute, shear (Woop et al. section 3).
    let a = p0 - r.origin;
    let b = p1 - r.origin;
    let c = p2 - r.origin;
    let (az, bz, cz) = (a[r.kz], b[r.kz], c[r.kz]);
    let ax = a[r.kx] - r.sx * az;
    let ay = a[r.ky] - r.sy * az;
    let bx = b[r.kx] - r.sx * bz;
    let by = b[r.ky] - r.sy * bz;
    let cx = c[r.kx] - r.sx * cz;
    let cy = c[r.ky] - r.sy * cz;

    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;
    if u == 0.0 || v == 0.0 || w == 0.0 {
        // Exactly on an edge in single precision: decide in double so neighbours agree.
        let f = |p: f32, q: f32, s: f32, t: f32| {
            (f64::from(p) * f64::from(q) - f64::from(s) * f64::from(t)) as f32
        };
        u = f(cx, by, cy, bx);
        v = f(ax, cy, ay, cx);
        w = f(bx, ay, by, ax);
    }
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let (zs0, zs1, zs2) = (r.sz * az, r.sz * bz, r.sz * cz);
    let t_scaled = u * zs0 + v * zs1 + w * zs2;
    // Same sign as det means t > 0; the t_max test is done on t itself, so whether a triangle
    // counts depends only on its own t (never on rounding of t_max * det).
    if (det < 0.0) != (t_scaled < 0.0) {
        return None;
    }
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    if t.is_nan() || t >= t_max {
        return None;
    }
    // Conservative t > 0 (pbrt-v4 section 6.8.6): reject hits whose t is within its rounding
    // error of zero, so a ray leaving a surface never hits that surface again.
    let max_zt = zs0.abs().max(zs1.abs()).max(zs2.abs());
    let max_xt = ax.abs().max(bx.abs()).max(cx.abs());
    let max_yt = ay.abs().max(by.abs()).max(cy.abs());
    let delta_z = gamma(3.0) * max_zt;
    let delta_x = gamma(5.0) * (max_xt + max_zt);
    let delta_y = gamma(5.0) * (max_yt + max_zt);
    let delta_e = 2.0 * (gamma(2.0) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = u.abs().max(v.abs()).max(w.abs());
    let delta_t =
        3.0 * (gamma(3.0) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv_det.abs();
    if t <= delta_t {
        return None;
    }
    Some(TriangleHit {
        t,
        b: [u * inv_det, v * inv_det, w * inv_det],
    })
}

/// gamma(n) = n·u / (1 - n·u) with u = 2^-24: the bound on the relative error of n roundings.
pub const fn gamma(n: f32) -> f32 {
    let u = f32::EPSILON * 0.5;
    n * u / (1.0 - n * u)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(o: [f32; 3], d: [f32; 3]) -> RayPrep {
        RayPrep::new(&Ray {
            origin: Vec3::from(o),
            dir: Vec3::from(d),
        })
    }

    #[test]
    fn hits_centre_with_expected_t_and_barycentrics() {
        let r = ray([0.25, 0.25, 5.0], [0.0, 0.0, -1.0]);
        let h = intersect(&r, Vec3::ZERO, Vec3::X, Vec3::Y, f32::INFINITY).expect("hit");
        assert_eq!(h.t, 5.0);
        assert_eq!(h.b, [0.5, 0.25, 0.25]);
    }

    #[test]
    fn misses_outside_behind_and_beyond_t_max() {
        let r = ray([2.0, 2.0, 5.0], [0.0, 0.0, -1.0]);
        assert!(intersect(&r, Vec3::ZERO, Vec3::X, Vec3::Y, f32::INFINITY).is_none());
        let r = ray([0.25, 0.25, 5.0], [0.0, 0.0, 1.0]);
        assert!(intersect(&r, Vec3::ZERO, Vec3::X, Vec3::Y, f32::INFINITY).is_none());
        let r = ray([0.25, 0.25, 5.0], [0.0, 0.0, -1.0]);
        assert!(intersect(&r, Vec3::ZERO, Vec3::X, Vec3::Y, 5.0).is_none());
        assert!(intersect(&r, Vec3::ZERO, Vec3::X, Vec3::Y, 5.0001).is_some());
    }

    /// Two triangles sharing the edge `edge`; `opposite[i]` is the corner of `triangles[i]` off
    /// the edge, so a hit on the edge has barycentric `b[opposite[i]] == 0`.
    #[derive(Clone, Copy)]
    struct EdgePair {
        triangles: [[Vec3; 3]; 2],
        opposite: [usize; 2],
        edge: [Vec3; 2],
    }

    /// The unit square at z = 0 cut along its diagonal from (1, 0, 0) to (0, 1, 0).
    const SQUARE: EdgePair = EdgePair {
        triangles: [
            [Vec3::ZERO, Vec3::X, Vec3::Y],
            [Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
        ],
        opposite: [0, 1],
        edge: [Vec3::X, Vec3::Y],
    };

    /// A folded pair in general position: not coplanar, no axis-aligned edge, and the points of
    /// the edge A-B are (apart from A and B) not representable.
    const A: Vec3 = Vec3::new(0.3, -1.7, 0.2);
    const B: Vec3 = Vec3::new(2.1, 0.9, -0.4);
    const FOLDED: EdgePair = EdgePair {
        triangles: [
            [A, B, Vec3::new(-1.1, 0.8, 0.5)],
            [Vec3::new(2.9, -1.6, -0.3), B, A],
        ],
        opposite: [2, 0],
        edge: [A, B],
    };

    /// Traces `origin + t dir` against both triangles of `pair` and asserts watertightness: at
    /// least one of them hits. Also asserts that every hit is on the shared edge (barycentric
    /// across it within `b_tol` of 0) at t within `t_tol` of `t_aim`, and that two hits agree on
    /// t to a few ulps. Returns both answers.
    fn trace_edge(
        pair: EdgePair,
        origin: Vec3,
        dir: Vec3,
        t_aim: f32,
        b_tol: f32,
        t_tol: f32,
    ) -> [Option<TriangleHit>; 2] {
        let r = RayPrep::new(&Ray { origin, dir });
        let hits = pair
            .triangles
            .map(|[p0, p1, p2]| intersect(&r, p0, p1, p2, f32::INFINITY));
        let what = format!("ray {origin} + t {dir}");
        assert!(
            hits.iter().any(Option::is_some),
            "{what} leaked through the edge"
        );
        for (hit, off) in hits.iter().zip(pair.opposite) {
            if let Some(h) = hit {
                assert!(h.b[off].abs() <= b_tol, "{what}: {h:?} is not on the edge");
                assert!(
                    (h.t - t_aim).abs() <= t_tol,
                    "{what}: {h:?}, aimed at t = {t_aim}"
                );
            }
        }
        if let [Some(h0), Some(h1)] = hits {
            let ulps = 4.0 * f32::EPSILON * h0.t;
            assert!(
                (h0.t - h1.t).abs() <= ulps,
                "{what}: t {} vs {}",
                h0.t,
                h1.t
            );
        }
        hits
    }

    #[test]
    fn shared_edge_is_hit_by_both_sides_when_aimed_exactly() {
        // The points (1 - k/16, k/16, 0), endpoints included, are exactly on the square's
        // diagonal. With these directions (components of few bits, the largest a power of two)
        // the origin `point - 4 dir`, the translation and the shear are exact, so the ray passes
        // exactly through the point: it is on both closed triangles, and both must report it at
        // t = 4 with barycentric exactly 0 across the edge.
        let dirs = [
            [0.0, 0.0, -1.0],
            [0.25, -0.5, -1.0],
            [-0.375, 0.125, -1.0],
            [0.5, 0.75, 1.0],     // from below
            [-1.0, 0.5, -0.75],   // x is the major axis
            [0.25, -1.0, 0.5],    // y is the major axis, from below
            [1.0, 1.0, -0.125],   // grazing, across the edge
            [-0.5, 0.5, -0.0625], // grazing, along the edge
        ];
        for k in 0..=16 {
            let s = k as f32 / 16.0;
            let point = Vec3::new(1.0 - s, s, 0.0);
            for d in dirs {
                let dir = Vec3::from(d);
                let origin = point - 4.0 * dir;
                assert_eq!(origin + 4.0 * dir, point, "inexact aim");
                let hits = trace_edge(SQUARE, origin, dir, 4.0, 0.0, 0.0);
                assert!(
                    hits.iter().all(Option::is_some),
                    "k = {k}, dir {dir}: {hits:?}"
                );
            }
        }
    }

    #[test]
    fn shared_edge_is_hit_by_at_least_one_side() {
        // Points `a + s (b - a)` of the edge rounded to f32. For most s (i / 1000, 1/3, ...) the
        // point of the real edge is not representable, so the ray passes within a rounding error
        // of the edge on either side or through it; the non-dyadic directions also round the
        // origin `point - 3 dir`. Whatever the rounding, one of the two triangles must hit (at
        // t ~ 3, barycentric ~0 across the edge): a leak here is a crack in a closed mesh. (A
        // Moller-Trumbore test, which is not watertight, lets 552 of these 12,048 rays through.)
        let dirs = [
            [0.0, 0.0, -1.0],
            [0.3, -0.7, -1.1],
            [-0.123, 0.456, 0.789],
            [0.9, 0.8, -0.05], // grazing the square
            [-2.0, 0.1, 0.3],
            [0.01, -1.0, 0.02],
        ];
        let mut fractions: Vec<f64> = (1..1000).map(|i| f64::from(i) / 1000.0).collect();
        fractions.extend([1.0 / 3.0, 2.0 / 3.0, 1e-6, 1.0 - 1e-6, 0.5 + 1e-9]);
        for pair in [SQUARE, FOLDED] {
            let [a, b] = pair.edge.map(|p| p.as_dvec3());
            for &s in &fractions {
                let point = (a + s * (b - a)).as_vec3();
                for d in dirs {
                    let dir = Vec3::from(d);
                    trace_edge(pair, point - 3.0 * dir, dir, 3.0, 1e-5, 1e-5);
                }
            }
        }
    }

    #[test]
    fn degenerate_triangle_never_hits() {
        let r = ray([0.0, 0.0, 5.0], [0.0, 0.0, -1.0]);
        assert!(intersect(&r, Vec3::ZERO, Vec3::ZERO, Vec3::X, f32::INFINITY).is_none());
    }
}
