//! Four-wide box and triangle tests over [`Node4`] and [`Packet`] (the `wide` crate: SSE on
//! x86-64, NEON on aarch64, plain arrays elsewhere). Every lane computes the same IEEE
//! operations in the same order as the scalar code (no FMA, comparisons and selects instead of
//! min/max), so results are the same bits on every machine:
//! - [`BoxTester::test`] is [`SlabRay::entry`](super::traverse) on each child box;
//! - [`triangle_candidates`] rejects only lanes that [`crate::triangle::intersect`] rejects;
//!   the survivors go through `intersect` itself, which alone decides hits and t.

use super::node4::{Node4, Packet};
use crate::triangle::{Ray, RayPrep, gamma};
use wide::f32x4;

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
            origin: [0, 1, 2].map(|a| f32x4::splat(ray.origin[a])),
            inv_dir: [0, 1, 2].map(|a| f32x4::splat(inv[a])),
            near_hi: [0, 1, 2].map(|a| inv[a].is_sign_negative()),
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
            t0 = near.simd_gt(t0).select(near, t0);
            t1 = far.simd_lt(t1).select(far, t1);
        }
        let miss = t0.simd_gt(t1).to_bitmask();
        (!miss & 0xf, t0.to_array())
    }
}

/// Per-ray constants of the 4-wide triangle pre-test: the permuted origin and the shear.
pub(super) struct TriangleTester {
    axes: [usize; 3],
    origin: [f32x4; 3],
    shear: [f32x4; 3],
}

impl TriangleTester {
    pub fn new(prep: &RayPrep) -> Self {
        let (axes, shear) = prep.shear();
        TriangleTester {
            axes,
            origin: axes.map(|a| f32x4::splat(prep.origin[a])),
            shear: shear.map(f32x4::splat),
        }
    }
}

/// Lanes of `p` (bit i = lane i, only lanes < `p.lanes`) for which `intersect(prep, .., t_max)`
/// may hit with `t <= t_max` (`inclusive`) or `t < t_max`. A lane is dropped only when the
/// scalar test computes the same edge functions and rejects it: mixed signs with none zero,
/// zero or wrongly signed determinant, t beyond `t_max`, or (not `inclusive`) t within its
/// rounding error of 0.
#[inline(always)]
pub(super) fn triangle_candidates(
    r: &TriangleTester,
    p: &Packet,
    t_max: f32,
    inclusive: bool,
) -> u32 {
    let [kx, ky, kz] = r.axes;
    let [ox, oy, oz] = r.origin;
    let [sx, sy, sz] = r.shear;
    let corner = |c: usize| {
        let v = &p.v[c];
        let x = f32x4::from(v[kx]) - ox;
        let y = f32x4::from(v[ky]) - oy;
        let z = f32x4::from(v[kz]) - oz;
        (x - sx * z, y - sy * z, z)
    };
    let (ax, ay, az) = corner(0);
    let (bx, by, bz) = corner(1);
    let (cx, cy, cz) = corner(2);
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    let zero = f32x4::ZERO;
    let any_zero = u.simd_eq(zero) | v.simd_eq(zero) | w.simd_eq(zero);
    let any_neg = u.simd_lt(zero) | v.simd_lt(zero) | w.simd_lt(zero);
    let any_pos = u.simd_gt(zero) | v.simd_gt(zero) | w.simd_gt(zero);
    let det = u + v + w;
    let (zs0, zs1, zs2) = (sz * az, sz * bz, sz * cz);
    let t_scaled = u * zs0 + v * zs1 + w * zs2;
    let inv_det = f32x4::ONE / det;
    let t = t_scaled * inv_det;
    let t_max = f32x4::splat(t_max);
    // The scalar test rejects a NaN t too.
    let beyond = if inclusive {
        !t.simd_le(t_max)
    } else {
        !t.simd_lt(t_max)
    };
    let wrong_side = det.simd_lt(zero) ^ t_scaled.simd_lt(zero);
    let reject = (any_neg & any_pos) | det.simd_eq(zero) | wrong_side | beyond;
    // With an edge function exactly zero the scalar test recomputes them in f64: keep the lane.
    let lanes = (1u32 << p.lanes) - 1;
    let keep = !(reject & !any_zero).to_bitmask() & lanes;
    // Closest-hit survivors are mostly real hits; shadow rays meet the triangle they start
    // on, which only the next test rejects.
    if keep == 0 || inclusive {
        return keep;
    }
    // The conservative t > 0 test (pbrt-v4 6.8.6), in the scalar order of operations. The
    // maxima are of non-negative values, where `select(a > b, a, b)` equals `f32::max` unless a
    // NaN is involved; then `t <= delta_t` is false and the lane is kept.
    let max = |a: f32x4, b: f32x4| a.simd_gt(b).select(a, b);
    let max_zt = max(max(zs0.abs(), zs1.abs()), zs2.abs());
    let max_xt = max(max(ax.abs(), bx.abs()), cx.abs());
    let max_yt = max(max(ay.abs(), by.abs()), cy.abs());
    let g = |n: f32| f32x4::splat(gamma(n));
    let delta_z = g(3.0) * max_zt;
    let delta_x = g(5.0) * (max_xt + max_zt);
    let delta_y = g(5.0) * (max_yt + max_zt);
    let delta_e =
        f32x4::splat(2.0) * (g(2.0) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = max(max(u.abs(), v.abs()), w.abs());
    let delta_t = f32x4::splat(3.0)
        * (g(3.0) * max_e * max_zt + delta_e * max_zt + delta_z * max_e)
        * inv_det.abs();
    let too_close = (t.simd_le(delta_t) & !any_zero).to_bitmask();
    keep & !too_close
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::triangle::intersect;
    use glam::Vec3;

    /// splitmix64, for reproducible test data.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^ (z >> 31)
        }
        fn unit(&mut self) -> f32 {
            (self.next() >> 40) as f32 / (1u64 << 24) as f32
        }
        /// Mostly ordinary values, often exact grid values, zeros of both signs, extremes.
        fn coord(&mut self) -> f32 {
            const SPECIAL: [f32; 10] = [0.0, -0.0, 1.0, -1.0, 0.5, 2.0, 1e-30, -1e-30, 1e30, -1e30];
            match self.next() % 8 {
                0 => SPECIAL[(self.next() % 10) as usize],
                1 => (self.next() % 5) as f32 - 2.0,
                _ => self.unit() * 4.0 - 2.0,
            }
        }
        fn vec(&mut self) -> Vec3 {
            Vec3::new(self.coord(), self.coord(), self.coord())
        }
    }

    fn packet(tris: &[[Vec3; 3]; 4]) -> Packet {
        let mut v = [[[0.0f32; 4]; 3]; 3];
        for (lane, t) in tris.iter().enumerate() {
            for (c, p) in t.iter().enumerate() {
                for a in 0..3 {
                    v[c][a][lane] = p[a];
                }
            }
        }
        Packet {
            v,
            first: 0,
            lanes: 4,
        }
    }

    /// The 4-wide pre-test never drops a lane the scalar test hits: 4 million ray/triangle
    /// pairs, random and degenerate (shared vertices, axis-parallel rays, signed zeros, huge and
    /// tiny coordinates, origins on vertices and on triangles).
    #[test]
    fn packet_pretest_keeps_every_scalar_hit() {
        let mut rng = Rng(42);
        let mut hits = 0;
        for _ in 0..1_000_000 {
            let shared = rng.vec();
            let tris: [[Vec3; 3]; 4] = std::array::from_fn(|_| {
                let a = if rng.next() % 4 == 0 {
                    shared
                } else {
                    rng.vec()
                };
                [a, rng.vec(), rng.vec()]
            });
            let origin = match rng.next() % 4 {
                0 => tris[(rng.next() % 4) as usize][(rng.next() % 3) as usize],
                1 => {
                    // On (or next to) a triangle's surface, as shadow rays start.
                    let [p0, p1, p2] = tris[(rng.next() % 4) as usize];
                    let (b1, b2) = (rng.unit() * 0.5, rng.unit() * 0.5);
                    p0 * (1.0 - b1 - b2) + p1 * b1 + p2 * b2
                }
                _ => rng.vec() * 3.0,
            };
            let dir = match rng.next() % 3 {
                0 => rng.vec(),
                _ => tris[(rng.next() % 4) as usize][(rng.next() % 3) as usize] - origin,
            };
            if dir == Vec3::ZERO || !dir.is_finite() {
                continue;
            }
            let ray = Ray { origin, dir };
            let prep = RayPrep::new(&ray);
            let tester = TriangleTester::new(&prep);
            let p = packet(&tris);
            let t_max = [f32::INFINITY, rng.unit() * 4.0][(rng.next() % 2) as usize];
            let exclusive = triangle_candidates(&tester, &p, t_max, false);
            let inclusive = triangle_candidates(&tester, &p, t_max, true);
            for (lane, [p0, p1, p2]) in tris.iter().enumerate() {
                if intersect(&prep, *p0, *p1, *p2, t_max).is_some() {
                    hits += 1;
                    assert!(exclusive & (1 << lane) != 0, "{ray:?} {:?}", tris[lane]);
                }
                if let Some(h) = intersect(&prep, *p0, *p1, *p2, f32::INFINITY)
                    && h.t <= t_max
                {
                    assert!(inclusive & (1 << lane) != 0, "{ray:?} {:?}", tris[lane]);
                }
            }
        }
        assert!(hits > 100_000, "the test should exercise hits ({hits})");
    }
}
