//! [`S3Store`]: the [`BlobStore`] over AWS S3 or any S3-compatible server, through aws-sdk-s3.
//!
//! `BlobStore` is synchronous (the core has no async runtime), so every method blocks the
//! calling thread on a tokio runtime with `Handle::block_on`. Call the methods from plain
//! threads or from `tokio::task::spawn_blocking`, never from inside an async task: tokio panics
//! when a runtime thread blocks on another future ("Cannot start a runtime from within a
//! runtime"). The runtime must be multi-threaded, since its worker threads drive the sockets
//! while the caller blocks.

use std::ops::Range;

use aws_sdk_s3::Client;
use aws_sdk_s3::config::{ProvideCredentials, SharedCredentialsProvider};
use aws_sdk_s3::error::SdkError;
use aws_sdk_s3::operation::list_objects_v2::ListObjectsV2Output;
use aws_sdk_s3::operation::put_object::builders::PutObjectFluentBuilder;
use aws_sdk_s3::operation::put_object::{PutObjectError, PutObjectOutput};
use aws_sdk_s3::primitives::ByteStream;
use aws_sdk_s3::types::{BucketLocationConstraint, CreateBucketConfiguration};
use futures_util::{StreamExt, stream};
use hort_core::store::{BlobStore, PARALLEL_REQUESTS, PutOutcome, StoreError};
use tokio::runtime::{Handle, Runtime, RuntimeFlavor};

use crate::s3_config::{S3Config, signs_payloads};
use crate::s3_errors::{self, Request, Target};

/// How often `put_if_absent` retries AWS S3's 409 `ConditionalRequestConflict` (another
/// conditional write to the key was in flight); the retry then sees 412 or succeeds.
const CONDITIONAL_CONFLICT_ATTEMPTS: u32 = 5;

/// Bodies are preallocated from `Content-Length` up to this size, so a lying server cannot make
/// the store reserve memory it never fills.
const MAX_PREALLOCATION: usize = 64 << 20;

/// How many `DeleteObjects` requests [`S3Store::delete_all`] keeps in flight.
const PARALLEL_DELETE_BATCHES: usize = 4;

/// Why the bucket cannot be used, as [`S3Store::probe_bucket`] finds out: the two cases callers
/// explain in their own words, and every other classified failure.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BucketProblem {
    /// The credential chain found no credentials (only possible with
    /// [`crate::S3Credentials::DefaultChain`]); `detail` is what its last source said when it
    /// failed for another reason than having nothing to offer.
    NoCredentials {
        /// The last source's reason, on one line, if it gave one.
        detail: Option<String>,
    },
    /// The bucket does not exist at the endpoint.
    Missing,
    /// Anything else (unreachable endpoint, refused credentials, refused permission, ...).
    Store(StoreError),
}

/// One object of a listing with its size.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ListedObject {
    /// The object's key.
    pub key: String,
    /// Its size in bytes.
    pub bytes: u64,
}

/// A [`BlobStore`] on one S3 bucket.
///
/// Guarantees the [`BlobStore`] contract (it passes `hort_core::store::conformance`) on AWS S3
/// and on servers that implement `If-None-Match: *` on PUT atomically; errors are classified
/// in one place (module `s3_errors`). Objects are sent with one PUT each (S3 caps those at 5 GiB;
/// the body is signed only where [`signs_payloads`] says it must be)
/// and read whole into memory. Each request is retried by the SDK (standard mode,
/// [`S3Config::max_attempts`] attempts) on connection failures, timeouts, 5xx and throttling
/// before an error is returned. A GET whose body breaks off (reset, or fewer bytes than its
/// `Content-Length`) is sent again by the store itself, up to the same number of times; a body
/// shorter than announced is never returned.
pub struct S3Store {
    client: Client,
    target: Target,
    region: Option<String>,
    /// The provider the client signs with, when known (not for [`S3Store::from_client`]).
    credentials: Option<SharedCredentialsProvider>,
    handle: Handle,
    /// The runtime made by [`S3Store::open`], if this store owns one.
    runtime: Option<Runtime>,
    /// Times a GET is sent when its body breaks off ([`S3Config::max_attempts`]).
    body_attempts: u32,
    /// Whether PUT bodies are covered by the signature ([`signs_payloads`] of the endpoint).
    signs_payloads: bool,
}

impl S3Store {
    /// Builds the S3 client for `config` on the current tokio runtime, which must be
    /// multi-threaded; fails with [`StoreError::Other`] on a malformed endpoint, a
    /// current-thread runtime, or no region. Sends no request (see [`S3Store::check_bucket`]).
    pub async fn connect(config: &S3Config) -> Result<Self, StoreError> {
        let handle = Handle::current();
        if handle.runtime_flavor() == RuntimeFlavor::CurrentThread {
            return Err(StoreError::Other {
                what: "S3Store needs a multi-threaded tokio runtime (its workers drive the \
                       sockets while callers block), not a current-thread one"
                    .to_owned(),
            });
        }
        let (client, label, credentials) = config.sdk_parts().await?;
        let region = client.config().region().map(ToString::to_string);
        let mut store = Self::from_client(client, &config.bucket, label, handle);
        store.credentials = credentials;
        store.target.connect_timeout = config.connect_timeout;
        store.target.attempt_timeout = config.attempt_timeout;
        store.body_attempts = config.max_attempts.max(1);
        store.region = region;
        Ok(store)
    }

    /// Like [`S3Store::connect`], on a runtime of the store's own (two worker threads named
    /// `hort-s3`), so callers need no runtime. Call it, and drop the store, outside async tasks.
    pub fn open(config: &S3Config) -> Result<Self, StoreError> {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("hort-s3")
            .enable_all()
            .build()
            .map_err(|e| StoreError::Other {
                what: format!("cannot start the S3 client's tokio runtime: {e}"),
            })?;
        let mut store = runtime.block_on(Self::connect(config))?;
        store.runtime = Some(runtime);
        Ok(store)
    }

    /// A store over an SDK client built elsewhere (for example with [`S3Config::sdk_client`], once
    /// per Lambda environment, in `main`). `endpoint` names the server in error messages and
    /// decides whether PUT bodies are signed ([`signs_payloads`]: the client's endpoint URL, or
    /// any other label for AWS S3 itself); `handle` must belong to a multi-threaded runtime that
    /// outlives the store.
    pub fn from_client(
        client: Client,
        bucket: impl Into<String>,
        endpoint: impl Into<String>,
        handle: Handle,
    ) -> Self {
        let region = client.config().region().map(ToString::to_string);
        let endpoint = endpoint.into();
        Self {
            signs_payloads: signs_payloads(&endpoint),
            client,
            target: Target {
                bucket: bucket.into(),
                endpoint,
                connect_timeout: crate::s3_config::DEFAULT_CONNECT_TIMEOUT,
                attempt_timeout: crate::s3_config::DEFAULT_ATTEMPT_TIMEOUT,
            },
            region,
            credentials: None,
            handle,
            runtime: None,
            body_attempts: crate::s3_config::DEFAULT_MAX_ATTEMPTS,
        }
    }

    /// The bucket every key lives in.
    pub fn bucket(&self) -> &str {
        &self.target.bucket
    }

    /// The endpoint URL, or `AWS S3 (REGION)`, as named in error messages.
    pub fn endpoint(&self) -> &str {
        &self.target.endpoint
    }

    /// The SDK client, for operations the [`BlobStore`] trait does not cover.
    pub fn client(&self) -> &Client {
        &self.client
    }

    /// The signing region.
    pub fn region(&self) -> Option<&str> {
        self.region.as_deref()
    }

    /// Checks that credentials can be found (stores made by [`S3Store::connect`] or
    /// [`S3Store::open`]), the bucket exists and the credentials are accepted
    /// (HeadBucket), so a misconfiguration fails up front with one-line errors, prefixed
    /// `check bucket`: `Other` for missing credentials or a missing bucket, `Denied` for
    /// refused credentials or permissions, `Unavailable` for an unreachable endpoint.
    pub fn check_bucket(&self) -> Result<(), StoreError> {
        let op = "check bucket";
        self.handle
            .block_on(self.probe_bucket_async(op))
            .map_err(|problem| self.problem_error(op, problem))
    }

    /// [`S3Store::check_bucket`], with the missing credentials and the missing bucket told
    /// apart, for callers that explain them in their own words.
    pub fn probe_bucket(&self) -> Result<(), BucketProblem> {
        self.handle
            .block_on(self.probe_bucket_async("check bucket"))
    }

    /// A [`BucketProblem`] as the one-line error of operation `op`.
    fn problem_error(&self, op: &str, problem: BucketProblem) -> StoreError {
        match problem {
            BucketProblem::NoCredentials { detail } => StoreError::Other {
                what: s3_errors::no_credentials(op, &self.target, detail.as_deref()),
            },
            BucketProblem::Missing => StoreError::Other {
                what: s3_errors::missing_bucket(op, &self.target.bucket, &self.target.endpoint),
            },
            BucketProblem::Store(e) => e,
        }
    }

    /// The size of object `key` in bytes (HeadObject); `NotFound` when there is none.
    pub fn size(&self, key: &str) -> Result<u64, StoreError> {
        self.handle.block_on(self.object_len(key, "head"))
    }

    /// A presigned GET of object `key`, valid for `expires_in`: a URL anyone holding it can
    /// fetch the object with, straight from S3 (or the S3-compatible endpoint), without
    /// credentials of their own. Signing is local: nothing is sent.
    pub fn presigned_get(
        &self,
        key: &str,
        expires_in: std::time::Duration,
    ) -> Result<String, StoreError> {
        let config =
            aws_sdk_s3::presigning::PresigningConfig::expires_in(expires_in).map_err(|e| {
                StoreError::Other {
                    what: format!("presign {key:?}: {e}"),
                }
            })?;
        let presigned = self.handle.block_on(
            self.client
                .get_object()
                .bucket(&self.target.bucket)
                .key(key)
                .presigned(config),
        );
        presigned
            .map(|p| p.uri().to_owned())
            .map_err(|e| StoreError::Other {
                what: format!(
                    "presign {key:?} on S3 endpoint {}: {e}",
                    self.target.endpoint
                ),
            })
    }

    /// The "folders" right under `prefix`: each distinct key prefix up to and including the
    /// first `/` after `prefix` (S3's `CommonPrefixes` of a listing with `Delimiter` `/`),
    /// sorted, all pages. One entry per folder however many objects it holds: a listing of
    /// `jobs/` is one page per 1,000 jobs, not one per 1,000 objects.
    pub fn list_folders(&self, prefix: &str) -> Result<Vec<String>, StoreError> {
        let mut folders = Vec::new();
        self.handle
            .block_on(self.list_pages(prefix, Some("/"), |page| {
                folders.extend(
                    page.common_prefixes()
                        .iter()
                        .filter_map(|p| p.prefix().map(str::to_owned)),
                );
            }))?;
        folders.sort_unstable();
        folders.dedup();
        Ok(folders)
    }

    /// Every object under `prefix` with its size, sorted by key (all pages).
    pub fn list_sizes(&self, prefix: &str) -> Result<Vec<ListedObject>, StoreError> {
        self.handle.block_on(self.list_async(prefix))
    }

    /// Deletes every key of `keys` (missing ones included, as [`BlobStore::delete`]) with
    /// `DeleteObjects` requests of at most 1,000 keys (S3's limit), up to
    /// [`PARALLEL_DELETE_BATCHES`] in flight; the first failure (a failed request, or the first
    /// key S3 could not delete, named) is returned after the requests in flight end, and keys
    /// not yet sent are left alone.
    pub fn delete_all(&self, keys: &[String]) -> Result<(), StoreError> {
        let batches: Vec<&[String]> = keys
            .chunks(hort_aws_quotas::S3_DELETE_OBJECTS_MAX_KEYS)
            .collect();
        self.handle.block_on(async {
            for wave in batches.chunks(PARALLEL_DELETE_BATCHES) {
                let mut deletes = tokio::task::JoinSet::new();
                for batch in wave {
                    let (client, target, batch) =
                        (self.client.clone(), self.target.clone(), batch.to_vec());
                    deletes.spawn(async move { delete_objects(&client, &target, &batch).await });
                }
                let mut first_error = None;
                while let Some(done) = deletes.join_next().await {
                    let result = done.unwrap_or_else(|e| {
                        Err(StoreError::Other {
                            what: format!("delete: the request task failed ({e})"),
                        })
                    });
                    if let Err(e) = result {
                        first_error.get_or_insert(e);
                    }
                }
                if let Some(e) = first_error {
                    return Err(e);
                }
            }
            Ok(())
        })
    }

    /// Creates the bucket unless it exists (in the store's region), then checks it as
    /// [`S3Store::check_bucket`] does. For local servers and tests; production buckets come
    /// from the infrastructure templates.
    pub fn create_bucket_if_missing(&self) -> Result<(), StoreError> {
        self.handle.block_on(async {
            let request = Request {
                op: "create bucket",
                key: None,
                object_read: false,
            };
            match self.probe_bucket_async(request.op).await {
                Err(BucketProblem::Missing) => {}
                other => return other.map_err(|p| self.problem_error(request.op, p)),
            }
            let mut create = self.client.create_bucket().bucket(&self.target.bucket);
            if let Some(region) = self.region.as_deref().filter(|r| *r != "us-east-1") {
                create = create.create_bucket_configuration(
                    CreateBucketConfiguration::builder()
                        .location_constraint(BucketLocationConstraint::from(region))
                        .build(),
                );
            }
            if let Err(err) = create.send().await {
                let raced = matches!(
                    aws_sdk_s3::error::ProvideErrorMetadata::code(&err),
                    Some("BucketAlreadyOwnedByYou" | "BucketAlreadyExists")
                );
                if !raced {
                    return Err(s3_errors::store_error(err, request, &self.target));
                }
            }
            self.probe_bucket_async(request.op)
                .await
                .map_err(|p| self.problem_error(request.op, p))
        })
    }

    async fn probe_bucket_async(&self, op: &str) -> Result<(), BucketProblem> {
        let request = Request {
            op,
            key: None,
            object_read: false,
        };
        // Resolve the credentials first: a request would fail with the last source's reason
        // (often the EC2 metadata service's), which does not say that none were found.
        if let Some(provider) = &self.credentials
            && let Err(e) = provider.provide_credentials().await
        {
            return Err(BucketProblem::NoCredentials {
                detail: s3_errors::credentials_detail(&e),
            });
        }
        let head = self
            .client
            .head_bucket()
            .bucket(&self.target.bucket)
            .send()
            .await;
        let Err(err) = head else {
            return Ok(());
        };
        if s3_errors::is_missing_bucket(&err, request) {
            return Err(BucketProblem::Missing);
        }
        if s3_errors::lacks_code(&err) {
            // A HEAD answer has no body, hence no error code: a GET tells which refusal it was.
            let list = self
                .client
                .list_objects_v2()
                .bucket(&self.target.bucket)
                .max_keys(1)
                .send()
                .await;
            if let Err(list_err) = list {
                if s3_errors::is_missing_bucket(&list_err, request) {
                    return Err(BucketProblem::Missing);
                }
                return Err(BucketProblem::Store(s3_errors::store_error(
                    list_err,
                    request,
                    &self.target,
                )));
            }
        }
        Err(BucketProblem::Store(s3_errors::store_error(
            err,
            request,
            &self.target,
        )))
    }

    /// The length of object `key` (HeadObject).
    async fn object_len(&self, key: &str, op: &str) -> Result<u64, StoreError> {
        let request = Request {
            op,
            key: Some(key),
            object_read: true,
        };
        let head = self
            .client
            .head_object()
            .bucket(&self.target.bucket)
            .key(key)
            .send()
            .await
            .map_err(|e| s3_errors::store_error(e, request, &self.target))?;
        u64::try_from(head.content_length().unwrap_or(0)).map_err(|_| StoreError::Other {
            what: format!(
                "{op} {key:?}: S3 endpoint {} reported a negative length",
                self.target.endpoint
            ),
        })
    }

    /// Reads `body` whole; `expected` is the announced length, checked at the end.
    async fn collect(
        &self,
        mut body: ByteStream,
        expected: Option<i64>,
        request: Request<'_>,
    ) -> Result<Vec<u8>, StoreError> {
        let expected = expected.and_then(|n| usize::try_from(n).ok());
        let mut bytes = Vec::with_capacity(expected.unwrap_or(0).min(MAX_PREALLOCATION));
        let failed = |reason: String| StoreError::Unavailable {
            what: format!(
                "{} {:?}: reading the object from S3 endpoint {} failed ({reason})",
                request.op,
                request.key.unwrap_or_default(),
                self.target.endpoint
            ),
        };
        loop {
            match body.try_next().await {
                Ok(Some(chunk)) => bytes.extend_from_slice(&chunk),
                Ok(None) => break,
                Err(e) => return Err(failed(one_line_error(&e))),
            }
        }
        match expected {
            Some(n) if n != bytes.len() => Err(failed(format!(
                "got {} of {n} announced bytes",
                bytes.len()
            ))),
            _ => Ok(bytes),
        }
    }

    async fn get_range_async(&self, key: &str, range: Range<u64>) -> Result<Vec<u8>, StoreError> {
        let op = "get range";
        let invalid = |len: u64| StoreError::InvalidRange {
            key: key.to_owned(),
            start: range.start,
            end: range.end,
            len,
        };
        // No object is longer than i64::MAX bytes, and servers parse ranges as signed 64-bit.
        let signed_max = i64::MAX as u64;
        if range.start >= range.end || range.start > signed_max {
            return Err(invalid(self.object_len(key, op).await?));
        }
        let header = if range.end > signed_max {
            format!("bytes={}-", range.start)
        } else {
            format!("bytes={}-{}", range.start, range.end - 1)
        };
        let request = Request {
            op,
            key: Some(key),
            object_read: true,
        };
        let mut attempt = 1;
        let (content_range, bytes) = loop {
            let answer = self
                .client
                .get_object()
                .bucket(&self.target.bucket)
                .key(key)
                .range(&header)
                .send()
                .await;
            let out = match answer {
                Ok(out) => out,
                Err(err) if s3_errors::is_invalid_range(&err) => {
                    return Err(invalid(self.object_len(key, op).await?));
                }
                Err(err) => return Err(s3_errors::store_error(err, request, &self.target)),
            };
            let content_range = out.content_range().map(str::to_owned);
            match self.collect(out.body, out.content_length, request).await {
                Ok(bytes) => break (content_range, bytes),
                Err(_) if attempt < self.body_attempts => {
                    body_retry_pause(attempt).await;
                    attempt += 1;
                }
                Err(e) => return Err(e),
            }
        };
        match content_range.as_deref().and_then(parse_content_range) {
            Some((first, total)) => {
                if range.start >= total {
                    Err(invalid(total))
                } else if first != range.start {
                    Err(StoreError::Other {
                        what: format!(
                            "{op} {key:?}: S3 endpoint {} sent bytes from {first}, not from {}",
                            self.target.endpoint, range.start
                        ),
                    })
                } else {
                    Ok(bytes)
                }
            }
            // No Content-Range: the server sent the whole object; cut the range out here.
            None => {
                let len = bytes.len() as u64;
                if range.start >= len {
                    return Err(invalid(len));
                }
                // Both bounds are <= len, which fits in usize since the bytes are in memory.
                let (start, end) = (range.start as usize, range.end.min(len) as usize);
                Ok(bytes[start..end].to_vec())
            }
        }
    }

    async fn put_if_absent_async(&self, key: &str, bytes: &[u8]) -> Result<PutOutcome, StoreError> {
        let request = Request {
            op: "put if absent",
            key: Some(key),
            object_read: false,
        };
        let mut attempt = 0;
        loop {
            attempt += 1;
            let put = self
                .client
                .put_object()
                .bucket(&self.target.bucket)
                .key(key)
                .if_none_match("*")
                .content_length(len_i64(bytes))
                .body(ByteStream::from(bytes.to_vec()));
            match self.send_put(put).await {
                Ok(_) => return Ok(PutOutcome::Created),
                Err(err) if s3_errors::is_precondition_failed(&err) => {
                    return Ok(PutOutcome::AlreadyExists);
                }
                Err(err)
                    if s3_errors::is_conditional_conflict(&err)
                        && attempt < CONDITIONAL_CONFLICT_ATTEMPTS =>
                {
                    let backoff = 50u64 << attempt;
                    tokio::time::sleep(std::time::Duration::from_millis(backoff)).await;
                }
                Err(err) => return Err(s3_errors::store_error(err, request, &self.target)),
            }
        }
    }

    async fn list_async(&self, prefix: &str) -> Result<Vec<ListedObject>, StoreError> {
        let mut keys = Vec::new();
        self.list_pages(prefix, None, |page| {
            keys.extend(page.contents().iter().filter_map(|object| {
                Some(ListedObject {
                    key: object.key()?.to_owned(),
                    bytes: u64::try_from(object.size().unwrap_or(0)).unwrap_or(0),
                })
            }));
        })
        .await?;
        keys.sort_unstable_by(|a, b| a.key.cmp(&b.key));
        keys.dedup_by(|a, b| a.key == b.key);
        Ok(keys)
    }

    /// Every page of the listing of `prefix` (with `delimiter`, if given), each handed to
    /// `page`; a truncated page without a new continuation token is an error.
    async fn list_pages(
        &self,
        prefix: &str,
        delimiter: Option<&str>,
        mut page: impl FnMut(&ListObjectsV2Output),
    ) -> Result<(), StoreError> {
        let request = Request {
            op: "list",
            key: Some(prefix),
            object_read: false,
        };
        let mut token: Option<String> = None;
        loop {
            let out = self
                .client
                .list_objects_v2()
                .bucket(&self.target.bucket)
                .prefix(prefix)
                .set_delimiter(delimiter.map(str::to_owned))
                .set_continuation_token(token.clone())
                .send()
                .await
                .map_err(|e| s3_errors::store_error(e, request, &self.target))?;
            page(&out);
            if !out.is_truncated().unwrap_or(false) {
                return Ok(());
            }
            match out.next_continuation_token() {
                Some(next) if token.as_deref() != Some(next) => token = Some(next.to_owned()),
                _ => {
                    return Err(StoreError::Other {
                        what: format!(
                            "list {prefix:?}: S3 endpoint {} sent a truncated page without a \
                             new continuation token",
                            self.target.endpoint
                        ),
                    });
                }
            }
        }
    }
}

impl S3Store {
    async fn get_async(&self, key: &str) -> Result<Vec<u8>, StoreError> {
        let request = Request {
            op: "get",
            key: Some(key),
            object_read: true,
        };
        let mut attempt = 1;
        loop {
            let out = self
                .client
                .get_object()
                .bucket(&self.target.bucket)
                .key(key)
                .send()
                .await
                .map_err(|e| s3_errors::store_error(e, request, &self.target))?;
            match self.collect(out.body, out.content_length, request).await {
                Err(_) if attempt < self.body_attempts => {
                    body_retry_pause(attempt).await;
                    attempt += 1;
                }
                read => return read,
            }
        }
    }

    /// Sends `put`, its body signed only where [`signs_payloads`] says it must be.
    async fn send_put(
        &self,
        put: PutObjectFluentBuilder,
    ) -> Result<PutObjectOutput, SdkError<PutObjectError>> {
        if self.signs_payloads {
            put.send().await
        } else {
            put.customize().disable_payload_signing().send().await
        }
    }

    async fn put_async(&self, key: &str, bytes: &[u8]) -> Result<(), StoreError> {
        let request = Request {
            op: "put",
            key: Some(key),
            object_read: false,
        };
        let put = self
            .client
            .put_object()
            .bucket(&self.target.bucket)
            .key(key)
            .content_length(len_i64(bytes))
            .body(ByteStream::from(bytes.to_vec()));
        self.send_put(put)
            .await
            .map(drop)
            .map_err(|e| s3_errors::store_error(e, request, &self.target))
    }
}

impl BlobStore for S3Store {
    fn get(&self, key: &str) -> Result<Vec<u8>, StoreError> {
        self.handle.block_on(self.get_async(key))
    }

    /// Up to [`PARALLEL_REQUESTS`] GETs in flight, driven on the calling thread.
    fn get_many(&self, keys: &[String]) -> Vec<Result<Vec<u8>, StoreError>> {
        self.handle.block_on(
            stream::iter(keys)
                .map(|key| self.get_async(key))
                .buffered(PARALLEL_REQUESTS)
                .collect(),
        )
    }

    /// Up to [`PARALLEL_REQUESTS`] PUTs in flight, driven on the calling thread.
    fn put_many(&self, objects: &[(String, Vec<u8>)]) -> Vec<Result<(), StoreError>> {
        self.handle.block_on(
            stream::iter(objects)
                .map(|(key, bytes)| self.put_async(key, bytes))
                .buffered(PARALLEL_REQUESTS)
                .collect(),
        )
    }

    fn get_range(&self, key: &str, range: Range<u64>) -> Result<Vec<u8>, StoreError> {
        self.handle.block_on(self.get_range_async(key, range))
    }

    fn put(&self, key: &str, bytes: &[u8]) -> Result<(), StoreError> {
        self.handle.block_on(self.put_async(key, bytes))
    }

    /// Sends `If-None-Match: *`: HTTP 412 means [`PutOutcome::AlreadyExists`]. If an attempt
    /// created the object but its answer was lost, the SDK's retry sees 412 and reports
    /// `AlreadyExists` for the caller's own bytes; compare contents where that matters.
    fn put_if_absent(&self, key: &str, bytes: &[u8]) -> Result<PutOutcome, StoreError> {
        self.handle.block_on(self.put_if_absent_async(key, bytes))
    }

    fn list(&self, prefix: &str) -> Result<Vec<String>, StoreError> {
        let objects = self.handle.block_on(self.list_async(prefix))?;
        Ok(objects.into_iter().map(|o| o.key).collect())
    }

    fn delete(&self, key: &str) -> Result<(), StoreError> {
        self.handle
            .block_on(delete_object(&self.client, &self.target, key))
    }

    fn size(&self, key: &str) -> Result<u64, StoreError> {
        S3Store::size(self, key)
    }

    /// CopyObject inside the bucket: no bytes pass through this process. S3 copies at most
    /// [`hort_core::store::COPY_MAX_BYTES`] this way; a larger source fails with S3's error.
    fn copy(&self, from: &str, to: &str) -> Result<(), StoreError> {
        self.handle.block_on(self.copy_async(from, to))
    }
}

/// The characters CopyObject's source must have percent-encoded: all but letters, digits,
/// `/`, `-`, `_`, `.` and `~`.
const COPY_SOURCE_ENCODED: &percent_encoding::AsciiSet = &percent_encoding::NON_ALPHANUMERIC
    .remove(b'/')
    .remove(b'-')
    .remove(b'_')
    .remove(b'.')
    .remove(b'~');

impl S3Store {
    async fn copy_async(&self, from: &str, to: &str) -> Result<(), StoreError> {
        // A missing source is the error to name: S3 answers NoSuchKey for it.
        let request = Request {
            op: "copy",
            key: Some(from),
            object_read: true,
        };
        let source = format!(
            "{}/{}",
            self.target.bucket,
            percent_encoding::utf8_percent_encode(from, COPY_SOURCE_ENCODED)
        );
        self.client
            .copy_object()
            .bucket(&self.target.bucket)
            .key(to)
            .copy_source(source)
            .send()
            .await
            .map(drop)
            .map_err(|e| s3_errors::store_error(e, request, &self.target))
    }
}

/// The wait before sending a GET again whose body broke off: 20 ms, doubling per attempt, at
/// most 1 s. The SDK retries failures before an answer's head (with its own backoff) but hands
/// the body over as a stream, so a connection reset or cut in the body reaches the store.
async fn body_retry_pause(attempt: u32) {
    let ms = (20u64 << attempt.min(6).saturating_sub(1)).min(1000);
    tokio::time::sleep(std::time::Duration::from_millis(ms)).await;
}

/// One DELETE; a missing key is success (S3 semantics).
async fn delete_object(client: &Client, target: &Target, key: &str) -> Result<(), StoreError> {
    let request = Request {
        op: "delete",
        key: Some(key),
        object_read: false,
    };
    match client
        .delete_object()
        .bucket(&target.bucket)
        .key(key)
        .send()
        .await
    {
        Ok(_) => Ok(()),
        // Some servers answer 404 NoSuchKey where S3 answers 204: same meaning.
        Err(err) if aws_sdk_s3::error::ProvideErrorMetadata::code(&err) == Some("NoSuchKey") => {
            Ok(())
        }
        Err(err) => Err(s3_errors::store_error(err, request, target)),
    }
}

/// One `DeleteObjects` request for `keys` (at most 1,000), in quiet mode: S3 answers only the
/// keys it could not delete, and the first of them is the error.
async fn delete_objects(
    client: &Client,
    target: &Target,
    keys: &[String],
) -> Result<(), StoreError> {
    use aws_sdk_s3::types::{Delete, ObjectIdentifier};
    let Some(first) = keys.first() else {
        return Ok(());
    };
    let request = Request {
        op: "delete",
        key: Some(first),
        object_read: false,
    };
    let objects = keys
        .iter()
        .map(|key| ObjectIdentifier::builder().key(key).build())
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| StoreError::Other {
            what: format!("delete {first:?} and on: {e}"),
        })?;
    let delete = Delete::builder()
        .set_objects(Some(objects))
        .quiet(true)
        .build()
        .map_err(|e| StoreError::Other {
            what: format!("delete {first:?} and on: {e}"),
        })?;
    let output = client
        .delete_objects()
        .bucket(&target.bucket)
        .delete(delete)
        .send()
        .await
        .map_err(|err| s3_errors::store_error(err, request, target))?;
    match output.errors().first() {
        None => Ok(()),
        Some(failed) => Err(StoreError::Other {
            what: format!(
                "delete {:?} on S3 endpoint {} (bucket {}): {} {} ({} of {} keys of the request \
                 not deleted)",
                failed.key().unwrap_or_default(),
                target.endpoint,
                target.bucket,
                failed.code().unwrap_or("an error"),
                failed.message().unwrap_or_default(),
                output.errors().len(),
                keys.len()
            ),
        }),
    }
}

impl std::fmt::Debug for S3Store {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("S3Store")
            .field("bucket", &self.target.bucket)
            .field("endpoint", &self.target.endpoint)
            .finish_non_exhaustive()
    }
}

impl Drop for S3Store {
    fn drop(&mut self) {
        // No request is in flight (they all borrow the store); idle connections may be. This
        // does not block, so it is safe even inside an async context.
        if let Some(runtime) = self.runtime.take() {
            runtime.shutdown_background();
        }
    }
}

/// `(first byte, total length)` from `Content-Range: bytes FIRST-LAST/TOTAL`.
fn parse_content_range(value: &str) -> Option<(u64, u64)> {
    let (span, total) = value.strip_prefix("bytes ")?.split_once('/')?;
    let (first, _last) = span.split_once('-')?;
    Some((first.trim().parse().ok()?, total.trim().parse().ok()?))
}

fn len_i64(bytes: &[u8]) -> i64 {
    i64::try_from(bytes.len()).unwrap_or(i64::MAX)
}

/// An error and its sources on one line, `: `-separated.
fn one_line_error(err: &(dyn std::error::Error + 'static)) -> String {
    let mut parts = vec![err.to_string()];
    let mut source = err.source();
    while let Some(e) = source {
        parts.push(e.to_string());
        source = e.source();
    }
    parts
        .join(": ")
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn content_range_gives_first_byte_and_total() {
        assert_eq!(parse_content_range("bytes 2-4/10"), Some((2, 10)));
        assert_eq!(parse_content_range("bytes */10"), None);
        assert_eq!(parse_content_range("items 2-4/10"), None);
    }
}
