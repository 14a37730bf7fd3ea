//! Per-task memory in the emulator, with the counting allocator installed as in `hort` (for the
//! whole test binary, in `main.rs`): each stage reports the most memory one of its tasks held (at
//! least the split objects it used), the image stays the monolithic render's, and a task over the
//! functions' memory fails the job at once with `Runtime.OutOfMemory`, naming the task, what it
//! used and the budget.

use asl_interpreter::{Event, FunctionLimits, NoObserver, Observer};
use hort::emulator::{EmulatorConfig, run_job};
use hort_core::pipeline::{
    PlanRequest, SplitMode, StoredOutputs, decode_split, rebuild_split, split_build_preset,
};
use hort_core::scene::load_scene;
use hort_core::stage::Stage;
use hort_tests::{hit_bits, pixel_bits, scene_path, stored};
use std::sync::Mutex;

const SCENE: &str = "bunny/bunny.json";
const W: u32 = 64;
const H: u32 = 48;

fn config(workers: usize, memory_mb: u32, job: Option<&str>) -> EmulatorConfig {
    EmulatorConfig {
        job: job.map(str::to_owned),
        // Timeouts of 250 s x 0.02 = 5 s: far above a task's time, so none times out.
        time_scale: 0.02,
        task_timeout_seconds: Some(250),
        memory_mb,
        // The deployment's Worker timeout (120 s) would be 2.4 s at this time scale: these
        // tests time their tasks by their own 250 s timeouts instead.
        functions: FunctionLimits::none(),
        ..EmulatorConfig::embedded(workers)
    }
}

fn request(k: u32, spans: u32, mode: SplitMode, spp: u32) -> PlanRequest {
    PlanRequest {
        width: W,
        height: H,
        spp,
        splits: Some(k),
        spans: Some(spans),
        mode,
        execution: None,
        memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
        adaptive: None,
        outputs: StoredOutputs::ALL,
        frame: Default::default(),
    }
}

/// `memory_bytes` of each decoded split object of the scene cut into `k` splits, as a job of
/// `request(k, _, mode, 1)` builds them.
fn split_memory(k: u32, mode: SplitMode) -> Vec<u64> {
    let scene = load_scene(&scene_path(SCENE)).unwrap();
    let triangles = scene.mesh.triangle_count() as u64;
    let preset = split_build_preset(&request(k, 2, mode, 1), triangles);
    (0..k)
        .map(|split| {
            let bytes = rebuild_split(&scene.mesh, k as usize, mode, preset, split).unwrap();
            decode_split("split", &bytes).unwrap().memory_bytes()
        })
        .collect()
}

/// The stage's `peak_memory_bytes` in `run`.
fn peak(stages: &[hort_core::report::StageReport], name: &str) -> u64 {
    stages
        .iter()
        .find(|s| s.name == name)
        .unwrap_or_else(|| panic!("no stage {name}"))
        .peak_memory_bytes
}

#[test]
fn every_task_reports_its_peak_and_the_image_stays_the_same() {
    let mono = hort_tests::monolithic(SCENE, W, H, 1);
    for (k, spans, mode, map_stage) in [
        (1, 2, SplitMode::Spatial, "render"),
        (2, 2, SplitMode::Naive, "cast-map"),
    ] {
        let run = run_job(
            &config(2, 2048, None),
            &scene_path(SCENE),
            request(k, spans, mode, 1),
            &NoObserver,
        )
        .unwrap_or_else(|e| panic!("k = {k}: {e:#}"));
        assert_eq!(
            pixel_bits(&stored(&run.image).pixels),
            pixel_bits(&mono.image.pixels)
        );
        assert_eq!(hit_bits(stored(&run.hits).as_slice()), hit_bits(&mono.hits));
        // Every task of every stage after the plan was measured, within the budget.
        assert!(!run.ledger.tasks.is_empty());
        for ((stage, _, task), m) in &run.ledger.tasks {
            assert!(
                m.peak_memory_bytes > 0 && m.peak_memory_bytes < (2048 - 96) << 20,
                "k = {k}: {stage} task {} peak {}",
                task.0,
                m.peak_memory_bytes
            );
        }
        // The plan builds every split object in memory, one after another.
        let largest_split = split_memory(k, mode).into_iter().max().unwrap();
        assert_eq!(peak(&run.stages, "plan"), run.ledger.plan_peak_memory_bytes);
        assert!(
            peak(&run.stages, "plan") >= largest_split,
            "k = {k}: plan peak {} below its largest split's {largest_split} bytes",
            peak(&run.stages, "plan")
        );
        // The task stages report the largest of their tasks' peaks.
        for s in run.stages.iter().filter(|s| s.name != "plan") {
            let largest = run
                .ledger
                .tasks
                .iter()
                .filter(|((stage, _, _), _)| stage.to_string() == s.name)
                .map(|(_, m)| m.peak_memory_bytes)
                .max();
            assert_eq!(Some(s.peak_memory_bytes), largest, "k = {k}: {}", s.name);
        }
        // A task that uses a split holds it decoded (naive mode: every pair is cast, so some
        // task uses the largest split; fused: the one split).
        assert!(
            peak(&run.stages, map_stage) >= largest_split,
            "k = {k}: {map_stage} peak {} below its split's {largest_split} bytes",
            peak(&run.stages, map_stage)
        );
    }
}

/// Counts the task attempts the state machine starts.
#[derive(Default)]
struct Attempts(Mutex<Vec<String>>);

impl Observer for Attempts {
    fn event(&self, e: &Event) {
        if let Event::TaskAttemptStarted { state, .. } = e {
            self.0.lock().unwrap().push(state.clone());
        }
    }
}

#[test]
fn a_task_over_the_functions_memory_fails_the_job_without_a_retry() {
    // The job asks for 2048 MB, so its plan runs fused in one split; the functions have 97 MB:
    // 1 MB above the runtime allowance, less than the decoded scene and the one span's pixels
    // (320x240: 1.5 MB of radiance, triangle ids and distances) that the render task holds.
    let attempts = Attempts::default();
    let big = PlanRequest {
        width: 320,
        height: 240,
        ..request(1, 1, SplitMode::Spatial, 1)
    };
    let e = run_job(
        &config(1, 97, Some("oom")),
        &scene_path(SCENE),
        big,
        &attempts,
    )
    .err()
    .expect("the render task does not fit 97 MB");
    let message = format!("{e:#}");
    let prefix = "job oom failed in render task 0: Runtime.OutOfMemory: task render/0/0 used ";
    let rest = message
        .strip_prefix(prefix)
        .unwrap_or_else(|| panic!("{message}"));
    // `{used} MB of its 97 MB memory budget (96.0 MB runtime allowance + {measured} MB
    // measured)`, the figures measured.
    let (used, rest) = rest.split_once(' ').unwrap();
    let rest = rest
        .strip_prefix("MB of its 97 MB memory budget (96.0 MB runtime allowance + ")
        .unwrap_or_else(|| panic!("{message}"));
    let measured = rest
        .strip_suffix(" MB measured)")
        .unwrap_or_else(|| panic!("{message}"));
    let (used, measured): (f64, f64) = (used.parse().unwrap(), measured.parse().unwrap());
    assert!((used - 96.0 - measured).abs() <= 0.1, "{message}");
    let split = split_memory(1, SplitMode::Spatial)[0] as f64 / f64::from(1 << 20);
    assert!(
        measured >= split && used > 97.0,
        "{message}: the split alone is {split:.1} MB"
    );
    // The plan and the one render attempt: Runtime.OutOfMemory is never retried.
    assert_eq!(*attempts.0.lock().unwrap(), ["Plan", "Render/RenderTask"]);
}

#[test]
fn a_warm_workers_cached_splits_count_for_every_task_it_runs() {
    // One function slot: one warm worker, whose cache keeps both splits once cast-map has
    // decoded them (1 GiB of cache, capped at half of 2048 MB); every later task runs there.
    let (k, mode) = (2, SplitMode::Naive);
    let run = run_job(
        &config(1, 2048, None),
        &scene_path(SCENE),
        request(k, 2, mode, 1),
        &NoObserver,
    )
    .unwrap_or_else(|e| panic!("{e:#}"));
    let mono = hort_tests::monolithic(SCENE, W, H, 1);
    assert_eq!(
        pixel_bits(&stored(&run.image).pixels),
        pixel_bits(&mono.image.pixels)
    );
    let both: u64 = split_memory(k, mode).into_iter().sum();
    let mut later = 0;
    for ((stage, _, task), m) in &run.ledger.tasks {
        // The plan (building the splits one at a time) and cast-map (decoding them) run
        // before the cache holds both.
        if ![Stage::Plan, Stage::CastMap].contains(stage) {
            later += 1;
            assert!(
                m.peak_memory_bytes >= both,
                "{stage} task {} peak {} below the cached splits' {both} bytes",
                task.0,
                m.peak_memory_bytes
            );
        }
    }
    assert_eq!(
        later,
        2 + 2 + 4 + 2 + 1,
        "cast-reduce, expand, trace-map, trace-reduce, combine"
    );
}
