//! The kd table of a split object: its distinct kd values in order of first use and one index
//! per triangle, with the fixed index width the table's size calls for.

use std::collections::HashMap;
use std::collections::hash_map::Entry;
use std::hash::{BuildHasherDefault, Hasher};

/// Bytes per kd index for a table of `values` distinct kd: 1 up to 256 values, 2 up to 65,536,
/// else 4.
pub(super) fn index_width(values: u32) -> usize {
    match values {
        0..=256 => 1,
        257..=65_536 => 2,
        _ => 4,
    }
}

/// Distinct kd values (as bit patterns, so signed zeros and NaN payloads stay apart) numbered in
/// order of first use, and the index of each use.
#[derive(Default)]
pub(super) struct KdTable {
    /// The distinct values, in order of first use.
    pub values: Vec<[f32; 3]>,
    index: HashMap<[u32; 3], u32, BuildHasherDefault<WordHasher>>,
    /// One index into `values` per use, in order.
    pub uses: Vec<u32>,
}

impl KdTable {
    /// Records one use of `kd`.
    pub fn push(&mut self, kd: [f32; 3]) {
        let next = self.values.len() as u32;
        let i = match self.index.entry(kd.map(f32::to_bits)) {
            Entry::Occupied(e) => *e.get(),
            Entry::Vacant(e) => {
                e.insert(next);
                self.values.push(kd);
                next
            }
        };
        self.uses.push(i);
    }
}

/// A multiply-xor hasher for the bit patterns the kd table maps (one per triangle): several
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
