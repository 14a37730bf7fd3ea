//! Invoking a function through the Lambda Invoke API (synchronous, `RequestResponse`), as Step
//! Functions' `lambda:invoke` integration does: `hort render --lambda-endpoint` runs the Plan
//! and Worker functions this way, in AWS or under `cargo lambda watch`.
//!
//! Guarantees: an answer is either the function's JSON result or an [`InvokeFailure`] whose
//! `error` is what a state machine's `Retry` and `Catch` match:
//!
//! - a function error keeps the function's own type (`Hort.Retryable`, `Hort.BadInput`), and
//!   `Lambda.Unknown` when its answer carries none (a crash);
//! - a refused or failed request is `Lambda.<code>` as the service named it (for example
//!   `Lambda.TooManyRequestsException`, `Lambda.ResourceNotFoundException`), else
//!   `Lambda.SdkClientException` (unreachable, timed out) or `Lambda.AWSLambdaException`.
//!
//! Causes are one line naming the function and the endpoint.

use aws_sdk_lambda::primitives::Blob;
use aws_sdk_lambda::types::InvocationType;
use serde_json::Value;

use super::AwsSettings;
use super::error::{AwsErrorKind, classify};

/// Step Functions' name for a request that never got an answer.
pub const SDK_CLIENT_ERROR: &str = "Lambda.SdkClientException";
/// Step Functions' name for any other failed request.
pub const LAMBDA_ERROR: &str = "Lambda.AWSLambdaException";
/// Step Functions' name for a function error of no declared type (a crash).
pub const UNKNOWN_ERROR: &str = "Lambda.Unknown";

/// A failed invocation, as a state machine sees it.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{error}: {cause}")]
pub struct InvokeFailure {
    /// The error name `Retry` and `Catch` match.
    pub error: String,
    /// One line: what failed, naming the function.
    pub cause: String,
}

/// A Lambda client built once and shared by every invocation.
#[derive(Clone, Debug)]
pub struct LambdaFunctions {
    client: aws_sdk_lambda::Client,
    label: String,
}

impl LambdaFunctions {
    /// A client for `settings`: an endpoint such as `cargo lambda watch`'s, or AWS itself.
    pub async fn connect(settings: &AwsSettings) -> Self {
        let config = settings.sdk_config().await;
        LambdaFunctions {
            label: AwsSettings::label(&config),
            client: aws_sdk_lambda::Client::new(&config),
        }
    }

    /// How messages name where the functions run: the endpoint's URL or `AWS (REGION)`.
    pub fn label(&self) -> &str {
        &self.label
    }

    /// Invokes `function` (a name or ARN) with `event` and waits for its answer.
    pub async fn invoke(&self, function: &str, event: &Value) -> Result<Value, InvokeFailure> {
        let payload = serde_json::to_vec(event).map_err(|e| InvokeFailure {
            error: LAMBDA_ERROR.to_owned(),
            cause: format!("invoke {function}: cannot encode the event: {e}"),
        })?;
        let answer = self
            .client
            .invoke()
            .function_name(function)
            .invocation_type(InvocationType::RequestResponse)
            .payload(Blob::new(payload))
            .send()
            .await
            .map_err(|e| {
                // `cargo lambda watch` answers a function error with HTTP 500 and the error
                // document, where AWS answers 200 with `X-Amz-Function-Error`: the same failure.
                if let Some(failure) = e
                    .raw_response()
                    .and_then(|raw| raw.body().bytes())
                    .and_then(declared_function_error)
                {
                    return failure;
                }
                let op = format!("invoke {function}");
                let code = aws_sdk_lambda::error::ProvideErrorMetadata::code(&e).map(str::to_owned);
                let failure = classify(e, &op, "Lambda", &self.label);
                let error = match code {
                    Some(code) if !code.is_empty() => format!("Lambda.{code}"),
                    _ if failure.kind == AwsErrorKind::Unavailable => SDK_CLIENT_ERROR.to_owned(),
                    _ => LAMBDA_ERROR.to_owned(),
                };
                InvokeFailure {
                    error,
                    cause: failure.what,
                }
            })?;
        let body = answer.payload().map_or(&[][..], |b| b.as_ref());
        match answer.function_error() {
            Some(_) => Err(function_error(function, body)),
            None => serde_json::from_slice(body).map_err(|e| InvokeFailure {
                error: LAMBDA_ERROR.to_owned(),
                cause: format!("invoke {function}: the answer is not JSON: {e}"),
            }),
        }
    }
}

/// The failure a function reported: its `errorType` and `errorMessage`, or `Lambda.Unknown`
/// with whatever it answered.
fn function_error(function: &str, body: &[u8]) -> InvokeFailure {
    declared_function_error(body).unwrap_or_else(|| InvokeFailure {
        error: UNKNOWN_ERROR.to_owned(),
        cause: format!(
            "{function} failed without an error type: {}",
            crate::s3_errors::one_line(&String::from_utf8_lossy(body))
        ),
    })
}

/// The failure in a Lambda error document `{"errorType": ..., "errorMessage": ...}`, if `body`
/// is one.
fn declared_function_error(body: &[u8]) -> Option<InvokeFailure> {
    let answer: Value = serde_json::from_slice(body).ok()?;
    let text = |field: &str| answer.get(field).and_then(Value::as_str).map(str::to_owned);
    let error = text("errorType").filter(|e| !e.is_empty())?;
    Some(InvokeFailure {
        error,
        cause: text("errorMessage").unwrap_or_default(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_function_error_keeps_its_type_and_message() {
        let body = br#"{"errorType":"Hort.BadInput","errorMessage":"no such stage"}"#;
        assert_eq!(
            function_error("worker", body),
            InvokeFailure {
                error: "Hort.BadInput".into(),
                cause: "no such stage".into()
            }
        );
    }

    #[test]
    fn a_function_error_without_a_type_is_unknown() {
        assert_eq!(
            function_error("worker", b"Runtime exited\nwith signal 9"),
            InvokeFailure {
                error: "Lambda.Unknown".into(),
                cause: "worker failed without an error type: Runtime exited with signal 9".into()
            }
        );
    }
}
