//! Lambda's own limits on a function, as its deployment sets them: an invocation over the
//! function's reserved concurrency is throttled (`Lambda.TooManyRequestsException`), not
//! queued; an invocation past the function's timeout is stopped (`Sandbox.Timedout`) whatever
//! the state's `TimeoutSeconds`, and its seat is free from then on.

use super::*;
use crate::{FunctionLimit, FunctionLimits};

/// Lambda's error names, written out (see the note on the error names in `tests.rs`).
const THROTTLED: &str = "Lambda.TooManyRequestsException";
const FUNCTION_TIMED_OUT: &str = "Sandbox.Timedout";

/// A Map of `jobs/j1/items/x.json` running two children at once, each invoking the Worker
/// once, with a Retry of `retry_throttles` attempts on throttling, 10 s apart.
fn two_at_once(retry_throttles: u32) -> String {
    json!({
        "StartAt": "M",
        "States": {"M": {
            "Type": "Map",
            "MaxConcurrency": 2,
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
                    "Retry": [{"ErrorEquals": [THROTTLED], "IntervalSeconds": 10,
                        "MaxAttempts": retry_throttles, "BackoffRate": 1.0}],
                    "OutputPath": "$.Payload",
                    "End": true
                }}
            },
            "ResultSelector": {},
            "End": true
        }}
    })
    .to_string()
}

fn worker(reserved: Option<usize>, timeout_seconds: Option<f64>) -> OrchestratorOptions {
    OrchestratorOptions {
        functions: FunctionLimits::none().with(
            "WorkerFunctionArn",
            FunctionLimit {
                reserved_concurrency: reserved,
                timeout_seconds,
            },
        ),
        ..options(2)
    }
}

fn throttled(s: &Seen) -> bool {
    s.events
        .iter()
        .any(|e| matches!(e, Event::TaskAttemptFailed { error, .. } if error == THROTTLED))
}

/// The child that gets the only seat holds it until the other child has been throttled.
fn hold_the_seat_until_throttled() -> Arc<Fake> {
    Fake::new(0, |fake, _, _, _| {
        fake.board.wait("the other child is throttled", throttled);
        Ok(json!({}))
    })
}

#[test]
fn an_invocation_over_reserved_concurrency_is_throttled_not_queued() {
    // Two machine slots and MaxConcurrency 2, but the Worker has one reserved seat.
    let fake = hold_the_seat_until_throttled();
    let store = MemoryItems::new();
    store.put("jobs/j1/items/x.json", b"[{\"task\": 0}, {\"task\": 1}]");
    let o = fake.machine(&two_at_once(0), worker(Some(1), None));
    let (out, _) = run_on(&o, &fake, input(), &store);
    let failure = out.unwrap_err();
    assert_eq!(failure.error, EXCEED_TOLERATED_FAILURE);
    let item = failure.item.unwrap();
    assert_eq!(item.error, THROTTLED);
    assert!(
        item.cause.starts_with("Rate Exceeded.")
            && item.cause.contains(
                "WorkerFunctionArn has a reserved concurrency of 1, all in use (M/T, attempt 0)"
            ),
        "{}",
        item.cause
    );
    assert_eq!(fake.peak(), 1);

    // With a Retry, the throttled child runs once the seat is free: never two at once. On
    // real time (10 ms between retries, up to 1,000 of them): on the test clock the retries
    // would cost no time and could all be spent before the seat's holder returns.
    let fake = hold_the_seat_until_throttled();
    let o = Orchestrator::new(&two_at_once(1000), worker(Some(1), None)).unwrap();
    let (out, events) = run_on(&o, &fake, input(), &store);
    out.unwrap();
    assert_eq!(fake.peak(), 1);
    assert!(events.iter().any(|e| matches!(e,
        Event::TaskAttemptFailed { error, will_retry: true, .. } if error == THROTTLED)));

    // Unreserved, both run at once.
    let fake = Fake::new(0, |fake, _, _, _| {
        fake.board.wait("both run", |s| s.peak == 2);
        Ok(json!({}))
    });
    let o = fake.machine(&two_at_once(0), worker(None, None));
    run_on(&o, &fake, input(), &store).0.unwrap();
    assert_eq!(fake.peak(), 2);
}

#[test]
fn a_function_is_stopped_at_its_own_timeout_whatever_the_states_timeout_and_frees_its_seat() {
    // The state's timeout is 10 s, the Worker's own 5 s, with one reserved seat. The first
    // CastMap attempt runs 6 s and on: Lambda stops it at 5 s (Sandbox.Timedout, retried by
    // HORT's definition), and its retry gets the seat while the stopped handler still runs.
    let fake = Fake::new(0, |fake, stage, _, n| {
        if stage == "cast-map" && n == 0 {
            fake.clock.advance(scaled(6.0));
            fake.board
                .wait("the retry runs beside the stopped attempt", |s| s.peak == 2);
        }
        Ok(json!({}))
    });
    let store = store_with_items(1, 10);
    let (out, events) = run_with(&fake, &store, worker(Some(1), Some(5.0)));
    out.unwrap();
    let failed: Vec<(String, String, bool)> = events
        .iter()
        .filter_map(|e| match e {
            Event::TaskAttemptFailed {
                state,
                error,
                cause,
                will_retry,
                ..
            } => Some((state.clone(), format!("{error}: {cause}"), *will_retry)),
            _ => None,
        })
        .collect();
    assert_eq!(failed.len(), 1, "{failed:?}");
    let (state, message, will_retry) = &failed[0];
    assert_eq!(state, CAST_TASK);
    assert!(will_retry);
    assert!(
        message.starts_with(&format!(
            "{FUNCTION_TIMED_OUT}: {CAST_TASK}: attempt 0: Task timed out after 5.00 seconds"
        )),
        "{message}"
    );
    assert_eq!(fake.peak(), 2, "the retry ran beside the stopped attempt");
}
