//! Where a render finds the shading data of the triangles its BVH hits: the scene's mesh (the
//! monolithic renderer, triangle ids in scene order) or a split object (a fused task, shading
//! in the split's leaf order). Both give the same surface for the same triangle, so a render
//! through either has the same bits.

use super::{flat_kd, surface_with};
use crate::bvh::{Bvh, ClosestHit};
use crate::pipeline::SplitObject;
use crate::scene::Mesh;
use crate::shading::{LastFrame, SurfacePoint, surface_point_on};
use crate::triangle::Ray;

/// The shading data of hit triangles.
pub trait Surfaces {
    /// The reflectance of the hit triangle when it is flat (no vertex normals) and
    /// untextured, which is then the `kd` of [`Surfaces::surface`]; else `None`.
    fn flat_kd(&self, hit: &ClosestHit) -> Option<[f32; 3]>;

    /// The surface point of `hit`, found by `bvh` along `ray`; the triangle's frame is taken
    /// from `last`, which keeps the frame of the last triangle of `bvh` it was asked for.
    fn surface(&self, bvh: &Bvh, hit: &ClosestHit, ray: &Ray, last: &mut LastFrame)
    -> SurfacePoint;
}

impl Surfaces for Mesh {
    #[inline]
    fn flat_kd(&self, hit: &ClosestHit) -> Option<[f32; 3]> {
        flat_kd(self, hit.id)
    }

    #[inline]
    fn surface(
        &self,
        bvh: &Bvh,
        hit: &ClosestHit,
        ray: &Ray,
        last: &mut LastFrame,
    ) -> SurfacePoint {
        surface_with(self, bvh, hit, ray, last)
    }
}

impl Surfaces for SplitObject {
    #[inline]
    fn flat_kd(&self, hit: &ClosestHit) -> Option<[f32; 3]> {
        self.shading.flat_kd(hit.index as usize)
    }

    /// `bvh` is the split's own.
    #[inline]
    fn surface(
        &self,
        bvh: &Bvh,
        hit: &ClosestHit,
        ray: &Ray,
        last: &mut LastFrame,
    ) -> SurfacePoint {
        let shading = self
            .shading
            .get(hit.index as usize)
            .expect("a split's shading covers its BVH's triangles (decode_split checks it)");
        let corners = bvh.hit_corners(hit).corners();
        let frame = last.of(hit.index, || (corners, shading.normals));
        let kd = self.kd_at(&shading, hit.b);
        surface_point_on(frame, corners, hit.b, ray.dir, shading.normals, kd)
    }
}
