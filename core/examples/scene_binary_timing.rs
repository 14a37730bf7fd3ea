//! Parsing a scene against decoding its binary form (docs/ARCHITECTURE.md, "Binary scene"):
//! `cargo run --release -p hort-core --example scene_binary_timing -- SCENE [REPEATS]`.
//!
//! Prints the best of REPEATS (default 3) wall times of `load_scene` (OBJ/MTL/manifest
//! parsing), `encode_scene` and `decode_scene`, the binary scene's size, and what zstd (level
//! 1 and 3, as the shuffle blocks use) would make of it and cost to undo, so that the choice of
//! storing it uncompressed can be checked on any scene.

use hort_core::scene::{decode_scene, encode_scene, load_scene};
use std::path::PathBuf;

#[path = "support/best.rs"]
mod support;
use support::best;

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(path) = args.next().map(PathBuf::from) else {
        eprintln!("usage: scene_binary_timing SCENE [REPEATS]");
        std::process::exit(2);
    };
    let repeats: usize = args.next().map_or(3, |r| r.parse().expect("REPEATS"));
    let (parse, scene) = best(repeats, || load_scene(&path).expect("the scene loads"));
    let (encode, bytes) = best(repeats, || encode_scene(&scene));
    let (decode, _) = best(repeats, || {
        decode_scene("scene.bin", &bytes).expect("decodes")
    });
    let files: u64 = std::fs::metadata(&path).map_or(0, |m| m.len());
    println!(
        "{}: {} triangles, {} positions; main file {files} bytes",
        path.display(),
        scene.mesh.triangle_count(),
        scene.mesh.positions.len()
    );
    println!("parse (load_scene)   {:8.1} ms", parse * 1e3);
    println!("encode_scene         {:8.1} ms", encode * 1e3);
    println!(
        "decode_scene         {:8.1} ms  ({} bytes, {:.0} MB/s)",
        decode * 1e3,
        bytes.len(),
        bytes.len() as f64 / decode / 1e6
    );
    for level in [1, 3] {
        let (compress, packed) = best(repeats, || {
            zstd::bulk::compress(&bytes, level).expect("compresses")
        });
        let (inflate, _) = best(repeats, || {
            zstd::bulk::decompress(&packed, bytes.len()).expect("decompresses")
        });
        println!(
            "zstd level {level}: {} bytes ({:.2}x), compress {:.1} ms, decompress {:.1} ms",
            packed.len(),
            bytes.len() as f64 / packed.len() as f64,
            compress * 1e3,
            inflate * 1e3
        );
    }
}
