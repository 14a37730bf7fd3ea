//! The builder builds exactly the nodes and leaf order of its specification
//! (`build_reference.rs`) on inputs chosen to reach every branch: random soups of many sizes,
//! a real mesh, coincident centroids (the split by index), flat and tiny extents, signed zeros,
//! huge coordinates and a chain deep enough to meet the depth limit.

use super::tests::{Rng, closed_cube};
use super::{Node, build, build_reference};
use glam::Vec3;

/// Every node (box compared with `==`, so a zero's sign does not count) and the leaf order, on
/// one thread and on two, with the leaves of small trees and of large ones (`build::max_leaf`).
fn check(name: &str, triangles: &[[Vec3; 3]]) {
    for max_leaf in [build::MAX_LEAF, build::LARGE_TREE_LEAF] {
        let (want_nodes, want_order) =
            build_reference::binary_tree_with_leaves(triangles, max_leaf);
        for threads in [1, 2] {
            let want = (&want_nodes[..], &want_order[..]);
            check_against(name, triangles, (threads, max_leaf), want);
        }
    }
}

fn check_against(
    name: &str,
    triangles: &[[Vec3; 3]],
    (threads, max_leaf): (usize, u32),
    (want_nodes, want_order): (&[Node], &[u32]),
) {
    let name = format!("{name}, {threads} threads, leaves of {max_leaf}");
    let (nodes, order) = build::binary_tree_with_leaves(triangles, threads, max_leaf);
    assert_eq!(nodes.len(), want_nodes.len(), "{name}: node count");
    for (i, (got, want)) in nodes.iter().zip(want_nodes).enumerate() {
        assert_eq!(got, want, "{name}: node {i}");
    }
    assert_eq!(order, want_order, "{name}: leaf order");
    if let Some(root) = nodes.first() {
        // The root's box is stored, so its bits (zero signs included) must be the same.
        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
        assert_eq!(
            bits(root.bounds.lo),
            bits(want_nodes[0].bounds.lo),
            "{name}"
        );
        assert_eq!(
            bits(root.bounds.hi),
            bits(want_nodes[0].bounds.hi),
            "{name}"
        );
    }
}

fn soup(rng: &mut Rng, n: usize, spread: f32, size: f32) -> Vec<[Vec3; 3]> {
    let mut v = |scale: f32| {
        Vec3::new(rng.unit(), rng.unit(), rng.unit()) * (2.0 * scale) - Vec3::splat(scale)
    };
    (0..n)
        .map(|_| {
            let c = v(spread);
            [c + v(size), c + v(size), c + v(size)]
        })
        .collect()
}

#[test]
fn random_soups_of_every_size_build_the_specified_tree() {
    let mut rng = Rng(3);
    for n in [0, 1, 2, 4, 5, 6, 9, 17, 64, 255, 1000, 20_000] {
        check(&format!("soup of {n}"), &soup(&mut rng, n, 10.0, 1.0));
    }
    check("long thin", &soup(&mut rng, 5000, 1e4, 1e-3));
    check("huge coordinates", &soup(&mut rng, 3000, 1e30, 1e28));
    check("tiny coordinates", &soup(&mut rng, 3000, 1e-30, 1e-32));
}

#[test]
fn every_thread_count_builds_the_specified_tree() {
    // Large enough for subtrees on other threads (build::FORK_MIN refs) several levels down.
    let mut rng = Rng(9);
    let triangles = soup(&mut rng, 150_000, 100.0, 1.0);
    let (want_nodes, want_order) = build_reference::binary_tree(&triangles);
    let max_leaf = build::max_leaf(triangles.len());
    for threads in [1, 2, 3, 4, 7, 16] {
        let want = (&want_nodes[..], &want_order[..]);
        check_against("soup of 150000", &triangles, (threads, max_leaf), want);
    }
}

/// Trees of `LARGE_TREE` triangles or more take the large leaves, smaller ones the small, and
/// `binary_tree` builds with them: its leaves of a large soup hold more than `MAX_LEAF`.
#[test]
fn large_trees_take_large_leaves() {
    assert_eq!(build::max_leaf(build::LARGE_TREE - 1), build::MAX_LEAF);
    assert_eq!(build::max_leaf(build::LARGE_TREE), build::LARGE_TREE_LEAF);
    let mut rng = Rng(5);
    let triangles = soup(&mut rng, build::LARGE_TREE, 100.0, 0.5);
    let (nodes, _) = build::binary_tree(&triangles, 2);
    let largest = nodes.iter().map(|n| n.count).max();
    assert_eq!(largest, Some(build::LARGE_TREE_LEAF));
}

#[test]
fn meshes_build_the_specified_tree() {
    check("closed cube", &closed_cube(30));
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/bunny/bunny.obj");
    let mesh = crate::scene::parse_obj(
        std::io::BufReader::new(std::fs::File::open(path).expect("bundled bunny")),
        std::path::Path::new(path),
        &mut Vec::new(),
    )
    .expect("bunny parses");
    let bunny: Vec<[Vec3; 3]> = (0..mesh.triangle_count())
        .map(|i| mesh.corners(i))
        .collect();
    check("bunny", &bunny);
}

#[test]
fn degenerate_layouts_build_the_specified_tree() {
    let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
    check("one triangle 100 times (split by index)", &vec![tri; 100]);
    let mut rng = Rng(5);
    let mut mixed = soup(&mut rng, 300, 5.0, 1.0);
    for i in 0..300 {
        // Clusters of coincident centroids among scattered triangles.
        mixed.insert(
            i * 2,
            [Vec3::splat((i % 3) as f32), Vec3::ONE, Vec3::NEG_ONE],
        );
    }
    check("clusters of coincident centroids", &mixed);
    let flat: Vec<[Vec3; 3]> = soup(&mut rng, 2000, 5.0, 1.0)
        .into_iter()
        .map(|t| t.map(|p| Vec3::new(p.x, 0.0, p.z)))
        .collect();
    check("flat in y", &flat);
    let signed_zeros: Vec<[Vec3; 3]> = (0..500)
        .map(|i| {
            let z = if i % 2 == 0 { 0.0 } else { -0.0 };
            let x = (i / 7) as f32;
            [Vec3::new(z, x, z), Vec3::new(x, z, -z), Vec3::new(-z, z, x)]
        })
        .collect();
    check("signed zeros", &signed_zeros);
    let subnormal: Vec<[Vec3; 3]> = (0..200)
        .map(|i| {
            let d = f32::from_bits(1 + i % 5);
            [
                Vec3::splat(d),
                Vec3::new(d, 0.0, 0.0),
                Vec3::new(0.0, d, 0.0),
            ]
        })
        .collect();
    check("subnormal extents", &subnormal);
}

#[test]
fn a_chain_deeper_than_the_limit_builds_the_specified_tree() {
    // Triangle i at 2^i, of size 2^(i-1): each level's top bins hold the few largest, so SAH
    // peels them off a few per level, past MAX_DEPTH, where the rest becomes one large leaf.
    let chain: Vec<[Vec3; 3]> = (-125..125)
        .map(|i| {
            let x = 2.0f32.powi(i);
            let s = x * 0.5;
            [
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x + s, 0.0, 0.0),
                Vec3::new(x, s, 0.0),
            ]
        })
        .collect();
    let (nodes, _) = build::binary_tree(&chain, 1);
    assert!(
        nodes.iter().any(|n| n.count > 4),
        "the depth limit makes a large leaf"
    );
    check("deep chain", &chain);
}

/// The two triangles of each face of an axis-aligned box from `lo` to `hi`, face by face.
fn room(lo: Vec3, hi: Vec3) -> Vec<[Vec3; 3]> {
    let mut faces = Vec::new();
    for axis in 0..3 {
        for side in [lo, hi] {
            // The face's four corners: the box's corners with this axis at `side`.
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let corner = |a: f32, b: f32| {
                let mut p = side;
                p[u] = a;
                p[v] = b;
                p
            };
            let [p00, p10, p11, p01] = [
                corner(lo[u], lo[v]),
                corner(hi[u], lo[v]),
                corner(hi[u], hi[v]),
                corner(lo[u], hi[v]),
            ];
            faces.push([p00, p10, p11]);
            faces.push([p00, p11, p01]);
        }
    }
    faces
}

/// Walls, floors and ceilings: a node of a few triangles whose box is mostly empty is split, so
/// no leaf pools two faces of a room (each face's two triangles are flat along one axis, a
/// leaf's box of two faces is a room), and the builder builds the specified tree.
#[test]
fn mostly_empty_small_nodes_are_split() {
    let one = room(Vec3::ZERO, Vec3::new(5.0, 3.0, 8.0));
    check("a room", &one);
    let (nodes, order) = build::binary_tree(&one, 1);
    for leaf in nodes.iter().filter(|n| n.count > 0) {
        let range = leaf.first as usize..(leaf.first + leaf.count) as usize;
        let mut faces: Vec<u32> = order[range].iter().map(|&t| t / 2).collect();
        faces.dedup();
        assert_eq!(faces.len(), 1, "a leaf pools faces {faces:?}");
    }
    let mut rng = Rng(11);
    let mut rooms: Vec<[Vec3; 3]> = (0..40)
        .flat_map(|i| {
            let lo = Vec3::new((i % 8) as f32 * 6.0, 0.0, (i / 8) as f32 * 9.0);
            room(lo, lo + Vec3::new(5.0, 3.0, 8.0))
        })
        .collect();
    // Furniture: small tilted triangles, whose leaves stay leaves.
    rooms.extend(soup(&mut rng, 500, 20.0, 0.3));
    check("rooms with furniture", &rooms);
}
