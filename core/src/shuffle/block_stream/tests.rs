//! The stream gives exactly the raw bytes `decode_block` gives, and exactly its
//! errors, whatever the reader took.

use super::*;
use crate::shuffle::encode_block;

const KIND: RecordKind = RecordKind::SplitObject;

/// Compressible raw bytes of `len` bytes (words counting up, some noise).
fn raw_of(len: usize) -> Vec<u8> {
    let mut x = 0x9e37_79b9u32;
    (0..len)
        .map(|i| {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            if i % 5 == 0 {
                x as u8
            } else {
                (i / 4096) as u8
            }
        })
        .collect()
}

/// Everything the stream gives in takes of `sizes` (cycled), then whatever is left.
fn read_all(stream: &mut RawStream<'_>, sizes: &[usize]) -> Vec<u8> {
    let mut out = Vec::new();
    for &size in sizes.iter().cycle() {
        match stream.take(size) {
            Some(b) => out.extend_from_slice(b),
            None => break,
        }
    }
    while let Some(b) = stream.take(1) {
        out.extend_from_slice(b);
    }
    out
}

/// `bytes` with its header field at `at` set to `value` and the block CRC recomputed.
fn resealed(bytes: &[u8], at: usize, value: &[u8]) -> Vec<u8> {
    let mut bytes = bytes.to_vec();
    bytes[at..at + value.len()].copy_from_slice(value);
    let mut hasher = crc32fast::Hasher::new();
    hasher.update(&bytes[..32]);
    hasher.update(&bytes[BLOCK_HEADER_LEN..]);
    let crc = hasher.finalize().to_le_bytes();
    bytes[32..36].copy_from_slice(&crc);
    bytes
}

#[test]
fn gives_the_raw_bytes() {
    for len in [0, 1, 1000, CHUNK, CHUNK + 1, 3 * CHUNK + 12345] {
        let raw = raw_of(len);
        let bytes = encode_block(KIND, 1, &raw);
        for sizes in [&[1usize, 7, 4096][..], &[MAX_TAKE], &[12, 36 * 1000]] {
            let got = read_block("k", &bytes, KIND, |s| {
                assert_eq!(s.raw_len(), len as u64);
                read_all(s, sizes)
            })
            .unwrap();
            assert!(got == raw, "len {len}, sizes {sizes:?}");
        }
        let taken = read_block("k", &bytes, KIND, |s| s.take(MAX_TAKE + 1).is_none());
        assert_eq!(taken, Ok(true), "takes are at most MAX_TAKE");
    }
}

#[test]
fn errors_are_decode_blocks_whatever_the_reader_took() {
    let raw = raw_of(3 * CHUNK + 777);
    let good = encode_block(KIND, 1, &raw);
    let raw_len = raw.len() as u64;
    let last = good.len() - 1;
    let mut flipped = good.clone();
    flipped[last] ^= 1;
    let cases = [
        // Raw CRC of other bytes.
        resealed(&good, 28, &0xdead_beefu32.to_le_bytes()),
        // Declared raw lengths one short and one long.
        resealed(&good, 20, &(raw_len - 1).to_le_bytes()),
        resealed(&good, 20, &(raw_len + 1).to_le_bytes()),
        // A damaged frame (and block CRC), and the frame cut short.
        flipped.clone(),
        resealed(&flipped, 28, &good[28..32]),
        resealed(&good[..good.len() - 100], 28, &good[28..32]),
        good[..20].to_vec(),
    ];
    for bytes in &cases {
        let expected = decode_block("k", bytes, KIND).unwrap_err();
        for takes in [0usize, 3, usize::MAX] {
            let got = read_block("k", bytes, KIND, |s| {
                for _ in 0..takes {
                    if s.take(MAX_TAKE).is_none() {
                        break;
                    }
                }
            });
            assert_eq!(got, Err(expected.clone()), "takes {takes}");
        }
    }
}
