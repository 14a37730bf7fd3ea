//! A small synchronous object-storage interface with S3 semantics, an in-memory implementation,
//! a counting wrapper, and a conformance suite every implementation must pass.
//!
//! The trait is synchronous because `core` has no async runtime; AWS adapters block on their own
//! runtime. Keys are UTF-8 strings built by [`crate::keys`]; the store gives them no structure
//! beyond prefix listing.

mod counting;
mod memory;
mod patient;
mod timed;

pub mod conformance;

use std::ops::Range;
use std::sync::Arc;

pub use counting::CountingStore;
pub use memory::MemoryStore;
pub use patient::PatientStore;
pub use timed::TimedStore;

/// Why a storage request failed. Every message names the key or the operation.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum StoreError {
    /// No object has this key.
    #[error("object not found: {key}")]
    NotFound {
        /// The requested key.
        key: String,
    },
    /// A byte range that is empty, reversed, or starts at or beyond the end of the object.
    #[error(
        "invalid byte range {start}..{end} of {key} ({len} bytes): a range must be non-empty \
         and start inside the object"
    )]
    InvalidRange {
        /// The requested key.
        key: String,
        /// First requested byte.
        start: u64,
        /// One past the last requested byte.
        end: u64,
        /// The object's length in bytes.
        len: u64,
    },
    /// A transient failure: network, timeout, throttling, 5xx. Retrying may succeed.
    #[error("storage unavailable (retryable): {what}")]
    Unavailable {
        /// What failed, naming the key or operation.
        what: String,
    },
    /// A permanent refusal: bad credentials, missing bucket, forbidden key. Retrying will not help.
    #[error("storage access denied: {what}")]
    Denied {
        /// What was refused, naming the key or operation.
        what: String,
    },
    /// Any other failure, treated as not retryable.
    #[error("storage error: {what}")]
    Other {
        /// What failed, naming the key or operation.
        what: String,
    },
}

impl StoreError {
    /// True only for [`StoreError::Unavailable`]: the one class the orchestrator retries.
    pub fn is_retryable(&self) -> bool {
        matches!(self, StoreError::Unavailable { .. })
    }

    /// True only for [`StoreError::NotFound`] (a lost input block may be recomputed from lineage).
    pub fn is_not_found(&self) -> bool {
        matches!(self, StoreError::NotFound { .. })
    }
}

/// The result of [`BlobStore::put_if_absent`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PutOutcome {
    /// The object did not exist and now holds the given bytes.
    Created,
    /// An object already had the key; it was left untouched.
    AlreadyExists,
}

/// Object storage with S3 semantics. Implementations are shared between threads.
///
/// Guarantees every implementation gives (checked by [`conformance::run_all`]): a successful
/// `put` is visible to every later `get` and `list` (strong read-after-write, as S3 gives);
/// objects are immutable byte strings replaced whole; `put_if_absent` is atomic, so among racing
/// callers exactly one sees [`PutOutcome::Created`].
pub trait BlobStore: Send + Sync {
    /// The whole object; [`StoreError::NotFound`] naming the key if there is none.
    fn get(&self, key: &str) -> Result<Vec<u8>, StoreError>;

    /// Bytes `range.start..min(range.end, len)` of the object (clamped like an S3 range GET).
    /// [`StoreError::InvalidRange`] if the range is empty or reversed or `range.start >= len`
    /// (so any range of an empty object); [`StoreError::NotFound`] if there is no object.
    fn get_range(&self, key: &str, range: Range<u64>) -> Result<Vec<u8>, StoreError>;

    /// Stores `bytes` under `key`, replacing any existing object.
    fn put(&self, key: &str, bytes: &[u8]) -> Result<(), StoreError>;

    /// Stores `bytes` only if no object has `key`; an existing object is left untouched.
    fn put_if_absent(&self, key: &str, bytes: &[u8]) -> Result<PutOutcome, StoreError>;

    /// Every key starting with `prefix` (deeper `/` levels included, no delimiter), sorted by
    /// bytes; empty if none. Implementations over paginated APIs return all pages.
    fn list(&self, prefix: &str) -> Result<Vec<String>, StoreError>;

    /// Removes the object; deleting a missing key succeeds (S3 semantics).
    fn delete(&self, key: &str) -> Result<(), StoreError>;

    /// The object's size in bytes, without its bytes (S3: HeadObject); [`StoreError::NotFound`]
    /// naming the key if there is none. By default the length of a whole `get`.
    fn size(&self, key: &str) -> Result<u64, StoreError> {
        self.get(key).map(|bytes| bytes.len() as u64)
    }

    /// Stores a copy of object `from` under `to`, replacing any object there (S3: CopyObject,
    /// inside the store, no bytes through the caller; at most
    /// [`COPY_MAX_BYTES`] bytes); [`StoreError::NotFound`] naming `from` if there is none. By
    /// default a `get` and a `put`.
    fn copy(&self, from: &str, to: &str) -> Result<(), StoreError> {
        let bytes = self.get(from)?;
        self.put(to, &bytes)
    }

    /// `get` of every key of `keys`, in order. A store whose requests wait on a network keeps up
    /// to [`PARALLEL_REQUESTS`] in flight at once, on the calling thread (so a task's memory
    /// count, which is per thread, sees the bytes); by default they run one after another.
    fn get_many(&self, keys: &[String]) -> Vec<Result<Vec<u8>, StoreError>> {
        keys.iter().map(|key| self.get(key)).collect()
    }

    /// `put` of every `(key, bytes)` of `objects`, in order, as [`BlobStore::get_many`] runs
    /// its requests.
    fn put_many(&self, objects: &[(String, Vec<u8>)]) -> Vec<Result<(), StoreError>> {
        objects
            .iter()
            .map(|(key, bytes)| self.put(key, bytes))
            .collect()
    }
}

/// The largest object one [`BlobStore::copy`] copies: S3's CopyObject limit, 5 GiB (larger
/// objects need a multipart copy, which this project does not do).
pub const COPY_MAX_BYTES: u64 = hort_aws_quotas::S3_COPY_OBJECT_MAX_BYTES;

/// How many requests [`BlobStore::get_many`] and [`BlobStore::put_many`] keep in flight on a
/// store whose requests wait on a network: on S3 each waits tens of milliseconds for its first
/// byte, and waiting for several at once costs no more than for one.
pub const PARALLEL_REQUESTS: usize = 8;

/// Request and byte counts of a store, as counted by [`CountingStore`] or [`MemoryStore`].
///
/// Requests are counted whether or not they succeed; bytes only for successful transfers.
/// `gets` includes range gets; `puts` includes conditional puts; `bytes_written` counts a
/// conditional put only when it created the object.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct StoreStats {
    /// GET and range GET requests.
    pub gets: u64,
    /// PUT and conditional PUT requests.
    pub puts: u64,
    /// LIST calls (one per [`BlobStore::list`] call, whatever the page count).
    pub lists: u64,
    /// DELETE requests.
    pub deletes: u64,
    /// Bytes returned by successful gets.
    pub bytes_read: u64,
    /// Bytes stored by successful puts.
    pub bytes_written: u64,
}

impl StoreStats {
    /// The counts accumulated since `earlier` (a snapshot of the same counters taken before);
    /// saturates at zero, so a mismatched pair never underflows.
    pub fn since(&self, earlier: &StoreStats) -> StoreStats {
        StoreStats {
            gets: self.gets.saturating_sub(earlier.gets),
            puts: self.puts.saturating_sub(earlier.puts),
            lists: self.lists.saturating_sub(earlier.lists),
            deletes: self.deletes.saturating_sub(earlier.deletes),
            bytes_read: self.bytes_read.saturating_sub(earlier.bytes_read),
            bytes_written: self.bytes_written.saturating_sub(earlier.bytes_written),
        }
    }
}

macro_rules! forward_blob_store {
    ($($target:ty),*) => {$(
        /// Forwards every call to the pointed-to store.
        impl<T: BlobStore + ?Sized> BlobStore for $target {
            fn get(&self, key: &str) -> Result<Vec<u8>, StoreError> {
                (**self).get(key)
            }
            fn get_range(&self, key: &str, range: Range<u64>) -> Result<Vec<u8>, StoreError> {
                (**self).get_range(key, range)
            }
            fn put(&self, key: &str, bytes: &[u8]) -> Result<(), StoreError> {
                (**self).put(key, bytes)
            }
            fn put_if_absent(&self, key: &str, bytes: &[u8]) -> Result<PutOutcome, StoreError> {
                (**self).put_if_absent(key, bytes)
            }
            fn list(&self, prefix: &str) -> Result<Vec<String>, StoreError> {
                (**self).list(prefix)
            }
            fn delete(&self, key: &str) -> Result<(), StoreError> {
                (**self).delete(key)
            }
            fn size(&self, key: &str) -> Result<u64, StoreError> {
                (**self).size(key)
            }
            fn copy(&self, from: &str, to: &str) -> Result<(), StoreError> {
                (**self).copy(from, to)
            }
            fn get_many(&self, keys: &[String]) -> Vec<Result<Vec<u8>, StoreError>> {
                (**self).get_many(keys)
            }
            fn put_many(&self, objects: &[(String, Vec<u8>)]) -> Vec<Result<(), StoreError>> {
                (**self).put_many(objects)
            }
        }
    )*};
}

forward_blob_store!(&T, Box<T>, Arc<T>);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_unavailable_is_retryable() {
        let what = String::from("x");
        assert!(StoreError::Unavailable { what: what.clone() }.is_retryable());
        assert!(!StoreError::Denied { what: what.clone() }.is_retryable());
        assert!(!StoreError::Other { what }.is_retryable());
        assert!(!StoreError::NotFound { key: "k".into() }.is_retryable());
    }

    #[test]
    fn messages_name_the_key() {
        let e = StoreError::NotFound {
            key: "jobs/a/splits/00001.bin".into(),
        };
        assert_eq!(e.to_string(), "object not found: jobs/a/splits/00001.bin");
        let e = StoreError::InvalidRange {
            key: "k/x".into(),
            start: 9,
            end: 12,
            len: 4,
        };
        assert!(e.to_string().contains("9..12 of k/x (4 bytes)"), "{e}");
    }

    #[test]
    fn stats_since_subtracts_and_saturates() {
        let a = StoreStats {
            gets: 3,
            puts: 2,
            lists: 1,
            deletes: 0,
            bytes_read: 10,
            bytes_written: 5,
        };
        let b = StoreStats {
            gets: 5,
            puts: 2,
            lists: 1,
            deletes: 4,
            bytes_read: 30,
            bytes_written: 5,
        };
        let d = b.since(&a);
        assert_eq!(
            d,
            StoreStats {
                gets: 2,
                puts: 0,
                lists: 0,
                deletes: 4,
                bytes_read: 20,
                bytes_written: 0
            }
        );
        assert_eq!(a.since(&b).gets, 0);
    }

    #[test]
    fn pointers_to_stores_are_stores() {
        let store = Arc::new(MemoryStore::new());
        let shared: Arc<dyn BlobStore> = store.clone();
        shared.put("k", b"v").unwrap();
        let by_ref: &dyn BlobStore = &*store;
        assert_eq!((&by_ref).get("k").unwrap(), b"v");
        let boxed: Box<dyn BlobStore> = Box::new(MemoryStore::new());
        assert!(boxed.get("k").unwrap_err().is_not_found());
    }
}
