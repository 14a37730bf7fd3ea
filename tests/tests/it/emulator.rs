//! The local emulator end to end over the real S3 protocol: the image and hit buffer equal the
//! monolithic render's for several partitionings and worker counts, under injected faults, and
//! when a block is corrupted in storage between stages.

use crate::s3_support;

use asl_interpreter::{Event, FunctionLimits, NoObserver, Observer};
use hort::emulator::{EmulatorConfig, EmulatorRun, FaultSettings, StorageTarget, run_job};
use hort_core::cost::Arch;
use hort_core::pipeline::{PlanRequest, SplitMode, StoredOutputs};
use hort_core::render::RenderOutput;
use hort_core::store::BlobStore;
use hort_functions::S3Credentials;
use hort_tests::{hit_bits, pixel_bits, scene_path, stored};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};

const W: u32 = 64;
const H: u32 = 48;

fn monolithic(rel: &str, spp: u32) -> RenderOutput {
    hort_tests::monolithic(rel, W, H, spp)
}

fn config(server: &s3_support::Embedded, workers: usize, faults: FaultSettings) -> EmulatorConfig {
    EmulatorConfig {
        storage: StorageTarget::External {
            endpoint: server.server.endpoint(),
            bucket: "emu".into(),
            credentials: S3Credentials::Static {
                access_key: s3_support::ACCESS_KEY.into(),
                secret_key: s3_support::SECRET_KEY.into(),
            },
        },
        job: None,
        workers,
        faults,
        // Fast backoff for tests. Timeouts of 250 s x 0.02 = 5 s stay far above a task's time
        // (tens of milliseconds) even on a loaded machine, so no attempt times out unless a
        // fault makes it; the fault test shortens them (its assertions allow extra timeouts).
        time_scale: 0.02,
        task_timeout_seconds: Some(250),
        split_cache_bytes: 1 << 28,
        memory_mb: 2048,
        arch: Arch::Arm64,
        cancel: Arc::new(AtomicBool::new(false)),
        lambda: None,
        // The deployment's Worker timeout (120 s) would be 2.4 s at this time scale: these
        // tests time their tasks by their own 250 s timeouts instead.
        functions: FunctionLimits::none(),
    }
}

fn settings(spp: u32, k: u32, s: u32, mode: SplitMode) -> PlanRequest {
    PlanRequest {
        width: W,
        height: H,
        spp,
        splits: Some(k),
        spans: Some(s),
        mode,
        execution: None,
        memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
        adaptive: None,
        outputs: StoredOutputs::ALL,
        frame: Default::default(),
    }
}

fn assert_same(run: &EmulatorRun, mono: &RenderOutput, what: &str) {
    assert_eq!(
        pixel_bits(&stored(&run.image).pixels),
        pixel_bits(&mono.image.pixels),
        "image differs: {what}"
    );
    assert_eq!(
        hit_bits(stored(&run.hits).as_slice()),
        hit_bits(&mono.hits),
        "hit buffer differs: {what}"
    );
}

#[test]
fn emulated_pipeline_equals_monolithic_for_several_partitionings() {
    let server = s3_support::Embedded::start(Some("emu"));
    let mono = monolithic("bunny/bunny.json", 1);
    let fused: &[&str] = &["plan", "render", "combine"];
    let staged: &[&str] = &[
        "plan",
        "cast-map",
        "cast-reduce",
        "expand",
        "trace-map",
        "trace-reduce",
        "combine",
    ];
    for (k, s, workers, mode, stages) in [
        (1, 1, 1, SplitMode::Spatial, fused),
        (1, 6, 3, SplitMode::Spatial, fused),
        (3, 7, 4, SplitMode::Spatial, staged),
        (8, 5, 3, SplitMode::Naive, staged),
    ] {
        let run = run_job(
            &config(&server, workers, FaultSettings::default()),
            &scene_path("bunny/bunny.json"),
            settings(1, k, s, mode),
            &NoObserver,
        )
        .unwrap_or_else(|e| panic!("k={k} s={s}: {e:#}"));
        assert_same(
            &run,
            &mono,
            &format!("k={k} s={s} workers={workers} {mode:?}"),
        );
        assert_eq!(run.failed_attempts(), 0);
        let names: Vec<&str> = run.stages.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, stages);
        assert!(run.cost.total > 0.0);
        // The first stage after plan has one task per span (render), or a reduce stage does.
        let per_span = if stages == fused { 1 } else { 2 };
        assert_eq!(run.stages[per_span].tasks, u64::from(s));
    }
}

/// A textured scene in the emulator: the textures go up inside the binary scene, the Plan
/// function stores each once under its content key, and every task that shades reads them
/// (faults included): the monolithic image, fused and staged.
#[test]
fn a_textured_scene_under_faults_equals_monolithic() {
    let server = s3_support::Embedded::start(Some("emu"));
    let mono = monolithic("globe/globe.json", 2);
    for (seed, k, s) in [(7u64, 1, 9), (8, 3, 4)] {
        let faults = FaultSettings {
            fail_rate: 0.2,
            duplicate_rate: 0.2,
            slow_rate: 0.0,
            seed,
            kill_slot_after: None,
        };
        let run = run_job(
            &config(&server, 3, faults),
            &scene_path("globe/globe.json"),
            settings(2, k, s, SplitMode::Spatial),
            &NoObserver,
        )
        .unwrap_or_else(|e| panic!("seed {seed} k={k}: {e:#}"));
        assert_same(
            &run,
            &mono,
            &format!("textured, faults with seed {seed}, k={k}"),
        );
        assert_eq!(run.plan.textures.len(), 2, "globe.png and tiles.png");
    }
}

#[test]
fn injected_faults_give_the_identical_image_and_are_counted() {
    let server = s3_support::Embedded::start(Some("emu"));
    let mono = monolithic("cornell/cornell.json", 2);
    let clean = run_job(
        &config(&server, 4, FaultSettings::default()),
        &scene_path("cornell/cornell.json"),
        settings(2, 3, 6, SplitMode::Spatial),
        &NoObserver,
    )
    .unwrap();
    let clean_fused = run_job(
        &config(&server, 4, FaultSettings::default()),
        &scene_path("cornell/cornell.json"),
        settings(2, 1, 16, SplitMode::Spatial),
        &NoObserver,
    )
    .unwrap();
    assert_eq!(
        clean_fused.plan.mode,
        hort_core::pipeline::ExecutionMode::Fused
    );
    // What each task stage wrote, one successful attempt per task: the same under any faults.
    // (The plan stage reports no task metrics: its bytes are its storage traffic.)
    let useful = |run: &EmulatorRun| -> Vec<(String, u64, u64)> {
        run.stages
            .iter()
            .filter(|s| s.name != "plan")
            .map(|s| (s.name.clone(), s.bytes_written, s.bytes_written_raw))
            .collect()
    };
    let (mut failed_before, mut failed_after_writing) = (0, 0);
    // Seeds 1 to 3 staged (3 splits, 6 spans), 4 and 5 fused (one split, 16 spans).
    for (seed, k) in [(1u64, 3), (2, 3), (3, 3), (4, 1), (5, 1)] {
        let faults = FaultSettings {
            fail_rate: 0.2,
            duplicate_rate: 0.2,
            slow_rate: 0.1,
            seed,
            kill_slot_after: None,
        };
        // Stragglers sleep past their timeout: 1 s here keeps the test short.
        let config = EmulatorConfig {
            task_timeout_seconds: Some(50),
            ..config(&server, 4, faults)
        };
        let run = run_job(
            &config,
            &scene_path("cornell/cornell.json"),
            // Fused jobs have fewer tasks: more spans give each fault kind a chance.
            settings(2, k, if k == 1 { 16 } else { 6 }, SplitMode::Spatial),
            &NoObserver,
        )
        .unwrap_or_else(|e| panic!("seed {seed}: {e:#}"));
        assert_same(&run, &mono, &format!("faults with seed {seed}, k={k}"));
        let clean = if k == 1 { &clean_fused } else { &clean };
        assert_eq!(useful(&run), useful(clean), "seed {seed}: useful bytes");
        let traffic: u64 = run.stages.iter().map(|s| s.attempts_bytes_written).sum();
        let needed: u64 = run.stages.iter().map(|s| s.bytes_written).sum();
        assert!(
            traffic > needed,
            "seed {seed}: failed and duplicated attempts wrote more ({traffic} <= {needed})"
        );
        let counts = run.faults.as_ref().expect("fault counts");
        failed_before += counts.failed_before.load(Ordering::Relaxed);
        failed_after_writing += counts.failed_after_writing.load(Ordering::Relaxed);
        let injected_failures = counts.failed_before.load(Ordering::Relaxed)
            + counts.failed_after_writing.load(Ordering::Relaxed);
        assert!(
            injected_failures > 0 && counts.duplicated.load(Ordering::Relaxed) > 0,
            "seed {seed}: faults were injected"
        );
        assert!(
            counts.slowed.load(Ordering::Relaxed) > 0,
            "seed {seed}: stragglers were injected"
        );
        // Every injected failure and straggler is a failed attempt the report counts.
        assert!(
            run.failed_attempts() >= injected_failures,
            "seed {seed}: {} retried attempts",
            run.failed_attempts()
        );
        let attempts: u64 = run.stages.iter().map(|s| s.attempts).sum();
        let tasks: u64 = run.stages.iter().map(|s| s.tasks).sum();
        assert_eq!(
            attempts,
            tasks + run.failed_attempts(),
            "seed {seed}: attempts = tasks + retries"
        );
    }
    // Both kinds of failure happened: before running, and after writing part of the outputs
    // (whose partial objects the retry overwrites with the same bytes).
    assert!(failed_before > 0, "no attempt failed before running");
    assert!(
        failed_after_writing > 0,
        "no attempt failed after writing part of its outputs"
    );
}

/// Corrupts one cast-reduce block as soon as the trace-reduce stage starts.
struct CorruptBeforeTraceReduce {
    store: hort_functions::S3Store,
    corrupted: AtomicU32,
}

impl Observer for CorruptBeforeTraceReduce {
    fn event(&self, event: &Event) {
        if let Event::StateEntered {
            state,
            item_index: None,
        } = event
            && state == "TraceReduce"
            && self.corrupted.fetch_add(1, Ordering::Relaxed) == 0
        {
            let keys = self.store.list("jobs/").unwrap();
            let key = keys
                .iter()
                .find(|k| k.contains("/cast-reduce/00002/"))
                .expect("a cast-reduce block");
            let mut bytes = self.store.get(key).unwrap();
            let at = bytes.len() / 2;
            bytes[at] ^= 0x5a;
            self.store.put(key, &bytes).unwrap();
        }
    }
}

#[test]
fn a_block_corrupted_between_stages_is_recomputed_from_lineage() {
    let server = s3_support::Embedded::start(Some("emu"));
    let mono = monolithic("teapot/teapot.json", 1);
    let observer = CorruptBeforeTraceReduce {
        store: server.store("emu"),
        corrupted: AtomicU32::new(0),
    };
    let run = run_job(
        &config(&server, 2, FaultSettings::default()),
        &scene_path("teapot/teapot.json"),
        settings(1, 2, 4, SplitMode::Spatial),
        &observer,
    )
    .unwrap();
    assert_eq!(observer.corrupted.load(Ordering::Relaxed), 1);
    assert_same(&run, &mono, "after corruption");
    assert_eq!(run.recomputed(), 1, "the corrupt block was recomputed once");
}

#[test]
fn a_function_slot_dying_mid_run_loses_nothing() {
    let server = s3_support::Embedded::start(Some("emu"));
    let mono = monolithic("bunny/bunny.json", 1);
    let faults = FaultSettings {
        kill_slot_after: Some(0.0),
        ..FaultSettings::default()
    };
    let run = run_job(
        &config(&server, 4, faults),
        &scene_path("bunny/bunny.json"),
        settings(1, 2, 4, SplitMode::Spatial),
        &NoObserver,
    )
    .unwrap();
    assert_same(&run, &mono, "one slot died");
    let counts = run.faults.as_ref().unwrap();
    assert_eq!(counts.slots_killed.load(Ordering::Relaxed), 1);
    assert_eq!(
        run.failed_attempts(),
        1,
        "the lost attempt timed out once and was retried"
    );
}
