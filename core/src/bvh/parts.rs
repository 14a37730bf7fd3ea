//! Taking a built BVH apart into flat arrays and putting it back without rebuilding, for split
//! objects. Reassembly validates everything traversal relies on, so a corrupt or hostile split
//! object gives an error, never a panic or an endless loop.

use super::build::MAX_DEPTH;
use super::{Bvh, Node};
use glam::Vec3;

/// Why stored BVH arrays cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BvhPartsError {
    #[error("BVH has {triangles} triangles but {ids} ids")]
    LengthMismatch { triangles: usize, ids: usize },
    #[error("BVH node {node}: {problem}")]
    BadNode { node: usize, problem: String },
    #[error("BVH with triangles has no nodes")]
    NoNodes,
    #[error("BVH is deeper than {MAX_DEPTH} levels")]
    TooDeep,
    #[error("BVH leaves cover {covered} of {triangles} triangles")]
    Coverage { covered: usize, triangles: usize },
}

impl Bvh {
    /// The nodes (root first), the triangles in leaf order and their scene-wide ids.
    pub fn parts(&self) -> (&[Node], &[[Vec3; 3]], &[u32]) {
        (&self.nodes, &self.triangles, &self.ids)
    }

    /// Reassembles a BVH from [`Bvh::parts`] output, checking that children come after their
    /// parent, leaves stay inside the triangle array and cover it exactly once, and the depth
    /// stays within the traversal stack.
    pub fn from_parts(
        nodes: Vec<Node>,
        triangles: Vec<[Vec3; 3]>,
        ids: Vec<u32>,
    ) -> Result<Bvh, BvhPartsError> {
        if triangles.len() != ids.len() {
            return Err(BvhPartsError::LengthMismatch {
                triangles: triangles.len(),
                ids: ids.len(),
            });
        }
        if nodes.is_empty() {
            if triangles.is_empty() {
                return Ok(Bvh::assemble(nodes, triangles, ids));
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
                let end = n.first as usize + n.count as usize;
                if end > triangles.len() {
                    return Err(bad(format!("leaf ends at {end} past {}", triangles.len())));
                }
                covered += n.count as usize;
            }
        }
        if covered != triangles.len() {
            return Err(BvhPartsError::Coverage {
                covered,
                triangles: triangles.len(),
            });
        }
        Ok(Bvh::assemble(nodes, triangles, ids))
    }
}
