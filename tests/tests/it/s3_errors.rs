//! `S3Store` errors are one clear line each, in the right class: an unreachable endpoint is
//! retryable, a missing bucket, missing credentials or refused credentials are not; a missing
//! bucket and missing credentials are not called "access denied".

use crate::s3_support;

use hort_core::store::{BlobStore, StoreError};
use hort_functions::s3_store::BucketProblem;
use hort_functions::{S3Config, S3Credentials, S3Store};
use s3_support::{ACCESS_KEY, Embedded};

/// Asserts `err` is one line of plain words, not SDK debug output.
fn assert_one_clean_line(err: &StoreError) {
    let text = err.to_string();
    assert!(!text.contains('\n'), "line break in {text:?}");
    for noise in [
        "Error {",
        "SdkError",
        "DispatchFailure",
        "ServiceError",
        "ConnectorError",
        "source:",
        "os error",
    ] {
        assert!(!text.contains(noise), "{noise:?} in {text:?}");
    }
}

#[test]
fn unreachable_endpoint_is_retryable_and_says_connection_refused() {
    let endpoint = {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("free port");
        format!("http://{}", listener.local_addr().expect("address"))
    };
    let mut config = S3Config::compatible(endpoint.as_str(), "b", "k", "s");
    config.max_attempts = 2;
    let store = S3Store::open(&config).expect("client");

    let err = store.get("jobs/a/part-0").expect_err("nothing listens");
    assert_eq!(
        err.to_string(),
        format!(
            "storage unavailable (retryable): get \"jobs/a/part-0\": S3 endpoint {endpoint} is \
             unreachable (connection refused)"
        )
    );
    assert!(err.is_retryable());
    assert_one_clean_line(&err);

    let err = store.check_bucket().expect_err("nothing listens");
    assert_eq!(
        err,
        StoreError::Unavailable {
            what: format!(
                "check bucket: S3 endpoint {endpoint} is unreachable (connection refused)"
            )
        }
    );
    assert_one_clean_line(&err);
}

#[test]
fn unresolvable_host_is_retryable_and_names_the_dns_failure() {
    let mut config = S3Config::compatible("http://no-such-host.invalid:9000", "b", "k", "s");
    config.max_attempts = 1;
    let store = S3Store::open(&config).expect("client");
    let err = store.put("k", b"v").expect_err("no such host");
    let prefix = "storage unavailable (retryable): put \"k\": S3 endpoint \
                  http://no-such-host.invalid:9000 is unreachable (DNS lookup failed: ";
    assert!(err.to_string().starts_with(prefix), "{err}");
    assert!(err.is_retryable());
    assert_one_clean_line(&err);
}

#[test]
fn missing_bucket_is_named_not_denied() {
    let embedded = Embedded::start(Some("present"));
    let endpoint = embedded.server.endpoint();
    let store = embedded.store("nope");
    assert_eq!(store.probe_bucket(), Err(BucketProblem::Missing));
    let says =
        |op: &str| format!("storage error: {op}: bucket \"nope\" does not exist at {endpoint}");

    let err = store.check_bucket().expect_err("no such bucket");
    assert_eq!(err.to_string(), says("check bucket"));
    assert!(!err.is_retryable());
    assert_one_clean_line(&err);

    let err = store.put("k", b"v").expect_err("no such bucket");
    assert_eq!(err.to_string(), says("put \"k\""));
    let err = store.get("k").expect_err("no such bucket");
    assert_eq!(err.to_string(), says("get \"k\""));
    let err = store.list("jobs/").expect_err("no such bucket");
    assert_eq!(err.to_string(), says("list \"jobs/\""));
    assert!(matches!(err, StoreError::Other { .. }));
    let err = store.delete("k").expect_err("no such bucket");
    assert_eq!(err.to_string(), says("delete \"k\""));
    assert!(
        !embedded.dir.path().join("nope").exists(),
        "a put must not create the bucket"
    );
}

#[test]
fn unknown_access_key_is_denied_as_bad_credentials() {
    let embedded = Embedded::start(Some("bkt"));
    let endpoint = embedded.server.endpoint();
    let store = embedded.store_with_keys("bkt", "someone-else", "their-secret");
    let says = |op: &str| {
        format!(
            "storage access denied: {op}: S3 rejected the credentials (InvalidAccessKeyId) for \
             bucket \"bkt\" at {endpoint}"
        )
    };

    let err = store.check_bucket().expect_err("unknown key");
    assert_eq!(err.to_string(), says("check bucket"));
    assert!(!err.is_retryable());
    assert_one_clean_line(&err);
    assert_eq!(store.probe_bucket(), Err(BucketProblem::Store(err)));

    let err = store.get("k").expect_err("unknown key");
    assert_eq!(err.to_string(), says("get \"k\""));
    let err = store.put_if_absent("k", b"v").expect_err("unknown key");
    assert_eq!(err.to_string(), says("put if absent \"k\""));
}

#[test]
fn wrong_secret_is_denied_as_a_bad_signature() {
    let embedded = Embedded::start(Some("bkt"));
    let endpoint = embedded.server.endpoint();
    let store = embedded.store_with_keys("bkt", ACCESS_KEY, "not-the-secret");
    let err = store.put("k", b"v").expect_err("wrong secret");
    assert_eq!(
        err.to_string(),
        format!(
            "storage access denied: put \"k\": S3 rejected the credentials \
             (SignatureDoesNotMatch) for bucket \"bkt\" at {endpoint}"
        )
    );
    assert_one_clean_line(&err);
    let err = store.check_bucket().expect_err("wrong secret");
    assert!(
        err.to_string()
            .contains("S3 rejected the credentials (SignatureDoesNotMatch)"),
        "{err}"
    );
}

#[test]
fn missing_object_is_not_found_naming_the_key() {
    let embedded = Embedded::start(Some("bkt"));
    let store = embedded.store("bkt");
    let err = store.get("jobs/j/cast/3/part-1").expect_err("missing");
    assert_eq!(
        err,
        StoreError::NotFound {
            key: "jobs/j/cast/3/part-1".to_owned()
        }
    );
    assert_eq!(err.to_string(), "object not found: jobs/j/cast/3/part-1");
}

#[test]
fn malformed_endpoint_is_refused_before_any_request() {
    let config = S3Config::compatible("127.0.0.1:9000", "b", "k", "s");
    let err = S3Store::open(&config).expect_err("no scheme");
    assert_eq!(
        err.to_string(),
        "storage error: invalid S3 endpoint \"127.0.0.1:9000\": expected http://HOST[:PORT] or \
         https://HOST[:PORT]"
    );
}

/// Set in the environment of the child process that [`missing_credentials_say_where_to_set_them`]
/// starts; the child test runs only then.
const CHILD: &str = "HORT_TEST_NO_CREDENTIALS_CHILD";

#[test]
fn missing_credentials_say_where_to_set_them() {
    // The default credential chain reads the environment and the home folder: look at them in a
    // child process with neither (and no EC2 metadata service), so this process stays as it is.
    let home = tempfile::tempdir().expect("temporary directory");
    // The child test's full name in this binary: its module path without the crate's name.
    let (_, module) = module_path!()
        .split_once("::")
        .expect("a module of the test binary");
    let child = std::process::Command::new(std::env::current_exe().expect("test binary"))
        .args([
            "--exact",
            &format!("{module}::no_credentials_child"),
            "--nocapture",
            "--test-threads",
            "1",
        ])
        .env_clear()
        .env("HOME", home.path())
        .env("AWS_EC2_METADATA_DISABLED", "true")
        .env(CHILD, "1")
        .output()
        .expect("the test binary runs");
    let out = String::from_utf8_lossy(&child.stdout);
    assert!(
        child.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&child.stderr)
    );
    let said: Vec<&str> = out
        .lines()
        .filter_map(|l| l.split_once("said: ").map(|(_, said)| said))
        .collect();
    assert_eq!(
        said,
        [
            "storage error: check bucket: no AWS credentials found for bucket \"b\" at \
             http://127.0.0.1:9: set AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY (or configure an \
             AWS profile)",
            // Without an endpoint the store is on AWS S3, in us-east-1 when nothing names a region.
            "storage error: check bucket: no AWS credentials found for bucket \"b\" at AWS S3 \
             (us-east-1): set AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY (or configure an AWS \
             profile)",
        ]
    );
}

/// Run by [`missing_credentials_say_where_to_set_them`] in a child process; passes trivially
/// otherwise. Prints each error as `said: ...` (after the harness's `test ... ` on the first).
#[test]
fn no_credentials_child() {
    if std::env::var_os(CHILD).is_none() {
        return;
    }
    let mut compatible = S3Config::compatible("http://127.0.0.1:9", "b", "", "");
    compatible.credentials = S3Credentials::DefaultChain;
    for config in [compatible, S3Config::aws("b", None)] {
        let store = S3Store::open(&config).expect("client");
        assert!(matches!(
            store.probe_bucket(),
            Err(BucketProblem::NoCredentials { detail: None })
        ));
        let err = store.check_bucket().expect_err("no credentials");
        assert!(matches!(err, StoreError::Other { .. }));
        assert_one_clean_line(&err);
        println!("said: {err}");
    }
}
