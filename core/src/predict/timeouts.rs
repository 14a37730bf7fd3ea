//! Per-task timeouts: a few times a task's time as the prediction model puts it, on a function
//! slower than the reference machine and with every bound taken at its worst.
//!
//! One model of task time serves the predictions (`hort plan`, dry runs, budgets), the
//! projection and the timeouts: [`task_milliseconds`](super::task_milliseconds) at
//! [`RATES`](super::RATES). A timeout takes that model's upper bound of the task's work (every
//! camera sample hits, the adaptive sampler's `max_spp` everywhere, the largest span and split),
//! adds a cold start, assumes a function [`TIMEOUT_SLOWDOWN`] times slower than the reference,
//! and allows [`TIMEOUT_MULTIPLE`] times that, rounded up to whole seconds and clamped.
//!
//! The timeouts are written into the Map states' item files, so they must be the same bytes on
//! every machine: the arithmetic is IEEE f64 without platform maths (`libm` for the logarithm).

use super::{JobStep, RATES, split_load_ms, task_ms};
use crate::pipeline::JobPlan;
use crate::stage::Stage;

/// Shortest per-task timeout of a stage task, seconds (`hort render --help` says it).
pub const MIN_TIMEOUT_SECONDS: u64 = 2;
/// Longest per-task timeout of a stage task, seconds: the five timed-out attempts the state
/// machine allows, with their backoff, must fit an EXPRESS child's 5 minutes.
pub const MAX_TIMEOUT_SECONDS: u64 = 40;
/// A task's timeout is this many times its predicted time.
pub const TIMEOUT_MULTIPLE: u64 = 3;
/// How many times slower than the reference machine of [`RATES`] a timeout assumes the
/// function may run: the smallest Lambda memory sizes get a fraction of a vCPU, and a loaded
/// emulator host shares its cores.
pub const TIMEOUT_SLOWDOWN: f64 = 4.0;
/// A cold function's start (runtime initialisation, first storage round trips), ms.
const COLD_START_MS: f64 = 500.0;
/// Shortest timeout of a Partition or Build task, seconds: they read ranges of the scene's
/// files or many runs of records, so their storage round trips alone can take tens of seconds.
pub const MIN_PARTS_TIMEOUT_SECONDS: u64 = 60;
/// Longest timeout of a Partition or Build task, seconds: Lambda's longest (the Worker's own
/// timeout bounds it further, `docs/AWS-LIMITS.md`).
pub const MAX_PARTS_TIMEOUT_SECONDS: u64 = 900;

/// The timeout of every task of `stage` in `plan`, seconds (see the module documentation). A
/// round-2 task gets that of the stage, which bounds the work of any of its tasks.
pub fn task_timeout_seconds(plan: &JobPlan, stage: Stage) -> u32 {
    let step = JobStep::Stage(stage);
    let speed = 1.0 / TIMEOUT_SLOWDOWN;
    let ms =
        task_ms(plan, step, &RATES, speed, Bound::Upper) + split_load_ms(plan, step, &RATES, speed);
    timeout_of(ms, MIN_TIMEOUT_SECONDS, MAX_TIMEOUT_SECONDS)
}

/// The Combine state's timeout in the state machine, seconds: Lambda's longest.
pub const COMBINE_TIMEOUT_SECONDS: u64 = 900;

/// Whether one Combine task can assemble `frames` images of `width` x `height` within
/// [`COMBINE_TIMEOUT_SECONDS`], as a timeout reckons (on a function [`TIMEOUT_SLOWDOWN`] times
/// slower than the reference, [`TIMEOUT_MULTIPLE`] times over): else the error, naming the
/// most frames that fit. Checked before a job of several frames starts.
pub fn check_combine_time(width: u32, height: u32, frames: u32) -> Result<(), String> {
    let r = &RATES;
    let frame_ms = f64::from(width) * f64::from(height) * r.combine_us_per_pixel / 1000.0;
    let budget_ms =
        COMBINE_TIMEOUT_SECONDS as f64 * 1000.0 / TIMEOUT_MULTIPLE as f64 / TIMEOUT_SLOWDOWN
            - COLD_START_MS
            - r.task_overhead_ms;
    let most = (budget_ms / frame_ms).floor().max(1.0) as u64;
    if u64::from(frames) <= most {
        return Ok(());
    }
    Err(format!(
        "{frames} frames of {width}x{height}: one Combine task assembles every frame within the \
         state machine's {COMBINE_TIMEOUT_SECONDS} s, which holds at most {most} frames of that \
         size; render them in runs of {most} (--frames A..B)"
    ))
}

/// The timeout of a Partition task over a byte range of `range_bytes`, seconds.
pub fn partition_timeout_seconds(range_bytes: u64) -> u32 {
    let r = &RATES;
    let ms = r.task_overhead_ms + range_bytes as f64 * r.partition_us_per_byte / 1000.0;
    parts_timeout_of(ms * TIMEOUT_SLOWDOWN)
}

/// The timeout of a Build task whose split holds `triangles`, seconds.
pub fn build_timeout_seconds(triangles: u64) -> u32 {
    let r = &RATES;
    let ms = r.task_overhead_ms + triangles as f64 * r.build_us_per_triangle / 1000.0;
    parts_timeout_of(ms * TIMEOUT_SLOWDOWN)
}

fn parts_timeout_of(ms: f64) -> u32 {
    timeout_of(ms, MIN_PARTS_TIMEOUT_SECONDS, MAX_PARTS_TIMEOUT_SECONDS)
}

/// [`TIMEOUT_MULTIPLE`] times a cold start and `ms`, in whole seconds rounded up, in
/// `min..=max`.
fn timeout_of(ms: f64, min: u64, max: u64) -> u32 {
    let seconds = (TIMEOUT_MULTIPLE as f64 * (COLD_START_MS + ms) / 1000.0).ceil();
    // `as` saturates: an absurd plan's infinite time is the longest timeout.
    (seconds as u64).clamp(min, max) as u32
}

/// Which of the model's assumptions a task time takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Bound {
    /// The expected work: the plan's estimate of the samples that hit, its `spp`.
    Expected,
    /// The most work any task of the step may do: every sample hits, `max_spp` everywhere.
    Upper,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::{
        DEFAULT_MEMORY_MB, PlanRequest, SplitMode, StoredOutputs, plan_job, resolve_counts,
        split_build_preset, split_scene,
    };

    /// The bundled Cornell box at 64x48, staged over 3 splits and 7 spans.
    fn cornell() -> JobPlan {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../scenes/cornell/cornell.json"
        );
        let scene = crate::scene::load_scene(std::path::Path::new(path)).unwrap();
        let request = PlanRequest {
            width: 64,
            height: 48,
            spp: 1,
            splits: Some(3),
            spans: Some(7),
            mode: SplitMode::Spatial,
            execution: None,
            memory_mb: DEFAULT_MEMORY_MB,
            adaptive: None,
            outputs: StoredOutputs::ALL,
            frame: Default::default(),
        };
        let preset = split_build_preset(&request, scene.mesh.triangle_count() as u64);
        let infos = split_scene(&scene.mesh, 3, SplitMode::Spatial, preset, |_, _| {
            Ok::<(), ()>(())
        })
        .unwrap();
        let (shape, _) = resolve_counts(&request, 100).unwrap();
        plan_job(&scene, &request, infos, &shape, 7).unwrap()
    }

    #[test]
    fn small_tasks_get_the_floor_and_more_work_a_longer_timeout_up_to_the_ceiling() {
        let plan = cornell();
        // 438 pixels a span, one light: a cold start and a few ms, three times over.
        for stage in [
            Stage::CastMap,
            Stage::CastReduce,
            Stage::TraceMap,
            Stage::Combine,
        ] {
            assert_eq!(task_timeout_seconds(&plan, stage), 2, "{stage:?}");
        }
        let mut dense = plan.clone();
        let mut last = 2;
        for spp in [1_000, 4_000, 16_000, 1_000_000] {
            dense.spp = spp;
            let t = task_timeout_seconds(&dense, Stage::CastMap);
            assert!(t >= last, "spp {spp}: {t} s after {last} s");
            last = t;
        }
        assert_eq!(last, MAX_TIMEOUT_SECONDS as u32);
        // 438,000 samples at 0.24 us, 4 times slower: 0.43 s; (0.5 + 0.43) x 3 = 2.8 s.
        dense.spp = 1_000;
        let expected = 3.0
            * (COLD_START_MS
                + 4.0 * (RATES.task_overhead_ms + 438_000.0 * RATES.cast_us_per_sample / 1000.0));
        assert_eq!(
            task_timeout_seconds(&dense, Stage::CastMap),
            (expected / 1000.0).ceil() as u32
        );
        // A split of 4 million triangles adds its load to the tasks that read splits only.
        let before = task_timeout_seconds(&dense, Stage::CastReduce);
        dense.splits[0].triangles = 4_000_000;
        assert!(
            task_timeout_seconds(&dense, Stage::CastMap)
                > task_timeout_seconds(&plan, Stage::CastMap)
        );
        assert_eq!(task_timeout_seconds(&dense, Stage::CastReduce), before);
    }

    #[test]
    fn the_timeouts_bound_the_adaptive_samplers_most_samples_and_every_hit() {
        let mut plan = cornell();
        plan.spp = 64;
        plan.camera_hit_estimate = Some(0.0);
        let none_hit = task_timeout_seconds(&plan, Stage::TraceReduce);
        plan.camera_hit_estimate = None;
        assert_eq!(
            task_timeout_seconds(&plan, Stage::TraceReduce),
            none_hit,
            "the upper bound ignores the estimate"
        );
        plan.adaptive = Some(crate::adaptive::AdaptiveSettings {
            base_spp: 4,
            max_spp: 65_536,
            threshold: 0.01,
        });
        assert_eq!(
            task_timeout_seconds(&plan, Stage::CastMap),
            MAX_TIMEOUT_SECONDS as u32
        );
    }

    #[test]
    fn parts_get_their_own_bounds() {
        assert_eq!(partition_timeout_seconds(0), 60);
        assert_eq!(build_timeout_seconds(0), 60);
        assert_eq!(partition_timeout_seconds(u64::MAX), 900);
        assert_eq!(build_timeout_seconds(u64::MAX), 900);
        assert!(build_timeout_seconds(20_000_000) > build_timeout_seconds(1_000_000));
    }
}
