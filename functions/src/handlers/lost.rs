//! The Plan function's `lost` step: after each Map Run of a stage (`{Map}Lost` in the state
//! machine), read the results its `ResultWriter` stored and hand the items whose task was lost
//! after its retries to the stage's rerun Map, through an items file rather than the state.
//!
//! Why a function: a Distributed Map's results come back inline only within Step Functions'
//! 256 KiB payload, and over it the execution fails with `States.DataLimitExceeded`, which no
//! Catch catches. Every Map of our machine therefore writes its results to S3, and this step
//! turns them into what the `{Map}Check` Choice needs: how many items were lost, in which round,
//! where their items file is, and the first one's task and error for the job's failure.
//!
//! Results format (AWS's `ResultWriter` of `s3:putObject`, which the emulator writes the same
//! way): `manifest.json` lists result files under `ResultFiles.SUCCEEDED`; each is a JSON array
//! of child executions whose `Output` is the child's output as JSON text. A child that lost its
//! item ends in `{Map}TaskLost` with `{"lost": {"item", "error", "cause"}}`; one that succeeded
//! ends with `{}`.

use hort_core::ids::{JobId, TaskId};
use hort_core::keys::lost_items_key;
use hort_core::stage::Stage;
use hort_core::store::BlobStore;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::events::TaskItem;
use super::{HandlerError, check_bucket};

/// Input of the Plan function's `lost` step.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LostEvent {
    /// The job whose Map ran.
    pub job: JobId,
    /// The bucket holding the job (must be the one the function serves).
    pub bucket: String,
    /// Always `"lost"`.
    pub step: String,
    /// The Map's stage (named in errors only).
    pub stage: Stage,
    /// The Map Run's `ResultWriterDetails.Key`: its `manifest.json`.
    pub results: String,
    /// 0 after the stage's Map, n after its n-th rerun.
    pub round: u32,
    /// Retry count of this attempt (`$$.State.RetryCount`), 0 for the first.
    #[serde(default)]
    pub attempt: u32,
}

/// What the `{Map}Check` Choice reads at `$.rerun`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct LostOutput {
    /// How many items the Map Run lost.
    pub lost: usize,
    /// The event's round, echoed so the state machine can count reruns.
    pub rounds: u32,
    /// The key of the items file of the lost items (in task order), for the rerun Map's
    /// `ItemReader`; `None` when none was lost.
    pub items: Option<String>,
    /// The lost item with the smallest task, with its last error; `None` when none was lost.
    pub first: Option<LostItem>,
}

/// A lost item's task and the last error its retries ended with.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct LostItem {
    /// The task.
    pub task: TaskId,
    /// The error name (e.g. `States.Timeout`).
    pub error: String,
    /// Its cause.
    pub cause: String,
}

/// What a `{Map}TaskLost` child outputs.
#[derive(Deserialize)]
struct LostRecord {
    item: TaskItem,
    error: String,
    cause: String,
}

/// True if `event` is for the `lost` step (the Plan function's other events have no such step).
pub fn is_lost_event(event: &Value) -> bool {
    event.get("step").and_then(Value::as_str) == Some("lost")
}

/// Reads the Map Run's results named by `event.results`, stores the lost items (if any) beside
/// them (`lost.json`) and says how many there were. Store errors keep their classification;
/// results of another job, or that do not parse, are bad input naming the key. The same results
/// give the same items file, byte for byte.
pub fn handle_lost(
    store: &dyn BlobStore,
    bucket: &str,
    event: &LostEvent,
) -> Result<LostOutput, HandlerError> {
    check_bucket(&event.bucket, bucket)?;
    let stage = event.stage;
    let items_key = lost_items_key(&event.job, &event.results).ok_or_else(|| {
        HandlerError::bad_input(format!(
            "lost step of {stage}: results {:?} is not a Map Run manifest of job {}",
            event.results, event.job
        ))
    })?;
    let manifest = read_json(store, &event.results)?;
    let files = manifest["ResultFiles"]["SUCCEEDED"]
        .as_array()
        .ok_or_else(|| malformed(&event.results, "no ResultFiles.SUCCEEDED array"))?;
    let mut lost = Vec::new();
    for file in files {
        let key = file["Key"]
            .as_str()
            .ok_or_else(|| malformed(&event.results, "a result file without a Key"))?;
        let folder = event.results.trim_end_matches("manifest.json");
        if !key.starts_with(folder) || key[folder.len()..].contains('/') {
            return Err(malformed(
                &event.results,
                &format!("result file {key:?} is outside its Map Run's folder"),
            ));
        }
        let children = read_json(store, key)?;
        let children = children
            .as_array()
            .ok_or_else(|| malformed(key, "not a JSON array of child executions"))?;
        for (i, child) in children.iter().enumerate() {
            let output = child["Output"]
                .as_str()
                .ok_or_else(|| malformed(key, &format!("child {i} has no Output text")))?;
            let output: Value = serde_json::from_str(output)
                .map_err(|e| malformed(key, &format!("child {i}'s Output is not JSON: {e}")))?;
            if let Some(record) = output.get("lost") {
                let record: LostRecord = serde_json::from_value(record.clone())
                    .map_err(|e| malformed(key, &format!("child {i}'s lost item: {e}")))?;
                lost.push(record);
            }
        }
    }
    lost.sort_by_key(|r| (r.item.frame, r.item.task));
    lost.dedup_by_key(|r| (r.item.frame, r.item.task));
    let Some(first) = lost.first() else {
        return Ok(LostOutput {
            lost: 0,
            rounds: event.round,
            items: None,
            first: None,
        });
    };
    let first = LostItem {
        task: first.item.task,
        error: first.error.clone(),
        cause: first.cause.clone(),
    };
    let items: Vec<TaskItem> = lost.iter().map(|r| r.item).collect();
    let bytes = serde_json::to_vec(&items)
        .map_err(|e| HandlerError::bad_input(format!("cannot encode lost items: {e}")))?;
    store.put(&items_key, &bytes)?;
    Ok(LostOutput {
        lost: items.len(),
        rounds: event.round,
        items: Some(items_key),
        first: Some(first),
    })
}

fn read_json(store: &dyn BlobStore, key: &str) -> Result<Value, HandlerError> {
    let bytes = store.get(key)?;
    serde_json::from_slice(&bytes).map_err(|e| malformed(key, &format!("not JSON: {e}")))
}

fn malformed(key: &str, what: &str) -> HandlerError {
    HandlerError::bad_input(format!("Map Run results {key}: {what}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use hort_core::store::MemoryStore;
    use serde_json::json;

    const MANIFEST: &str = "jobs/j1/map-results/CastMap-4/manifest.json";
    const RESULTS: &str = "jobs/j1/map-results/CastMap-4/SUCCEEDED_0.json";

    fn event(results: &str, round: u32) -> LostEvent {
        serde_json::from_value(json!({
            "job": "j1", "bucket": "b", "step": "lost", "stage": "cast-map",
            "results": results, "round": round
        }))
        .unwrap()
    }

    /// A Map Run's results as a ResultWriter stores them: children answering `outputs`.
    fn store_results(store: &MemoryStore, outputs: &[Value]) {
        let children: Vec<Value> = outputs
            .iter()
            .map(|o| json!({"Status": "SUCCEEDED", "Input": "{}", "Output": o.to_string()}))
            .collect();
        store
            .put(RESULTS, json!(children).to_string().as_bytes())
            .unwrap();
        let manifest = json!({"ResultFiles": {"FAILED": [], "PENDING": [],
            "SUCCEEDED": [{"Key": RESULTS, "Size": 1}]}});
        store
            .put(MANIFEST, manifest.to_string().as_bytes())
            .unwrap();
    }

    fn lost(task: u32, error: &str) -> Value {
        json!({"lost": {"item": {"task": task, "timeout_seconds": 9}, "error": error,
            "cause": format!("cause {task}")}})
    }

    #[test]
    fn lost_items_go_to_an_items_file_in_task_order_and_the_first_names_the_error() {
        let store = MemoryStore::new();
        store_results(
            &store,
            &[
                json!({}),
                lost(7, "States.Timeout"),
                json!({}),
                lost(3, "Hort.Retryable"),
            ],
        );
        let out = handle_lost(&store, "b", &event(MANIFEST, 2)).unwrap();
        let key = "jobs/j1/map-results/CastMap-4/lost.json";
        assert_eq!(
            serde_json::to_value(&out).unwrap(),
            json!({"lost": 2, "rounds": 2, "items": key,
                "first": {"task": 3, "error": "Hort.Retryable", "cause": "cause 3"}})
        );
        assert_eq!(
            store.get(key).unwrap(),
            br#"[{"task":3,"timeout_seconds":9},{"task":7,"timeout_seconds":9}]"#
        );
    }

    #[test]
    fn nothing_lost_writes_nothing() {
        let store = MemoryStore::new();
        store_results(&store, &[json!({}), json!({})]);
        let out = handle_lost(&store, "b", &event(MANIFEST, 0)).unwrap();
        assert_eq!(
            serde_json::to_value(&out).unwrap(),
            json!({"lost": 0, "rounds": 0, "items": null, "first": null})
        );
        assert!(
            store
                .get("jobs/j1/map-results/CastMap-4/lost.json")
                .is_err()
        );
    }

    #[test]
    fn results_of_another_job_or_malformed_are_refused_naming_them() {
        let store = MemoryStore::new();
        let other = "jobs/j2/map-results/CastMap-4/manifest.json";
        let e = handle_lost(&store, "b", &event(other, 0)).unwrap_err();
        assert_eq!(
            e.cause,
            format!(
                "lost step of cast-map: results \"{other}\" is not a Map Run manifest of job j1"
            )
        );
        store.put(MANIFEST, b"{\"ResultFiles\": {}}").unwrap();
        let e = handle_lost(&store, "b", &event(MANIFEST, 0)).unwrap_err();
        assert_eq!(
            e.cause,
            format!("Map Run results {MANIFEST}: no ResultFiles.SUCCEEDED array")
        );
        store_results(&store, &[json!({"lost": {"item": {"task": "x"}}})]);
        let e = handle_lost(&store, "b", &event(MANIFEST, 0)).unwrap_err();
        assert!(
            e.cause
                .starts_with(&format!("Map Run results {RESULTS}: child 0's lost item: ")),
            "{}",
            e.cause
        );
        let e = handle_lost(&store, "elsewhere", &event(MANIFEST, 0)).unwrap_err();
        assert!(e.cause.contains("bucket"), "{}", e.cause);
    }
}
