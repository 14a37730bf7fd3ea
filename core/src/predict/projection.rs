//! A job's projected wall time, function-seconds, requests and dollars on N functions, on AWS
//! Lambda or on the local emulator, from the per-task model of [`super::predict`].
//!
//! # Guarantees
//! - Same plan, same per-task work: a task's compute is [`task_milliseconds`] with the fixed
//!   overheads left out, and its requests and bytes are [`stage_requests`] and [`stage_bytes`],
//!   so the projection and `POST /renders?dry_run=true` count the same tasks and requests.
//! - A stage of T tasks on C slots takes ceil(T / C) task times, but never less than the
//!   floors AWS imposes (S3 requests per second on the job's one prefix, Map children started
//!   per second); more functions never make a stage's waves longer, so seconds do not grow with
//!   N except by the cold-start ramp ([`LambdaFacts::scale_per_10s`]), which is stated.
//! - Dollars are `crate::cost::estimate` over the projected invocations, requests and
//!   transitions: the constants of `core/src/cost.rs`, nothing else.
//! - Retries: at failure rate P every task runs 1 / (1 - P) attempts on average (billed,
//!   requested and waited for), and a stage with a failure waits one more attempt plus the state
//!   machine's 1 s retry interval with probability 1 - (1 - P)^T (the straggler tail).

use crate::cost::{Arch, CostBreakdown, CostInputs, estimate};
use crate::pipeline::JobPlan;
use crate::stage::Stage;
use serde::Serialize;

use super::{
    CLIENT_PUTS, JobStep, Rates, add, job_steps, split_load_ms, stage_bytes, stage_bytes_read,
    stage_requests, standard_transitions, step_tasks, task_milliseconds, task_waits, upload_ms,
};

/// The function counts of the sweep every projection reports.
pub const SWEEP: [u32; 4] = [10, 100, 1_000, 10_000];

/// Facts about AWS the Lambda projection uses, with their sources (read 2026-11).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct LambdaFacts {
    /// Memory that buys one full vCPU, MB: below it a task's compute stretches by
    /// `vcpu_memory_mb / memory_mb`; above it a single-threaded task gains nothing (Lambda
    /// developer guide, "Configuring Lambda function memory").
    pub vcpu_memory_mb: f64,
    /// Init of a Rust `provided.al2023` function, ms, arm64.
    pub cold_start_ms_arm64: f64,
    /// Init of a Rust `provided.al2023` function, ms, x86_64.
    pub cold_start_ms_x86_64: f64,
    /// Step Functions to Lambda dispatch of one task, ms (our estimate).
    pub invoke_ms: f64,
    /// S3 first byte of one request from Lambda in the same Region, ms (S3 performance
    /// guidelines: 100 to 200 ms for small objects at the tail, about 30 typical).
    pub s3_first_byte_ms: f64,
    /// S3 throughput of one connection from a function, MB/s (our estimate).
    pub s3_mb_per_s: f64,
    /// PUT-like requests per second per partitioned prefix before 503 SlowDown (S3 user
    /// guide, "Best practices design patterns: optimizing Amazon S3 performance").
    pub s3_puts_per_s: f64,
    /// GET-like requests per second per partitioned prefix.
    pub s3_gets_per_s: f64,
    /// New execution environments Lambda adds per 10 s per function (Lambda scaling behavior).
    pub scale_per_10s: f64,
    /// Default concurrent executions per Region; more needs a quota raise.
    pub default_concurrency: u32,
    /// Parallel child executions of one Distributed Map run.
    pub map_max_children: u32,
    /// Child executions a Map state starts per second (StartExecution refill rate).
    pub map_starts_per_s: f64,
    /// The state machine's first retry interval, s (`infra/statemachine.asl.json`).
    pub retry_interval_s: f64,
}

/// The values [`project`] uses for AWS.
pub const LAMBDA_FACTS: LambdaFacts = LambdaFacts {
    vcpu_memory_mb: 1769.0,
    cold_start_ms_arm64: 13.0,
    cold_start_ms_x86_64: 17.0,
    invoke_ms: 10.0,
    s3_first_byte_ms: 30.0,
    s3_mb_per_s: 90.0,
    s3_puts_per_s: 3500.0,
    s3_gets_per_s: 5500.0,
    scale_per_10s: 1000.0,
    default_concurrency: 1000,
    map_max_children: 10_000,
    map_starts_per_s: 300.0,
    retry_interval_s: 1.0,
};

/// Requests of one task the emulator's fixed task overhead (`Rates::task_overhead_ms`) covers.
pub const EMULATOR_REQUESTS_IN_OVERHEAD: f64 = 3.0;
/// The embedded S3 server's time per further request, ms, in a release build on the reference
/// machine (fitted with [`super::RATES`]).
pub const EMULATOR_REQUEST_MS: f64 = 0.5;
/// The embedded S3 server's time per byte of the job's outputs (Combine's PNG, and the PFM and
/// hit buffer when the job stores them, uncompressed, at once), us at speed 1, beyond
/// Combine's per-pixel rate: fitted with [`super::RATES`] from the Combine stage of the teapot
/// at 1920x1080 storing the PNG only and the PNG, PFM and hit buffer (41.5 MB more: 0.23 s
/// more at speed 0.7). The shuffle blocks of the other stages are compressed and small beside
/// their work.
pub const EMULATOR_OUTPUT_BYTE_US: f64 = 0.004;

/// Where the job would run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "target")]
pub enum Target {
    /// AWS Lambda and Step Functions with functions of `memory_mb` on `arch`.
    Aws {
        /// Function memory, MB.
        memory_mb: u32,
        /// Instruction set.
        arch: Arch,
    },
    /// The local emulator (`hort render --workers N`) on a machine of `cores` cores, its
    /// embedded S3 server delaying every request by `s3_latency_ms`.
    Emulator {
        /// Cores the function slots share.
        cores: u32,
        /// Injected delay of every S3 request, ms.
        s3_latency_ms: f64,
        /// Memory the cost estimate assumes, MB.
        memory_mb: u32,
        /// Architecture the cost estimate assumes.
        arch: Arch,
    },
}

/// What a projection assumes besides the plan.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ProjectionSettings {
    /// Where it runs.
    pub target: Target,
    /// How much faster than the reference machine of [`super::RATES`] one function's core
    /// computes (a calibration's result; 1 = the reference machine).
    pub speed: f64,
    /// The per-unit costs.
    pub rates: Rates,
    /// Probability that an attempt fails and is retried, 0 to below 1.
    pub fail_rate: f64,
}

/// One stage of a projection.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageProjection {
    /// The stage's name.
    pub name: String,
    /// Its tasks (the plan's task count).
    pub tasks: u64,
    /// Estimated bytes it writes.
    pub bytes: u64,
    /// Seconds of one attempt of one task.
    pub task_seconds: f64,
    /// Seconds of the stage, from its start to its last task's end.
    pub seconds: f64,
    /// What bounds the stage: `waves` (ceil(T / C) task times), `s3` (requests per second on
    /// the job's prefix), `map-starts` (children started per second) or `cores` (emulator slots
    /// sharing fewer cores).
    pub bound: String,
    /// S3 GET-like requests.
    pub s3_gets: u64,
    /// S3 PUT-like requests.
    pub s3_puts: u64,
}

/// A job projected on `functions` functions.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Projection {
    /// Functions (Lambda concurrency, or emulator slots).
    pub functions: u32,
    /// Tasks that actually run at once: `functions`, capped by the Map's 10,000 children.
    pub concurrency: u32,
    /// Wall seconds from upload to outputs read back.
    pub seconds: f64,
    /// Billed function-seconds (every attempt).
    pub function_seconds: f64,
    /// S3 GET-like requests (every attempt).
    pub s3_gets: u64,
    /// S3 PUT-like requests (every attempt, and the client's upload).
    pub s3_puts: u64,
    /// Step Functions Standard state transitions.
    pub transitions: u64,
    /// Projected cost, USD.
    pub dollars: f64,
    /// The cost per service line.
    pub cost: CostBreakdown,
    /// Every stage in order.
    pub stages: Vec<StageProjection>,
    /// Limits the run meets, one sentence each (quota raises, throttles).
    pub notes: Vec<String>,
}

/// Projects `plan` on `functions` functions under `settings` (see the module documentation).
pub fn project(plan: &JobPlan, functions: u32, settings: &ProjectionSettings) -> Projection {
    let a = Assumptions::new(functions, settings);
    let mut totals = Totals::new();
    let mut first_worker_stage = true;
    for step in job_steps(plan) {
        let work = StepWork::new(plan, step, &a);
        let time = match settings.target {
            Target::Aws { .. } => aws_step_time(plan, &work, &a, settings, &mut first_worker_stage),
            Target::Emulator {
                cores,
                s3_latency_ms,
                ..
            } => emulator_step_time(plan, &work, &a, settings, cores, s3_latency_ms),
        };
        totals.add_step(&work, &time, &a, settings);
    }
    let Totals {
        stages,
        mut seconds,
        function_seconds,
        gets,
        puts,
        mut cost,
        children,
    } = totals;
    let bytes: u64 = stages.iter().map(|s| s.bytes).sum();
    seconds += client_seconds(plan, settings, a.speed);
    let transitions = standard_transitions(plan, children);
    let rest = estimate(&CostInputs {
        arch: a.arch,
        memory_mb: a.memory_mb,
        s3_put_like: puts.round() as u64,
        s3_get_like: gets.round() as u64,
        s3_byte_seconds: bytes as f64 * seconds,
        standard_transitions: transitions,
        ..CostInputs::default()
    });
    add(&mut cost, &rest, 1.0);
    let notes = if a.aws {
        aws_notes(&a, &stages)
    } else {
        Vec::new()
    };
    Projection {
        functions: a.functions,
        concurrency: a.concurrency,
        seconds,
        function_seconds,
        s3_gets: gets.round() as u64,
        s3_puts: puts.round() as u64,
        transitions,
        dollars: cost.total,
        cost,
        stages,
        notes,
    }
}

/// What [`project`] derives from its settings once, for every step.
struct Assumptions {
    /// The settings' speed, 1 unless positive.
    speed: f64,
    /// The failure rate, clamped to 0..=0.99.
    p: f64,
    /// Attempts per task on average: 1 / (1 - p).
    attempts: f64,
    /// The functions asked for, at least 1.
    functions: u32,
    /// Tasks at once: `functions`, on AWS capped by the Map's children.
    concurrency: u32,
    /// The target's function memory and architecture (the cost estimate's).
    memory_mb: u32,
    arch: Arch,
    /// True on AWS, false on the emulator.
    aws: bool,
    /// The settings' rates with the fixed overheads left out: the work alone.
    work_rates: Rates,
    /// How much a function's compute stretches for want of a full vCPU (1 on the emulator).
    vcpu: f64,
}

impl Assumptions {
    fn new(functions: u32, settings: &ProjectionSettings) -> Assumptions {
        let f = &LAMBDA_FACTS;
        let speed = if settings.speed > 0.0 {
            settings.speed
        } else {
            1.0
        };
        let p = settings.fail_rate.clamp(0.0, 0.99);
        let functions = functions.max(1);
        let (memory_mb, arch, aws) = match settings.target {
            Target::Aws { memory_mb, arch } => (memory_mb, arch, true),
            Target::Emulator {
                memory_mb, arch, ..
            } => (memory_mb, arch, false),
        };
        Assumptions {
            speed,
            p,
            attempts: 1.0 / (1.0 - p),
            functions,
            concurrency: if aws {
                functions.min(f.map_max_children)
            } else {
                functions
            },
            memory_mb,
            arch,
            aws,
            work_rates: Rates {
                task_overhead_ms: 0.0,
                plan_overhead_ms: 0.0,
                ..settings.rates
            },
            vcpu: if aws {
                (f.vcpu_memory_mb / f64::from(memory_mb)).max(1.0)
            } else {
                1.0
            },
        }
    }
}

/// One step's tasks, requests, bytes and per-task work, as the model counts them.
struct StepWork {
    step: JobStep,
    tasks: u64,
    /// S3 GET-like and PUT-like requests of one attempt of every task.
    gets: u64,
    puts: u64,
    /// Estimated bytes the step writes.
    bytes: u64,
    /// A task's compute, ms, without the fixed overheads (stretched by the vCPU share).
    work_ms: f64,
    /// Requests a task waits for one after another (several inputs are fetched at once).
    waits: f64,
}

impl StepWork {
    fn new(plan: &JobPlan, step: JobStep, a: &Assumptions) -> StepWork {
        let (gets, puts) = stage_requests(plan, step);
        StepWork {
            step,
            tasks: step_tasks(plan, step),
            gets,
            puts,
            bytes: stage_bytes(plan, step),
            work_ms: task_milliseconds(plan, step, &a.work_rates, a.speed) * a.vcpu,
            waits: task_waits(plan, step),
        }
    }

    /// `n` spread over the step's tasks.
    fn per_task(&self, n: u64) -> f64 {
        n as f64 / self.tasks.max(1) as f64
    }
}

/// One step's projected time, before its overhead and retry tail.
struct StepTime {
    /// Milliseconds of one attempt of one task.
    task_ms: f64,
    /// Seconds of the step's waves (or of the floor that bounds it).
    seconds: f64,
    /// What bounds it (see [`StageProjection::bound`]).
    bound: &'static str,
}

/// A step on AWS Lambda: the longest of its waves of tasks (with the split loads and, for the
/// first worker stage, the cold start and scaling ramp), its S3 requests at the prefix's rate
/// and its Map children's starts. Clears `first_worker_stage` once it counted the cold start.
fn aws_step_time(
    plan: &JobPlan,
    work: &StepWork,
    a: &Assumptions,
    settings: &ProjectionSettings,
    first_worker_stage: &mut bool,
) -> StepTime {
    let f = &LAMBDA_FACTS;
    let (step, tasks, attempts) = (work.step, work.tasks, a.attempts);
    let moved = work.bytes + stage_bytes_read(plan, step);
    let task_ms = f.invoke_ms
        + work.waits * f.s3_first_byte_ms
        + work.per_task(moved) / (f.s3_mb_per_s * 1e3)
        + work.work_ms;
    let c = u64::from(a.concurrency).min(tasks.max(1));
    let waves = (tasks as f64 * attempts / c as f64).ceil().max(1.0);
    // Each function's first read of a split: fetch and decode, in parallel; a warm
    // function keeps it, and reads at most one per task.
    let largest_bytes = plan.splits.iter().map(|s| s.bytes).max().unwrap_or(0);
    let decode_ms = split_load_ms(plan, step, &settings.rates, a.speed);
    let load_ms = if decode_ms > 0.0 {
        decode_ms * a.vcpu + largest_bytes as f64 / (f.s3_mb_per_s * 1e3)
    } else {
        0.0
    };
    let loads = f64::from(plan.k()).min(waves);
    let mut wave_s = (waves * task_ms + loads * load_ms) / 1e3;
    if !step.is_plan_function() && *first_worker_stage {
        // New environments: init plus a first S3 connection, once; beyond 1,000
        // at once Lambda adds 1,000 environments per 10 s.
        let cold = match a.arch {
            Arch::Arm64 => f.cold_start_ms_arm64,
            Arch::X86_64 => f.cold_start_ms_x86_64,
        };
        wave_s += (cold + f.s3_first_byte_ms) / 1e3;
        let ramps = ((c as f64 / f.scale_per_10s).ceil() - 1.0).max(0.0);
        wave_s += ramps * 10.0;
        *first_worker_stage = false;
    }
    let s3_s = (work.gets as f64 * attempts / f.s3_gets_per_s)
        .max(work.puts as f64 * attempts / f.s3_puts_per_s);
    let starts_s = if step.is_map() {
        tasks as f64 * attempts / f.map_starts_per_s
    } else {
        0.0
    };
    let (seconds, bound) = [(wave_s, "waves"), (s3_s, "s3"), (starts_s, "map-starts")]
        .into_iter()
        .fold((0.0, "waves"), |max, b| if b.0 > max.0 { b } else { max });
    StepTime {
        task_ms,
        seconds,
        bound,
    }
}

/// A step on the local emulator with `cores` cores and `s3_latency_ms` per request: waves of
/// slots whose waits overlap others' compute but whose compute shares the cores, plus each
/// slot's first split loads.
fn emulator_step_time(
    plan: &JobPlan,
    work: &StepWork,
    a: &Assumptions,
    settings: &ProjectionSettings,
    cores: u32,
    s3_latency_ms: f64,
) -> StepTime {
    let (step, speed) = (work.step, a.speed);
    let fixed_ms = if step.is_plan_function() {
        settings.rates.plan_overhead_ms
    } else {
        settings.rates.task_overhead_ms
    };
    let round_trips = work.per_task(work.gets) + work.per_task(work.puts);
    // The fixed overhead covers a task's first few requests; the rest cost the
    // embedded server's own time each.
    let extra = (round_trips - EMULATOR_REQUESTS_IN_OVERHEAD).max(0.0);
    let bytes_ms = if step == JobStep::Stage(Stage::Combine) {
        work.per_task(work.bytes) * EMULATOR_OUTPUT_BYTE_US / 1e3 / speed
    } else {
        0.0
    };
    let cpu_ms = fixed_ms + work.work_ms + extra * EMULATOR_REQUEST_MS + bytes_ms;
    let runs = (work.tasks as f64 * a.attempts).ceil().max(1.0);
    let w = f64::from(a.concurrency).min(runs);
    let cached = warm_reads(plan, step) * (1.0 - w / runs);
    let wait_ms = (work.waits - cached).max(0.0) * s3_latency_ms;
    let task_ms = cpu_ms + wait_ms;
    let c = f64::from(cores.max(1));
    // Slots beyond the cores overlap their waits with others' compute, but the
    // compute of a wave of n tasks takes at least n / cores task computes.
    let full = (runs / w).floor();
    let rest = runs - full * w;
    let wave = |n: f64| {
        if n <= 0.0 {
            0.0
        } else {
            task_ms.max(n * cpu_ms / c)
        }
    };
    // Each slot's first read of each split it needs (a warm slot keeps them),
    // the slots loading at once sharing the cores.
    let loads = f64::from(plan.k()).min((runs / w).ceil());
    let load_ms = loads * split_load_ms(plan, step, &settings.rates, speed) * (w / c).max(1.0);
    let seconds = (full * wave(w) + wave(rest) + load_ms) / 1e3;
    let bound = if w > c && wave(w) > task_ms {
        "cores"
    } else {
        "waves"
    };
    StepTime {
        task_ms,
        seconds,
        bound,
    }
}

/// The reads of one task of `step` a warm emulator slot keeps from its first task (the plan
/// and the splits it read), 0 for the steps that split a scene by tasks (they read no plan).
fn warm_reads(plan: &JobPlan, step: JobStep) -> f64 {
    match step {
        JobStep::Stage(
            Stage::Render
            | Stage::CastMap
            | Stage::CastReduce
            | Stage::Expand
            | Stage::TraceMap
            | Stage::TraceReduce,
        ) => {
            let splits = match step {
                JobStep::Stage(Stage::Render) => f64::from(plan.k()),
                JobStep::Stage(Stage::CastMap | Stage::TraceMap) => 1.0,
                _ => 0.0,
            };
            1.0 + splits
        }
        _ => 0.0,
    }
}

/// The sums over a projection's steps.
struct Totals {
    stages: Vec<StageProjection>,
    seconds: f64,
    function_seconds: f64,
    gets: f64,
    puts: f64,
    cost: CostBreakdown,
    /// Map children started (for the state transitions).
    children: u64,
}

impl Totals {
    /// Nothing run yet but the client's upload PUTs.
    fn new() -> Totals {
        Totals {
            stages: Vec::new(),
            seconds: 0.0,
            function_seconds: 0.0,
            gets: 0.0,
            puts: CLIENT_PUTS as f64,
            cost: CostBreakdown::default(),
            children: 0,
        }
    }

    /// Adds a step that takes `time`: its overhead and retry tail, every attempt's
    /// function-seconds, requests and cost, and its row.
    fn add_step(
        &mut self,
        work: &StepWork,
        time: &StepTime,
        a: &Assumptions,
        settings: &ProjectionSettings,
    ) {
        let (tasks, attempts, task_ms) = (work.tasks, a.attempts, time.task_ms);
        let tail_s = (1.0 - (1.0 - a.p).powf(tasks as f64))
            * (task_ms / 1e3 + LAMBDA_FACTS.retry_interval_s);
        let stage_s = settings.rates.stage_overhead_ms / 1e3 + time.seconds + tail_s;
        self.seconds += stage_s;
        let is_map = work.step.is_map();
        if is_map {
            self.children += tasks;
        }
        let runs = tasks as f64 * attempts;
        self.function_seconds += runs * task_ms / 1e3;
        self.gets += work.gets as f64 * attempts;
        self.puts += work.puts as f64 * attempts;
        let one = estimate(&CostInputs {
            arch: a.arch,
            memory_mb: a.memory_mb,
            invocation_ms: vec![task_ms],
            express_ms: if is_map { vec![task_ms] } else { Vec::new() },
            ..CostInputs::default()
        });
        add(&mut self.cost, &one, runs);
        self.stages.push(StageProjection {
            name: work.step.name().to_owned(),
            tasks,
            bytes: work.bytes,
            task_seconds: task_ms / 1e3,
            seconds: stage_s,
            bound: time.bound.to_owned(),
            s3_gets: (work.gets as f64 * attempts).round() as u64,
            s3_puts: (work.puts as f64 * attempts).round() as u64,
        });
    }
}

/// Seconds of the client's part of a job: on AWS, upload the scene (its files, for a scene split
/// by tasks), start the execution and read the outputs back; on the emulator, its fixed job
/// overhead, the upload (at `speed`) and the client's requests' latency.
fn client_seconds(plan: &JobPlan, settings: &ProjectionSettings, speed: f64) -> f64 {
    let f = &LAMBDA_FACTS;
    match settings.target {
        Target::Aws { .. } => {
            let uploaded = plan
                .scene_parts
                .map_or(plan.scene_bytes(), |parts| parts.scene_bytes);
            (CLIENT_PUTS as f64 + 3.0) * f.s3_first_byte_ms / 1e3
                + uploaded as f64 / (f.s3_mb_per_s * 1e6)
        }
        Target::Emulator { s3_latency_ms, .. } => {
            (settings.rates.job_overhead_ms
                + upload_ms(plan, &settings.rates, speed)
                + (CLIENT_PUTS as f64 + 3.0) * s3_latency_ms)
                / 1e3
        }
    }
}

/// The AWS limits a projection on AWS meets, one sentence each: the default concurrency, the
/// Map's children, S3's requests per prefix.
fn aws_notes(a: &Assumptions, stages: &[StageProjection]) -> Vec<String> {
    let f = &LAMBDA_FACTS;
    let functions = a.functions;
    let mut notes = Vec::new();
    let widest = stages.iter().map(|s| s.tasks).max().unwrap_or(1);
    let used = u64::from(a.concurrency).min(widest);
    if used > u64::from(f.default_concurrency) {
        notes.push(format!(
            "{used} functions at once exceed the default Lambda concurrency of {} per \
             Region: ask for a quota raise",
            f.default_concurrency
        ));
    }
    if functions > f.map_max_children {
        notes.push(format!(
            "a Distributed Map runs at most {} children at once: {functions} functions \
             run as {}",
            f.map_max_children, f.map_max_children
        ));
    }
    if stages.iter().any(|s| s.bound == "s3") {
        notes.push(
            "every key shares the prefix jobs/{job}/ (core/src/keys.rs): S3's 3,500 PUT \
             and 5,500 GET per second per prefix bound a stage"
                .to_owned(),
        );
    }
    notes
}

/// The index of the best projection: the fewest functions whose time is within 5% of the
/// fastest (more functions than that buy almost no time). `None` for an empty slice.
pub fn best_of(projections: &[Projection]) -> Option<usize> {
    let fastest = projections
        .iter()
        .map(|p| p.seconds)
        .fold(f64::INFINITY, f64::min);
    projections
        .iter()
        .enumerate()
        .filter(|(_, p)| p.seconds <= fastest * 1.05)
        .min_by_key(|(_, p)| p.functions)
        .map(|(i, _)| i)
}
