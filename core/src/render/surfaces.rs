//! Where a render finds the shading data of the triangles its BVH hits: the scene's mesh (the
//! monolithic renderer, triangle ids in scene order) or a split object (a fused task, shading
//! in the split's leaf order). Both give the same surface for the same triangle, so a render
//! through either has the same bits.

use super::{flat_kd, surface_of};
use crate::bvh::{Bvh, ClosestHit};
use crate::pipeline::SplitObject;
use crate::scene::Mesh;
use crate::shading::{SurfacePoint, surface_point};
use crate::triangle::Ray;

/// The shading data of hit triangles.
pub trait Surfaces {
    /// The reflectance of the hit triangle when it is flat (no vertex normals) and
    /// untextured, which is then the `kd` of [`Surfaces::surface`]; else `None`.
    fn flat_kd(&self, hit: &ClosestHit) -> Option<[f32; 3]>;

    /// The surface point of `hit`, found by `bvh` along `ray`.
    fn surface(&self, bvh: &Bvh, hit: &ClosestHit, ray: &Ray) -> SurfacePoint;
}

impl Surfaces for Mesh {
    #[inline]
    fn flat_kd(&self, hit: &ClosestHit) -> Option<[f32; 3]> {
        flat_kd(self, hit.id)
    }

    #[inline]
    fn surface(&self, bvh: &Bvh, hit: &ClosestHit, ray: &Ray) -> SurfacePoint {
        surface_of(self, bvh, hit, ray)
    }
}

impl Surfaces for SplitObject {
    #[inline]
    fn flat_kd(&self, hit: &ClosestHit) -> Option<[f32; 3]> {
        self.shading.flat_kd(hit.index as usize)
    }

    /// `bvh` is the split's own.
    #[inline]
    fn surface(&self, bvh: &Bvh, hit: &ClosestHit, ray: &Ray) -> SurfacePoint {
        let shading = self
            .shading
            .get(hit.index as usize)
            .expect("a split's shading covers its BVH's triangles (decode_split checks it)");
        surface_point(
            bvh.hit_corners(hit).corners(),
            hit.b,
            ray.dir,
            shading.normals,
            self.kd_at(&shading, hit.b),
        )
    }
}
