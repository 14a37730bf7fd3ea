use super::*;

fn sample_raw() -> Vec<u8> {
    (0..64u32).flat_map(|i| (i * 7).to_le_bytes()).collect()
}

fn decode_err(bytes: &[u8], kind: RecordKind) -> BlockError {
    match decode_block("jobs/j/cast-map/00001/part-00002", bytes, kind) {
        Ok(block) => panic!("decoded corrupt bytes as {block:?}"),
        Err(e) => e,
    }
}

#[test]
fn round_trips_every_kind_and_size() {
    for kind in RecordKind::ALL {
        for raw in [Vec::new(), vec![9], sample_raw(), vec![0u8; 1 << 20]] {
            let bytes = encode_block(kind, 77, &raw);
            assert_eq!(&bytes[..8], b"HORTBLK\0");
            let block = decode_block("k", &bytes, kind).unwrap();
            assert_eq!(
                block,
                Block {
                    kind,
                    record_count: 77,
                    raw
                }
            );
        }
    }
}

#[test]
fn encoding_is_deterministic_and_compresses() {
    let raw = vec![0u8; 1 << 20];
    let a = encode_block(RecordKind::Hit, 1, &raw);
    assert_eq!(a, encode_block(RecordKind::Hit, 1, &raw));
    assert!(a.len() < 1024, "{} bytes", a.len());
}

/// Recomputes the block CRC after a test patched the header or payload.
fn reseal(mut bytes: Vec<u8>) -> Vec<u8> {
    let mut crc = crc32fast::Hasher::new();
    crc.update(&bytes[..32]);
    crc.update(&bytes[36..]);
    let crc = crc.finalize().to_le_bytes();
    bytes[32..36].copy_from_slice(&crc);
    bytes
}

#[test]
fn header_layout_is_exact() {
    let raw = b"abc";
    let bytes = encode_block(RecordKind::ShadowQuery, 0x0102_0304_0506_0708, raw);
    assert_eq!(BLOCK_HEADER_LEN, 36);
    assert_eq!(&bytes[8..10], &[1, 0]);
    assert_eq!(&bytes[10..12], &[3, 0]);
    assert_eq!(&bytes[12..20], &[8, 7, 6, 5, 4, 3, 2, 1]);
    assert_eq!(&bytes[20..28], &[3, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(&bytes[28..32], &crc32fast::hash(raw).to_le_bytes());
    assert_eq!(reseal(bytes.clone()), bytes);
    assert_eq!(zstd::decode_all(&bytes[36..]).unwrap(), raw);
}

#[test]
fn every_truncation_is_an_error() {
    let bytes = encode_block(RecordKind::Hit, 64, &sample_raw());
    for len in 0..bytes.len() {
        let err = decode_err(&bytes[..len], RecordKind::Hit);
        assert!(
            err.to_string()
                .starts_with("shuffle block jobs/j/cast-map/00001/part-00002: ")
        );
        if len < BLOCK_HEADER_LEN {
            assert_eq!(err.problem, BlockProblem::TooShort { len });
        }
    }
    let empty = encode_block(RecordKind::Hit, 0, &[]);
    for len in 0..empty.len() {
        decode_err(&empty[..len], RecordKind::Hit);
    }
}

#[test]
fn every_bit_flip_is_an_error() {
    let bytes = encode_block(RecordKind::PixelColor, 64, &sample_raw());
    for bit in 0..bytes.len() * 8 {
        let mut corrupt = bytes.clone();
        corrupt[bit / 8] ^= 1 << (bit % 8);
        decode_err(&corrupt, RecordKind::PixelColor);
    }
}

#[test]
fn header_problems_are_named() {
    let bytes = encode_block(RecordKind::Hit, 1, b"xyz");
    let patch = |at: usize, patch: &[u8]| {
        let mut b = bytes.clone();
        b[at..at + patch.len()].copy_from_slice(patch);
        b
    };
    let err = decode_err(&patch(0, b"PNG"), RecordKind::Hit);
    assert!(
        err.to_string()
            .contains("not a HORT block: starts with \"PNGTBLK\\x00\""),
        "{err}"
    );
    let err = decode_err(&patch(8, &2u16.to_le_bytes()), RecordKind::Hit);
    assert_eq!(
        err.problem,
        BlockProblem::UnsupportedVersion {
            found: 2,
            supported: 1
        }
    );
    assert!(
        err.to_string()
            .contains("version 2; this build reads version 1"),
        "{err}"
    );
    let err = decode_err(&patch(10, &999u16.to_le_bytes()), RecordKind::Hit);
    assert_eq!(
        err.problem,
        BlockProblem::UnknownKind {
            found: 999,
            expected: RecordKind::Hit
        }
    );
    let err = decode_err(&patch(20, &(5u64 << 30).to_le_bytes()), RecordKind::Hit);
    assert!(matches!(err.problem, BlockProblem::RawTooLarge { len, .. } if len == 5 << 30));
    let err = decode_err(&patch(12, &2u64.to_le_bytes()), RecordKind::Hit);
    assert!(
        matches!(err.problem, BlockProblem::BlockChecksumMismatch { .. }),
        "{err}"
    );
    assert!(err.to_string().contains("stored bytes damaged"), "{err}");
}

#[test]
fn resealed_payload_problems_are_named() {
    let bytes = encode_block(RecordKind::Hit, 1, b"xyz");
    let patch = |at: usize, patch: &[u8]| {
        let mut b = bytes.clone();
        b[at..at + patch.len()].copy_from_slice(patch);
        reseal(b)
    };
    let err = decode_err(&patch(20, &4u64.to_le_bytes()), RecordKind::Hit);
    assert_eq!(
        err.problem,
        BlockProblem::RawLengthMismatch {
            declared: 4,
            found: 3
        }
    );
    let err = decode_err(&patch(20, &2u64.to_le_bytes()), RecordKind::Hit);
    assert!(
        err.to_string()
            .contains("declares 2 bytes, payload holds 3 or more"),
        "{err}"
    );
    let err = decode_err(&patch(28, &[0, 0, 0, 0]), RecordKind::Hit);
    assert!(
        matches!(err.problem, BlockProblem::RawChecksumMismatch { .. }),
        "{err}"
    );
    let err = decode_err(&patch(36, &[0, 0, 0, 0]), RecordKind::Hit);
    assert!(
        matches!(err.problem, BlockProblem::CorruptPayload { .. }),
        "{err}"
    );
    assert!(
        err.to_string()
            .contains("zstd payload corrupt or truncated"),
        "{err}"
    );
    let truncated = reseal(bytes[..bytes.len() - 1].to_vec());
    let err = decode_err(&truncated, RecordKind::Hit);
    assert!(
        matches!(err.problem, BlockProblem::CorruptPayload { .. }),
        "{err}"
    );
    let mut trailing = bytes.clone();
    trailing.push(0);
    let err = decode_err(&reseal(trailing), RecordKind::Hit);
    assert!(err.to_string().contains("1 bytes follow the"), "{err}");
}

#[test]
fn wrong_kind_says_found_and_expected() {
    let bytes = encode_block(RecordKind::CastCandidate, 1, b"xyz");
    let err = decode_err(&bytes, RecordKind::Hit);
    assert_eq!(
        err.to_string(),
        "shuffle block jobs/j/cast-map/00001/part-00002: unexpected record kind \
         CastCandidate (1), expected Hit (2)"
    );
}

#[test]
fn record_kind_codes_are_fixed() {
    let codes: Vec<u16> = RecordKind::ALL.iter().map(|k| k.code()).collect();
    assert_eq!(codes, [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]);
    for kind in RecordKind::ALL {
        assert_eq!(RecordKind::from_code(kind.code()), Some(kind));
    }
    assert_eq!(RecordKind::from_code(0), None);
    assert_eq!(RecordKind::from_code(11), None);
}

#[test]
fn frames_without_a_content_size_decode_and_are_length_checked() {
    // A streaming encoder does not know the size ahead, so its frame header omits it.
    let raw = sample_raw();
    let stream = zstd::stream::encode_all(&raw[..], ZSTD_LEVEL).unwrap();
    let frame = |declared: u64| {
        let mut bytes = encode_block(RecordKind::Hit, 1, &raw)[..BLOCK_HEADER_LEN].to_vec();
        bytes[20..28].copy_from_slice(&declared.to_le_bytes());
        bytes.extend_from_slice(&stream);
        reseal(bytes)
    };
    let n = raw.len() as u64;
    assert_eq!(
        decode_block("k", &frame(n), RecordKind::Hit).unwrap().raw,
        raw
    );
    for (declared, found) in [(n - 1, n), (n + 1, n), (0, 1), (n - 10, n - 9)] {
        assert_eq!(
            decode_err(&frame(declared), RecordKind::Hit).problem,
            BlockProblem::RawLengthMismatch { declared, found }
        );
    }
}

#[test]
fn relabelling_equals_encoding_as_the_new_kind() {
    for from in RecordKind::ALL {
        for to in RecordKind::ALL {
            for raw in [Vec::new(), vec![9], sample_raw(), vec![0u8; 1 << 20]] {
                let bytes = encode_block(from, 41, &raw);
                let relabelled = relabel_block("k", &bytes, from, to).unwrap();
                assert_eq!(relabelled, encode_block(to, 41, &raw), "{from} -> {to}");
                assert_eq!(decode_block("k", &relabelled, to).unwrap().raw, raw);
            }
        }
    }
}

#[test]
fn relabelling_refuses_every_bit_flip_and_truncation() {
    let bytes = encode_block(RecordKind::CastCandidate, 64, &sample_raw());
    for bit in 0..bytes.len() * 8 {
        let mut damaged = bytes.clone();
        damaged[bit / 8] ^= 1 << (bit % 8);
        let result = relabel_block("k", &damaged, RecordKind::CastCandidate, RecordKind::Hit);
        assert!(result.is_err(), "bit {bit} flipped was relabelled");
    }
    for len in 0..bytes.len() {
        let result = relabel_block(
            "k",
            &bytes[..len],
            RecordKind::CastCandidate,
            RecordKind::Hit,
        );
        assert!(result.is_err(), "{len} bytes were relabelled");
    }
}

#[test]
fn relabelling_names_the_key_and_the_problem() {
    let key = "jobs/j/cast-map/00001/part-00002";
    let bytes = encode_block(RecordKind::Hit, 1, b"xyz");
    let err = relabel_block(key, &bytes, RecordKind::CastCandidate, RecordKind::Hit).unwrap_err();
    assert_eq!(
        err.to_string(),
        "shuffle block jobs/j/cast-map/00001/part-00002: unexpected record kind Hit (2), \
         expected CastCandidate (1)"
    );
    let mut damaged = encode_block(RecordKind::CastCandidate, 1, b"xyz");
    let last = damaged.len() - 1;
    damaged[last] ^= 0x40;
    let stored = u32::from_le_bytes(damaged[32..36].try_into().unwrap());
    let computed = reseal(damaged.clone())[32..36].to_vec();
    let computed = u32::from_le_bytes(computed.try_into().unwrap());
    let err = relabel_block(key, &damaged, RecordKind::CastCandidate, RecordKind::Hit).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "shuffle block jobs/j/cast-map/00001/part-00002: block checksum mismatch (stored \
             bytes damaged): header stores CRC-32 {stored:#010x}, bytes give {computed:#010x}"
        )
    );
    let err =
        relabel_block(key, &bytes[..5], RecordKind::CastCandidate, RecordKind::Hit).unwrap_err();
    assert_eq!(
        err.to_string(),
        "shuffle block jobs/j/cast-map/00001/part-00002: truncated: 5 bytes, shorter than the \
         36-byte header"
    );
}
