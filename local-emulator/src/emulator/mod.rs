//! The local emulator: the whole serverless pipeline on one machine. The same handlers as the
//! cloud functions, the same state machine definition (`infra/statemachine.asl.json`,
//! interpreted by `asl_interpreter`), the same S3 protocol (an embedded server or any
//! S3-compatible endpoint), plus seeded fault injection.

mod accounting;
mod faults;
mod invoker;
mod lambda_invoker;
mod memory;
mod storage;
mod upload;
#[cfg(test)]
mod upload_tests;

pub use accounting::{Accounting, FanOut, StageUsage};
pub use faults::{FaultCounts, FaultSettings, FaultyInvoker};
pub use invoker::{FrameFigures, InProcessInvoker, Ledger};
pub use lambda_invoker::{LambdaInvoker, LambdaTarget};
pub use memory::{MemoryBudget, OUT_OF_MEMORY};
pub use storage::{
    EMBEDDED_BUCKET, S3_FAULTS_VAR, Storage, StorageTarget, exit_now, remove_stale_temp_folders,
    remove_temp_folders,
};
pub use upload::{
    Deleted, JobSummary, SkipFinishedTasks, Submitted, binary_scene, delete_intermediates,
    delete_job, list_jobs, scene_files, submit_job, submit_or_resume,
};

use crate::deployment::Deployment;
use crate::state_machine::{StoreItems, hort_orchestrator};
use anyhow::{Context, Result, anyhow};
use asl_interpreter::{
    ExecutionFailure, FunctionLimits, Observer, Orchestrator, OrchestratorOptions, TaskInvoker,
};
use hort_core::breakdown::{StageBreakdown, uncovered};
use hort_core::cost::{Arch, CostBreakdown, CostInputs, estimate, standard_transitions_for};
use hort_core::hits::Hit;
use hort_core::ids::{JobId, TaskId};
use hort_core::image::Image;
use hort_core::keys::{parts_table_key, plan_key};
use hort_core::pipeline::partition::{PartsTable, scene_range_bytes};
use hort_core::pipeline::{JobOutputs, JobPlan, PlanRequest, read_frame_outputs, read_outputs};
use hort_core::report::StageReport;
use hort_core::scene::{Scene, load_scene};
use hort_core::stage::Stage;
use hort_core::store::{BlobStore, PatientStore, StoreError};
use hort_functions::handlers::{BudgetCheck, JobRequest, SceneFormat};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Tries of each request the emulator's client makes itself (upload, items, outputs), each
/// already retried by the SDK.
const CLIENT_ATTEMPTS: u32 = 5;
/// The client's first wait between those tries, doubled after each (times `time_scale`).
const CLIENT_FIRST_WAIT: std::time::Duration = std::time::Duration::from_millis(200);

/// How the emulator runs a job.
#[derive(Clone, Debug)]
pub struct EmulatorConfig {
    /// Which S3 service holds the job.
    pub storage: StorageTarget,
    /// Job id; a fresh one per run when `None`.
    pub job: Option<String>,
    /// Concurrent function slots (Lambda concurrency).
    pub workers: usize,
    /// Seeded faults to inject (none by default).
    pub faults: FaultSettings,
    /// Multiplies the state machine's waits and timeouts and the S3 client's backoff between
    /// attempts (1.0 = real time).
    pub time_scale: f64,
    /// Per-task timeout override, seconds (default: derived from each task's work).
    pub task_timeout_seconds: Option<u32>,
    /// Memory of decoded splits all warm workers together may keep (each worker's share is at
    /// most half of `memory_mb`, as in the Worker function).
    pub split_cache_bytes: u64,
    /// The functions' memory, MB of 2^20 bytes: the cost estimate assumes it, and every
    /// in-process Worker invocation is held to it ([`MemoryBudget`]; the job's own
    /// `memory_mb`, which shapes the plan, is the request's).
    pub memory_mb: u32,
    /// Lambda architecture the cost estimate assumes.
    pub arch: Arch,
    /// Set to stop the run (Ctrl-C).
    pub cancel: Arc<AtomicBool>,
    /// Invoke the Plan and Worker functions through the Lambda Invoke API instead of in this
    /// process (`--lambda-endpoint`); they must serve the run's bucket.
    pub lambda: Option<LambdaTarget>,
    /// The Plan and Worker functions' reserved concurrency and timeouts (by default the
    /// deployment's, [`Deployment::function_limits`]); clones share the count of running
    /// invocations, so jobs given clones of one value throttle each other as one account's do.
    pub functions: FunctionLimits,
}

impl EmulatorConfig {
    /// A fresh embedded S3 server in a temporary folder, `workers` function slots, no faults,
    /// real time, derived timeouts, 1 GiB of split cache, arm64 functions with the deployment's
    /// memory, reserved concurrency and timeouts.
    pub fn embedded(workers: usize) -> EmulatorConfig {
        EmulatorConfig {
            storage: StorageTarget::Embedded { data_dir: None },
            job: None,
            workers,
            faults: FaultSettings::default(),
            time_scale: 1.0,
            task_timeout_seconds: None,
            split_cache_bytes: 1 << 30,
            memory_mb: Deployment::bundled().worker.memory_mb,
            arch: Arch::Arm64,
            cancel: Arc::new(AtomicBool::new(false)),
            lambda: None,
            functions: Deployment::bundled().function_limits(),
        }
    }
}

/// A finished job as the emulator saw it.
pub struct EmulatorRun {
    /// The job's id.
    pub job: JobId,
    /// The S3 endpoint the job ran against.
    pub endpoint: String,
    /// The plan the Plan function stored.
    pub plan: JobPlan,
    /// The linear image the Combine function stored (bit-exact from its PFM); `None` unless
    /// the request's `outputs.linear` asked for it.
    pub image: Option<Image>,
    /// The PNG the Combine function stored.
    pub png: Vec<u8>,
    /// The hit buffer the Combine function stored; `None` unless the request's
    /// `outputs.hits` asked for it. (In a job of several frames, the image, PNG and hits are
    /// the first frame's.)
    pub hits: Option<Vec<Hit>>,
    /// Each frame's number and outputs, in a job of several frames; empty otherwise.
    pub frames: Vec<(u32, JobOutputs)>,
    /// Each frame's figures in a job of several frames: when it was ready (assembled by the
    /// task that finished it), its shadow rays and its tasks' seconds; empty otherwise.
    pub frame_figures: Vec<FrameFigures>,
    /// `plan`, then the task stages of the plan's mode, `combine` last.
    pub stages: Vec<StageReport>,
    /// What each top-level state used (time, attempts, storage traffic), in order entered.
    pub usage: Vec<StageUsage>,
    /// What the function invocations did.
    pub ledger: Ledger,
    /// Faults injected, when any were asked for.
    pub faults: Option<Arc<FaultCounts>>,
    /// The AWS cost estimate of the run.
    pub cost: CostBreakdown,
    /// Wall-clock seconds of the whole job, upload to outputs read back.
    pub seconds: f64,
    /// Tasks of a resumed job skipped because their outputs were all there.
    pub skipped_tasks: u64,
    /// The intermediate objects deleted after the job succeeded, or why that failed; `None`
    /// when they were kept (`JobOptions::keep_intermediates`, or a temporary embedded server).
    pub deleted_intermediates: Option<Result<Deleted, String>>,
    /// What the Plan function's scan of a scene split by tasks warns of (the loader's warnings,
    /// which the client, not loading such a scene, could not print); empty otherwise.
    pub scan_warnings: Vec<String>,
}

/// What happens to a job's objects.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct JobOptions {
    /// Keep every object after success; by default the intermediates are deleted from a
    /// bucket or data folder (see [`hort_core::keys::kept_after_success`]).
    pub keep_intermediates: bool,
    /// Continue a stopped job of the same id, request and scene, skipping the tasks whose
    /// outputs exist (see [`submit_or_resume`]).
    pub resume: bool,
    /// Split the scene by tasks in byte ranges of this size (`--scene-range-bytes`); by
    /// default only a scene too large for one function is (its files are then stored as they
    /// are, not parsed).
    pub scene_range_bytes: Option<u64>,
}

impl EmulatorRun {
    /// Attempts that failed and were retried or abandoned, over all stages.
    pub fn failed_attempts(&self) -> u64 {
        self.usage.iter().map(|u| u.failed_attempts).sum()
    }

    /// Input blocks recomputed from lineage, over all stages.
    pub fn recomputed(&self) -> u64 {
        self.ledger.total().recomputed
    }
}

/// A job id unique to this process and moment.
fn fresh_job_id() -> String {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    format!(
        "local-{}-{:x}",
        std::process::id(),
        nanos & 0xffff_ffff_ffff
    )
}

/// Opens storage, uploads the scene and the job request, runs the state machine, and reads the
/// outputs back, with the default [`JobOptions`]. `observer` sees the orchestrator's events
/// (progress display).
pub fn run_job(
    config: &EmulatorConfig,
    scene: &Path,
    settings: PlanRequest,
    observer: &dyn Observer,
) -> Result<EmulatorRun> {
    run_job_with(config, JobOptions::default(), scene, settings, observer)
}

/// [`run_job`] with `options`: resume a stopped job, keep the intermediates. Loads the scene
/// (its warnings are not shown), then runs [`run_job_loaded`].
pub fn run_job_with(
    config: &EmulatorConfig,
    options: JobOptions,
    scene: &Path,
    settings: PlanRequest,
    observer: &dyn Observer,
) -> Result<EmulatorRun> {
    let loaded = load_scene(scene)?;
    run_job_loaded(config, options, scene, Some(&loaded), settings, observer)
}

/// [`run_job_with`] for a scene the caller loaded already from `scene`: it is stored parsed
/// (the binary scene, see [`binary_scene`]), so no function parses it again. A scene split by
/// tasks ([`splits_by_tasks`]) is stored as its files and need not be loaded (`None`).
pub fn run_job_loaded(
    config: &EmulatorConfig,
    options: JobOptions,
    scene: &Path,
    loaded: Option<&Scene>,
    settings: PlanRequest,
    observer: &dyn Observer,
) -> Result<EmulatorRun> {
    run_job_of(
        config,
        options,
        SceneInput::File {
            path: scene,
            loaded,
        },
        settings,
        observer,
    )
}

/// [`run_job_with`] for a scene already in the bucket at `key` (and the files it names beside
/// it): nothing is uploaded or loaded here; the Plan function copies it into the job, as it does
/// for a scene the HTTP API accepted by key, and checks `budget` (if any) on its exact plan.
pub fn run_job_by_key(
    config: &EmulatorConfig,
    options: JobOptions,
    key: &str,
    budget: Option<BudgetCheck>,
    settings: PlanRequest,
    observer: &dyn Observer,
) -> Result<EmulatorRun> {
    run_job_of(
        config,
        options,
        SceneInput::Key {
            key,
            budget: budget.map(Box::new),
        },
        settings,
        observer,
    )
}

/// Where a job's scene comes from.
enum SceneInput<'a> {
    /// A file on this machine (loaded already, or not, see [`run_job_loaded`]).
    File {
        path: &'a Path,
        loaded: Option<&'a Scene>,
    },
    /// A key in the bucket, with the budget to check on the exact plan (boxed: the check
    /// carries the whole prediction model).
    Key {
        key: &'a str,
        budget: Option<Box<BudgetCheck>>,
    },
}

fn run_job_of(
    config: &EmulatorConfig,
    options: JobOptions,
    input: SceneInput<'_>,
    settings: PlanRequest,
    observer: &dyn Observer,
) -> Result<EmulatorRun> {
    let started = Instant::now();
    check_reserved_concurrency(config)?;
    let storage = Storage::open_scaled(&config.storage, config.time_scale)?;
    let job = JobId::new(config.job.clone().unwrap_or_else(fresh_job_id))?;
    let (scene, loaded) = match &input {
        SceneInput::File { path, loaded } => (*path, *loaded),
        SceneInput::Key { key, .. } => (Path::new(*key), None),
    };
    let request = job_request(config, options, input, scene, settings)?;
    let store = storage.blob_store();
    // The client's own requests (upload, items, outputs) have no state machine to retry them:
    // a few more tries than the SDK's own keep one unlucky request from failing the run.
    let client = PatientStore::new(
        Arc::clone(&store),
        CLIENT_ATTEMPTS,
        CLIENT_FIRST_WAIT.mul_f64(config.time_scale.clamp(1e-3, 1e3)),
    );
    let submitted = submit_or_resume(
        &client,
        &job,
        scene,
        loaded,
        &request,
        options.resume,
        &config.storage.flags(),
    )?;

    let finished = Arc::new(AtomicBool::new(false));
    let functions = functions_for(config, &storage, &store)?;
    let (invoker, fault_counts) = with_faults(config, &functions, &store, &finished);
    let (invoker, skipper) = skipping_finished_tasks(invoker, submitted, &store, &job);
    let orchestrator = orchestrator_for(config)?;
    let accounting = Accounting::new(Arc::clone(&storage.store));
    let fan_out = FanOut(vec![&accounting, observer]);
    let input = serde_json::json!({"job": job.as_str(), "bucket": storage.bucket});
    let outcome = orchestrator.run(input, invoker, &StoreItems(&client), &fan_out);
    finished.store(true, Ordering::Relaxed);
    let usage = accounting.finish();
    if let Err(failure) = outcome {
        return Err(run_error(config, &functions, &job, &failure));
    }

    // Read before the intermediates go.
    let scan_warnings = read_scan_warnings(&client, &job)?;
    let plan_bytes = client.get(&plan_key(&job))?;
    let plan = JobPlan::from_json(&plan_key(&job), &plan_bytes)?;
    let JobOutputs { image, hits, png } = read_outputs(&client, &job, &plan)?;
    let frames = read_frame_outputs(&client, &job, &plan)?;
    let deleted_intermediates = (config.storage.is_persistent() && !options.keep_intermediates)
        .then(|| delete_intermediates(storage.s3(), &job).map_err(|e| format!("{e:#}")));
    let ledger = functions.ledger();
    let frame_figures = ledger.frames(plan.mode.pixel_stage(), started);
    let stages = stage_reports(&plan, &usage, &ledger);
    let seconds = started.elapsed().as_secs_f64();
    let cost = estimate_cost(
        config,
        &usage,
        &ledger,
        seconds,
        accounting.top_level_transitions(),
    );
    Ok(EmulatorRun {
        job,
        endpoint: storage.endpoint.clone(),
        plan,
        image,
        png,
        hits,
        frames,
        frame_figures,
        stages,
        usage,
        ledger,
        faults: fault_counts,
        cost,
        seconds,
        skipped_tasks: skipper.map_or(0, |s| s.skipped.load(Ordering::Relaxed)),
        deleted_intermediates,
        scan_warnings,
    })
}

/// Refuses more function slots than the Worker function's reserved concurrency: Lambda would
/// throttle every task past it.
fn check_reserved_concurrency(config: &EmulatorConfig) -> Result<()> {
    let reserved = config
        .functions
        .limit(hort_core::stage::WORKER_FUNCTION)
        .reserved_concurrency;
    if let Some(reserved) = reserved.filter(|&r| config.workers > r) {
        return Err(anyhow!(
            "--workers {} is more than the Worker function's reserved concurrency ({reserved}, \
             WorkerConcurrency in infra/template.yaml): Lambda would throttle every task past \
             it; give --workers {reserved} or fewer",
            config.workers
        ));
    }
    Ok(())
}

/// The request the client submits for the scene of `input` (at `scene`, or named by its key):
/// how it goes up, the render settings and the run's concurrency and timeouts.
fn job_request(
    config: &EmulatorConfig,
    options: JobOptions,
    input: SceneInput<'_>,
    scene: &Path,
    settings: PlanRequest,
) -> Result<JobRequest> {
    Ok(JobRequest {
        scene: scene
            .file_name()
            .context("the scene path names no file")?
            .to_string_lossy()
            .into_owned(),
        render: settings,
        max_concurrency: config.workers as u32,
        task_timeout_seconds: config.task_timeout_seconds,
        // A scene split by tasks goes up as its files (the partition tasks read byte ranges
        // of them); any other goes up parsed, so no function parses it again. A scene by key
        // is copied as its files.
        scene_format: match input {
            SceneInput::File { path, .. }
                if !splits_by_tasks(path, settings.memory_mb, options.scene_range_bytes) =>
            {
                SceneFormat::Binary
            }
            _ => SceneFormat::Files,
        },
        scene_range_bytes: options.scene_range_bytes,
        scene_key: match input {
            SceneInput::Key { key, .. } => Some(key.to_owned()),
            SceneInput::File { .. } => None,
        },
        budget: match input {
            SceneInput::Key { budget, .. } => budget.map(|b| *b),
            SceneInput::File { .. } => None,
        },
    })
}

/// The Plan and Worker functions of the run: behind the Lambda Invoke API
/// (`config.lambda`, which refuses fault injection), or in this process over `store`, each
/// warm worker with its share of the split cache and held to the functions' memory.
fn functions_for(
    config: &EmulatorConfig,
    storage: &Storage,
    store: &Arc<dyn BlobStore>,
) -> Result<Functions> {
    Ok(match &config.lambda {
        Some(target) => {
            if config.faults.any() {
                return Err(anyhow!(
                    "fault injection needs the functions in process: it cannot be combined with \
                     --lambda-endpoint"
                ));
            }
            Functions::Lambda(Arc::new(LambdaInvoker::new(target.clone())?))
        }
        None => Functions::InProcess(Arc::new(
            InProcessInvoker::new(
                Arc::clone(store),
                &storage.bucket,
                storage.work_dir(),
                // The budget is for the whole emulator: each warm worker gets its share, at most
                // half its memory (as `HORT_SPLIT_CACHE_MB` is capped in the Worker function).
                (config.split_cache_bytes / config.workers.max(1) as u64)
                    .min(u64::from(config.memory_mb) << 19),
            )
            .with_memory_budget(MemoryBudget {
                mb: config.memory_mb,
            }),
        )),
    })
}

/// The invoker of `functions`, behind seeded fault injection when `config.faults` asks for any
/// (in-process functions only; its faults stop once `finished` is set), with the count of the
/// faults it injects.
fn with_faults(
    config: &EmulatorConfig,
    functions: &Functions,
    store: &Arc<dyn BlobStore>,
    finished: &Arc<AtomicBool>,
) -> (Arc<dyn TaskInvoker>, Option<Arc<FaultCounts>>) {
    match functions {
        Functions::InProcess(in_process) if config.faults.any() => {
            let mut faulty = FaultyInvoker::new(
                Arc::clone(in_process),
                Arc::clone(store),
                config.faults,
                config.time_scale,
            );
            faulty.finished = Arc::clone(finished);
            let counts = Arc::clone(&faulty.counts);
            (Arc::new(faulty), Some(counts))
        }
        Functions::InProcess(in_process) => (in_process.clone(), None),
        Functions::Lambda(lambda) => (lambda.clone(), None),
    }
}

/// `invoker` behind a [`SkipFinishedTasks`] when the job was resumed (`submitted`), which skips
/// the tasks of `job` whose outputs are all in `store`; the skipper too, for its count.
fn skipping_finished_tasks(
    invoker: Arc<dyn TaskInvoker>,
    submitted: Submitted,
    store: &Arc<dyn BlobStore>,
    job: &JobId,
) -> (Arc<dyn TaskInvoker>, Option<Arc<SkipFinishedTasks>>) {
    if submitted != Submitted::Resumed {
        return (invoker, None);
    }
    let skipper = Arc::new(SkipFinishedTasks::new(
        invoker,
        Arc::clone(store),
        job.clone(),
    ));
    (skipper.clone(), Some(skipper))
}

/// The state machine of `infra/statemachine.asl.json` with the run's slots, time scale, fault
/// seed, cancel flag and function limits.
fn orchestrator_for(config: &EmulatorConfig) -> Result<Orchestrator> {
    hort_orchestrator(OrchestratorOptions {
        slots: config.workers.max(1),
        time_scale: config.time_scale,
        seed: config.faults.seed,
        cancel: Arc::clone(&config.cancel),
        functions: config.functions.clone(),
    })
    .map_err(|e| anyhow!("the state machine definition: {e}"))
}

/// The error of job `job`, whose state machine stopped with `failure`: cancelled (once the
/// in-process attempts the cancel abandoned have ended, saying how to resume when the objects
/// are kept), or failed in the stage and task that failed it.
fn run_error(
    config: &EmulatorConfig,
    functions: &Functions,
    job: &JobId,
    failure: &ExecutionFailure,
) -> anyhow::Error {
    if config.cancel.load(Ordering::Relaxed) {
        // Attempts the cancel abandoned may still be writing: let them end, so that a
        // caller deleting the job's objects next finds nothing landing after.
        if let Functions::InProcess(functions) = functions {
            functions.wait_idle(std::time::Duration::from_secs(60));
        }
        // A temporary embedded store is removed on exit: promise nothing then.
        let kept = !matches!(config.storage, StorageTarget::Embedded { data_dir: None });
        return if kept {
            anyhow!(
                "cancelled; objects so far are kept under jobs/{job}/: continue with --job \
                 {job} --resume"
            )
        } else {
            anyhow!("cancelled")
        };
    }
    let detail = match &failure.item {
        Some(item) => format!(
            "{} task {}: {}: {}",
            stage_name(&item.map_state),
            item.index,
            item.error,
            item.cause
        ),
        None => format!(
            "{}: {}: {}",
            stage_name(&failure.state),
            failure.error,
            failure.cause
        ),
    };
    anyhow!("job {job} failed in {detail}")
}

/// What the Plan function's scan of a scene split by tasks warned of (its parts table); empty
/// for a job without one.
fn read_scan_warnings(client: &dyn BlobStore, job: &JobId) -> Result<Vec<String>> {
    match client.get(&parts_table_key(job)) {
        Ok(bytes) => Ok(serde_json::from_slice::<PartsTable>(&bytes)
            .map(|table| table.warnings)
            .with_context(|| parts_table_key(job))?),
        Err(StoreError::NotFound { .. }) => Ok(Vec::new()),
        Err(e) => Err(e.into()),
    }
}

/// Whether the Plan function will split the scene at `main` by tasks for functions of
/// `memory_mb`: asked for (`asked`, `--scene-range-bytes`), or its files too large for one
/// function to load whole (see [`scene_range_bytes`]).
pub fn splits_by_tasks(main: &Path, memory_mb: u32, asked: Option<u64>) -> bool {
    scene_range_for(main, memory_mb, asked).is_some()
}

/// The byte range size the Plan function will split the scene at `main` by tasks with, for
/// functions of `memory_mb`: `asked` (`--scene-range-bytes`), else [`scene_range_bytes`] of its
/// files' size; `None` when it loads the scene whole.
pub fn scene_range_for(main: &Path, memory_mb: u32, asked: Option<u64>) -> Option<u64> {
    if asked.is_some() {
        return asked;
    }
    // A scene whose files cannot be listed or read is loaded whole, whose loader then says
    // what is wrong, in its usual order (a bad camera before a file outside the folder).
    let base = main.parent().unwrap_or(Path::new("."));
    let files = scene_files(main).ok()?;
    let mut bytes = 0;
    for file in files {
        bytes += std::fs::metadata(base.join(file)).ok()?.len();
    }
    scene_range_bytes(bytes, memory_mb)
}

/// Where the functions run.
enum Functions {
    InProcess(Arc<InProcessInvoker>),
    Lambda(Arc<LambdaInvoker>),
}

impl Functions {
    fn ledger(&self) -> Ledger {
        match self {
            Functions::InProcess(f) => f.ledger(),
            Functions::Lambda(f) => f.ledger(),
        }
    }
}

/// The stage name of a state path (`CastMap/CastMapTask` -> `cast-map`, and the states of its
/// rerun loop and its Fail state, `CastMapLost`, `CastMapRerun/CastMapRerunTask` or
/// `CastMapFailed`, too); a state outside the stage table keeps its own name.
pub fn stage_name(state: &str) -> String {
    let top = state.split('/').next().unwrap_or(state);
    Stage::of_state(state)
        .or_else(|| Stage::of_rerun_loop_state(state))
        .or_else(|| {
            Stage::ALL
                .into_iter()
                .find(|s| top.strip_prefix(s.state_name()) == Some("Failed"))
        })
        .map_or_else(
            || match top {
                // The Plan function's second round (staged adaptive jobs).
                "Refine" => "refine".to_owned(),
                // The Plan function's steps for a scene split by tasks.
                "Cut" => "cut".to_owned(),
                "PlanFromParts" => "plan-from-parts".to_owned(),
                _ => state.to_owned(),
            },
            |s| s.to_string(),
        )
}

/// One report row per state that invoked functions, in order of first entry. A state entered
/// again (the staged Maps in round 2 of an adaptive job) adds its attempts, time and traffic
/// to its first row; the task metrics are the ledger's, which already holds every round.
fn stage_reports(plan: &JobPlan, usage: &[StageUsage], ledger: &Ledger) -> Vec<StageReport> {
    let mut rows: Vec<(&str, StageReport)> = Vec::new();
    for u in usage.iter().filter(|u| u.attempts > 0 || u.items > 0) {
        let row = stage_report(plan, u, ledger);
        match rows.iter_mut().find(|(state, _)| *state == u.state) {
            Some((_, first)) => {
                first.attempts += row.attempts;
                first.seconds += row.seconds;
                first.attempts_bytes_read += row.attempts_bytes_read;
                first.attempts_bytes_written += row.attempts_bytes_written;
                first.breakdown.orchestration += row.breakdown.orchestration;
            }
            None => rows.push((&u.state, row)),
        }
    }
    rows.into_iter().map(|(_, row)| row).collect()
}

fn stage_report(plan: &JobPlan, u: &StageUsage, ledger: &Ledger) -> StageReport {
    let stage = Stage::of_state(&u.state);
    // Round 1's tasks, plus the round-2 tasks that ran (ids past round 1's).
    let tasks = stage.map_or(1, |stage| {
        let first = plan.job_task_count(stage) as u32;
        let later = ledger
            .tasks
            .range((stage, None, TaskId(first))..=(stage, None, TaskId(u32::MAX)))
            .count();
        u64::from(first) + later as u64
    });
    let mut breakdown = match stage {
        Some(stage) => ledger.stage_breakdown(stage),
        None => StageBreakdown::default(),
    };
    if let Some((start, end)) = u.window {
        breakdown.orchestration = uncovered(start, end, &ledger.busy).as_secs_f64();
    }
    // The Plan function reports only its time breakdown: its traffic is what it needed.
    let (read, written, raw, peak) = match stage {
        Some(stage) if stage != Stage::Plan => {
            let m = ledger.stage(stage);
            let raw = m.bytes_written_raw;
            (m.bytes_read, m.bytes_written, raw, m.peak_memory_bytes)
        }
        _ => (
            u.traffic.bytes_read,
            u.traffic.bytes_written,
            u.traffic.bytes_written,
            ledger.plan_peak_memory_bytes,
        ),
    };
    StageReport {
        name: stage_name(&u.state),
        tasks,
        attempts: u.attempts,
        seconds: u.seconds,
        bytes_read: read,
        bytes_written: written,
        bytes_written_raw: raw,
        attempts_bytes_read: u.traffic.bytes_read,
        attempts_bytes_written: u.traffic.bytes_written,
        breakdown,
        peak_memory_bytes: peak,
    }
}

/// The job's cost from what it used; `top_level_transitions` is the execution's own states
/// entered and retried ([`Accounting::top_level_transitions`]).
fn estimate_cost(
    config: &EmulatorConfig,
    usage: &[StageUsage],
    ledger: &Ledger,
    seconds: f64,
    top_level_transitions: u64,
) -> CostBreakdown {
    let traffic = usage
        .iter()
        .fold(hort_core::store::StoreStats::default(), |mut a, u| {
            a.gets += u.traffic.gets;
            a.puts += u.traffic.puts;
            a.lists += u.traffic.lists;
            a.bytes_written += u.traffic.bytes_written;
            a
        });
    let children: u64 = usage.iter().map(|u| u.items).sum();
    estimate(&CostInputs {
        arch: config.arch,
        memory_mb: config.memory_mb,
        invocation_ms: ledger.invocation_ms.clone(),
        s3_put_like: traffic.puts + traffic.lists,
        s3_get_like: traffic.gets,
        s3_byte_seconds: traffic.bytes_written as f64 * seconds,
        standard_transitions: standard_transitions_for(top_level_transitions, children, 0),
        // One EXPRESS child per item; its duration is approximated by its worker's run time.
        express_ms: ledger
            .invocation_ms
            .iter()
            .copied()
            .take(children as usize)
            .collect(),
    })
}
