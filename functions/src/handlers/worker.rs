//! The Worker function: run one task of one stage (the plan names its inputs and outputs).

use super::events::WorkerEvent;
use super::{HandlerError, check_bucket};
use hort_core::keys::plan_key;
use hort_core::pipeline::{JobPlan, SplitCache, TaskMetrics, run_task_cached};
use hort_core::store::BlobStore;

/// Runs `event.stage` task `event.item.task` of `event.job`; `cache` is the worker's decoded
/// splits (a warm container's memory). Returns what the task did. The outputs are the same bytes
/// on every attempt.
pub fn handle_worker(
    store: &dyn BlobStore,
    bucket: &str,
    cache: &SplitCache,
    event: &WorkerEvent,
) -> Result<TaskMetrics, HandlerError> {
    check_bucket(&event.bucket, bucket)?;
    let key = plan_key(&event.job);
    let plan = JobPlan::from_json(&key, &store.get(&key)?)?;
    Ok(run_task_cached(
        store,
        &event.job,
        &plan,
        event.stage,
        event.item.task.0,
        cache,
    )?)
}
