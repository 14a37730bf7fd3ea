//! The function handlers as plain functions over an injected [`BlobStore`]: the Plan function
//! ([`handle_plan`]) and the Worker function that runs any task of the other stages
//! ([`handle_worker`]). [`dispatch`] decodes a JSON event, runs the handler and maps its error to
//! the state machine's error type; the local emulator calls it for every invocation.
//!
//! Error contract with the state machine (`infra/statemachine.asl.json`): a handler fails with
//! [`ErrorType::Retryable`] (`Hort.Retryable`: storage trouble, a corrupt object; retried with
//! backoff) or [`ErrorType::BadInput`] (`Hort.BadInput`: a bad scene, request or event, a missing
//! object; never retried). Missing or corrupt shuffle blocks, split objects and plans never reach the
//! state machine: the consuming task recomputes them from lineage (their producer task, or the
//! job's scene) first.

mod budget;
mod dispatch;
mod events;
mod lost;
mod plan;
mod plan_parts;
mod stage_in;
mod tmp;
mod worker;

pub use dispatch::{Function, FunctionEnv, Invoked, TaskDone, dispatch};
pub use events::{
    BudgetCheck, JobRequest, PlanEvent, PlanOutput, PlanStep, SceneFormat, TaskItem, WorkerEvent,
};
pub use lost::{LostEvent, LostItem, LostOutput, handle_lost};
pub use plan::{handle_plan, handle_plan_measured, scene_prefix};
pub use stage_in::MAX_MANIFEST_BYTES;
pub use tmp::Tmp;
pub use worker::handle_worker;

pub use hort_core::ErrorType;
use hort_core::pipeline::PipelineError;
use hort_core::store::{BlobStore, StoreError};

/// A handler failure: its error type and a one-line cause. `Display` is `{type}: {cause}`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{error_type}: {cause}")]
pub struct HandlerError {
    /// What the state machine does with it: retry or give up.
    pub error_type: ErrorType,
    /// What went wrong, naming the object, field or file.
    pub cause: String,
}

impl HandlerError {
    /// A failure that a retry may fix.
    pub fn retryable(cause: impl Into<String>) -> Self {
        HandlerError {
            error_type: ErrorType::Retryable,
            cause: cause.into(),
        }
    }

    /// A failure that no retry fixes.
    pub fn bad_input(cause: impl Into<String>) -> Self {
        HandlerError {
            error_type: ErrorType::BadInput,
            cause: cause.into(),
        }
    }
}

impl From<PipelineError> for HandlerError {
    fn from(e: PipelineError) -> Self {
        HandlerError {
            error_type: e.error_type(),
            cause: e.to_string(),
        }
    }
}

impl From<StoreError> for HandlerError {
    fn from(e: StoreError) -> Self {
        PipelineError::Store(e).into()
    }
}

/// Refuses an event meant for another bucket than the one the function serves.
fn check_bucket(event_bucket: &str, bucket: &str) -> Result<(), HandlerError> {
    if event_bucket == bucket {
        Ok(())
    } else {
        Err(HandlerError::bad_input(format!(
            "the event names bucket \"{event_bucket}\", this function serves \"{bucket}\""
        )))
    }
}

#[cfg(test)]
mod tests;
