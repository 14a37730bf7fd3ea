//! Step 3, the cut: the local frame and the k splits, from the partition indexes alone.

use super::range_task::PartIndex;
use super::{PipelineError, write_json};
use crate::ids::JobId;
use crate::keys::parts_splits_key;
use crate::store::BlobStore;
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// Records `start..end` of range `range`'s records object.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct RecordRun {
    /// The range whose records object holds the run.
    pub range: u32,
    /// First record of the run.
    pub start: u64,
    /// One past its last record.
    pub end: u64,
}

/// `jobs/{job}/parts/splits.json`: the local frame and what each split takes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CutSplits {
    /// The local frame's origin: the centre of the box of the vertices triangles use (world
    /// coordinates), as a whole-scene load computes it.
    pub origin: [f64; 3],
    /// Each split's runs, by split id; a range appears at most once per split.
    pub splits: Vec<Vec<RecordRun>>,
    /// How the build tasks build the splits' BVHs: the plan's preset
    /// ([`crate::pipeline::split_build_preset`] of the request and the triangle count).
    #[serde(default)]
    pub bvh_build: crate::bvh::BuildPreset,
}

/// Cuts the scene whose partition tasks wrote `indexes` (by range) into `k` splits (`1 <= k`,
/// at most the triangle count) and stores the cut at `parts/splits.json`. The scene's
/// triangles in (bucket, id) order are cut into `k` runs of `i * n / k .. (i + 1) * n / k`, as
/// the in-memory splitter cuts its Morton order: every triangle in exactly one split, sizes
/// differing by at most one.
pub fn cut_splits(
    store: &dyn BlobStore,
    job: &JobId,
    indexes: &[PartIndex],
    k: u32,
    bvh_build: crate::bvh::BuildPreset,
) -> Result<CutSplits, PipelineError> {
    for (range, index) in indexes.iter().enumerate() {
        let counted: u64 = index.buckets.iter().map(|b| b.1).sum();
        let ascending = index.buckets.windows(2).all(|w| w[0].0 < w[1].0);
        if counted != index.records || !ascending {
            return Err(PipelineError::Corrupt(format!(
                "partition index of range {range}: {} records, its buckets hold {counted}{}",
                index.records,
                if ascending {
                    ""
                } else {
                    " and are out of order"
                }
            )));
        }
    }
    let n: u64 = indexes.iter().map(|i| i.records).sum();
    if k == 0 || u64::from(k) > n {
        return Err(PipelineError::BadInput(format!(
            "cannot cut {} into {}",
            crate::plural::count(n, "triangle"),
            crate::plural::count(u64::from(k), "split")
        )));
    }
    let mut used: Option<(DVec3, DVec3)> = None;
    for (lo, hi) in indexes.iter().filter_map(|i| i.used) {
        let (l, h) = used.get_or_insert((lo.into(), hi.into()));
        *l = l.min(lo.into());
        *h = h.max(hi.into());
    }
    let (lo, hi) = used.expect("a scene with triangles uses vertices");
    let bounds: Vec<Vec<u64>> = (0..=u64::from(k))
        .map(|i| records_before(indexes, i * n / u64::from(k)))
        .collect();
    let splits = bounds
        .windows(2)
        .map(|pair| {
            (0..indexes.len())
                .filter(|&r| pair[1][r] > pair[0][r])
                .map(|r| RecordRun {
                    range: r as u32,
                    start: pair[0][r],
                    end: pair[1][r],
                })
                .collect()
        })
        .collect();
    let cut = CutSplits {
        origin: ((lo + hi) * 0.5).to_array(),
        splits,
        bvh_build,
    };
    write_json(store, &parts_splits_key(job), &cut)?;
    Ok(cut)
}

/// For each range, how many of its records come before rank `rank` of the whole scene's
/// (bucket, id) order. Ranges hold ascending ids, so within a bucket the earlier range's
/// records come first.
fn records_before(indexes: &[PartIndex], rank: u64) -> Vec<u64> {
    let mut before = vec![0u64; indexes.len()];
    let mut cursors = vec![0usize; indexes.len()];
    let mut left = rank;
    while left > 0 {
        let bucket = indexes
            .iter()
            .zip(&cursors)
            .filter_map(|(index, &c)| index.buckets.get(c).map(|b| b.0))
            .min()
            .expect("rank is below the record count");
        for (r, index) in indexes.iter().enumerate() {
            let Some(&(b, count)) = index.buckets.get(cursors[r]) else {
                continue;
            };
            if b != bucket || left == 0 {
                continue;
            }
            let take = count.min(left);
            before[r] += take;
            left -= take;
            cursors[r] += 1;
        }
    }
    before
}

/// Step 3 for job `job` planned by `request`: reads the table and every range's index, cuts
/// the scene into the split count the request resolves to for its triangle count, stores the
/// cut and returns it with the shape the request resolves to.
pub fn cut_scene(
    store: &dyn BlobStore,
    job: &JobId,
    request: &crate::pipeline::PlanRequest,
) -> Result<(CutSplits, crate::pipeline::JobShape), PipelineError> {
    use crate::keys::{parts_index_key, parts_table_key};
    let table: super::PartsTable = super::read_json(store, &parts_table_key(job))?;
    let (shape, _) = crate::pipeline::resolve_counts(request, table.triangles)?;
    let indexes: Vec<PartIndex> = (0..table.ranges.len() as u32)
        .map(|range| super::read_json(store, &parts_index_key(job, range)))
        .collect::<Result<_, _>>()?;
    let preset = crate::pipeline::split_build_preset(request, table.triangles);
    Ok((
        cut_splits(store, job, &indexes, shape.splits, preset)?,
        shape,
    ))
}
