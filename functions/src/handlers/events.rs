//! The JSON the state machine passes to the handlers and gets back, and the job request the
//! client stores before starting an execution. Ids are typed: a malformed job id, stage name or
//! task number fails decoding, naming the field.

use std::collections::BTreeMap;

use hort_core::ids::{JobId, TaskId};
use hort_core::pipeline::{ExecutionMode, PlanRequest};
use hort_core::stage::Stage;
use serde::{Deserialize, Serialize};

/// What the client stores at `jobs/{job}/manifest.json` (created once, with `put_if_absent`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JobRequest {
    /// The scene's main file (OBJ or manifest), relative to `jobs/{job}/scene/`; the files it
    /// names are stored beside it under the same prefix.
    pub scene: String,
    /// Image size, samples, splits, spans and split mode, as for `hort render`.
    pub render: PlanRequest,
    /// Map iterations at once (0: no limit beyond the account's concurrency).
    pub max_concurrency: u32,
    /// Per-task timeout override in seconds; by default derived from each task's work.
    pub task_timeout_seconds: Option<u32>,
    /// What the client stored under `jobs/{job}/scene/`: the scene files (`files`, the
    /// default, which is also what a request without this field means, and which is then not
    /// written) or the parsed scene at `jobs/{job}/scene/scene.bin` (`binary`).
    #[serde(default, skip_serializing_if = "SceneFormat::is_files")]
    pub scene_format: SceneFormat,
    /// Split the scene by tasks (`hort_core::pipeline::partition`) in byte ranges of this size,
    /// whatever its size; by default a scene of the `files` format is split by tasks when a
    /// whole-scene load would not fit the function's memory.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene_range_bytes: Option<u64>,
    /// A scene given by key in the bucket (`scenes/box/cornell.json`), which the HTTP API does
    /// not load: the Plan function copies it and the files it names into `jobs/{job}/scene/`
    /// (see `handlers/stage_in.rs`) before anything else, and `scene` is its file name there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene_key: Option<String>,
    /// The budget to check again on the exact plan: set when the job was accepted on a plan
    /// estimated from the scene's sizes (a scene given by key), so the Plan function refuses a
    /// job whose loaded scene costs more than its `max_cost_usd` before any Map runs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub budget: Option<BudgetCheck>,
}

/// The budget a job was accepted under, and the model its cost was predicted with.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BudgetCheck {
    /// The request's `max_cost_usd`.
    pub max_cost_usd: f64,
    /// What the API predicted the cost with (the deployment's concurrency, memory, rates).
    pub model: hort_core::predict::PredictionModel,
}

/// How a job's scene is stored (the job request's `scene_format`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SceneFormat {
    /// The original files (OBJ, MTL, manifest) under `jobs/{job}/scene/`, parsed by the Plan
    /// function: what the HTTP API stores, having only validated them.
    #[default]
    Files,
    /// One object, `jobs/{job}/scene/scene.bin`, holding the scene the client parsed already
    /// (`hort_core::scene::encode_scene`): decoded, never parsed again.
    Binary,
}

impl SceneFormat {
    /// True for [`SceneFormat::Files`] (the default, left out of the JSON).
    pub fn is_files(&self) -> bool {
        *self == SceneFormat::Files
    }
}

/// Input of the Plan function.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanEvent {
    /// The job to plan.
    pub job: JobId,
    /// The bucket holding the job (must be the one the function serves).
    pub bucket: String,
    /// Retry count of this attempt (`$$.State.RetryCount`), 0 for the first.
    #[serde(default)]
    pub attempt: u32,
    /// Which round to plan: 1 (the default) splits the scene and plans the job; 2 plans a
    /// staged adaptive job's second round from its first round's refine lists (the state
    /// machine's `Refine` state), without loading the scene.
    #[serde(default = "first_round")]
    pub round: u32,
    /// For a scene split by tasks, the Plan function's step: `start` (the default) scans the
    /// scene (or, for a scene loaded whole, plans the job), `cut` cuts the partitioned scene
    /// into splits after the Partition Map, `finish` plans the job after the Build Map.
    #[serde(default, skip_serializing_if = "PlanStep::is_start")]
    pub step: PlanStep,
}

/// The Plan function's step (see [`PlanEvent::step`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PlanStep {
    /// Load or scan the scene; plan, or hand out the partition tasks.
    #[default]
    Start,
    /// Cut the partitioned scene into splits; hand out the build tasks.
    Cut,
    /// Plan the job from the built splits.
    Finish,
}

impl PlanStep {
    /// True for [`PlanStep::Start`] (the default, left out of the JSON).
    pub fn is_start(&self) -> bool {
        *self == PlanStep::Start
    }
}

fn first_round() -> u32 {
    1
}

/// One Map item: a task of a stage and its timeout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TaskItem {
    /// The task's index within its stage (within its frame's tasks, in a job of several
    /// frames).
    pub task: TaskId,
    /// The task's frame, in a job of several frames ([`hort_core::pipeline::JobPlan::frames`]);
    /// absent for a job of one frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame: Option<u32>,
    /// The task's timeout (the Map's `TimeoutSecondsPath`); `None` leaves the state's default.
    #[serde(default)]
    pub timeout_seconds: Option<u32>,
}

/// Input of the Worker function.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorkerEvent {
    /// The job the task belongs to.
    pub job: JobId,
    /// The bucket holding the job (must be the one the function serves).
    pub bucket: String,
    /// The task's stage (never [`Stage::Plan`], which the Plan function runs).
    pub stage: Stage,
    /// Which task, and its timeout.
    pub item: TaskItem,
    /// Retry count of this attempt (`$$.State.RetryCount`), 0 for the first.
    #[serde(default)]
    pub attempt: u32,
}

/// Output of the Plan function: the job's mode (the state machine's Choice after Plan follows
/// it), where each Map state of that mode reads its items, and its concurrency.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PlanOutput {
    /// `fused` (Render, then Combine) or `staged` (CastMap to TraceReduce, then Combine).
    pub mode: ExecutionMode,
    /// Items file key per Map stage, by [`Stage::items_field`] (`$.plan.items.cast_map`, ...).
    pub items: BTreeMap<String, String>,
    /// Map iterations at once (0: no limit beyond the account's concurrency).
    pub max_concurrency: u32,
    /// Whether the job traces shadow rays (its scene has a light some surface can occlude). A
    /// staged job without them skips Expand and TraceMap (`ChooseShadows` in the state
    /// machine).
    pub shadows: bool,
    /// Whether a second round may follow this one: true for round 1 of a staged adaptive job,
    /// whose TraceReduce is followed by the `Refine` state (the Plan function with round 2).
    pub refine_after: bool,
    /// Where the Map states' `ResultWriter`s store each Map Run's results
    /// ([`hort_core::keys::map_results_prefix`]), read by the Plan function's `lost` step.
    pub results: String,
}

impl PlanOutput {
    /// The stages whose tasks the Worker function runs, in order, as the state machine walks
    /// them for this output's mode and `shadows`.
    pub fn task_stages(&self) -> &'static [Stage] {
        &self.mode.stages_with(self.shadows)[1..]
    }

    /// The items file key of `stage`, if it is a Map stage this output names.
    pub fn items_key(&self, stage: Stage) -> Option<&str> {
        self.items.get(stage.items_field()?).map(String::as_str)
    }
}
