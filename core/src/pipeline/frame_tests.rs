//! Frames arrive as they finish: a job of several frames assembles each frame in the task that
//! completes it, with the bytes of that frame rendered alone.

use super::{
    ExecutionMode, FrameChoice, Orbit, PipelineOptions, PlanRequest, SplitMode, StoredOutputs,
    plan_into_store, run_frame_task, run_pipeline,
};
use crate::ids::JobId;
use crate::keys::{FrameKeys, image_key};
use crate::pipeline::split_cache::SplitCache;
use crate::stage::Stage;
use crate::store::{BlobStore, MemoryStore};

const ORBIT: Orbit = Orbit {
    degrees: 90.0,
    frames: 3,
};

fn request(frame: FrameChoice, execution: ExecutionMode, splits: u32) -> PlanRequest {
    PlanRequest {
        width: 16,
        height: 12,
        spp: 2,
        splits: Some(splits),
        spans: Some(3),
        mode: SplitMode::Spatial,
        execution: Some(execution),
        memory_mb: 2048,
        adaptive: None,
        outputs: StoredOutputs::ALL,
        frame,
    }
}

/// Frame `frame`'s PNG in `store`, if stored.
fn png(store: &MemoryStore, job: &JobId, frame: u32) -> Option<Vec<u8>> {
    let key = image_key(
        &FrameKeys {
            job,
            frame: Some(frame),
        },
        "png",
    );
    store.get(&key).ok()
}

/// Running every task of frame 0 of a 3-frame job (fused, and staged over two splits) stores
/// frame 0's PNG, the bytes of frame 0 rendered as a job of its own, before any task of frame
/// 1 runs; the Combine task then assembles only what is left and writes the poster.
#[test]
fn a_frame_is_assembled_by_the_task_that_finishes_it() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/cornell.json");
    let scene = crate::scene::load_scene(&path).expect("the bundled Cornell box");
    for (execution, splits) in [(ExecutionMode::Fused, 1), (ExecutionMode::Staged, 2)] {
        let store = MemoryStore::new();
        let job = JobId::new("frames").unwrap();
        let all = FrameChoice::range(0..3, Some(ORBIT));
        let plan = plan_into_store(&store, &job, &scene, &request(all, execution, splits))
            .unwrap()
            .plan;
        let cache = SplitCache::new(0);
        let run = |frame: u32| {
            for &stage in plan.task_stages() {
                for (f, task) in plan.frame_tasks(stage).unwrap() {
                    if f == Some(frame) {
                        run_frame_task(&store, &job, &plan, f, stage, task, &cache, None).unwrap();
                    }
                }
            }
        };
        run(0);
        let alone = run_pipeline(
            &MemoryStore::new(),
            &scene,
            request(FrameChoice::new(0, Some(ORBIT)), execution, splits),
            &PipelineOptions {
                job: JobId::new("alone").unwrap(),
                workers: 1,
                split_cache_bytes: 0,
            },
        )
        .unwrap();
        assert!(
            png(&store, &job, 0) == Some(alone.png.clone()),
            "{execution}: frame 0"
        );
        assert_eq!(
            png(&store, &job, 1),
            None,
            "{execution}: frame 1 did not run"
        );
        assert!(
            store.get(&image_key(&job, "png")).is_err(),
            "no poster before Combine"
        );
        run(1);
        run(2);
        assert!(png(&store, &job, 2).is_some(), "{execution}: frame 2");
        run_frame_task(&store, &job, &plan, None, Stage::Combine, 0, &cache, None).unwrap();
        assert_eq!(
            store.get(&image_key(&job, "png")).unwrap(),
            alone.png,
            "the poster"
        );
    }
}

/// A task that finishes a frame also holds the frame while it assembles it: a job of several
/// frames whose pixel-stage task and frame together would not fit the function's memory is
/// refused before anything is stored, where the same image as one frame fits.
#[test]
fn a_job_of_frames_is_refused_when_a_task_cannot_also_hold_its_frame() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/cornell.json");
    let scene = crate::scene::load_scene(&path).expect("the bundled Cornell box");
    let wide = |frame: FrameChoice| PlanRequest {
        width: 3840,
        height: 1080,
        spp: 1,
        splits: None,
        spans: None,
        memory_mb: 256,
        outputs: StoredOutputs::PNG,
        ..request(frame, ExecutionMode::Fused, 1)
    };
    let job = JobId::new("wide").unwrap();
    let one = FrameChoice::new(1, Some(ORBIT));
    plan_into_store(&MemoryStore::new(), &job, &scene, &wide(one)).expect("one frame fits");
    let store = MemoryStore::new();
    let all = FrameChoice::range(0..3, Some(ORBIT));
    let error = plan_into_store(&store, &job, &scene, &wide(all)).unwrap_err();
    assert_eq!(
        error.to_string(),
        "a task that finishes a frame also assembles it: rendering and assembling a 3840x1080 \
         frame would need about 282 MB, over --memory-mb 256: raise --memory-mb, store fewer \
         outputs, or render fewer pixels"
    );
    assert!(store.list("").unwrap().is_empty(), "nothing stored");
}
