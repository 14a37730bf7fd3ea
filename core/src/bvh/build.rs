//! Binned SAH construction (Wald 2007): 16 bins per axis on centroid bounds; every node of at
//! most [`MAX_LEAF`] triangles is a leaf (one 4-wide `Triangle4` test), or of at most
//! [`LARGE_TREE_LEAF`] in trees of [`LARGE_TREE`] triangles or more ([`max_leaf`]); larger
//! ones are split.
//!
//! What it builds is defined by the plain algorithm kept beside it for the tests
//! (`build_reference.rs`): the same nodes, bit for bit, for any finite triangles (scenes are
//! validated to finite coordinates before they get here). It is faster because
//! - each triangle's box and centroid travel with its index through the partitions, so every
//!   pass over a node reads one contiguous run instead of gathering from scene-order arrays;
//! - one pass bins a node on all three axes, and the partition pass accumulates both children's
//!   centroid bounds, while a child's box is the union of its side's bins: two passes per node
//!   instead of six. Unions of finite values are exact in any order (only the sign of a zero
//!   may differ, which no area or cost can see), so the children's boxes and centroid bounds
//!   are the values the plain folds compute.

use super::{Aabb, Bvh, Node};
use glam::Vec3;
use wide::{f32x4, i32x4};

const BINS: usize = 16;
/// How many triangles ahead of the collapse [`build`] fetches.
const PREFETCH_AHEAD: usize = 16;
/// Nodes this small become leaves (one `Triangle4` test) unless their box is mostly empty
/// ([`mostly_empty`]); coincident centroids are split by index instead.
pub(super) const MAX_LEAF: u32 = 4;
/// Trees of this many triangles or more take leaves of up to [`LARGE_TREE_LEAF`] ([`max_leaf`]).
pub(super) const LARGE_TREE: usize = 1 << 18;
/// The largest leaf of a large tree: two `Triangle4` tests.
pub(super) const LARGE_TREE_LEAF: u32 = 8;

/// The largest leaf of a tree over `triangles` triangles: [`MAX_LEAF`], or [`LARGE_TREE_LEAF`]
/// from [`LARGE_TREE`] triangles on. A large tree's nodes and `Triangle4`s (about 40 bytes a
/// triangle) outgrow the caches, so a node visit is more likely a miss, and fewer nodes are a
/// shorter build. Measured on generated meshes, one core (`bvh/README.md`, "Larger leaves"):
/// leaves of 8 cost a 100k mesh 2-3% at 64 spp, left a 300k one level, and made the 1M mesh
/// 2-3% faster at 64 spp, 7% at 1 spp, its build 18% shorter; the small bundled scenes lose
/// 1-3% with them.
pub(super) fn max_leaf(triangles: usize) -> u32 {
    if triangles >= LARGE_TREE {
        LARGE_TREE_LEAF
    } else {
        MAX_LEAF
    }
}

/// Deepest level a node may have; deeper subtrees become (large) leaves. Traversal stacks hold
/// one entry per level, so this bounds them (see `traverse::STACK`).
pub(super) const MAX_DEPTH: usize = 60;

/// A box in 4-wide lanes x, y, z (the fourth lane is not part of the box: a [`Ref`] keeps its
/// triangle's index there, and unions of boxes carry whatever it becomes).
#[derive(Clone, Copy)]
struct Box3 {
    lo: f32x4,
    hi: f32x4,
}

impl Box3 {
    const EMPTY: Box3 = Box3 {
        lo: f32x4::new([f32::INFINITY; 4]),
        hi: f32x4::new([f32::NEG_INFINITY; 4]),
    };

    fn union(self, o: Box3) -> Box3 {
        Box3 {
            lo: self.lo.fast_min(o.lo),
            hi: self.hi.fast_max(o.hi),
        }
    }

    fn grow(self, p: f32x4) -> Box3 {
        Box3 {
            lo: self.lo.fast_min(p),
            hi: self.hi.fast_max(p),
        }
    }

    fn aabb(self) -> Aabb {
        let (lo, hi) = (self.lo.to_array(), self.hi.to_array());
        Aabb {
            lo: Vec3::new(lo[0], lo[1], lo[2]),
            hi: Vec3::new(hi[0], hi[1], hi[2]),
        }
    }

    /// The volume (x, y, z extents; `build_reference::volume`, same operations).
    fn volume(self) -> f32 {
        let d = (self.hi - self.lo).fast_max(f32x4::ZERO).to_array();
        d[0] * d[1] * d[2]
    }

    /// [`Aabb::half_area`], same operations.
    fn half_area(self) -> f32 {
        let d = (self.hi - self.lo).fast_max(f32x4::ZERO).to_array();
        d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
    }
}

/// Whether a leaf-sized node ([`max_leaf`]) whose triangles' boxes have the volumes summing to
/// `filled` (in the node's order) is split anyway, its box of volume `node` being mostly empty:
/// the triangles' boxes fill less than a sixteenth of it. Walls, floors and ceilings (flat,
/// axis-aligned, far apart) pooled in one leaf make a box around a whole room, which every ray
/// inside the room enters (the surface-area heuristic counts rays from outside); split, each
/// is entered only by the rays that meet it. A node flat along an axis (volume 0) stays a leaf.
pub(super) fn mostly_empty(filled: f32, node: f32) -> bool {
    filled * 16.0 < node
}

/// One triangle being partitioned: its box, with its index in the scene kept in the fourth
/// lanes (the low 16 bits in `lo`'s, the high 16 in `hi`'s, each as an exact float: as raw bits
/// they would be subnormal numbers, which the centroid's arithmetic would slow to a crawl), so
/// that a partition moves one 32-byte record.
#[derive(Clone, Copy)]
struct Ref(Box3);

impl Ref {
    fn new(index: u32, b: Aabb) -> Ref {
        Ref(Box3 {
            lo: f32x4::new([b.lo.x, b.lo.y, b.lo.z, (index & 0xffff) as f32]),
            hi: f32x4::new([b.hi.x, b.hi.y, b.hi.z, (index >> 16) as f32]),
        })
    }

    fn index(&self) -> u32 {
        self.0.lo.to_array()[3] as u32 | (self.0.hi.to_array()[3] as u32) << 16
    }

    /// The centroid in lanes x, y, z, as the plain algorithm computes it: (lo + hi) * 0.5.
    fn centroid(&self) -> f32x4 {
        (self.0.lo + self.0.hi) * f32x4::splat(0.5)
    }
}

/// A node waiting to be built: its slot, its range of refs, its depth and the bounds of its
/// centroids.
#[derive(Clone, Copy)]
struct Pending {
    node: usize,
    start: usize,
    end: usize,
    depth: usize,
    centroid_bounds: Box3,
    /// The tree's largest leaf ([`max_leaf`]).
    max_leaf: u32,
}

pub(super) fn build(triangles: Vec<[Vec3; 3]>, ids: Vec<u32>, threads: usize) -> Bvh {
    let (nodes, order) = binary_tree(&triangles, threads);
    let ids_in_order = order.iter().map(|&i| ids[i as usize]).collect();
    // The collapse asks for the triangles in nearly increasing leaf order, and `order` jumps
    // around the scene: the one wanted 16 calls later is fetched ahead (2-4% of the 1M build).
    Bvh::assemble(nodes, ids_in_order, |t| {
        if let Some(&ahead) = order.get(t + PREFETCH_AHEAD) {
            crate::prefetch::prefetch(&triangles[ahead as usize]);
        }
        triangles[order[t] as usize]
    })
}

/// The binary tree over `triangles` (root first; empty for no triangles) and its leaf order:
/// `order[t]` is the index in `triangles` of leaf-order triangle `t`. The same for any number
/// of `threads` (at least 1 is used).
pub(super) fn binary_tree(triangles: &[[Vec3; 3]], threads: usize) -> (Vec<Node>, Vec<u32>) {
    binary_tree_with_leaves(triangles, threads, max_leaf(triangles.len()))
}

/// [`binary_tree`] with leaves of up to `max_leaf` triangles (the tests build both sizes at any
/// size of tree).
pub(super) fn binary_tree_with_leaves(
    triangles: &[[Vec3; 3]],
    threads: usize,
    max_leaf: u32,
) -> (Vec<Node>, Vec<u32>) {
    let n = triangles.len();
    if n == 0 {
        return (Vec::new(), Vec::new());
    }
    let mut refs: Vec<Ref> = triangles
        .iter()
        .enumerate()
        .map(|(i, t)| Ref::new(i as u32, Aabb::of_triangle(t)))
        .collect();
    // The root's box folds the triangles' `Aabb`s in scene order, as the plain algorithm does,
    // so that even the signs of its zeros are the same (the root's box is stored).
    let root_box = triangles
        .iter()
        .fold(Aabb::EMPTY, |b, t| b.union(Aabb::of_triangle(t)));
    let root = Pending {
        node: 0,
        start: 0,
        end: n,
        depth: 0,
        centroid_bounds: refs.iter().fold(Box3::EMPTY, |b, r| b.grow(r.centroid())),
        max_leaf,
    };
    let mut nodes = Vec::with_capacity(2 * n / max_leaf as usize + 1);
    nodes.push(Node {
        bounds: root_box,
        first: 0,
        count: 0,
    });
    grow(&mut refs, 0, root, &mut nodes, fork_levels(threads));
    (nodes, refs.iter().map(Ref::index).collect())
}

/// Nodes with fewer refs than this are not worth a thread of their own.
const FORK_MIN: usize = 1 << 15;

/// The levels of the tree at which a large node's right subtree gets its own thread: about
/// four subtrees per thread, so that uneven splits still keep every thread busy.
fn fork_levels(threads: usize) -> usize {
    if threads <= 1 {
        0
    } else {
        threads.ilog2() as usize + 2
    }
}

/// Builds the subtree under `root` (already in `nodes`, box set) over `refs`, whose first ref
/// is `offset` in the whole leaf order, appending its nodes to `nodes` in the order of the
/// sequential algorithm: a node's two children side by side when it is split, then the left
/// child's subtree, then the right's. For `forks` more levels, a node of at least
/// [`FORK_MIN`] refs builds its right subtree on another thread into its own array, appended
/// (renumbered) once the left subtree is done, which gives the same nodes.
fn grow(refs: &mut [Ref], offset: usize, root: Pending, nodes: &mut Vec<Node>, forks: usize) {
    let mut stack = vec![root];
    while let Some(p) = stack.pop() {
        let split = if p.depth + 1 >= MAX_DEPTH {
            None
        } else {
            split(&mut refs[p.start..p.end], p.centroid_bounds, p.max_leaf)
        };
        let Some(s) = split else {
            nodes[p.node].first = (offset + p.start) as u32;
            nodes[p.node].count = (p.end - p.start) as u32;
            continue;
        };
        let left = nodes.len();
        for side in [&s.left, &s.right] {
            nodes.push(Node {
                bounds: side.bounds.aabb(),
                first: 0,
                count: 0,
            });
        }
        nodes[p.node].first = left as u32;
        nodes[p.node].count = 0;
        let mid = p.start + s.mid;
        let child = |node, start, end, side: Side| Pending {
            node,
            start,
            end,
            depth: p.depth + 1,
            centroid_bounds: side.centroid_bounds,
            max_leaf: p.max_leaf,
        };
        let (left_child, right_child) = (
            child(left, p.start, mid, s.left),
            child(left + 1, mid, p.end, s.right),
        );
        if forks == 0 || p.end - p.start < FORK_MIN {
            stack.push(right_child);
            stack.push(left_child);
            continue;
        }
        let (left_refs, right_refs) = refs[p.start..p.end].split_at_mut(mid - p.start);
        let right_root = nodes[left + 1];
        let right_nodes = std::thread::scope(|scope| {
            let right = scope.spawn(|| {
                let mut right_nodes = vec![right_root];
                let root = Pending {
                    node: 0,
                    start: 0,
                    end: right_refs.len(),
                    ..right_child
                };
                grow(right_refs, offset + mid, root, &mut right_nodes, forks - 1);
                right_nodes
            });
            let root = Pending {
                start: 0,
                end: left_refs.len(),
                ..left_child
            };
            grow(left_refs, offset + p.start, root, nodes, forks - 1);
            right
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
        });
        append_subtree(nodes, left + 1, right_nodes);
    }
}

/// Puts a subtree built on its own (its root at 0, its other nodes after) into `nodes`: the
/// root at `at`, the rest appended, inner nodes' child indices renumbered to match.
fn append_subtree(nodes: &mut Vec<Node>, at: usize, subtree: Vec<Node>) {
    let base = nodes.len() as u32 - 1;
    let renumber = |mut n: Node| {
        if n.count == 0 {
            n.first += base;
        }
        n
    };
    nodes[at] = renumber(subtree[0]);
    nodes.extend(subtree[1..].iter().map(|&n| renumber(n)));
}

/// One side of a split: its box and the bounds of its centroids.
struct Side {
    bounds: Box3,
    centroid_bounds: Box3,
}

/// A split of a node's refs: the first `mid` go left.
struct Split {
    mid: usize,
    left: Side,
    right: Side,
}

/// Each ref's bin on each axis (lanes x, y, z), as the plain algorithm computes it:
/// `((c - origin) * scale) as usize`, at most `BINS - 1`. The products are never negative,
/// since no centroid lies below `origin`, the least centroid.
struct Binner {
    origin: f32x4,
    scale: f32x4,
    /// Some axis's scale is infinite (a positive extent too small for `BINS / extent`): its
    /// products may be NaN or infinite, and are truncated as `as` does (NaN to 0,
    /// saturating). Otherwise every product lies in [0, `BINS`] (up to rounding, far below
    /// 2^31) and a plain truncation gives the same values.
    saturate: bool,
}

impl Binner {
    /// The binner of a node whose centroids lie in `bounds`, and the bounds' extent.
    fn new(bounds: Box3) -> (Binner, f32x4) {
        let extent = bounds.hi - bounds.lo;
        // Along an axis without extent every centroid is at `origin`, and its product is
        // 0 · ∞ = NaN, bin 0: a scale of 0 gives that bin with a product of 0.
        let zero = extent.simd_eq(f32x4::ZERO);
        let scale = zero.select(f32x4::ZERO, f32x4::splat(BINS as f32) / extent);
        let infinite = scale.simd_eq(f32x4::splat(f32::INFINITY)).to_bitmask() & 0b111;
        let binner = Binner {
            origin: bounds.lo,
            scale,
            saturate: infinite != 0,
        };
        (binner, extent)
    }

    /// The bins, each in `0..BINS`.
    #[inline(always)]
    fn bins(&self, c: f32x4) -> [usize; 4] {
        let product = (c - self.origin) * self.scale;
        let whole = if self.saturate {
            product.trunc_int()
        } else {
            product.fast_trunc_int()
        };
        let bins = whole.min(i32x4::splat(BINS as i32 - 1)).to_array();
        // The mask keeps what is already in range (no product is negative); it spares the
        // bounds checks of the bins' arrays.
        bins.map(|b| b as usize & (BINS - 1))
    }
}

/// Partitions `refs` and returns the split, or `None` to make a leaf (of at most `max_leaf`
/// triangles, [`max_leaf`]).
fn split(refs: &mut [Ref], centroid_bounds: Box3, max_leaf: u32) -> Option<Split> {
    let count = refs.len();
    // Up to MAX_LEAF triangles are one 4-wide Triangle4 test, cheaper than any split (measured:
    // about +10% primary and shadow rays/s on a 1M-triangle scene against an SAH leaf cost),
    // unless the node's box is mostly empty ([`mostly_empty`]); in large trees up to
    // LARGE_TREE_LEAF.
    if count as u32 <= max_leaf {
        let node = refs.iter().fold(Box3::EMPTY, |a, r| a.union(r.0));
        let filled = refs.iter().fold(0.0, |sum, r| sum + r.0.volume());
        if !mostly_empty(filled, node.volume()) {
            return None;
        }
    }
    let (binner, extent) = Binner::new(centroid_bounds);
    let extent = extent.to_array();
    let mut bins = [[Box3::EMPTY; BINS]; 3];
    let mut counts = [[0u32; BINS]; 3];
    for r in refs.iter() {
        let b = binner.bins(r.centroid());
        for axis in 0..3 {
            let k = b[axis];
            bins[axis][k] = bins[axis][k].union(r.0);
            counts[axis][k] += 1;
        }
    }
    let mut best: Option<(f32, usize, usize)> = None; // (cost, axis, bins left of split)
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        let (bins, counts) = (&bins[axis], &counts[axis]);
        // Only bins that hold refs change a side: a split after an empty bin costs what the
        // split before it costs (the same sides), and ties keep the first, so the sweeps visit
        // the occupied bins alone and find the plain sweep's split. Small nodes, most of the
        // tree's nodes, occupy few of the bins.
        let occupied = (0..BINS).fold(0u32, |m, k| m | u32::from(counts[k] != 0) << k);
        // right_cost[j], j occupied: the cost of the side made of bins j and up.
        let mut right_cost = [0.0f32; BINS];
        let (mut acc, mut n) = (Box3::EMPTY, 0u32);
        let mut above = occupied & !1;
        while above != 0 {
            let j = (u32::BITS - 1 - above.leading_zeros()) as usize;
            above &= !(1 << j);
            acc = acc.union(bins[j]);
            n += counts[j];
            right_cost[j] = acc.half_area() * n as f32;
        }
        let (mut acc, mut n) = (Box3::EMPTY, 0u32);
        let mut rest = occupied;
        while rest != 0 {
            let i = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            if rest == 0 {
                break; // every ref would go left
            }
            acc = acc.union(bins[i]);
            n += counts[i];
            let cost = acc.half_area() * n as f32 + right_cost[rest.trailing_zeros() as usize];
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, i + 1));
            }
        }
    }
    let side = |refs: &[Ref]| Side {
        bounds: refs.iter().fold(Box3::EMPTY, |a, r| a.union(r.0)),
        centroid_bounds: refs.iter().fold(Box3::EMPTY, |a, r| a.grow(r.centroid())),
    };
    let Some((_, axis, k)) = best else {
        if count as u32 <= max_leaf {
            return None;
        }
        // All centroids coincide: split by index so leaves stay small.
        let mid = count / 2;
        return Some(Split {
            mid,
            left: side(&refs[..mid]),
            right: side(&refs[mid..]),
        });
    };
    let side_box = |range: std::ops::Range<usize>| {
        bins[axis][range]
            .iter()
            .fold(Box3::EMPTY, |a, &b| a.union(b))
    };
    let (mid, left_centroids, right_centroids) = partition(refs, &binner, (axis, k));
    Some(Split {
        mid,
        left: Side {
            bounds: side_box(0..k),
            centroid_bounds: left_centroids,
        },
        right: Side {
            bounds: side_box(k..BINS),
            centroid_bounds: right_centroids,
        },
    })
}

/// Moves the refs whose centroid bins left of `k` on `axis` to the front, in the plain
/// algorithm's order (swap each one with the first ref not yet known to go left); returns how
/// many went left and the bounds of both sides' centroids. A function of its own: inlined
/// into [`grow`], the bounds stayed in memory, a store and a load on every ref's path (the
/// 1M-triangle build took 2-4% longer).
#[inline(never)]
fn partition(refs: &mut [Ref], binner: &Binner, (axis, k): (usize, usize)) -> (usize, Box3, Box3) {
    // One loop per axis, so that the bin is read from its lane; with the axis a variable, the
    // lanes went through memory on every ref's path.
    match axis {
        0 => partition_on::<0>(refs, binner, k),
        1 => partition_on::<1>(refs, binner, k),
        _ => partition_on::<2>(refs, binner, k),
    }
}

/// [`partition`] on axis `AXIS`.
#[inline(always)]
fn partition_on<const AXIS: usize>(
    refs: &mut [Ref],
    binner: &Binner,
    k: usize,
) -> (usize, Box3, Box3) {
    let (mut mid, mut left, mut right) = (0, Box3::EMPTY, Box3::EMPTY);
    for i in 0..refs.len() {
        let r = refs[i];
        let c = r.centroid();
        if binner.bins(c)[AXIS] < k {
            left = left.grow(c);
            refs[i] = refs[mid];
            refs[mid] = r;
            mid += 1;
        } else {
            right = right.grow(c);
        }
    }
    (mid, left, right)
}
