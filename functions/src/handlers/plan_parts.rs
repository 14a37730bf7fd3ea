//! The Plan function's steps for a scene split by tasks (`hort_core::pipeline::partition`):
//! `start` scans the scene and hands out one Partition task per byte range, `cut` cuts the
//! partitioned scene into splits and hands out one Build task per split, `finish` plans the
//! job from the built splits. None of them holds more than one range's vertices.

use super::HandlerError;
use super::Tmp;
use super::events::{JobRequest, PlanOutput, SceneFormat};
use super::plan::{
    download_object, load_requested_scene, read_request, scratch_dir, with_scene_files,
    write_items, write_round,
};
use hort_core::ids::JobId;
use hort_core::keys::{items_key, parts_table_key, scene_prefix};
use hort_core::pipeline::partition::{cut_scene, plan_from_parts, scan_scene, scene_range_bytes};
use hort_core::pipeline::{JobPlan, TaskMetrics, micros, resolve_counts};
use hort_core::predict::{build_timeout_seconds, partition_timeout_seconds};
use hort_core::scene::{Scene, load_scene};
use hort_core::stage::Stage;
use hort_core::store::{BlobStore, StoreError, TimedStore};
use std::path::Path;
use std::time::Instant;

/// What the `start` step found.
pub(super) enum Loaded {
    /// A scene loaded whole, to be planned at once.
    Whole(Box<(JobRequest, Scene)>),
    /// A scene split by tasks: scanned, its Partition items written; the answer to return.
    Scanned(PlanOutput),
}

/// The `start` step's scene: the binary scene decoded, or the scene files copied into a scratch
/// folder under `tmp` (named after `label`) and loaded whole, or, when the request asks for
/// it or a whole load would not fit the function's memory, scanned (see [`scene_range_bytes`]).
pub(super) fn load_or_scan(
    store: &dyn BlobStore,
    job: &JobId,
    tmp: Tmp<'_>,
    label: &str,
) -> Result<Loaded, HandlerError> {
    let request = read_request(store, job)?;
    if request.scene_format == SceneFormat::Binary {
        let scene = load_requested_scene(store, job, &request, tmp, label)?;
        return Ok(Loaded::Whole(Box::new((request, scene))));
    }
    with_scene_files(store, job, &request, tmp, label, |dir, main| {
        let bytes = folder_bytes(dir);
        let range = request
            .scene_range_bytes
            .or_else(|| scene_range_bytes(bytes, request.render.memory_mb));
        let loaded = match range {
            Some(range) => scan(store, job, &request, dir, main, range).map(Loaded::Scanned),
            None => load_scene(main)
                .map(|scene| Loaded::Whole(Box::new((request.clone(), scene))))
                .map_err(|e| HandlerError::bad_input(e.to_string())),
        };
        loaded.map_err(|e| shown_as_given(e, dir, &request))
    })
}

/// `e` with the scratch folder `dir` in its message replaced by where the user's files are:
/// the folder of the request's `scene_key`, or nothing (names relative to the scene's folder).
fn shown_as_given(e: HandlerError, dir: &Path, request: &JobRequest) -> HandlerError {
    let folder = match request
        .scene_key
        .as_deref()
        .and_then(|k| k.rsplit_once('/'))
    {
        Some((folder, _)) => format!("{folder}/"),
        None => String::new(),
    };
    HandlerError {
        cause: e.cause.replace(&format!("{}/", dir.display()), &folder),
        ..e
    }
}

/// Bytes of the files under `dir` (recursively).
fn folder_bytes(dir: &Path) -> u64 {
    std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|entry| match entry.file_type() {
            Ok(t) if t.is_dir() => folder_bytes(&entry.path()),
            _ => entry.metadata().map_or(0, |m| m.len()),
        })
        .sum()
}

/// Scans the scene in ranges of `range` bytes and writes the Partition items.
fn scan(
    store: &dyn BlobStore,
    job: &JobId,
    request: &JobRequest,
    dir: &Path,
    main: &Path,
    range: u64,
) -> Result<PlanOutput, HandlerError> {
    // Files are named as the user named them, relative to the scene's folder.
    let table = scan_scene(store, job, dir, main, range)?;
    let (shape, _) = resolve_counts(&request.render, table.triangles)?;
    let timeout = partition_timeout_seconds(range);
    let ranges = table.ranges.len() as u32;
    parts_output(
        store,
        job,
        request,
        shape.mode,
        Stage::Partition,
        ranges,
        timeout,
    )
}

/// The `cut` step, after the Partition Map: cuts the scene into splits and writes the Build
/// items.
pub(super) fn cut_step(
    store: &TimedStore<&dyn BlobStore>,
    job: &JobId,
    started: Instant,
) -> Result<(PlanOutput, TaskMetrics), HandlerError> {
    let request = read_request(store, job)?;
    let (cut, shape) = cut_scene(store, job, &request.render)?;
    let largest = cut
        .splits
        .iter()
        .map(|runs| runs.iter().map(|r| r.end - r.start).sum::<u64>())
        .max()
        .unwrap_or(0);
    let k = cut.splits.len() as u32;
    let timeout = build_timeout_seconds(largest);
    let output = parts_output(store, job, &request, shape.mode, Stage::Build, k, timeout)?;
    Ok((output, step_metrics(store, started)))
}

/// The `finish` step, after the Build Map: plans the job from the built splits (reading the
/// scene's manifest, if it has one, and no mesh) and writes the items of its Map stages.
pub(super) fn finish_step(
    store: &TimedStore<&dyn BlobStore>,
    job: &JobId,
    tmp: Tmp<'_>,
    started: Instant,
) -> Result<(PlanOutput, TaskMetrics), HandlerError> {
    let request = read_request(store, job)?;
    let plan = plan_from_stored_parts(store, job, &request, tmp)?;
    super::budget::check_budget(&request, &plan)?;
    let output = write_round(store, job, &plan, &request, None)?;
    Ok((output, step_metrics(store, started)))
}

/// Plans job `job` (`request`) from its built splits, reading the scene's manifest, if it has
/// one, into a scratch folder under `tmp`, and no mesh; stores and returns the plan.
pub(super) fn plan_from_stored_parts(
    store: &dyn BlobStore,
    job: &JobId,
    request: &JobRequest,
    tmp: Tmp<'_>,
) -> Result<JobPlan, HandlerError> {
    let main = Path::new(&request.scene);
    if !hort_core::scene::is_manifest(main) {
        return Ok(plan_from_parts(store, job, main, &request.render)?.plan);
    }
    let dir = scratch_dir(tmp.dir, "finish", job);
    let local = dir.join(main.file_name().unwrap_or_default());
    let result = std::fs::create_dir_all(&dir)
        .map_err(|e| HandlerError::retryable(format!("cannot create {}: {e}", dir.display())))
        .and_then(|()| {
            let key = format!("{}{}", scene_prefix(job), request.scene);
            download_object(store, &key, &local, tmp, 0).map(drop)
        })
        .and_then(|()| Ok(plan_from_parts(store, job, &local, &request.render)?.plan));
    let _ = std::fs::remove_dir_all(&dir);
    result
}

/// Whether job `job`'s scene was split by tasks (its parts table exists).
pub(super) fn split_by_tasks(store: &dyn BlobStore, job: &JobId) -> Result<bool, StoreError> {
    match store.get_range(&parts_table_key(job), 0..1) {
        Ok(_) => Ok(true),
        Err(e) if e.is_not_found() => Ok(false),
        Err(e) => Err(e),
    }
}

/// Writes the items of `stage` (tasks `0..tasks`, each with `timeout` unless the request sets
/// one) and the answer naming them.
fn parts_output(
    store: &dyn BlobStore,
    job: &JobId,
    request: &JobRequest,
    mode: hort_core::pipeline::ExecutionMode,
    stage: Stage,
    tasks: u32,
    timeout: u32,
) -> Result<PlanOutput, HandlerError> {
    let key = items_key(job, stage);
    write_items(store, &key, request, (0..tasks).map(|t| (None, t)), |_| {
        timeout
    })?;
    let field = stage.items_field().expect("a Map stage");
    Ok(PlanOutput {
        mode,
        items: [(field.to_owned(), key)].into_iter().collect(),
        max_concurrency: request.max_concurrency,
        shadows: false,
        refine_after: false,
        results: hort_core::keys::map_results_prefix(job),
    })
}

/// A step's time: all of it, and how much was spent waiting on storage.
fn step_metrics(store: &TimedStore<&dyn BlobStore>, started: Instant) -> TaskMetrics {
    let task_us = micros(started.elapsed());
    TaskMetrics {
        task_us,
        storage_us: store.waited_us(),
        compute_us: task_us.saturating_sub(store.waited_us()),
        ..Default::default()
    }
}
