//! Retry and catch policy, as Step Functions applies it.
//!
//! - A failed attempt is matched against the state's retriers in order; only the FIRST retrier
//!   whose `ErrorEquals` matches applies. If that retrier has attempts left the state is retried,
//!   otherwise it fails (later retriers are not consulted).
//! - Attempt counts are kept per retrier; the delay before the retrier's (n+1)-th retry
//!   (n = 0, 1, …) is `IntervalSeconds * BackoffRate^n`, capped at `MaxDelaySeconds`; with
//!   `JitterStrategy: FULL` the delay is uniform in `[0, delay)`.
//! - `States.ALL` matches every error but `States.Runtime` and `States.DataLimitExceeded`;
//!   `States.TaskFailed` matches every error but those two and `States.Timeout`. Those two are
//!   terminal: never retried or caught, by any name.
//!
//! Jitter is deterministic: it is a hash of the run's seed, the state path, the item index and
//! the retry number, so it does not depend on thread interleaving.

use std::time::Duration;

/// The error name of a data or path error inside the interpreter: never retried or caught.
pub const RUNTIME: &str = "States.Runtime";
/// The error of a payload over Step Functions' 256 KiB (terminal, like [`RUNTIME`]).
pub const DATA_LIMIT_EXCEEDED: &str = hort_aws_quotas::DATA_LIMIT_EXCEEDED;
/// The error name of an attempt (or execution) that ran past its timeout.
pub const TIMEOUT: &str = "States.Timeout";
/// The wildcard matching every error but [`RUNTIME`].
pub const ALL: &str = "States.ALL";
/// The wildcard matching every error but [`TIMEOUT`] and [`RUNTIME`].
pub const TASK_FAILED: &str = "States.TaskFailed";

/// How a retry delay is randomised.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Jitter {
    /// The delay is exactly the backoff interval.
    None,
    /// The delay is uniform in `[0, interval)`.
    Full,
}

/// One entry of a state's `Retry` array, with the Step Functions defaults filled in.
#[derive(Debug, Clone, PartialEq)]
pub struct Retrier {
    /// Error names this retrier matches (wildcards allowed).
    pub error_equals: Vec<String>,
    /// Seconds before the first retry (default 1).
    pub interval_seconds: f64,
    /// Retries this retrier allows (default 3; 0 means never retry).
    pub max_attempts: u32,
    /// Multiplier of the interval per retry (default 2.0, at least 1.0).
    pub backoff_rate: f64,
    /// Upper bound of the interval in seconds, if any.
    pub max_delay_seconds: Option<f64>,
    /// Randomisation of the interval (default none).
    pub jitter: Jitter,
}

/// One entry of a state's `Catch` array.
#[derive(Debug, Clone, PartialEq)]
pub struct Catcher {
    /// Error names this catcher matches (wildcards allowed).
    pub error_equals: Vec<String>,
    /// The state to go to.
    pub next: String,
    /// Where the error object `{"Error", "Cause"}` goes in the state's raw input.
    pub result_path: super::paths::ResultPath,
}

/// True if the pattern (an `ErrorEquals` entry) matches the error name.
pub fn error_matches(pattern: &str, error: &str) -> bool {
    if error == RUNTIME || error == DATA_LIMIT_EXCEEDED {
        return false;
    }
    match pattern {
        ALL => true,
        TASK_FAILED => error != TIMEOUT,
        _ => pattern == error,
    }
}

/// The index of the first entry whose `ErrorEquals` matches the error, if any.
pub fn first_match<'p>(
    lists: impl IntoIterator<Item = &'p [String]>,
    error: &str,
) -> Option<usize> {
    lists
        .into_iter()
        .position(|names| names.iter().any(|p| error_matches(p, error)))
}

/// The backoff before the retry that follows `retries_done` earlier retries of the same
/// retrier, before jitter: `IntervalSeconds * BackoffRate^retries_done` capped at
/// `MaxDelaySeconds`.
pub fn backoff_seconds(retrier: &Retrier, retries_done: u32) -> f64 {
    let exponent = i32::try_from(retries_done).unwrap_or(i32::MAX);
    let delay = retrier.interval_seconds * retrier.backoff_rate.powi(exponent);
    match retrier.max_delay_seconds {
        Some(cap) => delay.min(cap),
        None => delay,
    }
}

/// The delay actually waited: the backoff, and with FULL jitter a deterministic uniform draw
/// in `[0, backoff)` keyed by `(seed, state, item, retry)`.
pub fn retry_delay(
    retrier: &Retrier,
    retries_done: u32,
    seed: u64,
    state: &str,
    item: Option<usize>,
) -> Duration {
    let backoff = backoff_seconds(retrier, retries_done);
    let seconds = match retrier.jitter {
        Jitter::None => backoff,
        Jitter::Full => backoff * unit_draw(seed, state, item, retries_done),
    };
    Duration::try_from_secs_f64(seconds).unwrap_or(Duration::MAX)
}

/// A uniform number in `[0, 1)` that depends only on its arguments: the FULL jitter of retries,
/// and any other seeded decision a caller wants reproducible (the emulator's fault injection).
pub fn unit_draw(seed: u64, state: &str, item: Option<usize>, retry: u32) -> f64 {
    // FNV-1a over the state path, then splitmix64 rounds mixing in the other keys.
    let h = hort_digest::fnv1a64(state.as_bytes());
    let item = item.map_or(u64::MAX, |i| i as u64);
    let mut x = splitmix(seed ^ splitmix(h));
    x = splitmix(x ^ item);
    x = splitmix(x ^ u64::from(retry));
    (x >> 11) as f64 / (1u64 << 53) as f64
}

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Retry bookkeeping of one state entry: retries used per retrier, and the total, which is what
/// `$$.State.RetryCount` reports.
#[derive(Debug, Clone)]
pub struct RetryState {
    used: Vec<u32>,
    total: u32,
}

/// What to do after a failed attempt.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Decision {
    /// Retry after this delay.
    Retry(Duration),
    /// No retrier matched, or the matching one is exhausted.
    GiveUp,
}

impl RetryState {
    /// Fresh bookkeeping for a state with `retriers` retriers.
    pub fn new(retriers: usize) -> Self {
        Self {
            used: vec![0; retriers],
            total: 0,
        }
    }

    /// Retries made so far in this state entry, over all retriers (`$$.State.RetryCount`).
    pub fn total(&self) -> u32 {
        self.total
    }

    /// Decides on a failed attempt with error `error`, counting the retry if there is one.
    pub fn decide(
        &mut self,
        retriers: &[Retrier],
        error: &str,
        seed: u64,
        state: &str,
        item: Option<usize>,
    ) -> Decision {
        let Some(i) = first_match(retriers.iter().map(|r| r.error_equals.as_slice()), error) else {
            return Decision::GiveUp;
        };
        let retrier = &retriers[i];
        if self.used[i] >= retrier.max_attempts {
            return Decision::GiveUp;
        }
        let delay = retry_delay(retrier, self.used[i], seed, state, item);
        self.used[i] += 1;
        self.total += 1;
        Decision::Retry(delay)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn retrier(names: &[&str], interval: f64, max: u32, rate: f64, cap: Option<f64>) -> Retrier {
        Retrier {
            error_equals: names.iter().map(|s| s.to_string()).collect(),
            interval_seconds: interval,
            max_attempts: max,
            backoff_rate: rate,
            max_delay_seconds: cap,
            jitter: Jitter::None,
        }
    }

    #[test]
    fn backoff_is_interval_times_rate_power_capped() {
        let r = retrier(&["X"], 1.0, 10, 2.0, Some(20.0));
        let got: Vec<f64> = (0..7).map(|n| backoff_seconds(&r, n)).collect();
        assert_eq!(got, [1.0, 2.0, 4.0, 8.0, 16.0, 20.0, 20.0]);
        let r = retrier(&["X"], 3.0, 10, 1.5, None);
        let got: Vec<f64> = (0..4).map(|n| backoff_seconds(&r, n)).collect();
        assert_eq!(got, [3.0, 4.5, 6.75, 10.125]);
        let r = retrier(&["X"], 2.0, 10, 1.0, Some(1.0));
        assert_eq!(backoff_seconds(&r, 5), 1.0);
        assert_eq!(
            retry_delay(&r, 0, 0, "S", None),
            Duration::from_secs_f64(1.0)
        );
    }

    #[test]
    fn full_jitter_is_bounded_deterministic_and_spread() {
        let mut r = retrier(&["X"], 1.0, 10, 2.0, Some(8.0));
        r.jitter = Jitter::Full;
        let mut seen = Vec::new();
        for item in 0..200 {
            for n in 0..6 {
                let cap = backoff_seconds(&r, n);
                let d = retry_delay(&r, n, 42, "CastMap/CastMapTask", Some(item));
                assert!(
                    d.as_secs_f64() < cap && d.as_secs_f64() >= 0.0,
                    "{d:?} vs {cap}"
                );
                assert_eq!(d, retry_delay(&r, n, 42, "CastMap/CastMapTask", Some(item)));
                seen.push(d.as_secs_f64() / cap);
            }
        }
        let mean = seen.iter().sum::<f64>() / seen.len() as f64;
        assert!((mean - 0.5).abs() < 0.05, "mean {mean}");
        assert!(seen.iter().any(|&u| u < 0.1) && seen.iter().any(|&u| u > 0.9));
        let other_seed = retry_delay(&r, 0, 43, "CastMap/CastMapTask", Some(0));
        let other_state = retry_delay(&r, 0, 42, "TraceMap/TraceMapTask", Some(0));
        let base = retry_delay(&r, 0, 42, "CastMap/CastMapTask", Some(0));
        assert!(other_seed != base && other_state != base);
    }

    #[test]
    fn wildcards_follow_step_functions() {
        assert!(error_matches(ALL, "Hort.BadInput"));
        assert!(error_matches(ALL, TIMEOUT));
        assert!(!error_matches(ALL, RUNTIME));
        assert!(error_matches(TASK_FAILED, "Hort.Retryable"));
        assert!(!error_matches(TASK_FAILED, TIMEOUT));
        assert!(!error_matches(RUNTIME, RUNTIME));
        assert!(!error_matches(ALL, DATA_LIMIT_EXCEEDED));
        assert!(!error_matches(TASK_FAILED, DATA_LIMIT_EXCEEDED));
        assert!(!error_matches(DATA_LIMIT_EXCEEDED, DATA_LIMIT_EXCEEDED));
        assert!(error_matches("Hort.Retryable", "Hort.Retryable"));
        assert!(!error_matches("Hort.Retryable", "Hort.BadInput"));
    }

    #[test]
    fn first_matching_retrier_decides_and_counts_per_retrier() {
        let retriers = [
            retrier(&["Hort.BadInput"], 1.0, 0, 2.0, None),
            retrier(&[TIMEOUT], 1.0, 1, 2.0, None),
            retrier(&["Hort.Retryable", TASK_FAILED], 1.0, 2, 2.0, None),
        ];
        let mut st = RetryState::new(retriers.len());
        let mut decide = |e: &str| st.decide(&retriers, e, 0, "S", None);
        assert_eq!(decide("Hort.BadInput"), Decision::GiveUp);
        assert_eq!(
            decide("Hort.Retryable"),
            Decision::Retry(Duration::from_secs(1))
        );
        assert_eq!(decide(TIMEOUT), Decision::Retry(Duration::from_secs(1)));
        assert_eq!(decide("Other"), Decision::Retry(Duration::from_secs(2)));
        // The third retrier is exhausted; the timeout one too, and nothing falls through.
        assert_eq!(decide("Hort.Retryable"), Decision::GiveUp);
        assert_eq!(decide(TIMEOUT), Decision::GiveUp);
        assert_eq!(decide(RUNTIME), Decision::GiveUp);
        assert_eq!(st.total(), 3);
    }
}
