//! [`AwsBackend`]: the HTTP API's [`RenderBackend`] in a deployment. A submitted job is stored
//! in the bucket (`jobs/{job}/scene/`, `manifest.json`, and the API's own record
//! `jobs/{job}/api.json`) and its message sent to the intake queue, where the Starter function
//! starts the execution named by the job id. Status comes from that execution and its Map Runs
//! (DescribeExecution, ListMapRuns, DescribeMapRun: a handful of requests, however many objects
//! the job has); images are read from `jobs/{job}/out/`. The list reads the job folders with a
//! delimited listing (one entry per job), one small record per job, and the executions' states
//! with ListExecutions (1,000 a page), so it answers within API Gateway's 30 s for thousands of
//! jobs; a cancel deletes the job's intermediates with `DeleteObjects` (1,000 keys a request).
//!
//! What a deployment does not report (yet): `cost_usd` (no per-task accounting in the cloud:
//! `null`), `retried_attempts` (0), and the report JSON of `hort render --report` (404 saying so).
//! `tasks_done` counts the Plan step and the Map items that succeeded; in the list, only jobs
//! still running carry it (a finished job's is `tasks_total` if it succeeded, else 0 there: its
//! own status has the count).
//!
//! Every method blocks: S3 through the store, SQS and Step Functions on the runtime `handle`.
//! Call them from a blocking thread (`tokio::task::spawn_blocking`), never from an async task.

use hort_core::cost::Arch;
use hort_core::ids::JobId;
use hort_core::keys::{api_record_key, kept_on_cancel, manifest_key, scene_binary_key};
use hort_core::stage::Stage;
use hort_core::store::{BlobStore, PutOutcome, StoreError};
use tokio::runtime::Handle;

use super::error::AwsErrorKind;
use super::sfn::{ExecutionInput, ExecutionStatus, Executions, Listed, MapRun};
use super::sqs::JobQueue;
use crate::S3Store;
use crate::api::{
    ApiError, ImageAnswer, ImageFormat, JobRecord, JobScene, JobSpec, JobState, JobStatus,
    PredictionModel, RATES, RenderBackend, Submission, frames_of, idempotency_key_expired,
    idempotency_key_reused, job_for, now_unix_us, object_in, object_range_in, object_size_in,
    stored_image, with_frames_done,
};
use crate::handlers::{BudgetCheck, JobRequest};

/// What a deployment's jobs run with, for the job requests and the predictions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeploymentLimits {
    /// The Map states' concurrency written into each job request (the Worker's reserved
    /// concurrency; 0: no limit).
    pub max_concurrency: u32,
    /// The Worker's memory in MB.
    pub worker_memory_mb: u32,
}

/// The render API's backend over S3, the intake queue and the state machine.
pub struct AwsBackend {
    store: S3Store,
    queue: JobQueue,
    executions: Executions,
    handle: Handle,
    limits: DeploymentLimits,
}

impl AwsBackend {
    /// A backend storing jobs through `store` (its bucket is the functions' bucket), sending
    /// them to `queue`, finding them among the executions of `executions`; SQS and Step
    /// Functions calls block on `handle` (a multi-threaded runtime's).
    pub fn new(
        store: S3Store,
        queue: JobQueue,
        executions: Executions,
        handle: Handle,
        limits: DeploymentLimits,
    ) -> Self {
        AwsBackend {
            store,
            queue,
            executions,
            handle,
            limits,
        }
    }

    fn job_id(id: &str) -> Result<JobId, ApiError> {
        JobId::new(id).map_err(|_| ApiError::not_found(format!("no render {id:?}")))
    }

    fn storage_error(what: &str, e: StoreError) -> ApiError {
        ApiError::internal(format!("{what}: {e}"))
    }

    fn record(&self, job: &JobId) -> Result<JobRecord, ApiError> {
        JobRecord::read(&self.store, job)
    }

    /// Stores the scene and the job request of `spec` as job `job`: the binary scene the API
    /// parsed and checked (so the Plan function decodes it and never parses the files again),
    /// or, for a scene by key, nothing but the request naming the key (the Plan function
    /// copies the scene into the job, and checks the budget again on its exact plan).
    fn store_job(&self, job: &JobId, spec: &JobSpec) -> Result<(), ApiError> {
        let mut request = JobRequest {
            scene: String::new(),
            render: spec.request,
            max_concurrency: self.limits.max_concurrency,
            task_timeout_seconds: None,
            scene_format: crate::handlers::SceneFormat::Binary,
            scene_range_bytes: None,
            scene_key: None,
            budget: None,
        };
        match &spec.scene {
            JobScene::Uploaded {
                main, scene_bin, ..
            } => {
                self.store
                    .put(&scene_binary_key(job), scene_bin)
                    .map_err(|e| Self::storage_error("cannot store the scene", e))?;
                request.scene = main.clone();
            }
            JobScene::Key(key) => {
                request.scene = key.rsplit('/').next().unwrap_or(key).to_owned();
                request.scene_format = crate::handlers::SceneFormat::Files;
                request.scene_key = Some(key.clone());
                request.budget = spec.max_cost_usd.map(|max_cost_usd| BudgetCheck {
                    max_cost_usd,
                    model: self.prediction_model(),
                });
            }
        }
        let json = serde_json::to_vec(&request)
            .map_err(|e| ApiError::internal(format!("cannot encode the job request: {e}")))?;
        self.store
            .put(&manifest_key(job), &json)
            .map_err(|e| Self::storage_error("cannot store the job request", e))
    }

    fn enqueue(&self, job: &JobId) -> Result<(), ApiError> {
        let input = ExecutionInput {
            job: job.clone(),
            bucket: self.store.bucket().to_owned(),
        };
        self.handle
            .block_on(self.queue.enqueue(&input))
            .map(drop)
            .map_err(|e| ApiError::internal(e.to_string()))
    }

    /// The execution's status, `None` while the job waits in the queue.
    fn execution(&self, job: &JobId) -> Result<Option<super::sfn::Execution>, ApiError> {
        match self.handle.block_on(self.executions.describe(job)) {
            Ok(execution) => Ok(Some(execution)),
            Err(e) if e.kind == AwsErrorKind::NotFound => Ok(None),
            Err(e) => Err(ApiError::internal(e.to_string())),
        }
    }

    /// Tasks done (the Plan step once a Map Run started, and every Map item that succeeded)
    /// and the stage of the latest Map Run, from the execution's Map Runs: no listing of the
    /// job's objects.
    fn progress(&self, job: &JobId) -> Result<(u64, Option<Stage>), ApiError> {
        let runs = self
            .handle
            .block_on(self.executions.map_runs(job))
            .map_err(|e| ApiError::internal(e.to_string()))?;
        Ok(progress_of(&runs))
    }

    /// The job's status from its record and its execution's state (`None`: still queued);
    /// with `progress`, the execution's Map Runs are read for the tasks done.
    fn status_of(
        &self,
        job: &JobId,
        record: &JobRecord,
        execution: Option<ExecutionView>,
        progress: bool,
    ) -> Result<JobStatus, ApiError> {
        let status = match execution.as_ref().map(|e| &e.status) {
            None => JobState::Queued,
            Some(ExecutionStatus::Running | ExecutionStatus::PendingRedrive) => JobState::Running,
            Some(ExecutionStatus::Succeeded) => JobState::Succeeded,
            Some(ExecutionStatus::Aborted) => JobState::Cancelled,
            Some(
                ExecutionStatus::Failed | ExecutionStatus::TimedOut | ExecutionStatus::Unknown(_),
            ) => JobState::Failed,
        };
        let (tasks_done, stage) = match status {
            JobState::Succeeded => (record.tasks_total, Some(Stage::Combine)),
            JobState::Queued => (0, None),
            _ if progress => self.progress(job)?,
            _ => (0, None),
        };
        let error = match (status, &execution) {
            (JobState::Failed, Some(e)) => e.error.clone(),
            _ => None,
        };
        let end = if status.is_final() {
            execution
                .as_ref()
                .and_then(|e| e.stopped_unix_us)
                .unwrap_or_else(now_unix_us)
        } else {
            now_unix_us()
        };
        Ok(JobStatus {
            job: job.to_string(),
            status,
            stage: stage.map(|s| s.to_string()),
            tasks_done: tasks_done.min(record.tasks_total),
            tasks_total: record.tasks_total,
            retried_attempts: 0,
            elapsed_seconds: end.saturating_sub(record.created_unix_us) as f64 / 1e6,
            cost_usd: None,
            predicted_cost_usd: record.predicted_cost_usd,
            max_cost_usd: record.max_cost_usd,
            error,
            image_url: None,
            scene: Some(record.scene.clone()),
            stages: Vec::new(),
            outputs: record.outputs,
            frames: frames_of(record.request.as_ref()),
            frames_done: None,
        })
    }

    /// The job's status with its progress: DescribeExecution, then its Map Runs.
    fn full_status(&self, job: &JobId, record: &JobRecord) -> Result<JobStatus, ApiError> {
        let execution = self.execution(job)?.map(ExecutionView::described);
        self.status_of(job, record, execution, true)
    }
}

/// Tasks done and the current stage of an execution whose Map Runs (oldest first) are `runs`:
/// before the first Map Run it is planning (nothing done); after, the Plan step and every item
/// that succeeded in any run (a rerun's items are the ones an earlier run lost), in the stage of
/// the latest run.
fn progress_of(runs: &[MapRun]) -> (u64, Option<Stage>) {
    let Some(latest) = runs.last() else {
        return (0, Some(Stage::Plan));
    };
    let items: u64 = runs.iter().map(|r| r.succeeded).sum();
    let stage = Stage::of_state(&latest.label).or(Stage::of_rerun_loop_state(&latest.label));
    (1 + items, stage)
}

/// What a job's status needs of its execution.
struct ExecutionView {
    status: ExecutionStatus,
    /// `"{error}: {cause}"` of a failed execution, when described.
    error: Option<String>,
    stopped_unix_us: Option<u64>,
}

impl ExecutionView {
    fn described(e: super::sfn::Execution) -> Self {
        let error = Some(format!(
            "{}: {}",
            e.error.as_deref().unwrap_or("failed"),
            e.cause.as_deref().unwrap_or("no cause given")
        ));
        ExecutionView {
            status: e.status,
            error,
            stopped_unix_us: e.stopped_unix_us,
        }
    }

    fn listed(e: &Listed) -> Self {
        ExecutionView {
            status: e.status.clone(),
            error: None,
            stopped_unix_us: e.stopped_unix_us,
        }
    }
}

impl RenderBackend for AwsBackend {
    fn read_object(&self, key: &str) -> Result<Option<Vec<u8>>, ApiError> {
        object_in(&self.store, key)
    }

    fn object_size(&self, key: &str) -> Result<Option<u64>, ApiError> {
        object_size_in(&self.store, key)
    }

    fn read_object_range(
        &self,
        key: &str,
        range: std::ops::Range<u64>,
    ) -> Result<Vec<u8>, ApiError> {
        object_range_in(&self.store, key, range)
    }

    fn prediction_model(&self) -> PredictionModel {
        PredictionModel {
            // No limit means the account's default Lambda concurrency quota.
            concurrency: match self.limits.max_concurrency {
                0 => 1000,
                n => n,
            },
            memory_mb: self.limits.worker_memory_mb,
            arch: Arch::Arm64,
            speed: 1.0,
            rates: RATES,
        }
    }

    fn submit(&self, spec: JobSpec) -> Result<Submission, ApiError> {
        let job = job_for(spec.idempotency_key.as_deref());
        let outcome = JobRecord::accepted(&job, &spec).create(&self.store)?;
        let replayed = match outcome {
            PutOutcome::Created
                if spec.idempotency_key.is_some() && self.execution(&job)?.is_some() =>
            {
                // The key's earlier job expired (S3 deletes jobs/ after JobExpirationDays) while
                // Step Functions keeps its execution's name for 90 days: a new execution under
                // that name could never start, so the job would never run.
                let _ = self.store.delete(&api_record_key(&job));
                return Err(idempotency_key_expired(
                    spec.idempotency_key.as_deref().unwrap_or_default(),
                    job.as_str(),
                ));
            }
            PutOutcome::Created => false,
            PutOutcome::AlreadyExists if spec.idempotency_key.is_some() => true,
            PutOutcome::AlreadyExists => {
                return Err(ApiError::internal(format!(
                    "job id {job} is taken; try again"
                )));
            }
        };
        if replayed {
            let first_fingerprint = self.record(&job).ok().and_then(|r| r.request_fingerprint);
            if let (Some(key), Some(first)) = (&spec.idempotency_key, first_fingerprint)
                && first != spec.request_fingerprint
            {
                return Err(idempotency_key_reused(key, job.as_str()));
            }
            // The first submission may have stopped between its record and its message: finish
            // its work (the Starter starts each job once, whatever the messages).
            if self.execution(&job)?.is_some() {
                return Ok(Submission {
                    job: job.to_string(),
                    replayed,
                });
            }
            let stored = self.read_object(&manifest_key(&job))?.is_some();
            if !stored {
                self.store_job(&job, &spec)?;
            }
        } else {
            self.store_job(&job, &spec)?;
        }
        self.enqueue(&job)?;
        Ok(Submission {
            job: job.to_string(),
            replayed,
        })
    }

    fn status(&self, id: &str) -> Result<JobStatus, ApiError> {
        let job = Self::job_id(id)?;
        let record = self.record(&job)?;
        Ok(with_frames_done(
            self.full_status(&job, &record)?,
            &job,
            &self.store,
        ))
    }

    /// The job folders under `jobs/` (a delimited listing: one entry per job, however many
    /// objects each holds), each job's record, and every execution's state (ListExecutions);
    /// the progress of the jobs still running (their Map Runs), and the error of the failed
    /// ones among the `limit` answered (DescribeExecution).
    fn list(&self, limit: usize) -> Result<Vec<JobStatus>, ApiError> {
        let folders = self
            .store
            .list_folders("jobs/")
            .map_err(|e| Self::storage_error("cannot list the jobs", e))?;
        let jobs: Vec<JobId> = folders
            .iter()
            .filter_map(|f| f.strip_prefix("jobs/")?.strip_suffix('/'))
            .filter_map(|id| JobId::new(id).ok())
            .collect();
        let keys: Vec<String> = jobs.iter().map(api_record_key).collect();
        let mut records = Vec::new();
        for ((job, key), bytes) in jobs.into_iter().zip(&keys).zip(self.store.get_many(&keys)) {
            let bytes = match bytes {
                Ok(bytes) => bytes,
                // A folder the API did not make (a job run by `hort render` on this bucket).
                Err(StoreError::NotFound { .. }) => continue,
                Err(e) => return Err(Self::storage_error("cannot read a job's record", e)),
            };
            let record = JobRecord::decode(key, &bytes)?;
            records.push((record, job));
        }
        records.sort_by(|(a, _), (b, _)| {
            (b.created_unix_us, &b.job).cmp(&(a.created_unix_us, &a.job))
        });
        records.truncate(limit);
        let executions = self
            .handle
            .block_on(self.executions.list())
            .map_err(|e| ApiError::internal(e.to_string()))?;
        records
            .iter()
            .map(|(record, job)| {
                let listed = executions.get(job.as_str());
                let running = listed.is_some_and(|l| !l.status.is_final());
                let execution = match listed {
                    Some(l) if l.status == ExecutionStatus::Failed => {
                        self.execution(job)?.map(ExecutionView::described)
                    }
                    Some(l) => Some(ExecutionView::listed(l)),
                    None => None,
                };
                self.status_of(job, record, execution, running)
            })
            .collect()
    }

    fn image(
        &self,
        id: &str,
        format: ImageFormat,
        frame: Option<u32>,
    ) -> Result<ImageAnswer, ApiError> {
        let status = self.status(id)?;
        if status.status != JobState::Succeeded {
            return Err(ApiError::not_found(format!(
                "render {id} has no image: it is {}",
                status.status.as_str()
            )));
        }
        let job = Self::job_id(id)?;
        stored_image(id, &job, frame, format, &self.store)
    }

    fn report(&self, id: &str) -> Result<Vec<u8>, ApiError> {
        self.status(id)?;
        Err(ApiError::not_found(format!(
            "render {id}: a deployment keeps no report (no per-task accounting in the cloud \
             yet); the image and GET /renders/{id} are available"
        )))
    }

    fn cancel(&self, id: &str) -> Result<JobStatus, ApiError> {
        let job = Self::job_id(id)?;
        let record = self.record(&job)?;
        let status = self.full_status(&job, &record)?;
        if status.status.is_final() {
            return Ok(status);
        }
        let aws = |e: super::AwsError| ApiError::internal(e.to_string());
        if status.status == JobState::Queued {
            // Start it under its name so that the queued message starts nothing, then stop it.
            let input = ExecutionInput {
                job: job.clone(),
                bucket: self.store.bucket().to_owned(),
            };
            self.handle
                .block_on(self.executions.start(&input))
                .map_err(aws)?;
        }
        self.handle
            .block_on(
                self.executions
                    .stop(&job, "Hort.Cancelled", "DELETE /renders"),
            )
            .map_err(aws)?;
        // Intermediate objects go; the request, the scene and the record stay.
        let keys: Vec<String> = self
            .store
            .list(&format!("jobs/{job}/"))
            .map_err(|e| Self::storage_error("cannot list the job's objects", e))?
            .into_iter()
            .filter(|k| !kept_on_cancel(&job, k))
            .collect();
        self.store
            .delete_all(&keys)
            .map_err(|e| Self::storage_error("cannot delete the job's objects", e))?;
        self.full_status(&job, &record)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn progress_counts_the_plan_and_every_succeeded_item_in_the_latest_runs_stage() {
        let run = |label: &str, succeeded, total, started| MapRun {
            arn: format!("arn:aws:states:r:1:mapRun:m/{label}:{started}"),
            label: label.into(),
            succeeded,
            total,
            started_unix_ms: started,
        };
        assert_eq!(progress_of(&[]), (0, Some(Stage::Plan)));
        let runs = [
            run("CastMap", 98, 100, 1),
            run("CastMapRerun", 2, 2, 2),
            run("CastReduce", 7, 10, 3),
        ];
        assert_eq!(progress_of(&runs), (108, Some(Stage::CastReduce)));
        assert_eq!(progress_of(&runs[..2]), (101, Some(Stage::CastMap)));
    }
}
