//! An interpreter of Amazon States Language: runs a state machine definition (for HORT,
//! `infra/statemachine.asl.json`, the same file AWS Step Functions runs) against in-process
//! functions ([`TaskInvoker`]) and an [`ItemReader`] standing in for S3. It knows nothing of ray
//! tracing: the definition, the functions and the bucket are the caller's.
//!
//! # Why our own interpreter, not the `asl` crate
//! crates.io `asl` 0.2.0 was evaluated first. It parses Task, Pass, Wait,
//! Choice, Succeed and Fail, but its executor treats Map (and Parallel) as a no-op, has no Retry
//! (retriers parse but nothing retries, so no BackoffRate/MaxDelaySeconds/JitterStrategy), no
//! TimeoutSeconds, and intrinsic functions return a placeholder string; its Map model
//! (`deny_unknown_fields`) rejects `ItemReader`. Everything the HORT definition needs —
//! Distributed Map over S3 items, retries with backoff and jitter, per-task timeouts, the
//! `$$` context — would have to be written anyway, and wrapping it would add its dependencies
//! (pest, chrono, jsonpath-rust, thiserror 1) for a parser we would bypass. So this module is a
//! small interpreter of exactly the subset HORT uses; anything else is refused at load time
//! with the state and field named (see [`definition`]).
//!
//! # Semantics (what the cloud does, and nothing it would not)
//! `run.rs` documents the state-by-state rules; in short: `Retry` per first matching retrier with
//! counts per retrier, delay `IntervalSeconds * BackoffRate^n` capped at `MaxDelaySeconds`, FULL
//! jitter uniform in `[0, delay)` (deterministic from [`OrchestratorOptions::seed`]); `Catch`
//! after retries; Task `TimeoutSeconds` fails the attempt with `States.Timeout` while the
//! invocation runs on as a zombie holding its slot; a failed Map item fails the Map with
//! `States.ExceedToleratedFailureThreshold`; a state input or output, a Task's payload or
//! result, or a Map's inline results over 256 KiB fail the execution with
//! `States.DataLimitExceeded`, which no Catch catches (`hort_aws_quotas`).
//!
//! # Error contract of the functions
//! A function signals failure with a [`TaskFailure`] whose `error` is the error name Step
//! Functions sees (the Lambda `errorType`); `Retry` and `Catch` match on it exactly as in the
//! cloud. Which names a definition retries is the definition's business (HORT's are
//! `Hort.Retryable` and `Hort.BadInput`, see `hort_core::ErrorType`).
//!
//! # Time
//! Retry backoff, Task timeouts and the EXPRESS limit are waited on a [`Clock`]: real time by
//! default ([`RealClock`]), scaled by [`OrchestratorOptions::time_scale`]. Tests can run an
//! execution on virtual time instead ([`ManualClock`], through [`Orchestrator::with_clock`]),
//! so that whether an attempt times out depends on what the test does, not on how fast the
//! machine is (see [`clock`]).

#![warn(missing_docs)]

pub mod clock;
pub mod definition;
pub mod events;
pub mod functions;
pub mod intrinsic;
pub mod paths;
pub mod retry;
mod run;
mod slots;

#[cfg(test)]
mod tests;

use std::collections::BTreeSet;
use std::fmt;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use serde_json::{Value, json};

pub use clock::{Clock, ManualClock, RealClock};
pub use definition::{DefinitionError, State, StateMachine};
pub use events::{Event, EventLog, NoObserver, Observer};
pub use functions::{FunctionLimit, FunctionLimits};
pub use retry::{Jitter, Retrier, backoff_seconds, retry_delay};
pub use run::{
    CANCELLED, EXCEED_TOLERATED_FAILURE, ITEM_READER_FAILED, NO_CHOICE_MATCHED, PANIC,
    RESULT_WRITER_FAILED,
};

/// The error of an attempt that ran past its `TimeoutSeconds`.
pub const TIMEOUT: &str = retry::TIMEOUT;
/// The error of a path or data error inside the interpreter (never retried or caught).
pub const RUNTIME: &str = retry::RUNTIME;
/// The error of a state input or output, Task payload or result, or inline Map result over
/// Step Functions' 256 KiB (never retried or caught).
pub const DATA_LIMIT_EXCEEDED: &str = retry::DATA_LIMIT_EXCEEDED;

/// The execution's bucket as Distributed Maps use it: the stand-in for S3 `GetObject` of an
/// `ItemReader` and `PutObject` of a `ResultWriter`.
pub trait Bucket: Sync {
    /// The bytes of object `key` of the execution's bucket, or a one-line reason it cannot be
    /// read (shown in the `States.ItemReaderFailed` cause).
    fn read_object(&self, key: &str) -> Result<Vec<u8>, String>;

    /// Stores `bytes` at `key` of the execution's bucket (replacing any object there), or a
    /// one-line reason it cannot (shown in the `States.ResultWriterFailed` cause).
    fn write_object(&self, key: &str, bytes: Vec<u8>) -> Result<(), String>;
}

/// Runs functions for the emulator: the in-process stand-in for Lambda.
pub trait TaskInvoker: Send + Sync {
    /// Runs one task attempt synchronously. `resource` is the function placeholder name (e.g.
    /// `"WorkerFunctionArn"` for `${WorkerFunctionArn}`); `input` is exactly the Lambda event
    /// (the Task's `Parameters.Payload`). The returned value becomes the `Payload` of the
    /// `lambda:invoke` result.
    fn invoke(&self, resource: &str, input: Value) -> Result<Value, TaskFailure>;
}

/// A failed task attempt: the Lambda error type and message as Step Functions sees them.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{error}: {cause}")]
pub struct TaskFailure {
    /// The error name matched by `Retry`/`Catch` (e.g. `Hort.Retryable`).
    pub error: String,
    /// A human-readable cause.
    pub cause: String,
}

impl TaskFailure {
    /// A failure with the given error name.
    pub fn new(error: impl Into<String>, cause: impl Into<String>) -> Self {
        Self {
            error: error.into(),
            cause: cause.into(),
        }
    }
}

/// How the emulator runs an execution.
#[derive(Debug, Clone)]
pub struct OrchestratorOptions {
    /// Invocations running at once at most, over the whole execution (like Lambda's
    /// concurrency limit); at least 1. A Map runs min(MaxConcurrency, slots) items at once.
    pub slots: usize,
    /// Multiplies every wait and timeout (retry delays, `TimeoutSeconds`, the 5-minute EXPRESS
    /// limit) before it is waited on the execution's [`Clock`]; 1.0 is real time, tests use
    /// e.g. 0.001. Finite and positive.
    pub time_scale: f64,
    /// Seed of the FULL jitter draws; the same seed gives the same delays.
    pub seed: u64,
    /// Set to stop: no new attempt starts and [`Orchestrator::run`] returns
    /// [`CANCELLED`] within milliseconds (invocations in flight run on and are ignored).
    pub cancel: Arc<AtomicBool>,
    /// Each function's reserved concurrency and timeout, as its deployment sets them (see
    /// [`functions`]); clones share the count of running invocations, so executions given
    /// clones of one value are one account's jobs.
    pub functions: FunctionLimits,
}

impl Default for OrchestratorOptions {
    /// One slot per available core, real time, seed 0, not cancelled, no function limits.
    fn default() -> Self {
        Self {
            slots: std::thread::available_parallelism().map_or(1, |n| n.get()),
            time_scale: 1.0,
            seed: 0,
            cancel: Arc::new(AtomicBool::new(false)),
            functions: FunctionLimits::none(),
        }
    }
}

/// Why an execution did not succeed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExecutionFailure {
    /// The error name (of the Fail state, or of the uncaught error).
    pub error: String,
    /// The cause.
    pub cause: String,
    /// The state (path) where the error arose: for a job that failed through a Catch into a
    /// Fail state, the state that failed (e.g. `CastMap`), not the Fail state.
    pub state: String,
    /// For a failed Map, the item whose failure failed it.
    pub item: Option<Box<ItemFailure>>,
}

/// The Map item whose failure failed a Map Run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ItemFailure {
    /// The Map state's path.
    pub map_state: String,
    /// The item's index in the items file.
    pub index: usize,
    /// The state inside the ItemProcessor that failed (e.g. `CastMap/CastMapTask`).
    pub state: String,
    /// Its error name (e.g. `Hort.BadInput`).
    pub error: String,
    /// Its cause.
    pub cause: String,
}

impl fmt::Display for ExecutionFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} failed with {}: {}",
            self.state, self.error, self.cause
        )
    }
}

impl std::error::Error for ExecutionFailure {}

/// A loaded state machine, ready to run executions.
#[derive(Debug, Clone)]
pub struct Orchestrator {
    machine: StateMachine,
    options: OrchestratorOptions,
    clock: Arc<dyn Clock>,
}

impl Orchestrator {
    /// Loads and checks an ASL definition; unsupported or malformed parts are errors naming the
    /// state and field, and so are unusable options.
    pub fn new(definition: &str, options: OrchestratorOptions) -> Result<Self, DefinitionError> {
        if !(options.time_scale.is_finite() && options.time_scale > 0.0) {
            return Err(DefinitionError::Machine {
                within: None,
                message: format!(
                    "OrchestratorOptions.time_scale must be finite and positive, found {}",
                    options.time_scale
                ),
            });
        }
        let machine = definition::load(definition)?;
        Ok(Self {
            machine,
            options,
            clock: Arc::new(RealClock::new()),
        })
    }

    /// Runs executions on `clock` instead of real time: retry backoff is waited with
    /// [`Clock::sleep`], and Task timeouts and the EXPRESS limit are deadlines on
    /// [`Clock::now`] (all still scaled by [`OrchestratorOptions::time_scale`]). For tests,
    /// with a [`ManualClock`]; a clock shared by concurrent executions is shared time.
    pub fn with_clock(mut self, clock: Arc<dyn Clock>) -> Self {
        self.clock = clock;
        self
    }

    /// The checked definition.
    pub fn machine(&self) -> &StateMachine {
        &self.machine
    }

    /// The options executions run with.
    pub fn options(&self) -> &OrchestratorOptions {
        &self.options
    }

    /// Every function name the definition invokes (e.g. `PlanFunctionArn`,
    /// `WorkerFunctionArn`), so a caller can check it has a handler for each before running.
    pub fn functions(&self) -> BTreeSet<String> {
        fn collect(machine: &StateMachine, out: &mut BTreeSet<String>) {
            for state in machine.states.values() {
                match state {
                    State::Task(t) => {
                        out.insert(t.function.clone());
                    }
                    State::Map(m) => collect(&m.processor, out),
                    _ => {}
                }
            }
        }
        let mut out = BTreeSet::new();
        collect(&self.machine, &mut out);
        out
    }

    /// Runs one execution to its end and returns its output.
    ///
    /// `invoker` runs the functions (shared with invocation threads that may outlive a timed-out
    /// attempt, hence the `Arc`); `items` is the bucket named by the input's `"bucket"` field,
    /// the only bucket an `ItemReader` may read and a `ResultWriter` may write; `observer` sees
    /// progress from many threads.
    pub fn run(
        &self,
        input: Value,
        invoker: Arc<dyn TaskInvoker>,
        items: &dyn Bucket,
        observer: &dyn Observer,
    ) -> Result<Value, ExecutionFailure> {
        let name = input
            .get("job")
            .and_then(Value::as_str)
            .unwrap_or("local")
            .to_owned();
        let execution = run::Execution {
            options: &self.options,
            clock: &self.clock,
            invoker: &invoker,
            items,
            observer,
            slots: slots::Slots::new(self.options.slots),
            map_runs: std::sync::atomic::AtomicU64::new(0),
            context: json!({
                "Execution": {
                    "Id": format!("arn:aws:states:local:000000000000:execution:hort:{name}"),
                    "Name": name,
                    "Input": input.clone(),
                },
                "StateMachine": {
                    "Id": "arn:aws:states:local:000000000000:stateMachine:hort",
                    "Name": "hort",
                },
            }),
            bucket: input
                .get("bucket")
                .and_then(Value::as_str)
                .map(str::to_owned),
        };
        execution
            .run(&self.machine, input)
            .map_err(|stop| match stop {
                run::Stop::Failed(f) => ExecutionFailure {
                    error: f.error,
                    cause: f.cause,
                    state: f.state,
                    item: f.item,
                },
                run::Stop::Halted(state) => ExecutionFailure {
                    error: CANCELLED.into(),
                    cause: format!("the execution was cancelled while in {state}"),
                    state,
                    item: None,
                },
            })
    }
}
