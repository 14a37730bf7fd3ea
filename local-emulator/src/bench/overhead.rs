//! The emulator's fixed cost per stage and per task: two jobs whose tasks do almost nothing
//! (a small scene, a tiny image) on one function slot, one with few spans and one with many.
//! Tasks then run one after another, and the report's time breakdown says where each second
//! went. A stage's orchestration time (no invocation running) is a fixed part per stage plus a
//! gap per task (handing out the next item): `O = stages x per_stage + tasks x gap`. The two
//! jobs have the same stages and different task counts, which gives both. A task's fixed cost
//! is its own time and its invocation overhead (means over the larger job) plus that gap.
//! Fitting the stages' whole wall time instead would take the difference of two large sums
//! and drown the small per-stage part in their noise.

use super::table::Table;
use anyhow::{Result, bail};
use asl_interpreter::NoObserver;
use hort::emulator::{EmulatorConfig, EmulatorRun, run_job};
use hort_core::breakdown::StageBreakdown;
use hort_core::pipeline::{PlanRequest, SplitMode, StoredOutputs};
use std::path::Path;

/// Image size of the overhead jobs: small enough that tracing is negligible.
const SIZE: (u32, u32) = (32, 24);
/// Scene splits of the overhead jobs.
const SPLITS: u32 = 2;
/// Span counts of the two jobs.
const SPANS: [u32; 2] = [2, 32];

/// The task stages' summed breakdown, their count and their tasks' count (the plan stage,
/// which runs no Map, left out).
fn task_stages(run: &EmulatorRun) -> (StageBreakdown, f64, f64) {
    let mut sum = StageBreakdown::default();
    let (mut stages, mut tasks) = (0.0, 0.0);
    for s in run.stages.iter().filter(|s| s.name != "plan") {
        let b = &s.breakdown;
        sum.task += b.task;
        sum.compute += b.compute;
        sum.encode += b.encode;
        sum.decode += b.decode;
        sum.storage += b.storage;
        sum.invocation += b.invocation;
        sum.orchestration += b.orchestration;
        stages += 1.0;
        tasks += s.tasks as f64;
    }
    (sum, stages, tasks)
}

/// Runs the two overhead jobs on `scene` with `config` (its `workers` forced to 1) and returns
/// the table: the fitted seconds per stage and per task, then what the breakdown of the larger
/// job says a task and a stage spend.
pub fn overhead_table(config: &EmulatorConfig, scene: &Path) -> Result<Table> {
    let config = EmulatorConfig {
        workers: 1,
        ..config.clone()
    };
    let mut runs = Vec::new();
    for spans in SPANS {
        let request = PlanRequest {
            width: SIZE.0,
            height: SIZE.1,
            spp: 1,
            splits: Some(SPLITS),
            spans: Some(spans),
            mode: SplitMode::Spatial,
            execution: Some(hort_core::pipeline::ExecutionMode::Staged),
            memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
            adaptive: None,
            outputs: StoredOutputs::ALL,
            frame: Default::default(),
        };
        runs.push(run_job(&config, scene, request, &NoObserver)?);
    }
    let (b1, stages1, t1) = task_stages(&runs[0]);
    let (sum, stages2, t2) = task_stages(&runs[1]);
    if stages1 != stages2 || t2 <= t1 {
        bail!("the overhead jobs differ in stages ({stages1}, {stages2}) or not in tasks");
    }
    let gap = (sum.orchestration - b1.orchestration) / (t2 - t1);
    let per_stage = (b1.orchestration - t1 * gap) / stages1;
    let requests: u64 = runs[1]
        .usage
        .iter()
        .filter(|u| u.state != "Plan")
        .map(|u| u.traffic.gets + u.traffic.puts + u.traffic.lists)
        .sum();
    let requests_per_task = requests as f64 / t2;
    let own = sum.task / t2;
    let invocation = sum.invocation / t2;
    let mut table = Table::new(
        &format!(
            "emulator fixed overhead: 1 slot, {}x{}, k={SPLITS}, s={} ({t1} tasks) vs s={} ({t2} \
             tasks), {stages1} task stages",
            SIZE.0, SIZE.1, SPANS[0], SPANS[1]
        ),
        &["measure", "seconds", "from"],
    );
    let mut row = |measure: &str, seconds: f64, from: &str| {
        table.push(vec![measure.into(), format!("{seconds:.4}"), from.into()]);
    };
    let fit = "orchestration of both jobs, fitted";
    let mean = format!("s={} job, mean per task", SPANS[1]);
    row("per stage", per_stage, fit);
    row("per task", own + invocation + gap, "the three rows below");
    row("  task own time", own, &mean);
    row("    storage", sum.storage / t2, &mean);
    row(
        "      per request",
        sum.storage / t2 / requests_per_task,
        &format!("{requests_per_task:.2} storage requests per task"),
    );
    row("    decode", sum.decode / t2, &mean);
    row("    encode", sum.encode / t2, &mean);
    row("    compute", sum.compute / t2, &mean);
    row("  invocation", invocation, &mean);
    row("  orchestration gap", gap, fit);
    Ok(table)
}
