//! What a job will be before it runs: its plan (splits, spans, tasks per stage) and a predicted
//! duration and cost, for `POST /renders?dry_run=true` and the `max_cost_usd` budget.
//!
//! # The plan
//! Exact: the split and span counts of `hort render` ([`resolve_counts`]), the triangles of each
//! split as the Plan function assigns them ([`assign_splits`]), and [`plan_job`] over their
//! bounding boxes, so the CastMap pairs that spatial mode leaves out are left out here too. No
//! BVH is built and nothing is stored.
//!
//! # The duration
//! Each task's time is a fixed overhead (an invocation, its storage round trips) plus its work
//! at a reference rate per unit ([`RATES`]: microseconds per camera sample, shadow ray, record
//! or pixel, measured on the local emulator of a 2-core x86-64 machine), divided by the
//! backend's [`PredictionModel::speed`]. Spans differ by at most one pixel, so the tasks of a
//! stage take the same time and a stage of T tasks on C slots takes ceil(T / C) task times,
//! plus one first read of its largest split (stages that read splits), a fixed orchestration
//! overhead per stage, and one per job (upload, start, outputs read back). Every sample is
//! assumed to hit something, so shadow work is an upper bound. A fused Render ray costs more
//! with the scene's size, by log2 of its triangles (the depth of its BVH).
//!
//! `hort plan` projects the same per-task model onto N functions on Lambda or the emulator
//! (`super::projection`).
//!
//! # The cost
//! The price model of `hort_core::cost` applied to the predicted invocations: one Lambda
//! invocation per task (no retries) at the predicted duration, one EXPRESS child per Map item,
//! the Standard transitions of a run without retries, and the S3 requests each task makes by
//! the dataflow table of docs/ARCHITECTURE.md (its inputs read, its outputs written, the plan
//! read once per task, the Map states' item files).

use hort_core::cost::{Arch, CostBreakdown, CostInputs, estimate, standard_transitions_for};
use hort_core::ids::Stage;
use hort_core::pipeline::{JobPlan, JobShape, PlanRequest, SplitInfo, assign_splits, plan_job};
use hort_core::scene::Scene;
use serde::Serialize;

use super::error::ApiError;

/// Reference costs of the work units, microseconds each, at `speed` 1.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Rates {
    /// A job's fixed cost outside its stages: uploading the scene and the job request,
    /// starting the execution, reading the outputs back (ms).
    pub job_overhead_ms: f64,
    /// A task's fixed cost: invocation, reading the plan, storage round trips (ms).
    pub task_overhead_ms: f64,
    /// A top-level state's fixed cost: orchestration, reading its items (ms).
    pub stage_overhead_ms: f64,
    /// The plan step's fixed cost (ms).
    pub plan_overhead_ms: f64,
    /// Plan: per triangle (split assignment, BVH build, encoding, upload).
    pub plan_us_per_triangle: f64,
    /// CastMap: per camera sample of the span, against one split.
    pub cast_us_per_sample: f64,
    /// CastReduce: per camera sample of the span.
    pub cast_reduce_us_per_sample: f64,
    /// Expand: per (sample, light) of the span.
    pub expand_us_per_query: f64,
    /// TraceMap: per shadow ray (sample and light) of the span, against one split.
    pub trace_us_per_query: f64,
    /// TraceReduce: per (sample, light) of the span.
    pub trace_reduce_us_per_query: f64,
    /// Combine: per pixel (PNG, PFM and hit buffer encoding, upload).
    pub combine_us_per_pixel: f64,
    /// Render (fused): per ray (camera sample or (sample, light) of the span) against the
    /// whole scene, without a shuffle (shading, hit buffer, the span's pixels encoded and
    /// uploaded): this plus [`Rates::render_us_per_ray_log2`] times log2 of the triangles.
    pub render_us_per_ray: f64,
    /// Render (fused): per ray, per doubling of the scene's triangles (BVH depth).
    pub render_us_per_ray_log2: f64,
    /// A function's first read of a split: fetch and decode, per triangle of the split (a warm
    /// function keeps it).
    pub split_load_us_per_triangle: f64,
    /// The client's upload of the parsed scene, per triangle.
    pub upload_us_per_triangle: f64,
}

/// The reference rates: `hort render` through the emulator (embedded S3 server, debug build of
/// everything but `hort-core`) on a 2-core x86-64 machine, refitted 2026-12-02 from the stage
/// times of the bundled Cornell box (512x512, 16 spp), teapot and bunny and a generated
/// 300,000-triangle scene (960x540, 1 spp), fused and staged with 2 splits (docs/ARCHITECTURE.md
/// section 13, `hort plan`). See the module documentation.
pub const RATES: Rates = Rates {
    job_overhead_ms: 200.0,
    task_overhead_ms: 10.0,
    stage_overhead_ms: 20.0,
    plan_overhead_ms: 20.0,
    plan_us_per_triangle: 2.5,
    cast_us_per_sample: 0.6,
    cast_reduce_us_per_sample: 1.2,
    expand_us_per_query: 1.0,
    trace_us_per_query: 0.1,
    trace_reduce_us_per_query: 0.3,
    combine_us_per_pixel: 1.5,
    render_us_per_ray: 0.057,
    render_us_per_ray_log2: 0.013,
    split_load_us_per_triangle: 0.4,
    upload_us_per_triangle: 2.0,
};

/// What a backend runs jobs on.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PredictionModel {
    /// Tasks running at once (function slots, or the Map states' concurrency).
    pub concurrency: u32,
    /// Lambda memory the cost assumes, MB.
    pub memory_mb: u32,
    /// Lambda architecture the cost assumes.
    pub arch: Arch,
    /// How much faster than [`RATES`] the functions run (1: the reference machine).
    pub speed: f64,
    /// The unit costs.
    pub rates: Rates,
}

impl PredictionModel {
    /// The reference rates at `concurrency`, 2048 MB arm64 (the `hort render` defaults).
    pub fn reference(concurrency: u32) -> Self {
        PredictionModel {
            concurrency: concurrency.max(1),
            memory_mb: 2048,
            arch: Arch::Arm64,
            speed: 1.0,
            rates: RATES,
        }
    }
}

/// One stage of a predicted job.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StagePrediction {
    /// The stage's name (`plan`, `cast-map`, ...).
    pub stage: String,
    /// Its tasks.
    pub tasks: u64,
    /// Predicted seconds of one task.
    pub task_seconds: f64,
    /// Predicted seconds of the stage.
    pub seconds: f64,
}

/// A job's plan and its predicted time and cost.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Prediction {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Triangles in the scene.
    pub triangles: u64,
    /// Lights in the scene.
    pub lights: u64,
    /// `spatial` or `naive`.
    pub split_mode: hort_core::pipeline::SplitMode,
    /// Scene splits k.
    pub splits: u32,
    /// Pixel spans s.
    pub spans: u32,
    /// Every stage in order, with its tasks.
    pub stages: Vec<StagePrediction>,
    /// Tasks over all stages.
    pub tasks_total: u64,
    /// Tasks at once the prediction assumes.
    pub concurrency: u32,
    /// Predicted wall-clock seconds from the job's start to its outputs read back.
    pub predicted_seconds: f64,
    /// Predicted cost, USD (`hort_core::cost`).
    pub predicted_cost_usd: f64,
    /// The predicted cost per service line.
    pub cost: CostBreakdown,
}

/// Estimated stored bytes of a split object per triangle (triangles, shading, BVH).
const SPLIT_BYTES_PER_TRIANGLE: u64 = 60;
/// Estimated stored bytes of one shuffle record (compressed).
const RECORD_BYTES: f64 = 8.0;

/// The plan `hort render` would make for `scene` with `request`, shape and span count `s`
/// already resolved: split triangle counts and bounds as the Plan function computes them, no
/// BVH built.
pub fn preview_plan(
    scene: &Scene,
    request: &PlanRequest,
    shape: &JobShape,
    s: u32,
) -> Result<JobPlan, ApiError> {
    let groups = assign_splits(&scene.mesh, shape.splits as usize, request.mode);
    let infos = groups
        .iter()
        .enumerate()
        .map(|(id, ids)| {
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            for &t in ids {
                for corner in scene.mesh.corners(t as usize) {
                    let c = corner.to_array();
                    for axis in 0..3 {
                        lo[axis] = lo[axis].min(c[axis]);
                        hi[axis] = hi[axis].max(c[axis]);
                    }
                }
            }
            SplitInfo {
                id: id as u32,
                triangles: ids.len() as u64,
                lo,
                hi,
                bytes: ids.len() as u64 * SPLIT_BYTES_PER_TRIANGLE,
            }
        })
        .collect();
    plan_job(scene, request, infos, shape, s).map_err(|e| ApiError::invalid_scene(e.to_string()))
}

/// The predicted stages, time and cost of `plan` under `model` (see the module documentation).
pub fn predict(plan: &JobPlan, model: &PredictionModel) -> Prediction {
    let r = &model.rates;
    let speed = if model.speed > 0.0 { model.speed } else { 1.0 };
    let concurrency = u64::from(model.concurrency.max(1));
    let s = plan.spans.len() as u64;
    let k = u64::from(plan.k());
    let pixels = u64::from(plan.width) * u64::from(plan.height);
    let lights = plan.lights.len() as u64;
    let task_ms = |stage: Stage| task_milliseconds(plan, stage, r, speed);
    let mut stages = Vec::new();
    let mut seconds =
        r.job_overhead_ms / 1000.0 + plan.triangles as f64 * r.upload_us_per_triangle / 1e6 / speed;
    let mut cost = CostBreakdown::default();
    let mut children = 0u64;
    for &stage in plan.stages() {
        let tasks = plan.task_count(stage) as u64;
        let one_ms = task_ms(stage);
        let waves = tasks.div_ceil(concurrency).max(1) as f64;
        let stage_seconds =
            (r.stage_overhead_ms + waves * one_ms + split_load_ms(plan, stage, r, speed)) / 1000.0;
        seconds += stage_seconds;
        let is_map = stage.items_field().is_some();
        if is_map {
            children += tasks;
        }
        // Every task of a stage takes the same time: price one, times the tasks.
        let one = estimate(&CostInputs {
            arch: model.arch,
            memory_mb: model.memory_mb,
            invocation_ms: vec![one_ms],
            express_ms: if is_map { vec![one_ms] } else { Vec::new() },
            ..CostInputs::default()
        });
        add(&mut cost, &one, tasks as f64);
        stages.push(StagePrediction {
            stage: stage.as_str().to_owned(),
            tasks,
            task_seconds: one_ms / 1000.0,
            seconds: stage_seconds,
        });
    }
    let (gets, puts) = s3_requests(plan, s, k);
    let samples = pixels as f64 * f64::from(plan.spp);
    let bytes_written = plan.scene_bytes() as f64
        + samples * (3.0 + 2.0 * lights as f64) * RECORD_BYTES
        + pixels as f64 * 24.0;
    let rest = estimate(&CostInputs {
        arch: model.arch,
        memory_mb: model.memory_mb,
        s3_put_like: puts,
        s3_get_like: gets,
        s3_byte_seconds: bytes_written * seconds,
        standard_transitions: standard_transitions_for(5, 2, children, 0),
        ..CostInputs::default()
    });
    add(&mut cost, &rest, 1.0);
    Prediction {
        width: plan.width,
        height: plan.height,
        spp: plan.spp,
        triangles: plan.triangles,
        lights,
        split_mode: plan.split_mode,
        splits: plan.k(),
        spans: s as u32,
        tasks_total: stages.iter().map(|st| st.tasks).sum(),
        stages,
        concurrency: concurrency as u32,
        predicted_seconds: seconds,
        predicted_cost_usd: cost.total,
        cost,
    }
}

/// Predicted milliseconds of one task of `stage` in `plan`: the stage's fixed overhead plus its
/// work (the largest span's camera samples and shadow queries, or the plan's triangles, or the
/// image's pixels) at `rates`, the work divided by `speed` (1: the reference machine).
pub fn task_milliseconds(plan: &JobPlan, stage: Stage, r: &Rates, speed: f64) -> f64 {
    let speed = if speed > 0.0 { speed } else { 1.0 };
    let s = plan.spans.len() as u64;
    let pixels = u64::from(plan.width) * u64::from(plan.height);
    // The largest span's samples: spans differ by at most one pixel.
    let span_samples = pixels.div_ceil(s.max(1)) as f64 * f64::from(plan.spp);
    let queries = span_samples * plan.lights.len() as f64;
    let ms = |fixed: f64, units: f64, us: f64| fixed + units * us / 1000.0 / speed;
    match stage {
        // A scene split by tasks: the plan's per-triangle rate stands for the scan, partition
        // and build tasks together (not modelled one by one).
        Stage::Plan | Stage::Partition | Stage::Build => ms(
            r.plan_overhead_ms,
            plan.triangles as f64,
            r.plan_us_per_triangle,
        ),
        Stage::Render => ms(
            r.task_overhead_ms,
            1.0,
            (span_samples + queries)
                * (r.render_us_per_ray
                    + r.render_us_per_ray_log2 * (plan.triangles.max(2) as f64).log2()),
        ),
        Stage::CastMap => ms(r.task_overhead_ms, span_samples, r.cast_us_per_sample),
        Stage::CastReduce => ms(
            r.task_overhead_ms,
            span_samples,
            r.cast_reduce_us_per_sample,
        ),
        Stage::Expand => ms(r.task_overhead_ms, queries, r.expand_us_per_query),
        Stage::TraceMap => ms(r.task_overhead_ms, queries, r.trace_us_per_query),
        Stage::TraceReduce => ms(
            r.task_overhead_ms,
            span_samples + queries,
            r.trace_reduce_us_per_query,
        ),
        Stage::Combine => ms(r.task_overhead_ms, pixels as f64, r.combine_us_per_pixel),
    }
}

/// Milliseconds a function spends on its first read of the largest split `stage` reads (0 for
/// the stages that read none): once per stage, in parallel over the functions.
pub fn split_load_ms(plan: &JobPlan, stage: Stage, r: &Rates, speed: f64) -> f64 {
    let speed = if speed > 0.0 { speed } else { 1.0 };
    match stage {
        Stage::Render | Stage::CastMap | Stage::TraceMap => {
            let largest = plan.splits.iter().map(|s| s.triangles).max().unwrap_or(0);
            largest as f64 * r.split_load_us_per_triangle / 1000.0 / speed
        }
        _ => 0.0,
    }
}

/// S3 GET-like and PUT-like requests of a run without retries: the client's upload, the plan
/// step, each task's inputs and outputs (and its read of the plan), the item files.
fn s3_requests(plan: &JobPlan, s: u64, k: u64) -> (u64, u64) {
    debug_assert_eq!((s, k), (plan.spans.len() as u64, u64::from(plan.k())));
    // The client's upload: scene files and the job request.
    let (mut gets, mut puts) = (0, CLIENT_PUTS);
    for &stage in plan.mode.stages() {
        let (g, p) = stage_requests(plan, stage);
        gets += g;
        puts += p;
    }
    (gets, puts)
}

/// S3 PUT-like requests of the client before the job starts: scene files and the job request.
pub const CLIENT_PUTS: u64 = 5;

/// S3 GET-like and PUT-like requests of one stage of `plan` over all its tasks, by the dataflow
/// table of docs/ARCHITECTURE.md: each task's inputs, its read of the plan, the Map state's item
/// file, and its outputs. [`predict`]'s totals are [`CLIENT_PUTS`] plus the sum over the stages
/// of the plan's execution mode.
pub fn stage_requests(plan: &JobPlan, stage: Stage) -> (u64, u64) {
    let s = plan.spans.len() as u64;
    let k = u64::from(plan.k());
    let cast = plan.cast_tasks.len() as u64;
    let trace = plan.trace_tasks.len() as u64;
    let fused = plan.mode == hort_core::pipeline::ExecutionMode::Fused;
    match stage {
        // Reads the manifest and the scene files (about three); writes the splits, the plan,
        // the item files and a listing.
        Stage::Plan => (4, k + 3 + if fused { 0 } else { 4 }),
        // Not in a plan's stages (a scene split by tasks); counted with the plan.
        Stage::Partition | Stage::Build => (0, 0),
        // Every split, the plan, the item file; one partition.
        Stage::Render => (s * k + s + 1, s),
        // Its split and the plan, the item file; one partition.
        Stage::CastMap => (2 * cast + 1, cast),
        // Every CastMap partition of its span, the plan, the item file; one partition.
        Stage::CastReduce => (cast + s + 1, s),
        // Its span's hits and the plan, the item file; one partition per split.
        Stage::Expand => (2 * s + 1, s * k),
        // Its queries, its split and the plan, the item file; one partition.
        Stage::TraceMap => (3 * trace + 1, trace),
        // Its hits, one partition per split, the plan, the item file; one partition.
        Stage::TraceReduce => (s * (1 + k) + s + 1, s),
        // Every span's pixels and the plan; PNG, PFM, hit buffer.
        Stage::Combine => (s + 1, 3),
    }
}

/// Estimated bytes `stage` of `plan` writes over all its tasks: the split objects (plan), a
/// record per camera sample (cast-map, cast-reduce, trace-reduce), a record per shadow query
/// (expand, trace-map), the pixels' sums and hits (render, fused), the PNG, PFM and hit buffer
/// (combine). The sum
/// over the stages of a staged plan is the byte count [`predict`] prices storage with.
pub fn stage_bytes(plan: &JobPlan, stage: Stage) -> u64 {
    let pixels = u64::from(plan.width) * u64::from(plan.height);
    let samples = pixels as f64 * f64::from(plan.spp);
    let queries = samples * plan.lights.len() as f64;
    let bytes = match stage {
        Stage::Plan => plan.scene_bytes() as f64,
        Stage::Partition | Stage::Build => 0.0,
        // Each pixel's radiance sums and hit (20 bytes before compression).
        Stage::Render => pixels as f64 * 20.0,
        Stage::CastMap | Stage::CastReduce | Stage::TraceReduce => samples * RECORD_BYTES,
        Stage::Expand | Stage::TraceMap => queries * RECORD_BYTES,
        Stage::Combine => pixels as f64 * 24.0,
    };
    bytes as u64
}

fn add(total: &mut CostBreakdown, part: &CostBreakdown, times: f64) {
    total.lambda_compute += part.lambda_compute * times;
    total.lambda_requests += part.lambda_requests * times;
    total.s3_requests += part.s3_requests * times;
    total.s3_storage += part.s3_storage * times;
    total.step_functions += part.step_functions * times;
    total.total += part.total * times;
}

/// Dollars for messages: four decimals from a cent up, else three significant digits.
pub fn usd(x: f64) -> String {
    if !x.is_finite() || x >= 0.01 || x == 0.0 {
        return format!("${x:.4}");
    }
    let decimals = (2 - x.abs().log10().floor() as i32).clamp(4, 15) as usize;
    format!("${x:.decimals$}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dollars_keep_three_significant_digits() {
        assert_eq!(usd(1.5), "$1.5000");
        assert_eq!(usd(0.0123456), "$0.0123");
        assert_eq!(usd(0.001234), "$0.00123");
        assert_eq!(usd(0.000001234), "$0.00000123");
        assert_eq!(usd(0.0), "$0.0000");
    }
}
