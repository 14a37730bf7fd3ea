//! A fused task with the whole scene as its one split renders its span as the monolithic
//! renderer does; these tests hold it to the bits of the stage functions run in turn.

use super::stages::{render_span, render_span_staged};
use super::{
    ExecutionMode, FrameChoice, PlanRequest, SplitMode, SplitObject, StoredOutputs,
    plan_into_store_keeping,
};
use crate::ids::JobId;
use crate::scene::{Light, Scene, load_scene};
use crate::store::MemoryStore;

fn bundled(name: &str) -> Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenes")
        .join(name);
    load_scene(&path).expect("a bundled scene")
}

/// Every span of a fused one-split job of `scene`: the block and shadow-ray count of
/// `render_span` have the bits of the stages run in turn on the same split.
fn check(scene: &Scene, (width, height, spp): (u32, u32, u32)) {
    let request = PlanRequest {
        width,
        height,
        spp,
        splits: Some(1),
        spans: Some(5),
        mode: SplitMode::Spatial,
        execution: Some(ExecutionMode::Fused),
        memory_mb: 2048,
        adaptive: None,
        outputs: StoredOutputs::ALL,
        frame: FrameChoice::STILL,
    };
    let mut kept: Vec<SplitObject> = Vec::new();
    let job = JobId::new("fused").unwrap();
    let store = MemoryStore::new();
    let planned =
        plan_into_store_keeping(&store, &job, scene, &request, |_, split| kept.push(split))
            .expect("plan");
    let plan = &planned.plan;
    assert_eq!((plan.mode, plan.k()), (ExecutionMode::Fused, 1));
    let whole = [&kept[0]];
    let mut hit_samples = 0;
    for span in &plan.spans {
        let (fused, fused_rays) = render_span(plan, span, &whole).unwrap();
        let (staged, staged_rays) = render_span_staged(plan, span, &whole).unwrap();
        let bits =
            |c: &[[f32; 3]]| -> Vec<[u32; 3]> { c.iter().map(|p| p.map(f32::to_bits)).collect() };
        assert_eq!(bits(&fused.colours), bits(&staged.colours), "span {span:?}");
        assert_eq!(fused.triangles, staged.triangles, "span {span:?}");
        let ts = |t: &[f32]| -> Vec<u32> { t.iter().map(|t| t.to_bits()).collect() };
        assert_eq!(ts(&fused.ts), ts(&staged.ts), "span {span:?}");
        assert_eq!(fused.start, span.start);
        assert_eq!(fused_rays, staged_rays, "span {span:?}");
        hit_samples += fused_rays;
    }
    assert!(hit_samples > 0, "the scene should be in the picture");
}

/// The teapot (vertex normals) with three lights, one of them directional: spans that start
/// and end mid-row and mid-band, at 12 spp (several batches of whole pixels per band).
#[test]
fn one_split_fused_spans_equal_the_stages_in_turn_with_several_lights() {
    let mut scene = bundled("teapot/teapot.json");
    let first = scene.lights[0];
    scene.lights.push(Light::Directional {
        direction: glam::DVec3::new(0.3, -1.0, -0.2).normalize(),
        irradiance: [0.4, 0.3, 0.2],
    });
    scene.lights.push(first);
    check(&scene, (37, 11, 12));
}

/// The Cornell box (flat triangles, lights inside the room) at 1 and 5 spp.
#[test]
fn one_split_fused_spans_equal_the_stages_in_turn_on_flat_triangles() {
    let scene = bundled("cornell/cornell.json");
    check(&scene, (29, 13, 1));
    check(&scene, (21, 9, 5));
}
