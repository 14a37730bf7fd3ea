//! Cutting a scene into k splits: HORT's naive even index ranges, or spatial clusters (Morton
//! order of triangle centroids cut into k equal runs: balanced to within one triangle, compact
//! boxes). The splitter holds the parsed mesh and one split's buffers at a time; it never builds
//! acceleration data for the whole scene.

use super::split_object::{SplitObject, TriangleShading, encode_split};
use crate::bvh::{BuildPreset, Bvh};
use crate::morton::morton_code;
use crate::render::shading_of;
use crate::scene::Mesh;
use crate::worker_pool::available_cores;
use serde::{Deserialize, Serialize};

/// How triangles are grouped into splits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SplitMode {
    /// The paper's splitter: k even ranges of scene order, no regard for position.
    Naive,
    /// Spatially compact clusters, so stages can skip (span, split) pairs that cannot meet.
    Spatial,
}

impl std::str::FromStr for SplitMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "naive" => Ok(SplitMode::Naive),
            "spatial" => Ok(SplitMode::Spatial),
            other => Err(format!(
                "unknown split mode \"{other}\": use spatial or naive"
            )),
        }
    }
}

/// The global triangle ids of each of the `k` splits (`1 <= k <= triangles`), ascending within a
/// split. Every triangle is in exactly one split; split sizes differ by at most one.
pub fn assign_splits(mesh: &Mesh, k: usize, mode: SplitMode) -> Vec<Vec<u32>> {
    let n = mesh.triangle_count();
    let order: Vec<u32> = match mode {
        // One split holds everything in either mode: no need to sort.
        _ if k == 1 => (0..n as u32).collect(),
        SplitMode::Naive => (0..n as u32).collect(),
        SplitMode::Spatial => morton_order(mesh),
    };
    (0..k)
        .map(|i| {
            let mut ids = order[i * n / k..(i + 1) * n / k].to_vec();
            ids.sort_unstable();
            ids
        })
        .collect()
}

/// Triangle ids sorted by the 63-bit Morton code of their centroid (ties by id).
fn morton_order(mesh: &Mesh) -> Vec<u32> {
    let centroid = |i: usize| {
        let [a, b, c] = mesh.corners(i);
        (a.as_dvec3() + b.as_dvec3() + c.as_dvec3()) / 3.0
    };
    let n = mesh.triangle_count();
    let (mut lo, mut hi) = (
        glam::DVec3::splat(f64::INFINITY),
        glam::DVec3::splat(f64::NEG_INFINITY),
    );
    for i in 0..n {
        let c = centroid(i);
        lo = lo.min(c);
        hi = hi.max(c);
    }
    let extent = (hi - lo).max(glam::DVec3::splat(f64::MIN_POSITIVE));
    let scale = f64::from((1u32 << 21) - 1);
    let mut keyed: Vec<(u64, u32)> = (0..n)
        .map(|i| {
            let q = ((centroid(i) - lo) / extent * scale).round();
            let code = morton_code([q.x as u64, q.y as u64, q.z as u64]);
            (code, i as u32)
        })
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// Builds each split (triangles, shading, BVH) one at a time and hands its encoded bytes to
/// `emit` before building the next, so only one split's buffers are alive at once. Returns the
/// decoded-side summary of each split (bounds, triangle count, encoded size).
pub fn split_scene<E>(
    mesh: &Mesh,
    k: usize,
    mode: SplitMode,
    preset: BuildPreset,
    mut emit: impl FnMut(u32, Vec<u8>) -> Result<(), E>,
) -> Result<Vec<super::SplitInfo>, E> {
    split_scene_objects(mesh, k, mode, preset, |split, _, bytes, _| {
        emit(split, bytes)
    })
}

/// [`split_scene`] that also hands `emit` each split object as built, before it is dropped:
/// exactly what [`super::decode_split`] gives back from its bytes (the encoding is lossless),
/// for a caller that keeps it instead of decoding it again, and the microseconds its encoding
/// took (for the plan step's time breakdown).
pub fn split_scene_objects<E>(
    mesh: &Mesh,
    k: usize,
    mode: SplitMode,
    preset: BuildPreset,
    mut emit: impl FnMut(u32, SplitObject, Vec<u8>, u64) -> Result<(), E>,
) -> Result<Vec<super::SplitInfo>, E> {
    let mut infos = Vec::with_capacity(k);
    for (split, ids) in assign_splits(mesh, k, mode).into_iter().enumerate() {
        let mut encode_us = 0;
        let (info, object, bytes) =
            build_split_object(mesh, split as u32, ids, preset, &mut encode_us);
        infos.push(info);
        emit(split as u32, object, bytes, encode_us)?;
    }
    Ok(infos)
}

/// The encoded split object `split` of `k` in `mode`: exactly the bytes [`split_scene`] emits
/// for it, built alone (lineage recomputation of a lost or corrupt split object). `None` if
/// `split` is not below `k`.
pub fn rebuild_split(
    mesh: &Mesh,
    k: usize,
    mode: SplitMode,
    preset: BuildPreset,
    split: u32,
) -> Option<Vec<u8>> {
    let ids = assign_splits(mesh, k, mode)
        .into_iter()
        .nth(split as usize)?;
    Some(build_split_object(mesh, split, ids, preset, &mut 0).2)
}

/// Builds split `split` of the triangles `ids`: its summary, the object and its encoding, whose
/// microseconds are added to `encode_us`.
fn build_split_object(
    mesh: &Mesh,
    split: u32,
    ids: Vec<u32>,
    preset: BuildPreset,
    encode_us: &mut u64,
) -> (super::SplitInfo, SplitObject, Vec<u8>) {
    let triangles = ids.iter().map(|&i| mesh.corners(i as usize)).collect();
    let object = build_split_bvh(split, triangles, ids, preset, |id| shading_of(mesh, id));
    encode_built_split(object, encode_us)
}

/// The split object of split `split` over the triangles `ids` with corners `triangles` (same
/// order), each with the shading `shading` gives its id, its BVH built with `preset`; not yet
/// encoded, so a caller can drop what `shading` borrows before encoding it. The one place
/// split objects are made, whether the triangles come from a loaded scene or from partition
/// tasks (then [`encode_built_split`]).
pub(super) fn build_split_bvh(
    split: u32,
    triangles: Vec<[glam::Vec3; 3]>,
    ids: Vec<u32>,
    preset: BuildPreset,
    shading: impl Fn(u32) -> TriangleShading,
) -> SplitObject {
    let bvh = Bvh::build_preset(triangles, ids, available_cores(), preset);
    let shading = bvh.ids().iter().map(|&id| shading(id)).collect();
    SplitObject {
        split,
        bvh,
        shading,
        textures: Default::default(),
    }
}

/// `object`'s summary, the object and its encoding, whose microseconds are added to
/// `encode_us`.
pub(super) fn encode_built_split(
    object: SplitObject,
    encode_us: &mut u64,
) -> (super::SplitInfo, SplitObject, Vec<u8>) {
    let bounds = object.bvh.bounds();
    let triangles = object.bvh.triangle_count() as u64;
    let bytes = super::timed(encode_us, || encode_split(&object));
    let info = super::SplitInfo {
        id: object.split,
        triangles,
        lo: bounds.lo.to_array(),
        hi: bounds.hi.to_array(),
        bytes: bytes.len() as u64,
    };
    (info, object, bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn grid_mesh(n: usize) -> Mesh {
        let mut mesh = Mesh::default();
        mesh.materials
            .push(crate::scene::Material::plain("default", [0.7; 3]));
        for i in 0..n {
            let x = ((i * 7919) % n) as f32;
            let base = mesh.positions.len() as u32;
            mesh.positions.extend([
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x + 1.0, 0.0, 0.0),
                Vec3::new(x, 1.0, 0.0),
            ]);
            mesh.triangles.push([base, base + 1, base + 2]);
            mesh.triangle_normals.push([crate::scene::NO_NORMAL; 3]);
            mesh.triangle_materials.push(0);
        }
        mesh
    }

    #[test]
    fn every_triangle_lands_in_exactly_one_balanced_split() {
        let mesh = grid_mesh(1003);
        for mode in [SplitMode::Naive, SplitMode::Spatial] {
            for k in [1, 2, 3, 7, 16] {
                let splits = assign_splits(&mesh, k, mode);
                assert_eq!(splits.len(), k);
                let mut all: Vec<u32> = splits.iter().flatten().copied().collect();
                all.sort_unstable();
                assert_eq!(all, (0..1003).collect::<Vec<_>>());
                let (min, max) = (
                    splits.iter().map(Vec::len).min().unwrap(),
                    splits.iter().map(Vec::len).max().unwrap(),
                );
                assert!(max - min <= 1, "{mode:?} k={k}: {min}..{max}");
            }
        }
    }

    #[test]
    fn naive_splits_are_index_ranges_and_spatial_ones_are_compact() {
        let mesh = grid_mesh(1000);
        assert_eq!(
            assign_splits(&mesh, 4, SplitMode::Naive)[1],
            (250..500).collect::<Vec<_>>()
        );
        // Spatial: each split covers a contiguous x range, a quarter of the width.
        for ids in assign_splits(&mesh, 4, SplitMode::Spatial) {
            let xs: Vec<f32> = ids.iter().map(|&i| mesh.corners(i as usize)[0].x).collect();
            let span = xs.iter().cloned().fold(f32::MIN, f32::max)
                - xs.iter().cloned().fold(f32::MAX, f32::min);
            assert!(span < 260.0, "split spans {span} of 1000");
        }
    }

    #[test]
    fn a_rebuilt_split_has_exactly_the_bytes_split_scene_emitted() {
        let mesh = grid_mesh(301);
        let presets = [BuildPreset::Quality, BuildPreset::Fast];
        for (mode, preset) in [SplitMode::Naive, SplitMode::Spatial]
            .into_iter()
            .flat_map(|mode| presets.map(|preset| (mode, preset)))
        {
            let mut emitted = Vec::new();
            split_scene(&mesh, 5, mode, preset, |split, bytes| {
                emitted.push((split, bytes));
                Ok::<(), ()>(())
            })
            .unwrap();
            for (split, bytes) in emitted {
                assert_eq!(
                    rebuild_split(&mesh, 5, mode, preset, split).as_deref(),
                    Some(bytes.as_slice()),
                    "{mode:?} {preset:?} split {split}"
                );
            }
            assert_eq!(rebuild_split(&mesh, 5, mode, preset, 5), None);
        }
    }
}
