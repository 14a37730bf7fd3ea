//! Where a render finds the shading data of the triangles its BVH hits: the scene's mesh (the
//! monolithic renderer, triangle ids in scene order) or a split object (a fused task, shading
//! in the split's leaf order). Both give the same surface for the same triangle, so a render
//! through either has the same bits.

use super::{flat_kd, shading_of};
use crate::bvh::{Bvh, ClosestHit};
use crate::pipeline::SplitObject;
use crate::scene::{Mesh, TriangleShading};
use crate::shading::{LastFrame, SurfacePoint, surface_point_on};
use crate::texture::{Texture, TexturedCorners};
use crate::triangle::Ray;
use glam::Vec3;

/// The shading data of hit triangles.
pub trait Surfaces {
    /// The reflectance of the hit triangle when it is flat (no vertex normals) and
    /// untextured; else `None`.
    fn flat_kd(&self, hit: &ClosestHit) -> Option<[f32; 3]>;

    /// The hit triangle's shading data: its vertex normals, material reflectance and texture.
    fn shading(&self, hit: &ClosestHit) -> TriangleShading;

    /// The texture a textured triangle's shading data (from [`Surfaces::shading`]) names.
    fn texture(&self, corners: &TexturedCorners) -> &Texture;

    /// The reflectance at barycentrics `b` of a triangle whose shading data is `shading`
    /// (from [`Surfaces::shading`]): its material's, times its texture where it has one.
    #[inline]
    fn kd_on(&self, shading: &TriangleShading, b: [f32; 3]) -> [f32; 3] {
        match &shading.texture {
            None => shading.kd,
            Some(t) => t.kd_at(shading.kd, self.texture(t), b),
        }
    }

    /// The hit triangle's vertex normals, if it has them, and the reflectance at the hit,
    /// textured or not.
    #[inline]
    fn normals_and_kd(&self, hit: &ClosestHit) -> (Option<[Vec3; 3]>, [f32; 3]) {
        let shading = self.shading(hit);
        (shading.normals, self.kd_on(&shading, hit.b))
    }

    /// The surface point of `hit`, found by `bvh` along `ray`; the triangle's frame is taken
    /// from `last`, which keeps the frame of the last triangle of `bvh` it was asked for.
    #[inline]
    fn surface(
        &self,
        bvh: &Bvh,
        hit: &ClosestHit,
        ray: &Ray,
        last: &mut LastFrame,
    ) -> SurfacePoint {
        let (normals, kd) = self.normals_and_kd(hit);
        let corners = bvh.hit_corners(hit).corners();
        let frame = last.of(hit.index, || (corners, normals));
        surface_point_on(frame, corners, hit.b, ray.dir, normals, kd)
    }
}

impl Surfaces for Mesh {
    #[inline]
    fn flat_kd(&self, hit: &ClosestHit) -> Option<[f32; 3]> {
        flat_kd(self, hit.id)
    }

    #[inline]
    fn shading(&self, hit: &ClosestHit) -> TriangleShading {
        shading_of(self, hit.id)
    }

    #[inline]
    fn texture(&self, corners: &TexturedCorners) -> &Texture {
        &self.textures[corners.texture as usize]
    }
}

/// A split's hits are found by its own BVH (`hit.index` is a leaf-order index into its
/// shading).
impl Surfaces for SplitObject {
    #[inline]
    fn flat_kd(&self, hit: &ClosestHit) -> Option<[f32; 3]> {
        self.shading.flat_kd(hit.index as usize)
    }

    #[inline]
    fn shading(&self, hit: &ClosestHit) -> TriangleShading {
        self.shading
            .get(hit.index as usize)
            .expect("a split's shading covers its BVH's triangles (decode_split checks it)")
    }

    #[inline]
    fn texture(&self, corners: &TexturedCorners) -> &Texture {
        self.attached_texture(corners.texture)
    }
}
