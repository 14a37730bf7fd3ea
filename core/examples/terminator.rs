//! The shadow-terminator figures of docs/perf/terminator.md: coarse UV spheres with exact vertex
//! normals against the analytic sphere ([`hort_core::terminator`]).
//!
//! `cargo run -p hort-core --example terminator [size]` (default 400 x 400 pixels).

use hort_core::terminator::{measure, table};

fn main() {
    let size = std::env::args()
        .nth(1)
        .map_or(400, |s| s.parse().expect("size: a pixel count"));
    let rows: Vec<_> = [(4, 8), (8, 16), (16, 32), (32, 64)]
        .into_iter()
        .map(|(stacks, slices)| ((stacks, slices), measure(stacks, slices, size)))
        .collect();
    println!("{size} x {size} pixels, 1 sample a pixel (its centre)\n");
    print!("{}", table(&rows));
}
