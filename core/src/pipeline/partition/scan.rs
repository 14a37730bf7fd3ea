//! Step 1, the scan: the scene's files cut into ranges, each range's vertices stored.

use super::page::encode_page;
use super::{PipelineError, write_json};
use crate::ids::JobId;
use crate::keys::{parts_table_key, parts_vertices_key};
use crate::pipeline::ScenePartsShape;
use crate::scene::{ObjRange, override_materials, scan_obj, scene_mesh_files};
use crate::store::BlobStore;
use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One OBJ file of a scene split by tasks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartFile {
    /// The file's path relative to the scene's folder, `/`-separated (its key under
    /// `jobs/{job}/scene/`).
    pub path: String,
    /// The diffuse reflectance of each of the file's materials (index 0: the default grey),
    /// after the manifest's overrides.
    pub kd: Vec<[f32; 3]>,
}

/// One byte range of one of the scene's files.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartRange {
    /// Index of the file in [`PartsTable::files`].
    pub file: u32,
    /// Scene-wide id of the range's first triangle.
    pub first_id: u64,
    /// Where the range lies and what its lines need from the lines before.
    #[serde(flatten)]
    pub obj: ObjRange,
}

/// What the scan found: `jobs/{job}/parts/table.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartsTable {
    /// The scene's OBJ files, in scene order.
    pub files: Vec<PartFile>,
    /// Every range of every file, in scene order (range `r` is `ranges[r]`).
    pub ranges: Vec<PartRange>,
    /// The box of every vertex of the scene as written (the spatial key's frame).
    pub vertex_lo: [f64; 3],
    /// See `vertex_lo`.
    pub vertex_hi: [f64; 3],
    /// Triangles in the scene.
    pub triangles: u64,
    /// What a whole-scene load warns of.
    pub warnings: Vec<String>,
}

impl PartsTable {
    /// What the models that count the partition and build tasks need of the scan.
    pub fn shape(&self) -> ScenePartsShape {
        let sum = |f: fn(&PartRange) -> u64| self.ranges.iter().map(f).sum();
        ScenePartsShape {
            ranges: self.ranges.len() as u32,
            scene_bytes: sum(|r| r.obj.end - r.obj.start),
            vertices: sum(|r| r.obj.vertex_count),
            normals: sum(|r| r.obj.normal_count),
        }
    }

    /// The ranges of `file`, as indices into `ranges` (consecutive).
    pub(super) fn ranges_of(&self, file: u32) -> std::ops::Range<usize> {
        let start = self.ranges.partition_point(|r| r.file < file);
        let end = self.ranges.partition_point(|r| r.file <= file);
        start..end
    }
}

/// Scans the scene whose main file (OBJ or manifest) is `main`, inside the folder `dir` that
/// holds all its files, in ranges of about `range_bytes` bytes: stores each range's vertices
/// at `parts/vertices-{range}` as it closes, then the table at `parts/table.json`. A scene a
/// whole-scene load refuses is refused with the same error.
pub fn scan_scene(
    store: &dyn BlobStore,
    job: &JobId,
    dir: &Path,
    main: &Path,
    range_bytes: u64,
) -> Result<PartsTable, PipelineError> {
    let table = scan_table(dir, main, range_bytes, |range, positions, normals| {
        let key = parts_vertices_key(job, range);
        store.put(&key, &encode_page(positions, normals))?;
        Ok(())
    })?;
    write_json(store, &parts_table_key(job), &table)?;
    Ok(table)
}

/// The scan of [`scan_scene`] without storing anything: `on_page` gets each range's index and
/// the vertex positions and normals it defines as the range closes (and may drop them).
pub fn scan_table(
    dir: &Path,
    main: &Path,
    range_bytes: u64,
    mut on_page: impl FnMut(u32, &[DVec3], &[Vec3]) -> Result<(), PipelineError>,
) -> Result<PartsTable, PipelineError> {
    let mut warnings = Vec::new();
    let mut files = Vec::new();
    let mut ranges: Vec<PartRange> = Vec::new();
    let mut materials = Vec::new();
    let mut bounds: Option<([f64; 3], [f64; 3])> = None;
    let mut triangles = 0u64;
    for path in scene_mesh_files(main)? {
        let rel = path.strip_prefix(dir).map_err(|_| {
            PipelineError::BadInput(format!(
                "mesh {} lies outside the scene's folder {}",
                path.display(),
                dir.display()
            ))
        })?;
        let rel = rel
            .components()
            .map(|c| c.as_os_str().to_string_lossy())
            .collect::<Vec<_>>()
            .join("/");
        let file = files.len() as u32;
        let scan = scan_obj(
            &path,
            range_bytes,
            &mut warnings,
            |range, positions, normals| {
                on_page(ranges.len() as u32, positions, normals)?;
                ranges.push(PartRange {
                    file,
                    first_id: triangles,
                    obj: range.clone(),
                });
                triangles += range.triangle_count;
                Ok::<(), PipelineError>(())
            },
        )?;
        if let Some((lo, hi)) = scan.vertex_bounds {
            let (l, h) = bounds.get_or_insert((lo.to_array(), hi.to_array()));
            *l = glam::DVec3::from(*l).min(lo).to_array();
            *h = glam::DVec3::from(*h).max(hi).to_array();
        }
        materials.push(scan.materials);
        files.push(PartFile {
            path: rel,
            kd: Vec::new(),
        });
    }
    if triangles > u64::from(u32::MAX) {
        return Err(PipelineError::BadInput(format!(
            "the scene has {triangles} triangles; at most {} are supported",
            u32::MAX
        )));
    }
    let counts: Vec<usize> = materials.iter().map(Vec::len).collect();
    let mut all = materials.concat();
    override_materials(main, &mut all)?;
    let mut rest = all.as_slice();
    for (file, count) in files.iter_mut().zip(counts) {
        let (mine, after) = rest.split_at(count);
        file.kd = mine.iter().map(|m| m.kd).collect();
        rest = after;
    }
    // Two meshes may share a material library: say each thing once (as a whole-scene load).
    let mut seen = std::collections::HashSet::new();
    warnings.retain(|w| seen.insert(w.clone()));
    // Files are named as the user named them, relative to the scene's folder.
    let folder = format!("{}/", dir.display());
    let warnings = warnings.iter().map(|w| w.replace(&folder, "")).collect();
    let (vertex_lo, vertex_hi) = bounds.unwrap_or_default();
    Ok(PartsTable {
        files,
        ranges,
        vertex_lo,
        vertex_hi,
        triangles,
        warnings,
    })
}
