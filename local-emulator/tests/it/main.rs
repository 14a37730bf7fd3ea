//! The integration tests of the `hort` command, one module per former test file, in one test
//! binary: each binary links the AWS SDK, so one binary instead of fourteen saves their links and
//! their disk (`autotests = false` in `local-emulator/Cargo.toml` keeps a new file under `tests/`
//! from becoming a binary of its own; add it here as a module). Most tests run the `hort` binary
//! in a child process; the modules' tests run concurrently in this one process, so none of them
//! may change what the process shares (environment variables, the current folder: give them to
//! the child instead). `common` is their shared setup; `../fixtures/` holds their input files.
//!
//! One file's tests alone: `cargo test -p hort --test it serve::` (a filter matches any part of
//! a test's name `module::test`: `cli::` also selects `adaptive_cli::`, which
//! `-- --skip adaptive_cli::` leaves out).

mod adaptive_cli;
mod bad_input;
mod breakdown;
mod cli;
mod cli_eval;
mod cli_first_use;
mod cli_jobs;
mod cli_plan;
mod cli_scene;
mod cli_textures;
mod common;
mod frames;
mod readme;
mod scene_by_tasks;
mod serve;
mod serve_load;
