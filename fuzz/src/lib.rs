//! Fuzz targets for everything that reads bytes a user or another task controls: OBJ and MTL
//! files, scene manifests, split objects, shuffle blocks, state machine definitions and HTTP
//! API requests.
//!
//! Each target is a plain function of arbitrary bytes. Guarantees it checks on every input
//! (a failed check is a panic, which the fuzzer and the replay test report):
//!
//! - the code under test returns: no panic, no unbounded allocation, no hang;
//! - every error is one line (no `\n` or `\r`), and decoder errors name the object key;
//! - what decodes re-encodes to something that decodes to the same value;
//! - what loads is usable: finite vertices, in-range indices, a ray query on a decoded BVH
//!   returns.
//!
//! The AFL++ binaries in `src/bin/` call these functions; `tests/it/replay.rs` runs them over the
//! kept corpora in `corpus/<target>/` on the stable toolchain.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod asl;
#[cfg(feature = "http")]
mod http;
mod scene;
mod scratch;
mod shuffle;

pub use asl::asl;
#[cfg(feature = "http")]
pub use http::http;
pub use scene::{manifest, obj};
pub use shuffle::{shuffle_block, split_object};

/// A fuzz target: takes any bytes, panics only on a finding.
pub type Target = fn(&[u8]);

/// Every target by name (the name is its corpus folder and its AFL++ binary); `http` only with
/// the `http` feature (the default).
pub const TARGETS: &[(&str, Target)] = &[
    ("obj", obj),
    ("manifest", manifest),
    ("split_object", split_object),
    ("shuffle_block", shuffle_block),
    ("asl", asl),
    #[cfg(feature = "http")]
    ("http", http),
];

/// Panics unless `message` is one line; `what` names the input kind in the panic.
fn assert_one_line(what: &str, message: &str) {
    assert!(
        !message.is_empty() && !message.contains(['\n', '\r']),
        "{what}: error message is not one line: {message:?}"
    );
}
