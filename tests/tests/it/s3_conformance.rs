//! The store conformance suite against `S3Store` over HTTP: always against the embedded S3
//! server, and against an external S3-compatible server when `HORT_TEST_S3_ENDPOINT` is set
//! (`bash tests/s3-servers/with-moto.sh cargo test -p hort-tests --test it s3_conformance::`).

use crate::s3_support;

use hort_core::store::{BlobStore, PutOutcome, conformance};
use s3_support::{Embedded, external_config, unique_prefix};

#[test]
fn embedded_s3_passes_the_conformance_suite() {
    let embedded = Embedded::start(Some("conformance"));
    let store = embedded.store("conformance");
    store.check_bucket().expect("bucket is reachable");
    conformance::run_all(&store, "suite/");

    // The bytes really went through this server: they are in its data directory.
    store.put("suite-probe/k=v.bin", b"probe").expect("put");
    let file = embedded
        .server
        .data_dir()
        .join("conformance/suite-probe/k=v.bin~obj");
    assert_eq!(std::fs::read(&file).expect("object file"), b"probe");
    assert_eq!(store.list("").expect("list"), ["suite-probe/k=v.bin"]);
}

#[test]
fn embedded_s3_lists_every_page() {
    let embedded = Embedded::start(Some("pages"));
    let store = embedded.store("pages");
    conformance::list_returns_every_page(&store, "suite/");
    assert_eq!(store.list("suite/").expect("list"), Vec::<String>::new());
}

/// A copy source over S3's 5 GiB single-copy limit is refused as S3 refuses it (a sparse file
/// stands in for the object: no 5 GiB is written).
#[test]
fn embedded_s3_refuses_a_copy_over_five_gib() {
    let embedded = Embedded::start(Some("big"));
    let store = embedded.store("big");
    let file = embedded.server.data_dir().join("big/huge.obj~obj");
    std::fs::File::create(&file)
        .and_then(|f| f.set_len(hort_aws_quotas::S3_COPY_OBJECT_MAX_BYTES + 1))
        .expect("sparse file");
    let e = store
        .copy("huge.obj", "jobs/j/scene/huge.obj")
        .expect_err("over the limit");
    let message = e.to_string();
    assert!(
        message.contains("InvalidRequest")
            && message.contains("larger than the maximum allowable size for a copy source"),
        "{message}"
    );
    assert!(
        store.list("jobs/").expect("list").is_empty(),
        "nothing copied"
    );
}

#[test]
fn embedded_s3_keeps_objects_across_restarts() {
    let embedded = Embedded::start(Some("durable"));
    embedded
        .store("durable")
        .put("jobs/j/manifest.json", b"{}")
        .expect("put");
    let Embedded { server, dir } = embedded;
    drop(server);
    let again =
        embedded_s3::EmbeddedS3::start(dir.path(), s3_support::ACCESS_KEY, s3_support::SECRET_KEY)
            .expect("restart");
    let again = Embedded { server: again, dir };
    let store = again.store("durable");
    assert_eq!(store.get("jobs/j/manifest.json").expect("get"), b"{}");
    assert_eq!(
        store.put_if_absent("jobs/j/manifest.json", b"[]"),
        Ok(PutOutcome::AlreadyExists)
    );
}

#[test]
fn create_bucket_if_missing_creates_once_then_accepts_the_existing_bucket() {
    let embedded = Embedded::start(None);
    let store = embedded.store("fresh-bucket");
    let before = store.check_bucket().expect_err("no bucket yet");
    assert!(before.to_string().contains("does not exist"), "{before}");
    store.create_bucket_if_missing().expect("created");
    store.create_bucket_if_missing().expect("already there");
    store.check_bucket().expect("bucket now exists");
    store.put("k", b"v").expect("put");
    assert_eq!(store.get("k").expect("get"), b"v");
}

#[test]
fn external_s3_passes_the_conformance_suite() {
    let Some(config) = external_config() else {
        return;
    };
    println!(
        "external S3 endpoint: {} bucket: {}",
        config.endpoint.as_deref().unwrap_or("AWS"),
        config.bucket
    );
    let store = hort_functions::S3Store::open(&config).expect("S3 client");
    store.create_bucket_if_missing().expect("bucket ready");
    let prefix = unique_prefix("conformance");
    conformance::run_all(&store, &prefix);
    conformance::list_returns_every_page(&store, &prefix);
    assert_eq!(store.list(&prefix).expect("list"), Vec::<String>::new());
    delete_all_takes_more_keys_than_one_request(&store, &prefix);
}

#[test]
fn embedded_s3_deletes_more_keys_than_one_request_takes() {
    let embedded = Embedded::start(Some("batches"));
    delete_all_takes_more_keys_than_one_request(&embedded.store("batches"), "suite/");
}

/// `delete_all` of 1,001 stored keys and 2 missing ones (two `DeleteObjects` requests, S3
/// taking at most 1,000 keys each) removes exactly those keys.
fn delete_all_takes_more_keys_than_one_request(store: &hort_functions::S3Store, prefix: &str) {
    let base = format!("{prefix}batches/");
    let kept = format!("{prefix}kept");
    store.put(&kept, b"k").expect("put");
    let mut doomed: Vec<String> = (0..1001).map(|i| format!("{base}{i:05}")).collect();
    for key in &doomed {
        store.put(key, b"d").expect("put");
    }
    doomed.push(format!("{base}missing-1"));
    doomed.insert(500, format!("{base}missing-0"));
    store.delete_all(&doomed).expect("delete_all");
    assert_eq!(store.list(&base).expect("list"), Vec::<String>::new());
    assert_eq!(store.get(&kept).expect("get"), b"k");
    store.delete(&kept).expect("delete");
}

/// Every file and folder under `dir`, relative to it, sorted.
fn tree(dir: &std::path::Path) -> Vec<String> {
    let mut found = Vec::new();
    let mut pending = vec![dir.to_path_buf()];
    while let Some(next) = pending.pop() {
        for entry in std::fs::read_dir(&next).expect("read_dir") {
            let path = entry.expect("entry").path();
            found.push(
                path.strip_prefix(dir)
                    .expect("under dir")
                    .display()
                    .to_string(),
            );
            if path.is_dir() {
                pending.push(path);
            }
        }
    }
    found.sort();
    found
}

/// Deletes leave nothing on disk: no object file, no metadata file of `s3s-fs` in the data
/// directory, no folder of a key (the bucket's folder stays), by one `DeleteObject` and by
/// `DeleteObjects`; a folder still holding another key stays until that key goes too.
#[test]
fn embedded_s3_deletes_leave_no_files_or_folders_behind() {
    let embedded = Embedded::start(Some("tidy"));
    let store = embedded.store("tidy");
    let data_dir = embedded.server.data_dir();
    let keys = ["top", "jobs/j/a/b/c.bin", "jobs/j/a/d.bin", "jobs/k/e"];
    for key in keys {
        store.put(key, b"bytes").expect("put");
    }
    assert_eq!(
        tree(&data_dir.join("tidy")),
        [
            "jobs",
            "jobs/j",
            "jobs/j/a",
            "jobs/j/a/b",
            "jobs/j/a/b/c.bin~obj",
            "jobs/j/a/d.bin~obj",
            "jobs/k",
            "jobs/k/e~obj",
            "top~obj",
        ]
    );
    assert!(
        tree(data_dir).len() > tree(&data_dir.join("tidy")).len() + 1,
        "s3s-fs keeps metadata files beside the bucket: {:?}",
        tree(data_dir)
    );

    store.delete("jobs/j/a/b/c.bin").expect("delete");
    assert_eq!(
        tree(&data_dir.join("tidy")),
        [
            "jobs",
            "jobs/j",
            "jobs/j/a",
            "jobs/j/a/d.bin~obj",
            "jobs/k",
            "jobs/k/e~obj",
            "top~obj"
        ]
    );
    store.delete("top").expect("delete");
    let rest: Vec<String> = ["jobs/j/a/d.bin", "jobs/k/e"].map(str::to_owned).into();
    store.delete_all(&rest).expect("delete_all");
    assert_eq!(tree(&data_dir.join("tidy")), Vec::<String>::new());
    assert_eq!(tree(data_dir), ["tidy"]);
}
