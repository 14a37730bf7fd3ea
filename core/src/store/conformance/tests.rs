use std::ops::Range;
use std::panic::{AssertUnwindSafe, catch_unwind};

use super::*;
use crate::store::MemoryStore;

/// A memory store with one seeded defect, to prove the suite notices it.
struct Broken {
    inner: MemoryStore,
    defect: Defect,
}

#[derive(Clone, Copy, Debug)]
enum Defect {
    NoClamp,
    OverwritingPutIfAbsent,
    UnsortedList,
    DeleteMissingFails,
    NotFoundWithoutKey,
}

impl BlobStore for Broken {
    fn get(&self, key: &str) -> Result<Vec<u8>, StoreError> {
        match (self.defect, self.inner.get(key)) {
            (Defect::NotFoundWithoutKey, Err(StoreError::NotFound { .. })) => {
                Err(StoreError::NotFound { key: String::new() })
            }
            (_, result) => result,
        }
    }
    fn get_range(&self, key: &str, range: Range<u64>) -> Result<Vec<u8>, StoreError> {
        let len = self.inner.get(key)?.len() as u64;
        if matches!(self.defect, Defect::NoClamp) && range.end > len {
            return Err(StoreError::InvalidRange {
                key: key.into(),
                start: range.start,
                end: range.end,
                len,
            });
        }
        self.inner.get_range(key, range)
    }
    fn put(&self, key: &str, bytes: &[u8]) -> Result<(), StoreError> {
        self.inner.put(key, bytes)
    }
    fn put_if_absent(&self, key: &str, bytes: &[u8]) -> Result<PutOutcome, StoreError> {
        if matches!(self.defect, Defect::OverwritingPutIfAbsent) {
            let existed = self.inner.get(key).is_ok();
            self.inner.put(key, bytes)?;
            return Ok(if existed {
                PutOutcome::AlreadyExists
            } else {
                PutOutcome::Created
            });
        }
        self.inner.put_if_absent(key, bytes)
    }
    fn list(&self, prefix: &str) -> Result<Vec<String>, StoreError> {
        let mut keys = self.inner.list(prefix)?;
        if matches!(self.defect, Defect::UnsortedList) {
            keys.sort_by_key(|k| k.replace('/', "\u{0}"));
        }
        Ok(keys)
    }
    fn delete(&self, key: &str) -> Result<(), StoreError> {
        if matches!(self.defect, Defect::DeleteMissingFails) && self.inner.get(key).is_err() {
            return Err(StoreError::NotFound { key: key.into() });
        }
        self.inner.delete(key)
    }
}

#[test]
fn the_suite_catches_each_seeded_defect() {
    for (defect, clue) in [
        (Defect::NoClamp, "get_range"),
        (Defect::OverwritingPutIfAbsent, "put_if_absent"),
        (Defect::UnsortedList, "list"),
        (Defect::DeleteMissingFails, "delete"),
        (Defect::NotFoundWithoutKey, "does not name"),
    ] {
        let store = Broken {
            inner: MemoryStore::new(),
            defect,
        };
        let panic = catch_unwind(AssertUnwindSafe(|| run_all(&store, "t/")))
            .expect_err(&format!("{defect:?} went unnoticed"));
        let msg = panic.downcast_ref::<String>().cloned().unwrap_or_default();
        assert!(
            msg.starts_with("store conformance:") && msg.contains(clue),
            "{defect:?}: {msg}"
        );
    }
}

#[test]
fn list_pagination_check_passes_on_memory() {
    let store = MemoryStore::new();
    list_returns_every_page(&store, "p/");
    assert!(store.is_empty());
}
