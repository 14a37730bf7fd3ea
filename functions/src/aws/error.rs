//! The one place where SQS and Step Functions SDK errors become [`AwsError`]s with one-line
//! messages, classified as `s3_errors` classifies S3's: an unreachable endpoint, a timeout, a 5xx
//! answer or throttling is [`AwsErrorKind::Unavailable`] (the only retryable kind); refused
//! credentials or permissions are [`AwsErrorKind::Denied`]; a queue, state machine or execution
//! that does not exist is [`AwsErrorKind::NotFound`]; an execution name already taken is
//! [`AwsErrorKind::AlreadyExists`]; a request the service calls malformed is
//! [`AwsErrorKind::Invalid`]; anything else is [`AwsErrorKind::Other`]. Messages start with the
//! operation, name the service and endpoint, and never hold SDK debug text or line breaks.

use std::error::Error;

use crate::s3_errors::{innermost, one_line};
use aws_sdk_sqs::config::http::HttpResponse;
use aws_sdk_sqs::error::{ProvideErrorMetadata, SdkError};
use hort_core::ErrorType;

/// What kind of failure an SQS or Step Functions request met.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AwsErrorKind {
    /// The endpoint is unreachable, timed out, failed (5xx) or throttled: a retry may succeed.
    Unavailable,
    /// The credentials or a permission were refused.
    Denied,
    /// The queue, state machine or execution does not exist.
    NotFound,
    /// An execution of that name exists already (`StartExecution`).
    AlreadyExists,
    /// The service refused the request as malformed (a name, ARN, input or attribute).
    Invalid,
    /// Anything else (missing credentials, an unreadable answer, an unknown error code).
    Other,
}

/// A failed SQS or Step Functions request. `Display` is the one-line message.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{what}")]
pub struct AwsError {
    /// The failure's class.
    pub kind: AwsErrorKind,
    /// One line: the operation, the service and endpoint, and what went wrong.
    pub what: String,
}

impl AwsError {
    /// True if the same request may succeed later ([`AwsErrorKind::Unavailable`]).
    pub fn is_retryable(&self) -> bool {
        self.kind == AwsErrorKind::Unavailable
    }

    /// The state machine's error type for this failure: [`ErrorType::Retryable`] for
    /// [`AwsErrorKind::Unavailable`], else [`ErrorType::BadInput`].
    pub fn error_type(&self) -> ErrorType {
        if self.is_retryable() {
            ErrorType::Retryable
        } else {
            ErrorType::BadInput
        }
    }
}

/// Codes of answers meaning "no such queue, state machine or execution".
const NOT_FOUND_CODES: &[&str] = &[
    "QueueDoesNotExist",
    "AWS.SimpleQueueService.NonExistentQueue",
    "StateMachineDoesNotExist",
    "ExecutionDoesNotExist",
    "ResourceNotFound",
];

/// Codes of answers meaning "the request itself is malformed".
const INVALID_CODES: &[&str] = &[
    "InvalidName",
    "InvalidArn",
    "InvalidExecutionInput",
    "InvalidDefinition",
    "InvalidParameterValue",
    "InvalidAttributeName",
    "InvalidAttributeValue",
    "InvalidMessageContents",
    "InvalidAddress",
    "MissingParameter",
    "ValidationException",
    "ValidationError",
];

/// Codes of answers refusing the credentials or a permission.
const DENIED_CODES: &[&str] = &[
    "AccessDenied",
    "AccessDeniedException",
    "UnrecognizedClientException",
    "InvalidClientTokenId",
    "InvalidSecurity",
    "SignatureDoesNotMatch",
    "IncompleteSignature",
    "MissingAuthenticationToken",
    "ExpiredToken",
    "ExpiredTokenException",
    "KMSAccessDeniedException",
];

/// Codes of answers meaning "slow down or try again later", whatever the status.
const RETRYABLE_CODES: &[&str] = &[
    "Throttling",
    "ThrottlingException",
    "RequestThrottled",
    "AWS.SimpleQueueService.RequestThrottled",
    "TooManyRequestsException",
    "ServiceUnavailable",
    "InternalFailure",
    "InternalError",
    "InternalServerError",
    "KMSThrottlingException",
    "ExecutionLimitExceeded",
];

/// Classifies `err`, the failure of operation `op` (for example `start execution "job-1"`)
/// against `service` (`SQS`, `Step Functions`) at `endpoint` (a URL, or `AWS (REGION)`).
pub(crate) fn classify<E>(
    err: SdkError<E, HttpResponse>,
    op: &str,
    service: &str,
    endpoint: &str,
) -> AwsError
where
    E: ProvideErrorMetadata + Error + Send + Sync + 'static,
{
    let at = format!("{service} at {endpoint}");
    let (kind, what) = match &err {
        SdkError::DispatchFailure(failure) if failure.is_io() || failure.is_timeout() => (
            AwsErrorKind::Unavailable,
            format!("{op}: {at} is unreachable ({})", innermost(&err)),
        ),
        SdkError::DispatchFailure(_) => (
            AwsErrorKind::Other,
            format!("{op}: cannot talk to {at} ({})", innermost(&err)),
        ),
        SdkError::TimeoutError(_) => (
            AwsErrorKind::Unavailable,
            format!("{op}: {at} did not answer in time"),
        ),
        SdkError::ConstructionFailure(_) => (
            AwsErrorKind::Other,
            format!(
                "{op}: the request could not be prepared ({})",
                innermost(&err)
            ),
        ),
        SdkError::ResponseError(_) => {
            let status = status_of(&err).unwrap_or(0);
            let kind = if status >= 500 {
                AwsErrorKind::Unavailable
            } else {
                AwsErrorKind::Other
            };
            (
                kind,
                format!("{op}: {at} sent an unreadable answer (HTTP {status})"),
            )
        }
        _ => service_error(&err, op, &at),
    };
    AwsError { kind, what }
}

/// Classifies an answer the service gave with an error status.
fn service_error<E: ProvideErrorMetadata>(
    err: &SdkError<E, HttpResponse>,
    op: &str,
    at: &str,
) -> (AwsErrorKind, String) {
    let status = status_of(err).unwrap_or(0);
    let code = err.code().unwrap_or("");
    let message = err.message().map(one_line).unwrap_or_default();
    let detail = match (code.is_empty(), message.is_empty()) {
        (true, true) => format!("HTTP {status}"),
        (true, false) => format!("HTTP {status}: {message}"),
        (false, true) => code.to_owned(),
        (false, false) => format!("{code}: {message}"),
    };
    let kind = if NOT_FOUND_CODES.contains(&code) {
        AwsErrorKind::NotFound
    } else if code == "ExecutionAlreadyExists" {
        AwsErrorKind::AlreadyExists
    } else if DENIED_CODES.contains(&code) || status == 403 {
        AwsErrorKind::Denied
    } else if RETRYABLE_CODES.contains(&code) || status >= 500 || status == 429 {
        AwsErrorKind::Unavailable
    } else if INVALID_CODES.contains(&code) {
        AwsErrorKind::Invalid
    } else {
        AwsErrorKind::Other
    };
    let what = match kind {
        AwsErrorKind::NotFound => format!("{op}: {at}: does not exist ({detail})"),
        AwsErrorKind::AlreadyExists => format!("{op}: {at}: already exists ({detail})"),
        AwsErrorKind::Denied => format!("{op}: {at} denied access ({detail})"),
        AwsErrorKind::Unavailable => format!("{op}: {at} failed ({detail})"),
        AwsErrorKind::Invalid | AwsErrorKind::Other => {
            format!("{op}: {at} refused the request ({detail})")
        }
    };
    (kind, what)
}

/// The HTTP status of the answer, if the service answered at all.
fn status_of<E>(err: &SdkError<E, HttpResponse>) -> Option<u16> {
    err.raw_response().map(|r| r.status().as_u16())
}

#[cfg(test)]
mod tests {
    use super::*;
    use aws_sdk_s3::primitives::SdkBody;
    use aws_sdk_sqs::config::http::HttpResponse;
    use aws_sdk_sqs::error::ErrorMetadata;
    use aws_sdk_sqs::operation::send_message::SendMessageError;

    /// A service answer with HTTP `status` and error `code`.
    fn answer(status: u16, code: &str) -> AwsError {
        let meta = ErrorMetadata::builder()
            .code(code)
            .message("line one\nline two")
            .build();
        let response = HttpResponse::new(status.try_into().unwrap(), SdkBody::empty());
        let err = SdkError::service_error(SendMessageError::generic(meta), response);
        classify(err, "enqueue job \"j\"", "SQS", "http://127.0.0.1:1")
    }

    #[test]
    fn codes_and_statuses_get_their_kinds() {
        let cases = [
            (400, "QueueDoesNotExist", AwsErrorKind::NotFound),
            (
                400,
                "AWS.SimpleQueueService.NonExistentQueue",
                AwsErrorKind::NotFound,
            ),
            (400, "ExecutionDoesNotExist", AwsErrorKind::NotFound),
            (400, "ExecutionAlreadyExists", AwsErrorKind::AlreadyExists),
            (400, "AccessDeniedException", AwsErrorKind::Denied),
            (403, "", AwsErrorKind::Denied),
            (400, "ThrottlingException", AwsErrorKind::Unavailable),
            (400, "ExecutionLimitExceeded", AwsErrorKind::Unavailable),
            (503, "", AwsErrorKind::Unavailable),
            (429, "", AwsErrorKind::Unavailable),
            (400, "InvalidName", AwsErrorKind::Invalid),
            (400, "SomethingNew", AwsErrorKind::Other),
        ];
        for (status, code, kind) in cases {
            let e = answer(status, code);
            assert_eq!(e.kind, kind, "{status} {code}: {e}");
            assert_eq!(e.is_retryable(), kind == AwsErrorKind::Unavailable);
            assert!(!e.what.contains('\n'), "{e}");
            assert!(
                e.what
                    .starts_with("enqueue job \"j\": SQS at http://127.0.0.1:1"),
                "{e}"
            );
        }
        let e = answer(400, "QueueDoesNotExist");
        assert_eq!(
            e.to_string(),
            "enqueue job \"j\": SQS at http://127.0.0.1:1: does not exist \
             (QueueDoesNotExist: line one line two)"
        );
        assert_eq!(e.error_type(), ErrorType::BadInput);
        assert_eq!(answer(500, "").error_type(), ErrorType::Retryable);
    }
}
