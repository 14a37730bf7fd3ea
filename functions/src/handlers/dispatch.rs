//! One invocation from JSON to JSON: decode the event, run the handler, encode the answer, and
//! classify any failure. The local emulator calls [`dispatch`] for every invocation; a Lambda
//! entry point would do the same.

use super::Tmp;

use hort_core::ids::TaskId;
use hort_core::pipeline::{SplitCache, TaskMetrics};
use hort_core::stage::Stage;
use hort_core::stage::{PLAN_FUNCTION, WORKER_FUNCTION};
use serde_json::Value;

use super::events::{PlanEvent, PlanStep, WorkerEvent};
use super::lost::{LostEvent, handle_lost, is_lost_event};
use super::plan::{check_plan_memory, check_worker_memory};
use super::{BlobStore, HandlerError, handle_plan_measured, handle_worker};

/// The functions of a deployment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Function {
    /// Splits and plans a job ([`handle_plan`](super::handle_plan)).
    Plan,
    /// Runs one task of any stage after the plan ([`handle_worker`]).
    Worker,
}

impl Function {
    /// The function the state machine names `name` (`PlanFunctionArn`, `WorkerFunctionArn`).
    pub fn from_state_machine_name(name: &str) -> Option<Function> {
        match name {
            PLAN_FUNCTION => Some(Function::Plan),
            WORKER_FUNCTION => Some(Function::Worker),
            _ => None,
        }
    }
}

/// What an invocation may use besides its event: a warm container's state.
pub struct FunctionEnv<'a> {
    /// The bucket's objects.
    pub store: &'a dyn BlobStore,
    /// The bucket the function serves; events naming another are refused.
    pub bucket: &'a str,
    /// Scratch space (a function's `/tmp`) and its size: the Plan function copies the scene
    /// here, and so does a Worker rebuilding a lost split object from the scene.
    pub tmp: Tmp<'a>,
    /// Decoded splits kept between invocations of this container.
    pub split_cache: &'a SplitCache,
    /// The deployed Worker function's memory, MB, where known: the Plan function refuses a job
    /// request planned for more, and so does the Worker (knowing its own memory) a task of a
    /// plan for more, before any work (its tasks would run out of memory, be retried, lost and
    /// rerun before the job failed). `None` checks nothing.
    pub worker_memory_mb: Option<u32>,
}

/// A successful invocation.
#[derive(Debug, Clone, PartialEq)]
pub struct Invoked {
    /// The function's JSON answer (the `Payload` the state machine sees).
    pub output: Value,
    /// Which task ran and what it did: a Worker's task, or the Plan function's first round as
    /// task 0 of stage `plan` (its time breakdown only; see [`handle_plan_measured`]); `None`
    /// for the Plan function's second round.
    pub task: Option<TaskDone>,
}

impl Invoked {
    /// Records the task's measured memory high-water mark, `bytes`, in its metrics and in the
    /// JSON answer (`peak_memory_bytes`); nothing for an invocation that ran no Worker task (the
    /// Plan function's answer is the plan output, read by the state machine, and stays as it is).
    pub fn set_peak_memory(&mut self, bytes: u64) {
        if let Some(done) = self.task.as_mut().filter(|d| d.stage != Stage::Plan) {
            done.metrics.peak_memory_bytes = bytes;
            if let Some(answer) = self.output.as_object_mut() {
                answer.insert("peak_memory_bytes".into(), bytes.into());
            }
        }
    }
}

/// A task a Worker invocation completed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TaskDone {
    /// The task's stage.
    pub stage: Stage,
    /// The task's frame, in a job of several frames.
    pub frame: Option<u32>,
    /// The task's index within its stage (and frame).
    pub task: TaskId,
    /// What the task read, wrote and computed.
    pub metrics: TaskMetrics,
}

/// Runs `function` on the JSON `event`. A malformed event is [`HandlerError::bad_input`] naming
/// the function and the field; handler failures keep their own classification.
pub fn dispatch(
    function: Function,
    event: Value,
    env: &FunctionEnv<'_>,
) -> Result<Invoked, HandlerError> {
    let malformed = |what: &str, e: serde_json::Error| {
        HandlerError::bad_input(format!("malformed {what} event: {e}"))
    };
    let encode = |e: serde_json::Error| HandlerError::bad_input(format!("cannot encode: {e}"));
    match function {
        Function::Plan if is_lost_event(&event) => {
            let event: LostEvent =
                serde_json::from_value(event).map_err(|e| malformed("Plan (lost step)", e))?;
            let out = handle_lost(env.store, env.bucket, &event)?;
            Ok(Invoked {
                output: serde_json::to_value(out).map_err(encode)?,
                task: None,
            })
        }
        Function::Plan => {
            let event: PlanEvent =
                serde_json::from_value(event).map_err(|e| malformed("Plan", e))?;
            if let Some(worker_mb) = env.worker_memory_mb
                && event.round == 1
                && event.step == PlanStep::Start
            {
                check_worker_memory(env.store, &event.job, worker_mb)?;
            }
            let (out, metrics) = handle_plan_measured(env.store, env.bucket, &event, env.tmp)?;
            Ok(Invoked {
                output: serde_json::to_value(out).map_err(encode)?,
                // Round 2 (the `Refine` state) is no task of the plan stage.
                task: (event.round == 1).then_some(TaskDone {
                    stage: Stage::Plan,
                    frame: None,
                    task: TaskId(0),
                    metrics,
                }),
            })
        }
        Function::Worker => {
            let event: WorkerEvent =
                serde_json::from_value(event).map_err(|e| malformed("Worker", e))?;
            if let Some(own_mb) = env.worker_memory_mb {
                check_plan_memory(env.store, env.split_cache, &event, own_mb)?;
            }
            let metrics = handle_worker(env.store, env.bucket, env.split_cache, &event, env.tmp)?;
            Ok(Invoked {
                output: serde_json::to_value(metrics).map_err(encode)?,
                task: Some(TaskDone {
                    stage: event.stage,
                    frame: event.item.frame,
                    task: event.item.task,
                    metrics,
                }),
            })
        }
    }
}
