//! Steps 4 and 5: a build task makes one split object from its runs of records; the plan is
//! made from the split summaries and the scene without its geometry.

use super::cut::CutSplits;
use super::range_task::{PartIndex, partition_range};
use super::record::{FRAME_RECORDS, PartRecord, decode_frame};
use super::scan::PartsTable;
use super::{PipelineError, read_json, write_json};
use crate::error::SceneError;
use crate::ids::{JobId, SplitId};
use crate::keys::{
    parts_index_key, parts_records_key, parts_split_info_key, parts_splits_key, parts_table_key,
    plan_key, split_key,
};
use crate::pipeline::plan::{JobPlan, PlanRequest, plan_job, resolve_counts};
use crate::pipeline::plan_step::PlannedJob;
use crate::pipeline::split::{build_split_bvh, encode_built_split};
use crate::pipeline::split_object::TriangleShading;
use crate::pipeline::{SplitInfo, TaskMetrics};
use crate::scene::scene_without_geometry;
use crate::store::{BlobStore, StoreError};
use glam::{DVec3, Vec3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Runs the build task of split `split` of job `job` (whose cut is stored): reads its records,
/// builds the split object, stores it at `splits/{split}` and its summary at
/// `parts/split-{split}.json`. Returns the summary and the object's bytes (the lineage of a
/// lost split object is this task).
pub fn build_split_from_parts(
    store: &dyn BlobStore,
    job: &JobId,
    split: u32,
) -> Result<(SplitInfo, Vec<u8>), PipelineError> {
    let table: PartsTable = read_json(store, &parts_table_key(job))?;
    let cut: CutSplits = read_json(store, &parts_splits_key(job))?;
    let runs = cut.splits.get(split as usize).ok_or_else(|| {
        PipelineError::BadInput(format!(
            "build task {split}: the scene has {} splits",
            cut.splits.len()
        ))
    })?;
    let origin = DVec3::from(cut.origin);
    let mut columns = Columns::default();
    for run in runs {
        let before = columns.lens();
        let read = |columns: &mut Columns| {
            let index: PartIndex = read_json(store, &parts_index_key(job, run.range))?;
            read_run(store, job, run, &index, &mut |record| {
                columns.push(record, origin, &table)
            })
        };
        match read(&mut columns) {
            // Lost or damaged: the range's partition task writes the same bytes again (its
            // lineage), then the run is read afresh.
            Err(PipelineError::Corrupt(_) | PipelineError::Store(StoreError::NotFound { .. })) => {
                columns.truncate(before);
                partition_range(store, job, run.range)?;
                read(&mut columns)?;
            }
            other => other?,
        }
    }
    let Columns {
        mut ids,
        mut corners,
        mut kd_index,
        kd_values,
        mut normals,
        ..
    } = columns;
    // Scene order (runs arrive by range, each by bucket then id).
    let order = sorted_order(&ids);
    permute(&mut ids, &order);
    permute(&mut corners, &order);
    permute(&mut kd_index, &order);
    drop(order);
    normals.sort_unstable_by_key(|n| n.0);
    let sorted_ids = ids.clone();
    let object = build_split_bvh(split, corners, ids, cut.bvh_build, |id| {
        let at = sorted_ids.binary_search(&id).expect("a split's own id");
        TriangleShading {
            normals: normals
                .binary_search_by_key(&id, |n| n.0)
                .ok()
                .map(|i| normals[i].1),
            kd: kd_values[kd_index[at] as usize],
            // Scenes read in ranges have no textures (refused when planned).
            texture: None,
        }
    });
    drop((kd_index, normals, sorted_ids));
    let (info, _, bytes) = encode_built_split(object, &mut 0);
    store.put(&split_key(job, SplitId(split)), &bytes)?;
    write_json(store, &parts_split_info_key(job, split), &info)?;
    Ok((info, bytes))
}

/// A split's triangles as a build task gathers them, converted record by record so that the
/// records (128 bytes, f64 corners) never pile up: id and corners in the local frame in
/// columns the BVH build takes over without copies; kd as an index into the split's distinct
/// values, and normals only for the triangles that have them (44 bytes a triangle without).
#[derive(Default)]
struct Columns {
    ids: Vec<u32>,
    corners: Vec<[Vec3; 3]>,
    kd_index: Vec<u32>,
    kd_values: Vec<[f32; 3]>,
    kd_seen: HashMap<[u32; 3], u32>,
    normals: Vec<(u32, [Vec3; 3])>,
}

impl Columns {
    /// Lengths to [`Columns::truncate`] back to.
    fn lens(&self) -> (usize, usize) {
        (self.ids.len(), self.normals.len())
    }

    /// Drops what was pushed since [`Columns::lens`] gave `lens` (the kd table may keep values
    /// no triangle uses any more: it is only a lookup).
    fn truncate(&mut self, (triangles, normals): (usize, usize)) {
        self.ids.truncate(triangles);
        self.corners.truncate(triangles);
        self.kd_index.truncate(triangles);
        self.normals.truncate(normals);
    }

    /// Adds `record` with its corners moved into the frame of `origin` (rounded once to f32,
    /// as a whole-scene load does); an offset f32 cannot hold is the scene's error.
    fn push(
        &mut self,
        record: &PartRecord,
        origin: DVec3,
        table: &PartsTable,
    ) -> Result<(), PipelineError> {
        let local = record.corners.map(|p| (p - origin).as_vec3());
        if !local.iter().all(|p| p.is_finite()) {
            let path = file_of(table, record.id);
            return Err(SceneError::TooLarge { path }.into());
        }
        self.ids.push(record.id);
        self.corners.push(local);
        let values = &mut self.kd_values;
        let kd = *self
            .kd_seen
            .entry(record.kd.map(f32::to_bits))
            .or_insert_with(|| {
                values.push(record.kd);
                (values.len() - 1) as u32
            });
        self.kd_index.push(kd);
        self.normals.extend(record.normals.map(|n| (record.id, n)));
        Ok(())
    }
}

/// The positions of `ids` in ascending order of id (`ids` are distinct).
fn sorted_order(ids: &[u32]) -> Vec<u32> {
    let mut order: Vec<u32> = (0..ids.len() as u32).collect();
    order.sort_unstable_by_key(|&i| ids[i as usize]);
    order
}

/// Reorders `items` in place so that `items[i]` becomes the old `items[order[i]]`, with no
/// second copy of `items` (one bit per item marks what is placed).
fn permute<T>(items: &mut [T], order: &[u32]) {
    let mut placed = vec![0u64; items.len().div_ceil(64)];
    for start in 0..items.len() {
        if placed[start / 64] >> (start % 64) & 1 == 1 {
            continue;
        }
        // Follow the cycle through `start`: each slot takes the item its order names.
        let mut at = start;
        loop {
            placed[at / 64] |= 1 << (at % 64);
            let from = order[at] as usize;
            if from == start {
                break;
            }
            items.swap(at, from);
            at = from;
        }
    }
}

/// The file that holds triangle `id`, for messages.
fn file_of(table: &PartsTable, id: u32) -> PathBuf {
    let at = table
        .ranges
        .partition_point(|r| r.first_id + r.obj.triangle_count <= u64::from(id));
    let file = table.ranges.get(at).map_or(0, |r| r.file as usize);
    PathBuf::from(&table.files[file].path)
}

/// Frames a build task fetches in one ranged GET (about 8 MiB of raw records).
const FRAMES_PER_READ: u64 = 8;

/// Hands each record of `run` to `each`, in the records object's order, fetching the frames
/// that hold them a few at a time.
fn read_run(
    store: &dyn BlobStore,
    job: &JobId,
    run: &super::RecordRun,
    index: &PartIndex,
    each: &mut dyn FnMut(&PartRecord) -> Result<(), PipelineError>,
) -> Result<(), PipelineError> {
    let key = parts_records_key(job, run.range);
    let frames = FRAME_RECORDS as u64;
    let (first, last) = (run.start / frames, (run.end - 1) / frames);
    let offsets = &index.frames;
    if run.end > index.records || last as usize + 1 >= offsets.len() {
        return Err(PipelineError::Corrupt(format!(
            "{key}: records {}..{} asked for, its index lists {} in {} frames",
            run.start,
            run.end,
            index.records,
            offsets.len().saturating_sub(1)
        )));
    }
    let mut group = first;
    while group <= last {
        let end = (group + FRAMES_PER_READ).min(last + 1);
        let base = offsets[group as usize];
        let bytes = store.get_range(&key, base..offsets[end as usize])?;
        for frame in group..end {
            let at = (offsets[frame as usize] - base) as usize
                ..(offsets[frame as usize + 1] - base) as usize;
            let records = decode_frame(&key, bytes.get(at).unwrap_or_default())?;
            let from = run.start.saturating_sub(frame * frames) as usize;
            let to = ((run.end - frame * frames) as usize).min(records.len());
            let wanted = records.get(from..to).ok_or_else(|| {
                PipelineError::Corrupt(format!(
                    "{key}: frame {frame} holds {} records",
                    records.len()
                ))
            })?;
            wanted.iter().try_for_each(&mut *each)?;
        }
        group = end;
    }
    Ok(())
}

/// Step 5: plans job `job` from its built splits: the scene at `main` (the main file, OBJ or
/// manifest, in a folder holding the manifest; its meshes are not read) without its geometry,
/// framed by the splits' bounds, planned as [`crate::pipeline::plan_into_store`] plans a
/// loaded scene; stores and returns the plan.
pub fn plan_from_parts(
    store: &dyn BlobStore,
    job: &JobId,
    main: &Path,
    request: &PlanRequest,
) -> Result<PlannedJob, PipelineError> {
    let started = std::time::Instant::now();
    let table: PartsTable = read_json(store, &parts_table_key(job))?;
    let cut: CutSplits = read_json(store, &parts_splits_key(job))?;
    let (shape, _) = resolve_counts(request, table.triangles)?;
    if shape.splits as usize != cut.splits.len() {
        return Err(PipelineError::Corrupt(format!(
            "{}: {} splits, the request plans {}",
            parts_splits_key(job),
            cut.splits.len(),
            shape.splits
        )));
    }
    let infos: Vec<SplitInfo> = (0..cut.splits.len() as u32)
        .map(|split| read_json(store, &parts_split_info_key(job, split)))
        .collect::<Result<_, _>>()?;
    let plan = plan_for_splits(main, &table, cut.origin, infos, request)?;
    let plan_json = serde_json::to_vec_pretty(&plan)
        .map_err(|e| PipelineError::BadInput(format!("cannot encode the plan: {e}")))?;
    store.put(&plan_key(job), &plan_json)?;
    let task_us = crate::pipeline::micros(started.elapsed());
    Ok(PlannedJob {
        bytes_written: plan_json.len() as u64,
        plan,
        metrics: TaskMetrics {
            task_us,
            compute_us: task_us,
            ..Default::default()
        },
    })
}

/// The plan of a scene split by tasks whose scan found `table`, its local frame's origin at
/// `origin` (world coordinates), built into the splits `infos` (local frame): the scene at `main`
/// without its geometry, framed by the splits' bounds, planned as a loaded scene is.
fn plan_for_splits(
    main: &Path,
    table: &PartsTable,
    origin: [f64; 3],
    infos: Vec<SplitInfo>,
    request: &PlanRequest,
) -> Result<JobPlan, PipelineError> {
    let (shape, s) = resolve_counts(request, table.triangles)?;
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for info in &infos {
        lo = lo.min(Vec3::from(info.lo).as_dvec3());
        hi = hi.max(Vec3::from(info.hi).as_dvec3());
    }
    if (hi - lo).length() <= 0.0 {
        return Err(SceneError::NoExtent {
            path: main.to_path_buf(),
        }
        .into());
    }
    let scene =
        scene_without_geometry(main, DVec3::from(origin), (lo, hi), table.warnings.clone())?;
    let mut plan = plan_job(&scene, request, infos, &shape, s)?;
    plan.scene_parts = Some(table.shape());
    Ok(plan)
}

/// The plan [`plan_from_parts`] would make for the scene at `main` whose scan found `table`,
/// before any partition or build task ran (`hort plan`): the same split and span counts and
/// triangles per split, each split's bounds taken as the box of every vertex (so no CastMap
/// pair is left out: an upper bound on the tasks) and its bytes as `bytes_per_triangle` times
/// its triangles.
pub fn preview_plan_from_table(
    main: &Path,
    table: &PartsTable,
    request: &PlanRequest,
    bytes_per_triangle: u64,
) -> Result<JobPlan, PipelineError> {
    let (shape, _) = resolve_counts(request, table.triangles)?;
    let (lo, hi) = (DVec3::from(table.vertex_lo), DVec3::from(table.vertex_hi));
    let origin = (lo + hi) / 2.0;
    let n = table.triangles;
    let k = u64::from(shape.splits);
    let infos = (0..k)
        .map(|i| {
            let triangles = (i + 1) * n / k - i * n / k;
            SplitInfo {
                id: i as u32,
                triangles,
                lo: (lo - origin).as_vec3().to_array(),
                hi: (hi - origin).as_vec3().to_array(),
                bytes: triangles * bytes_per_triangle,
            }
        })
        .collect();
    plan_for_splits(main, table, origin.to_array(), infos, request)
}
