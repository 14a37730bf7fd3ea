//! The stage functions of the adaptive sampler's two rounds, shared by fused Render tasks
//! (both rounds in one task, [`super::adaptive_span`]) and staged jobs (each round through
//! the five staged stages, [`super::rounds`]):
//! - which samples a round casts ([`first_round_samples`], [`second_round_samples`]) and
//!   their camera rays ([`cast_samples`]);
//! - the radiance of each sample from its hit and the occlusion keys ([`sample_colours`]);
//! - the pixels after round 1 and the pixels that need round 2 ([`first_round_pixels`]), and
//!   the pixels after round 2 ([`second_round_pixels`]).
//!
//! A pixel's decision uses only its own first-pass samples, and its value is the in-order f32
//! sum of its samples in rank order divided by their count, the second round continuing the
//! first round's sum ([`PixelSum::from_sum`]); so every path gives the monolithic adaptive
//! render's bits ([`crate::adaptive`]).

use super::plan::{JobPlan, Span};
use super::records::{Occluded, PixelBlock, SurfaceHit};
use super::refine_list::RefineList;
use super::split_object::SplitObject;
use super::stages::{BATCH, push_surface_hits, sample_colour};
use crate::adaptive::{AdaptiveCounts, AdaptiveSettings, Decision, decide};
use crate::bvh::ClosestPackets;
use crate::camera::Camera;
use crate::hits::Hit;
use crate::sampling::PixelSum;

/// Round 1's samples of `span`: ranks `0..base_spp` of every pixel, sorted by (pixel, rank).
pub fn first_round_samples(span: &Span, a: &AdaptiveSettings) -> Vec<(u64, u32)> {
    (span.start..span.end)
        .flat_map(|p| (0..a.base_spp).map(move |r| (p, r)))
        .collect()
}

/// Round 2's samples of the pixels `list` refines: ranks `base_spp..max_spp` of each, sorted
/// by (pixel, rank).
pub fn second_round_samples(list: &RefineList, a: &AdaptiveSettings) -> Vec<(u64, u32)> {
    list.pixels
        .iter()
        .flat_map(|&p| (a.base_spp..a.max_spp).map(move |r| (u64::from(p), r)))
        .collect()
}

/// CastMap over an explicit sample list with the adaptive pattern's rays: the split's nearest
/// hit of each sample that hits it, in sample order (so sorted by (pixel, rank)).
pub fn cast_samples(
    camera: &Camera,
    split: &SplitObject,
    samples: &[(u64, u32)],
    max_spp: u32,
) -> Vec<SurfaceHit> {
    let mut out = Vec::new();
    let mut hits = Vec::with_capacity(BATCH);
    let (mut rays, mut ranks) = (Vec::with_capacity(BATCH), Vec::new());
    for batch in samples.chunks(BATCH) {
        // Each pixel's run of samples at once: `Camera::sample_ray` of each, the pixel's work
        // done once and the rays made in lanes.
        rays.clear();
        for run in batch.chunk_by(|a, b| a.0 == b.0) {
            ranks.clear();
            ranks.extend(run.iter().map(|&(_, rank)| rank));
            camera.pixels_samples_rays(&[run[0].0], (&ranks, max_spp), &mut rays);
        }
        let rays = (batch, rays.as_slice(), ClosestPackets::DEFAULT);
        push_surface_hits(split, rays, &mut hits, &mut out, 0..batch.len());
    }
    out
}

/// Each sample's radiance and hit ([`Hit::MISS`] for a miss), in the order of `samples`
/// ((pixel, rank) sorted), from the samples' nearest hits `hits` (sorted the same way; samples
/// that missed are absent) and the occlusion keys `blocked` (sorted).
pub fn sample_colours(
    plan: &JobPlan,
    samples: &[(u64, u32)],
    hits: &[SurfaceHit],
    blocked: &[Occluded],
) -> (Vec<[f32; 3]>, Vec<Hit>) {
    let mut next_hit = hits.iter().peekable();
    let mut colours = Vec::with_capacity(samples.len());
    let mut sample_hits = Vec::with_capacity(samples.len());
    for &(pixel, rank) in samples {
        let pixel = pixel as u32;
        let hit = next_hit.next_if(|h| h.pixel == pixel && h.sample == rank);
        colours.push(sample_colour(plan, pixel, rank, hit, blocked));
        sample_hits.push(hit.map_or(Hit::MISS, |h| Hit {
            triangle: h.triangle,
            t: h.t,
        }));
    }
    (colours, sample_hits)
}

/// The pixels of `span` after round 1 from its first-pass samples (`colours` and `hits`, rank
/// order, `base_spp` per pixel): each pixel's first-pass mean and rank-0 hit (final for the
/// pixels that get no more samples), the pixels round 2 refines with their first-pass sums,
/// and the decision counts.
pub fn first_round_pixels(
    span: &Span,
    a: &AdaptiveSettings,
    colours: &[[f32; 3]],
    hits: &[Hit],
) -> (PixelBlock, RefineList, AdaptiveCounts) {
    let base = a.base_spp as usize;
    let n = (span.end - span.start) as usize;
    let mut block = PixelBlock::with_capacity(span.start, n);
    let mut list = RefineList::default();
    let mut counts = AdaptiveCounts::default();
    for ((pixel, first), hits) in (span.start..span.end)
        .zip(colours.chunks(base))
        .zip(hits.chunks(base))
    {
        let any_hit = hits.iter().any(|h| h.triangle != Hit::MISS.triangle);
        let decision = decide(first, any_hit, a.threshold);
        let mut sum = PixelSum::default();
        for &c in first {
            sum.add(c);
        }
        block.colours.push(sum.mean(a.base_spp));
        block.triangles.push(hits[0].triangle);
        block.ts.push(hits[0].t);
        if decision == Decision::Refine {
            list.pixels.push(pixel as u32);
            list.sums.push(sum.sum());
        }
        counts.add(decision, a);
    }
    (block, list, counts)
}

/// The pixels of a span after round 2: `first` (round 1's block) with each pixel of `list`
/// replaced by its first-pass sum continued with its second-pass radiances `colours` (rank
/// order, `max_spp - base_spp` per listed pixel, in list order) over `max_spp`.
pub fn second_round_pixels(
    mut first: PixelBlock,
    list: &RefineList,
    a: &AdaptiveSettings,
    colours: &[[f32; 3]],
) -> PixelBlock {
    let extra = (a.max_spp - a.base_spp) as usize;
    for ((&pixel, &sum), second) in list
        .pixels
        .iter()
        .zip(&list.sums)
        .zip(colours.chunks(extra))
    {
        let mut sum = PixelSum::from_sum(sum);
        for &c in second {
            sum.add(c);
        }
        first.colours[(u64::from(pixel) - first.start) as usize] = sum.mean(a.max_spp);
    }
    first
}
