//! The functions, invoked through the Lambda Invoke API (`hort render --lambda-endpoint`): the
//! same events and answers as in process, but each one goes over HTTP to a Plan or Worker
//! function running elsewhere, such as the real `bootstrap` binaries under `cargo lambda watch`,
//! or functions deployed to AWS. Those functions read and write the bucket themselves, so they
//! must be configured for the same S3 endpoint and bucket as the run.

use super::invoker::Ledger;
use asl_interpreter::{TaskFailure, TaskInvoker};
use hort_core::pipeline::TaskMetrics;
use hort_functions::S3Credentials;
use hort_functions::aws::{AwsSettings, LambdaFunctions};
use hort_functions::handlers::{Function, TaskDone, WorkerEvent};
use serde_json::Value;
use std::sync::Mutex;
use std::time::Instant;

/// Where the functions run and what they are called.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LambdaTarget {
    /// The Lambda API endpoint (`cargo lambda watch` serves `http://127.0.0.1:9000`); `None`
    /// is AWS Lambda itself.
    pub endpoint: Option<String>,
    /// The Plan function's name or ARN (`plan` under `cargo lambda watch`).
    pub plan: String,
    /// The Worker function's name or ARN (`worker` under `cargo lambda watch`).
    pub worker: String,
}

/// Invokes the functions of a [`LambdaTarget`] and keeps the same [`Ledger`] as the in-process
/// invoker, from the Worker's answers (its task metrics).
pub struct LambdaInvoker {
    target: LambdaTarget,
    functions: LambdaFunctions,
    runtime: tokio::runtime::Runtime,
    ledger: Mutex<Ledger>,
}

impl LambdaInvoker {
    /// A client for `target`. A local endpoint needs no real credentials: without
    /// `AWS_ACCESS_KEY_ID`, requests to it are signed with placeholder keys.
    pub fn new(target: LambdaTarget) -> anyhow::Result<Self> {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("hort-lambda-client")
            .enable_all()
            .build()?;
        let credentials = match &target.endpoint {
            Some(_) if std::env::var_os("AWS_ACCESS_KEY_ID").is_none() => S3Credentials::Static {
                access_key: "local".into(),
                secret_key: "local".into(),
            },
            _ => S3Credentials::DefaultChain,
        };
        let settings = AwsSettings {
            endpoint: target.endpoint.clone(),
            region: None,
            credentials,
        };
        let functions = runtime.block_on(LambdaFunctions::connect(&settings));
        Ok(LambdaInvoker {
            target,
            functions,
            runtime,
            ledger: Mutex::new(Ledger::default()),
        })
    }

    /// Where the functions run, for messages: the endpoint's URL or `AWS (REGION)`.
    pub fn label(&self) -> &str {
        self.functions.label()
    }

    /// A copy of the ledger so far.
    pub fn ledger(&self) -> Ledger {
        self.ledger
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }
}

impl TaskInvoker for LambdaInvoker {
    fn invoke(&self, resource: &str, input: Value) -> Result<Value, TaskFailure> {
        let Some(function) = Function::from_state_machine_name(resource) else {
            return Err(TaskFailure::new(
                "Lambda.ResourceNotFoundException",
                format!("no function named {resource}"),
            ));
        };
        let name = match function {
            Function::Plan => &self.target.plan,
            Function::Worker => &self.target.worker,
        };
        // The task an answer belongs to; a malformed event is the function's to refuse.
        let task = match function {
            Function::Worker => serde_json::from_value::<WorkerEvent>(input.clone()).ok(),
            Function::Plan => None,
        };
        let started = Instant::now();
        let result = self
            .runtime
            .block_on(self.functions.invoke(name, &input))
            .map_err(|e| TaskFailure::new(e.error, e.cause));
        let ended = Instant::now();
        let done = match (&result, task) {
            (Ok(output), Some(event)) => {
                let metrics: TaskMetrics = serde_json::from_value(output.clone()).map_err(|e| {
                    TaskFailure::new(
                        hort_functions::aws::invoke::LAMBDA_ERROR,
                        format!("{name} answered no task metrics: {e}"),
                    )
                })?;
                Some(TaskDone {
                    stage: event.stage,
                    frame: event.item.frame,
                    task: event.item.task,
                    metrics,
                })
            }
            _ => None,
        };
        self.ledger
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .record(started, ended, done);
        result
    }
}
