//! Runs the real `infra/statemachine.asl.json` with fake functions over an in-memory bucket.
//!
//! # No test depends on the machine's speed
//! Executions run on a [`ManualClock`]: virtual time that moves only when a backoff is waited
//! or a fake moves it. An attempt times out only when a test moves the clock past its deadline
//! while it runs; every other attempt is instantaneous and cannot time out however long the
//! machine stalls. Fakes that must outlive something (a zombie past its timeout, an invocation
//! in flight when the run is cancelled) block on the [`Board`] until the event that ends their
//! role has been observed or the run has returned, never for a fixed time; the assertions are
//! about order and counts (the run returned while they were still blocked; the retry started
//! after the zombie ended). A wait a correct interpreter always ends is capped at [`CAP`], and
//! every run asserts no cap was reached.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

use super::*;
use crate::retry::retry_delay;

mod functions;
mod payload;

/// HORT's state machine: the definition these tests run.
pub(crate) const HORT_DEFINITION: &str = include_str!("../../../infra/statemachine.asl.json");

/// The error names HORT's definition retries and refuses to retry, as documented in
/// `infra/README.md`.
const RETRYABLE: &str = "Hort.Retryable";
const BAD_INPUT: &str = "Hort.BadInput";

// The Step Functions error names, as AWS documents them ("Error names" in the Step Functions
// developer guide), written out so the tests check the interpreter against the documented text
// rather than against its own constants (these shadow the crate's constants here).
const TIMEOUT: &str = "States.Timeout";
const RUNTIME: &str = "States.Runtime";
const ITEM_READER_FAILED: &str = "States.ItemReaderFailed";
const EXCEED_TOLERATED_FAILURE: &str = "States.ExceedToleratedFailureThreshold";
/// Not an AWS name: what this interpreter reports for an execution stopped by its cancel flag.
const CANCELLED: &str = "States.Cancelled";
/// How Lambda reports a function that crashed without an error type.
const PANIC: &str = "Lambda.Unknown";

/// The time scale of the tests' executions (virtual time, so it only shows in the numbers).
const SCALE: f64 = 0.001;

/// The longest a fake waits for something a correct interpreter makes happen. Only a broken or
/// deadlocked run reaches it, and [`run_on`] fails the test if any wait did.
const CAP: Duration = Duration::from_secs(30);

/// How long a fake lingers to give a broken interpreter the chance to do what a correct one
/// never does (start a retry while its zombie holds the only slot, exceed a concurrency
/// limit). A correct run passes whatever the machine's speed; this only sets how reliably a
/// broken one is caught.
const GRACE: Duration = Duration::from_millis(50);

const CAST_TASK: &str = "CastMap/CastMapTask";
const TRACE_TASK: &str = "TraceMap/TraceMapTask";

/// `seconds` of the definition's time, as the clock sees it.
fn scaled(seconds: f64) -> Duration {
    Duration::from_secs_f64(seconds * SCALE)
}

/// What the tests' threads see of a run, kept under one lock.
#[derive(Debug, Default)]
struct Seen {
    /// Every event, in arrival order.
    events: Vec<Event>,
    /// Invocations of the fake running now.
    in_flight: usize,
    /// The most that ever ran at once (zombies included).
    peak: usize,
    /// Per stage (`plan` for Plan): (running now, most at once).
    stages: BTreeMap<String, (usize, usize)>,
    /// Invocations still running when the run returned.
    in_flight_at_return: Option<usize>,
    /// Set once the run has returned: blocked fakes may end.
    released: bool,
    /// The waits that reached [`CAP`].
    capped: Vec<String>,
}

impl Seen {
    /// True once attempt `attempt` of `state` for `item` has failed.
    fn attempt_failed(&self, state: &str, item: Option<usize>, attempt: u32) -> bool {
        self.events.iter().any(|e| {
            matches!(e, Event::TaskAttemptFailed { state: s, item_index, attempt: a, .. }
                if s == state && *item_index == item && *a == attempt)
        })
    }
}

/// The observer of a run, and where its fakes wait for what the run does.
#[derive(Debug, Default)]
struct Board {
    seen: Mutex<Seen>,
    changed: Condvar,
}

impl Board {
    fn lock(&self) -> MutexGuard<'_, Seen> {
        self.seen.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Changes what was seen and wakes every waiter.
    fn update<T>(&self, change: impl FnOnce(&mut Seen) -> T) -> T {
        let out = change(&mut self.lock());
        self.changed.notify_all();
        out
    }

    /// Waits at most `limit` for `done`; whether it came.
    fn wait_for(&self, limit: Duration, done: impl Fn(&Seen) -> bool) -> bool {
        let end = Instant::now() + limit;
        let mut seen = self.lock();
        loop {
            if done(&seen) {
                return true;
            }
            let left = end.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return false;
            }
            seen = self
                .changed
                .wait_timeout(seen, left)
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
    }

    /// Waits for something a correct run makes happen; reaching [`CAP`] is recorded and fails
    /// the test in [`run_on`].
    fn wait(&self, what: &str, done: impl Fn(&Seen) -> bool) {
        if !self.wait_for(CAP, done) {
            self.update(|s| s.capped.push(what.to_owned()));
        }
    }

    /// Blocks until the run has returned (a zombie, or an invocation the run abandoned).
    fn until_released(&self) {
        self.wait("the run returns", |s| s.released);
    }

    fn events(&self) -> Vec<Event> {
        self.lock().events.clone()
    }
}

impl Observer for Board {
    fn event(&self, e: &Event) {
        self.update(|s| s.events.push(e.clone()));
    }
}

/// An in-memory bucket serving the Map states' items files and taking their results; clones
/// share the objects.
#[derive(Default, Clone)]
struct MemoryItems(Arc<Mutex<BTreeMap<String, Vec<u8>>>>);

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
    fn keys(&self) -> Vec<String> {
        self.0.lock().unwrap().keys().cloned().collect()
    }
    fn json(&self, key: &str) -> Value {
        serde_json::from_slice(&self.read_object(key).unwrap()).unwrap()
    }
}

impl Bucket for MemoryItems {
    fn read_object(&self, key: &str) -> Result<Vec<u8>, String> {
        self.0
            .lock()
            .unwrap()
            .get(key)
            .cloned()
            .ok_or_else(|| format!("no object {key}"))
    }

    fn write_object(&self, key: &str, bytes: Vec<u8>) -> Result<(), String> {
        self.put(key, &bytes);
        Ok(())
    }
}

const STAGES: [(&str, &str); 5] = [
    ("cast_map", "cast-map"),
    ("cast_reduce", "cast-reduce"),
    ("expand", "expand"),
    ("trace_map", "trace-map"),
    ("trace_reduce", "trace-reduce"),
];

/// The one Map stage of a fused job.
const FUSED_STAGE: (&str, &str) = ("render", "render");

fn items_key(stage: &str) -> String {
    format!("jobs/j1/items/{stage}.json")
}

/// A store holding `count` items per stage, each `{"task": i, "timeout_seconds": timeout}`.
fn store_with_items(count: usize, timeout: u64) -> MemoryItems {
    let store = MemoryItems::new();
    for (_, stage) in STAGES.iter().chain([&FUSED_STAGE]) {
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
        time_scale: SCALE,
        seed: 7,
        cancel: Arc::new(AtomicBool::new(false)),
        functions: crate::FunctionLimits::none(),
    }
}

type Behaviour = dyn Fn(&Fake, &str, &Value, u32) -> Result<Value, TaskFailure> + Send + Sync;

/// A fake Lambda: answers Plan with the items keys, runs `behaviour` for every worker call
/// (the fake, stage, event, call number of this (stage, task)), and records calls and
/// concurrency on its board. Its clock is the one its executions run on.
struct Fake {
    max_concurrency: u64,
    /// Plan answers mode `fused` (items for `render` only) instead of `staged`.
    fused: AtomicBool,
    behaviour: Box<Behaviour>,
    board: Board,
    clock: Arc<ManualClock>,
    calls: Mutex<Vec<(String, String, Value)>>,
    per_task: Mutex<BTreeMap<(String, u64), u32>>,
    /// The bucket of the running execution, for the Plan function's `lost` step.
    bucket: Mutex<Option<MemoryItems>>,
}

/// Counts an invocation out of the board when it ends, panicking or not.
struct Running<'a> {
    board: &'a Board,
    stage: String,
}

impl Drop for Running<'_> {
    fn drop(&mut self) {
        self.board.update(|s| {
            s.in_flight -= 1;
            if let Some(stage) = s.stages.get_mut(&self.stage) {
                stage.0 -= 1;
            }
        });
    }
}

impl Fake {
    fn new(
        max_concurrency: u64,
        behaviour: impl Fn(&Fake, &str, &Value, u32) -> Result<Value, TaskFailure>
        + Send
        + Sync
        + 'static,
    ) -> Arc<Fake> {
        Arc::new(Fake {
            max_concurrency,
            fused: AtomicBool::new(false),
            behaviour: Box::new(behaviour),
            board: Board::default(),
            clock: Arc::new(ManualClock::new()),
            calls: Mutex::new(Vec::new()),
            per_task: Mutex::new(BTreeMap::new()),
            bucket: Mutex::new(None),
        })
    }

    fn ok() -> Arc<Fake> {
        Fake::new(0, |_, _, _, _| Ok(json!({"ok": true})))
    }

    fn calls(&self) -> Vec<(String, String, Value)> {
        self.calls.lock().unwrap().clone()
    }

    /// (stage, task, attempt) of every worker call, in call order.
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

    /// The most invocations that ever ran at once.
    fn peak(&self) -> usize {
        self.board.lock().peak
    }

    /// The Plan function's `lost` step, as `hort_functions` runs it: the lost items of the Map
    /// Run whose manifest is `input.results`, stored beside it.
    fn lost_step(&self, input: &Value) -> Value {
        let bucket = self.bucket.lock().unwrap().clone().expect("a bucket");
        let manifest_key = input["results"].as_str().unwrap();
        let manifest = bucket.json(manifest_key);
        let mut lost: Vec<Value> = Vec::new();
        for file in manifest["ResultFiles"]["SUCCEEDED"].as_array().unwrap() {
            let children = bucket.json(file["Key"].as_str().unwrap());
            for child in children.as_array().unwrap() {
                assert_eq!(child["Status"], "SUCCEEDED");
                let output: Value =
                    serde_json::from_str(child["Output"].as_str().unwrap()).unwrap();
                if let Some(record) = output.get("lost") {
                    lost.push(record.clone());
                }
            }
        }
        lost.sort_by_key(|r| r["item"]["task"].as_u64());
        let rounds = input["round"].clone();
        let Some(first) = lost.first() else {
            return json!({"lost": 0, "rounds": rounds, "items": null, "first": null});
        };
        let key = manifest_key.replace("manifest.json", "lost.json");
        let items: Vec<Value> = lost.iter().map(|r| r["item"].clone()).collect();
        bucket.put(&key, json!(items).to_string().as_bytes());
        json!({
            "lost": lost.len(),
            "rounds": rounds,
            "items": key,
            "first": {"task": first["item"]["task"], "error": first["error"], "cause": first["cause"]},
        })
    }

    /// The HORT definition on this fake's clock.
    fn hort(&self, options: OrchestratorOptions) -> Orchestrator {
        self.machine(HORT_DEFINITION, options)
    }

    /// A definition on this fake's clock.
    fn machine(&self, definition: &str, options: OrchestratorOptions) -> Orchestrator {
        Orchestrator::new(definition, options)
            .unwrap()
            .with_clock(self.clock.clone())
    }
}

impl TaskInvoker for Fake {
    fn invoke(&self, resource: &str, input: Value) -> Result<Value, TaskFailure> {
        let lost_step = input["step"] == "lost";
        let stage = match input["stage"].as_str() {
            Some(stage) if lost_step => format!("lost:{stage}"),
            Some(stage) => stage.to_owned(),
            None => "plan".to_owned(),
        };
        // The call is recorded before the board sees it run, so a test that waits on the board
        // finds the calls it waited for in `calls`, in order.
        self.calls
            .lock()
            .unwrap()
            .push((resource.to_owned(), stage.clone(), input.clone()));
        self.board.update(|s| {
            s.in_flight += 1;
            s.peak = s.peak.max(s.in_flight);
            let (now, peak) = s.stages.entry(stage.clone()).or_default();
            *now += 1;
            *peak = (*peak).max(*now);
        });
        let _running = Running {
            board: &self.board,
            stage: stage.clone(),
        };
        match resource {
            "PlanFunctionArn" if lost_step => Ok(self.lost_step(&input)),
            "PlanFunctionArn" => {
                assert_eq!(input, json!({"job": "j1", "bucket": "b1", "attempt": 0}));
                let fused = self.fused.load(Ordering::Relaxed);
                let stages: &[(&str, &str)] = if fused { &[FUSED_STAGE] } else { &STAGES };
                let items: serde_json::Map<String, Value> = stages
                    .iter()
                    .map(|(field, stage)| (field.to_string(), json!(items_key(stage))))
                    .collect();
                let mode = if fused { "fused" } else { "staged" };
                Ok(
                    json!({"mode": mode, "items": items, "max_concurrency": self.max_concurrency, "shadows": true, "refine_after": false, "results": "jobs/j1/map-results"}),
                )
            }
            "WorkerFunctionArn" => {
                let task = input["item"]["task"].as_u64().unwrap_or(0);
                let n = {
                    let mut per = self.per_task.lock().unwrap();
                    let n = per.entry((stage.clone(), task)).or_insert(0);
                    *n += 1;
                    *n - 1
                };
                (self.behaviour)(self, &stage, &input, n)
            }
            other => panic!("unexpected function {other}"),
        }
    }
}

/// Runs one execution observed by the fake's board; then releases the fakes still blocked,
/// waits for every invocation to end, and fails the test if any wait reached [`CAP`].
fn run_on(
    orchestrator: &Orchestrator,
    fake: &Arc<Fake>,
    input: Value,
    store: &MemoryItems,
) -> (Result<Value, ExecutionFailure>, Vec<Event>) {
    let invoker: Arc<dyn TaskInvoker> = fake.clone();
    *fake.bucket.lock().unwrap() = Some(store.clone());
    let out = orchestrator.run(input, invoker, store, &fake.board);
    fake.board.update(|s| {
        s.in_flight_at_return = Some(s.in_flight);
        s.released = true;
    });
    fake.board
        .wait("every invocation ends once released", |s| s.in_flight == 0);
    let capped = fake.board.lock().capped.clone();
    assert!(capped.is_empty(), "waits that never ended: {capped:?}");
    (out, fake.board.events())
}

/// Runs HORT's definition on the fake's clock.
fn run_with(
    fake: &Arc<Fake>,
    store: &MemoryItems,
    opts: OrchestratorOptions,
) -> (Result<Value, ExecutionFailure>, Vec<Event>) {
    run_on(&fake.hort(opts), fake, input(), store)
}

#[test]
fn the_hort_definition_loads_and_names_its_functions() {
    let o = Orchestrator::new(HORT_DEFINITION, options(2)).unwrap();
    let functions: Vec<String> = o.functions().into_iter().collect();
    assert_eq!(functions, ["PlanFunctionArn", "WorkerFunctionArn"]);
    assert_eq!(o.machine().start_at, "Plan");
}

#[test]
fn a_fused_plan_runs_render_then_combine_and_nothing_staged() {
    let fake = Fake::ok();
    fake.fused.store(true, Ordering::Relaxed);
    let store = store_with_items(3, 60);
    let (out, _) = run_with(&fake, &store, options(2));
    let out = out.unwrap();
    assert_eq!(out["plan"]["mode"], "fused");
    let calls = fake.worker_calls();
    let mut stages: Vec<(&str, u64)> = calls.iter().map(|(s, t, _)| (s.as_str(), *t)).collect();
    stages[..3].sort_unstable();
    assert_eq!(
        stages,
        [("render", 0), ("render", 1), ("render", 2), ("combine", 0)]
    );
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
            "ChooseScene",
            "ChooseMode",
            "CastMap",
            "CastMapLost",
            "CastMapCheck",
            "CastReduce",
            "CastReduceLost",
            "CastReduceCheck",
            "ChooseShadows",
            "Expand",
            "ExpandLost",
            "ExpandCheck",
            "TraceMap",
            "TraceMapLost",
            "TraceMapCheck",
            "TraceReduce",
            "TraceReduceLost",
            "TraceReduceCheck",
            "ChooseRefine",
            "Combine",
            "Done"
        ],
        "no item was lost: no rerun"
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
    let fake = Fake::new(0, |_, stage, _, n| {
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
fn retry_backoff_is_waited_on_the_clock_after_scaling() {
    let fake = Fake::new(0, |_, stage, _, n| {
        if stage == "cast-reduce" && n < 2 {
            Err(TaskFailure::new(RETRYABLE, "storage unavailable"))
        } else {
            Ok(json!({}))
        }
    });
    let orchestrator = fake.hort(options(1));
    let (out, events) = run_on(&orchestrator, &fake, input(), &store_with_items(1, 60));
    out.unwrap();
    let State::Map(map) = &orchestrator.machine().states["CastReduce"] else {
        panic!("CastReduce is a Map")
    };
    let State::Task(task) = &map.processor.states["CastReduceTask"] else {
        panic!("CastReduceTask is a Task")
    };
    // The third retrier (Hort.Retryable, …), with the seed 7 draws for item 0.
    let retrier = &task.retry[2];
    let expected: Vec<Duration> = (0..2)
        .map(|n| retry_delay(retrier, n, 7, "CastReduce/CastReduceTask", Some(0)).mul_f64(SCALE))
        .collect();
    let delays: Vec<Duration> = events
        .iter()
        .filter_map(|e| match e {
            Event::TaskAttemptFailed { retry_delay, .. } => Some(*retry_delay),
            _ => None,
        })
        .collect();
    assert_eq!(delays, expected);
    // The only time that passed is the backoff, waited on the execution's clock.
    assert_eq!(fake.clock.now(), delays.iter().sum::<Duration>());
}

#[test]
fn bad_input_is_not_retried_and_fails_the_job_naming_the_state() {
    let fake = Fake::new(0, |_, stage, e, _| {
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
    // Items time out after 20 s. The first attempt of each TraceMap item is a zombie: once both
    // have called the function (two TraceMap calls at once: nothing can time out before), the
    // clock moves past their deadlines (once, so no retry can time out), and they block until
    // the run has returned. "Called", not "started": an attempt is started before its thread
    // calls the function, so on a loaded machine the clock could otherwise move while one
    // attempt's thread had not yet run, and its retry would call the function first. The
    // zombies are told by the payload's attempt number, not by the order of calls, and wait for
    // the peak, which stays reached (the count running now moves on once retries run).
    let moved = AtomicBool::new(false);
    let fake = Fake::new(0, move |fake, stage, e, _| {
        if stage == "trace-map" && e["attempt"] == 0 {
            fake.board.wait("both zombies run", |s| {
                s.stages.get(stage).is_some_and(|&(_, peak)| peak >= 2)
            });
            if !moved.swap(true, Ordering::SeqCst) {
                fake.clock.advance(scaled(21.0));
            }
            fake.board.until_released();
        }
        Ok(json!({}))
    });
    let store = store_with_items(2, 20);
    let (out, events) = run_with(&fake, &store, options(4));
    out.unwrap();
    assert_eq!(
        fake.board.lock().in_flight_at_return,
        Some(2),
        "the execution moved on without waiting for the zombies"
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
            } if state == TRACE_TASK => {
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
    for task in 0..2 {
        let attempts: Vec<u64> = fake
            .worker_calls()
            .into_iter()
            .filter(|(s, t, _)| s == "trace-map" && *t == task)
            .map(|(_, _, a)| a)
            .collect();
        assert_eq!(attempts, [0, 1]);
    }
    // Invocations, zombies included, never exceed the slots.
    assert!(fake.peak() <= 4);
}

#[test]
fn in_flight_never_exceeds_max_concurrency_or_slots() {
    for (max_concurrency, slots, expect) in [(2, 8, 2), (0, 3, 3), (5, 2, 2)] {
        // The first `expect` items of each stage (claimed first, one per iteration thread)
        // stay in flight until all of them are, proving the limit is reached; then they linger
        // so that an invocation beyond the limit would show in the peak.
        let fake = Fake::new(max_concurrency, move |fake, stage, e, _| {
            let task = e["item"]["task"].as_u64().unwrap();
            if stage != "combine" && task < expect as u64 {
                fake.board.wait("the limit is reached", |s| {
                    s.stages.get(stage).is_some_and(|&(_, peak)| peak >= expect)
                });
                fake.board.wait_for(GRACE, |s| s.in_flight > expect);
            }
            Ok(json!({}))
        });
        let store = store_with_items(12, 60);
        let (out, events) = run_with(&fake, &store, options(slots));
        out.unwrap();
        assert_eq!(
            fake.peak(),
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
    let zombie_ended = Arc::new(AtomicBool::new(false));
    let retry_saw_it_end = Arc::new(AtomicBool::new(false));
    let fake = Fake::new(0, {
        let zombie_ended = zombie_ended.clone();
        let retry_saw_it_end = retry_saw_it_end.clone();
        move |fake, stage, _, n| {
            if stage == "cast-map" {
                if n == 0 {
                    // Past the 10 s timeout; the zombie runs on until the timeout is reported,
                    // and a little longer in case the retry (wrongly) starts beside it.
                    fake.clock.advance(scaled(11.0));
                    fake.board.wait("the attempt times out", |s| {
                        s.attempt_failed(CAST_TASK, Some(0), 0)
                    });
                    fake.board.wait_for(GRACE, |s| s.in_flight > 1);
                    zombie_ended.store(true, Ordering::SeqCst);
                } else {
                    retry_saw_it_end.store(zombie_ended.load(Ordering::SeqCst), Ordering::SeqCst);
                }
            }
            Ok(json!({}))
        }
    });
    let store = store_with_items(1, 10);
    let (out, events) = run_with(&fake, &store, options(1));
    out.unwrap();
    assert_eq!(fake.peak(), 1);
    assert!(
        retry_saw_it_end.load(Ordering::SeqCst),
        "the retry started only after the zombie ended"
    );
    assert!(events.iter().any(|e| matches!(e,
        Event::TaskAttemptFailed { state, attempt: 0, error, will_retry: true, .. }
            if state == CAST_TASK && error == TIMEOUT)));
    let attempts: Vec<u64> = fake
        .worker_calls()
        .into_iter()
        .filter(|(s, _, _)| s == "cast-map")
        .map(|(_, _, a)| a)
        .collect();
    assert_eq!(attempts, [0, 1]);
}

#[test]
fn cancellation_stops_promptly() {
    // The reduce tasks cancel the run and then never end by themselves: the run must return
    // while they are still running.
    let opts = options(2);
    let cancel = opts.cancel.clone();
    let fake = Fake::new(0, move |fake, stage, _, _| {
        if stage == "cast-reduce" {
            cancel.store(true, Ordering::SeqCst);
            fake.board.until_released();
        }
        Ok(json!({}))
    });
    let store = store_with_items(6, 600);
    let (out, _) = run_with(&fake, &store, opts);
    let failure = out.unwrap_err();
    let still_running = fake.board.lock().in_flight_at_return.unwrap();
    assert!(
        still_running >= 1,
        "the run returned without waiting for the cancelled invocation"
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
    let fake = Fake::ok();
    let o = fake.machine(&definition, options(2));
    let (out, _) = run_on(&o, &fake, input(), &store_with_items(1, 60));
    let failure = out.unwrap_err();
    assert_eq!(failure.error, ITEM_READER_FAILED);
    assert!(
        failure.cause.contains("\"other\"") && failure.cause.contains("\"b1\""),
        "{}",
        failure.cause
    );
}

#[test]
fn express_children_time_out_after_five_minutes() {
    // Every attempt times out (10 s): the clock moves past its deadline while it runs, and it
    // runs on until its timeout is reported. Retries with backoff push the child past 300 s.
    let definition = HORT_DEFINITION.replace("\"MaxAttempts\": 4", "\"MaxAttempts\": 100");
    let fake = Fake::new(0, |fake, stage, e, _| {
        if stage == "cast-map" {
            let attempt = u32::try_from(e["attempt"].as_u64().unwrap()).unwrap();
            fake.clock.advance(scaled(11.0));
            fake.board.wait("the attempt times out", |s| {
                s.released || s.attempt_failed(CAST_TASK, Some(0), attempt)
            });
        }
        Ok(json!({}))
    });
    let o = fake.machine(&definition, options(4));
    let (out, events) = run_on(&o, &fake, input(), &store_with_items(1, 10));
    let failure = out.unwrap_err();
    let item = failure.item.unwrap();
    assert_eq!(item.error, TIMEOUT);
    assert!(item.cause.contains("EXPRESS"), "{}", item.cause);
    assert!(fake.clock.now() >= scaled(300.0), "{:?}", fake.clock.now());
    // Every attempt before the limit timed out and was retried: the limit, not the retrier,
    // ended the child.
    let attempts = events
        .iter()
        .filter(|e| matches!(e, Event::TaskAttemptStarted { state, .. } if state == CAST_TASK))
        .count();
    assert!((2..=100).contains(&attempts), "{attempts}");
    assert!(events.iter().all(|e| match e {
        Event::TaskAttemptFailed {
            state,
            error,
            will_retry,
            ..
        } if state == CAST_TASK => error == TIMEOUT && *will_retry,
        _ => true,
    }));
}

#[test]
fn the_real_clock_waits_scaled_wall_clock_time() {
    // Without a test clock: a 2 s backoff and a 3 s timeout at time_scale 0.01. The only
    // attempt with a timeout is the one meant to time out, and it blocks until it has.
    let machine = json!({
        "StartAt": "Flaky",
        "States": {
            "Flaky": {
                "Type": "Task",
                "Resource": "arn:aws:states:::lambda:invoke",
                "Parameters": {"FunctionName": "${WorkerFunctionArn}",
                    "Payload": {"stage": "flaky", "item": {"task": 0}, "attempt.$": "$$.State.RetryCount"}},
                "Retry": [{"ErrorEquals": [RETRYABLE], "IntervalSeconds": 2, "MaxAttempts": 1}],
                "ResultPath": null,
                "Next": "Slow"
            },
            "Slow": {
                "Type": "Task",
                "Resource": "arn:aws:states:::lambda:invoke",
                "Parameters": {"FunctionName": "${WorkerFunctionArn}",
                    "Payload": {"stage": "slow", "item": {"task": 0}, "attempt.$": "$$.State.RetryCount"}},
                "TimeoutSeconds": 3,
                "ResultPath": "$.slow",
                "Catch": [{"ErrorEquals": [TIMEOUT], "ResultPath": "$.timeout", "Next": "Done"}],
                "Next": "Done"
            },
            "Done": {"Type": "Succeed"}
        }
    });
    let fake = Fake::new(0, |fake, stage, _, n| match stage {
        "flaky" if n == 0 => Err(TaskFailure::new(RETRYABLE, "once")),
        "slow" => {
            fake.board.wait("the attempt times out", |s| {
                s.released || s.attempt_failed("Slow", None, 0)
            });
            Ok(json!({}))
        }
        _ => Ok(json!({})),
    });
    let mut opts = options(2);
    opts.time_scale = 0.01;
    let o = Orchestrator::new(&machine.to_string(), opts).unwrap();
    let started = Instant::now();
    let (out, events) = run_on(&o, &fake, json!({}), &MemoryItems::new());
    let elapsed = started.elapsed();
    let out = out.unwrap();
    assert_eq!(out["timeout"]["Error"], TIMEOUT);
    let cause = out["timeout"]["Cause"].as_str().unwrap();
    assert!(cause.contains("timeout of 3 s"), "{cause}");
    let backoff = Duration::from_secs(2).mul_f64(0.01);
    assert!(events.iter().any(|e| matches!(e,
        Event::TaskAttemptFailed { state, retry_delay, will_retry: true, .. }
            if state == "Flaky" && *retry_delay == backoff)));
    // A lower bound only: real time cannot pass faster than the waits it holds.
    assert!(
        elapsed >= backoff + Duration::from_secs(3).mul_f64(0.01),
        "{elapsed:?}"
    );
    assert_eq!(
        fake.clock.now(),
        Duration::ZERO,
        "the test clock was not used"
    );
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
    let fake = Fake::ok();
    let o = fake.machine(&machine.to_string(), options(1));
    let (out, _) = run_on(&o, &fake, json!({}), &MemoryItems::new());
    let f = out.unwrap_err();
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
    let o = fake.machine(&machine.to_string(), options(1));
    let (out, _) = run_on(&o, &fake, json!({}), &MemoryItems::new());
    let f = out.unwrap_err();
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
    // On a clock that never moves, Plan cannot time out however slow the machine.
    let o = Orchestrator::new(HORT_DEFINITION, options(1))
        .unwrap()
        .with_clock(Arc::new(ManualClock::new()));
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
    let fake = Fake::new(0, |_, stage, _, _| {
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

/// The (state, items) of every Map Run, in order.
fn map_runs(events: &[Event]) -> Vec<(String, usize)> {
    events
        .iter()
        .filter_map(|e| match e {
            Event::MapStarted { state, items, .. } => Some((state.clone(), *items)),
            _ => None,
        })
        .collect()
}

#[test]
fn an_item_that_exhausts_its_retries_is_rerun_alone_and_the_job_succeeds() {
    // Task 2 of TraceMap fails its six attempts (1 + 5 retries), then succeeds on the rerun.
    let fake = Fake::new(0, |_, stage, e, n| {
        if stage == "trace-map" && e["item"]["task"] == 2 && n < 6 {
            Err(TaskFailure::new(RETRYABLE, "worker died"))
        } else {
            Ok(json!({}))
        }
    });
    let store = store_with_items(4, 60);
    let (out, events) = run_with(&fake, &store, options(2));
    let out = out.unwrap();
    assert_eq!(out["combine"], json!({"output": {}}));
    let calls: Vec<(u64, u64)> = fake
        .worker_calls()
        .into_iter()
        .filter(|(s, _, _)| s == "trace-map")
        .map(|(_, t, a)| (t, a))
        .collect();
    let task2: Vec<u64> = calls.iter().filter(|c| c.0 == 2).map(|c| c.1).collect();
    assert_eq!(
        task2,
        [0, 1, 2, 3, 4, 5, 0],
        "six attempts, then a fresh child"
    );
    assert_eq!(calls.len(), 3 + 7, "the other items ran once");
    let runs = map_runs(&events);
    assert_eq!(
        runs.iter()
            .map(|(s, n)| (s.as_str(), *n))
            .collect::<Vec<_>>(),
        [
            ("CastMap", 4),
            ("CastReduce", 4),
            ("Expand", 4),
            ("TraceMap", 4),
            ("TraceMapRerun", 1),
            ("TraceReduce", 4),
        ]
    );
    // The rerun ran item 2's own item object.
    let rerun = fake
        .calls()
        .into_iter()
        .rfind(|(_, s, e)| s == "trace-map" && e["item"]["task"] == 2)
        .unwrap()
        .2;
    assert_eq!(rerun["item"], json!({"task": 2, "timeout_seconds": 60}));
    assert_eq!(rerun.as_object().unwrap().len(), 5);
    let order: Vec<String> = fake.worker_calls().into_iter().map(|c| c.0).collect();
    let last_trace_map = order.iter().rposition(|s| s == "trace-map").unwrap();
    let first_trace_reduce = order.iter().position(|s| s == "trace-reduce").unwrap();
    assert!(
        last_trace_map < first_trace_reduce,
        "the rerun ends before the next stage"
    );
}

#[test]
fn an_item_that_keeps_failing_fails_the_job_after_three_reruns_naming_task_and_stage() {
    let fake = Fake::new(0, |_, stage, e, _| {
        if stage == "expand" && e["item"]["task"] == 1 {
            Err(TaskFailure::new(RETRYABLE, "split 3 is corrupt"))
        } else {
            Ok(json!({}))
        }
    });
    let store = store_with_items(3, 60);
    let (out, events) = run_with(&fake, &store, options(2));
    let f = out.unwrap_err();
    assert_eq!(f.error, RETRYABLE);
    assert_eq!(
        f.cause,
        "Expand failed: task 1 still failed after 3 reruns: split 3 is corrupt"
    );
    assert_eq!(f.state, "ExpandFailed");
    let attempts = fake
        .worker_calls()
        .into_iter()
        .filter(|(s, t, _)| s == "expand" && *t == 1)
        .count();
    assert_eq!(
        attempts,
        6 * 4,
        "six attempts in the first run and in each of 3 reruns"
    );
    let runs = map_runs(&events);
    assert_eq!(
        runs.iter()
            .map(|(s, n)| (s.as_str(), *n))
            .collect::<Vec<_>>(),
        [
            ("CastMap", 3),
            ("CastReduce", 3),
            ("Expand", 3),
            ("ExpandRerun", 1),
            ("ExpandRerun", 1),
            ("ExpandRerun", 1),
        ]
    );
    assert!(fake.worker_calls().iter().all(|c| c.0 != "trace-map"));
}

#[test]
fn bad_input_is_never_rerun() {
    let fake = Fake::new(0, |_, stage, e, _| {
        if stage == "cast-map" && e["item"]["task"] == 0 {
            Err(TaskFailure::new(BAD_INPUT, "no such split"))
        } else {
            Ok(json!({}))
        }
    });
    let store = store_with_items(2, 60);
    let (out, events) = run_with(&fake, &store, options(1));
    let f = out.unwrap_err();
    assert_eq!(
        (f.error.as_str(), f.state.as_str()),
        (EXCEED_TOLERATED_FAILURE, "CastMap")
    );
    let item = f.item.unwrap();
    assert_eq!((item.map_state.as_str(), item.index), ("CastMap", 0));
    assert_eq!(
        (item.state.as_str(), item.error.as_str()),
        (CAST_TASK, BAD_INPUT)
    );
    assert!(map_runs(&events).iter().all(|(s, _)| s == "CastMap"));
}

#[test]
fn choice_rules_pick_the_first_match_else_default() {
    let machine = json!({
        "StartAt": "C",
        "States": {
            "C": {"Type": "Choice", "Choices": [
                {"Variable": "$.list[0]", "IsPresent": false, "Next": "Empty"},
                {"Variable": "$.n", "NumericGreaterThanEquals": 3, "Next": "Big"},
                {"Variable": "$.n", "NumericLessThan": 0, "Next": "Negative"}
            ], "Default": "Other"},
            "Empty": {"Type": "Pass", "Result": "empty", "End": true},
            "Big": {"Type": "Pass", "Result": "big", "End": true},
            "Negative": {"Type": "Pass", "Result": "negative", "End": true},
            "Other": {"Type": "Pass", "Result": "other", "End": true}
        }
    });
    let fake = Fake::ok();
    let o = fake.machine(&machine.to_string(), options(1));
    let run = |input: Value| run_on(&o, &fake, input, &MemoryItems::new()).0;
    assert_eq!(run(json!({"list": [], "n": 9})), Ok(json!("empty")));
    assert_eq!(run(json!({"list": [1], "n": 3})), Ok(json!("big")));
    assert_eq!(run(json!({"list": [1], "n": -0.5})), Ok(json!("negative")));
    assert_eq!(run(json!({"list": [1], "n": 1})), Ok(json!("other")));
    let f = run(json!({"list": [1], "n": "3"})).unwrap_err();
    assert_eq!(f.error, RUNTIME);
    assert!(
        f.cause.contains("$.n") && f.cause.contains("number"),
        "{}",
        f.cause
    );

    let machine = json!({
        "StartAt": "C",
        "States": {
            "C": {"Type": "Choice", "Choices": [
                {"Variable": "$.n", "NumericEquals": 1, "Next": "One"}
            ]},
            "One": {"Type": "Succeed"}
        }
    });
    let o = fake.machine(&machine.to_string(), options(1));
    let f = run_on(&o, &fake, json!({"n": 2}), &MemoryItems::new())
        .0
        .unwrap_err();
    assert_eq!(
        (f.error.as_str(), f.state.as_str()),
        ("States.NoChoiceMatched", "C")
    );
}

#[test]
fn string_equals_picks_the_branch_and_a_non_string_is_a_runtime_error() {
    let fake = Fake::ok();
    let machine = json!({
        "StartAt": "C",
        "States": {
            "C": {"Type": "Choice", "Choices": [
                {"Variable": "$.mode", "StringEquals": "fused", "Next": "Fused"}
            ], "Default": "Staged"},
            "Fused": {"Type": "Pass", "Result": "fused", "End": true},
            "Staged": {"Type": "Pass", "Result": "staged", "End": true}
        }
    });
    let o = fake.machine(&machine.to_string(), options(1));
    let run = |input: Value| run_on(&o, &fake, input, &MemoryItems::new()).0;
    assert_eq!(run(json!({"mode": "fused"})).unwrap(), json!("fused"));
    assert_eq!(run(json!({"mode": "staged"})).unwrap(), json!("staged"));
    assert_eq!(run(json!({"mode": "Fused"})).unwrap(), json!("staged"));
    let f = run(json!({"mode": 1})).unwrap_err();
    assert_eq!(f.error, "States.Runtime");
    assert!(
        f.cause
            .contains("the Variable \"$.mode\" must select a string, found 1"),
        "{}",
        f.cause
    );
}

#[test]
fn boolean_equals_picks_the_branch_and_a_non_boolean_is_a_runtime_error() {
    let fake = Fake::ok();
    let machine = json!({
        "StartAt": "C",
        "States": {
            "C": {"Type": "Choice", "Choices": [
                {"Variable": "$.shadows", "BooleanEquals": false, "Next": "Dark"}
            ], "Default": "Lit"},
            "Dark": {"Type": "Pass", "Result": "dark", "End": true},
            "Lit": {"Type": "Pass", "Result": "lit", "End": true}
        }
    });
    let o = fake.machine(&machine.to_string(), options(1));
    let run = |input: Value| run_on(&o, &fake, input, &MemoryItems::new()).0;
    assert_eq!(run(json!({"shadows": false})).unwrap(), json!("dark"));
    assert_eq!(run(json!({"shadows": true})).unwrap(), json!("lit"));
    let f = run(json!({"shadows": "false"})).unwrap_err();
    assert_eq!(f.error, "States.Runtime");
    assert!(
        f.cause
            .contains("the Variable \"$.shadows\" must select true or false, found \"false\""),
        "{}",
        f.cause
    );
    let bad = json!({"StartAt": "C", "States": {"C": {"Type": "Choice", "Choices": [
        {"Variable": "$.shadows", "BooleanEquals": 0, "Next": "C"}]}}});
    let err = Orchestrator::new(&bad.to_string(), options(1)).unwrap_err();
    assert!(
        err.to_string()
            .contains("Choices[0]: BooleanEquals must be true or false"),
        "{err}"
    );
}

#[test]
fn a_map_over_items_path_runs_each_inline_item() {
    let machine = json!({
        "StartAt": "M",
        "States": {
            "M": {
                "Type": "Map",
                "ItemsPath": "$.todo",
                "ItemSelector": {"job.$": "$.job", "stage": "expand", "item.$": "$$.Map.Item.Value.item"},
                "ItemProcessor": {
                    "ProcessorConfig": {"Mode": "DISTRIBUTED", "ExecutionType": "EXPRESS"},
                    "StartAt": "T",
                    "States": {"T": {
                        "Type": "Task",
                        "Resource": "arn:aws:states:::lambda:invoke",
                        "Parameters": {"FunctionName": "${WorkerFunctionArn}", "Payload": {
                            "stage.$": "$.stage", "item.$": "$.item"}},
                        "ResultSelector": {"task.$": "$.Payload.task"},
                        "End": true
                    }}
                },
                "ResultSelector": {"done.$": "$[*].task"},
                "End": true
            }
        }
    });
    let fake = Fake::new(0, |_, _, e, _| Ok(json!({"task": e["item"]["task"]})));
    let o = fake.machine(&machine.to_string(), options(2));
    let input = json!({"job": "j1", "todo": [{"item": {"task": 5}}, {"item": {"task": 9}}]});
    let (out, _) = run_on(&o, &fake, input, &MemoryItems::new());
    assert_eq!(out.unwrap(), json!({"done": [5, 9]}));
    let f = run_on(&o, &fake, json!({"todo": {}}), &MemoryItems::new())
        .0
        .unwrap_err();
    assert_eq!(f.error, RUNTIME);
    assert!(f.cause.contains("ItemsPath"), "{}", f.cause);
}
