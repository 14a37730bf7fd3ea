//! Coherent ray packets: up to [`PACKET`] neighbouring rays (camera rays of neighbouring pixels
//! or samples, or their shadow rays towards one light) traverse the 4-wide BVH together, for
//! closest hits ([`Bvh::closest_hits`]) and for shadow segments ([`Bvh::occluded_many`]). At each inner node
//! one interval test bounds what every ray of the packet can do with the four child boxes: a
//! child no ray can enter is dropped for all of them, a child every active ray certainly enters
//! keeps them all, and only the children in between are tested ray by ray (four rays per SIMD
//! test). A single remaining ray goes on alone with the single-ray traversal; leaves run the
//! single-ray leaf test for each ray. Packets with a non-finite origin or direction are traced
//! ray by ray.
//!
//! Guarantee: [`Bvh::closest_hits`] gives every ray exactly what [`Bvh::closest_hit`] gives it.
//! Each lane's box test is the single-ray slab test (same operations in the same order, so the
//! same bits). The interval test takes, per axis, the products of the offsets `plane - origin`
//! at the packet's smallest and largest origin with its smallest and largest inverse direction
//! (one offset when all rays share an origin); rounding is monotonic, so the extremes of these
//! are exactly the smallest and largest per-ray values, and the test can
//! only claim "no ray enters" or "every ray enters" when the per-ray tests would say so. A ray
//! leaves a child only when its own test says the child cannot hold a better hit, and all hits
//! go through the single-ray best-hit update ([`Bvh::closest_in_leaf`]). The closest hit is
//! unique (smaller t, then smaller id), so the visiting order cannot change it.

use super::node4::{LEAF, Node4};
use super::packet::{BoxTester, each3, each4};
use super::traverse::{
    ClosestSearch, Entry, FAR_SCALE, ROOT, STACK, STACKS, ShadowSearch, defer_all_but_nearest,
    insert_farthest_first, segment_may_hit,
};
use super::{Bvh, ClosestHit};
use crate::triangle::Ray;
use wide::f32x4;

/// Rays per packet: 16, as in Embree's widest packets (a 4x4 tile or 16 pixels of a row).
pub const PACKET: usize = 16;
const GROUPS: usize = PACKET / 4;
/// Wide nodes below which shadow segments are traced one by one.
const SMALL_TREE: usize = 16;

/// `LANES[bits]`: all-ones in the lanes whose bit is set.
const LANES: [[u32; 4]; 16] = {
    let mut t = [[0u32; 4]; 16];
    let mut bits = 0;
    while bits < 16 {
        let mut l = 0;
        while l < 4 {
            if bits & (1 << l) != 0 {
                t[bits][l] = u32::MAX;
            }
            l += 1;
        }
        bits += 1;
    }
    t
};

fn lane_mask(bits: u32) -> f32x4 {
    let l = &LANES[bits as usize];
    f32x4::from(each4(|k| f32::from_bits(l[k])))
}

/// The packet's rays four lanes per group, for slab tests across rays, and the interval hull of
/// their inverse directions for the whole-packet test.
struct PacketBoxes {
    origin: [[f32x4; 3]; GROUPS],
    /// Per axis: the smallest and largest origin coordinate of the packet.
    origin_lo: [f32x4; 3],
    origin_hi: [f32x4; 3],
    /// Every ray has the same origin (`origin_lo == origin_hi`).
    one_origin: bool,
    inv_dir: [[f32x4; 3]; GROUPS],
    /// All-ones lanes where the direction's sign bit is set (the near plane is the box's hi).
    near_hi: [[f32x4; 3]; GROUPS],
    /// Per axis: the smallest and largest inverse direction of the packet.
    inv_lo: [f32x4; 3],
    inv_hi: [f32x4; 3],
    /// Per axis: every ray's near plane is the box's hi (all signs negative).
    all_near_hi: [bool; 3],
    /// Per axis: the rays' signs differ or an inverse direction is infinite, so the interval
    /// test leaves this axis out (it then never claims that every ray enters).
    loose: [bool; 3],
}

impl PacketBoxes {
    /// `rays` holds 1..=PACKET rays with finite origins and directions; lanes past the end
    /// repeat the last ray (and are never active).
    fn new(rays: &[Ray]) -> Self {
        let last = rays.len() - 1;
        let valid = (1u32 << rays.len()) - 1;
        let dir = |g: usize, a: usize| f32x4::from(each4(|l| rays[(4 * g + l).min(last)].dir[a]));
        let origin: [[f32x4; 3]; GROUPS] =
            each4(|g| each3(|a| f32x4::from(each4(|l| rays[(4 * g + l).min(last)].origin[a]))));
        // The same correctly rounded division as the single-ray testers (`Vec3::ONE / dir`).
        let inv_dir: [[f32x4; 3]; GROUPS] = each4(|g| each3(|a| f32x4::ONE / dir(g, a)));
        // Directions are finite (`is_coherent`), so 1/d is never zero or NaN: its sign bit is
        // set exactly when it is below zero.
        let near_hi = each4(|g| each3(|a| inv_dir[g][a].simd_lt(f32x4::ZERO)));
        let inf = f32x4::splat(f32::INFINITY);
        let (mut lo, mut hi) = ([inf; 3], [-inf; 3]);
        let (mut o_lo, mut o_hi) = ([inf; 3], [-inf; 3]);
        let (mut negative, mut infinite) = ([0u32; 3], [0u32; 3]);
        for g in 0..GROUPS {
            let bits = (valid >> (4 * g)) & 0xf;
            let lanes = lane_mask(bits);
            for a in 0..3 {
                let x = inv_dir[g][a];
                lo[a] = (lanes & x.simd_lt(lo[a])).select(x, lo[a]);
                hi[a] = (lanes & x.simd_gt(hi[a])).select(x, hi[a]);
                let o = origin[g][a];
                o_lo[a] = (lanes & o.simd_lt(o_lo[a])).select(o, o_lo[a]);
                o_hi[a] = (lanes & o.simd_gt(o_hi[a])).select(o, o_hi[a]);
                negative[a] |= (near_hi[g][a].to_bitmask() & bits) << (4 * g);
                infinite[a] |= (x.abs().simd_eq(inf).to_bitmask() & bits) << (4 * g);
            }
        }
        let all_near_hi = each3(|a| negative[a] == valid);
        let origin_lo = each3(|a| lowest(o_lo[a]));
        let origin_hi = each3(|a| -lowest(-o_hi[a]));
        PacketBoxes {
            origin,
            origin_lo: each3(|a| f32x4::splat(origin_lo[a])),
            origin_hi: each3(|a| f32x4::splat(origin_hi[a])),
            one_origin: origin_lo == origin_hi,
            inv_dir,
            near_hi,
            inv_lo: each3(|a| f32x4::splat(lowest(lo[a]))),
            inv_hi: each3(|a| f32x4::splat(-lowest(-hi[a]))),
            all_near_hi,
            loose: each3(|a| infinite[a] != 0 || (negative[a] != 0 && !all_near_hi[a])),
        }
    }

    /// The whole-packet test of the four child boxes of `node` for rays whose bounds lie in
    /// `[bound_lo, bound_hi]`: (children some ray may enter, children every ray enters, a lower
    /// bound of every ray's entry distance per child).
    #[inline(always)]
    fn test_hull(&self, node: &Node4, bound_lo: f32, bound_hi: f32) -> (u32, u32, [f32; 4]) {
        let scale = f32x4::splat(FAR_SCALE);
        let zero = f32x4::ZERO;
        let (mut some0, mut some1) = (zero, f32x4::splat(bound_hi));
        let (mut all0, mut all1) = (zero, f32x4::splat(bound_lo));
        let mut all_axes = true;
        for axis in 0..3 {
            if self.loose[axis] {
                all_axes = false;
                continue;
            }
            let (near_plane, far_plane) = if self.all_near_hi[axis] {
                (node.hi[axis], node.lo[axis])
            } else {
                (node.lo[axis], node.hi[axis])
            };
            let (lo, hi) = (self.inv_lo[axis], self.inv_hi[axis]);
            // `plane - origin` falls as the origin rises; `x * inv` is monotonic in inv, rising
            // for x >= 0 and falling otherwise; rounding keeps both monotonic. So the extremes
            // over the packet are at the extreme origins and inverse directions.
            let low = |x: f32x4| x.simd_ge(zero).select(x * lo, x * hi);
            let high = |x: f32x4| x.simd_ge(zero).select(x * hi, x * lo);
            let min = |a: f32x4, b: f32x4| a.simd_lt(b).select(a, b);
            let max = |a: f32x4, b: f32x4| a.simd_gt(b).select(a, b);
            let (o_lo, o_hi) = (self.origin_lo[axis], self.origin_hi[axis]);
            let (near_plane, far_plane) = (f32x4::from(near_plane), f32x4::from(far_plane));
            let (near_min, near_max, far_max, far_min) = if self.one_origin {
                // Camera rays: one origin, so one offset per plane.
                let (d, f) = (near_plane - o_lo, far_plane - o_lo);
                (low(d), high(d), high(f) * scale, low(f) * scale)
            } else {
                let (d_lo, d_hi) = (near_plane - o_hi, near_plane - o_lo);
                let (f_lo, f_hi) = (far_plane - o_hi, far_plane - o_lo);
                (
                    min(low(d_lo), low(d_hi)),
                    max(high(d_lo), high(d_hi)),
                    max(high(f_lo), high(f_hi)) * scale,
                    min(low(f_lo), low(f_hi)) * scale,
                )
            };
            some0 = near_min.simd_gt(some0).select(near_min, some0);
            some1 = far_max.simd_lt(some1).select(far_max, some1);
            all0 = near_max.simd_gt(all0).select(near_max, all0);
            all1 = far_min.simd_lt(all1).select(far_min, all1);
        }
        let some = !some0.simd_gt(some1).to_bitmask() & 0xf;
        let all = if all_axes {
            // Comparisons with a NaN are false, so a NaN never claims "every ray".
            all0.simd_le(all1).to_bitmask() & some
        } else {
            0
        };
        (some, all, some0.to_array())
    }

    /// For each child of `node`: the rays of `active` that enter it at or before their bound
    /// (lane i of group i / 4 of `bound`) and a lower bound of their entry distances. The hull
    /// test decides what it can; the single-ray test decides the rest ray by ray.
    #[inline(always)]
    fn enter_children(
        &self,
        node: &Node4,
        active: u32,
        bound: &[f32x4; GROUPS],
    ) -> ([u32; 4], [f32; 4]) {
        let (bound_lo, bound_hi) = bound_range(bound, active);
        let (some, all, mut entry) = self.test_hull(node, bound_lo, bound_hi);
        let mut enter = [0u32; 4];
        for slot in bits(some) {
            if all & (1 << slot) != 0 {
                enter[slot] = active;
            } else {
                (enter[slot], entry[slot]) = self.test_rays(node, slot, active, bound);
            }
        }
        (enter, entry)
    }

    /// The rays of `active` (bit i = ray i) that enter child `slot` of `node` at or before their
    /// bound (lane i of group i / 4 of `bound`), by the single-ray slab test, and the smallest
    /// entry distance among them (+inf when none).
    #[inline(always)]
    fn test_rays(
        &self,
        node: &Node4,
        slot: usize,
        active: u32,
        bound: &[f32x4; GROUPS],
    ) -> (u32, f32) {
        let scale = f32x4::splat(FAR_SCALE);
        let lo = each3(|a| f32x4::splat(node.lo[a][slot]));
        let hi = each3(|a| f32x4::splat(node.hi[a][slot]));
        let mut rays = 0;
        let mut entry = f32x4::splat(f32::INFINITY);
        for (g, &bound) in bound.iter().enumerate() {
            let lanes = (active >> (4 * g)) & 0xf;
            if lanes == 0 {
                continue;
            }
            let mut t0 = f32x4::ZERO;
            let mut t1 = bound;
            for axis in 0..3 {
                let near_hi = self.near_hi[g][axis];
                let (o, inv) = (self.origin[g][axis], self.inv_dir[g][axis]);
                let near = (near_hi.select(hi[axis], lo[axis]) - o) * inv;
                let far = (near_hi.select(lo[axis], hi[axis]) - o) * inv * scale;
                // As the single-ray test: a NaN never passes, so it changes nothing.
                t0 = near.simd_gt(t0).select(near, t0);
                t1 = far.simd_lt(t1).select(far, t1);
            }
            let hit = !t0.simd_gt(t1).to_bitmask() & lanes;
            rays |= hit << (4 * g);
            entry = (lane_mask(hit) & t0.simd_lt(entry)).select(t0, entry);
        }
        (rays, lowest(entry))
    }
}

/// A deferred child of a packet: its child word, packet count, the rays that enter it and a
/// lower bound of their entry distances.
#[derive(Clone, Copy)]
struct PacketEntry {
    child: u32,
    packets: u32,
    rays: u32,
    t: f32,
}

const NO_ENTRY: PacketEntry = PacketEntry {
    child: 0,
    packets: 0,
    rays: 0,
    t: 0.0,
};

thread_local! {
    /// One packet traversal stack per thread, reused (as the single-ray stacks).
    static PACKET_STACKS: std::cell::RefCell<[PacketEntry; STACK]> =
        const { std::cell::RefCell::new([NO_ENTRY; STACK]) };
}

/// Whether `ray` can travel in a packet: the hull test needs finite origins and directions.
fn is_finite(ray: &Ray) -> bool {
    ray.origin.is_finite() && ray.dir.is_finite()
}

impl Bvh {
    /// The closest hit of every ray (`out[i]` for `rays[i]`), exactly as [`Bvh::closest_hit`]
    /// gives it, traced in packets of [`PACKET`] consecutive rays: faster when neighbours in
    /// `rays` are coherent (camera rays of neighbouring pixels, best with one origin). Panics if
    /// the lengths differ.
    pub fn closest_hits(&self, rays: &[Ray], out: &mut [Option<ClosestHit>]) {
        assert_eq!(rays.len(), out.len(), "one output per ray");
        if self.wide.is_empty() {
            out.fill(None);
            return;
        }
        PACKET_STACKS.with_borrow_mut(|stack| {
            STACKS.with_borrow_mut(|ray_stack| {
                for (rays, out) in rays.chunks(PACKET).zip(out.chunks_mut(PACKET)) {
                    if rays.iter().all(is_finite) {
                        self.trace_packet(rays, out, stack, ray_stack);
                    } else {
                        for (ray, out) in rays.iter().zip(out) {
                            *out = self.closest_hit_with(ray, ray_stack);
                        }
                    }
                }
            })
        });
    }

    /// For every shadow segment `(ray, t_max)`, whether [`Bvh::occluded`] says it is blocked
    /// (`out[i]` for `rays[i]`), traced in packets of [`PACKET`] consecutive segments: faster
    /// when neighbours are coherent (the shadow rays of neighbouring pixels towards one light).
    /// Panics if the lengths differ.
    pub fn occluded_many(&self, rays: &[(Ray, f32)], out: &mut [bool]) {
        assert_eq!(rays.len(), out.len(), "one output per ray");
        if self.wide.is_empty() {
            out.fill(false);
            return;
        }
        if self.wide.len() < SMALL_TREE {
            // In a tree of a few nodes there is nothing to share: packets would only add setup
            // (cornell, 36 triangles: 0.7x single rays).
            for ((ray, t_max), out) in rays.iter().zip(out) {
                *out = self.occluded(ray, *t_max);
            }
            return;
        }
        PACKET_STACKS.with_borrow_mut(|stack| {
            STACKS.with_borrow_mut(|ray_stack| {
                for (rays, out) in rays.chunks(PACKET).zip(out.chunks_mut(PACKET)) {
                    self.trace_shadow_packet(rays, out, stack, ray_stack);
                }
            })
        });
    }

    fn trace_shadow_packet(
        &self,
        segments: &[(Ray, f32)],
        out: &mut [bool],
        stack: &mut [PacketEntry; STACK],
        ray_stack: &mut [Entry; STACK],
    ) {
        let root = self.bounds();
        let mut rays = [segments[0].0; PACKET];
        // Rays still to trace: the root test of `occluded` and finite inputs (others go alone).
        let mut active = 0u32;
        for (i, (ray, t_max)) in segments.iter().enumerate() {
            rays[i] = *ray;
            out[i] = false;
            if segment_may_hit(&root, ray, *t_max) {
                active |= 1 << i;
            }
        }
        let finite = |(r, t): &(Ray, f32)| is_finite(r) && !t.is_nan();
        if active == 0 || !segments.iter().all(finite) {
            for i in bits(active) {
                let (ray, t_max) = &segments[i];
                out[i] = self.occluded_with(ray, *t_max, ray_stack);
            }
            return;
        }
        let boxes = PacketBoxes::new(&rays[..segments.len()]);
        let mut searches: [Option<ShadowSearch>; PACKET] = [None; PACKET];
        let mut bounds = [[f32::NEG_INFINITY; 4]; GROUPS];
        for (i, (_, t_max)) in segments.iter().enumerate() {
            bounds[i / 4][i % 4] = *t_max * super::traverse::CULL_MARGIN;
        }
        let bound = each4(|g| f32x4::from(bounds[g]));
        let mut blocked = 0u32;
        let mut depth = 0usize;
        let (mut child, mut packets) = ROOT;
        loop {
            if active.count_ones() <= 1 {
                for i in bits(active) {
                    let (ray, t_max) = &segments[i];
                    let s = searches[i].get_or_insert_with(|| ShadowSearch::new(ray, *t_max));
                    let single = BoxTester::new(ray);
                    let start = (child, packets);
                    if self.occluded_from(start, &single, &s.prep, &s.tris, s.t_max, ray_stack) {
                        blocked |= 1 << i;
                    }
                }
            } else if child & LEAF == 0 {
                let node = &self.wide[child as usize];
                let (enter, entry) = boxes.enter_children(node, active, &bound);
                if let Some(next) = descend(node, &enter, &entry, stack, &mut depth) {
                    (child, packets, active) = next;
                    continue;
                }
            } else {
                let first = (child & !LEAF) as usize;
                for i in bits(active) {
                    let (ray, t_max) = &segments[i];
                    let s = searches[i].get_or_insert_with(|| ShadowSearch::new(ray, *t_max));
                    if self.occluded_in_leaf(first, packets as usize, &s.prep, &s.tris, s.t_max) {
                        blocked |= 1 << i;
                    }
                }
            }
            // Pop the next child with the rays not yet known to be blocked (bounds never
            // shrink: each ray's segment is fixed).
            loop {
                if depth == 0 {
                    for (i, o) in out.iter_mut().enumerate() {
                        *o = blocked & (1 << i) != 0;
                    }
                    return;
                }
                depth -= 1;
                let e = stack[depth];
                let keep = e.rays & !blocked;
                if keep != 0 {
                    (child, packets, active) = (e.child, e.packets, keep);
                    break;
                }
            }
        }
    }

    fn trace_packet(
        &self,
        rays: &[Ray],
        out: &mut [Option<ClosestHit>],
        stack: &mut [PacketEntry; STACK],
        ray_stack: &mut [Entry; STACK],
    ) {
        let boxes = PacketBoxes::new(rays);
        // A packet that misses every child of the root (background) needs no per-ray setup.
        let (some, _, _) = boxes.test_hull(&self.wide[0], f32::INFINITY, f32::INFINITY);
        if some == 0 {
            out.fill(None);
            return;
        }
        // Per-ray searches are set up when the ray first reaches a leaf (or goes on alone):
        // rays that miss everything never pay for it.
        let mut searches: [Option<ClosestSearch>; PACKET] = [None; PACKET];
        // Each ray's culling bound, kept in step with its search.
        let mut bounds = [[f32::INFINITY; 4]; GROUPS];
        let mut depth = 0usize;
        let (mut child, mut packets) = ROOT;
        let mut active = (1u32 << rays.len()) - 1;
        loop {
            if active.count_ones() <= 1 {
                for i in bits(active) {
                    let single = BoxTester::new(&rays[i]);
                    let search = searches[i].get_or_insert_with(|| ClosestSearch::new(&rays[i]));
                    self.closest_from((child, packets), &single, search, ray_stack);
                    bounds[i / 4][i % 4] = search.bound();
                }
            } else if child & LEAF == 0 {
                let node = &self.wide[child as usize];
                let bound = each4(|g| f32x4::from(bounds[g]));
                let (enter, entry) = boxes.enter_children(node, active, &bound);
                if let Some(next) = descend(node, &enter, &entry, stack, &mut depth) {
                    (child, packets, active) = next;
                    continue;
                }
            } else {
                let first = (child & !LEAF) as usize;
                for i in bits(active) {
                    let search = searches[i].get_or_insert_with(|| ClosestSearch::new(&rays[i]));
                    self.closest_in_leaf(first, packets as usize, search);
                    bounds[i / 4][i % 4] = search.bound();
                }
            }
            // Pop the next child with the rays that may still find a better hit in it: a ray
            // whose bound is below the child's entry bound would fail its box test now.
            loop {
                if depth == 0 {
                    for (o, s) in out.iter_mut().zip(&searches) {
                        *o = s.as_ref().and_then(|s| self.closest_result(s));
                    }
                    return;
                }
                depth -= 1;
                let e = stack[depth];
                let mut keep = 0;
                for i in bits(e.rays) {
                    if e.t <= bounds[i / 4][i % 4] {
                        keep |= 1 << i;
                    }
                }
                if keep != 0 {
                    (child, packets, active) = (e.child, e.packets, keep);
                    break;
                }
            }
        }
    }
}

/// The indices of the set bits of `mask`, lowest first.
#[inline(always)]
fn bits(mut mask: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let i = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            i
        })
    })
}

/// The smallest lane of `x` (no NaN lanes).
#[inline(always)]
fn lowest(x: f32x4) -> f32 {
    let x = x.to_array();
    x[0].min(x[1]).min(x[2].min(x[3]))
}

/// The smallest and largest bound among the `active` rays.
#[inline(always)]
fn bound_range(bound: &[f32x4; GROUPS], active: u32) -> (f32, f32) {
    let mut lo = f32x4::splat(f32::INFINITY);
    let mut hi = f32x4::splat(f32::NEG_INFINITY);
    for (g, b) in bound.iter().enumerate() {
        let lanes = lane_mask((active >> (4 * g)) & 0xf);
        lo = (lanes & b.simd_lt(lo)).select(*b, lo);
        hi = (lanes & b.simd_gt(hi)).select(*b, hi);
    }
    (lowest(lo), -lowest(-hi))
}

/// Defers the entered children of `node` (rays per slot in `enter`, entry bounds `entry`)
/// farthest first onto `stack`, except the nearest, which it returns to visit now; `None` when
/// no ray enters any child.
#[inline(always)]
fn descend(
    node: &Node4,
    enter: &[u32; 4],
    entry: &[f32; 4],
    stack: &mut [PacketEntry; STACK],
    depth: &mut usize,
) -> Option<(u32, u32, u32)> {
    let mut hit = [NO_ENTRY; 4];
    let mut n = 0;
    for slot in 0..4 {
        if enter[slot] != 0 {
            let e = PacketEntry {
                child: node.child[slot],
                packets: node.packets[slot],
                rays: enter[slot],
                t: entry[slot],
            };
            n = insert_farthest_first(&mut hit, n, e, |e| e.t);
        }
    }
    if n == 0 {
        return None;
    }
    let e = defer_all_but_nearest(&hit[..n], stack, depth);
    Some((e.child, e.packets, e.rays))
}
