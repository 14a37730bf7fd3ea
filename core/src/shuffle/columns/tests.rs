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
    let mut writer = ColumnWriter::new();
    writer.put_u32_sorted_delta(ids);
    writer.put_u32(tris);
    writer.put_f32(ts);
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

#[test]
fn random_garbage_never_panics() {
    let mut rng = Rng(42);
    for _ in 0..2000 {
        let len = (rng.next() % 40) as usize;
        let bytes: Vec<u8> = (0..len).map(|_| (rng.next() % 6) as u8 * 51).collect();
        let mut reader = ColumnReader::new(&bytes);
        let _ = reader.read_u32_sorted_delta();
        let _ = reader.read_u32();
        let _ = reader.read_f32();
        let _ = reader.read_bytes();
    }
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
