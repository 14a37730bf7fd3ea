//! Map states: reading the items file, running the children on at most
//! min(MaxConcurrency, slots, items) threads, failing the Map Run on the first failed item, and
//! handing back the results inline (within 256 KiB) or written by the `ResultWriter`.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::thread;

use serde_json::{Value, json};

use super::{
    EXCEED_TOLERATED_FAILURE, EXPRESS_LIMIT_SECONDS, Execution, Failure, Frame, Halt,
    ITEM_READER_FAILED, RESULT_WRITER_FAILED, Step, Stop, lock, next, positive, select,
    within_limit,
};
use crate::ItemFailure;
use crate::definition::{Items, MapState};
use crate::events::Event;

impl Execution<'_> {
    pub(super) fn map<'m>(
        &self,
        map: &'m MapState,
        path: &str,
        name: &str,
        raw: Value,
        frame: &Frame,
    ) -> Result<Step<'m>, Stop> {
        let ctx0 = self.context(name, 0, None);
        let effective = select(&map.io.input_path, raw.clone(), &ctx0)
            .map_err(|e| Stop::Failed(Self::runtime(path, e)))?;
        let outcome = self.with_retries(&map.retry, path, frame, false, |attempt| {
            self.map_run(map, path, name, &effective, attempt, frame)
        })?;
        match outcome {
            Ok((results, attempt)) => {
                let ctx = self.context(name, attempt, None);
                let finish = || -> Result<Value, String> {
                    let selected = match &map.result_selector {
                        Some(s) => s.eval(&results, &ctx)?,
                        None => results.clone(),
                    };
                    let out = map.result_path.apply(raw.clone(), selected)?;
                    select(&map.io.output_path, out, &ctx)
                };
                Ok(Step {
                    output: finish().map_err(|e| Stop::Failed(Self::runtime(path, e)))?,
                    next: next(&map.transition),
                    caught: None,
                })
            }
            Err(failure) => self.catch(&map.catch, path, raw, failure),
        }
    }

    /// Reads the items: the array at `ItemsPath`, or the object `ItemReader.Parameters` names
    /// (`Bucket`, the execution's bucket, and `Key` of a JSON array).
    fn read_items(
        &self,
        map: &MapState,
        path: &str,
        input: &Value,
        ctx: &Value,
    ) -> Result<Vec<Value>, Failure> {
        let reader = match &map.items {
            Items::Reader(reader) => reader,
            Items::Path(items) => {
                return match items.resolve(input, ctx) {
                    Ok(Value::Array(items)) => Ok(items),
                    Ok(other) => Err(Self::runtime(
                        path,
                        format!(
                            "ItemsPath {:?} must select an array, found {other}",
                            items.text
                        ),
                    )),
                    Err(e) => Err(Self::runtime(path, format!("ItemsPath: {e}"))),
                };
            }
        };
        let reader_failed = |cause: String| Failure {
            error: ITEM_READER_FAILED.into(),
            cause: format!("{path}: {cause}"),
            state: path.to_owned(),
            item: None,
        };
        let (bucket, key) = self.s3_parameters(
            ("ItemReader", "reads", "Key"),
            reader,
            path,
            input,
            ctx,
            reader_failed,
        )?;
        let (bucket, key) = (bucket.as_str(), key.as_str());
        let bytes = self
            .items
            .read_object(key)
            .map_err(|e| reader_failed(format!("cannot read items s3://{bucket}/{key}: {e}")))?;
        match serde_json::from_slice::<Value>(&bytes) {
            Ok(Value::Array(items)) => Ok(items),
            Ok(_) => Err(reader_failed(format!(
                "s3://{bucket}/{key} is not a JSON array"
            ))),
            Err(e) => Err(reader_failed(format!(
                "s3://{bucket}/{key} is not valid JSON: {e}"
            ))),
        }
    }

    /// One Map Run: read the items, run the children, collect their outputs in item order.
    fn map_run(
        &self,
        map: &MapState,
        path: &str,
        name: &str,
        input: &Value,
        attempt: u32,
        frame: &Frame,
    ) -> Result<Result<Value, Failure>, Stop> {
        let ctx = self.context(name, attempt, None);
        let items = match self.read_items(map, path, input, &ctx) {
            Ok(items) => items,
            Err(failure) => return Ok(Err(failure)),
        };
        let limit = match &map.max_concurrency {
            None => 0,
            Some(n) => match positive(n, input, &ctx, 0) {
                Ok(n) => n,
                Err(e) => return Ok(Err(Self::runtime(path, e))),
            },
        };
        let limit = if limit == 0 {
            usize::MAX
        } else {
            usize::try_from(limit).unwrap_or(usize::MAX)
        };
        let concurrency = limit.min(self.options.slots.max(1)).min(items.len());
        self.emit(Event::MapStarted {
            state: path.to_owned(),
            items: items.len(),
            concurrency,
        });
        let abort = AtomicBool::new(false);
        let next_item = AtomicUsize::new(0);
        let first_failure: Mutex<Option<(usize, Failure)>> = Mutex::new(None);
        let outputs: Mutex<Vec<Value>> = Mutex::new(vec![Value::Null; items.len()]);
        // The children's inputs, for the result files of a ResultWriter.
        let inputs: Mutex<Vec<Value>> = Mutex::new(match map.result_writer {
            Some(_) => vec![Value::Null; items.len()],
            None => Vec::new(),
        });
        let halt = Halt {
            flag: &abort,
            parent: Some(&frame.halt),
        };
        thread::scope(|s| {
            for _ in 0..concurrency {
                s.spawn(|| {
                    loop {
                        if halt.is_set() {
                            break;
                        }
                        let i = next_item.fetch_add(1, Ordering::SeqCst);
                        let Some(item) = items.get(i) else { break };
                        let child = Frame {
                            map: Some(path),
                            item: Some(i),
                            halt,
                            deadline: map.express.then(|| {
                                self.clock
                                    .now()
                                    .saturating_add(self.scaled(EXPRESS_LIMIT_SECONDS))
                            }),
                        };
                        let child_ctx = self.context(name, attempt, Some((i, item)));
                        let child_input = match &map.item_selector {
                            Some(t) => t.eval(input, &child_ctx),
                            None => Ok(item.clone()),
                        };
                        let child_input = child_input.and_then(|input| {
                            within_limit(&input, path, &format!("the input of item {i}"))
                                .map_err(|f| f.cause)?;
                            Ok(input)
                        });
                        if let (Ok(input), Some(slot)) = (&child_input, lock(&inputs).get_mut(i)) {
                            *slot = input.clone();
                        }
                        let result = match child_input {
                            Ok(child_input) => self.machine(&map.processor, child_input, &child),
                            Err(e) => Err(Stop::Failed(Self::runtime(
                                path,
                                format!("ItemSelector of item {i}: {e}"),
                            ))),
                        };
                        match result {
                            Ok(value) => lock(&outputs)[i] = value,
                            Err(Stop::Failed(failure)) => {
                                lock(&first_failure).get_or_insert((i, failure));
                                abort.store(true, Ordering::SeqCst);
                            }
                            Err(Stop::Halted(_)) => {}
                        }
                    }
                });
            }
        });
        let failed = lock(&first_failure).take();
        self.emit(Event::MapFinished {
            state: path.to_owned(),
            succeeded: failed.is_none() && !frame.halt.is_set(),
        });
        self.check(frame, path)?;
        if let Some((index, failure)) = failed {
            let cause = format!(
                "{path}: the Map Run failed because item {index} failed in {} with {}: {} \
                 (tolerated failures: 0)",
                failure.state, failure.error, failure.cause
            );
            return Ok(Err(Failure {
                error: EXCEED_TOLERATED_FAILURE.into(),
                cause,
                state: path.to_owned(),
                item: Some(Box::new(ItemFailure {
                    map_state: path.to_owned(),
                    index,
                    state: failure.state,
                    error: failure.error,
                    cause: failure.cause,
                })),
            }));
        }
        let outputs = outputs.into_inner().unwrap_or_else(|p| p.into_inner());
        if map.result_writer.is_some() {
            let inputs = inputs.into_inner().unwrap_or_else(|p| p.into_inner());
            return Ok(self.write_results(map, path, name, input, &ctx, &inputs, &outputs));
        }
        let outputs = Value::Array(outputs);
        if let Err(failure) = within_limit(&outputs, path, "the Map's inline result array") {
            return Ok(Err(failure));
        }
        Ok(Ok(outputs))
    }

    /// The `Bucket` and the `Key` (or `Prefix`) an `ItemReader` (or `ResultWriter`) names:
    /// `field` is (its name, what it does to the bucket, the second parameter). Parameters that
    /// do not give both strings are `States.Runtime`; a bucket other than the execution input's
    /// is `failed` (the field's own error).
    fn s3_parameters(
        &self,
        (field, verb, second): (&str, &str, &str),
        template: &crate::paths::Template,
        path: &str,
        input: &Value,
        ctx: &Value,
        failed: impl Fn(String) -> Failure,
    ) -> Result<(String, String), Failure> {
        let params = template
            .eval(input, ctx)
            .map_err(|e| Self::runtime(path, format!("{field}.Parameters: {e}")))?;
        let (Some(bucket), Some(value)) = (
            params.get("Bucket").and_then(Value::as_str),
            params.get(second).and_then(Value::as_str),
        ) else {
            return Err(Self::runtime(
                path,
                format!("{field}.Parameters must give Bucket and {second} strings, got {params}"),
            ));
        };
        if self.bucket.as_deref() != Some(bucket) {
            return Err(failed(format!(
                "{field} {verb} bucket {bucket:?}, but the emulator's store holds only the \
                 execution input's bucket ({:?})",
                self.bucket.as_deref().unwrap_or("none given")
            )));
        }
        Ok((bucket.to_owned(), value.to_owned()))
    }

    /// Writes a successful Map Run's results as a `ResultWriter` of `s3:putObject` does, and
    /// returns the Map's result: `{"MapRunArn", "ResultWriterDetails": {"Bucket", "Key"}}`.
    #[allow(clippy::too_many_arguments)]
    fn write_results(
        &self,
        map: &MapState,
        path: &str,
        name: &str,
        input: &Value,
        ctx: &Value,
        inputs: &[Value],
        outputs: &[Value],
    ) -> Result<Value, Failure> {
        let failed = |cause: String| Failure {
            error: RESULT_WRITER_FAILED.into(),
            cause: format!("{path}: {cause}"),
            state: path.to_owned(),
            item: None,
        };
        let Some(writer) = &map.result_writer else {
            return Err(failed("no ResultWriter".into()));
        };
        let (bucket, prefix) = self.s3_parameters(
            ("ResultWriter", "writes", "Prefix"),
            writer,
            path,
            input,
            ctx,
            failed,
        )?;
        let (bucket, prefix) = (bucket.as_str(), prefix.as_str());
        let run = format!("{name}-{}", self.map_runs.fetch_add(1, Ordering::SeqCst));
        let machine_arn = self.context["StateMachine"]["Id"].as_str().unwrap_or("");
        // AWS: `…:mapRun:{machine}/{label}:{id}`, children `…:express:{machine}/{label}:…`.
        let map_run_arn = format!(
            "{}/{name}:{run}",
            machine_arn.replacen(":stateMachine:", ":mapRun:", 1)
        );
        let child_kind = if map.express {
            ":express:"
        } else {
            ":execution:"
        };
        let child_arn = |i: usize| {
            format!(
                "{}/{name}:{run}:{i}",
                machine_arn.replacen(":stateMachine:", child_kind, 1)
            )
        };
        let records: Vec<Value> = outputs
            .iter()
            .enumerate()
            .map(|(i, output)| {
                json!({
                    "ExecutionArn": child_arn(i),
                    "Name": i.to_string(),
                    "Input": inputs.get(i).unwrap_or(&Value::Null).to_string(),
                    "InputDetails": {"Included": true},
                    "Output": output.to_string(),
                    "OutputDetails": {"Included": true},
                    "StateMachineArn": machine_arn,
                    "Status": "SUCCEEDED",
                })
            })
            .collect();
        let folder = match prefix {
            "" => run.clone(),
            p if p.ends_with('/') => format!("{p}{run}"),
            p => format!("{p}/{run}"),
        };
        let results_key = format!("{folder}/SUCCEEDED_0.json");
        let results = Value::Array(records).to_string().into_bytes();
        let size = results.len();
        let put = |key: &str, bytes: Vec<u8>| {
            self.items
                .write_object(key, bytes)
                .map_err(|e| failed(format!("cannot write s3://{bucket}/{key}: {e}")))
        };
        put(&results_key, results)?;
        let manifest_key = format!("{folder}/manifest.json");
        let manifest = json!({
            "DestinationBucket": bucket,
            "MapRunArn": map_run_arn,
            "ResultFiles": {
                "FAILED": [],
                "PENDING": [],
                "SUCCEEDED": [{"Key": results_key, "Size": size}],
            },
        });
        put(&manifest_key, manifest.to_string().into_bytes())?;
        Ok(json!({
            "MapRunArn": map_run_arn,
            "ResultWriterDetails": {"Bucket": bucket, "Key": manifest_key},
        }))
    }
}
