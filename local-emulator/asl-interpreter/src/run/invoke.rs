//! One Task attempt: an invocation on its own thread, holding a machine slot until the
//! function returns and a seat of its function's reserved concurrency until it returns or its
//! function's timeout stops it, raced against the attempt's timeout, the function's timeout, the
//! cancel flag and the EXPRESS limit. Both timeouts are deadlines on the execution's clock, fixed
//! before the function is called. An invocation over its function's reserved concurrency is
//! throttled at once (see [`crate::functions`]).

use std::panic::{self, AssertUnwindSafe};
use std::sync::Arc;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::thread;
use std::time::Duration;

use serde_json::Value;

use super::{Execution, Failure, Frame, PANIC, POLL, Stop};
use crate::TaskFailure;
use crate::events::Event;
use crate::functions::FUNCTION_TIMED_OUT;
use crate::retry;

impl Execution<'_> {
    /// One invocation on its own thread, holding a slot until the function returns.
    pub(super) fn invoke(
        &self,
        function: &str,
        payload: Value,
        timeout: Option<Duration>,
        path: &str,
        attempt: u32,
        frame: &Frame,
    ) -> Result<Result<Value, Failure>, Stop> {
        let Some(slot) = self
            .slots
            .acquire(|| frame.halt.is_set() || frame.expired(self.clock.as_ref()))
        else {
            self.check(frame, path)?;
            return Err(Stop::Halted(path.to_owned()));
        };
        // Before the function can run (and, on a test clock, move time on).
        let now = self.clock.now();
        let deadline = timeout.map(|t| now.saturating_add(t));
        let function_timeout = self.options.functions.limit(function).timeout_seconds;
        let stopped_at = function_timeout.map(|s| now.saturating_add(self.scaled(s)));
        self.emit(Event::TaskAttemptStarted {
            state: path.to_owned(),
            item_index: frame.item,
            attempt,
        });
        let failure = |error: &str, cause: String| Failure {
            error: error.to_owned(),
            cause,
            state: path.to_owned(),
            item: None,
        };
        let seat = match self
            .options
            .functions
            .enter(function, self.clock, stopped_at)
        {
            Ok(seat) => seat,
            Err(throttled) => {
                return Ok(Err(failure(
                    crate::functions::THROTTLED,
                    throttled.cause(path, attempt),
                )));
            }
        };
        let thread_seat = Arc::clone(&seat);
        let (tx, rx) = mpsc::channel();
        let invoker = Arc::clone(self.invoker);
        let function_name = function.to_owned();
        let spawned = thread::Builder::new()
            .name(format!("hort-invoke {path}"))
            .spawn(move || {
                let result = panic::catch_unwind(AssertUnwindSafe(|| {
                    invoker.invoke(&function_name, payload)
                }));
                thread_seat.release();
                drop(slot);
                // The receiver is gone when the attempt timed out: the result is dropped.
                let _ = tx.send(result);
            });
        if let Err(e) = spawned {
            return Ok(Err(failure(
                "Lambda.ServiceException",
                format!("{path}: cannot start the invocation thread: {e}"),
            )));
        }
        loop {
            let mut wait = POLL;
            for d in deadline.iter().chain(stopped_at.iter()) {
                wait = wait.min(d.saturating_sub(self.clock.now()));
            }
            match rx.recv_timeout(wait) {
                Ok(Ok(Ok(value))) => return Ok(Ok(value)),
                Ok(Ok(Err(TaskFailure { error, cause }))) => {
                    return Ok(Err(failure(&error, cause)));
                }
                Ok(Err(panic)) => {
                    let message = panic
                        .downcast_ref::<&str>()
                        .map(|s| s.to_string())
                        .or_else(|| panic.downcast_ref::<String>().cloned())
                        .unwrap_or_else(|| "no message".into());
                    return Ok(Err(failure(
                        PANIC,
                        format!("{path}: the function {function} panicked: {message}"),
                    )));
                }
                Err(RecvTimeoutError::Disconnected) => {
                    return Ok(Err(failure(
                        PANIC,
                        format!("{path}: the function {function} ended without a result"),
                    )));
                }
                Err(RecvTimeoutError::Timeout) => {
                    self.check(frame, path)?;
                    let now = self.clock.now();
                    // At a tie the function's own timeout wins: Lambda stops it as the state
                    // gives up, and the seat is free either way.
                    if stopped_at.is_some_and(|at| now >= at) {
                        seat.release();
                        return Ok(Err(failure(
                            FUNCTION_TIMED_OUT,
                            format!(
                                "{path}: attempt {attempt}: Task timed out after {:.2} seconds \
                                 (the timeout of {function}, whatever the state's TimeoutSeconds)",
                                function_timeout.unwrap_or_default()
                            ),
                        )));
                    }
                    if deadline.is_some_and(|d| now >= d) {
                        let limit =
                            timeout.unwrap_or_default().as_secs_f64() / self.options.time_scale;
                        return Ok(Err(failure(
                            retry::TIMEOUT,
                            format!(
                                "{path}: attempt {attempt} ran longer than its timeout of {limit} s"
                            ),
                        )));
                    }
                }
            }
        }
    }
}
