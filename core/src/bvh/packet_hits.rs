//! The best hit of every ray of a closest-hit packet (`ray_packet.rs`), kept for the packet's
//! whole traversal in the layout lanes read and write directly: one array per field, ray i at
//! index i. The leaf tests in lanes (`leaf_lanes.rs`) load a group's hits with one vector load
//! per field and store them back the same way; the culling bounds are one vector product per
//! four rays. Rays that go 4-wide or on alone lend their [`BestHit`] to a
//! [`super::traverse::ClosestSearch`] and take it back after, so every path offers hits to the
//! same best hit by the same rule.

use super::ray_packet::{GROUPS, RAY_PACKET, bound_range, culling_bounds, groups_of};
use super::traverse::BestHit;
use wide::f32x4;

/// Each ray's [`BestHit`], field by field (ray i at index i; rays past the packet's end keep
/// [`BestHit::NONE`]).
#[derive(Clone, Copy)]
#[repr(C, align(64))]
pub(super) struct PacketHits {
    pub t: [f32; RAY_PACKET],
    pub b: [[f32; RAY_PACKET]; 3],
    pub id: [u32; RAY_PACKET],
    pub place: [u32; RAY_PACKET],
}

impl PacketHits {
    /// No ray has a hit yet.
    pub const NONE: PacketHits = PacketHits {
        t: [BestHit::NONE.t; RAY_PACKET],
        b: [[0.0; RAY_PACKET]; 3],
        id: [BestHit::NONE.id; RAY_PACKET],
        place: [BestHit::NONE.place; RAY_PACKET],
    };

    /// Ray `i`'s best hit.
    #[inline(always)]
    pub fn get(&self, i: usize) -> BestHit {
        BestHit {
            t: self.t[i],
            b: [self.b[0][i], self.b[1][i], self.b[2][i]],
            id: self.id[i],
            place: self.place[i],
        }
    }

    /// Sets ray `i`'s best hit.
    #[inline(always)]
    pub fn set(&mut self, i: usize, h: BestHit) {
        self.t[i] = h.t;
        for c in 0..3 {
            self.b[c][i] = h.b[c];
        }
        self.id[i] = h.id;
        self.place[i] = h.place;
    }

    /// Hands ray `i`'s best hit to `best`, a search's (the 4-wide leaf test and the single-ray
    /// traversal run on searches): only its distance and id, all that offering a hit compares
    /// with. [`Self::take_back`] after the search.
    #[inline(always)]
    pub fn lend(&self, i: usize, best: &mut BestHit) {
        (best.t, best.id) = (self.t[i], self.id[i]);
    }

    /// Keeps `best`, ray `i`'s search's best hit after [`Self::lend`], when the search found a
    /// better hit than the one lent (which then holds every field). Fewer moves than a whole
    /// copy each way, on the 4-wide path, where every leaf goes through a search.
    #[inline(always)]
    pub fn take_back(&mut self, i: usize, best: &BestHit) {
        // Distances are never NaN (+inf or a hit's finite t), so `!=` sees every change.
        if best.t != self.t[i] || best.id != self.id[i] {
            self.set(i, *best);
        }
    }

    /// Each ray's culling bound ([`BestHit::bound`]), ray i in lane i % 4 of group i / 4, and
    /// the smallest and largest bound among the rays of `rays`: what the hull test and the pop
    /// filter read.
    #[inline(always)]
    pub fn bounds(&self, rays: u64) -> ([f32x4; GROUPS], (f32, f32)) {
        let bound = culling_bounds(&self.t, groups_of(rays));
        let range = bound_range(&bound, rays);
        (bound, range)
    }
}
