//! Split objects round-trip every bit, and corrupt or hostile ones are errors, never panics.

use super::*;
use crate::bvh::BvhParts;
use crate::shuffle::columns::ColumnWriter;
use crate::shuffle::decode_block;
use glam::Vec3;

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
            texture: (i % 3 == 0).then_some(crate::texture::TexturedCorners {
                texture: i % 2,
                uv: [[0.0, 1.0], [0.5 * i as f32, -0.0], [1e9, 0.25]],
            }),
        })
        .collect();
    SplitObject {
        split: 3,
        bvh,
        shading,
        textures: Default::default(),
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
            texture: None,
        })
        .collect();
    SplitObject {
        split: 9,
        bvh,
        shading,
        textures: Default::default(),
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
        // The boxes are derived on loading: to the bit the built ones, whichever zero a
        // bound holds (mesh_object's corners tie at -0 and +0 on z).
        assert_eq!(format!("{:?}", decoded.bvh), format!("{:?}", object.bvh));
        assert_eq!(decoded.bvh.triangle_count(), n as usize);
        assert_eq!(decoded.shading.len(), n as usize);
    }
}

#[test]
fn leaf_triangles_pair_each_id_with_its_triangle() {
    let object = mesh_object(300);
    let triangles = object.bvh.leaf_triangles();
    assert_eq!(triangles.len(), 300);
    // Building again over the same pairs, in leaf order, gives the same pairs.
    let pairs = |bvh: &Bvh| {
        let mut p: Vec<(u32, [[u32; 3]; 3])> = bvh
            .ids()
            .iter()
            .zip(bvh.leaf_triangles())
            .map(|(&id, t)| (id, t.map(|v| v.to_array().map(f32::to_bits))))
            .collect();
        p.sort_unstable();
        p
    };
    let rebuilt = Bvh::build(triangles, object.bvh.ids().to_vec());
    assert_eq!(pairs(&rebuilt), pairs(&object.bvh));
    assert_eq!(pairs(&object.bvh)[0].0, 2, "mesh_object's ids are 7i + 2");
}

#[test]
fn many_distinct_values_round_trip() {
    // More kd values than one or two bytes can number.
    for (n, materials) in [(600, 300), (65_537, 65_537)] {
        let mut object = sample_object_of(n);
        object.shading = (object.shading.iter().enumerate())
            .map(|(i, s)| TriangleShading {
                kd: [(i % materials) as f32, 0.5, 0.25],
                ..s
            })
            .collect();
        let bytes = encode_split(&object);
        let s = Sections::of(&raw_of_bytes(&bytes));
        assert_eq!(s.words[7], materials as u32, "{n}");
        assert_eq!(s.kd_values.len(), 12 * materials, "{n}");
        assert_eq!(decode_split("k", &bytes).unwrap(), object, "{n}");
    }
}

/// `n` small triangles in a row, ids `2i + 5`, kd from 3 materials, no normals.
fn sample_object_of(n: usize) -> SplitObject {
    let triangles: Vec<[Vec3; 3]> = (0..n)
        .map(|i| {
            let o = Vec3::new(i as f32, 0.0, 0.0);
            [o, o + Vec3::X, o + Vec3::Y]
        })
        .collect();
    let bvh = Bvh::build(triangles, (0..n as u32).map(|i| 2 * i + 5).collect());
    let shading = (0..n)
        .map(|i| TriangleShading {
            normals: None,
            kd: [(i % 3) as f32, 0.5, 0.25],
            texture: None,
        })
        .collect();
    SplitObject {
        split: 0,
        bvh,
        shading,
        textures: Default::default(),
    }
}

fn raw_of_bytes(bytes: &[u8]) -> Vec<u8> {
    decode_block("k", bytes, RecordKind::SplitObject)
        .unwrap()
        .raw
}

fn raw_of(object: &SplitObject) -> Vec<u8> {
    raw_of_bytes(&encode_split(object))
}

/// The header's words and each section's byte range in a raw split object.
struct Sections {
    words: Vec<u32>,
    nodes: std::ops::Range<usize>,
    lanes: std::ops::Range<usize>,
    vertices: std::ops::Range<usize>,
    corners: std::ops::Range<usize>,
    flags: std::ops::Range<usize>,
    kd_values: std::ops::Range<usize>,
    kd_indices: std::ops::Range<usize>,
}

impl Sections {
    fn of(raw: &[u8]) -> Sections {
        let words: Vec<u32> = raw[..HEADER_BYTES]
            .chunks(4)
            .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
            .collect();
        let lengths = Counts {
            n: words[2],
            w: words[3],
            p: words[4],
            v: words[5],
            c: words[6],
            k: words[7],
            x: words[8],
        }
        .section_lengths();
        let mut at = HEADER_BYTES;
        let ranges: Vec<std::ops::Range<usize>> = lengths
            .iter()
            .map(|&len| {
                at += len as usize;
                at - len as usize..at
            })
            .collect();
        assert_eq!(at, raw.len());
        Sections {
            words,
            nodes: ranges[0].clone(),
            lanes: ranges[1].clone(),
            vertices: ranges[2].clone(),
            corners: ranges[3].clone(),
            kd_values: ranges[5].clone(),
            kd_indices: ranges[6].clone(),
            flags: ranges[7].clone(),
        }
    }

    /// The word of `slot`'s child (`field` 0) or pack count (`field` 1) of `node`.
    fn slot_word(&self, node: usize, field: usize, slot: usize) -> usize {
        self.nodes.start + node * NODE_BYTES + 4 * (4 * field + slot)
    }
}

fn get_word(raw: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(raw[at..at + 4].try_into().unwrap())
}

fn set_word(raw: &mut [u8], at: usize, value: u32) {
    raw[at..at + 4].copy_from_slice(&value.to_le_bytes());
}

const KEY: &str = "jobs/j/splits/00009.bin";

/// The error decoding `raw` (sealed in a valid block) gives, without the key prefix, which it
/// checks.
fn decode_err(raw: &[u8]) -> String {
    let e = decode_split(KEY, &encode_block(RecordKind::SplitObject, 0, raw))
        .unwrap_err()
        .to_string();
    let prefix = format!("split object {KEY}: ");
    assert!(e.starts_with(&prefix), "{e}");
    e[prefix.len()..].to_owned()
}

/// `raw` with `f` applied.
fn damaged(raw: &[u8], f: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    let mut raw = raw.to_vec();
    f(&mut raw);
    raw
}

#[test]
fn versions_and_header_counts_are_checked() {
    let good = raw_of(&mesh_object(64));
    let s = Sections::of(&good);
    assert!(decode_split("k", &encode_block(RecordKind::SplitObject, 0, &good)).is_ok());
    assert_eq!(
        decode_err(&damaged(&good, |r| set_word(r, 0, 4))),
        "format version 4, this build reads 6"
    );
    // A version 2 object: columns, the first a u32 column holding the version.
    let mut w = ColumnWriter::new();
    w.put_u32(&[2, 9, 64, 40, 0, 10, 0, 1]);
    w.put_f32(&[0.0; 6]);
    assert_eq!(
        decode_err(w.as_bytes()),
        "format version 2, this build reads 6"
    );
    assert_eq!(
        decode_err(&good[..10]),
        "10 raw bytes, shorter than the 60-byte header"
    );
    assert_eq!(
        decode_err(&damaged(&good, |r| set_word(r, 24, 65))),
        "header declares 65 triangles with normals of 64"
    );
    assert_eq!(
        decode_err(&damaged(&good, |r| set_word(r, 28, 0))),
        "header declares 0 kd values for 64 triangles"
    );
    assert_eq!(
        decode_err(&damaged(&good, |r| set_word(r, 28, 65))),
        "header declares 65 kd values for 64 triangles"
    );
    let body = good.len() - HEADER_BYTES;
    assert_eq!(
        decode_err(&damaged(&good, |r| r.push(0))),
        format!(
            "{} bytes after the header, whose counts call for {body}",
            body + 1
        )
    );
    assert_eq!(
        decode_err(&damaged(&good, |r| set_word(r, 16, s.words[4] + 1))),
        format!(
            "{body} bytes after the header, whose counts call for {}",
            body + 1
        )
    );
}

#[test]
fn hostile_nodes_and_packs_are_errors_naming_what_is_wrong() {
    let good = raw_of(&mesh_object(64));
    let s = Sections::of(&good);
    let (w, p) = (s.words[3] as usize, s.words[4] as usize);
    // The root's first inner and first leaf slots, and the leaf with the last packs.
    let child = |node: usize, slot: usize| get_word(&good, s.slot_word(node, 0, slot));
    let inner = (0..4).find(|&k| child(0, k) & LEAF_BIT == 0).unwrap();
    let (last_node, last_slot) = (0..w)
        .flat_map(|node| (0..4).map(move |slot| (node, slot)))
        .filter(|&(node, slot)| {
            child(node, slot) & LEAF_BIT != 0 && get_word(&good, s.slot_word(node, 1, slot)) > 0
        })
        .max_by_key(|&(node, slot)| child(node, slot))
        .unwrap();
    let last_first = (child(last_node, last_slot) & !LEAF_BIT) as usize;
    let cases: Vec<(Vec<u8>, String)> = vec![
        (
            damaged(&good, |r| set_word(r, s.slot_word(0, 0, inner), 0)),
            format!(
                "BVH node 0: slot {inner}: child 0, expected node 1 of {w} (depth-first order)"
            ),
        ),
        (
            damaged(&good, |r| set_word(r, s.slot_word(0, 0, inner), w as u32)),
            format!(
                "BVH node 0: slot {inner}: child {w}, expected node 1 of {w} (depth-first order)"
            ),
        ),
        (
            damaged(&good, |r| set_word(r, s.slot_word(0, 1, inner), 2)),
            format!("BVH node 0: slot {inner}: inner child with 2 triangle packs"),
        ),
        (
            damaged(&good, |r| {
                set_word(
                    r,
                    s.slot_word(last_node, 0, last_slot),
                    LEAF_BIT | (last_first as u32 + 1),
                )
            }),
            format!(
                "BVH node {last_node}: slot {last_slot}: leaf starts at triangle pack {}, expected {last_first}",
                last_first + 1
            ),
        ),
        (
            damaged(&good, |r| {
                let at = s.slot_word(last_node, 1, last_slot);
                let count = get_word(r, at);
                set_word(r, at, count + 1)
            }),
            format!(
                "BVH node {last_node}: slot {last_slot}: leaf ends at triangle pack {} past {p}",
                p + 1
            ),
        ),
        (
            damaged(&good, |r| r[s.lanes.start] = 0),
            "BVH triangle pack 0: holds 0 triangles, expected 1 to 4".to_owned(),
        ),
        (
            damaged(&good, |r| r[s.lanes.start + 1] = 5),
            "BVH triangle pack 1: holds 5 triangles, expected 1 to 4".to_owned(),
        ),
        (
            damaged(&good, |r| {
                let at = (s.lanes.start..s.lanes.end).find(|&i| r[i] > 1).unwrap();
                r[at] -= 1;
            }),
            "BVH triangle packs hold 63 triangles, expected 64".to_owned(),
        ),
        (
            // One node more that nothing reaches.
            damaged(&good, |r| {
                set_word(r, 12, w as u32 + 1);
                let empty = empty_node();
                r.splice(s.nodes.end..s.nodes.end, empty);
            }),
            format!("BVH root reaches {w} of {} nodes", w + 1),
        ),
        (
            // The last leaf's last pack split in two, the leaf still counting one pack.
            damaged(&good, |r| {
                let last = s.lanes.end - 1;
                assert!(r[last] >= 2, "the last pack holds {}", r[last]);
                r[last] -= 1;
                r.insert(last + 1, 1);
                set_word(r, 16, p as u32 + 1);
            }),
            format!("BVH leaves cover {p} of {} triangle packs", p + 1),
        ),
        (
            damaged(&good, |r| {
                r.drain(s.nodes.clone());
                set_word(r, 12, 0);
            }),
            "BVH with triangles has no nodes".to_owned(),
        ),
    ];
    for (raw, expected) in cases {
        assert_eq!(decode_err(&raw), expected);
    }
}

const LEAF_BIT: u32 = 1 << 31;

/// A node with four empty slots, as stored.
fn empty_node() -> Vec<u8> {
    let mut b = Vec::new();
    for _ in 0..4 {
        b.extend_from_slice(&LEAF_BIT.to_le_bytes());
    }
    b.extend_from_slice(&[0; 16]);
    b
}

/// The raw object of one triangle under a chain of `depth` nodes, each the only inner child of
/// the one before, the last holding the triangle's leaf.
fn chain(depth: usize) -> Vec<u8> {
    let good = raw_of(&mesh_object(1));
    let s = Sections::of(&good);
    assert_eq!(s.words[3], 1);
    let mut nodes = Vec::new();
    for k in 0..depth {
        let mut node = empty_node();
        let (word, count): (u32, u32) = if k + 1 < depth {
            (k as u32 + 1, 0)
        } else {
            (LEAF_BIT, 1)
        };
        node[0..4].copy_from_slice(&word.to_le_bytes());
        node[16..20].copy_from_slice(&count.to_le_bytes());
        nodes.extend(node);
    }
    damaged(&good, |r| {
        r.splice(s.nodes.clone(), nodes);
        set_word(r, 12, depth as u32);
    })
}

#[test]
fn depth_is_bounded_by_the_traversal_stack() {
    let object = decode_split("k", &encode_block(RecordKind::SplitObject, 0, &chain(60))).unwrap();
    assert_eq!(object.bvh.wide_node_count(), 60);
    let ray = crate::triangle::Ray {
        origin: Vec3::new(0.2, 0.1, 5.0),
        dir: Vec3::NEG_Z,
    };
    let hit = object
        .bvh
        .closest_hit(&ray)
        .expect("the chain's leaf is reached");
    assert_eq!(hit.id, 2);
    assert!((hit.t - 5.0).abs() < 1e-5, "{}", hit.t);
    assert!(object.bvh.occluded(&ray, 10.0));
    assert_eq!(decode_err(&chain(61)), "BVH is deeper than 60 levels");
}

#[test]
fn empty_slots_and_empty_objects_are_canonical() {
    let one = raw_of(&mesh_object(1));
    let s = Sections::of(&one);
    assert_eq!(
        decode_err(&damaged(&one, |r| set_word(
            r,
            s.slot_word(0, 0, 1),
            LEAF_BIT | 3
        ))),
        "BVH node 0: slot 1: empty slot with child word 0x80000003, expected 0x80000000"
    );
    let empty = raw_of(&mesh_object(0));
    assert_eq!(Sections::of(&empty).words[2..8], [0, 0, 0, 0, 0, 0]);
    assert_eq!(
        decode_err(&damaged(&empty, |r| {
            r.extend(empty_node());
            set_word(r, 12, 1);
        })),
        "BVH without triangles has 1 nodes and 0 triangle packs"
    );
}

#[test]
fn hostile_shading_is_an_error_naming_the_triangle() {
    let good = raw_of(&mesh_object(64));
    let s = Sections::of(&good);
    let c = s.words[6];
    let flags = &good[s.flags.clone()];
    let set = s.flags.start + flags.iter().position(|&f| f == 1).unwrap();
    let clear = s.flags.start + flags.iter().position(|&f| f == 0).unwrap();
    assert_eq!(
        decode_err(&damaged(&good, |r| r[clear] = 4)),
        format!(
            "shading flags of triangle {} are 4, expected bits 0 and 1 only",
            clear - s.flags.start
        )
    );
    assert_eq!(
        decode_err(&damaged(&good, |r| r[clear] = 2)),
        "shading flags: more textured triangles than the header's 0"
    );
    assert_eq!(
        decode_err(&damaged(&good, |r| r[set] = 0)),
        format!(
            "shading flags: {} triangles with normals, the header declares {c}",
            c - 1
        )
    );
    assert_eq!(
        decode_err(&damaged(&good, |r| r[clear] = 1)),
        format!("shading flags: more triangles with normals than the header's {c}")
    );
    assert_eq!(
        decode_err(&damaged(&good, |r| r[s.kd_indices.start] = 1)),
        "kd index 0 is 1, expected at most 0 (values in order of first use)"
    );
    let k = s.words[7];
    assert_eq!(
        decode_err(&damaged(&good, |r| r[s.kd_indices.start + 63] = k as u8)),
        format!(
            "kd index 63 is {k}, expected at most {} (values in order of first use)",
            k - 1
        )
    );
    // One kd value more than the indices use.
    assert_eq!(
        decode_err(&damaged(&good, |r| {
            r.splice(s.kd_values.end..s.kd_values.end, [0; 12]);
            set_word(r, 28, k + 1);
        })),
        format!("kd values: {k} of {} used", k + 1)
    );
}

#[test]
fn random_damage_never_panics_and_what_decodes_re_encodes_to_the_same_object() {
    let good = raw_of(&mesh_object(40));
    let mut rng = Rng(99);
    let (mut errors, mut decoded) = (0, 0);
    for _ in 0..3000 {
        let mut raw = good.clone();
        for _ in 0..1 + (rng.next() % 3) {
            let at = (rng.next() % raw.len() as u64) as usize;
            match rng.next() % 4 {
                0 => raw[at] = rng.next() as u8,
                1 => raw[at] ^= 1 << (rng.next() % 8),
                2 => raw.truncate(at),
                _ => raw.insert(at, rng.next() as u8),
            }
            if raw.is_empty() {
                raw.push(0);
            }
        }
        match decode_split("k", &encode_block(RecordKind::SplitObject, 0, &raw)) {
            Ok(object) => {
                decoded += 1;
                // Re-encoding may merge table values the damage made equal; from then on the
                // bytes are fixed and decode to the same object.
                let again = raw_of(&object);
                let object_again =
                    decode_split("k", &encode_block(RecordKind::SplitObject, 0, &again)).unwrap();
                // Debug shows signed zeros and NaNs that `==` would not compare as equal.
                let shown = |o: &SplitObject| {
                    let shading: Vec<_> = o.shading.iter().collect();
                    format!("{} {:?} {shading:?}", o.split, o.bvh)
                };
                assert_eq!(shown(&object), shown(&object_again));
                assert_eq!(raw_of(&object_again), again);
                if again.len() == raw.len() {
                    assert_eq!(again, raw);
                }
            }
            Err(e) => {
                errors += 1;
                assert!(!e.to_string().contains('\n'), "{e}");
            }
        }
    }
    // Damage to boxes, corners, ids and normals decodes (the values are free).
    assert!(
        errors > 1000 && decoded > 300,
        "{errors} errors, {decoded} decoded"
    );
}

#[test]
fn vertex_indices_number_the_vertices_in_order_of_first_use() {
    let good = raw_of(&mesh_object(64));
    let s = Sections::of(&good);
    let v = s.words[5];
    // 64 triangles of a 17-wide grid share corners: fewer vertices than corners.
    assert!(v < 3 * 64, "{v}");
    assert_eq!(s.vertices.len(), 12 * v as usize);
    assert_eq!(s.corners.len(), 12 * 64);
    assert_eq!(
        decode_err(&damaged(&good, |r| r[s.corners.start] = 1)),
        "vertex index 0 is 1, expected at most 0 (values in order of first use)"
    );
    // The last index's low byte (the first plane's last byte).
    let last = s.corners.start + 3 * 64 - 1;
    assert_eq!(
        decode_err(&damaged(&good, |r| r[last] = v as u8)),
        format!(
            "vertex index {} is {v}, expected at most {} (values in order of first use)",
            3 * 64 - 1,
            v - 1
        )
    );
    assert_eq!(
        decode_err(&damaged(&good, |r| {
            r.splice(s.vertices.end..s.vertices.end, [0; 12]);
            set_word(r, 20, v + 1);
        })),
        format!("vertex values: {v} of {} used", v + 1)
    );
}

#[test]
fn from_parts_refuses_partial_nodes() {
    let parts = BvhParts {
        bounds: Aabb::EMPTY,
        nodes: &[0; 100],
        lanes: &[1],
    };
    let e = Bvh::from_parts(parts, vec![7], |_| [Vec3::ZERO; 3]).unwrap_err();
    assert_eq!(
        e.to_string(),
        "BVH nodes: 100 bytes, not a whole number of 32-byte nodes"
    );
}
