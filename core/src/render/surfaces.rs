//! Where a render finds the shading data of the triangles its BVH hits: the scene's mesh (the
//! monolithic renderer, triangle ids in scene order) or a split object (a fused task, shading
//! in the split's leaf order). Both give the same surface for the same triangle, so a render
//! through either has the same bits.

use super::{flat_kd, kd_with, shading_of, surface_with};
use crate::bvh::{Bvh, ClosestHit};
use crate::pipeline::{SplitObject, TriangleShading};
use crate::scene::Mesh;
use crate::shading::{LastFrame, SurfacePoint, surface_point_on};
use crate::triangle::Ray;
use glam::Vec3;

/// The shading data of hit triangles.
pub trait Surfaces {
    /// The reflectance of the hit triangle when it is flat (no vertex normals) and
    /// untextured, which is then the `kd` of [`Surfaces::surface`]; else `None`.
    fn flat_kd(&self, hit: &ClosestHit) -> Option<[f32; 3]>;

    /// The hit triangle's vertex normals (zeros for a triangle without: the same surface point)
    /// and the reflectance at the hit, textured or not: what
    /// [`crate::shading::FlatShader::smooth_tests4`] takes of a hit.
    fn lane_shading(&self, hit: &ClosestHit) -> ([Vec3; 3], [f32; 3]);

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
    fn lane_shading(&self, hit: &ClosestHit) -> ([Vec3; 3], [f32; 3]) {
        let s = shading_of(self, hit.id);
        (s.normals.unwrap_or([Vec3::ZERO; 3]), kd_with(self, &s, hit))
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

    #[inline]
    fn lane_shading(&self, hit: &ClosestHit) -> ([Vec3; 3], [f32; 3]) {
        let shading = shading_at(self, hit);
        let kd = self.kd_at(&shading, hit.b);
        (shading.normals.unwrap_or([Vec3::ZERO; 3]), kd)
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
        let shading = shading_at(self, hit);
        let corners = bvh.hit_corners(hit).corners();
        let frame = last.of(hit.index, || (corners, shading.normals));
        let kd = self.kd_at(&shading, hit.b);
        surface_point_on(frame, corners, hit.b, ray.dir, shading.normals, kd)
    }
}

/// The shading of the split's triangle that `hit` (found by the split's BVH) is on.
#[inline]
fn shading_at(split: &SplitObject, hit: &ClosestHit) -> TriangleShading {
    split
        .shading
        .get(hit.index as usize)
        .expect("a split's shading covers its BVH's triangles (decode_split checks it)")
}
