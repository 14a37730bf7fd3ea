use std::io::Write;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use hort_core::report::StageReport;

use super::*;

/// A writer whose bytes the test reads afterwards.
#[derive(Clone, Default)]
struct Capture(Arc<Mutex<Vec<u8>>>);

impl Write for Capture {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Capture {
    fn text(&self) -> String {
        String::from_utf8(self.0.lock().unwrap().clone()).unwrap()
    }
}

/// A clock the test sets, in milliseconds.
#[derive(Clone, Default)]
struct Clock(Arc<AtomicU64>);

impl Clock {
    fn set(&self, ms: u64) {
        self.0.store(ms, Ordering::SeqCst);
    }
    fn observe(&self, o: ProgressObserver) -> ProgressObserver {
        let ms = self.0.clone();
        o.with_clock(move || Duration::from_millis(ms.load(Ordering::SeqCst)))
    }
}

fn entered(state: &str, item_index: Option<usize>) -> Event {
    Event::StateEntered {
        state: state.into(),
        item_index,
    }
}

fn map_started(state: &str, items: usize, concurrency: usize) -> Event {
    Event::MapStarted {
        state: state.into(),
        items,
        concurrency,
    }
}

fn attempt(state: &str, item_index: Option<usize>, attempt: u32) -> Event {
    Event::TaskAttemptStarted {
        state: state.into(),
        item_index,
        attempt,
    }
}

fn failed(
    state: &str,
    item: Option<usize>,
    attempt: u32,
    error: &str,
    retry_ms: Option<u64>,
) -> Event {
    Event::TaskAttemptFailed {
        state: state.into(),
        item_index: item,
        attempt,
        error: error.into(),
        cause: format!("cause of {error}\nsecond line"),
        will_retry: retry_ms.is_some(),
        retry_delay: Duration::from_millis(retry_ms.unwrap_or(0)),
    }
}

fn succeeded(state: &str, item_index: Option<usize>, attempt: u32) -> Event {
    Event::TaskSucceeded {
        state: state.into(),
        item_index,
        attempt,
    }
}

fn map_finished(state: &str, succeeded: bool) -> Event {
    Event::MapFinished {
        state: state.into(),
        succeeded,
    }
}

fn state_failed(state: &str, error: &str) -> Event {
    Event::StateFailed {
        state: state.into(),
        error: error.into(),
        cause: "it broke".into(),
        caught: true,
    }
}

fn stats(
    name: &str,
    tasks: u64,
    attempts: u64,
    failed_attempts: u64,
    retries: u64,
    successes: u64,
) -> StageStats {
    StageStats {
        name: name.into(),
        tasks,
        attempts,
        failed_attempts,
        retries,
        successes,
        seconds: 0.0,
    }
}

/// The events of one Map item: attempts fail `fails` times (retried), then succeed.
fn item_events(task: &str, i: usize, fails: u32) -> Vec<Event> {
    let mut v = vec![entered(task, Some(i))];
    for a in 0..fails {
        v.push(attempt(task, Some(i), a));
        v.push(failed(task, Some(i), a, "States.Timeout", Some(10)));
    }
    v.push(attempt(task, Some(i), fails));
    v.push(succeeded(task, Some(i), fails));
    v
}

/// Runs a Map stage with its items spread over `threads` threads.
fn run_map(o: &ProgressObserver, map: &str, items: usize, threads: usize, fails: fn(usize) -> u32) {
    o.event(&entered(map, None));
    o.event(&map_started(map, items, threads));
    let task = format!("{map}/{map}Task");
    thread::scope(|s| {
        for t in 0..threads {
            let task = &task;
            s.spawn(move || {
                for i in (t..items).step_by(threads) {
                    for e in item_events(task, i, fails(i)) {
                        o.event(&e);
                    }
                }
            });
        }
    });
    o.event(&map_finished(map, true));
}

#[test]
fn stats_from_events_of_many_threads() {
    let o = ProgressObserver::new(ProgressMode::Quiet);
    o.event(&entered("Plan", None));
    o.event(&attempt("Plan", None, 0));
    o.event(&failed("Plan", None, 0, "Hort.Retryable", Some(5)));
    o.event(&attempt("Plan", None, 1));
    o.event(&succeeded("Plan", None, 1));
    // 40 items, every third fails once, item 7 twice.
    run_map(&o, "CastMap", 40, 8, |i| match i {
        7 => 2,
        i if i % 3 == 0 => 1,
        _ => 0,
    });
    run_map(&o, "Expand", 13, 5, |_| 0);
    // TraceMap: item 2 fails for good, the Map Run fails, the Catch goes to a Fail state.
    o.event(&entered("TraceMap", None));
    o.event(&map_started("TraceMap", 4, 2));
    thread::scope(|s| {
        s.spawn(|| {
            for e in item_events("TraceMap/TraceMapTask", 0, 0) {
                o.event(&e);
            }
            o.event(&attempt("TraceMap/TraceMapTask", Some(2), 0));
            o.event(&failed(
                "TraceMap/TraceMapTask",
                Some(2),
                0,
                "Hort.BadInput",
                None,
            ));
            o.event(&state_failed("TraceMap/TraceMapTask", "Hort.BadInput"));
        });
        s.spawn(|| {
            for e in item_events("TraceMap/TraceMapTask", 1, 1) {
                o.event(&e);
            }
        });
    });
    o.event(&map_finished("TraceMap", false));
    o.event(&state_failed(
        "TraceMap",
        "States.ExceedToleratedFailureThreshold",
    ));
    o.event(&entered("TraceMapFailed", None));

    let got: Vec<StageStats> = o
        .stage_stats()
        .into_iter()
        .map(|s| {
            assert!(s.seconds >= 0.0, "{s:?}");
            StageStats { seconds: 0.0, ..s }
        })
        .collect();
    // CastMap: 40 items; items 0,3,..,39 (14 of them) fail once, item 7 twice.
    assert_eq!(
        got,
        vec![
            stats("plan", 1, 2, 1, 1, 1),
            stats("cast-map", 40, 40 + 14 + 2, 16, 16, 40),
            stats("expand", 13, 13, 0, 0, 13),
            stats("trace-map", 4, 4, 2, 1, 2),
        ]
    );
}

#[test]
fn stage_times_and_order_follow_the_pipeline() {
    let clock = Clock::default();
    let o = clock.observe(ProgressObserver::new(ProgressMode::Quiet));
    // Events out of pipeline order still come back in pipeline order; Task states outside the
    // stage table keep their state names and come after the known ones.
    clock.set(1000);
    o.event(&entered("Combine", None));
    clock.set(1500);
    o.event(&attempt("Combine", None, 0));
    clock.set(3250);
    o.event(&succeeded("Combine", None, 0));
    clock.set(4000);
    o.event(&entered("ExtraStep", None));
    o.event(&attempt("ExtraStep", None, 0));
    clock.set(4100);
    o.event(&attempt("CastReduce/CastReduceTask", Some(0), 0));
    clock.set(5000);
    let got = o.stage_stats();
    let names: Vec<&str> = got.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["cast-reduce", "combine", "ExtraStep"]);
    assert_eq!(got[1].seconds, 2.25);
    // Still running: measured to now.
    assert_eq!(got[2].seconds, 1.0);
    assert_eq!(got[0].seconds, 0.9);
}

#[test]
fn lines_mode_writes_the_expected_lines() {
    let clock = Clock::default();
    let out = Capture::default();
    let o = clock.observe(ProgressObserver::with_writer(
        ProgressMode::Lines,
        Box::new(out.clone()),
    ));
    assert_eq!(o.mode(), ProgressMode::Lines);
    o.event(&entered("Plan", None));
    o.event(&attempt("Plan", None, 0));
    clock.set(300);
    o.event(&succeeded("Plan", None, 0));
    clock.set(1200);
    o.event(&entered("CastMap", None));
    o.event(&map_started("CastMap", 20, 4));
    let task = "CastMap/CastMapTask";
    for i in 0..20 {
        clock.set(1200 + 100 * i as u64);
        o.event(&attempt(task, Some(i), 0));
        if i == 12 {
            o.event(&failed(task, Some(i), 0, "States.Timeout", Some(410)));
            o.event(&attempt(task, Some(i), 1));
        }
        o.event(&succeeded(task, Some(i), u32::from(i == 12)));
    }
    clock.set(3100);
    o.event(&map_finished("CastMap", true));
    // The Plan function's lost step after the Map Run is bookkeeping: no line, no task.
    o.event(&entered("CastMapLost", None));
    o.event(&attempt("CastMapLost", None, 0));
    o.event(&succeeded("CastMapLost", None, 0));
    o.event(&entered("CastMapCheck", None));
    o.event(&entered("CastReduce", None));
    o.event(&map_started("CastReduce", 2, 2));
    clock.set(3500);
    o.event(&attempt("CastReduce/CastReduceTask", Some(1), 0));
    o.event(&failed(
        "CastReduce/CastReduceTask",
        Some(1),
        0,
        "Hort.BadInput",
        None,
    ));
    o.event(&state_failed("CastReduce/CastReduceTask", "Hort.BadInput"));
    clock.set(3600);
    o.event(&map_finished("CastReduce", false));
    o.event(&state_failed(
        "CastReduce",
        "States.ExceedToleratedFailureThreshold",
    ));
    o.event(&entered("CastReduceFailed", None));

    let expected = "\
[  0.0s] plan: started, 1 task
[  0.3s] plan: done, 1 task, 1 attempt, 0.3s
[  1.2s] cast-map: started, 20 tasks (4 at once)
[  1.3s] cast-map: 2/20 tasks (10%)
[  1.5s] cast-map: 4/20 tasks (20%)
[  1.7s] cast-map: 6/20 tasks (30%)
[  1.9s] cast-map: 8/20 tasks (40%)
[  2.1s] cast-map: 10/20 tasks (50%)
[  2.3s] cast-map: 12/20 tasks (60%)
[  2.4s] cast-map task 12 attempt 0 failed: States.Timeout (will retry in 0.41s)
[  2.5s] cast-map: 14/20 tasks (70%)
[  2.7s] cast-map: 16/20 tasks (80%)
[  2.9s] cast-map: 18/20 tasks (90%)
[  3.1s] cast-map: done, 20 tasks, 21 attempts, 1.9s
[  3.1s] cast-reduce: started, 2 tasks (2 at once)
[  3.5s] cast-reduce task 1 attempt 0 failed: Hort.BadInput: cause of Hort.BadInput (no retry)
[  3.6s] cast-reduce: failed, 0/2 tasks done, 1 attempt, 0.5s
[  3.6s] cast-reduce: States.ExceedToleratedFailureThreshold: it broke
";
    assert_eq!(out.text(), expected);
}

#[test]
fn lines_mode_reports_a_failed_single_task_and_a_rerun_map() {
    let clock = Clock::default();
    let out = Capture::default();
    let o = clock.observe(ProgressObserver::with_writer(
        ProgressMode::Lines,
        Box::new(out.clone()),
    ));
    o.event(&entered("Expand", None));
    o.event(&map_started("Expand", 1, 1));
    o.event(&map_finished("Expand", false));
    clock.set(2000);
    o.event(&map_started("Expand", 1, 1));
    o.event(&attempt("Expand/ExpandTask", Some(0), 0));
    o.event(&succeeded("Expand/ExpandTask", Some(0), 0));
    o.event(&map_finished("Expand", true));
    o.event(&entered("Combine", None));
    o.event(&attempt("Combine", None, 0));
    clock.set(2500);
    o.event(&failed("Combine", None, 0, "Hort.BadInput", None));
    o.event(&state_failed("Combine", "Hort.BadInput"));
    let expected = "\
[  0.0s] expand: started, 1 task (1 at once)
[  0.0s] expand: failed, 0/1 tasks done, 0 attempts, 0.0s
[  2.0s] expand: restarted, 1 task (1 at once)
[  2.0s] expand: done, 1 task, 1 attempt, 2.0s
[  2.0s] combine: started, 1 task
[  2.5s] combine attempt 0 failed: Hort.BadInput: cause of Hort.BadInput (no retry)
[  2.5s] combine: failed, 0/1 tasks done, 1 attempt, 0.5s
[  2.5s] combine: Hort.BadInput: it broke
";
    assert_eq!(out.text(), expected);
    let got = o.stage_stats();
    assert_eq!(
        got[0],
        StageStats {
            seconds: 2.0,
            ..stats("expand", 1, 1, 0, 0, 1)
        }
    );
    assert_eq!(
        got[1],
        StageStats {
            seconds: 0.5,
            ..stats("combine", 1, 1, 1, 0, 0)
        }
    );
}

#[test]
fn bars_mode_draws_to_the_writer_and_quiet_writes_nothing() {
    let out = Capture::default();
    let o = ProgressObserver::with_writer(ProgressMode::Bars, Box::new(out.clone()));
    run_map(&o, "CastMap", 3, 1, |i| u32::from(i == 1));
    let text = out.text();
    assert!(text.contains("cast-map"), "{text:?}");
    assert!(
        text.contains("[##############################] 3/3 tasks, 1 retry, "),
        "{text:?}"
    );
    assert_eq!(o.stage_stats()[0].attempts, 4);

    let quiet = Capture::default();
    let o = ProgressObserver::with_writer(ProgressMode::Quiet, Box::new(quiet.clone()));
    run_map(&o, "CastMap", 3, 2, |_| 1);
    assert_eq!(quiet.text(), "");
    assert_eq!(
        o.stage_stats(),
        vec![StageStats {
            seconds: o.stage_stats()[0].seconds,
            ..stats("cast-map", 3, 6, 3, 3, 3)
        }]
    );
}

#[test]
fn summary_table_is_aligned_with_a_total() {
    let stage = |name: &str, tasks, attempts, seconds, read, written, raw, peak| StageReport {
        name: String::from(name),
        tasks,
        attempts,
        seconds,
        bytes_read: read,
        bytes_written: written,
        bytes_written_raw: raw,
        peak_memory_bytes: peak,
        ..StageReport::default()
    };
    let stages = [
        stage("plan", 1, 1, 0.125, 2_500_000, 10_000, 10_000, 0),
        stage(
            "cast-map",
            70,
            74,
            1.9,
            123_456_789,
            4_000_000,
            12_000_000,
            150 << 20,
        ),
        stage("combine", 1, 1, 0.5, 0, 0, 0, 3 << 19),
    ];
    let mut out = Vec::new();
    print_summary(&stages, &mut out).unwrap();
    let expected = "\
stage     tasks  attempts  time (s)  MB read  MB written  compression  peak MB
plan          1         1      0.12     2.50        0.01        1.00x        -
cast-map     70        74      1.90   123.46        4.00        3.00x    150.0
combine       1         1      0.50     0.00        0.00            -      1.5
------------------------------------------------------------------------------
total        72        76      2.52   125.96        4.01        3.00x    150.0
";
    assert_eq!(String::from_utf8(out).unwrap(), expected);

    let mut out = Vec::new();
    print_summary(&[], &mut out).unwrap();
    assert_eq!(
        String::from_utf8(out).unwrap(),
        "\
stage  tasks  attempts  time (s)  MB read  MB written  compression  peak MB
---------------------------------------------------------------------------
total      0         0      0.00     0.00        0.00            -        -
"
    );
}

#[test]
fn detect_and_stage_names() {
    let mode = ProgressMode::detect();
    assert!(matches!(mode, ProgressMode::Bars | ProgressMode::Lines));
    for (state, name) in [
        ("Plan", "plan"),
        ("CastMap", "cast-map"),
        ("CastReduce/CastReduceTask", "cast-reduce"),
        ("Expand", "expand"),
        ("TraceMap", "trace-map"),
        ("TraceReduce", "trace-reduce"),
        ("Combine", "combine"),
    ] {
        assert_eq!(track::stage_name(state), name);
    }
    assert_eq!(track::stage_name("SomeNewMap"), "SomeNewMap");
}

#[test]
fn breakdown_table_has_each_part_other_and_a_total() {
    use hort_core::report::StageBreakdown;
    let stage = |name: &str, breakdown| StageReport {
        name: String::from(name),
        breakdown,
        ..StageReport::default()
    };
    let stages = [
        stage(
            "plan",
            StageBreakdown {
                orchestration: 0.25,
                ..StageBreakdown::default()
            },
        ),
        stage(
            "cast-map",
            StageBreakdown {
                task: 4.0,
                compute: 2.5,
                encode: 0.5,
                decode: 0.25,
                storage: 0.5,
                invocation: 0.125,
                orchestration: 0.375,
            },
        ),
    ];
    let mut out = Vec::new();
    print_breakdown(&stages, &mut out).unwrap();
    let expected = "\
stage     task s  compute  encode  decode  storage  other  invocation  orchestration
plan        0.00     0.00    0.00    0.00     0.00   0.00        0.00           0.25
cast-map    4.00     2.50    0.50    0.25     0.50   0.25        0.12           0.38
------------------------------------------------------------------------------------
total       4.00     2.50    0.50    0.25     0.50   0.25        0.12           0.62
";
    assert_eq!(String::from_utf8(out).unwrap(), expected);
}
