//! The end-to-end tests of `hort-tests`, one module per former test file, in one test binary:
//! each binary links the AWS SDK, so one binary instead of nine saves their links and their disk
//! (`autotests = false` in `tests/Cargo.toml` keeps a new file under `tests/` from becoming a
//! binary of its own; add it here as a module). The modules' tests run concurrently in this one
//! process, so none of them may change what the process shares (environment variables, the
//! current folder); `s3_support` is their shared S3 setup.
//!
//! One file's tests alone: `cargo test -p hort-tests --test it emulator::`.

// Every test runs with the counting allocator, as the `hort` binary and the Worker function do:
// the emulator then measures each task's memory and holds it to the functions' budget
// (`task_memory` checks that). A global allocator is one per binary, so it is set here, for all.
#[global_allocator]
static ALLOCATOR: hort_task_memory::TaskAlloc = hort_task_memory::TaskAlloc;

mod adaptive_equality;
mod aws_moto;
mod emulator;
mod mode_choice;
mod pipeline_equality;
mod s3_conformance;
mod s3_errors;
mod s3_support;
mod storage_faults;
mod task_memory;
