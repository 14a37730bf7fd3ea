//! Step 2, a partition task: one range's triangles, with their vertices looked up, written in
//! spatial-bucket order.

use super::page::{VertexPage, decode_page};
use super::record::{PartRecord, encode_frames};
use super::scan::PartsTable;
use super::{PipelineError, read_json, write_json};
use crate::ids::JobId;
use crate::keys::{
    parts_index_key, parts_records_key, parts_table_key, parts_vertices_key, scene_prefix,
};
use crate::scene::{NO_NORMAL, parse_obj_range};
use crate::store::BlobStore;
use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::Path;

/// Bits of the Morton code that make a spatial bucket: 4096 buckets.
pub const BUCKET_BITS: u32 = 12;

/// Vertex objects of other ranges a partition task keeps decoded at once, in bytes; past it,
/// the cache is emptied (a scene whose faces name vertices far back in the file costs reads,
/// never memory).
const PAGE_CACHE_BYTES: u64 = 256 << 20;

/// `jobs/{job}/parts/index-{range}.json`: what a range's records object holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartIndex {
    /// Records (triangles) in the object.
    pub records: u64,
    /// `(bucket, records)` for each bucket with records, ascending: the object holds the
    /// buckets in this order, each bucket's records by ascending id.
    pub buckets: Vec<(u32, u64)>,
    /// Byte offset of each frame's start, then the object's length.
    pub frames: Vec<u64>,
    /// The box of the vertices the range's triangles use (as written); `None` without triangles.
    pub used: Option<([f64; 3], [f64; 3])>,
}

/// Runs the partition task of range `range` of job `job` (whose scan stored the table): stores
/// its records and index and returns the index.
pub fn partition_range(
    store: &dyn BlobStore,
    job: &JobId,
    range: u32,
) -> Result<PartIndex, PipelineError> {
    let table: PartsTable = read_json(store, &parts_table_key(job))?;
    let part = table.ranges.get(range as usize).ok_or_else(|| {
        PipelineError::BadInput(format!(
            "partition task {range}: the scene has {} ranges",
            table.ranges.len()
        ))
    })?;
    let file = &table.files[part.file as usize];
    let key = format!("{}{}", scene_prefix(job), file.path);
    let bytes = if part.obj.end > part.obj.start {
        store.get_range(&key, part.obj.start..part.obj.end)?
    } else {
        Vec::new()
    };
    let faces = parse_obj_range(&bytes, Path::new(&file.path), &part.obj)?;
    drop(bytes);
    let mut pages = PageCache::new(store, job, &table, part.file);
    let lo = DVec3::from(table.vertex_lo);
    let extent = (DVec3::from(table.vertex_hi) - lo).max(DVec3::splat(f64::MIN_POSITIVE));
    let mut used: Option<(DVec3, DVec3)> = None;
    let mut keyed = Vec::with_capacity(faces.triangles.len());
    for (i, tri) in faces.triangles.iter().enumerate() {
        let mut corners = [DVec3::ZERO; 3];
        for (corner, &v) in corners.iter_mut().zip(tri) {
            *corner = match u64::from(v).checked_sub(part.obj.vertices) {
                Some(own) if own < part.obj.vertex_count => faces.positions[own as usize],
                _ => pages.position(v)?,
            };
            let (l, h) = used.get_or_insert((*corner, *corner));
            *l = l.min(*corner);
            *h = h.max(*corner);
        }
        let normal_ids = faces.triangle_normals[i];
        let normals = if normal_ids[0] == NO_NORMAL {
            None
        } else {
            let mut n = [Vec3::ZERO; 3];
            for (slot, &id) in n.iter_mut().zip(&normal_ids) {
                *slot = match u64::from(id).checked_sub(part.obj.normals) {
                    Some(own) if own < part.obj.normal_count => faces.normals[own as usize],
                    _ => pages.normal(id)?,
                };
            }
            Some(n)
        };
        let kd = file.kd[faces.triangle_materials[i] as usize];
        let centroid = (corners[0] + corners[1] + corners[2]) / 3.0;
        let record = PartRecord {
            id: (part.first_id + i as u64) as u32,
            corners,
            normals,
            kd,
        };
        keyed.push((bucket_of(centroid, lo, extent), record));
    }
    drop(faces);
    drop(pages);
    // Stable: within a bucket, records keep ascending id order.
    keyed.sort_by_key(|(bucket, _)| *bucket);
    let mut buckets: Vec<(u32, u64)> = Vec::new();
    for (bucket, _) in &keyed {
        match buckets.last_mut() {
            Some((b, n)) if b == bucket => *n += 1,
            _ => buckets.push((*bucket, 1)),
        }
    }
    let (bytes, frames) = encode_frames(keyed.iter().map(|(_, r)| r));
    let records = keyed.len();
    drop(keyed);
    store.put(&parts_records_key(job, range), &bytes)?;
    let index = PartIndex {
        records: records as u64,
        buckets,
        frames,
        used: used.map(|(l, h)| (l.to_array(), h.to_array())),
    };
    write_json(store, &parts_index_key(job, range), &index)?;
    Ok(index)
}

/// The spatial bucket of a centroid: the top [`BUCKET_BITS`] bits of its 63-bit Morton code
/// in the box `lo .. lo + extent`.
fn bucket_of(centroid: DVec3, lo: DVec3, extent: DVec3) -> u32 {
    let scale = f64::from((1u32 << 21) - 1);
    let q = ((centroid - lo) / extent * scale)
        .round()
        .clamp(DVec3::ZERO, DVec3::splat(scale));
    let code = crate::morton::morton_code([q.x as u64, q.y as u64, q.z as u64]);
    (code >> (63 - BUCKET_BITS)) as u32
}

/// The vertex objects of one file's other ranges, fetched when a face names their vertices.
struct PageCache<'a> {
    store: &'a dyn BlobStore,
    job: &'a JobId,
    table: &'a PartsTable,
    file: u32,
    pages: HashMap<usize, VertexPage>,
    bytes: u64,
}

impl<'a> PageCache<'a> {
    fn new(store: &'a dyn BlobStore, job: &'a JobId, table: &'a PartsTable, file: u32) -> Self {
        PageCache {
            store,
            job,
            table,
            file,
            pages: HashMap::new(),
            bytes: 0,
        }
    }

    /// The page of the range of this file that defines item `index` (counted by `count` from
    /// the file's start: a range covers `base(range) .. base(range) + len(range)`).
    fn page_with(
        &mut self,
        index: u32,
        what: &str,
        span: impl Fn(&super::PartRange) -> (u64, u64),
    ) -> Result<(&VertexPage, u64), PipelineError> {
        let ranges = self.table.ranges_of(self.file);
        let ours = &self.table.ranges[ranges.clone()];
        let at = ours.partition_point(|r| span(r).0 + span(r).1 <= u64::from(index));
        let Some(part) = ours.get(at).filter(|r| span(r).0 <= u64::from(index)) else {
            return Err(PipelineError::Corrupt(format!(
                "{what} {index}: no range of the file defines it"
            )));
        };
        let range = ranges.start + at;
        if !self.pages.contains_key(&range) {
            let key = parts_vertices_key(self.job, range as u32);
            let page = decode_page(&key, &self.store.get(&key)?, part.obj.normal_count)?;
            if self.bytes + page.memory_bytes() > PAGE_CACHE_BYTES {
                self.pages.clear();
                self.bytes = 0;
            }
            self.bytes += page.memory_bytes();
            self.pages.insert(range, page);
        }
        Ok((&self.pages[&range], u64::from(index) - span(part).0))
    }

    fn position(&mut self, index: u32) -> Result<DVec3, PipelineError> {
        let (page, at) =
            self.page_with(index, "vertex", |r| (r.obj.vertices, r.obj.vertex_count))?;
        page.positions.get(at as usize).copied().ok_or_else(|| {
            PipelineError::Corrupt(format!("vertex {index}: its vertex object is short"))
        })
    }

    fn normal(&mut self, index: u32) -> Result<Vec3, PipelineError> {
        let (page, at) =
            self.page_with(index, "normal", |r| (r.obj.normals, r.obj.normal_count))?;
        page.normals.get(at as usize).copied().ok_or_else(|| {
            PipelineError::Corrupt(format!("normal {index}: its vertex object is short"))
        })
    }
}
