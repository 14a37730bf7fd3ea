//! The Plan task: read the job request and scene from storage, split the scene (one split
//! object at a time), write the plan and one items file per Map state of the plan's mode
//! (fused: `render`; staged: `cast_map` to `trace_reduce`). A scene too large to load whole is
//! scanned instead and split by tasks (`plan_parts.rs`: the `start`, `cut` and `finish` steps).

use super::Tmp;
use super::events::{JobRequest, PlanEvent, PlanOutput, PlanStep, SceneFormat, TaskItem};
use super::{HandlerError, check_bucket};
use hort_core::ids::{JobId, TaskId};
use hort_core::keys::{items_key, manifest_key, plan_key, round_two_items_key, scene_binary_key};
use hort_core::pipeline::{
    JobPlan, SplitCache, TaskMetrics, micros, plan_into_store, refined_spans,
};
use hort_core::predict::{check_combine_time, task_timeout_seconds};
use hort_core::scene::{Scene, decode_scene, load_scene};
use hort_core::store::{BlobStore, StoreError, TimedStore};
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

pub use hort_core::keys::scene_prefix;

/// Plans job `event.job`: reads `jobs/{job}/manifest.json` and the scene (see
/// [`load_job_scene`]), writes the split objects, `plan.json` and the items files, and returns
/// the items files' keys.
pub fn handle_plan(
    store: &dyn BlobStore,
    bucket: &str,
    event: &PlanEvent,
    tmp: Tmp<'_>,
) -> Result<PlanOutput, HandlerError> {
    handle_plan_measured(store, bucket, event, tmp).map(|(output, _)| output)
}

/// [`handle_plan`], and where its time went: `storage_us` waiting on the store, `decode_us`
/// loading the scene (decoding `scene.bin` or parsing the files), `encode_us` encoding split
/// objects, `compute_us` building the splits and planning, `task_us` all of it. Byte counts
/// are 0 (the caller's storage accounting has them).
pub fn handle_plan_measured(
    store: &dyn BlobStore,
    bucket: &str,
    event: &PlanEvent,
    tmp: Tmp<'_>,
) -> Result<(PlanOutput, TaskMetrics), HandlerError> {
    let started = Instant::now();
    let store = TimedStore::new(store);
    let job = &event.job;
    check_bucket(&event.bucket, bucket)?;
    match (event.round, event.step) {
        (1, PlanStep::Start) => {}
        (1, PlanStep::Cut) => return super::plan_parts::cut_step(&store, job, started),
        (1, PlanStep::Finish) => {
            return super::plan_parts::finish_step(&store, job, tmp, started);
        }
        (2, PlanStep::Start) => return plan_round_two(&store, job, started),
        (2, step) => {
            return Err(HandlerError::bad_input(format!(
                "plan event round 2 with step {step:?}: only round 1 has steps"
            )));
        }
        (other, _) => {
            return Err(HandlerError::bad_input(format!(
                "plan event round {other}: a job has rounds 1 and 2"
            )));
        }
    }
    super::stage_in::stage_in(&store, job, &read_request(&store, job)?)?;
    let label = format!("plan-{}", event.attempt);
    let (request, scene) = match super::plan_parts::load_or_scan(&store, job, tmp, &label)? {
        super::plan_parts::Loaded::Whole(loaded) => *loaded,
        super::plan_parts::Loaded::Scanned(output) => {
            let task_us = micros(started.elapsed());
            let metrics = TaskMetrics {
                task_us,
                storage_us: store.waited_us(),
                decode_us: task_us.saturating_sub(store.waited_us()),
                ..Default::default()
            };
            return Ok((output, metrics));
        }
    };
    let decode_us = micros(started.elapsed()).saturating_sub(store.waited_us());
    if request.budget.is_some() {
        // The cheap plan the API would have checked an uploaded scene with: no split is built
        // before the budget holds.
        let (shape, s) = hort_core::pipeline::resolve_counts_with(
            &request.render,
            scene.mesh.triangle_count() as u64,
            &scene.mesh.textures,
        )?;
        let preview = hort_core::predict::preview_plan(&scene, &request.render, &shape, s)
            .map_err(|e| HandlerError::bad_input(e.to_string()))?;
        super::budget::check_budget(&request, &preview)?;
    }
    let render = &request.render;
    check_combine_time(render.width, render.height, render.frame.count)
        .map_err(HandlerError::bad_input)?;
    let planned = plan_into_store(&store, job, &scene, render)?;
    let plan = planned.plan;
    let output = write_round(&store, job, &plan, &request, None)?;
    let metrics = TaskMetrics {
        task_us: micros(started.elapsed()),
        storage_us: store.waited_us(),
        decode_us,
        ..planned.metrics
    };
    Ok((output, metrics))
}

/// Writes the items files of a round and returns the Plan function's answer naming them:
/// round 1 (`refined` is `None`): every Map stage the job runs, all its tasks; round 2 (the
/// spans with pixels to refine): only the stages with round-2 tasks for those spans.
pub(super) fn write_round(
    store: &dyn BlobStore,
    job: &JobId,
    plan: &JobPlan,
    request: &JobRequest,
    refined: Option<&[u32]>,
) -> Result<PlanOutput, HandlerError> {
    let mut items = std::collections::BTreeMap::new();
    for &stage in plan.stages() {
        let (tasks, key) = match refined {
            None => (plan.frame_tasks(stage)?, items_key(job, stage)),
            Some(spans) => (
                plan.dispatch_order(stage, plan.round_two_tasks(stage, spans))
                    .into_iter()
                    .map(|task| (None, task))
                    .collect(),
                round_two_items_key(job, stage),
            ),
        };
        let wanted = refined.is_none() || !tasks.is_empty();
        let Some(field) = stage.items_field().filter(|_| wanted) else {
            continue;
        };
        let timeout = task_timeout_seconds(plan, stage);
        write_items(store, &key, request, tasks, |_| timeout)?;
        items.insert(field.to_owned(), key);
    }
    Ok(PlanOutput {
        mode: plan.mode,
        items,
        max_concurrency: request.max_concurrency,
        shadows: plan.has_shadows(),
        refine_after: refined.is_none() && plan.has_second_round(),
        results: hort_core::keys::map_results_prefix(job),
    })
}

/// Writes the items file `key` of a Map state: one item per (frame, task) of `tasks`, in that
/// order, with its timeout (the request's override, else `timeout` of the task).
pub(super) fn write_items(
    store: &dyn BlobStore,
    key: &str,
    request: &JobRequest,
    tasks: impl IntoIterator<Item = (Option<u32>, u32)>,
    timeout: impl Fn(u32) -> u32,
) -> Result<(), HandlerError> {
    let items: Vec<TaskItem> = tasks
        .into_iter()
        .map(|(frame, task)| TaskItem {
            task: TaskId(task),
            frame,
            timeout_seconds: Some(
                request
                    .task_timeout_seconds
                    .unwrap_or_else(|| timeout(task)),
            ),
        })
        .collect();
    let json = serde_json::to_vec(&items)
        .map_err(|e| HandlerError::bad_input(format!("cannot encode items: {e}")))?;
    store.put(key, &json)?;
    Ok(())
}

/// Round 2 of a staged adaptive job (the `Refine` state): reads `plan.json` and the refine
/// lists round 1's TraceReduce tasks wrote (recomputing a lost one from its producer), and
/// writes the round-2 items of every stage for the spans with pixels to refine only. The
/// output names those items files; it names none when no pixel needs more samples, so the
/// state machine goes straight to Combine. The scene is not loaded.
fn plan_round_two(
    store: &TimedStore<&dyn BlobStore>,
    job: &JobId,
    started: Instant,
) -> Result<(PlanOutput, TaskMetrics), HandlerError> {
    let request = read_request(store, job)?;
    let key = plan_key(job);
    let plan = JobPlan::from_json(&key, &store.get(&key)?)?;
    if !plan.has_second_round() {
        return Err(HandlerError::bad_input(format!(
            "plan {key}: the job has no second round (it is not a staged adaptive job)"
        )));
    }
    let (spans, metrics) = refined_spans(store, job, &plan, &SplitCache::new(0))?;
    let output = write_round(store, job, &plan, &request, Some(&spans))?;
    let metrics = TaskMetrics {
        task_us: micros(started.elapsed()),
        storage_us: store.waited_us(),
        ..metrics
    };
    Ok((output, metrics))
}

/// Reads the job request and loads the job's scene as its `scene_format` says: the binary
/// scene `jobs/{job}/scene/scene.bin`, decoded (never parsed; a missing or invalid one is
/// `Hort.BadInput`, naming the key), or the files under `jobs/{job}/scene/`, parsed from a
/// scratch copy under `tmp` (in a folder named after `label`, unique per call, removed
/// afterwards).
pub(super) fn load_job_scene(
    store: &dyn BlobStore,
    job: &JobId,
    tmp: Tmp<'_>,
    label: &str,
) -> Result<(JobRequest, Scene), HandlerError> {
    let request = read_request(store, job)?;
    let scene = load_requested_scene(store, job, &request, tmp, label)?;
    Ok((request, scene))
}

/// [`load_job_scene`] for a job whose `request` was read already.
pub(super) fn load_requested_scene(
    store: &dyn BlobStore,
    job: &JobId,
    request: &JobRequest,
    tmp: Tmp<'_>,
    label: &str,
) -> Result<Scene, HandlerError> {
    if request.scene_format == SceneFormat::Binary {
        let key = scene_binary_key(job);
        let bytes = store.get(&key).map_err(|e| {
            if e.is_not_found() {
                HandlerError::bad_input(format!(
                    "scene {key} does not exist (the job request's scene_format is binary)"
                ))
            } else {
                e.into()
            }
        })?;
        return decode_scene(&key, &bytes).map_err(|e| HandlerError::bad_input(e.to_string()));
    }
    with_scene_files(store, job, request, tmp, label, |_, main| {
        load_scene(main).map_err(|e| HandlerError::bad_input(e.to_string()))
    })
}

/// Copies the job's scene files into a scratch folder under `tmp` (named after `label`,
/// unique per call) and runs `f` with the folder and the main file's path there; the folder is
/// removed afterwards, whatever `f` returns.
pub(super) fn with_scene_files<T>(
    store: &dyn BlobStore,
    job: &JobId,
    request: &JobRequest,
    tmp: Tmp<'_>,
    label: &str,
    f: impl FnOnce(&Path, &Path) -> Result<T, HandlerError>,
) -> Result<T, HandlerError> {
    let scene_dir = scratch_dir(tmp.dir, label, job);
    let result =
        download_scene(store, job, request, tmp, &scene_dir).and_then(|main| f(&scene_dir, &main));
    let _ = std::fs::remove_dir_all(&scene_dir);
    result
}

/// A folder under `work_dir` for one invocation's files, named after `label` and `job`.
pub(super) fn scratch_dir(work_dir: &Path, label: &str, job: &JobId) -> PathBuf {
    // Unique per invocation: a duplicated delivery of the same attempt must not share it.
    static INVOCATION: AtomicU64 = AtomicU64::new(0);
    work_dir.join(format!(
        "hort-{label}-{job}-{}-{}",
        std::process::id(),
        INVOCATION.fetch_add(1, Ordering::Relaxed)
    ))
}

/// Refuses job `job` when its request plans tasks for more memory than the deployed Worker
/// function has (`worker_mb`), naming both. A request that cannot be read is left to the plan
/// itself to report.
pub(super) fn check_worker_memory(
    store: &dyn BlobStore,
    job: &JobId,
    worker_mb: u32,
) -> Result<(), HandlerError> {
    let Ok(request) = read_request(store, job) else {
        return Ok(());
    };
    let asked = request.render.memory_mb;
    if asked <= worker_mb {
        return Ok(());
    }
    Err(HandlerError::bad_input(format!(
        "job request {} plans tasks for {asked} MB (render.memory_mb), but the Worker function \
         has {worker_mb} MB: plan for {worker_mb} MB or less, or deploy the Worker with more \
         memory (WorkerMemoryMB)",
        manifest_key(job)
    )))
}

/// Refuses a Worker task of a job whose plan is for more memory than this Worker function has
/// (`own_mb`, its `AWS_LAMBDA_FUNCTION_MEMORY_SIZE`), naming both, before any work. The plan is
/// read through the warm container's cache, where the task finds it next (no second GET); a
/// plan that cannot be read is left to the task (which rebuilds a lost one), and the tasks that
/// cut the scene before there is a plan (Partition, Build) are sized by byte ranges, not by it.
pub(super) fn check_plan_memory(
    store: &dyn BlobStore,
    cache: &SplitCache,
    event: &super::events::WorkerEvent,
    own_mb: u32,
) -> Result<(), HandlerError> {
    use hort_core::stage::Stage;
    if matches!(event.stage, Stage::Partition | Stage::Build) {
        return Ok(());
    }
    let key = plan_key(&event.job);
    let plan = match cache.plan(&key) {
        Some(plan) => plan,
        None => {
            let Ok(plan) = store
                .get(&key)
                .map_err(hort_core::pipeline::PipelineError::from)
                .and_then(|bytes| JobPlan::from_json(&key, &bytes))
            else {
                return Ok(());
            };
            let plan = std::sync::Arc::new(plan);
            cache.insert_plan(&key, std::sync::Arc::clone(&plan));
            plan
        }
    };
    if plan.memory_mb <= own_mb {
        return Ok(());
    }
    Err(HandlerError::bad_input(format!(
        "plan {key} is for functions of {} MB, but this Worker function has {own_mb} MB \
         (AWS_LAMBDA_FUNCTION_MEMORY_SIZE): its tasks would run out of memory; plan for \
         {own_mb} MB or less, or deploy the Worker with more memory (WorkerMemoryMB)",
        plan.memory_mb
    )))
}

pub(super) fn read_request(store: &dyn BlobStore, job: &JobId) -> Result<JobRequest, HandlerError> {
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
    tmp: Tmp<'_>,
    dir: &Path,
) -> Result<PathBuf, HandlerError> {
    let mut copied = 0u64;
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
        copied += download_object(store, &key, &path, tmp, copied)?;
    }
    let main = safe_relative(&request.scene).ok_or_else(|| {
        HandlerError::bad_input(format!(
            "job request names an unsafe scene path \"{}\"",
            request.scene
        ))
    })?;
    Ok(dir.join(main))
}

/// Bytes a function holds at once while copying an object to a file.
const DOWNLOAD_CHUNK_BYTES: u64 = 16 << 20;

/// Copies object `key` into the file `path` in ranged reads of [`DOWNLOAD_CHUNK_BYTES`], so
/// that a scene file larger than the function's memory can be copied, and returns its size;
/// `copied` bytes of the same copy are in `tmp` already, and a chunk that would not fit it is
/// refused before it is written ([`Tmp::check`]).
pub(super) fn download_object(
    store: &dyn BlobStore,
    key: &str,
    path: &Path,
    tmp: Tmp<'_>,
    copied: u64,
) -> Result<u64, HandlerError> {
    use std::io::Write;
    let io = |e: std::io::Error| {
        HandlerError::retryable(format!("cannot write {}: {e}", path.display()))
    };
    let mut file = std::fs::File::create(path).map_err(io)?;
    let mut offset = 0u64;
    loop {
        let chunk = match store.get_range(key, offset..offset + DOWNLOAD_CHUNK_BYTES) {
            Ok(chunk) => chunk,
            // Past the end (or an empty object): the copy is complete.
            Err(StoreError::InvalidRange { .. }) => break,
            Err(e) => return Err(e.into()),
        };
        tmp.check(
            copied + offset,
            chunk.len() as u64,
            &format!("scene file {key}"),
        )?;
        file.write_all(&chunk).map_err(io)?;
        offset += chunk.len() as u64;
        if (chunk.len() as u64) < DOWNLOAD_CHUNK_BYTES {
            break;
        }
    }
    file.flush().map_err(io)?;
    Ok(offset)
}

/// `rel` as a relative path without `..`, root or prefix components.
fn safe_relative(rel: &str) -> Option<PathBuf> {
    let path = PathBuf::from(rel);
    let ok = !rel.is_empty() && path.components().all(|c| matches!(c, Component::Normal(_)));
    ok.then_some(path)
}
