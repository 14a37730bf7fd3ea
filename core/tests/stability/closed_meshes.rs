//! Rays aimed exactly at the shared edges and vertices of closed meshes never leak: from any
//! point inside, every such ray hits the mesh; from outside, every ray aimed at an edge or vertex
//! whose triangles all face the eye hits it. The watertight triangle test promises this; here it
//! is checked on a cube and an icosphere, near the origin and a million units away.

use crate::support::{Scratch, bundled, monolithic, scene_path};
use glam::Vec3;
use hort_core::render::build_scene_bvh;
use hort_core::scene::{Scene, load_scene};
use hort_core::triangle::Ray;
use std::collections::BTreeMap;

/// Points on every edge (its ends and fractions of its length) and every vertex.
fn edge_and_vertex_targets(scene: &Scene) -> Vec<(Vec3, [u32; 2])> {
    let mut edges = std::collections::BTreeSet::new();
    for t in &scene.mesh.triangles {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            edges.insert((a.min(b), a.max(b)));
        }
    }
    let p = &scene.mesh.positions;
    let mut targets = Vec::new();
    for (a, b) in edges {
        let (pa, pb) = (p[a as usize], p[b as usize]);
        for f in [0.0f32, 0.5, 1.0 / 3.0, 0.1, 0.9, 1.0] {
            targets.push((pa + (pb - pa) * f, [a, b]));
        }
    }
    targets
}

/// The triangles around each edge and vertex, by the sorted vertex pair (a vertex is (v, v)).
fn incident(scene: &Scene) -> BTreeMap<(u32, u32), Vec<usize>> {
    let mut map: BTreeMap<(u32, u32), Vec<usize>> = BTreeMap::new();
    for (id, t) in scene.mesh.triangles.iter().enumerate() {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            map.entry((a.min(b), a.max(b))).or_default().push(id);
            map.entry((a, a)).or_default().push(id);
        }
    }
    map
}

/// Counts (rays, leaks) of rays from `eyes` aimed at every edge point and vertex; from an eye
/// outside the mesh only targets whose triangles all face the eye count.
fn leaks(scene: &Scene, eyes: &[Vec3], inside: bool) -> (usize, usize) {
    let bvh = build_scene_bvh(&scene.mesh);
    let around = incident(scene);
    let mut rays = 0;
    let mut leaked = 0;
    for &eye in eyes {
        for (target, [a, b]) in edge_and_vertex_targets(scene) {
            let key = if target == scene.mesh.positions[a as usize] {
                (a, a)
            } else if target == scene.mesh.positions[b as usize] {
                (b, b)
            } else {
                (a, b)
            };
            if !inside {
                let faces_eye = around[&key].iter().all(|&id| {
                    let [p0, p1, p2] = scene.mesh.corners(id);
                    let n = (p1 - p0).cross(p2 - p0);
                    n.dot(eye - p0) > 1e-3 * n.length() * (eye - p0).length()
                });
                if !faces_eye {
                    continue;
                }
            }
            rays += 1;
            let ray = Ray {
                origin: eye,
                dir: target - eye,
            };
            if bvh.closest_hit(&ray).is_none() {
                leaked += 1;
            }
        }
    }
    (rays, leaked)
}

fn eyes(scale: f32, inside: bool) -> Vec<Vec3> {
    let unit = [
        Vec3::ZERO,
        Vec3::new(0.1, 0.2, -0.3),
        Vec3::new(-0.37, 0.11, 0.52),
        Vec3::new(0.5, 0.5, 0.5),
        Vec3::new(-0.25, 0.0, 0.0),
    ];
    let far = [
        Vec3::new(3.0, 2.0, 5.0),
        Vec3::new(-4.0, 1.5, 0.3),
        Vec3::new(0.2, -6.0, -2.0),
        Vec3::new(5.0, 5.0, 5.0),
    ];
    let set: &[Vec3] = if inside { &unit } else { &far };
    set.iter().map(|e| *e * scale).collect()
}

/// The same closed mesh written a million units from the origin (every coordinate + 1e6).
fn far_copy(rel: &str, scratch: &Scratch) -> Scene {
    let text = std::fs::read_to_string(scene_path(rel)).unwrap();
    let moved: String = text
        .lines()
        .map(|line| match line.strip_prefix("v ") {
            Some(rest) => {
                let c: Vec<f64> = rest.split(' ').map(|w| w.parse().unwrap()).collect();
                format!("v {} {} {}\n", c[0] + 1e6, c[1] - 1e6, c[2] + 1e6)
            }
            None => format!("{line}\n"),
        })
        .collect();
    load_scene(&scratch.write("far.obj", &moved)).unwrap()
}

#[test]
fn rays_at_edges_and_vertices_of_closed_meshes_never_leak() {
    let scratch = Scratch::new("closed");
    let mut total = 0;
    for rel in ["stability/closed_box.obj", "stability/closed_sphere.obj"] {
        // Both unit meshes are centred on the origin: local and file coordinates agree.
        for (what, scene) in [("near", bundled(rel)), ("far", far_copy(rel, &scratch))] {
            let r = if rel.ends_with("sphere.obj") {
                0.5
            } else {
                1.0
            };
            let (inside_rays, inside_leaks) = leaks(&scene, &eyes(r, true), true);
            let (outside_rays, outside_leaks) = leaks(&scene, &eyes(1.0, false), false);
            println!(
                "{rel} {what}: {inside_leaks} of {inside_rays} rays from inside and \
                 {outside_leaks} of {outside_rays} from outside leak"
            );
            assert!(
                inside_rays > 100 && outside_rays > 50,
                "{rel}: too few rays"
            );
            assert_eq!((inside_leaks, outside_leaks), (0, 0), "{rel} {what}");
            total += inside_rays + outside_rays;
        }
    }
    println!("closed meshes: 0 leaks of {total} rays");
}

/// Seen from its centre, a closed box covers every pixel: no background shows through an edge
/// or a corner, whichever way the camera looks (at a face, an edge, a corner).
#[test]
fn a_closed_box_seen_from_inside_covers_every_pixel() {
    let mut scene = bundled("stability/closed_box.obj");
    let mut misses = 0;
    for look_at in [
        glam::DVec3::new(0.0, 0.0, -1.0),
        glam::DVec3::new(1.0, 0.0, -1.0),
        glam::DVec3::new(1.0, 1.0, -1.0),
        glam::DVec3::new(-0.3, 0.7, 1.0),
    ] {
        scene.camera.eye = glam::DVec3::ZERO;
        scene.camera.look_at = look_at;
        scene.camera.vfov_degrees = 120.0;
        scene.framed_bounds = None;
        let out = monolithic(&scene, 65, 49);
        misses += out.hits.iter().filter(|h| h.is_miss()).count();
    }
    println!("closed box from inside: {misses} background pixels of 4 x 65 x 49");
    assert_eq!(misses, 0);
}
