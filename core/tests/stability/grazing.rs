//! Grazing rays: a camera 1 cm above a tessellated plane looking along it, lit by a directional
//! light 0.5 degrees above it. Every camera ray that meets the plane inside the grid hits it
//! (none slips through an edge), and every hit is lit (no shadow acne: the plane cannot shadow
//! itself). A camera exactly in the plane sees nothing and makes no NaN.

use crate::support::{assert_every_k_identical, bundled, has_non_finite, monolithic};
use hort_core::camera::Camera;

#[test]
fn grazing_rays_neither_leak_nor_self_shadow() {
    let scene = bundled("stability/grazing.json");
    let (w, h) = (96u32, 64u32);
    let mono = assert_every_k_identical("grazing.json", &scene, w, h, 8);
    let camera = Camera::new(&scene.camera_for(w, h), w, h).unwrap();
    let (mut expected, mut leaked, mut acne) = (0, 0, 0);
    for (pixel, hit) in mono.hits.iter().enumerate() {
        let ray = camera.sample_ray(pixel as u64, 0, 1);
        // Where the ray meets the plane y = 0 (in the local frame, the grid's y is 0 too:
        // its centre is the origin).
        if ray.dir.y < 0.0 {
            let t = -ray.origin.y / ray.dir.y;
            let p = ray.origin + t * ray.dir;
            if p.x.abs() < 7.99 && p.z.abs() < 7.99 {
                expected += 1;
                leaked += usize::from(hit.is_miss());
            }
        }
        if !hit.is_miss() && mono.image.pixels[pixel].iter().any(|&v| v <= 0.0) {
            acne += 1;
        }
    }
    println!(
        "grazing: {leaked} of {expected} rays that meet the grid leak, {acne} hit pixels unlit"
    );
    assert!(expected > 1000, "{expected}");
    assert_eq!((leaked, acne), (0, 0));
    assert!(!has_non_finite(&mono.image.pixels));
}

#[test]
fn a_camera_in_the_plane_sees_nothing() {
    let mut scene = bundled("stability/grazing.json");
    scene.camera.eye.y = 0.0;
    scene.camera.look_at.y = 0.0;
    let out = monolithic(&scene, 64, 48);
    assert!(!has_non_finite(&out.image.pixels));
    let hits = out.hits.iter().filter(|h| !h.is_miss()).count();
    assert_eq!(hits, 0, "rays starting in the plane must not hit it");
}
