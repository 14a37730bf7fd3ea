//! Request and byte counting for any store.

use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

use super::{BlobStore, PutOutcome, StoreError, StoreStats};

/// Thread-safe counters behind [`StoreStats`]; shared by [`CountingStore`] and the memory store.
#[derive(Debug, Default)]
pub(super) struct Counters {
    gets: AtomicU64,
    puts: AtomicU64,
    lists: AtomicU64,
    deletes: AtomicU64,
    bytes_read: AtomicU64,
    bytes_written: AtomicU64,
}

fn add(counter: &AtomicU64, n: usize) {
    // usize -> u64 never truncates on supported targets (<= 64-bit).
    counter.fetch_add(n as u64, Ordering::Relaxed);
}

impl Counters {
    /// Counts one get; adds the returned bytes if it succeeded.
    pub(super) fn get(&self, result: &Result<Vec<u8>, StoreError>) {
        add(&self.gets, 1);
        if let Ok(bytes) = result {
            add(&self.bytes_read, bytes.len());
        }
    }

    /// Counts one HEAD, as a get of no bytes.
    pub(super) fn head(&self) {
        add(&self.gets, 1);
    }

    /// Counts one put of `len` bytes; adds them if `stored`.
    pub(super) fn put(&self, len: usize, stored: bool) {
        add(&self.puts, 1);
        if stored {
            add(&self.bytes_written, len);
        }
    }

    /// Counts one list call.
    pub(super) fn list(&self) {
        add(&self.lists, 1);
    }

    /// Counts one delete.
    pub(super) fn delete(&self) {
        add(&self.deletes, 1);
    }

    /// A snapshot; each field is exact, fields racing with in-flight requests may be one apart.
    pub(super) fn snapshot(&self) -> StoreStats {
        StoreStats {
            gets: self.gets.load(Ordering::Relaxed),
            puts: self.puts.load(Ordering::Relaxed),
            lists: self.lists.load(Ordering::Relaxed),
            deletes: self.deletes.load(Ordering::Relaxed),
            bytes_read: self.bytes_read.load(Ordering::Relaxed),
            bytes_written: self.bytes_written.load(Ordering::Relaxed),
        }
    }
}

/// Wraps any store and counts its requests and bytes (see [`StoreStats`] for what is counted).
///
/// Behaviour is otherwise identical to the wrapped store: every call and result passes through.
/// Take [`CountingStore::stats`] before and after a stage and use [`StoreStats::since`] for the
/// stage's own traffic.
#[derive(Debug, Default)]
pub struct CountingStore<S: BlobStore> {
    inner: S,
    counters: Counters,
}

impl<S: BlobStore> CountingStore<S> {
    /// Wraps `inner` with all counts at zero.
    pub fn new(inner: S) -> Self {
        Self {
            inner,
            counters: Counters::default(),
        }
    }

    /// The counts since construction.
    pub fn stats(&self) -> StoreStats {
        self.counters.snapshot()
    }

    /// The wrapped store (requests made through it are not counted).
    pub fn inner(&self) -> &S {
        &self.inner
    }

    /// Unwraps the store, dropping the counts.
    pub fn into_inner(self) -> S {
        self.inner
    }
}

impl<S: BlobStore> BlobStore for CountingStore<S> {
    fn get(&self, key: &str) -> Result<Vec<u8>, StoreError> {
        let result = self.inner.get(key);
        self.counters.get(&result);
        result
    }

    fn get_range(&self, key: &str, range: Range<u64>) -> Result<Vec<u8>, StoreError> {
        let result = self.inner.get_range(key, range);
        self.counters.get(&result);
        result
    }

    fn put(&self, key: &str, bytes: &[u8]) -> Result<(), StoreError> {
        let result = self.inner.put(key, bytes);
        self.counters.put(bytes.len(), result.is_ok());
        result
    }

    fn put_if_absent(&self, key: &str, bytes: &[u8]) -> Result<PutOutcome, StoreError> {
        let result = self.inner.put_if_absent(key, bytes);
        self.counters
            .put(bytes.len(), matches!(result, Ok(PutOutcome::Created)));
        result
    }

    fn list(&self, prefix: &str) -> Result<Vec<String>, StoreError> {
        self.counters.list();
        self.inner.list(prefix)
    }

    fn delete(&self, key: &str) -> Result<(), StoreError> {
        self.counters.delete();
        self.inner.delete(key)
    }

    /// A HEAD: counted as a GET of no bytes (S3 prices them alike).
    fn size(&self, key: &str) -> Result<u64, StoreError> {
        let result = self.inner.size(key);
        self.counters.head();
        result
    }

    /// A copy inside the store: counted as a PUT of no bytes through the client (S3 prices a
    /// CopyObject as a PUT).
    fn copy(&self, from: &str, to: &str) -> Result<(), StoreError> {
        let result = self.inner.copy(from, to);
        self.counters.put(0, result.is_ok());
        result
    }

    fn get_many(&self, keys: &[String]) -> Vec<Result<Vec<u8>, StoreError>> {
        let results = self.inner.get_many(keys);
        results.iter().for_each(|result| self.counters.get(result));
        results
    }

    fn put_many(&self, objects: &[(String, Vec<u8>)]) -> Vec<Result<(), StoreError>> {
        let results = self.inner.put_many(objects);
        for ((_, bytes), result) in objects.iter().zip(&results) {
            self.counters.put(bytes.len(), result.is_ok());
        }
        results
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::MemoryStore;

    #[test]
    fn counts_requests_and_successful_bytes() {
        let store = CountingStore::new(MemoryStore::new());
        store.put("a", b"hello").unwrap();
        assert_eq!(
            store.put_if_absent("a", b"xx").unwrap(),
            PutOutcome::AlreadyExists
        );
        assert_eq!(
            store.put_if_absent("b", b"xyz").unwrap(),
            PutOutcome::Created
        );
        assert_eq!(store.get("a").unwrap(), b"hello");
        assert_eq!(store.get_range("a", 1..3).unwrap(), b"el");
        assert!(store.get("missing").is_err());
        assert_eq!(store.list("").unwrap(), ["a", "b"]);
        store.delete("b").unwrap();
        let expected = StoreStats {
            gets: 3,
            puts: 3,
            lists: 1,
            deletes: 1,
            bytes_read: 7,
            bytes_written: 8,
        };
        assert_eq!(store.stats(), expected);
        assert_eq!(
            store.inner().stats(),
            expected,
            "memory store counts the same"
        );
    }

    #[test]
    fn counting_store_passes_conformance() {
        let store = CountingStore::new(MemoryStore::new());
        crate::store::conformance::run_all(&store, "conformance/");
        let stats = store.stats();
        assert!(
            stats.bytes_written >= 3 << 20 && stats.bytes_read >= 3 << 20,
            "{stats:?}"
        );
    }
}
