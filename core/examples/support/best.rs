//! The timing loop the timing examples share (included with `#[path]`; not an example itself).

use std::time::Instant;

/// Runs `f` `repeats` times: the shortest wall time in seconds and the last result.
pub fn best<T>(repeats: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..repeats {
        let t = Instant::now();
        let v = f();
        best = best.min(t.elapsed().as_secs_f64());
        out = Some(v);
    }
    (best, out.expect("at least one repeat"))
}
