//! Time of a whole-scene BVH build (the issue of build speed, `core/src/bvh/README.md`):
//! `cargo run --release -p hort-core --example bvh_build_timing -- SCENE [REPEATS [THREADS]]`, where SCENE
//! is a scene file or `generated:N`, the scene `hort scene generate --triangles N --seed 1`
//! writes (generated here into a temporary file, deleted after loading).
//!
//! Builds the scene's BVH REPEATS (default 5) times on THREADS threads (default 1) and prints the minimum and median seconds and
//! a digest of the stored form of the BVH (its split-object node and pack bytes, ids and root
//! box), so that a change to the builder can be timed and shown to build the same tree.

use hort_core::bvh::Bvh;
use std::time::Instant;

#[path = "support/scene_arg.rs"]
mod scene_arg;
use scene_arg::load_scene_arg;

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(scene_arg) = args.next() else {
        eprintln!("usage: bvh_build_timing SCENE|generated:N [REPEATS]");
        std::process::exit(2);
    };
    let repeats: usize = args.next().map_or(5, |r| r.parse().expect("REPEATS"));
    let threads: usize = args.next().map_or(1, |t| t.parse().expect("THREADS"));
    let scene = load_scene_arg(&scene_arg);
    let mut seconds = Vec::with_capacity(repeats);
    let mut bvh = None;
    for _ in 0..repeats.max(1) {
        drop(bvh.take());
        let n = scene.mesh.triangle_count();
        let triangles = (0..n).map(|i| scene.mesh.corners(i)).collect();
        let start = Instant::now();
        bvh = Some(std::hint::black_box(Bvh::build_on_threads(
            triangles,
            (0..n as u32).collect(),
            threads,
        )));
        seconds.push(start.elapsed().as_secs_f64());
    }
    seconds.sort_by(f64::total_cmp);
    let bvh = bvh.expect("at least one build");
    let mut bytes = Vec::new();
    bvh.put_nodes(&mut bytes);
    bvh.put_lanes(&mut bytes);
    for id in bvh.ids() {
        bytes.extend_from_slice(&id.to_le_bytes());
    }
    let b = bvh.bounds();
    for v in [b.lo, b.hi] {
        for x in v.to_array() {
            bytes.extend_from_slice(&x.to_bits().to_le_bytes());
        }
    }
    println!(
        "{} triangles, {threads} threads: build min {:.4} s, median {:.4} s over {} runs; {} wide nodes, {} packs; digest {:016x}",
        bvh.triangle_count(),
        seconds[0],
        seconds[seconds.len() / 2],
        seconds.len(),
        bvh.wide_node_count(),
        bvh.pack_count(),
        hort_digest::fnv1a64(&bytes)
    );
}
