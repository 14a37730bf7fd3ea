//! The Plan task: read the job request and scene from storage, split the scene (one split
//! object at a time), write the plan and one items file per Map state.

use super::HandlerError;
use super::events::{JobRequest, PlanEvent, PlanOutput, StageItems, TaskItem};
use hort_core::ids::{JobId, SplitId, Stage};
use hort_core::keys::{items_key, manifest_key, plan_key, split_key};
use hort_core::pipeline::{
    JobPlan, PlanRequest, plan_job, resolve_counts, split_scene, task_count,
};
use hort_core::scene::load_scene;
use hort_core::store::BlobStore;
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

pub use hort_core::keys::scene_prefix;

/// Shortest per-task timeout, seconds.
const MIN_TIMEOUT: u32 = 10;
/// Longest per-task timeout, seconds: three attempts must fit an EXPRESS child's 5 minutes.
const MAX_TIMEOUT: u32 = 90;
/// Rays per second a task is assumed to manage at the least, for its timeout.
const SLOWEST_RAYS_PER_SECOND: u64 = 100_000;

/// Plans job `event.job`: reads `jobs/{job}/manifest.json` and the files under
/// `jobs/{job}/scene/` (copied into `work_dir`, like a function's `/tmp`), writes the split
/// objects, `plan.json` and the items files, and returns the items files' keys.
pub fn handle_plan(
    store: &dyn BlobStore,
    bucket: &str,
    event: &PlanEvent,
    work_dir: &Path,
) -> Result<PlanOutput, HandlerError> {
    let job = JobId::new(event.job.clone()).map_err(|e| HandlerError::bad_input(e.to_string()))?;
    if event.bucket != bucket {
        return Err(HandlerError::bad_input(format!(
            "the event names bucket \"{}\", this function serves \"{bucket}\"",
            event.bucket
        )));
    }
    let request = read_request(store, &job)?;
    // Unique per invocation: a duplicated delivery of the same attempt must not share it.
    static INVOCATION: AtomicU64 = AtomicU64::new(0);
    let scene_dir = work_dir.join(format!(
        "hort-plan-{job}-{}-{}-{}",
        event.attempt,
        std::process::id(),
        INVOCATION.fetch_add(1, Ordering::Relaxed)
    ));
    let scene_path = download_scene(store, &job, &request, &scene_dir)?;
    let loaded = load_scene(&scene_path);
    let _ = std::fs::remove_dir_all(&scene_dir);
    let scene = loaded.map_err(|e| HandlerError::bad_input(e.to_string()))?;
    let plan_request = PlanRequest {
        width: request.width,
        height: request.height,
        spp: request.spp,
        splits: request.splits,
        spans: request.spans,
        mode: request.split_mode,
    };
    let (k, s) = resolve_counts(&plan_request, scene.mesh.triangle_count() as u64)?;
    let infos = split_scene(
        &scene.mesh,
        k as usize,
        plan_request.mode,
        |split, bytes| store.put(&split_key(&job, SplitId(split)), &bytes),
    )?;
    let plan = plan_job(&scene, &plan_request, infos, s)?;
    let plan_json = serde_json::to_vec_pretty(&plan)
        .map_err(|e| HandlerError::bad_input(format!("cannot encode the plan: {e}")))?;
    store.put(&plan_key(&job), &plan_json)?;
    let write_items = |stage: Stage| -> Result<String, HandlerError> {
        let items: Vec<TaskItem> = (0..task_count(&plan, stage) as u32)
            .map(|task| TaskItem {
                task,
                timeout_seconds: Some(
                    request
                        .task_timeout_seconds
                        .unwrap_or_else(|| task_timeout_seconds(&plan, stage, task)),
                ),
            })
            .collect();
        let key = items_key(&job, stage);
        let json = serde_json::to_vec(&items)
            .map_err(|e| HandlerError::bad_input(format!("cannot encode items: {e}")))?;
        store.put(&key, &json)?;
        Ok(key)
    };
    Ok(PlanOutput {
        items: StageItems {
            cast_map: write_items(Stage::CastMap)?,
            cast_reduce: write_items(Stage::CastReduce)?,
            expand: write_items(Stage::Expand)?,
            trace_map: write_items(Stage::TraceMap)?,
            trace_reduce: write_items(Stage::TraceReduce)?,
        },
        max_concurrency: request.max_concurrency,
    })
}

/// A task's timeout: 10 s plus its rays at a pessimistic 100k rays/s, at most 90 s.
pub fn task_timeout_seconds(plan: &JobPlan, stage: Stage, task: u32) -> u32 {
    let span_samples = |span: u32| {
        plan.spans
            .get(span as usize)
            .map_or(0, |s| (s.end - s.start) * u64::from(plan.spp))
    };
    let lights = plan.lights.len() as u64;
    let rays = match stage {
        Stage::CastMap => plan
            .cast_tasks
            .get(task as usize)
            .map_or(0, |t| span_samples(t.span)),
        Stage::TraceMap => plan
            .trace_tasks
            .get(task as usize)
            .map_or(0, |t| span_samples(t.span) * lights),
        Stage::CastReduce | Stage::Expand | Stage::TraceReduce => {
            span_samples(task) * (1 + lights) / 4
        }
        Stage::Combine | Stage::Split => u64::from(plan.width) * u64::from(plan.height) / 4,
    };
    let seconds = u64::from(MIN_TIMEOUT) + rays / SLOWEST_RAYS_PER_SECOND;
    seconds.min(u64::from(MAX_TIMEOUT)) as u32
}

fn read_request(store: &dyn BlobStore, job: &JobId) -> Result<JobRequest, HandlerError> {
    let key = manifest_key(job);
    let bytes = store.get(&key).map_err(|e| {
        if e.is_not_found() {
            HandlerError::bad_input(format!("job request {key} does not exist"))
        } else {
            e.into()
        }
    })?;
    serde_json::from_slice(&bytes)
        .map_err(|e| HandlerError::bad_input(format!("job request {key}: {e}")))
}

/// Copies the job's scene files into `dir`; returns the path of the main file.
fn download_scene(
    store: &dyn BlobStore,
    job: &JobId,
    request: &JobRequest,
    dir: &Path,
) -> Result<PathBuf, HandlerError> {
    let prefix = scene_prefix(job);
    let io = |what: &Path, e: std::io::Error| {
        HandlerError::retryable(format!("cannot write {}: {e}", what.display()))
    };
    for key in store.list(&prefix)? {
        let rel = safe_relative(&key[prefix.len()..]).ok_or_else(|| {
            HandlerError::bad_input(format!("scene object {key} has an unsafe path"))
        })?;
        let path = dir.join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|e| io(parent, e))?;
        }
        std::fs::write(&path, store.get(&key)?).map_err(|e| io(&path, e))?;
    }
    let main = safe_relative(&request.scene).ok_or_else(|| {
        HandlerError::bad_input(format!(
            "job request names an unsafe scene path \"{}\"",
            request.scene
        ))
    })?;
    Ok(dir.join(main))
}

/// `rel` as a relative path without `..`, root or prefix components.
fn safe_relative(rel: &str) -> Option<PathBuf> {
    let path = PathBuf::from(rel);
    let ok = !rel.is_empty() && path.components().all(|c| matches!(c, Component::Normal(_)));
    ok.then_some(path)
}
