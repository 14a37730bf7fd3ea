//! The stage functions: pure, deterministic transformations of decoded records. The runner
//! (`runner.rs`) moves their inputs and outputs through storage.

use super::PipelineError;
use super::plan::{JobPlan, Span};
use super::query_order::QueryOrder;
use super::records::{Occluded, PixelBlock, ShadowQuery, SurfaceHit};
use super::split::SplitMode;
use super::split_object::SplitObject;
use crate::bvh::{ClosestHit, ClosestPackets, SegmentGroups, camera_packet, segment_may_hit};
use crate::error::SceneError;
use crate::hits::Hit;
use crate::image::Image;
use crate::phase_timer::NoTimer;
use crate::render::{Lighting, Surfaces, View, band_runs, render_run};
use crate::sampling::{PixelSum, TraceOrder};
use crate::shading::{LastFrame, combine as combine_light, shadow_ray, shadow_test};
use crate::triangle::Ray;

/// CastMap: every camera sample of `span` against one split; the split's nearest hit of each
/// sample that hits it, sorted by (pixel, sample).
pub fn cast_map(
    plan: &JobPlan,
    span: &Span,
    split: &SplitObject,
) -> Result<Vec<SurfaceHit>, SceneError> {
    let camera = plan.ray_camera()?;
    // Batches of whole pixels, each pixel's samples traced in trace order (as the monolithic
    // renderer traces them: coherent packets) and written in sample order.
    let order = TraceOrder::new(plan.spp);
    let spp = plan.spp as usize;
    let pixels_per_batch = (BATCH / spp.max(1)).max(1) as u64;
    let packet = camera_packet(spp);
    let mut out = Vec::new();
    let mut batch: Vec<(u64, u32)> = Vec::with_capacity(BATCH);
    let mut rays = Vec::with_capacity(BATCH);
    let mut batch_pixels = Vec::with_capacity(BATCH);
    let mut hits = Vec::with_capacity(BATCH);
    for first in (span.start..span.end).step_by(pixels_per_batch as usize) {
        let pixels = first..(first + pixels_per_batch).min(span.end);
        batch.clear();
        rays.clear();
        batch_pixels.clear();
        batch_pixels.extend(pixels.clone());
        camera.pixels_rays(&batch_pixels, &order, &mut rays);
        for pixel in pixels.clone() {
            batch.extend(order.samples().iter().map(|&sample| (pixel, sample)));
        }
        let in_sample_order = (0..pixels.count())
            .flat_map(|p| (0..plan.spp).map(move |sample| (p, sample)))
            .map(|(p, sample)| p * spp + order.position(sample));
        push_surface_hits(
            split,
            (&batch, &rays, packet),
            &mut hits,
            &mut out,
            in_sample_order,
        );
    }
    Ok(out)
}

/// Traces the camera rays `rays` of the samples `batch` ((pixel, sample), one per ray) against
/// `split` in `packet`'s packets, and appends the split's nearest hit of each sample that
/// hits it to `out`, taking the samples in the order of the indices `write_order` (into
/// `batch`). `hits` is scratch space.
pub(super) fn push_surface_hits(
    split: &SplitObject,
    (batch, rays, packet): (&[(u64, u32)], &[Ray], ClosestPackets),
    hits: &mut Vec<Option<ClosestHit>>,
    out: &mut Vec<SurfaceHit>,
    write_order: impl IntoIterator<Item = usize>,
) {
    // `closest_hits_in_packets` writes every place: only a new length is filled.
    hits.resize(rays.len(), None);
    split.bvh.closest_hits_in_packets(rays, hits, packet);
    let mut last = LastFrame::default();
    for i in write_order {
        let Some(hit) = &hits[i] else {
            continue;
        };
        let (pixel, sample) = batch[i];
        out.push(SurfaceHit {
            pixel: pixel as u32,
            sample,
            t: hit.t,
            triangle: hit.id,
            surface: split.surface(&split.bvh, hit, &rays[i], &mut last),
        });
    }
}

/// Camera samples (CastMap) or shadow queries (TraceMap) traced per packet call.
pub(crate) const BATCH: usize = 1024;

/// CastReduce: the nearest candidate per (pixel, sample): smaller t, then smaller triangle id.
/// The result does not depend on the order or grouping of the inputs.
pub fn cast_reduce(inputs: Vec<Vec<SurfaceHit>>) -> Vec<SurfaceHit> {
    let mut all: Vec<SurfaceHit> = inputs.into_iter().flatten().collect();
    all.sort_unstable_by(|a, b| {
        (a.pixel, a.sample)
            .cmp(&(b.pixel, b.sample))
            .then(a.t.total_cmp(&b.t))
            .then(a.triangle.cmp(&b.triangle))
    });
    all.dedup_by_key(|h| (h.pixel, h.sample));
    all
}

/// Expand: for each hit and light whose light can reach it (lights no surface can occlude
/// aside: they need no test), the shadow segment, routed to every
/// split (naive mode, as HORT) or only to splits whose box the segment can meet (spatial mode).
/// Returns one sorted query list per split.
pub fn expand(plan: &JobPlan, hits: &[SurfaceHit]) -> Vec<Vec<ShadowQuery>> {
    let boxes: Vec<_> = plan.splits.iter().map(|s| s.bounds()).collect();
    let mut out = vec![Vec::new(); boxes.len()];
    for hit in hits {
        for (light_index, light) in plan.lights.iter().enumerate() {
            if plan.is_unoccludable(light_index as u32) {
                continue;
            }
            let Some(test) = shadow_test(&hit.surface, light) else {
                continue;
            };
            let query = ShadowQuery {
                pixel: hit.pixel,
                sample: hit.sample,
                light: light_index as u32,
                origin: test.ray.origin,
            };
            for (split, b) in boxes.iter().enumerate() {
                if plan.split_mode == SplitMode::Naive || segment_may_hit(b, &test.ray, test.t_max)
                {
                    out[split].push(query);
                }
            }
        }
    }
    out
}

/// TraceMap: the queries this split blocks, in input order (so sorted when the input is).
/// Errors when a query names a light the plan does not have.
pub fn trace_map(
    plan: &JobPlan,
    split: &SplitObject,
    queries: &[ShadowQuery],
) -> Result<Vec<Occluded>, u32> {
    let mut out = Vec::new();
    let mut segments = Vec::with_capacity(BATCH);
    let mut blocked = Vec::with_capacity(BATCH);
    let mut traced = Vec::with_capacity(BATCH);
    let mut answers = Vec::with_capacity(BATCH);
    let mut segment_lights = Vec::with_capacity(BATCH);
    let mut groups = SegmentGroups::default();
    let mut order = QueryOrder::new(plan.spp);
    // Neighbours in trace order are coherent, so a batch is traced as packets; the answers
    // are read back in input order.
    for batch in queries.chunks(BATCH) {
        traced.clear();
        order.append(batch, &mut traced);
        segments.clear();
        segment_lights.clear();
        for &i in &traced {
            let q = &batch[i];
            let light = plan.lights.get(q.light as usize).ok_or(q.light)?;
            segments.push(shadow_ray(light, q.origin));
            segment_lights.push(q.light);
        }
        answers.clear();
        answers.resize(segments.len(), false);
        // Light by light: with several lights, neighbouring queries alternate lights.
        let (lights, bvh) = ((segment_lights.as_slice(), plan.lights.len()), &split.bvh);
        bvh.occluded_grouped(&segments, lights, &mut answers, &mut groups);
        blocked.clear();
        blocked.resize(batch.len(), false);
        for (&i, &answer) in traced.iter().zip(&answers) {
            blocked[i] = answer;
        }
        out.extend(
            batch
                .iter()
                .zip(&blocked)
                .filter(|(_, b)| **b)
                .map(|(q, _)| Occluded {
                    pixel: q.pixel,
                    sample: q.sample,
                    light: q.light,
                }),
        );
    }
    Ok(out)
}

/// TraceReduce: shades every sample of `span` (a light counts unless some split blocks it:
/// the darkest contribution wins), averages each pixel's samples, and keeps sample 0's hit.
/// `hits` must be sorted by (pixel, sample) as CastReduce writes them.
pub fn trace_reduce(
    plan: &JobPlan,
    span: &Span,
    hits: &[SurfaceHit],
    occluded: Vec<Vec<Occluded>>,
) -> PixelBlock {
    let blocked = merge_occluded(occluded);
    let n = (span.end - span.start) as usize;
    let mut block = PixelBlock::with_capacity(span.start, n);
    let mut next_hit = hits.iter().peekable();
    for pixel in span.start..span.end {
        let pixel = pixel as u32;
        let mut sum = PixelSum::default();
        let mut first = Hit::MISS;
        for sample in 0..plan.spp {
            let hit = next_hit.next_if(|h| h.pixel == pixel && h.sample == sample);
            if sample == 0
                && let Some(h) = hit
            {
                first = Hit {
                    triangle: h.triangle,
                    t: h.t,
                };
            }
            sum.add(sample_colour(plan, pixel, sample, hit, &blocked));
        }
        block.colours.push(sum.mean(plan.spp));
        block.triangles.push(first.triangle);
        block.ts.push(first.t);
    }
    block
}

/// The occlusion keys of every split as one sorted list without repeats (a key blocked by
/// several splits counts once), as [`sample_colour`] looks them up.
pub(super) fn merge_occluded(occluded: Vec<Vec<Occluded>>) -> Vec<Occluded> {
    let mut blocked: Vec<Occluded> = occluded.into_iter().flatten().collect();
    blocked.sort_unstable();
    blocked.dedup();
    blocked
}

/// The radiance of sample `sample` of `pixel` whose camera ray hit `hit` (the background when
/// `None`): a light counts unless `blocked` (sorted) holds its (pixel, sample, light) key.
pub fn sample_colour(
    plan: &JobPlan,
    pixel: u32,
    sample: u32,
    hit: Option<&SurfaceHit>,
    blocked: &[Occluded],
) -> [f32; 3] {
    let Some(h) = hit else {
        return plan.background;
    };
    let contributions = plan.lights.iter().enumerate().filter_map(|(l, light)| {
        let test = shadow_test(&h.surface, light)?;
        let key = Occluded {
            pixel,
            sample,
            light: l as u32,
        };
        blocked
            .binary_search(&key)
            .is_err()
            .then_some(test.unoccluded)
    });
    combine_light(h.surface.kd, contributions, plan.ambient)
}

/// Render (fused mode): the span's pixels from every split in memory, bit-identical to the
/// staged path's block. With several splits it runs CastMap on each split, CastReduce, Expand,
/// TraceMap on each split and TraceReduce in turn, with no encoding in between; with one (the
/// whole scene) it renders the pixels as the monolithic renderer does, which gives the same
/// bits without making the stages' records. `splits` are the plan's splits in id order.
/// Returns the block and the logical shadow rays (hit samples x lights).
pub fn render_span(
    plan: &JobPlan,
    span: &Span,
    splits: &[&SplitObject],
) -> Result<(PixelBlock, u64), PipelineError> {
    match splits {
        [whole] => Ok(render_span_whole(plan, span, whole)?),
        _ => render_span_staged(plan, span, splits),
    }
}

/// [`render_span`] by running the stage functions in turn.
pub(super) fn render_span_staged(
    plan: &JobPlan,
    span: &Span,
    splits: &[&SplitObject],
) -> Result<(PixelBlock, u64), PipelineError> {
    let candidates = splits
        .iter()
        .map(|split| cast_map(plan, span, split))
        .collect::<Result<Vec<_>, _>>()?;
    // One split's hits are already the nearest per sample, in order.
    let hits = if candidates.len() == 1 {
        candidates.into_iter().next().unwrap_or_default()
    } else {
        cast_reduce(candidates)
    };
    let occluded = trace_in_memory(plan, splits, &expand(plan, &hits))?;
    let shadow_rays = hits.len() as u64 * plan.lights.len() as u64;
    Ok((trace_reduce(plan, span, &hits, occluded), shadow_rays))
}

/// [`render_span`] with one split, the whole scene: the span is rendered as the monolithic
/// renderer renders its pixels ([`render_run`], band by band), which gives the bits of the
/// stages run in turn without making their records.
fn render_span_whole(
    plan: &JobPlan,
    span: &Span,
    whole: &SplitObject,
) -> Result<(PixelBlock, u64), SceneError> {
    let camera = plan.ray_camera()?;
    let order = TraceOrder::new(plan.spp);
    let view = View {
        camera: &camera,
        width: plan.width,
        spp: plan.spp,
        order: &order,
    };
    let mut block = PixelBlock::with_capacity(span.start, (span.end - span.start) as usize);
    let mut shadow_rays = 0;
    with_plan_lighting(plan, |lighting| {
        for run in band_runs(span.start..span.end, plan.width) {
            let band = render_run((whole, &whole.bvh), lighting, &view, run, &mut NoTimer);
            block.extend(band.colours, &band.hits);
            shadow_rays += band.rays.shadow;
        }
    });
    Ok((block, shadow_rays))
}

/// `f` of the plan's lights, ambient and background, with each light's unoccludability, as
/// the renderer's batch path takes them.
pub(super) fn with_plan_lighting<R>(plan: &JobPlan, f: impl FnOnce(&Lighting) -> R) -> R {
    let unoccludable: Vec<bool> = (0..plan.lights.len() as u32)
        .map(|light| plan.is_unoccludable(light))
        .collect();
    f(&Lighting {
        lights: &plan.lights,
        unoccludable: &unoccludable,
        ambient: plan.ambient,
        background: plan.background,
    })
}

/// TraceMap of every split on its queries (`queries[i]` for `splits[i]`), in memory: each
/// split's occlusion keys. A query naming a light the plan lacks is an error.
pub(super) fn trace_in_memory(
    plan: &JobPlan,
    splits: &[&SplitObject],
    queries: &[Vec<ShadowQuery>],
) -> Result<Vec<Vec<Occluded>>, PipelineError> {
    splits
        .iter()
        .zip(queries)
        .map(|(split, queries)| {
            trace_map(plan, split, queries).map_err(|light| {
                PipelineError::BadInput(format!(
                    "expand named light {light}, the plan has {}",
                    plan.lights.len()
                ))
            })
        })
        .collect()
}

/// Combine: the image and the hit buffer from every span's pixels (in any order); a block
/// without its hits ([`PixelBlock::without_hits`]) leaves misses in the buffer.
pub fn combine(plan: &JobPlan, blocks: &[PixelBlock]) -> (Image, Vec<Hit>) {
    let mut image = Image::new(plan.width, plan.height);
    let mut hits = vec![Hit::MISS; plan.width as usize * plan.height as usize];
    for b in blocks {
        let start = b.start as usize;
        image.pixels[start..start + b.colours.len()].copy_from_slice(&b.colours);
        if b.has_hits() {
            let buffer = &mut hits[start..start + b.colours.len()];
            for ((hit, &triangle), &t) in buffer.iter_mut().zip(&b.triangles).zip(&b.ts) {
                *hit = Hit { triangle, t };
            }
        }
    }
    (image, hits)
}
