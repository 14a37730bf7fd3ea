//! Helpers of the stability suite: scene files, renders (monolithic and distributed), and the
//! pixel comparison the transformed-scene figures use.

use hort_core::hits::Hit;
use hort_core::ids::JobId;
use hort_core::image::linear_to_srgb8;
use hort_core::pipeline::{PipelineOptions, PlanRequest, SplitMode, StoredOutputs, run_pipeline};
use hort_core::render::{RenderOutput, RenderSettings, build_scene_bvh, render};
use hort_core::scene::{Scene, load_scene};
use hort_core::store::MemoryStore;
use std::path::{Path, PathBuf};

/// The path of a bundled scene file, e.g. `scene_path("stability/closed_box.obj")`.
pub fn scene_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenes")
        .join(rel)
}

/// Loads a bundled scene, panicking with its path on error.
pub fn bundled(rel: &str) -> Scene {
    load_scene(&scene_path(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// A fresh empty folder under the system temporary folder, removed on drop.
pub struct Scratch(tempfile::TempDir);

impl Scratch {
    /// A new folder whose name starts with the test's.
    pub fn new(name: &str) -> Scratch {
        let dir = tempfile::Builder::new()
            .prefix(&format!("hort-stability-{name}-"))
            .tempdir()
            .expect("scratch folder");
        Scratch(dir)
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        self.0.path()
    }

    /// Writes `text` to `name` in the folder and returns its path.
    pub fn write(&self, name: &str, text: &str) -> PathBuf {
        let path = self.0.path().join(name);
        std::fs::write(&path, text).expect("scratch file");
        path
    }
}

/// The monolithic render of `scene` at `width` x `height`, one sample per pixel.
pub fn monolithic(scene: &Scene, width: u32, height: u32) -> RenderOutput {
    let bvh = build_scene_bvh(&scene.mesh);
    let settings = RenderSettings {
        width,
        height,
        spp: 1,
        threads: 2,
        frame: Default::default(),
    };
    render(scene, &bvh, settings).expect("monolithic render")
}

/// The distributed render (in-process pipeline over memory) of `scene` with `k` splits and
/// `spans` spans in `mode`: its image and hit buffer.
pub fn distributed(
    scene: &Scene,
    width: u32,
    height: u32,
    k: u32,
    spans: u32,
    mode: SplitMode,
) -> (Vec<[f32; 3]>, Vec<Hit>) {
    let store = MemoryStore::new();
    let request = PlanRequest {
        width,
        height,
        spp: 1,
        splits: Some(k),
        spans: Some(spans),
        mode,
        execution: None,
        memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
        adaptive: None,
        outputs: StoredOutputs::ALL,
        frame: Default::default(),
    };
    let options = PipelineOptions {
        job: JobId::new("stability").unwrap(),
        workers: 2,
        split_cache_bytes: 1 << 30,
    };
    let run = run_pipeline(&store, scene, request, &options)
        .unwrap_or_else(|e| panic!("k={k} {mode:?}: {e}"));
    assert_eq!(run.plan.k(), k);
    (
        run.image.expect("the linear image").pixels,
        run.hits.expect("the hit buffer"),
    )
}

/// Every channel of every pixel as its f32 bit pattern.
pub fn pixel_bits(pixels: &[[f32; 3]]) -> Vec<u32> {
    pixels.iter().flatten().map(|v| v.to_bits()).collect()
}

/// Every hit as (triangle, t bit pattern).
pub fn hit_bits(hits: &[Hit]) -> Vec<(u32, u32)> {
    hits.iter().map(|h| (h.triangle, h.t.to_bits())).collect()
}

/// Asserts that the distributed render equals the monolithic one bit for bit for every split
/// count in `1..=max_k`, both split modes (image and hit buffer), and returns the monolithic
/// render.
pub fn assert_every_k_identical(
    what: &str,
    scene: &Scene,
    width: u32,
    height: u32,
    max_k: u32,
) -> RenderOutput {
    let mono = monolithic(scene, width, height);
    let (pixels, hits) = (pixel_bits(&mono.image.pixels), hit_bits(&mono.hits));
    for mode in [SplitMode::Spatial, SplitMode::Naive] {
        for k in 1..=max_k {
            let (p, h) = distributed(scene, width, height, k, 3, mode);
            assert_eq!(
                pixel_bits(&p),
                pixels,
                "{what}: image differs, k={k} {mode:?}"
            );
            assert_eq!(hit_bits(&h), hits, "{what}: hits differ, k={k} {mode:?}");
        }
    }
    mono
}

/// How two renders of the same view differ. A pixel *differs* if its sample-0 hit names another
/// triangle (or hit against miss) or some 8-bit sRGB channel changes by more than one level;
/// a change of exactly one level is what any last-bit change of a value near a rounding step
/// of the 8-bit encoding gives, and is counted apart (`srgb8_one_level`).
#[derive(Debug, Default, PartialEq)]
pub struct Difference {
    /// Pixels whose sample-0 hit names a different triangle.
    pub hits: usize,
    /// Pixels whose 8-bit sRGB colour changes by exactly one level (and whose hit agrees).
    pub srgb8_one_level: usize,
    /// Pixels that differ: another triangle, or a channel more than one level off.
    pub pixels: usize,
    /// Largest |a - b| / max(|a|, |b|) over all channels (0 where both are 0).
    pub max_relative: f32,
    /// Largest difference of an 8-bit sRGB channel, in levels.
    pub max_srgb8: u8,
}

/// Compares two renders of the same size pixel by pixel.
pub fn difference(a: &RenderOutput, b: &RenderOutput) -> Difference {
    let mut d = Difference::default();
    for (i, (pa, pb)) in a.image.pixels.iter().zip(&b.image.pixels).enumerate() {
        let hit = a.hits[i].triangle != b.hits[i].triangle;
        let levels = pa
            .iter()
            .zip(pb)
            .map(|(x, y)| linear_to_srgb8(*x).abs_diff(linear_to_srgb8(*y)))
            .max()
            .unwrap_or(0);
        d.max_srgb8 = d.max_srgb8.max(levels);
        d.hits += usize::from(hit);
        d.srgb8_one_level += usize::from(!hit && levels == 1);
        d.pixels += usize::from(hit || levels > 1);
        for (x, y) in pa.iter().zip(pb) {
            let m = x.abs().max(y.abs());
            if m > 0.0 {
                d.max_relative = d.max_relative.max((x - y).abs() / m);
            }
        }
    }
    d
}

/// Whether some channel of some pixel is NaN or infinite.
pub fn has_non_finite(pixels: &[[f32; 3]]) -> bool {
    pixels.iter().flatten().any(|v| !v.is_finite())
}
