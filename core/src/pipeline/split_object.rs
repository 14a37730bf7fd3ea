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
//! exactly. A reference column holds one LEB128 varint `d` per use: with `c` distinct values used
//! before, `d = 0` is the next new value (the value at index `c`), `1 <= d <= c` the value at
//! index `c - d` (1 is the newest). Every distinct value is used.
//!
//! Triangles of a mesh share corners (about six triangles per vertex) and materials, so this is
//! much smaller than nine floats of corners and three of kd per triangle (version 1), and
//! loading mostly decompresses and copies bytes: on the generated 1M-triangle scene the
//! corners take 9.4 MB (6.0 MB vertices, 3.3 MB references) instead of 36 MB, kd 1 MB instead of
//! 12 MB, the whole object 35 MB raw (19 MB stored) instead of 73 MB (36 MB).

use super::PipelineError;
use crate::bvh::{Aabb, Bvh, Node};
use crate::shuffle::columns::{ColumnReader, ColumnWriter};
use crate::shuffle::{RecordKind, decode_block, encode_block};
use glam::Vec3;
use std::collections::HashMap;
use std::collections::hash_map::Entry;

/// Version of the column layout above; bump on any change.
pub const SPLIT_FORMAT_VERSION: u32 = 2;

/// Per-triangle shading data carried by a split.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleShading {
    pub normals: Option<[Vec3; 3]>,
    pub kd: [f32; 3],
}

/// A decoded split: its BVH (triangles in leaf order) and the shading data in the same order.
#[derive(Clone, Debug, PartialEq)]
pub struct SplitObject {
    pub split: u32,
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
    index: HashMap<[u32; 3], u32>,
    refs: Vec<u8>,
}

impl Distinct {
    fn push(&mut self, value: [f32; 3]) {
        let seen = self.index.len() as u32;
        match self.index.entry(value.map(f32::to_bits)) {
            Entry::Occupied(e) => put_varint(&mut self.refs, seen - e.get()),
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

fn put_varint(bytes: &mut Vec<u8>, mut value: u32) {
    while value >= 0x80 {
        bytes.push((value as u8 & 0x7f) | 0x80);
        value >>= 7;
    }
    bytes.push(value as u8);
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
        let (&byte, rest) = self.bytes.split_first()?;
        let d = if byte < 0x80 {
            self.bytes = rest;
            u32::from(byte)
        } else {
            self.long_varint()?
        };
        if d == 0 {
            (self.seen < self.distinct).then(|| {
                self.seen += 1;
                self.seen - 1
            })
        } else {
            self.seen.checked_sub(d)
        }
    }

    /// A varint of 2 to 5 bytes (at most 32 bits).
    #[cold]
    fn long_varint(&mut self) -> Option<u32> {
        let mut d = 0u32;
        for shift in (0..35).step_by(7) {
            let (&byte, rest) = self.bytes.split_first()?;
            self.bytes = rest;
            let bits = u32::from(byte & 0x7f);
            if shift == 28 && bits > 0x0f {
                return None;
            }
            d |= bits << shift;
            if byte & 0x80 == 0 {
                return Some(d);
            }
        }
        None
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
mod tests {
    use super::*;

    fn sample_object() -> SplitObject {
        let triangles: Vec<[Vec3; 3]> = (0..40)
            .map(|i| {
                let o = Vec3::new(i as f32, (i % 7) as f32, (i % 3) as f32);
                [o, o + Vec3::X, o + Vec3::Y]
            })
            .collect();
        let ids: Vec<u32> = (0..40).map(|i| i * 3 + 1).collect();
        let bvh = Bvh::build(triangles, ids);
        let shading = (0..40)
            .map(|i| TriangleShading {
                normals: (i % 2 == 0).then_some([Vec3::Z, Vec3::Y, Vec3::X]),
                kd: [0.1 * (i % 5) as f32, 0.5, 0.25],
            })
            .collect();
        SplitObject {
            split: 3,
            bvh,
            shading,
        }
    }

    #[test]
    fn round_trips_exactly() {
        let object = sample_object();
        let bytes = encode_split(&object);
        assert_eq!(decode_split("k", &bytes).unwrap(), object);
        assert_eq!(encode_split(&object), bytes, "deterministic");
    }

    #[test]
    fn corruption_is_an_error_naming_the_key() {
        let mut bytes = encode_split(&sample_object());
        let last = bytes.len() - 1;
        bytes[last] ^= 0x40;
        let e = decode_split("jobs/j/splits/00003.bin", &bytes)
            .unwrap_err()
            .to_string();
        assert!(e.contains("jobs/j/splits/00003.bin"), "{e}");
        let e = decode_split("jobs/j/splits/00003.bin", &bytes[..20])
            .unwrap_err()
            .to_string();
        assert!(e.contains("jobs/j/splits/00003.bin"), "{e}");
    }
    use crate::bvh::tests::Rng;

    /// A grid mesh of `n` triangles sharing corners (with signed zeros), some with vertex
    /// normals (one of them NaN with a payload), kd from a few materials.
    fn mesh_object(n: u32) -> SplitObject {
        let mut rng = Rng(0x1234_5678);
        let vertex = |i: u32| {
            let (x, y) = (i % 17, i / 17);
            let z = if (x + y) % 3 == 0 { -0.0 } else { 0.0 };
            Vec3::new(x as f32 * 0.5, y as f32 * 0.25, z)
        };
        let triangles: Vec<[Vec3; 3]> = (0..n)
            .map(|i| {
                let q = i / 2;
                let (a, b, c, d) = (q, q + 1, q + 17, q + 18);
                if i % 2 == 0 {
                    [vertex(a), vertex(b), vertex(c)]
                } else {
                    [vertex(b), vertex(d), vertex(c)]
                }
            })
            .collect();
        let ids: Vec<u32> = (0..n).map(|i| 7 * i + 2).collect();
        let bvh = Bvh::build(triangles, ids);
        let nan = f32::from_bits(0x7fc0_1234);
        let shading = (0..n)
            .map(|i| TriangleShading {
                normals: match rng.next() % 4 {
                    0 => None,
                    1 => Some([Vec3::Y, Vec3::new(0.0, 1.0, -0.0), Vec3::Y]),
                    2 => Some([Vec3::new(nan, 0.0, 1.0), Vec3::Z, Vec3::X]),
                    _ => Some([Vec3::splat(i as f32); 3]),
                },
                kd: [
                    0.25 * (rng.next() % 3) as f32,
                    0.5,
                    if i % 5 == 0 { -0.0 } else { 0.0 },
                ],
            })
            .collect();
        SplitObject {
            split: 9,
            bvh,
            shading,
        }
    }

    #[test]
    fn round_trips_every_bit() {
        for n in [0, 1, 2, 5, 1000] {
            let object = mesh_object(n);
            let bytes = encode_split(&object);
            let decoded = decode_split("k", &bytes).unwrap();
            // `==` on floats ignores the sign of zero and fails on NaN: compare encodings too.
            assert_eq!(encode_split(&decoded), bytes, "{n} triangles");
            assert_eq!(decoded.bvh, object.bvh);
            assert_eq!(decoded.bvh.triangle_count(), n as usize);
            assert_eq!(decoded.shading.len(), n as usize);
        }
    }

    #[test]
    fn parts_gives_the_leaf_order_triangles() {
        let object = mesh_object(300);
        let (_, triangles, ids) = object.bvh.parts();
        assert_eq!(triangles.len(), 300);
        let again = mesh_object(300);
        let (_, built, _) = again.bvh.parts();
        assert_eq!(triangles, built);
        // Every triangle is one of the grid's, with its own id: rebuild from the parts.
        let rebuilt = Bvh::build(triangles.clone(), ids.to_vec());
        assert_eq!(rebuilt.parts().1, triangles);
    }

    #[test]
    fn shared_corners_are_stored_once() {
        let columns = columns_of(&mesh_object(1000));
        let (Column::F32(vertices), Column::Bytes(refs)) = (&columns[4], &columns[5]) else {
            panic!("column types");
        };
        // 1000 triangles over a grid of 17 x 31 points; one byte per corner reference.
        assert!(vertices.len() <= 3 * 17 * 31, "{}", vertices.len());
        assert_eq!(refs.len(), 3000);
    }

    /// The columns of an encoded object, to damage one and seal it again.
    #[derive(Clone, Debug)]
    enum Column {
        U32(Vec<u32>),
        F32(Vec<f32>),
        Bytes(Vec<u8>),
    }

    fn columns_of(object: &SplitObject) -> Vec<Column> {
        let raw = decode_block("k", &encode_split(object), RecordKind::SplitObject)
            .unwrap()
            .raw;
        let mut r = ColumnReader::new(&raw);
        let mut out = vec![Column::U32(r.read_u32().unwrap())];
        for kind in "fuufbubfbfb".chars() {
            out.push(match kind {
                'u' => Column::U32(r.read_u32().unwrap()),
                'f' => Column::F32(r.read_f32().unwrap()),
                _ => Column::Bytes(r.read_bytes().unwrap().to_vec()),
            });
        }
        r.finish().unwrap();
        out
    }

    fn seal(columns: &[Column]) -> Vec<u8> {
        let mut w = ColumnWriter::new();
        for c in columns {
            match c {
                Column::U32(v) => w.put_u32(v),
                Column::F32(v) => w.put_f32(v),
                Column::Bytes(v) => w.put_bytes(v),
            }
        }
        encode_block(RecordKind::SplitObject, 0, w.as_bytes())
    }

    fn decode_err(columns: &[Column]) -> String {
        let key = "jobs/j/splits/00009.bin";
        let e = decode_split(key, &seal(columns)).unwrap_err().to_string();
        assert!(e.contains(key), "{e}");
        e
    }

    fn u32s(c: &mut Column) -> &mut Vec<u32> {
        match c {
            Column::U32(v) => v,
            _ => panic!("not a u32 column"),
        }
    }

    fn bytes(c: &mut Column) -> &mut Vec<u8> {
        match c {
            Column::Bytes(v) => v,
            _ => panic!("not a bytes column"),
        }
    }

    #[test]
    fn hostile_columns_are_errors_naming_the_key() {
        let good = columns_of(&mesh_object(64));
        assert!(decode_split("k", &seal(&good)).is_ok());
        let damaged = |f: &dyn Fn(&mut Vec<Column>)| {
            let mut c = good.clone();
            f(&mut c);
            decode_err(&c)
        };
        // Version 1 objects (and anything else) name the version.
        let e = damaged(&|c| u32s(&mut c[0])[0] = 1);
        assert!(e.contains("format version 1, this build reads 2"), "{e}");
        let e = damaged(&|c| u32s(&mut c[0]).truncate(5));
        assert!(e.contains("header has 5 values"), "{e}");
        // Counts that disagree with the columns.
        for at in 2..8 {
            let e = damaged(&|c| u32s(&mut c[0])[at] += 1);
            assert!(
                e.contains("expected") || e.contains("disagree"),
                "{at}: {e}"
            );
        }
        // References: past the newest value, a new value beyond the distinct count, values
        // never used, trailing or missing bytes, overlong varints.
        for column in [5, 9, 11] {
            let e = damaged(&|c| {
                let refs = bytes(&mut c[column]);
                let last = refs.len() - 1;
                refs[last] = 0x7f;
            });
            assert!(e.contains("references"), "{column}: {e}");
            let e = damaged(&|c| bytes(&mut c[column]).push(1));
            assert!(e.contains("references"), "{column}: {e}");
            let e = damaged(&|c| {
                bytes(&mut c[column]).pop();
            });
            assert!(e.contains("references"), "{column}: {e}");
            let e = damaged(&|c| {
                let refs = bytes(&mut c[column]);
                refs[0] = 0x80;
                refs.insert(1, 0xff);
                refs.insert(2, 0xff);
                refs.insert(3, 0xff);
                refs.insert(4, 0x7f);
            });
            assert!(e.contains("references"), "{column}: {e}");
        }
        let e = damaged(&|c| {
            // A new value where an old one was used: one value too many.
            let refs = bytes(&mut c[5]);
            let at = refs.iter().rposition(|&b| b != 0).unwrap();
            refs[at] = 0;
        });
        assert!(e.contains("references"), "{e}");
        // BVH structure: a leaf that repeats triangles of another, a child before its parent.
        let e = damaged(&|c| {
            let counts = u32s(&mut c[3]).clone();
            let leaves: Vec<usize> = (0..counts.len()).filter(|&i| counts[i] > 0).collect();
            let first = u32s(&mut c[2])[leaves[0]];
            u32s(&mut c[2])[leaves[1]] = first;
        });
        assert!(e.contains("leaf starts at triangle"), "{e}");
        let e = damaged(&|c| u32s(&mut c[2])[0] = 0);
        assert!(e.contains("out of order"), "{e}");
    }

    #[test]
    fn random_damage_never_panics() {
        let good = columns_of(&mesh_object(40));
        let raw = {
            let mut w = ColumnWriter::new();
            for c in &good {
                match c {
                    Column::U32(v) => w.put_u32(v),
                    Column::F32(v) => w.put_f32(v),
                    Column::Bytes(v) => w.put_bytes(v),
                }
            }
            w.into_bytes()
        };
        let mut rng = Rng(99);
        let mut errors = 0;
        for _ in 0..3000 {
            let mut damaged = raw.clone();
            for _ in 0..1 + (rng.next() % 3) {
                let at = (rng.next() % damaged.len() as u64) as usize;
                match rng.next() % 4 {
                    0 => damaged[at] = rng.next() as u8,
                    1 => damaged[at] ^= 1 << (rng.next() % 8),
                    2 => damaged.truncate(at),
                    _ => damaged.insert(at, rng.next() as u8),
                }
                if damaged.is_empty() {
                    damaged.push(0);
                }
            }
            let bytes = encode_block(RecordKind::SplitObject, 0, &damaged);
            errors += usize::from(decode_split("k", &bytes).is_err());
        }
        assert!(errors > 2000, "{errors} errors");
    }
}
