//! Time spent waiting on any store.

use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use super::{BlobStore, PutOutcome, StoreError};

/// Wraps any store and adds up the wall time of its calls, in microseconds, for the storage part
/// of a function's time breakdown. Calls and results pass through unchanged; calls made on
/// several threads at once each count their own time.
#[derive(Debug, Default)]
pub struct TimedStore<S: BlobStore> {
    inner: S,
    waited_us: AtomicU64,
}

impl<S: BlobStore> TimedStore<S> {
    /// Wraps `inner` with no time counted.
    pub fn new(inner: S) -> Self {
        Self {
            inner,
            waited_us: AtomicU64::new(0),
        }
    }

    /// Microseconds spent in calls so far.
    pub fn waited_us(&self) -> u64 {
        self.waited_us.load(Ordering::Relaxed)
    }

    fn timed<T>(&self, call: impl FnOnce(&S) -> T) -> T {
        let started = Instant::now();
        let out = call(&self.inner);
        let us = u64::try_from(started.elapsed().as_micros()).unwrap_or(u64::MAX);
        self.waited_us.fetch_add(us, Ordering::Relaxed);
        out
    }
}

impl<S: BlobStore> BlobStore for TimedStore<S> {
    fn get(&self, key: &str) -> Result<Vec<u8>, StoreError> {
        self.timed(|s| s.get(key))
    }

    fn get_range(&self, key: &str, range: Range<u64>) -> Result<Vec<u8>, StoreError> {
        self.timed(|s| s.get_range(key, range))
    }

    fn put(&self, key: &str, bytes: &[u8]) -> Result<(), StoreError> {
        self.timed(|s| s.put(key, bytes))
    }

    fn put_if_absent(&self, key: &str, bytes: &[u8]) -> Result<PutOutcome, StoreError> {
        self.timed(|s| s.put_if_absent(key, bytes))
    }

    fn list(&self, prefix: &str) -> Result<Vec<String>, StoreError> {
        self.timed(|s| s.list(prefix))
    }

    fn delete(&self, key: &str) -> Result<(), StoreError> {
        self.timed(|s| s.delete(key))
    }

    fn size(&self, key: &str) -> Result<u64, StoreError> {
        self.timed(|s| s.size(key))
    }

    fn copy(&self, from: &str, to: &str) -> Result<(), StoreError> {
        self.timed(|s| s.copy(from, to))
    }

    fn get_many(&self, keys: &[String]) -> Vec<Result<Vec<u8>, StoreError>> {
        self.timed(|s| s.get_many(keys))
    }

    fn put_many(&self, objects: &[(String, Vec<u8>)]) -> Vec<Result<(), StoreError>> {
        self.timed(|s| s.put_many(objects))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::MemoryStore;

    /// A store whose every call takes at least 2 ms.
    struct Slow(MemoryStore);

    const CALL: std::time::Duration = std::time::Duration::from_millis(2);

    impl BlobStore for Slow {
        fn get(&self, key: &str) -> Result<Vec<u8>, StoreError> {
            std::thread::sleep(CALL);
            self.0.get(key)
        }
        fn get_range(&self, key: &str, range: Range<u64>) -> Result<Vec<u8>, StoreError> {
            std::thread::sleep(CALL);
            self.0.get_range(key, range)
        }
        fn put(&self, key: &str, bytes: &[u8]) -> Result<(), StoreError> {
            std::thread::sleep(CALL);
            self.0.put(key, bytes)
        }
        fn put_if_absent(&self, key: &str, bytes: &[u8]) -> Result<PutOutcome, StoreError> {
            std::thread::sleep(CALL);
            self.0.put_if_absent(key, bytes)
        }
        fn list(&self, prefix: &str) -> Result<Vec<String>, StoreError> {
            std::thread::sleep(CALL);
            self.0.list(prefix)
        }
        fn delete(&self, key: &str) -> Result<(), StoreError> {
            std::thread::sleep(CALL);
            self.0.delete(key)
        }
    }

    /// Every call passes through, and each one's time is counted: nine calls of at least
    /// 2 ms each wait at least 18 ms.
    #[test]
    fn passes_calls_through_and_counts_their_time() {
        let store = TimedStore::new(Slow(MemoryStore::new()));
        store.put("a", b"xyz").unwrap();
        assert!(
            store.waited_us() >= 2_000,
            "the put's 2 ms are counted: {} us",
            store.waited_us()
        );
        assert_eq!(store.get("a").unwrap(), b"xyz");
        assert_eq!(store.get_range("a", 1..3).unwrap(), b"yz");
        assert_eq!(store.list("").unwrap(), ["a"]);
        assert!(store.get("b").unwrap_err().is_not_found());
        assert_eq!(store.size("a").unwrap(), 3);
        store.copy("a", "c").unwrap();
        assert_eq!(
            store.get_many(&["c".to_owned()])[0].as_deref().unwrap(),
            b"xyz"
        );
        store.delete("a").unwrap();
        assert!(
            store.waited_us() >= 9 * 2_000,
            "nine calls' 18 ms are counted: {} us",
            store.waited_us()
        );
    }
}
