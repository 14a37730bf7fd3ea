//! The split object: one scene split as one stored blob, loadable without building anything.
//!
//! It is a shuffle block of kind `SplitObject` (zstd, checksums; see [`crate::shuffle`]) whose
//! raw bytes are these columns, in order (version [`SPLIT_FORMAT_VERSION`]):
//!
//! | column | type | values |
//! |---|---|---|
//! | header | u32 | format version, split id, triangle count n, node count m, triangles with normals |
//! | node boxes | f32 | 6 per node: lo.xyz, hi.xyz |
//! | node first | u32 | m: first child, or first triangle of a leaf |
//! | node count | u32 | m: 0 for an interior node, else the leaf's triangle count |
//! | corners | f32 | 9 per triangle, BVH leaf order |
//! | ids | u32 | n: global triangle id (scene order), leaf order |
//! | has normals | bytes | n: 1 if the triangle has vertex normals |
//! | normals | f32 | 9 per triangle with normals, leaf order |
//! | kd | f32 | 3 per triangle, leaf order |

use super::PipelineError;
use crate::bvh::{Aabb, Bvh, Node};
use crate::shuffle::columns::{ColumnReader, ColumnWriter};
use crate::shuffle::{RecordKind, decode_block, encode_block};
use glam::Vec3;

/// Version of the column layout above; bump on any change.
pub const SPLIT_FORMAT_VERSION: u32 = 1;

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

/// Encodes a split object as a compressed block.
pub fn encode_split(object: &SplitObject) -> Vec<u8> {
    let (nodes, triangles, ids) = object.bvh.parts();
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
    let corners: Vec<f32> = triangles
        .iter()
        .flatten()
        .flat_map(|v| v.to_array())
        .collect();
    w.put_f32(&corners);
    w.put_u32(ids);
    let flags: Vec<u8> = object
        .shading
        .iter()
        .map(|s| u8::from(s.normals.is_some()))
        .collect();
    w.put_bytes(&flags);
    let normals: Vec<f32> = object
        .shading
        .iter()
        .filter_map(|s| s.normals)
        .flatten()
        .flat_map(|v| v.to_array())
        .collect();
    w.put_f32(&normals);
    w.put_f32(&object.shading.iter().flat_map(|s| s.kd).collect::<Vec<_>>());
    encode_block(
        RecordKind::SplitObject,
        triangles.len() as u64,
        w.as_bytes(),
    )
}

/// Decodes and validates a split object read from `key`.
pub fn decode_split(key: &str, bytes: &[u8]) -> Result<SplitObject, PipelineError> {
    let block = decode_block(key, bytes, RecordKind::SplitObject)
        .map_err(|e| PipelineError::Corrupt(e.to_string()))?;
    let corrupt = |what: String| PipelineError::Corrupt(format!("split object {key}: {what}"));
    let mut r = ColumnReader::new(&block.raw);
    let col = |e: crate::shuffle::columns::ColumnError| corrupt(e.to_string());
    let header = r.read_u32().map_err(col)?;
    let [version, split, n, m, with_normals] = header[..] else {
        return Err(corrupt(format!(
            "header has {} values, expected 5",
            header.len()
        )));
    };
    if version != SPLIT_FORMAT_VERSION {
        return Err(corrupt(format!(
            "format version {version}, this build reads {SPLIT_FORMAT_VERSION}"
        )));
    }
    let (n, m) = (n as usize, m as usize);
    let boxes = r.read_f32().map_err(col)?;
    let firsts = r.read_u32().map_err(col)?;
    let counts = r.read_u32().map_err(col)?;
    let corners = r.read_f32().map_err(col)?;
    let ids = r.read_u32().map_err(col)?;
    let flags = r.read_bytes().map_err(col)?.to_vec();
    let normals = r.read_f32().map_err(col)?;
    let kd = r.read_f32().map_err(col)?;
    r.finish().map_err(col)?;
    let lengths = [
        (boxes.len(), 6 * m, "node boxes"),
        (firsts.len(), m, "node firsts"),
        (counts.len(), m, "node counts"),
        (corners.len(), 9 * n, "corners"),
        (ids.len(), n, "ids"),
        (flags.len(), n, "normal flags"),
        (normals.len(), 9 * with_normals as usize, "normals"),
        (kd.len(), 3 * n, "kd"),
    ];
    for (found, expected, what) in lengths {
        if found != expected {
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
    let nodes = (0..m)
        .map(|i| Node {
            bounds: Aabb {
                lo: Vec3::from_slice(&boxes[6 * i..6 * i + 3]),
                hi: Vec3::from_slice(&boxes[6 * i + 3..6 * i + 6]),
            },
            first: firsts[i],
            count: counts[i],
        })
        .collect();
    let vec3 = |s: &[f32], i: usize| Vec3::from_slice(&s[3 * i..3 * i + 3]);
    let triangles = (0..n)
        .map(|t| {
            [
                vec3(&corners, 3 * t),
                vec3(&corners, 3 * t + 1),
                vec3(&corners, 3 * t + 2),
            ]
        })
        .collect();
    let bvh = Bvh::from_parts(nodes, triangles, ids).map_err(|e| corrupt(e.to_string()))?;
    let mut next_normal = 0usize;
    let shading = (0..n)
        .map(|t| {
            let normals = (flags[t] == 1).then(|| {
                let i = next_normal;
                next_normal += 1;
                [
                    vec3(&normals, 3 * i),
                    vec3(&normals, 3 * i + 1),
                    vec3(&normals, 3 * i + 2),
                ]
            });
            TriangleShading {
                normals,
                kd: [kd[3 * t], kd[3 * t + 1], kd[3 * t + 2]],
            }
        })
        .collect();
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
}
