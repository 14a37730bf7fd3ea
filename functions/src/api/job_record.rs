//! The API's record of a job, one for both backends (the deployment's API function and
//! `hort serve`): what was accepted, stored once at [`api_record_key`] with a conditional put;
//! the job id scheme (an idempotency key always names the same job); and the clock.
//!
//! Both backends keep the same bucket layout, so a bucket written by `hort serve` reads as a
//! deployment's would. Where the job's run stands is not in this record: a deployment asks its
//! Step Functions execution, `hort serve` keeps its own record of the run beside this one
//! (`hort_core::keys::execution_record_key`).

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

use hort_core::ids::JobId;
use hort_core::keys::api_record_key;
use hort_core::pipeline::{PlanRequest, StoredOutputs};
use hort_core::store::{BlobStore, PutOutcome, StoreError};
use serde::{Deserialize, Serialize};

use super::backend::{JobSpec, StageProgress};
use super::error::ApiError;

/// The API's record of a job, at `jobs/{job}/api.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobRecord {
    /// The job id.
    pub job: String,
    /// How the job's scene is named: its main file, or its key.
    pub scene: String,
    /// Triangles of the scene (records of older versions: 0).
    #[serde(default)]
    pub triangles: u64,
    /// Tasks of the whole job, as predicted.
    pub tasks_total: u64,
    /// The predicted cost, USD.
    pub predicted_cost_usd: f64,
    /// The predicted wall-clock time, seconds.
    pub predicted_seconds: f64,
    /// When the job was accepted: microseconds since the Unix epoch (integers, so a record
    /// read back gives the same elapsed time to the bit).
    pub created_unix_us: u64,
    /// The request's `Idempotency-Key`, if it had one.
    pub idempotency_key: Option<String>,
    /// The request's budget, if it had one.
    pub max_cost_usd: Option<f64>,
    /// The request body's fingerprint (records of older versions have none: any body matches).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub request_fingerprint: Option<String>,
    /// The resolved render settings (records of older versions have none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub request: Option<PlanRequest>,
    /// What the job stores besides its PNG (records of older versions: everything).
    #[serde(default)]
    pub outputs: StoredOutputs,
    /// The predicted stages with their task counts, in stage order (records of older versions
    /// have none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub stages: Vec<StageProgress>,
}

impl JobRecord {
    /// The record of `spec`, accepted now as `job`.
    pub fn accepted(job: &JobId, spec: &JobSpec) -> JobRecord {
        JobRecord {
            job: job.to_string(),
            scene: spec.scene_name.clone(),
            triangles: spec.prediction.triangles,
            tasks_total: spec.prediction.tasks_total,
            predicted_cost_usd: spec.prediction.predicted_cost_usd,
            predicted_seconds: spec.prediction.predicted_seconds,
            created_unix_us: now_unix_us(),
            idempotency_key: spec.idempotency_key.clone(),
            max_cost_usd: spec.max_cost_usd,
            request_fingerprint: Some(spec.request_fingerprint.clone()),
            request: Some(spec.request),
            outputs: spec.request.outputs,
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
        }
    }

    /// Stores the record unless the job has one: [`PutOutcome::AlreadyExists`] then, and the
    /// stored record is left as it was.
    pub fn create(&self, store: &dyn BlobStore) -> Result<PutOutcome, ApiError> {
        let job = JobId::new(&self.job)
            .map_err(|e| ApiError::internal(format!("job id {:?}: {e}", self.job)))?;
        let json = serde_json::to_vec_pretty(self)
            .map_err(|e| ApiError::internal(format!("cannot encode the job's record: {e}")))?;
        store
            .put_if_absent(&api_record_key(&job), &json)
            .map_err(|e| ApiError::internal(format!("cannot store the job's record: {e}")))
    }

    /// The record of `job` in `store`: 404 if the job has none.
    pub fn read(store: &dyn BlobStore, job: &JobId) -> Result<JobRecord, ApiError> {
        let key = api_record_key(job);
        let bytes = store.get(&key).map_err(|e| match e {
            StoreError::NotFound { .. } => ApiError::not_found(format!("no render {job}")),
            e => ApiError::internal(format!("cannot read the job's record: {e}")),
        })?;
        JobRecord::decode(&key, &bytes)
    }

    /// The record stored at `key` as `bytes`.
    pub fn decode(key: &str, bytes: &[u8]) -> Result<JobRecord, ApiError> {
        serde_json::from_slice(bytes)
            .map_err(|e| ApiError::internal(format!("the record {key} is malformed: {e}")))
    }
}

/// Microseconds since the Unix epoch: the clock of every record.
pub fn now_unix_us() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64)
}

/// The job id an idempotency key always names: `key-` and a 64-bit FNV-1a hash of the key.
pub fn keyed_id(key: &str) -> JobId {
    let hash = hort_core::digest::fnv1a64(key.as_bytes());
    JobId::new(format!("key-{hash:016x}")).expect("a valid job id")
}

/// A job id not used before: `r-`, the time in microseconds, and a per-process counter mixed
/// with the process id.
pub fn fresh_id() -> JobId {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let salt = (u64::from(std::process::id()) << 20) ^ n;
    JobId::new(format!("r-{}-{salt:x}", now_unix_us())).expect("a valid job id")
}

/// The job a submission with `idempotency_key` names: the key's job, else a fresh one.
pub fn job_for(idempotency_key: Option<&str>) -> JobId {
    idempotency_key.map_or_else(fresh_id, keyed_id)
}

#[cfg(test)]
mod tests {
    use super::*;
    use hort_core::store::MemoryStore;

    #[test]
    fn ids_are_valid_and_keys_name_one_job() {
        assert_eq!(keyed_id("k1"), keyed_id("k1"));
        assert_ne!(keyed_id("k1"), keyed_id("k2"));
        assert!(keyed_id(&"x".repeat(255)).as_str().len() <= 64);
        assert_ne!(fresh_id(), fresh_id());
        assert!(fresh_id().as_str().len() <= 64);
        assert_eq!(job_for(Some("k1")), keyed_id("k1"));
        assert!(job_for(None).as_str().starts_with("r-"));
    }

    #[test]
    fn a_record_is_created_once_and_reads_back_exactly() {
        let store = MemoryStore::new();
        let job = keyed_id("k");
        let record = JobRecord {
            job: job.to_string(),
            scene: "cornell.json".into(),
            triangles: 36,
            tasks_total: 5,
            predicted_cost_usd: 0.1 + 0.2,
            predicted_seconds: 1.0 / 3.0,
            created_unix_us: 1_765_000_000_000_001,
            idempotency_key: Some("k".into()),
            max_cost_usd: None,
            request_fingerprint: Some("f".into()),
            request: None,
            outputs: StoredOutputs::PNG,
            stages: vec![StageProgress {
                stage: "render".into(),
                done: 0,
                total: 3,
            }],
        };
        assert_eq!(record.create(&store).unwrap(), PutOutcome::Created);
        let mut second = record.clone();
        second.scene = "other.json".into();
        assert_eq!(second.create(&store).unwrap(), PutOutcome::AlreadyExists);
        assert_eq!(JobRecord::read(&store, &job).unwrap(), record);
        let missing = JobRecord::read(&store, &keyed_id("other")).unwrap_err();
        assert_eq!(missing.status, 404);
        assert_eq!(missing.message, format!("no render {}", keyed_id("other")));
    }

    #[test]
    fn records_of_older_versions_still_read() {
        let old = br#"{"job":"r-1-0","scene":"x.obj","tasks_total":3,"predicted_cost_usd":0.5,
            "predicted_seconds":2.0,"created_unix_us":7,"idempotency_key":null,"max_cost_usd":null}"#;
        let r = JobRecord::decode("jobs/r-1-0/api.json", old).unwrap();
        assert_eq!(
            (r.triangles, r.outputs, r.request),
            (0, StoredOutputs::ALL, None)
        );
        assert!(r.stages.is_empty() && r.request_fingerprint.is_none());
        let e = JobRecord::decode("jobs/r-1-0/api.json", b"{").unwrap_err();
        assert!(
            e.message
                .starts_with("the record jobs/r-1-0/api.json is malformed: "),
            "{}",
            e.message
        );
    }
}
