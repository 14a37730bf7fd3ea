//! Split extremes: every triangle of a large generated scene in one split, and splits that
//! contribute nothing (out of view, behind the camera, or only zero-area triangles). The
//! distributed render equals the monolithic one bit for bit in both.

use crate::support::{Scratch, assert_every_k_identical, distributed, hit_bits, monolithic};
use crate::support::{pixel_bits, scene_path};
use hort_core::pipeline::SplitMode;
use hort_core::scene::load_scene;

/// Triangles of the generated scene rendered as one split.
const HUGE: u64 = 1_000_000;

#[test]
fn a_huge_scene_in_one_split_equals_the_monolithic_render() {
    let scratch = Scratch::new("huge");
    let path = scratch.path().join("huge.obj");
    let mut file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
    hort_core::generate::generate_scene(HUGE, 7, &mut file).unwrap();
    drop(file);
    let scene = load_scene(&path).unwrap();
    assert_eq!(scene.mesh.triangle_count() as u64, HUGE);
    let (w, h) = (64, 48);
    let mono = monolithic(&scene, w, h);
    let (pixels, hits) = distributed(&scene, w, h, 1, 4, SplitMode::Spatial);
    assert_eq!(pixel_bits(&pixels), pixel_bits(&mono.image.pixels));
    assert_eq!(hit_bits(&hits), hit_bits(&mono.hits));
    let seen = mono.hits.iter().filter(|h| !h.is_miss()).count();
    assert!(seen > 300, "the generated scene must be in view ({seen})");
    println!("huge split: {HUGE} triangles in one split, image and hits identical");
}

/// One triangle per split (k = n), with splits behind the camera, far outside the view and
/// made of a zero-area triangle: the image is the same for every k from 1 to n.
#[test]
fn splits_that_contribute_nothing_change_nothing() {
    let scratch = Scratch::new("empty");
    let text = std::fs::read_to_string(scene_path("stability/degenerate.obj")).unwrap();
    // The degenerate scene plus a triangle behind the camera and one far to the side.
    let extra = "v -0.5 0 6\nv 0.5 0 6\nv 0 1 6\nv 50 0 0\nv 51 0 0\nv 50 1 0\n\
                 f -6 -5 -4\nf -3 -2 -1\n";
    scratch.write("degenerate.obj", &(text + extra));
    let manifest = std::fs::read_to_string(scene_path("stability/degenerate.json")).unwrap();
    let scene = load_scene(&scratch.write("scene.json", &manifest)).unwrap();
    let n = scene.mesh.triangle_count() as u32;
    assert_eq!(n, 22);
    assert_every_k_identical("empty splits", &scene, 48, 32, n);
    println!("empty splits: identical image for k = 1..={n} (one triangle per split at k = {n})");
}
