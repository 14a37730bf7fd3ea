//! The adaptive sampler in the monolithic renderer: per row, a first pass of `base_spp` samples
//! in every pixel, then the ranks `base_spp..max_spp` of the pixels [`decide`] refines, traced
//! and shaded by the renderer's own batch path ([`crate::render`]'s `shade_batch`).

use super::{AdaptiveCounts, AdaptiveSettings, Decision, decide, pixel_value};
use crate::bvh::{Bvh, ClosestHit};
use crate::camera::Camera;
use crate::error::SceneError;
use crate::hits::Hit;
use crate::image::Image;
use crate::render::{BATCH_SAMPLES, RayCounts, RenderOutput, RenderSettings, shade_batch};
use crate::scene::{Scene, check_image_size};
use crate::unoccludable::unoccludable_lights;
use crate::worker_pool::run_indexed;
use std::convert::Infallible;
use std::time::Instant;

/// Renders `scene` with the adaptive sampler: `settings` gives the size and threads (its `spp`
/// is not used: a pixel gets `adaptive.base_spp` or `adaptive.max_spp` samples). The image,
/// hit buffer (rank 0's hit), ray counts and decision counts do not depend on the thread count.
pub fn render_adaptive(
    scene: &Scene,
    bvh: &Bvh,
    settings: RenderSettings,
    adaptive: AdaptiveSettings,
) -> Result<(RenderOutput, AdaptiveCounts), SceneError> {
    let RenderSettings {
        width,
        height,
        threads,
        ..
    } = settings;
    adaptive.check()?;
    check_image_size(width, height, adaptive.max_spp)?;
    let camera = settings.camera(scene)?;
    let threads = if threads == 0 {
        crate::worker_pool::available_cores()
    } else {
        threads
    };
    let unoccludable = unoccludable_lights(&scene.mesh, &scene.lights);
    let start = Instant::now();
    let mut image = Image::new(width, height);
    let mut hits = vec![Hit::MISS; width as usize * height as usize];
    let mut rays = RayCounts::default();
    let mut counts = AdaptiveCounts::default();
    // One item per row; each row lands at its own place, so the thread count changes nothing.
    let Ok(()) = run_indexed(
        std::iter::repeat_n((), threads),
        height as usize,
        |(), y| {
            let lights = (scene, bvh, unoccludable.as_slice());
            Ok::<Row, Infallible>(render_row(lights, &camera, width, adaptive, y as u32))
        },
        |y, row| {
            let range = y * width as usize..(y + 1) * width as usize;
            image.pixels[range.clone()].copy_from_slice(&row.colours);
            hits[range].copy_from_slice(&row.hits);
            rays += row.rays;
            counts += row.counts;
        },
    );
    let output = RenderOutput {
        image,
        hits,
        rays,
        render_seconds: start.elapsed().as_secs_f64(),
    };
    Ok((output, counts))
}

struct Row {
    colours: Vec<[f32; 3]>,
    hits: Vec<Hit>,
    rays: RayCounts,
    counts: AdaptiveCounts,
}

/// Traces and shades the given (pixel, rank) samples in batches of about `BATCH_SAMPLES`
/// neighbouring camera rays; returns each sample's radiance and whether it hit, in order.
fn trace_samples(
    (scene, bvh, unoccludable): Shading<'_>,
    camera: &Camera,
    max_spp: u32,
    samples: &[(u64, u32)],
) -> (Vec<[f32; 3]>, Vec<Option<ClosestHit>>) {
    let mut colours = Vec::with_capacity(samples.len());
    let mut all_hits = Vec::with_capacity(samples.len());
    let mut hits = Vec::new();
    for batch in samples.chunks(BATCH_SAMPLES) {
        let rays: Vec<_> = batch
            .iter()
            .map(|&(pixel, rank)| camera.sample_ray(pixel, rank, max_spp))
            .collect();
        hits.clear();
        hits.resize(rays.len(), None);
        bvh.closest_hits(&rays, &mut hits);
        colours.extend(shade_batch(scene, bvh, unoccludable, &rays, &hits));
        all_hits.extend_from_slice(&hits);
    }
    (colours, all_hits)
}

/// The scene, its BVH and its unoccludable lights: what shading a sample needs.
type Shading<'a> = (&'a Scene, &'a Bvh, &'a [bool]);

fn render_row(
    shading: Shading<'_>,
    camera: &Camera,
    width: u32,
    a: AdaptiveSettings,
    y: u32,
) -> Row {
    let first_pixel = u64::from(y) * u64::from(width);
    let pixels = first_pixel..first_pixel + u64::from(width);
    let base = a.base_spp as usize;
    let lights = shading.0.lights.len() as u64;
    let mut rays = RayCounts::default();
    let mut count = |hits: &[Option<ClosestHit>]| {
        for hit in hits {
            rays += RayCounts {
                primary: 1,
                shadow: if hit.is_some() { lights } else { 0 },
            };
        }
    };
    // First pass: ranks 0..base of every pixel.
    let first: Vec<(u64, u32)> = pixels
        .clone()
        .flat_map(|p| (0..a.base_spp).map(move |r| (p, r)))
        .collect();
    let (colours1, hits1) = trace_samples(shading, camera, a.max_spp, &first);
    count(&hits1);
    let decisions: Vec<Decision> = colours1
        .chunks(base)
        .zip(hits1.chunks(base))
        .map(|(c, h)| decide(c, h.iter().any(Option::is_some), a.threshold))
        .collect();
    // Second pass: ranks base..max of the refined pixels only, if any.
    let second: Vec<(u64, u32)> = pixels
        .zip(&decisions)
        .filter(|(_, d)| **d == Decision::Refine)
        .flat_map(|(p, _)| (a.base_spp..a.max_spp).map(move |r| (p, r)))
        .collect();
    let (colours2, hits2) = trace_samples(shading, camera, a.max_spp, &second);
    count(&hits2);
    let extra = (a.max_spp - a.base_spp) as usize;
    let mut refined = colours2.chunks(extra);
    let mut row = Row {
        colours: Vec::with_capacity(width as usize),
        hits: Vec::with_capacity(width as usize),
        rays,
        counts: AdaptiveCounts::default(),
    };
    for ((first, hits), &decision) in colours1
        .chunks(base)
        .zip(hits1.chunks(base))
        .zip(&decisions)
    {
        let second = match decision {
            Decision::Refine => refined.next().unwrap_or_default(),
            _ => &[],
        };
        row.colours.push(pixel_value(first, second));
        row.hits.push(hits[0].map_or(Hit::MISS, |h| Hit {
            triangle: h.id,
            t: h.t,
        }));
        row.counts.add(decision, &a);
    }
    row
}

#[cfg(test)]
mod tests;
