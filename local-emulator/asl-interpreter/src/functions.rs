//! What Lambda holds each function to, besides the machine's own slots: its reserved
//! concurrency and its timeout, as the deployment sets them.
//!
//! - **Reserved concurrency.** A function with reserved concurrency N runs at most N
//!   invocations at once, over every execution sharing the same [`FunctionLimits`] (an
//!   account's function is shared by all its jobs). One more is not queued: it is throttled,
//!   failing at once with [`THROTTLED`] (`Lambda.TooManyRequestsException`), which the state's
//!   `Retry` may retry. An invocation holds its seat until it returns or Lambda stops it at its
//!   timeout, whichever is first, so a zombie (an attempt the state machine gave up on at its
//!   `TimeoutSeconds`) still counts until then.
//! - **Timeout.** Lambda stops an invocation that runs past the function's timeout whatever the
//!   state's `TimeoutSeconds` says: the attempt fails with [`FUNCTION_TIMED_OUT`]
//!   (`Sandbox.Timedout`) and its seat is free. The emulator cannot stop the thread, so the
//!   handler runs on and its result is dropped, as a timed-out attempt's is; it keeps its machine
//!   slot (it still takes a core) but no longer its reserved seat.
//!
//! Timeouts are scaled by [`crate::OrchestratorOptions::time_scale`] and measured on the
//! execution's clock, like every other wait.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::Clock;

/// The error of an invocation over its function's reserved concurrency.
pub const THROTTLED: &str = hort_aws_quotas::LAMBDA_THROTTLED;
/// The error of an invocation Lambda stopped at its function's timeout.
pub const FUNCTION_TIMED_OUT: &str = hort_aws_quotas::LAMBDA_TIMED_OUT;

/// One function's settings, as its deployment sets them.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FunctionLimit {
    /// Reserved concurrency: at most this many invocations at once; `None`: unreserved (only
    /// the machine's slots bound it).
    pub reserved_concurrency: Option<usize>,
    /// The function's timeout, seconds (before scaling); `None`: none but the state's.
    pub timeout_seconds: Option<f64>,
}

/// Every function's limits and the invocations counted against them; clones share the count.
#[derive(Debug, Clone, Default)]
pub struct FunctionLimits {
    limits: BTreeMap<String, FunctionLimit>,
    running: Arc<Mutex<BTreeMap<String, Vec<Arc<Seat>>>>>,
}

/// One invocation counted against its function's reserved concurrency.
#[derive(Debug)]
pub struct Seat {
    released: AtomicBool,
    /// When Lambda stops the invocation, on `clock`.
    stopped_at: Option<(Arc<dyn Clock>, Duration)>,
}

/// Why an invocation was throttled: its function and reserved concurrency.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Throttled {
    /// The function.
    pub function: String,
    /// Its reserved concurrency, all in use.
    pub reserved: usize,
}

impl FunctionLimits {
    /// No limits: every function unreserved, no function timeout.
    pub fn none() -> Self {
        Self::default()
    }

    /// The same limits with `function`'s set to `limit`.
    pub fn with(mut self, function: &str, limit: FunctionLimit) -> Self {
        self.limits.insert(function.to_owned(), limit);
        self
    }

    /// `function`'s limit (the default, none, for a function not set).
    pub fn limit(&self, function: &str) -> FunctionLimit {
        self.limits.get(function).copied().unwrap_or_default()
    }

    /// Takes a seat for one invocation of `function`, which Lambda stops at `stopped_at` on
    /// `clock` (if it has a timeout), or says it is throttled.
    pub fn enter(
        &self,
        function: &str,
        clock: &Arc<dyn Clock>,
        stopped_at: Option<Duration>,
    ) -> Result<Arc<Seat>, Throttled> {
        let seat = Arc::new(Seat {
            released: AtomicBool::new(false),
            stopped_at: stopped_at.map(|at| (Arc::clone(clock), at)),
        });
        let Some(reserved) = self.limit(function).reserved_concurrency else {
            return Ok(seat);
        };
        let mut running = self.running.lock().unwrap_or_else(|p| p.into_inner());
        let seats = running.entry(function.to_owned()).or_default();
        seats.retain(|s| s.holds());
        if seats.len() >= reserved {
            return Err(Throttled {
                function: function.to_owned(),
                reserved,
            });
        }
        seats.push(Arc::clone(&seat));
        Ok(seat)
    }

    /// Invocations of `function` counted against its reserved concurrency now.
    pub fn running(&self, function: &str) -> usize {
        let mut running = self.running.lock().unwrap_or_else(|p| p.into_inner());
        running.get_mut(function).map_or(0, |seats| {
            seats.retain(|s| s.holds());
            seats.len()
        })
    }
}

impl Seat {
    /// Frees the seat: the invocation returned, or Lambda stopped it.
    pub fn release(&self) {
        self.released.store(true, Ordering::SeqCst);
    }

    fn holds(&self) -> bool {
        !self.released.load(Ordering::SeqCst)
            && self
                .stopped_at
                .as_ref()
                .is_none_or(|(clock, at)| clock.now() < *at)
    }
}

impl Throttled {
    /// The cause Step Functions records, in Lambda's words.
    pub fn cause(&self, path: &str, attempt: u32) -> String {
        format!(
            "Rate Exceeded. (Service: Lambda, Status Code: 429, Reason: \
             ReservedFunctionConcurrentInvocationLimitExceeded): {} has a reserved concurrency \
             of {}, all in use ({path}, attempt {attempt})",
            self.function, self.reserved
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ManualClock;

    #[test]
    fn a_seat_is_held_until_released_or_stopped_and_unreserved_functions_are_never_throttled() {
        let manual = Arc::new(ManualClock::new());
        let clock: Arc<dyn Clock> = manual.clone();
        let limits = FunctionLimits::none().with(
            "W",
            FunctionLimit {
                reserved_concurrency: Some(2),
                timeout_seconds: Some(10.0),
            },
        );
        let shared = limits.clone();
        let a = limits
            .enter("W", &clock, Some(Duration::from_secs(10)))
            .unwrap();
        let _b = shared.enter("W", &clock, None).unwrap();
        assert_eq!(
            limits.enter("W", &clock, None).unwrap_err(),
            Throttled {
                function: "W".into(),
                reserved: 2
            }
        );
        a.release();
        let c = limits
            .enter("W", &clock, Some(Duration::from_secs(5)))
            .unwrap();
        assert_eq!(shared.running("W"), 2);
        // Lambda stops `c` at 5 s: its seat is free even though nobody released it.
        manual.advance(Duration::from_secs(5));
        assert_eq!(limits.running("W"), 1);
        drop(c);
        for _ in 0..100 {
            limits.enter("Other", &clock, None).unwrap();
        }
        assert_eq!(limits.running("Other"), 0);
    }
}
