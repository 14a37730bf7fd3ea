//! The split object: one scene split as one stored blob, loadable without building anything.
//!
//! It is a shuffle block of kind `SplitObject` (zstd, checksums; see [`crate::shuffle`]) whose
//! raw bytes are these columns, in order (version [`SPLIT_FORMAT_VERSION`]):
//!
//! | column | type | values |
//! |---|---|---|
//! | header | u32 | format version, split id, triangle count n, node count m, triangles with normals, distinct vertices, distinct normals, distinct kd |
//! | node boxes | f32 | 6 per node: lo.xyz, hi.xyz |
//! | node first | u32 | m: first child, or first triangle of a leaf |
//! | node count | u32 | m: 0 for an interior node, else the leaf's triangle count |
//! | vertices | f32 | 3 per distinct corner position (x, y, z), in order of first use |
//! | corners | bytes | 3 references to vertices per triangle, BVH leaf order |
//! | ids | u32 | n: global triangle id (scene order), leaf order |
//! | has normals | bytes | n: 1 if the triangle has vertex normals |
//! | normal vectors | f32 | 3 per distinct vertex normal, in order of first use |
//! | normals | bytes | 3 references to normal vectors per triangle with normals, leaf order |
//! | kd values | f32 | 3 per distinct kd, in order of first use |
//! | kd | bytes | 1 reference to kd values per triangle, leaf order |
//!
//! "Distinct" compares bit patterns, so every value (signed zeros, NaN payloads) round-trips
//! exactly. A reference column holds one LEB128 varint `d` per use (`shuffle::varint`, at most
//! 32 bits): with `c` distinct values used before, `d = 0` is the next new value (the value at
//! index `c`), `1 <= d <= c` the value at index `c - d` (1 is the newest). Every distinct value
//! is used.
//!
//! Triangles of a mesh share corners (about six triangles per vertex) and materials, so this is
//! much smaller than nine floats of corners and three of kd per triangle (version 1), and
//! loading mostly decompresses and copies bytes: on the generated 1M-triangle scene the
//! corners take 9.4 MB (6.0 MB vertices, 3.3 MB references) instead of 36 MB, kd 1 MB instead of
//! 12 MB, the whole object 35 MB raw (19 MB stored) instead of 73 MB (36 MB).

use super::PipelineError;
use crate::bvh::{Aabb, Bvh, Node};
use crate::shuffle::columns::{ColumnReader, ColumnWriter};
use crate::shuffle::varint;
use crate::shuffle::{RecordKind, decode_block, encode_block};
use glam::Vec3;
use std::collections::HashMap;
use std::collections::hash_map::Entry;
use std::hash::{BuildHasherDefault, Hasher};

/// Version of the column layout above; bump on any change.
pub const SPLIT_FORMAT_VERSION: u32 = 2;

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

/// Encodes a split object as a compressed block.
pub fn encode_split(object: &SplitObject) -> Vec<u8> {
    let (nodes, triangles, ids) = object.bvh.parts();
    let mut vertices = Distinct::default();
    for corner in triangles.iter().flatten() {
        vertices.push(corner.to_array());
    }
    let mut normals = Distinct::default();
    let mut kd = Distinct::default();
    for s in &object.shading {
        for normal in s.normals.iter().flatten() {
            normals.push(normal.to_array());
        }
        kd.push(s.kd);
    }
    let with_normals = object
        .shading
        .iter()
        .filter(|s| s.normals.is_some())
        .count();
    let mut w = ColumnWriter::new();
    w.put_u32(&[
        SPLIT_FORMAT_VERSION,
        object.split,
        triangles.len() as u32,
        nodes.len() as u32,
        with_normals as u32,
        vertices.count(),
        normals.count(),
        kd.count(),
    ]);
    let boxes: Vec<f32> = nodes
        .iter()
        .flat_map(|n| {
            n.bounds
                .lo
                .to_array()
                .into_iter()
                .chain(n.bounds.hi.to_array())
        })
        .collect();
    w.put_f32(&boxes);
    w.put_u32(&nodes.iter().map(|n| n.first).collect::<Vec<_>>());
    w.put_u32(&nodes.iter().map(|n| n.count).collect::<Vec<_>>());
    vertices.put(&mut w);
    w.put_u32(ids);
    let flags: Vec<u8> = object
        .shading
        .iter()
        .map(|s| u8::from(s.normals.is_some()))
        .collect();
    w.put_bytes(&flags);
    normals.put(&mut w);
    kd.put(&mut w);
    encode_block(
        RecordKind::SplitObject,
        triangles.len() as u64,
        w.as_bytes(),
    )
}

/// The distinct values of a column in order of first use and a reference to them per use (see
/// the module docs).
#[derive(Default)]
struct Distinct {
    values: Vec<f32>,
    index: HashMap<[u32; 3], u32, BuildHasherDefault<WordHasher>>,
    refs: Vec<u8>,
}

/// A multiply-xor hasher for the bit patterns `Distinct` maps (millions per split): several
/// times faster than the standard library's SipHash, whose resistance to chosen keys buys
/// nothing here. The hasher only affects speed, never the bytes: values are numbered in order
/// of first use, whatever the map's layout.
#[derive(Default)]
struct WordHasher(u64);

impl WordHasher {
    const K: u64 = 0x9E37_79B9_7F4A_7C15;

    #[inline]
    fn add(&mut self, word: u64) {
        self.0 = (self.0.rotate_left(23) ^ word).wrapping_mul(Self::K);
    }
}

impl Hasher for WordHasher {
    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        let (words, rest) = bytes.as_chunks::<8>();
        for w in words {
            self.add(u64::from_le_bytes(*w));
        }
        let mut last = [0u8; 8];
        last[..rest.len()].copy_from_slice(rest);
        self.add(u64::from_le_bytes(last) ^ ((rest.len() as u64) << 56));
    }

    #[inline]
    fn write_usize(&mut self, n: usize) {
        self.add(n as u64);
    }

    #[inline]
    fn finish(&self) -> u64 {
        // Fold the high bits, which the multiplications mixed well, into the low ones.
        let h = self.0 ^ (self.0 >> 29);
        h.wrapping_mul(Self::K) ^ (h >> 32)
    }
}

impl Distinct {
    fn push(&mut self, value: [f32; 3]) {
        let seen = self.index.len() as u32;
        match self.index.entry(value.map(f32::to_bits)) {
            Entry::Occupied(e) => varint::write(&mut self.refs, u64::from(seen - e.get())),
            Entry::Vacant(e) => {
                e.insert(seen);
                self.values.extend(value);
                self.refs.push(0);
            }
        }
    }

    fn count(&self) -> u32 {
        self.index.len() as u32
    }

    /// Writes the values column, then the references column.
    fn put(&self, w: &mut ColumnWriter) {
        w.put_f32(&self.values);
        w.put_bytes(&self.refs);
    }
}

/// Reads a references column (see the module docs) one use at a time.
struct References<'a> {
    bytes: &'a [u8],
    seen: u32,
    distinct: u32,
}

impl<'a> References<'a> {
    fn new(bytes: &'a [u8], distinct: usize) -> Self {
        References {
            bytes,
            seen: 0,
            // `distinct` counts the values of a column, so it is below 2^32.
            distinct: u32::try_from(distinct).unwrap_or(u32::MAX),
        }
    }

    /// The index of the next use's value; `None` if the column ends, a varint is malformed or
    /// the reference points outside the values.
    #[inline]
    fn next(&mut self) -> Option<u32> {
        let d = varint::read_u32(&mut self.bytes).ok()?;
        if d == 0 {
            (self.seen < self.distinct).then(|| {
                self.seen += 1;
                self.seen - 1
            })
        } else {
            self.seen.checked_sub(d)
        }
    }

    /// True when every byte was read and every value was used.
    fn is_done(&self) -> bool {
        self.bytes.is_empty() && self.seen == self.distinct
    }
}

/// Decodes and validates a split object read from `key`.
pub fn decode_split(key: &str, bytes: &[u8]) -> Result<SplitObject, PipelineError> {
    let block = decode_block(key, bytes, RecordKind::SplitObject)
        .map_err(|e| PipelineError::Corrupt(e.to_string()))?;
    let corrupt = |what: String| PipelineError::Corrupt(format!("split object {key}: {what}"));
    let mut r = ColumnReader::new(&block.raw);
    let col = |e: crate::shuffle::columns::ColumnError| corrupt(e.to_string());
    let header = r.read_u32().map_err(col)?;
    let version = header.first().copied().unwrap_or(0);
    if version != SPLIT_FORMAT_VERSION {
        return Err(corrupt(format!(
            "format version {version}, this build reads {SPLIT_FORMAT_VERSION}"
        )));
    }
    let [_, split, n, m, with_normals, v, w, k] = header[..] else {
        return Err(corrupt(format!(
            "header has {} values, expected 8",
            header.len()
        )));
    };
    let boxes = r.read_f32_planes().map_err(col)?;
    let firsts = r.read_u32_planes().map_err(col)?;
    let counts = r.read_u32_planes().map_err(col)?;
    let vertices = r.read_f32_planes().map_err(col)?;
    let corner_refs = r.read_bytes().map_err(col)?;
    let ids = r.read_u32_planes().map_err(col)?;
    let flags = r.read_bytes().map_err(col)?;
    let normal_values = r.read_f32_planes().map_err(col)?;
    let normal_refs = r.read_bytes().map_err(col)?;
    let kd_values = r.read_f32_planes().map_err(col)?;
    let kd_refs = r.read_bytes().map_err(col)?;
    r.finish().map_err(col)?;
    let lengths = [
        (boxes.len(), 6 * u64::from(m), "node boxes"),
        (firsts.len(), u64::from(m), "node firsts"),
        (counts.len(), u64::from(m), "node counts"),
        (vertices.len(), 3 * u64::from(v), "vertices"),
        (ids.len(), u64::from(n), "ids"),
        (flags.len(), u64::from(n), "normal flags"),
        (normal_values.len(), 3 * u64::from(w), "normal vectors"),
        (kd_values.len(), 3 * u64::from(k), "kd values"),
    ];
    for (found, expected, what) in lengths {
        if found as u64 != expected {
            return Err(corrupt(format!(
                "{what}: {found} values, expected {expected}"
            )));
        }
    }
    if flags.iter().filter(|&&f| f == 1).count() != with_normals as usize
        || flags.iter().any(|&f| f > 1)
    {
        return Err(corrupt("normal flags disagree with the header".into()));
    }
    // Every use takes at least one byte of its references column.
    let uses = [
        (corner_refs.len(), 3 * u64::from(n), "corners"),
        (normal_refs.len(), 3 * u64::from(with_normals), "normals"),
        (kd_refs.len(), u64::from(n), "kd"),
    ];
    for (found, needed, what) in uses {
        if (found as u64) < needed {
            return Err(corrupt(format!(
                "{what}: {found} bytes of references for {needed} uses"
            )));
        }
    }
    // From here on every count (n, m and the distinct counts) is bounded by the length of a
    // column just read, so the allocations below are bounded by the input.
    let n = ids.len();
    let vec3 = |w: [u32; 3]| Vec3::from_array(w.map(f32::from_bits));
    let nodes = boxes
        .groups::<6>()
        .zip(firsts.u32s())
        .zip(counts.u32s())
        .map(|((b, first), count)| Node {
            bounds: Aabb {
                lo: vec3([b[0], b[1], b[2]]),
                hi: vec3([b[3], b[4], b[5]]),
            },
            first,
            count,
        })
        .collect();
    let vertices: Vec<Vec3> = vertices.groups::<3>().map(vec3).collect();
    let bad_refs = |what: &str| corrupt(format!("{what}: malformed or out-of-range references"));
    let mut refs = References::new(corner_refs, vertices.len());
    let mut corners = Vec::with_capacity(n);
    for _ in 0..n {
        match (refs.next(), refs.next(), refs.next()) {
            (Some(a), Some(b), Some(c)) => corners.push([a, b, c]),
            _ => return Err(bad_refs("corners")),
        }
    }
    if !refs.is_done() {
        return Err(bad_refs("corners"));
    }
    // Every reference is below vertices.len() (checked while reading them), and from_parts
    // asks only for triangles below n = corners.len().
    let vertex = |i: u32| vertices.get(i as usize).copied().unwrap_or(Vec3::ZERO);
    let bvh = Bvh::from_parts(nodes, ids.u32s().collect(), |t| {
        corners.get(t).map_or([Vec3::ZERO; 3], |&[a, b, c]| {
            [vertex(a), vertex(b), vertex(c)]
        })
    })
    .map_err(|e| corrupt(e.to_string()))?;
    drop(corners);
    let normal_values: Vec<Vec3> = normal_values.groups::<3>().map(vec3).collect();
    let normal = |i: u32| normal_values.get(i as usize).copied().unwrap_or(Vec3::ZERO);
    let kd_values: Vec<[f32; 3]> = kd_values
        .groups::<3>()
        .map(|w| w.map(f32::from_bits))
        .collect();
    let mut normal_refs = References::new(normal_refs, normal_values.len());
    let mut kd_refs = References::new(kd_refs, kd_values.len());
    let mut shading = Vec::with_capacity(n);
    for &flag in flags {
        let normals = if flag == 1 {
            let mut three = || {
                Some([
                    normal_refs.next()?,
                    normal_refs.next()?,
                    normal_refs.next()?,
                ])
            };
            Some(three().ok_or_else(|| bad_refs("normals"))?.map(normal))
        } else {
            None
        };
        let kd = kd_refs
            .next()
            .and_then(|i| kd_values.get(i as usize))
            .ok_or_else(|| bad_refs("kd"))?;
        shading.push(TriangleShading { normals, kd: *kd });
    }
    if !normal_refs.is_done() {
        return Err(bad_refs("normals"));
    }
    if !kd_refs.is_done() {
        return Err(bad_refs("kd"));
    }
    Ok(SplitObject {
        split,
        bvh,
        shading,
    })
}

#[cfg(test)]
mod tests;
