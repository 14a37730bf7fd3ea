//! What a job will be before it runs: its plan (splits, spans, tasks per stage) and a predicted
//! duration and cost, for `POST /renders?dry_run=true` and the `max_cost_usd` budget.
//!
//! # The plan
//! Exact: the split and span counts of `hort render` ([`crate::pipeline::resolve_counts`]),
//! the triangles of each split as the Plan function assigns them ([`assign_splits`]), and
//! [`plan_job`] over their bounding boxes, so the CastMap pairs that spatial mode leaves out
//! are left out here too. No BVH is built and nothing is stored.
//!
//! # The duration
//! Each task's time is a fixed overhead (an invocation, its storage round trips) plus its work
//! at a reference rate per unit ([`RATES`]: microseconds per camera sample, shadow ray, record
//! or pixel, measured on the local emulator of a 2-core x86-64 machine), divided by the
//! backend's [`PredictionModel::speed`]. Spans differ by at most one pixel, so the tasks of a
//! stage take the same time and a stage of T tasks on C slots takes ceil(T / C) task times,
//! plus one first read of its largest split (stages that read splits), a fixed orchestration
//! overhead per stage, and one per job (upload, start, outputs read back). Hit records and
//! shadow rays are made for hits only: a previewed plan estimates the fraction of camera
//! samples that hit ([`JobPlan::camera_hit_estimate`], a coarse rasterization); without it
//! every sample is assumed to hit, an upper bound. A scene split by tasks adds its scan,
//! Partition, cut, Build and plan-from-parts steps ([`job_steps`]). A fused Render task pays
//! per pixel, per hit and per shadow ray, and each of these rays costs more with the scene's size: a little by log2
//! of its triangles (the depth of its BVH), much more by log2(1 + triangles / hitting camera
//! samples of the frame), the part of the BVH each ray meets cold because few other rays
//! share it (a ray of a generated 300,000-triangle scene costs twice as much at 320x180 as at
//! 1920x1080).
//!
//! `hort plan` projects the same per-task model onto N functions on Lambda or the emulator
//! ([`projection`]). The HTTP API (`hort_functions::api`) answers dry runs and checks budgets
//! with it; it lives here, under the crates that use it, with nothing of HTTP or AWS.
//!
//! # The cost
//! The price model of `crate::cost` applied to the predicted invocations: one Lambda
//! invocation per task (no retries) at the predicted duration, one EXPRESS child per Map item,
//! the Standard transitions of a run without retries, and the S3 requests each task makes by
//! the dataflow table of docs/ARCHITECTURE.md (its inputs read, its outputs written, the plan
//! read once per task, the Map states' item files).

mod projection;
mod timeouts;

pub use projection::{
    LAMBDA_FACTS, LambdaFacts, Projection, ProjectionSettings, SWEEP, StageProjection, Target,
    best_of, project,
};
use timeouts::Bound;
pub use timeouts::{
    COMBINE_TIMEOUT_SECONDS, MAX_PARTS_TIMEOUT_SECONDS, MAX_TIMEOUT_SECONDS,
    MIN_PARTS_TIMEOUT_SECONDS, MIN_TIMEOUT_SECONDS, TIMEOUT_MULTIPLE, TIMEOUT_SLOWDOWN,
    build_timeout_seconds, check_combine_time, partition_timeout_seconds, task_timeout_seconds,
};

use crate::cost::{
    Arch, CostBreakdown, CostInputs, clean_path_states, estimate, standard_transitions_for,
};
use crate::coverage::camera_hit_fraction;
use crate::pipeline::{
    JobPlan, JobShape, PipelineError, PlanRequest, SplitInfo, assign_splits, plan_job,
};
use crate::scene::{NO_NORMAL, Scene};
use crate::stage::Stage;
use crate::store::PARALLEL_REQUESTS;
use serde::{Deserialize, Serialize};

/// Reference costs of the work units, microseconds each, at `speed` 1.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
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
    /// Plan: per triangle (split assignment, BVH build, encoding, upload), plus
    /// [`Rates::plan_us_per_triangle_per_million`].
    pub plan_us_per_triangle: f64,
    /// Plan: per triangle, per million triangles of the scene: the build and encoding slow
    /// down as their arrays outgrow the caches (0.50 us a triangle at 100,000 triangles, 0.78
    /// at 2,000,000, on the reference machine).
    pub plan_us_per_triangle_per_million: f64,
    /// CastMap: per camera sample of the span, against one split.
    pub cast_us_per_sample: f64,
    /// CastReduce: per camera sample of the span that hits (a hit record).
    pub cast_reduce_us_per_sample: f64,
    /// Expand: per (hit, traced light) of the span.
    pub expand_us_per_query: f64,
    /// TraceMap: per shadow ray (hit and traced light) of the span, against one split.
    pub trace_us_per_query: f64,
    /// TraceReduce: per camera sample and per (hit, traced light) of the span.
    pub trace_reduce_us_per_query: f64,
    /// Combine: per pixel (reading the spans' pixels, encoding the outputs; the emulator's
    /// projection adds its storage's time per stored byte).
    pub combine_us_per_pixel: f64,
    /// Render (fused): per pixel of the span (its camera rays' setup, its mean and its place in
    /// the stored block), whether its samples hit or miss.
    pub render_us_per_pixel: f64,
    /// Render (fused): per camera sample that hits (its shading), against the whole scene,
    /// without a shuffle. A sample that misses costs about nothing beyond its pixel's share.
    pub render_us_per_hit: f64,
    /// Render (fused): per shadow ray ((hit, traced light) of the span).
    pub render_us_per_query: f64,
    /// Render (fused): per ray that enters the BVH (a hit or a shadow ray; a miss leaves at
    /// the root box), per doubling of the scene's triangles (the BVH's depth).
    pub render_us_per_ray_log2: f64,
    /// Render (fused): per ray that enters the BVH, per unit of log2(1 + triangles / camera
    /// samples that hit in the frame): the BVH nodes and triangles a ray visits that its
    /// neighbours have not brought into the cache, which dominates large scenes at low
    /// resolutions. Counted for hits only, the term grows with the hit fraction, so the
    /// timeouts' every-sample-hits bound stays an upper bound.
    pub render_us_per_ray_cold: f64,
    /// A function's first read of a split: fetch and decode, per triangle of the split (a warm
    /// function keeps it).
    pub split_load_us_per_triangle: f64,
    /// The client's upload of the parsed scene, per triangle.
    pub upload_us_per_triangle: f64,
    /// A scene split by tasks: the client's upload of its files, per byte.
    pub file_upload_us_per_byte: f64,
    /// A scene split by tasks: the Plan function's scan, per byte of the scene's files (read,
    /// checked, vertex pages written).
    pub scan_us_per_byte: f64,
    /// Partition: per byte of its range (parse, look-ups, records sorted, encoded, written).
    pub partition_us_per_byte: f64,
    /// Cut and plan-from-parts (the Plan function): per object they read (a range's index, a
    /// split's summary).
    pub parts_us_per_object: f64,
    /// Build: per triangle of its split (records read, BVH built, split object encoded and
    /// written).
    pub build_us_per_triangle: f64,
}

/// The reference rates: `hort render` through the emulator (embedded S3 server) built with
/// `cargo build --release`, on a 2-core x86-64 machine; fitted from the stage times of
/// `hort bench plan --stages` on the bundled teapot, Cornell box and globe and a generated
/// 300,000-triangle scene at 320x180, 960x540 and 1920x1080, fused and staged over 2 splits;
/// the fused Render rates (refitted 2026-12-06, when a fused task came to render its pixels
/// as the monolithic renderer does) from its tasks' times on the bundled teapot, Cornell box,
/// bunny and globe, copies of the bunny and the Cornell box with 3 lights and generated scenes
/// of 300,000 and 1,000,000 triangles at 320x180 and 960x540, 1 to 64 spp
/// (`docs/perf/plan-validation.md` has the tables and the commands). See the module
/// documentation.
pub const RATES: Rates = Rates {
    job_overhead_ms: 15.0,
    task_overhead_ms: 4.0,
    stage_overhead_ms: 3.0,
    plan_overhead_ms: 2.0,
    plan_us_per_triangle: 0.49,
    plan_us_per_triangle_per_million: 0.136,
    cast_us_per_sample: 0.2,
    cast_reduce_us_per_sample: 0.45,
    expand_us_per_query: 0.28,
    trace_us_per_query: 0.045,
    trace_reduce_us_per_query: 0.07,
    combine_us_per_pixel: 0.03,
    render_us_per_pixel: 0.099,
    render_us_per_hit: 0.017,
    render_us_per_query: 0.038,
    render_us_per_ray_log2: 0.0003,
    render_us_per_ray_cold: 0.121,
    split_load_us_per_triangle: 0.11,
    upload_us_per_triangle: 0.2,
    file_upload_us_per_byte: 0.004,
    scan_us_per_byte: 0.0075,
    partition_us_per_byte: 0.024,
    parts_us_per_object: 200.0,
    build_us_per_triangle: 0.8,
};

/// What a backend runs jobs on.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
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
    pub split_mode: crate::pipeline::SplitMode,
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
    /// Predicted cost, USD (`crate::cost`).
    pub predicted_cost_usd: f64,
    /// The predicted cost per service line.
    pub cost: CostBreakdown,
    /// A job of several frames: how many, and the time and cost per frame (the whole job's
    /// divided by them, the one-time preparation shared). Absent for one image.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub per_frame: Option<PerFrame>,
}

/// The prediction of a job of several frames, per frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PerFrame {
    /// Frames in the job.
    pub frames: u32,
    /// The job's predicted seconds per frame.
    pub seconds: f64,
    /// The job's predicted cost per frame, USD.
    pub cost_usd: f64,
}

/// One step of a job as the models count it: a stage of its plan, or a step of the Plan
/// function that splits a scene by tasks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JobStep {
    /// A stage. For a scene split by tasks, [`Stage::Plan`] is the scan, and
    /// [`Stage::Partition`] and [`Stage::Build`] are its Maps.
    Stage(Stage),
    /// The cut of a scene split by tasks into splits, after the Partition Map.
    Cut,
    /// The plan made from the built splits, after the Build Map.
    PlanFromParts,
}

impl JobStep {
    /// The step's name, as the report's stage rows name it.
    pub fn name(self) -> &'static str {
        match self {
            JobStep::Stage(stage) => stage.as_str(),
            JobStep::Cut => "cut",
            JobStep::PlanFromParts => "plan-from-parts",
        }
    }

    /// Whether a Map state runs the step's tasks (one child execution each).
    pub fn is_map(self) -> bool {
        matches!(self, JobStep::Stage(stage) if stage.items_field().is_some())
    }

    /// Whether the Plan function runs the step (one task, no Map).
    pub fn is_plan_function(self) -> bool {
        matches!(
            self,
            JobStep::Stage(Stage::Plan) | JobStep::Cut | JobStep::PlanFromParts
        )
    }
}

/// The steps of `plan`'s job in order: its stages, with a scene split by tasks partitioned,
/// cut, built and planned between the scan ([`Stage::Plan`]) and the first stage after it.
pub fn job_steps(plan: &JobPlan) -> Vec<JobStep> {
    let mut steps = vec![JobStep::Stage(Stage::Plan)];
    if plan.scene_parts.is_some() {
        steps.extend([
            JobStep::Stage(Stage::Partition),
            JobStep::Cut,
            JobStep::Stage(Stage::Build),
            JobStep::PlanFromParts,
        ]);
    }
    steps.extend(
        plan.task_stages()
            .iter()
            .map(|&stage| JobStep::Stage(stage)),
    );
    steps
}

/// Tasks of `step` in `plan`'s job: a Partition task per range, a Build task per split, one
/// for each Plan function step, and the plan's task count for the other stages.
pub fn step_tasks(plan: &JobPlan, step: JobStep) -> u64 {
    match (step, plan.scene_parts) {
        (JobStep::Stage(Stage::Partition), Some(parts)) => u64::from(parts.ranges),
        (JobStep::Stage(Stage::Build), Some(_)) => u64::from(plan.k()),
        (JobStep::Cut | JobStep::PlanFromParts, Some(_)) => 1,
        (JobStep::Stage(stage), _) => plan.job_task_count(stage) as u64,
        (JobStep::Cut | JobStep::PlanFromParts, None) => 0,
    }
}

/// The client's time to upload the scene before the job starts, ms: its files for a scene split
/// by tasks, else the parsed scene.
pub fn upload_ms(plan: &JobPlan, r: &Rates, speed: f64) -> f64 {
    let speed = if speed > 0.0 { speed } else { 1.0 };
    match plan.scene_parts {
        Some(parts) => parts.scene_bytes as f64 * r.file_upload_us_per_byte / 1e3 / speed,
        None => plan.triangles as f64 * r.upload_us_per_triangle / 1e3 / speed,
    }
}

/// Estimated stored bytes of a split object per triangle without vertex normals (split
/// format 5: measured 10.5 to 16.3 on the bundled scenes and 11.1 on a generated
/// million-triangle mesh; rounded up).
pub const SPLIT_BYTES_PER_TRIANGLE: u64 = 16;
/// Estimated stored bytes a triangle's vertex normals add to its split object (36 raw bytes,
/// compressed).
pub const SPLIT_NORMAL_BYTES_PER_TRIANGLE: u64 = 24;
/// Estimated stored bytes of one shuffle record (compressed).
const RECORD_BYTES: f64 = 8.0;

/// The plan `hort render` would make for `scene` with `request`, shape and span count `s`
/// already resolved: split triangle counts and bounds as the Plan function computes them, no
/// BVH built, and the fraction of camera samples estimated to hit
/// ([`JobPlan::camera_hit_estimate`]).
pub fn preview_plan(
    scene: &Scene,
    request: &PlanRequest,
    shape: &JobShape,
    s: u32,
) -> Result<JobPlan, PipelineError> {
    let groups = assign_splits(&scene.mesh, shape.splits as usize, request.mode);
    let infos = groups
        .iter()
        .enumerate()
        .map(|(id, ids)| {
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            let mut with_normals = 0u64;
            for &t in ids {
                with_normals += u64::from(scene.mesh.triangle_normals[t as usize][0] != NO_NORMAL);
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
                bytes: ids.len() as u64 * SPLIT_BYTES_PER_TRIANGLE
                    + with_normals * SPLIT_NORMAL_BYTES_PER_TRIANGLE,
            }
        })
        .collect();
    let mut plan = plan_job(scene, request, infos, shape, s)?;
    let camera = plan.ray_camera()?;
    plan.camera_hit_estimate = Some(camera_hit_fraction(
        &scene.mesh,
        &camera,
        plan.width,
        plan.height,
    ));
    Ok(plan)
}

/// The predicted stages, time and cost of `plan` under `model` (see the module documentation).
pub fn predict(plan: &JobPlan, model: &PredictionModel) -> Prediction {
    let r = &model.rates;
    let speed = if model.speed > 0.0 { model.speed } else { 1.0 };
    let concurrency = u64::from(model.concurrency.max(1));
    let s = plan.spans.len() as u64;
    let k = u64::from(plan.k());
    let lights = plan.lights.len() as u64;
    let task_ms = |step: JobStep| task_milliseconds(plan, step, r, speed);
    let mut stages = Vec::new();
    let mut seconds = (r.job_overhead_ms + upload_ms(plan, r, speed)) / 1000.0;
    let mut cost = CostBreakdown::default();
    let mut children = 0u64;
    for step in job_steps(plan) {
        let tasks = step_tasks(plan, step);
        let one_ms = task_ms(step);
        let waves = tasks.div_ceil(concurrency).max(1) as f64;
        let stage_seconds =
            (r.stage_overhead_ms + waves * one_ms + split_load_ms(plan, step, r, speed)) / 1000.0;
        seconds += stage_seconds;
        let is_map = step.is_map();
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
            stage: step.name().to_owned(),
            tasks,
            task_seconds: one_ms / 1000.0,
            seconds: stage_seconds,
        });
    }
    let (gets, puts) = s3_requests(plan, s, k);
    // What the job stores, priced for its whole duration: the bytes of every step.
    let bytes_written: f64 = job_steps(plan)
        .into_iter()
        .map(|step| stage_bytes(plan, step) as f64)
        .sum();
    let rest = estimate(&CostInputs {
        arch: model.arch,
        memory_mb: model.memory_mb,
        s3_put_like: puts,
        s3_get_like: gets,
        s3_byte_seconds: bytes_written * seconds,
        standard_transitions: standard_transitions(plan, children),
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
        per_frame: (!plan.frames.is_empty()).then(|| {
            let frames = plan.frames.len() as u32;
            PerFrame {
                frames,
                seconds: seconds / f64::from(frames),
                cost_usd: cost.total / f64::from(frames),
            }
        }),
        cost,
    }
}

/// Predicted milliseconds of one task of `step` in `plan`: the step's fixed overhead plus its
/// work (the largest span's camera samples and shadow queries, or the plan's triangles, or the
/// image's pixels; for a scene split by tasks, the scene's bytes, a range's bytes, a split's
/// triangles or the objects the cut reads) at `rates`, the work divided by `speed` (1: the
/// reference machine).
pub fn task_milliseconds(plan: &JobPlan, step: JobStep, r: &Rates, speed: f64) -> f64 {
    task_ms(plan, step, r, speed, Bound::Expected)
}

/// [`task_milliseconds`] under the assumptions of `bound`.
fn task_ms(plan: &JobPlan, step: JobStep, r: &Rates, speed: f64, bound: Bound) -> f64 {
    let speed = if speed > 0.0 { speed } else { 1.0 };
    let s = plan.spans.len() as u64;
    let pixels = u64::from(plan.width) * u64::from(plan.height);
    let (spp, hit_fraction) = match bound {
        Bound::Expected => (plan.spp, hit_fraction(plan)),
        Bound::Upper => (plan.max_spp(), 1.0),
    };
    // The largest span's samples: spans differ by at most one pixel.
    let span_samples = pixels.div_ceil(s.max(1)) as f64 * f64::from(spp);
    let hits = span_samples * hit_fraction;
    let queries = hits * traced_lights(plan);
    let ms = |fixed: f64, units: f64, us: f64| fixed + units * us / 1000.0 / speed;
    let largest_split = plan.splits.iter().map(|s| s.triangles).max().unwrap_or(0) as f64;
    let stage = match (step, plan.scene_parts) {
        (JobStep::Stage(stage), _) => stage,
        (JobStep::Cut, parts) => {
            let ranges = parts.map_or(0, |p| p.ranges);
            return ms(r.plan_overhead_ms, f64::from(ranges), r.parts_us_per_object);
        }
        (JobStep::PlanFromParts, _) => {
            return ms(
                r.plan_overhead_ms,
                f64::from(plan.k()),
                r.parts_us_per_object,
            );
        }
    };
    let work = match (stage, plan.scene_parts) {
        (Stage::Plan, Some(parts)) => ms(
            r.plan_overhead_ms,
            parts.scene_bytes as f64,
            r.scan_us_per_byte,
        ),
        (Stage::Plan, None) => {
            let triangles = plan.triangles as f64;
            ms(
                r.plan_overhead_ms,
                triangles,
                r.plan_us_per_triangle + r.plan_us_per_triangle_per_million * triangles / 1e6,
            )
        }
        // The ranges are of one size but the last of each file.
        (Stage::Partition, parts) => {
            let range = parts.map_or(0.0, |p| p.scene_bytes as f64 / f64::from(p.ranges.max(1)));
            ms(r.task_overhead_ms, range, r.partition_us_per_byte)
        }
        (Stage::Build, _) => ms(r.task_overhead_ms, largest_split, r.build_us_per_triangle),
        (Stage::Render, _) => {
            let frame_hits = pixels as f64 * f64::from(spp) * hit_fraction;
            let per_ray = render_us_per_ray(r, plan.triangles, frame_hits);
            // Rays that enter the BVH: hits and shadow rays (a miss leaves at the root box).
            ms(
                r.task_overhead_ms,
                1.0,
                span_samples / f64::from(spp.max(1)) * r.render_us_per_pixel
                    + hits * r.render_us_per_hit
                    + queries * r.render_us_per_query
                    + (hits + queries) * per_ray,
            )
        }
        (Stage::CastMap, _) => ms(r.task_overhead_ms, span_samples, r.cast_us_per_sample),
        (Stage::CastReduce, _) => ms(r.task_overhead_ms, hits, r.cast_reduce_us_per_sample),
        (Stage::Expand, _) => ms(r.task_overhead_ms, queries, r.expand_us_per_query),
        (Stage::TraceMap, _) => ms(r.task_overhead_ms, queries, r.trace_us_per_query),
        (Stage::TraceReduce, _) => ms(
            r.task_overhead_ms,
            span_samples + queries,
            r.trace_reduce_us_per_query,
        ),
        // A job of several frames: the frames are assembled by the tasks that finish them
        // (below); the Combine task assembles what is left, about one frame.
        (Stage::Combine, _) => ms(r.task_overhead_ms, pixels as f64, r.combine_us_per_pixel),
    };
    // In a job of several frames the last of a frame's pixel-stage tasks assembles the frame:
    // one task in s does, each on average a share of it (a timeout allows a whole frame).
    if plan.frames.is_empty() || stage != plan.mode.pixel_stage() {
        return work;
    }
    let assembled = match bound {
        Bound::Expected => pixels as f64 / s.max(1) as f64,
        Bound::Upper => pixels as f64,
    };
    work + ms(0.0, assembled, r.combine_us_per_pixel)
}

/// Microseconds a fused Render task spends per ray that enters the BVH of a scene of
/// `triangles` triangles, when `frame_hits` camera samples of the frame hit: the BVH's depth,
/// and the part of it a ray meets cold.
fn render_us_per_ray(r: &Rates, triangles: u64, frame_hits: f64) -> f64 {
    let triangles = triangles.max(2) as f64;
    r.render_us_per_ray_log2 * libm::log2(triangles)
        + r.render_us_per_ray_cold * libm::log2(1.0 + triangles / frame_hits.max(1.0))
}

/// The fused Render work of one frame of `pixels` pixels at `spp` samples on a scene of
/// `triangles` triangles, at the reference rates ([`RATES`], speed 1), without the tasks'
/// fixed costs (ms), with every sample hitting and one traced light: what a plan can estimate
/// before it knows the scene's lights and coverage. The plan sizes fused spans by it
/// (`pipeline::resolve_counts`).
pub fn fused_frame_work_ms(pixels: u64, spp: u32, triangles: u64) -> f64 {
    let r = &RATES;
    let samples = pixels as f64 * f64::from(spp);
    let per_ray = render_us_per_ray(r, triangles, samples);
    let per_sample = r.render_us_per_hit + r.render_us_per_query + 2.0 * per_ray;
    (pixels as f64 * r.render_us_per_pixel + samples * per_sample) / 1000.0
}

/// Milliseconds a function spends on its first read of the largest split `step` reads (0 for
/// the steps that read none): once per stage, in parallel over the functions.
pub fn split_load_ms(plan: &JobPlan, step: JobStep, r: &Rates, speed: f64) -> f64 {
    let speed = if speed > 0.0 { speed } else { 1.0 };
    match step {
        JobStep::Stage(Stage::Render | Stage::CastMap | Stage::TraceMap) => {
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
    for step in job_steps(plan) {
        let (g, p) = stage_requests(plan, step);
        gets += g;
        puts += p;
    }
    (gets, puts)
}

/// Step Functions Standard transitions of `plan`'s job without retries or lost items, its Map
/// states' `children` child executions among them: the states of its path through
/// `infra/statemachine.asl.json` ([`clean_path_states`]).
pub fn standard_transitions(plan: &JobPlan, children: u64) -> u64 {
    let map_stages = plan
        .task_stages()
        .iter()
        .filter(|s| s.items_field().is_some())
        .count() as u64;
    let staged = plan.mode == crate::pipeline::ExecutionMode::Staged;
    let states = clean_path_states(map_stages, staged, plan.scene_parts.is_some());
    standard_transitions_for(states, children, 0)
}

/// S3 PUT-like requests of the client before the job starts: scene files and the job request.
pub const CLIENT_PUTS: u64 = 5;

/// S3 GET-like and PUT-like requests of one step of `plan` over all its tasks, by the
/// dataflow table of docs/ARCHITECTURE.md: each task's inputs, its read of the plan, the Map
/// state's item file, and its outputs. [`predict`]'s totals are [`CLIENT_PUTS`] plus the sum
/// over the job's steps ([`job_steps`]).
pub fn stage_requests(plan: &JobPlan, step: JobStep) -> (u64, u64) {
    let (gets, puts) = frame_stage_requests(plan, step);
    let frames = per_frame_multiple(step, plan);
    let (gets, puts) = (gets * frames, puts * frames);
    if plan.frames.is_empty() {
        return (gets, puts);
    }
    // A job of several frames: each pixel-stage task lists its frame's blocks, the one that
    // finishes a frame assembles it (Combine's reads and writes, once per frame), and Combine
    // lists the frames and copies the poster.
    let n = plan.frames.len() as u64;
    let (combine_gets, combine_puts) = frame_stage_requests(plan, JobStep::Stage(Stage::Combine));
    match step {
        JobStep::Stage(stage) if stage == plan.mode.pixel_stage() => (
            gets + step_tasks(plan, step) + n * combine_gets,
            puts + n * combine_puts,
        ),
        JobStep::Stage(Stage::Combine) => (n.div_ceil(1000) + 1, 1),
        _ => (gets, puts),
    }
}

/// How many times a job's frames repeat `step`: every frame's tasks for the stages after the
/// plan (their requests and bytes; the first frame's stand for all), once for the rest.
fn per_frame_multiple(step: JobStep, plan: &JobPlan) -> u64 {
    match step {
        JobStep::Stage(Stage::Plan | Stage::Partition | Stage::Build | Stage::Combine)
        | JobStep::Cut
        | JobStep::PlanFromParts => 1,
        JobStep::Stage(_) => plan.frame_numbers().len() as u64,
    }
}

/// [`stage_requests`] of one frame.
fn frame_stage_requests(plan: &JobPlan, step: JobStep) -> (u64, u64) {
    let s = plan.spans.len() as u64;
    let k = u64::from(plan.k());
    let cast = plan.cast_tasks.len() as u64;
    let trace = plan.trace_tasks.len() as u64;
    let fused = plan.mode == crate::pipeline::ExecutionMode::Fused;
    let ranges = plan.scene_parts.map_or(0, |p| u64::from(p.ranges));
    let stage = match step {
        // Every range's index and the table; the cut and the Build items.
        JobStep::Cut => return (ranges + 1, 2),
        // The table, the cut, every split's summary, the request and manifest; the plan and the
        // item files of the stages after it.
        JobStep::PlanFromParts => return (k + 4, 1 + if fused { 1 } else { 5 }),
        JobStep::Stage(stage) => stage,
    };
    match stage {
        // A scene split by tasks: the request and the scene's files (about three); a vertex
        // page per range, the table, the Partition items.
        Stage::Plan if plan.scene_parts.is_some() => (4, ranges + 2),
        // Reads the manifest and the scene files (about three); writes the splits, the plan,
        // the item files and a listing.
        Stage::Plan => (4, k + 3 + if fused { 0 } else { 4 }),
        // Its range's bytes, the table, the vertex pages of the ranges before it that its faces
        // use (about one), the item file; its records and their index.
        Stage::Partition => (3 * ranges + 1, 2 * ranges),
        // Per range, its index and its run of records, the cut, the table, the item file; the
        // split object and its summary.
        Stage::Build => (k * (2 * ranges + 2) + 1, 2 * k),
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

/// Requests one task of `step` waits for one after another, on average: its share of
/// [`stage_requests`], except that the several inputs a task reads (cast-reduce, trace-reduce,
/// combine) and the several partitions it writes (expand) count once per wave of
/// [`PARALLEL_REQUESTS`] it has in flight at once (docs/ARCHITECTURE.md, section 3).
pub fn task_waits(plan: &JobPlan, step: JobStep) -> f64 {
    let tasks = step_tasks(plan, step).max(1) as f64;
    let (gets, puts) = stage_requests(plan, step);
    let requests = (gets + puts) as f64 / tasks;
    let s = plan.spans.len().max(1) as f64;
    let k = f64::from(plan.k());
    let waves = |n: f64| (n / PARALLEL_REQUESTS as f64).ceil();
    // Per task: the requests made several at a time, and as how many waits they count.
    let several = match step {
        JobStep::Stage(Stage::CastReduce) => plan.cast_tasks.len() as f64 / s,
        JobStep::Stage(Stage::TraceReduce) if plan.has_shadows() => k,
        JobStep::Stage(Stage::Expand) => k,
        // A job of several frames: its frames were assembled by the tasks that finished them.
        JobStep::Stage(Stage::Combine) if plan.frames.is_empty() => s,
        _ => 0.0,
    };
    if several <= 1.0 {
        return requests;
    }
    requests - several + waves(several)
}

/// Estimated bytes `step` of `plan` writes over all its tasks: the split objects (plan, or
/// build for a scene split by tasks), a record per hit (cast-map, cast-reduce) or per camera
/// sample (trace-reduce), a record per shadow query (expand, trace-map), the pixels' sums and hits
/// (render, fused), the PNG, PFM and hit buffer (combine); for a scene split by tasks, the
/// vertex pages (the scan) and a record per triangle (partition), before compression. The sum
/// over the steps is the byte count [`predict`] prices storage with.
pub fn stage_bytes(plan: &JobPlan, step: JobStep) -> u64 {
    let pixels = u64::from(plan.width) * u64::from(plan.height);
    let samples = pixels as f64 * f64::from(plan.spp);
    let hits = samples * hit_fraction(plan);
    let queries = hits * traced_lights(plan);
    let JobStep::Stage(stage) = step else {
        return 0;
    };
    let bytes = match (stage, plan.scene_parts) {
        (Stage::Plan, Some(parts)) => (parts.vertices * 24 + parts.normals * 12) as f64,
        (Stage::Plan, None) | (Stage::Build, _) => plan.scene_bytes() as f64,
        (Stage::Partition, _) => (plan.triangles * PART_RECORD_BYTES) as f64,
        // Each pixel's radiance sums and hit (20 bytes before compression).
        (Stage::Render, _) => pixels as f64 * 20.0,
        (Stage::CastMap | Stage::CastReduce, _) => hits * RECORD_BYTES,
        (Stage::TraceReduce, _) => samples * RECORD_BYTES,
        (Stage::Expand | Stage::TraceMap, _) => queries * RECORD_BYTES,
        // The PNG (3 bytes and a filter byte per pixel before compression), and the linear
        // image and the hit buffer when the job stores them.
        (Stage::Combine, _) if plan.frames.is_empty() => {
            (pixels * 4 + extra_output_bytes(plan)) as f64
        }
        // A job of several frames: the poster (the frames are the pixel stage's, below).
        (Stage::Combine, _) => (pixels * 4) as f64,
    };
    let frames = plan.frames.len() as u64;
    let assembled = if frames > 0 && stage == plan.mode.pixel_stage() {
        frames * (pixels * 4 + extra_output_bytes(plan))
    } else {
        0
    };
    bytes as u64 * per_frame_multiple(step, plan) + assembled
}

/// Bytes of the outputs `plan`'s job stores besides its PNG: the linear image (12 bytes a pixel)
/// and the hit buffer (8), when it stores them.
fn extra_output_bytes(plan: &JobPlan) -> u64 {
    let pixels = u64::from(plan.width) * u64::from(plan.height);
    pixels * (12 * u64::from(plan.outputs.linear) + 8 * u64::from(plan.outputs.hits))
}

/// The fraction of camera samples the models count as hits: the plan's estimate, else all.
fn hit_fraction(plan: &JobPlan) -> f64 {
    plan.camera_hit_estimate.unwrap_or(1.0).clamp(0.0, 1.0)
}

/// Lights whose shadow rays are traced: those some surface can occlude.
fn traced_lights(plan: &JobPlan) -> f64 {
    plan.lights
        .len()
        .saturating_sub(plan.unoccludable_lights.len()) as f64
}

/// Bytes the tasks of `step` read besides the plan and the split objects (which the models
/// count as split loads): for a scene split by tasks, the scene's files (the scan), each
/// range (partition) and each split's records (build); none for the other steps, whose inputs
/// are the compressed shuffle blocks the step before wrote.
pub fn stage_bytes_read(plan: &JobPlan, step: JobStep) -> u64 {
    match (step, plan.scene_parts) {
        (JobStep::Stage(Stage::Plan | Stage::Partition), Some(parts)) => parts.scene_bytes,
        (JobStep::Stage(Stage::Build), Some(_)) => plan.triangles * PART_RECORD_BYTES,
        _ => 0,
    }
}

/// Bytes of one partition record of a scene split by tasks, before compression.
const PART_RECORD_BYTES: u64 = 128;

/// Adds `part`, `times` over, to `total`, field by field (the plan's and the projection's one
/// way of summing costs).
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
    use crate::pipeline::{ScenePartsShape, SplitMode};

    /// The bundled Cornell box previewed at 64x48, 2 spp, staged over 2 splits and 3 spans.
    fn cornell_plan() -> JobPlan {
        cornell_plan_of(2, 3, SplitMode::Spatial)
    }

    /// The bundled Cornell box previewed at 64x48, 2 spp, over `splits` splits cut by `mode`
    /// and `spans` spans.
    fn cornell_plan_of(splits: u32, spans: u32, mode: SplitMode) -> JobPlan {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/cornell.json");
        let scene = crate::scene::load_scene(&path).expect("the bundled Cornell box");
        let request = PlanRequest {
            width: 64,
            height: 48,
            spp: 2,
            splits: Some(splits),
            spans: Some(spans),
            mode,
            execution: None,
            memory_mb: 2048,
            adaptive: None,
            outputs: crate::pipeline::StoredOutputs::ALL,
            frame: Default::default(),
        };
        let (shape, s) = crate::pipeline::resolve_counts(&request, 36).unwrap();
        preview_plan(&scene, &request, &shape, s).unwrap()
    }

    /// A job of 6 frames counts 6 times each stage's tasks after the plan, their requests and
    /// bytes, and one plan and one Combine task; its frames are assembled by the tasks that
    /// finish them.
    #[test]
    fn a_job_of_frames_counts_every_frames_tasks_and_one_plan() {
        let one = cornell_plan_of(2, 4, SplitMode::Spatial);
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/cornell.json");
        let scene = crate::scene::load_scene(&path).expect("the bundled Cornell box");
        let orbit = crate::pipeline::Orbit {
            degrees: 360.0,
            frames: 6,
        };
        let request = PlanRequest {
            width: 64,
            height: 48,
            spp: 2,
            splits: Some(2),
            spans: Some(4),
            mode: SplitMode::Spatial,
            execution: None,
            memory_mb: 2048,
            adaptive: None,
            outputs: crate::pipeline::StoredOutputs::ALL,
            frame: crate::pipeline::FrameChoice::range(0..6, Some(orbit)),
        };
        let (shape, s) = crate::pipeline::resolve_counts(&request, 36).unwrap();
        let six = preview_plan(&scene, &request, &shape, s).unwrap();
        assert_eq!(six.frames.len(), 6);
        for stage in [Stage::CastReduce, Stage::Expand, Stage::TraceMap] {
            let step = JobStep::Stage(stage);
            assert_eq!(
                step_tasks(&six, step),
                6 * step_tasks(&one, step),
                "{stage}"
            );
            let (g1, p1) = stage_requests(&one, step);
            assert_eq!(stage_requests(&six, step), (6 * g1, 6 * p1), "{stage}");
            assert_eq!(
                stage_bytes(&six, step),
                6 * stage_bytes(&one, step),
                "{stage}"
            );
        }
        for stage in [Stage::Plan, Stage::Combine] {
            assert_eq!(step_tasks(&six, JobStep::Stage(stage)), 1, "{stage}");
        }
        let plan_step = JobStep::Stage(Stage::Plan);
        assert_eq!(
            stage_requests(&six, plan_step),
            stage_requests(&one, plan_step)
        );
        // The frames are assembled by the tasks that finish them: the last pixel stage's
        // tasks list their frame's blocks, and Combine only lists the frames and copies one.
        let last = JobStep::Stage(Stage::TraceReduce);
        let (g1, p1) = stage_requests(&one, last);
        let (cg, cp) = stage_requests(&one, JobStep::Stage(Stage::Combine));
        let tasks = step_tasks(&six, last);
        assert_eq!(
            stage_requests(&six, last),
            (6 * g1 + tasks + 6 * cg, 6 * p1 + 6 * cp)
        );
        assert_eq!(stage_requests(&six, JobStep::Stage(Stage::Combine)), (2, 1));
        let model = PredictionModel::reference(4);
        let whole = predict(&six, &model);
        let per_frame = whole
            .per_frame
            .expect("a job of frames is priced per frame");
        assert_eq!(per_frame.frames, 6);
        assert_eq!(per_frame.seconds, whole.predicted_seconds / 6.0);
        assert_eq!(per_frame.cost_usd, whole.predicted_cost_usd / 6.0);
        assert_eq!(predict(&one, &model).per_frame, None);
        let combine = JobStep::Stage(Stage::Combine);
        assert_eq!(
            stage_bytes(&six, last),
            6 * stage_bytes(&one, last) + 6 * stage_bytes(&one, combine)
        );
        assert_eq!(stage_bytes(&six, combine), 64 * 48 * 4);
    }

    #[test]
    fn several_inputs_or_outputs_of_a_task_are_waited_for_in_waves_of_eight() {
        let plan = cornell_plan_of(20, 10, SplitMode::Naive);
        assert!(plan.has_shadows());
        let per_task = |stage: Stage| {
            let (g, p) = stage_requests(&plan, JobStep::Stage(stage));
            (g + p) as f64 / step_tasks(&plan, JobStep::Stage(stage)) as f64
        };
        let waits = |stage: Stage| task_waits(&plan, JobStep::Stage(stage));
        // Naive splits: every span casts against all 20 splits. 20 inputs or outputs are
        // three waves of at most eight; the spans' 10 pixel blocks two.
        assert_eq!(
            waits(Stage::CastReduce),
            per_task(Stage::CastReduce) - 20.0 + 3.0
        );
        assert_eq!(
            waits(Stage::TraceReduce),
            per_task(Stage::TraceReduce) - 20.0 + 3.0
        );
        assert_eq!(waits(Stage::Expand), per_task(Stage::Expand) - 20.0 + 3.0);
        assert_eq!(waits(Stage::Combine), per_task(Stage::Combine) - 10.0 + 2.0);
        // One input each: every request is waited for.
        for stage in [Stage::Plan, Stage::CastMap, Stage::TraceMap] {
            assert_eq!(waits(stage), per_task(stage), "{stage}");
        }
    }

    #[test]
    fn hit_records_and_shadow_rays_scale_with_the_estimated_hits() {
        let mut plan = cornell_plan();
        let estimate = plan
            .camera_hit_estimate
            .expect("a previewed plan estimates hits");
        assert!(estimate > 0.5 && estimate <= 1.0, "{estimate}");
        let work = |plan: &JobPlan, stage: Stage| {
            let r = Rates {
                task_overhead_ms: 0.0,
                ..RATES
            };
            task_milliseconds(plan, JobStep::Stage(stage), &r, 1.0)
        };
        let stages = [
            Stage::CastMap,
            Stage::CastReduce,
            Stage::Expand,
            Stage::TraceMap,
        ];
        plan.camera_hit_estimate = Some(1.0);
        let all = stages.map(|stage| work(&plan, stage));
        plan.camera_hit_estimate = Some(0.25);
        let quarter = stages.map(|stage| work(&plan, stage));
        // Camera rays are cast whether they hit or not; records and shadow rays are per hit.
        assert_eq!(quarter[0], all[0]);
        for i in 1..4 {
            assert!((quarter[i] - all[i] / 4.0).abs() < 1e-12, "{i}");
        }
        // A job's own plan has no estimate: every sample counts as a hit.
        plan.camera_hit_estimate = None;
        assert_eq!(work(&plan, Stage::Expand), all[2]);
    }

    /// A fused Render ray of a large scene costs more where few camera rays share its BVH (a
    /// small image); a small scene's BVH is shared at any size.
    #[test]
    fn a_render_ray_costs_more_where_few_rays_share_the_bvh() {
        let mut plan = cornell_plan();
        plan.camera_hit_estimate = Some(1.0);
        let per_sample = |width: u32, height: u32, triangles: u64| {
            let mut plan = plan.clone();
            (plan.width, plan.height, plan.triangles) = (width, height, triangles);
            let r = Rates {
                task_overhead_ms: 0.0,
                ..RATES
            };
            let ms = task_milliseconds(&plan, JobStep::Stage(Stage::Render), &r, 1.0);
            ms / f64::from(width * height)
        };
        let (low, high) = (
            per_sample(320, 180, 1_000_000),
            per_sample(1920, 1080, 1_000_000),
        );
        assert!(low > 1.5 * high, "{low} vs {high}");
        let (low, high) = (per_sample(320, 180, 36), per_sample(1920, 1080, 36));
        assert!((low / high - 1.0).abs() < 0.01, "{low} vs {high}");
    }

    /// The timeouts' bound (every sample hits) is above the expected Render time whatever
    /// the estimated hit fraction, though a rarer hit meets more of a large BVH cold.
    #[test]
    fn every_sample_hitting_bounds_the_render_time_at_any_hit_fraction() {
        let mut plan = cornell_plan();
        plan.triangles = 20_000_000;
        let step = JobStep::Stage(Stage::Render);
        let upper = task_ms(&plan, step, &RATES, 1.0, Bound::Upper);
        for fraction in [1e-6, 1e-3, 0.01, 0.1, 0.5, 0.9, 1.0] {
            plan.camera_hit_estimate = Some(fraction);
            let expected = task_ms(&plan, step, &RATES, 1.0, Bound::Expected);
            assert!(expected <= upper, "{fraction}: {expected} > {upper}");
        }
    }

    #[test]
    fn a_scene_split_by_tasks_adds_its_partition_and_build_steps() {
        let mut plan = cornell_plan();
        let names = |plan: &JobPlan| job_steps(plan).iter().map(|s| s.name()).collect::<Vec<_>>();
        assert_eq!(
            names(&plan),
            [
                "plan",
                "cast-map",
                "cast-reduce",
                "expand",
                "trace-map",
                "trace-reduce",
                "combine"
            ]
        );
        plan.scene_parts = Some(ScenePartsShape {
            ranges: 5,
            scene_bytes: 50_000,
            vertices: 1_000,
            normals: 0,
        });
        let steps = job_steps(&plan);
        assert_eq!(
            steps.iter().map(|s| s.name()).collect::<Vec<_>>(),
            [
                "plan",
                "partition",
                "cut",
                "build",
                "plan-from-parts",
                "cast-map",
                "cast-reduce",
                "expand",
                "trace-map",
                "trace-reduce",
                "combine"
            ]
        );
        let tasks: Vec<u64> = steps.iter().map(|&s| step_tasks(&plan, s)).collect();
        assert_eq!(&tasks[..5], [1, 5, 1, 2, 1]);
        // The scan reads the scene's bytes, each partition task a fifth of them.
        let r = Rates {
            plan_overhead_ms: 0.0,
            task_overhead_ms: 0.0,
            ..RATES
        };
        let ms = |step| task_milliseconds(&plan, step, &r, 1.0);
        assert!(
            (ms(JobStep::Stage(Stage::Plan)) - 50_000.0 * r.scan_us_per_byte / 1e3).abs() < 1e-9
        );
        assert!(
            (ms(JobStep::Stage(Stage::Partition)) - 10_000.0 * r.partition_us_per_byte / 1e3).abs()
                < 1e-9
        );
        assert!(
            (ms(JobStep::Stage(Stage::Build)) - 18.0 * r.build_us_per_triangle / 1e3).abs() < 1e-9
        );
        assert_eq!(stage_bytes(&plan, JobStep::Stage(Stage::Plan)), 24_000);
        assert_eq!(
            stage_bytes(&plan, JobStep::Stage(Stage::Partition)),
            36 * 128
        );
        // Eight more top-level states than a scene loaded whole (22 for a staged job): two Map
        // stages of three states (Map, lost step, Check) and two Plan steps.
        assert_eq!(standard_transitions(&plan, 0), 30);
    }

    #[test]
    fn dollars_keep_three_significant_digits() {
        assert_eq!(usd(1.5), "$1.5000");
        assert_eq!(usd(0.0123456), "$0.0123");
        assert_eq!(usd(0.001234), "$0.00123");
        assert_eq!(usd(0.000001234), "$0.00000123");
        assert_eq!(usd(0.0), "$0.0000");
    }
}
