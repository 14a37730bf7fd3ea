//! The adaptive sampler through the pipeline: fused jobs equal the monolithic adaptive render
//! bit for bit (image, hit buffer, rays, decisions) for every split, span and worker count;
//! staged jobs are refused with one line.

use hort_core::adaptive::{AdaptiveSettings, render_adaptive};
use hort_core::ids::JobId;
use hort_core::pipeline::{ExecutionMode, PipelineOptions, PlanRequest, SplitMode, run_pipeline};
use hort_core::render::{RenderSettings, build_scene_bvh};
use hort_core::scene::load_scene;
use hort_core::store::MemoryStore;
use hort_tests::{hit_bits, pixel_bits, scene_path};

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
    }
}

#[test]
fn fused_adaptive_jobs_equal_the_monolithic_adaptive_render() {
    for rel in ["teapot/teapot.json", "cornell/cornell.json"] {
        let scene = load_scene(&scene_path(rel)).expect("bundled scene");
        let bvh = build_scene_bvh(&scene.mesh);
        let adaptive = AdaptiveSettings {
            base_spp: 4,
            max_spp: 16,
            threshold: 0.01,
        };
        let settings = RenderSettings {
            width: W,
            height: H,
            spp: 4,
            threads: 2,
        };
        let (mono, counts) = render_adaptive(&scene, &bvh, settings, adaptive).unwrap();
        assert!(
            counts.refined_pixels > 0 && counts.converged_pixels > 0,
            "{rel}: {counts:?}"
        );
        for (k, s, workers) in [(1u32, 1u32, 1usize), (1, 7, 3), (3, 5, 2)] {
            let what = format!("{rel} k={k} s={s} workers={workers}");
            let options = PipelineOptions {
                job: JobId::new("adaptive").unwrap(),
                workers,
                split_cache_bytes: 1 << 30,
            };
            let run = run_pipeline(
                &MemoryStore::new(),
                &scene,
                request(adaptive, k, s, Some(ExecutionMode::Fused)),
                &options,
            )
            .unwrap_or_else(|e| panic!("{what}: {e}"));
            assert_eq!(run.plan.mode, ExecutionMode::Fused, "{what}");
            assert_eq!(
                pixel_bits(&run.image.pixels),
                pixel_bits(&mono.image.pixels),
                "image differs: {what}"
            );
            assert_eq!(hit_bits(&run.hits), hit_bits(&mono.hits), "{what}");
            assert_eq!(run.primary_rays, mono.rays.primary, "{what}");
            assert_eq!(run.shadow_rays, mono.rays.shadow, "{what}");
            let mut summed = hort_core::adaptive::AdaptiveCounts::default();
            for m in &run.metrics {
                summed += m.adaptive;
            }
            assert_eq!(summed, counts, "{what}");
        }
    }
}

#[test]
fn staged_adaptive_jobs_are_refused() {
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
    let Err(e) = run_pipeline(
        &MemoryStore::new(),
        &scene,
        request(adaptive, 2, 2, None),
        &options,
    ) else {
        panic!("staged adaptive must be refused");
    };
    let e = e.to_string();
    assert_eq!(
        e,
        "--adaptive runs in fused mode only, and this job would run staged (--splits 2: \
         HORT's staged shuffle over 2 splits); use --splits 1 or --mode fused"
    );
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
