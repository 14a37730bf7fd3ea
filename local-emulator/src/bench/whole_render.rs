//! `hort bench kernel`'s whole-render table: the monolithic renderer at the kernel bench's size,
//! one sample per pixel, on one thread, over the tree `hort render --monolithic` would build for
//! it ([`BuildPreset::for_samples`]) and over the quality tree, with its phases beside native
//! Embree's single-ray kernel on exactly the rays it traces (`breakdown.rs`). This is the
//! "rays per second of a whole render against Embree's kernel" measure: the render pays for
//! sampling, shading and accumulation as well as its rays.

use super::breakdown::{self, Breakdown};
use anyhow::{Result, bail};
use hort_core::bvh::{BuildPreset, Bvh};
use hort_core::render::{RenderSettings, build_scene_bvh_with, render};
use hort_core::scene::Scene;
use std::path::Path;

/// Measures the 1-spp render of `scene` at `width` x `height` on the tree a monolithic render
/// would build and (when that is another) on `quality`, the quality tree; `repeats` timed renders
/// each after one warm-up, best counts. Both trees must render the same image.
pub(super) fn measure(
    name: &str,
    scene: &Scene,
    quality: &Bvh,
    (width, height): (u32, u32),
    repeats: u32,
    harness: Option<(&Path, &Path)>,
) -> Result<Vec<Breakdown>> {
    let settings = RenderSettings {
        width,
        height,
        spp: 1,
        threads: 1,
        frame: Default::default(),
    };
    let samples = u64::from(width) * u64::from(height);
    let chosen = BuildPreset::for_samples(samples, scene.mesh.triangle_count() as u64);
    let fast;
    let mut trees = vec![];
    if chosen == BuildPreset::Fast {
        fast = build_scene_bvh_with(&scene.mesh, 1, BuildPreset::Fast);
        trees.push(("fast", &fast));
    }
    trees.push(("quality", quality));
    let mut rows = Vec::new();
    let mut first_pixels: Option<Vec<[f32; 3]>> = None;
    for (preset, bvh) in trees {
        let label = format!("{name} {preset}");
        let warm_up = render(scene, bvh, settings)?;
        let pixels = first_pixels.get_or_insert_with(|| warm_up.image.pixels.clone());
        if warm_up.image.pixels != *pixels {
            bail!("{label}: the image differs from the other tree's");
        }
        let mut best = f64::INFINITY;
        for _ in 0..repeats.max(1) {
            best = best.min(render(scene, bvh, settings)?.render_seconds);
        }
        rows.push(breakdown::measure(
            &label, scene, bvh, settings, repeats, best, None, pixels, harness,
        )?);
    }
    Ok(rows)
}
