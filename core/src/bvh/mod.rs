//! A bounding volume hierarchy over triangles: binned-SAH build of a binary tree, collapsed into
//! 4-wide nodes whose leaves are `Triangle4`s (four triangles stored axis by axis) for traversal
//! with 4-wide box and triangle tests; the binary tree is dropped after collapsing. Split objects
//! store the 4-wide form without its boxes (`parts.rs`), which both building and loading derive
//! from the triangles (`refit.rs`). Layout, measurements
//! against native Embree and where time goes: `README.md` in this folder.
//!
//! Vocabulary: a `Triangle4` is four triangles of one leaf tested at once (`node4.rs`,
//! `simd4.rs`); a ray packet is [`RAY_PACKET`] neighbouring rays traversing together, either a
//! closest-hit packet of camera rays (`ray_packet.rs`) or a segment packet of shadow segments
//! (`segment_packet.rs`).
//!
//! Guarantees:
//! - [`Bvh::closest_hit`] returns exactly what a brute-force loop over all triangles returns with
//!   the order "smaller t, then smaller triangle id" (same triangle, same t bits): box culling is
//!   conservative and the triangle test ([`crate::triangle::intersect`]) is a pure function.
//!   Hence the answer never depends on how triangles are grouped into BVHs or splits.
//! - [`Bvh::closest_hits`] (closest-hit ray packets) gives every ray exactly
//!   [`Bvh::closest_hit`]'s answer.
//! - [`Bvh::occluded`] is true exactly when some triangle has a hit with `0 < t < t_max`, and
//!   [`Bvh::occluded_many`] (segment packets) gives every segment exactly its answer.
//! - Building is deterministic: the same triangles in the same order give the same nodes, on
//!   any number of threads.

mod build;
mod build_morton;
#[cfg(test)]
mod build_reference;
#[cfg(test)]
mod build_tests;
mod dispatch;
mod hit_columns;
mod hit_corners;
mod lanes;
mod leaf_lanes;
mod node4;
mod packet_boxes;
mod packet_hits;
mod packet_rays;
mod packet_setup;
mod parts;
mod ray_packet;
mod refit;
mod segment_columns;
mod segment_groups;
mod segment_packet;
mod simd4;
mod traverse;

pub use dispatch::{
    KernelWidth, WIDTH_VARIABLE, available_kernel_widths, force_kernel_width, kernel_width,
};
pub use hit_columns::HitColumns;
pub use hit_corners::CornerLanes;
pub use parts::{BvhParts, BvhPartsError, NODE_BYTES, PartsLoader};
pub use ray_packet::{CLOSEST_PACKET, ClosestPackets, RAY_PACKET, camera_packet};
pub(crate) use ray_packet::{bits, first_bits};
pub use segment_columns::SegmentColumns;
pub use segment_groups::SegmentGroups;
pub use traverse::{ClosestHit, segment_may_hit};

use glam::Vec3;

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner, per axis; `lo > hi` on some axis means the box is empty.
    pub lo: Vec3,
    /// Maximum corner, per axis (inclusive).
    pub hi: Vec3,
}

impl Aabb {
    /// The empty box (min = +inf, max = -inf); growing it by any point gives that point.
    pub const EMPTY: Aabb = Aabb {
        lo: Vec3::splat(f32::INFINITY),
        hi: Vec3::splat(f32::NEG_INFINITY),
    };

    /// The smallest box holding the three corners.
    pub fn of_triangle(t: &[Vec3; 3]) -> Aabb {
        Aabb {
            lo: t[0].min(t[1]).min(t[2]),
            hi: t[0].max(t[1]).max(t[2]),
        }
    }

    /// The smallest box holding both.
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }

    /// Half the surface area (enough for SAH ratios); 0 for an empty box.
    pub fn half_area(&self) -> f32 {
        let d = (self.hi - self.lo).max(Vec3::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    }
}

/// How a BVH is constructed: a trade between build time and ray speed. A job plan records
/// its split objects' preset (`"quality"` or `"fast"`), so a task rebuilding a lost one makes
/// the same bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BuildPreset {
    /// Binned SAH (`build.rs`): the faster tree, for trees that serve many rays.
    #[default]
    Quality,
    /// Morton order (`build_morton.rs`): a several times faster build of a slower tree, for
    /// trees that serve few rays.
    Fast,
}

impl BuildPreset {
    /// Below this many camera samples per triangle the fast preset wins. Measured on one core
    /// with one point light (a camera ray and a shadow ray per sample; 1M and 2M generated
    /// triangles, docs/perf/time-per-sample.md, "Build presets"): the fast build saves about
    /// 300 ns per triangle and its tree costs 30 to 45 ns more per sample, so it pays up to 7
    /// to 10 samples per triangle; this keeps well inside that.
    pub const FAST_BELOW_SAMPLES_PER_TRIANGLE: u64 = 4;

    /// The preset for a tree over `triangles` that will serve the rays of about `samples`
    /// camera samples (and their shadow rays).
    pub fn for_samples(samples: u64, triangles: u64) -> BuildPreset {
        if samples < BuildPreset::FAST_BELOW_SAMPLES_PER_TRIANGLE.saturating_mul(triangles) {
            BuildPreset::Fast
        } else {
            BuildPreset::Quality
        }
    }
}

/// One BVH node: its box and either two children (`count == 0`, children at `first` and
/// `first + 1`) or a leaf of `count` triangles starting at `first` in leaf order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node {
    /// A box holding every triangle below the node.
    pub bounds: Aabb,
    /// Inner node: index of the left child (the right is `first + 1`). Leaf: its first
    /// triangle in leaf order.
    pub first: u32,
    /// Triangles in the leaf; 0 marks an inner node.
    pub count: u32,
}

/// A built BVH owning its triangles in leaf order with their scene-wide ids.
#[derive(Clone, Debug, PartialEq)]
pub struct Bvh {
    /// The root's box: every triangle lies in it ([`Aabb::EMPTY`] when there are none).
    bounds: Aabb,
    /// Scene-wide id of each triangle, in leaf order (the order of the `Triangle4`s' lanes).
    ids: Vec<u32>,
    /// Traversal form collapsed from the binary tree (see [`node4`]). The
    /// `Triangle4`s hold the only copy of the triangles: leaf-order triangle `t` is lane
    /// `t - first` of the `Triangle4` whose lanes start at `first`.
    wide: Vec<node4::Node4>,
    triangles: Vec<node4::Triangle4>,
}

impl Bvh {
    /// Builds over `triangles`, where `ids[i]` is the scene-wide id of `triangles[i]` (used for
    /// tie-breaks and reported in hits), on as many threads as the process may use. Panics if
    /// the lengths differ.
    pub fn build(triangles: Vec<[Vec3; 3]>, ids: Vec<u32>) -> Bvh {
        Bvh::build_on_threads(triangles, ids, crate::worker_pool::available_cores())
    }

    /// [`Bvh::build`] on at most `threads` threads (1 or 0: the calling thread only). The BVH
    /// is the same for every thread count.
    pub fn build_on_threads(triangles: Vec<[Vec3; 3]>, ids: Vec<u32>, threads: usize) -> Bvh {
        Bvh::build_preset(triangles, ids, threads, BuildPreset::Quality)
    }

    /// [`Bvh::build_on_threads`] with the given construction. Every preset gives the same
    /// closest hits and occlusion answers (the hit rule does not depend on the tree); they
    /// differ in build time and rays per second.
    pub fn build_preset(
        triangles: Vec<[Vec3; 3]>,
        ids: Vec<u32>,
        threads: usize,
        preset: BuildPreset,
    ) -> Bvh {
        assert_eq!(triangles.len(), ids.len(), "one id per triangle");
        match preset {
            BuildPreset::Quality => build::build(triangles, ids, threads),
            BuildPreset::Fast => {
                let (nodes, order) = build_morton::binary_tree(&triangles);
                let ids_in_order = order.iter().map(|&i| ids[i as usize]).collect();
                Bvh::assemble(nodes, ids_in_order, |t| triangles[order[t] as usize])
            }
        }
    }

    /// Assembles a BVH from valid binary nodes whose leaves cover the `ids.len()` triangles
    /// exactly once: collapses them into the traversal form, whose pack order becomes the leaf
    /// order (`ids` are reordered to match), sets its boxes from the packs as a loaded BVH's
    /// are set ([`refit`]), and keeps only the root's box of the binary ones; `ids[t]` and
    /// `corners(t)` are triangle `t` in the binary tree's leaf order.
    fn assemble(nodes: Vec<Node>, ids: Vec<u32>, corners: impl Fn(usize) -> [Vec3; 3]) -> Bvh {
        let (mut wide, triangles, order) = node4::collapse(&nodes, ids.len(), corners);
        let pack_boxes: Vec<Aabb> = triangles.iter().map(refit::pack_box).collect();
        refit::refit(&mut wide, &pack_boxes);
        Bvh {
            bounds: nodes.first().map_or(Aabb::EMPTY, |n| n.bounds),
            ids: order.iter().map(|&t| ids[t as usize]).collect(),
            wide,
            triangles,
        }
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.ids.len()
    }

    /// The scene-wide id of each triangle, in leaf order.
    pub fn ids(&self) -> &[u32] {
        &self.ids
    }

    /// Bytes this BVH holds in memory (its arrays; what a cache of decoded splits budgets).
    pub fn memory_bytes(&self) -> u64 {
        use std::mem::size_of;
        (self.ids.len() * size_of::<u32>()
            + self.wide.len() * size_of::<node4::Node4>()
            + self.triangles.len() * size_of::<node4::Triangle4>()) as u64
    }

    /// Number of 4-wide nodes (0 when empty).
    pub fn wide_node_count(&self) -> usize {
        self.wide.len()
    }

    /// Number of `Triangle4` packs (each holds 1 to 4 triangles of one leaf).
    pub fn pack_count(&self) -> usize {
        self.triangles.len()
    }

    /// Bounds of everything in the BVH ([`Aabb::EMPTY`] when empty).
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }
}

#[cfg(test)]
pub(crate) mod tests;
