//! The emulator behind `hort serve`: a [`RenderBackend`] that runs every job on a background
//! thread through the emulator's `run_job_with` (the state machine interpreted, the function
//! handlers in process, an embedded S3 server over the data folder), keeps each job's record in
//! the bucket so a restarted server still answers for it, and cancels jobs on request.
//!
//! Objects of the API (beside the jobs' own `jobs/{job}/...`):
//!
//! ```text
//! api/renders/{job}/status.json   the job's record (state, progress, times, cost, request)
//! api/renders/{job}/report.json   the report of a succeeded job (hort render --report's JSON)
//! ```

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result};
use asl_interpreter::{Event, FunctionLimits, Observer};
use hort::deployment::Deployment;
use hort::emulator::{
    EmulatorConfig, EmulatorRun, FaultSettings, JobOptions, Storage, StorageTarget, run_job_by_key,
    run_job_with, stage_name,
};
use hort_core::cost::Arch;
use hort_core::ids::{JobId, Stage};
use hort_core::keys::manifest_key;
use hort_core::pipeline::PlanRequest;
use hort_core::report::{Outputs, RayReport, Report, Seconds};
use hort_core::store::{BlobStore, CountingStore};
use hort_functions::api::{
    ApiError, ImageAnswer, ImageFormat, JobScene, JobSpec, JobState, JobStatus, PredictionModel,
    RenderBackend, StageProgress, Submission, idempotency_key_reused, object_in, object_range_in,
    object_size_in, stored_image,
};
use hort_functions::handlers::BudgetCheck;
use hort_functions::{S3Config, S3Store};
use serde::{Deserialize, Serialize};

/// Where the API keeps its own objects.
const API_PREFIX: &str = "api/renders/";
/// How long `DELETE` waits for a job to stop before answering with its state so far.
const CANCEL_WAIT: Duration = Duration::from_secs(60);

fn status_key(job: &str) -> String {
    format!("{API_PREFIX}{job}/status.json")
}

/// The state `hort serve` recorded for `job` in `store` (its `status.json`), or `None` if it
/// served no job of that id. `hort jobs list` shows it.
pub fn recorded_state(store: &dyn BlobStore, job: &str) -> Result<Option<JobState>> {
    let key = status_key(job);
    let bytes = match store.get(&key) {
        Ok(bytes) => bytes,
        Err(e) if e.is_not_found() => return Ok(None),
        Err(e) => return Err(e).with_context(|| format!("cannot read {key}")),
    };
    let record: JobRecord =
        serde_json::from_slice(&bytes).with_context(|| format!("cannot decode {key}"))?;
    Ok(Some(record.status))
}

fn report_key(job: &str) -> String {
    format!("{API_PREFIX}{job}/report.json")
}

/// Microseconds since the Unix epoch: integers, so a record read back gives the same elapsed
/// time to the bit (JSON floats need not parse back exactly).
fn now_unix_us() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64)
}

/// A job's record, as stored at `api/renders/{job}/status.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct JobRecord {
    job: String,
    status: JobState,
    stage: Option<String>,
    tasks_done: u64,
    tasks_total: u64,
    retried_attempts: u64,
    /// When the job was accepted, started, ended: microseconds since the Unix epoch.
    created_unix_us: u64,
    started_unix_us: Option<u64>,
    finished_unix_us: Option<u64>,
    cost_usd: Option<f64>,
    predicted_cost_usd: f64,
    predicted_seconds: f64,
    error: Option<String>,
    idempotency_key: Option<String>,
    scene: String,
    triangles: u64,
    request: PlanRequest,
    max_cost_usd: Option<f64>,
    /// Tasks done of each stage's tasks, in stage order (records of older servers have none).
    #[serde(default)]
    stages: Vec<StageProgress>,
    /// The request body's fingerprint (records of older servers have none: any body matches).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    request_fingerprint: Option<String>,
}

/// Live progress of a running job, from the orchestrator's events.
#[derive(Default)]
struct Live {
    stage: Mutex<Option<String>>,
    tasks_done: AtomicU64,
    retried: AtomicU64,
    /// Tasks that succeeded, by stage name.
    done_by_stage: Mutex<BTreeMap<String, u64>>,
}

impl Live {
    /// `stages` with their done counts as counted so far (each at most its total).
    fn stages(&self, stages: &[StageProgress]) -> Vec<StageProgress> {
        let done = lock(&self.done_by_stage);
        stages
            .iter()
            .map(|s| StageProgress {
                done: done.get(&s.stage).copied().unwrap_or(0).min(s.total),
                ..s.clone()
            })
            .collect()
    }
}

impl Observer for Live {
    fn event(&self, e: &Event) {
        match e {
            Event::StateEntered { state, .. } if Stage::of_state(state).is_some() => {
                *lock(&self.stage) = Some(stage_name(state));
            }
            Event::TaskSucceeded { state, .. } => {
                self.tasks_done.fetch_add(1, Ordering::Relaxed);
                *lock(&self.done_by_stage)
                    .entry(stage_name(state))
                    .or_default() += 1;
            }
            Event::TaskAttemptFailed {
                will_retry: true, ..
            } => {
                self.retried.fetch_add(1, Ordering::Relaxed);
            }
            _ => {}
        }
    }
}

/// One job of this server.
struct Job {
    record: Mutex<JobRecord>,
    live: Live,
    cancel: Arc<AtomicBool>,
    /// Set when the job's thread has ended (or the job was loaded already ended).
    ended: Mutex<bool>,
    ended_signal: Condvar,
}

impl Job {
    fn new(record: JobRecord) -> Job {
        let ended = record.status.is_final();
        Job {
            record: Mutex::new(record),
            live: Live::default(),
            cancel: Arc::new(AtomicBool::new(false)),
            ended: Mutex::new(ended),
            ended_signal: Condvar::new(),
        }
    }

    fn status(&self) -> JobStatus {
        let r = lock(&self.record).clone();
        let running = r.status == JobState::Running;
        let end = r.finished_unix_us.unwrap_or_else(now_unix_us);
        JobStatus {
            stage: if running {
                lock(&self.live.stage).clone().or(r.stage)
            } else {
                r.stage
            },
            tasks_done: if running {
                self.live
                    .tasks_done
                    .load(Ordering::Relaxed)
                    .min(r.tasks_total)
            } else {
                r.tasks_done
            },
            retried_attempts: if running {
                self.live.retried.load(Ordering::Relaxed)
            } else {
                r.retried_attempts
            },
            elapsed_seconds: end.saturating_sub(r.created_unix_us) as f64 / 1e6,
            job: r.job,
            status: r.status,
            tasks_total: r.tasks_total,
            cost_usd: r.cost_usd,
            predicted_cost_usd: r.predicted_cost_usd,
            max_cost_usd: r.max_cost_usd,
            error: r.error,
            image_url: None,
            stages: if running {
                self.live.stages(&r.stages)
            } else {
                r.stages
            },
            scene: Some(r.scene),
            outputs: r.request.outputs,
        }
    }

    fn wait_ended(&self, limit: Duration) {
        let ended = lock(&self.ended);
        let _ = self
            .ended_signal
            .wait_timeout_while(ended, limit, |ended| !*ended);
    }

    fn mark_ended(&self) {
        *lock(&self.ended) = true;
        self.ended_signal.notify_all();
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The jobs, and the job each idempotency key started.
#[derive(Default)]
struct Registry {
    jobs: BTreeMap<String, Arc<Job>>,
    by_key: HashMap<String, String>,
}

/// What job threads share with the server.
struct Shared {
    /// How jobs reach the bucket: the server's one embedded S3 server over its data folder
    /// (a job never starts a server of its own there: two servers over one folder would clean
    /// up each other's uploads in progress).
    s3: S3Config,
    workers: usize,
    /// The functions' reserved concurrency and timeouts, one count for all the jobs.
    functions: FunctionLimits,
    /// The bucket, through the server's own embedded S3 server over `data_dir`.
    store: Arc<CountingStore<S3Store>>,
    /// Scene files of jobs about to start, `{scratch}/{job}/...` (removed when they end).
    scratch: PathBuf,
    /// Set when the server stops: jobs still running end as FAILED (interrupted), their
    /// objects kept.
    stopping: AtomicBool,
}

impl Shared {
    /// Stores `record`, and replaces it with the record as read back, so what this server
    /// answers is exactly what a restarted one would (JSON numbers need not parse back to the
    /// same bits).
    fn save(&self, record: &mut JobRecord) -> Result<(), ApiError> {
        let json = serde_json::to_vec_pretty(record)
            .map_err(|e| ApiError::internal(format!("cannot encode the job record: {e}")))?;
        *record = serde_json::from_slice(&json)
            .map_err(|e| ApiError::internal(format!("cannot decode the job record: {e}")))?;
        self.store
            .put(&status_key(&record.job), &json)
            .map_err(|e| ApiError::internal(format!("cannot store the job record: {e}")))
    }

    /// What the jobs' costs are predicted with: the reference rates at this server's workers.
    fn prediction_model(&self) -> PredictionModel {
        PredictionModel::reference(self.workers as u32)
    }
}

/// The emulator as a [`RenderBackend`].
pub struct EmulatorBackend {
    shared: Arc<Shared>,
    registry: Mutex<Registry>,
    /// Keeps the embedded S3 server of `shared.store` alive.
    _storage: Storage,
    next_id: AtomicU64,
    /// Most jobs queued or running at once; a submission past it is refused (429).
    max_jobs: usize,
}

impl EmulatorBackend {
    /// Opens the bucket over `data_dir` (an embedded S3 server) and loads the records of the
    /// jobs a previous server left there; jobs that were still queued or running then are
    /// marked FAILED (interrupted).
    pub fn open(data_dir: &Path, workers: usize, max_jobs: usize) -> Result<EmulatorBackend> {
        let storage = Storage::open(&StorageTarget::Embedded {
            data_dir: Some(data_dir.to_path_buf()),
        })?;
        let scratch = storage.work_dir().join("serve-scenes");
        let shared = Arc::new(Shared {
            s3: storage.config.clone(),
            workers,
            functions: Deployment::bundled().function_limits(),
            store: Arc::clone(&storage.store),
            scratch,
            stopping: AtomicBool::new(false),
        });
        let mut registry = Registry::default();
        let keys = shared
            .store
            .list(API_PREFIX)
            .context("cannot list the job records")?;
        for key in keys.iter().filter(|k| k.ends_with("/status.json")) {
            let bytes = shared.store.get(key)?;
            let mut record: JobRecord =
                serde_json::from_slice(&bytes).with_context(|| format!("the job record {key}"))?;
            if !record.status.is_final() {
                record.error = Some(format!(
                    "interrupted: hort serve stopped while the job was {}; submit it again",
                    record.status.as_str()
                ));
                record.status = JobState::Failed;
                record.finished_unix_us = Some(now_unix_us());
                shared
                    .save(&mut record)
                    .map_err(|e| anyhow::anyhow!("{}", e.message))?;
            }
            if let Some(k) = &record.idempotency_key {
                registry.by_key.insert(k.clone(), record.job.clone());
            }
            registry
                .jobs
                .insert(record.job.clone(), Arc::new(Job::new(record)));
        }
        Ok(EmulatorBackend {
            shared,
            registry: Mutex::new(registry),
            _storage: storage,
            next_id: AtomicU64::new(0),
            max_jobs,
        })
    }

    /// Jobs known (loaded or submitted).
    pub fn job_count(&self) -> usize {
        lock(&self.registry).jobs.len()
    }

    /// Stops every running job (they end FAILED, interrupted, objects kept) and waits a little
    /// for their threads, so their records say so.
    pub fn stop(&self) {
        self.shared.stopping.store(true, Ordering::SeqCst);
        let jobs: Vec<Arc<Job>> = lock(&self.registry).jobs.values().cloned().collect();
        for job in &jobs {
            job.cancel.store(true, Ordering::SeqCst);
        }
        for job in &jobs {
            job.wait_ended(Duration::from_secs(10));
        }
    }

    fn job(&self, id: &str) -> Result<Arc<Job>, ApiError> {
        lock(&self.registry)
            .jobs
            .get(id)
            .cloned()
            .ok_or_else(|| ApiError::not_found(format!("no render {id:?}")))
    }

    /// A fresh job id: `r-{unix milliseconds}-{n}`, unused in the registry.
    fn fresh_id(&self, registry: &Registry) -> String {
        let millis = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_millis());
        loop {
            let n = self.next_id.fetch_add(1, Ordering::Relaxed);
            let id = format!("r-{millis}-{n}");
            if !registry.jobs.contains_key(&id) {
                return id;
            }
        }
    }

    /// The finished output of a job, or why there is none.
    fn require_succeeded(&self, id: &str, what: &str) -> Result<(), ApiError> {
        let status = self.job(id)?.status().status;
        match status {
            JobState::Succeeded => Ok(()),
            s if s.is_final() => Err(ApiError::not_found(format!(
                "render {id} has no {what}: the job is {}",
                s.as_str()
            ))),
            s => Err(ApiError::not_found(format!(
                "render {id} has no {what} yet: the job is {}",
                s.as_str()
            ))),
        }
    }

    fn get(&self, key: &str) -> Result<Vec<u8>, ApiError> {
        self.shared
            .store
            .get(key)
            .map_err(|e| ApiError::internal(format!("cannot read {key}: {e}")))
    }
}

impl RenderBackend for EmulatorBackend {
    fn read_object(&self, key: &str) -> Result<Option<Vec<u8>>, ApiError> {
        object_in(self.shared.store.as_ref(), key)
    }

    fn object_size(&self, key: &str) -> Result<Option<u64>, ApiError> {
        object_size_in(self.shared.store.as_ref(), key)
    }

    fn read_object_range(
        &self,
        key: &str,
        range: std::ops::Range<u64>,
    ) -> Result<Vec<u8>, ApiError> {
        object_range_in(self.shared.store.as_ref(), key, range)
    }

    fn prediction_model(&self) -> PredictionModel {
        self.shared.prediction_model()
    }

    fn submit(&self, spec: JobSpec) -> Result<Submission, ApiError> {
        let mut registry = lock(&self.registry);
        if let Some(key) = &spec.idempotency_key
            && let Some(job) = registry.by_key.get(key)
        {
            let first = registry
                .jobs
                .get(job)
                .and_then(|j| lock(&j.record).request_fingerprint.clone());
            if first.is_some_and(|f| f != spec.request_fingerprint) {
                return Err(idempotency_key_reused(key, job));
            }
            return Ok(Submission {
                job: job.clone(),
                replayed: true,
            });
        }
        let active = registry
            .jobs
            .values()
            .filter(|j| !lock(&j.record).status.is_final())
            .count();
        if active >= self.max_jobs {
            return Err(ApiError::too_many_jobs(format!(
                "{active} jobs are queued or running, the most this server runs at once \
                 (hort serve --max-jobs {}); submit again once one has ended",
                self.max_jobs
            )));
        }
        let id = self.fresh_id(&registry);
        let record = JobRecord {
            job: id.clone(),
            status: JobState::Queued,
            stage: None,
            tasks_done: 0,
            tasks_total: spec.prediction.tasks_total,
            retried_attempts: 0,
            created_unix_us: now_unix_us(),
            started_unix_us: None,
            finished_unix_us: None,
            cost_usd: None,
            predicted_cost_usd: spec.prediction.predicted_cost_usd,
            predicted_seconds: spec.prediction.predicted_seconds,
            error: None,
            idempotency_key: spec.idempotency_key.clone(),
            scene: spec.scene_name.clone(),
            triangles: spec.prediction.triangles,
            request: spec.request,
            max_cost_usd: spec.max_cost_usd,
            request_fingerprint: Some(spec.request_fingerprint.clone()),
            stages: spec
                .prediction
                .stages
                .iter()
                .map(|s| StageProgress {
                    stage: s.stage.clone(),
                    done: 0,
                    total: s.tasks,
                })
                .collect(),
        };
        let mut record = record;
        self.shared.save(&mut record)?;
        let job = Arc::new(Job::new(record));
        registry.jobs.insert(id.clone(), Arc::clone(&job));
        if let Some(key) = &spec.idempotency_key {
            registry.by_key.insert(key.clone(), id.clone());
        }
        drop(registry);
        let shared = Arc::clone(&self.shared);
        let thread_job = Arc::clone(&job);
        let spawned = std::thread::Builder::new()
            .name(format!("hort-serve {id}"))
            .spawn(move || run(&shared, &thread_job, &spec));
        if let Err(e) = spawned {
            let mut r = lock(&job.record);
            r.status = JobState::Failed;
            r.error = Some(format!("cannot start the job's thread: {e}"));
            r.finished_unix_us = Some(now_unix_us());
            let _ = self.shared.save(&mut r);
            drop(r);
            job.mark_ended();
        }
        Ok(Submission {
            job: id,
            replayed: false,
        })
    }

    fn status(&self, id: &str) -> Result<JobStatus, ApiError> {
        Ok(self.job(id)?.status())
    }

    fn list(&self, limit: usize) -> Result<Vec<JobStatus>, ApiError> {
        let jobs: Vec<Arc<Job>> = lock(&self.registry).jobs.values().cloned().collect();
        let mut statuses: Vec<(u64, JobStatus)> = jobs
            .iter()
            .map(|j| {
                // The record's lock is released before `status` takes it again.
                let created = lock(&j.record).created_unix_us;
                (created, j.status())
            })
            .collect();
        statuses.sort_by(|(a, x), (b, y)| (b, &y.job).cmp(&(a, &x.job)));
        Ok(statuses.into_iter().take(limit).map(|(_, s)| s).collect())
    }

    fn image(&self, id: &str, format: ImageFormat) -> Result<ImageAnswer, ApiError> {
        self.require_succeeded(id, "image")?;
        let job = JobId::new(id).map_err(|_| ApiError::not_found(format!("no render {id:?}")))?;
        stored_image(id, &job, format, self.shared.store.inner())
    }

    fn report(&self, id: &str) -> Result<Vec<u8>, ApiError> {
        self.require_succeeded(id, "report")?;
        self.get(&report_key(id))
    }

    fn cancel(&self, id: &str) -> Result<JobStatus, ApiError> {
        let job = self.job(id)?;
        if !job.status().status.is_final() {
            job.cancel.store(true, Ordering::SeqCst);
            job.wait_ended(CANCEL_WAIT);
        }
        Ok(job.status())
    }
}

/// A job's thread: write the scene files where the emulator reads them, run the job, record
/// how it ended.
fn run(shared: &Shared, job: &Job, spec: &JobSpec) {
    let id = lock(&job.record).job.clone();
    let folder = shared.scratch.join(&id);
    let outcome = if job.cancel.load(Ordering::SeqCst) {
        None
    } else {
        {
            let mut r = lock(&job.record);
            r.status = JobState::Running;
            r.started_unix_us = Some(now_unix_us());
            let _ = shared.save(&mut r);
        }
        Some({
            let config = EmulatorConfig {
                storage: StorageTarget::Bucket(shared.s3.clone()),
                job: Some(id.clone()),
                workers: shared.workers,
                faults: FaultSettings::default(),
                time_scale: 1.0,
                task_timeout_seconds: None,
                split_cache_bytes: 1 << 30,
                memory_mb: Deployment::bundled().worker.memory_mb,
                arch: Arch::Arm64,
                cancel: Arc::clone(&job.cancel),
                lambda: None,
                // One account: the jobs share the functions' reserved concurrency.
                functions: shared.functions.clone(),
            };
            match &spec.scene {
                JobScene::Uploaded { main, files, .. } => write_scene(&folder, main, files)
                    .and_then(|main| {
                        run_job_with(
                            &config,
                            JobOptions::default(),
                            &main,
                            spec.request,
                            &job.live,
                        )
                    }),
                JobScene::Key(key) => run_job_by_key(
                    &config,
                    JobOptions::default(),
                    key,
                    spec.max_cost_usd.map(|max_cost_usd| BudgetCheck {
                        max_cost_usd,
                        model: shared.prediction_model(),
                    }),
                    spec.request,
                    &job.live,
                ),
            }
        })
    };
    let _ = std::fs::remove_dir_all(&folder);
    let cancelled = job.cancel.load(Ordering::SeqCst);
    let mut r = lock(&job.record);
    r.stage = lock(&job.live.stage).clone();
    r.tasks_done = job
        .live
        .tasks_done
        .load(Ordering::Relaxed)
        .min(r.tasks_total);
    r.retried_attempts = job.live.retried.load(Ordering::Relaxed);
    r.stages = job.live.stages(&r.stages);
    match outcome {
        Some(Ok(run)) => match store_report(shared, &r, &run) {
            Ok(()) => {
                r.status = JobState::Succeeded;
                r.tasks_done = r.tasks_total;
                for s in &mut r.stages {
                    s.done = s.total;
                }
                r.retried_attempts = run.failed_attempts();
                r.cost_usd = Some(run.cost.total);
            }
            Err(e) => {
                r.status = JobState::Failed;
                r.error = Some(e.message);
            }
        },
        _ if cancelled && shared.stopping.load(Ordering::SeqCst) => {
            r.status = JobState::Failed;
            r.error = Some(
                "interrupted: hort serve stopped while the job was running; submit it again".into(),
            );
        }
        _ if cancelled => {
            r.status = JobState::Cancelled;
            if let Err(e) = delete_intermediates(&shared.store, &id) {
                r.error = Some(format!(
                    "cancelled, but its intermediate objects were not all deleted: {e:#}"
                ));
            }
        }
        // Not started means cancelled before it started: the arm above.
        None => {
            r.status = JobState::Failed;
            r.error = Some("the job did not start".into());
        }
        Some(Err(e)) => {
            r.status = JobState::Failed;
            r.error = Some(format!("{e:#}"));
        }
    }
    r.finished_unix_us = Some(now_unix_us());
    if let Err(e) = shared.save(&mut r) {
        eprintln!("hort serve: job {id}: {}", e.message);
    }
    drop(r);
    job.mark_ended();
}

/// Writes the scene's `files` under `folder`; the path of the main file `main`.
fn write_scene(folder: &Path, main: &str, files: &BTreeMap<String, Vec<u8>>) -> Result<PathBuf> {
    for (name, bytes) in files {
        let path = folder.join(name);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent)
                .with_context(|| format!("cannot create {}", parent.display()))?;
        }
        std::fs::write(&path, bytes).with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(folder.join(main))
}

/// Deletes every object of a cancelled job but its job request (`manifest.json`, the job's
/// identity: the id stays taken).
fn delete_intermediates(store: &CountingStore<S3Store>, id: &str) -> Result<()> {
    let job = JobId::new(id)?;
    let s3 = store.inner();
    let keep = manifest_key(&job);
    let doomed: Vec<String> = s3
        .list_sizes(&format!("jobs/{id}/"))?
        .into_iter()
        .map(|o| o.key)
        .filter(|k| *k != keep)
        .collect();
    s3.delete_all(&doomed)?;
    Ok(())
}

/// The report of `hort render --report` for a job run by the server, stored beside its record.
fn store_report(shared: &Shared, r: &JobRecord, run: &EmulatorRun) -> Result<(), ApiError> {
    let request = r.request;
    let render_seconds = run
        .stages
        .iter()
        .filter(|s| s.name != "plan")
        .map(|s| s.seconds)
        .sum();
    let report = Report {
        mode: "emulator".into(),
        scene: r.scene.clone(),
        width: request.width,
        height: request.height,
        spp: request.spp,
        triangles: r.triangles,
        threads: shared.workers,
        rays: RayReport {
            primary: u64::from(request.width) * u64::from(request.height) * u64::from(request.spp),
            shadow: run.ledger.total().shadow_rays,
        },
        seconds: Seconds {
            total: run.seconds,
            render: render_seconds,
            // The scene was parsed when the request was checked, not by the job.
            load: 0.0,
            build: run.stages.first().map_or(0.0, |s| s.seconds),
        },
        stages: run.stages.clone(),
        replication: Some(
            run.ledger.total().split_bytes_read as f64 / run.plan.scene_bytes().max(1) as f64,
        ),
        cost_usd: Some(run.cost.total),
        retried_attempts: run.failed_attempts(),
        recomputed_blocks: run.recomputed(),
        splits: Some(run.plan.k()),
        spans: Some(run.plan.spans.len() as u32),
        execution: Some(run.plan.mode.to_string()),
        execution_reason: Some(run.plan.mode_reason.clone()),
        workers: Some(shared.workers),
        job: Some(r.job.clone()),
        outputs: Outputs {
            image: Some(format!("/renders/{}/image", r.job)),
            hits: None,
            report: Some(format!("/renders/{}/report", r.job)),
        },
        adaptive: None,
        skips: Vec::new(),
    };
    shared
        .store
        .put(&report_key(&r.job), (report.to_json() + "\n").as_bytes())
        .map_err(|e| ApiError::internal(format!("cannot store the report: {e}")))
}
