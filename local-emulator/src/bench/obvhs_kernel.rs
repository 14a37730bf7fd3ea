//! The obvhs column set of `hort bench kernel` (only with `--features obvhs-bench`): the crate
//! `obvhs` 0.4 (a compressed 8-wide BVH, "CwBvh", built with its medium preset) on the same
//! scene and the identical primary and shadow rays, traced one ray at a time on this thread, as
//! a user of obvhs would: `build_cwbvh_from_tris(.., BvhBuildParams::medium_build(), ..)`,
//! triangles reordered by `primitive_indices` (as its cornell example does), closest hit with
//! `CwBvh::ray_traverse` and shadow rays with `CwBvh::ray_traverse_miss` (stops at the first
//! hit), both with obvhs's own `Triangle::intersect` (Moeller-Trumbore, not watertight).
//!
//! Semantics against ours: `Triangle::intersect` accepts `tmin <= t <= tmax` and the traversals
//! keep a hit only when `t < tmax`; with `tmin` = the smallest positive f32 that is exactly our
//! `0 < t < t_max` (obvhs's node test starts at f32::EPSILON whatever `tmin` is, and ours
//! also rejects t below pbrt's error bound). Equal t: obvhs keeps the first triangle it
//! visits, ours the smaller id. Without pre-splits (the medium preset has none) every leaf
//! primitive is one input triangle, so `primitive_indices` maps back to the scene's triangle
//! index, which is our `ClosestHit::id`.

use super::table::f3;
use super::timing::best_of;
use hort_core::bvh::ClosestHit;
use hort_core::scene::Scene;
use hort_core::triangle::Ray;
use obvhs::BvhBuildParams;
use obvhs::cwbvh::builder::build_cwbvh_from_tris;
use obvhs::ray::{Ray as ORay, RayHit};
use obvhs::triangle::Triangle;
use std::time::{Duration, Instant};

/// What obvhs measured on one scene.
pub struct ObvhsResult {
    pub build_s: f64,
    pub primary_s: f64,
    pub shadow_s: f64,
    /// Primary rays whose obvhs answer (triangle id, or miss) equals ours.
    pub primary_same_id: u64,
    /// Shadow rays whose obvhs occlusion answer equals ours.
    pub shadow_same: u64,
}

/// Exactly `t > 0` for obvhs's `t >= tmin`.
const T_MIN: f32 = f32::from_bits(1);

fn obvhs_ray(r: &Ray, t_max: f32) -> ORay {
    ORay::new(
        r.origin.to_array().into(),
        r.dir.to_array().into(),
        T_MIN,
        t_max,
    )
}

/// Builds obvhs's CwBvh over `scene.mesh` and traces `primary` (closest hit) and `shadow`
/// (any hit below each t_max) with it; agreement is counted against our `hits` and `occluded`.
pub fn run(
    scene: &Scene,
    primary: &[Ray],
    hits: &[Option<ClosestHit>],
    shadow: &[(Ray, f32)],
    occluded: &[bool],
    repeats: u32,
) -> ObvhsResult {
    let start = Instant::now();
    let n = scene.mesh.triangle_count();
    let tris: Vec<Triangle> = (0..n)
        .map(|i| {
            let [v0, v1, v2] = scene.mesh.corners(i).map(|c| c.to_array().into());
            Triangle { v0, v1, v2 }
        })
        .collect();
    let bvh = build_cwbvh_from_tris(
        &tris,
        BvhBuildParams::medium_build(),
        &mut Duration::default(),
    );
    let bvh_tris: Vec<Triangle> = bvh
        .primitive_indices
        .iter()
        .map(|&i| tris[i as usize])
        .collect();
    let build_s = start.elapsed().as_secs_f64();

    // Output buffers are allocated before timing, as for our kernel and Embree.
    let mut ids = vec![u32::MAX; primary.len()];
    let (primary_s, ()) = best_of(repeats, || {
        for (out, r) in ids.iter_mut().zip(primary) {
            let mut hit = RayHit::none();
            *out = if bvh.ray_traverse(obvhs_ray(r, f32::INFINITY), &mut hit, |ray, id| {
                bvh_tris[id].intersect(ray)
            }) {
                bvh.primitive_indices[hit.primitive_id as usize]
            } else {
                u32::MAX
            };
        }
    });
    let mut blocked = vec![false; shadow.len()];
    let (shadow_s, ()) = best_of(repeats, || {
        for (out, (r, t_max)) in blocked.iter_mut().zip(shadow) {
            *out =
                !bvh.ray_traverse_miss(obvhs_ray(r, *t_max), |ray, id| bvh_tris[id].intersect(ray));
        }
    });

    let primary_same_id = ids
        .iter()
        .zip(hits)
        .filter(|&(&id, h)| id == h.map_or(u32::MAX, |h| h.id))
        .count() as u64;
    let shadow_same = blocked.iter().zip(occluded).filter(|(a, b)| a == b).count() as u64;
    ObvhsResult {
        build_s,
        primary_s,
        shadow_s,
        primary_same_id,
        shadow_same,
    }
}

fn mrays(rays: usize, seconds: f64) -> f64 {
    rays as f64 / seconds.max(1e-12) / 1e6
}

/// Columns appended to the ray table.
pub const RAY_HEADER: [&str; 8] = [
    "obvhs primary",
    "obvhs/Embree",
    "ours/obvhs",
    "obvhs same id %",
    "obvhs shadow",
    "obvhs/Embree",
    "ours/obvhs",
    "obvhs same %",
];

/// The ray-table cells of one scene: `ours` and `embree` are (primary_s, shadow_s).
pub fn ray_cells(
    o: &ObvhsResult,
    primary: usize,
    shadow: usize,
    ours: (f64, f64),
    embree: Option<(f64, f64)>,
) -> Vec<String> {
    let pct = |a: u64, b: usize| format!("{:.2}", 100.0 * a as f64 / b.max(1) as f64);
    let (op, os) = (mrays(primary, o.primary_s), mrays(shadow, o.shadow_s));
    let vs_embree = |ours: f64, rays: usize, embree_s: Option<f64>| {
        embree_s.map_or("-".to_string(), |s| f3(ours / mrays(rays, s)))
    };
    vec![
        format!("{op:.2}"),
        vs_embree(op, primary, embree.map(|e| e.0)),
        f3(mrays(primary, ours.0) / op),
        pct(o.primary_same_id, primary),
        format!("{os:.2}"),
        vs_embree(os, shadow, embree.map(|e| e.1)),
        f3(mrays(shadow, ours.1) / os),
        pct(o.shadow_same, shadow),
    ]
}

/// Columns appended to the build table.
pub const BUILD_HEADER: [&str; 2] = ["obvhs build s", "ours/obvhs"];

/// The build-table cells of one scene.
pub fn build_cells(o: &ObvhsResult, ours_build_s: f64) -> Vec<String> {
    vec![f3(o.build_s), f3(ours_build_s / o.build_s)]
}
