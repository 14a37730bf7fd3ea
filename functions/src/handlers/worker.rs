//! The Worker task: run one task of one stage (the plan names its inputs and outputs).

use super::HandlerError;
use super::events::WorkerEvent;
use hort_core::ids::{JobId, Stage};
use hort_core::keys::plan_key;
use hort_core::pipeline::{JobPlan, SplitCache, TaskMetrics, run_task_cached};
use hort_core::store::BlobStore;

/// Runs `event.stage` task `event.item.task` of `event.job`; `cache` is the worker's decoded
/// splits (a warm container's memory). Returns what the task did.
pub fn handle_worker(
    store: &dyn BlobStore,
    bucket: &str,
    cache: &SplitCache,
    event: &WorkerEvent,
) -> Result<TaskMetrics, HandlerError> {
    let job = JobId::new(event.job.clone()).map_err(|e| HandlerError::bad_input(e.to_string()))?;
    if event.bucket != bucket {
        return Err(HandlerError::bad_input(format!(
            "the event names bucket \"{}\", this function serves \"{bucket}\"",
            event.bucket
        )));
    }
    let stage: Stage = event
        .stage
        .parse()
        .map_err(|e: hort_core::ids::IdError| HandlerError::bad_input(e.to_string()))?;
    let key = plan_key(&job);
    let plan = JobPlan::from_json(&key, &store.get(&key)?)?;
    Ok(run_task_cached(
        store,
        &job,
        &plan,
        stage,
        event.item.task,
        cache,
    )?)
}
