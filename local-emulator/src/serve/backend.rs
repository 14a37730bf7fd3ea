//! The emulator behind `hort serve`: a [`RenderBackend`] that runs every job on a background
//! thread through the emulator's `run_job_loaded` (the state machine interpreted, the function
//! handlers in process, an embedded S3 server over the data folder), keeps each job's records in
//! the bucket so a restarted server still answers for it, and cancels jobs on request.
//!
//! The bucket's layout is the deployment's (`hort_core::keys`): the API's record of each job at
//! `jobs/{job}/api.json` ([`JobRecord`], the same as the deployment's API function writes, with
//! the same job ids), and, where a deployment asks Step Functions, the record of the job's run
//! at `jobs/{job}/execution.json` ([`ExecutionRecord`]) and its report at
//! `jobs/{job}/report.json`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Duration;

use anyhow::{Context, Result};
use asl_interpreter::{Event, FunctionLimits, Observer};
use hort::deployment::Deployment;
use hort::emulator::{
    EmulatorConfig, EmulatorRun, FaultSettings, JobOptions, Storage, StorageTarget, run_job_by_key,
    run_job_loaded, stage_name,
};
use hort_core::cost::Arch;
use hort_core::ids::JobId;
use hort_core::keys::{api_record_key, kept_on_cancel, report_key};
use hort_core::pipeline::PlanRequest;
use hort_core::report::{Outputs, RayReport, Report, Seconds};
use hort_core::scene::decode_scene;
use hort_core::stage::Stage;
use hort_core::store::{BlobStore, CountingStore, PutOutcome};
use hort_functions::api::{
    ApiError, ImageAnswer, ImageFormat, JobRecord, JobScene, JobSpec, JobState, JobStatus,
    PredictionModel, RenderBackend, StageProgress, Submission, frames_of, idempotency_key_reused,
    job_for, now_unix_us, object_in, object_range_in, object_size_in, stored_image,
    with_frames_done,
};
use hort_functions::handlers::BudgetCheck;
use hort_functions::{S3Config, S3Store};

use super::execution::{ExecutionRecord, migrate_legacy_records};

/// How long `DELETE` waits for a job to stop before answering with its state so far.
const CANCEL_WAIT: Duration = Duration::from_secs(60);

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
    /// The API's record: what was accepted.
    record: JobRecord,
    /// The job id, checked.
    id: JobId,
    /// Where its run stands, as last stored.
    run: Mutex<ExecutionRecord>,
    live: Live,
    cancel: Arc<AtomicBool>,
    /// Set when the job's thread has ended (or the job was loaded already ended).
    ended: Mutex<bool>,
    ended_signal: Condvar,
}

impl Job {
    fn new(id: JobId, record: JobRecord, run: ExecutionRecord) -> Job {
        let ended = run.status.is_final();
        Job {
            record,
            id,
            run: Mutex::new(run),
            live: Live::default(),
            cancel: Arc::new(AtomicBool::new(false)),
            ended: Mutex::new(ended),
            ended_signal: Condvar::new(),
        }
    }

    fn status(&self) -> JobStatus {
        let r = &self.record;
        let run = lock(&self.run).clone();
        let running = run.status == JobState::Running;
        let end = run.finished_unix_us.unwrap_or_else(now_unix_us);
        JobStatus {
            stage: if running {
                lock(&self.live.stage).clone().or(run.stage)
            } else {
                run.stage
            },
            tasks_done: if running {
                self.live
                    .tasks_done
                    .load(Ordering::Relaxed)
                    .min(r.tasks_total)
            } else {
                run.tasks_done
            },
            retried_attempts: if running {
                self.live.retried.load(Ordering::Relaxed)
            } else {
                run.retried_attempts
            },
            elapsed_seconds: end.saturating_sub(r.created_unix_us) as f64 / 1e6,
            job: r.job.clone(),
            status: run.status,
            tasks_total: r.tasks_total,
            cost_usd: run.cost_usd,
            predicted_cost_usd: r.predicted_cost_usd,
            max_cost_usd: r.max_cost_usd,
            error: run.error,
            image_url: None,
            stages: if running {
                self.live.stages(&run.stages)
            } else {
                run.stages
            },
            scene: Some(r.scene.clone()),
            outputs: r.outputs,
            frames: frames_of(r.request.as_ref()),
            frames_done: None,
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

/// The jobs, by id (an idempotency key names its job: [`job_for`]).
#[derive(Default)]
struct Registry {
    jobs: BTreeMap<String, Arc<Job>>,
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
    /// Stores the record of `job`'s run (as [`ExecutionRecord::save`]).
    fn save(&self, job: &JobId, run: &mut ExecutionRecord) -> Result<(), ApiError> {
        run.save(self.store.as_ref(), job)
            .map_err(|e| ApiError::internal(format!("{e:#}")))
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
        migrate_legacy_records(shared.store.as_ref())?;
        let mut registry = Registry::default();
        let folders = shared
            .store
            .inner()
            .list_folders("jobs/")
            .context("cannot list the jobs")?;
        let ids = folders
            .iter()
            .filter_map(|f| f.strip_prefix("jobs/")?.strip_suffix('/'))
            .filter_map(|id| JobId::new(id).ok());
        for id in ids {
            let record = match shared.store.get(&api_record_key(&id)) {
                Ok(bytes) => JobRecord::decode(&api_record_key(&id), &bytes)
                    .map_err(|e| anyhow::anyhow!("{}", e.message))?,
                // A job `hort render` ran in this bucket, not one of the API's.
                Err(e) if e.is_not_found() => continue,
                Err(e) => return Err(e).context("cannot read a job's record"),
            };
            let mut run = ExecutionRecord::read(shared.store.as_ref(), &id)?
                .unwrap_or_else(|| ExecutionRecord::queued(record.stages.clone()));
            if !run.status.is_final() {
                run.error = Some(format!(
                    "interrupted: hort serve stopped while the job was {}; submit it again",
                    run.status.as_str()
                ));
                run.status = JobState::Failed;
                run.finished_unix_us = Some(now_unix_us());
                shared
                    .save(&id, &mut run)
                    .map_err(|e| anyhow::anyhow!("{}", e.message))?;
            }
            registry
                .jobs
                .insert(id.to_string(), Arc::new(Job::new(id, record, run)));
        }
        Ok(EmulatorBackend {
            shared,
            registry: Mutex::new(registry),
            _storage: storage,
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
        let id = job_for(spec.idempotency_key.as_deref());
        if let Some(job) = registry.jobs.get(id.as_str()) {
            let Some(key) = &spec.idempotency_key else {
                return Err(ApiError::internal(format!(
                    "job id {id} is taken; try again"
                )));
            };
            if job
                .record
                .request_fingerprint
                .as_ref()
                .is_some_and(|f| *f != spec.request_fingerprint)
            {
                return Err(idempotency_key_reused(key, id.as_str()));
            }
            return Ok(Submission {
                job: id.to_string(),
                replayed: true,
            });
        }
        let active = registry
            .jobs
            .values()
            .filter(|j| !lock(&j.run).status.is_final())
            .count();
        if active >= self.max_jobs {
            return Err(ApiError::too_many_jobs(format!(
                "{active} jobs are queued or running, the most this server runs at once \
                 (hort serve --max-jobs {}); submit again once one has ended",
                self.max_jobs
            )));
        }
        let record = JobRecord::accepted(&id, &spec);
        if record.create(self.shared.store.as_ref())? == PutOutcome::AlreadyExists {
            return Err(ApiError::internal(format!(
                "job {id} has a record this server did not load; try again"
            )));
        }
        let mut run = ExecutionRecord::queued(record.stages.clone());
        self.shared.save(&id, &mut run)?;
        let job = Arc::new(Job::new(id.clone(), record, run));
        registry.jobs.insert(id.to_string(), Arc::clone(&job));
        drop(registry);
        let shared = Arc::clone(&self.shared);
        let thread_job = Arc::clone(&job);
        let spawned = std::thread::Builder::new()
            .name(format!("hort-serve {id}"))
            .spawn(move || run_job(&shared, &thread_job, &spec));
        if let Err(e) = spawned {
            let mut run = lock(&job.run);
            run.status = JobState::Failed;
            run.error = Some(format!("cannot start the job's thread: {e}"));
            run.finished_unix_us = Some(now_unix_us());
            let _ = self.shared.save(&id, &mut run);
            drop(run);
            job.mark_ended();
        }
        Ok(Submission {
            job: id.to_string(),
            replayed: false,
        })
    }

    fn status(&self, id: &str) -> Result<JobStatus, ApiError> {
        let job = self.job(id)?;
        Ok(with_frames_done(
            job.status(),
            &job.id,
            self.shared.store.inner(),
        ))
    }

    fn list(&self, limit: usize) -> Result<Vec<JobStatus>, ApiError> {
        let jobs: Vec<Arc<Job>> = lock(&self.registry).jobs.values().cloned().collect();
        let mut statuses: Vec<(u64, JobStatus)> = jobs
            .iter()
            .map(|j| {
                // The record's lock is released before `status` takes it again.
                let created = j.record.created_unix_us;
                (created, j.status())
            })
            .collect();
        statuses.sort_by(|(a, x), (b, y)| (b, &y.job).cmp(&(a, &x.job)));
        Ok(statuses.into_iter().take(limit).map(|(_, s)| s).collect())
    }

    fn image(
        &self,
        id: &str,
        format: ImageFormat,
        frame: Option<u32>,
    ) -> Result<ImageAnswer, ApiError> {
        self.require_succeeded(id, "image")?;
        let job = JobId::new(id).map_err(|_| ApiError::not_found(format!("no render {id:?}")))?;
        stored_image(id, &job, frame, format, self.shared.store.inner())
    }

    fn report(&self, id: &str) -> Result<Vec<u8>, ApiError> {
        self.require_succeeded(id, "report")?;
        self.get(&report_key(&self.job(id)?.id))
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
fn run_job(shared: &Shared, job: &Job, spec: &JobSpec) {
    let id = job.record.job.clone();
    let folder = shared.scratch.join(&id);
    let outcome = if job.cancel.load(Ordering::SeqCst) {
        None
    } else {
        {
            let mut run = lock(&job.run);
            run.status = JobState::Running;
            run.started_unix_us = Some(now_unix_us());
            let _ = shared.save(&job.id, &mut run);
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
                // The scene as the API parsed it (with a request's animation, if any): the
                // binary scene it stored, which the job uploads as it is.
                JobScene::Uploaded {
                    main,
                    files,
                    scene_bin,
                } => write_scene(&folder, main, files).and_then(|main| {
                    let scene = decode_scene(&main.display().to_string(), scene_bin)?;
                    run_job_loaded(
                        &config,
                        JobOptions::default(),
                        &main,
                        Some(&scene),
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
    let mut r = lock(&job.run);
    r.stage = lock(&job.live.stage).clone();
    r.tasks_done = job
        .live
        .tasks_done
        .load(Ordering::Relaxed)
        .min(job.record.tasks_total);
    r.retried_attempts = job.live.retried.load(Ordering::Relaxed);
    r.stages = job.live.stages(&r.stages);
    match outcome {
        Some(Ok(run)) => match store_report(shared, job, spec.request, &run) {
            Ok(()) => {
                r.status = JobState::Succeeded;
                r.tasks_done = job.record.tasks_total;
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
            if let Err(e) = delete_intermediates(&shared.store, &job.id) {
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
    if let Err(e) = shared.save(&job.id, &mut r) {
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

/// Deletes every object of a cancelled job but those it keeps ([`kept_on_cancel`]: its request,
/// scene and records; the id stays taken).
fn delete_intermediates(store: &CountingStore<S3Store>, job: &JobId) -> Result<()> {
    let s3 = store.inner();
    let doomed: Vec<String> = s3
        .list_sizes(&format!("jobs/{job}/"))?
        .into_iter()
        .map(|o| o.key)
        .filter(|k| !kept_on_cancel(job, k))
        .collect();
    s3.delete_all(&doomed)?;
    Ok(())
}

/// The report of `hort render --report` for a job run by the server, stored beside its record.
fn store_report(
    shared: &Shared,
    job: &Job,
    request: PlanRequest,
    run: &EmulatorRun,
) -> Result<(), ApiError> {
    let r = &job.record;
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
            primary: request.samples(),
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
        bvh_build: Some(run.plan.bvh_build),
        workers: Some(shared.workers),
        job: Some(r.job.clone()),
        outputs: Outputs {
            image: Some(format!("/renders/{}/image", r.job)),
            hits: None,
            report: Some(format!("/renders/{}/report", r.job)),
        },
        adaptive: None,
        skips: Vec::new(),
        frames: Vec::new(),
        preparation: None,
    };
    shared
        .store
        .put(&report_key(&job.id), (report.to_json() + "\n").as_bytes())
        .map_err(|e| ApiError::internal(format!("cannot store the report: {e}")))
}
