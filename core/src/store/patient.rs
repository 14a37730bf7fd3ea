//! [`PatientStore`]: retries what storage calls retryable, for callers with no orchestrator
//! behind them (a client uploading a job, reading its outputs back), where one unlucky request
//! would otherwise fail the whole run.

use super::{BlobStore, PutOutcome, StoreError};
use std::ops::Range;
use std::time::Duration;

/// A store that repeats a request failing with [`StoreError::Unavailable`], up to `attempts`
/// times in all, waiting `first_wait`, then twice that, and so on between them. Every other
/// result is returned at once. Safe for every operation: puts replace whole objects, and a
/// repeated `put_if_absent` whose first answer was lost sees [`PutOutcome::AlreadyExists`]
/// (callers compare the stored bytes, as the job upload does).
pub struct PatientStore<S> {
    inner: S,
    attempts: u32,
    first_wait: Duration,
}

impl<S: BlobStore> PatientStore<S> {
    /// `inner` with up to `attempts` tries per request (at least 1).
    pub fn new(inner: S, attempts: u32, first_wait: Duration) -> Self {
        PatientStore {
            inner,
            attempts: attempts.max(1),
            first_wait,
        }
    }

    fn patiently<T>(&self, op: impl Fn() -> Result<T, StoreError>) -> Result<T, StoreError> {
        self.retried(op(), op)
    }

    /// `first`, the result of a first try of `op`, or the result of trying `op` again while
    /// the failure is retryable and attempts are left.
    fn retried<T>(
        &self,
        first: Result<T, StoreError>,
        op: impl Fn() -> Result<T, StoreError>,
    ) -> Result<T, StoreError> {
        let mut result = first;
        let mut wait = self.first_wait;
        let mut tries = 1;
        loop {
            match result {
                Err(e) if e.is_retryable() && tries < self.attempts => {
                    std::thread::sleep(wait);
                    wait = wait.saturating_mul(2);
                    tries += 1;
                    result = op();
                }
                result => return result,
            }
        }
    }

    /// [`PatientStore::retried`] of each item's first result (`firsts[i]` the first try of
    /// `op(&items[i])`), in order.
    fn each_retried<I, T>(
        &self,
        firsts: Vec<Result<T, StoreError>>,
        items: &[I],
        op: impl Fn(&I) -> Result<T, StoreError>,
    ) -> Vec<Result<T, StoreError>> {
        firsts
            .into_iter()
            .zip(items)
            .map(|(first, item)| self.retried(first, || op(item)))
            .collect()
    }
}

impl<S: BlobStore> BlobStore for PatientStore<S> {
    fn get(&self, key: &str) -> Result<Vec<u8>, StoreError> {
        self.patiently(|| self.inner.get(key))
    }

    fn get_range(&self, key: &str, range: Range<u64>) -> Result<Vec<u8>, StoreError> {
        self.patiently(|| self.inner.get_range(key, range.clone()))
    }

    fn put(&self, key: &str, bytes: &[u8]) -> Result<(), StoreError> {
        self.patiently(|| self.inner.put(key, bytes))
    }

    fn put_if_absent(&self, key: &str, bytes: &[u8]) -> Result<PutOutcome, StoreError> {
        self.patiently(|| self.inner.put_if_absent(key, bytes))
    }

    fn list(&self, prefix: &str) -> Result<Vec<String>, StoreError> {
        self.patiently(|| self.inner.list(prefix))
    }

    fn delete(&self, key: &str) -> Result<(), StoreError> {
        self.patiently(|| self.inner.delete(key))
    }

    fn size(&self, key: &str) -> Result<u64, StoreError> {
        self.patiently(|| self.inner.size(key))
    }

    fn copy(&self, from: &str, to: &str) -> Result<(), StoreError> {
        self.patiently(|| self.inner.copy(from, to))
    }

    /// All at once through the inner store's `get_many`; then each key whose first try failed
    /// retryably is tried again on its own, with the attempts left.
    fn get_many(&self, keys: &[String]) -> Vec<Result<Vec<u8>, StoreError>> {
        self.each_retried(self.inner.get_many(keys), keys, |key| self.inner.get(key))
    }

    /// As [`PatientStore::get_many`], for puts.
    fn put_many(&self, objects: &[(String, Vec<u8>)]) -> Vec<Result<(), StoreError>> {
        self.each_retried(self.inner.put_many(objects), objects, |(key, bytes)| {
            self.inner.put(key, bytes)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::MemoryStore;
    use std::sync::atomic::{AtomicU32, Ordering};

    /// Fails the first `failures` calls of each kind with `error`, then passes through.
    struct Flaky {
        inner: MemoryStore,
        failures: u32,
        calls: AtomicU32,
        error: fn() -> StoreError,
    }

    impl BlobStore for Flaky {
        fn get(&self, key: &str) -> Result<Vec<u8>, StoreError> {
            if self.calls.fetch_add(1, Ordering::SeqCst) < self.failures {
                return Err((self.error)());
            }
            self.inner.get(key)
        }
        fn get_range(&self, key: &str, range: Range<u64>) -> Result<Vec<u8>, StoreError> {
            self.inner.get_range(key, range)
        }
        fn put(&self, key: &str, bytes: &[u8]) -> Result<(), StoreError> {
            self.inner.put(key, bytes)
        }
        fn put_if_absent(&self, key: &str, bytes: &[u8]) -> Result<PutOutcome, StoreError> {
            self.inner.put_if_absent(key, bytes)
        }
        fn list(&self, prefix: &str) -> Result<Vec<String>, StoreError> {
            self.inner.list(prefix)
        }
        fn delete(&self, key: &str) -> Result<(), StoreError> {
            self.inner.delete(key)
        }
    }

    fn flaky(failures: u32, error: fn() -> StoreError) -> PatientStore<Flaky> {
        let inner = MemoryStore::new();
        inner.put("k", b"v").unwrap();
        let flaky = Flaky {
            inner,
            failures,
            calls: AtomicU32::new(0),
            error,
        };
        PatientStore::new(flaky, 4, Duration::ZERO)
    }

    fn unavailable() -> StoreError {
        StoreError::Unavailable { what: "503".into() }
    }

    #[test]
    fn retryable_failures_are_repeated_up_to_the_attempts() {
        let store = flaky(3, unavailable);
        assert_eq!(store.get("k").unwrap(), b"v");
        assert_eq!(store.inner.calls.load(Ordering::SeqCst), 4);
        let store = flaky(4, unavailable);
        assert_eq!(store.get("k"), Err(unavailable()));
        assert_eq!(store.inner.calls.load(Ordering::SeqCst), 4);
    }

    #[test]
    fn several_at_once_retry_each_failed_key_with_the_attempts_left() {
        // Flaky's get_many is one get after another: the batch's two gets fail (calls 1 and 2),
        // then the first key is tried again (call 3 fails, call 4 succeeds) and the second
        // (call 5 succeeds).
        let keys = ["k".to_owned(), "k".to_owned()];
        let store = flaky(3, unavailable);
        assert_eq!(
            store.get_many(&keys),
            [Ok(b"v".to_vec()), Ok(b"v".to_vec())]
        );
        assert_eq!(store.inner.calls.load(Ordering::SeqCst), 5);
        // Five failures: the first key's four attempts (calls 1, 3, 4, 5) all fail; the second
        // key's first try (call 2) failed and its retry (call 6) succeeds.
        let store = flaky(5, unavailable);
        assert_eq!(
            store.get_many(&keys),
            [Err(unavailable()), Ok(b"v".to_vec())]
        );
        assert_eq!(store.inner.calls.load(Ordering::SeqCst), 6);
        // A missing key is an answer, not a failure: no retry.
        let store = flaky(0, unavailable);
        let results = store.get_many(&["gone".to_owned()]);
        assert!(matches!(results[0], Err(StoreError::NotFound { .. })));
        assert_eq!(store.inner.calls.load(Ordering::SeqCst), 1);
    }

    #[test]
    fn other_failures_are_returned_at_once() {
        let store = flaky(1, || StoreError::Denied { what: "no".into() });
        assert_eq!(
            store.get("k"),
            Err(StoreError::Denied { what: "no".into() })
        );
        assert_eq!(store.inner.calls.load(Ordering::SeqCst), 1);
    }
}
