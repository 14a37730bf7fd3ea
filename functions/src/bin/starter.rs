//! The Starter function's Lambda entry point (`bootstrap` of the `hort-starter` function in
//! `infra/template.yaml`): the intake queue's messages (`{"job", "bucket"}`) become executions
//! of the state machine named by their job ids, with partial batch failures
//! (`ReportBatchItemFailures`). Logic: `hort_functions::aws::starter`; settings:
//! `hort_functions::aws::lambda`.
#![forbid(unsafe_code)]

fn main() -> Result<(), lambda_runtime::Error> {
    hort_functions::aws::lambda::run_starter()
}
