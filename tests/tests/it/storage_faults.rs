//! Storage faults at the HTTP level of the embedded S3 server: under transient faults of every
//! kind the emulator's image and hit buffer are byte for byte the fault-free (and monolithic)
//! ones; a persistent fault fails the job with one line naming the key; a cut body is never
//! taken for the object; objects deleted or corrupted between stages (split objects, and every
//! stage's input blocks, Combine's included) are recomputed from lineage.

use crate::s3_support;

use asl_interpreter::{Event, FunctionLimits, NoObserver, Observer};
use embedded_s3::{FaultKind, PersistentFault, StorageFaults};
use hort::emulator::{EmulatorConfig, EmulatorRun, FaultSettings, StorageTarget, run_job};
use hort_core::cost::Arch;
use hort_core::image::encode_png;
use hort_core::pipeline::{PlanRequest, SplitMode, StoredOutputs};
use hort_core::store::{BlobStore, StoreError};
use hort_functions::{S3Config, S3Store};
use hort_tests::{hit_bits, pixel_bits, scene_path, stored};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const SCENE: &str = "cornell/cornell.json";
const BUCKET: &str = "emu";

/// The client of `server` the emulator uses: the default 3 attempts per request, with a short
/// backoff so that tests with many faults stay fast.
fn client_config(server: &s3_support::Embedded) -> S3Config {
    let mut config = S3Config::compatible(
        server.server.endpoint(),
        BUCKET,
        s3_support::ACCESS_KEY,
        s3_support::SECRET_KEY,
    );
    config.initial_backoff = Duration::from_millis(10);
    config
}

fn config(server: &s3_support::Embedded, job: Option<&str>) -> EmulatorConfig {
    EmulatorConfig {
        storage: StorageTarget::Bucket(client_config(server)),
        job: job.map(str::to_owned),
        workers: 2,
        faults: FaultSettings::default(),
        // Fast state machine backoff; timeouts of 250 s x 0.02 = 5 s, far above a task's time.
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

fn settings() -> PlanRequest {
    PlanRequest {
        width: 64,
        height: 48,
        spp: 1,
        splits: Some(2),
        spans: Some(3),
        mode: SplitMode::Spatial,
        execution: None,
        memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
        adaptive: None,
        outputs: StoredOutputs::ALL,
        frame: Default::default(),
    }
}

fn render(server: &s3_support::Embedded, observer: &dyn Observer) -> EmulatorRun {
    run_job(
        &config(server, None),
        &scene_path(SCENE),
        settings(),
        observer,
    )
    .unwrap_or_else(|e| panic!("{e:#}"))
}

/// The fault-free emulator run's PNG, which must equal the monolithic render's encoding.
fn reference() -> Vec<u8> {
    let mono = hort_tests::monolithic(SCENE, 64, 48, 1);
    let server = s3_support::Embedded::start(Some(BUCKET));
    let clean = render(&server, &NoObserver);
    assert_same(&clean, &mono, "fault-free");
    let png = encode_png(&mono.image).unwrap();
    assert_eq!(clean.png, png, "fault-free PNG = monolithic PNG");
    png
}

fn assert_same(run: &EmulatorRun, mono: &hort_core::render::RenderOutput, what: &str) {
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

fn only(kind: FaultKind, rate: f64, seed: u64) -> StorageFaults {
    let mut faults = StorageFaults {
        seed,
        latency_duration: Duration::from_millis(20),
        ..StorageFaults::default()
    };
    match kind {
        FaultKind::SlowDown => faults.slow_down = rate,
        FaultKind::InternalError => faults.internal_error = rate,
        FaultKind::Latency => faults.latency = rate,
        FaultKind::Reset => faults.reset = rate,
        FaultKind::Truncate => faults.truncate = rate,
    }
    faults
}

#[test]
fn transient_faults_of_every_kind_leave_the_image_identical() {
    let mono = hort_tests::monolithic(SCENE, 64, 48, 1);
    let png = reference();
    let mut cases: Vec<(String, StorageFaults)> = FaultKind::ALL
        .into_iter()
        .map(|kind| (kind.name().to_owned(), only(kind, 0.1, 11)))
        .collect();
    cases.push((
        "all kinds".into(),
        "seed=12,slow-down=0.05,internal-error=0.05,latency=0.05,latency-ms=20,reset=0.05,\
         truncate=0.05"
            .parse()
            .unwrap(),
    ));
    for (name, faults) in cases {
        let started = Instant::now();
        let server = s3_support::Embedded::start_with_faults(BUCKET, faults.clone());
        // A fixed job id: the keys, hence the draws, are the same on every run of the test.
        let job = format!("faults-{}", name.replace(' ', "-"));
        let run = run_job(
            &config(&server, Some(&job)),
            &scene_path(SCENE),
            settings(),
            &NoObserver,
        )
        .unwrap_or_else(|e| panic!("{name}: {e:#}"));
        let counts = server.server.fault_counts();
        eprintln!(
            "storage faults {name}: {counts}; {} task attempts retried; {:.2} s",
            run.failed_attempts(),
            started.elapsed().as_secs_f64()
        );
        assert_same(&run, &mono, &name);
        assert_eq!(run.png, png, "{name}: PNG bytes");
        for kind in FaultKind::ALL {
            assert_eq!(
                counts.of(kind) > 0,
                faults.rate(kind) > 0.0,
                "{name}: {kind} faults were injected exactly when asked for ({counts})"
            );
        }
        assert_eq!(counts.persistent, 0);
    }
}

#[test]
fn a_persistent_fault_fails_the_job_with_one_line_naming_the_key() {
    let job = "persistent";
    let key = format!("jobs/{job}/trace-reduce/00001/part-00000");
    let faults = StorageFaults {
        persistent: Some(PersistentFault {
            key_prefix: key.clone(),
            kind: FaultKind::SlowDown,
        }),
        ..StorageFaults::default()
    };
    let server = s3_support::Embedded::start_with_faults(BUCKET, faults);
    let started = Instant::now();
    let err = run_job(
        &config(&server, Some(job)),
        &scene_path(SCENE),
        settings(),
        &NoObserver,
    )
    .err()
    .expect("the job fails");
    let text = format!("{err:#}");
    let counts = server.server.fault_counts();
    eprintln!(
        "persistent fault: {counts}; {:.2} s; {text}",
        started.elapsed().as_secs_f64()
    );
    let endpoint = server.server.endpoint();
    assert_eq!(
        text,
        format!(
            "job {job} failed in trace-reduce: Hort.Retryable: TraceReduce failed: task 1 still \
             failed after 3 reruns: storage unavailable (retryable): put \"{key}\": S3 endpoint \
             {endpoint} failed (HTTP 503 SlowDown: Please reduce your request rate.)"
        )
    );
    // 4 rounds (the first run and 3 reruns) of 6 attempts each sent the PUT, each up to 3 times
    // (the SDK's attempts; fewer once the SDK's retry quota, shared by every client of the
    // process, runs low).
    assert!(
        (4 * 6..=4 * 6 * 3).contains(&counts.persistent),
        "{} requests met the persistent fault",
        counts.persistent
    );
    assert_eq!(counts.total(), counts.persistent);
}

#[test]
fn a_cut_body_is_never_taken_for_the_object() {
    let payload: Vec<u8> = (0..50_000u32).map(|i| (i * 7 % 251) as u8).collect();
    // Every answer with a body is cut (PUT answers have none, so objects can be stored).
    let server = s3_support::Embedded::start_with_faults(BUCKET, only(FaultKind::Truncate, 1.0, 0));
    let store = S3Store::open(&client_config(&server)).unwrap();
    store.put("k", &payload).unwrap();
    let err = store.get("k").expect_err("every body is cut");
    let prefix = format!(
        "storage unavailable (retryable): get \"k\": reading the object from S3 endpoint {} \
         failed (",
        server.server.endpoint()
    );
    assert!(err.to_string().starts_with(&prefix), "{err}");
    assert!(!err.to_string().contains('\n'), "{err}");
    assert!(err.is_retryable());
    // The store sent the GET 3 times; each answer was cut once.
    assert_eq!(server.server.fault_counts().truncate, 3);
    let err = store.get_range("k", 10..20_000).expect_err("cut");
    assert!(matches!(err, StoreError::Unavailable { .. }), "{err}");
    let err = store.list("").expect_err("the listing is cut too");
    assert!(matches!(err, StoreError::Unavailable { .. }), "{err}");

    // At half the rate, a read returns the object whole or fails as unavailable; the retries
    // make most reads succeed (all three attempts are cut for 1 in 8).
    for kind in [FaultKind::Truncate, FaultKind::Reset] {
        let started = Instant::now();
        let server = s3_support::Embedded::start_with_faults(BUCKET, only(kind, 0.5, 5));
        let store = S3Store::open(&client_config(&server)).unwrap();
        let (mut whole, mut failed) = (0, 0);
        for i in 0..24 {
            let key = format!("obj/{i}");
            // PUTs meet resets too (after storing): the SDK and this loop send them again.
            let stored = (0..4).any(|_| store.put(&key, &payload[i..]).is_ok());
            assert!(stored, "{kind} {key}: 12 PUTs failed");
            for read in [
                store.get(&key).map(|b| (b, &payload[i..])),
                store
                    .get_range(&key, 100..200)
                    .map(|b| (b, &payload[i + 100..i + 200])),
            ] {
                match read {
                    Ok((got, expected)) => {
                        assert_eq!(got, expected, "{kind} {key}");
                        whole += 1;
                    }
                    Err(StoreError::Unavailable { what }) => {
                        assert!(what.contains(&format!("\"{key}\": ")), "{what}");
                        failed += 1;
                    }
                    Err(e) => panic!("{kind} {key}: {e}"),
                }
            }
        }
        let counts = server.server.fault_counts();
        eprintln!(
            "store under 50% {kind}: {counts}; {whole} reads whole, {failed} failed; {:.2} s",
            started.elapsed().as_secs_f64()
        );
        assert!(whole >= 36, "{kind}: {whole} of 48 reads whole");
        assert!(counts.of(kind) > 24, "{kind}: {counts}");
    }
}

/// Deletes the first and corrupts the last input object of each stage as it starts: the split
/// objects cast-map reads, and the shuffle partitions of the stages before for the others; and
/// deletes `plan.json` before expand and cuts it before trace-map.
struct DamageEveryStage {
    store: S3Store,
    /// (stage, deleted key, corrupted key), in order.
    damaged: Mutex<Vec<(String, String, String)>>,
}

impl DamageEveryStage {
    fn inputs(state: &str) -> Option<&'static [&'static str]> {
        Some(match state {
            "CastMap" => &["/splits/"],
            "CastReduce" => &["/cast-map/"],
            "Expand" => &["/cast-reduce/"],
            "TraceMap" => &["/expand/"],
            "TraceReduce" => &["/cast-reduce/", "/trace-map/"],
            "Combine" => &["/trace-reduce/"],
            _ => return None,
        })
    }
}

impl Observer for DamageEveryStage {
    fn event(&self, event: &Event) {
        let Event::StateEntered {
            state,
            item_index: None,
        } = event
        else {
            return;
        };
        let Some(inputs) = Self::inputs(state) else {
            return;
        };
        let keys: Vec<String> = self
            .store
            .list("jobs/")
            .unwrap()
            .into_iter()
            .filter(|k| inputs.iter().any(|i| k.contains(i)))
            .collect();
        let (first, last) = (keys.first().unwrap(), keys.last().unwrap());
        assert_ne!(first, last, "{state} has two input blocks");
        self.store.delete(first).unwrap();
        let mut bytes = self.store.get(last).unwrap();
        let at = bytes.len() / 2;
        bytes[at] ^= 0x5a;
        self.store.put(last, &bytes).unwrap();
        self.damaged
            .lock()
            .unwrap()
            .push((state.clone(), first.clone(), last.clone()));
        // Every worker reads the plan: lose it before expand, cut it in half before trace-map.
        let plan = keys[0].split("/").take(2).collect::<Vec<_>>().join("/") + "/plan.json";
        if state == "Expand" {
            self.store.delete(&plan).unwrap();
        } else if state == "TraceMap" {
            let bytes = self.store.get(&plan).unwrap();
            self.store.put(&plan, &bytes[..bytes.len() / 2]).unwrap();
        }
    }
}

#[test]
fn objects_lost_or_corrupted_before_every_stage_are_recomputed() {
    let mono = hort_tests::monolithic(SCENE, 64, 48, 1);
    let png = encode_png(&mono.image).unwrap();
    let server = s3_support::Embedded::start(Some(BUCKET));
    let observer = DamageEveryStage {
        store: server.store(BUCKET),
        damaged: Mutex::new(Vec::new()),
    };
    // One function slot: the first cast-map task that needs a split rebuilds it, and no other
    // task reads it from storage at the same time (which would rebuild it twice). Cold
    // workers (no cache): every task reads the plan and its splits from storage, so the lost
    // and the cut plan are found and rebuilt (a warm worker would go on with the plan it has).
    let config = EmulatorConfig {
        workers: 1,
        split_cache_bytes: 0,
        ..config(&server, None)
    };
    let run = run_job(&config, &scene_path(SCENE), settings(), &observer)
        .unwrap_or_else(|e| panic!("{e:#}"));
    let damaged = observer.damaged.lock().unwrap().clone();
    let stages: Vec<&str> = damaged.iter().map(|(s, _, _)| s.as_str()).collect();
    assert_eq!(
        stages,
        [
            "CastMap",
            "CastReduce",
            "Expand",
            "TraceMap",
            "TraceReduce",
            "Combine"
        ]
    );
    assert!(damaged[0].1.ends_with("/splits/00000.bin"));
    assert!(damaged[0].2.ends_with("/splits/00001.bin"));
    assert!(damaged[5].1.ends_with("/trace-reduce/00000/part-00000"));
    assert!(damaged[5].2.ends_with("/trace-reduce/00002/part-00000"));
    assert_same(&run, &mono, "after damage before every stage");
    assert_eq!(run.png, png, "PNG bytes");
    assert_eq!(
        run.recomputed(),
        14,
        "each damaged object (12 blocks and splits, the plan twice) was recomputed once"
    );
    assert_eq!(
        run.failed_attempts(),
        0,
        "no attempt failed: lineage, not retries"
    );
    let per_stage: Vec<(String, u64)> = [
        hort_core::stage::Stage::CastMap,
        hort_core::stage::Stage::CastReduce,
        hort_core::stage::Stage::Expand,
        hort_core::stage::Stage::TraceMap,
        hort_core::stage::Stage::TraceReduce,
        hort_core::stage::Stage::Combine,
    ]
    .into_iter()
    .map(|s| (s.to_string(), run.ledger.stage(s).recomputed))
    .collect();
    assert_eq!(
        per_stage,
        [
            ("cast-map".to_owned(), 2),
            ("cast-reduce".to_owned(), 2),
            ("expand".to_owned(), 3),
            ("trace-map".to_owned(), 3),
            ("trace-reduce".to_owned(), 2),
            ("combine".to_owned(), 2),
        ]
    );
}
