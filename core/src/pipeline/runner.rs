//! Running one stage task over a [`BlobStore`]: read the inputs named by the plan, call the
//! stage function, write the outputs with plain PUTs (same bytes on every attempt).
//!
//! Lineage: when an input shuffle block is missing or corrupt, the task recomputes it by running
//! its producer task (a pure function of the producer's own inputs), which rewrites it, and goes
//! on; [`TaskMetrics::recomputed`] counts these. Split objects come from the plan step: given a
//! [`RebuildSplit`] (which needs the scene, so only callers that can load it pass one), a
//! missing or corrupt split object is rebuilt, checked against the plan's size and rewritten;
//! without one it is an error.
//!
//! Durations: a task also measures where its own time went ([`TaskMetrics::task_us`] and the
//! four parts `compute_us`, `encode_us`, `decode_us`, `storage_us`). They are measurements,
//! different on every run; nothing stored or returned besides the metrics depends on them.

use super::PipelineError;
use super::adaptive_rounds::{
    cast_samples, first_round_pixels, first_round_samples, sample_colours, second_round_pixels,
    second_round_samples,
};
use super::adaptive_span::render_span_adaptive;
use super::frames::assembled_frames;
use super::plan::{CastTask, JobPlan, Span};
use super::records::{Occluded, SurfaceHit};
use super::records::{
    PixelBlock, decode_occluded, decode_pixels, decode_queries, decode_surface_hits,
    encode_occluded, encode_pixels, encode_queries, encode_surface_hits,
};
use super::refine_list::{RefineList, decode_refine_list, encode_refine_list};
use super::split_cache::SplitCache;
use super::split_object::{SplitObject, decode_split};
use super::stages;
use super::textures::decode_planned_texture;
use crate::adaptive::{AdaptiveCounts, AdaptiveSettings};
use crate::hits::{Hit, encode_hits};
use crate::ids::{JobId, PartitionId, SplitId, TaskId};
use crate::image::{Image, encode_pfm, encode_png};
use crate::keys::{
    FrameKeys, hits_key, image_key, parse_partition_key, partition_key, split_key, texture_key,
};
use crate::shuffle::{RecordKind, relabel_block};
use crate::stage::Stage;
use crate::store::{BlobStore, StoreError};
use crate::task_metrics::{TaskMetrics, micros, timed};
use crate::texture::Texture;
use std::sync::Arc;
use std::time::Instant;

/// Checks that the pixel block stored at `key` covers exactly `span`.
fn check_block(key: &str, block: &PixelBlock, span: &Span) -> Result<(), PipelineError> {
    if block.start != span.start || block.colours.len() as u64 != span.end - span.start {
        return Err(PipelineError::Corrupt(format!(
            "shuffle block {key}: holds pixels {}..{}, the plan's span is {}..{}",
            block.start,
            block.start + block.colours.len() as u64,
            span.start,
            span.end
        )));
    }
    Ok(())
}

/// Builds the encoded split object with the given id from the job's scene, exactly as the plan
/// step stored it (see `rebuild_split`): the lineage of split objects.
pub type RebuildSplit<'a> = &'a dyn Fn(u32) -> Result<Vec<u8>, PipelineError>;

/// The task that writes partition `key`, if it is a shuffle partition of this job.
pub fn producer_of(key: &str) -> Option<(Stage, u32)> {
    parse_partition_key(key).map(|k| (k.stage, k.task.0))
}

/// Runs task `task` of `stage` for `job` and writes its outputs.
pub fn run_task(
    store: &dyn BlobStore,
    job: &JobId,
    plan: &JobPlan,
    stage: Stage,
    task: u32,
) -> Result<TaskMetrics, PipelineError> {
    run_task_cached(store, job, plan, stage, task, &SplitCache::new(0))
}

/// [`run_task`] with a worker's cache of decoded splits (same outputs, fewer split reads).
pub fn run_task_cached(
    store: &dyn BlobStore,
    job: &JobId,
    plan: &JobPlan,
    stage: Stage,
    task: u32,
    cache: &SplitCache,
) -> Result<TaskMetrics, PipelineError> {
    run_task_with(store, job, plan, stage, task, cache, None)
}

/// [`run_task_cached`] that rebuilds lost or corrupt split objects with `rebuild`, if given.
pub fn run_task_with(
    store: &dyn BlobStore,
    job: &JobId,
    plan: &JobPlan,
    stage: Stage,
    task: u32,
    cache: &SplitCache,
    rebuild: Option<RebuildSplit<'_>>,
) -> Result<TaskMetrics, PipelineError> {
    run_frame_task(store, job, plan, None, stage, task, cache, rebuild)
}

/// [`run_task_with`] for frame `frame` of a job of several frames (`None` in a job of one):
/// the task of that frame alone ([`JobPlan::frame_view`]), its partitions and outputs under the
/// frame's keys ([`FrameKeys`]), the splits and textures the job's. The task of a frame's last
/// pixel stage that finds the frame complete assembles it (`assemble_frame_when_done`); the
/// Combine task of a job of several frames, named without a frame, assembles the frames no task
/// did and then writes the poster.
#[allow(clippy::too_many_arguments)]
pub fn run_frame_task(
    store: &dyn BlobStore,
    job: &JobId,
    plan: &JobPlan,
    frame: Option<u32>,
    stage: Stage,
    task: u32,
    cache: &SplitCache,
    rebuild: Option<RebuildSplit<'_>>,
) -> Result<TaskMetrics, PipelineError> {
    if stage == Stage::Combine && frame.is_none() && !plan.frames.is_empty() {
        // Most frames were assembled by the task that finished them: assemble the rest.
        let mut metrics = TaskMetrics::default();
        let assembled = assembled_frames_timed(store, job, &mut metrics)?;
        for frame in plan.frame_numbers() {
            if !frame.is_some_and(|f| assembled.contains(&f)) {
                metrics += run_frame_task(store, job, plan, frame, stage, task, cache, rebuild)?;
            }
        }
        metrics += write_poster(store, job, plan)?;
        return Ok(metrics);
    }
    let view = plan.frame_view(frame)?;
    let mut ctx = Task {
        store,
        job,
        frame,
        plan: &view,
        cache,
        rebuild,
        metrics: TaskMetrics::default(),
        depth: 0,
    };
    let started = Instant::now();
    ctx.run(stage, task)?;
    if frame.is_some() && stage == view.mode.pixel_stage() {
        ctx.assemble_frame_when_done()?;
    }
    ctx.metrics.task_us = micros(started.elapsed());
    Ok(ctx.metrics)
}

/// [`assembled_frames`], timed into `metrics`.
fn assembled_frames_timed(
    store: &dyn BlobStore,
    job: &JobId,
    metrics: &mut TaskMetrics,
) -> Result<std::collections::BTreeSet<u32>, PipelineError> {
    Ok(timed(&mut metrics.storage_us, || {
        assembled_frames(store, job)
    })?)
}

/// The last object the Combine task of a job of several frames writes: the first frame's PNG
/// as the job's own `out/image.png` (its poster), so a job whose PNG exists has every frame.
fn write_poster(
    store: &dyn BlobStore,
    job: &JobId,
    plan: &JobPlan,
) -> Result<TaskMetrics, PipelineError> {
    let mut metrics = TaskMetrics::default();
    let first = FrameKeys {
        job,
        frame: plan.frames.first().map(|f| f.frame),
    };
    let png = timed(&mut metrics.storage_us, || {
        store.get(&image_key(&first, "png"))
    })?;
    timed(&mut metrics.storage_us, || {
        store.put(&image_key(job, "png"), &png)
    })?;
    metrics.bytes_read += png.len() as u64;
    metrics.bytes_written += png.len() as u64;
    metrics.bytes_written_raw += png.len() as u64;
    Ok(metrics)
}

/// The spans whose pixels round 1 of a staged adaptive job left to refine (those with a
/// non-empty refine list), ascending, and what reading the lists took. Empty for other jobs.
/// A missing or corrupt list is recomputed from its TraceReduce task, as any input block.
pub fn refined_spans(
    store: &dyn BlobStore,
    job: &JobId,
    plan: &JobPlan,
    cache: &SplitCache,
) -> Result<(Vec<u32>, TaskMetrics), PipelineError> {
    let mut ctx = Task {
        store,
        job,
        frame: None,
        plan,
        cache,
        rebuild: None,
        metrics: TaskMetrics::default(),
        depth: 0,
    };
    let started = Instant::now();
    let mut spans = Vec::new();
    if plan.has_second_round() {
        for span in 0..plan.spans.len() as u32 {
            if !ctx.read_refine_list(span)?.pixels.is_empty() {
                spans.push(span);
            }
        }
    }
    ctx.metrics.task_us = micros(started.elapsed());
    Ok((spans, ctx.metrics))
}

/// The error of a task that the plan does not have: `what` names the plan's list it is not in.
fn missing(stage: Stage, task: u32, what: &str) -> PipelineError {
    PipelineError::BadInput(format!(
        "{stage} task {task} does not exist in the plan ({what})"
    ))
}

struct Task<'a> {
    store: &'a dyn BlobStore,
    job: &'a JobId,
    /// The frame, in a job of several frames: its partitions and outputs have its keys.
    frame: Option<u32>,
    /// The plan of the task's frame ([`JobPlan::frame_view`]).
    plan: &'a JobPlan,
    cache: &'a SplitCache,
    rebuild: Option<RebuildSplit<'a>>,
    metrics: TaskMetrics,
    /// Nesting of lineage recomputation (bounded by the stage chain).
    depth: u32,
}

impl Task<'_> {
    fn run(&mut self, stage: Stage, task: u32) -> Result<(), PipelineError> {
        match stage {
            Stage::Render => self.render(task),
            Stage::CastMap => self.cast_map(task),
            Stage::CastReduce => self.cast_reduce(task),
            Stage::Expand => self.expand(task),
            Stage::TraceMap => self.trace_map(task),
            Stage::TraceReduce => self.trace_reduce(task),
            Stage::Combine => self.combine(),
            Stage::Plan => Err(PipelineError::BadInput(
                "the plan stage runs in the Plan function, not as a worker task".into(),
            )),
            Stage::Partition | Stage::Build => Err(PipelineError::BadInput(format!(
                "{stage} task {task}: not a task of the plan (a scene's partition and build \
                 tasks run before the plan exists)"
            ))),
        }
    }

    /// Render (fused mode): one span against every split, cast, shadow rays and shading.
    fn render(&mut self, task: u32) -> Result<(), PipelineError> {
        let plan = self.plan;
        let stage = Stage::Render;
        let span = *plan
            .spans
            .get(task as usize)
            .filter(|_| plan.task_count(Stage::Render) > 0)
            .ok_or_else(|| missing(stage, task, "render tasks"))?;
        let splits = (0..plan.k())
            .map(|split| self.read_split(split))
            .collect::<Result<Vec<_>, _>>()?;
        let splits: Vec<&SplitObject> = splits.iter().map(Arc::as_ref).collect();
        let (block, shadow_rays, adaptive) =
            timed(&mut self.metrics.compute_us, || match plan.adaptive {
                Some(a) => render_span_adaptive(plan, &span, &splits, a),
                None => stages::render_span(plan, &span, &splits)
                    .map(|(block, rays)| (block, rays, AdaptiveCounts::default())),
            })?;
        self.metrics.shadow_rays += shadow_rays;
        self.metrics.adaptive += adaptive;
        self.write_pixels(stage, task, block)
    }

    /// CastMap: a span's camera samples (or a round's) against one split; candidate hits by
    /// reducer.
    fn cast_map(&mut self, task: u32) -> Result<(), PipelineError> {
        let plan = self.plan;
        let stage = Stage::CastMap;
        let (round, index) = plan
            .round_of(stage, task)
            .ok_or_else(|| missing(stage, task, "cast tasks"))?;
        let t = plan.cast_tasks[index as usize];
        let span = plan.spans[t.span as usize];
        let reduce = plan.round_task(Stage::CastReduce, t.span, round);
        let hits = match plan.adaptive {
            Some(a) => self.cast_round(t, &span, round, a)?,
            None => self.cast_uniform(t, &span)?,
        };
        self.write_hits(stage, task, reduce, RecordKind::CastCandidate, &hits)
    }

    /// The candidate hits of an adaptive job's CastMap task `t` in `round`: round 1 casts the
    /// first `base_spp` samples of every pixel of `span`, round 2 the further samples of the
    /// pixels round 1 listed for refining. With no samples the split is not read and the task
    /// counts as skipped.
    fn cast_round(
        &mut self,
        t: CastTask,
        span: &Span,
        round: u32,
        a: AdaptiveSettings,
    ) -> Result<Vec<SurfaceHit>, PipelineError> {
        let samples = match round {
            1 => first_round_samples(span, &a),
            _ => second_round_samples(&self.read_refine_list(t.span)?, &a),
        };
        if samples.is_empty() {
            self.metrics.skipped_tasks += 1;
            return Ok(Vec::new());
        }
        let split = self.read_split(t.split)?;
        let plan = self.plan;
        let camera = plan.ray_camera()?;
        Ok(timed(&mut self.metrics.compute_us, || {
            cast_samples(&camera, &split, &samples, a.max_spp)
        }))
    }

    /// The candidate hits of a uniform job's CastMap task `t`: every sample of `span` against
    /// its split.
    fn cast_uniform(&mut self, t: CastTask, span: &Span) -> Result<Vec<SurfaceHit>, PipelineError> {
        let split = self.read_split(t.split)?;
        let plan = self.plan;
        let hits = timed(&mut self.metrics.compute_us, || {
            stages::cast_map(plan, span, &split)
        })?;
        Ok(hits)
    }

    /// CastReduce: the nearest candidate per sample of a span (one input is passed through).
    fn cast_reduce(&mut self, task: u32) -> Result<(), PipelineError> {
        let plan = self.plan;
        let stage = Stage::CastReduce;
        let (round, index) = plan
            .round_of(stage, task)
            .ok_or_else(|| missing(stage, task, "spans"))?;
        let span = plan.spans[index as usize];
        let inputs: Vec<u32> = plan
            .cast_tasks_of(index)
            .map(|t| plan.round_task(Stage::CastMap, t.task, round))
            .collect();
        if let [only] = inputs[..] {
            return self.pass_through_hits(only, task);
        }
        let keys: Vec<String> = inputs
            .iter()
            .map(|&cast_task| self.key(Stage::CastMap, cast_task, task))
            .collect();
        let candidates = self.read_all(&keys, |k, b| {
            decode_surface_hits(k, b, RecordKind::CastCandidate)
        })?;
        let hits = timed(&mut self.metrics.compute_us, || {
            stages::cast_reduce(candidates)
        });
        debug_assert!(
            hits.iter()
                .all(|h| u64::from(h.pixel) >= span.start && u64::from(h.pixel) < span.end)
        );
        self.write_hits(stage, task, 0, RecordKind::Hit, &hits)
    }

    /// Expand: a span's hits routed to the splits their shadow rays must be tested against.
    fn expand(&mut self, task: u32) -> Result<(), PipelineError> {
        let plan = self.plan;
        let stage = Stage::Expand;
        plan.round_of(stage, task)
            .ok_or_else(|| missing(stage, task, "spans"))?;
        let hits = self.read_span_hits(task)?;
        let routed = timed(&mut self.metrics.compute_us, || stages::expand(plan, &hits));
        let blocks = routed
            .iter()
            .enumerate()
            .map(|(split, queries)| {
                let block = timed(&mut self.metrics.encode_us, || encode_queries(queries));
                (self.key(stage, task, split as u32), block, queries.len())
            })
            .collect();
        self.write_all(blocks)
    }

    /// TraceMap: routed shadow queries against one split; the occluded ones.
    fn trace_map(&mut self, task: u32) -> Result<(), PipelineError> {
        let plan = self.plan;
        let stage = Stage::TraceMap;
        let (round, index) = plan
            .round_of(stage, task)
            .ok_or_else(|| missing(stage, task, "trace tasks"))?;
        let t = plan.trace_tasks[index as usize];
        let expand = plan.round_task(Stage::Expand, t.span, round);
        let key = self.key(Stage::Expand, expand, t.split);
        let queries = self.read(&key, decode_queries)?;
        let occluded = if queries.is_empty() {
            self.metrics.skipped_tasks += 1;
            Vec::new()
        } else {
            let split = self.read_split(t.split)?;
            timed(&mut self.metrics.compute_us, || {
                stages::trace_map(plan, &split, &queries)
            })
            .map_err(|light| {
                PipelineError::Corrupt(format!(
                    "shuffle block {key}: a query names light {light}, the plan has {}",
                    plan.lights.len()
                ))
            })?
        };
        let bytes = timed(&mut self.metrics.encode_us, || encode_occluded(&occluded));
        let reduce = plan.round_task(Stage::TraceReduce, t.span, round);
        self.write(&self.key(stage, task, reduce), bytes, occluded.len())
    }

    /// TraceReduce: a span's samples shaded from its hits and the occluded queries (with the
    /// adaptive sampler, round 1 also writes the refine list and round 2 refines).
    fn trace_reduce(&mut self, task: u32) -> Result<(), PipelineError> {
        let plan = self.plan;
        let stage = Stage::TraceReduce;
        let (round, index) = plan
            .round_of(stage, task)
            .ok_or_else(|| missing(stage, task, "spans"))?;
        let span = plan.spans[index as usize];
        let hits = self.read_span_hits(task)?;
        let keys = self.occluded_keys(index, round, task);
        let occluded = self.read_all(&keys, decode_occluded)?;
        self.metrics.shadow_rays += hits.len() as u64 * plan.lights.len() as u64;
        let Some(a) = plan.adaptive else {
            return self.shade_uniform(task, &span, &hits, occluded);
        };
        let blocked = stages::merge_occluded(occluded);
        if round == 1 {
            self.shade_first_round(task, &span, a, &hits, &blocked)
        } else {
            self.shade_second_round(task, index, &span, a, &hits, &blocked)
        }
    }

    /// The keys of the occluded-query blocks TraceReduce task `task` (span `index`, `round`)
    /// reads: one per split's TraceMap task, none without shadow rays (no light a surface can
    /// occlude, so no TraceMap tasks).
    fn occluded_keys(&self, index: u32, round: u32, task: u32) -> Vec<String> {
        let plan = self.plan;
        let shadow_splits = if plan.has_shadows() { plan.k() } else { 0 };
        (0..shadow_splits)
            .map(|split| {
                let map = plan.trace_task_id(index, split);
                self.key(
                    Stage::TraceMap,
                    plan.round_task(Stage::TraceMap, map, round),
                    task,
                )
            })
            .collect()
    }

    /// A uniform job's TraceReduce task: every sample of `span` shaded from its hits and the
    /// TraceMap tasks' `occluded` queries, written as the span's pixels.
    fn shade_uniform(
        &mut self,
        task: u32,
        span: &Span,
        hits: &[SurfaceHit],
        occluded: Vec<Vec<Occluded>>,
    ) -> Result<(), PipelineError> {
        let plan = self.plan;
        let block = timed(&mut self.metrics.compute_us, || {
            stages::trace_reduce(plan, span, hits, occluded)
        });
        self.write_pixels(Stage::TraceReduce, task, block)
    }

    /// Round 1 of an adaptive TraceReduce task: the first `base_spp` samples of every pixel of
    /// `span` shaded, the refine list (partition 1) written, then the round's pixels
    /// (partition 0).
    fn shade_first_round(
        &mut self,
        task: u32,
        span: &Span,
        a: AdaptiveSettings,
        hits: &[SurfaceHit],
        blocked: &[Occluded],
    ) -> Result<(), PipelineError> {
        let plan = self.plan;
        let samples = first_round_samples(span, &a);
        let (block, list, counts) = timed(&mut self.metrics.compute_us, || {
            let (colours, sample_hits) = sample_colours(plan, &samples, hits, blocked);
            first_round_pixels(span, &a, &colours, &sample_hits)
        });
        self.metrics.adaptive += counts;
        let bytes = timed(&mut self.metrics.encode_us, || encode_refine_list(&list));
        self.write(
            &self.key(Stage::TraceReduce, task, 1),
            bytes,
            list.pixels.len(),
        )?;
        self.write_pixels(Stage::TraceReduce, task, block)
    }

    /// Round 2 of an adaptive TraceReduce task for span `index`: the further samples of the
    /// pixels round 1 listed shaded and folded into round 1's pixels of the span (read and
    /// checked against it), which are written as the span's final pixels.
    fn shade_second_round(
        &mut self,
        task: u32,
        index: u32,
        span: &Span,
        a: AdaptiveSettings,
        hits: &[SurfaceHit],
        blocked: &[Occluded],
    ) -> Result<(), PipelineError> {
        let plan = self.plan;
        let list = self.read_refine_list(index)?;
        let first_key = self.key(Stage::TraceReduce, index, 0);
        let first = self.read(&first_key, decode_pixels)?;
        check_block(&first_key, &first, span)?;
        let block = timed(&mut self.metrics.compute_us, || {
            let samples = second_round_samples(&list, &a);
            let (colours, _) = sample_colours(plan, &samples, hits, blocked);
            second_round_pixels(first, &list, &a, &colours)
        });
        self.write_pixels(Stage::TraceReduce, task, block)
    }

    /// Combine: every span's pixels assembled into the image and the outputs the plan asks for.
    fn combine(&mut self) -> Result<(), PipelineError> {
        let plan = self.plan;
        let keys = self.final_pixel_keys()?;
        let blocks = self.read_all(&keys, decode_pixels)?;
        for ((key, block), span) in keys.iter().zip(&blocks).zip(&plan.spans) {
            check_block(key, block, span)?;
        }
        let (image, hits) = timed(&mut self.metrics.compute_us, || {
            stages::combine(plan, &blocks)
        });
        self.write_job_outputs(&image, &hits)?;
        self.metrics.records += hits.len() as u64;
        Ok(())
    }

    /// In a job of several frames, after a task of the frame's last pixel stage: once every
    /// span's pixel block of the frame is stored, assemble the frame's outputs now, so frames
    /// arrive as they finish rather than when the job ends. Of the tasks that finish a frame at
    /// about the same time, the one that lists last sees every block (listings are strongly
    /// consistent), so the frame is always assembled by one of them; two that both see every
    /// block write the same bytes. A frame whose PNG is stored is left as it is.
    fn assemble_frame_when_done(&mut self) -> Result<(), PipelineError> {
        let stage = self.plan.mode.pixel_stage();
        let prefix = format!("jobs/{}/{stage}/", self.scope());
        let store = self.store;
        let listed: std::collections::HashSet<String> =
            timed(&mut self.metrics.storage_us, || store.list(&prefix))?
                .into_iter()
                .collect();
        let spans = self.plan.spans.len() as u32;
        if !(0..spans).all(|span| listed.contains(&self.key(stage, span, 0))) {
            return Ok(());
        }
        let png = image_key(&self.scope(), "png");
        if timed(&mut self.metrics.storage_us, || store.size(&png)).is_ok() {
            return Ok(());
        }
        self.combine()
    }

    /// The key of every span's final pixel block, in span order: round 2's for a span with
    /// pixels to refine, round 1's (the only round of other jobs) for the rest.
    fn final_pixel_keys(&mut self) -> Result<Vec<String>, PipelineError> {
        let plan = self.plan;
        let mut keys = Vec::with_capacity(plan.spans.len());
        for i in 0..plan.spans.len() as u32 {
            let round = if plan.has_second_round() && !self.read_refine_list(i)?.pixels.is_empty() {
                2
            } else {
                1
            };
            let stage = plan.mode.pixel_stage();
            keys.push(self.key(stage, plan.round_task(stage, i, round), 0));
        }
        Ok(keys)
    }

    /// Stores the job's outputs: those the plan asks for besides the PNG at once
    /// ([`BlobStore::put_many`]), then the PNG, so a job whose PNG exists has every output it
    /// asked for.
    fn write_job_outputs(&mut self, image: &Image, hits: &[Hit]) -> Result<(), PipelineError> {
        let outputs = self.plan.outputs;
        let (job, frame) = (self.job, self.frame);
        let scope = FrameKeys { job, frame };
        let (png, others) = timed(&mut self.metrics.encode_us, || {
            let mut others = Vec::new();
            if outputs.linear {
                others.push((image_key(&scope, "pfm"), encode_pfm(image)));
            }
            if outputs.hits {
                others.push((hits_key(&scope), encode_hits(hits)));
            }
            (encode_png(image), others)
        });
        let png = png.map_err(|e| PipelineError::BadInput(e.to_string()))?;
        if !others.is_empty() {
            self.write_plain_all(&others)?;
        }
        self.write_plain_all(&[(image_key(&scope, "png"), png)])
    }

    /// The keys of the task's frame's own objects.
    fn scope(&self) -> FrameKeys<'_> {
        FrameKeys {
            job: self.job,
            frame: self.frame,
        }
    }

    fn key(&self, stage: Stage, task: u32, partition: u32) -> String {
        partition_key(&self.scope(), stage, TaskId(task), PartitionId(partition))
    }

    fn read_split(&mut self, split: u32) -> Result<Arc<SplitObject>, PipelineError> {
        let key = split_key(self.job, SplitId(split));
        if let Some(object) = self.cache.get(&key) {
            self.metrics.split_cache_hits += 1;
            return Ok(object);
        }
        let store = self.store;
        let first = timed(&mut self.metrics.storage_us, || store.get(&key))
            .map_err(PipelineError::from)
            .and_then(|bytes| {
                self.metrics.bytes_read += bytes.len() as u64;
                self.metrics.split_bytes_read += bytes.len() as u64;
                timed(&mut self.metrics.decode_us, || decode_split(&key, &bytes))
            });
        let lost = match &first {
            Err(PipelineError::Store(e)) => e.is_not_found(),
            Err(PipelineError::Corrupt(_)) => true,
            _ => false,
        };
        let mut object = match (first, self.rebuild) {
            (Err(_), Some(rebuild)) if lost => self.rebuilt_split(&key, split, rebuild)?,
            (first, _) => first?,
        };
        object.attach(|id| self.read_texture(split, id))?;
        let object = Arc::new(object);
        self.cache.insert(&key, Arc::clone(&object));
        Ok(object)
    }

    /// Texture `id` of the plan (used by split `split`): from the cache if a split holds it,
    /// else read, checked against the plan's content key and remembered.
    fn read_texture(&mut self, split: u32, id: u32) -> Result<Arc<Texture>, PipelineError> {
        let planned = self.plan.textures.get(id as usize).ok_or_else(|| {
            PipelineError::Corrupt(format!(
                "split {split} uses texture {id}, but the plan lists {} textures",
                self.plan.textures.len()
            ))
        })?;
        let key = texture_key(self.job, &planned.key);
        if let Some(texture) = self.cache.texture(&key) {
            return Ok(texture);
        }
        let store = self.store;
        let bytes = timed(&mut self.metrics.storage_us, || store.get(&key))?;
        self.metrics.bytes_read += bytes.len() as u64;
        let texture = timed(&mut self.metrics.decode_us, || {
            decode_planned_texture(&key, &bytes, planned)
        })?;
        let texture = Arc::new(texture);
        self.cache.insert_texture(&key, &texture);
        Ok(texture)
    }

    /// Rebuilds split object `split` (stored at `key`) from the scene, checks its size against
    /// the plan, stores it and decodes it.
    fn rebuilt_split(
        &mut self,
        key: &str,
        split: u32,
        rebuild: RebuildSplit<'_>,
    ) -> Result<SplitObject, PipelineError> {
        let bytes = timed(&mut self.metrics.compute_us, || rebuild(split))?;
        let planned = self.plan.splits.get(split as usize).map(|s| s.bytes);
        if planned != Some(bytes.len() as u64) {
            return Err(PipelineError::Corrupt(format!(
                "split object {key}: rebuilt from the scene it has {} bytes, the plan says {}",
                bytes.len(),
                planned.map_or_else(|| "no such split".to_owned(), |n| n.to_string())
            )));
        }
        self.metrics.bytes_written += bytes.len() as u64;
        let store = self.store;
        timed(&mut self.metrics.storage_us, || store.put(key, &bytes))?;
        self.metrics.recomputed += 1;
        timed(&mut self.metrics.decode_us, || decode_split(key, &bytes))
    }

    /// The refine list round 1 wrote for span `span` (TraceReduce's partition 1), checked
    /// against the span.
    fn read_refine_list(&mut self, span: u32) -> Result<RefineList, PipelineError> {
        let key = self.key(Stage::TraceReduce, span, 1);
        let list = self.read(&key, decode_refine_list)?;
        let s = self.plan.spans[span as usize];
        list.check(&key, s.start, s.end)?;
        Ok(list)
    }

    /// Stores a task's pixel block (partition 0 of `stage`), without its sample-0 hits when the
    /// job stores no hit buffer (nothing reads them then).
    fn write_pixels(
        &mut self,
        stage: Stage,
        task: u32,
        block: PixelBlock,
    ) -> Result<(), PipelineError> {
        let block = if self.plan.outputs.hits {
            block
        } else {
            block.without_hits()
        };
        let n = block.colours.len();
        let bytes = timed(&mut self.metrics.encode_us, || encode_pixels(&block));
        self.write(&self.key(stage, task, 0), bytes, n)
    }

    fn read_span_hits(&mut self, span: u32) -> Result<Vec<super::SurfaceHit>, PipelineError> {
        let key = self.key(Stage::CastReduce, span, 0);
        self.read(&key, |k, b| decode_surface_hits(k, b, RecordKind::Hit))
    }

    /// Reads and decodes a shuffle block; recomputes it from its producer once when it is
    /// missing or corrupt.
    fn read<T>(
        &mut self,
        key: &str,
        decode: impl Fn(&str, &[u8]) -> Result<T, PipelineError>,
    ) -> Result<T, PipelineError> {
        let store = self.store;
        let fetched = timed(&mut self.metrics.storage_us, || store.get(key));
        self.decode_or_recompute(key, fetched, decode)
    }

    /// [`Task::read`] of every key of `keys`, decoded in order, all fetched first with
    /// [`BlobStore::get_many`] (on S3 several at once, so their requests' latencies overlap
    /// instead of adding up; storage time is the wall time of the fetches). A block lost or
    /// corrupt is recomputed from its producer as `read` does.
    fn read_all<T>(
        &mut self,
        keys: &[String],
        decode: impl Fn(&str, &[u8]) -> Result<T, PipelineError>,
    ) -> Result<Vec<T>, PipelineError> {
        let store = self.store;
        let fetched = timed(&mut self.metrics.storage_us, || store.get_many(keys));
        keys.iter()
            .zip(fetched)
            .map(|(key, bytes)| self.decode_or_recompute(key, bytes, &decode))
            .collect()
    }

    /// Decodes the bytes fetched for `key`; if they are missing or corrupt, reruns the task
    /// that produced them (lineage) and reads them again.
    fn decode_or_recompute<T>(
        &mut self,
        key: &str,
        fetched: Result<Vec<u8>, StoreError>,
        decode: impl Fn(&str, &[u8]) -> Result<T, PipelineError>,
    ) -> Result<T, PipelineError> {
        let store = self.store;
        let first = fetched.map_err(PipelineError::from).and_then(|bytes| {
            self.metrics.bytes_read += bytes.len() as u64;
            timed(&mut self.metrics.decode_us, || decode(key, &bytes))
        });
        let lost = match &first {
            Err(PipelineError::Store(e)) => e.is_not_found(),
            Err(PipelineError::Corrupt(_)) => true,
            _ => false,
        };
        // The chain of producers is at most the stage chain long.
        let Some((stage, task)) = producer_of(key).filter(|_| lost && self.depth < 8) else {
            return first;
        };
        self.depth += 1;
        let result = self.run(stage, task);
        self.depth -= 1;
        result?;
        self.metrics.recomputed += 1;
        let bytes = timed(&mut self.metrics.storage_us, || store.get(key))?;
        self.metrics.bytes_read += bytes.len() as u64;
        timed(&mut self.metrics.decode_us, || decode(key, &bytes))
    }

    /// CastReduce of a span with one CastMap input (`cast_task`): those candidates are already
    /// the nearest hit per sample, sorted, so decoding, reducing and encoding them would give
    /// the same raw bytes. The block is relabelled instead ([`relabel_block`]): the stored Hit
    /// block is byte for byte what the general path writes, at the cost of one CRC pass and a
    /// copy (timed as decoding).
    fn pass_through_hits(&mut self, cast_task: u32, span: u32) -> Result<(), PipelineError> {
        let key = self.key(Stage::CastMap, cast_task, span);
        let block = self.read(&key, |k, b| {
            relabel_block(k, b, RecordKind::CastCandidate, RecordKind::Hit)
                .map_err(|e| PipelineError::Corrupt(e.to_string()))
        })?;
        let records = record_count(&block);
        self.write(&self.key(Stage::CastReduce, span, 0), block, records)
    }

    fn write_hits(
        &mut self,
        stage: Stage,
        task: u32,
        partition: u32,
        kind: RecordKind,
        hits: &[super::SurfaceHit],
    ) -> Result<(), PipelineError> {
        let bytes = timed(&mut self.metrics.encode_us, || {
            encode_surface_hits(kind, hits)
        });
        self.write(&self.key(stage, task, partition), bytes, hits.len())
    }

    fn write(&mut self, key: &str, block: Vec<u8>, records: usize) -> Result<(), PipelineError> {
        let raw_len = raw_length(&block);
        self.metrics.bytes_written_raw += raw_len;
        self.metrics.records += records as u64;
        self.put_output(key, block)
    }

    /// Writes blocks `(key, block, records)` with [`Task::put_objects`].
    fn write_all(&mut self, blocks: Vec<(String, Vec<u8>, usize)>) -> Result<(), PipelineError> {
        let objects = blocks
            .into_iter()
            .map(|(key, block, records)| {
                self.metrics.bytes_written_raw += raw_length(&block);
                self.metrics.records += records as u64;
                (key, block)
            })
            .collect::<Vec<_>>();
        self.put_objects(&objects)
    }

    /// Writes final outputs (not blocks: their raw size is their size) with
    /// [`Task::put_objects`].
    fn write_plain_all(&mut self, outputs: &[(String, Vec<u8>)]) -> Result<(), PipelineError> {
        for (_, bytes) in outputs {
            self.metrics.bytes_written_raw += bytes.len() as u64;
        }
        self.put_objects(outputs)
    }

    /// Stores every `(key, bytes)` with [`BlobStore::put_many`], counting the bytes written and
    /// the wall time as storage time: the first error in `objects` order, if any (others may be
    /// stored; a retry rewrites the same bytes).
    fn put_objects(&mut self, objects: &[(String, Vec<u8>)]) -> Result<(), PipelineError> {
        for (_, bytes) in objects {
            self.metrics.bytes_written += bytes.len() as u64;
        }
        let store = self.store;
        timed(&mut self.metrics.storage_us, || store.put_many(objects))
            .into_iter()
            .collect::<Result<(), StoreError>>()?;
        Ok(())
    }

    fn put_output(&mut self, key: &str, bytes: Vec<u8>) -> Result<(), PipelineError> {
        self.metrics.bytes_written += bytes.len() as u64;
        let store = self.store;
        timed(&mut self.metrics.storage_us, || store.put(key, &bytes))?;
        Ok(())
    }
}

/// The record count recorded at bytes 12..20 of a block header already checked.
fn record_count(block: &[u8]) -> usize {
    block
        .get(12..20)
        .and_then(|b| b.try_into().ok())
        .map_or(0, u64::from_le_bytes) as usize
}

/// The raw (uncompressed) length recorded at bytes 20..28 of a block header we just encoded.
fn raw_length(block: &[u8]) -> u64 {
    block
        .get(20..28)
        .and_then(|b| b.try_into().ok())
        .map_or(0, u64::from_le_bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::{PlanRequest, SplitMode, StoredOutputs, plan_into_store};
    use crate::store::MemoryStore;

    #[test]
    fn split_cache_hits_are_counted_and_change_no_output() {
        let dir = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../scenes/cornell/cornell.json"
        );
        let scene = crate::scene::load_scene(std::path::Path::new(dir)).unwrap();
        let store = MemoryStore::new();
        let job = JobId::new("cache").unwrap();
        let request = PlanRequest {
            width: 16,
            height: 12,
            spp: 1,
            splits: Some(2),
            spans: Some(1),
            mode: SplitMode::Spatial,
            execution: None,
            memory_mb: crate::pipeline::DEFAULT_MEMORY_MB,
            adaptive: None,
            outputs: StoredOutputs::ALL,
            frame: Default::default(),
        };
        let plan = plan_into_store(&store, &job, &scene, &request)
            .unwrap()
            .plan;
        let cache = SplitCache::new(1 << 24);
        let planned = store.list("").unwrap();
        // Every object the task stored (any key the plan did not), key and bytes, and then
        // none: each run writes its own.
        let take_outputs = || -> Vec<(String, Vec<u8>)> {
            let keys: Vec<String> = store
                .list("")
                .unwrap()
                .into_iter()
                .filter(|k| !planned.contains(k))
                .collect();
            let outputs = keys
                .iter()
                .map(|k| (k.clone(), store.get(k).unwrap()))
                .collect();
            keys.iter().for_each(|k| store.delete(k).unwrap());
            outputs
        };
        let cold = run_task_cached(&store, &job, &plan, Stage::CastMap, 0, &cache).unwrap();
        let cold_outputs = take_outputs();
        assert!(
            cold_outputs
                .iter()
                .any(|(k, _)| k.starts_with("jobs/cache/cast-map/")),
            "a cast-map task stores its outputs: {:?}",
            cold_outputs.iter().map(|(k, _)| k).collect::<Vec<_>>()
        );
        assert_eq!(cold.split_cache_hits, 0);
        assert!(cold.split_bytes_read > 0);
        let warm = run_task_cached(&store, &job, &plan, Stage::CastMap, 0, &cache).unwrap();
        assert_eq!(warm.split_cache_hits, 1);
        assert_eq!(warm.split_bytes_read, 0);
        assert_eq!(
            take_outputs(),
            cold_outputs,
            "a cache hit stores the same bytes"
        );
        let uncached = run_task(&store, &job, &plan, Stage::CastMap, 0).unwrap();
        assert_eq!(uncached.split_cache_hits, 0);
        assert_eq!(take_outputs(), cold_outputs, "so does no cache");
        let mut total = cold;
        total += warm;
        assert_eq!(total.split_cache_hits, 1);
    }

    #[test]
    fn a_lost_or_corrupt_split_is_rebuilt_only_with_a_rebuilder_and_checked() {
        let dir = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../scenes/cornell/cornell.json"
        );
        let scene = crate::scene::load_scene(std::path::Path::new(dir)).unwrap();
        let store = MemoryStore::new();
        let job = JobId::new("rebuild").unwrap();
        let request = PlanRequest {
            width: 16,
            height: 12,
            spp: 1,
            splits: Some(2),
            spans: Some(1),
            mode: SplitMode::Naive,
            execution: None,
            memory_mb: crate::pipeline::DEFAULT_MEMORY_MB,
            adaptive: None,
            outputs: StoredOutputs::ALL,
            frame: Default::default(),
        };
        let plan = plan_into_store(&store, &job, &scene, &request)
            .unwrap()
            .plan;
        let key = split_key(&job, SplitId(1));
        let stored = store.get(&key).unwrap();
        let task = plan.cast_tasks.iter().find(|t| t.split == 1).unwrap().task;
        let reference = run_task(&store, &job, &plan, Stage::CastMap, task).unwrap();
        let output = partition_key(&job, Stage::CastMap, TaskId(task), PartitionId(0));
        let expected = store.get(&output).unwrap();
        let cache = SplitCache::new(0);
        let rebuild = |split: u32| {
            crate::pipeline::rebuild_split(&scene.mesh, 2, SplitMode::Naive, plan.bvh_build, split)
                .ok_or_else(|| PipelineError::BadInput("no split".into()))
        };

        // Missing: an error without a rebuilder, rebuilt with one.
        store.delete(&key).unwrap();
        let err = run_task(&store, &job, &plan, Stage::CastMap, task).unwrap_err();
        assert!(
            matches!(err, PipelineError::Store(ref e) if e.is_not_found()),
            "{err}"
        );
        let m = run_task_with(
            &store,
            &job,
            &plan,
            Stage::CastMap,
            task,
            &cache,
            Some(&rebuild),
        )
        .unwrap();
        assert_eq!((m.recomputed, m.records), (1, reference.records));
        assert_eq!(store.get(&key).unwrap(), stored);
        assert_eq!(store.get(&output).unwrap(), expected);

        // Corrupt: rebuilt the same way.
        let mut bad = stored.clone();
        let at = bad.len() / 2;
        bad[at] ^= 0x5a;
        store.put(&key, &bad).unwrap();
        let m = run_task_with(
            &store,
            &job,
            &plan,
            Stage::CastMap,
            task,
            &cache,
            Some(&rebuild),
        )
        .unwrap();
        assert_eq!(m.recomputed, 1);
        assert_eq!(store.get(&key).unwrap(), stored);

        // A rebuild that disagrees with the plan is refused, naming the object.
        store.delete(&key).unwrap();
        let wrong = |_: u32| Ok(vec![0u8; 10]);
        let err = run_task_with(
            &store,
            &job,
            &plan,
            Stage::CastMap,
            task,
            &cache,
            Some(&wrong),
        )
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            format!(
                "split object {key}: rebuilt from the scene it has 10 bytes, the plan says {}",
                stored.len()
            )
        );
        assert!(err.is_retryable());
    }

    #[test]
    fn a_single_input_cast_reduce_stores_the_bytes_of_the_general_path() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/teapot/teapot.json");
        let scene = crate::scene::load_scene(std::path::Path::new(dir)).unwrap();
        let (mut single, mut several) = (0, 0);
        // k = 1: every span has one input; k = 4: the teapot's spans have several or none.
        for k in [1, 4] {
            let store = MemoryStore::new();
            let job = JobId::new("single").unwrap();
            let request = PlanRequest {
                width: 32,
                height: 24,
                spp: 2,
                splits: Some(k),
                spans: Some(8),
                mode: SplitMode::Spatial,
                execution: Some(crate::pipeline::ExecutionMode::Staged),
                memory_mb: crate::pipeline::DEFAULT_MEMORY_MB,
                adaptive: None,
                outputs: StoredOutputs::ALL,
                frame: Default::default(),
            };
            let plan = plan_into_store(&store, &job, &scene, &request)
                .unwrap()
                .plan;
            for t in &plan.cast_tasks {
                run_task(&store, &job, &plan, Stage::CastMap, t.task).unwrap();
            }
            for span in 0..plan.spans.len() as u32 {
                let keys: Vec<_> = plan
                    .cast_tasks_of(span)
                    .map(|t| partition_key(&job, Stage::CastMap, TaskId(t.task), PartitionId(span)))
                    .collect();
                let candidates = keys
                    .iter()
                    .map(|k| {
                        let bytes = store.get(k).unwrap();
                        decode_surface_hits(k, &bytes, RecordKind::CastCandidate).unwrap()
                    })
                    .collect();
                let hits = stages::cast_reduce(candidates);
                let expected = encode_surface_hits(RecordKind::Hit, &hits);
                let output = partition_key(&job, Stage::CastReduce, TaskId(span), PartitionId(0));
                let m = run_task(&store, &job, &plan, Stage::CastReduce, span).unwrap();
                assert_eq!(store.get(&output).unwrap(), expected, "k {k} span {span}");
                assert_eq!(m.records, hits.len() as u64, "k {k} span {span}");
                let [key] = &keys[..] else {
                    several += usize::from(keys.len() > 1);
                    continue;
                };
                single += usize::from(!hits.is_empty());
                // A damaged input is recomputed from its producer; the output is the same.
                let mut bad = store.get(key).unwrap();
                let at = bad.len() - 1;
                bad[at] ^= 0x10;
                store.put(key, &bad).unwrap();
                store.delete(&output).unwrap();
                let m = run_task(&store, &job, &plan, Stage::CastReduce, span).unwrap();
                assert_eq!(m.recomputed, 1, "k {k} span {span}");
                assert_eq!(store.get(&output).unwrap(), expected, "k {k} span {span}");
            }
        }
        assert!(single > 0, "no span had a single cast-map input with hits");
        assert!(several > 0, "no span had several cast-map inputs");
    }

    #[test]
    fn summed_metrics_keep_the_largest_peak_memory() {
        let task = |peak, bytes_read| TaskMetrics {
            peak_memory_bytes: peak,
            bytes_read,
            ..TaskMetrics::default()
        };
        let mut total = TaskMetrics::default();
        for m in [task(300, 1), task(700, 2), task(500, 4)] {
            total += m;
        }
        assert_eq!((total.peak_memory_bytes, total.bytes_read), (700, 7));
    }
}
