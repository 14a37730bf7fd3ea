//! The JSON the state machine passes to the handlers and gets back, and the job request the
//! client stores before starting an execution.

use hort_core::pipeline::SplitMode;
use serde::{Deserialize, Serialize};

/// What the client stores at `jobs/{job}/manifest.json` (created once, with `put_if_absent`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JobRequest {
    /// The scene's main file (OBJ or manifest), relative to `jobs/{job}/scene/`; the files it
    /// names are stored beside it under the same prefix.
    pub scene: String,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub splits: Option<u32>,
    pub spans: Option<u32>,
    pub split_mode: SplitMode,
    /// Map iterations at once (0: no limit beyond the account's concurrency).
    pub max_concurrency: u32,
    /// Per-task timeout override in seconds; by default derived from each task's work.
    pub task_timeout_seconds: Option<u32>,
}

/// Input of the Plan task.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PlanEvent {
    pub job: String,
    pub bucket: String,
    #[serde(default)]
    pub attempt: u32,
}

/// One Map item: a task of a stage and its timeout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TaskItem {
    pub task: u32,
    #[serde(default)]
    pub timeout_seconds: Option<u32>,
}

/// Input of the Worker task.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct WorkerEvent {
    pub job: String,
    pub bucket: String,
    /// Stage name, e.g. `cast-map`.
    pub stage: String,
    pub item: TaskItem,
    #[serde(default)]
    pub attempt: u32,
}

/// The keys of each Map state's items file.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct StageItems {
    pub cast_map: String,
    pub cast_reduce: String,
    pub expand: String,
    pub trace_map: String,
    pub trace_reduce: String,
}

/// Output of the Plan task.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PlanOutput {
    pub items: StageItems,
    pub max_concurrency: u32,
}
