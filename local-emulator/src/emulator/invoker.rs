//! The functions, invoked in process: routes the state machine's function names to the
//! handlers of `hort-functions`, gives each invocation a warm container's split cache, measures
//! each Worker invocation's memory and holds it to the function's budget, and keeps a ledger of
//! what the invocations did (for the report and the cost estimate).

use super::memory::MemoryBudget;
use asl_interpreter::{TaskFailure, TaskInvoker};
use hort_core::breakdown::StageBreakdown;
use hort_core::ids::TaskId;
use hort_core::pipeline::{SplitCache, TaskMetrics, micros};
use hort_core::stage::Stage;
use hort_core::store::BlobStore;
use hort_functions::handlers::{Function, FunctionEnv, Invoked, TaskDone, Tmp, dispatch};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// What one frame of a job of several frames took ([`Ledger::frames`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameFigures {
    /// The frame's number.
    pub frame: u32,
    /// When it was ready, seconds after the job started.
    pub ready_seconds: f64,
    /// Its shadow rays (one per hit sample and light).
    pub shadow_rays: u64,
    /// Its tasks' own seconds, over every stage.
    pub task_seconds: f64,
}

/// A task: its stage, frame (in a job of several frames) and index.
pub type TaskKey = (Stage, Option<u32>, TaskId);

/// Every [`TaskKey`] of `stage`.
fn stage_range(stage: Stage) -> std::ops::RangeInclusive<TaskKey> {
    (stage, None, TaskId(0))..=(stage, Some(u32::MAX), TaskId(u32::MAX))
}

/// What the invocations did.
#[derive(Clone, Debug, Default)]
pub struct Ledger {
    /// Metrics of each task's successful attempt (the last one, when a retry or a duplicate
    /// delivery also succeeded: every successful attempt writes the same bytes), by stage and
    /// task. Failed attempts are not here: their traffic is in the per-state accounting.
    pub tasks: BTreeMap<TaskKey, TaskMetrics>,
    /// Duration of every invocation (successful or not), milliseconds.
    pub invocation_ms: Vec<f64>,
    /// Wall-clock interval of every invocation (successful or not), as its invoker saw it.
    pub busy: Vec<(Instant, Instant)>,
    /// Microseconds the invoker measured around the attempt whose metrics are in `tasks`.
    pub wall_us: BTreeMap<TaskKey, u64>,
    /// When the attempt whose metrics are in `tasks` ended, as its invoker saw it.
    pub ended: BTreeMap<TaskKey, Instant>,
    /// The most memory a successful Plan invocation held, bytes (0 where not measured). The
    /// Plan function reports no task metrics, so it is kept here; it is not held to the
    /// functions' memory budget (see docs/ARCHITECTURE.md, "Task memory").
    pub plan_peak_memory_bytes: u64,
}

impl Ledger {
    /// Records one invocation that ran from `started` to `ended` and, for a successful Worker
    /// attempt, its task's metrics (replacing an earlier successful attempt's: both wrote the
    /// same bytes).
    pub fn record(&mut self, started: Instant, ended: Instant, done: Option<TaskDone>) {
        let took = ended.saturating_duration_since(started);
        self.invocation_ms.push(took.as_secs_f64() * 1e3);
        self.busy.push((started, ended));
        if let Some(done) = done {
            let key = (done.stage, done.frame, done.task);
            self.tasks.insert(key, done.metrics);
            self.wall_us.insert(key, micros(took));
            self.ended.insert(key, ended);
        }
    }

    /// The task-measured parts of `stage`'s time and its invocation overhead: the invoker's
    /// wall time of each task's recorded attempt minus the task's own time (0 where the task
    /// measured more, as a function on another clock might). `orchestration` is left at 0:
    /// it needs the stage's wall-clock window (see `uncovered`).
    pub fn stage_breakdown(&self, stage: Stage) -> StageBreakdown {
        let range = stage_range(stage);
        let overhead_us: u64 = self
            .wall_us
            .range(range.clone())
            .map(|(id, wall)| {
                let own = self.tasks.get(id).map_or(0, |m| m.task_us);
                wall.saturating_sub(own)
            })
            .sum();
        StageBreakdown {
            invocation: overhead_us as f64 / 1e6,
            ..StageBreakdown::from_tasks(&self.stage(stage))
        }
    }

    /// The summed metrics of one successful attempt per task of `stage`.
    pub fn stage(&self, stage: Stage) -> TaskMetrics {
        let mut total = TaskMetrics::default();
        for (_, m) in self.tasks.range(stage_range(stage)) {
            total += *m;
        }
        total
    }

    /// Each frame of a job of several frames, in frame order (empty for a job of one frame):
    /// when it was ready after `started` (the end of the last of its `stage` tasks, the frame's
    /// last pixel stage, whose last task assembles it), its shadow rays and its tasks' own
    /// seconds over every stage.
    pub fn frames(&self, stage: Stage, started: Instant) -> Vec<FrameFigures> {
        let mut frames: BTreeMap<u32, FrameFigures> = BTreeMap::new();
        for ((_, frame, _), m) in &self.tasks {
            if let Some(frame) = *frame {
                let f = frames.entry(frame).or_insert(FrameFigures {
                    frame,
                    ready_seconds: 0.0,
                    shadow_rays: 0,
                    task_seconds: 0.0,
                });
                f.shadow_rays += m.shadow_rays;
                f.task_seconds += m.task_us as f64 / 1e6;
            }
        }
        for ((_, frame, _), ended) in self.ended.range(stage_range(stage)) {
            if let Some(f) = frame.and_then(|k| frames.get_mut(&k)) {
                let at = ended.saturating_duration_since(started).as_secs_f64();
                f.ready_seconds = f.ready_seconds.max(at);
            }
        }
        frames.into_values().collect()
    }

    /// The summed metrics of one successful attempt per task, over all stages.
    pub fn total(&self) -> TaskMetrics {
        let mut total = TaskMetrics::default();
        for m in self.tasks.values() {
            total += *m;
        }
        total
    }
}

/// Runs the handlers in this process.
pub struct InProcessInvoker {
    store: Arc<dyn BlobStore>,
    bucket: String,
    work_dir: PathBuf,
    cache_bytes: u64,
    /// The memory each Worker invocation may use; `None`: measured, not enforced.
    budget: Option<MemoryBudget>,
    /// Idle warm containers' caches; an invocation takes one (or a cold one) and gives it back.
    caches: Mutex<Vec<SplitCache>>,
    ledger: Mutex<Ledger>,
    /// Invocations running now (abandoned ones included, until their handler returns).
    in_flight: Mutex<usize>,
    idle: std::sync::Condvar,
}

impl InProcessInvoker {
    /// Handlers over `store` (bucket `bucket`), a scratch folder for the Plan function's scene
    /// copy, and `cache_bytes` of decoded splits per warm worker.
    pub fn new(
        store: Arc<dyn BlobStore>,
        bucket: &str,
        work_dir: PathBuf,
        cache_bytes: u64,
    ) -> Self {
        InProcessInvoker {
            store,
            bucket: bucket.to_string(),
            work_dir,
            cache_bytes,
            budget: None,
            caches: Mutex::new(Vec::new()),
            ledger: Mutex::new(Ledger::default()),
            in_flight: Mutex::new(0),
            idle: std::sync::Condvar::new(),
        }
    }

    /// Holds every Worker invocation to `budget`: an attempt whose measured memory does not fit
    /// fails with [`super::OUT_OF_MEMORY`] (see [`MemoryBudget::check`]). Only where the
    /// process's global allocator is `hort_task_memory::TaskAlloc`: without it nothing is
    /// measured and nothing is enforced.
    pub fn with_memory_budget(mut self, budget: MemoryBudget) -> Self {
        self.budget = Some(budget);
        self
    }

    /// A copy of the ledger so far.
    pub fn ledger(&self) -> Ledger {
        self.ledger
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// Waits until no invocation runs, at most `limit`; true if none does. The state machine
    /// abandons attempts (timeouts, a cancelled run) whose handlers may still be writing: a
    /// caller that deletes a job's objects waits here first, so nothing lands after.
    pub fn wait_idle(&self, limit: std::time::Duration) -> bool {
        let running = self.in_flight.lock().unwrap_or_else(|e| e.into_inner());
        let (running, _) = self
            .idle
            .wait_timeout_while(running, limit, |n| *n > 0)
            .unwrap_or_else(|e| e.into_inner());
        *running == 0
    }

    /// Invokes `function` with `input` against `store` (the fault injector passes a failing
    /// store here).
    pub fn invoke_with_store(
        &self,
        function: &str,
        input: Value,
        store: &dyn BlobStore,
    ) -> Result<Value, TaskFailure> {
        *self.in_flight.lock().unwrap_or_else(|e| e.into_inner()) += 1;
        let started = Instant::now();
        let result = self.dispatch(function, input, store);
        let ended = Instant::now();
        {
            let mut running = self.in_flight.lock().unwrap_or_else(|e| e.into_inner());
            *running -= 1;
            if *running == 0 {
                self.idle.notify_all();
            }
        }
        let (result, done) = match result {
            Ok(invoked) => (Ok(invoked.output), invoked.task),
            Err(e) => (Err(e), None),
        };
        self.ledger
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .record(started, ended, done);
        result
    }

    fn dispatch(
        &self,
        function: &str,
        input: Value,
        store: &dyn BlobStore,
    ) -> Result<Invoked, TaskFailure> {
        let Some(function) = Function::from_state_machine_name(function) else {
            return Err(TaskFailure::new(
                "Lambda.ResourceNotFoundException",
                format!("no function named {function}"),
            ));
        };
        // An invocation takes an idle warm container's cache (or a cold one) and gives it back.
        let cache = self
            .caches
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .pop()
            .unwrap_or_else(|| SplitCache::new(self.cache_bytes));
        // Each function's /tmp as the template sets it (the emulator's folder stands in).
        let deployed = crate::deployment::Deployment::bundled();
        let tmp_mb = match function {
            Function::Plan => deployed.plan.tmp_mb,
            Function::Worker => deployed.worker.tmp_mb,
        };
        let env = FunctionEnv {
            store,
            bucket: &self.bucket,
            tmp: Tmp {
                dir: &self.work_dir,
                limit_bytes: Some(u64::from(tmp_mb) << 20),
            },
            split_cache: &cache,
            // The emulator's clients plan every job for the functions' own memory (`--memory-mb`
            // is both), so the Plan function's check could only refuse what a harness built
            // on purpose, such as a job planned past its functions to reach the Worker's
            // `Runtime.OutOfMemory`; the deployment sets it (`HORT_WORKER_MEMORY_MB` for the
            // Plan function, Lambda's `AWS_LAMBDA_FUNCTION_MEMORY_SIZE` for the Worker).
            worker_memory_mb: None,
        };
        let attempt = input.get("attempt").and_then(Value::as_u64).unwrap_or(0);
        // The warm container's splits are its memory too, whichever task uses them.
        let resident = cache.resident_bytes();
        let (result, measured) = hort_task_memory::measure(|| dispatch(function, input, &env));
        self.caches
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(cache);
        let mut invoked = result.map_err(|e| TaskFailure::new(e.error_type.as_str(), e.cause))?;
        // The Plan function (task 0 of stage `plan`, time breakdown only) is measured, not
        // held to the budget; its answer is the plan output, which stays as it is.
        let worker_task = invoked.task.filter(|done| done.stage != Stage::Plan);
        if let (None, Some(measured)) = (worker_task, measured) {
            let peak = resident.saturating_add(measured);
            {
                let mut ledger = self.ledger.lock().unwrap_or_else(|e| e.into_inner());
                ledger.plan_peak_memory_bytes = ledger.plan_peak_memory_bytes.max(peak);
            }
            if let Some(done) = &mut invoked.task {
                done.metrics.peak_memory_bytes = peak;
            }
            // The Plan function's own memory, as the template sets it.
            let plan = MemoryBudget {
                mb: deployed.plan.memory_mb,
            };
            if let Some(failure) = plan.check(Stage::Plan, 0, attempt, peak) {
                return Err(failure);
            }
        }
        if let (Some(done), Some(measured)) = (worker_task, measured) {
            let peak = resident.saturating_add(measured);
            invoked.set_peak_memory(peak);
            let over = self
                .budget
                .and_then(|budget| budget.check(done.stage, done.task.0, attempt, peak));
            if let Some(failure) = over {
                return Err(failure);
            }
        }
        Ok(invoked)
    }
}

impl TaskInvoker for InProcessInvoker {
    fn invoke(&self, resource: &str, input: Value) -> Result<Value, TaskFailure> {
        let store = Arc::clone(&self.store);
        self.invoke_with_store(resource, input, store.as_ref())
    }
}
