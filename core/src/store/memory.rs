//! An in-memory store for tests and the monolithic path.

use std::collections::BTreeMap;
use std::ops::{Bound, Range};
use std::sync::{Mutex, MutexGuard, PoisonError};

use super::counting::Counters;
use super::{BlobStore, PutOutcome, StoreError, StoreStats};

/// A [`BlobStore`] held in memory: a sorted map behind a mutex, with built-in [`StoreStats`].
///
/// Guarantees the full trait contract (it passes [`super::conformance::run_all`]), never fails
/// except with `NotFound` and `InvalidRange`, and stays usable after a panicking thread (a
/// poisoned lock is recovered, since every update is a single map operation).
#[derive(Debug, Default)]
pub struct MemoryStore {
    objects: Mutex<BTreeMap<String, Vec<u8>>>,
    counters: Counters,
}

impl MemoryStore {
    /// An empty store with all counts at zero.
    pub fn new() -> Self {
        Self::default()
    }

    /// Requests and bytes served since construction.
    pub fn stats(&self) -> StoreStats {
        self.counters.snapshot()
    }

    /// Number of objects stored.
    pub fn len(&self) -> usize {
        self.objects().len()
    }

    /// True if no object is stored.
    pub fn is_empty(&self) -> bool {
        self.objects().is_empty()
    }

    fn objects(&self) -> MutexGuard<'_, BTreeMap<String, Vec<u8>>> {
        self.objects.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn read(&self, key: &str, range: Option<Range<u64>>) -> Result<Vec<u8>, StoreError> {
        let objects = self.objects();
        let object = objects.get(key).ok_or_else(|| StoreError::NotFound {
            key: key.to_owned(),
        })?;
        let Some(range) = range else {
            return Ok(object.clone());
        };
        let len = object.len() as u64;
        if range.start >= range.end || range.start >= len {
            return Err(StoreError::InvalidRange {
                key: key.to_owned(),
                start: range.start,
                end: range.end,
                len,
            });
        }
        // Both bounds are <= len, which fits in usize because the object is in memory.
        let (start, end) = (range.start as usize, range.end.min(len) as usize);
        Ok(object[start..end].to_vec())
    }
}

impl BlobStore for MemoryStore {
    fn get(&self, key: &str) -> Result<Vec<u8>, StoreError> {
        let result = self.read(key, None);
        self.counters.get(&result);
        result
    }

    fn get_range(&self, key: &str, range: Range<u64>) -> Result<Vec<u8>, StoreError> {
        let result = self.read(key, Some(range));
        self.counters.get(&result);
        result
    }

    fn put(&self, key: &str, bytes: &[u8]) -> Result<(), StoreError> {
        self.objects().insert(key.to_owned(), bytes.to_vec());
        self.counters.put(bytes.len(), true);
        Ok(())
    }

    fn size(&self, key: &str) -> Result<u64, StoreError> {
        self.counters.head();
        let objects = self.objects();
        let object = objects.get(key).ok_or_else(|| StoreError::NotFound {
            key: key.to_owned(),
        })?;
        Ok(object.len() as u64)
    }

    fn copy(&self, from: &str, to: &str) -> Result<(), StoreError> {
        let mut objects = self.objects();
        let copied = objects.get(from).cloned();
        self.counters.put(0, copied.is_some());
        let bytes = copied.ok_or_else(|| StoreError::NotFound {
            key: from.to_owned(),
        })?;
        objects.insert(to.to_owned(), bytes);
        Ok(())
    }

    fn put_if_absent(&self, key: &str, bytes: &[u8]) -> Result<PutOutcome, StoreError> {
        let outcome = match self.objects().entry(key.to_owned()) {
            std::collections::btree_map::Entry::Occupied(_) => PutOutcome::AlreadyExists,
            std::collections::btree_map::Entry::Vacant(slot) => {
                slot.insert(bytes.to_vec());
                PutOutcome::Created
            }
        };
        self.counters
            .put(bytes.len(), outcome == PutOutcome::Created);
        Ok(outcome)
    }

    fn list(&self, prefix: &str) -> Result<Vec<String>, StoreError> {
        self.counters.list();
        let objects = self.objects();
        let keys = objects
            .range::<str, _>((Bound::Included(prefix), Bound::Unbounded))
            .map(|(key, _)| key)
            .take_while(|key| key.starts_with(prefix))
            .cloned()
            .collect();
        Ok(keys)
    }

    fn delete(&self, key: &str) -> Result<(), StoreError> {
        self.counters.delete();
        self.objects().remove(key);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn memory_store_passes_conformance() {
        let store = MemoryStore::new();
        super::super::conformance::run_all(&store, "suite/run-1/");
        // The suite cleans up after itself and leaves other prefixes alone.
        store.put("other/key", b"x").unwrap();
        super::super::conformance::run_all(&store, "suite/run-2/");
        assert_eq!(store.list("").unwrap(), ["other/key"]);
    }

    #[test]
    fn memory_store_passes_conformance_with_empty_prefix() {
        super::super::conformance::run_all(&MemoryStore::new(), "");
    }

    #[test]
    fn len_and_stats_follow_the_contents() {
        let store = MemoryStore::new();
        assert!(store.is_empty());
        store.put("a", &[1, 2, 3]).unwrap();
        store.put("a", &[1]).unwrap();
        assert_eq!(store.len(), 1);
        assert_eq!(store.get("a").unwrap(), [1]);
        let stats = store.stats();
        assert_eq!(
            (
                stats.puts,
                stats.bytes_written,
                stats.gets,
                stats.bytes_read
            ),
            (2, 4, 1, 1)
        );
    }
}
