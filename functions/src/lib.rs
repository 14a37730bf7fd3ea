//! AWS-facing adapters of HORT-serverless: the S3 object store and the Lambda handlers.
//!
//! The stage functions themselves live in `hort-core` as pure functions over bytes; this crate
//! only moves bytes between them and AWS. It is filled in by the local-emulator issue; until
//! then it re-exports the core so that downstream crates already depend on the right name.
#![forbid(unsafe_code)]

pub use hort_core as core;
