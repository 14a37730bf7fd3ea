//! Taking a built BVH apart into flat arrays and putting it back without rebuilding, for split
//! objects. Reassembly validates everything traversal relies on, so a corrupt or hostile split
//! object gives an error, never a panic or an endless loop.

use super::build::MAX_DEPTH;
use super::{Bvh, Node};
use glam::Vec3;

/// Why stored BVH arrays cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BvhPartsError {
    /// A node breaks the layout: children out of order or range, or a leaf out of place.
    #[error("BVH node {node}: {problem}")]
    BadNode {
        /// Index of the node in the node array (root = 0).
        node: usize,
        /// What is wrong with it.
        problem: String,
    },
    /// There are triangle ids but no nodes to reach them.
    #[error("BVH with triangles has no nodes")]
    NoNodes,
    /// A path from the root is deeper than the traversal stack, or nodes are reached twice.
    #[error("BVH is deeper than {MAX_DEPTH} levels")]
    TooDeep,
    /// The leaves are consistent but cover only some of the triangles.
    #[error("BVH leaves cover {covered} of {triangles} triangles")]
    Coverage {
        /// Triangles the leaves cover, fewer than `triangles`.
        covered: usize,
        /// Triangles the BVH holds (one per id).
        triangles: usize,
    },
}

impl Bvh {
    /// The nodes (root first), the triangles in leaf order and their scene-wide ids. The
    /// triangles are gathered from the traversal form's `Triangle4`s (their only copy) into a new
    /// vector.
    pub fn parts(&self) -> (&[Node], Vec<[Vec3; 3]>, &[u32]) {
        let mut triangles = vec![[Vec3::ZERO; 3]; self.ids.len()];
        for p in &self.triangles {
            let first = p.first as usize;
            for (lane, t) in triangles[first..first + p.lanes as usize]
                .iter_mut()
                .enumerate()
            {
                *t = p.corners(lane);
            }
        }
        (&self.nodes, triangles, &self.ids)
    }

    /// Reassembles a BVH from [`Bvh::parts`] output: `ids.len()` triangles, where `corners(t)`
    /// is leaf-order triangle `t`. Checks that children come after their parent, the depth
    /// stays within the traversal stack, and the leaves, visited depth first (left child
    /// first), cover the triangles exactly once and in order, as [`Bvh::build`] lays them out.
    /// Only after these checks pass, `corners` is called once for each `t < ids.len()`.
    pub fn from_parts(
        nodes: Vec<Node>,
        ids: Vec<u32>,
        corners: impl Fn(usize) -> [Vec3; 3],
    ) -> Result<Bvh, BvhPartsError> {
        let triangles = ids.len();
        if nodes.is_empty() {
            if triangles == 0 {
                return Ok(Bvh::assemble(nodes, ids, corners));
            }
            return Err(BvhPartsError::NoNodes);
        }
        let mut covered = 0usize;
        let mut stack = vec![(0usize, 1usize)];
        let mut visited = 0usize;
        while let Some((index, depth)) = stack.pop() {
            visited += 1;
            if depth > MAX_DEPTH || visited > nodes.len() {
                return Err(BvhPartsError::TooDeep);
            }
            let n = nodes[index];
            let bad = |problem: String| BvhPartsError::BadNode {
                node: index,
                problem,
            };
            if n.count == 0 {
                let left = n.first as usize;
                if left <= index || left + 1 >= nodes.len() {
                    return Err(bad(format!("children at {left} out of order or range")));
                }
                stack.push((left + 1, depth + 1));
                stack.push((left, depth + 1));
            } else {
                if n.first as usize != covered {
                    return Err(bad(format!(
                        "leaf starts at triangle {}, expected {covered}",
                        n.first
                    )));
                }
                // `covered <= triangles` holds here, so neither side can overflow.
                if n.count as usize > triangles - covered {
                    let end = u64::from(n.first) + u64::from(n.count);
                    return Err(bad(format!("leaf ends at {end} past {triangles}")));
                }
                covered += n.count as usize;
            }
        }
        if covered != triangles {
            return Err(BvhPartsError::Coverage { covered, triangles });
        }
        Ok(Bvh::assemble(nodes, ids, corners))
    }
}
