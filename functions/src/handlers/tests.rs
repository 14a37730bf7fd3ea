//! The handlers called directly over an in-memory store, as the Lambda runtime would call them.

use super::*;
use hort_core::ids::JobId;
use hort_core::ids::TaskId;
use hort_core::keys::{hits_key, items_key, manifest_key, scene_binary_key, scene_prefix};
use hort_core::pipeline::{PlanRequest, SplitCache, SplitMode, StoredOutputs};
use hort_core::stage::Stage;
use hort_core::store::{BlobStore, MemoryStore};

pub(super) fn request(scene: &str) -> JobRequest {
    JobRequest {
        scene: scene.into(),
        render: PlanRequest {
            width: 32,
            height: 24,
            spp: 1,
            splits: Some(2),
            spans: Some(3),
            mode: SplitMode::Spatial,
            execution: None,
            memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
            adaptive: None,
            outputs: StoredOutputs::ALL,
            frame: Default::default(),
        },
        max_concurrency: 4,
        task_timeout_seconds: None,
        scene_format: SceneFormat::Files,
        scene_range_bytes: None,
        scene_key: None,
        budget: None,
    }
}

/// A store holding the bundled Cornell room and a job request for it.
fn submitted(job: &str) -> MemoryStore {
    let store = MemoryStore::new();
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/cornell");
    let prefix = scene_prefix(&JobId::new(job).unwrap());
    for file in ["cornell.json", "cornell.obj", "cornell.mtl"] {
        let bytes = std::fs::read(format!("{dir}/{file}")).unwrap();
        store.put(&format!("{prefix}{file}"), &bytes).unwrap();
    }
    let json = serde_json::to_vec(&request("cornell.json")).unwrap();
    store
        .put(&manifest_key(&JobId::new(job).unwrap()), &json)
        .unwrap();
    store
}

fn plan_event(job: &str) -> PlanEvent {
    PlanEvent {
        job: JobId::new(job).unwrap(),
        bucket: "b".into(),
        attempt: 0,
        round: 1,
        step: PlanStep::Start,
    }
}

#[test]
fn a_second_round_is_planned_only_for_staged_adaptive_jobs_and_rounds_stop_at_two() {
    let store = submitted("j1");
    let tmp = std::env::temp_dir();
    let out = handle_plan(&store, "b", &plan_event("j1"), Tmp::unlimited(&tmp)).unwrap();
    assert!(!out.refine_after && out.shadows);
    let round = |n: u32| {
        let event = PlanEvent {
            round: n,
            ..plan_event("j1")
        };
        handle_plan(&store, "b", &event, Tmp::unlimited(&tmp))
            .unwrap_err()
            .cause
    };
    assert_eq!(
        round(2),
        "plan jobs/j1/plan.json: the job has no second round (it is not a staged adaptive job)"
    );
    assert_eq!(round(3), "plan event round 3: a job has rounds 1 and 2");
}

#[test]
fn plan_then_every_worker_task_produces_the_outputs() {
    let store = submitted("j1");
    let out = handle_plan(
        &store,
        "b",
        &plan_event("j1"),
        Tmp::unlimited(&std::env::temp_dir()),
    )
    .unwrap();
    let job = JobId::new("j1").unwrap();
    assert_eq!(
        serde_json::to_value(&out.items).unwrap(),
        serde_json::json!({
            "cast_map": "jobs/j1/items/cast-map.json",
            "cast_reduce": "jobs/j1/items/cast-reduce.json",
            "expand": "jobs/j1/items/expand.json",
            "trace_map": "jobs/j1/items/trace-map.json",
            "trace_reduce": "jobs/j1/items/trace-reduce.json",
        })
    );
    assert_eq!(
        out.items_key(Stage::CastReduce),
        Some(items_key(&job, Stage::CastReduce).as_str())
    );
    assert_eq!(out.max_concurrency, 4);
    let cache = SplitCache::new(1 << 24);
    for stage in [
        Stage::CastMap,
        Stage::CastReduce,
        Stage::Expand,
        Stage::TraceMap,
        Stage::TraceReduce,
    ] {
        let key = out.items_key(stage).unwrap();
        let items: Vec<TaskItem> = serde_json::from_slice(&store.get(key).unwrap()).unwrap();
        assert!(!items.is_empty());
        for item in items {
            let timeout = item.timeout_seconds.unwrap();
            assert!((2..=40).contains(&timeout), "{stage}: timeout {timeout}");
            let event = WorkerEvent {
                job: job.clone(),
                bucket: "b".into(),
                stage,
                item,
                attempt: 0,
            };
            handle_worker(
                &store,
                "b",
                &cache,
                &event,
                Tmp::unlimited(&std::env::temp_dir()),
            )
            .unwrap();
        }
    }
    let combine = WorkerEvent {
        job: job.clone(),
        bucket: "b".into(),
        stage: Stage::Combine,
        item: TaskItem {
            task: TaskId(0),
            timeout_seconds: None,
            frame: None,
        },
        attempt: 0,
    };
    handle_worker(
        &store,
        "b",
        &cache,
        &combine,
        Tmp::unlimited(&std::env::temp_dir()),
    )
    .unwrap();
    assert_eq!(store.get(&hits_key(&job)).unwrap().len(), 32 * 24 * 8);
}

/// The Worker event of cast-map task `task` of `job`, first attempt.
fn cast_map_event(job: &str, task: u32) -> WorkerEvent {
    WorkerEvent {
        job: JobId::new(job).unwrap(),
        bucket: "b".into(),
        stage: Stage::CastMap,
        item: TaskItem {
            task: TaskId(task),
            timeout_seconds: None,
            frame: None,
        },
        attempt: 0,
    }
}

/// Runs the Plan function, then every task of every later stage, over `store`.
fn run_job(store: &MemoryStore, job: &str) {
    let tmp = std::env::temp_dir();
    let out = handle_plan(store, "b", &plan_event(job), Tmp::unlimited(&tmp)).unwrap();
    let cache = SplitCache::new(0);
    for &stage in out.task_stages() {
        let items: Vec<TaskItem> = match out.items_key(stage) {
            Some(key) => serde_json::from_slice(&store.get(key).unwrap()).unwrap(),
            None => vec![TaskItem {
                task: TaskId(0),
                timeout_seconds: None,
                frame: None,
            }],
        };
        for item in items {
            let event = WorkerEvent {
                job: JobId::new(job).unwrap(),
                bucket: "b".into(),
                stage,
                item,
                attempt: 0,
            };
            handle_worker(store, "b", &cache, &event, Tmp::unlimited(&tmp)).unwrap();
        }
    }
}

/// A store holding only the bundled Cornell room's binary scene and a job request saying so:
/// no OBJ, MTL or manifest at all, so nothing can parse them.
fn submitted_binary(job: &str) -> MemoryStore {
    let store = MemoryStore::new();
    let id = JobId::new(job).unwrap();
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenes/cornell/cornell.json"
    );
    let scene = hort_core::scene::load_scene(std::path::Path::new(path)).unwrap();
    let bytes = hort_core::scene::encode_scene(&scene);
    store.put(&scene_binary_key(&id), &bytes).unwrap();
    let request = JobRequest {
        scene_format: SceneFormat::Binary,
        scene_range_bytes: None,
        scene_key: None,
        budget: None,
        ..request("cornell.json")
    };
    store
        .put(&manifest_key(&id), &serde_json::to_vec(&request).unwrap())
        .unwrap();
    store
}

/// Every object of `job` in `store` under `jobs/{job}/{under}`, by key relative to the job.
fn objects(store: &MemoryStore, job: &str, under: &str) -> Vec<(String, Vec<u8>)> {
    let prefix = format!("jobs/{job}/");
    store
        .list(&format!("{prefix}{under}"))
        .unwrap()
        .into_iter()
        .map(|k| (k[prefix.len()..].to_owned(), store.get(&k).unwrap()))
        .collect()
}

#[test]
fn a_binary_scene_job_renders_the_same_bytes_as_the_files_without_parsing() {
    let files = submitted("jf");
    run_job(&files, "jf");
    let binary = submitted_binary("jb");
    run_job(&binary, "jb");
    // The Plan function and the Workers had only scene.bin: nothing was parsed.
    assert_eq!(
        binary.list("jobs/jb/scene/").unwrap(),
        ["jobs/jb/scene/scene.bin"]
    );
    for under in [
        "plan.json",
        "splits/",
        "items/",
        "cast-map/",
        "trace-reduce/",
        "out/",
    ] {
        let (f, b) = (objects(&files, "jf", under), objects(&binary, "jb", under));
        assert!(!f.is_empty(), "{under}");
        // Items files name their job: compare them with the id replaced (they are JSON).
        let b: Vec<_> = if under == "items/" {
            b.into_iter()
                .map(|(k, v)| {
                    (
                        k,
                        String::from_utf8(v)
                            .unwrap()
                            .replace("jb", "jf")
                            .into_bytes(),
                    )
                })
                .collect()
        } else {
            b
        };
        assert!(f == b, "{under} differs");
    }
    // Lineage from the binary scene: a lost plan is rebuilt (the plan step again), and so are
    // corrupt split objects (one at a time), with the same bytes.
    let tmp = std::env::temp_dir();
    let cast = |task: u32| cast_map_event("jb", task);
    let plan = binary.get("jobs/jb/plan.json").unwrap();
    let splits = objects(&binary, "jb", "splits/");
    assert_eq!(splits.len(), 2);
    binary.delete("jobs/jb/plan.json").unwrap();
    let done = handle_worker(
        &binary,
        "b",
        &SplitCache::new(0),
        &cast(0),
        Tmp::unlimited(&tmp),
    )
    .unwrap();
    assert_eq!(done.recomputed, 1);
    assert_eq!(binary.get("jobs/jb/plan.json").unwrap(), plan);
    for (key, _) in &splits {
        binary.put(&format!("jobs/jb/{key}"), b"junk").unwrap();
    }
    let cast_tasks = serde_json::from_slice::<serde_json::Value>(&plan).unwrap()["cast_tasks"]
        .as_array()
        .unwrap()
        .len() as u32;
    let recomputed: u64 = (0..cast_tasks)
        .map(|t| {
            handle_worker(
                &binary,
                "b",
                &SplitCache::new(0),
                &cast(t),
                Tmp::unlimited(&tmp),
            )
            .unwrap()
            .recomputed
        })
        .sum();
    assert_eq!(recomputed, 2);
    assert_eq!(objects(&binary, "jb", "splits/"), splits);
}

#[test]
fn a_missing_corrupt_or_newer_binary_scene_is_bad_input_naming_the_key() {
    let tmp = std::env::temp_dir();
    let plan = |store: &MemoryStore| {
        handle_plan(store, "b", &plan_event("jb"), Tmp::unlimited(&tmp)).unwrap_err()
    };
    let store = submitted_binary("jb");
    let good = store.get("jobs/jb/scene/scene.bin").unwrap();
    let body = good.len() - 24;

    store.delete("jobs/jb/scene/scene.bin").unwrap();
    assert_eq!(
        plan(&store),
        HandlerError::bad_input(
            "scene jobs/jb/scene/scene.bin does not exist (the job request's scene_format is \
             binary)"
        )
    );
    store
        .put("jobs/jb/scene/scene.bin", &good[..good.len() - 100])
        .unwrap();
    assert_eq!(
        plan(&store),
        HandlerError::bad_input(format!(
            "jobs/jb/scene/scene.bin: body length at byte 12 declares {body} bytes, but {} \
             follow the header",
            body - 100
        ))
    );
    let mut newer = good.clone();
    newer[8] = 3;
    store.put("jobs/jb/scene/scene.bin", &newer).unwrap();
    assert_eq!(
        plan(&store),
        HandlerError::bad_input(
            "jobs/jb/scene/scene.bin: format version 3 at byte 8 is not supported: this build \
             reads version 2 only"
        )
    );
    let mut flipped = good.clone();
    flipped[1000] ^= 4;
    store.put("jobs/jb/scene/scene.bin", &flipped).unwrap();
    let e = plan(&store);
    assert_eq!(e.error_type, ErrorType::BadInput);
    assert!(
        e.cause
            .starts_with("jobs/jb/scene/scene.bin: checksum at byte 20 is 0x")
            && e.cause.ends_with(": the object is corrupt"),
        "{}",
        e.cause
    );
    // A Worker rebuilding from it fails the same way.
    store.put("jobs/jb/scene/scene.bin", &newer).unwrap();
    let worker = WorkerEvent {
        job: JobId::new("jb").unwrap(),
        bucket: "b".into(),
        stage: Stage::CastMap,
        item: TaskItem {
            task: TaskId(0),
            timeout_seconds: None,
            frame: None,
        },
        attempt: 0,
    };
    let e = handle_worker(
        &store,
        "b",
        &SplitCache::new(0),
        &worker,
        Tmp::unlimited(&tmp),
    )
    .unwrap_err();
    assert_eq!(
        e,
        HandlerError::bad_input(
            "jobs/jb/scene/scene.bin: format version 3 at byte 8 is not supported: this build \
             reads version 2 only"
        )
    );
}

#[test]
fn the_job_request_reads_old_json_and_writes_files_format_as_before() {
    let old = r#"{"scene": "a.obj", "render": {"width": 8, "height": 8, "spp": 1, "splits": null,
        "spans": null, "split_mode": "spatial"}, "max_concurrency": 1, "task_timeout_seconds": null}"#;
    let request: JobRequest = serde_json::from_str(old).unwrap();
    assert_eq!(request.scene_format, SceneFormat::Files);
    let json = serde_json::to_value(&request).unwrap();
    assert!(json.get("scene_format").is_none(), "{json}");
    let binary = JobRequest {
        scene_format: SceneFormat::Binary,
        scene_range_bytes: None,
        scene_key: None,
        budget: None,
        ..request
    };
    let json = serde_json::to_value(&binary).unwrap();
    assert_eq!(json["scene_format"], "binary");
    assert_eq!(serde_json::from_value::<JobRequest>(json).unwrap(), binary);
    let e = serde_json::from_str::<JobRequest>(
        &old.replace("}, \"max", "}, \"scene_format\": \"obj\", \"max"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.starts_with("unknown variant `obj`, expected `files` or `binary`"),
        "{e}"
    );
}

#[test]
fn bad_requests_are_bad_input_with_clear_causes() {
    let store = MemoryStore::new();
    let tmp = std::env::temp_dir();
    let e = handle_plan(&store, "b", &plan_event("nojob"), Tmp::unlimited(&tmp)).unwrap_err();
    assert_eq!(
        e,
        HandlerError::bad_input("job request jobs/nojob/manifest.json does not exist")
    );
    let e = handle_plan(&store, "other", &plan_event("nojob"), Tmp::unlimited(&tmp)).unwrap_err();
    assert_eq!(
        e,
        HandlerError::bad_input("the event names bucket \"b\", this function serves \"other\"")
    );
    let env = FunctionEnv {
        store: &store,
        bucket: "b",
        tmp: Tmp::unlimited(&tmp),
        split_cache: &SplitCache::new(0),
        worker_memory_mb: None,
    };
    let bad_id = serde_json::json!({"job": "Bad Id", "bucket": "b"});
    let e = dispatch(Function::Plan, bad_id, &env).unwrap_err();
    assert_eq!(
        e,
        HandlerError::bad_input(
            "malformed Plan event: invalid job id \"Bad Id\": character 'B' is not one of a-z, \
             0-9, '-'"
        )
    );

    let store = submitted("j2");
    let json = serde_json::to_vec(&request("../escape.json")).unwrap();
    store.put("jobs/j2/manifest.json", &json).unwrap();
    let e = handle_plan(&store, "b", &plan_event("j2"), Tmp::unlimited(&tmp)).unwrap_err();
    assert_eq!(
        e,
        HandlerError::bad_input("job request names an unsafe scene path \"../escape.json\"")
    );

    let env = FunctionEnv {
        store: &store,
        bucket: "b",
        tmp: Tmp::unlimited(&tmp),
        split_cache: &SplitCache::new(0),
        worker_memory_mb: None,
    };
    let shine = serde_json::json!({"job": "j2", "bucket": "b", "stage": "shine",
        "item": {"task": 0}});
    let e = dispatch(Function::Worker, shine, &env).unwrap_err();
    assert_eq!(e.error_type, ErrorType::BadInput);
    assert!(
        e.cause
            .starts_with("malformed Worker event: unknown variant `shine`"),
        "{}",
        e.cause
    );
    let negative = serde_json::json!({"job": "j2", "bucket": "b", "stage": "expand",
        "item": {"task": -1}});
    let e = dispatch(Function::Worker, negative, &env).unwrap_err();
    assert!(
        e.cause
            .starts_with("malformed Worker event: invalid value: integer `-1`"),
        "{}",
        e.cause
    );
    assert_eq!(
        Function::from_state_machine_name("WorkerFunctionArn"),
        Some(Function::Worker)
    );
    assert_eq!(
        Function::from_state_machine_name("PlanFunctionArn"),
        Some(Function::Plan)
    );
    assert_eq!(Function::from_state_machine_name("Other"), None);
}

#[test]
fn a_missing_plan_is_rebuilt_and_a_missing_request_or_bad_scene_is_not_retried() {
    let store = submitted("j3");
    let worker = WorkerEvent {
        job: JobId::new("j3").unwrap(),
        bucket: "b".into(),
        stage: Stage::CastMap,
        item: TaskItem {
            task: TaskId(0),
            timeout_seconds: None,
            frame: None,
        },
        attempt: 0,
    };
    // A missing plan is rebuilt from the scene (the plan step again), with its split objects.
    let done = handle_worker(
        &store,
        "b",
        &SplitCache::new(0),
        &worker,
        Tmp::unlimited(&std::env::temp_dir()),
    )
    .unwrap();
    assert_eq!(done.recomputed, 1);
    let rebuilt = store.get("jobs/j3/plan.json").unwrap();
    let planned = submitted("j3");
    handle_plan(
        &planned,
        "b",
        &plan_event("j3"),
        Tmp::unlimited(&std::env::temp_dir()),
    )
    .unwrap();
    assert_eq!(rebuilt, planned.get("jobs/j3/plan.json").unwrap());
    // Without the job request it cannot be: S3 is strongly consistent, so an object that is
    // not there now will not appear on a retry.
    store.delete("jobs/j3/plan.json").unwrap();
    store.delete("jobs/j3/manifest.json").unwrap();
    let e = handle_worker(
        &store,
        "b",
        &SplitCache::new(0),
        &worker,
        Tmp::unlimited(&std::env::temp_dir()),
    )
    .unwrap_err();
    assert_eq!(
        e,
        HandlerError::bad_input("job request jobs/j3/manifest.json does not exist")
    );

    let manifest = planned.get("jobs/j3/manifest.json").unwrap();
    store.put("jobs/j3/manifest.json", &manifest).unwrap();
    store
        .put("jobs/j3/scene/cornell.obj", b"v 0 0 0\nf 1 2 3\n")
        .unwrap();
    let e = handle_plan(
        &store,
        "b",
        &plan_event("j3"),
        Tmp::unlimited(&std::env::temp_dir()),
    )
    .unwrap_err();
    assert_eq!(e.error_type, ErrorType::BadInput);
    assert!(
        e.cause.contains("cornell.obj:2: face refers to vertex 2"),
        "{}",
        e.cause
    );
}

/// A warm worker reads `plan.json` once per job: its later tasks run from the cached plan even
/// when the stored one is gone (and do not rebuild it), while a cold worker rebuilds it.
#[test]
fn a_warm_worker_reads_the_plan_once_per_job() {
    let store = submitted("jw");
    let tmp = std::env::temp_dir();
    handle_plan(&store, "b", &plan_event("jw"), Tmp::unlimited(&tmp)).unwrap();
    let cast = |task: u32| cast_map_event("jw", task);
    let warm = SplitCache::new(1 << 24);
    let first = handle_worker(&store, "b", &warm, &cast(0), Tmp::unlimited(&tmp)).unwrap();
    assert_eq!(first.recomputed, 0);
    assert!(first.storage_us > 0 || first.bytes_read > 0);
    let plan = store.get("jobs/jw/plan.json").unwrap();
    store.delete("jobs/jw/plan.json").unwrap();
    let second = handle_worker(&store, "b", &warm, &cast(1), Tmp::unlimited(&tmp)).unwrap();
    assert_eq!(second.recomputed, 0, "the cached plan served the task");
    assert!(
        store.get("jobs/jw/plan.json").is_err(),
        "a warm worker does not rewrite the plan"
    );
    let cold = handle_worker(
        &store,
        "b",
        &SplitCache::new(0),
        &cast(1),
        Tmp::unlimited(&tmp),
    )
    .unwrap();
    assert_eq!(cold.recomputed, 1, "a cold worker rebuilds the lost plan");
    assert_eq!(store.get("jobs/jw/plan.json").unwrap(), plan);
}

#[test]
fn a_measured_peak_goes_into_the_metrics_and_the_answer_of_a_task_only() {
    let metrics = hort_core::pipeline::TaskMetrics {
        bytes_read: 5,
        ..Default::default()
    };
    let mut invoked = Invoked {
        output: serde_json::to_value(metrics).unwrap(),
        task: Some(TaskDone {
            stage: Stage::CastMap,
            task: TaskId(3),
            metrics,
            frame: None,
        }),
    };
    invoked.set_peak_memory(123_456);
    let done = invoked.task.unwrap();
    assert_eq!(done.metrics.peak_memory_bytes, 123_456);
    assert_eq!(
        serde_json::from_value::<hort_core::pipeline::TaskMetrics>(invoked.output).unwrap(),
        done.metrics,
        "the answer carries the same metrics"
    );
    let plan_answer = serde_json::json!({"plan": "p"});
    let mut plan = Invoked {
        output: plan_answer.clone(),
        task: None,
    };
    plan.set_peak_memory(1);
    assert_eq!(plan.output, plan_answer, "no task, nothing recorded");
    let mut measured_plan = Invoked {
        output: plan_answer.clone(),
        task: Some(TaskDone {
            stage: Stage::Plan,
            task: TaskId(0),
            metrics,
            frame: None,
        }),
    };
    measured_plan.set_peak_memory(1);
    assert_eq!(
        measured_plan.output, plan_answer,
        "the Plan function's answer is the plan output, left as it is"
    );
    assert_eq!(measured_plan.task.unwrap().metrics, metrics);
}

/// Runs every item of the items file `key` of `stage` through the Worker.
fn run_items(store: &MemoryStore, job: &JobId, stage: Stage, key: &str, cache: &SplitCache) {
    let items: Vec<TaskItem> = serde_json::from_slice(&store.get(key).unwrap()).unwrap();
    for item in items {
        let event = WorkerEvent {
            job: job.clone(),
            bucket: "b".into(),
            stage,
            item,
            attempt: 0,
        };
        handle_worker(
            store,
            "b",
            cache,
            &event,
            Tmp::unlimited(&std::env::temp_dir()),
        )
        .unwrap();
    }
}

/// A job runs its Map stages and Combine as the state machine would after a plan answered
/// `out`; returns the hit buffer.
fn run_job_from(store: &MemoryStore, job: &JobId, out: &PlanOutput) -> Vec<u8> {
    let cache = SplitCache::new(0);
    for &stage in out.task_stages() {
        match out.items_key(stage) {
            Some(key) => run_items(store, job, stage, key, &cache),
            None => {
                let combine = WorkerEvent {
                    job: job.clone(),
                    bucket: "b".into(),
                    stage,
                    item: TaskItem {
                        task: TaskId(0),
                        timeout_seconds: None,
                        frame: None,
                    },
                    attempt: 0,
                };
                handle_worker(
                    store,
                    "b",
                    &cache,
                    &combine,
                    Tmp::unlimited(&std::env::temp_dir()),
                )
                .unwrap();
            }
        }
    }
    store.get(&hits_key(job)).unwrap()
}

#[test]
fn a_scene_split_by_tasks_plans_in_steps_and_rebuilds_what_is_lost_from_its_parts() {
    let whole = submitted("whole");
    let job = JobId::new("whole").unwrap();
    let tmp = std::env::temp_dir();
    let out = handle_plan(&whole, "b", &plan_event("whole"), Tmp::unlimited(&tmp)).unwrap();
    let expected = run_job_from(&whole, &job, &out);

    let store = submitted("parts");
    let job = JobId::new("parts").unwrap();
    let mut req = request("cornell.json");
    req.scene_range_bytes = Some(400);
    store
        .put(&manifest_key(&job), &serde_json::to_vec(&req).unwrap())
        .unwrap();
    let step = |step: PlanStep| {
        let event = PlanEvent {
            step,
            ..plan_event("parts")
        };
        handle_plan(&store, "b", &event, Tmp::unlimited(&tmp)).unwrap()
    };
    let cache = SplitCache::new(0);
    let scanned = step(PlanStep::Start);
    assert_eq!(scanned.items.keys().collect::<Vec<_>>(), ["partition"]);
    let key = scanned.items_key(Stage::Partition).unwrap();
    run_items(&store, &job, Stage::Partition, key, &cache);
    let cut = step(PlanStep::Cut);
    assert_eq!(cut.items.keys().collect::<Vec<_>>(), ["build"]);
    run_items(
        &store,
        &job,
        Stage::Build,
        cut.items_key(Stage::Build).unwrap(),
        &cache,
    );
    let planned = step(PlanStep::Finish);
    let renamed = serde_json::to_string(&planned)
        .unwrap()
        .replace("/parts/", "/whole/");
    assert_eq!(
        renamed,
        serde_json::to_string(&out).unwrap(),
        "the same answer as a whole-scene plan"
    );
    assert_eq!(run_job_from(&store, &job, &planned), expected);
    // A lost plan and a lost split object are rebuilt from the parts, not the scene: the
    // scene's mesh and material files are gone too (the manifest stays).
    for key in store.list(&scene_prefix(&job)).unwrap() {
        if !key.ends_with(".json") {
            store.delete(&key).unwrap();
        }
    }
    store.delete(&hort_core::keys::plan_key(&job)).unwrap();
    store
        .delete(&hort_core::keys::split_key(
            &job,
            hort_core::ids::SplitId(1),
        ))
        .unwrap();
    let cast = handle_worker(
        &store,
        "b",
        &cache,
        &cast_map_event("parts", 1),
        Tmp::unlimited(&tmp),
    )
    .unwrap();
    assert!(cast.recomputed >= 1, "{cast:?}");
    assert_eq!(run_job_from(&store, &job, &planned), expected);
    // Steps out of place are refused, naming what is missing.
    let early = PlanEvent {
        step: PlanStep::Cut,
        ..plan_event("j1")
    };
    let submitted_only = submitted("j1");
    let err = handle_plan(&submitted_only, "b", &early, Tmp::unlimited(&tmp)).unwrap_err();
    assert_eq!(err.error_type, ErrorType::BadInput, "{err}");
    assert!(err.cause.contains("jobs/j1/parts/table.json"), "{err}");
    let late = PlanEvent {
        round: 2,
        step: PlanStep::Finish,
        ..plan_event("j1")
    };
    assert_eq!(
        handle_plan(&submitted_only, "b", &late, Tmp::unlimited(&tmp))
            .unwrap_err()
            .cause,
        "plan event round 2 with step Finish: only round 1 has steps"
    );
}

/// The Plan function never plans tasks for more memory than the deployed Worker has: a request
/// asking for more is refused before any work, naming both; one within it is planned.
#[test]
fn a_job_planned_for_more_memory_than_the_worker_has_is_refused_naming_both() {
    let store = submitted("j1");
    let tmp = std::env::temp_dir();
    let cache = SplitCache::new(0);
    let env = |worker_memory_mb| FunctionEnv {
        store: &store,
        bucket: "b",
        tmp: Tmp::unlimited(&tmp),
        split_cache: &cache,
        worker_memory_mb,
    };
    let event = serde_json::json!({"job": "j1", "bucket": "b"});
    let e = dispatch(Function::Plan, event.clone(), &env(Some(1024))).unwrap_err();
    assert_eq!(
        e,
        HandlerError::bad_input(
            "job request jobs/j1/manifest.json plans tasks for 2048 MB (render.memory_mb), but \
             the Worker function has 1024 MB: plan for 1024 MB or less, or deploy the Worker \
             with more memory (WorkerMemoryMB)"
        )
    );
    assert!(
        store.get("jobs/j1/plan.json").is_err(),
        "nothing was planned"
    );
    dispatch(Function::Plan, event, &env(Some(2048))).unwrap();
    assert!(store.get("jobs/j1/plan.json").is_ok());

    // A Worker with less memory than the plan's (its own AWS_LAMBDA_FUNCTION_MEMORY_SIZE)
    // refuses its task before any work; with enough, the task runs.
    let task = serde_json::json!({"job": "j1", "bucket": "b", "stage": "cast-map",
        "item": {"task": 0}});
    let fresh = SplitCache::new(0);
    let small = FunctionEnv {
        split_cache: &fresh,
        ..env(Some(1024))
    };
    let e = dispatch(Function::Worker, task.clone(), &small).unwrap_err();
    assert_eq!(
        e,
        HandlerError::bad_input(
            "plan jobs/j1/plan.json is for functions of 2048 MB, but this Worker function has \
             1024 MB (AWS_LAMBDA_FUNCTION_MEMORY_SIZE): its tasks would run out of memory; plan \
             for 1024 MB or less, or deploy the Worker with more memory (WorkerMemoryMB)"
        )
    );
    assert!(
        store.list("jobs/j1/cast-map/").unwrap().is_empty(),
        "no work done"
    );
    dispatch(Function::Worker, task, &env(Some(2048))).unwrap();
    assert!(!store.list("jobs/j1/cast-map/").unwrap().is_empty());
}

#[test]
fn a_scene_copy_that_would_not_fit_tmp_is_refused_naming_both_sizes() {
    // The Cornell room's files are about 3 KB: a /tmp of 2 KiB cannot hold them; 1 MiB can.
    let store = submitted("j1");
    let dir = std::env::temp_dir();
    let small = Tmp {
        dir: &dir,
        limit_bytes: Some(2048),
    };
    let e = handle_plan(&store, "b", &plan_event("j1"), small).unwrap_err();
    assert_eq!(e.error_type, ErrorType::BadInput);
    assert!(
        e.cause.starts_with("scene file jobs/j1/scene/cornell.")
            && e.cause.contains(
                " does not fit this function's /tmp of 2048 bytes: the copy would reach "
            )
            && e.cause.ends_with(
                " bytes; raise the function's EphemeralStorage (infra/template.yaml; Lambda \
                 allows up to 10240 MB)"
            ),
        "{}",
        e.cause
    );
    let roomy = Tmp {
        dir: &dir,
        limit_bytes: Some(1 << 20),
    };
    handle_plan(&store, "b", &plan_event("j1"), roomy).unwrap();
}

/// A store holding the bundled Cornell room under `scenes/box/` and a job request naming it by
/// key, with `budget`.
fn submitted_by_key(job: &str, budget: Option<BudgetCheck>) -> MemoryStore {
    let store = MemoryStore::new();
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/cornell");
    for file in ["cornell.json", "cornell.obj", "cornell.mtl"] {
        let bytes = std::fs::read(format!("{dir}/{file}")).unwrap();
        store.put(&format!("scenes/box/{file}"), &bytes).unwrap();
    }
    let request = JobRequest {
        scene_key: Some("scenes/box/cornell.json".into()),
        budget,
        ..request("cornell.json")
    };
    let json = serde_json::to_vec(&request).unwrap();
    store
        .put(&manifest_key(&JobId::new(job).unwrap()), &json)
        .unwrap();
    store
}

#[test]
fn a_scene_by_key_is_copied_into_its_job_and_planned_as_if_uploaded() {
    let tmp = std::env::temp_dir();
    let uploaded = submitted("j1");
    handle_plan(&uploaded, "b", &plan_event("j1"), Tmp::unlimited(&tmp)).unwrap();
    let by_key = submitted_by_key("j1", None);
    handle_plan(&by_key, "b", &plan_event("j1"), Tmp::unlimited(&tmp)).unwrap();
    for key in uploaded.list("jobs/j1/").unwrap() {
        if key != manifest_key(&JobId::new("j1").unwrap()) {
            assert_eq!(by_key.get(&key).ok(), uploaded.get(&key).ok(), "{key}");
        }
    }
    assert_eq!(
        by_key.list("jobs/j1/").unwrap().len(),
        uploaded.list("jobs/j1/").unwrap().len()
    );
}

#[test]
fn a_scene_by_key_is_refused_at_plan_naming_its_key_or_its_budget() {
    let tmp = std::env::temp_dir();
    let store = submitted_by_key("j1", None);
    store
        .put(
            "scenes/box/cornell.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
        )
        .unwrap();
    let e = handle_plan(&store, "b", &plan_event("j1"), Tmp::unlimited(&tmp)).unwrap_err();
    assert_eq!(
        e.cause,
        "scenes/box/cornell.obj:4: face refers to vertex 9, but only 3 vertices are defined so far"
    );
    assert_eq!(e.error_type, ErrorType::BadInput);

    let budget = BudgetCheck {
        max_cost_usd: 1e-9,
        model: hort_core::predict::PredictionModel::reference(4),
    };
    let store = submitted_by_key("j1", Some(budget));
    let e = handle_plan(&store, "b", &plan_event("j1"), Tmp::unlimited(&tmp)).unwrap_err();
    assert!(
        e.cause.starts_with("the predicted cost $")
            && e.cause.contains(" of the scene as loaded (36 triangles, ")
            && e.cause.ends_with(
                " is over the budget max_cost_usd = $0.00000000100: the job was accepted on an \
                 estimate from the scene's file sizes; raise the budget or render fewer pixels \
                 or samples"
            ),
        "{}",
        e.cause
    );
    assert!(
        store.list("jobs/j1/splits/").unwrap().is_empty(),
        "no split is built before the budget holds"
    );
}
