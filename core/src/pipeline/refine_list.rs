//! The refine list: what the first round of a staged adaptive job leaves for the second. One
//! block per span (TraceReduce's partition 1, kind [`RecordKind::RefineList`]): the span's
//! pixels whose first pass asked for more samples ([`crate::adaptive::Decision::Refine`]), in
//! ascending order, each with the in-order f32 sum of its first-pass sample radiances, so the
//! second round continues the sum exactly where the first stopped (the pixel is then the same
//! bits as the monolithic adaptive render's). Empty when no pixel of the span needs more.

use super::PipelineError;
use super::records::{check_len, corrupt, put_vec3s, read_vec3s};
use crate::shuffle::columns::{ColumnReader, ColumnWriter};
use crate::shuffle::{RecordKind, decode_block, encode_block};
use glam::Vec3;

/// The pixels of one span that get a second round, and their first-pass sums.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RefineList {
    /// Row-major pixel indices, strictly ascending.
    pub pixels: Vec<u32>,
    /// `sums[i]`: the in-order f32 sum of pixel `pixels[i]`'s first-pass radiances.
    pub sums: Vec<[f32; 3]>,
}

impl RefineList {
    /// Checks the list against the span `start..end` it must belong to: pixels strictly
    /// ascending inside it, one sum per pixel. `key` names the block in the error.
    pub fn check(&self, key: &str, start: u64, end: u64) -> Result<(), PipelineError> {
        let inside = self
            .pixels
            .iter()
            .all(|&p| u64::from(p) >= start && u64::from(p) < end);
        let ascending = self.pixels.windows(2).all(|w| w[0] < w[1]);
        if !inside || !ascending || self.sums.len() != self.pixels.len() {
            return Err(PipelineError::Corrupt(format!(
                "shuffle block {key}: the refine list must hold ascending pixels of the span \
                 {start}..{end}, one sum each"
            )));
        }
        Ok(())
    }
}

/// Encodes a refine list.
pub fn encode_refine_list(list: &RefineList) -> Vec<u8> {
    let mut w = ColumnWriter::new();
    w.put_u32_sorted_delta(&list.pixels);
    put_vec3s(&mut w, list.sums.iter().map(|s| Vec3::from(*s)));
    encode_block(
        RecordKind::RefineList,
        list.pixels.len() as u64,
        w.as_bytes(),
    )
}

/// Decodes a block written by [`encode_refine_list`].
pub fn decode_refine_list(key: &str, bytes: &[u8]) -> Result<RefineList, PipelineError> {
    let block = decode_block(key, bytes, RecordKind::RefineList)
        .map_err(|e| PipelineError::Corrupt(e.to_string()))?;
    let mut r = ColumnReader::new(&block.raw);
    let pixels = r.read_u32_sorted_delta().map_err(|e| corrupt(key, e))?;
    check_len(key, "pixel", pixels.len(), block.record_count as usize)?;
    let sums = read_vec3s(&mut r, pixels.len(), key)?;
    r.finish().map_err(|e| corrupt(key, e))?;
    Ok(RefineList {
        pixels,
        sums: sums.into_iter().map(|v| v.to_array()).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_round_trip_bit_for_bit_and_are_checked_against_their_span() {
        let list = RefineList {
            pixels: vec![3, 4, 90],
            sums: vec![[0.5, -0.0, f32::MIN_POSITIVE], [1.0; 3], [7.25, 3.0, 1e-30]],
        };
        let bytes = encode_refine_list(&list);
        let back = decode_refine_list("k", &bytes).unwrap();
        let bits = |l: &RefineList| {
            l.sums
                .iter()
                .map(|s| s.map(f32::to_bits))
                .collect::<Vec<_>>()
        };
        assert_eq!(
            (back.pixels.clone(), bits(&back)),
            (list.pixels.clone(), bits(&list))
        );
        assert!(back.check("k", 3, 91).is_ok());
        assert_eq!(
            back.check("k", 4, 91).unwrap_err().to_string(),
            "shuffle block k: the refine list must hold ascending pixels of the span 4..91, \
             one sum each"
        );
        assert_eq!(
            decode_refine_list("k", &encode_refine_list(&RefineList::default())).unwrap(),
            RefineList::default()
        );
        let e = decode_refine_list("k", &crate::pipeline::encode_occluded(&[]))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("shuffle block k: "), "{e}");
    }
}
