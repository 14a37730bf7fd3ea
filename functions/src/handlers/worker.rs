//! The Worker function: run one task of one stage (the plan names its inputs and outputs).

use super::Tmp;
use super::events::WorkerEvent;
use super::plan::{load_job_scene, read_request};
use super::plan_parts::{plan_from_stored_parts, split_by_tasks};
use super::{HandlerError, check_bucket};
use hort_core::ErrorType;
use hort_core::ids::{JobId, SplitId};
use hort_core::keys::{plan_key, split_key};
use hort_core::pipeline::partition::{build_split_from_parts, partition_range};
use hort_core::pipeline::{
    ExecutionMode, JobPlan, PipelineError, SpanLoad, SpanMemory, SplitCache, TaskMetrics, micros,
    plan_into_store, rebuild_split, run_frame_task, task_bytes, timed,
};
use hort_core::stage::Stage;
use hort_core::store::BlobStore;
use std::sync::Arc;
use std::time::Instant;

/// Runs `event.stage` task `event.item.task` of `event.job`; `cache` is the worker's decoded
/// splits and plans (a warm container's memory). Returns what the task did. The outputs are the same bytes
/// on every attempt. A lost or corrupt input block is recomputed from its producer; a lost or
/// corrupt split object, or a lost or unreadable `plan.json`, is rebuilt from the job's scene,
/// copied into `tmp` (the function's `/tmp`) for the purpose (the plan step again, for
/// the plan: the same bytes, split objects included). Before the task runs, `cache` is trimmed
/// to what the job's memory leaves beside the plan's largest task as the memory model predicts
/// it, so cache and task together stay within the function's memory; the splits the task
/// itself reads stay (the model counts them in the task), so consecutive tasks of one split
/// decode it once.
pub fn handle_worker(
    store: &dyn BlobStore,
    bucket: &str,
    cache: &SplitCache,
    event: &WorkerEvent,
    tmp: Tmp<'_>,
) -> Result<TaskMetrics, HandlerError> {
    let started = Instant::now();
    check_bucket(&event.bucket, bucket)?;
    let task = event.item.task.0;
    match event.stage {
        Stage::Partition => {
            let index = partition_range(store, &event.job, task)?;
            return Ok(parts_metrics(index.records, started));
        }
        Stage::Build => {
            let (info, _) = build_split_from_parts(store, &event.job, task)?;
            return Ok(parts_metrics(info.triangles, started));
        }
        _ => {}
    }
    let key = plan_key(&event.job);
    let load = |what: &str| {
        let label = format!("{what}-{}-{}", event.stage, event.item.task.0);
        load_job_scene(store, &event.job, tmp, &label).map_err(|e| {
            // Same class and cause once the handler reports it.
            match e.error_type {
                ErrorType::Retryable => PipelineError::Corrupt(e.cause),
                ErrorType::BadInput => PipelineError::BadInput(e.cause),
            }
        })
    };
    let (mut storage_us, mut decode_us) = (0, 0);
    let (plan, replanned) = match cache.plan(&key) {
        Some(plan) => (plan, false),
        None => {
            let stored = timed(&mut storage_us, || store.get(&key))
                .map_err(PipelineError::from)
                .and_then(|bytes| timed(&mut decode_us, || JobPlan::from_json(&key, &bytes)));
            let (plan, replanned) = match stored {
                Ok(plan) => (plan, false),
                Err(PipelineError::Store(e)) if !e.is_not_found() => return Err(e.into()),
                Err(PipelineError::Store(_) | PipelineError::Corrupt(_))
                    if split_by_tasks(store, &event.job)? =>
                {
                    let request = read_request(store, &event.job)?;
                    (
                        plan_from_stored_parts(store, &event.job, &request, tmp)?,
                        true,
                    )
                }
                Err(PipelineError::Store(_) | PipelineError::Corrupt(_)) => {
                    let (request, scene) = load("plan")?;
                    let plan = plan_into_store(store, &event.job, &scene, &request.render)?.plan;
                    (plan, true)
                }
                Err(e) => return Err(e.into()),
            };
            let plan = Arc::new(plan);
            cache.insert_plan(&key, Arc::clone(&plan));
            (plan, replanned)
        }
    };
    // A warm container's cached splits share its memory with the task: keep only what leaves
    // the plan's largest task its predicted need within the job's memory.
    // The splits this task reads are part of its own predicted memory: they stay.
    // Combine reads no split (and, in a job of several frames, combines them all).
    let reads = match event.stage {
        Stage::Combine => Vec::new(),
        stage => {
            let view = plan.frame_view(event.item.frame)?;
            splits_read(&event.job, &view, stage, event.item.task.0)
        }
    };
    cache.trim_to_keeping(
        (u64::from(plan.memory_mb) << 20).saturating_sub(largest_task_bytes(&plan)),
        &|key| reads.iter().any(|k| k == key),
    );
    let rebuild = |split: u32| -> Result<Vec<u8>, PipelineError> {
        if split_by_tasks(store, &event.job)? {
            // Its producer: the build task of the split.
            return Ok(build_split_from_parts(store, &event.job, split)?.1);
        }
        let (_, scene) = load(&format!("split-{split}"))?;
        rebuild_split(
            &scene.mesh,
            plan.k() as usize,
            plan.split_mode,
            plan.bvh_build,
            split,
        )
        .ok_or_else(|| PipelineError::BadInput(format!("split {split} is not in the plan {key}")))
    };
    let mut metrics = run_frame_task(
        store,
        &event.job,
        &plan,
        event.item.frame,
        event.stage,
        event.item.task.0,
        cache,
        Some(&rebuild),
    )?;
    metrics.recomputed += u64::from(replanned);
    metrics.storage_us += storage_us;
    metrics.decode_us += decode_us;
    metrics.task_us = micros(started.elapsed());
    Ok(metrics)
}

/// What a partition or build task did: its triangles and time (its traffic is the caller's
/// storage accounting's).
fn parts_metrics(triangles: u64, started: Instant) -> TaskMetrics {
    let task_us = micros(started.elapsed());
    TaskMetrics {
        records: triangles,
        task_us,
        compute_us: task_us,
        ..Default::default()
    }
}

/// The keys of the split objects task `task` of `stage` of `job` reads: every split for Render,
/// its own for the map stages, none for the others.
fn splits_read(job: &JobId, plan: &JobPlan, stage: Stage, task: u32) -> Vec<String> {
    let splits: Vec<u32> = match stage {
        Stage::Render => (0..plan.k()).collect(),
        _ => plan.split_of(stage, task).into_iter().collect(),
    };
    splits
        .into_iter()
        .map(|s| split_key(job, SplitId(s)))
        .collect()
}

/// The plan's memory model ([`task_bytes`]) for its largest task: the most triangles a task
/// holds (the whole scene fused, the largest split staged) and the largest span.
fn largest_task_bytes(plan: &JobPlan) -> u64 {
    let triangles = match plan.mode {
        ExecutionMode::Fused => plan.triangles,
        ExecutionMode::Staged => plan.splits.iter().map(|s| s.triangles).max().unwrap_or(0),
    };
    let pixels = plan
        .spans
        .iter()
        .map(|s| s.end - s.start)
        .max()
        .unwrap_or(0);
    let load = SpanLoad {
        pixels,
        spp: plan.max_spp(),
        adaptive: plan.adaptive.is_some(),
    };
    task_bytes(SpanMemory::of(plan.mode, plan.k(), load), triangles, load)
}
