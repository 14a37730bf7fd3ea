//! Render (fused mode) with the adaptive sampler: the span's first pass (ranks `0..base_spp`
//! of every pixel) through the stage functions in memory (cast on every split, reduce,
//! expand, trace on every split, shade), then a second round of the same functions for ranks
//! `base_spp..max_spp` of the pixels [`crate::adaptive::decide`] refines, only if any. With
//! one split (the whole scene) the span is rendered as the monolithic adaptive renderer
//! renders its pixels, row by row, without making the stages' records. A span's pixels are
//! all local to its task, and a pixel's decision depends only on its own samples, so the
//! block is bit-identical to the monolithic adaptive render's pixels ([`crate::adaptive`]) and
//! to a staged job's ([`super::adaptive_rounds`]).

use super::PipelineError;
use super::adaptive_rounds::{
    cast_samples, first_round_pixels, first_round_samples, sample_colours, second_round_pixels,
    second_round_samples,
};
use super::plan::{JobPlan, Span};
use super::records::{PixelBlock, SurfaceHit};
use super::split_object::SplitObject;
use super::stages::{cast_reduce, expand, merge_occluded, trace_in_memory, with_plan_lighting};
use crate::adaptive::{AdaptiveCounts, AdaptiveSettings, RefinementOrder, adaptive_run};
use crate::hits::Hit;

/// The span's pixels with the adaptive sampler `a`, the logical shadow rays (hit samples x
/// lights, both passes) and the decision counts. `splits` are the plan's splits in id order.
pub fn render_span_adaptive(
    plan: &JobPlan,
    span: &Span,
    splits: &[&SplitObject],
    a: AdaptiveSettings,
) -> Result<(PixelBlock, u64, AdaptiveCounts), PipelineError> {
    if let [whole] = splits {
        return render_span_whole(plan, span, whole, a);
    }
    let first = pass(plan, splits, &first_round_samples(span, &a), a.max_spp)?;
    let (block, list, counts) = first_round_pixels(span, &a, &first.colours, &first.hits);
    if list.pixels.is_empty() {
        return Ok((block, first.shadow_rays, counts));
    }
    let second = pass(plan, splits, &second_round_samples(&list, &a), a.max_spp)?;
    let block = second_round_pixels(block, &list, &a, &second.colours);
    Ok((block, first.shadow_rays + second.shadow_rays, counts))
}

/// [`render_span_adaptive`] with one split, the whole scene: the span's pixels row by row as
/// the monolithic adaptive renderer renders them ([`adaptive_run`]).
fn render_span_whole(
    plan: &JobPlan,
    span: &Span,
    whole: &SplitObject,
    a: AdaptiveSettings,
) -> Result<(PixelBlock, u64, AdaptiveCounts), PipelineError> {
    let camera = plan.ray_camera()?;
    let refinement = RefinementOrder::new(a);
    let mut block = PixelBlock::with_capacity(span.start, (span.end - span.start) as usize);
    let (mut shadow_rays, mut counts) = (0, AdaptiveCounts::default());
    let width = u64::from(plan.width);
    with_plan_lighting(plan, |lighting| {
        let mut start = span.start;
        while start < span.end {
            // The rest of `start`'s row within the span.
            let end = ((start / width + 1) * width).min(span.end);
            let shading = (whole, &whole.bvh);
            let run = adaptive_run(shading, lighting, &camera, start..end, (a, &refinement));
            block.extend(run.colours, &run.hits);
            shadow_rays += run.rays.shadow;
            counts += run.counts;
            start = end;
        }
    });
    Ok((block, shadow_rays, counts))
}

/// What one round of the stage functions gives, per sample in order.
struct Pass {
    /// Each sample's radiance.
    colours: Vec<[f32; 3]>,
    /// Each sample's hit; a miss is [`Hit::MISS`].
    hits: Vec<Hit>,
    /// Logical shadow rays: hit samples x lights.
    shadow_rays: u64,
}

/// One round of the stage functions over `samples` ((pixel, rank) pairs sorted by pixel, then
/// rank).
fn pass(
    plan: &JobPlan,
    splits: &[&SplitObject],
    samples: &[(u64, u32)],
    max_spp: u32,
) -> Result<Pass, PipelineError> {
    let camera = plan.ray_camera()?;
    let candidates: Vec<Vec<SurfaceHit>> = splits
        .iter()
        .map(|split| cast_samples(&camera, split, samples, max_spp))
        .collect();
    // One split's hits are already the nearest per sample, in order.
    let hits = if candidates.len() == 1 {
        candidates.into_iter().next().unwrap_or_default()
    } else {
        cast_reduce(candidates)
    };
    let blocked = merge_occluded(trace_in_memory(plan, splits, &expand(plan, &hits))?);
    let (colours, sample_hits) = sample_colours(plan, samples, &hits, &blocked);
    Ok(Pass {
        colours,
        hits: sample_hits,
        shadow_rays: hits.len() as u64 * plan.lights.len() as u64,
    })
}
