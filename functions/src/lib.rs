//! The HORT stage functions' handlers and HTTP API router, and their AWS adapters.
//!
//! The stage functions themselves live in `hort-core` as pure functions over bytes; this crate
//! moves bytes between them and storage, and answers the render API.
//!
//! - [`handlers`]: the Plan and Worker functions as plain functions over a `BlobStore`.
//! - [`api`]: the HTTP API router, a plain function over a `RenderBackend` (plain `http` types).
//!
//! Feature `aws` (default) adds the AWS side, which uses those two and is never used by them:
//!
//! - `S3Store` (`s3_store`): the core's `BlobStore` over AWS S3 or any S3-compatible server,
//!   configured by `S3Config` (`s3_config`); SDK errors are classified in one private module,
//!   `s3_errors`, into the core's `StoreError` with one-line messages. It is also the router's
//!   `ImageBucket` (presigned GETs of large images).
//! - `aws`: the SQS, Step Functions and Lambda clients, the deployment's API backend, and the
//!   glue of the Lambda entry points (`src/bin/`, built only with the feature).
//!
//! Rule: the handlers and the router build without the AWS SDK (`default-features = false`),
//! so a crate that only routes, such as the fuzzer's `http` target, does not build the SDK.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub use hort_core as core;

pub mod api;
#[cfg(feature = "aws")]
pub mod aws;
pub mod handlers;
#[cfg(feature = "aws")]
pub mod s3_config;
#[cfg(feature = "aws")]
mod s3_errors;
#[cfg(feature = "aws")]
mod s3_image_bucket;
#[cfg(feature = "aws")]
pub mod s3_store;

#[cfg(feature = "aws")]
pub use s3_config::{S3Config, S3Credentials};
#[cfg(feature = "aws")]
pub use s3_store::S3Store;
