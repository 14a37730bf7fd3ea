//! The one place where AWS SDK errors become [`StoreError`]s with one-line messages.
//!
//! Classes: a missing object is `NotFound`; an unreachable endpoint, a timeout, a 5xx answer,
//! throttling or an answer that breaks off is `Unavailable` (retryable); refused credentials or a refused permission is
//! `Denied` (not retryable); a missing bucket, missing credentials and anything else is `Other`
//! (not retryable either: "access denied" would send users looking for a permission problem
//! they do not have). Messages start with the
//! operation (`get "jobs/a/part-0"`), then say what went wrong in words, naming the bucket and
//! the endpoint; they never contain SDK debug text or line breaks.

use std::error::Error;
use std::time::Duration;

use aws_sdk_s3::config::http::HttpResponse;
use aws_sdk_s3::error::{ProvideErrorMetadata, SdkError};
use aws_sdk_s3::operation::put_object::PutObjectError;
use hort_core::store::StoreError;

/// Error codes meaning the credentials themselves were refused.
const CREDENTIAL_CODES: &[&str] = &[
    "InvalidAccessKeyId",
    "SignatureDoesNotMatch",
    "NotSignedUp",
    "InvalidToken",
    "ExpiredToken",
    "InvalidSecurity",
];

/// Error codes meaning "slow down or try again later", whatever the status.
const RETRYABLE_CODES: &[&str] = &[
    "SlowDown",
    "Throttling",
    "ThrottlingException",
    "ThrottledException",
    "RequestThrottled",
    "RequestLimitExceeded",
    "TooManyRequests",
    "RequestTimeout",
    "InternalError",
    "ServiceUnavailable",
    "ConditionalRequestConflict",
];

/// The bucket and endpoint a store talks to, as named in error messages.
#[derive(Debug, Clone)]
pub(crate) struct Target {
    /// The bucket name.
    pub(crate) bucket: String,
    /// The endpoint URL, or `AWS S3 (REGION)` when talking to AWS itself.
    pub(crate) endpoint: String,
    /// The configured connect timeout.
    pub(crate) connect_timeout: Duration,
    /// The configured per-attempt timeout.
    pub(crate) attempt_timeout: Duration,
}

/// What a failed request was doing: the operation and, for object requests, the key.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Request<'a> {
    /// Short verb phrase: `get`, `put`, `list`, `check bucket`, ...
    pub(crate) op: &'a str,
    /// The object key or list prefix, if the request has one.
    pub(crate) key: Option<&'a str>,
    /// True if a 404 means "no such object" (object reads), not "no such bucket".
    pub(crate) object_read: bool,
}

impl Request<'_> {
    fn label(&self) -> String {
        match self.key {
            Some(key) => format!("{} {key:?}", self.op),
            None => self.op.to_owned(),
        }
    }
}

/// The HTTP status of the answer, if the server answered at all.
pub(crate) fn status_of<E>(err: &SdkError<E, HttpResponse>) -> Option<u16> {
    err.raw_response().map(|r| r.status().as_u16())
}

/// True if the error is the server's answer "precondition failed" (HTTP 412).
pub(crate) fn is_precondition_failed(err: &SdkError<PutObjectError, HttpResponse>) -> bool {
    status_of(err) == Some(412) || err.code() == Some("PreconditionFailed")
}

/// True if the error is AWS S3's "a concurrent conditional write is in progress" (HTTP 409).
pub(crate) fn is_conditional_conflict(err: &SdkError<PutObjectError, HttpResponse>) -> bool {
    err.code() == Some("ConditionalRequestConflict")
}

/// True if the error is HTTP 416 or `InvalidRange`: the range starts past the end.
pub(crate) fn is_invalid_range<E: ProvideErrorMetadata>(err: &SdkError<E, HttpResponse>) -> bool {
    status_of(err) == Some(416) || err.code() == Some("InvalidRange")
}

/// True if the error is a service answer without an error code (the answer to a HEAD request
/// has no body), so a GET would tell more.
pub(crate) fn lacks_code<E: ProvideErrorMetadata>(err: &SdkError<E, HttpResponse>) -> bool {
    matches!(err, SdkError::ServiceError(_))
        && err
            .code()
            .is_none_or(|c| c == "Forbidden" || c == "BadRequest")
}

/// Classifies `err`, the failure of `request` against `target`.
pub(crate) fn store_error<E>(
    err: SdkError<E, HttpResponse>,
    request: Request<'_>,
    target: &Target,
) -> StoreError
where
    E: ProvideErrorMetadata + Error + Send + Sync + 'static,
{
    let op = request.label();
    let ep = &target.endpoint;
    let bucket = &target.bucket;
    match &err {
        SdkError::DispatchFailure(failure) => {
            let reason = if failure.is_timeout() {
                format!("connect timed out after {:?}", target.connect_timeout)
            } else {
                connection_reason(&err)
            };
            if failure.is_io() || failure.is_timeout() {
                StoreError::Unavailable {
                    what: format!("{op}: S3 endpoint {ep} is unreachable ({reason})"),
                }
            } else {
                StoreError::Other {
                    what: format!("{op}: cannot talk to S3 endpoint {ep} ({reason})"),
                }
            }
        }
        SdkError::TimeoutError(_) => StoreError::Unavailable {
            what: format!(
                "{op}: S3 endpoint {ep} did not answer within {:?}",
                target.attempt_timeout
            ),
        },
        SdkError::ConstructionFailure(_) => StoreError::Other {
            what: format!(
                "{op}: the S3 request could not be prepared ({})",
                innermost(&err)
            ),
        },
        // The answer's body broke off or did not parse. The SDK counts this as transient (it
        // retried already), and a connection cut in the middle of a listing looks exactly so.
        SdkError::ResponseError(_) => StoreError::Unavailable {
            what: format!(
                "{op}: S3 endpoint {ep} sent an unreadable answer (HTTP {}: {})",
                status_of(&err).unwrap_or(0),
                innermost(&err)
            ),
        },
        _ => service_error(&err, request, &op, ep, bucket),
    }
}

/// Classifies an answer the server gave with an error status.
fn service_error<E>(
    err: &SdkError<E, HttpResponse>,
    request: Request<'_>,
    op: &str,
    ep: &str,
    bucket: &str,
) -> StoreError
where
    E: ProvideErrorMetadata,
{
    let status = status_of(err).unwrap_or(0);
    let code = err.code().unwrap_or("");
    let code_or_status = if code.is_empty() {
        format!("HTTP {status}")
    } else {
        code.to_owned()
    };
    if is_missing_bucket(err, request) {
        return StoreError::Other {
            what: missing_bucket(op, bucket, ep),
        };
    }
    if (status == 404 || code == "NoSuchKey")
        && request.object_read
        && let Some(key) = request.key
    {
        return StoreError::NotFound {
            key: key.to_owned(),
        };
    }
    if CREDENTIAL_CODES.contains(&code) {
        return StoreError::Denied {
            what: format!(
                "{op}: S3 rejected the credentials ({code}) for bucket {bucket:?} at {ep}"
            ),
        };
    }
    if code == "AccessDenied" || code == "AllAccessDisabled" || status == 403 {
        return StoreError::Denied {
            what: format!("{op}: S3 denied access ({code_or_status}) to bucket {bucket:?} at {ep}"),
        };
    }
    if code == "PermanentRedirect" || code == "AuthorizationHeaderMalformed" || status == 301 {
        // S3 names the bucket's region in a header of the answer (HEAD answers have no body).
        let region = err
            .raw_response()
            .and_then(|r| r.headers().get("x-amz-bucket-region"))
            .map(|r| format!("; it is in {r}"))
            .unwrap_or_default();
        return StoreError::Denied {
            what: format!(
                "{op}: bucket {bucket:?} is not in the configured region at {ep} \
                 ({code_or_status}{region})"
            ),
        };
    }
    let message = err.message().map(one_line).unwrap_or_default();
    let detail = if message.is_empty() {
        format!("HTTP {status} {code}")
    } else {
        format!("HTTP {status} {code}: {message}")
    };
    let detail = detail.trim_end();
    if status >= 500 || status == 429 || RETRYABLE_CODES.contains(&code) {
        StoreError::Unavailable {
            what: format!("{op}: S3 endpoint {ep} failed ({detail})"),
        }
    } else {
        StoreError::Other {
            what: format!("{op}: S3 endpoint {ep} refused the request ({detail})"),
        }
    }
}

/// True if the answer means "no such bucket": the code `NoSuchBucket`, or a 404 to a request
/// that is not an object read (HEAD answers carry no code).
pub(crate) fn is_missing_bucket<E: ProvideErrorMetadata>(
    err: &SdkError<E, HttpResponse>,
    request: Request<'_>,
) -> bool {
    matches!(err, SdkError::ServiceError(_))
        && (err.code() == Some("NoSuchBucket")
            || (status_of(err) == Some(404) && !request.object_read))
}

/// The message of a missing bucket.
pub(crate) fn missing_bucket(op: &str, bucket: &str, ep: &str) -> String {
    format!("{op}: bucket {bucket:?} does not exist at {ep}")
}

/// The message of a credential chain that found nothing usable; `detail` is what the last
/// source said when it failed for another reason than having nothing to offer.
pub(crate) fn no_credentials(op: &str, target: &Target, detail: Option<&str>) -> String {
    let detail = detail.map(|d| format!(" ({d})")).unwrap_or_default();
    format!(
        "{op}: no AWS credentials found for bucket {:?} at {}{detail}: set AWS_ACCESS_KEY_ID \
         and AWS_SECRET_ACCESS_KEY (or configure an AWS profile)",
        target.bucket, target.endpoint
    )
}

/// Why loading credentials failed, for [`no_credentials`]: `None` when the chain simply found
/// none (the SDK's `CredentialsNotLoaded`), else the innermost cause on one line.
pub(crate) fn credentials_detail(err: &(dyn Error + 'static)) -> Option<String> {
    // `CredentialsNotLoaded` is the one variant whose message is exactly this.
    (err.to_string() != "the credential provider was not enabled").then(|| innermost(err))
}

/// Why a connection failed, in words: `connection refused`, `DNS lookup failed: ...`, or the
/// innermost error's message.
fn connection_reason(err: &(dyn Error + 'static)) -> String {
    let mut dns = false;
    let mut current: Option<&(dyn Error + 'static)> = Some(err);
    while let Some(e) = current {
        if e.to_string().starts_with("dns error") {
            dns = true;
        }
        if let Some(io) = e.downcast_ref::<std::io::Error>() {
            use std::io::ErrorKind;
            let named = match io.kind() {
                ErrorKind::ConnectionRefused => Some("connection refused"),
                ErrorKind::ConnectionReset => Some("connection reset"),
                ErrorKind::ConnectionAborted => Some("connection aborted"),
                ErrorKind::TimedOut => Some("connection timed out"),
                ErrorKind::HostUnreachable => Some("host unreachable"),
                ErrorKind::NetworkUnreachable => Some("network unreachable"),
                ErrorKind::AddrNotAvailable => Some("address not available"),
                _ => None,
            };
            if let Some(named) = named.filter(|_| !dns) {
                return named.to_owned();
            }
        }
        current = e.source();
    }
    let inner = innermost(err);
    if dns {
        format!("DNS lookup failed: {inner}")
    } else {
        inner
    }
}

/// The message of the last error in the source chain, on one line, without `(os error N)`.
/// Shared by the SQS and Step Functions error classification (`aws::error`).
pub(crate) fn innermost(err: &(dyn Error + 'static)) -> String {
    let mut last = err;
    while let Some(next) = last.source() {
        last = next;
    }
    let text = one_line(&last.to_string());
    match text.rfind(" (os error ") {
        Some(at) if text.ends_with(')') => text[..at].to_owned(),
        _ => text,
    }
}

/// `text` with every run of whitespace (line breaks included) collapsed to one space.
pub(crate) fn one_line(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_line_collapses_breaks() {
        assert_eq!(one_line(" a\n  b\r\nc "), "a b c");
    }

    #[test]
    fn innermost_drops_the_os_error_number() {
        let io = std::io::Error::from_raw_os_error(111);
        let text = innermost(&io);
        assert!(!text.contains("os error"), "{text}");
        assert!(!text.is_empty());
    }

    #[test]
    fn connection_refused_is_named() {
        let io = std::io::Error::from(std::io::ErrorKind::ConnectionRefused);
        assert_eq!(connection_reason(&io), "connection refused");
    }
}
