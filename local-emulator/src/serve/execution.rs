//! `hort serve`'s record of a job's run, at `jobs/{job}/execution.json`: where the run stands
//! (state, stage, progress, times, cost, error). A deployment asks its Step Functions execution
//! for the same facts; what was accepted is the API's own record (`jobs/{job}/api.json`,
//! [`JobRecord`]), the same for both.
//!
//! Servers before this layout kept one record per job at `api/renders/{job}/status.json` and
//! the report beside it; [`migrate_legacy_records`] carries them over when a server opens the
//! data folder, leaving the old objects where they are.

use anyhow::{Context, Result};
use hort_core::ids::JobId;
use hort_core::keys::{execution_record_key, report_key};
use hort_core::pipeline::PlanRequest;
use hort_core::store::{BlobStore, PutOutcome};
use hort_functions::api::{JobRecord, JobState, StageProgress};
use serde::{Deserialize, Serialize};

/// A job's run as `hort serve` records it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExecutionRecord {
    /// Where the job stands.
    pub status: JobState,
    /// The stage running, or the last one entered.
    pub stage: Option<String>,
    /// Tasks that succeeded, over all stages.
    pub tasks_done: u64,
    /// Task attempts that failed and were retried.
    pub retried_attempts: u64,
    /// When the run started and ended: microseconds since the Unix epoch.
    pub started_unix_us: Option<u64>,
    /// See `started_unix_us`.
    pub finished_unix_us: Option<u64>,
    /// The finished job's cost.
    pub cost_usd: Option<f64>,
    /// Why the job failed.
    pub error: Option<String>,
    /// Tasks done of each stage's tasks, in stage order.
    pub stages: Vec<StageProgress>,
}

impl ExecutionRecord {
    /// The run of a job just accepted: queued, nothing done of `stages`.
    pub fn queued(stages: Vec<StageProgress>) -> ExecutionRecord {
        ExecutionRecord {
            status: JobState::Queued,
            stage: None,
            tasks_done: 0,
            retried_attempts: 0,
            started_unix_us: None,
            finished_unix_us: None,
            cost_usd: None,
            error: None,
            stages,
        }
    }

    /// Stores the record of `job`'s run, and replaces it with the record as read back, so what
    /// this server answers is exactly what a restarted one would (JSON numbers need not parse
    /// back to the same bits).
    pub fn save(&mut self, store: &dyn BlobStore, job: &JobId) -> Result<()> {
        let json = serde_json::to_vec_pretty(self).context("cannot encode the job's run")?;
        *self = serde_json::from_slice(&json).context("cannot decode the job's run")?;
        let key = execution_record_key(job);
        store
            .put(&key, &json)
            .with_context(|| format!("cannot store {key}"))
    }

    /// The record of `job`'s run in `store`, `None` if it has none.
    pub fn read(store: &dyn BlobStore, job: &JobId) -> Result<Option<ExecutionRecord>> {
        let key = execution_record_key(job);
        let bytes = match store.get(&key) {
            Ok(bytes) => bytes,
            Err(e) if e.is_not_found() => return Ok(None),
            Err(e) => return Err(e).with_context(|| format!("cannot read {key}")),
        };
        let record =
            serde_json::from_slice(&bytes).with_context(|| format!("cannot decode {key}"))?;
        Ok(Some(record))
    }
}

/// The state `hort serve` recorded for `job` in `store`, or `None` if it served no job of that
/// id. `hort jobs list` shows it.
pub fn recorded_state(store: &dyn BlobStore, job: &JobId) -> Result<Option<JobState>> {
    Ok(ExecutionRecord::read(store, job)?.map(|r| r.status))
}

/// Where servers before this layout kept their records.
const LEGACY_PREFIX: &str = "api/renders/";

/// A record of a server before this layout: the API's record and the run's in one.
#[derive(Deserialize)]
struct LegacyRecord {
    job: String,
    status: JobState,
    stage: Option<String>,
    tasks_done: u64,
    tasks_total: u64,
    retried_attempts: u64,
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
    #[serde(default)]
    stages: Vec<StageProgress>,
    #[serde(default)]
    request_fingerprint: Option<String>,
}

/// Carries the records (and reports) of servers before this layout over to it: each job of
/// `api/renders/{job}/status.json` without an API record gets one, its run's record and its
/// report. The old objects stay. Returns the jobs carried over.
pub fn migrate_legacy_records(store: &dyn BlobStore) -> Result<Vec<String>> {
    let keys = store
        .list(LEGACY_PREFIX)
        .context("cannot list the records of earlier servers")?;
    let mut migrated = Vec::new();
    for key in keys.iter().filter(|k| k.ends_with("/status.json")) {
        let bytes = store
            .get(key)
            .with_context(|| format!("cannot read {key}"))?;
        let old: LegacyRecord =
            serde_json::from_slice(&bytes).with_context(|| format!("cannot decode {key}"))?;
        let job = JobId::new(&old.job).with_context(|| format!("{key}: job id"))?;
        let record = JobRecord {
            job: old.job.clone(),
            scene: old.scene,
            triangles: old.triangles,
            tasks_total: old.tasks_total,
            predicted_cost_usd: old.predicted_cost_usd,
            predicted_seconds: old.predicted_seconds,
            created_unix_us: old.created_unix_us,
            idempotency_key: old.idempotency_key,
            max_cost_usd: old.max_cost_usd,
            request_fingerprint: old.request_fingerprint,
            request: Some(old.request),
            outputs: old.request.outputs,
            stages: old
                .stages
                .iter()
                .map(|s| StageProgress {
                    done: 0,
                    ..s.clone()
                })
                .collect(),
        };
        let created = record
            .create(store)
            .map_err(|e| anyhow::anyhow!("{key}: {}", e.message))?;
        if created == PutOutcome::AlreadyExists {
            continue;
        }
        let mut run = ExecutionRecord {
            status: old.status,
            stage: old.stage,
            tasks_done: old.tasks_done,
            retried_attempts: old.retried_attempts,
            started_unix_us: old.started_unix_us,
            finished_unix_us: old.finished_unix_us,
            cost_usd: old.cost_usd,
            error: old.error,
            stages: old.stages,
        };
        run.save(store, &job)?;
        let old_report = format!("{LEGACY_PREFIX}{job}/report.json");
        match store.get(&old_report) {
            Ok(report) => store
                .put(&report_key(&job), &report)
                .with_context(|| format!("cannot copy {old_report}"))?,
            Err(e) if e.is_not_found() => {}
            Err(e) => return Err(e).with_context(|| format!("cannot read {old_report}")),
        }
        migrated.push(old.job);
    }
    Ok(migrated)
}

#[cfg(test)]
mod tests {
    use super::*;
    use hort_core::keys::api_record_key;
    use hort_core::store::MemoryStore;

    const OLD: &str = r#"{"job":"r-1764000000000-0","status":"SUCCEEDED","stage":"combine",
        "tasks_done":5,"tasks_total":5,"retried_attempts":1,"created_unix_us":10,
        "started_unix_us":11,"finished_unix_us":20,"cost_usd":0.25,"predicted_cost_usd":0.5,
        "predicted_seconds":2.0,"error":null,"idempotency_key":"k","scene":"cornell.json",
        "triangles":36,"request":{"width":64,"height":48,"spp":2,"splits":null,"spans":null,
        "split_mode":"spatial"},"max_cost_usd":null,
        "stages":[{"stage":"render","done":3,"total":3}],"request_fingerprint":"f"}"#;

    #[test]
    fn records_of_earlier_servers_are_carried_over_once_and_kept() {
        let store = MemoryStore::new();
        let job = JobId::new("r-1764000000000-0").unwrap();
        store
            .put("api/renders/r-1764000000000-0/status.json", OLD.as_bytes())
            .unwrap();
        store
            .put(
                "api/renders/r-1764000000000-0/report.json",
                b"{\"report\":1}\n",
            )
            .unwrap();
        assert_eq!(migrate_legacy_records(&store).unwrap(), [job.to_string()]);
        let record = JobRecord::read(&store, &job).unwrap();
        assert_eq!(
            (record.scene.as_str(), record.triangles, record.tasks_total),
            ("cornell.json", 36, 5)
        );
        assert_eq!(
            record.request.map(|r| (r.width, r.height, r.spp)),
            Some((64, 48, 2))
        );
        assert_eq!(record.stages[0].done, 0);
        let run = ExecutionRecord::read(&store, &job).unwrap().unwrap();
        assert_eq!(
            (run.status, run.tasks_done, run.cost_usd),
            (JobState::Succeeded, 5, Some(0.25))
        );
        assert_eq!(run.stages[0].done, 3);
        assert_eq!(store.get(&report_key(&job)).unwrap(), b"{\"report\":1}\n");
        assert_eq!(
            recorded_state(&store, &job).unwrap(),
            Some(JobState::Succeeded)
        );
        // The old objects stay; a second opening carries nothing over again.
        assert!(
            store
                .get("api/renders/r-1764000000000-0/status.json")
                .is_ok()
        );
        let api = store.get(&api_record_key(&job)).unwrap();
        assert!(migrate_legacy_records(&store).unwrap().is_empty());
        assert_eq!(store.get(&api_record_key(&job)).unwrap(), api);
    }

    #[test]
    fn a_malformed_old_record_is_named() {
        let store = MemoryStore::new();
        store.put("api/renders/x/status.json", b"{").unwrap();
        let e = migrate_legacy_records(&store).unwrap_err();
        assert_eq!(format!("{e}"), "cannot decode api/renders/x/status.json");
    }
}
