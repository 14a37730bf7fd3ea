//! AWS services besides S3, as small typed wrappers, and the glue of the Lambda entry points
//! (`src/bin/`):
//!
//! - [`sqs`]: the job intake queue ([`JobQueue`]): enqueue a job, receive and delete messages.
//! - [`sfn`]: executions of the HORT state machine ([`Executions`]): start one named by its job
//!   id (idempotent), describe it, stop it.
//! - [`starter`]: the Starter function's logic: an SQS batch of job messages becomes executions,
//!   with partial batch failures.
//! - [`api_backend`]: the HTTP API's backend in a deployment ([`api_backend::AwsBackend`]):
//!   jobs stored in the bucket and sent to the intake queue, status from their executions.
//! - [`invoke`]: invoking a function through the Lambda Invoke API ([`LambdaFunctions`]), as
//!   Step Functions does (`hort render --lambda-endpoint`).
//! - [`lambda`]: what the Plan and Worker entry points share: settings from the environment,
//!   clients built once per container, the handlers run on blocking threads, failures as Lambda
//!   errors typed `Hort.Retryable` or `Hort.BadInput`.
//!
//! Every request failure is an [`AwsError`], classified in one place ([`error`]). The SDK crates
//! are re-exported ([`aws_sdk_sqs`], [`aws_sdk_sfn`]) for what the wrappers do not cover (tests
//! create queues and state machines with them).

pub mod api_backend;
pub mod error;
pub mod invoke;
pub mod lambda;
pub mod sfn;
pub mod sqs;
pub mod starter;

pub use aws_config::SdkConfig;
pub use aws_lambda_events;
pub use aws_sdk_sfn;
pub use aws_sdk_sqs;
pub use error::{AwsError, AwsErrorKind};
pub use invoke::{InvokeFailure, LambdaFunctions};
pub use sfn::{Execution, ExecutionInput, ExecutionStatus, Executions, Started};
pub use sqs::{JobQueue, ReceivedMessage};

use aws_config::BehaviorVersion;
use aws_config::retry::RetryConfig;
use aws_config::timeout::TimeoutConfig;
use aws_sdk_s3::config::{Credentials, Region};

use crate::S3Credentials;
use crate::s3_config::{DEFAULT_ATTEMPT_TIMEOUT, DEFAULT_CONNECT_TIMEOUT, DEFAULT_MAX_ATTEMPTS};

/// Where the SQS and Step Functions clients send their requests.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AwsSettings {
    /// `None`: AWS itself. Otherwise the URL of a server speaking the AWS APIs (moto), such as
    /// `http://127.0.0.1:5000`.
    pub endpoint: Option<String>,
    /// The signing region; `None` takes it from the SDK's default chain (`AWS_REGION`, as set
    /// on Lambda), else `us-east-1`.
    pub region: Option<String>,
    /// Where the credentials come from (on Lambda: [`S3Credentials::DefaultChain`], the
    /// function's role).
    pub credentials: S3Credentials,
}

impl AwsSettings {
    /// AWS itself, with the default region and credential chains.
    pub fn aws() -> Self {
        AwsSettings {
            endpoint: None,
            region: None,
            credentials: S3Credentials::DefaultChain,
        }
    }

    /// The shared SDK configuration (standard retries, 3 attempts; 3 s to connect, 30 s per
    /// attempt). Build it once per process and make every client from it.
    pub async fn sdk_config(&self) -> SdkConfig {
        let timeouts = TimeoutConfig::builder()
            .connect_timeout(DEFAULT_CONNECT_TIMEOUT)
            .operation_attempt_timeout(DEFAULT_ATTEMPT_TIMEOUT)
            .build();
        let mut loader = aws_config::defaults(BehaviorVersion::latest())
            .timeout_config(timeouts)
            .retry_config(RetryConfig::standard().with_max_attempts(DEFAULT_MAX_ATTEMPTS));
        if let Some(region) = &self.region {
            loader = loader.region(Region::new(region.clone()));
        }
        if let S3Credentials::Static {
            access_key,
            secret_key,
        } = &self.credentials
        {
            loader = loader.credentials_provider(Credentials::new(
                access_key,
                secret_key,
                None,
                None,
                "hort-static",
            ));
        }
        if let Some(endpoint) = &self.endpoint {
            loader = loader.endpoint_url(endpoint.trim_end_matches('/'));
        }
        let config = loader.load().await;
        if config.region().is_some() {
            config
        } else {
            config
                .into_builder()
                .region(Region::new(crate::s3_config::DEFAULT_REGION))
                .build()
        }
    }

    /// How error messages name the endpoint: its URL, or `AWS (REGION)`.
    pub fn label(config: &SdkConfig) -> String {
        match config.endpoint_url() {
            Some(url) => url.to_owned(),
            None => format!(
                "AWS ({})",
                config.region().map_or("no region", |r| r.as_ref())
            ),
        }
    }
}
