//! A scene loaded without holding its geometry: its OBJ files read in ranges (see
//! `obj/stream.rs`), and the scene around them (camera, lights, colours, materials) assembled
//! once the local frame and bounds are known, exactly as [`super::load_scene`] assembles it.

use super::framing::{default_camera, default_light};
use super::manifest::{
    Manifest, apply_material_overrides, image_settings, manifest_scene, read_manifest,
};
use super::mesh::{Material, Mesh};
use super::{ImageSettings, Scene, is_manifest};
use crate::error::SceneError;
use glam::DVec3;
use std::path::{Path, PathBuf};

/// The OBJ files of the scene at `path`, in scene order: the file itself, or the meshes its
/// manifest lists (relative to the manifest's folder).
pub fn scene_mesh_files(path: &Path) -> Result<Vec<PathBuf>, SceneError> {
    if !is_manifest(path) {
        return Ok(vec![path.to_path_buf()]);
    }
    let base = path.parent().unwrap_or(Path::new("."));
    Ok(read_manifest(path)?
        .meshes
        .iter()
        .map(|file| base.join(file))
        .collect())
}

/// Applies the material overrides of the scene at `path` (a manifest's `materials`; nothing for
/// an OBJ file) to `materials`, every file's materials in scene order, with the errors
/// [`super::load_scene`] gives.
pub fn override_materials(path: &Path, materials: &mut Vec<Material>) -> Result<(), SceneError> {
    if !is_manifest(path) {
        return Ok(());
    }
    let manifest = read_manifest(path)?;
    let mut mesh = Mesh {
        materials: std::mem::take(materials),
        ..Mesh::default()
    };
    apply_material_overrides(&mut mesh, &manifest, path)?;
    *materials = mesh.materials;
    Ok(())
}

/// The image settings the scene at `path` fixes (a manifest's; none for an OBJ file), read
/// without its meshes.
pub fn scene_image_settings(path: &Path) -> Result<ImageSettings, SceneError> {
    if !is_manifest(path) {
        return Ok(ImageSettings::default());
    }
    image_settings(&read_manifest(path)?, path)
}

/// The scene at `path` without its triangles (an empty mesh), for a local frame at `origin`
/// whose geometry has bounds `bounds` (min, max; local frame): the camera, lights, colours and
/// image settings [`super::load_scene`] gives the whole scene, and `warnings` with the
/// manifest's own added.
pub fn scene_without_geometry(
    path: &Path,
    origin: DVec3,
    bounds: (DVec3, DVec3),
    warnings: Vec<String>,
) -> Result<Scene, SceneError> {
    let manifest = if is_manifest(path) {
        Some(read_manifest(path)?)
    } else {
        None
    };
    scene_of_manifest_without_geometry(path, manifest.as_ref(), origin, bounds, warnings)
}

/// [`scene_without_geometry`] for a manifest read already (`None`: the scene is the OBJ file
/// at `path`, which is not read): nothing is read from disk, `path` names the scene in
/// messages.
pub fn scene_of_manifest_without_geometry(
    path: &Path,
    manifest: Option<&Manifest>,
    origin: DVec3,
    bounds: (DVec3, DVec3),
    warnings: Vec<String>,
) -> Result<Scene, SceneError> {
    if let Some(manifest) = manifest {
        return manifest_scene(path, manifest, origin, bounds, Mesh::default(), warnings);
    }
    let (lo, hi) = bounds;
    Ok(Scene {
        source: path.to_path_buf(),
        origin,
        camera: default_camera(lo, hi),
        framed_bounds: Some((lo, hi)),
        lights: vec![default_light(lo, hi)],
        mesh: Mesh::default(),
        ambient: [0.0; 3],
        background: [0.0; 3],
        image: ImageSettings::default(),
        warnings,
        animation: None,
    })
}
