//! Split objects round-trip every bit, and corrupt or hostile ones are errors, never panics.

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
use crate::bvh::tests::Rng;

/// A grid mesh of `n` triangles sharing corners (with signed zeros), some with vertex
/// normals (one of them NaN with a payload), kd from a few materials.
fn mesh_object(n: u32) -> SplitObject {
    let mut rng = Rng(0x1234_5678);
    let vertex = |i: u32| {
        let (x, y) = (i % 17, i / 17);
        let z = if (x + y) % 3 == 0 { -0.0 } else { 0.0 };
        Vec3::new(x as f32 * 0.5, y as f32 * 0.25, z)
    };
    let triangles: Vec<[Vec3; 3]> = (0..n)
        .map(|i| {
            let q = i / 2;
            let (a, b, c, d) = (q, q + 1, q + 17, q + 18);
            if i % 2 == 0 {
                [vertex(a), vertex(b), vertex(c)]
            } else {
                [vertex(b), vertex(d), vertex(c)]
            }
        })
        .collect();
    let ids: Vec<u32> = (0..n).map(|i| 7 * i + 2).collect();
    let bvh = Bvh::build(triangles, ids);
    let nan = f32::from_bits(0x7fc0_1234);
    let shading = (0..n)
        .map(|i| TriangleShading {
            normals: match rng.next() % 4 {
                0 => None,
                1 => Some([Vec3::Y, Vec3::new(0.0, 1.0, -0.0), Vec3::Y]),
                2 => Some([Vec3::new(nan, 0.0, 1.0), Vec3::Z, Vec3::X]),
                _ => Some([Vec3::splat(i as f32); 3]),
            },
            kd: [
                0.25 * (rng.next() % 3) as f32,
                0.5,
                if i % 5 == 0 { -0.0 } else { 0.0 },
            ],
        })
        .collect();
    SplitObject {
        split: 9,
        bvh,
        shading,
    }
}

#[test]
fn round_trips_every_bit() {
    for n in [0, 1, 2, 5, 1000] {
        let object = mesh_object(n);
        let bytes = encode_split(&object);
        let decoded = decode_split("k", &bytes).unwrap();
        // `==` on floats ignores the sign of zero and fails on NaN: compare encodings too.
        assert_eq!(encode_split(&decoded), bytes, "{n} triangles");
        assert_eq!(decoded.bvh, object.bvh);
        assert_eq!(decoded.bvh.triangle_count(), n as usize);
        assert_eq!(decoded.shading.len(), n as usize);
    }
}

#[test]
fn parts_gives_the_leaf_order_triangles() {
    let object = mesh_object(300);
    let (_, triangles, ids) = object.bvh.parts();
    assert_eq!(triangles.len(), 300);
    let again = mesh_object(300);
    let (_, built, _) = again.bvh.parts();
    assert_eq!(triangles, built);
    // Every triangle is one of the grid's, with its own id: rebuild from the parts.
    let rebuilt = Bvh::build(triangles.clone(), ids.to_vec());
    assert_eq!(rebuilt.parts().1, triangles);
}

#[test]
fn shared_corners_are_stored_once() {
    let columns = columns_of(&mesh_object(1000));
    let (Column::F32(vertices), Column::Bytes(refs)) = (&columns[4], &columns[5]) else {
        panic!("column types");
    };
    // 1000 triangles over a grid of 17 x 31 points; one byte per corner reference.
    assert!(vertices.len() <= 3 * 17 * 31, "{}", vertices.len());
    assert_eq!(refs.len(), 3000);
}

/// The columns of an encoded object, to damage one and seal it again.
#[derive(Clone, Debug)]
enum Column {
    U32(Vec<u32>),
    F32(Vec<f32>),
    Bytes(Vec<u8>),
}

fn columns_of(object: &SplitObject) -> Vec<Column> {
    let raw = decode_block("k", &encode_split(object), RecordKind::SplitObject)
        .unwrap()
        .raw;
    let mut r = ColumnReader::new(&raw);
    let mut out = vec![Column::U32(r.read_u32().unwrap())];
    for kind in "fuufbubfbfb".chars() {
        out.push(match kind {
            'u' => Column::U32(r.read_u32().unwrap()),
            'f' => Column::F32(r.read_f32().unwrap()),
            _ => Column::Bytes(r.read_bytes().unwrap().to_vec()),
        });
    }
    r.finish().unwrap();
    out
}

fn seal(columns: &[Column]) -> Vec<u8> {
    let mut w = ColumnWriter::new();
    for c in columns {
        match c {
            Column::U32(v) => w.put_u32(v),
            Column::F32(v) => w.put_f32(v),
            Column::Bytes(v) => w.put_bytes(v),
        }
    }
    encode_block(RecordKind::SplitObject, 0, w.as_bytes())
}

fn decode_err(columns: &[Column]) -> String {
    let key = "jobs/j/splits/00009.bin";
    let e = decode_split(key, &seal(columns)).unwrap_err().to_string();
    assert!(e.contains(key), "{e}");
    e
}

fn u32s(c: &mut Column) -> &mut Vec<u32> {
    match c {
        Column::U32(v) => v,
        _ => panic!("not a u32 column"),
    }
}

fn bytes(c: &mut Column) -> &mut Vec<u8> {
    match c {
        Column::Bytes(v) => v,
        _ => panic!("not a bytes column"),
    }
}

#[test]
fn hostile_columns_are_errors_naming_the_key() {
    let good = columns_of(&mesh_object(64));
    assert!(decode_split("k", &seal(&good)).is_ok());
    let damaged = |f: &dyn Fn(&mut Vec<Column>)| {
        let mut c = good.clone();
        f(&mut c);
        decode_err(&c)
    };
    // Version 1 objects (and anything else) name the version.
    let e = damaged(&|c| u32s(&mut c[0])[0] = 1);
    assert!(e.contains("format version 1, this build reads 2"), "{e}");
    let e = damaged(&|c| u32s(&mut c[0]).truncate(5));
    assert!(e.contains("header has 5 values"), "{e}");
    // Counts that disagree with the columns.
    for at in 2..8 {
        let e = damaged(&|c| u32s(&mut c[0])[at] += 1);
        assert!(
            e.contains("expected") || e.contains("disagree"),
            "{at}: {e}"
        );
    }
    // References: past the newest value, a new value beyond the distinct count, values
    // never used, trailing or missing bytes, overlong varints.
    for column in [5, 9, 11] {
        let e = damaged(&|c| {
            let refs = bytes(&mut c[column]);
            let last = refs.len() - 1;
            refs[last] = 0x7f;
        });
        assert!(e.contains("references"), "{column}: {e}");
        let e = damaged(&|c| bytes(&mut c[column]).push(1));
        assert!(e.contains("references"), "{column}: {e}");
        let e = damaged(&|c| {
            bytes(&mut c[column]).pop();
        });
        assert!(e.contains("references"), "{column}: {e}");
        let e = damaged(&|c| {
            let refs = bytes(&mut c[column]);
            refs[0] = 0x80;
            refs.insert(1, 0xff);
            refs.insert(2, 0xff);
            refs.insert(3, 0xff);
            refs.insert(4, 0x7f);
        });
        assert!(e.contains("references"), "{column}: {e}");
    }
    let e = damaged(&|c| {
        // A new value where an old one was used: one value too many.
        let refs = bytes(&mut c[5]);
        let at = refs.iter().rposition(|&b| b != 0).unwrap();
        refs[at] = 0;
    });
    assert!(e.contains("references"), "{e}");
    // BVH structure: a leaf that repeats triangles of another, a child before its parent.
    let e = damaged(&|c| {
        let counts = u32s(&mut c[3]).clone();
        let leaves: Vec<usize> = (0..counts.len()).filter(|&i| counts[i] > 0).collect();
        let first = u32s(&mut c[2])[leaves[0]];
        u32s(&mut c[2])[leaves[1]] = first;
    });
    assert!(e.contains("leaf starts at triangle"), "{e}");
    let e = damaged(&|c| u32s(&mut c[2])[0] = 0);
    assert!(e.contains("out of order"), "{e}");
}

#[test]
fn random_damage_never_panics() {
    let good = columns_of(&mesh_object(40));
    let raw = {
        let mut w = ColumnWriter::new();
        for c in &good {
            match c {
                Column::U32(v) => w.put_u32(v),
                Column::F32(v) => w.put_f32(v),
                Column::Bytes(v) => w.put_bytes(v),
            }
        }
        w.into_bytes()
    };
    let mut rng = Rng(99);
    let mut errors = 0;
    for _ in 0..3000 {
        let mut damaged = raw.clone();
        for _ in 0..1 + (rng.next() % 3) {
            let at = (rng.next() % damaged.len() as u64) as usize;
            match rng.next() % 4 {
                0 => damaged[at] = rng.next() as u8,
                1 => damaged[at] ^= 1 << (rng.next() % 8),
                2 => damaged.truncate(at),
                _ => damaged.insert(at, rng.next() as u8),
            }
            if damaged.is_empty() {
                damaged.push(0);
            }
        }
        let bytes = encode_block(RecordKind::SplitObject, 0, &damaged);
        errors += usize::from(decode_split("k", &bytes).is_err());
    }
    assert!(errors > 2000, "{errors} errors");
}
