//! Tables of distinct values (vertices, kd) of a split object, numbered in order of first use,
//! with one index per use.

use std::collections::HashMap;
use std::collections::hash_map::Entry;
use std::hash::{BuildHasherDefault, Hasher};

/// Distinct values (as bit patterns, so signed zeros and NaN payloads stay apart) numbered in
/// order of first use, and the index of each use.
#[derive(Default)]
pub(super) struct Distinct {
    /// The distinct values, in order of first use.
    pub values: Vec<[f32; 3]>,
    index: HashMap<[u32; 3], u32, BuildHasherDefault<WordHasher>>,
    /// One index into `values` per use, in order.
    pub uses: Vec<u32>,
}

impl Distinct {
    /// An empty table expecting `uses` uses.
    pub fn with_capacity(uses: usize) -> Self {
        Distinct {
            values: Vec::new(),
            index: HashMap::default(),
            uses: Vec::with_capacity(uses),
        }
    }

    /// Records one use of `value`.
    pub fn push(&mut self, value: [f32; 3]) {
        let next = self.values.len() as u32;
        let i = match self.index.entry(value.map(f32::to_bits)) {
            Entry::Occupied(e) => *e.get(),
            Entry::Vacant(e) => {
                e.insert(next);
                self.values.push(value);
                next
            }
        };
        self.uses.push(i);
    }
}

/// A multiply-xor hasher for the bit patterns the tables map (millions per split): several
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
