//! The closest hits of a batch of rays field by field ([`HitColumns`]), as the closest-hit
//! packets keep them (`packet_hits.rs`): a finished packet's hits are copied column by column,
//! and the shading reads a run of hits' barycentrics with one vector load per corner. Where
//! [`Bvh::closest_hits_in_packets`] writes an `Option<ClosestHit>` per ray, eight scalar stores
//! (and the shading's eight scalar loads back), [`Bvh::closest_hits_in_columns`] writes a
//! packet's answers as six copies and looks up each hit's leaf-order index.
//!
//! Guarantee: [`Bvh::hit_in`] gives, for every ray, exactly the `Option<ClosestHit>`
//! [`Bvh::closest_hits_in_packets`] gives it, at every packet length and kernel width.

use super::packet_hits::PacketHits;
use super::packet_rays::copy_in_blocks;
use super::ray_packet::RAY_PACKET;
use super::traverse::BestHit;
use super::{Bvh, ClosestHit};

/// The closest hit of each ray of a batch (ray i at index i), field by field: its distance
/// (`+inf` for a miss), barycentrics, scene-wide triangle id, place in the BVH and leaf-order
/// index (read whole through [`Bvh::hit_in`]).
#[derive(Clone, Debug, Default)]
pub struct HitColumns {
    t: Vec<f32>,
    b: [Vec<f32>; 3],
    id: Vec<u32>,
    place: Vec<u32>,
    index: Vec<u32>,
}

impl HitColumns {
    /// How many rays' hits it holds.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Holds no ray's hit.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Holds `len` rays' hits: misses past the old length.
    pub fn resize(&mut self, len: usize) {
        let none = BestHit::NONE;
        self.t.resize(len, none.t);
        self.b.iter_mut().for_each(|b| b.resize(len, 0.0));
        self.id.resize(len, none.id);
        self.place.resize(len, none.place);
        self.index.resize(len, 0);
    }

    /// The hits of `hits`, in order (what [`Bvh::closest_hits_in_columns`] writes for rays
    /// whose closest hits they are).
    pub fn from_hits(hits: &[Option<ClosestHit>]) -> Self {
        let mut columns = HitColumns::default();
        columns.resize(hits.len());
        for (i, hit) in hits.iter().enumerate() {
            columns.set(i, hit.as_ref());
        }
        columns
    }

    /// Whether ray `i` hit something. Panics unless `i < len`.
    #[inline(always)]
    pub fn is_hit(&self, i: usize) -> bool {
        // Hits have finite t: +inf means none was found.
        self.t[i] < f32::INFINITY
    }

    /// Each ray's hit distance, `+inf` for a miss.
    #[inline(always)]
    pub fn t(&self) -> &[f32] {
        &self.t
    }

    /// Each ray's barycentric weight of corner `c` (unspecified for a miss).
    #[inline(always)]
    pub fn b(&self, c: usize) -> &[f32] {
        &self.b[c]
    }

    /// Each ray's scene-wide triangle id (`u32::MAX` for a miss).
    #[inline(always)]
    pub fn id(&self) -> &[u32] {
        &self.id
    }

    /// Each ray's triangle's place in the BVH (unspecified for a miss): two hits are on one
    /// triangle exactly when their places are equal.
    #[inline(always)]
    pub fn place(&self) -> &[u32] {
        &self.place
    }

    /// Ray `i`'s hit is `hit`.
    #[inline(always)]
    fn set(&mut self, i: usize, hit: Option<&ClosestHit>) {
        let best = hit.map_or(BestHit::NONE, |h| BestHit {
            t: h.t,
            b: h.b,
            id: h.id,
            place: h.place,
        });
        self.t[i] = best.t;
        for c in 0..3 {
            self.b[c][i] = best.b[c];
        }
        self.id[i] = best.id;
        self.place[i] = best.place;
        self.index[i] = hit.map_or(0, |h| h.index);
    }

    /// Rays `from..from + len` hit nothing.
    #[inline(always)]
    fn set_misses(&mut self, from: usize, len: usize) {
        self.t[from..from + len].fill(f32::INFINITY);
        self.id[from..from + len].fill(u32::MAX);
    }

    /// Rays `from..from + len` (a packet's, `len` at most [`RAY_PACKET`]) have the packet's
    /// hits `hits` (ray `from + i` in place i), found by `bvh`.
    #[inline(always)]
    fn set_packet(&mut self, bvh: &Bvh, from: usize, len: usize, hits: &PacketHits) {
        copy_prefix(&mut self.t[from..], &hits.t, len);
        for c in 0..3 {
            copy_prefix(&mut self.b[c][from..], &hits.b[c], len);
        }
        copy_prefix(&mut self.id[from..], &hits.id, len);
        copy_prefix(&mut self.place[from..], &hits.place, len);
        // The leaf-order indices now, while the hits' `Triangle4`s are in the cache (the
        // traversal has just tested them): shading reads them for hits on many triangles,
        // where a big mesh's `Triangle4`s are cache misses by then. A miss's place is some
        // `Triangle4`'s too, so every place is looked up.
        for (index, &place) in self.index[from..from + len].iter_mut().zip(&hits.place) {
            *index = bvh.leaf_index(place);
        }
    }
}

/// Copies `src[..len]` to `to[..len]`, in blocks ([`copy_in_blocks`]).
#[inline(always)]
fn copy_prefix<T: Copy>(to: &mut [T], src: &[T; RAY_PACKET], len: usize) {
    copy_in_blocks(&mut to[..len], &src[..len]);
}

/// Where a closest-hit traversal puts its answers: an `Option<ClosestHit>` per ray, or
/// [`HitColumns`]. Rays are numbered from the batch's first.
pub(super) trait ClosestOut {
    /// Rays `from..from + len` hit nothing.
    fn misses(&mut self, from: usize, len: usize);
    /// Rays `from..from + len` (a packet's) have the packet's hits `hits`.
    fn packet(&mut self, bvh: &Bvh, from: usize, len: usize, hits: &PacketHits);
    /// Ray `i` has `hit`.
    fn one(&mut self, i: usize, hit: Option<ClosestHit>);
}

impl ClosestOut for [Option<ClosestHit>] {
    #[inline(always)]
    fn misses(&mut self, from: usize, len: usize) {
        self[from..from + len].fill(None);
    }

    #[inline(always)]
    fn packet(&mut self, bvh: &Bvh, from: usize, len: usize, hits: &PacketHits) {
        bvh.packet_results(hits, &mut self[from..from + len]);
    }

    #[inline(always)]
    fn one(&mut self, i: usize, hit: Option<ClosestHit>) {
        self[i] = hit;
    }
}

impl ClosestOut for HitColumns {
    #[inline(always)]
    fn misses(&mut self, from: usize, len: usize) {
        self.set_misses(from, len);
    }

    #[inline(always)]
    fn packet(&mut self, bvh: &Bvh, from: usize, len: usize, hits: &PacketHits) {
        self.set_packet(bvh, from, len, hits);
    }

    #[inline(always)]
    fn one(&mut self, i: usize, hit: Option<ClosestHit>) {
        self.set(i, hit.as_ref());
    }
}

impl Bvh {
    /// Ray `i`'s closest hit in `hits` (written by this BVH's
    /// [`Bvh::closest_hits_in_columns`]), as [`Bvh::closest_hits_in_packets`] gives it.
    /// Panics unless `i < hits.len()`.
    #[inline(always)]
    pub fn hit_in(&self, hits: &HitColumns, i: usize) -> Option<ClosestHit> {
        // Hits have finite t: +inf means none was found.
        hits.is_hit(i).then(|| ClosestHit {
            id: hits.id[i],
            t: hits.t[i],
            b: [hits.b[0][i], hits.b[1][i], hits.b[2][i]],
            index: hits.index[i],
            place: hits.place[i],
        })
    }
}
