//! The Worker function's Lambda entry point (`bootstrap` of the `hort-worker` function in
//! `infra/template.yaml`): builds the S3 client and the split cache once per container, then
//! hands each event to `hort_functions::handlers::dispatch` on a blocking thread; a failure is a
//! Lambda error typed `Hort.Retryable` or `Hort.BadInput`. Settings:
//! `hort_functions::aws::lambda`. Its allocator counts bytes, so each answer's task metrics
//! carry the process's memory high-water mark during the invocation (`peak_memory_bytes`).
#![forbid(unsafe_code)]

use hort_functions::aws::lambda::run_handler_function;
use hort_functions::handlers::Function;
use hort_task_memory::TaskAlloc;

/// Counts allocations: the memory each invocation reports.
#[global_allocator]
static ALLOCATOR: TaskAlloc = TaskAlloc;

fn main() -> Result<(), lambda_runtime::Error> {
    run_handler_function(Function::Worker)
}
