//! Where a pipeline stage's time went: the per-stage `breakdown` of the `--report` JSON
//! (docs/ARCHITECTURE.md, section 14), built from the tasks' own measurements
//! ([`TaskMetrics`]) and the wall-clock intervals in which tasks ran.
//!
//! Every figure is a measurement: it differs from run to run, and nothing that must be
//! byte-identical (images, hit buffers, stored objects) depends on it.

use crate::task_metrics::TaskMetrics;
use serde::{Deserialize, Serialize};
use std::time::{Duration, Instant};

/// Seconds of one stage, split by what they were spent on.
///
/// `task`, `compute`, `encode`, `decode`, `storage` and `invocation` are sums over the stage's
/// tasks (one successful attempt per task, like the `bytes_*` fields), so with several tasks at
/// once they may exceed the stage's wall time. `compute + encode + decode + storage <= task`
/// for every task, hence for the sums; the remainder is the task's bookkeeping.
/// `orchestration` is wall-clock time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StageBreakdown {
    /// The tasks' own run time ([`TaskMetrics::task_us`]).
    pub task: f64,
    /// Of `task`: the stage functions (tracing, reducing, routing, shading, assembling).
    pub compute: f64,
    /// Of `task`: encoding and compressing outputs.
    pub encode: f64,
    /// Of `task`: decompressing and decoding inputs (blocks, split objects, the plan).
    pub decode: f64,
    /// Of `task`: waiting inside storage calls (GET and PUT, client retries included).
    pub storage: f64,
    /// Invocation overhead: for each task, the wall time its invoker measured around the
    /// function call minus the task's own time (event decoding, answer encoding, the
    /// container's setup; the HTTP round trip with `--lambda-endpoint`). 0 in process.
    pub invocation: f64,
    /// Wall-clock seconds of the stage during which no function invocation (in process: no
    /// task) was running: the orchestrator's own work (reading the items, starting the Map,
    /// scheduling, waits between retries) that no task hides.
    pub orchestration: f64,
}

impl std::ops::AddAssign for StageBreakdown {
    fn add_assign(&mut self, o: StageBreakdown) {
        self.task += o.task;
        self.compute += o.compute;
        self.encode += o.encode;
        self.decode += o.decode;
        self.storage += o.storage;
        self.invocation += o.invocation;
        self.orchestration += o.orchestration;
    }
}

impl StageBreakdown {
    /// The task-measured parts of `tasks` (the summed metrics of the stage's tasks), with
    /// `invocation` and `orchestration` left at 0.
    pub fn from_tasks(tasks: &TaskMetrics) -> Self {
        let s = |us: u64| us as f64 / 1e6;
        StageBreakdown {
            task: s(tasks.task_us),
            compute: s(tasks.compute_us),
            encode: s(tasks.encode_us),
            decode: s(tasks.decode_us),
            storage: s(tasks.storage_us),
            invocation: 0.0,
            orchestration: 0.0,
        }
    }
}

/// The part of the window `[start, end)` covered by none of the intervals `busy` (each
/// `[from, to)`; intervals may overlap each other and reach outside the window).
pub fn uncovered(start: Instant, end: Instant, busy: &[(Instant, Instant)]) -> Duration {
    if end <= start {
        return Duration::ZERO;
    }
    let mut clipped: Vec<(Instant, Instant)> = busy
        .iter()
        .map(|&(from, to)| (from.max(start), to.min(end)))
        .filter(|(from, to)| from < to)
        .collect();
    clipped.sort();
    let mut covered = Duration::ZERO;
    let mut run: Option<(Instant, Instant)> = None;
    for (from, to) in clipped {
        run = match run {
            Some((a, b)) if from <= b => Some((a, b.max(to))),
            Some((a, b)) => {
                covered += b - a;
                Some((from, to))
            }
            None => Some((from, to)),
        };
    }
    if let Some((a, b)) = run {
        covered += b - a;
    }
    (end - start).saturating_sub(covered)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uncovered_time_is_the_window_minus_the_union_of_busy_intervals() {
        let t0 = Instant::now();
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        let ms = |d: Duration| d.as_millis();
        // Nothing running: the whole window.
        assert_eq!(ms(uncovered(at(0), at(100), &[])), 100);
        // Overlapping, nested and touching intervals count once; parts outside are clipped.
        let busy = [
            (at(10), at(30)),
            (at(20), at(40)),
            (at(25), at(26)),
            (at(40), at(50)),
            (at(90), at(200)),
            (at(0), at(5)),
        ];
        assert_eq!(ms(uncovered(at(0), at(100), &busy)), 100 - 5 - 40 - 10);
        // Intervals wholly outside, empty or reversed ones cover nothing.
        let outside = [(at(200), at(300)), (at(50), at(50)), (at(60), at(55))];
        assert_eq!(ms(uncovered(at(0), at(100), &outside)), 100);
        // An empty or reversed window has no uncovered time.
        assert_eq!(uncovered(at(50), at(50), &[]), Duration::ZERO);
        assert_eq!(uncovered(at(60), at(50), &[]), Duration::ZERO);
    }

    #[test]
    fn task_parts_convert_microseconds_to_seconds() {
        let m = TaskMetrics {
            task_us: 2_000_000,
            compute_us: 1_250_000,
            encode_us: 250_000,
            decode_us: 125_000,
            storage_us: 62_500,
            ..TaskMetrics::default()
        };
        let b = StageBreakdown::from_tasks(&m);
        assert_eq!(
            (b.task, b.compute, b.encode, b.decode, b.storage),
            (2.0, 1.25, 0.25, 0.125, 0.0625)
        );
        assert_eq!((b.invocation, b.orchestration), (0.0, 0.0));
    }
}
