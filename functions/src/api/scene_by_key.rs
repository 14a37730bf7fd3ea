//! A scene given by key (`{"scene": {"key": "scenes/box/cornell.json"}}`), sized but never
//! loaded: the API function has 29 s and little memory, and a scene by key may be gigabytes.
//! It reads the main file's size, a manifest's JSON (at most
//! [`MAX_MANIFEST_BYTES`](crate::handlers::MAX_MANIFEST_BYTES)), each mesh's size and a few
//! samples of its text ([`hort_core::pipeline::estimate`]), and so predicts the job from an
//! estimated triangle count. The Plan function copies the scene into the job, loads it, plans
//! it exactly and checks the budget again (`handlers/stage_in.rs`, `handlers/budget.rs`).

use std::path::Path;

use glam::DVec3;
use hort_core::pipeline::estimate::{OBJ_SAMPLES, estimate_obj_triangles, obj_sample_ranges};
use hort_core::scene::{Scene, parse_manifest, scene_of_manifest_without_geometry};
use hort_core::store::COPY_MAX_BYTES;
use serde::Serialize;

use super::backend::RenderBackend;
use super::error::ApiError;
use super::scene::{MAX_SCENE_FILES, check_relative};
use crate::handlers::MAX_MANIFEST_BYTES;

/// The box a scene by key is framed in before its geometry is known (the local frame's unit
/// box): the camera and lights of the estimate only, never of the render.
pub const ESTIMATE_BOUNDS: ([f32; 3], [f32; 3]) = ([-0.5; 3], [0.5; 3]);

/// Most sample reads over all of a scene's meshes (each mesh gets at least one): about 4 s of
/// S3 requests one after another at 15 ms each, with the meshes' HEADs.
const SAMPLE_READS: u64 = 256;

/// A scene given by key, as far as the API reads it.
pub struct SizedScene {
    /// The key (`scenes/box/cornell.json`), which names the scene in reports.
    pub key: String,
    /// The scene without geometry: its camera, lights and image settings (a manifest's, or the
    /// defaults around [`ESTIMATE_BOUNDS`]).
    pub scene: Scene,
    /// What the estimate is from.
    pub estimate: SceneEstimate,
}

/// How a scene by key was sized (the dry run's `scene_estimate`).
#[derive(Clone, Debug, Serialize)]
pub struct SceneEstimate {
    /// Bytes of its OBJ files.
    pub obj_bytes: u64,
    /// Triangles estimated from them.
    pub triangles: u64,
    /// Bytes read to estimate them (whole small files, samples of large ones).
    pub sampled_bytes: u64,
    /// What the numbers mean.
    pub note: &'static str,
}

const NOTE: &str = "a scene given by key is not loaded by the API: its triangles are estimated \
                    from its OBJ files' sizes and samples of their text, each split taken as \
                    large as the scene; the Plan function plans the loaded scene exactly and \
                    refuses the job there if its cost is over max_cost_usd";

/// Sizes the scene whose main file is `key` in the bucket: the main file and every mesh must
/// exist, each at most [`COPY_MAX_BYTES`], and a manifest must parse and name at most
/// [`MAX_SCENE_FILES`] meshes, each a relative path beside it.
pub fn size_scene(backend: &dyn RenderBackend, key: &str) -> Result<SizedScene, ApiError> {
    let (folder, main) = match key.rsplit_once('/') {
        Some((folder, main)) => (format!("{folder}/"), main.to_owned()),
        None => (String::new(), key.to_owned()),
    };
    let Some(main_bytes) = backend.object_size(key)? else {
        return Err(ApiError::invalid_field(
            "scene.key",
            format!("scene.key: there is no object {key} in the bucket"),
        ));
    };
    let path = Path::new(key);
    let (manifest, meshes) = if hort_core::scene::is_manifest(path) {
        if main_bytes > MAX_MANIFEST_BYTES {
            return Err(ApiError::invalid_scene(format!(
                "{key}: {main_bytes} bytes, over the {MAX_MANIFEST_BYTES} bytes a manifest may have"
            )));
        }
        let text = backend.read_object(key)?.unwrap_or_default();
        let manifest = parse_manifest(&String::from_utf8_lossy(&text), path)
            .map_err(|e| ApiError::invalid_scene(e.to_string()))?;
        if manifest.meshes.len() > MAX_SCENE_FILES {
            return Err(ApiError::invalid_scene(format!(
                "{key}: the scene has more than {MAX_SCENE_FILES} files"
            )));
        }
        let mut meshes = Vec::new();
        for mesh in &manifest.meshes {
            check_relative(mesh, "mesh")
                .map_err(|m| ApiError::invalid_scene(format!("{key}: {m}")))?;
            let name = match main.rsplit_once('/') {
                Some((dir, _)) => format!("{folder}{dir}/{mesh}"),
                None => format!("{folder}{mesh}"),
            };
            if !meshes.contains(&name) {
                meshes.push(name);
            }
        }
        (Some(manifest), meshes)
    } else {
        (None, vec![key.to_owned()])
    };
    let mut sizes = Vec::with_capacity(meshes.len());
    for mesh in &meshes {
        let size = if mesh == key {
            main_bytes
        } else {
            backend.object_size(mesh)?.ok_or_else(|| {
                ApiError::invalid_scene(format!("{key}: the mesh {mesh} does not exist"))
            })?
        };
        if size > COPY_MAX_BYTES {
            return Err(ApiError::invalid_scene(format!(
                "{mesh}: {size} bytes, over the {COPY_MAX_BYTES} bytes S3 copies in one request; \
                 split the mesh into files of at most 5 GiB and list them in a manifest"
            )));
        }
        sizes.push(size);
    }
    let per_mesh = (SAMPLE_READS / meshes.len().max(1) as u64).clamp(1, OBJ_SAMPLES);
    let (mut triangles, mut sampled_bytes) = (0u64, 0u64);
    for (mesh, &len) in meshes.iter().zip(&sizes) {
        let mut samples = Vec::new();
        for range in obj_sample_ranges(len, per_mesh) {
            let bytes = backend.read_object_range(mesh, range.clone())?;
            sampled_bytes += bytes.len() as u64;
            samples.push((range, bytes));
        }
        triangles = triangles.saturating_add(estimate_obj_triangles(len, &samples));
    }
    if triangles == 0 {
        // Read whole (a larger file is never estimated at 0): as the loader would say.
        return Err(ApiError::invalid_scene(format!(
            "{key}: the scene contains no triangles"
        )));
    }
    let (lo, hi) = ESTIMATE_BOUNDS;
    let bounds = (
        DVec3::from(lo.map(f64::from)),
        DVec3::from(hi.map(f64::from)),
    );
    let scene =
        scene_of_manifest_without_geometry(path, manifest.as_ref(), DVec3::ZERO, bounds, vec![])
            .map_err(|e| ApiError::invalid_scene(e.to_string()))?;
    Ok(SizedScene {
        key: key.to_owned(),
        scene,
        estimate: SceneEstimate {
            obj_bytes: sizes.iter().sum(),
            triangles,
            sampled_bytes,
            note: NOTE,
        },
    })
}
