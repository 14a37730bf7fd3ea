//! The Plan function's Lambda entry point (`bootstrap` of the `hort-plan` function in
//! `infra/template.yaml`): builds the S3 client and the split cache once per container, then
//! hands each event to `hort_functions::handlers::dispatch` on a blocking thread; a failure is a
//! Lambda error typed `Hort.Retryable` or `Hort.BadInput`. Settings:
//! `hort_functions::aws::lambda`.
#![forbid(unsafe_code)]

use hort_functions::aws::lambda::run_handler_function;
use hort_functions::handlers::Function;

fn main() -> Result<(), lambda_runtime::Error> {
    run_handler_function(Function::Plan)
}
