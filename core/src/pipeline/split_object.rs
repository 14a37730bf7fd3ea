//! The split object: one scene split as one stored blob, loadable without building anything.
//!
//! It is a shuffle block of kind `SplitObject` (zstd, checksums; see [`crate::shuffle`]) whose
//! raw bytes are the BVH's traversal form as it is in memory, then the ids and the shading, in
//! these sections (version [`SPLIT_FORMAT_VERSION`]; little-endian, floats as IEEE bits):
//!
//! | section | bytes | values |
//! |---|---|---|
//! | header | 52 | u32: format version, split id, triangle count n, 4-wide node count w, triangle pack count p, triangles with normals c, distinct kd count k; f32: root box lo.xyz, hi.xyz |
//! | nodes | 128 w | the 4-wide nodes as in memory, root first ([`NODE_BYTES`]: 4 child boxes axis by axis, 4 child words, 4 pack counts) |
//! | pack lanes | p | u8: triangles in each `Triangle4` pack (1 to 4), in pack order |
//! | corners | 36 n | 9 f32 per triangle (corner 0 xyz, 1, 2), BVH leaf order |
//! | ids | 4 n | u32: global triangle id (scene order), leaf order |
//! | normal flags | n | u8: 1 if the triangle has vertex normals, else 0 |
//! | normals | 36 c | 9 f32 per triangle with normals (corner 0 xyz, 1, 2), leaf order |
//! | kd values | 12 k | 3 f32 per distinct kd, in order of first use |
//! | kd indices | 1, 2 or 4 per triangle | index of the triangle's kd; the width is 1 byte for k <= 256, 2 for k <= 65,536, else 4 |
//!
//! Why this layout (measured, docs/ARCHITECTURE.md section 8): loading is decompression plus
//! linear copies into the final arrays (the packs' corners transposed into lanes four
//! triangles at a time) and linear checks; nothing is collapsed, gathered or looked up. The
//! corners are written out instead of referring to distinct vertices (version 2): zstd finds
//! the repeated vertices itself, so they are barely larger stored and much cheaper to load.
//! Stored per triangle, not per pack lane, the corners skip the empty lanes and keep each
//! vertex's three coordinates together, which zstd matches far better than the lanes' axis by
//! axis layout. kd values repeat per material, so an index into a small table costs one byte
//! per triangle to load.
//!
//! Decoding checks everything it relies on: the version (objects of version 2 and older name
//! their version and are refused), the header's counts against each other and the exact raw
//! length, the BVH as [`Bvh::from_parts`] does (children in depth-first order after their
//! parent, depth, leaves inside the packs and covering them, pack sizes), normal flags 0 or 1
//! and as many set as declared, kd indices numbering the kd values in order of first use, each
//! used. So `encode_split(&decode_split(k, b)?) == b` for every object that decodes.

use super::PipelineError;
use crate::bvh::{Aabb, Bvh, BvhParts, CORNER_BYTES, NODE_BYTES};
use crate::shuffle::columns::ColumnReader;
use crate::shuffle::{RecordKind, decode_block, encode_block};
use glam::Vec3;

mod kd;
use kd::{KdTable, index_width};

/// Version of the layout above; bump on any change.
pub const SPLIT_FORMAT_VERSION: u32 = 3;

/// Bytes of the header section: 7 u32 and 6 f32.
const HEADER_BYTES: usize = 52;

/// Per-triangle shading data carried by a split.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleShading {
    /// The corners' vertex normals, in corner order; `None` shades with the geometric normal.
    pub normals: Option<[Vec3; 3]>,
    /// Diffuse reflectance per RGB channel, from the triangle's material.
    pub kd: [f32; 3],
}

/// A decoded split: its BVH (triangles in leaf order) and the shading data in the same order.
#[derive(Clone, Debug, PartialEq)]
pub struct SplitObject {
    /// The split's id, `0..k`.
    pub split: u32,
    /// BVH over the split's triangles, carrying their scene-wide ids.
    pub bvh: Bvh,
    /// `shading[i]` belongs to the BVH's i-th triangle in leaf order.
    pub shading: Vec<TriangleShading>,
}

impl SplitObject {
    /// Bytes the decoded object holds in memory.
    pub fn memory_bytes(&self) -> u64 {
        self.bvh.memory_bytes()
            + (self.shading.len() * std::mem::size_of::<TriangleShading>()) as u64
    }
}

/// The sections' lengths in bytes after the header, in order, for the header's counts.
fn section_lengths(n: u32, w: u32, p: u32, with_normals: u32, k: u32) -> [(u64, &'static str); 8] {
    let [n, w, p, c, k64] = [n, w, p, with_normals, k].map(u64::from);
    [
        (w * NODE_BYTES as u64, "nodes"),
        (p, "pack lanes"),
        (n * CORNER_BYTES as u64, "corners"),
        (4 * n, "ids"),
        (n, "normal flags"),
        (36 * c, "normals"),
        (12 * k64, "kd values"),
        (index_width(k) as u64 * n, "kd indices"),
    ]
}

/// Encodes a split object as a compressed block (deterministic: the same object gives the same
/// bytes). `object.shading` holds one entry per triangle.
pub fn encode_split(object: &SplitObject) -> Vec<u8> {
    let bvh = &object.bvh;
    let n = bvh.triangle_count() as u32;
    let mut kd = KdTable::default();
    for s in &object.shading {
        kd.push(s.kd);
    }
    let with_normals = object
        .shading
        .iter()
        .filter(|s| s.normals.is_some())
        .count() as u32;
    let (w, p, k) = (
        bvh.wide_node_count() as u32,
        bvh.pack_count() as u32,
        kd.values.len() as u32,
    );
    let total: u64 = section_lengths(n, w, p, with_normals, k)
        .iter()
        .map(|s| s.0)
        .sum();
    let mut raw = Vec::with_capacity(HEADER_BYTES + total as usize);
    for word in [SPLIT_FORMAT_VERSION, object.split, n, w, p, with_normals, k] {
        raw.extend_from_slice(&word.to_le_bytes());
    }
    let Aabb { lo, hi } = bvh.bounds();
    for x in lo.to_array().into_iter().chain(hi.to_array()) {
        raw.extend_from_slice(&x.to_le_bytes());
    }
    bvh.put_nodes(&mut raw);
    bvh.put_lanes(&mut raw);
    bvh.put_corners(&mut raw);
    for id in bvh.ids() {
        raw.extend_from_slice(&id.to_le_bytes());
    }
    raw.extend(object.shading.iter().map(|s| u8::from(s.normals.is_some())));
    for normals in object.shading.iter().filter_map(|s| s.normals.as_ref()) {
        for x in normals.iter().flat_map(|v| v.to_array()) {
            raw.extend_from_slice(&x.to_le_bytes());
        }
    }
    for x in kd.values.iter().flatten() {
        raw.extend_from_slice(&x.to_le_bytes());
    }
    match index_width(k) {
        1 => raw.extend(kd.uses.iter().map(|&i| i as u8)),
        2 => raw.extend(kd.uses.iter().flat_map(|&i| (i as u16).to_le_bytes())),
        _ => raw.extend(kd.uses.iter().flat_map(|&i| i.to_le_bytes())),
    }
    encode_block(RecordKind::SplitObject, u64::from(n), &raw)
}

/// The format version of a split object written before version 3, whose raw bytes are columns
/// starting with a u32 column that holds the version; `None` for anything else (version 3 raw
/// bytes start with the word 3, which is no u32 column's tag).
fn older_version(raw: &[u8]) -> Option<u32> {
    ColumnReader::new(raw).read_u32().ok()?.first().copied()
}

/// Decodes and validates a split object read from `key`. Every error is one line naming `key`
/// and what is wrong (see the module docs for what is checked).
pub fn decode_split(key: &str, bytes: &[u8]) -> Result<SplitObject, PipelineError> {
    let block = decode_block(key, bytes, RecordKind::SplitObject)
        .map_err(|e| PipelineError::Corrupt(e.to_string()))?;
    let corrupt = |what: String| PipelineError::Corrupt(format!("split object {key}: {what}"));
    let raw = &block.raw[..];
    if let Some(old) = older_version(raw) {
        return Err(corrupt(format!(
            "format version {old}, this build reads {SPLIT_FORMAT_VERSION}"
        )));
    }
    let Some((head, body)) = raw.split_first_chunk::<HEADER_BYTES>() else {
        return Err(corrupt(format!(
            "{} raw bytes, shorter than the {HEADER_BYTES}-byte header",
            raw.len()
        )));
    };
    let (words, _) = head.as_chunks::<4>();
    let word = |k: usize| u32::from_le_bytes(words[k]);
    let version = word(0);
    if version != SPLIT_FORMAT_VERSION {
        return Err(corrupt(format!(
            "format version {version}, this build reads {SPLIT_FORMAT_VERSION}"
        )));
    }
    let [split, n, w, p, with_normals, k] = [1, 2, 3, 4, 5, 6].map(word);
    if with_normals > n {
        return Err(corrupt(format!(
            "header declares {with_normals} triangles with normals of {n}"
        )));
    }
    if k > n || (k == 0 && n > 0) {
        return Err(corrupt(format!(
            "header declares {k} kd values for {n} triangles"
        )));
    }
    let lengths = section_lengths(n, w, p, with_normals, k);
    let expected: u64 = lengths.iter().map(|s| s.0).sum();
    if body.len() as u64 != expected {
        return Err(corrupt(format!(
            "{} bytes after the header, whose counts call for {expected}",
            body.len()
        )));
    }
    // Every length sums to body.len(), so each fits in usize and the splits stay in range.
    let mut rest = body;
    let [
        nodes,
        lanes,
        corners,
        ids,
        flags,
        normals,
        kd_values,
        kd_indices,
    ] = lengths.map(|(len, _)| {
        let (section, after) = rest.split_at(len as usize);
        rest = after;
        section
    });
    let f = |b: &[u8; 4]| f32::from_le_bytes(*b);
    let vec3 = |b: &[[u8; 4]]| Vec3::new(f(&b[0]), f(&b[1]), f(&b[2]));
    let bounds = Aabb {
        lo: vec3(&words[7..10]),
        hi: vec3(&words[10..13]),
    };
    let ids: Vec<u32> = ids
        .as_chunks::<4>()
        .0
        .iter()
        .map(|b| u32::from_le_bytes(*b))
        .collect();
    let bvh = Bvh::from_parts(
        BvhParts {
            bounds,
            nodes,
            lanes,
            corners,
        },
        ids,
    )
    .map_err(|e| corrupt(e.to_string()))?;
    let (normals, _) = normals.as_chunks::<36>();
    let mut normals = normals.iter().map(|t| {
        let (w, _) = t.as_chunks::<4>();
        [vec3(&w[0..3]), vec3(&w[3..6]), vec3(&w[6..9])]
    });
    let kd_values: Vec<[f32; 3]> = kd_values
        .as_chunks::<12>()
        .0
        .iter()
        .map(|b| {
            let (w, _) = b.as_chunks::<4>();
            [f(&w[0]), f(&w[1]), f(&w[2])]
        })
        .collect();
    let width = index_width(k);
    let kd_index = |i: usize| match width {
        1 => u32::from(kd_indices[i]),
        2 => u32::from(u16::from_le_bytes([
            kd_indices[2 * i],
            kd_indices[2 * i + 1],
        ])),
        _ => u32::from_le_bytes([
            kd_indices[4 * i],
            kd_indices[4 * i + 1],
            kd_indices[4 * i + 2],
            kd_indices[4 * i + 3],
        ]),
    };
    let mut shading = Vec::with_capacity(flags.len());
    let (mut normals_used, mut kd_used) = (0u32, 0u32);
    for (i, &flag) in flags.iter().enumerate() {
        let normals = match flag {
            0 => None,
            1 => {
                normals_used += 1;
                Some(normals.next().ok_or_else(|| {
                    corrupt(format!(
                        "normal flags: more than the header's {with_normals} are set"
                    ))
                })?)
            }
            _ => {
                return Err(corrupt(format!(
                    "normal flag of triangle {i} is {flag}, expected 0 or 1"
                )));
            }
        };
        let index = kd_index(i);
        if index > kd_used || index >= k {
            return Err(corrupt(format!(
                "kd index of triangle {i} is {index}, expected at most {} (kd values in order of first use)",
                kd_used.min(k - 1)
            )));
        }
        kd_used += u32::from(index == kd_used);
        shading.push(TriangleShading {
            normals,
            kd: kd_values[index as usize],
        });
    }
    if normals_used != with_normals {
        return Err(corrupt(format!(
            "normal flags: {normals_used} set, the header declares {with_normals}"
        )));
    }
    if kd_used != k {
        return Err(corrupt(format!("kd values: {kd_used} of {k} used")));
    }
    Ok(SplitObject {
        split,
        bvh,
        shading,
    })
}

#[cfg(test)]
mod tests;
