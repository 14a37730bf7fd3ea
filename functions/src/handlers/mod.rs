//! The function handlers as plain functions over an injected [`BlobStore`]: the orchestrator's
//! Plan task (`plan`) and the Worker task that runs any stage task (`worker`). The Lambda
//! binaries and the local emulator call exactly these.
//!
//! Error contract with the state machine (`infra/statemachine.asl.json`): a handler fails with
//! error type `Hort.Retryable` (storage trouble, a lost or corrupt block that could not be
//! recomputed: retried with backoff) or `Hort.BadInput` (a bad scene or request: never retried).

mod events;
mod plan;
mod worker;

pub use events::{JobRequest, PlanEvent, PlanOutput, StageItems, TaskItem, WorkerEvent};
pub use plan::{handle_plan, scene_prefix, task_timeout_seconds};
pub use worker::handle_worker;

use hort_core::pipeline::PipelineError;
use hort_core::store::StoreError;

/// Error type of retryable failures.
pub const RETRYABLE: &str = "Hort.Retryable";
/// Error type of failures no retry can fix.
pub const BAD_INPUT: &str = "Hort.BadInput";

/// A handler failure: its error type (one of [`RETRYABLE`], [`BAD_INPUT`]) and a one-line cause.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{error_type}: {cause}")]
pub struct HandlerError {
    pub error_type: &'static str,
    pub cause: String,
}

impl HandlerError {
    /// A failure that a retry may fix.
    pub fn retryable(cause: impl Into<String>) -> Self {
        HandlerError {
            error_type: RETRYABLE,
            cause: cause.into(),
        }
    }

    /// A failure that no retry fixes.
    pub fn bad_input(cause: impl Into<String>) -> Self {
        HandlerError {
            error_type: BAD_INPUT,
            cause: cause.into(),
        }
    }
}

impl From<PipelineError> for HandlerError {
    fn from(e: PipelineError) -> Self {
        if e.is_retryable() {
            HandlerError::retryable(e.to_string())
        } else {
            HandlerError::bad_input(e.to_string())
        }
    }
}

impl From<StoreError> for HandlerError {
    fn from(e: StoreError) -> Self {
        PipelineError::Store(e).into()
    }
}

#[cfg(test)]
mod tests;
