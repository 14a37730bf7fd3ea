//! Leaves of ray packets (closest-hit and segment packets) eight rays at a time (x86-64 with
//! AVX2, `dispatch.rs`): each triangle of the leaf is tested against up to eight rays of the
//! packet, one per lane, where the 4-wide path tests each ray against the leaf's
//! [`Triangle4`]s in turn. A leaf of n triangles in m `Triangle4`s then costs n tests for the
//! group instead of m per ray; rays of one pixel's samples, which reach the same leaves
//! together, gain most.
//!
//! Guarantee: every ray keeps exactly the hit (and every segment the answer) the 4-wide path
//! gives it. Each lane runs the
//! watertight test of [`crate::triangle::intersect`] in its order of operations (`simd4.rs`,
//! `edges`, over [`Lanes`]), which needs the lanes' rays to permute the axes alike (the
//! packet's group falls back to the 4-wide path otherwise); lanes only the scalar test can
//! decide go to it; and each lane keeps its best hit by [`ClosestSearch::offer`]'s rule
//! (smaller t, then smaller id), whose winner does not depend on the order of the hits.

use super::Bvh;
use super::lanes::{F32x8, Lanes};
use super::node4::Triangle4;
use super::ray_packet::bits;
use super::simd4::{any_hit_verdict, closest_verdict, each3, edges};
use super::traverse::ClosestSearch;
use crate::triangle::{Ray, RayPrep, TriangleHit, intersect};

/// Rays per 8-wide leaf test.
pub(super) const LANES: usize = 8;

/// 8-wide leaf tests run so far (closest-hit and any-hit), so tests can show they ran.
#[cfg(test)]
pub(super) static LEAF_TESTS: std::sync::atomic::AtomicUsize =
    std::sync::atomic::AtomicUsize::new(0);

#[inline(always)]
fn count_leaf_test() {
    #[cfg(test)]
    LEAF_TESTS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
}

/// Whether testing the leaf of `count` `Triangle4`s from `first` 8-wide against the rays of
/// `group` (bit i = lane i) takes fewer tests than the 4-wide path: one test per triangle of
/// the leaf against one per `Triangle4` per ray. (An 8-wide test costs more than a 4-wide one;
/// weighting it so measured no better on the bundled scenes and a 1M mesh.)
#[inline(always)]
fn pays_eight_wide(bvh: &Bvh, (first, count): (usize, usize), group: u32) -> bool {
    let leaf = &bvh.triangles[first..first + count];
    let triangles: usize = leaf.iter().map(|p| p.lanes as usize).sum();
    group.count_ones() as usize * count > triangles
}

/// Up to eight rays in lanes for the triangle test: the permutation they share and, per
/// permuted axis, each lane's origin and shear. Lanes past the last ray repeat it (and are
/// never active).
pub(super) struct RayLanes8 {
    axes: [usize; 3],
    origin: [F32x8; 3],
    shear: [F32x8; 3],
}

impl RayLanes8 {
    /// Rays `ray(0..count)` (`count` in 1..=8) in lanes, with exactly
    /// [`crate::triangle::RayPrep::new`]'s permutation and shear for each; `None` when the rays
    /// permute the axes differently (their largest direction components differ in axis or
    /// sign). Call only on hosts with AVX2.
    #[target_feature(enable = "avx2")]
    pub fn new<'a>(count: usize, ray: impl Fn(usize) -> &'a Ray) -> Option<Self> {
        let lanes = |f: &dyn Fn(&Ray) -> f32| {
            F32x8::from_array(std::array::from_fn(|l| f(ray(l.min(count - 1)))))
        };
        let dir: [F32x8; 3] = each3(|a| lanes(&|r| r.dir[a]));
        let [ax, ay, az] = dir.map(Lanes::abs);
        // As `RayPrep::new`: z is x when |x| > |y| and |x| > |z|, else y when |y| > |z|, else z.
        let x_over_y = ax.cmp_gt(ay);
        let z_is_x = x_over_y & ax.cmp_gt(az);
        let z_is_y = !x_over_y & ay.cmp_gt(az);
        let kz = match (z_is_x.bitmask(), z_is_y.bitmask()) {
            (0xff, _) => 0,
            (_, 0xff) => 1,
            (0, 0) => 2,
            _ => return None,
        };
        let negative = dir[kz].cmp_lt(F32x8::splat(0.0)).bitmask();
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        match negative {
            0 => {}
            0xff => std::mem::swap(&mut kx, &mut ky),
            _ => return None,
        }
        let dz = dir[kz];
        Some(RayLanes8 {
            axes: [kx, ky, kz],
            origin: each3(|k| lanes(&|r| r.origin[[kx, ky, kz][k]])),
            shear: [dir[kx] / dz, dir[ky] / dz, F32x8::splat(1.0) / dz],
        })
    }
}

/// A packet's two groups of eight rays in lanes, each made when the group first meets a leaf
/// 8-wide (`None` inside: its rays permute the axes differently, so it stays 4-wide).
#[derive(Default)]
pub(super) struct PacketLanes8([Option<Option<RayLanes8>>; 2]);

impl PacketLanes8 {
    /// Calls `test(from, group, lanes)` for each group of eight rays of `active` that meets the
    /// leaf `(first Triangle4, count)` 8-wide: the packet's rays `from..from + 8`, bit i of
    /// `group` standing for ray `from + i`, where that takes fewer tests than the 4-wide path
    /// ([`pays_eight_wide`]) and the group's rays permute the axes alike. Returns the rays of
    /// `active` left for the 4-wide path. `ray(i)` is ray i of the packet's `len`. Only at
    /// kernel width `Eight` (hosts with AVX2).
    #[inline(always)]
    pub fn by_eights<'r>(
        &mut self,
        bvh: &Bvh,
        leaf: (usize, usize),
        active: u32,
        len: usize,
        ray: impl Fn(usize) -> &'r Ray,
        mut test: impl FnMut(usize, u32, &RayLanes8),
    ) -> u32 {
        let mut rest = active;
        for (g, slot) in self.0.iter_mut().enumerate() {
            let from = g * LANES;
            let group = (active >> from) & 0xff;
            if !pays_eight_wide(bvh, leaf, group) {
                continue;
            }
            let count = len.min(from + LANES) - from;
            // SAFETY: callers reach this only at kernel width `Eight`, so on hosts with AVX2
            // (`dispatch.rs`).
            #[allow(unsafe_code)]
            let lanes =
                slot.get_or_insert_with(|| unsafe { RayLanes8::new(count, |i| ray(from + i)) });
            let Some(lanes) = lanes else {
                continue;
            };
            test(from, group, lanes);
            rest &= !(group << from);
        }
        rest
    }
}

impl RayLanes8 {
    /// Lane `lane` of `p` in every lane, on the rays' permuted axes: `[corner][axis]`.
    #[inline(always)]
    fn corners(&self, p: &Triangle4, lane: usize) -> [[F32x8; 3]; 3] {
        let mut corners = [[F32x8::splat(0.0); 3]; 3];
        for (c, corner) in corners.iter_mut().enumerate() {
            for (k, x) in corner.iter_mut().enumerate() {
                *x = F32x8::splat(p.v[c][self.axes[k]][lane]);
            }
        }
        corners
    }
}

/// Tests the `count` `Triangle4`s from `first` (one leaf) against the rays of `active` (bit i =
/// lane i of `lanes`), keeping each ray's best hit in `searches[i]`, which must be `Some` for
/// every active ray. Call only on hosts with AVX2.
#[target_feature(enable = "avx2")]
pub(super) fn closest_in_leaf8(
    bvh: &Bvh,
    (first, count): (usize, usize),
    lanes: &RayLanes8,
    active: u32,
    searches: &mut [Option<ClosestSearch>],
) {
    count_leaf_test();
    let mut best = BestLanes::load(searches, active);
    for k in first..first + count {
        let p: &Triangle4 = &bvh.triangles[k];
        for lane in 0..p.lanes as usize {
            let e = edges(&lanes.origin, &lanes.shear, &lanes.corners(p, lane));
            let (exact, scalar) = closest_verdict(&e, active, best.t);
            if exact | scalar == 0 {
                continue;
            }
            let id = bvh.ids[p.first as usize + lane];
            let b = [e.u * e.inv_det, e.v * e.inv_det, e.w * e.inv_det];
            best.offer(exact, e.t, b, id, (k * 4 + lane) as u32);
            for i in bits(scalar) {
                let s = searches[i].as_ref().expect("every active ray has a search");
                if let Some(h) = s.scalar_hit(p, lane) {
                    best.offer_one(i, h, id, (k * 4 + lane) as u32);
                }
            }
        }
    }
    best.store(searches);
}

/// Each lane's best hit during one leaf: t, barycentrics, triangle id and the hit's place
/// (`Triangle4` index times 4 plus lane), ids and places as `u32` bits.
struct BestLanes {
    t: F32x8,
    b: [F32x8; 3],
    id: F32x8,
    place: F32x8,
    /// Lanes whose best hit changed in this leaf.
    changed: u32,
}

impl BestLanes {
    #[inline(always)]
    fn load(searches: &[Option<ClosestSearch>], active: u32) -> Self {
        let mut t = [f32::INFINITY; LANES];
        let mut b = [[0.0f32; LANES]; 3];
        let mut id = [u32::MAX; LANES];
        let mut place = [0u32; LANES];
        for i in bits(active) {
            let s = searches[i].as_ref().expect("every active ray has a search");
            if let Some((h, best_id, k, lane)) = s.best() {
                t[i] = h.t;
                (0..3).for_each(|c| b[c][i] = h.b[c]);
                id[i] = best_id;
                place[i] = (k * 4 + lane) as u32;
            }
        }
        BestLanes {
            t: F32x8::from_array(t),
            b: [
                F32x8::from_array(b[0]),
                F32x8::from_array(b[1]),
                F32x8::from_array(b[2]),
            ],
            id: F32x8::from_bits(id),
            place: F32x8::from_bits(place),
            changed: 0,
        }
    }

    /// Keeps, in the lanes of `hits`, hits at `t` with barycentrics `b` on triangle `id` at
    /// `place` that beat the lane's best: smaller t, or equal t and smaller id.
    #[inline(always)]
    fn offer(&mut self, hits: u32, t: F32x8, b: [F32x8; 3], id: u32, place: u32) {
        if hits == 0 {
            return;
        }
        let better = t.cmp_lt(self.t) | (t.cmp_eq(self.t) & self.id.u32_above(id));
        let better = better & F32x8::lane_mask(hits);
        self.t = better.select(t, self.t);
        self.b = [
            better.select(b[0], self.b[0]),
            better.select(b[1], self.b[1]),
            better.select(b[2], self.b[2]),
        ];
        let id = F32x8::splat(f32::from_bits(id));
        let place = F32x8::splat(f32::from_bits(place));
        self.id = better.select(id, self.id);
        self.place = better.select(place, self.place);
        self.changed |= better.bitmask();
    }

    /// [`Self::offer`] of one hit, in lane `i`.
    #[cold]
    #[target_feature(enable = "avx2")]
    fn offer_one(&mut self, i: usize, h: TriangleHit, id: u32, place: u32) {
        let lanes = |x: F32x8, v: f32| {
            let mut a = x.to_array();
            a[i] = v;
            F32x8::from_array(a)
        };
        let t = lanes(F32x8::splat(f32::INFINITY), h.t);
        let b = each3(|c| lanes(F32x8::splat(0.0), h.b[c]));
        self.offer(1 << i, t, b, id, place);
    }

    /// Writes the changed lanes back to their searches.
    #[inline(always)]
    fn store(&self, searches: &mut [Option<ClosestSearch>]) {
        if self.changed == 0 {
            return;
        }
        let t = self.t.to_array();
        let b = [
            self.b[0].to_array(),
            self.b[1].to_array(),
            self.b[2].to_array(),
        ];
        let id = self.id.to_bits();
        let place = self.place.to_bits();
        for i in bits(self.changed) {
            let s = searches[i].as_mut().expect("every active ray has a search");
            let h = TriangleHit {
                t: t[i],
                b: each3(|c| b[c][i]),
            };
            let (k, lane) = ((place[i] / 4) as usize, (place[i] % 4) as usize);
            s.replace_best(h, id[i], k, lane);
        }
    }
}

/// Of the shadow segments of `active` (bit i = lane i of `lanes`; `segments[i]` is lane i's
/// ray and `t_max`), those some triangle of the leaf (`count` `Triangle4`s from `first`) blocks
/// (a hit with `0 < t < t_max`), as [`super::Bvh::occluded`]'s leaf test decides. Call only on
/// hosts with AVX2.
#[target_feature(enable = "avx2")]
pub(super) fn occluded_in_leaf8(
    bvh: &Bvh,
    (first, count): (usize, usize),
    lanes: &RayLanes8,
    active: u32,
    segments: &[(Ray, f32)],
) -> u32 {
    count_leaf_test();
    let last = segments.len() - 1;
    let t_max = F32x8::from_array(std::array::from_fn(|l| segments[l.min(last)].1));
    let mut open = active;
    for p in &bvh.triangles[first..first + count] {
        for lane in 0..p.lanes as usize {
            let e = edges(&lanes.origin, &lanes.shear, &lanes.corners(p, lane));
            let (hit, unsure) = any_hit_verdict(&e, open, t_max);
            open &= !hit;
            for i in bits(unsure) {
                let (ray, t_max) = &segments[i];
                let [p0, p1, p2] = p.corners(lane);
                if intersect(&RayPrep::new(ray), p0, p1, p2, *t_max).is_some() {
                    open &= !(1 << i);
                }
            }
            if open == 0 {
                return active;
            }
        }
    }
    active & !open
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::dispatch::{KernelWidth, available_kernel_widths};
    use crate::bvh::simd4::tests::any_vec;
    use crate::bvh::tests::Rng;
    use glam::Vec3;

    /// The 8-wide verdicts of one triangle (lane 0 of `p`) against the rays of `lanes`:
    /// (closest-hit `exact` and `scalar`, t, barycentrics, any-hit `hit` and `unsure`).
    #[target_feature(enable = "avx2")]
    fn verdicts(
        lanes: &RayLanes8,
        p: &Triangle4,
        valid: u32,
        t_max: [f32; LANES],
    ) -> (u32, u32, [f32; LANES], [[f32; LANES]; 3], u32, u32) {
        let e = edges(&lanes.origin, &lanes.shear, &lanes.corners(p, 0));
        let t_max = F32x8::from_array(t_max);
        let (exact, scalar) = closest_verdict(&e, valid, t_max);
        let (hit, unsure) = any_hit_verdict(&e, valid, t_max);
        let b = [e.u * e.inv_det, e.v * e.inv_det, e.w * e.inv_det];
        let b = [b[0].to_array(), b[1].to_array(), b[2].to_array()];
        (exact, scalar, e.t.to_array(), b, hit, unsure)
    }

    /// Rays at the triangle as shadow and camera rays meet it: from its corners, from points
    /// on it, from anywhere; toward its corners or anywhere.
    fn ray_at(rng: &mut Rng, tri: &[Vec3; 3]) -> Option<Ray> {
        let origin = match rng.next() % 4 {
            0 => tri[(rng.next() % 3) as usize],
            1 => {
                let (b1, b2) = (rng.unit() * 0.5, rng.unit() * 0.5);
                tri[0] * (1.0 - b1 - b2) + tri[1] * b1 + tri[2] * b2
            }
            _ => any_vec(rng) * 3.0,
        };
        let dir = match rng.next() % 3 {
            0 => any_vec(rng),
            _ => tri[(rng.next() % 3) as usize] - origin + any_vec(rng) * 0.01,
        };
        (dir != Vec3::ZERO && dir.is_finite()).then_some(Ray { origin, dir })
    }

    /// On every lane it decides, the 8-wide test decides as the scalar test: the closest-hit
    /// verdict with the scalar test's exact t and barycentric bits, the any-hit verdict with
    /// its answer. 500,000 groups of up to eight rays sharing a permutation (4 million
    /// ray/triangle pairs), on random and degenerate triangles (collinear, repeated corners,
    /// signed zeros, huge and tiny coordinates). The lanes' setup is `RayPrep`'s, bit for bit.
    #[test]
    fn eight_wide_tests_agree_with_the_scalar_test() {
        if !available_kernel_widths().contains(&KernelWidth::Eight) {
            eprintln!("this host has no AVX2: there is no 8-wide path to test");
            return;
        }
        let mut rng = Rng(7);
        let (mut pairs, mut exact_hits, mut any_hits, mut mixed) = (0, 0, 0, 0);
        for _ in 0..500_000 {
            let mut tri = [any_vec(&mut rng), any_vec(&mut rng), any_vec(&mut rng)];
            match rng.next() % 8 {
                0 => tri[2] = tri[0],
                1 => tri[2] = tri[0] + (tri[1] - tri[0]) * 2.0,
                _ => {}
            }
            let mut rays: Vec<Ray> = Vec::new();
            for _ in 0..32 {
                let Some(ray) = ray_at(&mut rng, &tri) else {
                    continue;
                };
                let axes = |r: &Ray| RayPrep::new(r).shear().0;
                if rays.first().is_none_or(|r0| axes(r0) == axes(&ray)) {
                    rays.push(ray);
                } else if mixed < 1000 {
                    // A group whose rays permute the axes differently stays 4-wide.
                    let pair = [rays[0], ray];
                    // SAFETY: the host has AVX2 (checked above).
                    #[allow(unsafe_code)]
                    let lanes = unsafe { RayLanes8::new(2, |i| &pair[i]) };
                    assert!(lanes.is_none(), "{pair:?}");
                    mixed += 1;
                }
                if rays.len() == LANES {
                    break;
                }
            }
            if rays.is_empty() {
                continue;
            }
            // SAFETY: the host has AVX2 (checked above).
            #[allow(unsafe_code)]
            let lanes = unsafe { RayLanes8::new(rays.len(), |i| &rays[i]) }
                .expect("the rays share their permutation");
            let t_max: [f32; LANES] = std::array::from_fn(|_| {
                [f32::INFINITY, rng.unit() * 4.0][(rng.next() % 2) as usize]
            });
            let mut v = [[[0.0f32; 4]; 3]; 3];
            for (c, corner) in tri.iter().enumerate() {
                for a in 0..3 {
                    v[c][a][0] = corner[a];
                }
            }
            let p = Triangle4 {
                v,
                first: 0,
                lanes: 1,
            };
            let valid = (1u32 << rays.len()) - 1;
            // SAFETY: the host has AVX2 (checked above).
            #[allow(unsafe_code)]
            let (exact, scalar, t, b, hit, unsure) = unsafe { verdicts(&lanes, &p, valid, t_max) };
            assert_eq!(exact & scalar, 0);
            assert_eq!(hit & unsure, 0);
            exact_hits += exact.count_ones();
            any_hits += hit.count_ones();
            for (i, ray) in rays.iter().enumerate() {
                pairs += 1;
                let prep = RayPrep::new(ray);
                let (axes, shear) = prep.shear();
                assert_eq!(axes, lanes.axes);
                for k in 0..3 {
                    let lane = |x: F32x8| x.to_array()[i].to_bits();
                    assert_eq!(lane(lanes.origin[k]), prep.origin[axes[k]].to_bits());
                    assert_eq!(lane(lanes.shear[k]), shear[k].to_bits());
                }
                let [p0, p1, p2] = tri;
                let bit = 1 << i;
                let any = intersect(&prep, p0, p1, p2, t_max[i]).is_some();
                if hit & bit != 0 {
                    assert!(any, "a claimed hit the scalar test misses: {ray:?} {tri:?}");
                } else if unsure & bit == 0 {
                    assert!(!any, "a claimed miss the scalar test hits: {ray:?} {tri:?}");
                }
                if scalar & bit != 0 {
                    continue;
                }
                let wide = (exact & bit != 0)
                    .then(|| (t[i].to_bits(), [0, 1, 2].map(|c| b[c][i].to_bits())));
                let expected = intersect(&prep, p0, p1, p2, f32::INFINITY)
                    .filter(|h| h.t <= t_max[i])
                    .map(|h| (h.t.to_bits(), h.b.map(f32::to_bits)));
                assert_eq!(wide, expected, "{ray:?} {tri:?}");
            }
        }
        assert!(pairs > 3_000_000, "pairs tested ({pairs})");
        assert!(exact_hits > 50_000, "8-wide exact hits ({exact_hits})");
        assert!(any_hits > 50_000, "8-wide any hits ({any_hits})");
        assert_eq!(mixed, 1000, "groups of mixed permutations");
    }
}
