//! Where a hit's triangle corners are read from: the BVH's own `Triangle4`s, so a closest hit
//! carries only its place and shading reads the corners where traversal left them (in cache).

use glam::Vec3;

/// One triangle's corners in a four-lane layout, `v[corner][axis][lane]` at lane `lane`: a
/// [`super::Bvh`]'s storage of its triangles ([`super::Bvh::hit_corners`]), or any such array.
#[derive(Clone, Copy, Debug)]
pub struct CornerLanes<'a> {
    v: &'a [[[f32; 4]; 3]; 3],
    lane: usize,
}

impl<'a> CornerLanes<'a> {
    /// The corners at lane `lane` of `v`. Panics unless `lane < 4`.
    pub fn new(v: &'a [[[f32; 4]; 3]; 3], lane: usize) -> Self {
        assert!(lane < 4, "lane {lane} of four");
        CornerLanes { v, lane }
    }

    /// Corner `c` (0, 1 or 2).
    #[inline(always)]
    pub fn corner(&self, c: usize) -> Vec3 {
        let v = &self.v[c];
        Vec3::new(v[0][self.lane], v[1][self.lane], v[2][self.lane])
    }

    /// The three corners.
    #[inline(always)]
    pub fn corners(&self) -> [Vec3; 3] {
        [self.corner(0), self.corner(1), self.corner(2)]
    }
}
