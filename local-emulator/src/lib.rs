//! The local emulator behind the `hort` command: the serverless pipeline on one machine, with
//! the same function handlers as the cloud (`hort-functions`), the same state machine definition
//! (interpreted by `asl-interpreter`), and real S3-protocol storage (`embedded-s3` or any
//! S3-compatible endpoint). The `hort` binary (`src/main.rs`) adds the command line and the
//! benchmarks.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod deployment;
pub mod emulator;
pub mod progress;
pub mod state_machine;
