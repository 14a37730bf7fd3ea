//! The in-process driver: plans a job, then runs every stage's tasks on N worker threads over
//! any [`BlobStore`], stage after stage, and collects the per-stage metrics of the report.

use super::PipelineError;
use super::outputs::{JobOutputs, read_frame_outputs, read_outputs};
use super::plan::{JobPlan, PlanRequest};
use super::plan_step::plan_into_store_keeping;
use super::runner::{refined_spans, run_frame_task};
use super::split_cache::SplitCache;
use crate::breakdown::{StageBreakdown, uncovered};
use crate::hits::Hit;
use crate::ids::{JobId, SplitId};
use crate::image::Image;
use crate::keys::split_key;
use crate::report::StageReport;
use crate::scene::Scene;
use crate::stage::Stage;
use crate::store::BlobStore;
use crate::task_metrics::TaskMetrics;
use crate::worker_pool::run_indexed;
use std::sync::Arc;
use std::sync::Mutex;
use std::time::Instant;

/// How to run a job in process.
#[derive(Clone, Debug)]
pub struct PipelineOptions {
    /// The job's id: every object it stores is under `jobs/{job}/`.
    pub job: JobId,
    /// Worker threads running tasks concurrently (at least 1).
    pub workers: usize,
    /// Memory of decoded splits each worker may keep between tasks (0: none).
    pub split_cache_bytes: u64,
}

/// A finished job.
#[derive(Clone, Debug)]
pub struct PipelineRun {
    /// The plan the job ran.
    pub plan: JobPlan,
    /// The linear image, bit-identical to the monolithic render's; `None` unless the plan's
    /// `outputs.linear` asked for it.
    pub image: Option<Image>,
    /// The hit buffer (sample 0 of each pixel), row-major from the top-left; `None` unless the
    /// plan's `outputs.hits` asked for it.
    pub hits: Option<Vec<Hit>>,
    /// The PNG the Combine task stored: `encode_png` of the linear image, byte for byte (in
    /// a job of several frames, the image, hits and PNG are the first frame's).
    pub png: Vec<u8>,
    /// Each frame's number and outputs, in a job of several frames; empty otherwise.
    pub frames: Vec<(u32, JobOutputs)>,
    /// Per stage: `plan` then the task stages of the plan's mode, in order.
    pub stages: Vec<StageReport>,
    /// Summed task metrics per stage, same order as `stages`.
    pub metrics: Vec<TaskMetrics>,
    /// Camera rays traced: width x height x spp, or the adaptive sampler's samples.
    pub primary_rays: u64,
    /// Logical shadow rays: one per hit sample and light.
    pub shadow_rays: u64,
    /// Split bytes read by all tasks / bytes of all splits.
    pub replication: f64,
    /// Wall-clock seconds of the task stages (cast-map to combine).
    pub render_seconds: f64,
}

/// Splits and plans `scene` into `store`, runs every stage, and reads back the outputs.
pub fn run_pipeline(
    store: &dyn BlobStore,
    scene: &Scene,
    request: PlanRequest,
    options: &PipelineOptions,
) -> Result<PipelineRun, PipelineError> {
    let job = &options.job;
    let started = Instant::now();
    // In one process the split objects the plan step builds are the ones the tasks would
    // decode from storage (the encoding is lossless): keep them for the workers' caches.
    let mut built = Vec::new();
    let planned = plan_into_store_keeping(store, job, scene, &request, |split, object| {
        if options.split_cache_bytes > 0 {
            built.push((split, Arc::new(object)));
        }
    })?;
    let plan = planned.plan;
    let mut stages = vec![StageReport {
        name: Stage::Plan.to_string(),
        tasks: 1,
        attempts: 1,
        seconds: started.elapsed().as_secs_f64(),
        bytes_read: 0,
        bytes_written: planned.bytes_written,
        bytes_written_raw: planned.bytes_written,
        attempts_bytes_read: 0,
        attempts_bytes_written: planned.bytes_written,
        breakdown: StageBreakdown::from_tasks(&planned.metrics),
        peak_memory_bytes: 0,
    }];
    let mut metrics = vec![TaskMetrics::default()];
    let render_start = Instant::now();
    // One cache per worker for the whole job, like a warm container serving task after task.
    let caches: Vec<SplitCache> = (0..options.workers.max(1))
        .map(|_| SplitCache::new(options.split_cache_bytes))
        .collect();
    for (split, object) in built {
        let key = split_key(job, SplitId(split));
        for cache in &caches {
            cache.insert(&key, Arc::clone(&object));
        }
    }
    for &stage in plan.task_stages() {
        if stage == Stage::Combine && plan.has_second_round() {
            // Round 2 of a staged adaptive job: only the spans with pixels to refine, only if
            // any; each stage's tasks count in the stage's row.
            let refine_start = Instant::now();
            let (spans, m) = refined_spans(store, job, &plan, &caches[0])?;
            stages.push(stage_report(
                "refine",
                1,
                refine_start,
                Instant::now(),
                &m,
                &[],
            ));
            metrics.push(m);
            for (row, &round_stage) in plan.task_stages().iter().enumerate() {
                let tasks: Vec<(Option<u32>, u32)> = plan
                    .dispatch_order(round_stage, plan.round_two_tasks(round_stage, &spans))
                    .into_iter()
                    .map(|task| (None, task))
                    .collect();
                if tasks.is_empty() {
                    continue;
                }
                let stage_start = Instant::now();
                let (m, busy) = run_stage(store, job, &plan, round_stage, &tasks, &caches)?;
                let more = stage_report(
                    round_stage.as_str(),
                    tasks.len(),
                    stage_start,
                    Instant::now(),
                    &m,
                    &busy,
                );
                stages[row + 1].add(&more);
                metrics[row + 1] += m;
            }
        }
        let stage_start = Instant::now();
        let tasks = plan.frame_tasks(stage)?;
        let (m, busy) = run_stage(store, job, &plan, stage, &tasks, &caches)?;
        stages.push(stage_report(
            stage.as_str(),
            tasks.len(),
            stage_start,
            Instant::now(),
            &m,
            &busy,
        ));
        metrics.push(m);
    }
    let render_seconds = render_start.elapsed().as_secs_f64();
    let outputs = read_outputs(store, job, &plan)?;
    let frames = read_frame_outputs(store, job, &plan)?;
    let split_bytes = plan.scene_bytes();
    let split_read: u64 = metrics.iter().map(|m| m.split_bytes_read).sum();
    Ok(PipelineRun {
        primary_rays: match plan.adaptive {
            Some(_) => metrics.iter().map(|m| m.adaptive.samples).sum(),
            None => {
                let frames = plan.frame_numbers().len() as u64;
                u64::from(plan.width) * u64::from(plan.height) * u64::from(plan.spp) * frames
            }
        },
        shadow_rays: metrics.iter().map(|m| m.shadow_rays).sum(),
        replication: split_read as f64 / split_bytes.max(1) as f64,
        plan,
        image: outputs.image,
        hits: outputs.hits,
        png: outputs.png,
        frames,
        stages,
        metrics,
        render_seconds,
    })
}

/// The report row of a stage that ran `tasks` tasks from `start` to `end` with the summed
/// metrics `m` and the tasks' wall-clock intervals `busy`.
fn stage_report(
    name: &str,
    tasks: usize,
    start: Instant,
    end: Instant,
    m: &TaskMetrics,
    busy: &[(Instant, Instant)],
) -> StageReport {
    StageReport {
        name: name.to_owned(),
        tasks: tasks as u64,
        attempts: tasks as u64,
        seconds: (end - start).as_secs_f64(),
        bytes_read: m.bytes_read,
        bytes_written: m.bytes_written,
        bytes_written_raw: m.bytes_written_raw,
        attempts_bytes_read: m.bytes_read,
        attempts_bytes_written: m.bytes_written,
        breakdown: StageBreakdown {
            orchestration: uncovered(start, end, busy).as_secs_f64(),
            ..StageBreakdown::from_tasks(m)
        },
        peak_memory_bytes: m.peak_memory_bytes,
    }
}

/// Runs the tasks `tasks` of `stage` on one thread per cache; the first error stops the stage.
/// Returns the summed metrics, which do not depend on which worker ran which task (integer
/// sums, durations aside), and the wall-clock interval of each task.
fn run_stage(
    store: &dyn BlobStore,
    job: &JobId,
    plan: &JobPlan,
    stage: Stage,
    tasks: &[(Option<u32>, u32)],
    caches: &[SplitCache],
) -> Result<(TaskMetrics, Vec<(Instant, Instant)>), PipelineError> {
    let mut total = TaskMetrics::default();
    let busy = Mutex::new(Vec::with_capacity(tasks.len()));
    run_indexed(
        caches,
        tasks.len(),
        |cache, i| {
            let started = Instant::now();
            let (frame, task) = tasks[i];
            let result = run_frame_task(store, job, plan, frame, stage, task, cache, None);
            busy.lock()
                .unwrap_or_else(|e| e.into_inner())
                .push((started, Instant::now()));
            result
        },
        |_, metrics| total += metrics,
    )?;
    Ok((total, busy.into_inner().unwrap_or_else(|e| e.into_inner())))
}
