//! What a surface point takes from its triangle alone, the same for every hit on it: the unit
//! geometric normal before it is turned to face the ray, and the unit vertex normals. Hits on
//! one triangle come together in a renderer's batches (a packet's rays cover a small square of
//! a pixel or of the image), so [`LastFrame`] makes a triangle's frame once for a run of hits
//! on it: four of the five square roots and divisions of a smooth surface point.

use glam::Vec3;

/// A triangle's unit geometric normal (`(p1 - p0) × (p2 - p0)`, not yet turned to face a ray)
/// and its unit vertex normals (each `normalize_or_zero`), as [`super::surface_point`] would
/// compute them for any hit on it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TriangleFrame {
    pub(super) n_geo: Vec3,
    pub(super) unit_normals: Option<[Vec3; 3]>,
}

impl TriangleFrame {
    /// The frame of the triangle with `corners` and vertex `normals` (if any).
    #[inline]
    pub fn new(corners: [Vec3; 3], normals: Option<[Vec3; 3]>) -> Self {
        let [p0, p1, p2] = corners;
        TriangleFrame {
            n_geo: (p1 - p0).cross(p2 - p0).normalize_or_zero(),
            unit_normals: normals.map(|n| n.map(Vec3::normalize_or_zero)),
        }
    }
}

/// The frame of the last triangle asked for, kept until another is: for hits of one BVH,
/// keyed by the triangle's leaf-order index.
#[derive(Clone, Copy, Debug, Default)]
pub struct LastFrame {
    index: Option<u32>,
    frame: TriangleFrame,
}

impl LastFrame {
    /// The frame of the triangle at leaf-order `index`, whose corners and vertex normals
    /// `triangle` gives (called only when the triangle differs from the last one asked for).
    #[inline]
    pub fn of(
        &mut self,
        index: u32,
        triangle: impl FnOnce() -> ([Vec3; 3], Option<[Vec3; 3]>),
    ) -> &TriangleFrame {
        if self.index != Some(index) {
            let (corners, normals) = triangle();
            self.frame = TriangleFrame::new(corners, normals);
            self.index = Some(index);
        }
        &self.frame
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shading::tests::rng;
    use crate::shading::{surface_point, surface_point_on};

    /// What the frame relies on: a negated vector normalises to the negated unit vector, bit
    /// for bit, at every scale (the zero fallback aside, which is +0 either way before the
    /// negation and never moves a shadow point).
    #[test]
    fn normalising_commutes_with_negation() {
        let mut r = rng(5);
        for scale in [1e-30f32, 1e-3, 1.0, 7e3, 1e30] {
            for _ in 0..2000 {
                let v = Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5) * scale;
                let (a, b) = ((-v).normalize_or_zero(), -(v.normalize_or_zero()));
                if a != Vec3::ZERO {
                    assert_eq!(
                        a.to_array().map(f32::to_bits),
                        b.to_array().map(f32::to_bits)
                    );
                }
            }
        }
    }

    /// Hits on one triangle after another, each triangle hit from both sides with vertex
    /// normals toward either side (or none, or zero): the points made with the last frame kept
    /// are the points made alone.
    #[test]
    fn a_kept_frame_gives_the_points_made_alone() {
        let mut r = rng(17);
        let mut last = LastFrame::default();
        let bits = |s: &crate::shading::SurfacePoint| format!("{s:?}");
        for triangle in 0..300u32 {
            let mut v = || Vec3::new(r() * 4.0 - 2.0, r() * 2.0 - 1.0, r() * 4.0 - 2.0);
            let corners = [v(), v(), v()];
            let normals = match triangle % 4 {
                0 => None,
                1 => Some([Vec3::ZERO; 3]),
                _ => Some([v(), v(), v()]),
            };
            // The same index twice in a row only for the same triangle.
            for k in 0..6 {
                let b1 = r() * 0.5;
                let b2 = r() * 0.5;
                let b = [1.0 - b1 - b2, b1, b2];
                let dir = Vec3::new(r() - 0.5, r() - 0.5, if k % 2 == 0 { 1.0 } else { -1.0 });
                let frame = last.of(triangle, || (corners, normals));
                let kept = surface_point_on(frame, corners, b, dir, normals, [0.5; 3]);
                let alone = surface_point(corners, b, dir, normals, [0.5; 3]);
                assert_eq!(bits(&kept), bits(&alone), "triangle {triangle}, hit {k}");
            }
        }
    }
}
