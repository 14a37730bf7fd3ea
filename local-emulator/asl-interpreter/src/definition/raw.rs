//! The serde model of the supported ASL subset: one struct per JSON object, every one with
//! `deny_unknown_fields`, so an unsupported field is a load error naming it.

use serde::Deserialize;
use serde_json::{Map, Value};

/// A field where absent and `null` mean different things (`ResultPath`, `InputPath`, …).
#[derive(Debug, Default)]
pub(super) enum Nullable {
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
pub(super) struct RawMachine {
    pub(super) start_at: String,
    pub(super) states: Map<String, Value>,
    #[serde(rename = "Comment")]
    pub(super) _comment: Option<String>,
    #[serde(rename = "Version")]
    pub(super) _version: Option<String>,
    pub(super) query_language: Option<String>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
pub(super) struct RawTask {
    #[serde(rename = "Type")]
    pub(super) _type: String,
    #[serde(rename = "Comment")]
    pub(super) _comment: Option<String>,
    pub(super) resource: String,
    pub(super) parameters: Option<Value>,
    pub(super) result_selector: Option<Value>,
    #[serde(default)]
    pub(super) result_path: Nullable,
    #[serde(default)]
    pub(super) input_path: Nullable,
    #[serde(default)]
    pub(super) output_path: Nullable,
    pub(super) timeout_seconds: Option<u64>,
    pub(super) timeout_seconds_path: Option<String>,
    #[serde(default)]
    pub(super) retry: Vec<RawRetrier>,
    #[serde(default)]
    pub(super) catch: Vec<RawCatcher>,
    pub(super) next: Option<String>,
    pub(super) end: Option<bool>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
pub(super) struct RawMap {
    #[serde(rename = "Type")]
    pub(super) _type: String,
    #[serde(rename = "Comment")]
    pub(super) _comment: Option<String>,
    pub(super) item_reader: Option<RawItemReader>,
    pub(super) items_path: Option<String>,
    pub(super) result_writer: Option<RawResultWriter>,
    pub(super) item_selector: Option<Value>,
    pub(super) item_processor: RawProcessor,
    pub(super) max_concurrency: Option<u64>,
    pub(super) max_concurrency_path: Option<String>,
    pub(super) result_selector: Option<Value>,
    #[serde(default)]
    pub(super) result_path: Nullable,
    #[serde(default)]
    pub(super) input_path: Nullable,
    #[serde(default)]
    pub(super) output_path: Nullable,
    #[serde(default)]
    pub(super) retry: Vec<RawRetrier>,
    #[serde(default)]
    pub(super) catch: Vec<RawCatcher>,
    pub(super) next: Option<String>,
    pub(super) end: Option<bool>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
pub(super) struct RawItemReader {
    pub(super) resource: String,
    pub(super) reader_config: RawReaderConfig,
    pub(super) parameters: Value,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
pub(super) struct RawResultWriter {
    pub(super) resource: String,
    pub(super) parameters: Value,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
pub(super) struct RawReaderConfig {
    pub(super) input_type: String,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
pub(super) struct RawProcessor {
    pub(super) processor_config: Option<RawProcessorConfig>,
    pub(super) start_at: String,
    pub(super) states: Map<String, Value>,
    #[serde(rename = "Comment")]
    pub(super) _comment: Option<String>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
pub(super) struct RawProcessorConfig {
    pub(super) mode: Option<String>,
    pub(super) execution_type: Option<String>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
pub(super) struct RawRetrier {
    pub(super) error_equals: Vec<String>,
    pub(super) interval_seconds: Option<u64>,
    pub(super) max_attempts: Option<u64>,
    pub(super) backoff_rate: Option<f64>,
    pub(super) max_delay_seconds: Option<u64>,
    pub(super) jitter_strategy: Option<String>,
    #[serde(rename = "Comment")]
    pub(super) _comment: Option<String>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
pub(super) struct RawCatcher {
    pub(super) error_equals: Vec<String>,
    pub(super) next: String,
    #[serde(default)]
    pub(super) result_path: Nullable,
    #[serde(rename = "Comment")]
    pub(super) _comment: Option<String>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
pub(super) struct RawPass {
    #[serde(rename = "Type")]
    pub(super) _type: String,
    #[serde(rename = "Comment")]
    pub(super) _comment: Option<String>,
    pub(super) result: Option<Value>,
    pub(super) parameters: Option<Value>,
    #[serde(default)]
    pub(super) result_path: Nullable,
    #[serde(default)]
    pub(super) input_path: Nullable,
    #[serde(default)]
    pub(super) output_path: Nullable,
    pub(super) next: Option<String>,
    pub(super) end: Option<bool>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
pub(super) struct RawSucceed {
    #[serde(rename = "Type")]
    pub(super) _type: String,
    #[serde(rename = "Comment")]
    pub(super) _comment: Option<String>,
    #[serde(default)]
    pub(super) input_path: Nullable,
    #[serde(default)]
    pub(super) output_path: Nullable,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
pub(super) struct RawFail {
    #[serde(rename = "Type")]
    pub(super) _type: String,
    #[serde(rename = "Comment")]
    pub(super) _comment: Option<String>,
    pub(super) error: Option<String>,
    pub(super) error_path: Option<String>,
    pub(super) cause: Option<String>,
    pub(super) cause_path: Option<String>,
}

#[derive(Deserialize)]
#[serde(rename_all = "PascalCase", deny_unknown_fields)]
pub(super) struct RawChoice {
    #[serde(rename = "Type")]
    pub(super) _type: String,
    #[serde(rename = "Comment")]
    pub(super) _comment: Option<String>,
    pub(super) choices: Vec<Map<String, Value>>,
    pub(super) default: Option<String>,
    #[serde(default)]
    pub(super) input_path: Nullable,
    #[serde(default)]
    pub(super) output_path: Nullable,
}
