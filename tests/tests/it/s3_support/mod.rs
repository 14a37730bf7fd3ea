//! Shared setup of the S3 tests: an embedded S3 server in a temporary directory, and the
//! external server named by `HORT_TEST_S3_*` variables (see `tests/s3-servers/with-moto.sh`).

use embedded_s3::EmbeddedS3;
use hort_functions::{S3Config, S3Store};

/// Access key pair the embedded test servers accept.
pub const ACCESS_KEY: &str = "hort-test-access";
/// Secret key the embedded test servers accept.
pub const SECRET_KEY: &str = "hort-test-secret";

/// An embedded S3 server over a temporary directory; both go away on drop (server first).
pub struct Embedded {
    pub server: EmbeddedS3,
    pub dir: tempfile::TempDir,
}

impl Embedded {
    /// Starts a server on a fresh temporary directory, with bucket `bucket` created unless `None`.
    pub fn start(bucket: Option<&str>) -> Embedded {
        let dir = tempfile::tempdir().expect("temporary directory");
        let server =
            EmbeddedS3::start(dir.path(), ACCESS_KEY, SECRET_KEY).expect("embedded S3 starts");
        if let Some(bucket) = bucket {
            server.ensure_bucket(bucket).expect("bucket created");
        }
        Embedded { server, dir }
    }

    /// [`Embedded::start`] with storage faults injected into every HTTP exchange.
    pub fn start_with_faults(bucket: &str, faults: embedded_s3::StorageFaults) -> Embedded {
        let dir = tempfile::tempdir().expect("temporary directory");
        let server = EmbeddedS3::start_with_faults(dir.path(), ACCESS_KEY, SECRET_KEY, faults)
            .expect("embedded S3 starts");
        server.ensure_bucket(bucket).expect("bucket created");
        Embedded { server, dir }
    }

    /// A store on `bucket` of this server, signing with the given key pair.
    pub fn store_with_keys(&self, bucket: &str, access_key: &str, secret_key: &str) -> S3Store {
        let config = S3Config::compatible(self.server.endpoint(), bucket, access_key, secret_key);
        S3Store::open(&config).expect("S3 client")
    }

    /// A store on `bucket` of this server with the right keys.
    pub fn store(&self, bucket: &str) -> S3Store {
        self.store_with_keys(bucket, ACCESS_KEY, SECRET_KEY)
    }
}

/// The external S3-compatible server named by `HORT_TEST_S3_ENDPOINT`, `HORT_TEST_S3_BUCKET`,
/// `HORT_TEST_S3_ACCESS_KEY` and `HORT_TEST_S3_SECRET_KEY`, or `None` if the endpoint is unset.
///
/// # Panics
/// If the endpoint is set but another variable is missing.
pub fn external_config() -> Option<S3Config> {
    let endpoint = hort_tests::integration_endpoint(
        "HORT_TEST_S3_ENDPOINT",
        "see tests/s3-servers/with-moto.sh",
    )?;
    let var = |name: &str| {
        std::env::var(name)
            .unwrap_or_else(|_| panic!("HORT_TEST_S3_ENDPOINT is set, so {name} must be too"))
    };
    Some(S3Config::compatible(
        endpoint,
        var("HORT_TEST_S3_BUCKET"),
        var("HORT_TEST_S3_ACCESS_KEY"),
        var("HORT_TEST_S3_SECRET_KEY"),
    ))
}

/// A key prefix no other run uses, so runs can share a bucket.
pub fn unique_prefix(name: &str) -> String {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or_default();
    format!("{name}-{}-{nanos}/", std::process::id())
}
