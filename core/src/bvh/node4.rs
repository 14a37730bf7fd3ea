//! The traversal form of a BVH: the binary tree collapsed into 4-wide nodes whose child boxes
//! are tested together, and leaves as runs of [`Triangle4`]s (up to 4 triangles each, stored
//! axis by axis).
//!
//! [`Bvh::build`](super::Bvh::build) derives it from the binary nodes and the leaf-order
//! triangles (a pure function of them) and keeps only it; split objects store its structure
//! and [`Bvh::from_parts`](super::Bvh::from_parts) loads it back after checking it. Both set
//! the boxes from the packs (`refit.rs`), which gives the values of the binary tree's boxes
//! the wide nodes regroup, so every box the traversal tests is (in value) a box of the binary
//! tree. The `Triangle4`s are the only copy of the triangles a
//! `Bvh` keeps: every leaf-order triangle is one lane of one `Triangle4`.

use super::{Aabb, Node};
use glam::Vec3;

/// Child word flag: the child is a leaf (the low bits are its first `Triangle4`).
pub(super) const LEAF: u32 = 1 << 31;

/// Four child boxes (axis by axis, child by child) and what each child is. An unused slot has
/// the box lo = +inf, hi = -inf, which no ray with a finite origin enters, whatever its bound:
/// on every axis its entry distance is +inf and its exit -inf (the near plane is +inf or -inf
/// as the direction is positive or negative, zeros of both signs included). It is an empty
/// leaf.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub(super) struct Node4 {
    pub lo: [[f32; 4]; 3],
    pub hi: [[f32; 4]; 3],
    /// Inner child: its index in the node array. Leaf: `LEAF | first Triangle4`.
    pub child: [u32; 4],
    /// Leaf: its number of `Triangle4`s, from the first one in `child` on (0 for an unused
    /// slot). Inner: 0.
    pub triangle4_count: [u32; 4],
}

/// Up to four triangles of one leaf, laid out for the 4-wide triangle tests (not a ray packet):
/// `v[corner][axis][lane]`. Lane `i < lanes` is the leaf-order triangle `first + i`; unused
/// lanes are zero (degenerate) and masked out anyway. The packs are in leaf order: a pack's
/// `first` is the number of triangles in the packs before it.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(16))]
pub(super) struct Triangle4 {
    pub v: [[[f32; 4]; 3]; 3],
    pub first: u32,
    pub lanes: u32,
}

impl Triangle4 {
    /// Its lanes that hold triangles (bit i = lane i).
    #[inline(always)]
    pub fn valid(&self) -> u32 {
        (1u32 << self.lanes) - 1
    }

    /// The corners of lane `lane`: the same values as the leaf-order triangle `first + lane`.
    #[inline(always)]
    pub fn corners(&self, lane: usize) -> [Vec3; 3] {
        super::simd4::each3(|c| {
            Vec3::new(self.v[c][0][lane], self.v[c][1][lane], self.v[c][2][lane])
        })
    }
}

/// A node with four empty slots.
pub(super) const UNUSED: Node4 = Node4 {
    lo: [[f32::INFINITY; 4]; 3],
    hi: [[f32::NEG_INFINITY; 4]; 3],
    child: [LEAF; 4],
    triangle4_count: [0; 4],
};

/// Collapses valid binary `nodes` (root first, as `build` makes them) over `n` triangles in
/// the binary tree's leaf order, where `corners(t)` is triangle `t` (called once per triangle,
/// only for `t < n`). Empty for an empty tree; otherwise node 0 is the root, and the nodes are
/// numbered depth first (slots in order), so every inner child comes after its parent.
///
/// The wide tree visits the binary leaves in another order (opening the widest child first
/// reorders them), and its leaf order is the order of the packs, as they are made depth first:
/// the third result lists, for each triangle in that order, its index in the binary leaf order.
pub(super) fn collapse<F: Fn(usize) -> [Vec3; 3]>(
    nodes: &[Node],
    n: usize,
    corners: F,
) -> (Vec<Node4>, Vec<Triangle4>, Vec<u32>) {
    let mut out = Collapse {
        nodes,
        corners,
        wide: Vec::with_capacity(nodes.len() / 3 + 1),
        triangles: Vec::with_capacity(n / 2 + 1),
        order: Vec::with_capacity(n),
    };
    if !nodes.is_empty() {
        out.wide.push(UNUSED);
        let (children, len) = if nodes[0].count > 0 {
            ([0; 4], 1)
        } else {
            out.open(0)
        };
        out.fill(0, &children[..len]);
    }
    out.wide.shrink_to_fit();
    out.triangles.shrink_to_fit();
    (out.wide, out.triangles, out.order)
}

struct Collapse<'a, F> {
    nodes: &'a [Node],
    corners: F,
    wide: Vec<Node4>,
    triangles: Vec<Triangle4>,
    /// The binary leaf-order index of each triangle put in a pack so far, in pack order.
    order: Vec<u32>,
}

impl<F: Fn(usize) -> [Vec3; 3]> Collapse<'_, F> {
    /// The up to 4 binary nodes that become the children of the wide node for inner node `n`:
    /// its two children, then repeatedly the inner one with the largest box opened in place.
    fn open(&self, n: usize) -> ([usize; 4], usize) {
        let first = self.nodes[n].first as usize;
        let mut children = [first, first + 1, 0, 0];
        let mut len = 2;
        while len < 4 {
            let mut widest: Option<(usize, f32)> = None;
            for (k, &c) in children[..len].iter().enumerate() {
                let node = &self.nodes[c];
                let area = node.bounds.half_area();
                if node.count == 0 && widest.is_none_or(|(_, a)| area > a) {
                    widest = Some((k, area));
                }
            }
            let Some((k, _)) = widest else { break };
            let c = self.nodes[children[k]].first as usize;
            children[k] = c;
            children[len] = c + 1;
            len += 1;
        }
        (children, len)
    }

    /// Fills wide node `w` with binary `children`, creating their subtrees depth first.
    fn fill(&mut self, w: usize, children: &[usize]) {
        for (slot, &c) in children.iter().enumerate() {
            let node = self.nodes[c];
            let Aabb { lo, hi } = node.bounds;
            for axis in 0..3 {
                self.wide[w].lo[axis][slot] = lo[axis];
                self.wide[w].hi[axis][slot] = hi[axis];
            }
            if node.count > 0 {
                let first_triangle4 = self.triangles.len();
                let (start, end) = (
                    node.first as usize,
                    node.first as usize + node.count as usize,
                );
                for chunk in (start..end).step_by(4) {
                    let lanes = (end - chunk).min(4);
                    let mut v = [[[0.0f32; 4]; 3]; 3];
                    for (lane, t) in (chunk..chunk + lanes).map(&self.corners).enumerate() {
                        for (corner, p) in t.iter().enumerate() {
                            for axis in 0..3 {
                                v[corner][axis][lane] = p[axis];
                            }
                        }
                    }
                    self.triangles.push(Triangle4 {
                        v,
                        first: self.order.len() as u32,
                        lanes: lanes as u32,
                    });
                    self.order.extend(chunk as u32..(chunk + lanes) as u32);
                }
                self.wide[w].child[slot] = LEAF | first_triangle4 as u32;
                self.wide[w].triangle4_count[slot] =
                    (self.triangles.len() - first_triangle4) as u32;
            } else {
                let index = self.wide.len();
                self.wide.push(UNUSED);
                self.wide[w].child[slot] = index as u32;
                self.wide[w].triangle4_count[slot] = 0;
                let (grandchildren, len) = self.open(c);
                self.fill(index, &grandchildren[..len]);
            }
        }
    }
}
