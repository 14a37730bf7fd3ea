//! The fast build preset: a linear BVH over Morton codes (Lauterbach et al., "Fast BVH
//! Construction on GPUs", 2009; Karras, "Maximizing Parallelism in the Construction of BVHs,
//! Octrees, and k-d Trees", 2012), as Embree's low-quality builds are. Each triangle's box
//! centroid is placed on a 1024³ grid over the centroids' bounds, the triangles are sorted by
//! the cell's Morton code (ties by index, so the order is total), and each node splits its
//! sorted run where the highest code bit that differs within the run turns on (in the middle
//! when every code of the run is the same). One sort and a pass per node's run, against binned
//! SAH's two passes over every node's refs per tree level (`build.rs`), at the cost of a worse
//! tree: fewer rays per second (docs/perf/time-per-sample.md, "Build presets").
//!
//! It gives the same tree for the same triangles on any machine and any thread count (it runs
//! on one), and the same shape of output as the SAH builder: binary nodes root first, a node's
//! two children side by side, leaves of at most [`MORTON_LEAF`] triangles (deeper than
//! `MAX_DEPTH` levels a run becomes one leaf), and the leaf order.

use super::build::{LARGE_TREE_LEAF, MAX_DEPTH};
use super::{Aabb, Node};
use crate::morton::morton_code;
use glam::Vec3;

/// Runs this short become leaves: two `Triangle4`s, the SAH builder's largest leaf in large
/// trees (`build::max_leaf`; below `build::LARGE_TREE` triangles it stops at one). The preset serves
/// one-shot renders of large scenes (fewer samples than four a triangle), where a node visit is
/// likely a cache miss and the build's node count is paid once per render: on a 1M mesh at
/// 1280x720, 1 spp, leaves of 8 made the whole render 0.93-0.96x the time of leaves of 4
/// (`bvh/README.md`, "Larger leaves").
const MORTON_LEAF: usize = LARGE_TREE_LEAF as usize;

/// Grid cells per axis: 10 bits each, a 30-bit code.
const CELLS: f32 = 1024.0;

/// A node before its split or leaf is decided and its box is set.
const UNSET: Node = Node {
    bounds: Aabb::EMPTY,
    first: 0,
    count: 0,
};

/// The binary tree over `triangles` (root first; empty for no triangles) and its leaf order:
/// `order[t]` is the index in `triangles` of leaf-order triangle `t`.
pub(super) fn binary_tree(triangles: &[[Vec3; 3]]) -> (Vec<Node>, Vec<u32>) {
    let n = triangles.len();
    if n == 0 {
        return (Vec::new(), Vec::new());
    }
    let boxes: Vec<Aabb> = triangles.iter().map(Aabb::of_triangle).collect();
    let centroid = |b: &Aabb| (b.lo + b.hi) * 0.5;
    let (lo, hi) = boxes.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), b| (lo.min(centroid(b)), hi.max(centroid(b))),
    );
    let extent = hi - lo;
    let scale = Vec3::select(extent.cmpgt(Vec3::ZERO), CELLS / extent, Vec3::ZERO);
    let mut keys: Vec<u64> = boxes
        .iter()
        .enumerate()
        .map(|(i, b)| {
            // `as` saturates (and takes NaN to 0), so every cell index is in 0..1024.
            let cell = ((centroid(b) - lo) * scale)
                .to_array()
                .map(|x| u64::from((x as u32).min(1023)));
            // Cells below 2^10 per axis: a 30-bit code.
            morton_code(cell) << 32 | i as u64
        })
        .collect();
    keys.sort_unstable();
    let codes: Vec<u32> = keys.iter().map(|k| (k >> 32) as u32).collect();
    let order: Vec<u32> = keys.iter().map(|&k| k as u32).collect();
    let mut nodes = Vec::with_capacity(2 * n / MORTON_LEAF + 1);
    nodes.push(UNSET);
    // (node, start, end, depth), left child popped first.
    let mut stack = vec![(0usize, 0usize, n, 0usize)];
    while let Some((node, start, end, depth)) = stack.pop() {
        if end - start <= MORTON_LEAF || depth + 1 >= MAX_DEPTH {
            nodes[node].first = start as u32;
            nodes[node].count = (end - start) as u32;
            continue;
        }
        let mid = split_point(&codes[start..end]) + start;
        let left = nodes.len();
        nodes.extend([UNSET; 2]);
        nodes[node].first = left as u32;
        stack.push((left + 1, mid, end, depth + 1));
        stack.push((left, start, mid, depth + 1));
    }
    // Children come after their parent: boxes from the last node back to the root.
    for i in (0..nodes.len()).rev() {
        let Node { first, count, .. } = nodes[i];
        let (first, count) = (first as usize, count as usize);
        nodes[i].bounds = if count == 0 {
            nodes[first].bounds.union(nodes[first + 1].bounds)
        } else {
            order[first..first + count]
                .iter()
                .fold(Aabb::EMPTY, |b, &t| b.union(boxes[t as usize]))
        };
    }
    (nodes, order)
}

/// Where a sorted run of at least two codes splits: before the first code with the highest
/// differing bit set, or in the middle when all codes are equal. Both sides are never empty.
fn split_point(codes: &[u32]) -> usize {
    let (first, last) = (codes[0], codes[codes.len() - 1]);
    if first == last {
        return codes.len() / 2;
    }
    let bit = 1u32 << (31 - (first ^ last).leading_zeros());
    codes.partition_point(|&c| c & bit == 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_points_are_strictly_inside_the_run() {
        assert_eq!(split_point(&[5, 5, 5, 5]), 2);
        assert_eq!(split_point(&[0b001, 0b010, 0b011, 0b100, 0b101]), 3);
        assert_eq!(split_point(&[0b100, 0b101, 0b110]), 2);
        assert_eq!(split_point(&[7, 8]), 1);
    }

    /// Runs of up to `MORTON_LEAF` triangles are leaves and longer runs are split: `MORTON_LEAF`
    /// triangles make one leaf, one more makes a split, and a larger scene's leaves hold at most
    /// `MORTON_LEAF`, some of them exactly that many.
    #[test]
    fn leaves_hold_up_to_morton_leaf_triangles() {
        let triangle = |i: usize| {
            let p = Vec3::new(i as f32 * 3.0, (i % 7) as f32, (i % 5) as f32);
            [p, p + Vec3::X, p + Vec3::Y]
        };
        let scene = |n: usize| (0..n).map(triangle).collect::<Vec<_>>();
        let (nodes, _) = binary_tree(&scene(MORTON_LEAF));
        assert_eq!(nodes.len(), 1);
        assert_eq!(nodes[0].count as usize, MORTON_LEAF);
        let (nodes, _) = binary_tree(&scene(MORTON_LEAF + 1));
        assert!(nodes.len() > 1 && nodes[0].count == 0, "split");
        let (nodes, order) = binary_tree(&scene(5000));
        let leaves: Vec<usize> = nodes
            .iter()
            .filter(|n| n.count > 0)
            .map(|n| n.count as usize)
            .collect();
        assert_eq!(leaves.iter().sum::<usize>(), order.len());
        assert!(leaves.iter().all(|&c| c <= MORTON_LEAF), "{leaves:?}");
        assert!(leaves.contains(&MORTON_LEAF));
    }
}
