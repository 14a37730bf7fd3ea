//! The handlers called directly over an in-memory store, as the Lambda runtime would call them.

use super::*;
use hort_core::ids::TaskId;
use hort_core::ids::{JobId, Stage};
use hort_core::keys::{hits_key, items_key, manifest_key, scene_prefix};
use hort_core::pipeline::{PlanRequest, SplitCache, SplitMode};
use hort_core::store::{BlobStore, MemoryStore};

fn request(scene: &str) -> JobRequest {
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
        },
        max_concurrency: 4,
        task_timeout_seconds: None,
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
    }
}

#[test]
fn plan_then_every_worker_task_produces_the_outputs() {
    let store = submitted("j1");
    let out = handle_plan(&store, "b", &plan_event("j1"), &std::env::temp_dir()).unwrap();
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
            handle_worker(&store, "b", &cache, &event, &std::env::temp_dir()).unwrap();
        }
    }
    let combine = WorkerEvent {
        job: job.clone(),
        bucket: "b".into(),
        stage: Stage::Combine,
        item: TaskItem {
            task: TaskId(0),
            timeout_seconds: None,
        },
        attempt: 0,
    };
    handle_worker(&store, "b", &cache, &combine, &std::env::temp_dir()).unwrap();
    assert_eq!(store.get(&hits_key(&job)).unwrap().len(), 32 * 24 * 8);
}

#[test]
fn bad_requests_are_bad_input_with_clear_causes() {
    let store = MemoryStore::new();
    let tmp = std::env::temp_dir();
    let e = handle_plan(&store, "b", &plan_event("nojob"), &tmp).unwrap_err();
    assert_eq!(
        e,
        HandlerError::bad_input("job request jobs/nojob/manifest.json does not exist")
    );
    let e = handle_plan(&store, "other", &plan_event("nojob"), &tmp).unwrap_err();
    assert_eq!(
        e,
        HandlerError::bad_input("the event names bucket \"b\", this function serves \"other\"")
    );
    let env = FunctionEnv {
        store: &store,
        bucket: "b",
        work_dir: &tmp,
        split_cache: &SplitCache::new(0),
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
    let e = handle_plan(&store, "b", &plan_event("j2"), &tmp).unwrap_err();
    assert_eq!(
        e,
        HandlerError::bad_input("job request names an unsafe scene path \"../escape.json\"")
    );

    let env = FunctionEnv {
        store: &store,
        bucket: "b",
        work_dir: &tmp,
        split_cache: &SplitCache::new(0),
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
        },
        attempt: 0,
    };
    // A missing plan is rebuilt from the scene (the plan step again), with its split objects.
    let done = handle_worker(
        &store,
        "b",
        &SplitCache::new(0),
        &worker,
        &std::env::temp_dir(),
    )
    .unwrap();
    assert_eq!(done.recomputed, 1);
    let rebuilt = store.get("jobs/j3/plan.json").unwrap();
    let planned = submitted("j3");
    handle_plan(&planned, "b", &plan_event("j3"), &std::env::temp_dir()).unwrap();
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
        &std::env::temp_dir(),
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
    let e = handle_plan(&store, "b", &plan_event("j3"), &std::env::temp_dir()).unwrap_err();
    assert_eq!(e.error_type, ErrorType::BadInput);
    assert!(
        e.cause.contains("cornell.obj:2: face refers to vertex 2"),
        "{}",
        e.cause
    );
}
