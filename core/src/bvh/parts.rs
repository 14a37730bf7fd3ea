//! The traversal form as flat little-endian bytes and back, for split objects: the 4-wide nodes'
//! structure (child words and pack counts; the boxes are derived from the triangles, see
//! `refit.rs`) and each `Triangle4`'s lane count; the triangles come in leaf order from the
//! caller. Writing is a linear pass over the arrays; reading is a linear copy into the final
//! arrays, one linear check of everything traversal relies on, and one pass setting the boxes,
//! so a corrupt or hostile split object gives an error, never a panic, an endless loop or an
//! unbounded traversal.

use super::build::MAX_DEPTH;
use super::node4::{LEAF, Node4, Triangle4, UNUSED};
use super::refit::{pack_box, refit};
use super::{Aabb, Bvh};
use glam::Vec3;

/// Bytes of one stored 4-wide node: 8 little-endian u32, `child[slot]` (an inner child's node
/// index, or `0x8000_0000 | first triangle pack` for a leaf or an empty slot), then
/// `triangle4_count[slot]` (a leaf's number of packs, 0 for an inner child or an empty slot).
/// The child boxes are not stored: loading derives them from the triangles, as building does.
pub const NODE_BYTES: usize = 32;

/// The stored traversal form of a BVH (see the module docs and [`Bvh::from_parts`]).
#[derive(Clone, Copy, Debug)]
pub struct BvhParts<'a> {
    /// The root's box ([`Bvh::bounds`]).
    pub bounds: Aabb,
    /// The 4-wide nodes, [`NODE_BYTES`] each, root first.
    pub nodes: &'a [u8],
    /// Each `Triangle4` pack's number of triangles (1 to 4), one byte per pack, in pack order.
    pub lanes: &'a [u8],
}

/// Why stored BVH arrays cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BvhPartsError {
    /// The node bytes end inside a node.
    #[error("BVH nodes: {found} bytes, not a whole number of {NODE_BYTES}-byte nodes")]
    PartialNode {
        /// The length of the node bytes.
        found: usize,
    },
    /// A node breaks the layout: children out of order or range, or a leaf out of place.
    #[error("BVH node {node}: {problem}")]
    BadNode {
        /// Index of the node in the node array (root = 0).
        node: usize,
        /// What is wrong with it.
        problem: String,
    },
    /// A pack holds no triangle or more than four.
    #[error("BVH triangle pack {pack}: holds {lanes} triangles, expected 1 to 4")]
    BadPack {
        /// Index of the pack.
        pack: usize,
        /// Its lane count.
        lanes: u8,
    },
    /// The packs hold a different number of triangles than there are ids.
    #[error("BVH triangle packs hold {held} triangles, expected {triangles}")]
    PackTotal {
        /// Triangles the packs hold.
        held: usize,
        /// Triangles the BVH holds (one per id).
        triangles: usize,
    },
    /// There are triangle ids but no nodes to reach them.
    #[error("BVH with triangles has no nodes")]
    NoNodes,
    /// There are nodes or packs but no triangles.
    #[error("BVH without triangles has {nodes} nodes and {packs} triangle packs")]
    NotEmpty {
        /// Nodes found.
        nodes: usize,
        /// Packs found.
        packs: usize,
    },
    /// A path from the root is deeper than the traversal stack allows.
    #[error("BVH is deeper than {MAX_DEPTH} levels")]
    TooDeep,
    /// The nodes are consistent but the root does not reach all of them.
    #[error("BVH root reaches {reached} of {nodes} nodes")]
    Unreached {
        /// Nodes reached from the root.
        reached: usize,
        /// Nodes stored.
        nodes: usize,
    },
    /// The leaves are consistent but cover only some of the packs.
    #[error("BVH leaves cover {covered} of {packs} triangle packs")]
    Coverage {
        /// Packs the leaves cover, fewer than `packs`.
        covered: usize,
        /// Packs stored.
        packs: usize,
    },
}

impl Bvh {
    /// Appends the 4-wide nodes' structure, [`NODE_BYTES`] each (layout there), root first.
    pub fn put_nodes(&self, out: &mut Vec<u8>) {
        out.reserve(self.wide.len() * NODE_BYTES);
        for n in &self.wide {
            for w in n.child.iter().chain(&n.triangle4_count) {
                out.extend_from_slice(&w.to_le_bytes());
            }
        }
    }

    /// Appends each `Triangle4` pack's number of triangles (1 to 4), one byte per pack.
    pub fn put_lanes(&self, out: &mut Vec<u8>) {
        out.extend(self.triangles.iter().map(|p| p.lanes as u8));
    }

    /// The triangles in leaf order (gathered from the `Triangle4`s, their only copy).
    pub fn leaf_triangles(&self) -> Vec<[Vec3; 3]> {
        let mut triangles = Vec::with_capacity(self.ids.len());
        for p in &self.triangles {
            triangles.extend((0..p.lanes as usize).map(|lane| p.corners(lane)));
        }
        triangles
    }

    /// Loads a BVH from the arrays [`Bvh::put_nodes`] and [`Bvh::put_lanes`] wrote, with the
    /// scene-wide `ids` in leaf order and `corners(t)` the corners of leaf-order triangle `t`
    /// (called once for each `t < ids.len()`, in order, only after every check passed); the
    /// result equals the BVH they were written from. [`PartsLoader`] does the same piece by
    /// piece.
    ///
    /// Accepts exactly what [`Bvh::build`] lays out: the node bytes are whole nodes, every pack
    /// holds 1 to 4 triangles and the packs hold `ids.len()` together, and a depth-first walk
    /// from the root (slots in order) meets the inner children in node order (child `k` is the
    /// `k`-th node reached, so each comes after its parent and is reached once: no cycles, no
    /// sharing), no deeper than the traversal stack allows, reaching every node, and meets the
    /// leaves' packs in pack order, each leaf inside the array, covering every pack once. Empty
    /// slots are the empty leaf; inner children count no packs. The boxes are derived from the
    /// triangles exactly as [`Bvh::build`] derives them (`refit.rs`), so they are the stored
    /// BVH's to the bit (corners a hostile object makes NaN or infinite only cull more or less;
    /// traversal stays exact and bounded). Cost: one linear pass over each array.
    pub fn from_parts(
        parts: BvhParts<'_>,
        ids: Vec<u32>,
        mut corners: impl FnMut(usize) -> [Vec3; 3],
    ) -> Result<Bvh, BvhPartsError> {
        let BvhParts {
            bounds,
            nodes,
            lanes,
        } = parts;
        let mut loader = PartsLoader::new(bounds, nodes.len() / NODE_BYTES);
        loader.push_nodes(nodes)?;
        loader.set_lanes(lanes.to_vec(), ids.len())?;
        for t in 0..ids.len() {
            loader.push_triangle(corners(t));
        }
        Ok(loader.finish(ids))
    }
}

/// [`Bvh::from_parts`] piece by piece, for a reader that gets the stored arrays from a stream:
/// [`PartsLoader::new`], the node bytes in any number of whole-node pieces
/// ([`PartsLoader::push_nodes`]), the lane counts ([`PartsLoader::set_lanes`], which makes
/// every check `from_parts` makes, with the same errors), each triangle's corners in leaf
/// order ([`PartsLoader::push_triangle`], once per triangle), then the ids
/// ([`PartsLoader::finish`], which sets the boxes). Called in that order with the same bytes,
/// the result equals `from_parts`'s. Each array is written once, straight into its final
/// place, and the boxes once more at the end.
pub struct PartsLoader {
    bounds: Aabb,
    wide: Vec<Node4>,
    lanes: Vec<u8>,
    triangles: Vec<Triangle4>,
    /// Each full pack's box ([`pack_box`]).
    pack_boxes: Vec<Aabb>,
    /// The full packs, the next lane of the pack being filled (the last in `triangles` unless
    /// 0), and the triangles in the full packs.
    full: usize,
    lane: usize,
    first: usize,
}

impl PartsLoader {
    /// A loader for a BVH with root box `bounds` and `nodes` 4-wide nodes (the capacity it
    /// reserves).
    pub fn new(bounds: Aabb, nodes: usize) -> Self {
        PartsLoader {
            bounds,
            wide: hort_huge_pages::vec_with_capacity(nodes),
            lanes: Vec::new(),
            triangles: Vec::new(),
            pack_boxes: Vec::new(),
            full: 0,
            lane: 0,
            first: 0,
        }
    }

    /// Appends the nodes in `bytes`, [`NODE_BYTES`] each; an error if `bytes` ends inside a
    /// node.
    pub fn push_nodes(&mut self, bytes: &[u8]) -> Result<(), BvhPartsError> {
        let (nodes, rest) = bytes.as_chunks::<NODE_BYTES>();
        if !rest.is_empty() {
            return Err(BvhPartsError::PartialNode { found: bytes.len() });
        }
        self.wide.extend(nodes.iter().map(node_from_bytes));
        Ok(())
    }

    /// Takes each pack's lane count and checks the nodes pushed and the packs against a BVH of
    /// `triangles` triangles, as [`Bvh::from_parts`] does.
    pub fn set_lanes(&mut self, lanes: Vec<u8>, triangles: usize) -> Result<(), BvhPartsError> {
        if triangles == 0 {
            if !self.wide.is_empty() || !lanes.is_empty() {
                return Err(BvhPartsError::NotEmpty {
                    nodes: self.wide.len(),
                    packs: lanes.len(),
                });
            }
            return Ok(());
        }
        if self.wide.is_empty() {
            return Err(BvhPartsError::NoNodes);
        }
        let mut held = 0usize;
        for (pack, &l) in lanes.iter().enumerate() {
            if !(1..=4).contains(&l) {
                return Err(BvhPartsError::BadPack { pack, lanes: l });
            }
            held += usize::from(l);
        }
        if held != triangles {
            return Err(BvhPartsError::PackTotal { held, triangles });
        }
        check_nodes(&self.wide, lanes.len())?;
        self.triangles = hort_huge_pages::vec_with_capacity(lanes.len());
        self.pack_boxes = hort_huge_pages::vec_with_capacity(lanes.len());
        self.lanes = lanes;
        Ok(())
    }

    /// Puts the next leaf-order triangle in its pack (after [`PartsLoader::set_lanes`]
    /// succeeded; triangles beyond the packs are ignored). The pack is written where it stays,
    /// and its box is taken once it is full.
    #[inline]
    pub fn push_triangle(&mut self, corners: [Vec3; 3]) {
        let Some(&lanes) = self.lanes.get(self.full) else {
            return;
        };
        let lane = self.lane;
        if lane == 0 {
            self.triangles.push(Triangle4 {
                first: self.first as u32,
                lanes: u32::from(lanes),
                ..EMPTY_PACK
            });
        }
        let Some(pack) = self.triangles.last_mut() else {
            return;
        };
        for (vc, p) in pack.v.iter_mut().zip(corners) {
            for (va, x) in vc.iter_mut().zip(p.to_array()) {
                va[lane] = x;
            }
        }
        self.lane += 1;
        if self.lane == usize::from(lanes) {
            self.pack_boxes.push(pack_box(pack));
            self.first += self.lane;
            self.full += 1;
            self.lane = 0;
        }
    }

    /// The BVH, with the scene-wide `ids` in leaf order (one per triangle pushed), its boxes
    /// set from the packs (after [`PartsLoader::set_lanes`] succeeded).
    pub fn finish(mut self, ids: Vec<u32>) -> Bvh {
        refit(&mut self.wide, &self.pack_boxes);
        Bvh {
            bounds: self.bounds,
            ids,
            wide: self.wide,
            triangles: self.triangles,
        }
    }
}

/// A pack before its lanes are filled: unused lanes stay zero.
const EMPTY_PACK: Triangle4 = Triangle4 {
    v: [[[0.0; 4]; 3]; 3],
    first: 0,
    lanes: 0,
};

/// One node from its [`NODE_BYTES`] bytes, its boxes those of an unused node until
/// [`refit`] sets them.
#[inline]
fn node_from_bytes(b: &[u8; NODE_BYTES]) -> Node4 {
    let (w, _) = b.as_chunks::<4>();
    let u = |k: usize| u32::from_le_bytes(w[k]);
    Node4 {
        child: std::array::from_fn(u),
        triangle4_count: std::array::from_fn(|s| u(4 + s)),
        ..UNUSED
    }
}

/// The structural checks of [`Bvh::from_parts`] on `wide` (not empty) over `packs` packs: a
/// depth-first walk, which visits the nodes in index order when they are valid.
fn check_nodes(wide: &[Node4], packs: usize) -> Result<(), BvhPartsError> {
    // (node, next slot) per level of the walk; at most MAX_DEPTH levels.
    let mut stack: Vec<(usize, usize)> = Vec::with_capacity(MAX_DEPTH);
    stack.push((0, 0));
    let (mut reached, mut covered) = (1usize, 0usize);
    while let Some(top) = stack.last_mut() {
        let (index, slot) = *top;
        if slot == 4 {
            stack.pop();
            continue;
        }
        top.1 += 1;
        let (child, count) = (wide[index].child[slot], wide[index].triangle4_count[slot]);
        let bad = |problem: String| BvhPartsError::BadNode {
            node: index,
            problem: format!("slot {slot}: {problem}"),
        };
        if child & LEAF == 0 {
            if child as usize != reached || reached >= wide.len() {
                return Err(bad(format!(
                    "child {child}, expected node {reached} of {} (depth-first order)",
                    wide.len()
                )));
            }
            if count != 0 {
                return Err(bad(format!("inner child with {count} triangle packs")));
            }
            if stack.len() >= MAX_DEPTH {
                return Err(BvhPartsError::TooDeep);
            }
            reached += 1;
            stack.push((child as usize, 0));
        } else if count == 0 {
            if child != LEAF {
                return Err(bad(format!(
                    "empty slot with child word {child:#010x}, expected {LEAF:#010x}"
                )));
            }
        } else {
            let first = (child & !LEAF) as usize;
            if first != covered {
                return Err(bad(format!(
                    "leaf starts at triangle pack {first}, expected {covered}"
                )));
            }
            // `covered <= packs` holds here, so neither side can overflow.
            if count as usize > packs - covered {
                let end = first as u64 + u64::from(count);
                return Err(bad(format!(
                    "leaf ends at triangle pack {end} past {packs}"
                )));
            }
            covered += count as usize;
        }
    }
    if reached != wide.len() {
        return Err(BvhPartsError::Unreached {
            reached,
            nodes: wide.len(),
        });
    }
    if covered != packs {
        return Err(BvhPartsError::Coverage { covered, packs });
    }
    Ok(())
}
