//! Checks and compiles each state's raw fields into the [`super::State`] model, with Step
//! Functions' defaults and limits; every error message names the field.

use serde::de::DeserializeOwned;
use serde_json::Value;

use super::raw::{Nullable, RawCatcher, RawChoice, RawFail, RawMap, RawPass, RawRetrier, RawTask};
use super::{
    ChoiceRule, ChoiceState, Comparison, DefinitionError, FailState, Io, Items, MapState, Number,
    NumericOp, PassState, Selector, State, StateMachine, TaskState, Transition, machine,
};
use crate::paths::{Path, ResultPath, Template};
use crate::retry::{self, Catcher, Jitter, Retrier};

const LAMBDA_INVOKE: &str = "arn:aws:states:::lambda:invoke";
const S3_GET_OBJECT: &str = "arn:aws:states:::s3:getObject";
const S3_PUT_OBJECT: &str = "arn:aws:states:::s3:putObject";
/// The largest timeout or interval ASL accepts, in seconds.
const MAX_SECONDS: u64 = 99_999_999;

/// Deserializes with the path of the offending field in the message.
pub(super) fn typed<T: DeserializeOwned>(value: Value) -> Result<T, String> {
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

pub(super) fn transition(next: Option<String>, end: Option<bool>) -> Result<Transition, String> {
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

pub(super) fn io(input_path: Nullable, output_path: Nullable) -> Result<Io, String> {
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
        (Some(n), None) if n < min || n > MAX_SECONDS => Err(format!(
            "{field} must be between {min} and {MAX_SECONDS}, found {n}"
        )),
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
                return Err(format!(
                    "Retry[{i}].IntervalSeconds must be a positive integer"
                ));
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

pub(super) fn task(raw: RawTask) -> Result<State, String> {
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
        timeout: number(
            "TimeoutSeconds",
            raw.timeout_seconds,
            raw.timeout_seconds_path,
            1,
        )?,
        retry: retriers(raw.retry)?,
        catch: catchers(raw.catch)?,
        transition: transition(raw.next, raw.end)?,
    }))
}

pub(super) fn map(path: &str, mut raw: RawMap) -> Result<State, DefinitionError> {
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
    let mode = config
        .as_ref()
        .and_then(|c| c.mode.as_deref())
        .unwrap_or("INLINE");
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
    let items = match (raw.item_reader, raw.items_path) {
        (Some(_), Some(_)) => return Err("has both ItemReader and ItemsPath".into()),
        (None, None) => return Err("needs an ItemReader or an ItemsPath".into()),
        (None, Some(text)) => {
            Items::Path(Path::parse(&text).map_err(|e| format!("ItemsPath: {e}"))?)
        }
        (Some(reader), None) => {
            if reader.resource != S3_GET_OBJECT {
                return Err(format!(
                    "ItemReader.Resource {:?} is not supported by the emulator (only \
                     {S3_GET_OBJECT:?})",
                    reader.resource
                ));
            }
            if reader.reader_config.input_type != "JSON" {
                return Err(format!(
                    "ItemReader.ReaderConfig.InputType {:?} is not supported by the emulator \
                     (only \"JSON\")",
                    reader.reader_config.input_type
                ));
            }
            Items::Reader(
                template("ItemReader.Parameters", Some(reader.parameters))?
                    .ok_or("ItemReader.Parameters is required")?,
            )
        }
    };
    let result_writer = match raw.result_writer {
        None => None,
        Some(writer) => {
            if writer.resource != S3_PUT_OBJECT {
                return Err(format!(
                    "ResultWriter.Resource {:?} is not supported by the emulator (only \
                     {S3_PUT_OBJECT:?})",
                    writer.resource
                ));
            }
            Some(
                template("ResultWriter.Parameters", Some(writer.parameters))?
                    .ok_or("ResultWriter.Parameters is required")?,
            )
        }
    };
    Ok(State::Map(MapState {
        items,
        result_writer,
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

pub(super) fn pass(raw: RawPass) -> Result<State, String> {
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

const NUMERIC: [(&str, NumericOp); 5] = [
    ("NumericEquals", NumericOp::Equals),
    ("NumericLessThan", NumericOp::LessThan),
    ("NumericLessThanEquals", NumericOp::LessThanEquals),
    ("NumericGreaterThan", NumericOp::GreaterThan),
    ("NumericGreaterThanEquals", NumericOp::GreaterThanEquals),
];

pub(super) fn choice(raw: RawChoice) -> Result<State, String> {
    if raw.choices.is_empty() {
        return Err("Choices is empty".into());
    }
    let supported = || {
        let mut names = vec!["IsPresent", "StringEquals", "BooleanEquals"];
        names.extend(NUMERIC.iter().map(|(n, _)| *n));
        names.join(", ")
    };
    let choices = raw
        .choices
        .into_iter()
        .enumerate()
        .map(|(i, mut rule)| {
            let at = |m: String| format!("Choices[{i}]: {m}");
            rule.remove("Comment");
            let next = match rule.remove("Next") {
                Some(Value::String(n)) => n,
                _ => return Err(at("needs a string Next".into())),
            };
            let variable = match rule.remove("Variable") {
                Some(Value::String(v)) => {
                    Path::parse(&v).map_err(|e| at(format!("Variable: {e}")))?
                }
                _ => {
                    return Err(at(format!(
                        "needs a string Variable (And, Or and Not are not supported by the \
                         emulator; supported comparisons: {})",
                        supported()
                    )));
                }
            };
            let mut fields = rule.into_iter();
            let (Some((op, value)), None) = (fields.next(), fields.next()) else {
                return Err(at(format!(
                    "needs exactly one comparison besides Variable and Next (supported: {})",
                    supported()
                )));
            };
            let test = if op == "IsPresent" {
                Comparison::IsPresent(
                    value
                        .as_bool()
                        .ok_or_else(|| at("IsPresent must be true or false".into()))?,
                )
            } else if op == "StringEquals" {
                Comparison::StringEquals(
                    value
                        .as_str()
                        .ok_or_else(|| at("StringEquals must be a string".into()))?
                        .to_owned(),
                )
            } else if op == "BooleanEquals" {
                Comparison::BooleanEquals(
                    value
                        .as_bool()
                        .ok_or_else(|| at("BooleanEquals must be true or false".into()))?,
                )
            } else if let Some((_, numeric)) = NUMERIC.iter().find(|(n, _)| *n == op) {
                Comparison::Numeric(
                    *numeric,
                    value
                        .as_f64()
                        .ok_or_else(|| at(format!("{op} must be a number")))?,
                )
            } else {
                return Err(at(format!(
                    "{op} is not supported by the emulator (supported: {})",
                    supported()
                )));
            };
            Ok(ChoiceRule {
                variable,
                test,
                next,
            })
        })
        .collect::<Result<_, String>>()?;
    Ok(State::Choice(ChoiceState {
        choices,
        default: raw.default,
        io: io(raw.input_path, raw.output_path)?,
    }))
}

pub(super) fn fail(raw: RawFail) -> Result<State, String> {
    let pick = |field: &str, literal: Option<String>, path: Option<String>| match (literal, path) {
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
