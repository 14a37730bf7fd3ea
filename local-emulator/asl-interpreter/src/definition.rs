//! The subset of Amazon States Language the emulator runs: a serde model of the JSON, checked
//! and compiled once into [`StateMachine`].
//!
//! Supported: state types Task (`arn:aws:states:::lambda:invoke` with `Parameters.FunctionName`
//! and `Parameters.Payload`), Map (Distributed, items from an `ItemReader` of `s3:getObject`
//! with JSON input, or from the state input through `ItemsPath`), Choice (rules of one
//! `Variable` compared with `IsPresent`, `StringEquals`, `BooleanEquals` or a `Numeric…` operator against a literal, and
//! `Default`), Pass, Succeed, Fail; fields InputPath, OutputPath, Parameters, ResultSelector,
//! ResultPath, ItemSelector, TimeoutSeconds(Path), MaxConcurrency(Path), Retry, Catch,
//! Next/End, Comment, and a Map's `ResultWriter` (`s3:putObject` with `Bucket` and `Prefix`).
//! Anything else (Wait, Parallel, HeartbeatSeconds, `ResultWriter.WriterConfig`, ItemBatcher, ToleratedFailure*, And/Or/Not and string or timestamp comparisons in Choice,
//! JSONata, …) is a load error naming the state and the field: the emulator refuses what it
//! would not run exactly as Step Functions does.

mod raw;
mod states;
#[cfg(test)]
mod tests;

use std::collections::BTreeMap;

use serde_json::{Map, Value};

use super::paths::{Path, ResultPath, Template};
use super::retry::{Catcher, Retrier};
use raw::{RawMachine, RawSucceed};
use states::{choice, fail, io, map, pass, task, typed};

/// Why a definition cannot be run by the emulator. Every message names the state (as a path
/// such as `CastMap/CastMapTask` for states inside a Map) and the field.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DefinitionError {
    /// The text is not JSON.
    #[error("state machine definition is not valid JSON: {0}")]
    Json(String),
    /// A problem of the machine as a whole (or of a Map's ItemProcessor).
    #[error("state machine definition{}: {}", at_state(.within), printable(.message))]
    Machine {
        /// The Map state whose ItemProcessor is meant, if any.
        within: Option<String>,
        /// What is wrong.
        message: String,
    },
    /// A problem of one state.
    #[error("state {state:?}: {}", printable(.message))]
    State {
        /// The state's path.
        state: String,
        /// What is wrong, naming the field.
        message: String,
    },
}

/// `text` with control characters escaped (`\r`, `\u{1b}`): a message that quotes a field
/// name or an operator holding them stays on one line.
fn printable(text: &str) -> String {
    text.chars()
        .map(|c| {
            if c.is_control() {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

fn at_state(within: &Option<String>) -> String {
    within
        .as_ref()
        .map(|s| format!(" (ItemProcessor of {s:?})"))
        .unwrap_or_default()
}

/// A checked state machine (the top level, or a Map's ItemProcessor).
#[derive(Debug, Clone)]
pub struct StateMachine {
    /// The first state.
    pub start_at: String,
    /// Every state by name.
    pub states: BTreeMap<String, State>,
}

/// One state.
#[derive(Debug, Clone)]
pub enum State {
    /// A Lambda invocation.
    Task(TaskState),
    /// A Distributed Map over items read from the store.
    Map(MapState),
    /// Passes (and may reshape) its input.
    Pass(PassState),
    /// Picks the next state from its input.
    Choice(ChoiceState),
    /// Ends the machine successfully.
    Succeed(SucceedState),
    /// Ends the machine with an error.
    Fail(FailState),
}

/// `InputPath` or `OutputPath`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Selector {
    /// Absent or `"$"`: the whole value.
    Whole,
    /// `null`: an empty object.
    Empty,
    /// A path selecting part of the value.
    Path(Path),
}

/// Where a state goes next.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Transition {
    /// The named state.
    Next(String),
    /// The machine (or the Map iteration) ends with this state's output.
    End,
}

/// A number given directly or through a reference path.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Number {
    /// A fixed value.
    Fixed(u64),
    /// A reference path into the state's effective input.
    Path(Path),
}

/// Input and output filtering common to most states.
#[derive(Debug, Clone)]
pub struct Io {
    /// `InputPath`.
    pub input_path: Selector,
    /// `OutputPath`.
    pub output_path: Selector,
}

/// A Task state invoking a Lambda function through `arn:aws:states:::lambda:invoke`.
#[derive(Debug, Clone)]
pub struct TaskState {
    /// The function: the placeholder name inside `${…}` (e.g. `WorkerFunctionArn`), or the
    /// literal `FunctionName` when it is not a placeholder.
    pub function: String,
    /// `Parameters.Payload`: what the function receives.
    pub payload: Template,
    /// `ResultSelector`, applied to `{"Payload": result, "StatusCode": 200, …}`.
    pub result_selector: Option<Template>,
    /// `ResultPath`.
    pub result_path: ResultPath,
    /// `InputPath` and `OutputPath`.
    pub io: Io,
    /// `TimeoutSeconds` or `TimeoutSecondsPath`; none means no timeout.
    pub timeout: Option<Number>,
    /// `Retry`.
    pub retry: Vec<Retrier>,
    /// `Catch`.
    pub catch: Vec<Catcher>,
    /// `Next` or `End`.
    pub transition: Transition,
}

/// Where a Map state's items come from.
#[derive(Debug, Clone)]
pub enum Items {
    /// `ItemReader.Parameters`, evaluating to `{"Bucket": …, "Key": …}` of a JSON array.
    Reader(Template),
    /// `ItemsPath`: an array in the state's effective input.
    Path(Path),
}

/// A Distributed Map state over a JSON array of items from the store or from its input.
#[derive(Debug, Clone)]
pub struct MapState {
    /// Where the items come from.
    pub items: Items,
    /// `ResultWriter.Parameters` (`{"Bucket": …, "Prefix": …}`): the children's results go to
    /// the bucket as AWS writes them, and the Map's result is only where they went. Without
    /// it the results come back inline, and the 256 KiB payload limit applies to them.
    pub result_writer: Option<Template>,
    /// `ItemSelector`: each child's input, with `$$.Map.Item.{Index,Value}` in the context.
    pub item_selector: Option<Template>,
    /// `ItemProcessor`: the machine each item runs through.
    pub processor: StateMachine,
    /// `ProcessorConfig.ExecutionType` is `EXPRESS` (children then have a 5-minute limit).
    pub express: bool,
    /// `MaxConcurrency` or `MaxConcurrencyPath`; 0 or none means no limit but the slots.
    pub max_concurrency: Option<Number>,
    /// `ResultSelector`, applied to the array of child outputs.
    pub result_selector: Option<Template>,
    /// `ResultPath`.
    pub result_path: ResultPath,
    /// `InputPath` and `OutputPath`.
    pub io: Io,
    /// `Retry` (of the whole Map Run).
    pub retry: Vec<Retrier>,
    /// `Catch`.
    pub catch: Vec<Catcher>,
    /// `Next` or `End`.
    pub transition: Transition,
}

/// A Pass state.
#[derive(Debug, Clone)]
pub struct PassState {
    /// `Result`: the fixed result, if given.
    pub result: Option<Value>,
    /// `Parameters`: the result built from the input, if given (and no `Result`).
    pub parameters: Option<Template>,
    /// `ResultPath`.
    pub result_path: ResultPath,
    /// `InputPath` and `OutputPath`.
    pub io: Io,
    /// `Next` or `End`.
    pub transition: Transition,
}

/// A Choice state: the first rule that matches names the next state, else `Default`.
#[derive(Debug, Clone)]
pub struct ChoiceState {
    /// `Choices`, in order.
    pub choices: Vec<ChoiceRule>,
    /// `Default`; without it, no match fails the execution with `States.NoChoiceMatched`.
    pub default: Option<String>,
    /// `InputPath` and `OutputPath`.
    pub io: Io,
}

/// One rule of a Choice state.
#[derive(Debug, Clone)]
pub struct ChoiceRule {
    /// `Variable`: the reference path compared.
    pub variable: Path,
    /// The comparison.
    pub test: Comparison,
    /// `Next`.
    pub next: String,
}

/// A Choice rule's comparison of its `Variable`.
#[derive(Debug, Clone, PartialEq)]
pub enum Comparison {
    /// `IsPresent`: whether the path selects anything.
    IsPresent(bool),
    /// `NumericEquals`, `NumericLessThan`, …: the variable (which must be a number) against a
    /// literal.
    Numeric(NumericOp, f64),
    /// `StringEquals`: the variable (which must be a string) equals the literal exactly.
    StringEquals(String),
    /// `BooleanEquals`: the variable (which must be `true` or `false`) equals the literal.
    BooleanEquals(bool),
}

/// A numeric comparison operator of a Choice rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NumericOp {
    /// `NumericEquals`.
    Equals,
    /// `NumericLessThan`.
    LessThan,
    /// `NumericLessThanEquals`.
    LessThanEquals,
    /// `NumericGreaterThan`.
    GreaterThan,
    /// `NumericGreaterThanEquals`.
    GreaterThanEquals,
}

impl NumericOp {
    /// Whether `a op b`.
    pub fn holds(self, a: f64, b: f64) -> bool {
        match self {
            NumericOp::Equals => a == b,
            NumericOp::LessThan => a < b,
            NumericOp::LessThanEquals => a <= b,
            NumericOp::GreaterThan => a > b,
            NumericOp::GreaterThanEquals => a >= b,
        }
    }
}

/// A Succeed state.
#[derive(Debug, Clone)]
pub struct SucceedState {
    /// `InputPath` and `OutputPath`.
    pub io: Io,
}

/// A Fail state: `Error`/`Cause` literals or `ErrorPath`/`CausePath` (path or intrinsic).
#[derive(Debug, Clone)]
pub struct FailState {
    /// The error name, if any.
    pub error: Option<Template>,
    /// The cause, if any.
    pub cause: Option<Template>,
}

/// Parses and checks a definition.
pub fn load(text: &str) -> Result<StateMachine, DefinitionError> {
    let value: Value =
        serde_json::from_str(text).map_err(|e| DefinitionError::Json(e.to_string()))?;
    let raw: RawMachine = typed(value).map_err(|message| DefinitionError::Machine {
        within: None,
        message,
    })?;
    if let Some(lang) = raw.query_language.as_deref().filter(|l| *l != "JSONPath") {
        return Err(DefinitionError::Machine {
            within: None,
            message: format!(
                "QueryLanguage {lang:?} is not supported by the emulator (only JSONPath)"
            ),
        });
    }
    machine(raw.start_at, raw.states, None)
}

fn machine(
    start_at: String,
    raw_states: Map<String, Value>,
    within: Option<&str>,
) -> Result<StateMachine, DefinitionError> {
    let machine_error = |message: String| DefinitionError::Machine {
        within: within.map(str::to_owned),
        message,
    };
    if raw_states.is_empty() {
        return Err(machine_error("\"States\" is empty".into()));
    }
    if !raw_states.contains_key(&start_at) {
        return Err(machine_error(format!(
            "StartAt {start_at:?} names no state"
        )));
    }
    let mut states = BTreeMap::new();
    for (name, value) in raw_states {
        let path = match within {
            Some(parent) => format!("{parent}/{name}"),
            None => name.clone(),
        };
        let state = one_state(&path, value)?;
        states.insert(name, state);
    }
    for (name, state) in &states {
        for target in targets(state) {
            if !states.contains_key(target) {
                let path = within.map_or(name.clone(), |p| format!("{p}/{name}"));
                return Err(DefinitionError::State {
                    state: path,
                    message: format!(
                        "transition to {target:?}, which is not a state of the same machine"
                    ),
                });
            }
        }
    }
    Ok(StateMachine { start_at, states })
}

fn targets(state: &State) -> Vec<&String> {
    let (transition, catch) = match state {
        State::Task(t) => (&t.transition, t.catch.as_slice()),
        State::Map(m) => (&m.transition, m.catch.as_slice()),
        State::Pass(p) => (&p.transition, &[][..]),
        State::Choice(c) => {
            return c
                .choices
                .iter()
                .map(|r| &r.next)
                .chain(c.default.as_ref())
                .collect();
        }
        State::Succeed(_) | State::Fail(_) => return Vec::new(),
    };
    let mut out: Vec<&String> = catch.iter().map(|c| &c.next).collect();
    if let Transition::Next(next) = transition {
        out.push(next);
    }
    out
}

fn one_state(path: &str, value: Value) -> Result<State, DefinitionError> {
    let at = |message: String| DefinitionError::State {
        state: path.to_owned(),
        message,
    };
    let kind = value
        .get("Type")
        .and_then(Value::as_str)
        .ok_or_else(|| at("missing string field \"Type\"".into()))?
        .to_owned();
    match kind.as_str() {
        "Task" => typed(value).and_then(task).map_err(at),
        "Map" => map(path, typed(value).map_err(at)?),
        "Pass" => typed(value).and_then(pass).map_err(at),
        "Choice" => typed(value).and_then(choice).map_err(at),
        "Succeed" => typed(value)
            .and_then(|raw: RawSucceed| {
                Ok(State::Succeed(SucceedState {
                    io: io(raw.input_path, raw.output_path)?,
                }))
            })
            .map_err(at),
        "Fail" => typed(value).and_then(fail).map_err(at),
        other => Err(at(format!(
            "state type {other:?} is not supported by the emulator (supported: Task, Map, \
             Choice, Pass, Succeed, Fail)"
        ))),
    }
}
