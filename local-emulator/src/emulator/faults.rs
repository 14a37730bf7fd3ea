//! Seeded fault injection around the in-process functions: attempts that fail before running or
//! after writing part of their outputs, duplicated concurrent attempts, and stragglers that
//! outlive their timeout. Each decision is a pure function of (seed, stage, task, attempt,
//! round), so a run is reproducible; the round counts earlier invocations of the same (stage,
//! task, attempt), so that a Map item the state machine runs again (its rerun loop starts the
//! attempts of a rerun at 0 again) meets fresh faults, as it would in the cloud. None of it may change the image: every task writes the same bytes on
//! every attempt.

use super::invoker::InProcessInvoker;
use asl_interpreter::retry::unit_draw;
use asl_interpreter::{TaskFailure, TaskInvoker};
use hort_core::ErrorType;
use hort_core::store::{BlobStore, PutOutcome, StoreError};
use serde_json::Value;
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Probabilities (per attempt) and seed of the injected faults.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FaultSettings {
    /// Probability that an attempt fails (half before running, half after writing part of its
    /// outputs), 0 to 1.
    pub fail_rate: f64,
    /// Probability that an attempt is delivered twice, running concurrently, 0 to 1.
    pub duplicate_rate: f64,
    /// Probability that an attempt straggles past its timeout, 0 to 1.
    pub slow_rate: f64,
    /// Seed of every decision: the same seed injects the same faults.
    pub seed: u64,
    /// The paper's experiment: this many seconds into the run, one function slot dies: the
    /// attempt it runs is lost (it never answers, so it times out and is retried) and the slot
    /// never frees again.
    pub kill_slot_after: Option<f64>,
}

impl FaultSettings {
    /// Whether any fault is enabled.
    pub fn any(&self) -> bool {
        self.fail_rate > 0.0
            || self.duplicate_rate > 0.0
            || self.slow_rate > 0.0
            || self.kill_slot_after.is_some()
    }
}

/// How many faults were injected.
#[derive(Debug, Default)]
pub struct FaultCounts {
    /// Attempts failed before running.
    pub failed_before: AtomicU64,
    /// Attempts failed after writing part of their outputs.
    pub failed_after_writing: AtomicU64,
    /// Attempts delivered twice.
    pub duplicated: AtomicU64,
    /// Attempts that straggled past their timeout.
    pub slowed: AtomicU64,
    /// Function slots that died (0 or 1).
    pub slots_killed: AtomicU64,
}

/// (stage, frame, task, attempt) of an invocation.
type AttemptKey = (String, Option<u64>, Option<u64>, u64);

/// Wraps the functions with seeded faults.
pub struct FaultyInvoker {
    inner: Arc<InProcessInvoker>,
    store: Arc<dyn BlobStore>,
    settings: FaultSettings,
    /// Multiplies timeouts (the orchestrator's time scale), so stragglers outlive theirs.
    time_scale: f64,
    /// What was injected so far.
    pub counts: Arc<FaultCounts>,
    started: Instant,
    /// Set when the run is over: releases a dead slot's thread.
    pub finished: Arc<AtomicBool>,
    /// Invocations so far of each (stage, task, attempt).
    rounds: Mutex<HashMap<AttemptKey, u32>>,
}

impl FaultyInvoker {
    /// Wraps `inner`, whose attempts see `store` through the faults; `time_scale` is the
    /// orchestrator's, so stragglers outlive their scaled timeouts.
    pub fn new(
        inner: Arc<InProcessInvoker>,
        store: Arc<dyn BlobStore>,
        settings: FaultSettings,
        time_scale: f64,
    ) -> Self {
        FaultyInvoker {
            inner,
            store,
            settings,
            time_scale,
            counts: Arc::new(FaultCounts::default()),
            started: Instant::now(),
            finished: Arc::new(AtomicBool::new(false)),
            rounds: Mutex::new(HashMap::new()),
        }
    }

    /// Whether this invocation is the one that dies with its slot.
    fn dies_with_its_slot(&self) -> bool {
        self.settings
            .kill_slot_after
            .is_some_and(|t| self.started.elapsed().as_secs_f64() >= t)
            && self
                .counts
                .slots_killed
                .compare_exchange(0, 1, Ordering::Relaxed, Ordering::Relaxed)
                .is_ok()
    }

    /// How many invocations of this (stage, task, attempt) came before this one.
    fn round(&self, input: &Value) -> u32 {
        let key = (
            input
                .get("stage")
                .and_then(Value::as_str)
                .unwrap_or("")
                .to_owned(),
            input
                .get("item")
                .and_then(|i| i.get("frame"))
                .and_then(Value::as_u64),
            input
                .get("item")
                .and_then(|i| i.get("task"))
                .and_then(Value::as_u64),
            input.get("attempt").and_then(Value::as_u64).unwrap_or(0),
        );
        let mut rounds = self.rounds.lock().unwrap_or_else(|p| p.into_inner());
        let n = rounds.entry(key).or_insert(0);
        *n += 1;
        *n - 1
    }

    /// A uniform draw in [0, 1) for this attempt (stage, task, attempt), its round and purpose
    /// (`salt`): the same seeded draw the state machine's retry jitter uses. Round 0 draws as
    /// before rounds existed.
    fn draw(&self, input: &Value, round: u32, salt: u64) -> f64 {
        let stage = input.get("stage").and_then(Value::as_str).unwrap_or("");
        let task = input
            .get("item")
            .and_then(|i| i.get("task"))
            .and_then(Value::as_u64)
            .map(|t| t as usize);
        let attempt = input.get("attempt").and_then(Value::as_u64).unwrap_or(0);
        // A frame's tasks draw apart from other frames'; a job of one frame as always.
        let stage = match input
            .get("item")
            .and_then(|i| i.get("frame"))
            .and_then(Value::as_u64)
        {
            Some(frame) => format!("{stage}/frame-{frame}"),
            None => stage.to_owned(),
        };
        let label = match round {
            0 => format!("fault-{salt}/{stage}"),
            r => format!("fault-{salt}/{stage}/round-{r}"),
        };
        unit_draw(self.settings.seed, &label, task, attempt as u32)
    }
}

impl TaskInvoker for FaultyInvoker {
    fn invoke(&self, resource: &str, input: Value) -> Result<Value, TaskFailure> {
        if input.get("item").is_some() && self.dies_with_its_slot() {
            // Never answers: holds the slot until the run is over.
            while !self.finished.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(20));
            }
            return Err(TaskFailure::new(
                ErrorType::Retryable.as_str(),
                "injected fault: the function slot died",
            ));
        }
        let timeout = input
            .get("item")
            .and_then(|i| i.get("timeout_seconds"))
            .and_then(Value::as_f64);
        let round = self.round(&input);
        if self.draw(&input, round, 1) < self.settings.duplicate_rate {
            self.counts.duplicated.fetch_add(1, Ordering::Relaxed);
            let (inner, resource, twin) =
                (Arc::clone(&self.inner), resource.to_string(), input.clone());
            // The twin runs concurrently on its own; its outcome is ignored, as a duplicate
            // delivery's would be.
            std::thread::spawn(move || {
                let _ = inner.invoke(&resource, twin);
            });
        }
        if let Some(seconds) = timeout
            && self.draw(&input, round, 2) < self.settings.slow_rate
        {
            self.counts.slowed.fetch_add(1, Ordering::Relaxed);
            std::thread::sleep(Duration::from_secs_f64(
                seconds * self.time_scale * 1.2 + 0.05,
            ));
        }
        let fail = self.draw(&input, round, 3);
        if fail < self.settings.fail_rate / 2.0 {
            self.counts.failed_before.fetch_add(1, Ordering::Relaxed);
            return Err(TaskFailure::new(
                ErrorType::Retryable.as_str(),
                "injected fault: the worker died before running the task",
            ));
        }
        if fail < self.settings.fail_rate {
            self.counts
                .failed_after_writing
                .fetch_add(1, Ordering::Relaxed);
            let puts = 1 + (self.draw(&input, round, 4) * 3.0) as usize;
            let failing = FailAfterPuts {
                inner: self.store.as_ref(),
                puts_left: AtomicUsize::new(puts),
            };
            let _ = self.inner.invoke_with_store(resource, input, &failing);
            return Err(TaskFailure::new(
                ErrorType::Retryable.as_str(),
                "injected fault: the worker died after writing part of its outputs",
            ));
        }
        self.inner.invoke(resource, input)
    }
}

/// A store whose puts start failing after a number of successful ones (a worker dying
/// mid-write).
struct FailAfterPuts<'a> {
    inner: &'a dyn BlobStore,
    puts_left: AtomicUsize,
}

impl FailAfterPuts<'_> {
    fn spend(&self, key: &str) -> Result<(), StoreError> {
        let left = self.puts_left.load(Ordering::Relaxed);
        if left == 0 {
            return Err(StoreError::Unavailable {
                what: format!("injected fault: worker died before writing {key}"),
            });
        }
        self.puts_left.store(left - 1, Ordering::Relaxed);
        Ok(())
    }
}

impl BlobStore for FailAfterPuts<'_> {
    fn get(&self, key: &str) -> Result<Vec<u8>, StoreError> {
        self.inner.get(key)
    }
    fn get_range(&self, key: &str, range: std::ops::Range<u64>) -> Result<Vec<u8>, StoreError> {
        self.inner.get_range(key, range)
    }
    fn put(&self, key: &str, bytes: &[u8]) -> Result<(), StoreError> {
        self.spend(key)?;
        self.inner.put(key, bytes)
    }
    fn put_if_absent(&self, key: &str, bytes: &[u8]) -> Result<PutOutcome, StoreError> {
        self.spend(key)?;
        self.inner.put_if_absent(key, bytes)
    }
    fn list(&self, prefix: &str) -> Result<Vec<String>, StoreError> {
        self.inner.list(prefix)
    }
    fn delete(&self, key: &str) -> Result<(), StoreError> {
        self.inner.delete(key)
    }
    fn get_many(&self, keys: &[String]) -> Vec<Result<Vec<u8>, StoreError>> {
        self.inner.get_many(keys)
    }
    fn put_many(&self, objects: &[(String, Vec<u8>)]) -> Vec<Result<(), StoreError>> {
        // The objects the budget still covers go through; the first it does not, and every
        // one after, fail.
        let spent: Vec<Result<(), StoreError>> =
            objects.iter().map(|(key, _)| self.spend(key)).collect();
        let allowed = spent.iter().take_while(|r| r.is_ok()).count();
        let mut results = self.inner.put_many(&objects[..allowed]);
        results.extend(spent.into_iter().skip(allowed));
        results
    }
}
