//! Step Functions' 256 KiB payload quota and the `ResultWriter` that keeps a Map's results out
//! of it: over the quota an execution fails with `States.DataLimitExceeded`, which no Retry or
//! Catch matches; with a `ResultWriter` the same Map succeeds and its results are in the bucket
//! in AWS's format.

use super::*;

const DATA_LIMIT_EXCEEDED: &str = "States.DataLimitExceeded";

/// A Map over `jobs/j1/items/x.json` whose children each run the Worker, with a Catch of
/// `States.ALL` that would hide any catchable failure, and a `ResultWriter` when `write`.
fn map_machine(write: bool) -> Value {
    let mut map = json!({
        "Type": "Map",
        "ItemReader": {
            "Resource": "arn:aws:states:::s3:getObject",
            "ReaderConfig": {"InputType": "JSON"},
            "Parameters": {"Bucket.$": "$.bucket", "Key": "jobs/j1/items/x.json"}
        },
        "ItemSelector": {"stage": "expand", "item.$": "$$.Map.Item.Value"},
        "ItemProcessor": {
            "ProcessorConfig": {"Mode": "DISTRIBUTED", "ExecutionType": "EXPRESS"},
            "StartAt": "T",
            "States": {"T": {
                "Type": "Task",
                "Resource": "arn:aws:states:::lambda:invoke",
                "Parameters": {"FunctionName": "${WorkerFunctionArn}", "Payload": {
                    "stage.$": "$.stage", "item.$": "$.item"}},
                "OutputPath": "$.Payload",
                "End": true
            }}
        },
        "Catch": [{"ErrorEquals": ["States.ALL"], "ResultPath": "$.failure", "Next": "Caught"}],
        "Next": "Done"
    });
    if write {
        map["ResultWriter"] = json!({
            "Resource": "arn:aws:states:::s3:putObject",
            "Parameters": {"Bucket.$": "$.bucket", "Prefix": "jobs/j1/map-results"}
        });
    }
    json!({
        "StartAt": "M",
        "States": {
            "M": map,
            "Caught": {"Type": "Pass", "End": true},
            "Done": {"Type": "Pass", "End": true}
        }
    })
}

fn store_with(count: usize) -> MemoryItems {
    let store = MemoryItems::new();
    let items: Vec<Value> = (0..count).map(|i| json!({"task": i})).collect();
    store.put("jobs/j1/items/x.json", json!(items).to_string().as_bytes());
    store
}

/// 3,000 children answering 100 bytes each: 300 KB of results, over 256 KiB inline.
#[test]
fn inline_map_results_over_256_kib_fail_uncaught_and_a_result_writer_keeps_them_out() {
    let pad = "x".repeat(80);
    let fake = Fake::new(0, move |_, _, e, _| {
        Ok(json!({"task": e["item"]["task"], "pad": pad}))
    });
    let store = store_with(3000);
    let inline = fake.machine(&map_machine(false).to_string(), options(4));
    let (out, events) = run_on(&inline, &fake, input(), &store);
    let failure = out.unwrap_err();
    assert_eq!(failure.error, DATA_LIMIT_EXCEEDED);
    assert_eq!(failure.state, "M");
    assert!(
        failure
            .cause
            .starts_with("M: the Map's inline result array is ")
            && failure
                .cause
                .ends_with(" bytes, over Step Functions' 262144-byte (256 KiB) payload quota"),
        "{}",
        failure.cause
    );
    assert!(
        !events
            .iter()
            .any(|e| matches!(e, Event::StateEntered { state, .. } if state == "Caught")),
        "States.ALL must not catch States.DataLimitExceeded"
    );

    let written = fake.machine(&map_machine(true).to_string(), options(4));
    let (out, _) = run_on(&written, &fake, input(), &store);
    let out = out.unwrap();
    let manifest_key = "jobs/j1/map-results/M-0/manifest.json";
    assert_eq!(
        out,
        json!({
            "MapRunArn": "arn:aws:states:local:000000000000:mapRun:hort/M:M-0",
            "ResultWriterDetails": {"Bucket": "b1", "Key": manifest_key}
        })
    );
    let manifest = store.json(manifest_key);
    let results_key = "jobs/j1/map-results/M-0/SUCCEEDED_0.json";
    let size = store.read_object(results_key).unwrap().len();
    assert_eq!(
        manifest,
        json!({
            "DestinationBucket": "b1",
            "MapRunArn": "arn:aws:states:local:000000000000:mapRun:hort/M:M-0",
            "ResultFiles": {"FAILED": [], "PENDING": [],
                "SUCCEEDED": [{"Key": results_key, "Size": size}]}
        })
    );
    let children = store.json(results_key);
    let children = children.as_array().unwrap();
    assert_eq!(children.len(), 3000);
    for (i, child) in children.iter().enumerate() {
        assert_eq!(child["Status"], "SUCCEEDED");
        let output: Value = serde_json::from_str(child["Output"].as_str().unwrap()).unwrap();
        assert_eq!(output["task"], i, "results are in item order");
        let input: Value = serde_json::from_str(child["Input"].as_str().unwrap()).unwrap();
        assert_eq!(input, json!({"stage": "expand", "item": {"task": i}}));
        assert_eq!(
            child["ExecutionArn"],
            format!("arn:aws:states:local:000000000000:express:hort/M:M-0:{i}")
        );
    }
}

/// A function result over 256 KiB fails the Task with `States.DataLimitExceeded`: not retried
/// (one attempt, though `States.ALL` is retried) and not caught.
#[test]
fn a_function_result_over_256_kib_is_neither_retried_nor_caught() {
    let machine = json!({
        "StartAt": "T",
        "States": {
            "T": {
                "Type": "Task",
                "Resource": "arn:aws:states:::lambda:invoke",
                "Parameters": {"FunctionName": "${WorkerFunctionArn}", "Payload": {"stage": "combine", "item": {"task": 0}}},
                "Retry": [{"ErrorEquals": ["States.ALL"], "MaxAttempts": 3}],
                "Catch": [{"ErrorEquals": ["States.ALL"], "Next": "Caught"}],
                "End": true
            },
            "Caught": {"Type": "Pass", "End": true}
        }
    });
    let big = "y".repeat(262_144);
    let fake = Fake::new(0, move |_, _, _, _| Ok(json!(big)));
    let o = fake.machine(&machine.to_string(), options(1));
    let (out, _) = run_on(&o, &fake, input(), &MemoryItems::new());
    let failure = out.unwrap_err();
    assert_eq!(failure.error, DATA_LIMIT_EXCEEDED);
    assert_eq!(
        failure.cause,
        "T: the function's result is 262146 bytes, over Step Functions' 262144-byte (256 KiB) \
         payload quota"
    );
    assert_eq!(fake.calls().len(), 1, "one attempt");
}

/// HORT's definition with 90,000 CastMap tasks (one task in each other stage): every Map's
/// results go through its ResultWriter, so the job succeeds; the same definition with the
/// ResultWriters taken out fails in CastMap with `States.DataLimitExceeded` (each child's `{}`
/// and comma are 270,001 bytes of inline results), skipping the Catch into `CastMapFailed`.
#[test]
fn a_hort_stage_of_90000_tasks_fits_only_with_its_result_writer() {
    const TASKS: usize = 90_000;
    let fake = Fake::ok();
    let store = store_with_items(1, 60);
    let items: Vec<Value> = (0..TASKS)
        .map(|i| json!({"task": i, "timeout_seconds": 60}))
        .collect();
    store.put(&items_key("cast-map"), json!(items).to_string().as_bytes());
    let (out, _) = run_with(&fake, &store, options(2));
    out.unwrap();
    assert_eq!(fake.worker_calls().len(), TASKS + 4 + 1);

    let mut machine: Value = serde_json::from_str(HORT_DEFINITION).unwrap();
    for state in machine["States"].as_object_mut().unwrap().values_mut() {
        if let Some(map) = state
            .as_object_mut()
            .filter(|s| s.contains_key("ResultWriter"))
        {
            map.remove("ResultWriter");
        }
    }
    let fake = Fake::ok();
    let stripped = fake.machine(&machine.to_string(), options(2));
    let (out, events) = run_on(&stripped, &fake, input(), &store);
    let failure = out.unwrap_err();
    assert_eq!(failure.error, DATA_LIMIT_EXCEEDED);
    assert_eq!(failure.state, "CastMap");
    assert!(
        !events
            .iter()
            .any(|e| matches!(e, Event::StateEntered { state, .. } if state == "CastMapFailed")),
        "the Catch into CastMapFailed must not see States.DataLimitExceeded"
    );
    let keys = store.keys();
    assert!(
        !keys
            .iter()
            .any(|k| k.contains("manifest.json") && k.contains("CastMap-1")),
        "{keys:?}"
    );
}
