//! The split object: one scene split as one stored blob, loadable without building anything.
//!
//! It is a shuffle block of kind `SplitObject` (zstd, checksums; see [`crate::shuffle`]) whose
//! raw bytes are the BVH's traversal form as it is in memory, then the ids and the shading, in
//! these sections (version [`SPLIT_FORMAT_VERSION`]; little-endian, floats as IEEE bits):
//!
//! | section | bytes | values |
//! |---|---|---|
//! | header | 56 | u32: format version, split id, triangle count n, 4-wide node count w, triangle pack count p, distinct vertex count v, triangles with normals c, distinct kd count k; f32: root box lo.xyz, hi.xyz |
//! | nodes | 128 w | the 4-wide nodes as in memory, root first ([`NODE_BYTES`]: 4 child boxes axis by axis, 4 child words, 4 pack counts) |
//! | pack lanes | p | u8: triangles in each `Triangle4` pack (1 to 4), in pack order |
//! | vertices | 12 v | planes of 3 f32 (x, y, z) per distinct corner position, in order of first use |
//! | corners | 12 n | planes of 3 u32 per triangle: the indices of its corners' vertices, BVH leaf order |
//! | ids | 4 n | planes of u32: global triangle id (scene order), leaf order |
//! | normal flags | n | u8: 1 if the triangle has vertex normals, else 0 |
//! | normals | 36 c | 9 f32 per triangle with normals (corner 0 xyz, 1, 2), leaf order |
//! | kd values | 12 k | 3 f32 per distinct kd, in order of first use |
//! | kd indices | 4 n | planes of u32: index of each triangle's kd value, leaf order |
//!
//! A section of "planes" holds its words' byte 0s, then their byte 1s, 2s and 3s (as the
//! shuffle columns' byte planes). "Distinct" compares bit patterns, so every value (signed
//! zeros, NaN payloads) round-trips exactly; "in order of first use" means each index is at
//! most the number of values used before it, and every value is used.
//!
//! Why this layout (measured, docs/ARCHITECTURE.md section 8): loading is decompression plus
//! linear passes into the final arrays (the nodes byte for byte, the packs four triangles at a
//! time, gathering each corner from the vertices, which are numbered in order of first use and
//! so read almost in order) and linear checks; nothing is collapsed or searched. The corners
//! refer to distinct vertices rather than being written out: written out they compress about
//! as small (zstd finds the repeated vertices itself) but are twice the raw bytes, made of
//! short matches that took zstd several times as long to undo as the vertices and indices.
//! Byte planes make the vertices, indices and ids a quarter to a half smaller stored and faster
//! to decompress (high bytes repeat); the nodes gain little from them and are stored as they
//! are. kd values repeat per material, so kd indices are a small table's; normals are stored
//! written out, as few scenes have them.
//!
//! Decoding checks everything it relies on: the version (objects of version 2 and older name
//! their version and are refused; a task rebuilds such an object from the scene as it does a
//! damaged one), the header's counts against each other and the exact raw
//! length, the BVH as [`Bvh::from_parts`] does (children in depth-first order after their
//! parent, depth, leaves inside the packs and covering them, pack sizes), vertex and kd
//! indices numbering their tables in order of first use, normal flags 0 or 1 and as many set
//! as declared. It does not check that table values are distinct (a duplicate only costs bytes;
//! re-encoding merges it), so `encode_split` of a decoded object gives back the bytes it came
//! from whenever they were written by `encode_split`, and otherwise bytes that decode to an
//! equal object.

use super::PipelineError;
use crate::bvh::{Aabb, Bvh, BvhParts, NODE_BYTES};
use crate::shuffle::columns::ColumnReader;
use crate::shuffle::{RecordKind, decode_block, encode_block};
use glam::Vec3;

mod distinct;
use distinct::Distinct;

/// Version of the layout above; bump on any change.
pub const SPLIT_FORMAT_VERSION: u32 = 3;

/// Bytes of the header section: 8 u32 and 6 f32.
const HEADER_BYTES: usize = 56;

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

/// The header's counts: triangles, 4-wide nodes, packs, distinct vertices, triangles with
/// normals, distinct kd.
#[derive(Clone, Copy)]
struct Counts {
    n: u32,
    w: u32,
    p: u32,
    v: u32,
    c: u32,
    k: u32,
}

impl Counts {
    /// The sections' lengths in bytes after the header, in order.
    fn section_lengths(self) -> [u64; 9] {
        let Counts { n, w, p, v, c, k } = self;
        let [n, w, p, v, c, k] = [n, w, p, v, c, k].map(u64::from);
        [
            w * NODE_BYTES as u64,
            p,
            12 * v,
            12 * n,
            4 * n,
            n,
            36 * c,
            12 * k,
            4 * n,
        ]
    }
}

/// Appends `words` as byte planes: byte 0 of every word, then byte 1, 2 and 3.
fn put_planes(out: &mut Vec<u8>, words: &[u32]) {
    out.reserve(4 * words.len());
    for plane in 0..4 {
        out.extend(words.iter().map(|w| w.to_le_bytes()[plane]));
    }
}

/// The words of a planes section (its length a multiple of 4), in order.
fn planes(bytes: &[u8]) -> impl ExactSizeIterator<Item = u32> + Clone + '_ {
    let len = bytes.len() / 4;
    let (b0, rest) = bytes.split_at(len);
    let (b1, rest) = rest.split_at(len);
    let (b2, b3) = rest.split_at(len);
    b0.iter()
        .zip(b1)
        .zip(b2)
        .zip(&b3[..len])
        .map(|(((&a, &b), &c), &d)| u32::from_le_bytes([a, b, c, d]))
}

/// Checks that `indices` number a table of `values` values in order of first use (each at most
/// the number used before it, every value used); the error names `what` and the first bad
/// index.
fn check_first_use(
    indices: impl Iterator<Item = u32>,
    values: u32,
    what: &str,
) -> Result<(), String> {
    let mut used = 0u32;
    for (i, index) in indices.enumerate() {
        if index > used || index >= values {
            return Err(format!(
                "{what} index {i} is {index}, expected at most {} (values in order of first use)",
                used.min(values.saturating_sub(1))
            ));
        }
        used += u32::from(index == used);
    }
    if used != values {
        return Err(format!("{what} values: {used} of {values} used"));
    }
    Ok(())
}

/// Encodes a split object as a compressed block (deterministic: the same object gives the same
/// bytes). `object.shading` holds one entry per triangle.
pub fn encode_split(object: &SplitObject) -> Vec<u8> {
    let bvh = &object.bvh;
    let n = bvh.triangle_count();
    let mut vertices = Distinct::with_capacity(3 * n);
    for t in bvh.leaf_triangles() {
        for corner in t {
            vertices.push(corner.to_array());
        }
    }
    let mut kd = Distinct::with_capacity(n);
    for s in &object.shading {
        kd.push(s.kd);
    }
    let counts = Counts {
        n: n as u32,
        w: bvh.wide_node_count() as u32,
        p: bvh.pack_count() as u32,
        v: vertices.values.len() as u32,
        c: object
            .shading
            .iter()
            .filter(|s| s.normals.is_some())
            .count() as u32,
        k: kd.values.len() as u32,
    };
    let total: u64 = counts.section_lengths().iter().sum();
    let mut raw = Vec::with_capacity(HEADER_BYTES + total as usize);
    let Counts { n, w, p, v, c, k } = counts;
    for word in [SPLIT_FORMAT_VERSION, object.split, n, w, p, v, c, k] {
        raw.extend_from_slice(&word.to_le_bytes());
    }
    let Aabb { lo, hi } = bvh.bounds();
    for x in lo.to_array().into_iter().chain(hi.to_array()) {
        raw.extend_from_slice(&x.to_le_bytes());
    }
    bvh.put_nodes(&mut raw);
    bvh.put_lanes(&mut raw);
    let vertex_bits: Vec<u32> = vertices
        .values
        .iter()
        .flatten()
        .map(|x| x.to_bits())
        .collect();
    put_planes(&mut raw, &vertex_bits);
    put_planes(&mut raw, &vertices.uses);
    put_planes(&mut raw, bvh.ids());
    raw.extend(object.shading.iter().map(|s| u8::from(s.normals.is_some())));
    for normals in object.shading.iter().filter_map(|s| s.normals.as_ref()) {
        for x in normals.iter().flat_map(|v| v.to_array()) {
            raw.extend_from_slice(&x.to_le_bytes());
        }
    }
    for x in kd.values.iter().flatten() {
        raw.extend_from_slice(&x.to_le_bytes());
    }
    put_planes(&mut raw, &kd.uses);
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
    let [split, n, w, p, v, with_normals, k] = [1, 2, 3, 4, 5, 6, 7].map(word);
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
    let counts = Counts {
        n,
        w,
        p,
        v,
        c: with_normals,
        k,
    };
    let lengths = counts.section_lengths();
    let expected: u64 = lengths.iter().sum();
    if body.len() as u64 != expected {
        return Err(corrupt(format!(
            "{} bytes after the header, whose counts call for {expected}",
            body.len()
        )));
    }
    // The lengths sum to body.len(), so each fits in usize and the splits stay in range.
    let mut rest = body;
    let [
        nodes,
        lanes,
        vertices,
        corners,
        ids,
        flags,
        normals,
        kd_values,
        kd_indices,
    ] = lengths.map(|len| {
        let (section, after) = rest.split_at(len as usize);
        rest = after;
        section
    });
    check_first_use(planes(corners), v, "vertex").map_err(corrupt)?;
    check_first_use(planes(kd_indices), k, "kd").map_err(corrupt)?;
    let f = |b: &[u8; 4]| f32::from_le_bytes(*b);
    let vec3 = |b: &[[u8; 4]]| Vec3::new(f(&b[0]), f(&b[1]), f(&b[2]));
    let bounds = Aabb {
        lo: vec3(&words[8..11]),
        hi: vec3(&words[11..14]),
    };
    let ids: Vec<u32> = planes(ids).collect();
    let vertex_bits: Vec<u32> = planes(vertices).collect();
    let (vertices, _) = vertex_bits.as_chunks::<3>();
    let mut corners = planes(corners);
    // Every index is below v = vertices.len() (checked above), and from_parts asks for each
    // triangle once, in order: the fallbacks are never taken.
    let mut vertex = || {
        let i = corners.next().unwrap_or(0) as usize;
        vertices
            .get(i)
            .map_or(Vec3::ZERO, |w| Vec3::from_array(w.map(f32::from_bits)))
    };
    let bvh = Bvh::from_parts(
        BvhParts {
            bounds,
            nodes,
            lanes,
        },
        ids,
        |_| [vertex(), vertex(), vertex()],
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
    let mut kd_indices = planes(kd_indices);
    let mut shading = Vec::with_capacity(flags.len());
    let mut normals_used = 0u32;
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
        // Every kd index is below k = kd_values.len() (checked above).
        let kd = kd_values
            .get(kd_indices.next().unwrap_or(0) as usize)
            .copied()
            .unwrap_or_default();
        shading.push(TriangleShading { normals, kd });
    }
    if normals_used != with_normals {
        return Err(corrupt(format!(
            "normal flags: {normals_used} set, the header declares {with_normals}"
        )));
    }
    Ok(SplitObject {
        split,
        bvh,
        shading,
    })
}

#[cfg(test)]
mod tests;
