//! Timing one piece of work in a benchmark.

use std::time::Instant;

/// Best wall time of `repeats` runs of `f`, and the last run's result.
pub(super) fn best_of<T>(repeats: u32, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..repeats.max(1) {
        let start = Instant::now();
        let r = f();
        best = best.min(start.elapsed().as_secs_f64());
        last = Some(r);
    }
    (best, last.expect("at least one run"))
}
