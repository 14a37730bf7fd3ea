//! The adaptive sampler through the pipeline: fused jobs (both passes in each Render task) and
//! staged jobs (a second round of the staged stages for the pixels that need it, only if any)
//! equal the monolithic adaptive render bit for bit (image, hit buffer, rays, decisions) for
//! every split, span and worker count. A job that stores no hit buffer (uniform or adaptive)
//! stores the same image from pixel blocks without hits.

use hort_core::adaptive::{AdaptiveSettings, render_adaptive};
use hort_core::ids::JobId;
use hort_core::pipeline::{
    ExecutionMode, PipelineOptions, PlanRequest, SplitMode, StoredOutputs, run_pipeline,
};
use hort_core::render::{RenderSettings, build_scene_bvh};
use hort_core::scene::load_scene;
use hort_core::store::MemoryStore;
use hort_tests::{hit_bits, pixel_bits, scene_path, stored};

const W: u32 = 64;
const H: u32 = 48;

fn request(
    adaptive: AdaptiveSettings,
    splits: u32,
    spans: u32,
    execution: Option<ExecutionMode>,
) -> PlanRequest {
    PlanRequest {
        width: W,
        height: H,
        spp: adaptive.base_spp,
        splits: Some(splits),
        spans: Some(spans),
        mode: SplitMode::Spatial,
        execution,
        memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
        adaptive: Some(adaptive),
        outputs: StoredOutputs::ALL,
        frame: Default::default(),
    }
}

#[test]
fn adaptive_jobs_equal_the_monolithic_adaptive_render() {
    // Powers of 4, and counts that are not (any base and maximum are allowed).
    for (rel, base_spp, max_spp) in [
        ("teapot/teapot.json", 4, 16),
        ("cornell/cornell.json", 3, 12),
        ("globe/globe.json", 2, 8),
    ] {
        let scene = load_scene(&scene_path(rel)).expect("bundled scene");
        let bvh = build_scene_bvh(&scene.mesh);
        let adaptive = AdaptiveSettings {
            base_spp,
            max_spp,
            threshold: 0.01,
        };
        let settings = RenderSettings {
            width: W,
            height: H,
            spp: base_spp,
            threads: 2,
            frame: Default::default(),
        };
        let (mono, counts) = render_adaptive(&scene, &bvh, settings, adaptive).unwrap();
        assert!(
            counts.refined_pixels > 0 && counts.converged_pixels > 0,
            "{rel}: {counts:?}"
        );
        let cases = [
            (ExecutionMode::Fused, 1u32, 1u32, 1usize),
            (ExecutionMode::Fused, 1, 7, 3),
            (ExecutionMode::Fused, 3, 5, 2),
            (ExecutionMode::Staged, 1, 3, 2),
            (ExecutionMode::Staged, 2, 1, 1),
            (ExecutionMode::Staged, 3, 7, 3),
        ];
        for (mode, k, s, workers) in cases {
            let what = format!("{rel} {base_spp}/{max_spp} {mode} k={k} s={s} workers={workers}");
            let options = PipelineOptions {
                job: JobId::new("adaptive").unwrap(),
                workers,
                split_cache_bytes: 1 << 30,
            };
            let run = run_pipeline(
                &MemoryStore::new(),
                &scene,
                request(adaptive, k, s, Some(mode)),
                &options,
            )
            .unwrap_or_else(|e| panic!("{what}: {e}"));
            assert_eq!(run.plan.mode, mode, "{what}");
            assert_eq!(
                pixel_bits(&stored(&run.image).pixels),
                pixel_bits(&mono.image.pixels),
                "image differs: {what}"
            );
            assert_eq!(
                hit_bits(stored(&run.hits).as_slice()),
                hit_bits(&mono.hits),
                "{what}"
            );
            assert_eq!(run.primary_rays, mono.rays.primary, "{what}");
            assert_eq!(run.shadow_rays, mono.rays.shadow, "{what}");
            let mut summed = hort_core::adaptive::AdaptiveCounts::default();
            for m in &run.metrics {
                summed += m.adaptive;
            }
            assert_eq!(summed, counts, "{what}");
            if mode == ExecutionMode::Staged {
                // Round 2 ran for the spans with refined pixels: the refine row, and more
                // cast-map tasks than round 1's pairs.
                let names: Vec<&str> = run.stages.iter().map(|s| s.name.as_str()).collect();
                assert_eq!(
                    names,
                    [
                        "plan",
                        "cast-map",
                        "cast-reduce",
                        "expand",
                        "trace-map",
                        "trace-reduce",
                        "refine",
                        "combine"
                    ],
                    "{what}"
                );
                assert!(
                    run.stages[1].tasks > run.plan.cast_tasks.len() as u64,
                    "{what}"
                );
            }
        }
    }
}

/// A staged adaptive job whose first pass leaves nothing to refine (a threshold no pixel
/// exceeds) runs no second round, and equals the monolithic render.
#[test]
fn a_staged_adaptive_job_with_nothing_to_refine_runs_one_round() {
    let scene = load_scene(&scene_path("teapot/teapot.json")).expect("bundled scene");
    let bvh = build_scene_bvh(&scene.mesh);
    let adaptive = AdaptiveSettings {
        base_spp: 4,
        max_spp: 16,
        threshold: 1e6,
    };
    let settings = RenderSettings {
        width: W,
        height: H,
        spp: 4,
        threads: 2,
        frame: Default::default(),
    };
    let (mono, counts) = render_adaptive(&scene, &bvh, settings, adaptive).unwrap();
    assert_eq!(counts.refined_pixels, 0);
    let options = PipelineOptions {
        job: JobId::new("adaptive").unwrap(),
        workers: 2,
        split_cache_bytes: 0,
    };
    let run = run_pipeline(
        &MemoryStore::new(),
        &scene,
        request(adaptive, 2, 3, Some(ExecutionMode::Staged)),
        &options,
    )
    .unwrap();
    assert_eq!(
        pixel_bits(&stored(&run.image).pixels),
        pixel_bits(&mono.image.pixels)
    );
    let tasks: Vec<u64> = run.stages.iter().map(|s| s.tasks).collect();
    let p = &run.plan;
    assert_eq!(
        tasks,
        [
            1,
            p.cast_tasks.len() as u64,
            3,
            3,
            p.trace_tasks.len() as u64,
            3,
            1,
            1
        ]
    );
}

#[test]
fn a_base_spp_other_than_spp_is_refused() {
    let scene = load_scene(&scene_path("cornell/cornell.json")).expect("bundled scene");
    let adaptive = AdaptiveSettings {
        base_spp: 4,
        max_spp: 16,
        threshold: 0.01,
    };
    let options = PipelineOptions {
        job: JobId::new("adaptive").unwrap(),
        workers: 1,
        split_cache_bytes: 0,
    };
    let mut bad = request(adaptive, 1, 1, None);
    bad.spp = 16;
    let Err(e) = run_pipeline(&MemoryStore::new(), &scene, bad, &options) else {
        panic!("a base spp other than spp must be refused");
    };
    let e = e.to_string();
    assert_eq!(
        e,
        "adaptive base spp 4 differs from spp 16: the first pass takes spp samples"
    );
}

/// A job that stores no hit buffer leaves the hits out of its pixel blocks and stores the
/// same image: uniform and adaptive, fused and staged jobs, against the same job storing
/// every output (the linear image bit for bit, the PNG byte for byte), with fewer raw bytes
/// written by the stage that writes the pixel blocks.
#[test]
fn jobs_without_a_hit_buffer_store_the_same_image_in_smaller_blocks() {
    let scene = load_scene(&scene_path("cornell/cornell.json")).expect("bundled scene");
    let adaptive = AdaptiveSettings {
        base_spp: 3,
        max_spp: 12,
        threshold: 0.01,
    };
    for (sampler, mode, k, s) in [
        (None, ExecutionMode::Fused, 1u32, 3u32),
        (None, ExecutionMode::Staged, 2, 2),
        (Some(adaptive), ExecutionMode::Fused, 1, 3),
        (Some(adaptive), ExecutionMode::Staged, 2, 3),
    ] {
        let what = format!("adaptive {} {mode} k={k} s={s}", sampler.is_some());
        let run = |outputs: StoredOutputs| {
            let request = PlanRequest {
                adaptive: sampler,
                outputs,
                ..request(adaptive, k, s, Some(mode))
            };
            let options = PipelineOptions {
                job: JobId::new("no-hits").unwrap(),
                workers: 2,
                split_cache_bytes: 1 << 30,
            };
            run_pipeline(&MemoryStore::new(), &scene, request, &options)
                .unwrap_or_else(|e| panic!("{what}: {e}"))
        };
        let all = run(StoredOutputs::ALL);
        let bare = run(StoredOutputs {
            linear: true,
            hits: false,
        });
        assert!(bare.hits.is_none(), "{what}");
        assert_eq!(
            pixel_bits(&stored(&bare.image).pixels),
            pixel_bits(&stored(&all.image).pixels),
            "{what}"
        );
        assert_eq!(bare.png, all.png, "{what}");
        let pixel_stage = all.plan.mode.pixel_stage().to_string();
        let raw = |run: &hort_core::pipeline::PipelineRun| {
            let at = run.stages.iter().position(|r| r.name == pixel_stage);
            let at = at.unwrap_or_else(|| panic!("{what}: no stage {pixel_stage}"));
            run.metrics[at].bytes_written_raw
        };
        assert!(
            raw(&bare) < raw(&all),
            "{what}: {} >= {}",
            raw(&bare),
            raw(&all)
        );
    }
}
