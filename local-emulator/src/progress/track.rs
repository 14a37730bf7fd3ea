//! The bookkeeping behind [`ProgressObserver`](super::ProgressObserver): per-stage counts and
//! the Lines/Bars output, updated one event at a time under the observer's lock.

use std::collections::HashMap;
use std::io::Write;
use std::time::Duration;

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

use super::StageStats;
use asl_interpreter::Event;

pub(super) struct Inner {
    /// Lines mode: where lines go.
    pub(super) out: Option<Box<dyn Write + Send>>,
    /// Bars mode: the bars.
    pub(super) multi: Option<MultiProgress>,
    /// When each top-level state was first entered.
    pub(super) entered: HashMap<String, Duration>,
    pub(super) stages: Vec<Stage>,
}

pub(super) struct Stage {
    pub(super) state: String,
    pub(super) stats: StageStats,
    /// Position in the stage table (`Stage::ALL`), or after it in order of appearance.
    pub(super) rank: usize,
    /// A top-level Task (not a Map).
    pub(super) single: bool,
    pub(super) first: Duration,
    pub(super) finished: Option<Duration>,
    /// Map Runs started.
    pub(super) runs: u32,
    /// Items done in the current Map Run.
    pub(super) done: u64,
    /// Last tenth of the items reported (Lines mode).
    pub(super) decile: u64,
    pub(super) bar: Option<ProgressBar>,
}

pub(super) use crate::emulator::stage_name;

/// The top-level state of a path, and whether the path is that state itself.
fn top(path: &str) -> (&str, bool) {
    match path.split_once('/') {
        Some((top, _)) => (top, false),
        None => (path, true),
    }
}

/// `1 task`, `2 tasks`.
fn count(n: u64, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

fn secs(d: Duration) -> f64 {
    d.as_secs_f64()
}

impl Stage {
    pub(super) fn seconds(&self, now: Duration) -> f64 {
        secs(self.finished.unwrap_or(now).saturating_sub(self.first))
    }

    fn retries_message(&self) -> String {
        match self.stats.retries {
            0 => String::new(),
            n => format!(", {}", count(n, "retry", "retries")),
        }
    }
}

impl Inner {
    pub(super) fn handle(&mut self, e: &Event, now: Duration) {
        match e {
            // The Plan function's lost step after each Map Run (`CastMapLost`) is no task of
            // the stage; only its failure is shown (below).
            Event::TaskAttemptStarted { state, .. } | Event::TaskSucceeded { state, .. }
                if hort_core::stage::is_lost_step(state) => {}
            Event::StateEntered { state, .. } => {
                if let (top, true) = top(state) {
                    self.entered.entry(top.to_owned()).or_insert(now);
                }
            }
            Event::MapStarted {
                state,
                items,
                concurrency,
            } => {
                let (top, true) = top(state) else { return };
                let items = *items as u64;
                let i = self.stage(top, false, now);
                let s = &mut self.stages[i];
                let restarted = s.runs > 0;
                s.runs += 1;
                s.stats.tasks = items;
                s.done = 0;
                s.decile = 0;
                s.finished = None;
                let line = format!(
                    "{}: {}started, {} ({concurrency} at once)",
                    s.stats.name,
                    if restarted { "re" } else { "" },
                    count(items, "task", "tasks"),
                );
                self.start_bar(i);
                self.line(now, &line);
            }
            Event::TaskAttemptStarted { state, attempt, .. } => {
                let (top, single) = top(state);
                let fresh = single && *attempt == 0 && self.find(top).is_none();
                let i = self.stage(top, single, now);
                self.stages[i].stats.attempts += 1;
                if fresh {
                    let line = format!("{}: started, 1 task", self.stages[i].stats.name);
                    self.start_bar(i);
                    self.line(now, &line);
                }
            }
            Event::TaskAttemptFailed {
                state,
                item_index,
                attempt,
                error,
                cause,
                will_retry,
                retry_delay,
            } => {
                let (top, single) = top(state);
                let i = self.stage(top, single, now);
                let s = &mut self.stages[i];
                s.stats.failed_attempts += 1;
                let task = match item_index {
                    Some(n) => format!(" task {n}"),
                    None => String::new(),
                };
                let line = if *will_retry {
                    s.stats.retries += 1;
                    format!(
                        "{}{task} attempt {attempt} failed: {error} (will retry in {:.2}s)",
                        s.stats.name,
                        secs(*retry_delay)
                    )
                } else {
                    let cause = cause.lines().next().unwrap_or("");
                    format!(
                        "{}{task} attempt {attempt} failed: {error}: {cause} (no retry)",
                        s.stats.name
                    )
                };
                if let Some(bar) = &s.bar {
                    bar.set_message(s.retries_message());
                }
                if *will_retry {
                    self.line(now, &line);
                } else {
                    self.line_or_print(now, &line);
                }
            }
            Event::TaskSucceeded {
                state, item_index, ..
            } => {
                let (top, single) = top(state);
                let i = self.stage(top, single, now);
                let s = &mut self.stages[i];
                s.stats.successes += 1;
                if single {
                    s.done = 1;
                    self.finish(i, now, true);
                } else if item_index.is_some() {
                    s.done = (s.done + 1).min(s.stats.tasks);
                    if let Some(bar) = &s.bar {
                        bar.set_position(s.done);
                    }
                    let tasks = s.stats.tasks;
                    let decile = (s.done * 10).checked_div(tasks).unwrap_or(0);
                    if decile > s.decile && decile < 10 {
                        s.decile = decile;
                        let line = format!(
                            "{}: {}/{tasks} tasks ({}%)",
                            s.stats.name,
                            s.done,
                            s.done * 100 / tasks
                        );
                        self.line(now, &line);
                    }
                }
            }
            Event::MapFinished { state, succeeded } => {
                let (top, true) = top(state) else { return };
                if let Some(i) = self.find(top) {
                    self.finish(i, now, *succeeded);
                }
            }
            Event::StateFailed {
                state,
                error,
                cause,
                ..
            } => {
                let (top, true) = top(state) else { return };
                let i = self.find(top);
                if let Some(i) = i
                    && self.stages[i].single
                    && self.stages[i].finished.is_none()
                {
                    self.finish(i, now, false);
                }
                let name = match i {
                    Some(i) => self.stages[i].stats.name.clone(),
                    None => stage_name(top),
                };
                let cause = cause.lines().next().unwrap_or("");
                self.line_or_print(now, &format!("{name}: {error}: {cause}"));
            }
            // Events added to the interpreter later are not shown until the display knows them.
            _ => {}
        }
    }

    fn find(&self, top: &str) -> Option<usize> {
        self.stages.iter().position(|s| s.state == top)
    }

    /// The index of the stage of top-level state `top`, made if new.
    fn stage(&mut self, top: &str, single: bool, now: Duration) -> usize {
        if let Some(i) = self.find(top) {
            return i;
        }
        let rank = hort_core::stage::Stage::ALL
            .iter()
            .position(|s| s.state_name() == top)
            .unwrap_or(hort_core::stage::Stage::ALL.len() + self.stages.len());
        self.stages.push(Stage {
            state: top.to_owned(),
            stats: StageStats {
                name: stage_name(top),
                tasks: u64::from(single),
                attempts: 0,
                failed_attempts: 0,
                retries: 0,
                successes: 0,
                seconds: 0.0,
            },
            rank,
            single,
            first: self.entered.get(top).copied().unwrap_or(now),
            finished: None,
            runs: 0,
            done: 0,
            decile: 0,
            bar: None,
        });
        self.stages.len() - 1
    }

    fn start_bar(&mut self, i: usize) {
        let Some(multi) = &self.multi else { return };
        let s = &mut self.stages[i];
        let style = ProgressStyle::with_template("{prefix:<12} [{bar:30}] {pos}/{len} tasks{msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("#-");
        let bar = multi.add(ProgressBar::new(s.stats.tasks).with_style(style));
        bar.set_prefix(s.stats.name.clone());
        bar.set_message(s.retries_message());
        bar.set_position(s.done);
        if let Some(old) = s.bar.replace(bar) {
            old.finish_and_clear();
        }
    }

    fn finish(&mut self, i: usize, now: Duration, succeeded: bool) {
        let s = &mut self.stages[i];
        s.finished = Some(now);
        let seconds = s.seconds(now);
        let attempts = count(s.stats.attempts, "attempt", "attempts");
        let line = if succeeded {
            format!(
                "{}: done, {}, {attempts}, {seconds:.1}s",
                s.stats.name,
                count(s.stats.tasks, "task", "tasks"),
            )
        } else {
            format!(
                "{}: failed, {}/{} tasks done, {attempts}, {seconds:.1}s",
                s.stats.name, s.done, s.stats.tasks,
            )
        };
        if let Some(bar) = &s.bar {
            if succeeded {
                bar.finish_with_message(format!("{}, {seconds:.1}s", s.retries_message()));
            } else {
                bar.abandon_with_message(format!(
                    "{}, failed after {seconds:.1}s",
                    s.retries_message()
                ));
            }
        }
        self.line(now, &line);
    }

    /// A line in Lines mode.
    fn line(&mut self, now: Duration, text: &str) {
        if let Some(out) = &mut self.out {
            // Progress output is best effort: a closed stderr must not fail the render.
            let _ = writeln!(out, "[{:>5.1}s] {text}", secs(now));
            let _ = out.flush();
        }
    }

    /// A line in Lines mode, or printed above the bars in Bars mode.
    fn line_or_print(&mut self, now: Duration, text: &str) {
        if let Some(multi) = &self.multi {
            let _ = multi.println(format!("[{:>5.1}s] {text}", secs(now)));
        }
        self.line(now, text);
    }
}
