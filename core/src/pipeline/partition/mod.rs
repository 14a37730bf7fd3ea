//! Splitting a scene with tasks, so that no task holds the whole scene (a scene larger than
//! one function's memory).
//!
//! 1. **Scan** ([`scan_scene`], the Plan function): reads the scene's OBJ files once, front to
//!    back, checking them as a whole-scene load does, and cuts each into byte ranges of whole
//!    lines. It keeps one range's vertices at a time: each range's vertex positions (double
//!    precision, as written) and normals go to `parts/vertices-{range}`. The table
//!    (`parts/table.json`) records, per range, what its lines need from the lines before
//!    (line, vertex, normal and texture coordinate counts, the current material and what each
//!    `usemtl` selects) and its scene-wide first triangle id: this is how a range's faces, which
//!    index vertices from the start of their file, are read alone.
//! 2. **Partition** ([`partition_range`], one task per range): parses its range's bytes (a
//!    ranged GET), looks up the vertices of earlier ranges in their vertex objects, and writes
//!    its triangles (scene-wide id, corners as written, normals, kd) ordered by spatial bucket
//!    (the top [`BUCKET_BITS`] bits of the Morton code of the centroid in the box of all
//!    vertices), then id, in frames; its index says how many fall in each bucket, where each
//!    frame starts, and the bounds of the vertices its triangles use.
//! 3. **Cut** ([`cut_splits`], the Plan function): from the indexes alone, the local frame's
//!    origin (the centre of the bounds of the vertices triangles use, as a whole-scene load
//!    computes it) and k splits as k equal runs of the scene's triangles in (bucket, id) order:
//!    sizes differ by at most one, and each split is one run of records per range.
//! 4. **Build** ([`build_split_from_parts`], one task per split): reads its runs (ranged GETs of
//!    whole frames), moves the corners into the local frame exactly as a whole-scene load does,
//!    and builds and stores the split object as the in-memory splitter builds it from the same
//!    triangles.
//! 5. **Plan** ([`plan_from_parts`], the Plan function): the scene without its geometry
//!    (camera, lights, colours from the bounds of the split objects) and the job plan.
//!
//! Images are those of a whole-scene load: the same triangles, ids, corners and shading; only
//! which split holds which triangle differs, and the image never depends on that.

mod build;
mod cut;
mod page;
mod range_task;
mod record;
mod scan;
#[cfg(test)]
mod tests;

pub use build::{build_split_from_parts, plan_from_parts, preview_plan_from_table};
pub use cut::{CutSplits, RecordRun, cut_scene, cut_splits};
pub use page::{VertexPage, decode_page};
pub use range_task::{BUCKET_BITS, PartIndex, partition_range};
pub use record::{PartRecord, decode_frame, encode_frames};
pub use scan::{PartFile, PartRange, PartsTable, scan_scene, scan_table};

use super::PipelineError;
use crate::store::BlobStore;

/// Reads and parses the JSON object at `key`, naming it in errors.
fn read_json<T: serde::de::DeserializeOwned>(
    store: &dyn BlobStore,
    key: &str,
) -> Result<T, PipelineError> {
    let bytes = store.get(key)?;
    serde_json::from_slice(&bytes).map_err(|e| PipelineError::Corrupt(format!("{key}: {e}")))
}

/// Stores `value` as JSON at `key`.
fn write_json<T: serde::Serialize>(
    store: &dyn BlobStore,
    key: &str,
    value: &T,
) -> Result<u64, PipelineError> {
    let bytes = serde_json::to_vec(value)
        .map_err(|e| PipelineError::BadInput(format!("cannot encode {key}: {e}")))?;
    store.put(key, &bytes)?;
    Ok(bytes.len() as u64)
}

/// Memory a whole-scene plan step takes per byte of OBJ text (an estimate: the 20M-triangle
/// generated scene, 849 MB of OBJ, peaked at 1,524 MB in the Plan function loaded from its
/// binary form, and parsing from text adds the f64 positions; docs/ARCHITECTURE.md, "Scenes
/// split by tasks"); decides when a scene is split by tasks.
pub const LOAD_BYTES_PER_SCENE_BYTE: u64 = 4;

/// The byte range size to split a scene whose files hold `scene_bytes` bytes by tasks with,
/// for functions of `memory_mb`: `Some` when loading it whole would take more than half the
/// memory (a sixteenth of the memory per range, 1 to 256 MiB: a partition task holds its range's
/// text, records of about five times its size, and vertices of other ranges), else `None`.
pub fn scene_range_bytes(scene_bytes: u64, memory_mb: u32) -> Option<u64> {
    let budget = u64::from(memory_mb) << 20;
    (scene_bytes.saturating_mul(LOAD_BYTES_PER_SCENE_BYTE) > budget / 2)
        .then(|| (budget / 16).clamp(1 << 20, 256 << 20))
}
