//! The 4-wide nodes' child boxes, derived from the triangles: a leaf's box is the smallest box
//! holding its packs' triangles, an inner child's the smallest holding its node's children.
//!
//! Both [`Bvh::build`](super::Bvh::build) and the loader of stored BVHs
//! ([`PartsLoader`](super::PartsLoader)) set every box this way, with the same operations in the
//! same order over the same corner bits, so a loaded BVH has exactly the boxes of the one that
//! was stored, and split objects need not store them (they were three quarters of the node
//! bytes). The values are those of the binary tree's boxes the wide nodes regroup (min and max
//! are exact); only which zero a box bound holds where -0 and +0 tie could differ from them,
//! which no culling decision can see.

use super::Aabb;
use super::node4::{LEAF, Node4, Triangle4};
use wide::f32x4;

/// The smallest box holding pack `pack`'s triangles (its `lanes` lanes): per axis, the least
/// and the greatest of its corners' coordinates, four lanes at once. Taken with comparisons and
/// selects in a fixed order (corners 0, 1, 2 in each lane, then lanes 0 to 3; a value replaces
/// the one so far only if strictly less, or greater), so the bits are the same on every
/// machine, whichever zero wins a tie between -0 and +0; a NaN coordinate is passed over.
#[inline]
pub(super) fn pack_box(pack: &Triangle4) -> Aabb {
    let used = f32x4::from([0.0, 1.0, 2.0, 3.0]).simd_lt(f32x4::splat(pack.lanes as f32));
    let (inf, neg_inf) = (f32x4::splat(f32::INFINITY), f32x4::splat(f32::NEG_INFINITY));
    let mut lo = [0.0; 3];
    let mut hi = [0.0; 3];
    for axis in 0..3 {
        let (mut least, mut greatest) = (inf, neg_inf);
        for corner in &pack.v {
            let x = f32x4::from(corner[axis]);
            least = x.simd_lt(least).select(x, least);
            greatest = x.simd_gt(greatest).select(x, greatest);
        }
        let least = used.select(least, inf).to_array();
        let greatest = used.select(greatest, neg_inf).to_array();
        lo[axis] = least
            .into_iter()
            .fold(f32::INFINITY, |m, x| if x < m { x } else { m });
        hi[axis] = greatest
            .into_iter()
            .fold(f32::NEG_INFINITY, |m, x| if x > m { x } else { m });
    }
    Aabb {
        lo: glam::Vec3::from_array(lo),
        hi: glam::Vec3::from_array(hi),
    }
}

/// Sets every child box of `wide` from `pack_boxes` (one per pack, [`pack_box`]'s): a leaf
/// slot gets the union of its packs' boxes, an inner slot the union of its node's non-empty
/// slots, an empty slot the box no ray enters (lo = +inf, hi = -inf; `Node4` says why).
/// `wide` must be laid out as [`Bvh::from_parts`](super::Bvh::from_parts) checks (children
/// after their parent, leaves inside `pack_boxes`): nodes are set from the last to the first,
/// so every child is set before its parent reads it. Cost: one pass over the nodes and one
/// over the pack boxes.
pub(super) fn refit(wide: &mut [Node4], pack_boxes: &[Aabb]) {
    for index in (0..wide.len()).rev() {
        let node = wide[index];
        let mut lo = [[f32::INFINITY; 4]; 3];
        let mut hi = [[f32::NEG_INFINITY; 4]; 3];
        for slot in 0..4 {
            let (child, count) = (node.child[slot], node.triangle4_count[slot] as usize);
            let bounds = if is_empty(child, count) {
                continue;
            } else if child & LEAF != 0 {
                let first = (child & !LEAF) as usize;
                pack_boxes
                    .get(first..first + count)
                    .unwrap_or_default()
                    .iter()
                    .fold(Aabb::EMPTY, |b, &p| b.union(p))
            } else {
                wide.get(child as usize).map_or(Aabb::EMPTY, union_of_slots)
            };
            for axis in 0..3 {
                lo[axis][slot] = bounds.lo[axis];
                hi[axis][slot] = bounds.hi[axis];
            }
        }
        wide[index].lo = lo;
        wide[index].hi = hi;
    }
}

/// Whether a slot with child word `child` and `count` packs is empty (a leaf of no packs).
fn is_empty(child: u32, count: usize) -> bool {
    child & LEAF != 0 && count == 0
}

/// The union of `node`'s non-empty slots' boxes, in slot order.
fn union_of_slots(node: &Node4) -> Aabb {
    (0..4)
        .filter(|&s| !is_empty(node.child[s], node.triangle4_count[s] as usize))
        .fold(Aabb::EMPTY, |b, s| {
            b.union(Aabb {
                lo: glam::Vec3::new(node.lo[0][s], node.lo[1][s], node.lo[2][s]),
                hi: glam::Vec3::new(node.hi[0][s], node.hi[1][s], node.hi[2][s]),
            })
        })
}
