//! The distributed image equals the monolithic one bit for bit, for every split count, span
//! count, split mode, sample count and worker count.

use hort_core::ids::JobId;
use hort_core::pipeline::{
    ExecutionMode, PipelineOptions, PipelineRun, PlanRequest, SplitMode, StoredOutputs,
    run_pipeline,
};
use hort_core::scene::{Scene, load_scene};
use hort_core::stage::Stage;
use hort_core::store::{BlobStore, MemoryStore};
use hort_tests::{hit_bits, pixel_bits, scene_path, stored};

const W: u32 = 64;
const H: u32 = 48;

fn scene(rel: &str) -> Scene {
    load_scene(&scene_path(rel)).expect("bundled scene")
}

/// One distributed run's shape: split mode, split count, forced execution mode (or the
/// automatic choice), span count and worker count.
type Case = (SplitMode, u32, Option<ExecutionMode>, u32, usize);

/// Every split mode, split counts from 1 to 16 with and without a forced mode, and three
/// (spans, workers) shapes.
fn all_cases() -> Vec<Case> {
    let mut cases = Vec::new();
    for mode in [SplitMode::Spatial, SplitMode::Naive] {
        // One split runs fused and more run staged, unless the mode is forced.
        for (k, forced) in [
            (1u32, None),
            (1, Some(ExecutionMode::Staged)),
            (2, None),
            (3, None),
            (3, Some(ExecutionMode::Fused)),
            (7, None),
            (16, None),
        ] {
            for (s, workers) in [(1u32, 1usize), (7, 3), (16, 2)] {
                cases.push((mode, k, forced, s, workers));
            }
        }
    }
    cases
}

/// The request of a W x H job at `spp` with `k` splits and `s` spans, every output stored.
fn request(
    spp: u32,
    k: u32,
    s: u32,
    mode: SplitMode,
    forced: Option<ExecutionMode>,
) -> PlanRequest {
    PlanRequest {
        width: W,
        height: H,
        spp,
        splits: Some(k),
        spans: Some(s),
        mode,
        execution: forced,
        memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
        adaptive: None,
        outputs: StoredOutputs::ALL,
        frame: Default::default(),
    }
}

fn check_scene(rel: &str, spps: &[u32]) {
    check_cases(rel, spps, &all_cases());
}

fn check_cases(rel: &str, spps: &[u32], cases: &[Case]) {
    let scene = scene(rel);
    for &spp in spps {
        let mono = hort_tests::monolithic(rel, W, H, spp);
        let mono_bits = pixel_bits(&mono.image.pixels);
        assert!(
            mono_bits.iter().any(|&b| b != 0),
            "{rel}: the render must not be black"
        );
        for &(mode, k, forced, s, workers) in cases {
            let store = MemoryStore::new();
            let request = request(spp, k, s, mode, forced);
            let options = PipelineOptions {
                job: JobId::new("eq").unwrap(),
                workers,
                // With and without cached splits: the bytes must not change.
                split_cache_bytes: if workers == 3 { 0 } else { 1 << 30 },
            };
            let run = run_pipeline(&store, &scene, request, &options)
                .unwrap_or_else(|e| panic!("{rel} k={k} s={s} {mode:?}: {e}"));
            let execution = run.plan.mode;
            let what =
                format!("{rel} spp={spp} {mode:?} k={k} s={s} workers={workers} {execution}");
            let expected = forced.unwrap_or(if k == 1 {
                ExecutionMode::Fused
            } else {
                ExecutionMode::Staged
            });
            assert_eq!(execution, expected, "{what}");
            assert_eq!(
                pixel_bits(&stored(&run.image).pixels),
                mono_bits,
                "image differs: {what}"
            );
            assert_eq!(
                hit_bits(stored(&run.hits).as_slice()),
                hit_bits(&mono.hits),
                "hits differ: {what}"
            );
            assert_eq!(run.primary_rays, mono.rays.primary, "{what}");
            assert_eq!(run.shadow_rays, mono.rays.shadow, "{what}");
            assert_eq!(run.plan.k(), k);
            assert_eq!(run.plan.spans.len() as u32, s);
        }
    }
}

#[test]
fn bunny_on_ground_matches_monolithic() {
    check_scene("bunny/bunny.json", &[1, 4]);
}

#[test]
fn teapot_on_ground_matches_monolithic() {
    check_scene("teapot/teapot.json", &[1, 4]);
}

#[test]
fn cornell_room_matches_monolithic() {
    check_scene("cornell/cornell.json", &[1, 4]);
}

/// Sample counts that are neither powers of 2 nor squares (3, 12, 96): fused and staged, both
/// split modes, forced modes, several spans and workers.
#[test]
fn counts_that_are_not_powers_of_4_match_monolithic() {
    let cases = [
        (SplitMode::Spatial, 1, None, 7, 3),
        (SplitMode::Spatial, 1, Some(ExecutionMode::Staged), 16, 2),
        (SplitMode::Spatial, 3, None, 7, 3),
        (SplitMode::Naive, 3, Some(ExecutionMode::Fused), 1, 1),
        (SplitMode::Naive, 7, None, 16, 2),
    ];
    check_cases("cornell/cornell.json", &[3, 12, 96], &cases);
}

/// Vertex normals and diffuse textures (sampled where the hit is found, in CastMap or Render):
/// the same bytes in every mode.
#[test]
fn textured_smooth_globe_matches_monolithic() {
    check_scene("globe/globe.json", &[1, 4]);
}

#[test]
fn bare_bunny_matches_monolithic() {
    check_scene("bunny/bunny.obj", &[1]);
}

/// Every object of the store, sorted by key.
fn snapshot(store: &MemoryStore) -> Vec<(String, Vec<u8>)> {
    store
        .list("")
        .unwrap()
        .into_iter()
        .map(|k| {
            let v = store.get(&k).unwrap();
            (k, v)
        })
        .collect()
}

/// Runs the pipeline on a bundled scene into a fresh memory store.
fn run_in_memory(rel: &str, spp: u32, k: u32, s: u32) -> (MemoryStore, PipelineRun, JobId) {
    let store = MemoryStore::new();
    let request = request(spp, k, s, SplitMode::Spatial, None);
    let job = JobId::new("memory").unwrap();
    let options = PipelineOptions {
        job: job.clone(),
        workers: 2,
        split_cache_bytes: 1 << 30,
    };
    let run = run_pipeline(&store, &scene(rel), request, &options).unwrap();
    (store, run, job)
}

#[test]
fn every_task_run_twice_writes_identical_bytes() {
    let (store, run, job) = run_in_memory("cornell/cornell.json", 2, 3, 5);
    let before = snapshot(&store);
    for &stage in hort_core::stage::Stage::TASKS {
        for task in 0..run.plan.task_count(stage) {
            hort_core::pipeline::run_task(&store, &job, &run.plan, stage, task as u32).unwrap();
        }
    }
    assert_eq!(snapshot(&store), before);
    assert!(
        before.len() > 30,
        "the job wrote its blocks ({})",
        before.len()
    );
}

#[test]
fn lost_and_corrupt_blocks_are_recomputed_from_lineage() {
    let (store, run, job) = run_in_memory("bunny/bunny.json", 1, 4, 3);
    let before = snapshot(&store);
    let keys: Vec<String> = before.iter().map(|(k, _)| k.clone()).collect();
    // Corrupt one CastReduce block (flip a byte in its payload) and delete one CastMap block
    // it was made from, and a TraceMap block.
    let reduce = keys
        .iter()
        .find(|k| k.contains("/cast-reduce/00001/"))
        .unwrap();
    let mut bytes = store.get(reduce).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x10;
    store.put(reduce, &bytes).unwrap();
    let map = keys
        .iter()
        .find(|k| k.contains("/cast-map/") && k.ends_with("part-00001"))
        .unwrap();
    store.delete(map).unwrap();
    let trace = keys
        .iter()
        .find(|k| k.contains("/trace-map/") && k.ends_with("part-00002"))
        .unwrap();
    store.delete(trace).unwrap();
    let mut recomputed = 0;
    for span in 0..3 {
        recomputed +=
            hort_core::pipeline::run_task(&store, &job, &run.plan, Stage::TraceReduce, span)
                .unwrap()
                .recomputed;
    }
    recomputed += hort_core::pipeline::run_task(&store, &job, &run.plan, Stage::Combine, 0)
        .unwrap()
        .recomputed;
    // The corrupt reduce block, the lost map block it is made from (found while recomputing
    // it), and the lost trace block.
    assert_eq!(recomputed, 3);
    assert_eq!(
        snapshot(&store),
        before,
        "every block and the outputs are identical again"
    );
}

/// A task that reads textures gets them from their objects, checked against the plan's content
/// key: rerun cold it stores the same bytes; a damaged texture object is an error naming its
/// key, and one whose texels were replaced (a valid block with other contents) is refused too.
#[test]
fn tasks_read_textures_from_their_objects_checked_against_the_plan() {
    let (store, run, job) = run_in_memory("globe/globe.json", 1, 2, 3);
    assert_eq!(run.plan.textures.len(), 2);
    let before = snapshot(&store);
    let texture = before
        .iter()
        .map(|(k, _)| k.clone())
        .find(|k| k.contains("/textures/"))
        .expect("a texture object");
    for span in 0..3 {
        hort_core::pipeline::run_task(&store, &job, &run.plan, Stage::CastMap, span).unwrap();
    }
    assert_eq!(
        snapshot(&store),
        before,
        "a cold rerun stores the same bytes"
    );

    let mut damaged = store.get(&texture).unwrap();
    let mid = damaged.len() / 2;
    damaged[mid] ^= 0x10;
    store.put(&texture, &damaged).unwrap();
    let tasks = 0..run.plan.cast_tasks.len() as u32;
    let errors: Vec<String> = tasks
        .clone()
        .filter_map(|t| {
            hort_core::pipeline::run_task(&store, &job, &run.plan, Stage::CastMap, t).err()
        })
        .map(|e| e.to_string())
        .collect();
    assert!(
        !errors.is_empty(),
        "some cast task reads the damaged texture"
    );
    assert!(errors.iter().all(|e| e.contains(&texture)), "{errors:?}");

    let other = hort_core::texture::Texture::new("other.png".into(), 1, 1, vec![1, 2, 3]);
    store
        .put(&texture, &hort_core::texture::encode_texture(&other))
        .unwrap();
    let err = tasks
        .filter_map(|t| {
            hort_core::pipeline::run_task(&store, &job, &run.plan, Stage::CastMap, t).err()
        })
        .map(|e| e.to_string())
        .next()
        .expect("a replaced texture is refused");
    assert!(
        err.ends_with(&format!(
            "texture object {texture}: its texels do not match its content key (the object is \
             damaged or was replaced)"
        )),
        "{err}"
    );
}
