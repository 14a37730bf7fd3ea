//! Degenerate (zero-area) triangles are ignored and never produce NaN: a repeated index, three
//! distinct coincident vertices and collinear corners, placed among real triangles and in the
//! camera's view, are never hit, and the image equals that of the scene without them.

use crate::support::{Scratch, assert_every_k_identical, bundled, has_non_finite, monolithic};
use crate::support::{hit_bits, pixel_bits, scene_path};
use hort_core::hits::Hit;
use hort_core::scene::load_scene;

/// The ids of `degenerate.obj`'s zero-area triangles (see scenes/tools/make_stability.py).
const DEGENERATE: [u32; 6] = [1, 3, 7, 11, 15, 19];

#[test]
fn degenerate_triangles_are_never_hit_and_never_nan() {
    let scene = bundled("stability/degenerate.json");
    for &id in &DEGENERATE {
        let [a, b, c] = scene.mesh.corners(id as usize);
        assert_eq!((b - a).cross(c - a).length(), 0.0, "triangle {id} has area");
    }
    let mono = assert_every_k_identical("degenerate.json", &scene, 64, 48, 8);
    assert!(
        !has_non_finite(&mono.image.pixels),
        "NaN or infinity in the image"
    );
    let hit_degenerate = mono
        .hits
        .iter()
        .filter(|h| DEGENERATE.contains(&h.triangle))
        .count();
    let hits = mono.hits.iter().filter(|h| !h.is_miss()).count();
    assert!(hits > 300, "the box and ground must be in view ({hits})");
    assert_eq!(hit_degenerate, 0);

    // The same file without the degenerate faces renders the same image; its hits name the
    // same triangles once renumbered.
    let text = std::fs::read_to_string(scene_path("stability/degenerate.obj")).unwrap();
    let mut face = 0u32;
    let mut kept = Vec::new();
    let mut stripped = String::new();
    for line in text.lines() {
        if line.starts_with("f ") {
            face += 1;
            if DEGENERATE.contains(&(face - 1)) {
                continue;
            }
            kept.push(face - 1);
        }
        stripped.push_str(line);
        stripped.push('\n');
    }
    let scratch = Scratch::new("degenerate");
    scratch.write("degenerate.obj", &stripped);
    let manifest = std::fs::read_to_string(scene_path("stability/degenerate.json")).unwrap();
    let clean = load_scene(&scratch.write("degenerate.json", &manifest)).unwrap();
    // Degenerate triangles add no extent here, so both scenes have the same local frame.
    assert_eq!(clean.origin, scene.origin);
    let without = monolithic(&clean, 64, 48);
    let renumbered: Vec<Hit> = without
        .hits
        .iter()
        .map(|h| match h.is_miss() {
            true => *h,
            false => Hit {
                triangle: kept[h.triangle as usize],
                t: h.t,
            },
        })
        .collect();
    assert_eq!(
        pixel_bits(&without.image.pixels),
        pixel_bits(&mono.image.pixels)
    );
    assert_eq!(hit_bits(&renumbered), hit_bits(&mono.hits));
    println!(
        "degenerate: 0 of {hits} hit pixels name one of {} zero-area triangles, no NaN, image \
         identical to the scene without them and for k = 1..=8",
        DEGENERATE.len()
    );
}

/// A scene whose only triangles are degenerate but which has an extent (collinear corners)
/// loads and renders to the background, without NaN.
#[test]
fn a_scene_of_only_degenerate_triangles_renders_the_background() {
    let scratch = Scratch::new("only-degenerate");
    let path = scratch.write(
        "line.obj",
        "v -1 0 0\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 3 1 2\nf 4 4 4\nf 2 2 4\n",
    );
    let scene = load_scene(&path).unwrap();
    let out = monolithic(&scene, 32, 24);
    assert!(out.hits.iter().all(Hit::is_miss));
    assert!(out.image.pixels.iter().flatten().all(|&v| v == 0.0));
}
