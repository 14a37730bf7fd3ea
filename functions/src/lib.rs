//! AWS-facing adapters of HORT-serverless: the S3 object store and the Lambda handlers.
//!
//! The stage functions themselves live in `hort-core` as pure functions over bytes; this crate
//! only moves bytes between them and AWS.
//!
//! - [`handlers`]: the Plan and Worker functions as plain functions over a `BlobStore`.
//! - [`S3Store`] ([`s3_store`]): the core's `BlobStore` over AWS S3 or any S3-compatible server,
//!   configured by [`S3Config`] ([`s3_config`]); SDK errors are classified in one private
//!   module, `s3_errors`, into the core's `StoreError` with one-line messages.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub use hort_core as core;

pub mod api;
pub mod aws;
pub mod handlers;
pub mod s3_config;
mod s3_errors;
pub mod s3_store;

pub use s3_config::{S3Config, S3Credentials};
pub use s3_store::S3Store;
