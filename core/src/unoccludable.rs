//! Lights no surface of the scene can occlude: their shadow rays are not traced (a skip the
//! report names), because every one of them would come back unblocked.
//!
//! **The test.** A shadow segment runs from a point `p` on some triangle to the light `L` (or
//! toward a directional light, to infinity). It can only cross triangle `T` if `p` and `L` lie on
//! opposite sides of `T`'s plane. So when, for every triangle `T`, the light and every vertex of
//! the scene lie on the same side of `T`'s plane (or on it), every surface point does too, and
//! no segment crosses any triangle: the light is unoccludable. This holds for the inside of a
//! convex room with the light inside it, a ground plane under any light above it, a single
//! convex object lit from where it faces, and so on; it fails (conservatively) for anything
//! that can cast a shadow on itself or on another part.
//!
//! **Exactness.** Side tests are in f64 on the f32 vertices, with a tolerance of
//! [`RELATIVE_TOLERANCE`] times the plane normal's length times the scene's diagonal, so
//! vertices of neighbouring triangles that lie in the same plane count as on it. A light within
//! that tolerance of some triangle's plane is not skipped. Grazing segments (through a shared
//! edge of two coplanar triangles) are the only case where the real traversal could disagree,
//! and there the segment only touches an edge of a triangle it would not enter.
//!
//! **Vertex normals.** On a triangle whose vertex normals bend away from its plane, shading
//! decides a light's side with the interpolated normal and starts the shadow ray from a point
//! off the surface ([`crate::shading::shadow_point`], the terminator fix): a segment may then run
//! from in front of the triangle to a light behind it, or start on the far side of some plane
//! from the vertices, which the test above does not cover. So a mesh with such a triangle
//! (normals more than [`PARALLEL_TOLERANCE`] off the plane normal, or not all to one side)
//! makes every light occludable. Normals along the plane normal (flat shading written out as
//! normals) keep the test.
//!
//! **Determinism.** The answer depends only on the triangles and the lights, so the monolithic
//! renderer and every task of a pipeline (which take it from the plan) skip the same shadow
//! rays and the images stay bit-identical.
//!
//! **Cost.** Per light, every triangle's plane is first tested against the 8 corners of the
//! scene's bounding box (all on the light's side: nothing more to check), else against the
//! vertices one by one until one lies on the far side (the light can be occluded: stop). The
//! scan is capped at [`WORK_LIMIT`] vertex tests per light; past that the light counts as
//! occludable, so the test never costs more than a few tens of milliseconds.

use crate::scene::{Light, Mesh};
use glam::DVec3;

/// Side-test tolerance, relative to `|n| * diagonal` (n: the unnormalised plane normal).
pub const RELATIVE_TOLERANCE: f64 = 1e-9;

/// Most vertex-against-plane tests spent on one light before it counts as occludable.
pub const WORK_LIMIT: u64 = 50_000_000;

/// Largest sine of the angle between a vertex normal and its triangle's plane normal for the
/// normal to count as along it (see the module documentation, "Vertex normals").
pub const PARALLEL_TOLERANCE: f64 = 1e-6;

/// Whether triangle `t`'s vertex normals bend its shading away from its plane: some normal is
/// more than [`PARALLEL_TOLERANCE`] off the plane normal, or they do not all face one side.
fn bends_normals(mesh: &Mesh, t: usize) -> bool {
    let ids = mesh.triangle_normals[t];
    // Shading uses vertex normals when the first corner has one (crate::render::shading_of).
    if ids[0] == crate::scene::NO_NORMAL {
        return false;
    }
    if ids.contains(&crate::scene::NO_NORMAL) {
        return true;
    }
    let [a, b, c] = mesh.corners(t).map(|v| v.as_dvec3());
    let plane = (b - a).cross(c - a);
    if plane == DVec3::ZERO {
        // No area: never hit, so never shaded.
        return false;
    }
    let sides = ids.map(|i| {
        let n = mesh.normals[i as usize].as_dvec3();
        let scale = n.length() * plane.length();
        let along = n.cross(plane).length() <= PARALLEL_TOLERANCE * scale;
        if along { n.dot(plane).signum() } else { 0.0 }
    });
    !(sides.iter().all(|&s| s == 1.0) || sides.iter().all(|&s| s == -1.0))
}

/// For each light of `lights`, whether no triangle of `mesh` can occlude any shadow ray toward
/// it (see the module documentation). An empty mesh occludes nothing.
pub fn unoccludable_lights(mesh: &Mesh, lights: &[Light]) -> Vec<bool> {
    if (0..mesh.triangle_count()).any(|t| bends_normals(mesh, t)) {
        return vec![false; lights.len()];
    }
    let mut used = vec![false; mesh.positions.len()];
    for t in &mesh.triangles {
        for &i in t {
            used[i as usize] = true;
        }
    }
    let vertices: Vec<DVec3> = mesh
        .positions
        .iter()
        .zip(&used)
        .filter(|(_, u)| **u)
        .map(|(p, _)| p.as_dvec3())
        .collect();
    let (lo, hi) = vertices.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), v| (lo.min(*v), hi.max(*v)),
    );
    let diagonal = if vertices.is_empty() {
        0.0
    } else {
        (hi - lo).length()
    };
    let corners: Vec<DVec3> = (0..8)
        .map(|i| {
            DVec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        })
        .collect();
    lights
        .iter()
        .map(|light| {
            let mut work = 0u64;
            (0..mesh.triangle_count()).all(|t| {
                let [a, b, c] = mesh.corners(t).map(|v| v.as_dvec3());
                let n = (b - a).cross(c - a);
                let tolerance = RELATIVE_TOLERANCE * n.length() * diagonal;
                if n == DVec3::ZERO {
                    // No area: nothing to cross.
                    return true;
                }
                // The light's side of the plane, as a sign; a light on the plane fails.
                let light_side = match *light {
                    Light::Point { position, .. } => n.dot(position - a),
                    Light::Directional { direction, .. } => -n.dot(direction) * diagonal.max(1.0),
                };
                // (A NaN side fails too: coordinates are finite, but stay safe.)
                if light_side.abs() <= tolerance || light_side.is_nan() {
                    return false;
                }
                let sign = light_side.signum();
                let on_light_side = |v: &DVec3| sign * n.dot(*v - a) >= -tolerance;
                if corners.iter().all(on_light_side) {
                    return true;
                }
                for v in &vertices {
                    work += 1;
                    if work > WORK_LIMIT || !on_light_side(v) {
                        return false;
                    }
                }
                true
            })
        })
        .collect()
}

#[cfg(test)]
mod tests;
