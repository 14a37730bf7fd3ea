//! Render (fused mode) with the adaptive sampler: the span's first pass (ranks `0..base_spp`
//! of every pixel) through the stage functions in memory (cast on every split, reduce,
//! expand, trace on every split, shade), then a second round of the same functions for ranks
//! `base_spp..max_spp` of the pixels [`decide`] refines, only if any. A span's pixels are all
//! local to its task, and a pixel's decision depends only on its own samples, so the block is
//! bit-identical to the monolithic adaptive render's pixels ([`crate::adaptive`]).

use super::PipelineError;
use super::plan::{JobPlan, Span};
use super::records::{PixelBlock, SurfaceHit};
use super::split_object::SplitObject;
use super::stages::{BATCH, cast_reduce, expand, push_surface_hits, sample_colour, trace_map};
use crate::adaptive::{
    AdaptiveCounts, AdaptiveSettings, Decision, adaptive_ray, decide, pixel_value,
};
use crate::camera::Camera;
use crate::hits::Hit;

/// The span's pixels with the adaptive sampler `a`, the logical shadow rays (hit samples x
/// lights, both passes) and the decision counts. `splits` are the plan's splits in id order.
pub fn render_span_adaptive(
    plan: &JobPlan,
    span: &Span,
    splits: &[&SplitObject],
    a: AdaptiveSettings,
) -> Result<(PixelBlock, u64, AdaptiveCounts), PipelineError> {
    let first: Vec<(u64, u32)> = (span.start..span.end)
        .flat_map(|p| (0..a.base_spp).map(move |r| (p, r)))
        .collect();
    let Pass {
        colours: colours1,
        hits: hits1,
        mut shadow_rays,
    } = pass(plan, splits, &first, a.max_spp)?;
    let base = a.base_spp as usize;
    let decisions: Vec<Decision> = colours1
        .chunks(base)
        .zip(hits1.chunks(base))
        .map(|(c, h)| {
            decide(
                c,
                h.iter().any(|h| h.triangle != Hit::MISS.triangle),
                a.threshold,
            )
        })
        .collect();
    let second: Vec<(u64, u32)> = (span.start..span.end)
        .zip(&decisions)
        .filter(|(_, d)| **d == Decision::Refine)
        .flat_map(|(p, _)| (a.base_spp..a.max_spp).map(move |r| (p, r)))
        .collect();
    let colours2 = if second.is_empty() {
        Vec::new()
    } else {
        let round = pass(plan, splits, &second, a.max_spp)?;
        shadow_rays += round.shadow_rays;
        round.colours
    };
    let n = (span.end - span.start) as usize;
    let mut block = PixelBlock {
        start: span.start,
        colours: Vec::with_capacity(n),
        triangles: Vec::with_capacity(n),
        ts: Vec::with_capacity(n),
    };
    let mut counts = AdaptiveCounts::default();
    let mut refined = colours2.chunks((a.max_spp - a.base_spp) as usize);
    for ((first, hits), &decision) in colours1
        .chunks(base)
        .zip(hits1.chunks(base))
        .zip(&decisions)
    {
        let second = match decision {
            Decision::Refine => refined.next().unwrap_or_default(),
            _ => &[],
        };
        block.colours.push(pixel_value(first, second));
        block.triangles.push(hits[0].triangle);
        block.ts.push(hits[0].t);
        counts.add(decision, &a);
    }
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
    let camera = Camera::new(&plan.camera, plan.width, plan.height)?;
    let candidates: Vec<Vec<SurfaceHit>> = splits
        .iter()
        .map(|split| cast_samples(plan, &camera, split, samples, max_spp))
        .collect();
    // One split's hits are already the nearest per sample, in order.
    let hits = if candidates.len() == 1 {
        candidates.into_iter().next().unwrap_or_default()
    } else {
        cast_reduce(candidates)
    };
    let queries = expand(plan, &hits);
    let mut blocked = Vec::new();
    for (split, queries) in splits.iter().zip(&queries) {
        blocked.extend(trace_map(plan, split, queries).map_err(|light| {
            PipelineError::BadInput(format!(
                "expand named light {light}, the plan has {}",
                plan.lights.len()
            ))
        })?);
    }
    blocked.sort_unstable();
    blocked.dedup();
    let mut next_hit = hits.iter().peekable();
    let mut colours = Vec::with_capacity(samples.len());
    let mut sample_hits = Vec::with_capacity(samples.len());
    for &(pixel, rank) in samples {
        let pixel = pixel as u32;
        let hit = next_hit.next_if(|h| h.pixel == pixel && h.sample == rank);
        colours.push(sample_colour(plan, pixel, rank, hit, &blocked));
        sample_hits.push(hit.map_or(Hit::MISS, |h| Hit {
            triangle: h.triangle,
            t: h.t,
        }));
    }
    Ok(Pass {
        colours,
        hits: sample_hits,
        shadow_rays: hits.len() as u64 * plan.lights.len() as u64,
    })
}

/// CastMap over an explicit sample list with the adaptive pattern's rays: the split's nearest
/// hit of each sample that hits it, in sample order (so sorted by (pixel, rank)).
fn cast_samples(
    plan: &JobPlan,
    camera: &Camera,
    split: &SplitObject,
    samples: &[(u64, u32)],
    max_spp: u32,
) -> Vec<SurfaceHit> {
    let mut out = Vec::new();
    let mut hits = Vec::with_capacity(BATCH);
    for batch in samples.chunks(BATCH) {
        let rays: Vec<_> = batch
            .iter()
            .map(|&(pixel, rank)| adaptive_ray(camera, plan.width, pixel, rank, max_spp))
            .collect();
        push_surface_hits(split, batch, &rays, &mut hits, &mut out);
    }
    out
}
