use super::*;
use crate::render::{ShadingScratch, build_scene_bvh, shade_batch};
use crate::scene::load_scene;

fn teapot() -> Scene {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/teapot/teapot.json");
    load_scene(std::path::Path::new(path)).expect("bundled teapot")
}

fn settings(threads: usize) -> RenderSettings {
    RenderSettings {
        width: 32,
        height: 24,
        spp: 1,
        threads,
        frame: Default::default(),
    }
}

const ADAPTIVE: AdaptiveSettings = AdaptiveSettings {
    base_spp: 4,
    max_spp: 64,
    threshold: 0.01,
};

/// Every pixel equals its samples traced one by one: the first pass alone for background and
/// converged pixels (whose decisions the reference makes again), all 64 ranks for refined
/// ones; the scene has pixels of all three kinds, and constant pixels are never refined.
#[test]
fn pixels_equal_their_samples_traced_alone() {
    let scene = teapot();
    let bvh = build_scene_bvh(&scene.mesh);
    let (out, counts) = render_adaptive(&scene, &bvh, settings(2), ADAPTIVE).unwrap();
    let camera = Camera::new(&scene.camera_for(32, 24), 32, 24).unwrap();
    let unoccludable = unoccludable_lights(&scene.mesh, &scene.lights);
    let trace = |pixel: u64, rank: u32| {
        let ray = camera.sample_ray(pixel, rank, 64);
        let hit = bvh.closest_hit(&ray);
        (
            shade_batch(
                &scene,
                &bvh,
                &unoccludable,
                (&[ray], &[hit]),
                &mut ShadingScratch::default(),
            )[0],
            hit,
        )
    };
    let mut expected = AdaptiveCounts::default();
    let mut constant_pixels = 0;
    for pixel in 0..32 * 24u64 {
        let first: Vec<_> = (0..4).map(|r| trace(pixel, r)).collect();
        let colours: Vec<[f32; 3]> = first.iter().map(|s| s.0).collect();
        let decision = decide(&colours, first.iter().any(|s| s.1.is_some()), 0.01);
        if colours.iter().all(|c| *c == colours[0]) {
            constant_pixels += 1;
            assert_ne!(decision, Decision::Refine, "pixel {pixel}");
        }
        let second: Vec<[f32; 3]> = if decision == Decision::Refine {
            (4..64).map(|r| trace(pixel, r).0).collect()
        } else {
            Vec::new()
        };
        let want = pixel_value(&colours, &second);
        assert_eq!(
            out.image.pixels[pixel as usize].map(f32::to_bits),
            want.map(f32::to_bits),
            "pixel {pixel}, {decision:?}"
        );
        let hit0 = first[0].1.map_or(u32::MAX, |h| h.id);
        assert_eq!(out.hits[pixel as usize].triangle, hit0, "pixel {pixel}");
        expected.add(decision, &ADAPTIVE);
    }
    assert_eq!(counts, expected);
    assert!(constant_pixels > 0, "some pixels are constant");
    assert!(counts.refined_pixels > 0, "{counts:?}");
    assert!(counts.converged_pixels > 0, "{counts:?}");
    assert!(counts.background_pixels > 0, "{counts:?}");
    assert_eq!(out.rays.primary, counts.samples);
}

#[test]
fn thread_count_changes_nothing() {
    let scene = teapot();
    let bvh = build_scene_bvh(&scene.mesh);
    let (a, ca) = render_adaptive(&scene, &bvh, settings(1), ADAPTIVE).unwrap();
    let (b, cb) = render_adaptive(&scene, &bvh, settings(3), ADAPTIVE).unwrap();
    let bits = |o: &RenderOutput| -> Vec<[u32; 3]> {
        o.image.pixels.iter().map(|p| p.map(f32::to_bits)).collect()
    };
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(a.rays, b.rays);
    assert_eq!(ca, cb);
}

/// A scene without lights or ambient is black everywhere: constant, so nothing is refined
/// and no shadow ray is cast.
#[test]
fn a_scene_without_lights_gets_no_extra_samples() {
    let mut scene = teapot();
    scene.lights.clear();
    let bvh = build_scene_bvh(&scene.mesh);
    let (out, counts) = render_adaptive(&scene, &bvh, settings(2), ADAPTIVE).unwrap();
    assert_eq!(counts.refined_pixels, 0);
    assert_eq!(counts.samples, 32 * 24 * 4);
    assert_eq!(out.rays.shadow, 0);
}

#[test]
fn bad_settings_are_refused() {
    let scene = teapot();
    let bvh = build_scene_bvh(&scene.mesh);
    let bad = AdaptiveSettings {
        max_spp: 4,
        ..ADAPTIVE
    };
    let e = render_adaptive(&scene, &bvh, settings(1), bad).unwrap_err();
    assert_eq!(
        e.to_string(),
        "adaptive max spp = 4 is out of range: must be above the base spp 4 and at most 65536"
    );
}

/// The first pass is the uniform sampler's first samples: with a threshold no pixel exceeds,
/// an adaptive render at base B (any count, here 3 and 12) is the uniform render at B spp, bit
/// for bit, whatever the maximum.
#[test]
fn the_first_pass_is_the_uniform_render() {
    let scene = teapot();
    let bvh = build_scene_bvh(&scene.mesh);
    for (base_spp, max_spp) in [(3u32, 7u32), (12, 96)] {
        let adaptive = AdaptiveSettings {
            base_spp,
            max_spp,
            threshold: 1e9,
        };
        let uniform = RenderSettings {
            spp: base_spp,
            ..settings(2)
        };
        let (out, counts) = render_adaptive(&scene, &bvh, uniform, adaptive).unwrap();
        assert_eq!(counts.refined_pixels, 0);
        let reference = crate::render::render(&scene, &bvh, uniform).unwrap();
        let bits = |o: &RenderOutput| -> Vec<[u32; 3]> {
            o.image.pixels.iter().map(|p| p.map(f32::to_bits)).collect()
        };
        assert_eq!(
            bits(&out),
            bits(&reference),
            "base {base_spp} max {max_spp}"
        );
        assert_eq!(out.hits, reference.hits);
    }
}
