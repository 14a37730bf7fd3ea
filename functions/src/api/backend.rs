//! What the router needs from whatever runs the jobs: the [`RenderBackend`] trait, and the
//! values that cross it. The emulator (`hort serve`) implements it over its embedded S3 server
//! and background threads; a Lambda deployment would implement it over S3 and Step Functions.

use std::collections::BTreeMap;
use std::ops::Range;

use hort_core::pipeline::{PlanRequest, StoredOutputs};
use hort_core::store::{BlobStore, StoreError};
use serde::{Deserialize, Serialize};

use super::error::ApiError;
use super::image::{ImageAnswer, ImageFormat};
use hort_core::pipeline::JobPlan;
use hort_core::predict::{Prediction, PredictionModel, predict};

/// A job's state. Serialized in capitals (`"RUNNING"`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "UPPERCASE")]
pub enum JobState {
    /// Accepted, not started yet.
    Queued,
    /// Its state machine is running.
    Running,
    /// Done: the image and the report can be fetched.
    Succeeded,
    /// Stopped by a failure (`error` says which).
    Failed,
    /// Stopped by `DELETE /renders/{id}`; its intermediate objects are deleted.
    Cancelled,
}

impl JobState {
    /// True once the job can no longer change.
    pub fn is_final(self) -> bool {
        matches!(
            self,
            JobState::Succeeded | JobState::Failed | JobState::Cancelled
        )
    }

    /// The name as in JSON (`RUNNING`).
    pub fn as_str(self) -> &'static str {
        match self {
            JobState::Queued => "QUEUED",
            JobState::Running => "RUNNING",
            JobState::Succeeded => "SUCCEEDED",
            JobState::Failed => "FAILED",
            JobState::Cancelled => "CANCELLED",
        }
    }
}

/// The answer of `GET /renders/{id}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JobStatus {
    /// The job id.
    pub job: String,
    /// Its state.
    pub status: JobState,
    /// The stage running (or the last one entered); `null` before the plan step starts.
    pub stage: Option<String>,
    /// Tasks finished, over all stages.
    pub tasks_done: u64,
    /// Tasks of the whole job (known from the plan before it runs).
    pub tasks_total: u64,
    /// Task attempts that failed and were retried.
    pub retried_attempts: u64,
    /// Seconds since the job was accepted, until it ended.
    pub elapsed_seconds: f64,
    /// The cost estimate of the finished job (`hort_core::cost`, as `hort render` reports it);
    /// `null` until the job succeeded.
    pub cost_usd: Option<f64>,
    /// The cost predicted when the job was accepted.
    pub predicted_cost_usd: f64,
    /// The job's budget (`max_cost_usd` of its request), if it had one.
    #[serde(default)]
    pub max_cost_usd: Option<f64>,
    /// Why the job failed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Where the image is, once the job succeeded (set by the router).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_url: Option<String>,
    /// How the job's scene is named (its main file, or its key); `null` if the backend does
    /// not know.
    #[serde(default)]
    pub scene: Option<String>,
    /// Tasks done per stage, in stage order (empty if the backend does not count them).
    #[serde(default)]
    pub stages: Vec<StageProgress>,
    /// What the job stores besides its PNG (the request's `outputs`): `GET .../image` serves
    /// `format=pfm` and `format=exr` only if `linear`. Both for a job of a record that does not
    /// say (as for a request that does not).
    #[serde(default)]
    pub outputs: StoredOutputs,
    /// A job of several frames: its frames' numbers, each served at
    /// `GET /renders/{id}/frames/{k}/image` once the job succeeded; absent for one image.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub frames: Vec<u32>,
    /// A job of several frames: how many of `frames` are done (their images stored: each is
    /// assembled by the task that finishes it); absent for one image, and in a listing.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames_done: Option<u64>,
}

/// `status` of `job` with its [`JobStatus::frames_done`]: every frame of a job that succeeded,
/// else the frames whose image `store` holds (one listing of the job's frames); a job of one
/// frame, or one the store cannot list now, is left without.
pub fn with_frames_done(
    mut status: JobStatus,
    job: &hort_core::ids::JobId,
    store: &dyn BlobStore,
) -> JobStatus {
    if status.frames.is_empty() {
        return status;
    }
    status.frames_done = if status.status == JobState::Succeeded {
        Some(status.frames.len() as u64)
    } else {
        hort_core::pipeline::assembled_frames(store, job)
            .ok()
            .map(|done| done.len() as u64)
    };
    status
}

/// The frames a job of `request` renders, for [`JobStatus::frames`]: none for one image.
pub fn frames_of(request: Option<&hort_core::pipeline::PlanRequest>) -> Vec<u32> {
    match request {
        Some(r) if r.frame.count > 1 => r.frame.frames().collect(),
        _ => Vec::new(),
    }
}

/// One stage's progress in a [`JobStatus`].
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct StageProgress {
    /// The stage's name (`plan`, `cast-map`, ...).
    pub stage: String,
    /// Its tasks that succeeded.
    pub done: u64,
    /// Its tasks (from the plan).
    pub total: u64,
}

/// A validated job, ready to run.
#[derive(Clone, Debug)]
pub struct JobSpec {
    /// How the scene is named in reports: the main file, or its key.
    pub scene_name: String,
    /// The scene: files the request carried, or a key in the bucket.
    pub scene: JobScene,
    /// Image size, samples, splits, spans (resolved and checked) and split mode.
    pub request: PlanRequest,
    /// The prediction the request was checked against.
    pub prediction: Prediction,
    /// The budget, if one was given.
    pub max_cost_usd: Option<f64>,
    /// The client's `Idempotency-Key`: a second submission with the same key and the same body
    /// names the job of the first and starts nothing; with another body it is refused (422).
    pub idempotency_key: Option<String>,
    /// The fingerprint of the request body ([`request_fingerprint`]), which a reused
    /// `Idempotency-Key` must match.
    pub request_fingerprint: String,
}

/// Where a job's scene is.
#[derive(Clone, Debug)]
pub enum JobScene {
    /// Files the request carried, checked and parsed by the API.
    Uploaded {
        /// The main file, relative to the scene's folder.
        main: String,
        /// Every file of the scene, relative to the scene's folder.
        files: BTreeMap<String, Vec<u8>>,
        /// The scene the request was checked with, in the binary scene format
        /// ([`hort_core::scene::encode_scene_named`]): a backend that stores it instead of the
        /// files spares the Plan function a second parse.
        scene_bin: Vec<u8>,
    },
    /// The main file's key in the bucket (the files it names beside it), sized but not loaded
    /// by the API: the Plan function copies the scene into the job and plans it exactly, and
    /// checks the budget (`max_cost_usd`) again on that plan.
    Key(String),
}

/// The fingerprint of a `POST /renders` body: `fnv1a64-` and the 64-bit FNV-1a of its bytes in
/// hex. Two bodies with the same bytes have the same fingerprint on every machine.
pub fn request_fingerprint(body: &[u8]) -> String {
    format!("fnv1a64-{:016x}", hort_core::digest::fnv1a64(body))
}

/// The 422 of an `Idempotency-Key` reused with another body than the one that started `job`.
pub fn idempotency_key_reused(key: &str, job: &str) -> ApiError {
    ApiError::idempotency_key_reused(format!(
        "Idempotency-Key {key:?} was used for job {job} with another request body: a key names \
         one request; send the same body to see that job, or use a new key for a new request"
    ))
}

/// The 422 of an `Idempotency-Key` whose job's objects expired while its execution's name is
/// still taken (Step Functions keeps it 90 days): the same key can start nothing new.
pub fn idempotency_key_expired(key: &str, job: &str) -> ApiError {
    ApiError::idempotency_key_reused(format!(
        "Idempotency-Key {key:?} named job {job}, whose objects have expired (the bucket deletes \
         jobs/ after JobExpirationDays) while Step Functions keeps its execution's name for 90 \
         days: use a new key"
    ))
}

/// What [`RenderBackend::submit`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct Submission {
    /// The job's id.
    pub job: String,
    /// True if the idempotency key named an existing job, so nothing new was started.
    pub replayed: bool,
}

/// [`RenderBackend::read_object`] over a bucket's `store`.
pub fn object_in(store: &dyn BlobStore, key: &str) -> Result<Option<Vec<u8>>, ApiError> {
    match store.get(key) {
        Ok(bytes) => Ok(Some(bytes)),
        Err(StoreError::NotFound { .. }) => Ok(None),
        Err(e) => Err(ApiError::internal(format!("cannot read {key}: {e}"))),
    }
}

/// [`RenderBackend::object_size`] over a bucket's `store` (a HEAD).
pub fn object_size_in(store: &dyn BlobStore, key: &str) -> Result<Option<u64>, ApiError> {
    match store.size(key) {
        Ok(size) => Ok(Some(size)),
        Err(StoreError::NotFound { .. }) => Ok(None),
        Err(e) => Err(ApiError::internal(format!(
            "cannot read the size of {key}: {e}"
        ))),
    }
}

/// [`RenderBackend::read_object_range`] over a bucket's `store` (a range GET).
pub fn object_range_in(
    store: &dyn BlobStore,
    key: &str,
    range: Range<u64>,
) -> Result<Vec<u8>, ApiError> {
    match store.get_range(key, range) {
        Ok(bytes) => Ok(bytes),
        // Past the end of the object (it changed since its size was read): nothing there.
        Err(StoreError::InvalidRange { .. }) => Ok(Vec::new()),
        Err(e) => Err(ApiError::internal(format!("cannot read {key}: {e}"))),
    }
}

/// Whatever runs the jobs. Every method may block (storage, threads); the router calls them
/// from the request's thread. Unknown jobs are [`ApiError::not_found`].
pub trait RenderBackend: Send + Sync {
    /// An object of the bucket, for scenes given by key; `None` if there is none.
    fn read_object(&self, key: &str) -> Result<Option<Vec<u8>>, ApiError>;

    /// The size of an object of the bucket (a HEAD), `None` if there is none. By default the
    /// length of [`RenderBackend::read_object`]'s bytes.
    fn object_size(&self, key: &str) -> Result<Option<u64>, ApiError> {
        Ok(self.read_object(key)?.map(|bytes| bytes.len() as u64))
    }

    /// Bytes `range` of an object of the bucket, clamped to its end (a range GET). By default
    /// a slice of [`RenderBackend::read_object`]'s bytes.
    fn read_object_range(&self, key: &str, range: Range<u64>) -> Result<Vec<u8>, ApiError> {
        let bytes = self.read_object(key)?.unwrap_or_default();
        let end = (range.end as usize).min(bytes.len());
        Ok(bytes[(range.start as usize).min(end)..end].to_vec())
    }

    /// What jobs run on, for predictions.
    fn prediction_model(&self) -> PredictionModel;

    /// The predicted stages, time and cost of `plan` (the dry run, and the budget check).
    fn predict(&self, plan: &JobPlan) -> Prediction {
        predict(plan, &self.prediction_model())
    }

    /// Accepts a validated job and starts it (or, with a known idempotency key, names the job
    /// that key started). A backend that already runs as many jobs as it takes answers
    /// [`ApiError::too_many_jobs`] (429) and starts nothing.
    fn submit(&self, job: JobSpec) -> Result<Submission, ApiError>;

    /// The job's state and progress.
    fn status(&self, job: &str) -> Result<JobStatus, ApiError>;

    /// The jobs this backend knows, newest first, at most `limit` of them.
    fn list(&self, limit: usize) -> Result<Vec<JobStatus>, ApiError>;

    /// The finished job's image (frame `frame`'s, in a job of several frames), or where to
    /// fetch it when it is too large for a Lambda response
    /// ([`stored_image`](super::stored_image)); [`ApiError::not_found`] until it succeeded.
    fn image(
        &self,
        job: &str,
        format: ImageFormat,
        frame: Option<u32>,
    ) -> Result<ImageAnswer, ApiError>;

    /// The finished job's report (the JSON of `hort render --report`); not found until it
    /// succeeded.
    fn report(&self, job: &str) -> Result<Vec<u8>, ApiError>;

    /// Stops a queued or running job and deletes its intermediate objects (state
    /// [`JobState::Cancelled`]); a finished job is left as it is. Returns the state after.
    fn cancel(&self, job: &str) -> Result<JobStatus, ApiError>;
}

#[cfg(test)]
mod frames_done_tests {
    use super::*;
    use hort_core::ids::JobId;
    use hort_core::store::MemoryStore;

    fn status(state: JobState, frames: Vec<u32>) -> JobStatus {
        JobStatus {
            job: "j".into(),
            status: state,
            stage: None,
            tasks_done: 0,
            tasks_total: 0,
            retried_attempts: 0,
            elapsed_seconds: 0.0,
            cost_usd: None,
            predicted_cost_usd: 0.0,
            max_cost_usd: None,
            error: None,
            image_url: None,
            scene: None,
            stages: Vec::new(),
            outputs: StoredOutputs::ALL,
            frames,
            frames_done: None,
        }
    }

    /// A running job's frames done are those whose PNG is stored (a partition or another
    /// output is not); a succeeded job has them all; a job of one frame has no count.
    #[test]
    fn frames_done_count_the_stored_frame_images() {
        let store = MemoryStore::new();
        let job = JobId::new("j").unwrap();
        for key in [
            "jobs/j/frames/00000/out/image.png",
            "jobs/j/frames/00001/out/image.pfm",
            "jobs/j/frames/00001/render/00000/part-00000",
            "jobs/j/frames/00002/out/image.png",
            "jobs/j/out/image.png",
        ] {
            store.put(key, b"x").unwrap();
        }
        let running = with_frames_done(status(JobState::Running, vec![0, 1, 2, 3]), &job, &store);
        assert_eq!(running.frames_done, Some(2));
        let done = with_frames_done(status(JobState::Succeeded, vec![0, 1, 2, 3]), &job, &store);
        assert_eq!(done.frames_done, Some(4));
        let still = with_frames_done(status(JobState::Running, Vec::new()), &job, &store);
        assert_eq!(still.frames_done, None);
    }
}
