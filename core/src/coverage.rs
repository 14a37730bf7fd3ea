//! How much of the image a scene covers: an estimate of the fraction of camera samples that
//! hit a surface, without a BVH, for the models that predict a job's time before it runs (the
//! shuffle records and shadow rays of a job are made for hits only).
//!
//! The scene's triangles are rasterized onto a coarse grid of sample points spread over the
//! image ([`GRID_CELLS`] along its longer side, one point at each cell's centre), clipped first
//! against a plane just in front of the eye; the estimate is the fraction of points some
//! triangle covers. It is what a grid of camera rays through those points would find, up to
//! rays that pass exactly along an edge: exact for the probe grid, an estimate for the image.
//! Its cost is one projection per triangle and one test per point inside a triangle's box.

use crate::camera::Camera;
use crate::scene::Mesh;
use glam::{DVec2, DVec3};

/// Sample points along the image's longer side (fewer when the image has fewer pixels).
pub const GRID_CELLS: u32 = 96;

/// The fraction (0 to 1) of a `width` x `height` image's sample grid that `mesh`'s triangles
/// cover, seen by `camera` (see the module documentation); 0 for an empty mesh.
pub fn camera_hit_fraction(mesh: &Mesh, camera: &Camera, width: u32, height: u32) -> f64 {
    let longer = width.max(height).max(1);
    let cells = GRID_CELLS.min(longer);
    let gw = (u64::from(width) * u64::from(cells))
        .div_ceil(u64::from(longer))
        .max(1) as usize;
    let gh = (u64::from(height) * u64::from(cells))
        .div_ceil(u64::from(longer))
        .max(1) as usize;
    let scale = DVec2::new(gw as f64 / f64::from(width), gh as f64 / f64::from(height));
    let mut covered = vec![false; gw * gh];
    for t in 0..mesh.triangle_count() {
        let view = mesh.corners(t).map(|c| camera.to_view(c.as_dvec3()));
        let near = NEAR * view.iter().map(|v| v.length()).fold(0.0, f64::max);
        let polygon = clip_in_front(&view, near);
        if polygon.len() < 3 {
            continue;
        }
        let points: Vec<DVec2> = polygon
            .iter()
            .map(|&v| DVec2::from(camera.view_to_image(v)) * scale)
            .collect();
        for i in 1..points.len() - 1 {
            cover(&mut covered, gw, gh, [points[0], points[i], points[i + 1]]);
        }
    }
    covered.iter().filter(|&&c| c).count() as f64 / covered.len() as f64
}

/// The near plane's distance from the eye, relative to the triangle's farthest corner.
const NEAR: f64 = 1e-9;

/// The part of triangle `view` (camera frame) with `z >= near`, as a convex polygon of up to
/// four corners (none when the triangle lies wholly behind the plane).
fn clip_in_front(view: &[DVec3; 3], near: f64) -> Vec<DVec3> {
    let mut out = Vec::with_capacity(4);
    for i in 0..3 {
        let (a, b) = (view[i], view[(i + 1) % 3]);
        let (a_in, b_in) = (a.z >= near, b.z >= near);
        if a_in {
            out.push(a);
        }
        if a_in != b_in {
            let t = (near - a.z) / (b.z - a.z);
            let mut p = a + (b - a) * t;
            p.z = near;
            out.push(p);
        }
    }
    out
}

/// Marks the grid points (cell centres of a `gw` x `gh` grid) inside triangle `tri` (grid
/// units, either winding, edges included).
fn cover(covered: &mut [bool], gw: usize, gh: usize, tri: [DVec2; 3]) {
    let lo = tri[0].min(tri[1]).min(tri[2]);
    let hi = tri[0].max(tri[1]).max(tri[2]);
    if !(lo.is_finite() && hi.is_finite()) {
        return;
    }
    // Cell centres x + 0.5 inside [lo, hi].
    let first = |v: f64| (v - 0.5).ceil().max(0.0);
    let last = |v: f64, n: usize| (v - 0.5).floor().min(n as f64 - 1.0);
    let (x0, x1) = (first(lo.x), last(hi.x, gw));
    let (y0, y1) = (first(lo.y), last(hi.y, gh));
    if x0 > x1 || y0 > y1 {
        return;
    }
    let edge = |a: DVec2, b: DVec2, p: DVec2| (b - a).perp_dot(p - a);
    let area = edge(tri[0], tri[1], tri[2]);
    if area == 0.0 {
        return;
    }
    for y in y0 as usize..=y1 as usize {
        for x in x0 as usize..=x1 as usize {
            let p = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
            let inside = (0..3).all(|i| edge(tri[i], tri[(i + 1) % 3], p) * area >= 0.0);
            if inside {
                covered[y * gw + x] = true;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{CameraSpec, NO_NORMAL};
    use glam::Vec3;

    fn camera(width: u32, height: u32) -> Camera {
        let spec = CameraSpec {
            eye: DVec3::new(0.0, 0.0, 5.0),
            look_at: DVec3::ZERO,
            up: DVec3::Y,
            vfov_degrees: 90.0,
        };
        Camera::new(&spec, width, height).unwrap()
    }

    fn mesh(triangles: &[[Vec3; 3]]) -> Mesh {
        let n = triangles.len() as u32;
        Mesh {
            positions: triangles.iter().flatten().copied().collect(),
            triangles: (0..n).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect(),
            triangle_normals: vec![[NO_NORMAL; 3]; n as usize],
            triangle_materials: vec![0; n as usize],
            ..Mesh::default()
        }
    }

    /// A square of half-size `h` in the plane z = `z`, facing the camera.
    fn square(h: f32, z: f32) -> [[Vec3; 3]; 2] {
        let (a, b, c, d) = (
            Vec3::new(-h, -h, z),
            Vec3::new(h, -h, z),
            Vec3::new(h, h, z),
            Vec3::new(-h, h, z),
        );
        [[a, b, c], [a, c, d]]
    }

    #[test]
    fn a_square_covers_its_share_of_the_grid() {
        // At distance 5 with a 90° field of view the image spans -5..5: a square of half-size
        // 2.5 covers the middle half of each axis, a quarter of a square image.
        let f = camera_hit_fraction(&mesh(&square(2.5, 0.0)), &camera(96, 96), 96, 96);
        assert_eq!(f, 0.25);
    }

    #[test]
    fn a_wall_filling_the_view_covers_everything_and_nothing_behind_the_eye_counts() {
        let wall = mesh(&square(100.0, 0.0));
        assert_eq!(camera_hit_fraction(&wall, &camera(64, 48), 64, 48), 1.0);
        let behind = mesh(&square(100.0, 10.0));
        assert_eq!(camera_hit_fraction(&behind, &camera(64, 48), 64, 48), 0.0);
        assert_eq!(
            camera_hit_fraction(&Mesh::default(), &camera(8, 8), 8, 8),
            0.0
        );
    }

    #[test]
    fn a_floor_passing_under_the_eye_is_clipped_not_mirrored() {
        // The plane y = -1 from behind the eye to far in front: it covers the image's lower
        // half (below the horizon), and nothing above it.
        let floor = mesh(&[
            [
                Vec3::new(-100.0, -1.0, 100.0),
                Vec3::new(100.0, -1.0, 100.0),
                Vec3::new(100.0, -1.0, -100.0),
            ],
            [
                Vec3::new(-100.0, -1.0, 100.0),
                Vec3::new(100.0, -1.0, -100.0),
                Vec3::new(-100.0, -1.0, -100.0),
            ],
        ]);
        let f = camera_hit_fraction(&floor, &camera(96, 96), 96, 96);
        assert!((0.45..=0.5).contains(&f), "{f}");
    }
}
