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
use crate::ids::Stage;
use crate::pipeline::JobPlan;
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
/// The embedded S3 server's time per further request, ms (`hort bench emulator`'s fixed-cost
/// table: about 0.004 s per request on the reference machine).
pub const EMULATOR_REQUEST_MS: f64 = 4.0;
/// The embedded S3 server's time per byte of the job's outputs (Combine's PNG, PFM and hit
/// buffer, stored uncompressed, at once), us at speed 1, beyond Combine's per-pixel rate:
/// fitted 2026-12-02 to the Combine stage of the teapot, the Cornell box and a generated
/// 300,000-triangle scene at 960x540 (storage 0.14 to 0.26 s for 12.4 MB at speed 0.8) and
/// `hort bench plan`. The shuffle blocks of the other stages are compressed and small beside
/// their work.
pub const EMULATOR_OUTPUT_BYTE_US: f64 = 0.012;

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
    let f = &LAMBDA_FACTS;
    let speed = if settings.speed > 0.0 {
        settings.speed
    } else {
        1.0
    };
    let p = settings.fail_rate.clamp(0.0, 0.99);
    let attempts = 1.0 / (1.0 - p);
    let functions = functions.max(1);
    let (memory_mb, arch, aws) = match settings.target {
        Target::Aws { memory_mb, arch } => (memory_mb, arch, true),
        Target::Emulator {
            memory_mb, arch, ..
        } => (memory_mb, arch, false),
    };
    let concurrency = if aws {
        functions.min(f.map_max_children)
    } else {
        functions
    };
    // The work alone: the same rates with the fixed overheads left out.
    let work_rates = Rates {
        task_overhead_ms: 0.0,
        plan_overhead_ms: 0.0,
        ..settings.rates
    };
    let vcpu = if aws {
        (f.vcpu_memory_mb / f64::from(memory_mb)).max(1.0)
    } else {
        1.0
    };
    let mut notes = Vec::new();
    let mut stages = Vec::new();
    let mut seconds = 0.0;
    let mut function_seconds = 0.0;
    let (mut gets, mut puts) = (0.0f64, CLIENT_PUTS as f64);
    let mut cost = CostBreakdown::default();
    let mut children = 0u64;
    let mut first_worker_stage = true;
    for step in job_steps(plan) {
        let tasks = step_tasks(plan, step);
        let (g, pu) = stage_requests(plan, step);
        let bytes = stage_bytes(plan, step);
        let per_task = |n: u64| n as f64 / tasks.max(1) as f64;
        let work_ms = task_milliseconds(plan, step, &work_rates, speed) * vcpu;
        let fixed_ms = if step.is_plan_function() {
            settings.rates.plan_overhead_ms
        } else {
            settings.rates.task_overhead_ms
        };
        let round_trips = per_task(g) + per_task(pu);
        // Requests a task waits for one after another (several inputs are fetched at once).
        let waits = task_waits(plan, step);
        let (task_ms, seconds_of_stage, bound) = match settings.target {
            Target::Aws { .. } => {
                let moved = bytes + stage_bytes_read(plan, step);
                let task_ms = f.invoke_ms
                    + waits * f.s3_first_byte_ms
                    + per_task(moved) / (f.s3_mb_per_s * 1e3)
                    + work_ms;
                let c = u64::from(concurrency).min(tasks.max(1));
                let waves = (tasks as f64 * attempts / c as f64).ceil().max(1.0);
                // Each function's first read of a split: fetch and decode, in parallel; a warm
                // function keeps it, and reads at most one per task.
                let largest_bytes = plan.splits.iter().map(|s| s.bytes).max().unwrap_or(0);
                let decode_ms = split_load_ms(plan, step, &settings.rates, speed);
                let load_ms = if decode_ms > 0.0 {
                    decode_ms * vcpu + largest_bytes as f64 / (f.s3_mb_per_s * 1e3)
                } else {
                    0.0
                };
                let loads = f64::from(plan.k()).min(waves);
                let mut wave_s = (waves * task_ms + loads * load_ms) / 1e3;
                if !step.is_plan_function() && first_worker_stage {
                    // New environments: init plus a first S3 connection, once; beyond 1,000
                    // at once Lambda adds 1,000 environments per 10 s.
                    let cold = match arch {
                        Arch::Arm64 => f.cold_start_ms_arm64,
                        Arch::X86_64 => f.cold_start_ms_x86_64,
                    };
                    wave_s += (cold + f.s3_first_byte_ms) / 1e3;
                    let ramps = ((c as f64 / f.scale_per_10s).ceil() - 1.0).max(0.0);
                    wave_s += ramps * 10.0;
                    first_worker_stage = false;
                }
                let s3_s = (g as f64 * attempts / f.s3_gets_per_s)
                    .max(pu as f64 * attempts / f.s3_puts_per_s);
                let starts_s = if step.is_map() {
                    tasks as f64 * attempts / f.map_starts_per_s
                } else {
                    0.0
                };
                let (s, bound) = [(wave_s, "waves"), (s3_s, "s3"), (starts_s, "map-starts")]
                    .into_iter()
                    .fold((0.0, "waves"), |a, b| if b.0 > a.0 { b } else { a });
                (task_ms, s, bound)
            }
            Target::Emulator {
                cores,
                s3_latency_ms,
                ..
            } => {
                // The fixed overhead covers a task's first few requests; the rest cost the
                // embedded server's own time each.
                let extra = (round_trips - EMULATOR_REQUESTS_IN_OVERHEAD).max(0.0);
                let bytes_ms = if step == JobStep::Stage(Stage::Combine) {
                    per_task(bytes) * EMULATOR_OUTPUT_BYTE_US / 1e3 / speed
                } else {
                    0.0
                };
                let cpu_ms = fixed_ms + work_ms + extra * EMULATOR_REQUEST_MS + bytes_ms;
                let runs = (tasks as f64 * attempts).ceil().max(1.0);
                let w = f64::from(concurrency).min(runs);
                // A warm slot keeps the plan and the splits it read: only each slot's first
                // task reads them (the steps that split a scene by tasks read no plan).
                let cached = match step {
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
                        (1.0 + splits) * (1.0 - w / runs)
                    }
                    _ => 0.0,
                };
                let wait_ms = (waits - cached).max(0.0) * s3_latency_ms;
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
                let load_ms =
                    loads * split_load_ms(plan, step, &settings.rates, speed) * (w / c).max(1.0);
                let s = (full * wave(w) + wave(rest) + load_ms) / 1e3;
                let bound = if w > c && wave(w) > task_ms {
                    "cores"
                } else {
                    "waves"
                };
                (task_ms, s, bound)
            }
        };
        let tail_s = (1.0 - (1.0 - p).powf(tasks as f64)) * (task_ms / 1e3 + f.retry_interval_s);
        let stage_s = settings.rates.stage_overhead_ms / 1e3 + seconds_of_stage + tail_s;
        seconds += stage_s;
        let is_map = step.is_map();
        if is_map {
            children += tasks;
        }
        let runs = tasks as f64 * attempts;
        function_seconds += runs * task_ms / 1e3;
        gets += g as f64 * attempts;
        puts += pu as f64 * attempts;
        let one = estimate(&CostInputs {
            arch,
            memory_mb,
            invocation_ms: vec![task_ms],
            express_ms: if is_map { vec![task_ms] } else { Vec::new() },
            ..CostInputs::default()
        });
        add(&mut cost, &one, runs);
        stages.push(StageProjection {
            name: step.name().to_owned(),
            tasks,
            bytes,
            task_seconds: task_ms / 1e3,
            seconds: stage_s,
            bound: bound.to_owned(),
            s3_gets: (g as f64 * attempts).round() as u64,
            s3_puts: (pu as f64 * attempts).round() as u64,
        });
    }
    let bytes: u64 = stages.iter().map(|s| s.bytes).sum();
    seconds += match settings.target {
        Target::Aws { .. } => {
            // Upload the scene (its files, for a scene split by tasks), start the execution,
            // read the outputs back.
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
    };
    let transitions = standard_transitions(plan, children);
    let rest = estimate(&CostInputs {
        arch,
        memory_mb,
        s3_put_like: puts.round() as u64,
        s3_get_like: gets.round() as u64,
        s3_byte_seconds: bytes as f64 * seconds,
        standard_transitions: transitions,
        ..CostInputs::default()
    });
    add(&mut cost, &rest, 1.0);
    let widest = stages.iter().map(|s| s.tasks).max().unwrap_or(1);
    if aws {
        let used = u64::from(concurrency).min(widest);
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
    }
    Projection {
        functions,
        concurrency,
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
