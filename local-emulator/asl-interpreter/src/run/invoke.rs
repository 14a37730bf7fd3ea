//! One Task attempt: an invocation on its own thread, holding a function slot until the
//! function returns, raced against the attempt's timeout, the cancel flag and the EXPRESS limit.
//! The timeout is a deadline on the execution's clock, fixed before the function is called.

use std::panic::{self, AssertUnwindSafe};
use std::sync::Arc;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::thread;
use std::time::Duration;

use serde_json::Value;

use super::{Execution, Failure, Frame, PANIC, POLL, Stop};
use crate::TaskFailure;
use crate::events::Event;
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
            .acquire(|| frame.halt.is_set() || frame.expired(self.clock))
        else {
            self.check(frame, path)?;
            return Err(Stop::Halted(path.to_owned()));
        };
        // Before the function can run (and, on a test clock, move time on).
        let deadline = timeout.map(|t| self.clock.now().saturating_add(t));
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
        let (tx, rx) = mpsc::channel();
        let invoker = Arc::clone(self.invoker);
        let function_name = function.to_owned();
        let spawned = thread::Builder::new()
            .name(format!("hort-invoke {path}"))
            .spawn(move || {
                let result = panic::catch_unwind(AssertUnwindSafe(|| {
                    invoker.invoke(&function_name, payload)
                }));
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
            if let Some(d) = deadline {
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
                    if deadline.is_some_and(|d| self.clock.now() >= d) {
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
