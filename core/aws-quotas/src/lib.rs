//! The AWS quotas the product can meet, each one named constant with the AWS page it comes
//! from. The deployment (`infra/`) is designed within them and the local emulator enforces them
//! where AWS does, failing with the error name AWS gives. `docs/AWS-LIMITS.md` says, for each,
//! where the product meets it and which test goes over it.
//!
//! Sizes are bytes, times seconds. A quota a user can raise in their account (concurrency, for
//! instance) is not here: it comes from the deployment template.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

/// Step Functions: the largest input or output of a state, task or execution, and of a Map's
/// assembled results, as UTF-8 JSON text: 256 KiB.
/// <https://docs.aws.amazon.com/step-functions/latest/dg/service-quotas.html>
/// ("Maximum input or output size for a task, state, or execution").
pub const STATE_PAYLOAD_BYTES: usize = 256 * 1024;

/// Step Functions: the error of a payload over [`STATE_PAYLOAD_BYTES`]. `States.ALL` does not
/// catch it (<https://docs.aws.amazon.com/step-functions/latest/dg/concepts-error-handling.html>):
/// the execution fails at once, skipping every Catch.
pub const DATA_LIMIT_EXCEEDED: &str = "States.DataLimitExceeded";

/// Step Functions: the longest an Express execution (a Distributed Map's EXPRESS child) runs:
/// 5 minutes. <https://docs.aws.amazon.com/step-functions/latest/dg/service-quotas.html>
/// ("Maximum execution time", Express).
pub const EXPRESS_EXECUTION_SECONDS: u64 = 300;

/// Step Functions: the most child executions a Distributed Map runs at once.
/// <https://docs.aws.amazon.com/step-functions/latest/dg/concepts-asl-use-map-state-distributed.html>
pub const DISTRIBUTED_MAP_MAX_CONCURRENCY: u64 = 10_000;

/// Lambda: the largest synchronous invocation request and response, each: 6 MB (a binary HTTP
/// body counts after base64). <https://docs.aws.amazon.com/lambda/latest/dg/gettingstarted-limits.html>
/// ("Invocation payload (request and response)": 6 MB each for synchronous).
pub const LAMBDA_SYNC_PAYLOAD_BYTES: usize = 6 * 1024 * 1024;

/// Lambda: the error of a synchronous request over [`LAMBDA_SYNC_PAYLOAD_BYTES`] (HTTP 413).
/// <https://docs.aws.amazon.com/lambda/latest/api/API_Invoke.html>
pub const LAMBDA_REQUEST_TOO_LARGE: &str = "Lambda.RequestTooLargeException";

/// Lambda: the error of a function whose response is over [`LAMBDA_SYNC_PAYLOAD_BYTES`]
/// (the invocation fails; Step Functions sees it as a function error).
/// <https://docs.aws.amazon.com/lambda/latest/dg/gettingstarted-limits.html>
pub const LAMBDA_RESPONSE_TOO_LARGE: &str = "Function.ResponseSizeTooLarge";

/// Lambda: the error of an invocation over the function's reserved concurrency: it is
/// throttled, not queued. <https://docs.aws.amazon.com/lambda/latest/dg/lambda-concurrency.html>
pub const LAMBDA_THROTTLED: &str = "Lambda.TooManyRequestsException";

/// Lambda: the error of an invocation stopped at its function's own timeout (the runtime's
/// `errorType`; older runtimes leave it out and Step Functions reports `Lambda.Unknown`, which
/// HORT's definition retries alike).
/// <https://docs.aws.amazon.com/lambda/latest/dg/troubleshooting-invocation.html>,
/// <https://docs.aws.amazon.com/step-functions/latest/dg/bp-lambda-serviceexception.html>
pub const LAMBDA_TIMED_OUT: &str = "Sandbox.Timedout";

/// API Gateway: the answer to a client when the Lambda proxy integration fails (the function
/// timed out, crashed or was throttled): status 500 and this body.
/// <https://docs.aws.amazon.com/apigateway/latest/developerguide/http-api-troubleshooting-lambda.html>
pub const API_GATEWAY_INTERNAL_ERROR_BODY: &str = r#"{"message":"Internal Server Error"}"#;

/// Lambda: the longest a function may be configured to run: 900 s.
/// <https://docs.aws.amazon.com/lambda/latest/dg/gettingstarted-limits.html> ("Function timeout").
pub const LAMBDA_MAX_TIMEOUT_SECONDS: u64 = 900;

/// Lambda: the smallest and largest function memory, MB.
/// <https://docs.aws.amazon.com/lambda/latest/dg/gettingstarted-limits.html> ("Function memory
/// allocation").
pub const LAMBDA_MEMORY_MB: std::ops::RangeInclusive<u64> = 128..=10_240;

/// Lambda: `/tmp` unless the function raises its ephemeral storage, MB.
/// <https://docs.aws.amazon.com/lambda/latest/dg/configuration-ephemeral-storage.html>
pub const LAMBDA_DEFAULT_TMP_MB: u64 = 512;

/// API Gateway HTTP API: the longest an integration (our API function) may take to answer.
/// <https://docs.aws.amazon.com/apigateway/latest/developerguide/http-api-quotas.html>
/// ("Maximum integration timeout": 30 seconds).
pub const HTTP_API_INTEGRATION_SECONDS: u64 = 30;

/// API Gateway HTTP API: the largest request body: 10 MB.
/// <https://docs.aws.amazon.com/apigateway/latest/developerguide/http-api-quotas.html>
/// ("Payload size": 10 MB).
pub const HTTP_API_PAYLOAD_BYTES: usize = 10 * 1024 * 1024;

/// S3: the largest object one `CopyObject` request copies, 5 GiB (larger ones need a multipart
/// copy, `UploadPartCopy`). <https://docs.aws.amazon.com/AmazonS3/latest/API/API_CopyObject.html>
/// ("You can store individual objects of up to 5 TB in Amazon S3. You create a copy of your
/// object up to 5 GB in size in a single atomic action using this API").
pub const S3_COPY_OBJECT_MAX_BYTES: u64 = 5 * 1024 * 1024 * 1024;

/// S3: the most keys one `DeleteObjects` request removes.
/// <https://docs.aws.amazon.com/AmazonS3/latest/API/API_DeleteObjects.html>
pub const S3_DELETE_OBJECTS_MAX_KEYS: usize = 1000;

/// The size of a binary body of `raw` bytes once base64-encoded, as `lambda_http` sends it in a
/// Lambda response (4 characters per 3 bytes, padded).
pub const fn base64_len(raw: usize) -> usize {
    raw.div_ceil(3) * 4
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_counts_padding() {
        assert_eq!(base64_len(0), 0);
        assert_eq!(base64_len(1), 4);
        assert_eq!(base64_len(3), 4);
        assert_eq!(base64_len(4), 8);
        // The largest raw binary body a synchronous Lambda response can carry.
        let raw = LAMBDA_SYNC_PAYLOAD_BYTES / 4 * 3;
        assert!(base64_len(raw) <= LAMBDA_SYNC_PAYLOAD_BYTES);
        assert!(base64_len(raw + 3) > LAMBDA_SYNC_PAYLOAD_BYTES);
    }

    #[test]
    fn the_quotas_are_the_documented_numbers() {
        assert_eq!(STATE_PAYLOAD_BYTES, 262_144);
        assert_eq!(LAMBDA_SYNC_PAYLOAD_BYTES, 6_291_456);
        assert_eq!(HTTP_API_PAYLOAD_BYTES, 10_485_760);
    }
}
