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
    RAY_PACKET, RAY_PACKET_STACKS, RayPacketEntry, RayPacketTester, bits, bound_range,
    culling_bounds, descend,
};
use super::simd4::BoxTester;
use super::traverse::{Entry, ROOT, STACK, STACKS, ShadowSearch, segment_may_hit};
use crate::triangle::Ray;
use wide::f32x4;

impl Bvh {
    /// For every shadow segment `(ray, t_max)`, whether [`Bvh::occluded`] says it is blocked
    /// (`out[i]` for `rays[i]`), traced in packets of [`RAY_PACKET`] consecutive segments: faster
    /// when neighbours are coherent (the shadow rays of neighbouring pixels towards one light).
    /// Panics if the lengths differ.
    pub fn occluded_many(&self, rays: &[(Ray, f32)], out: &mut [bool]) {
        assert_eq!(rays.len(), out.len(), "one output per ray");
        if self.wide.is_empty() {
            out.fill(false);
            return;
        }
        // Packets at every width, small trees included: with leaves in lanes they pay there too
        // (cornell, 36 triangles, at width 4: whole renders 0.97x of tracing ray by ray, which
        // was faster while width 4 tested every ray on its own at the leaves).
        RAY_PACKET_STACKS.with_borrow_mut(|stack| {
            STACKS.with_borrow_mut(|ray_stack| match kernel_width() {
                KernelWidth::Sixteen => self.segment_packets::<16>(rays, out, stack, ray_stack),
                KernelWidth::Eight => self.segment_packets::<8>(rays, out, stack, ray_stack),
                KernelWidth::Four => self.segment_packets::<4>(rays, out, stack, ray_stack),
            })
        });
    }

    /// [`Bvh::occluded_many`] over a non-empty BVH, packet by packet, with leaves tested
    /// `WIDTH` rays at a time where that pays (4 anywhere; 8 or 16 only at that kernel width),
    /// else ray by ray; see `closest_packets`.
    #[inline(always)]
    fn segment_packets<const WIDTH: usize>(
        &self,
        rays: &[(Ray, f32)],
        out: &mut [bool],
        stack: &mut [RayPacketEntry; STACK],
        ray_stack: &mut [Entry; STACK],
    ) {
        let mut packet_rays = PacketRays::EMPTY;
        for (rays, out) in rays.chunks(RAY_PACKET).zip(out.chunks_mut(RAY_PACKET)) {
            self.trace_segment_packet::<WIDTH>(rays, &mut packet_rays, out, stack, ray_stack);
        }
    }

    /// [`Bvh::occluded_many`] of one packet of 1..=[`RAY_PACKET`] segments.
    #[inline(always)]
    fn trace_segment_packet<const WIDTH: usize>(
        &self,
        segments: &[(Ray, f32)],
        packet_rays: &mut PacketRays,
        out: &mut [bool],
        stack: &mut [RayPacketEntry; STACK],
        ray_stack: &mut [Entry; STACK],
    ) {
        let root = self.bounds();
        out.fill(false);
        let finite = packet_rays.fill(segments, |(ray, _)| ray);
        if !finite || segments.iter().any(|(_, t_max)| t_max.is_nan()) {
            // Ray by ray, behind `occluded`'s root test.
            for (i, (ray, t_max)) in segments.iter().enumerate() {
                if segment_may_hit(&root, ray, *t_max) {
                    out[i] = self.occluded_with(ray, *t_max, ray_stack);
                }
            }
            return;
        }
        let boxes = RayPacketTester::new(packet_rays);
        // Each segment's t_max, in lanes' layout (0 past the packet's end: never active).
        let mut t_max = [0.0f32; RAY_PACKET];
        for (t, (_, segment_t_max)) in t_max.iter_mut().zip(segments) {
            *t = *segment_t_max;
        }
        let bound = culling_bounds(&t_max);
        // Rays still to trace: `occluded`'s root test (`segment_may_hit`) in lanes, with the
        // tester's inverse directions (the same bits) where that test divides again per ray.
        let all_rays = (1u32 << segments.len()) - 1;
        let (lo, hi) = (root.lo.to_array(), root.hi.to_array());
        let (mut active, _) = boxes.rays_in_box(lo, hi, all_rays, &bound);
        if active == 0 {
            return;
        }
        let mut searches: [Option<ShadowSearch>; RAY_PACKET] = [None; RAY_PACKET];
        // Bounds never change, so their range over the packet holds for any active rays.
        let range = bound_range(&bound, active);
        let mut blocked = 0u32;
        let mut depth = 0usize;
        let (mut child, mut triangle4_count) = ROOT;
        let mut lanes4 = PacketLanes::new(packet_rays);
        #[cfg(target_arch = "x86_64")]
        let (mut lanes8, mut lanes16) =
            (PacketLanes::new(packet_rays), PacketLanes::new(packet_rays));
        loop {
            if active.count_ones() <= 1 {
                for i in bits(active) {
                    let (ray, t_max) = &segments[i];
                    let s = searches[i].get_or_insert_with(|| ShadowSearch::new(ray, *t_max));
                    let single = BoxTester::new(ray);
                    let start = (child, triangle4_count);
                    if self.occluded_from(start, &single, &s.prep, &s.tris, s.t_max, ray_stack) {
                        blocked |= 1 << i;
                    }
                }
            } else if child & LEAF == 0 {
                let node = &self.wide[child as usize];
                let (enter, entry) = boxes.enter_children(node, active, &bound, range);
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
                        let (segments, blocked) = (segments, &mut blocked);
                        let rest = if WIDTH == 16 {
                            let lanes = &mut lanes16;
                            occluded_in_lanes::<F32x16>(
                                self, lanes, leaf, active, segments, &t_max, blocked,
                            )
                        } else {
                            active
                        };
                        let lanes = &mut lanes8;
                        occluded_in_lanes::<F32x8>(
                            self, lanes, leaf, rest, segments, &t_max, blocked,
                        )
                    }
                    _ => {
                        let lanes = &mut lanes4;
                        occluded_in_lanes::<f32x4>(
                            self,
                            lanes,
                            leaf,
                            active,
                            segments,
                            &t_max,
                            &mut blocked,
                        )
                    }
                };
                for i in bits(active) {
                    let (ray, t_max) = &segments[i];
                    let s = searches[i].get_or_insert_with(|| ShadowSearch::new(ray, *t_max));
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
    active: u32,
    segments: &[(Ray, f32)],
    t_max: &[f32; RAY_PACKET],
    blocked: &mut u32,
) -> u32 {
    let len = segments.len();
    packet_lanes.by_groups(bvh, leaf, active, |from, group, lanes| {
        let group_segments = &segments[from..len.min(from + L::LANES)];
        // SAFETY: four lanes need nothing beyond every host's instruction set; eight and
        // sixteen are reached only from `segment_packets::<8>` and `::<16>`, which run only at
        // their kernel width, so on hosts with AVX2, and with AVX-512F too at width 16
        // (`dispatch.rs` offers `Sixteen` only where both are).
        #[allow(unsafe_code)]
        let hit =
            unsafe { L::occluded_in_leaf(bvh, leaf, lanes, group, group_segments, (t_max, from)) };
        *blocked |= hit << from;
    })
}
