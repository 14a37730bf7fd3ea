//! The triangle records partition tasks write and build tasks read.
//!
//! A records object is a sequence of frames, each one block of kind `PartRecords` holding up
//! to [`FRAME_RECORDS`] records of [`RECORD_BYTES`] raw bytes, little-endian: u32 scene-wide
//! triangle id; 9 f64: the corners as written in the file (x, y, z of corner 0, 1, 2); u32: 1
//! if the triangle has vertex normals, else 0; 9 f32: the normals (zero without); 3 f32: kd.
//! Frames let a build task fetch the part of a records object it needs with one ranged GET.

use super::PipelineError;
use crate::shuffle::{RecordKind, decode_block, encode_block};
use glam::{DVec3, Vec3};

/// Raw bytes of one record.
pub(super) const RECORD_BYTES: usize = 128;
/// Records in a full frame (1 MiB raw).
pub(super) const FRAME_RECORDS: usize = 8192;

/// One triangle as partition tasks hand it to build tasks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PartRecord {
    /// Scene-wide triangle id.
    pub id: u32,
    /// Corner positions as written (the file's frame, double precision).
    pub corners: [DVec3; 3],
    /// Corner normals, if the face names them.
    pub normals: Option<[Vec3; 3]>,
    /// Diffuse reflectance of its material.
    pub kd: [f32; 3],
}

impl PartRecord {
    fn encode_into(&self, raw: &mut Vec<u8>) {
        raw.extend_from_slice(&self.id.to_le_bytes());
        for c in self.corners {
            for v in c.to_array() {
                raw.extend_from_slice(&v.to_le_bytes());
            }
        }
        raw.extend_from_slice(&u32::from(self.normals.is_some()).to_le_bytes());
        for n in self.normals.unwrap_or([Vec3::ZERO; 3]) {
            for v in n.to_array() {
                raw.extend_from_slice(&v.to_le_bytes());
            }
        }
        for v in self.kd {
            raw.extend_from_slice(&v.to_le_bytes());
        }
    }

    fn decode(b: &[u8]) -> Option<PartRecord> {
        let u32_at = |at: usize| u32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"));
        let f32_at = |at: usize| f32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"));
        let f64_at = |at: usize| f64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"));
        let dvec = |at: usize| DVec3::new(f64_at(at), f64_at(at + 8), f64_at(at + 16));
        let vec = |at: usize| Vec3::new(f32_at(at), f32_at(at + 4), f32_at(at + 8));
        let normals = match u32_at(76) {
            0 => None,
            1 => Some([vec(80), vec(92), vec(104)]),
            _ => return None,
        };
        Some(PartRecord {
            id: u32_at(0),
            corners: [dvec(4), dvec(28), dvec(52)],
            normals,
            kd: [f32_at(116), f32_at(120), f32_at(124)],
        })
    }
}

/// The frames of `records`, concatenated, and the byte offset where each frame starts followed
/// by the total length.
pub fn encode_frames<'a>(records: impl IntoIterator<Item = &'a PartRecord>) -> (Vec<u8>, Vec<u64>) {
    let mut bytes = Vec::new();
    let mut offsets = vec![0];
    let mut raw = Vec::with_capacity(FRAME_RECORDS * RECORD_BYTES);
    let mut count = 0;
    let mut flush = |raw: &mut Vec<u8>, count: &mut usize| {
        bytes.extend_from_slice(&encode_block(RecordKind::PartRecords, *count as u64, raw));
        offsets.push(bytes.len() as u64);
        raw.clear();
        *count = 0;
    };
    for record in records {
        record.encode_into(&mut raw);
        count += 1;
        if count == FRAME_RECORDS {
            flush(&mut raw, &mut count);
        }
    }
    if count > 0 {
        flush(&mut raw, &mut count);
    }
    (bytes, offsets)
}

/// The records of the frame `bytes` read from `key`.
pub fn decode_frame(key: &str, bytes: &[u8]) -> Result<Vec<PartRecord>, PipelineError> {
    let block = decode_block(key, bytes, RecordKind::PartRecords)
        .map_err(|e| PipelineError::Corrupt(e.to_string()))?;
    let corrupt = |what: String| PipelineError::Corrupt(format!("records frame in {key}: {what}"));
    if block.record_count.checked_mul(RECORD_BYTES as u64) != Some(block.raw.len() as u64) {
        return Err(corrupt(format!(
            "{} raw bytes for {} records of {RECORD_BYTES}",
            block.raw.len(),
            block.record_count
        )));
    }
    block
        .raw
        .chunks_exact(RECORD_BYTES)
        .enumerate()
        .map(|(i, b)| {
            PartRecord::decode(b)
                .ok_or_else(|| corrupt(format!("record {i} has a normal flag other than 0 or 1")))
        })
        .collect()
}
