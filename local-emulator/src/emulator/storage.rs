//! Where the emulator keeps objects: an S3 server embedded in the process (default) or any
//! S3-compatible endpoint, always reached through the real S3 protocol with `S3Store`.

use embedded_s3::EmbeddedS3;
use hort_core::store::{BlobStore, CountingStore, StoreError};
use hort_functions::{S3Config, S3Credentials, S3Store};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// Keys of the embedded server (it only listens on 127.0.0.1).
const EMBEDDED_ACCESS_KEY: &str = "hort-local";
const EMBEDDED_SECRET_KEY: &str = "hort-local-secret";
/// Bucket used with the embedded server.
pub const EMBEDDED_BUCKET: &str = "hort";

/// Which S3 service to use.
#[derive(Clone, Debug)]
pub enum StorageTarget {
    /// Start an S3 server in this process over `data_dir` (a temporary folder when `None`).
    Embedded {
        /// Where objects are kept after the run; a temporary folder, removed at exit, if `None`.
        data_dir: Option<PathBuf>,
    },
    /// Use an S3-compatible endpoint (MinIO, Garage, Ceph RGW, moto, AWS).
    External {
        /// The endpoint URL, e.g. `http://127.0.0.1:9000`.
        endpoint: String,
        /// The bucket holding the jobs (created if absent).
        bucket: String,
        /// How requests are signed.
        credentials: S3Credentials,
    },
}

/// An opened bucket: the store every function and the orchestrator use, with request counts.
pub struct Storage {
    /// The bucket's objects over the S3 protocol, with request counts.
    pub store: Arc<CountingStore<S3Store>>,
    /// The bucket's name.
    pub bucket: String,
    /// The S3 endpoint URL the store talks to.
    pub endpoint: String,
    /// Keeps the embedded server (and its temporary folder) alive.
    _server: Option<EmbeddedS3>,
    _temp: Option<TempDir>,
}

/// A folder removed on drop.
struct TempDir(PathBuf);

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

impl Storage {
    /// Starts or connects to the target and checks the bucket, with one-line errors.
    pub fn open(target: &StorageTarget) -> Result<Storage, StoreError> {
        match target {
            StorageTarget::Embedded { data_dir } => {
                let (dir, temp) = match data_dir {
                    Some(d) => (d.clone(), None),
                    None => {
                        // Unique per run: several runs may share a process (benches, tests).
                        static RUN: AtomicU64 = AtomicU64::new(0);
                        let d = std::env::temp_dir().join(format!(
                            "hort-s3-{}-{}",
                            std::process::id(),
                            RUN.fetch_add(1, Ordering::Relaxed)
                        ));
                        (d.clone(), Some(TempDir(d)))
                    }
                };
                std::fs::create_dir_all(&dir).map_err(|e| StoreError::Other {
                    what: format!("cannot create data folder {}: {e}", dir.display()),
                })?;
                let server = EmbeddedS3::start(&dir, EMBEDDED_ACCESS_KEY, EMBEDDED_SECRET_KEY)
                    .map_err(|e| StoreError::Other {
                        what: format!("cannot start the embedded S3 server: {e}"),
                    })?;
                server
                    .ensure_bucket(EMBEDDED_BUCKET)
                    .map_err(|e| StoreError::Other {
                        what: format!("cannot create the embedded bucket: {e}"),
                    })?;
                let config = S3Config::compatible(
                    server.endpoint(),
                    EMBEDDED_BUCKET,
                    EMBEDDED_ACCESS_KEY,
                    EMBEDDED_SECRET_KEY,
                );
                let store = S3Store::open(&config)?;
                store.check_bucket()?;
                Ok(Storage {
                    endpoint: server.endpoint(),
                    store: Arc::new(CountingStore::new(store)),
                    bucket: EMBEDDED_BUCKET.into(),
                    _server: Some(server),
                    _temp: temp,
                })
            }
            StorageTarget::External {
                endpoint,
                bucket,
                credentials,
            } => {
                let mut config = S3Config::compatible(endpoint.clone(), bucket.clone(), "", "");
                config.credentials = credentials.clone();
                let store = S3Store::open(&config)?;
                store.check_bucket()?;
                Ok(Storage {
                    store: Arc::new(CountingStore::new(store)),
                    bucket: bucket.clone(),
                    endpoint: endpoint.clone(),
                    _server: None,
                    _temp: None,
                })
            }
        }
    }

    /// The store as the trait object handlers take.
    pub fn blob_store(&self) -> Arc<dyn BlobStore> {
        self.store.clone()
    }
}
