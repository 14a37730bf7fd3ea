//! The plan's choice of fused or staged on a real scene: a budget that holds the scene runs
//! fused with one split; a tiny budget runs staged with the fewest splits whose tasks fit; both
//! give the monolithic image and hit buffer bit for bit.

use hort_core::ids::JobId;
use hort_core::pipeline::{
    ExecutionMode, PipelineOptions, PlanRequest, SpanLoad, SpanMemory, SplitMode, StoredOutputs,
    run_pipeline, task_bytes,
};
use hort_core::render::{RenderSettings, build_scene_bvh, render};
use hort_core::scene::load_scene;
use hort_core::store::MemoryStore;
use hort_tests::{hit_bits, pixel_bits, stored};

/// 120,000 generated triangles: over what one 128 MB task holds (about 104,000 with this
/// image's small spans), far under what a 2048 MB one does.
const TRIANGLES: u64 = 120_000;

/// A 1-spp request with `spans` spans, the split count and mode left to the plan.
fn automatic(width: u32, height: u32, spans: u32, memory_mb: u32) -> PlanRequest {
    PlanRequest {
        width,
        height,
        spp: 1,
        splits: None,
        spans: Some(spans),
        mode: SplitMode::Spatial,
        execution: None,
        memory_mb,
        adaptive: None,
        outputs: StoredOutputs::ALL,
        frame: Default::default(),
    }
}

fn options(job: &str, workers: usize) -> PipelineOptions {
    PipelineOptions {
        job: JobId::new(job).unwrap(),
        workers,
        split_cache_bytes: 0,
    }
}

#[test]
fn a_tiny_budget_runs_staged_with_the_fewest_splits_and_a_large_one_fused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("g.obj");
    let mut file = std::fs::File::create(&path).unwrap();
    hort_core::generate::generate_scene(TRIANGLES, 3, &mut file).unwrap();
    drop(file);
    let scene = load_scene(&path).unwrap();
    drop(dir);
    let (width, height) = (64, 48);
    let mono = render(
        &scene,
        &build_scene_bvh(&scene.mesh),
        RenderSettings {
            width,
            height,
            spp: 1,
            threads: 2,
            frame: Default::default(),
        },
    )
    .unwrap();
    for (memory_mb, mode, splits) in [
        (2048, ExecutionMode::Fused, 1),
        (128, ExecutionMode::Staged, 2),
    ] {
        let request = automatic(width, height, 4, memory_mb);
        let options = options("choice", 2);
        let run = run_pipeline(&MemoryStore::new(), &scene, request, &options).unwrap();
        let what = format!("{memory_mb} MB: {}", run.plan.mode_reason);
        assert_eq!((run.plan.mode, run.plan.k()), (mode, splits), "{what}");
        assert_eq!(run.plan.memory_mb, memory_mb);
        // The fewest: one split fewer would not fit.
        let span_pixels = u64::from(width * height).div_ceil(4);
        let budget = u64::from(memory_mb) << 20;
        let held = |k: u64| TRIANGLES.div_ceil(k);
        let load = SpanLoad {
            pixels: span_pixels,
            spp: 1,
            adaptive: false,
        };
        let bytes = |mode, k: u64| {
            let memory = SpanMemory::of(mode, k as u32, load);
            task_bytes(memory, held(k), load)
        };
        assert!(bytes(mode, u64::from(splits)) <= budget, "{what}");
        if splits > 1 {
            assert!(bytes(mode, u64::from(splits) - 1) > budget, "{what}");
            // Not fused: the whole scene in one task would not fit either.
            assert!(bytes(ExecutionMode::Fused, 1) > budget, "{what}");
        }
        assert_eq!(
            pixel_bits(&stored(&run.image).pixels),
            pixel_bits(&mono.image.pixels),
            "{what}"
        );
        assert_eq!(
            hit_bits(stored(&run.hits).as_slice()),
            hit_bits(&mono.hits),
            "{what}"
        );
    }
}

/// Textures are held by every task that shades: a texture that leaves no room in a function's
/// budget is refused before anything is stored, naming it; a budget that holds it counts it.
#[test]
fn a_texture_too_large_for_the_budget_is_refused_before_any_work_naming_it() {
    let mut scene = load_scene(&hort_tests::scene_path("globe/globe.json")).unwrap();
    // A 4096 x 4096 texture is 48 MB decoded: over what 128 MB leaves beside the runtime.
    let big = std::sync::Arc::new(hort_core::texture::Texture::new(
        "huge.png".into(),
        4096,
        4096,
        vec![128; 3 * 4096 * 4096],
    ));
    scene.mesh.textures[0] = big;
    let request = |memory_mb| automatic(32, 24, 2, memory_mb);
    let options = options("tex", 1);
    let store = MemoryStore::new();
    let err = run_pipeline(&store, &scene, request(128), &options).unwrap_err();
    assert_eq!(
        err.to_string(),
        "texture huge.png (4096x4096 texels, 48 MB decoded) does not fit --memory-mb 128 beside \
         the 96 MB every task needs (the scene's 2 textures hold 49 MB): raise --memory-mb or \
         use a smaller texture"
    );
    assert!(
        store.is_empty(),
        "nothing is stored ({} objects)",
        store.len()
    );
    let run = run_pipeline(&store, &scene, request(256), &options).unwrap();
    assert_eq!(run.plan.textures[0].name, "huge.png");
    assert_eq!(run.plan.mode, ExecutionMode::Fused);
}
