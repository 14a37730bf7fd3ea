//! Progress events of an execution, delivered to an [`Observer`].
//!
//! State names are paths: a top-level state is its name (`Plan`), a state inside a Map's
//! ItemProcessor is `Map/State` (`CastMap/CastMapTask`), so the first segment always names the
//! top-level stage. Events come from several threads (one per Map iteration in flight); their
//! order is the order they happened on each thread, and across threads only as far as the
//! dataflow orders them (every event of a Map's items comes between its `MapStarted` and
//! `MapFinished`).

use std::sync::Mutex;
use std::time::Duration;

/// One thing that happened during an execution.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Event {
    /// A state was entered (each time: a retried Map Run is entered once).
    StateEntered {
        /// The state's path.
        state: String,
        /// The Map item this state runs for, if inside a Map.
        item_index: Option<usize>,
    },
    /// A Map state read its items and starts its iterations.
    MapStarted {
        /// The Map state's path.
        state: String,
        /// How many items it read.
        items: usize,
        /// How many iterations run at once at most: min(MaxConcurrency, slots, items).
        concurrency: usize,
    },
    /// A Task attempt starts (its function has a slot and is being invoked).
    TaskAttemptStarted {
        /// The Task state's path.
        state: String,
        /// The Map item, if inside a Map.
        item_index: Option<usize>,
        /// 0 for the first attempt; equals `$$.State.RetryCount`.
        attempt: u32,
    },
    /// A Task attempt failed.
    TaskAttemptFailed {
        /// The Task state's path.
        state: String,
        /// The Map item, if inside a Map.
        item_index: Option<usize>,
        /// The failed attempt's number.
        attempt: u32,
        /// The error name (`Hort.Retryable`, `States.Timeout`, …).
        error: String,
        /// The cause.
        cause: String,
        /// True if a retrier will run another attempt.
        will_retry: bool,
        /// The wait before that attempt (zero when not retrying), in real time after scaling.
        retry_delay: Duration,
    },
    /// A Task attempt succeeded.
    TaskSucceeded {
        /// The Task state's path.
        state: String,
        /// The Map item, if inside a Map.
        item_index: Option<usize>,
        /// The successful attempt's number.
        attempt: u32,
    },
    /// A Map Run ended.
    MapFinished {
        /// The Map state's path.
        state: String,
        /// True if every item succeeded.
        succeeded: bool,
    },
    /// A Task or Map state failed after its retries; its Catch (if any) decides what follows.
    StateFailed {
        /// The state's path.
        state: String,
        /// The error name.
        error: String,
        /// The cause.
        cause: String,
        /// True if a catcher matched.
        caught: bool,
    },
}

/// Receives events. Called from many threads at once; must not block for long.
pub trait Observer: Send + Sync {
    /// Handles one event.
    fn event(&self, e: &Event);
}

/// Ignores every event.
#[derive(Debug, Default, Clone, Copy)]
pub struct NoObserver;

impl Observer for NoObserver {
    fn event(&self, _e: &Event) {}
}

/// Records every event in arrival order.
#[derive(Debug, Default)]
pub struct EventLog {
    events: Mutex<Vec<Event>>,
}

impl EventLog {
    /// An empty log.
    pub fn new() -> Self {
        Self::default()
    }

    /// A copy of the events recorded so far, in arrival order.
    pub fn events(&self) -> Vec<Event> {
        self.events
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
            .clone()
    }
}

impl Observer for EventLog {
    fn event(&self, e: &Event) {
        self.events
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
            .push(e.clone());
    }
}
