use super::*;

/// A tiny deterministic generator (xorshift64*), enough for test data.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn u32(&mut self) -> u32 {
        (self.next() >> 32) as u32
    }
}

fn write_all(ids: &[u32], tris: &[u32], ts: &[f32], flags: &[u8]) -> Vec<u8> {
    write_all_as(ids, tris, ts, flags, false)
}

/// Like `write_all`, with the f32 column as a delta column when `delta`.
fn write_all_as(ids: &[u32], tris: &[u32], ts: &[f32], flags: &[u8], delta: bool) -> Vec<u8> {
    let mut writer = ColumnWriter::new();
    writer.put_u32_sorted_delta(ids);
    writer.put_u32(tris);
    if delta {
        writer.put_f32_delta(ts);
    } else {
        writer.put_f32(ts);
    }
    writer.put_bytes(flags);
    writer.into_bytes()
}

#[test]
fn round_trips_columns_in_order() {
    let ids = [0, 0, 1, 5, 300, 70_000, u32::MAX];
    let tris = [7, u32::MAX, 0, 1 << 20];
    let ts = [
        0.5,
        f32::INFINITY,
        -0.0,
        f32::MIN_POSITIVE,
        1e-40,
        f32::from_bits(0x7fc0_1234),
    ];
    let bytes = write_all(&ids, &tris, &ts, b"\x00\x01\xff");
    let mut reader = ColumnReader::new(&bytes);
    assert_eq!(reader.read_u32_sorted_delta().unwrap(), ids);
    assert_eq!(reader.read_u32().unwrap(), tris);
    let back = reader.read_f32().unwrap();
    let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&back), bits(&ts));
    assert_eq!(reader.read_bytes().unwrap(), b"\x00\x01\xff");
    assert_eq!(reader.remaining(), 0);
    reader.finish().unwrap();
}

#[test]
fn empty_columns_round_trip() {
    let bytes = write_all(&[], &[], &[], &[]);
    assert_eq!(bytes, [1, 0, 2, 0, 3, 0, 4, 0]);
    let mut reader = ColumnReader::new(&bytes);
    assert!(reader.read_u32_sorted_delta().unwrap().is_empty());
    assert!(reader.read_u32().unwrap().is_empty());
    assert!(reader.read_f32().unwrap().is_empty());
    assert!(reader.read_bytes().unwrap().is_empty());
    reader.finish().unwrap();
}

#[test]
fn layout_is_byte_planes_and_varint_deltas() {
    let mut writer = ColumnWriter::new();
    writer.put_u32(&[0x0403_0201, 0x0807_0605]);
    writer.put_u32_sorted_delta(&[3, 131]);
    assert_eq!(
        writer.as_bytes(),
        [2, 2, 1, 5, 2, 6, 3, 7, 4, 8, 1, 2, 3, 0x80, 1]
    );
}

#[test]
fn random_data_round_trips() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    for round in 0..50 {
        let n = (rng.next() % 2000) as usize;
        let mut ids: Vec<u32> = (0..n).map(|_| rng.u32() >> (round % 32)).collect();
        if round % 2 == 0 {
            ids.sort_unstable();
        }
        let tris: Vec<u32> = (0..n).map(|_| rng.u32()).collect();
        let ts: Vec<f32> = (0..n).map(|_| f32::from_bits(rng.u32())).collect();
        let flags: Vec<u8> = (0..n / 3).map(|_| rng.next() as u8).collect();
        let bytes = write_all(&ids, &tris, &ts, &flags);
        let mut reader = ColumnReader::new(&bytes);
        assert_eq!(reader.read_u32_sorted_delta().unwrap(), ids);
        assert_eq!(reader.read_u32().unwrap(), tris);
        let back: Vec<u32> = reader
            .read_f32()
            .unwrap()
            .iter()
            .map(|f| f.to_bits())
            .collect();
        assert_eq!(back, ts.iter().map(|f| f.to_bits()).collect::<Vec<_>>());
        assert_eq!(reader.read_bytes().unwrap(), flags);
        reader.finish().unwrap();
    }
}

#[test]
fn sorted_deltas_and_planes_compress_better_than_plain() {
    let ids: Vec<u32> = (0..100_000u32).map(|i| i * 3 + (i % 2)).collect();
    let mut writer = ColumnWriter::new();
    writer.put_u32_sorted_delta(&ids);
    let plain: Vec<u8> = ids.iter().flat_map(|v| v.to_le_bytes()).collect();
    assert!(
        writer.len() * 3 < plain.len(),
        "{} vs {}",
        writer.len(),
        plain.len()
    );

    let ts: Vec<f32> = (0..100_000)
        .map(|i| 10.0 + (i as f32 * 0.37).sin())
        .collect();
    let mut writer = ColumnWriter::new();
    writer.put_f32(&ts);
    let plain: Vec<u8> = ts.iter().flat_map(|v| v.to_le_bytes()).collect();
    let planar = zstd::bulk::compress(writer.as_bytes(), 3).unwrap().len();
    let interleaved = zstd::bulk::compress(&plain, 3).unwrap().len();
    assert!(
        planar < interleaved,
        "planar {planar} vs interleaved {interleaved}"
    );
}

#[test]
fn every_truncation_is_an_error() {
    let bytes = write_all(&[1, 2, 300], &[9, 8], &[1.5], b"ab");
    for len in 0..bytes.len() {
        let mut reader = ColumnReader::new(&bytes[..len]);
        let result = reader
            .read_u32_sorted_delta()
            .and_then(|_| reader.read_u32())
            .and_then(|_| reader.read_f32())
            .and_then(|_| reader.read_bytes().map(|_| ()))
            .and_then(|()| reader.clone().finish());
        assert!(
            matches!(result, Err(ColumnError::Truncated { .. })),
            "len {len}: {result:?}"
        );
    }
}

#[test]
fn malformed_input_is_an_error() {
    let wrong = ColumnReader::new(&[3, 0]).read_u32();
    assert_eq!(
        wrong,
        Err(ColumnError::WrongType {
            column: 0,
            found: 3,
            expected: "u32",
            expected_tag: 2
        })
    );
    // A count far beyond the input is rejected before allocating.
    let huge =
        ColumnReader::new(&[2, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x7f]).read_u32();
    assert!(
        matches!(huge, Err(ColumnError::Truncated { column: 0, .. })),
        "{huge:?}"
    );
    // Varints: 11 continuation bytes, and a 10-byte varint overflowing u64.
    let long = [&[1u8][..], &[0x80; 11]].concat();
    assert_eq!(
        ColumnReader::new(&long).read_u32_sorted_delta(),
        Err(ColumnError::BadVarint { column: 0 })
    );
    let overflow = [&[1u8][..], &[0xff; 9], &[0x02]].concat();
    assert_eq!(
        ColumnReader::new(&overflow).read_bytes(),
        Err(ColumnError::WrongType {
            column: 0,
            found: 1,
            expected: "bytes",
            expected_tag: 4
        })
    );
    assert_eq!(
        ColumnReader::new(&overflow).read_u32_sorted_delta(),
        Err(ColumnError::BadVarint { column: 0 })
    );
    // A delta above u32::MAX.
    let big_delta = [1, 1, 0x80, 0x80, 0x80, 0x80, 0x10];
    assert_eq!(
        ColumnReader::new(&big_delta).read_u32_sorted_delta(),
        Err(ColumnError::BadVarint { column: 0 })
    );
    // Trailing bytes after the last column, with the column count in the message.
    let mut reader = ColumnReader::new(&[4, 1, 7, 9]);
    assert_eq!(reader.read_bytes().unwrap(), [7]);
    let err = reader.finish().unwrap_err();
    assert_eq!(err.to_string(), "1 unread bytes after column 1");
}

/// The four columns of [`write_all`] (floats as bits), read back and finished.
/// The four columns, and whether the f32 column was a delta column.
type Columns = (Vec<u32>, Vec<u32>, Vec<u32>, Vec<u8>, bool);

fn read_all(bytes: &[u8]) -> Result<Columns, ColumnError> {
    let mut reader = ColumnReader::new(bytes);
    let ids = reader.read_u32_sorted_delta()?;
    let tris = reader.read_u32()?;
    let delta = bytes.get(bytes.len() - reader.remaining()) == Some(&5);
    let ts = reader.read_f32()?.into_iter().map(f32::to_bits).collect();
    let flags = reader.read_bytes()?.to_vec();
    reader.finish()?;
    Ok((ids, tris, ts, flags, delta))
}

/// Damaged encodings and random bytes drawn mostly from the format's own vocabulary (tags,
/// small counts, continuation bytes). Nothing panics, and every input either is an error that
/// names a column it could have happened in, with consistent details, or reads as four columns
/// that are a valid encoding: written again they read back the same, in the same bytes unless
/// the input spelled a varint longer than needed. Every outcome occurs, so every check of the
/// reader is reached.
#[test]
fn garbage_is_a_consistent_error_or_a_valid_encoding() {
    const VOCABULARY: [u8; 9] = [0, 1, 2, 3, 4, 5, 0x7f, 0x80, 0xff];
    let mut rng = Rng(42);
    let valid = write_all(
        &[1, 2, 300, 70_000],
        &[9, 8, u32::MAX],
        &[1.5, -0.0],
        b"abc",
    );
    // Truncated, wrong type, bad varint, trailing bytes, read.
    let mut outcomes = [0usize; 5];
    for i in 0..20_000 {
        let bytes: Vec<u8> = if i % 2 == 0 {
            let mut bytes = valid.clone();
            for _ in 0..1 + rng.next() % 3 {
                let at = (rng.next() % (bytes.len() as u64 + 1)) as usize;
                let byte = VOCABULARY[(rng.next() % 9) as usize];
                match rng.next() % 5 {
                    0 if at < bytes.len() => bytes[at] = byte,
                    1 if at < bytes.len() => bytes[at] ^= 1 << (rng.next() % 8),
                    2 => bytes.truncate(at),
                    // A run of continuation bytes: a varint grows past its length limit.
                    3 => {
                        let run = 1 + (rng.next() % 10) as usize;
                        bytes.splice(at..at, std::iter::repeat_n(0x80, run));
                    }
                    _ => bytes.insert(at, byte),
                }
            }
            bytes
        } else {
            let len = (rng.next() % 40) as usize;
            (0..len)
                .map(|_| match rng.next() % 4 {
                    0 => rng.next() as u8,
                    // Continuation bytes: long and overlong varints.
                    1 => 0x80 | rng.next() as u8,
                    _ => VOCABULARY[(rng.next() % 9) as usize],
                })
                .collect()
        };
        match read_all(&bytes) {
            Err(ColumnError::Truncated {
                column,
                needed,
                available,
            }) => {
                assert!(column < 4 && needed > available as u64, "{bytes:x?}");
                assert!(available < bytes.len().max(1), "{bytes:x?}");
                outcomes[0] += 1;
            }
            Err(ColumnError::WrongType {
                column,
                found,
                expected_tag,
                ..
            }) => {
                assert!(column < 4, "{bytes:x?}");
                assert_eq!(expected_tag, [1, 2, 3, 4][column], "{bytes:x?}");
                assert_ne!(found, expected_tag, "{bytes:x?}");
                outcomes[1] += 1;
            }
            Err(ColumnError::BadVarint { column }) => {
                assert!(column < 4, "{bytes:x?}");
                outcomes[2] += 1;
            }
            Err(ColumnError::TrailingBytes {
                count,
                columns_read,
            }) => {
                assert!(count > 0 && count < bytes.len(), "{bytes:x?}");
                assert_eq!(columns_read, 4, "{bytes:x?}");
                outcomes[3] += 1;
            }
            Ok((ids, tris, ts, flags, delta)) => {
                let ts: Vec<f32> = ts.iter().copied().map(f32::from_bits).collect();
                let again = write_all_as(&ids, &tris, &ts, &flags, delta);
                let back = read_all(&again).expect("a re-encoding reads back");
                assert_eq!(
                    back,
                    (
                        ids,
                        tris,
                        ts.iter().map(|t| t.to_bits()).collect(),
                        flags,
                        delta
                    )
                );
                assert!(again.len() <= bytes.len(), "{bytes:x?}");
                if again.len() == bytes.len() {
                    assert_eq!(again, bytes);
                }
                outcomes[4] += 1;
            }
        }
    }
    assert!(outcomes.iter().all(|&n| n > 0), "{outcomes:?}");
}

#[test]
fn planes_read_in_place_give_the_values_and_their_groups() {
    let mut rng = Rng(7);
    let values: Vec<u32> = (0..30).map(|_| rng.u32()).collect();
    let floats = [1.5f32, -0.0, f32::from_bits(0x7fc0_1234), f32::NEG_INFINITY];
    let mut writer = ColumnWriter::new();
    writer.put_u32(&values);
    writer.put_f32(&floats);
    writer.put_u32(&[]);
    let bytes = writer.into_bytes();
    let mut reader = ColumnReader::new(&bytes);
    let planes = reader.read_u32_planes().unwrap();
    let floats_back = reader.read_f32_planes().unwrap();
    let empty = reader.read_u32_planes().unwrap();
    reader.finish().unwrap();

    assert_eq!(planes.len(), 30);
    assert_eq!(planes.u32s().collect::<Vec<_>>(), values);
    let bits: Vec<u32> = floats_back.f32s().map(f32::to_bits).collect();
    assert_eq!(bits, floats.map(f32::to_bits));
    // Groups of 7: four whole groups, the last 2 values skipped.
    let groups: Vec<[u32; 7]> = planes.groups::<7>().collect();
    assert_eq!(groups.len(), 4);
    for (i, g) in groups.iter().enumerate() {
        assert_eq!(g[..], values[7 * i..7 * i + 7]);
    }
    assert!(empty.is_empty());
    assert_eq!(empty.groups::<3>().count(), 0);
    // Wrong types are still errors.
    let mut reader = ColumnReader::new(&bytes);
    assert!(matches!(
        reader.read_f32_planes(),
        Err(ColumnError::WrongType { column: 0, .. })
    ));
}

#[test]
fn f32_delta_columns_round_trip_bit_for_bit() {
    let special = [
        0.5,
        f32::INFINITY,
        -0.0,
        0.0,
        f32::NEG_INFINITY,
        f32::MIN_POSITIVE,
        1e-40,
        f32::from_bits(0x7fc0_1234),
        f32::from_bits(0xffff_ffff),
        f32::MAX,
        -f32::MAX,
    ];
    let mut rng = Rng(7);
    let random: Vec<f32> = (0..1000).map(|_| f32::from_bits(rng.u32())).collect();
    for values in [&special[..], &random[..], &[]] {
        let mut writer = ColumnWriter::new();
        writer.put_f32_delta(values);
        writer.put_f32(values);
        let bytes = writer.into_bytes();
        let mut reader = ColumnReader::new(&bytes);
        for _ in 0..2 {
            let read = reader.read_f32().unwrap();
            assert_eq!(
                read.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                values.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            );
        }
        reader.finish().unwrap();
    }
}

#[test]
fn f32_delta_layout_is_zigzagged_bit_differences_in_planes() {
    let mut writer = ColumnWriter::new();
    // Bits 0x3f80_0000, then 0x3f80_0001 (+1 -> 2), then 0x3f80_0000 (-1 -> 1).
    writer.put_f32_delta(&[1.0, f32::from_bits(0x3f80_0001), 1.0]);
    let first = 0x3f80_0000u32 * 2;
    let [b0, b1, b2, b3] = first.to_le_bytes();
    assert_eq!(
        writer.as_bytes(),
        &[5, 3, b0, 2, 1, b1, 0, 0, b2, 0, 0, b3, 0, 0]
    );
}

#[test]
fn an_f32_delta_column_is_not_read_as_another_type() {
    let mut writer = ColumnWriter::new();
    writer.put_f32_delta(&[1.0]);
    let bytes = writer.into_bytes();
    let err = ColumnReader::new(&bytes).read_u32().unwrap_err();
    assert_eq!(
        err.to_string(),
        "column 0: holds tag 5, expected u32 (tag 2)"
    );
    let err = ColumnReader::new(&bytes[..4]).read_f32().unwrap_err();
    assert_eq!(
        err.to_string(),
        "column 0: truncated, needs 4 more bytes, 2 left"
    );
}
