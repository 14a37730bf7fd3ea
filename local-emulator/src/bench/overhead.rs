//! The emulator's fixed cost per stage and per task: two jobs whose tasks do almost nothing
//! (a small scene, a tiny image) on one function slot, one with few spans and one with many.
//! On one slot a stage's wall time is its fixed cost plus the sum of its tasks' times, so the
//! task stages' summed wall time is `W = stages x per_stage + tasks x per_task`; the two jobs
//! have the same stages and different task counts, which gives both unknowns. The report's time
//! breakdown of the larger job says what a task's fixed cost is made of.

use super::table::Table;
use anyhow::{Result, bail};
use asl_interpreter::NoObserver;
use hort::emulator::{EmulatorConfig, EmulatorRun, run_job};
use hort_core::breakdown::StageBreakdown;
use hort_core::pipeline::{PlanRequest, SplitMode};
use std::path::Path;

/// Image size of the overhead jobs: small enough that tracing is negligible.
const SIZE: (u32, u32) = (32, 24);
/// Scene splits of the overhead jobs.
const SPLITS: u32 = 2;
/// Span counts of the two jobs.
const SPANS: [u32; 2] = [2, 32];

/// Task stages' summed wall time, their count and their tasks' count (the plan stage, which
/// runs no Map, left out).
fn task_stages(run: &EmulatorRun) -> (f64, f64, f64) {
    let stages: Vec<_> = run.stages.iter().filter(|s| s.name != "plan").collect();
    let wall = stages.iter().map(|s| s.seconds).sum();
    let tasks = stages.iter().map(|s| s.tasks as f64).sum();
    (wall, stages.len() as f64, tasks)
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
        };
        runs.push(run_job(&config, scene, request, &NoObserver)?);
    }
    let (w1, stages1, t1) = task_stages(&runs[0]);
    let (w2, stages2, t2) = task_stages(&runs[1]);
    if stages1 != stages2 || t2 <= t1 {
        bail!("the overhead jobs differ in stages ({stages1}, {stages2}) or not in tasks");
    }
    let per_task = (w2 - w1) / (t2 - t1);
    let per_stage = (w1 - t1 * per_task) / stages1;
    let big = &runs[1];
    let mut sum = StageBreakdown::default();
    for s in big.stages.iter().filter(|s| s.name != "plan") {
        let b = &s.breakdown;
        sum.task += b.task;
        sum.storage += b.storage;
        sum.decode += b.decode;
        sum.encode += b.encode;
        sum.compute += b.compute;
        sum.invocation += b.invocation;
        sum.orchestration += b.orchestration;
    }
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
    row("per stage", per_stage, "fit of both jobs' stage times");
    row("per task", per_task, "fit of both jobs' stage times");
    let fit_note = format!("s={} breakdown, per stage", SPANS[1]);
    row("  orchestration", sum.orchestration / stages2, &fit_note);
    let note = format!("s={} breakdown, per task", SPANS[1]);
    row("  task own time", sum.task / t2, &note);
    row("    storage", sum.storage / t2, &note);
    row("    decode", sum.decode / t2, &note);
    row("    encode", sum.encode / t2, &note);
    row("    compute", sum.compute / t2, &note);
    row("  invocation", sum.invocation / t2, &note);
    Ok(table)
}
