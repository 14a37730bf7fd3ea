//! The project's one digest, 64-bit FNV-1a (crate `hort-digest`), re-exported for the crates
//! that reach it through `hort-core`.

pub use hort_digest::{Fnv1a64, fnv1a64};
