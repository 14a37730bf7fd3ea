//! Per-stage accounting from the orchestrator's events: wall-clock time, attempts, and the
//! storage traffic between one top-level state's start and the next one's (stages run one
//! after another, so the traffic in between is the stage's).

use asl_interpreter::{Event, Observer};
use hort_core::stage::Stage;
use hort_core::stage::is_lost_step;
use hort_core::store::{CountingStore, StoreStats};
use hort_functions::S3Store;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// What one top-level state used.
#[derive(Clone, Debug, Default)]
pub struct StageUsage {
    /// The state's name (`Plan`, `CastMap`, …).
    pub state: String,
    /// Wall-clock seconds from entering the state to leaving it.
    pub seconds: f64,
    /// When the state was entered and left (`None` until it was left).
    pub window: Option<(Instant, Instant)>,
    /// Function invocations started for the state (first attempts and retries).
    pub attempts: u64,
    /// Attempts that failed (errors and timeouts), whether retried or not.
    pub failed_attempts: u64,
    /// Child executions a Map started (its items).
    pub items: u64,
    /// Storage requests and bytes while the state ran (all attempts, zombies included).
    pub traffic: StoreStats,
}

/// Observer that turns events into [`StageUsage`] rows.
pub struct Accounting {
    store: Arc<CountingStore<S3Store>>,
    inner: Mutex<State>,
}

struct State {
    rows: Vec<StageUsage>,
    started: Option<(Instant, StoreStats)>,
    /// Top-level states entered, and retries of top-level states: Standard transitions.
    transitions: u64,
}

impl Accounting {
    /// Accounting over the requests counted by `store`.
    pub fn new(store: Arc<CountingStore<S3Store>>) -> Self {
        Accounting {
            store,
            inner: Mutex::new(State {
                rows: Vec::new(),
                started: None,
                transitions: 0,
            }),
        }
    }

    /// The Standard state transitions of the execution's own states so far: one per top-level
    /// state entered (a rerun loop's states again each round) and one per retry of a top-level
    /// state; the Map children come on top (see `hort_core::cost::standard_transitions_for`).
    pub fn top_level_transitions(&self) -> u64 {
        self.inner
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .transitions
    }

    /// Closes the running stage and returns every row.
    pub fn finish(&self) -> Vec<StageUsage> {
        let mut s = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        self.close(&mut s);
        s.rows.clone()
    }

    fn close(&self, s: &mut State) {
        if let (Some((t0, stats0)), Some(row)) = (s.started.take(), s.rows.last_mut()) {
            let now = Instant::now();
            row.seconds = (now - t0).as_secs_f64();
            row.window = Some((t0, now));
            row.traffic = self.store.stats().since(&stats0);
        }
    }
}

/// The row a state's events count in: its top-level state, where the states of a Map stage's
/// rerun loop (`CastMapLost`, `CastMapCheck`, `CastMapRerun`, `CastMapRound`, `CastMapGiveUp`)
/// count in the stage's own row (`CastMap`).
fn top_level(state: &str) -> Option<&str> {
    let top = state.split('/').next()?;
    Some(Stage::of_rerun_loop_state(top).map_or(top, |s| s.state_name()))
}

impl Observer for Accounting {
    fn event(&self, event: &Event) {
        let mut s = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        // A retry of a top-level Task (Plan, a lost step, Combine) is a Standard transition.
        if let Event::TaskAttemptFailed {
            state, will_retry, ..
        } = event
        {
            s.transitions += u64::from(*will_retry && !state.contains('/'));
        }
        match event {
            Event::StateEntered {
                state,
                item_index: None,
            } if !state.contains('/') => {
                s.transitions += 1;
                let state = &top_level(state).unwrap_or(state).to_owned();
                if s.rows.last().is_some_and(|r| &r.state == state) {
                    return;
                }
                self.close(&mut s);
                s.rows.push(StageUsage {
                    state: state.clone(),
                    ..StageUsage::default()
                });
                s.started = Some((Instant::now(), self.store.stats()));
            }
            Event::MapStarted { state, items, .. } => {
                let top = top_level(state).unwrap_or_default().to_string();
                if let Some(row) = s.rows.iter_mut().rev().find(|r| r.state == top) {
                    row.items += *items as u64;
                }
            }
            // The Plan function's lost step (`CastMapLost`) is the orchestration's bookkeeping,
            // no task of the stage: its time counts in the row, its invocations in the cost
            // (the ledger), not in the stage's attempts.
            Event::TaskAttemptStarted { state, .. } | Event::TaskAttemptFailed { state, .. }
                if is_lost_step(state) => {}
            Event::TaskAttemptStarted { state, .. } => {
                let top = top_level(state).unwrap_or_default().to_string();
                if let Some(row) = s.rows.iter_mut().rev().find(|r| r.state == top) {
                    row.attempts += 1;
                }
            }
            Event::TaskAttemptFailed { state, .. } => {
                let top = top_level(state).unwrap_or_default().to_string();
                if let Some(row) = s.rows.iter_mut().rev().find(|r| r.state == top) {
                    row.failed_attempts += 1;
                }
            }
            _ => {}
        }
    }
}

/// Sends every event to each observer in turn.
pub struct FanOut<'a>(pub Vec<&'a dyn Observer>);

impl Observer for FanOut<'_> {
    fn event(&self, event: &Event) {
        for o in &self.0 {
            o.event(event);
        }
    }
}
