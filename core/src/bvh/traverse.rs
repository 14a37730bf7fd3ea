//! Closest-hit and any-hit traversal. Box tests are conservative (pbrt-v4's slab test with the
//! far distance scaled by 1 + 2·gamma(3)), and a node is skipped only when its entry distance
//! exceeds the current bound by a relative margin, so culling never changes the answer.

use super::hit_corners::CornerLanes;
use super::node4::{LEAF, Node4, Triangle4};
use super::simd4::{BoxTester, TriangleTester, each3, triangle_any_hit, triangle_hits};
use super::{Aabb, Bvh};
use crate::triangle::{Ray, RayPrep, TriangleHit, gamma, intersect};
use glam::Vec3;

/// Relative margin on culling distances: far larger than the rounding error of a box entry
/// distance or of a triangle's t, so culling stays conservative.
pub(super) const CULL_MARGIN: f32 = 1.0 + 1e-4;
/// 1 + 2·gamma(3) with gamma(n) = n·u / (1 - n·u), u = 2^-24 (pbrt-v4, Bounds3::IntersectP).
pub(super) const FAR_SCALE: f32 = 1.0 + 2.0 * gamma(3.0);
/// Each 4-wide level defers at most 3 children and 4-wide depth is at most the binary depth,
/// which the builder and `from_parts` cap at `MAX_DEPTH`.
pub(super) const STACK: usize = 3 * super::build::MAX_DEPTH + 1;

/// The nearest hit of a ray: scene-wide triangle id, distance and barycentrics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestHit {
    /// Scene-wide id of the triangle hit (ties in `t` go to the smaller id).
    pub id: u32,
    /// Ray parameter of the hit, `t > 0`, in units of the ray's `dir`.
    pub t: f32,
    /// Barycentrics of the corners, each >= 0, summing to 1 up to rounding.
    pub b: [f32; 3],
    /// The triangle's position in the BVH's leaf order (indexes per-triangle data stored in
    /// that order, as split objects do).
    pub index: u32,
    /// Where the BVH keeps the triangle: its `Triangle4` times 4 plus its lane
    /// ([`Bvh::hit_corners`] reads the corners there).
    pub(super) place: u32,
}

struct SlabRay {
    origin: Vec3,
    inv_dir: Vec3,
}

impl SlabRay {
    fn new(ray: &Ray) -> Self {
        SlabRay {
            origin: ray.origin,
            inv_dir: Vec3::ONE / ray.dir,
        }
    }

    /// Entry distance into `b` (0 when the origin is inside), or `None` if the ray misses it
    /// or enters beyond `t_max`. The near plane of each axis is chosen by the direction's sign
    /// bit, exactly as [`BoxTester::test`] does for four boxes at once.
    #[inline]
    fn entry(&self, b: &Aabb, t_max: f32) -> Option<f32> {
        let mut t0 = 0.0f32;
        let mut t1 = t_max;
        for axis in 0..3 {
            let inv = self.inv_dir[axis];
            let (near_plane, far_plane) = if inv.is_sign_negative() {
                (b.hi[axis], b.lo[axis])
            } else {
                (b.lo[axis], b.hi[axis])
            };
            let near = (near_plane - self.origin[axis]) * inv;
            let far = (far_plane - self.origin[axis]) * inv * FAR_SCALE;
            // NaN (0 * inf when the origin lies on a slab plane) leaves the interval unchanged.
            if near > t0 {
                t0 = near;
            }
            if far < t1 {
                t1 = far;
            }
        }
        if t0 > t1 { None } else { Some(t0) }
    }
}

/// Whether a shadow segment (`0 < t < t_max` along `ray`) can meet a BVH with root `bounds`:
/// exactly the root test of [`Bvh::occluded`], so `false` here guarantees `occluded` is false.
pub fn segment_may_hit(bounds: &Aabb, ray: &Ray, t_max: f32) -> bool {
    SlabRay::new(ray)
        .entry(bounds, t_max * CULL_MARGIN)
        .is_some()
}

/// The child word and `Triangle4` count that stand for the whole tree (wide node 0).
pub(super) const ROOT: (u32, u32) = (0, 0);

/// A deferred child: its child word, `Triangle4` count and entry distance.
#[derive(Clone, Copy)]
pub(super) struct Entry {
    child: u32,
    triangle4_count: u32,
    t: f32,
}

const NO_ENTRY: Entry = Entry {
    child: 0,
    triangle4_count: 0,
    t: 0.0,
};

thread_local! {
    /// One traversal stack per thread, reused: initialising a fresh one per ray costs as much
    /// as a small traversal.
    pub(super) static STACKS: std::cell::RefCell<[Entry; STACK]> =
        const { std::cell::RefCell::new([NO_ENTRY; STACK]) };
}

/// A ray's best hit so far: its distance (+inf while there is none: hits have finite t),
/// barycentrics, triangle id (`u32::MAX` while none) and place (`Triangle4` index times 4 plus
/// lane). Ray packets keep their rays' in lanes ([`super::ray_packet::PacketHits`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct BestHit {
    pub t: f32,
    pub b: [f32; 3],
    pub id: u32,
    pub place: u32,
}

impl BestHit {
    /// No hit yet: every hit beats it.
    pub const NONE: BestHit = BestHit {
        t: f32::INFINITY,
        b: [0.0; 3],
        id: u32::MAX,
        place: 0,
    };

    /// Whether `h`, a hit on triangle `id`, beats this one: smaller t, or equal t and smaller
    /// id. The winner is unique, so the order of the offers cannot change it.
    #[inline(always)]
    pub fn beaten_by(&self, h: &TriangleHit, id: u32) -> bool {
        h.t < self.t || (h.t == self.t && id < self.id)
    }

    /// The culling bound: a box entered beyond it cannot hold a better hit.
    #[inline(always)]
    pub fn bound(&self) -> f32 {
        self.t * CULL_MARGIN
    }
}

/// One ray's closest-hit search: its constants for the triangle tests and its best hit so far.
/// Shared by single rays and ray packets, so both keep exactly the same best hit.
#[derive(Clone, Copy)]
pub(super) struct ClosestSearch {
    /// The ray (the scalar test's constants are rebuilt from it in the rare lanes that need
    /// them: copying them here stalled every ray's setup).
    ray: Ray,
    /// The 4-wide triangle tests' constants.
    tris: TriangleTester,
    pub best: BestHit,
}

impl ClosestSearch {
    #[inline(always)]
    pub fn new(ray: &Ray) -> Self {
        ClosestSearch {
            tris: TriangleTester::new(&RayPrep::new(ray)),
            ray: *ray,
            best: BestHit::NONE,
        }
    }

    /// Keeps `h`, a hit on triangle `id` (lane `lane` of `Triangle4` `k`), when it beats the
    /// best hit so far ([`BestHit::beaten_by`]).
    #[inline(always)]
    pub fn offer(&mut self, h: TriangleHit, id: u32, k: usize, lane: usize) {
        if self.best.beaten_by(&h, id) {
            self.best = BestHit {
                t: h.t,
                b: h.b,
                id,
                place: (k * 4 + lane) as u32,
            };
        }
    }

    /// The scalar test of lane `lane` of `p`, for the pairs the SIMD tests leave to it.
    #[cold]
    pub fn scalar_hit(&self, p: &Triangle4, lane: usize) -> Option<TriangleHit> {
        scalar_hit(&self.ray, p, lane)
    }

    /// The culling bound: a box entered beyond it cannot hold a better hit.
    #[inline(always)]
    pub fn bound(&self) -> f32 {
        self.best.bound()
    }
}

/// The scalar test of `ray` against lane `lane` of `p`, for the pairs the SIMD tests leave to
/// it.
#[cold]
pub(super) fn scalar_hit(ray: &Ray, p: &Triangle4, lane: usize) -> Option<TriangleHit> {
    let [p0, p1, p2] = p.corners(lane);
    intersect(&RayPrep::new(ray), p0, p1, p2, f32::INFINITY)
}

impl Bvh {
    /// The nearest hit with `t > 0`: smaller t wins, equal t goes to the smaller id.
    pub fn closest_hit(&self, ray: &Ray) -> Option<ClosestHit> {
        if self.wide.is_empty() {
            return None;
        }
        STACKS.with_borrow_mut(|stack| self.closest_hit_with(ray, stack))
    }

    /// [`Bvh::closest_hit`] of a non-empty BVH with the caller's stack.
    #[inline(always)]
    pub(super) fn closest_hit_with(
        &self,
        ray: &Ray,
        stack: &mut [Entry; STACK],
    ) -> Option<ClosestHit> {
        let mut search = ClosestSearch::new(ray);
        self.closest_from(ROOT, &BoxTester::new(ray), &mut search, stack);
        self.closest_result(&search.best)
    }

    /// The corners of the triangle `hit` is on, where this BVH keeps them. `hit` must come
    /// from this BVH (else the corners are another triangle's, or this panics).
    #[inline(always)]
    pub fn hit_corners(&self, hit: &ClosestHit) -> CornerLanes<'_> {
        let (k, lane) = ((hit.place / 4) as usize, (hit.place % 4) as usize);
        CornerLanes::new(&self.triangles[k].v, lane)
    }

    /// The hit a finished search found, if any.
    #[inline(always)]
    pub(super) fn closest_result(&self, best: &BestHit) -> Option<ClosestHit> {
        // Hits have finite t: +inf means none was found.
        (best.t < f32::INFINITY).then(|| ClosestHit {
            id: best.id,
            t: best.t,
            b: best.b,
            index: self.leaf_index(best.place),
            place: best.place,
        })
    }

    /// The leaf-order index of the triangle at `place` (its `Triangle4` times 4 plus its lane).
    #[inline(always)]
    pub(super) fn leaf_index(&self, place: u32) -> u32 {
        let (k, lane) = ((place / 4) as usize, place % 4);
        self.triangles[k].first + lane
    }

    /// Tests the `count` `Triangle4`s from `first` (one leaf) against the search's ray, keeping the
    /// best hit.
    #[inline(always)]
    pub(super) fn closest_in_leaf(&self, first: usize, count: usize, s: &mut ClosestSearch) {
        for k in first..first + count {
            let p = &self.triangles[k];
            let Some(wide) = triangle_hits(&s.tris, p, s.best.t) else {
                continue;
            };
            let mut lanes = wide.exact | wide.scalar;
            while lanes != 0 {
                let lane = lanes.trailing_zeros() as usize;
                lanes &= lanes - 1;
                let hit = if wide.exact & (1 << lane) != 0 {
                    Some(TriangleHit {
                        t: wide.t[lane],
                        b: each3(|k| wide.b[k][lane]),
                    })
                } else {
                    s.scalar_hit(p, lane)
                };
                if let Some(h) = hit {
                    s.offer(h, self.ids[p.first as usize + lane], k, lane);
                }
            }
        }
    }

    /// Continues `s` over the subtree whose child word and `Triangle4` count are `start` (the
    /// whole tree for [`ROOT`]).
    #[inline(always)]
    pub(super) fn closest_from(
        &self,
        start: (u32, u32),
        boxes: &BoxTester,
        s: &mut ClosestSearch,
        stack: &mut [Entry; STACK],
    ) {
        let mut depth = 0usize;
        let (mut child, mut triangle4_count) = start;
        loop {
            if child & LEAF == 0 {
                let node = &self.wide[child as usize];
                let (mask, t0) = boxes.test(node, s.bound());
                if mask != 0 {
                    (child, triangle4_count) = descend(node, mask, &t0, stack, &mut depth);
                    continue;
                }
            } else {
                self.closest_in_leaf((child & !LEAF) as usize, triangle4_count as usize, s);
            }
            // Pop the next child still worth visiting: entering at or before the (scaled) best
            // t is exactly when its box test with the current bound would still pass.
            loop {
                if depth == 0 {
                    return;
                }
                depth -= 1;
                let e = stack[depth];
                if e.t <= s.bound() {
                    (child, triangle4_count) = (e.child, e.triangle4_count);
                    break;
                }
            }
        }
    }

    /// True when some triangle is hit with `0 < t < t_max` (shadow rays).
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        if self.wide.is_empty() || !segment_may_hit(&self.bounds(), ray, t_max) {
            return false;
        }
        STACKS.with_borrow_mut(|stack| self.occluded_with(ray, t_max, stack))
    }

    /// [`Bvh::occluded`] of a non-empty BVH past the root test, with the caller's stack.
    #[inline(always)]
    pub(super) fn occluded_with(&self, ray: &Ray, t_max: f32, stack: &mut [Entry; STACK]) -> bool {
        let prep = RayPrep::new(ray);
        let tris = TriangleTester::new(&prep);
        self.occluded_from(ROOT, &BoxTester::new(ray), &prep, &tris, t_max, stack)
    }

    /// Whether the segment `0 < t < t_max` of the ray that `prep`, `boxes` and `tris` were made
    /// for is blocked by a triangle of the subtree whose child word and `Triangle4` count are
    /// `start` (the whole tree for [`ROOT`]).
    #[inline(always)]
    pub(super) fn occluded_from(
        &self,
        start: (u32, u32),
        boxes: &BoxTester,
        prep: &RayPrep,
        tris: &TriangleTester,
        t_max: f32,
        stack: &mut [Entry; STACK],
    ) -> bool {
        let limit = t_max * CULL_MARGIN;
        let mut depth = 0usize;
        let (mut child, mut triangle4_count) = start;
        loop {
            if child & LEAF == 0 {
                let node = &self.wide[child as usize];
                let (mask, t0) = boxes.test(node, limit);
                if mask != 0 {
                    // Nearest first here too: +15-35% shadow rays/s against slot order.
                    (child, triangle4_count) = descend(node, mask, &t0, stack, &mut depth);
                    continue;
                }
            } else if self.occluded_in_leaf(
                (child & !LEAF) as usize,
                triangle4_count as usize,
                prep,
                tris,
                t_max,
            ) {
                return true;
            }
            if depth == 0 {
                return false;
            }
            depth -= 1;
            (child, triangle4_count) = (stack[depth].child, stack[depth].triangle4_count);
        }
    }

    /// Whether a triangle of the `count` `Triangle4`s from `first` (one leaf) blocks the segment.
    #[inline(always)]
    pub(super) fn occluded_in_leaf(
        &self,
        first: usize,
        count: usize,
        prep: &RayPrep,
        tris: &TriangleTester,
        t_max: f32,
    ) -> bool {
        for p in &self.triangles[first..first + count] {
            let (hit, mut unsure) = triangle_any_hit(tris, p, t_max);
            if hit != 0 {
                return true;
            }
            while unsure != 0 {
                let lane = unsure.trailing_zeros() as usize;
                unsure &= unsure - 1;
                let [p0, p1, p2] = p.corners(lane);
                if intersect(prep, p0, p1, p2, t_max).is_some() {
                    return true;
                }
            }
        }
        false
    }
}

/// One shadow ray's constants for the any-hit leaf tests of a segment packet: the segment
/// `0 < t < t_max`.
#[derive(Clone, Copy)]
pub(super) struct ShadowSearch {
    pub prep: RayPrep,
    pub tris: TriangleTester,
    pub t_max: f32,
}

impl ShadowSearch {
    #[inline(always)]
    pub fn new(ray: &Ray, t_max: f32) -> Self {
        let prep = RayPrep::new(ray);
        ShadowSearch {
            tris: TriangleTester::new(&prep),
            prep,
            t_max,
        }
    }
}

/// Defers the children of `node` in `mask` (entry distances `t0`) farthest first onto `stack`
/// except the nearest, which it returns (child word, `Triangle4` count) to visit now.
#[inline(always)]
fn descend(
    node: &Node4,
    mask: u32,
    t0: &[f32; 4],
    stack: &mut [Entry; STACK],
    depth: &mut usize,
) -> (u32, u32) {
    let mut hit = [NO_ENTRY; 4];
    let mut n = 0;
    for (slot, &t) in t0.iter().enumerate() {
        if mask & (1 << slot) != 0 {
            let e = Entry {
                child: node.child[slot],
                triangle4_count: node.triangle4_count[slot],
                t,
            };
            n = insert_farthest_first(&mut hit, n, e, |e| e.t);
        }
    }
    let e = defer_all_but_nearest(&hit, n, stack, depth);
    (e.child, e.triangle4_count)
}

/// Inserts `e` among the first `n` entries of `sorted`, kept farthest first by `t`; returns the
/// new count.
#[inline(always)]
pub(super) fn insert_farthest_first<E: Copy>(
    sorted: &mut [E; 4],
    n: usize,
    e: E,
    t: impl Fn(&E) -> f32,
) -> usize {
    let mut k = n;
    while k > 0 && t(&sorted[k - 1]) < t(&e) {
        sorted[k] = sorted[k - 1];
        k -= 1;
    }
    sorted[k] = e;
    n + 1
}

/// Pushes all but the last of the first `n` (1..=4) of `sorted` (farthest first) onto `stack`
/// at `depth` and returns the last, the nearest.
#[inline(always)]
pub(super) fn defer_all_but_nearest<E: Copy>(
    sorted: &[E; 4],
    n: usize,
    stack: &mut [E],
    depth: &mut usize,
) -> E {
    // Entry by entry: copying the 0 to 3 entries as one slice compiled to a call to `memcpy`
    // at every inner node.
    for (k, &e) in sorted.iter().take(3).enumerate() {
        if k + 1 < n {
            stack[*depth + k] = e;
        }
    }
    *depth += n - 1;
    sorted[n - 1]
}
