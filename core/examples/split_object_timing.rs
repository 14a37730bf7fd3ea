//! Where a split object's load time goes (docs/ARCHITECTURE.md, "Split objects"):
//! `cargo run --release -p hort-core --example split_object_timing -- SCENE [REPEATS]`, where
//! SCENE is a scene file or `generated:N`, the scene `hort scene generate --triangles N --seed
//! 1` writes (generated here into a temporary file, deleted after loading).
//!
//! Builds the scene as one split, then times REPEATS (default 5) runs each of encoding it, of
//! undoing the block (checksums and zstd), of the whole `decode_split`, and of a plain copy of
//! as many bytes as the decoded object holds into a fresh buffer (the memory-speed baseline:
//! the same allocation and page faults, no work), once as a plain `Vec` and once advised to use
//! huge pages as the decoder's arrays are (`hort_huge_pages`), and prints the sizes and the
//! minimum and median times, so that a change of the split object's layout can be judged on any
//! scene.

use hort_core::bvh::BuildPreset;
use hort_core::pipeline::{SplitMode, decode_split, encode_split, split_scene};
use hort_core::shuffle::{MAX_TAKE, RecordKind, decode_block, read_block};
use std::time::Instant;

#[path = "support/scene_arg.rs"]
mod scene_arg;
use scene_arg::load_scene_arg;

/// Runs `f` `repeats` times: the sorted wall times in seconds and the last result.
fn times<T>(repeats: usize, mut f: impl FnMut() -> T) -> (Vec<f64>, T) {
    let mut seconds = Vec::with_capacity(repeats);
    let mut out = None;
    for _ in 0..repeats {
        let t = Instant::now();
        let v = std::hint::black_box(f());
        seconds.push(t.elapsed().as_secs_f64());
        out = Some(v);
    }
    seconds.sort_by(f64::total_cmp);
    (seconds, out.expect("at least one repeat"))
}

/// "min / median ms" of sorted times.
fn ms(t: &[f64]) -> String {
    format!("{:7.1} / {:7.1} ms", t[0] * 1e3, t[t.len() / 2] * 1e3)
}

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(scene_arg) = args.next() else {
        eprintln!("usage: split_object_timing SCENE|generated:N [REPEATS]");
        std::process::exit(2);
    };
    let repeats: usize = args.next().map_or(5, |r| r.parse().expect("REPEATS"));
    let scene = load_scene_arg(&scene_arg);
    let mut stored = Vec::new();
    let (build, _) = times(1, || {
        split_scene(
            &scene.mesh,
            1,
            SplitMode::Spatial,
            BuildPreset::Quality,
            |_, bytes| {
                stored = bytes;
                Ok::<(), ()>(())
            },
        )
    });
    drop(scene);
    let (block, raw) = times(repeats, || {
        decode_block("split", &stored, RecordKind::SplitObject).expect("block decodes")
    });
    let raw_len = raw.raw.len();
    drop(raw);
    // What any reader of the stream pays before its own work: zstd and the CRC into the one
    // reused buffer, nothing kept.
    let (stream, _) = times(repeats, || {
        read_block("split", &stored, RecordKind::SplitObject, |s| {
            while s.take(MAX_TAKE).is_some() {}
        })
        .expect("block streams")
    });
    let (decode, object) = times(repeats, || decode_split("split", &stored).expect("decodes"));
    let (encode, again) = times(repeats, || encode_split(&object));
    assert_eq!(again, stored, "encoding is deterministic");
    drop(again);
    let decoded = object.memory_bytes() as usize;
    let n = object.bvh.triangle_count();
    drop(object);
    // The baseline: as many bytes as the decoded object, copied into a fresh allocation.
    let source = vec![0x5au8; decoded];
    let (copy, _) = times(repeats, || source.to_vec());
    // The same copy into a block advised to use huge pages, as the decoder's arrays are.
    let (huge_copy, _) = times(repeats, || {
        let mut fresh: Vec<u8> = hort_huge_pages::vec_with_capacity(decoded);
        fresh.extend_from_slice(&source);
        fresh
    });
    let mb = |b: usize| b as f64 / 1e6;
    let gbs = |t: &[f64]| decoded as f64 / t[0] / 1e9;
    println!(
        "{scene_arg}: {n} triangles; stored {:.1} MB, raw {:.1} MB, decoded {:.1} MB; per \
         triangle {:.1} stored, {:.1} raw, {:.1} decoded bytes",
        mb(stored.len()),
        mb(raw_len),
        mb(decoded),
        stored.len() as f64 / n.max(1) as f64,
        raw_len as f64 / n.max(1) as f64,
        decoded as f64 / n.max(1) as f64,
    );
    println!("times: min / median of {repeats}");
    println!("build + encode        {}", ms(&build));
    println!("encode_split          {}", ms(&encode));
    println!("block (crc + zstd)    {}", ms(&block));
    println!("streamed, nothing kept {}", ms(&stream));
    println!(
        "decode_split          {}  ({:.2} GB/s of decoded memory)",
        ms(&decode),
        gbs(&decode)
    );
    println!(
        "memcpy, fresh buffer  {}  ({:.2} GB/s); decode takes {:.2}x a copy",
        ms(&copy),
        gbs(&copy),
        decode[0] / copy[0]
    );
    println!(
        "memcpy, huge pages    {}  ({:.2} GB/s); decode takes {:.2}x the stream and this copy",
        ms(&huge_copy),
        gbs(&huge_copy),
        decode[0] / (stream[0] + huge_copy[0])
    );
}
