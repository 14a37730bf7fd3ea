//! The adaptive sampler in the monolithic renderer: per row, a first pass of `base_spp` samples
//! in every pixel, then the ranks `base_spp..max_spp` of the pixels [`decide`] refines, traced
//! and shaded by the renderer's own batch path ([`crate::render`]'s `shade_batch_lit`). A fused
//! task of one split renders its span's pixels the same way ([`adaptive_run`]).

use super::{AdaptiveCounts, AdaptiveSettings, Decision, decide, pixel_value};
use crate::bvh::{Bvh, ClosestHit, HitColumns, camera_packet};
use crate::camera::Camera;
use crate::error::SceneError;
use crate::hits::Hit;
use crate::image::Image;
use crate::render::{
    BATCH_SAMPLES, Lighting, RayCounts, RenderOutput, RenderSettings, ShadingScratch, Surfaces,
    lighting, shade_batch_lit,
};
use crate::sampling::TraceOrder;
use crate::scene::{Scene, check_image_size};
use crate::unoccludable::unoccludable_lights;
use crate::worker_pool::run_indexed;
use std::convert::Infallible;
use std::ops::Range;
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
    let lighting = lighting(scene, &unoccludable);
    let start = Instant::now();
    let refinement = RefinementOrder::new(adaptive);
    let mut image = Image::new(width, height);
    let mut hits = vec![Hit::MISS; width as usize * height as usize];
    let mut rays = RayCounts::default();
    let mut counts = AdaptiveCounts::default();
    // One item per row; each row lands at its own place, so the thread count changes nothing.
    let Ok(()) = run_indexed(
        std::iter::repeat_n((), threads),
        height as usize,
        |(), y| {
            let first = y as u64 * u64::from(width);
            let row = first..first + u64::from(width);
            let sampler = (adaptive, &refinement);
            let run = adaptive_run((&scene.mesh, bvh), &lighting, &camera, row, sampler);
            Ok::<AdaptiveRun, Infallible>(run)
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

/// A run of pixels rendered with the adaptive sampler ([`adaptive_run`]).
pub(crate) struct AdaptiveRun {
    /// Each pixel's value, in pixel order.
    pub colours: Vec<[f32; 3]>,
    /// Each pixel's rank-0 hit.
    pub hits: Vec<Hit>,
    /// Logical rays of both passes.
    pub rays: RayCounts,
    /// The pixels' decisions.
    pub counts: AdaptiveCounts,
}

/// The order the second pass traces a refined pixel's ranks `base..max` in: the renderer's
/// trace order at `max` samples ([`TraceOrder`]) without the first pass's ranks, so a packet
/// of neighbouring ranks covers a part of the pixel rather than all of it (every aligned run of
/// 16 ranks spans the whole pixel).
pub(crate) struct RefinementOrder {
    /// The ranks in trace order.
    ranks: Vec<u32>,
    /// Per rank `base + k`, where it is traced.
    positions: Vec<usize>,
}

impl RefinementOrder {
    /// The order for the settings `a`.
    pub(crate) fn new(a: AdaptiveSettings) -> Self {
        let order = TraceOrder::new(a.max_spp);
        let ranks: Vec<u32> = (order.samples().iter().copied())
            .filter(|&rank| rank >= a.base_spp)
            .collect();
        let mut positions = vec![0; ranks.len()];
        for (position, &rank) in ranks.iter().enumerate() {
            positions[(rank - a.base_spp) as usize] = position;
        }
        RefinementOrder { ranks, positions }
    }

    /// A refined pixel's radiances in rank order into `out`, from them in trace order.
    fn in_rank_order(&self, traced: &[[f32; 3]], out: &mut Vec<[f32; 3]>) {
        out.clear();
        out.extend(self.positions.iter().map(|&p| traced[p]));
    }
}

/// Traces and shades the samples `ranks` (of a sequence of `max_spp`) of each of `pixels`,
/// pixel by pixel, in batches of about `BATCH_SAMPLES` neighbouring camera rays; returns each
/// sample's radiance and whether it hit, in that order.
fn trace_samples(
    (surfaces, bvh): (&impl Surfaces, &Bvh),
    lighting: &Lighting,
    camera: &Camera,
    (pixels, ranks): (&[u64], &[u32]),
    max_spp: u32,
    scratch: &mut ShadingScratch,
) -> (Vec<[f32; 3]>, Vec<Option<ClosestHit>>) {
    let count = pixels.len() * ranks.len();
    let mut colours = Vec::with_capacity(count);
    let mut all_hits = Vec::with_capacity(count);
    let (mut rays, mut hits) = (Vec::new(), HitColumns::default());
    let pixels_per_batch = (BATCH_SAMPLES / ranks.len().max(1)).max(1);
    for batch in pixels.chunks(pixels_per_batch) {
        rays.clear();
        camera.pixels_samples_rays(batch, (ranks, max_spp), &mut rays);
        // `closest_hits_in_columns` writes every place: only a new length is filled.
        hits.resize(rays.len());
        bvh.closest_hits_in_columns(&rays, &mut hits, camera_packet(ranks.len()));
        let batch = (rays.as_slice(), &hits);
        colours.extend_from_slice(shade_batch_lit((surfaces, bvh), lighting, batch, scratch));
        all_hits.extend((0..hits.len()).map(|i| bvh.hit_in(&hits, i)));
    }
    (colours, all_hits)
}

/// The pixels `pixels` with the adaptive sampler `a` (whose second pass traces in
/// `refinement`'s order), through `bvh`, whose triangles `surfaces` describes, under
/// `lighting`: each pixel is a function of its own samples, so any run of pixels gives the
/// bits of the same pixels in a whole-image render.
pub(crate) fn adaptive_run(
    shading: (&impl Surfaces, &Bvh),
    lighting: &Lighting,
    camera: &Camera,
    pixels: Range<u64>,
    (a, refinement): (AdaptiveSettings, &RefinementOrder),
) -> AdaptiveRun {
    let base = a.base_spp as usize;
    let lights = lighting.lights.len() as u64;
    let mut rays = RayCounts::default();
    let mut count = |hits: &[Option<ClosestHit>]| {
        for hit in hits {
            rays += RayCounts {
                primary: 1,
                shadow: if hit.is_some() { lights } else { 0 },
            };
        }
    };
    let mut scratch = ShadingScratch::default();
    // First pass: ranks 0..base of every pixel.
    let all: Vec<u64> = pixels.clone().collect();
    let ranks: Vec<u32> = (0..a.base_spp).collect();
    let first = (all.as_slice(), ranks.as_slice());
    let (colours1, hits1) =
        trace_samples(shading, lighting, camera, first, a.max_spp, &mut scratch);
    count(&hits1);
    let decisions: Vec<Decision> = colours1
        .chunks(base)
        .zip(hits1.chunks(base))
        .map(|(c, h)| decide(c, h.iter().any(Option::is_some), a.threshold))
        .collect();
    // Second pass: ranks base..max of the refined pixels only, if any, in `refinement`'s order.
    let refine: Vec<u64> = pixels
        .zip(&decisions)
        .filter(|(_, d)| **d == Decision::Refine)
        .map(|(p, _)| p)
        .collect();
    let second = (refine.as_slice(), refinement.ranks.as_slice());
    let (colours2, hits2) =
        trace_samples(shading, lighting, camera, second, a.max_spp, &mut scratch);
    count(&hits2);
    let extra = (a.max_spp - a.base_spp) as usize;
    let mut refined = colours2.chunks(extra);
    // A refined pixel's second-pass radiances in rank order (empty for the others).
    let mut second = Vec::with_capacity(extra);
    let mut row = AdaptiveRun {
        colours: Vec::with_capacity(all.len()),
        hits: Vec::with_capacity(all.len()),
        rays,
        counts: AdaptiveCounts::default(),
    };
    for ((first, hits), &decision) in colours1
        .chunks(base)
        .zip(hits1.chunks(base))
        .zip(&decisions)
    {
        second.clear();
        if decision == Decision::Refine {
            let traced = refined
                .next()
                .expect("the second pass traced every refined pixel");
            refinement.in_rank_order(traced, &mut second);
        }
        row.colours.push(pixel_value(first, &second));
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
