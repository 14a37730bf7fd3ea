//! Progress of a `hort render` execution: an [`Observer`] that shows each pipeline stage as it
//! runs and counts its tasks and attempts, and the final summary table ([`print_summary`]).
//!
//! Three ways to show progress ([`ProgressMode`]):
//! - [`ProgressMode::Bars`] (a terminal): one indicatif bar per stage as it starts,
//!   `cast-map     [#####-----] 37/70 tasks, 3 retries`, left behind with the stage's time when
//!   it ends; failures that are not retried are printed above the bars.
//! - [`ProgressMode::Lines`] (not a terminal): plain log lines with the time since the observer
//!   was made: `[  1.2s] cast-map: started, 70 tasks (4 at once)`, one line per failed attempt,
//!   one every 10% of a Map's items, and `[  3.1s] cast-map: done, 70 tasks, 74 attempts, 1.9s`.
//! - [`ProgressMode::Quiet`]: nothing shown; the counts are still kept.
//!
//! Stages are the top-level states that run a Map or a Task: `CastMap` is `cast-map`, `Plan` is
//! `plan` and so on (other names are turned into kebab case). A stage's clock starts when its
//! state is entered and stops when its Map Run ends or its single task succeeds or fails.

mod summary;
mod term;
#[cfg(test)]
mod tests;
mod track;

use std::collections::HashMap;
use std::io::{IsTerminal, Write};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{MultiProgress, ProgressDrawTarget};

use track::{Inner, Stage};

use asl_interpreter::{Event, Observer};
pub use summary::{print_breakdown, print_summary};

/// How progress is shown.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProgressMode {
    /// One progress bar per stage (for a terminal).
    Bars,
    /// Plain log lines (for a log file or pipe).
    Lines,
    /// Nothing shown; statistics are still recorded.
    Quiet,
}

impl ProgressMode {
    /// [`Bars`](Self::Bars) if standard error is a terminal, else [`Lines`](Self::Lines).
    pub fn detect() -> Self {
        if std::io::stderr().is_terminal() {
            Self::Bars
        } else {
            Self::Lines
        }
    }
}

/// What one stage did, as seen through the events.
#[derive(Debug, Clone, PartialEq)]
pub struct StageStats {
    /// The stage name (`cast-map`, `plan`, …).
    pub name: String,
    /// Map items of its (last) Map Run, or 1 for a single-task stage.
    pub tasks: u64,
    /// Task attempts started.
    pub attempts: u64,
    /// Task attempts that failed (retried or not).
    pub failed_attempts: u64,
    /// Failed attempts after which a retry was scheduled.
    pub retries: u64,
    /// Task attempts that succeeded.
    pub successes: u64,
    /// Wall-clock seconds from the stage's first event to its end (to now if still running).
    pub seconds: f64,
}

type Clock = Box<dyn Fn() -> Duration + Send + Sync>;

/// Shows progress of an execution and records per-stage statistics. Events may arrive from
/// many threads; they are handled one at a time under a lock (no I/O but the progress output).
pub struct ProgressObserver {
    mode: ProgressMode,
    clock: Clock,
    inner: Mutex<Inner>,
}

impl std::fmt::Debug for ProgressObserver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ProgressObserver")
            .field("mode", &self.mode)
            .finish_non_exhaustive()
    }
}

impl ProgressObserver {
    /// An observer showing progress on standard error.
    pub fn new(mode: ProgressMode) -> Self {
        let target = match mode {
            ProgressMode::Bars => ProgressDrawTarget::stderr(),
            _ => ProgressDrawTarget::hidden(),
        };
        Self::build(mode, Box::new(std::io::stderr()), target)
    }

    /// An observer writing its lines (Lines mode) or bars (Bars mode, drawn with ANSI cursor
    /// moves and redrawn on every change) to `out` instead of standard error.
    pub fn with_writer(mode: ProgressMode, out: Box<dyn Write + Send>) -> Self {
        match mode {
            ProgressMode::Bars => {
                let target = ProgressDrawTarget::term_like(Box::new(term::WriterTerm::new(out)));
                Self::build(mode, Box::new(std::io::sink()), target)
            }
            _ => Self::build(mode, out, ProgressDrawTarget::hidden()),
        }
    }

    /// Replaces the clock: `clock()` is the time since the observer started (used for line
    /// timestamps and stage times). Tests use a scripted clock.
    pub fn with_clock(mut self, clock: impl Fn() -> Duration + Send + Sync + 'static) -> Self {
        self.clock = Box::new(clock);
        self
    }

    fn build(mode: ProgressMode, out: Box<dyn Write + Send>, target: ProgressDrawTarget) -> Self {
        let start = Instant::now();
        Self {
            mode,
            clock: Box::new(move || start.elapsed()),
            inner: Mutex::new(Inner {
                out: (mode == ProgressMode::Lines).then_some(out),
                multi: (mode == ProgressMode::Bars)
                    .then(|| MultiProgress::with_draw_target(target)),
                entered: HashMap::new(),
                stages: Vec::new(),
            }),
        }
    }

    /// How this observer shows progress.
    pub fn mode(&self) -> ProgressMode {
        self.mode
    }

    /// Statistics of every stage seen so far, in pipeline order.
    pub fn stage_stats(&self) -> Vec<StageStats> {
        let now = (self.clock)();
        let inner = self.lock();
        let mut stages: Vec<&Stage> = inner.stages.iter().collect();
        stages.sort_by_key(|s| s.rank);
        stages
            .into_iter()
            .map(|s| StageStats {
                seconds: s.seconds(now),
                ..s.stats.clone()
            })
            .collect()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|p| p.into_inner())
    }
}

impl Observer for ProgressObserver {
    fn event(&self, e: &Event) {
        let now = (self.clock)();
        self.lock().handle(e, now);
    }
}
