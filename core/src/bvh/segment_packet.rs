//! Segment packets: up to [`RAY_PACKET`] shadow segments `(ray, t_max)` (the shadow rays of
//! neighbouring samples towards one light) traverse the 4-wide BVH together for any-hit
//! ([`Bvh::occluded_many`]), with the interval hull and per-ray tests of
//! `RayPacketTester` (`ray_packet.rs`) spanning origins as well as directions. Leaves run
//! the single-ray any-hit test per ray (or 4, 8 or 16 rays per test, `leaf_lanes.rs`), and a
//! blocked ray leaves its packet.
//!
//! Guarantee: every segment gets exactly [`Bvh::occluded`]'s answer: the root test is
//! `occluded`'s own (in lanes: its operations lane by lane), every box test either is the
//! single-ray slab test or can only claim what it would claim, and every triangle test is the
//! single-ray leaf test or decides as it does (`leaf_lanes.rs`).

use super::Bvh;
use super::dispatch::{KernelWidth, kernel_width};
#[cfg(target_arch = "x86_64")]
use super::lanes::{F32x8, F32x16};
use super::leaf_lanes::{LeafLanes, PacketLanes};
use super::node4::LEAF;
use super::packet_rays::PacketRays;
use super::ray_packet::{
    RAY_PACKET, RAY_PACKET_STACKS, RayPacketEntry, RayPacketTester, bound_range, culling_bounds,
    descend, first_rays, groups_of, ray_bits,
};
use super::segment_columns::SegmentColumns;
use super::simd4::BoxTester;
use super::traverse::{Entry, ROOT, STACK, STACKS, ShadowSearch, segment_may_hit};
use crate::triangle::Ray;
use std::ops::Range;
use wide::f32x4;

impl Bvh {
    /// For every shadow segment `(ray, t_max)`, whether [`Bvh::occluded`] says it is blocked
    /// (`out[i]` for `rays[i]`), traced in packets of [`RAY_PACKET`] consecutive segments: faster
    /// when neighbours are coherent (the shadow rays of neighbouring pixels towards one light).
    /// Panics if the lengths differ.
    pub fn occluded_many(&self, rays: &[(Ray, f32)], out: &mut [bool]) {
        assert_eq!(rays.len(), out.len(), "one output per ray");
        self.each_segment_packet(out, |range, packet_rays, t_max| {
            let segments = &rays[range];
            *t_max = [0.0; RAY_PACKET];
            for (t, (_, segment_t_max)) in t_max.iter_mut().zip(segments) {
                *t = *segment_t_max;
            }
            packet_rays.fill(segments, |(ray, _)| ray)
        });
    }

    /// [`Bvh::occluded_many`] of segments kept column by column (`out[i]` for segment `i`):
    /// the same answers, the same packets. Panics if the lengths differ.
    pub fn occluded_columns(&self, segments: &SegmentColumns, out: &mut [bool]) {
        assert_eq!(segments.len(), out.len(), "one output per segment");
        self.each_segment_packet(out, |range, packet_rays, t_max| {
            segments.fill(range, packet_rays, t_max)
        });
    }

    /// Traces the segments of `out` (one place each) in packets of [`RAY_PACKET`] consecutive
    /// ones: `fill(range, rays, t_max)` puts segments `range` into a packet's rays and their
    /// `t_max` (0 past the last) and says whether every origin and direction is finite.
    #[inline(always)]
    fn each_segment_packet(
        &self,
        out: &mut [bool],
        fill: impl FnMut(Range<usize>, &mut PacketRays, &mut [f32; RAY_PACKET]) -> bool,
    ) {
        if self.wide.is_empty() {
            out.fill(false);
            return;
        }
        // Packets at every width, small trees included: with leaves in lanes they pay there too
        // (cornell, 36 triangles, at width 4: whole renders 0.97x of tracing ray by ray, which
        // was faster while width 4 tested every ray on its own at the leaves).
        RAY_PACKET_STACKS.with_borrow_mut(|stack| {
            STACKS.with_borrow_mut(|ray_stack| match kernel_width() {
                KernelWidth::Sixteen => self.segment_packets::<16>(out, fill, stack, ray_stack),
                KernelWidth::Eight => self.segment_packets::<8>(out, fill, stack, ray_stack),
                KernelWidth::Four => self.segment_packets::<4>(out, fill, stack, ray_stack),
            })
        });
    }

    /// [`Bvh::each_segment_packet`] over a non-empty BVH, packet by packet, with leaves tested
    /// `WIDTH` rays at a time where that pays (4 anywhere; 8 or 16 only at that kernel width),
    /// else ray by ray; see `closest_packets`.
    #[inline(always)]
    fn segment_packets<const WIDTH: usize>(
        &self,
        out: &mut [bool],
        mut fill: impl FnMut(Range<usize>, &mut PacketRays, &mut [f32; RAY_PACKET]) -> bool,
        stack: &mut [RayPacketEntry; STACK],
        ray_stack: &mut [Entry; STACK],
    ) {
        let mut packet_rays = PacketRays::EMPTY;
        let mut t_max = [0.0f32; RAY_PACKET];
        for (k, out) in out.chunks_mut(RAY_PACKET).enumerate() {
            let from = k * RAY_PACKET;
            let finite = fill(from..from + out.len(), &mut packet_rays, &mut t_max);
            let packet = (&packet_rays, &t_max, finite);
            self.trace_segment_packet::<WIDTH>(packet, out, stack, ray_stack);
        }
    }

    /// [`Bvh::occluded_many`] of one packet of 1..=[`RAY_PACKET`] segments (`out.len()`): their
    /// rays, their `t_max` (0 past the last) and whether every origin and direction is finite.
    #[inline(always)]
    fn trace_segment_packet<const WIDTH: usize>(
        &self,
        (packet_rays, t_max, finite): (&PacketRays, &[f32; RAY_PACKET], bool),
        out: &mut [bool],
        stack: &mut [RayPacketEntry; STACK],
        ray_stack: &mut [Entry; STACK],
    ) {
        let root = self.bounds();
        let len = out.len();
        out.fill(false);
        if !finite || t_max[..len].iter().any(|t| t.is_nan()) {
            // Ray by ray, behind `occluded`'s root test.
            for (i, out) in out.iter_mut().enumerate() {
                let (ray, t_max) = (packet_rays.ray(i), t_max[i]);
                if segment_may_hit(&root, &ray, t_max) {
                    *out = self.occluded_with(&ray, t_max, ray_stack);
                }
            }
            return;
        }
        let boxes = RayPacketTester::new::<WIDTH>(packet_rays, len);
        let all_rays = first_rays(len);
        // Each segment's t_max is in lanes' layout (0 past the packet's end: never active).
        let bound = culling_bounds(t_max, groups_of(all_rays));
        // Rays still to trace: `occluded`'s root test (`segment_may_hit`) in lanes, with the
        // tester's inverse directions (the same bits) where that test divides again per ray.
        let (lo, hi) = (root.lo.to_array(), root.hi.to_array());
        let (mut active, _) = boxes.rays_in_box::<WIDTH>(lo, hi, all_rays, &bound);
        if active == 0 {
            return;
        }
        let mut searches: [Option<ShadowSearch>; RAY_PACKET] = [None; RAY_PACKET];
        // Bounds never change, so their range over the packet holds for any active rays.
        let range = bound_range(&bound, active);
        let mut blocked = 0u64;
        let mut depth = 0usize;
        let (mut child, mut triangle4_count) = ROOT;
        let mut lanes4 = PacketLanes::new(packet_rays);
        #[cfg(target_arch = "x86_64")]
        let (mut lanes8, mut lanes16) =
            (PacketLanes::new(packet_rays), PacketLanes::new(packet_rays));
        loop {
            if active.count_ones() <= 1 {
                for i in ray_bits(active) {
                    let ray = packet_rays.ray(i);
                    let s = searches[i].get_or_insert_with(|| ShadowSearch::new(&ray, t_max[i]));
                    let single = BoxTester::new(&ray);
                    let start = (child, triangle4_count);
                    if self.occluded_from(start, &single, &s.prep, &s.tris, s.t_max, ray_stack) {
                        blocked |= 1 << i;
                    }
                }
            } else if child & LEAF == 0 {
                let node = &self.wide[child as usize];
                // Every child tested ray by ray: a shadow packet's segments start at
                // different points, and testing inner children only at the hull was 2% slower
                // on the bunny and took the shadow phase of a 1M mesh from 30 to 55 ns a sample.
                let (enter, entry) =
                    boxes.enter_children::<false, WIDTH>(node, active, &bound, range);
                if let Some(next) = descend(node, &enter, &entry, stack, &mut depth) {
                    (child, triangle4_count, active) = next;
                    continue;
                }
            } else {
                let leaf = ((child & !LEAF) as usize, triangle4_count as usize);
                let active = match WIDTH {
                    #[cfg(target_arch = "x86_64")]
                    8 | 16 => {
                        // At width 16, sixteen lanes where enough rays are active to pay for
                        // them ([`PacketLanes::by_groups`]); then eight where that pays.
                        let blocked = &mut blocked;
                        let rest = if WIDTH == 16 {
                            let lanes = &mut lanes16;
                            occluded_in_lanes::<F32x16>(self, lanes, leaf, active, t_max, blocked)
                        } else {
                            active
                        };
                        let lanes = &mut lanes8;
                        occluded_in_lanes::<F32x8>(self, lanes, leaf, rest, t_max, blocked)
                    }
                    _ => {
                        let lanes = &mut lanes4;
                        occluded_in_lanes::<f32x4>(self, lanes, leaf, active, t_max, &mut blocked)
                    }
                };
                for i in ray_bits(active) {
                    let s = searches[i]
                        .get_or_insert_with(|| ShadowSearch::new(&packet_rays.ray(i), t_max[i]));
                    if self.occluded_in_leaf(leaf.0, leaf.1, &s.prep, &s.tris, s.t_max) {
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
                    (child, triangle4_count, active) = (e.child, e.triangle4_count, keep);
                    break;
                }
            }
        }
    }
}

/// The leaf `(first Triangle4, count)` in lanes of `L` for the groups of `active` where that
/// pays ([`PacketLanes::by_groups`]), adding the segments it blocks to `blocked`; returns the
/// rays left for the 4-wide path. Only on hosts with the instruction set of `L` (see
/// [`PacketLanes::by_groups`]).
#[inline(always)]
fn occluded_in_lanes<L: LeafLanes>(
    bvh: &Bvh,
    packet_lanes: &mut PacketLanes<'_, L>,
    leaf: (usize, usize),
    active: u64,
    t_max: &[f32; RAY_PACKET],
    blocked: &mut u64,
) -> u64 {
    let rays = packet_lanes.rays();
    packet_lanes.by_groups(bvh, leaf, active, |from, group, lanes| {
        // SAFETY: four lanes need nothing beyond every host's instruction set; eight and
        // sixteen are reached only from `segment_packets::<8>` and `::<16>`, which run only at
        // their kernel width, so on hosts with AVX2, and with AVX-512F too at width 16
        // (`dispatch.rs` offers `Sixteen` only where both are).
        #[allow(unsafe_code)]
        let hit = unsafe { L::occluded_in_leaf(bvh, leaf, lanes, group, rays, (t_max, from)) };
        *blocked |= u64::from(hit) << from;
    })
}
