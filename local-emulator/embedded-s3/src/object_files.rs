//! `s3s_fs::FileSystem` with S3 key semantics: the storage behind [`super::EmbeddedS3`].
//!
//! Plain `s3s-fs` stores key `a/b` at the path `bucket/a/b`, so `a` and `a/b` cannot both exist
//! (one would be a file, the other needs a directory), and it checks `If-None-Match` before
//! writing without a lock, so two racing conditional puts can both succeed. This wrapper
//! - stores key `k` in the file named `k` + [`OBJECT_SUFFIX`] (a `~` in `k` is doubled first),
//!   so no object file is ever a directory of another key;
//! - serialises conditional puts against all other puts, so exactly one racer creates the object;
//! - removes on delete what `s3s-fs` leaves behind: the object's metadata files and the
//!   folders of its key left empty, so a data directory does not grow with deleted objects;
//! - lists by itself (sorted by key bytes, with prefix, delimiter, start-after, continuation token
//!   and max-keys as S3 defines them), since the stored names sort differently from the keys.
//!
//! Only the operations the project's S3 client uses are forwarded (bucket create/head/delete/
//! list/location, object put/get/head/delete/copy, DeleteObjects of at most 1,000 keys as on AWS,
//! ListObjects v1 and v2); the rest answer
//! `NotImplemented`. Keys that path normalisation would alter (`a//b`, `./a`, `a/../b`) are
//! outside the S3 subset this server supports.

use std::collections::BTreeSet;
use std::path::PathBuf;

use s3s::dto::{
    CommonPrefix, CopyObjectInput, CopyObjectOutput, CopySource, CreateBucketInput,
    CreateBucketOutput, DeleteBucketInput, DeleteBucketOutput, DeleteObjectInput,
    DeleteObjectOutput, DeleteObjectsInput, DeleteObjectsOutput, GetBucketLocationInput,
    GetBucketLocationOutput, GetObjectInput, GetObjectOutput, HeadBucketInput, HeadBucketOutput,
    HeadObjectInput, HeadObjectOutput, ListBucketsInput, ListBucketsOutput, ListObjectsInput,
    ListObjectsOutput, ListObjectsV2Input, ListObjectsV2Output, Object, PutObjectInput,
    PutObjectOutput,
};
use s3s::{S3, S3Request, S3Response, S3Result, s3_error};
use tokio::sync::RwLock;

/// Appended to every object's file name; never the end of a directory name (see module docs).
pub(crate) const OBJECT_SUFFIX: &str = "~obj";

/// The most keys one list page returns, as on AWS S3.
const MAX_KEYS_PER_PAGE: usize = 1000;

/// The S3 service of the embedded server: `s3s_fs::FileSystem` plus key encoding, atomic
/// conditional puts and exact listing.
pub(crate) struct ObjectFiles {
    files: s3s_fs::FileSystem,
    /// The data directory `files` serves; bucket `b` is its subdirectory `b`.
    root: PathBuf,
    /// Plain puts share it; conditional puts hold it alone, so check-then-write is atomic;
    /// deletes hold it alone, so pruning an emptied folder never races a put into it.
    puts: RwLock<()>,
}

impl ObjectFiles {
    /// Serves `files`, whose data directory is `root`.
    pub(crate) fn new(files: s3s_fs::FileSystem, root: PathBuf) -> Self {
        Self {
            files,
            root,
            puts: RwLock::new(()),
        }
    }

    /// `NoSuchBucket` unless the bucket exists. `s3s-fs` alone answers `NoSuchKey` for a get
    /// from a missing bucket and creates the bucket on a put, unlike S3.
    fn require_bucket(&self, bucket: &str) -> S3Result<()> {
        if s3s::path::check_bucket_name(bucket) && self.root.join(bucket).is_dir() {
            Ok(())
        } else {
            Err(s3_error!(NoSuchBucket))
        }
    }

    /// Every object under `prefix` as (key, size, last modified), sorted by key bytes.
    async fn all_objects<T>(
        &self,
        req: S3Request<T>,
        bucket: String,
        prefix: &str,
    ) -> S3Result<Vec<Object>> {
        self.require_bucket(&bucket)?;
        let inner = req.map_input(|_| ListObjectsV2Input {
            bucket,
            prefix: Some(escape(prefix)),
            max_keys: Some(i32::MAX),
            ..Default::default()
        });
        let listed = self.files.list_objects_v2(inner).await?.output;
        let mut objects: Vec<Object> = listed
            .contents
            .unwrap_or_default()
            .into_iter()
            .filter_map(|mut object| {
                let key = object.key.as_deref().and_then(key_of_file)?;
                if !key.starts_with(prefix) {
                    return None;
                }
                object.key = Some(key);
                Some(object)
            })
            .collect();
        objects.sort_by(|a, b| a.key.cmp(&b.key));
        Ok(objects)
    }

    /// Removes what `s3s-fs` leaves behind when it deletes the object stored as `file` (the
    /// encoded key, see [`file_of_key`]) in `bucket`: its metadata and checksum files in the
    /// data directory (`.bucket-B.object-K.metadata.json` and `.internal.json`, B and K in
    /// URL-safe base64), and the folders of the key left empty, up to the bucket's folder
    /// (kept). Without this, a data directory grows by two files per object ever deleted.
    /// Callers hold `puts` alone, so no put is between creating a folder and filling it.
    fn remove_leftovers(&self, bucket: &str, file: &str) -> S3Result<()> {
        let encode = |s: &str| base64_simd::URL_SAFE_NO_PAD.encode_to_string(s);
        let stem = format!(".bucket-{}.object-{}", encode(bucket), encode(file));
        for suffix in [".metadata.json", ".internal.json"] {
            let path = self.root.join(format!("{stem}{suffix}"));
            match std::fs::remove_file(&path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(s3_error!(
                        InternalError,
                        "cannot remove {}: {e}",
                        path.display()
                    ));
                }
                _ => {}
            }
        }
        let bucket_dir = self.root.join(bucket);
        let mut dir = bucket_dir.join(file);
        while dir.pop() && dir.starts_with(&bucket_dir) && dir != bucket_dir {
            match std::fs::remove_dir(&dir) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                // Not empty (another key lives there) or not removable: the folders above stay.
                Err(_) => break,
            }
        }
        Ok(())
    }
}

/// One page of a listing.
struct Page {
    objects: Vec<Object>,
    common_prefixes: Vec<String>,
    /// The last key or common prefix returned, if more follow.
    next: Option<String>,
}

/// S3 listing over `objects` (sorted, all under `prefix`): keys whose remainder after `prefix`
/// contains `delimiter` roll up into one common prefix each; entries at or before `after` are
/// skipped; at most `max_keys` entries (keys and common prefixes together).
fn page(
    objects: Vec<Object>,
    prefix: &str,
    delimiter: Option<&str>,
    after: Option<&str>,
    max_keys: usize,
) -> Page {
    let mut page = Page {
        objects: Vec::new(),
        common_prefixes: Vec::new(),
        next: None,
    };
    let mut seen_prefixes = BTreeSet::new();
    let mut taken = 0;
    for object in objects {
        let key = object.key.as_deref().unwrap_or_default();
        let rolled_up = delimiter
            .filter(|d| !d.is_empty())
            .and_then(|d| {
                let rest = &key[prefix.len()..];
                rest.find(d).map(|at| &key[..prefix.len() + at + d.len()])
            })
            .map(str::to_owned);
        let name = rolled_up.as_deref().unwrap_or(key);
        if after.is_some_and(|after| name <= after) {
            continue;
        }
        if rolled_up
            .as_ref()
            .is_some_and(|p| seen_prefixes.contains(p))
        {
            continue;
        }
        if taken == max_keys {
            // Something is left over: the page is truncated after the last entry taken.
            page.next = page
                .common_prefixes
                .last()
                .max(page.objects.last().and_then(|o| o.key.as_ref()))
                .cloned();
            break;
        }
        taken += 1;
        match rolled_up {
            Some(common) => {
                seen_prefixes.insert(common.clone());
                page.common_prefixes.push(common);
            }
            None => page.objects.push(object),
        }
    }
    page
}

fn max_keys(requested: Option<i32>) -> usize {
    requested.map_or(MAX_KEYS_PER_PAGE, |n| {
        usize::try_from(n).unwrap_or(0).min(MAX_KEYS_PER_PAGE)
    })
}

fn common_prefix_list(prefixes: Vec<String>) -> Option<Vec<CommonPrefix>> {
    (!prefixes.is_empty()).then(|| {
        prefixes
            .into_iter()
            .map(|prefix| CommonPrefix {
                prefix: Some(prefix),
            })
            .collect()
    })
}

/// `key` with every `~` doubled: prefix-preserving, and never ends in an odd run of `~`.
fn escape(key: &str) -> String {
    key.replace('~', "~~")
}

/// The stored name of object `key`.
pub(crate) fn file_of_key(key: &str) -> String {
    let mut name = escape(key);
    name.push_str(OBJECT_SUFFIX);
    name
}

/// The object key stored under `name`, or `None` if `name` is not an object file.
pub(crate) fn key_of_file(name: &str) -> Option<String> {
    let key = name.strip_suffix(OBJECT_SUFFIX)?.replace("~~", "~");
    (file_of_key(&key) == name).then_some(key)
}

#[async_trait::async_trait]
impl S3 for ObjectFiles {
    async fn create_bucket(
        &self,
        req: S3Request<CreateBucketInput>,
    ) -> S3Result<S3Response<CreateBucketOutput>> {
        self.files.create_bucket(req).await
    }

    async fn delete_bucket(
        &self,
        req: S3Request<DeleteBucketInput>,
    ) -> S3Result<S3Response<DeleteBucketOutput>> {
        self.files.delete_bucket(req).await
    }

    async fn head_bucket(
        &self,
        req: S3Request<HeadBucketInput>,
    ) -> S3Result<S3Response<HeadBucketOutput>> {
        self.files.head_bucket(req).await
    }

    async fn get_bucket_location(
        &self,
        req: S3Request<GetBucketLocationInput>,
    ) -> S3Result<S3Response<GetBucketLocationOutput>> {
        self.files.get_bucket_location(req).await
    }

    async fn list_buckets(
        &self,
        req: S3Request<ListBucketsInput>,
    ) -> S3Result<S3Response<ListBucketsOutput>> {
        self.files.list_buckets(req).await
    }

    async fn get_object(
        &self,
        mut req: S3Request<GetObjectInput>,
    ) -> S3Result<S3Response<GetObjectOutput>> {
        self.require_bucket(&req.input.bucket)?;
        req.input.key = file_of_key(&req.input.key);
        let path = self.root.join(&req.input.bucket).join(&req.input.key);
        let mut response = self.files.get_object(req).await?;
        whole_body(&mut response.output, path).await?;
        Ok(response)
    }

    async fn head_object(
        &self,
        mut req: S3Request<HeadObjectInput>,
    ) -> S3Result<S3Response<HeadObjectOutput>> {
        self.require_bucket(&req.input.bucket)?;
        req.input.key = file_of_key(&req.input.key);
        self.files.head_object(req).await
    }

    async fn put_object(
        &self,
        mut req: S3Request<PutObjectInput>,
    ) -> S3Result<S3Response<PutObjectOutput>> {
        self.require_bucket(&req.input.bucket)?;
        req.input.key = file_of_key(&req.input.key);
        gather_body(&mut req.input).await?;
        if req.input.if_none_match.is_some() || req.input.if_match.is_some() {
            let _alone = self.puts.write().await;
            self.files.put_object(req).await
        } else {
            let _shared = self.puts.read().await;
            self.files.put_object(req).await
        }
    }

    /// CopyObject of a source in a bucket of this server (as `s3s-fs` copies it, with both keys
    /// encoded); a source over S3's 5 GiB single-copy limit is refused with S3's error.
    async fn copy_object(
        &self,
        mut req: S3Request<CopyObjectInput>,
    ) -> S3Result<S3Response<CopyObjectOutput>> {
        self.require_bucket(&req.input.bucket)?;
        let CopySource::Bucket { bucket, key, .. } = &mut req.input.copy_source else {
            return Err(s3_error!(NotImplemented, "only bucket/key copy sources"));
        };
        self.require_bucket(bucket)?;
        *key = file_of_key(key).into();
        let source = self.root.join(&**bucket).join(&**key);
        let len = std::fs::metadata(&source).map_or(0, |m| m.len());
        if len > hort_aws_quotas::S3_COPY_OBJECT_MAX_BYTES {
            return Err(s3_error!(
                InvalidRequest,
                "The specified copy source is larger than the maximum allowable size for a copy \
                 source: {}",
                hort_aws_quotas::S3_COPY_OBJECT_MAX_BYTES
            ));
        }
        req.input.key = file_of_key(&req.input.key);
        let _shared = self.puts.read().await;
        self.files.copy_object(req).await
    }

    async fn delete_object(
        &self,
        mut req: S3Request<DeleteObjectInput>,
    ) -> S3Result<S3Response<DeleteObjectOutput>> {
        self.require_bucket(&req.input.bucket)?;
        req.input.key = file_of_key(&req.input.key);
        let bucket = req.input.bucket.clone();
        let file = req.input.key.clone();
        let _alone = self.puts.write().await;
        let response = self.files.delete_object(req).await?;
        self.remove_leftovers(&bucket, &file)?;
        Ok(response)
    }

    async fn delete_objects(
        &self,
        mut req: S3Request<DeleteObjectsInput>,
    ) -> S3Result<S3Response<DeleteObjectsOutput>> {
        self.require_bucket(&req.input.bucket)?;
        let objects = &mut req.input.delete.objects;
        if objects.len() > hort_aws_quotas::S3_DELETE_OBJECTS_MAX_KEYS {
            // What S3 answers a request of more keys than it takes.
            return Err(s3_error!(
                MalformedXML,
                "The XML you provided was not well-formed or did not validate against our \
                 published schema ({} keys; at most {} per request)",
                objects.len(),
                hort_aws_quotas::S3_DELETE_OBJECTS_MAX_KEYS
            ));
        }
        for object in objects.iter_mut() {
            object.key = file_of_key(&object.key);
        }
        let bucket = req.input.bucket.clone();
        let files: Vec<String> = objects.iter().map(|o| o.key.clone()).collect();
        let _alone = self.puts.write().await;
        let mut response = self.files.delete_objects(req).await?;
        for file in &files {
            self.remove_leftovers(&bucket, file)?;
        }
        for deleted in response.output.deleted.iter_mut().flatten() {
            deleted.key = deleted.key.as_deref().and_then(key_of_file);
        }
        Ok(response)
    }

    async fn list_objects_v2(
        &self,
        req: S3Request<ListObjectsV2Input>,
    ) -> S3Result<S3Response<ListObjectsV2Output>> {
        let input = req.input.clone();
        let prefix = input.prefix.clone().unwrap_or_default();
        let objects = self.all_objects(req, input.bucket.clone(), &prefix).await?;
        let after = match (&input.continuation_token, &input.start_after) {
            (Some(token), Some(start)) => Some(token.max(start)),
            (token, start) => token.as_ref().or(start.as_ref()),
        };
        let max_keys = max_keys(input.max_keys);
        let page = page(
            objects,
            &prefix,
            input.delimiter.as_deref(),
            after.map(String::as_str),
            max_keys,
        );
        let key_count = page.objects.len() + page.common_prefixes.len();
        Ok(S3Response::new(ListObjectsV2Output {
            name: Some(input.bucket),
            prefix: input.prefix,
            max_keys: Some(i32::try_from(max_keys).unwrap_or(i32::MAX)),
            key_count: Some(i32::try_from(key_count).unwrap_or(i32::MAX)),
            continuation_token: input.continuation_token,
            is_truncated: Some(page.next.is_some()),
            next_continuation_token: page.next,
            contents: (!page.objects.is_empty()).then_some(page.objects),
            common_prefixes: common_prefix_list(page.common_prefixes),
            delimiter: input.delimiter,
            encoding_type: input.encoding_type,
            start_after: input.start_after,
            ..Default::default()
        }))
    }

    async fn list_objects(
        &self,
        req: S3Request<ListObjectsInput>,
    ) -> S3Result<S3Response<ListObjectsOutput>> {
        let input = req.input.clone();
        let prefix = input.prefix.clone().unwrap_or_default();
        let objects = self.all_objects(req, input.bucket.clone(), &prefix).await?;
        let max_keys = max_keys(input.max_keys);
        let page = page(
            objects,
            &prefix,
            input.delimiter.as_deref(),
            input.marker.as_deref(),
            max_keys,
        );
        Ok(S3Response::new(ListObjectsOutput {
            name: Some(input.bucket),
            prefix: input.prefix,
            marker: input.marker,
            max_keys: Some(i32::try_from(max_keys).unwrap_or(i32::MAX)),
            is_truncated: Some(page.next.is_some()),
            next_marker: page.next,
            contents: (!page.objects.is_empty()).then_some(page.objects),
            common_prefixes: common_prefix_list(page.common_prefixes),
            delimiter: input.delimiter,
            encoding_type: input.encoding_type,
            ..Default::default()
        }))
    }
}

/// Put bodies up to this size are gathered in memory before `s3s-fs` writes them (see
/// [`gather_body`]), and get bodies up to it are read in one piece ([`whole_body`]); larger ones
/// stream, so the server never holds a huge object at once.
const GATHERED_BODY_MAX: i64 = 64 << 20;

/// Gathers a put's body of known length up to [`GATHERED_BODY_MAX`] into one chunk, so that
/// `s3s-fs` writes it in a few large writes (2 MiB per hop through tokio's blocking pool)
/// instead of one write per network chunk. Same bytes, same checks afterwards; a body that
/// breaks off fails the put as it would have inside `s3s-fs`.
async fn gather_body(input: &mut PutObjectInput) -> S3Result<()> {
    use futures_util::StreamExt;
    let Some(length) = input
        .content_length
        .filter(|l| (0..=GATHERED_BODY_MAX).contains(l))
    else {
        return Ok(());
    };
    let Some(mut body) = input.body.take() else {
        return Ok(());
    };
    let mut bytes = Vec::with_capacity(length as usize);
    while let Some(chunk) = body.next().await {
        let chunk = chunk.map_err(|e| s3_error!(IncompleteBody, "the body broke off: {e}"))?;
        bytes.extend_from_slice(&chunk);
    }
    input.body = Some(s3s::Body::from(bytes).into());
    Ok(())
}

/// Replaces the body `s3s-fs` streams (4 KiB reads, each a hop through tokio's blocking pool:
/// ~50 MB/s for a 20 MB split object on a busy machine) by one read of the same byte range of
/// `path`, sent as one chunk, for bodies up to [`GATHERED_BODY_MAX`]. The headers (length, range, ETag, checksums) stay `s3s-fs`'s. If a
/// put replaced the file in between and its length no longer covers the range, the answer is a
/// retryable `InternalError`; a replacement of the same length is served whole (outputs of a
/// job's tasks are rewritten only with the same bytes).
async fn whole_body(output: &mut GetObjectOutput, path: PathBuf) -> S3Result<()> {
    let length = output
        .content_length
        .and_then(|l| u64::try_from(l).ok())
        .ok_or_else(|| s3_error!(InternalError, "get without a content length"))?;
    if length > GATHERED_BODY_MAX as u64 {
        // Streamed as `s3s-fs` does: the server never holds a huge object at once.
        return Ok(());
    }
    let start = match output.content_range.as_deref() {
        None => 0,
        Some(range) => range_start(range)
            .ok_or_else(|| s3_error!(InternalError, "unreadable content range {range}"))?,
    };
    let read = tokio::task::spawn_blocking(move || read_range(&path, start, length));
    let bytes = read
        .await
        .map_err(|e| s3_error!(InternalError, "reading the object failed: {e}"))?
        .map_err(|e| s3_error!(InternalError, "the object changed while it was read: {e}"))?;
    output.body = Some(s3s::Body::from(bytes).into());
    Ok(())
}

/// The first byte of a `Content-Range` value `bytes FIRST-LAST/LENGTH`.
fn range_start(content_range: &str) -> Option<u64> {
    let (first, _) = content_range.strip_prefix("bytes ")?.split_once('-')?;
    first.parse().ok()
}

/// `length` bytes of the file at `path` from `start` on.
fn read_range(path: &std::path::Path, start: u64, length: u64) -> std::io::Result<Vec<u8>> {
    use std::io::{Read, Seek, SeekFrom};
    let mut file = std::fs::File::open(path)?;
    file.seek(SeekFrom::Start(start))?;
    let mut bytes = vec![0; usize::try_from(length).map_err(std::io::Error::other)?];
    file.read_exact(&mut bytes)?;
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn objects(keys: &[&str]) -> Vec<Object> {
        keys.iter()
            .map(|k| Object {
                key: Some((*k).to_owned()),
                ..Default::default()
            })
            .collect()
    }

    fn keys(page: &Page) -> Vec<&str> {
        page.objects
            .iter()
            .filter_map(|o| o.key.as_deref())
            .collect()
    }

    #[test]
    fn file_names_round_trip_and_never_collide_with_directories() {
        for key in ["a", "a/b", "~", "a~", "x~obj", "x~obj/y", "~~obj", ""] {
            let name = file_of_key(key);
            assert_eq!(key_of_file(&name).as_deref(), Some(key), "{name}");
        }
        // A directory component (escaped, without suffix) is never an object file name.
        for dir in ["x~~obj", "a", "~~", "obj"] {
            assert_eq!(key_of_file(dir), None, "{dir}");
        }
        assert_eq!(file_of_key("jobs/j/part-1"), "jobs/j/part-1~obj");
    }

    #[test]
    fn pages_resume_after_the_last_entry() {
        let all = ["p/a", "p/b", "p/c", "p/d", "p/e"];
        let first = page(objects(&all), "p/", None, None, 2);
        assert_eq!(keys(&first), ["p/a", "p/b"]);
        assert_eq!(first.next.as_deref(), Some("p/b"));
        let second = page(objects(&all), "p/", None, first.next.as_deref(), 2);
        assert_eq!(keys(&second), ["p/c", "p/d"]);
        let last = page(objects(&all), "p/", None, second.next.as_deref(), 2);
        assert_eq!(keys(&last), ["p/e"]);
        assert_eq!(last.next, None);
    }

    #[test]
    fn delimiter_rolls_up_common_prefixes_in_key_order() {
        let all = ["a", "a/b", "a/c/d", "b/x", "c"];
        let page = page(objects(&all), "", Some("/"), None, 1000);
        assert_eq!(keys(&page), ["a", "c"]);
        assert_eq!(page.common_prefixes, ["a/", "b/"]);
        assert_eq!(page.next, None);
    }

    #[test]
    fn a_page_ending_on_a_common_prefix_resumes_after_it() {
        let all = ["a/1", "a/2", "b"];
        let first = page(objects(&all), "", Some("/"), None, 1);
        assert_eq!(first.common_prefixes, ["a/"]);
        assert_eq!(first.next.as_deref(), Some("a/"));
        let second = page(objects(&all), "", Some("/"), first.next.as_deref(), 1);
        assert_eq!(keys(&second), ["b"]);
        assert!(second.common_prefixes.is_empty());
        assert_eq!(second.next, None);
    }
}
