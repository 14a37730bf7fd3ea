//! What storage faults the embedded server injects ([`StorageFaults`]), how each request's fault
//! is drawn (seeded, deterministic), and how many were injected ([`FaultCounts`]).
//!
//! A request's draw is a pure function of the seed, its method, its path and query, and how
//! many requests with the same method, path and query came before it (its occurrence). So a
//! client that retries a failed request meets a fresh draw, and a run whose requests arrive in
//! the same order meets the same faults; requests for one URL racing on several connections
//! may swap draws between them.

use std::collections::HashMap;
use std::fmt;
use std::str::FromStr;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// One kind of injected fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FaultKind {
    /// HTTP 503 with the S3 error body `SlowDown` (throttling); the request is not carried out.
    SlowDown,
    /// HTTP 500 with the S3 error body `InternalError`; the request is not carried out.
    InternalError,
    /// The request is carried out after [`StorageFaults::latency_duration`].
    Latency,
    /// The request is carried out, then the connection is reset (TCP RST) after at most half of
    /// the answer's body (before the answer, for answers without a body).
    Reset,
    /// The request is carried out and the answer announces its full `Content-Length`, but the
    /// connection is closed (TCP FIN) after half of the body. Answers without a body (HEAD,
    /// PUT, DELETE) are sent whole and not counted.
    Truncate,
}

impl FaultKind {
    /// Every kind, in the order draws are partitioned.
    pub const ALL: [FaultKind; 5] = [
        FaultKind::SlowDown,
        FaultKind::InternalError,
        FaultKind::Latency,
        FaultKind::Reset,
        FaultKind::Truncate,
    ];

    /// The name in a fault specification: `slow-down`, `internal-error`, `latency`, `reset`,
    /// `truncate`.
    pub fn name(self) -> &'static str {
        match self {
            FaultKind::SlowDown => "slow-down",
            FaultKind::InternalError => "internal-error",
            FaultKind::Latency => "latency",
            FaultKind::Reset => "reset",
            FaultKind::Truncate => "truncate",
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

impl fmt::Display for FaultKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A fault that every request on some keys meets, every time.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PersistentFault {
    /// Object requests (GET, HEAD, PUT, DELETE) whose key starts with this prefix fail.
    pub key_prefix: String,
    /// How they fail; [`FaultKind::Latency`] is refused (it is not a failure).
    pub kind: FaultKind,
}

/// The faults the embedded server injects: per-request probabilities of each kind (at most one
/// fault per request) and an optional persistent fault.
#[derive(Clone, Debug, PartialEq)]
pub struct StorageFaults {
    /// Seed of every draw: the same seed and request order give the same faults.
    pub seed: u64,
    /// Probability of [`FaultKind::SlowDown`] per request, 0 to 1.
    pub slow_down: f64,
    /// Probability of [`FaultKind::InternalError`] per request, 0 to 1.
    pub internal_error: f64,
    /// Probability of [`FaultKind::Latency`] per request, 0 to 1.
    pub latency: f64,
    /// The delay a [`FaultKind::Latency`] fault adds.
    pub latency_duration: Duration,
    /// Probability of [`FaultKind::Reset`] per request, 0 to 1.
    pub reset: f64,
    /// Probability of [`FaultKind::Truncate`] per request, 0 to 1.
    pub truncate: f64,
    /// Keys whose every request fails.
    pub persistent: Option<PersistentFault>,
}

impl Default for StorageFaults {
    /// No faults; latency faults, once enabled, add 50 ms.
    fn default() -> Self {
        StorageFaults {
            seed: 0,
            slow_down: 0.0,
            internal_error: 0.0,
            latency: 0.0,
            latency_duration: Duration::from_millis(50),
            reset: 0.0,
            truncate: 0.0,
            persistent: None,
        }
    }
}

impl StorageFaults {
    /// The probability of `kind`.
    pub fn rate(&self, kind: FaultKind) -> f64 {
        match kind {
            FaultKind::SlowDown => self.slow_down,
            FaultKind::InternalError => self.internal_error,
            FaultKind::Latency => self.latency,
            FaultKind::Reset => self.reset,
            FaultKind::Truncate => self.truncate,
        }
    }

    fn rate_mut(&mut self, kind: FaultKind) -> &mut f64 {
        match kind {
            FaultKind::SlowDown => &mut self.slow_down,
            FaultKind::InternalError => &mut self.internal_error,
            FaultKind::Latency => &mut self.latency,
            FaultKind::Reset => &mut self.reset,
            FaultKind::Truncate => &mut self.truncate,
        }
    }

    /// Checks that every rate lies in 0..=1, that they sum to at most 1, and that the persistent
    /// fault is a failure; the error is one line naming the field.
    pub fn validate(&self) -> Result<(), String> {
        for kind in FaultKind::ALL {
            let rate = self.rate(kind);
            if !(0.0..=1.0).contains(&rate) {
                return Err(format!("{kind}: the rate {rate} is not between 0 and 1"));
            }
        }
        let sum: f64 = FaultKind::ALL.iter().map(|&k| self.rate(k)).sum();
        if sum > 1.0 + 1e-9 {
            return Err(format!(
                "the rates sum to {sum}, more than 1 (a request meets at most one fault)"
            ));
        }
        if let Some(p) = &self.persistent
            && p.kind == FaultKind::Latency
        {
            return Err(
                "persistent-kind: latency is not a failure; use slow-down, internal-error, \
                 reset or truncate"
                    .to_owned(),
            );
        }
        Ok(())
    }
}

/// Parses `key=value` pairs separated by commas, for example
/// `seed=7,slow-down=0.05,internal-error=0.05,latency=0.05,latency-ms=20,reset=0.05,truncate=0.05`
/// or `persistent-prefix=jobs/j/plan.json,persistent-kind=internal-error`. Keys: `seed`, the
/// five kind names (rates), `latency-ms`, `persistent-prefix`, `persistent-kind` (default
/// `slow-down`). Unset rates are 0. Errors are one line naming the pair.
impl FromStr for StorageFaults {
    type Err = String;

    fn from_str(spec: &str) -> Result<Self, String> {
        let mut faults = StorageFaults::default();
        let mut prefix = None;
        let mut persistent_kind = FaultKind::SlowDown;
        for pair in spec.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let (key, value) = pair
                .split_once('=')
                .ok_or_else(|| format!("{pair:?} is not key=value"))?;
            let number = |what: &str| format!("{pair:?}: {value:?} is not {what}");
            if let Some(kind) = FaultKind::ALL.into_iter().find(|k| k.name() == key) {
                *faults.rate_mut(kind) =
                    value.parse().map_err(|_| number("a number from 0 to 1"))?;
                continue;
            }
            match key {
                "seed" => faults.seed = value.parse().map_err(|_| number("an integer"))?,
                "latency-ms" => {
                    let ms: u64 = value.parse().map_err(|_| number("an integer"))?;
                    faults.latency_duration = Duration::from_millis(ms);
                }
                "persistent-prefix" if !value.is_empty() => prefix = Some(value.to_owned()),
                "persistent-prefix" => return Err(format!("{pair:?}: the prefix is empty")),
                "persistent-kind" => {
                    persistent_kind = FaultKind::ALL
                        .into_iter()
                        .find(|k| k.name() == value)
                        .ok_or_else(|| number("a fault kind"))?;
                }
                _ => {
                    return Err(format!(
                        "{pair:?}: unknown key {key:?} (expected seed, slow-down, \
                         internal-error, latency, latency-ms, reset, truncate, \
                         persistent-prefix or persistent-kind)"
                    ));
                }
            }
        }
        faults.persistent = prefix.map(|key_prefix| PersistentFault {
            key_prefix,
            kind: persistent_kind,
        });
        faults.validate()?;
        Ok(faults)
    }
}

/// How many faults were injected, by kind; persistent faults are counted apart.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaultCounts {
    /// Requests answered 503 `SlowDown`.
    pub slow_down: u64,
    /// Requests answered 500 `InternalError`.
    pub internal_error: u64,
    /// Requests delayed.
    pub latency: u64,
    /// Connections reset.
    pub reset: u64,
    /// Bodies cut short.
    pub truncate: u64,
    /// Requests that met the persistent fault.
    pub persistent: u64,
}

impl FaultCounts {
    /// The number of `kind` faults (transient ones; see [`FaultCounts::persistent`]).
    pub fn of(&self, kind: FaultKind) -> u64 {
        match kind {
            FaultKind::SlowDown => self.slow_down,
            FaultKind::InternalError => self.internal_error,
            FaultKind::Latency => self.latency,
            FaultKind::Reset => self.reset,
            FaultKind::Truncate => self.truncate,
        }
    }

    /// Every transient fault plus the persistent ones.
    pub fn total(&self) -> u64 {
        FaultKind::ALL.iter().map(|&k| self.of(k)).sum::<u64>() + self.persistent
    }
}

impl fmt::Display for FaultCounts {
    /// `3 slow-down, 0 internal-error, 1 latency, 2 reset, 1 truncate, 0 persistent`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for kind in FaultKind::ALL {
            write!(f, "{} {kind}, ", self.of(kind))?;
        }
        write!(f, "{} persistent", self.persistent)
    }
}

/// The fault a request meets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Decision {
    pub(crate) kind: FaultKind,
    pub(crate) persistent: bool,
}

/// Draws and counts faults for one server.
#[derive(Debug)]
pub(crate) struct Injector {
    pub(crate) faults: StorageFaults,
    /// Requests seen so far by (method, path and query).
    occurrences: Mutex<HashMap<String, u64>>,
    counts: [AtomicU64; 5],
    persistent: AtomicU64,
}

impl Injector {
    pub(crate) fn new(faults: StorageFaults) -> Self {
        Injector {
            faults,
            occurrences: Mutex::new(HashMap::new()),
            counts: Default::default(),
            persistent: AtomicU64::new(0),
        }
    }

    /// The fault for a request to `path_and_query` whose object key (path-style, decoded) is
    /// `key`, if it meets one. Not counted yet: see [`Injector::count`].
    pub(crate) fn decide(
        &self,
        method: &str,
        path_and_query: &str,
        key: Option<&str>,
    ) -> Option<Decision> {
        if let (Some(p), Some(key)) = (&self.faults.persistent, key)
            && key.starts_with(&p.key_prefix)
        {
            return Some(Decision {
                kind: p.kind,
                persistent: true,
            });
        }
        let label = format!("{method} {path_and_query}");
        let occurrence = {
            let mut seen = self.occurrences.lock().unwrap_or_else(|e| e.into_inner());
            let n = seen.entry(label.clone()).or_insert(0);
            *n += 1;
            *n - 1
        };
        let draw = unit_draw(self.faults.seed, &label, occurrence);
        let mut below = 0.0;
        for kind in FaultKind::ALL {
            below += self.faults.rate(kind);
            if draw < below {
                return Some(Decision {
                    kind,
                    persistent: false,
                });
            }
        }
        None
    }

    /// Records that `decision` was carried out.
    pub(crate) fn count(&self, decision: Decision) {
        let counter = if decision.persistent {
            &self.persistent
        } else {
            &self.counts[decision.kind.index()]
        };
        counter.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn counts(&self) -> FaultCounts {
        let of = |k: FaultKind| self.counts[k.index()].load(Ordering::Relaxed);
        FaultCounts {
            slow_down: of(FaultKind::SlowDown),
            internal_error: of(FaultKind::InternalError),
            latency: of(FaultKind::Latency),
            reset: of(FaultKind::Reset),
            truncate: of(FaultKind::Truncate),
            persistent: self.persistent.load(Ordering::Relaxed),
        }
    }
}

/// A uniform draw in [0, 1) from the seed, a label and an occurrence number (FNV-1a over the
/// label, mixed with SplitMix64; the top 53 bits make the fraction).
fn unit_draw(seed: u64, label: &str, occurrence: u64) -> f64 {
    let h = hort_digest::fnv1a64(label.as_bytes());
    let mut x = seed ^ h.rotate_left(17) ^ occurrence.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    for _ in 0..2 {
        x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
        x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        x ^= x >> 31;
    }
    (x >> 11) as f64 / (1u64 << 53) as f64
}

/// The object key of a path-style request path `/bucket/key` (percent-decoded), if it names
/// one.
pub(crate) fn object_key(path: &str) -> Option<String> {
    let rest = path.strip_prefix('/')?;
    let (_bucket, key) = rest.split_once('/')?;
    (!key.is_empty()).then(|| percent_decode(key))
}

/// `text` with `%XX` escapes decoded (invalid escapes are kept as they are).
fn percent_decode(text: &str) -> String {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        if bytes[i] == b'%'
            && let (Some(hi), Some(lo)) = (
                bytes.get(i + 1).copied().and_then(hex),
                bytes.get(i + 2).copied().and_then(hex),
            )
        {
            out.push((hi * 16 + lo) as u8);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_specification_parses_and_bad_ones_name_the_pair() {
        let faults: StorageFaults =
            "seed=7, slow-down=0.1,internal-error=0.05,latency=0.2,latency-ms=20,reset=0.05,\
             truncate=0.1,persistent-prefix=jobs/j/a%20b,persistent-kind=reset"
                .parse()
                .unwrap();
        assert_eq!(
            faults,
            StorageFaults {
                seed: 7,
                slow_down: 0.1,
                internal_error: 0.05,
                latency: 0.2,
                latency_duration: Duration::from_millis(20),
                reset: 0.05,
                truncate: 0.1,
                persistent: Some(PersistentFault {
                    key_prefix: "jobs/j/a%20b".into(),
                    kind: FaultKind::Reset
                }),
            }
        );
        assert_eq!(
            "".parse::<StorageFaults>().unwrap(),
            StorageFaults::default()
        );
        for (spec, error) in [
            ("reset", "\"reset\" is not key=value"),
            ("reset=x", "\"reset=x\": \"x\" is not a number from 0 to 1"),
            ("reset=1.5", "reset: the rate 1.5 is not between 0 and 1"),
            (
                "reset=0.6,truncate=0.6",
                "the rates sum to 1.2, more than 1 (a request meets at most one fault)",
            ),
            ("seed=-1", "\"seed=-1\": \"-1\" is not an integer"),
            (
                "persistent-prefix=",
                "\"persistent-prefix=\": the prefix is empty",
            ),
            (
                "persistent-kind=boom",
                "\"persistent-kind=boom\": \"boom\" is not a fault kind",
            ),
            (
                "persistent-prefix=a,persistent-kind=latency",
                "persistent-kind: latency is not a failure; use slow-down, internal-error, \
                 reset or truncate",
            ),
        ] {
            assert_eq!(spec.parse::<StorageFaults>().unwrap_err(), error, "{spec}");
        }
        let unknown = "rate=1".parse::<StorageFaults>().unwrap_err();
        assert!(
            unknown.starts_with("\"rate=1\": unknown key \"rate\""),
            "{unknown}"
        );
    }

    #[test]
    fn draws_are_seeded_per_occurrence_and_follow_the_rates() {
        let faults = StorageFaults {
            seed: 3,
            slow_down: 0.1,
            internal_error: 0.1,
            latency: 0.1,
            reset: 0.1,
            truncate: 0.1,
            ..StorageFaults::default()
        };
        let run = || {
            let injector = Injector::new(faults.clone());
            (0..2000)
                .map(|i| injector.decide("GET", &format!("/b/k{}", i % 50), None))
                .collect::<Vec<_>>()
        };
        let first = run();
        assert_eq!(first, run(), "same seed, same order: same faults");
        for kind in FaultKind::ALL {
            let n = first
                .iter()
                .filter(|d| d.is_some_and(|d| d.kind == kind))
                .count();
            // 10% of 2000 = 200; 5 standard deviations is about 67.
            assert!((133..=267).contains(&n), "{kind}: {n} of 2000");
        }
        let other = Injector::new(StorageFaults { seed: 4, ..faults });
        let second: Vec<_> = (0..2000)
            .map(|i| other.decide("GET", &format!("/b/k{}", i % 50), None))
            .collect();
        assert_ne!(first, second, "another seed, other faults");
    }

    #[test]
    fn the_persistent_fault_meets_every_request_under_its_prefix() {
        let injector = Injector::new(StorageFaults {
            persistent: Some(PersistentFault {
                key_prefix: "jobs/j/cast-map/".into(),
                kind: FaultKind::InternalError,
            }),
            ..StorageFaults::default()
        });
        let key = object_key("/hort/jobs/j/cast-map/00001/part-00000").unwrap();
        assert_eq!(key, "jobs/j/cast-map/00001/part-00000");
        for _ in 0..5 {
            assert_eq!(
                injector.decide("GET", "/hort/jobs/j/cast-map/00001/part-00000", Some(&key)),
                Some(Decision {
                    kind: FaultKind::InternalError,
                    persistent: true
                })
            );
        }
        let other = object_key("/hort/jobs/j/expand/00001/part-00000").unwrap();
        assert_eq!(injector.decide("GET", "/x", Some(&other)), None);
        assert_eq!(object_key("/hort"), None);
        assert_eq!(object_key("/hort/"), None);
        assert_eq!(object_key("/hort/a%7Eb%2"), Some("a~b%2".into()));
    }

    #[test]
    fn counts_add_up_and_print_on_one_line() {
        let injector = Injector::new(StorageFaults::default());
        for (kind, persistent) in [
            (FaultKind::SlowDown, false),
            (FaultKind::SlowDown, false),
            (FaultKind::Truncate, false),
            (FaultKind::Reset, true),
        ] {
            injector.count(Decision { kind, persistent });
        }
        let counts = injector.counts();
        assert_eq!(counts.total(), 4);
        assert_eq!(
            counts.to_string(),
            "2 slow-down, 0 internal-error, 0 latency, 0 reset, 1 truncate, 1 persistent"
        );
    }
}
