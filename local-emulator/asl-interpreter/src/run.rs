//! Executing a checked [`StateMachine`] as Step Functions does.
//!
//! Per state: `InputPath` → (`Parameters` | `ItemReader` + `ItemSelector`) → work →
//! `ResultSelector` → `ResultPath` (into the raw input) → `OutputPath`. Work that fails goes
//! through `Retry` (first matching retrier, counts per retrier) and then `Catch` (the error
//! object `{"Error", "Cause"}` at the catcher's `ResultPath`). Path and data errors are
//! `States.Runtime`: never retried, never caught.
//!
//! A Task attempt runs its invocation on a thread of its own holding a function slot. If it
//! runs past `TimeoutSeconds`, the attempt fails with `States.Timeout` and the machine moves on;
//! the invocation keeps running and keeps its slot until it returns, and its result is dropped
//! (a zombie Lambda). The timeout clock starts when the invocation starts, not while it waits
//! for a slot (Lambda would throttle instead, with `Lambda.TooManyRequestsException`).
//!
//! Retry backoff, attempt timeouts and the EXPRESS limit are measured on the execution's
//! [`Clock`](crate::Clock), after scaling by `time_scale`; everything else (stop flags, free
//! slots, results) is polled every [`POLL`] of real time.
//!
//! A Distributed Map runs its items on min(MaxConcurrency, slots, items) threads, each running
//! one child execution at a time with `$$.Map.Item.{Index,Value}` available to `ItemSelector`.
//! The first failed child (after its own retries) stops the Map Run (no new children start,
//! children in flight stop at their next step), and the Map state fails with
//! `States.ExceedToleratedFailureThreshold` (the tolerated failure count is 0), whose cause names
//! the Map, the item and the child's error; the Map state's own Retry and Catch then apply.
//! EXPRESS children fail with `States.Timeout` after 5 minutes, as Express executions do.
//! A Map with `ItemsPath` runs the same way over an array of its effective input.
//!
//! With a `ResultWriter`, a Map's children's results go to the bucket as AWS writes them
//! (`{Prefix}/{map run}/manifest.json` naming `SUCCEEDED_0.json`, an array of
//! `{"ExecutionArn", "Name", "Input", "InputDetails", "Output", "OutputDetails", "Status",
//! "StateMachineArn"}` with `Input` and `Output` as JSON text), and the Map's result is
//! `{"MapRunArn", "ResultWriterDetails": {"Bucket", "Key"}}` with `Key` the manifest's. The
//! emulator names a Map Run `{state}-{n}` (n counts the execution's Map Runs) where AWS uses a
//! UUID, leaves out the start and stop dates (so the bytes do not depend on the clock), and
//! writes nothing for a Map Run that failed.
//!
//! Payloads are held to Step Functions' 256 KiB, counted as compact JSON text: the execution
//! input, each state's output, each Map child's input, each Task's payload and its function's
//! result, and a Map's results when they come back inline. Over it, the execution fails with
//! `States.DataLimitExceeded`, which neither Retry nor Catch matches.
//!
//! A Choice state goes to the `Next` of its first rule that holds, else to `Default`; with
//! neither, the execution fails with `States.NoChoiceMatched`. `IsPresent` holds when the
//! `Variable` selects something (true) or nothing (false); a `Numeric…` rule whose `Variable`
//! selects nothing or a non-number is `States.Runtime`, as in Step Functions.

mod invoke;
mod map_run;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use serde_json::{Value, json};

use super::definition::{
    ChoiceState, Comparison, FailState, Number, PassState, Selector, State, StateMachine,
    TaskState, Transition,
};
use super::events::{Event, Observer};
use super::retry::{self, Catcher, Decision, Retrier, RetryState};
use super::slots::Slots;
use super::{Clock, ItemFailure, OrchestratorOptions, TaskInvoker};

/// The error of a Map Run that failed because an item failed.
pub const EXCEED_TOLERATED_FAILURE: &str = "States.ExceedToleratedFailureThreshold";
/// The error of a Map whose items could not be read.
pub const ITEM_READER_FAILED: &str = "States.ItemReaderFailed";
/// The error of a Map whose results could not be written by its `ResultWriter`.
pub const RESULT_WRITER_FAILED: &str = "States.ResultWriterFailed";
/// The error of an execution stopped through the cancel flag.
pub const CANCELLED: &str = "States.Cancelled";
/// The error a panicking invocation reports: Step Functions reports unhandled Lambda errors
/// (crashes, out of memory, function timeouts) as `Lambda.Unknown`.
pub const PANIC: &str = "Lambda.Unknown";
/// The error of a Choice state none of whose rules held, without a `Default`.
pub const NO_CHOICE_MATCHED: &str = "States.NoChoiceMatched";
/// The longest an EXPRESS child execution may run, in seconds (before time scaling).
const EXPRESS_LIMIT_SECONDS: f64 = hort_aws_quotas::EXPRESS_EXECUTION_SECONDS as f64;
/// How often waits re-check the cancel flag and deadlines.
const POLL: Duration = Duration::from_millis(5);

/// A failure travelling up: the state it was raised in and, for a Map, the item behind it.
#[derive(Debug, Clone)]
pub struct Failure {
    /// The error name.
    pub error: String,
    /// The cause.
    pub cause: String,
    /// The state (path) that raised it.
    pub state: String,
    /// For a failed Map Run, the item whose failure failed it.
    pub item: Option<Box<ItemFailure>>,
}

/// Why a machine stopped without an output.
#[derive(Debug)]
pub enum Stop {
    /// It failed (uncaught, or at a Fail state).
    Failed(Failure),
    /// It was halted by the cancel flag or by its Map Run failing; the state it was in.
    Halted(String),
}

/// A chain of stop flags: the execution's cancel flag, then one per enclosing Map Run.
#[derive(Clone, Copy)]
struct Halt<'f> {
    flag: &'f AtomicBool,
    parent: Option<&'f Halt<'f>>,
}

impl Halt<'_> {
    fn is_set(&self) -> bool {
        self.flag.load(Ordering::SeqCst) || self.parent.is_some_and(|p| p.is_set())
    }
}

/// Where a machine runs: the top level, or one Map iteration.
#[derive(Clone, Copy)]
struct Frame<'f> {
    /// The enclosing Map state's path, for children.
    map: Option<&'f str>,
    item: Option<usize>,
    halt: Halt<'f>,
    /// The end of an EXPRESS child execution, on the execution's clock.
    deadline: Option<Duration>,
}

impl Frame<'_> {
    fn path(&self, name: &str) -> String {
        match self.map {
            Some(map) => format!("{map}/{name}"),
            None => name.to_owned(),
        }
    }

    fn expired(&self, clock: &dyn Clock) -> bool {
        self.deadline.is_some_and(|d| clock.now() >= d)
    }
}

/// What a state hands to the next one.
struct Step<'m> {
    output: Value,
    next: Option<&'m str>,
    caught: Option<Failure>,
}

/// One execution in progress.
pub struct Execution<'a> {
    /// The options it runs with.
    pub options: &'a OrchestratorOptions,
    /// What backoff, timeouts and the EXPRESS limit are measured on.
    pub clock: &'a Arc<dyn Clock>,
    /// Runs the functions.
    pub invoker: &'a Arc<dyn TaskInvoker>,
    /// Reads the Map states' items files and takes their written results.
    pub items: &'a dyn crate::Bucket,
    /// Sees the events.
    pub observer: &'a dyn Observer,
    /// The function slots shared by all its invocations.
    pub slots: Arc<Slots>,
    /// How many Map Runs the execution has started (names the runs' result folders).
    pub map_runs: AtomicU64,
    /// `{"Execution": …, "StateMachine": …}` of the context object.
    pub context: Value,
    /// The execution input's `bucket`, the only bucket ItemReader may read.
    pub bucket: Option<String>,
}

impl Execution<'_> {
    /// Runs the top-level machine.
    pub fn run(&self, machine: &StateMachine, input: Value) -> Result<Value, Stop> {
        let frame = Frame {
            map: None,
            item: None,
            halt: Halt {
                flag: &self.options.cancel,
                parent: None,
            },
            deadline: None,
        };
        within_limit(&input, "(execution input)", "the execution input").map_err(Stop::Failed)?;
        self.machine(machine, input, &frame)
    }

    fn scaled(&self, seconds: f64) -> Duration {
        Duration::try_from_secs_f64(seconds * self.options.time_scale).unwrap_or(Duration::MAX)
    }

    fn context(&self, state: &str, retry_count: u32, item: Option<(usize, &Value)>) -> Value {
        let mut ctx = self.context.clone();
        ctx["State"] = json!({"Name": state, "RetryCount": retry_count});
        if let Some((index, value)) = item {
            ctx["Map"] = json!({"Item": {"Index": index, "Value": value}});
        }
        ctx
    }

    fn emit(&self, e: Event) {
        self.observer.event(&e);
    }

    fn runtime(path: &str, message: String) -> Failure {
        Failure {
            error: retry::RUNTIME.into(),
            cause: format!("{path}: {message}"),
            state: path.to_owned(),
            item: None,
        }
    }

    /// Fails the frame if its EXPRESS deadline passed, halts it if a stop flag is set.
    fn check(&self, frame: &Frame, path: &str) -> Result<(), Stop> {
        if frame.halt.is_set() {
            return Err(Stop::Halted(path.to_owned()));
        }
        if frame.expired(self.clock.as_ref()) {
            return Err(Stop::Failed(Failure {
                error: retry::TIMEOUT.into(),
                cause: format!(
                    "{path}: the EXPRESS child execution of item {} ran longer than {} s",
                    frame.item.unwrap_or_default(),
                    EXPRESS_LIMIT_SECONDS
                ),
                state: path.to_owned(),
                item: None,
            }));
        }
        Ok(())
    }

    /// Waits `duration` on the clock, checking the stop flags and the EXPRESS deadline every
    /// [`POLL`] of it.
    fn sleep(&self, duration: Duration, frame: &Frame, path: &str) -> Result<(), Stop> {
        let end = self.clock.now().saturating_add(duration);
        loop {
            self.check(frame, path)?;
            let left = end.saturating_sub(self.clock.now());
            if left.is_zero() {
                return Ok(());
            }
            self.clock.sleep(left.min(POLL));
        }
    }

    fn machine(&self, machine: &StateMachine, input: Value, frame: &Frame) -> Result<Value, Stop> {
        let mut name = machine.start_at.as_str();
        let mut input = input;
        let mut caught: Option<Failure> = None;
        loop {
            let path = frame.path(name);
            self.check(frame, &path)?;
            let state = machine
                .states
                .get(name)
                .ok_or_else(|| Stop::Failed(Self::runtime(&path, "no such state".into())))?;
            self.emit(Event::StateEntered {
                state: path.clone(),
                item_index: frame.item,
            });
            let step = match state {
                State::Task(task) => self.task(task, &path, name, input, frame)?,
                State::Map(map) => self.map(map, &path, name, input, frame)?,
                State::Pass(pass) => self.pass(pass, &path, name, input)?,
                State::Choice(choice) => self.choice(choice, &path, name, input)?,
                State::Succeed(succeed) => {
                    let ctx = self.context(name, 0, None);
                    let run = select(&succeed.io.input_path, input, &ctx)
                        .and_then(|v| select(&succeed.io.output_path, v, &ctx));
                    return run.map_err(|e| Stop::Failed(Self::runtime(&path, e)));
                }
                State::Fail(fail) => return Err(self.fail(fail, &path, name, &input, caught)),
            };
            within_limit(&step.output, &path, "the state's output").map_err(Stop::Failed)?;
            if step.caught.is_some() {
                caught = step.caught;
            }
            match step.next {
                Some(next) => {
                    name = next;
                    input = step.output;
                }
                None => return Ok(step.output),
            }
        }
    }

    fn fail(
        &self,
        fail: &FailState,
        path: &str,
        name: &str,
        input: &Value,
        caught: Option<Failure>,
    ) -> Stop {
        let ctx = self.context(name, 0, None);
        let text = |t: &Option<super::paths::Template>| -> Result<String, String> {
            match t {
                None => Ok(String::new()),
                Some(t) => match t.eval(input, &ctx)? {
                    Value::String(s) => Ok(s),
                    Value::Null => Ok(String::new()),
                    other => Ok(other.to_string()),
                },
            }
        };
        match (text(&fail.error), text(&fail.cause)) {
            (Ok(error), Ok(cause)) => {
                let (state, item) = match caught {
                    Some(f) => (f.state, f.item),
                    None => (path.to_owned(), None),
                };
                Stop::Failed(Failure {
                    error,
                    cause,
                    state,
                    item,
                })
            }
            (Err(e), _) | (_, Err(e)) => Stop::Failed(Self::runtime(path, e)),
        }
    }

    fn pass<'m>(
        &self,
        pass: &'m PassState,
        path: &str,
        name: &str,
        raw: Value,
    ) -> Result<Step<'m>, Stop> {
        let ctx = self.context(name, 0, None);
        let run = || -> Result<Value, String> {
            let effective = select(&pass.io.input_path, raw.clone(), &ctx)?;
            let result = match (&pass.result, &pass.parameters) {
                (Some(result), _) => result.clone(),
                (None, Some(params)) => params.eval(&effective, &ctx)?,
                (None, None) => effective,
            };
            let out = pass.result_path.apply(raw.clone(), result)?;
            select(&pass.io.output_path, out, &ctx)
        };
        let output = run().map_err(|e| Stop::Failed(Self::runtime(path, e)))?;
        Ok(Step {
            output,
            next: next(&pass.transition),
            caught: None,
        })
    }

    fn choice<'m>(
        &self,
        choice: &'m ChoiceState,
        path: &str,
        name: &str,
        raw: Value,
    ) -> Result<Step<'m>, Stop> {
        let ctx = self.context(name, 0, None);
        let rt = |e: String| Stop::Failed(Self::runtime(path, e));
        let effective = select(&choice.io.input_path, raw, &ctx).map_err(rt)?;
        let mut target = None;
        for (i, rule) in choice.choices.iter().enumerate() {
            let value = rule.variable.select(&effective, &ctx);
            let holds = match rule.test {
                Comparison::IsPresent(present) => value.is_some() == present,
                Comparison::StringEquals(ref b) => {
                    let a = value.and_then(Value::as_str).ok_or_else(|| {
                        rt(format!(
                            "Choices[{i}]: the Variable {:?} must select a string, found {}",
                            rule.variable.text,
                            value.map_or("nothing".to_owned(), Value::to_string)
                        ))
                    })?;
                    a == b
                }
                Comparison::BooleanEquals(b) => {
                    let a = value.and_then(Value::as_bool).ok_or_else(|| {
                        rt(format!(
                            "Choices[{i}]: the Variable {:?} must select true or false, found {}",
                            rule.variable.text,
                            value.map_or("nothing".to_owned(), Value::to_string)
                        ))
                    })?;
                    a == b
                }
                Comparison::Numeric(op, b) => {
                    let a = value.and_then(Value::as_f64).ok_or_else(|| {
                        rt(format!(
                            "Choices[{i}]: the Variable {:?} must select a number, found {}",
                            rule.variable.text,
                            value.map_or("nothing".to_owned(), Value::to_string)
                        ))
                    })?;
                    op.holds(a, b)
                }
            };
            if holds {
                target = Some(rule.next.as_str());
                break;
            }
        }
        let Some(next) = target.or(choice.default.as_deref()) else {
            return Err(Stop::Failed(Failure {
                error: NO_CHOICE_MATCHED.into(),
                cause: format!("{path}: no choice rule matched and there is no Default"),
                state: path.to_owned(),
                item: None,
            }));
        };
        let output = select(&choice.io.output_path, effective, &ctx).map_err(rt)?;
        Ok(Step {
            output,
            next: Some(next),
            caught: None,
        })
    }

    fn task<'m>(
        &self,
        task: &'m TaskState,
        path: &str,
        name: &str,
        raw: Value,
        frame: &Frame,
    ) -> Result<Step<'m>, Stop> {
        let rt = |e: String| Stop::Failed(Self::runtime(path, e));
        let ctx0 = self.context(name, 0, None);
        let effective = select(&task.io.input_path, raw.clone(), &ctx0).map_err(rt)?;
        let timeout = match &task.timeout {
            None => None,
            Some(n) => Some(self.scaled(positive(n, &effective, &ctx0, 1).map_err(rt)? as f64)),
        };
        let outcome = self.with_retries(&task.retry, path, frame, true, |attempt| {
            let ctx = self.context(name, attempt, None);
            let payload = match task.payload.eval(&effective, &ctx) {
                Ok(p) => p,
                Err(e) => return Ok(Err(Self::runtime(path, e))),
            };
            if let Err(failure) = within_limit(&payload, path, "the Task's payload") {
                return Ok(Err(failure));
            }
            self.invoke(&task.function, payload, timeout, path, attempt, frame)
        })?;
        match outcome {
            Ok((result, attempt)) => {
                within_limit(&result, path, "the function's result").map_err(Stop::Failed)?;
                let ctx = self.context(name, attempt, None);
                let wrapped = json!({
                    "ExecutedVersion": "$LATEST",
                    "Payload": result,
                    "StatusCode": 200,
                });
                let finish = || -> Result<Value, String> {
                    let selected = match &task.result_selector {
                        Some(s) => s.eval(&wrapped, &ctx)?,
                        None => wrapped.clone(),
                    };
                    let out = task.result_path.apply(raw.clone(), selected)?;
                    select(&task.io.output_path, out, &ctx)
                };
                Ok(Step {
                    output: finish().map_err(rt)?,
                    next: next(&task.transition),
                    caught: None,
                })
            }
            Err(failure) => self.catch(&task.catch, path, raw, failure),
        }
    }

    /// Runs attempts until one succeeds (its value and attempt number) or the retriers give up
    /// (the last failure). `attempt` gets the attempt number (`$$.State.RetryCount`).
    fn with_retries(
        &self,
        retriers: &[Retrier],
        path: &str,
        frame: &Frame,
        task_events: bool,
        mut attempt: impl FnMut(u32) -> Result<Result<Value, Failure>, Stop>,
    ) -> Result<Result<(Value, u32), Failure>, Stop> {
        let mut retry = RetryState::new(retriers.len());
        loop {
            self.check(frame, path)?;
            let number = retry.total();
            match attempt(number)? {
                Ok(value) => {
                    if task_events {
                        self.emit(Event::TaskSucceeded {
                            state: path.to_owned(),
                            item_index: frame.item,
                            attempt: number,
                        });
                    }
                    return Ok(Ok((value, number)));
                }
                Err(failure) => {
                    let decision = retry.decide(
                        retriers,
                        &failure.error,
                        self.options.seed,
                        path,
                        frame.item,
                    );
                    let delay = match decision {
                        Decision::Retry(d) => Some(d.mul_f64(self.options.time_scale)),
                        Decision::GiveUp => None,
                    };
                    if task_events {
                        self.emit(Event::TaskAttemptFailed {
                            state: path.to_owned(),
                            item_index: frame.item,
                            attempt: number,
                            error: failure.error.clone(),
                            cause: failure.cause.clone(),
                            will_retry: delay.is_some(),
                            retry_delay: delay.unwrap_or_default(),
                        });
                    }
                    match delay {
                        Some(delay) => self.sleep(delay, frame, path)?,
                        None => return Ok(Err(failure)),
                    }
                }
            }
        }
    }

    fn catch<'m>(
        &self,
        catchers: &'m [Catcher],
        path: &str,
        raw: Value,
        failure: Failure,
    ) -> Result<Step<'m>, Stop> {
        let index = retry::first_match(
            catchers.iter().map(|c| c.error_equals.as_slice()),
            &failure.error,
        );
        self.emit(Event::StateFailed {
            state: path.to_owned(),
            error: failure.error.clone(),
            cause: failure.cause.clone(),
            caught: index.is_some(),
        });
        let Some(index) = index else {
            return Err(Stop::Failed(failure));
        };
        let catcher = &catchers[index];
        let error = json!({"Error": failure.error, "Cause": failure.cause});
        let output = catcher
            .result_path
            .apply(raw, error)
            .map_err(|e| Stop::Failed(Self::runtime(path, e)))?;
        Ok(Step {
            output,
            next: Some(&catcher.next),
            caught: Some(failure),
        })
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

fn next(t: &Transition) -> Option<&str> {
    match t {
        Transition::Next(n) => Some(n),
        Transition::End => None,
    }
}

/// Fails with `States.DataLimitExceeded` when `value`, as compact JSON text, is over Step
/// Functions' payload quota; `what` names the payload in the cause.
fn within_limit(value: &Value, path: &str, what: &str) -> Result<(), Failure> {
    let limit = hort_aws_quotas::STATE_PAYLOAD_BYTES;
    let size = json_len(value);
    if size <= limit {
        return Ok(());
    }
    Err(Failure {
        error: retry::DATA_LIMIT_EXCEEDED.into(),
        cause: format!(
            "{path}: {what} is {size} bytes, over Step Functions' {limit}-byte (256 KiB) \
             payload quota"
        ),
        state: path.to_owned(),
        item: None,
    })
}

/// The length of `value` as compact JSON text, without building the text.
fn json_len(value: &Value) -> usize {
    struct Count(usize);
    impl std::io::Write for Count {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.0 += buf.len();
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }
    let mut count = Count(0);
    // Writing into a counter cannot fail, and a Value always serialises.
    let _ = serde_json::to_writer(&mut count, value);
    count.0
}

fn select(selector: &Selector, value: Value, ctx: &Value) -> Result<Value, String> {
    match selector {
        Selector::Whole => Ok(value),
        Selector::Empty => Ok(json!({})),
        Selector::Path(p) => p.resolve(&value, ctx),
    }
}

/// A `TimeoutSeconds(Path)` or `MaxConcurrency(Path)` value: an integer of at least `min`.
fn positive(n: &Number, input: &Value, ctx: &Value, min: u64) -> Result<u64, String> {
    match n {
        Number::Fixed(v) => Ok(*v),
        Number::Path(p) => {
            let v = p.resolve(input, ctx)?;
            v.as_u64().filter(|&v| v >= min).ok_or_else(|| {
                format!(
                    "the path {:?} must select an integer of at least {min}, found {v}",
                    p.text
                )
            })
        }
    }
}
