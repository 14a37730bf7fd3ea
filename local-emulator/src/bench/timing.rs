//! Timing one piece of work in a benchmark.

use std::time::Instant;

/// Best wall time of `repeats` runs of `f`, and the last run's result.
pub(super) fn best_of<T>(repeats: u32, mut f: impl FnMut() -> T) -> (f64, T) {
    best_of_prepared(repeats, || (), |()| f())
}

/// [`best_of`] where each run's input is made by `prepare` first, outside the timed part.
pub(super) fn best_of_prepared<I, T>(
    repeats: u32,
    mut prepare: impl FnMut() -> I,
    mut f: impl FnMut(I) -> T,
) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..repeats.max(1) {
        let input = prepare();
        let start = Instant::now();
        let r = f(input);
        best = best.min(start.elapsed().as_secs_f64());
        last = Some(r);
    }
    (best, last.expect("at least one run"))
}
