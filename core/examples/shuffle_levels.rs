//! The zstd level of shuffle blocks, by measurement (docs/ARCHITECTURE.md, section 8):
//! `cargo run --release -p hort-core --example shuffle_levels -- SCENE [K] [REPEATS]`.
//!
//! Runs a staged job of SCENE (spatial splits, K of them, default 8; 640x360, 1 spp) in memory,
//! then takes every shuffle block it stored and, per record kind and for each candidate zstd
//! level, recompresses the block's raw bytes and decompresses them again (best of REPEATS,
//! default 3). Prints raw and compressed bytes, compress and decompress CPU time, and the total
//! cost (CPU seconds plus the seconds to move the compressed bytes once up and once down at
//! 100 MB/s), so the level in `core/src/shuffle/block.rs` can be checked on any scene.

use hort_core::ids::JobId;
use hort_core::pipeline::{
    ExecutionMode, PipelineOptions, PlanRequest, SplitMode, StoredOutputs, run_pipeline,
};
use hort_core::scene::load_scene;
use hort_core::shuffle::{BLOCK_HEADER_LEN, BLOCK_MAGIC, RecordKind, decode_block};
use hort_core::store::{BlobStore, MemoryStore};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

/// The levels compared: zstd's fast levels, its default, and two stronger ones.
const LEVELS: [i32; 6] = [-3, -1, 1, 2, 3, 6];
/// Storage bandwidth at which bytes are charged, bytes per second (Lambda to S3).
const BANDWIDTH: f64 = 100e6;

fn best(repeats: usize, mut f: impl FnMut()) -> f64 {
    (0..repeats)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(path) = args.next().map(PathBuf::from) else {
        eprintln!("usage: shuffle_levels SCENE [K] [REPEATS]");
        std::process::exit(2);
    };
    let k: u32 = args.next().map_or(8, |a| a.parse().expect("K"));
    let repeats: usize = args.next().map_or(3, |a| a.parse().expect("REPEATS"));
    let scene = load_scene(&path).expect("the scene loads");
    let store = MemoryStore::new();
    let request = PlanRequest {
        width: 640,
        height: 360,
        spp: 1,
        splits: Some(k),
        spans: None,
        mode: SplitMode::Spatial,
        execution: Some(ExecutionMode::Staged),
        memory_mb: 10_240,
        adaptive: None,
        outputs: StoredOutputs::ALL,
        frame: Default::default(),
    };
    let options = PipelineOptions {
        job: JobId::new("levels").expect("a valid job id"),
        workers: 1,
        split_cache_bytes: 0,
    };
    run_pipeline(&store, &scene, request, &options).expect("the job runs");
    // Raw bytes of every stored block, per kind.
    let mut blocks: BTreeMap<u16, (RecordKind, Vec<Vec<u8>>)> = BTreeMap::new();
    for key in store.list("jobs/").expect("lists") {
        let bytes = store.get(&key).expect("reads");
        if bytes.len() < BLOCK_HEADER_LEN || bytes[..8] != BLOCK_MAGIC {
            continue;
        }
        let code = u16::from_le_bytes([bytes[10], bytes[11]]);
        let kind = RecordKind::from_code(code).expect("a known kind");
        let block = decode_block(&key, &bytes, kind).expect("decodes");
        blocks
            .entry(code)
            .or_insert_with(|| (kind, Vec::new()))
            .1
            .push(block.raw);
    }
    let pixels = 640.0 * 360.0;
    println!(
        "{}: {} triangles, k = {k}, 640x360, 1 spp; bytes charged at {:.0} MB/s up and down",
        path.display(),
        scene.mesh.triangle_count(),
        BANDWIDTH / 1e6
    );
    println!(
        "{:<14} {:>6} {:>5} {:>11} {:>11} {:>7} {:>9} {:>9} {:>9}",
        "kind", "blocks", "level", "raw B", "zstd B", "B/px", "comp ms", "dec ms", "cost ms"
    );
    let mut totals = vec![(0usize, 0.0f64, 0.0f64); LEVELS.len()];
    for (kind, raws) in blocks.values() {
        let raw_bytes: usize = raws.iter().map(Vec::len).sum();
        for (li, &level) in LEVELS.iter().enumerate() {
            let packed: Vec<Vec<u8>> = raws
                .iter()
                .map(|r| zstd::bulk::compress(r, level).expect("compresses"))
                .collect();
            let compress = best(repeats, || {
                for r in raws {
                    std::hint::black_box(zstd::bulk::compress(r, level).expect("compresses"));
                }
            });
            let decompress = best(repeats, || {
                for (p, r) in packed.iter().zip(raws) {
                    std::hint::black_box(zstd::bulk::decompress(p, r.len()).expect("decompresses"));
                }
            });
            let zbytes: usize = packed.iter().map(Vec::len).sum();
            let cost = compress + decompress + 2.0 * zbytes as f64 / BANDWIDTH;
            totals[li].0 += zbytes;
            totals[li].1 += compress + decompress;
            totals[li].2 += cost;
            println!(
                "{:<14} {:>6} {:>5} {:>11} {:>11} {:>7.2} {:>9.1} {:>9.1} {:>9.1}",
                format!("{kind:?}"),
                raws.len(),
                level,
                raw_bytes,
                zbytes,
                zbytes as f64 / pixels,
                compress * 1e3,
                decompress * 1e3,
                cost * 1e3
            );
        }
    }
    println!("all shuffle and split blocks:");
    for (li, level) in LEVELS.iter().enumerate() {
        let (zbytes, cpu, cost) = totals[li];
        println!(
            "  level {level:>2}: {zbytes:>11} B, CPU {:>7.1} ms, total cost {:>7.1} ms",
            cpu * 1e3,
            cost * 1e3
        );
    }
}
