//! The integration tests of `hort-fuzz` in one test binary (one link instead of one per file):
//! `replay`, every kept corpus input through its target, and `seeds`, the hand-run writer of the
//! binary seed inputs. `autotests = false` in `fuzz/Cargo.toml` keeps a new file under `tests/`
//! from becoming a binary of its own.
//!
//! The replay alone: `cargo test -p hort-fuzz --test it replay::`.

mod replay;
mod seeds;
