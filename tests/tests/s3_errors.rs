//! `S3Store` errors are one clear line each, in the right class: an unreachable endpoint is
//! retryable, a missing bucket or refused credentials are not.

mod s3_support;

use hort_core::store::{BlobStore, StoreError};
use hort_functions::{S3Config, S3Store};
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
fn missing_bucket_is_denied_and_named() {
    let embedded = Embedded::start(Some("present"));
    let endpoint = embedded.server.endpoint();
    let store = embedded.store("nope");
    let says = |op: &str| {
        format!("storage access denied: {op}: bucket \"nope\" does not exist at {endpoint}")
    };

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
    assert!(matches!(err, StoreError::Denied { .. }));
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
