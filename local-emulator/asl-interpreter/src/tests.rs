//! Runs the real `infra/statemachine.asl.json` with fake functions over an in-memory bucket.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

use super::*;

/// HORT's state machine: the definition these tests run.
pub(crate) const HORT_DEFINITION: &str = include_str!("../../../infra/statemachine.asl.json");

/// The error names HORT's definition retries and refuses to retry, as documented in
/// `infra/README.md`.
const RETRYABLE: &str = "Hort.Retryable";
const BAD_INPUT: &str = "Hort.BadInput";

/// An in-memory bucket serving the Map states' items files.
#[derive(Default)]
struct MemoryItems(Mutex<BTreeMap<String, Vec<u8>>>);

impl MemoryItems {
    fn new() -> Self {
        Self::default()
    }
    fn put(&self, key: &str, bytes: &[u8]) {
        self.0
            .lock()
            .unwrap()
            .insert(key.to_owned(), bytes.to_vec());
    }
    fn delete(&self, key: &str) {
        self.0.lock().unwrap().remove(key);
    }
}

impl ItemReader for MemoryItems {
    fn read_object(&self, key: &str) -> Result<Vec<u8>, String> {
        self.0
            .lock()
            .unwrap()
            .get(key)
            .cloned()
            .ok_or_else(|| format!("no object {key}"))
    }
}

const STAGES: [(&str, &str); 5] = [
    ("cast_map", "cast-map"),
    ("cast_reduce", "cast-reduce"),
    ("expand", "expand"),
    ("trace_map", "trace-map"),
    ("trace_reduce", "trace-reduce"),
];

fn items_key(stage: &str) -> String {
    format!("jobs/j1/items/{stage}.json")
}

/// A store holding `count` items per stage, each `{"task": i, "timeout_seconds": timeout}`.
fn store_with_items(count: usize, timeout: u64) -> MemoryItems {
    let store = MemoryItems::new();
    for (_, stage) in STAGES {
        let items: Vec<Value> = (0..count)
            .map(|i| json!({"task": i, "timeout_seconds": timeout}))
            .collect();
        store.put(&items_key(stage), json!(items).to_string().as_bytes());
    }
    store
}

fn input() -> Value {
    json!({"job": "j1", "bucket": "b1"})
}

fn options(slots: usize) -> OrchestratorOptions {
    OrchestratorOptions {
        slots,
        time_scale: 0.001,
        seed: 7,
        cancel: Arc::new(AtomicBool::new(false)),
    }
}

type Behaviour = dyn Fn(&str, &Value, u32) -> Result<Value, TaskFailure> + Send + Sync;

/// A fake Lambda: answers Plan with the items keys, runs `behaviour` for every worker call
/// (stage, event, call number of this (stage, task)), and records calls and concurrency.
struct Fake {
    max_concurrency: u64,
    behaviour: Box<Behaviour>,
    calls: Mutex<Vec<(String, String, Value)>>,
    per_task: Mutex<BTreeMap<(String, u64), u32>>,
    in_flight: AtomicUsize,
    peak: AtomicUsize,
}

impl Fake {
    fn new(
        max_concurrency: u64,
        behaviour: impl Fn(&str, &Value, u32) -> Result<Value, TaskFailure> + Send + Sync + 'static,
    ) -> Arc<Fake> {
        Arc::new(Fake {
            max_concurrency,
            behaviour: Box::new(behaviour),
            calls: Mutex::new(Vec::new()),
            per_task: Mutex::new(BTreeMap::new()),
            in_flight: AtomicUsize::new(0),
            peak: AtomicUsize::new(0),
        })
    }

    fn ok() -> Arc<Fake> {
        Fake::new(0, |_, _, _| Ok(json!({"ok": true})))
    }

    fn calls(&self) -> Vec<(String, String, Value)> {
        self.calls.lock().unwrap().clone()
    }

    /// (stage, task) of every worker call, in call order.
    fn worker_calls(&self) -> Vec<(String, u64, u64)> {
        self.calls()
            .into_iter()
            .filter(|(f, _, _)| f == "WorkerFunctionArn")
            .map(|(_, stage, e)| {
                (
                    stage,
                    e["item"]["task"].as_u64().unwrap(),
                    e["attempt"].as_u64().unwrap(),
                )
            })
            .collect()
    }
}

impl TaskInvoker for Fake {
    fn invoke(&self, resource: &str, input: Value) -> Result<Value, TaskFailure> {
        let now = self.in_flight.fetch_add(1, Ordering::SeqCst) + 1;
        self.peak.fetch_max(now, Ordering::SeqCst);
        let stage = input["stage"].as_str().unwrap_or("plan").to_owned();
        self.calls
            .lock()
            .unwrap()
            .push((resource.to_owned(), stage.clone(), input.clone()));
        let result = match resource {
            "PlanFunctionArn" => {
                assert_eq!(input, json!({"job": "j1", "bucket": "b1", "attempt": 0}));
                let items: serde_json::Map<String, Value> = STAGES
                    .iter()
                    .map(|(field, stage)| (field.to_string(), json!(items_key(stage))))
                    .collect();
                Ok(json!({"items": items, "max_concurrency": self.max_concurrency}))
            }
            "WorkerFunctionArn" => {
                let task = input["item"]["task"].as_u64().unwrap_or(0);
                let n = {
                    let mut per = self.per_task.lock().unwrap();
                    let n = per.entry((stage.clone(), task)).or_insert(0);
                    *n += 1;
                    *n - 1
                };
                (self.behaviour)(&stage, &input, n)
            }
            other => panic!("unexpected function {other}"),
        };
        self.in_flight.fetch_sub(1, Ordering::SeqCst);
        result
    }
}

fn run_with(
    fake: &Arc<Fake>,
    store: &MemoryItems,
    opts: OrchestratorOptions,
) -> (Result<Value, ExecutionFailure>, Vec<Event>) {
    let orchestrator = Orchestrator::new(HORT_DEFINITION, opts).unwrap();
    let log = EventLog::new();
    let invoker: Arc<dyn TaskInvoker> = fake.clone();
    let out = orchestrator.run(input(), invoker, store, &log);
    (out, log.events())
}

#[test]
fn the_hort_definition_loads_and_names_its_functions() {
    let o = Orchestrator::new(HORT_DEFINITION, options(2)).unwrap();
    let functions: Vec<String> = o.functions().into_iter().collect();
    assert_eq!(functions, ["PlanFunctionArn", "WorkerFunctionArn"]);
    assert_eq!(o.machine().start_at, "Plan");
}

#[test]
fn all_stages_run_in_order_with_every_item_once() {
    let fake = Fake::ok();
    let store = store_with_items(4, 60);
    let (out, events) = run_with(&fake, &store, options(3));
    let out = out.unwrap();
    assert_eq!(out["job"], "j1");
    assert_eq!(out["combine"], json!({"output": {"ok": true}}));
    assert_eq!(out["plan"]["max_concurrency"], 0);
    assert!(out.get("failure").is_none());

    let calls = fake.worker_calls();
    let stages: Vec<&str> = calls.iter().map(|(s, _, _)| s.as_str()).collect();
    let mut expected = Vec::new();
    for (_, stage) in STAGES {
        expected.extend([stage; 4]);
    }
    expected.push("combine");
    assert_eq!(stages, expected, "stages run in order, each to completion");
    for (_, stage) in STAGES {
        let mut tasks: Vec<u64> = calls
            .iter()
            .filter(|(s, _, _)| s == stage)
            .map(|(_, t, a)| {
                assert_eq!(*a, 0);
                *t
            })
            .collect();
        tasks.sort_unstable();
        assert_eq!(tasks, [0, 1, 2, 3], "{stage}: every item exactly once");
    }
    // The worker sees exactly the documented event.
    let first = fake
        .calls()
        .into_iter()
        .find(|(_, s, _)| s == "cast-map")
        .unwrap()
        .2;
    assert_eq!(first["job"], "j1");
    assert_eq!(first["bucket"], "b1");
    assert_eq!(first["attempt"], 0);
    assert_eq!(first["item"]["timeout_seconds"], 60);
    assert_eq!(first.as_object().unwrap().len(), 5);

    let entered: Vec<String> = events
        .iter()
        .filter_map(|e| match e {
            Event::StateEntered {
                state,
                item_index: None,
            } => Some(state.clone()),
            _ => None,
        })
        .collect();
    assert_eq!(
        entered,
        [
            "Plan",
            "CastMap",
            "CastReduce",
            "Expand",
            "TraceMap",
            "TraceReduce",
            "Combine",
            "Done"
        ]
    );
    let maps: Vec<(String, usize)> = events
        .iter()
        .filter_map(|e| match e {
            Event::MapStarted { state, items, .. } => Some((state.clone(), *items)),
            _ => None,
        })
        .collect();
    assert_eq!(maps.len(), 5);
    assert!(maps.iter().all(|(_, n)| *n == 4));
}

#[test]
fn retryable_failures_are_retried_with_attempt_numbers() {
    let fake = Fake::new(0, |stage, _, n| {
        if stage == "cast-reduce" && n < 2 {
            Err(TaskFailure::new(RETRYABLE, "storage unavailable"))
        } else {
            Ok(json!({}))
        }
    });
    let store = store_with_items(2, 60);
    let (out, events) = run_with(&fake, &store, options(2));
    out.unwrap();
    for task in 0..2 {
        let attempts: Vec<u64> = fake
            .worker_calls()
            .into_iter()
            .filter(|(s, t, _)| s == "cast-reduce" && *t == task)
            .map(|(_, _, a)| a)
            .collect();
        assert_eq!(
            attempts,
            [0, 1, 2],
            "$$.State.RetryCount reaches the worker"
        );
    }
    let failed: Vec<(u32, bool, Duration)> = events
        .iter()
        .filter_map(|e| match e {
            Event::TaskAttemptFailed {
                state,
                item_index: Some(0),
                attempt,
                error,
                will_retry,
                retry_delay,
                ..
            } if state == "CastReduce/CastReduceTask" => {
                assert_eq!(error, RETRYABLE);
                Some((*attempt, *will_retry, *retry_delay))
            }
            _ => None,
        })
        .collect();
    assert_eq!(failed.len(), 2);
    assert_eq!((failed[0].0, failed[1].0), (0, 1));
    assert!(failed.iter().all(|f| f.1));
    // FULL jitter under the scaled backoff of 1 s, 2 s (time_scale 0.001).
    assert!(failed[0].2 < Duration::from_millis(1) && failed[1].2 < Duration::from_millis(2));
}

#[test]
fn bad_input_is_not_retried_and_fails_the_job_naming_the_state() {
    let fake = Fake::new(0, |stage, e, _| {
        if stage == "expand" && e["item"]["task"] == 1 {
            Err(TaskFailure::new(BAD_INPUT, "split 3 has a NaN vertex"))
        } else {
            Ok(json!({}))
        }
    });
    let store = store_with_items(3, 60);
    let (out, events) = run_with(&fake, &store, options(1));
    let failure = out.unwrap_err();
    assert_eq!(failure.error, EXCEED_TOLERATED_FAILURE);
    assert_eq!(failure.state, "Expand");
    assert!(
        failure
            .cause
            .starts_with("Expand failed: Expand: the Map Run failed because item 1")
            && failure
                .cause
                .contains("Hort.BadInput: split 3 has a NaN vertex"),
        "{}",
        failure.cause
    );
    assert_eq!(
        failure.item.as_deref(),
        Some(&ItemFailure {
            map_state: "Expand".into(),
            index: 1,
            state: "Expand/ExpandTask".into(),
            error: BAD_INPUT.into(),
            cause: "split 3 has a NaN vertex".into(),
        })
    );
    let expand_calls = fake
        .worker_calls()
        .into_iter()
        .filter(|(s, t, _)| s == "expand" && *t == 1)
        .count();
    assert_eq!(expand_calls, 1, "Hort.BadInput is never retried");
    assert!(
        !fake.worker_calls().iter().any(|(s, _, _)| s == "trace-map"),
        "no later stage runs"
    );
    assert!(events.iter().any(|e| matches!(e,
        Event::TaskAttemptFailed { will_retry: false, error, .. } if error == BAD_INPUT)));
    assert!(events.contains(&Event::StateEntered {
        state: "ExpandFailed".into(),
        item_index: None
    }));
}

#[test]
fn a_task_past_its_timeout_is_retried_while_the_zombie_holds_its_slot() {
    // time_scale 0.001: the 20 s timeout is 20 ms; the first attempt of each item sleeps 1 s.
    let fake = Fake::new(0, |stage, _, n| {
        if stage == "trace-map" && n == 0 {
            std::thread::sleep(Duration::from_millis(1000));
        }
        Ok(json!({}))
    });
    let store = store_with_items(2, 20);
    let started = Instant::now();
    let (out, events) = run_with(&fake, &store, options(4));
    out.unwrap();
    assert!(
        started.elapsed() < Duration::from_millis(700),
        "the execution moved on without waiting for the zombies: {:?}",
        started.elapsed()
    );
    let timeouts: Vec<(Option<usize>, u32, bool)> = events
        .iter()
        .filter_map(|e| match e {
            Event::TaskAttemptFailed {
                state,
                item_index,
                attempt,
                error,
                will_retry,
                cause,
                ..
            } if state == "TraceMap/TraceMapTask" => {
                assert_eq!(error, TIMEOUT);
                assert!(cause.contains("timeout of 20 s"), "{cause}");
                Some((*item_index, *attempt, *will_retry))
            }
            _ => None,
        })
        .collect();
    let mut timeouts = timeouts;
    timeouts.sort();
    assert_eq!(timeouts, [(Some(0), 0, true), (Some(1), 0, true)]);
    let attempts: Vec<u64> = fake
        .worker_calls()
        .into_iter()
        .filter(|(s, t, _)| s == "trace-map" && *t == 0)
        .map(|(_, _, a)| a)
        .collect();
    assert_eq!(attempts, [0, 1]);
    // Invocations, zombies included, never exceed the slots.
    assert!(fake.peak.load(Ordering::SeqCst) <= 4);
}

#[test]
fn in_flight_never_exceeds_max_concurrency_or_slots() {
    for (max_concurrency, slots, expect) in [(2, 8, 2), (0, 3, 3), (5, 2, 2)] {
        let fake = Fake::new(max_concurrency, |_, _, _| {
            std::thread::sleep(Duration::from_millis(3));
            Ok(json!({}))
        });
        let store = store_with_items(12, 60);
        let (out, events) = run_with(&fake, &store, options(slots));
        out.unwrap();
        assert_eq!(
            fake.peak.load(Ordering::SeqCst),
            expect,
            "MaxConcurrency {max_concurrency}, slots {slots}"
        );
        assert!(events.iter().all(|e| match e {
            Event::MapStarted { concurrency, .. } => *concurrency == expect,
            _ => true,
        }));
    }
}

#[test]
fn slots_bound_zombies_too() {
    // One slot: the timed-out attempt keeps the slot, so its retry waits for it to end.
    let fake = Fake::new(0, |stage, _, n| {
        if stage == "cast-map" && n == 0 {
            std::thread::sleep(Duration::from_millis(80));
        }
        Ok(json!({}))
    });
    let store = store_with_items(1, 10);
    let started = Instant::now();
    let (out, _) = run_with(&fake, &store, options(1));
    out.unwrap();
    assert_eq!(fake.peak.load(Ordering::SeqCst), 1);
    assert!(started.elapsed() >= Duration::from_millis(80));
}

#[test]
fn cancellation_stops_promptly() {
    let opts = options(2);
    let cancel = opts.cancel.clone();
    let fake = Fake::new(0, move |stage, _, _| {
        if stage == "cast-reduce" {
            cancel.store(true, Ordering::SeqCst);
            std::thread::sleep(Duration::from_millis(500));
        }
        Ok(json!({}))
    });
    let store = store_with_items(6, 600);
    let started = Instant::now();
    let (out, _) = run_with(&fake, &store, opts);
    let failure = out.unwrap_err();
    assert!(
        started.elapsed() < Duration::from_millis(400),
        "{:?}",
        started.elapsed()
    );
    assert_eq!(failure.error, CANCELLED);
    assert!(failure.state.starts_with("CastReduce"), "{}", failure.state);
    let reduce_calls = fake
        .worker_calls()
        .iter()
        .filter(|(s, _, _)| s == "cast-reduce")
        .count();
    assert!(
        reduce_calls <= 2,
        "no new attempts after cancel: {reduce_calls}"
    );
}

#[test]
fn a_missing_items_file_or_foreign_bucket_fails_the_map_clearly() {
    let store = store_with_items(1, 60);
    store.delete(&items_key("trace-map"));
    let (out, _) = run_with(&Fake::ok(), &store, options(2));
    let failure = out.unwrap_err();
    assert_eq!(failure.error, ITEM_READER_FAILED);
    assert_eq!(failure.state, "TraceMap");
    assert!(
        failure
            .cause
            .contains("s3://b1/jobs/j1/items/trace-map.json"),
        "{}",
        failure.cause
    );

    let definition = HORT_DEFINITION.replace("\"Bucket.$\": \"$.bucket\"", "\"Bucket\": \"other\"");
    let o = Orchestrator::new(&definition, options(2)).unwrap();
    let invoker: Arc<dyn TaskInvoker> = Fake::ok();
    let failure = o
        .run(input(), invoker, &store_with_items(1, 60), &NoObserver)
        .unwrap_err();
    assert_eq!(failure.error, ITEM_READER_FAILED);
    assert!(
        failure.cause.contains("\"other\"") && failure.cause.contains("\"b1\""),
        "{}",
        failure.cause
    );
}

#[test]
fn express_children_time_out_after_five_minutes() {
    // Every attempt times out (10 s); retries with backoff push the child past 300 s.
    let definition = HORT_DEFINITION.replace("\"MaxAttempts\": 4", "\"MaxAttempts\": 100");
    let mut opts = options(4);
    opts.time_scale = 0.0002;
    let o = Orchestrator::new(&definition, opts).unwrap();
    let fake = Fake::new(0, |stage, _, _| {
        if stage == "cast-map" {
            std::thread::sleep(Duration::from_millis(3));
        }
        Ok(json!({}))
    });
    let invoker: Arc<dyn TaskInvoker> = fake;
    let failure = o
        .run(input(), invoker, &store_with_items(1, 1), &NoObserver)
        .unwrap_err();
    let item = failure.item.unwrap();
    assert_eq!(item.error, TIMEOUT);
    assert!(item.cause.contains("EXPRESS"), "{}", item.cause);
}

#[test]
fn unusable_options_are_refused() {
    let mut bad = options(1);
    bad.time_scale = 0.0;
    let err = Orchestrator::new(HORT_DEFINITION, bad)
        .unwrap_err()
        .to_string();
    assert!(err.contains("time_scale"), "{err}");
}

#[test]
fn a_fail_state_reports_its_own_error_and_a_runtime_error_is_not_caught() {
    let machine = json!({
        "StartAt": "P",
        "States": {
            "P": {"Type": "Pass", "Result": {"why": "nope"}, "ResultPath": "$.r", "Next": "F"},
            "F": {"Type": "Fail", "Error": "Custom.Error", "CausePath": "States.Format('because {}', $.r.why)"}
        }
    });
    let o = Orchestrator::new(&machine.to_string(), options(1)).unwrap();
    let invoker: Arc<dyn TaskInvoker> = Fake::ok();
    let f = o
        .run(json!({}), invoker.clone(), &MemoryItems::new(), &NoObserver)
        .unwrap_err();
    assert_eq!(
        (f.error.as_str(), f.cause.as_str(), f.state.as_str()),
        ("Custom.Error", "because nope", "F")
    );

    let machine = json!({
        "StartAt": "T",
        "States": {
            "T": {
                "Type": "Task",
                "Resource": "arn:aws:states:::lambda:invoke",
                "Parameters": {"FunctionName": "${WorkerFunctionArn}", "Payload": {"x.$": "$.missing"}},
                "Catch": [{"ErrorEquals": ["States.ALL"], "Next": "Caught"}],
                "End": true
            },
            "Caught": {"Type": "Succeed"}
        }
    });
    let o = Orchestrator::new(&machine.to_string(), options(1)).unwrap();
    let f = o
        .run(json!({}), invoker, &MemoryItems::new(), &NoObserver)
        .unwrap_err();
    assert_eq!(f.error, RUNTIME);
    assert!(f.cause.contains("$.missing"), "{}", f.cause);
}

#[test]
fn plan_failures_are_caught_into_plan_failed() {
    struct PlanFails;
    impl TaskInvoker for PlanFails {
        fn invoke(&self, _: &str, _: Value) -> Result<Value, TaskFailure> {
            Err(TaskFailure::new(BAD_INPUT, "scene.obj line 4: bad face"))
        }
    }
    let o = Orchestrator::new(HORT_DEFINITION, options(1)).unwrap();
    let f = o
        .run(
            input(),
            Arc::new(PlanFails),
            &MemoryItems::new(),
            &NoObserver,
        )
        .unwrap_err();
    assert_eq!(f.error, BAD_INPUT);
    assert_eq!(f.cause, "Plan failed: scene.obj line 4: bad face");
    assert_eq!(f.state, "Plan");
}

#[test]
fn a_panicking_function_fails_like_an_unhandled_lambda_error_and_frees_its_slot() {
    let fake = Fake::new(0, |stage, _, _| {
        if stage == "combine" {
            panic!("boom");
        }
        Ok(json!({}))
    });
    let (out, events) = run_with(&fake, &store_with_items(1, 60), options(1));
    let f = out.unwrap_err();
    assert_eq!((f.error.as_str(), f.state.as_str()), (PANIC, "Combine"));
    assert!(f.cause.contains("boom"), "{}", f.cause);
    // Retried as Lambda.Unknown (5 retries), each attempt getting the single slot back.
    let attempts = events
        .iter()
        .filter(|e| matches!(e, Event::TaskAttemptStarted { state, .. } if state == "Combine"))
        .count();
    assert_eq!(attempts, 6);
}
