//! The API's errors: an HTTP status, a stable code, a one-line message and, where one field is
//! at fault, its JSON path. Every error response is `{"error": {"code", "message", "field"?}}`.

use hort_core::error::printable;
use http::{Response, StatusCode, header};
use serde::Serialize;

/// One failed request. [`ApiError::into_response`] renders it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ApiError {
    /// The HTTP status.
    pub status: StatusCode,
    /// A stable machine-readable code (`invalid_request`, `not_found`, ...).
    pub code: &'static str,
    /// One line for a person: what is wrong, naming the field, file and line where known.
    pub message: String,
    /// The JSON path of the bad field (`scene.files`, `width`), when one field is at fault.
    pub field: Option<String>,
    /// For 405: the methods the route allows (the `Allow` header).
    pub allow: Option<&'static str>,
}

/// The JSON body of an error response.
#[derive(Serialize)]
struct ErrorBody<'a> {
    error: ErrorFields<'a>,
}

#[derive(Serialize)]
struct ErrorFields<'a> {
    code: &'a str,
    message: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    field: Option<&'a str>,
}

impl ApiError {
    /// Control characters in `message` (a file name or key from the request) are escaped, so
    /// it stays one line.
    fn new(status: StatusCode, code: &'static str, message: impl Into<String>) -> Self {
        ApiError {
            status,
            code,
            message: printable(&message.into()),
            field: None,
            allow: None,
        }
    }

    /// 400 `invalid_json`: the body is not one JSON value.
    pub fn invalid_json(message: impl Into<String>) -> Self {
        Self::new(StatusCode::BAD_REQUEST, "invalid_json", message)
    }

    /// 400 `invalid_request`: a field is missing, unknown, of the wrong type or out of range.
    pub fn invalid_field(field: impl Into<String>, message: impl Into<String>) -> Self {
        let mut e = Self::new(StatusCode::BAD_REQUEST, "invalid_request", message);
        e.field = Some(printable(&field.into()));
        e
    }

    /// 400 `invalid_scene`: the scene does not load; the message names the file and line.
    pub fn invalid_scene(message: impl Into<String>) -> Self {
        let mut e = Self::new(StatusCode::BAD_REQUEST, "invalid_scene", message);
        e.field = Some("scene".into());
        e
    }

    /// 404 `not_found`.
    pub fn not_found(message: impl Into<String>) -> Self {
        Self::new(StatusCode::NOT_FOUND, "not_found", message)
    }

    /// 405 `method_not_allowed`, with the methods the route allows.
    pub fn method_not_allowed(message: impl Into<String>, allow: &'static str) -> Self {
        let mut e = Self::new(
            StatusCode::METHOD_NOT_ALLOWED,
            "method_not_allowed",
            message,
        );
        e.allow = Some(allow);
        e
    }

    /// 413 `payload_too_large`.
    pub fn too_large(message: impl Into<String>) -> Self {
        Self::new(StatusCode::PAYLOAD_TOO_LARGE, "payload_too_large", message)
    }

    /// 415 `unsupported_media_type`.
    pub fn unsupported_media_type(message: impl Into<String>) -> Self {
        Self::new(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "unsupported_media_type",
            message,
        )
    }

    /// 422 `over_budget`: the predicted cost exceeds `max_cost_usd`.
    pub fn over_budget(message: impl Into<String>) -> Self {
        let mut e = Self::new(StatusCode::UNPROCESSABLE_ENTITY, "over_budget", message);
        e.field = Some("max_cost_usd".into());
        e
    }

    /// 422 `over_deployment`: the request asks for more than the deployed functions have
    /// (`field` names what: e.g. `memory_mb` over the Worker's memory).
    pub fn over_deployment(field: impl Into<String>, message: impl Into<String>) -> Self {
        let mut e = Self::new(StatusCode::UNPROCESSABLE_ENTITY, "over_deployment", message);
        e.field = Some(field.into());
        e
    }

    /// 422 `idempotency_key_reused`: the `Idempotency-Key` named a job started by a request with
    /// another body (the IETF Idempotency-Key draft: the server must not treat it as a retry).
    pub fn idempotency_key_reused(message: impl Into<String>) -> Self {
        let mut e = Self::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "idempotency_key_reused",
            message,
        );
        e.field = Some("headers.Idempotency-Key".into());
        e
    }

    /// 429 `too_many_jobs`: the backend runs as many jobs as it takes; submit again once one
    /// ended.
    pub fn too_many_jobs(message: impl Into<String>) -> Self {
        Self::new(StatusCode::TOO_MANY_REQUESTS, "too_many_jobs", message)
    }

    /// 500 `internal`: the backend failed (storage, a thread); the request may be retried.
    pub fn internal(message: impl Into<String>) -> Self {
        Self::new(StatusCode::INTERNAL_SERVER_ERROR, "internal", message)
    }

    /// The JSON error response.
    pub fn into_response(self) -> Response<Vec<u8>> {
        let body = ErrorBody {
            error: ErrorFields {
                code: self.code,
                message: &self.message,
                field: self.field.as_deref(),
            },
        };
        let mut bytes = serde_json::to_vec(&body).unwrap_or_default();
        bytes.push(b'\n');
        let mut builder = Response::builder()
            .status(self.status)
            .header(header::CONTENT_TYPE, "application/json");
        if let Some(allow) = self.allow {
            builder = builder.header(header::ALLOW, allow);
        }
        builder.body(bytes).unwrap_or_else(|_| {
            let mut r = Response::new(Vec::new());
            *r.status_mut() = StatusCode::INTERNAL_SERVER_ERROR;
            r
        })
    }
}

impl std::fmt::Display for ApiError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} {}: {}",
            self.status.as_u16(),
            self.code,
            self.message
        )
    }
}

impl std::error::Error for ApiError {}

#[cfg(test)]
mod tests {
    use super::*;

    /// Found by fuzzing (fuzz/, target `http`): a file name or key with a newline, echoed in
    /// a message, made it two lines. Every message and field is escaped.
    #[test]
    fn names_from_the_request_stay_on_one_line() {
        let e = ApiError::invalid_field("scene.files.a\nb", "file \"a\nb\" is not relative");
        assert_eq!(e.field.as_deref(), Some("scene.files.a\\nb"));
        assert_eq!(e.message, "file \"a\\nb\" is not relative");
        let e = ApiError::invalid_scene("s.obj\r:1: bad");
        assert_eq!(e.message, "s.obj\\r:1: bad");
    }
}
