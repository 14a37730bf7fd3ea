//! The time source of an execution's own waits: retry backoff, Task `TimeoutSeconds` and the
//! 5-minute EXPRESS limit.
//!
//! Executions run on [`RealClock`] unless [`crate::Orchestrator::with_clock`] gives them
//! another clock. The interpreter scales every duration by
//! [`crate::OrchestratorOptions::time_scale`] *before* handing it to the clock, so a clock
//! only ever sees scaled durations; with [`RealClock`] the behaviour is wall-clock time,
//! exactly as without a clock.
//!
//! [`ManualClock`] is virtual time for tests: it stands still unless advanced, and
//! [`Clock::sleep`] advances it instead of waiting. With it, a test decides when an attempt
//! times out (by advancing the clock past the deadline while the attempt runs), and no machine
//! stall, however long, can make an attempt time out on its own; retry backoff costs no real
//! time and [`ManualClock::now`] tells exactly how much backoff was waited.
//!
//! Only these three waits use the clock. The interpreter still polls (its stop flags, a slot
//! coming free, an invocation's result) every few milliseconds of real time, whatever the clock.

use std::fmt;
use std::sync::Mutex;
use std::thread;
use std::time::{Duration, Instant};

/// A monotonic time source with a way to wait on it.
pub trait Clock: Send + Sync + fmt::Debug {
    /// The time elapsed since an origin fixed for the clock's lifetime; never decreases.
    fn now(&self) -> Duration;

    /// Lets about `duration` of this clock's time pass. The interpreter calls it with short
    /// durations (a few milliseconds), re-checking its stop conditions and [`Clock::now`]
    /// between calls, so returning early is harmless.
    fn sleep(&self, duration: Duration);
}

/// Wall-clock time: [`std::time::Instant`] and [`std::thread::sleep`]. The default.
#[derive(Debug, Clone, Copy)]
pub struct RealClock {
    origin: Instant,
}

impl RealClock {
    /// A clock whose origin is now.
    pub fn new() -> Self {
        Self {
            origin: Instant::now(),
        }
    }
}

impl Default for RealClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for RealClock {
    fn now(&self) -> Duration {
        self.origin.elapsed()
    }

    fn sleep(&self, duration: Duration) {
        thread::sleep(duration);
    }
}

/// Virtual time, shared by every thread of an execution: it starts at zero and moves only
/// through [`ManualClock::advance`] and [`Clock::sleep`], which advances it at once by the
/// duration asked for (so concurrent sleepers make it run faster, never slower).
#[derive(Debug, Default)]
pub struct ManualClock {
    now: Mutex<Duration>,
}

impl ManualClock {
    /// A clock at zero.
    pub fn new() -> Self {
        Self::default()
    }

    /// Moves the clock forward by `by`.
    pub fn advance(&self, by: Duration) {
        let mut now = self.now.lock().unwrap_or_else(|p| p.into_inner());
        *now = now.saturating_add(by);
    }
}

impl Clock for ManualClock {
    fn now(&self) -> Duration {
        *self.now.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn sleep(&self, duration: Duration) {
        self.advance(duration);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_manual_clock_moves_only_when_told() {
        let clock = ManualClock::new();
        assert_eq!(clock.now(), Duration::ZERO);
        clock.advance(Duration::from_millis(1500));
        clock.sleep(Duration::from_millis(500));
        assert_eq!(clock.now(), Duration::from_secs(2));
        clock.advance(Duration::MAX);
        assert_eq!(clock.now(), Duration::MAX);
    }

    #[test]
    fn the_real_clock_is_monotonic_and_sleeps_at_least_as_asked() {
        let clock = RealClock::new();
        let before = clock.now();
        clock.sleep(Duration::from_millis(2));
        assert!(clock.now() >= before + Duration::from_millis(2));
    }
}
