//! Shared helpers of the end-to-end tests in `tests/tests/it/`: bundled scenes, the monolithic
//! reference render, and bit-exact views of images and hit buffers.

use hort_core::hits::Hit;
use hort_core::render::{RenderOutput, RenderSettings, build_scene_bvh, render};
use hort_core::scene::load_scene;
use std::path::PathBuf;

/// Set (to anything), it makes the integration tests required: a test whose server variable
/// (`HORT_TEST_S3_ENDPOINT`, `HORT_TEST_AWS_ENDPOINT`) is missing fails instead of skipping.
/// `.ci/run` sets it for its moto steps, so a lost variable cannot pass as a skipped test.
pub const REQUIRE_INTEGRATION_VAR: &str = "HORT_TEST_INTEGRATION";

/// The value of the server variable `var` of an integration test, when set and not empty; else
/// `None` after saying the test is skipped (`how` says how to run it), or, when
/// [`REQUIRE_INTEGRATION_VAR`] is set, a panic naming both variables.
pub fn integration_endpoint(var: &str, how: &str) -> Option<String> {
    if let Some(value) = std::env::var(var).ok().filter(|v| !v.is_empty()) {
        return Some(value);
    }
    assert!(
        std::env::var_os(REQUIRE_INTEGRATION_VAR).is_none(),
        "{REQUIRE_INTEGRATION_VAR} is set, so this integration test must run, but {var} is not \
         set ({how})"
    );
    println!("skipped: set {var} ({how})");
    None
}

/// The path of a bundled scene, e.g. `scene_path("bunny/bunny.json")`.
pub fn scene_path(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../scenes")
        .join(rel)
}

/// The monolithic render of a bundled scene: the reference every pipeline run must equal.
pub fn monolithic(rel: &str, width: u32, height: u32, spp: u32) -> RenderOutput {
    let scene = load_scene(&scene_path(rel)).expect("bundled scene");
    let bvh = build_scene_bvh(&scene.mesh);
    let settings = RenderSettings {
        width,
        height,
        spp,
        threads: 2,
        frame: Default::default(),
    };
    render(&scene, &bvh, settings).expect("monolithic render")
}

/// An output a job stored (its request asks for every output, `StoredOutputs::ALL`).
pub fn stored<T>(output: &Option<T>) -> &T {
    output
        .as_ref()
        .expect("the job stores every output its request asks for")
}

/// Every channel of every pixel as its f32 bit pattern.
pub fn pixel_bits(pixels: &[[f32; 3]]) -> Vec<u32> {
    pixels.iter().flatten().map(|v| v.to_bits()).collect()
}

/// Every hit as (triangle, t bit pattern).
pub fn hit_bits(hits: &[Hit]) -> Vec<(u32, u32)> {
    hits.iter().map(|h| (h.triangle, h.t.to_bits())).collect()
}
