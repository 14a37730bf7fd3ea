//! Library side of the `hort` command: pieces of the local emulator that tests and other crates
//! use directly. The `hort` binary (`src/main.rs`) declares its own modules.
#![forbid(unsafe_code)]

pub mod embedded_s3;
pub mod emulator;
pub mod orchestrator;
pub mod progress;
