//! Where a split object's load time goes (docs/ARCHITECTURE.md, "Split objects"):
//! `cargo run --release -p hort-core --example split_object_timing -- SCENE [REPEATS]`.
//!
//! Builds the scene as one split, then prints the best of REPEATS (default 5) wall times of
//! encoding it, of undoing the block (checksums and zstd), and of the whole `decode_split`, with
//! the sizes, so that a change of the split object's layout can be judged on any scene; and,
//! for the layout that stores every corner instead of references, the corners' size at zstd
//! level 1 and the time to decompress them.

use hort_core::pipeline::{SplitMode, decode_split, encode_split, split_scene};
use hort_core::scene::load_scene;
use hort_core::shuffle::{RecordKind, decode_block};
use std::path::PathBuf;

#[path = "support/best.rs"]
mod support;
use support::best;

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(path) = args.next().map(PathBuf::from) else {
        eprintln!("usage: split_object_timing SCENE [REPEATS]");
        std::process::exit(2);
    };
    let repeats: usize = args.next().map_or(5, |r| r.parse().expect("REPEATS"));
    let scene = load_scene(&path).expect("the scene loads");
    let mut stored = Vec::new();
    let (build, _) = best(1, || {
        split_scene(&scene.mesh, 1, SplitMode::Spatial, |_, bytes| {
            stored = bytes;
            Ok::<(), ()>(())
        })
    });
    let (block, raw) = best(repeats, || {
        decode_block("split", &stored, RecordKind::SplitObject).expect("block decodes")
    });
    let (decode, object) = best(repeats, || decode_split("split", &stored).expect("decodes"));
    let (encode, again) = best(repeats, || encode_split(&object));
    assert_eq!(again, stored, "encoding is deterministic");
    let n = object.bvh.triangle_count();
    println!(
        "{}: {n} triangles; stored {} bytes, raw {} bytes, in memory {} bytes",
        path.display(),
        stored.len(),
        raw.raw.len(),
        object.memory_bytes()
    );
    println!("build + encode        {:8.1} ms", build * 1e3);
    println!("encode_split          {:8.1} ms", encode * 1e3);
    println!("block (crc + zstd)    {:8.1} ms", block * 1e3);
    println!(
        "decode_split          {:8.1} ms  ({:.0} MB/s of memory)",
        decode * 1e3,
        object.memory_bytes() as f64 / decode / 1e6
    );
    // The alternative layout: every corner of every triangle written out (no references to
    // distinct vertices), as a traversal form stored as it is would need, and what zstd level
    // 1 makes of it and costs to undo. Nodes, ids and shading would come on top.
    let (_, corners, _) = object.bvh.parts();
    let flat: Vec<u8> = corners
        .iter()
        .flatten()
        .flat_map(|v| v.to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    let packed = zstd::bulk::compress(&flat, 1).expect("compresses");
    let (inflate, _) = best(repeats, || {
        zstd::bulk::decompress(&packed, flat.len()).expect("decompresses")
    });
    println!(
        "flat corners alone    {:8.1} ms to decompress ({} bytes raw, {} at zstd 1)",
        inflate * 1e3,
        flat.len(),
        packed.len()
    );
}
