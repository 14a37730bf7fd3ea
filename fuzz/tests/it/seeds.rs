//! Writes the binary seed inputs of the `split_object` and `shuffle_block` targets (valid
//! objects of every kind, stored and unwrapped; see `src/shuffle.rs` for the input layout).
//! Run once by hand: `cargo test -p hort-fuzz --test it seeds:: -- --ignored`; the fuzzers grew
//! the kept corpora from these.

use glam::Vec3;
use hort_core::bvh::Bvh;
use hort_core::pipeline::{
    Occluded, PixelBlock, RefineList, ShadowQuery, SplitObject, SurfaceHit, TriangleShading,
    encode_occluded, encode_pixels, encode_queries, encode_refine_list, encode_split,
    encode_surface_hits,
};
use hort_core::shading::SurfacePoint;
use hort_core::shuffle::{RecordKind, decode_block};
use std::path::Path;

/// Both input forms of an encoded block: stored (0x80 | kind) and unwrapped (kind, count, raw).
fn forms(kind: RecordKind, stored: &[u8]) -> [Vec<u8>; 2] {
    let index = RecordKind::ALL.iter().position(|&k| k == kind).unwrap() as u8;
    let block = decode_block("seed", stored, kind).unwrap();
    let mut raw = vec![index, u8::try_from(block.record_count).unwrap()];
    raw.extend_from_slice(&block.raw);
    let mut whole = vec![0x80 | index];
    whole.extend_from_slice(stored);
    [whole, raw]
}

fn save(target: &str, name: &str, kind: RecordKind, stored: &[u8]) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("corpus")
        .join(target);
    std::fs::create_dir_all(&dir).unwrap();
    let [whole, raw] = forms(kind, stored);
    std::fs::write(dir.join(format!("seed-{name}-stored")), whole).unwrap();
    std::fs::write(dir.join(format!("seed-{name}-raw")), raw).unwrap();
}

fn split(n: usize, normals: bool) -> SplitObject {
    let triangles: Vec<[Vec3; 3]> = (0..n)
        .map(|i| {
            let x = i as f32;
            [
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x + 1.0, 0.0, 0.5),
                Vec3::new(x, 1.0, 0.25),
            ]
        })
        .collect();
    let ids: Vec<u32> = (0..n as u32).map(|i| 10 + 3 * i).collect();
    let bvh = Bvh::build(triangles, ids);
    let shading = (0..n)
        .map(|i| TriangleShading {
            normals: (normals && i % 2 == 0).then_some([Vec3::Z, Vec3::Y, Vec3::X]),
            kd: [0.1 * (i % 3) as f32, 0.5, 0.8],
            texture: (normals && i % 3 == 0).then_some(hort_core::texture::TexturedCorners {
                texture: (i % 2) as u32,
                uv: [[0.0, 1.0], [0.5, 0.25], [i as f32, -1.0]],
            }),
        })
        .collect();
    SplitObject {
        split: 1,
        bvh,
        shading,
        textures: Default::default(),
    }
}

/// `n` triangles of a strip sharing corners (so vertex indices refer back), kd from 2 materials.
fn strip(n: usize) -> SplitObject {
    let vertex = |i: usize| Vec3::new((i / 2) as f32, (i % 2) as f32, 0.0);
    let triangles: Vec<[Vec3; 3]> = (0..n)
        .map(|i| [vertex(i), vertex(i + 1), vertex(i + 2)])
        .collect();
    let bvh = Bvh::build(triangles, (0..n as u32).collect());
    let shading = (0..n)
        .map(|i| TriangleShading {
            normals: None,
            kd: [0.5, 0.25 * (i % 2) as f32, 0.0],
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

fn hits(n: u32) -> Vec<SurfaceHit> {
    (0..n)
        .map(|i| SurfaceHit {
            pixel: i / 2,
            sample: i % 2,
            t: 1.5 + i as f32,
            triangle: 7 * i,
            surface: SurfacePoint {
                p: Vec3::new(i as f32, 1.0, 2.0),
                p_error: Vec3::splat(1e-6),
                n_geo: Vec3::Z,
                n_shade: if i % 3 == 0 { Vec3::Y } else { Vec3::Z },
                p_shadow: Vec3::new(i as f32, 1.0, 2.0),
                p_shadow_error: Vec3::splat(1e-6),
                kd: [0.5, 0.25, 0.125],
            },
        })
        .collect()
}

#[test]
#[ignore = "writes the seed corpus; run by hand"]
fn write_seeds() {
    for (name, object) in [
        ("split-1", split(1, false)),
        ("split-5-normals", split(5, true)),
        ("split-40", split(40, true)),
        ("split-0", split(0, false)),
        ("strip-24", strip(24)),
    ] {
        let bytes = encode_split(&object);
        save("split_object", name, RecordKind::SplitObject, &bytes);
        save("shuffle_block", name, RecordKind::SplitObject, &bytes);
    }
    for kind in [RecordKind::CastCandidate, RecordKind::Hit] {
        for n in [1, 6] {
            let bytes = encode_surface_hits(kind, &hits(n));
            save("shuffle_block", &format!("{kind:?}-{n}"), kind, &bytes);
        }
    }
    let queries: Vec<ShadowQuery> = (0..5)
        .map(|i| ShadowQuery {
            pixel: i,
            sample: 0,
            light: i % 2,
            origin: Vec3::splat(i as f32),
        })
        .collect();
    save(
        "shuffle_block",
        "queries-5",
        RecordKind::ShadowQuery,
        &encode_queries(&queries),
    );
    let occluded: Vec<Occluded> = (0..5)
        .map(|i| Occluded {
            pixel: 2 * i,
            sample: 1,
            light: 0,
        })
        .collect();
    save(
        "shuffle_block",
        "occluded-5",
        RecordKind::ShadowResult,
        &encode_occluded(&occluded),
    );
    let pixels = PixelBlock {
        start: 12,
        colours: vec![[0.1, 0.2, 0.3], [1.0, 0.0, 0.5], [0.0; 3]],
        triangles: vec![3, u32::MAX, 0],
        ts: vec![2.0, f32::INFINITY, 0.5],
    };
    save(
        "shuffle_block",
        "pixels-3",
        RecordKind::PixelColor,
        &encode_pixels(&pixels),
    );
    save(
        "shuffle_block",
        "pixels-3-without-hits",
        RecordKind::PixelColor,
        &encode_pixels(&pixels.without_hits()),
    );
    let list = RefineList {
        pixels: vec![12, 13, 40],
        sums: vec![[0.4, 0.8, 1.2], [4.0, 0.0, 2.0], [0.25; 3]],
    };
    save(
        "shuffle_block",
        "refine-list-3",
        RecordKind::RefineList,
        &encode_refine_list(&list),
    );
}
