//! Ray packets: up to [`RAY_PACKET`] neighbouring rays traverse the 4-wide BVH together. Two
//! kinds share this machinery: closest-hit packets of camera rays ([`Bvh::closest_hits`], here)
//! and segment packets of shadow segments ([`Bvh::occluded_many`], `segment_packet.rs`). (Not
//! to be confused with a leaf's `Triangle4`s: four triangles tested by one 4-wide test.)
//!
//! At each inner node one interval test ([`RayPacketTester`]) bounds what every ray of the
//! packet can do with the four child boxes: a child no ray can enter is dropped for all of
//! them, a child every active ray certainly enters keeps them all, and only the children in
//! between are tested ray by ray, four, eight or sixteen rays a test at the kernel width
//! (`packet_boxes.rs`): every such child in segment packets, leaf children only in
//! closest-hit packets (an inner child takes all the active rays;
//! [`RayPacketTester::enter_children`] says why that is exact). A single remaining ray
//! goes on alone with the single-ray traversal; leaves test each triangle against four rays
//! at once (kernel width `Four`), eight or sixteen (`Eight`, `Sixteen`; `dispatch.rs`) where
//! that takes fewer tests (`leaf_lanes.rs`), and run the single-ray leaf test for the other
//! rays.
//! Packets with a non-finite origin or direction are traced ray by ray.
//!
//! Guarantee: [`Bvh::closest_hits`] gives every ray exactly what [`Bvh::closest_hit`] gives it.
//! Each lane's box test is the single-ray slab test (same operations in the same order, so the
//! same bits). The interval test takes, per axis, the products of the offsets `plane - origin`
//! at the packet's smallest and largest origin with its smallest and largest inverse direction
//! (one offset when all rays share an origin); rounding is monotonic, so the extremes of these
//! are exactly the smallest and largest per-ray values, and the test can only claim "no ray
//! enters" or "every ray enters" when the per-ray tests would say so. A ray leaves a child only
//! when its own test says the child cannot hold a better hit, and all hits go through the
//! single-ray best-hit rule ([`Bvh::closest_in_leaf`], or the same rule in lanes). The closest
//! hit is unique (smaller t, then smaller id), so the visiting order cannot change it.

use super::dispatch::{KernelWidth, kernel_width};
use super::hit_columns::{ClosestOut, HitColumns};
#[cfg(target_arch = "x86_64")]
use super::lanes::{F32x8, F32x16};
use super::lanes::{RayGroupLanes, greater4, lesser4, lowest4 as lowest};
use super::leaf_lanes::{LeafLanes, PacketLanes};
use super::node4::{LEAF, Node4};
use super::packet_boxes::{self, BoxRays};
use super::packet_hits::PacketHits;
use super::packet_rays::PacketRays;
use super::packet_setup::{PacketSetup, packet_setup};
use super::simd4::{BoxTester, each3, each4};
use super::traverse::{
    CULL_MARGIN, ClosestSearch, Entry, FAR_SCALE, ROOT, STACK, STACKS, defer_all_but_nearest,
    insert_farthest_first,
};
use super::{Bvh, ClosestHit};
use crate::triangle::Ray;
use wide::f32x4;

/// Rays a packet holds at most: 64, four groups of sixteen lanes at the widest leaf tests.
/// Segment packets take 64 ([`Bvh::occluded_many`]), and so do closest-hit packets of camera
/// rays at 64 spp and above ([`camera_packet`]: a whole pixel's samples); closest-hit packets
/// of camera rays below that take [`CLOSEST_PACKET`]. One packet test of a node and one setup
/// serve all of a packet's rays (at 64 spp 2-6% less time a sample than packets of 32,
/// `bvh/README.md`, "Packets of 64 rays").
pub const RAY_PACKET: usize = 64;
/// Groups of four rays (one SIMD register each) per packet.
pub(super) const GROUPS: usize = RAY_PACKET / 4;

/// A ray packet's box tester: its rays' origins and inverse directions coordinate by
/// coordinate, for slab tests across rays, and the interval hull of their origins and inverse
/// directions for the whole-packet test.
pub(super) struct RayPacketTester<'a> {
    /// The packet's rays (their origins are read from here).
    rays: &'a PacketRays,
    /// Per axis: the smallest and largest origin coordinate of the packet.
    origin_lo: [f32x4; 3],
    origin_hi: [f32x4; 3],
    /// Every ray has the same origin (`origin_lo == origin_hi`).
    one_origin: bool,
    /// Per axis, each ray's inverse direction (ray i at index i).
    inv_dir: [[f32; RAY_PACKET]; 3],
    /// Per axis: the smallest and largest inverse direction of the packet.
    inv_lo: [f32x4; 3],
    inv_hi: [f32x4; 3],
    /// Per axis: every ray's near plane is the box's hi (all signs negative).
    all_near_hi: [bool; 3],
    /// Per axis: the rays' signs differ or an inverse direction is infinite, so the interval
    /// test leaves this axis out (it then never claims that every ray enters).
    loose: [bool; 3],
}

impl<'a> RayPacketTester<'a> {
    /// `rays` holds the packet's `len` rays, with finite origins and directions (places past
    /// the last ray in its group of four repeat it, and are never active); its setup is made
    /// in lanes of the kernel width `WIDTH` (`packet_setup.rs`).
    pub(super) fn new<const WIDTH: usize>(rays: &'a PacketRays, len: usize) -> Self {
        let mut setup = PacketSetup {
            inv_dir: [[0.0; RAY_PACKET]; 3],
            origin_lo: [0.0; 3],
            origin_hi: [0.0; 3],
            inv_lo: [0.0; 3],
            inv_hi: [0.0; 3],
        };
        // Places past the last ray, in the groups of four in use, repeat it: the extremes over
        // them are those over the rays.
        let places = 4 * groups_of(first_rays(len));
        // SAFETY: the packet traversals run at `WIDTH` only at that kernel width, so on hosts
        // with AVX2 at 8 and AVX-512F at 16 (`dispatch.rs`).
        #[allow(unsafe_code)]
        unsafe {
            packet_setup::<WIDTH>(rays, places, &mut setup)
        };
        let PacketSetup {
            inv_dir,
            origin_lo,
            origin_hi,
            inv_lo,
            inv_hi,
        } = setup;
        // Signs and infinities from the extremes: inverse directions are never 0 or NaN, so
        // every one is below zero exactly when the largest is, and some is infinite exactly
        // when an extreme is.
        let all_near_hi = each3(|a| inv_hi[a] < 0.0);
        let some_negative = each3(|a| inv_lo[a] < 0.0);
        let infinite = each3(|a| inv_lo[a] == -f32::INFINITY || inv_hi[a] == f32::INFINITY);
        RayPacketTester {
            rays,
            origin_lo: each3(|a| f32x4::splat(origin_lo[a])),
            origin_hi: each3(|a| f32x4::splat(origin_hi[a])),
            one_origin: origin_lo == origin_hi,
            inv_dir,
            inv_lo: each3(|a| f32x4::splat(inv_lo[a])),
            inv_hi: each3(|a| f32x4::splat(inv_hi[a])),
            all_near_hi,
            loose: each3(|a| infinite[a] || (some_negative[a] && !all_near_hi[a])),
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
            let (min, max) = (lesser4, greater4);
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
            some0 = greater4(near_min, some0);
            some1 = lesser4(far_max, some1);
            all0 = greater4(near_max, all0);
            all1 = lesser4(far_min, all1);
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
    /// `[bound_lo, bound_hi]` holds the bound of every active ray ([`bound_range`] of `bound`
    /// over these rays or more: a wider range only leaves more to the single-ray test).
    ///
    /// With `LEAVES_ONLY`, only leaf children get the single-ray test: an inner child the hull
    /// test cannot rule out takes every active ray. A ray then tests a leaf's triangles only
    /// if it enters the leaf's own box, and boxes nest (a child's box lies in its parent's,
    /// and the slab test is monotonic in the planes), so it enters every ancestor's box too
    /// with the same bound: the triangles each ray tests are those the single-ray traversal
    /// reaches. On camera rays (a packet's rays are samples of one pixel or neighbours) the
    /// per-ray tests of inner children cost more than the subtrees they rule out.
    #[inline(always)]
    pub(super) fn enter_children<const LEAVES_ONLY: bool, const WIDTH: usize>(
        &self,
        node: &Node4,
        active: u64,
        bound: &[f32x4; GROUPS],
        (bound_lo, bound_hi): (f32, f32),
    ) -> ([u64; 4], [f32; 4]) {
        let (some, all, mut entry) = self.test_hull(node, bound_lo, bound_hi);
        let mut enter = [0u64; 4];
        for slot in bits(some) {
            let inner = node.child[slot] & LEAF == 0;
            if all & (1 << slot) != 0 || (LEAVES_ONLY && inner) {
                enter[slot] = active;
            } else {
                (enter[slot], entry[slot]) = self.test_rays::<WIDTH>(node, slot, active, bound);
            }
        }
        (enter, entry)
    }

    /// The rays of `active` (bit i = ray i) that enter child `slot` of `node` at or before their
    /// bound (lane i of group i / 4 of `bound`), by the single-ray slab test, and the smallest
    /// entry distance among them (+inf when none).
    #[inline(always)]
    fn test_rays<const WIDTH: usize>(
        &self,
        node: &Node4,
        slot: usize,
        active: u64,
        bound: &[f32x4; GROUPS],
    ) -> (u64, f32) {
        let lo = each3(|a| node.lo[a][slot]);
        let hi = each3(|a| node.hi[a][slot]);
        self.rays_in_box::<WIDTH>(lo, hi, active, bound)
    }

    /// The rays of `active` (bit i = ray i) that enter the box `lo..hi` at or before their
    /// bound (lane i of group i / 4 of `bound`), by the single-ray slab test (`SlabRay::entry`,
    /// lane by lane: the same bits) in lanes of the kernel width `WIDTH` (the traversal's),
    /// and the smallest entry distance among them (+inf when none).
    #[inline(always)]
    pub(super) fn rays_in_box<const WIDTH: usize>(
        &self,
        lo: [f32; 3],
        hi: [f32; 3],
        active: u64,
        bound: &[f32x4; GROUPS],
    ) -> (u64, f32) {
        let rays = BoxRays {
            origin: &self.rays.origin,
            inv_dir: &self.inv_dir,
        };
        let bound: &[f32; RAY_PACKET] = wide::bytemuck::cast_ref(bound);
        // SAFETY: the packet traversals run at `WIDTH` only at that kernel width, so on hosts
        // with AVX2 at 8 and AVX-512F at 16 (`dispatch.rs`).
        #[allow(unsafe_code)]
        unsafe {
            packet_boxes::rays_in_box::<WIDTH>(rays, (lo, hi), active, bound)
        }
    }
}

/// A deferred child of a ray packet: its child word, `Triangle4` count, the rays that enter
/// it and a lower bound of their entry distances.
#[derive(Clone, Copy)]
pub(super) struct RayPacketEntry {
    pub child: u32,
    pub triangle4_count: u32,
    /// Bit i: ray i of the packet enters the child.
    pub rays: u64,
    pub t: f32,
}

const NO_ENTRY: RayPacketEntry = RayPacketEntry {
    child: 0,
    triangle4_count: 0,
    rays: 0,
    t: 0.0,
};

thread_local! {
    /// One ray-packet traversal stack per thread, reused (as the single-ray stacks).
    pub(super) static RAY_PACKET_STACKS: std::cell::RefCell<[RayPacketEntry; STACK]> =
        const { std::cell::RefCell::new([NO_ENTRY; STACK]) };
}

/// Whether `ray` can travel in a packet: the hull test needs finite origins and directions.
pub(super) fn is_finite(ray: &Ray) -> bool {
    ray.origin.is_finite() && ray.dir.is_finite()
}

/// Rays a closest-hit packet takes by default ([`Bvh::closest_hits`]): 32, two 4x4 tiles
/// side by side at 1 spp. A packet of [`RAY_PACKET`] such rays (four tiles in a row) spans
/// too much of the image: on the 1M mesh at 1 spp (1280x720) closest hits took 10% longer.
pub const CLOSEST_PACKET: usize = 32;

/// How consecutive rays are cut into closest-hit packets, and how a packet descends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClosestPackets {
    /// Rays a packet takes: 1 to [`RAY_PACKET`].
    pub rays: usize,
    /// Whether an inner child the packet's interval test cannot decide is tested ray by ray
    /// (`true`), or entered by every active ray (`false`: rays then meet the single-ray box
    /// test only at leaves, `RayPacketTester::enter_children`). The per-ray tests cost more
    /// than they rule out when a packet is one pixel's samples, and pay when its rays spread
    /// over several pixels (`camera_packet`). The same answers either way.
    pub inner_tests: bool,
}

impl ClosestPackets {
    /// [`Bvh::closest_hits`]'s packets: [`CLOSEST_PACKET`] rays, tested ray by ray only at
    /// leaves.
    pub const DEFAULT: ClosestPackets = ClosestPackets {
        rays: CLOSEST_PACKET,
        inner_tests: false,
    };
}

/// The closest-hit packets of camera rays made `spp` samples of a pixel at a time, in trace
/// order: [`RAY_PACKET`] rays, a whole pixel's samples at 64 spp and above, several pixels'
/// below that, where their inner children are tested ray by ray too. Measured
/// (docs/perf/time-per-sample.md, "Camera packets below 64 spp"): at 4 and 16 spp, 64 rays
/// with per-ray inner tests took 0.78-0.82x the closest-hit time of 32 rays with leaf tests
/// only on the bundled scenes, 0.83-0.92x on the 1M mesh; at 64 spp per-ray inner tests
/// made the 1M mesh's closest hits 5-15% slower.
pub fn camera_packet(spp: usize) -> ClosestPackets {
    ClosestPackets {
        rays: RAY_PACKET,
        inner_tests: spp < RAY_PACKET,
    }
}

impl Bvh {
    /// The closest hit of every ray (`out[i]` for `rays[i]`), exactly as [`Bvh::closest_hit`]
    /// gives it, traced in packets of [`CLOSEST_PACKET`] consecutive rays: faster when
    /// neighbours in `rays` are coherent (camera rays of neighbouring pixels, best with one
    /// origin). Panics if the lengths differ.
    pub fn closest_hits(&self, rays: &[Ray], out: &mut [Option<ClosestHit>]) {
        self.closest_hits_in_packets(rays, out, ClosestPackets::DEFAULT);
    }

    /// [`Bvh::closest_hits`] in `packet`'s packets ([`camera_packet`] says which for camera
    /// rays): the same answers at every length and either way of descending. Panics if the
    /// lengths differ or the packets' length is out of range.
    pub fn closest_hits_in_packets(
        &self,
        rays: &[Ray],
        out: &mut [Option<ClosestHit>],
        packet: ClosestPackets,
    ) {
        assert_eq!(rays.len(), out.len(), "one output per ray");
        self.closest_hits_to(rays, out, packet);
    }

    /// [`Bvh::closest_hits_in_packets`] into columns: ray i's answer is
    /// [`Bvh::hit_in`]`(hits, i)`, the same at every length. Panics if the lengths differ or
    /// the packets' length is out of range.
    pub fn closest_hits_in_columns(
        &self,
        rays: &[Ray],
        hits: &mut HitColumns,
        packet: ClosestPackets,
    ) {
        assert_eq!(rays.len(), hits.len(), "one output per ray");
        self.closest_hits_to(rays, hits, packet);
    }

    /// The closest hit of every ray of `rays` into `out` (as many places), in `packet`'s
    /// packets.
    fn closest_hits_to<O: ClosestOut + ?Sized>(
        &self,
        rays: &[Ray],
        out: &mut O,
        packet: ClosestPackets,
    ) {
        assert!(
            (1..=RAY_PACKET).contains(&packet.rays),
            "packets of 1 to {RAY_PACKET} rays, not {}",
            packet.rays
        );
        if self.wide.is_empty() {
            out.misses(0, rays.len());
            return;
        }
        RAY_PACKET_STACKS.with_borrow_mut(|stack| {
            STACKS.with_borrow_mut(|ray_stack| match kernel_width() {
                KernelWidth::Sixteen => {
                    self.closest_packets::<16, O>((rays, packet), out, stack, ray_stack)
                }
                KernelWidth::Eight => {
                    self.closest_packets::<8, O>((rays, packet), out, stack, ray_stack)
                }
                KernelWidth::Four => {
                    self.closest_packets::<4, O>((rays, packet), out, stack, ray_stack)
                }
            })
        });
    }

    /// [`Bvh::closest_hits`] over a non-empty BVH, packet by packet, with leaves tested
    /// `WIDTH` rays at a time (4 anywhere; 8 or 16 only at that kernel width, so on hosts with
    /// AVX2 or AVX-512F) where that pays, else ray by ray. Only the leaf tests in lanes are
    /// compiled for the wider instruction sets: the traversal compiled for AVX2 ran 5-10%
    /// slower on the 1M mesh (AVX's `vblendvps` is two micro-operations where SSE4.1's
    /// `blendvps` is one).
    #[inline(always)]
    fn closest_packets<const WIDTH: usize, O: ClosestOut + ?Sized>(
        &self,
        (rays, packet): (&[Ray], ClosestPackets),
        out: &mut O,
        stack: &mut [RayPacketEntry; STACK],
        ray_stack: &mut [Entry; STACK],
    ) {
        let mut packet_rays = PacketRays::EMPTY;
        for (p, rays) in rays.chunks(packet.rays).enumerate() {
            let from = p * packet.rays;
            if packet_rays.fill(rays, |ray| ray) {
                let out = (&mut *out, from);
                let packet_rays = (&packet_rays, packet.inner_tests);
                self.trace_closest_packet::<WIDTH, O>(rays, packet_rays, out, stack, ray_stack);
            } else {
                for (i, ray) in rays.iter().enumerate() {
                    out.one(from + i, self.closest_hit_with(ray, ray_stack));
                }
            }
        }
    }

    /// [`Bvh::closest_hits`] of one packet of 1..=[`RAY_PACKET`] finite rays, also held in
    /// `packet_rays`, into `out` from place `from`, its inner children tested ray by ray where
    /// `inner_tests` ([`ClosestPackets::inner_tests`]).
    #[inline(always)]
    fn trace_closest_packet<const WIDTH: usize, O: ClosestOut + ?Sized>(
        &self,
        rays: &[Ray],
        (packet_rays, inner_tests): (&PacketRays, bool),
        (out, from): (&mut O, usize),
        stack: &mut [RayPacketEntry; STACK],
        ray_stack: &mut [Entry; STACK],
    ) {
        let boxes = RayPacketTester::new::<WIDTH>(packet_rays, rays.len());
        // A packet that misses every child of the root (background) needs no per-ray setup.
        let (some, _, _) = boxes.test_hull(&self.wide[0], f32::INFINITY, f32::INFINITY);
        if some == 0 {
            out.misses(from, rays.len());
            return;
        }
        // Every ray's best hit, in lanes' layout. The 4-wide path and single rays take theirs
        // into a search, made when the ray first needs one, and put it back after.
        let mut hits = PacketHits::NONE;
        let mut searches: [Option<ClosestSearch>; RAY_PACKET] = [None; RAY_PACKET];
        // Each ray's culling bound in lanes and their range over the packet, remade only when
        // a bound can change (after leaves and single rays).
        let all_rays = first_rays(rays.len());
        let (mut bound, mut range) = hits.bounds(all_rays);
        let mut depth = 0usize;
        let (mut child, mut triangle4_count) = ROOT;
        let mut active = all_rays;
        let mut lanes4 = PacketLanes::new(packet_rays);
        #[cfg(target_arch = "x86_64")]
        let (mut lanes8, mut lanes16) =
            (PacketLanes::new(packet_rays), PacketLanes::new(packet_rays));
        loop {
            if active.count_ones() <= 1 {
                for i in ray_bits(active) {
                    let single = BoxTester::new(&rays[i]);
                    let search = searches[i].get_or_insert_with(|| ClosestSearch::new(&rays[i]));
                    hits.lend(i, &mut search.best);
                    self.closest_from((child, triangle4_count), &single, search, ray_stack);
                    hits.take_back(i, &search.best);
                }
                (bound, range) = hits.bounds(all_rays);
            } else if child & LEAF == 0 {
                let node = &self.wide[child as usize];
                let (enter, entry) = if inner_tests {
                    boxes.enter_children::<false, WIDTH>(node, active, &bound, range)
                } else {
                    boxes.enter_children::<true, WIDTH>(node, active, &bound, range)
                };
                if let Some(next) = descend(node, &enter, &entry, stack, &mut depth) {
                    (child, triangle4_count, active) = next;
                    continue;
                }
            } else {
                let leaf = ((child & !LEAF) as usize, triangle4_count as usize);
                let rest = match WIDTH {
                    #[cfg(target_arch = "x86_64")]
                    8 | 16 => {
                        // At width 16, sixteen lanes where enough rays are active to pay for
                        // them ([`PacketLanes::by_groups`]); then eight where that pays.
                        let rest = if WIDTH == 16 {
                            let lanes = &mut lanes16;
                            closest_in_lanes::<F32x16>(self, lanes, leaf, active, rays, &mut hits)
                        } else {
                            active
                        };
                        let lanes = &mut lanes8;
                        closest_in_lanes::<F32x8>(self, lanes, leaf, rest, rays, &mut hits)
                    }
                    _ => {
                        let lanes = &mut lanes4;
                        closest_in_lanes::<f32x4>(self, lanes, leaf, active, rays, &mut hits)
                    }
                };
                for i in ray_bits(rest) {
                    let search = searches[i].get_or_insert_with(|| ClosestSearch::new(&rays[i]));
                    hits.lend(i, &mut search.best);
                    self.closest_in_leaf(leaf.0, leaf.1, search);
                    hits.take_back(i, &search.best);
                }
                (bound, range) = hits.bounds(all_rays);
            }
            // Pop the next child with the rays that may still find a better hit in it: a ray
            // whose bound is below the child's entry bound would fail its box test now.
            loop {
                if depth == 0 {
                    out.packet(self, from, rays.len(), &hits);
                    return;
                }
                depth -= 1;
                let e = stack[depth];
                let keep = rays_within(e.t, &bound, e.rays);
                if keep != 0 {
                    (child, triangle4_count, active) = (e.child, e.triangle4_count, keep);
                    break;
                }
            }
        }
    }
}

impl Bvh {
    /// Every ray's closest hit from a finished packet's `hits` (`out[i]` for ray i), as
    /// [`Bvh::closest_result`] gives it. Not inlined into the traversal: there its loop (one
    /// iteration a ray) kept values on the stack and was a fifth of the traversal's time on
    /// the Cornell box.
    #[inline(never)]
    pub(super) fn packet_results(&self, hits: &PacketHits, out: &mut [Option<ClosestHit>]) {
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.closest_result(&hits.get(i));
        }
    }
}

/// The leaf `(first Triangle4, count)` in lanes of `L` for the groups of `active` where that
/// pays ([`PacketLanes::by_groups`]), keeping their best hits in `hits`; returns the rays left
/// for the 4-wide path. Only on hosts with the instruction set of `L` (see
/// [`PacketLanes::by_groups`]).
#[inline(always)]
fn closest_in_lanes<L: LeafLanes>(
    bvh: &Bvh,
    packet_lanes: &mut PacketLanes<'_, L>,
    leaf: (usize, usize),
    active: u64,
    rays: &[Ray],
    hits: &mut PacketHits,
) -> u64 {
    packet_lanes.by_groups(bvh, leaf, active, |from, group, lanes| {
        // SAFETY: four lanes need nothing beyond every host's instruction set; eight and
        // sixteen are reached only from `closest_packets::<8>` and `::<16>`, which run only at
        // their kernel width, so on hosts with AVX2, and with AVX-512F too at width 16
        // (`dispatch.rs` offers `Sixteen` only where both are).
        #[allow(unsafe_code)]
        unsafe {
            L::closest_in_leaf(bvh, leaf, lanes, group, &rays[from..], (hits, from))
        };
    })
}

/// The mask of lanes `0..n` (bits below `n`; `n` at most 32).
#[inline(always)]
pub(crate) fn first_bits(n: usize) -> u32 {
    first_rays(n) as u32
}

/// The mask of a packet's rays `0..n` (bits below `n`; `n` at most [`RAY_PACKET`]).
#[inline(always)]
pub(crate) fn first_rays(n: usize) -> u64 {
    ((1u128 << n) - 1) as u64
}

/// The indices of the set bits of `mask`, lowest first.
#[inline(always)]
pub(crate) fn bits(mask: u32) -> impl Iterator<Item = usize> {
    ray_bits(u64::from(mask))
}

/// The indices of the set bits of `mask` (a packet's rays), lowest first.
#[inline(always)]
pub(crate) fn ray_bits(mut mask: u64) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let i = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            i
        })
    })
}

/// How many groups of four rays hold the rays of `rays` (up to the group of its highest bit):
/// the loops over a packet's groups stop there, so a packet of 32 in a structure of 64 pays
/// for 32.
#[inline(always)]
pub(super) fn groups_of(rays: u64) -> usize {
    (64 - rays.leading_zeros() as usize).div_ceil(4)
}

/// The rays of `rays` (bit i = ray i) whose bound (lane i % 4 of group i / 4) is at least
/// `t`; false where either is NaN, as `t <= bound` is.
#[inline(always)]
fn rays_within(t: f32, bound: &[f32x4; GROUPS], rays: u64) -> u64 {
    let t = f32x4::splat(t);
    let mut within = 0;
    for (g, bound) in bound.iter().enumerate().take(groups_of(rays)) {
        within |= u64::from(t.simd_le(*bound).to_bitmask()) << (4 * g);
    }
    within & rays
}

/// The culling bounds `t · CULL_MARGIN` of distances `t` (ray i's at `t[i]`), ray i in lane
/// i % 4 of group i / 4, for the first `groups` groups (zeros after them): the scalar product
/// lane by lane, so the same bits.
#[inline(always)]
pub(super) fn culling_bounds(t: &[f32; RAY_PACKET], groups: usize) -> [f32x4; GROUPS] {
    let margin = f32x4::splat(CULL_MARGIN);
    let mut bound = [f32x4::ZERO; GROUPS];
    for (g, bound) in bound.iter_mut().enumerate().take(groups) {
        *bound = f32x4::from(each4(|l| t[4 * g + l])) * margin;
    }
    bound
}

/// The smallest and largest bound among the `active` rays.
#[inline(always)]
pub(super) fn bound_range(bound: &[f32x4; GROUPS], active: u64) -> (f32, f32) {
    let mut lo = f32x4::splat(f32::INFINITY);
    let mut hi = f32x4::splat(f32::NEG_INFINITY);
    for (g, b) in bound.iter().enumerate().take(groups_of(active)) {
        let lanes = f32x4::lane_mask(((active >> (4 * g)) & 0xf) as u32);
        lo = (lanes & b.simd_lt(lo)).select(*b, lo);
        hi = (lanes & b.simd_gt(hi)).select(*b, hi);
    }
    (lowest(lo), -lowest(-hi))
}

/// Defers the entered children of `node` (rays per slot in `enter`, entry bounds `entry`)
/// farthest first onto `stack`, except the nearest, which it returns to visit now; `None` when
/// no ray enters any child.
#[inline(always)]
pub(super) fn descend(
    node: &Node4,
    enter: &[u64; 4],
    entry: &[f32; 4],
    stack: &mut [RayPacketEntry; STACK],
    depth: &mut usize,
) -> Option<(u32, u32, u64)> {
    let mut hit = [NO_ENTRY; 4];
    let mut n = 0;
    for slot in 0..4 {
        if enter[slot] != 0 {
            let e = RayPacketEntry {
                child: node.child[slot],
                triangle4_count: node.triangle4_count[slot],
                rays: enter[slot],
                t: entry[slot],
            };
            n = insert_farthest_first(&mut hit, n, e, |e| e.t);
        }
    }
    if n == 0 {
        return None;
    }
    let e = defer_all_but_nearest(&hit, n, stack, depth);
    Some((e.child, e.triangle4_count, e.rays))
}

#[cfg(test)]
mod lane_tests {
    use super::*;
    use crate::bvh::dispatch::available_kernel_widths;
    use crate::bvh::node4::UNUSED;
    use crate::bvh::tests::Rng;
    use glam::Vec3;

    /// No ray enters an unused slot, even one that has hit nothing yet (bound +inf): not by
    /// the single-ray test, not by the per-ray tests at any width this host has, in every
    /// octant, with zero direction components of both signs (infinite inverses). (Until
    /// 2026-12-07 the slot's box was lo = hi = +inf, which rays with no negative direction
    /// component entered at bound +inf: a Cornell box packet sent three rays on to the
    /// single-ray leaf path for nothing.)
    #[test]
    fn no_ray_enters_an_unused_slot() {
        let mut rng = Rng(11);
        let component = |rng: &mut Rng| match rng.next() % 6 {
            0 => 0.0,
            1 => -0.0,
            2 => 1e-30,
            _ => rng.unit() * 4.0 - 2.0,
        };
        for _ in 0..500 {
            let mut rays = Vec::new();
            for _ in 0..RAY_PACKET {
                let origin = [0, 1, 2].map(|_| rng.unit() * 8.0 - 4.0);
                let dir = Vec3::new(component(&mut rng), component(&mut rng), 0.5);
                // Every octant, the z component's sign too.
                let sign = [1.0, -1.0][(rng.next() % 2) as usize];
                rays.push(Ray {
                    origin: Vec3::from(origin),
                    dir: dir * sign,
                });
            }
            for bound in [f32::INFINITY, 1e30, 1.0] {
                for ray in &rays {
                    let (enter, _) = BoxTester::new(ray).test(&UNUSED, bound);
                    assert_eq!(enter, 0, "{ray:?} at bound {bound}");
                }
                let mut packet = PacketRays::EMPTY;
                assert!(packet.fill(&rays, |r| r));
                let bounds = [f32x4::splat(bound); GROUPS];
                for width in available_kernel_widths() {
                    let (len, range) = (rays.len(), (bound, bound));
                    let (enter, _) = match width {
                        KernelWidth::Four => RayPacketTester::new::<4>(&packet, len)
                            .enter_children::<false, 4>(&UNUSED, u64::MAX, &bounds, range),
                        KernelWidth::Eight => RayPacketTester::new::<8>(&packet, len)
                            .enter_children::<false, 8>(&UNUSED, u64::MAX, &bounds, range),
                        KernelWidth::Sixteen => RayPacketTester::new::<16>(&packet, len)
                            .enter_children::<false, 16>(&UNUSED, u64::MAX, &bounds, range),
                    };
                    assert_eq!(enter, [0; 4], "{width:?} at bound {bound}");
                }
            }
        }
    }

    /// `first_bits(n)` has exactly the bits below `n`, from none to all 32.
    #[test]
    fn first_bits_are_the_bits_below_n() {
        assert_eq!(first_bits(0), 0);
        assert_eq!(first_bits(1), 1);
        assert_eq!(first_bits(4), 0b1111);
        assert_eq!(first_bits(16), 0xffff);
        assert_eq!(first_bits(31), u32::MAX >> 1);
        assert_eq!(first_bits(32), u32::MAX);
    }

    /// `first_rays(n)` has exactly the bits below `n`, up to a whole packet's 64, and
    /// `groups_of` counts the groups of four up to the highest ray.
    #[test]
    fn packet_masks_count_their_rays_and_groups() {
        assert_eq!(first_rays(0), 0);
        assert_eq!(first_rays(1), 1);
        assert_eq!(first_rays(CLOSEST_PACKET), u64::from(u32::MAX));
        assert_eq!(first_rays(63), u64::MAX >> 1);
        assert_eq!(first_rays(RAY_PACKET), u64::MAX);
        assert_eq!(groups_of(0), 0);
        assert_eq!(groups_of(1), 1);
        assert_eq!(groups_of(0xf), 1);
        assert_eq!(groups_of(0x10), 2);
        assert_eq!(groups_of(1 << 33), 9);
        assert_eq!(groups_of(u64::MAX), GROUPS);
        assert_eq!(
            ray_bits(1 << 63 | 1 << 40 | 2).collect::<Vec<_>>(),
            [1, 40, 63]
        );
    }

    /// `lowest` is the least lane wherever it sits, infinities included, and
    /// `bound_range` the least and largest of the active lanes only.
    #[test]
    fn lowest_and_bound_range_pick_the_right_lanes() {
        let values = [3.0f32, -1.5, f32::INFINITY, f32::NEG_INFINITY, 0.25, 7.0];
        for a in values {
            for b in values {
                for c in values {
                    for d in values {
                        let expected = a.min(b).min(c.min(d));
                        let x = f32x4::from([a, b, c, d]);
                        assert_eq!(lowest(x), expected, "{a} {b} {c} {d}");
                    }
                }
            }
        }
        let mut bound = [f32x4::from([0.125, 20.0, 0.0625, 30.0]); GROUPS];
        bound[..4].copy_from_slice(&[
            f32x4::from([5.0, 1.0, 9.0, 2.0]),
            f32x4::from([0.5, 8.0, 3.0, 4.0]),
            f32x4::from([6.0, 7.0, 0.25, 11.0]),
            f32x4::from([2.5, 3.5, 4.5, 5.5]),
        ]);
        assert_eq!(bound_range(&bound, 0xffff), (0.25, 11.0));
        // Rays 0, 2 and 13 only: 5, 9 and 3.5.
        assert_eq!(bound_range(&bound, 1 | 1 << 2 | 1 << 13), (3.5, 9.0));
        // And the rays past sixteen.
        assert_eq!(bound_range(&bound, u64::MAX), (0.0625, 30.0));
    }
}
