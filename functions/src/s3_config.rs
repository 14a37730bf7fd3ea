//! Where and how [`crate::S3Store`] reaches S3: endpoint, bucket, region, credentials, timeouts.

use std::fmt;
use std::time::Duration;

use aws_config::BehaviorVersion;
use aws_config::retry::RetryConfig;
use aws_config::timeout::TimeoutConfig;
use aws_sdk_s3::Client;
use aws_sdk_s3::config::{
    Credentials, Region, RequestChecksumCalculation, ResponseChecksumValidation,
    SharedCredentialsProvider,
};
use hort_core::store::StoreError;

/// Default time to open a TCP (and TLS) connection.
pub const DEFAULT_CONNECT_TIMEOUT: Duration = Duration::from_secs(3);
/// Default time for one attempt of one request, body transfer included.
pub const DEFAULT_ATTEMPT_TIMEOUT: Duration = Duration::from_secs(30);
/// Default number of attempts per request (the first try plus retries), SDK standard mode.
pub const DEFAULT_MAX_ATTEMPTS: u32 = 3;
/// Default wait before the first retry of a request (the SDK's standard mode: each retry waits
/// a random fraction of this times 2^retry, at most 20 s).
pub const DEFAULT_INITIAL_BACKOFF: Duration = Duration::from_secs(1);
/// The region used when none is configured and the SDK's default chain finds none.
pub const DEFAULT_REGION: &str = "us-east-1";

/// Where credentials come from.
#[derive(Clone, PartialEq, Eq)]
pub enum S3Credentials {
    /// A fixed access key pair (local servers, tests).
    Static {
        /// The access key id.
        access_key: String,
        /// The secret access key; never printed by `Debug`.
        secret_key: String,
    },
    /// The AWS SDK's default chain: environment variables (`AWS_ACCESS_KEY_ID`, ... as set on
    /// Lambda), shared config and credentials files, `credential_process`, web identity, ECS and
    /// EC2 instance metadata. Resolved lazily and refreshed by the SDK.
    DefaultChain,
}

impl fmt::Debug for S3Credentials {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            S3Credentials::Static { access_key, .. } => f
                .debug_struct("Static")
                .field("access_key", access_key)
                .field("secret_key", &"<redacted>")
                .finish(),
            S3Credentials::DefaultChain => f.write_str("DefaultChain"),
        }
    }
}

/// Everything needed to open an [`crate::S3Store`] on one bucket.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct S3Config {
    /// `None`: AWS S3 itself. Otherwise the URL of an S3-compatible server, such as
    /// `http://127.0.0.1:9000` (no trailing path).
    pub endpoint: Option<String>,
    /// The bucket every key lives in.
    pub bucket: String,
    /// The signing region; `None` takes it from the SDK's default chain (`AWS_REGION`, as set on
    /// Lambda, or the profile's `region`), else [`DEFAULT_REGION`]. S3-compatible servers
    /// usually accept `us-east-1`.
    pub region: Option<String>,
    /// Where the credentials come from.
    pub credentials: S3Credentials,
    /// Address buckets as `ENDPOINT/bucket/key` instead of `bucket.ENDPOINT/key`; needed by
    /// most servers on an IP address or `localhost`.
    pub force_path_style: bool,
    /// Time to open a connection before the attempt fails (retryable).
    pub connect_timeout: Duration,
    /// Time one attempt of one request may take, body included, before it fails (retryable).
    pub attempt_timeout: Duration,
    /// Attempts per request, at least 1; the SDK retries transient failures (connection errors,
    /// timeouts, 5xx, throttling) with exponential backoff and jitter in between.
    pub max_attempts: u32,
    /// The scale of the SDK's backoff between attempts ([`DEFAULT_INITIAL_BACKOFF`]); tests
    /// that inject many storage faults shorten it.
    pub initial_backoff: Duration,
}

impl S3Config {
    /// AWS S3: default credential chain, virtual-hosted addressing, default timeouts; `region`
    /// `None` reads it from the environment, else uses [`DEFAULT_REGION`].
    pub fn aws(bucket: impl Into<String>, region: Option<String>) -> Self {
        Self {
            endpoint: None,
            bucket: bucket.into(),
            region,
            credentials: S3Credentials::DefaultChain,
            force_path_style: false,
            connect_timeout: DEFAULT_CONNECT_TIMEOUT,
            attempt_timeout: DEFAULT_ATTEMPT_TIMEOUT,
            max_attempts: DEFAULT_MAX_ATTEMPTS,
            initial_backoff: DEFAULT_INITIAL_BACKOFF,
        }
    }

    /// An S3-compatible server at `endpoint` (MinIO, moto, the embedded server) with a static
    /// key pair, region `us-east-1`, path-style addressing and default timeouts.
    pub fn compatible(
        endpoint: impl Into<String>,
        bucket: impl Into<String>,
        access_key: impl Into<String>,
        secret_key: impl Into<String>,
    ) -> Self {
        Self {
            endpoint: Some(endpoint.into()),
            bucket: bucket.into(),
            region: Some("us-east-1".to_owned()),
            credentials: S3Credentials::Static {
                access_key: access_key.into(),
                secret_key: secret_key.into(),
            },
            force_path_style: true,
            connect_timeout: DEFAULT_CONNECT_TIMEOUT,
            attempt_timeout: DEFAULT_ATTEMPT_TIMEOUT,
            max_attempts: DEFAULT_MAX_ATTEMPTS,
            initial_backoff: DEFAULT_INITIAL_BACKOFF,
        }
    }

    /// The SDK client for this configuration and the endpoint's name for messages (the URL,
    /// or `AWS S3 (REGION)`). Sends no request; fails with [`StoreError::Other`] on a
    /// malformed endpoint. The region is [`S3Config::region`], else the SDK's default chain's,
    /// else [`DEFAULT_REGION`]. Build it once per process (a Lambda environment) and share it:
    /// clients pool connections.
    pub async fn sdk_client(&self) -> Result<(Client, String), StoreError> {
        let (client, label, _) = self.sdk_parts().await?;
        Ok((client, label))
    }

    /// [`S3Config::sdk_client`] and the credentials provider the client signs with (`None` if
    /// the SDK has none), so that a store can check for credentials before any request.
    pub(crate) async fn sdk_parts(
        &self,
    ) -> Result<(Client, String, Option<SharedCredentialsProvider>), StoreError> {
        let endpoint = match &self.endpoint {
            Some(endpoint) => Some(checked_endpoint(endpoint)?),
            None => None,
        };
        let timeouts = TimeoutConfig::builder()
            .connect_timeout(self.connect_timeout)
            .operation_attempt_timeout(self.attempt_timeout)
            .build();
        let mut loader = aws_config::defaults(BehaviorVersion::latest())
            .timeout_config(timeouts)
            .retry_config(
                RetryConfig::standard()
                    .with_max_attempts(self.max_attempts.max(1))
                    .with_initial_backoff(self.initial_backoff),
            );
        if let Some(region) = &self.region {
            loader = loader.region(Region::new(region.clone()));
        }
        if let S3Credentials::Static {
            access_key,
            secret_key,
        } = &self.credentials
        {
            let credentials = Credentials::new(access_key, secret_key, None, None, "hort-static");
            loader = loader.credentials_provider(credentials);
        }
        if let Some(endpoint) = &endpoint {
            loader = loader.endpoint_url(endpoint);
        }
        let sdk_config = loader.load().await;
        let region = sdk_config
            .region()
            .map_or_else(|| DEFAULT_REGION.to_owned(), ToString::to_string);
        let mut s3 = aws_sdk_s3::config::Builder::from(&sdk_config)
            .region(Region::new(region.clone()))
            .force_path_style(self.force_path_style);
        if endpoint.is_some() {
            // Many S3-compatible servers reject the SDK's default CRC32 trailers; shuffle blocks
            // carry their own checksum, so only send checksums where S3 demands them.
            s3 = s3
                .request_checksum_calculation(RequestChecksumCalculation::WhenRequired)
                .response_checksum_validation(ResponseChecksumValidation::WhenRequired);
        }
        let label = endpoint.unwrap_or_else(|| format!("AWS S3 ({region})"));
        let credentials = sdk_config.credentials_provider();
        Ok((Client::from_conf(s3.build()), label, credentials))
    }
}

/// Whether PUT bodies sent to `endpoint` must be covered by the SigV4 signature: only over
/// plain `http://` to another machine, where nothing else protects them. `endpoint` is an
/// endpoint URL, or a label such as `AWS S3 (REGION)` for AWS S3 itself. Over `https://` (AWS
/// S3 always) TLS protects the body (and the SDK adds its CRC32 checksum there), and to a
/// loopback server nothing is in between; bodies then go as `UNSIGNED-PAYLOAD`, which spares a
/// SHA-256 pass over every byte on each side. Shuffle blocks and split objects carry their own
/// CRC either way.
pub(crate) fn signs_payloads(endpoint: &str) -> bool {
    let Some(rest) = endpoint.strip_prefix("http://") else {
        return false;
    };
    let authority = rest.split('/').next().unwrap_or_default();
    let host = match authority.strip_prefix('[') {
        // [IPv6]:port
        Some(v6) => v6.split(']').next().unwrap_or_default(),
        None => authority.split(':').next().unwrap_or_default(),
    };
    let loopback = host.eq_ignore_ascii_case("localhost")
        || host
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback());
    !loopback
}

/// `endpoint` without trailing slashes, if it is an `http://` or `https://` URL with a host.
fn checked_endpoint(endpoint: &str) -> Result<String, StoreError> {
    let trimmed = endpoint.trim_end_matches('/');
    let host = trimmed
        .strip_prefix("http://")
        .or_else(|| trimmed.strip_prefix("https://"));
    match host {
        Some(host) if !host.is_empty() && !host.contains('/') && !host.contains(' ') => {
            Ok(trimmed.to_owned())
        }
        _ => Err(StoreError::Other {
            what: format!(
                "invalid S3 endpoint {endpoint:?}: expected http://HOST[:PORT] or https://HOST[:PORT]"
            ),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn debug_never_shows_the_secret() {
        let config = S3Config::compatible("http://127.0.0.1:1", "b", "AKID", "hunter2");
        let shown = format!("{config:?}");
        assert!(shown.contains("AKID"), "{shown}");
        assert!(!shown.contains("hunter2"), "{shown}");
    }

    #[test]
    fn endpoints_must_be_http_urls() {
        assert_eq!(
            checked_endpoint("http://127.0.0.1:9000/").unwrap(),
            "http://127.0.0.1:9000"
        );
        assert!(checked_endpoint("https://s3.example.com").is_ok());
        for bad in ["127.0.0.1:9000", "http://", "ftp://x", "http://h/path"] {
            let err = checked_endpoint(bad).unwrap_err();
            assert!(err.to_string().contains("invalid S3 endpoint"), "{err}");
        }
    }

    #[test]
    fn payloads_are_signed_only_over_plain_http_to_another_machine() {
        for signed in [
            "http://minio.lan:9000",
            "http://10.0.0.5",
            "http://[fe80::1]:9000",
        ] {
            assert!(signs_payloads(signed), "{signed}");
        }
        for unsigned in [
            "https://minio.lan:9000",
            "AWS S3 (eu-west-1)",
            "http://127.0.0.1:9000",
            "http://127.8.9.10",
            "http://localhost:4566",
            "http://LOCALHOST",
            "http://[::1]:9000",
        ] {
            assert!(!signs_payloads(unsigned), "{unsigned}");
        }
    }
}
