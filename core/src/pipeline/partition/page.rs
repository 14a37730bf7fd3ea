//! The vertex object of one scene range: the positions (f64, as written) and normals (f32) its
//! lines define, as one block of kind `VertexPage` whose record count is the position count.
//! Raw bytes: 24 per position (x, y, z as f64), then 12 per normal (x, y, z as f32), all
//! little-endian.

use super::PipelineError;
use crate::shuffle::{RecordKind, decode_block, encode_block};
use glam::{DVec3, Vec3};

/// The vertices one range defines.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexPage {
    /// Positions as written, double precision.
    pub positions: Vec<DVec3>,
    /// Normals.
    pub normals: Vec<Vec3>,
}

impl VertexPage {
    /// Bytes it takes in memory, for cache budgets.
    pub(super) fn memory_bytes(&self) -> u64 {
        (self.positions.len() * 24 + self.normals.len() * 12) as u64
    }
}

/// The block of `positions` and `normals`.
pub(super) fn encode_page(positions: &[DVec3], normals: &[Vec3]) -> Vec<u8> {
    let mut raw = Vec::with_capacity(positions.len() * 24 + normals.len() * 12);
    for p in positions {
        for c in p.to_array() {
            raw.extend_from_slice(&c.to_le_bytes());
        }
    }
    for n in normals {
        for c in n.to_array() {
            raw.extend_from_slice(&c.to_le_bytes());
        }
    }
    encode_block(RecordKind::VertexPage, positions.len() as u64, &raw)
}

/// Decodes the page stored at `key`, which must hold `normals` normals.
pub fn decode_page(key: &str, bytes: &[u8], normals: u64) -> Result<VertexPage, PipelineError> {
    let block = decode_block(key, bytes, RecordKind::VertexPage)
        .map_err(|e| PipelineError::Corrupt(e.to_string()))?;
    let positions = block.record_count;
    let expected = positions
        .checked_mul(24)
        .and_then(|p| p.checked_add(normals.checked_mul(12)?));
    if expected != Some(block.raw.len() as u64) {
        return Err(PipelineError::Corrupt(format!(
            "vertex object {key}: {} raw bytes, but {positions} positions and {normals} normals \
             take {}",
            block.raw.len(),
            positions * 24 + normals * 12
        )));
    }
    let (pos_bytes, nrm_bytes) = block.raw.split_at(positions as usize * 24);
    let f64_at = |b: &[u8]| f64::from_le_bytes(b.try_into().expect("8 bytes"));
    let f32_at = |b: &[u8]| f32::from_le_bytes(b.try_into().expect("4 bytes"));
    Ok(VertexPage {
        positions: pos_bytes
            .chunks_exact(24)
            .map(|c| DVec3::new(f64_at(&c[0..8]), f64_at(&c[8..16]), f64_at(&c[16..24])))
            .collect(),
        normals: nrm_bytes
            .chunks_exact(12)
            .map(|c| Vec3::new(f32_at(&c[0..4]), f32_at(&c[4..8]), f32_at(&c[8..12])))
            .collect(),
    })
}
