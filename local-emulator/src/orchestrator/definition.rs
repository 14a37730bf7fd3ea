//! The subset of Amazon States Language the emulator runs: a serde model of the JSON, checked
//! and compiled once into [`StateMachine`].
//!
//! Supported: state types Task (`arn:aws:states:::lambda:invoke` with `Parameters.FunctionName`
//! and `Parameters.Payload`), Map (Distributed, `ItemReader` from `s3:getObject` with JSON input),
//! Pass, Succeed, Fail; fields InputPath, OutputPath, Parameters, ResultSelector, ResultPath,
//! ItemSelector, TimeoutSeconds(Path), MaxConcurrency(Path), Retry, Catch, Next/End, Comment.
//! Anything else (Choice, Wait, Parallel, HeartbeatSeconds, ResultWriter, ItemBatcher,
//! ToleratedFailure*, JSONata, …) is a load error naming the state and the field: the emulator
//! refuses what it would not run exactly as Step Functions does.

use std::collections::BTreeMap;

use serde::Deserialize;
use serde::de::DeserializeOwned;
use serde_json::{Map, Value};

use super::paths::{Path, ResultPath, Template};
use super::retry::{self, Catcher, Jitter, Retrier};

/// Why a definition cannot be run by the emulator. Every message names the state (as a path
/// such as `CastMap/CastMapTask` for states inside a Map) and the field.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DefinitionError {
    /// The text is not JSON.
    #[error("state machine definition is not valid JSON: {0}")]
    Json(String),
    /// A problem of the machine as a whole (or of a Map's ItemProcessor).
    #[error("state machine definition{}: {message}", at_state(.within))]
    Machine {
        /// The Map state whose ItemProcessor is meant, if any.
        within: Option<String>,
        /// What is wrong.
        message: String,
    },
    /// A problem of one state.
    #[error("state {state:?}: {message}")]
    State {
        /// The state's path.
        state: String,
        /// What is wrong, naming the field.
        message: String,
    },
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

/// A Distributed Map state reading a JSON array of items from the store.
#[derive(Debug, Clone)]
pub struct MapState {
    /// `ItemReader.Parameters`, evaluating to `{"Bucket": …, "Key": …}`.
    pub reader: Template,
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

const LAMBDA_INVOKE: &str = "arn:aws:states:::lambda:invoke";
const S3_GET_OBJECT: &str = "arn:aws:states:::s3:getObject";
/// The largest timeout or interval ASL accepts, in seconds.
const MAX_SECONDS: u64 = 99_999_999;

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
             Pass, Succeed, Fail)"
        ))),
    }
}

/// Deserializes with the path of the offending field in the message.
fn typed<T: DeserializeOwned>(value: Value) -> Result<T, String> {
    serde_path_to_error::deserialize(value).map_err(|e| {
        let path = e.path().to_string();
        let inner = e.into_inner().to_string();
        let inner = if inner.starts_with("unknown field") {
            format!("{inner} (not supported by the emulator)")
        } else {
            inner
        };
        if path == "." {
            inner
        } else {
            format!("{path}: {inner}")
        }
    })
}

fn transition(next: Option<String>, end: Option<bool>) -> Result<Transition, String> {
    match (next, end) {
        (Some(next), None | Some(false)) => Ok(Transition::Next(next)),
        (None, Some(true)) => Ok(Transition::End),
        (Some(_), Some(true)) => Err("has both \"Next\" and \"End\": true".into()),
        (None, _) => Err("needs \"Next\" or \"End\": true".into()),
    }
}

fn selector(field: &str, raw: Nullable) -> Result<Selector, String> {
    match raw {
        Nullable::Absent => Ok(Selector::Whole),
        Nullable::Null => Ok(Selector::Empty),
        Nullable::Text(text) => {
            let path = Path::parse(&text).map_err(|e| format!("{field}: {e}"))?;
            Ok(if path.steps.is_empty() && !path.context {
                Selector::Whole
            } else {
                Selector::Path(path)
            })
        }
    }
}

fn io(input_path: Nullable, output_path: Nullable) -> Result<Io, String> {
    Ok(Io {
        input_path: selector("InputPath", input_path)?,
        output_path: selector("OutputPath", output_path)?,
    })
}

fn result_path(raw: Nullable, field: &str) -> Result<ResultPath, String> {
    match raw {
        Nullable::Absent => Ok(ResultPath::Replace),
        Nullable::Null => Ok(ResultPath::Discard),
        Nullable::Text(text) => ResultPath::parse(Some(&text)).map_err(|e| format!("{field}: {e}")),
    }
}

fn template(field: &str, raw: Option<Value>) -> Result<Option<Template>, String> {
    raw.map(|v| {
        if !v.is_object() {
            return Err(format!("{field} must be an object"));
        }
        Template::compile(&v).map_err(|e| format!("{field}: {e}"))
    })
    .transpose()
}

fn number(
    field: &str,
    fixed: Option<u64>,
    path: Option<String>,
    min: u64,
) -> Result<Option<Number>, String> {
    match (fixed, path) {
        (Some(_), Some(_)) => Err(format!("has both {field} and {field}Path")),
        (Some(n), None) if n < min || n > MAX_SECONDS => {
            Err(format!("{field} must be between {min} and {MAX_SECONDS}, found {n}"))
        }
        (Some(n), None) => Ok(Some(Number::Fixed(n))),
        (None, Some(text)) => {
            let p = Path::parse(&text).map_err(|e| format!("{field}Path: {e}"))?;
            Ok(Some(Number::Path(p)))
        }
        (None, None) => Ok(None),
    }
}

fn error_lists(field: &str, lists: &[&[String]]) -> Result<(), String> {
    for (i, names) in lists.iter().enumerate() {
        if names.is_empty() {
            return Err(format!("{field}[{i}].ErrorEquals is empty"));
        }
        if names.iter().any(|n| n == retry::ALL) && (names.len() > 1 || i + 1 != lists.len()) {
            return Err(format!(
                "{field}[{i}]: \"States.ALL\" must be alone in ErrorEquals and in the last entry"
            ));
        }
    }
    Ok(())
}

fn retriers(raw: Vec<RawRetrier>) -> Result<Vec<Retrier>, String> {
    let lists: Vec<&[String]> = raw.iter().map(|r| r.error_equals.as_slice()).collect();
    error_lists("Retry", &lists)?;
    raw.into_iter()
        .enumerate()
        .map(|(i, r)| {
            let interval = r.interval_seconds.unwrap_or(1);
            if !(1..=MAX_SECONDS).contains(&interval) {
                return Err(format!("Retry[{i}].IntervalSeconds must be a positive integer"));
            }
            let max_attempts = r.max_attempts.unwrap_or(3);
            let max_attempts = u32::try_from(max_attempts)
                .ok()
                .filter(|&n| u64::from(n) <= MAX_SECONDS)
                .ok_or_else(|| format!("Retry[{i}].MaxAttempts is too large"))?;
            let backoff_rate = r.backoff_rate.unwrap_or(2.0);
            if !(backoff_rate.is_finite() && backoff_rate >= 1.0) {
                return Err(format!("Retry[{i}].BackoffRate must be at least 1.0"));
            }
            if let Some(cap) = r.max_delay_seconds
                && !(1..=31_622_400).contains(&cap)
            {
                return Err(format!(
                    "Retry[{i}].MaxDelaySeconds must be between 1 and 31622400"
                ));
            }
            let jitter = match r.jitter_strategy.as_deref() {
                None | Some("NONE") => Jitter::None,
                Some("FULL") => Jitter::Full,
                Some(other) => {
                    return Err(format!(
                        "Retry[{i}].JitterStrategy {other:?} must be \"FULL\" or \"NONE\""
                    ));
                }
            };
            Ok(Retrier {
                error_equals: r.error_equals,
                interval_seconds: interval as f64,
                max_attempts,
                backoff_rate,
                max_delay_seconds: r.max_delay_seconds.map(|s| s as f64),
                jitter,
            })
        })
        .collect()
}

fn catchers(raw: Vec<RawCatcher>) -> Result<Vec<Catcher>, String> {
    let lists: Vec<&[String]> = raw.iter().map(|c| c.error_equals.as_slice()).collect();
    error_lists("Catch", &lists)?;
    raw.into_iter()
        .enumerate()
        .map(|(i, c)| {
            Ok(Catcher {
                error_equals: c.error_equals,
                next: c.next,
                result_path: result_path(c.result_path, &format!("Catch[{i}].ResultPath"))?,
            })
        })
        .collect()
}

fn task(raw: RawTask) -> Result<State, String> {
    if raw.resource != LAMBDA_INVOKE {
        return Err(format!(
            "Resource {:?} is not supported by the emulator (only {LAMBDA_INVOKE:?})",
            raw.resource
        ));
    }
    let Some(Value::Object(mut params)) = raw.parameters else {
        return Err("Parameters must be an object with FunctionName and Payload".into());
    };
    let function = match params.remove("FunctionName") {
        Some(Value::String(name)) => name
            .strip_prefix("${")
            .and_then(|n| n.strip_suffix('}'))
            .map_or(name.clone(), str::to_owned),
        _ => return Err("Parameters.FunctionName must be a string".into()),
    };
    let payload = match (params.remove("Payload"), params.remove("Payload.$")) {
        (Some(v), None) => Template::compile(&v),
        (None, Some(Value::String(expr))) => Template::expression(&expr, "Payload.$"),
        _ => Err("exactly one of Payload and Payload.$ (a string) is required".into()),
    }
    .map_err(|e| format!("Parameters.Payload: {e}"))?;
    if let Some(extra) = params.keys().next() {
        return Err(format!(
            "Parameters.{extra} is not supported by the emulator (only FunctionName, Payload)"
        ));
    }
    Ok(State::Task(TaskState {
        function,
        payload,
        result_selector: template("ResultSelector", raw.result_selector)?,
        result_path: result_path(raw.result_path, "ResultPath")?,
        io: io(raw.input_path, raw.output_path)?,
        timeout: number("TimeoutSeconds", raw.timeout_seconds, raw.timeout_seconds_path, 1)?,
        retry: retriers(raw.retry)?,
        catch: catchers(raw.catch)?,
        transition: transition(raw.next, raw.end)?,
    }))
}

fn map(path: &str, mut raw: RawMap) -> Result<State, DefinitionError> {
    let processor = machine(
        std::mem::take(&mut raw.item_processor.start_at),
        std::mem::take(&mut raw.item_processor.states),
        Some(path),
    )?;
    map_fields(raw, processor).map_err(|message| DefinitionError::State {
        state: path.to_owned(),
        message,
    })
}

fn map_fields(raw: RawMap, processor: StateMachine) -> Result<State, String> {
    let config = raw.item_processor.processor_config;
    let mode = config.as_ref().and_then(|c| c.mode.as_deref()).unwrap_or("INLINE");
    if mode != "DISTRIBUTED" {
        return Err(format!(
            "ItemProcessor.ProcessorConfig.Mode {mode:?} is not supported by the emulator \
             (only DISTRIBUTED with an ItemReader)"
        ));
    }
    let express = match config.as_ref().and_then(|c| c.execution_type.as_deref()) {
        Some("EXPRESS") => true,
        Some("STANDARD") => false,
        other => {
            return Err(format!(
                "ItemProcessor.ProcessorConfig.ExecutionType must be \"STANDARD\" or \
                 \"EXPRESS\" for a DISTRIBUTED Map, found {other:?}"
            ));
        }
    };
    let reader = raw.item_reader;
    if reader.resource != S3_GET_OBJECT {
        return Err(format!(
            "ItemReader.Resource {:?} is not supported by the emulator (only {S3_GET_OBJECT:?})",
            reader.resource
        ));
    }
    if reader.reader_config.input_type != "JSON" {
        return Err(format!(
            "ItemReader.ReaderConfig.InputType {:?} is not supported by the emulator (only \
             \"JSON\")",
            reader.reader_config.input_type
        ));
    }
    let reader_params = template("ItemReader.Parameters", Some(reader.parameters))?
        .ok_or("ItemReader.Parameters is required")?;
    Ok(State::Map(MapState {
        reader: reader_params,
        item_selector: template("ItemSelector", raw.item_selector)?,
        processor,
        express,
        max_concurrency: number(
            "MaxConcurrency",
            raw.max_concurrency,
            raw.max_concurrency_path,
            0,
        )?,
        result_selector: template("ResultSelector", raw.result_selector)?,
        result_path: result_path(raw.result_path, "ResultPath")?,
        io: io(raw.input_path, raw.output_path)?,
        retry: retriers(raw.retry)?,
        catch: catchers(raw.catch)?,
        transition: transition(raw.next, raw.end)?,
    }))
}

fn pass(raw: RawPass) -> Result<State, String> {
    if raw.result.is_some() && raw.parameters.is_some() {
        return Err("has both Result and Parameters".into());
    }
    Ok(State::Pass(PassState {
        result: raw.result,
        parameters: template("Parameters", raw.parameters)?,
        result_path: result_path(raw.result_path, "ResultPath")?,
        io: io(raw.input_path, raw.output_path)?,
        transition: transition(raw.next, raw.end)?,
    }))
}

fn fail(raw: RawFail) -> Result<State, String> {
    let pick = |field: &str, literal: Option<String>, path: Option<String>| match (literal, path)
    {
        (Some(_), Some(_)) => Err(format!("has both {field} and {field}Path")),
        (Some(text), None) => Ok(Some(Template::Literal(Value::String(text)))),
        (None, Some(expr)) => Template::expression(&expr, &format!("{field}Path")).map(Some),
        (None, None) => Ok(None),
    };
    Ok(State::Fail(FailState {
        error: pick("Error", raw.error, raw.error_path)?,
        cause: pick("Cause", raw.cause, raw.cause_path)?,
    }))
}

/// A field where absent and `null` mean different things (`ResultPath`, `InputPath`, …).
#[derive(Debug, Default)]
enum Nullable {
    #[default]
    Absent,
    Null,
    Text(String),
}

impl<'de> Deserialize<'de> for Nullable {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Ok(Option::<String>::deserialize(d)?.map_or(Nullable::Null, Nullable::Text))
    }
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
struct RawMachine {
    start_at: String,
    states: Map<String, Value>,
    #[serde(rename = "Comment")]
    _comment: Option<String>,
    #[serde(rename = "Version")]
    _version: Option<String>,
    query_language: Option<String>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
struct RawTask {
    #[serde(rename = "Type")]
    _type: String,
    #[serde(rename = "Comment")]
    _comment: Option<String>,
    resource: String,
    parameters: Option<Value>,
    result_selector: Option<Value>,
    #[serde(default)]
    result_path: Nullable,
    #[serde(default)]
    input_path: Nullable,
    #[serde(default)]
    output_path: Nullable,
    timeout_seconds: Option<u64>,
    timeout_seconds_path: Option<String>,
    #[serde(default)]
    retry: Vec<RawRetrier>,
    #[serde(default)]
    catch: Vec<RawCatcher>,
    next: Option<String>,
    end: Option<bool>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
struct RawMap {
    #[serde(rename = "Type")]
    _type: String,
    #[serde(rename = "Comment")]
    _comment: Option<String>,
    item_reader: RawItemReader,
    item_selector: Option<Value>,
    item_processor: RawProcessor,
    max_concurrency: Option<u64>,
    max_concurrency_path: Option<String>,
    result_selector: Option<Value>,
    #[serde(default)]
    result_path: Nullable,
    #[serde(default)]
    input_path: Nullable,
    #[serde(default)]
    output_path: Nullable,
    #[serde(default)]
    retry: Vec<RawRetrier>,
    #[serde(default)]
    catch: Vec<RawCatcher>,
    next: Option<String>,
    end: Option<bool>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
struct RawItemReader {
    resource: String,
    reader_config: RawReaderConfig,
    parameters: Value,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
struct RawReaderConfig {
    input_type: String,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
struct RawProcessor {
    processor_config: Option<RawProcessorConfig>,
    start_at: String,
    states: Map<String, Value>,
    #[serde(rename = "Comment")]
    _comment: Option<String>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
struct RawProcessorConfig {
    mode: Option<String>,
    execution_type: Option<String>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
struct RawRetrier {
    error_equals: Vec<String>,
    interval_seconds: Option<u64>,
    max_attempts: Option<u64>,
    backoff_rate: Option<f64>,
    max_delay_seconds: Option<u64>,
    jitter_strategy: Option<String>,
    #[serde(rename = "Comment")]
    _comment: Option<String>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
struct RawCatcher {
    error_equals: Vec<String>,
    next: String,
    #[serde(default)]
    result_path: Nullable,
    #[serde(rename = "Comment")]
    _comment: Option<String>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
struct RawPass {
    #[serde(rename = "Type")]
    _type: String,
    #[serde(rename = "Comment")]
    _comment: Option<String>,
    result: Option<Value>,
    parameters: Option<Value>,
    #[serde(default)]
    result_path: Nullable,
    #[serde(default)]
    input_path: Nullable,
    #[serde(default)]
    output_path: Nullable,
    next: Option<String>,
    end: Option<bool>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
struct RawSucceed {
    #[serde(rename = "Type")]
    _type: String,
    #[serde(rename = "Comment")]
    _comment: Option<String>,
    #[serde(default)]
    input_path: Nullable,
    #[serde(default)]
    output_path: Nullable,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
struct RawFail {
    #[serde(rename = "Type")]
    _type: String,
    #[serde(rename = "Comment")]
    _comment: Option<String>,
    error: Option<String>,
    error_path: Option<String>,
    cause: Option<String>,
    cause_path: Option<String>,
}
