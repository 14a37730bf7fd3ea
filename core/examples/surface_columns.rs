//! Where the bytes of surface-hit records go (docs/ARCHITECTURE.md, section 8):
//! `cargo run --release -p hort-core --example surface_columns -- SCENE [K]`.
//!
//! Runs a staged job of SCENE (spatial splits, K of them, default 8; 640x360, 1 spp) in memory,
//! decodes every cast-reduce (`Hit`) block, and compresses each column group of those records
//! on its own at the blocks' zstd level. Prints raw and compressed bytes per pixel of each
//! group as plain f32 byte planes, of the diffuse reflectance as an index into a table of its
//! distinct values, of the float groups as bit deltas (as blocks store them), and of the stored
//! blocks, so that lighter record layouts can be weighed on any scene.

use hort_core::ids::JobId;
use hort_core::pipeline::{
    ExecutionMode, PipelineOptions, PlanRequest, SplitMode, StoredOutputs, SurfaceHit,
    decode_surface_hits, run_pipeline,
};
use hort_core::scene::load_scene;
use hort_core::shuffle::columns::ColumnWriter;
use hort_core::shuffle::{RecordKind, ZSTD_LEVEL};
use hort_core::store::{BlobStore, MemoryStore};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// One column group: its name and how it writes the records.
type Group = (&'static str, fn(&mut ColumnWriter, &[SurfaceHit]));

fn vec3s(w: &mut ColumnWriter, hits: &[SurfaceHit], f: impl Fn(&SurfaceHit) -> [f32; 3]) {
    for axis in 0..3 {
        w.put_f32(&hits.iter().map(|h| f(h)[axis]).collect::<Vec<_>>());
    }
}

const GROUPS: [Group; 9] = [
    ("pixel", |w, h| {
        w.put_u32_sorted_delta(&h.iter().map(|h| h.pixel).collect::<Vec<_>>())
    }),
    ("sample", |w, h| {
        w.put_u32(&h.iter().map(|h| h.sample).collect::<Vec<_>>())
    }),
    ("t", |w, h| {
        w.put_f32(&h.iter().map(|h| h.t).collect::<Vec<_>>())
    }),
    ("triangle", |w, h| {
        w.put_u32(&h.iter().map(|h| h.triangle).collect::<Vec<_>>())
    }),
    ("p", |w, h| vec3s(w, h, |h| h.surface.p.to_array())),
    ("p_error", |w, h| {
        vec3s(w, h, |h| h.surface.p_error.to_array())
    }),
    ("n_geo", |w, h| vec3s(w, h, |h| h.surface.n_geo.to_array())),
    ("n_shade (flags + smooth)", |w, h| {
        let smooth: Vec<bool> = h
            .iter()
            .map(|h| {
                h.surface.n_shade.to_array().map(f32::to_bits)
                    != h.surface.n_geo.to_array().map(f32::to_bits)
            })
            .collect();
        w.put_bytes(&smooth.iter().map(|&s| u8::from(s)).collect::<Vec<_>>());
        let only: Vec<SurfaceHit> = h
            .iter()
            .zip(&smooth)
            .filter(|(_, s)| **s)
            .map(|(h, _)| *h)
            .collect();
        vec3s(w, &only, |h| h.surface.n_shade.to_array());
    }),
    ("kd", |w, h| vec3s(w, h, |h| h.surface.kd)),
];

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(path) = args.next().map(PathBuf::from) else {
        eprintln!("usage: surface_columns SCENE [K]");
        std::process::exit(2);
    };
    let k: u32 = args.next().map_or(8, |a| a.parse().expect("K"));
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
        job: JobId::new("columns").expect("a valid job id"),
        workers: 1,
        split_cache_bytes: 0,
    };
    run_pipeline(&store, &scene, request, &options).expect("the job runs");
    let mut blocks = Vec::new();
    let (mut stored, mut stored_raw) = (0usize, 0u64);
    for key in store.list("jobs/columns/cast-reduce/").expect("lists") {
        let bytes = store.get(&key).expect("reads");
        stored += bytes.len();
        stored_raw += u64::from_le_bytes(bytes[20..28].try_into().expect("a header"));
        blocks.push(decode_surface_hits(&key, &bytes, RecordKind::Hit).expect("decodes"));
    }
    let records: usize = blocks.iter().map(Vec::len).sum();
    let pixels = 640.0 * 360.0;
    println!(
        "{}: {} triangles, k = {k}, 640x360, 1 spp: {} Hit blocks, {records} records; zstd level {ZSTD_LEVEL}",
        path.display(),
        scene.mesh.triangle_count(),
        blocks.len()
    );
    println!(
        "{:<26} {:>9} {:>9}",
        "column group", "raw B/px", "zstd B/px"
    );
    let measure = |name: &str, write: &dyn Fn(&mut ColumnWriter, &[SurfaceHit])| {
        let (mut raw, mut packed) = (0usize, 0usize);
        for hits in &blocks {
            let mut w = ColumnWriter::new();
            write(&mut w, hits);
            raw += w.len();
            packed += zstd::bulk::compress(w.as_bytes(), ZSTD_LEVEL)
                .expect("compresses")
                .len();
        }
        println!(
            "{name:<26} {:>9.2} {:>9.2}",
            raw as f64 / pixels,
            packed as f64 / pixels
        );
    };
    for (name, write) in GROUPS {
        measure(name, &write);
    }
    // The alternative: kd as an index into the block's table of distinct values.
    measure("kd as table index", &|w, hits| {
        let mut table: BTreeMap<[u32; 3], u32> = BTreeMap::new();
        let index: Vec<u32> = hits
            .iter()
            .map(|h| {
                let next = table.len() as u32;
                *table.entry(h.surface.kd.map(f32::to_bits)).or_insert(next)
            })
            .collect();
        let values: Vec<u32> = table.keys().flatten().copied().collect();
        w.put_u32(&values);
        w.put_u32(&index);
    });
    // The alternative: f32 columns as differences of successive IEEE bit patterns (zigzag), so
    // that neighbouring samples' nearby values leave mostly zero high bytes.
    for (name, f) in [
        (
            "t as bit deltas",
            (|h: &SurfaceHit| [h.t; 3]) as fn(&SurfaceHit) -> [f32; 3],
        ),
        ("p as bit deltas", |h| h.surface.p.to_array()),
        ("p_error as bit deltas", |h| h.surface.p_error.to_array()),
        ("n_geo as bit deltas", |h| h.surface.n_geo.to_array()),
    ] {
        let axes = if name.starts_with("t ") { 1 } else { 3 };
        measure(name, &|w, hits| {
            for axis in 0..axes {
                let mut last = 0u32;
                let deltas: Vec<u32> = hits
                    .iter()
                    .map(|h| {
                        let bits = f(h)[axis].to_bits();
                        let d = bits.wrapping_sub(last) as i32;
                        last = bits;
                        ((d << 1) ^ (d >> 31)) as u32
                    })
                    .collect();
                w.put_u32(&deltas);
            }
        });
    }
    measure("all, plain f32 planes", &|w, hits| {
        for (_, write) in GROUPS {
            write(w, hits);
        }
    });
    println!(
        "{:<26} {:>9.2} {:>9.2}",
        "all, as stored (blocks)",
        stored_raw as f64 / pixels,
        stored as f64 / pixels
    );
}
