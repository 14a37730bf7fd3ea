//! Rendering a run of pixels that lies in one band of rows: its pixels tile by tile
//! ([`crate::tiles`]), each pixel's samples together in trace order ([`TraceOrder`]), in batches
//! of about [`BATCH_SAMPLES`] samples (whole pixels), so memory stays bounded whatever the
//! width and spp.

use super::RayCounts;
use super::batch::{Lighting, ShadingScratch, shade_batch_timed};
use super::surfaces::Surfaces;
use crate::bvh::{Bvh, HitColumns, camera_packet};
use crate::camera::Camera;
use crate::hits::Hit;
use crate::phase_timer::{Phase, PhaseTimer};
use crate::sampling::{PixelSum, TraceOrder};
use crate::tiles::{BAND_ROWS, tile_order};
use std::ops::Range;

/// Camera samples traced per `closest_hits` call (rounded to whole pixels).
pub(crate) const BATCH_SAMPLES: usize = 1024;

/// The camera, image width, samples per pixel and trace order every band of a render shares.
#[derive(Clone, Copy, Debug)]
pub struct View<'a> {
    /// The camera, with the frame's sample streams.
    pub camera: &'a Camera,
    /// Image width in pixels.
    pub width: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// The order each pixel's samples are traced in (made for `spp`).
    pub order: &'a TraceOrder,
}

/// Pixels of a run, in order from its first, and their ray counts.
#[derive(Clone, Debug, Default)]
pub struct Band {
    /// Each pixel's radiance: the mean of its samples in sample order.
    pub colours: Vec<[f32; 3]>,
    /// Each pixel's sample 0 hit.
    pub hits: Vec<Hit>,
    /// One primary ray per sample; one shadow ray per light of every sample that hits.
    pub rays: RayCounts,
}

/// The row-major pixel range `pixels` of an image `width` pixels wide cut where bands of
/// [`BAND_ROWS`] rows begin: runs that each lie in one band, in order.
pub fn band_runs(pixels: Range<u64>, width: u32) -> impl Iterator<Item = Range<u64>> {
    let band = u64::from(BAND_ROWS) * u64::from(width.max(1));
    let mut start = pixels.start;
    std::iter::from_fn(move || {
        (start < pixels.end).then(|| {
            let end = ((start / band + 1) * band).min(pixels.end);
            let run = start..end;
            start = end;
            run
        })
    })
}

/// Renders the pixels `pixels` (a run of the row-major image that lies in one band of rows)
/// through `bvh`, whose triangles `surfaces` describes. Each pixel is the mean of its samples
/// in sample order, whatever order the pixels are traced in, so the run's bits are those of
/// rendering its pixels one by one.
pub fn render_run(
    scene: (&impl Surfaces, &Bvh),
    lighting: &Lighting,
    view: &View,
    pixels: Range<u64>,
    timer: &mut impl PhaseTimer,
) -> Band {
    let bvh = scene.1;
    let first_pixel = pixels.start;
    let count = (pixels.end - pixels.start) as usize;
    let mut band = Band {
        colours: vec![[0.0; 3]; count],
        hits: vec![Hit::MISS; count],
        rays: RayCounts::default(),
    };
    let order = tile_order(pixels, view.width);
    let spp = view.spp;
    let samples = spp as usize;
    let pixels_per_batch = (BATCH_SAMPLES / samples).max(1);
    let mut batch: Vec<u64> = Vec::with_capacity(pixels_per_batch);
    let mut order = order.peekable();
    let mut rays = Vec::new();
    let mut hits = HitColumns::default();
    let mut scratch = ShadingScratch::default();
    let trace_order = view.order;
    // Where each sample is traced, and the batch's pixel means.
    let positions: Vec<usize> = (0..spp).map(|s| trace_order.position(s)).collect();
    let mut means = Vec::new();
    while order.peek().is_some() {
        timer.lap(Phase::Loop);
        batch.clear();
        batch.extend(order.by_ref().take(pixels_per_batch));
        rays.clear();
        view.camera.pixels_rays(&batch, trace_order, &mut rays);
        // `closest_hits_in_columns` writes every place: only a new length is filled.
        hits.resize(rays.len());
        timer.lap(Phase::CameraRays);
        bvh.closest_hits_in_columns(&rays, &mut hits, camera_packet(samples));
        timer.lap(Phase::ClosestHits);
        let colours = shade_batch_timed(scene, lighting, (&rays, &hits), &mut scratch, timer);
        pixel_means(colours, &positions, &mut means);
        for (((&pixel, &mean), t), id) in batch
            .iter()
            .zip(&means)
            .zip(hits.t().chunks(samples))
            .zip(hits.id().chunks(samples))
        {
            let i = (pixel - first_pixel) as usize;
            // One primary ray per sample, and for a hit one shadow ray per light.
            // Hits have finite t: +inf means none was found.
            let hit_samples = t.iter().filter(|&&t| t < f32::INFINITY).count() as u64;
            band.rays += RayCounts {
                primary: u64::from(spp),
                shadow: hit_samples * lighting.lights.len() as u64,
            };
            band.colours[i] = mean;
            let first = trace_order.position(0);
            band.hits[i] = if t[first] < f32::INFINITY {
                Hit {
                    triangle: id[first],
                    t: t[first],
                }
            } else {
                Hit::MISS
            };
        }
        timer.lap(Phase::Accumulation);
    }
    band
}

/// Pixels whose sums [`pixel_means`] adds at once.
const PIXELS_AT_ONCE: usize = 4;

/// The mean of each pixel's radiances in `colours` (pixel by pixel, each pixel's samples in
/// trace order; sample s at `positions[s]`), in sample order ([`PixelSum`]), whatever the trace
/// order, into `means` (emptied first). The sums of [`PIXELS_AT_ONCE`] pixels are added sample
/// by sample together, so their chains of dependent additions (one pixel's is as long as its
/// sample count, per channel) overlap; each pixel's additions stay in its sample order, so
/// each mean is the same bits.
fn pixel_means(colours: &[[f32; 3]], positions: &[usize], means: &mut Vec<[f32; 3]>) {
    let spp = positions.len();
    means.clear();
    let mut groups = colours.chunks_exact(spp * PIXELS_AT_ONCE);
    for group in groups.by_ref() {
        let mut sums = [PixelSum::default(); PIXELS_AT_ONCE];
        for &position in positions {
            for (j, sum) in sums.iter_mut().enumerate() {
                sum.add(group[j * spp + position]);
            }
        }
        means.extend(sums.map(|sum| sum.mean(spp as u32)));
    }
    for pixel in groups.remainder().chunks(spp) {
        let mut sum = PixelSum::default();
        for &position in positions {
            sum.add(pixel[position]);
        }
        means.push(sum.mean(spp as u32));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs cover the range in order, each within one band, cut only where a band begins.
    #[test]
    fn band_runs_cut_a_range_where_bands_begin() {
        // Width 10: bands of 40 pixels.
        let runs: Vec<_> = band_runs(35..123, 10).collect();
        assert_eq!(runs, vec![35..40, 40..80, 80..120, 120..123]);
        assert_eq!(band_runs(40..80, 10).collect::<Vec<_>>(), vec![40..80]);
        assert_eq!(band_runs(7..7, 10).count(), 0);
        assert_eq!(band_runs(0..3, 1).collect::<Vec<_>>(), vec![0..3]);
    }
}
