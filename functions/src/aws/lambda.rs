//! What the Lambda entry points (`src/bin/plan.rs`, `worker.rs`, `starter.rs`) share: settings
//! from environment variables, SDK clients and the split cache built once per container, the
//! synchronous handlers run on tokio's blocking threads, and failures reported as Lambda errors
//! whose error type is the state machine's (`Hort.Retryable`, `Hort.BadInput`).
//!
//! Environment variables (set by `infra/template.yaml`):
//!
//! | variable | used by | meaning |
//! |---|---|---|
//! | `HORT_BUCKET` | all | the bucket the functions serve (required) |
//! | `HORT_SPLIT_CACHE_MB` | worker | decoded splits kept between invocations, in MiB (default: 1024, at most half the function's memory) |
//! | `HORT_STATE_MACHINE_ARN` | starter, api | the state machine to start (required) |
//! | `HORT_QUEUE_URL` | api | the intake queue (required) |
//! | `HORT_MAX_CONCURRENCY` | api | the Map concurrency of submitted jobs (default 0: no limit) |
//! | `HORT_WORKER_MEMORY_MB` | plan, api | the Worker's memory: the API's default and most for `memory_mb` (default 2048), the most the Plan function plans tasks for |
//! | `AWS_LAMBDA_FUNCTION_MEMORY_SIZE` | worker | set by Lambda: the Worker's own memory; a task of a plan for more is refused before any work, naming both |
//! | `HORT_TMP_MB` | plan, worker | the size of the function's `/tmp` (its `EphemeralStorage`), MB: a scene copy that would not fit is refused, naming both sizes (default: not checked) |
//! | `HORT_S3_ENDPOINT` | plan, worker, api | an S3-compatible server instead of AWS S3 (local runs), path-style |
//! | `HORT_AWS_ENDPOINT` | starter, api | a server for the SQS and Step Functions APIs instead of AWS (local runs) |
//!
//! Credentials and region come from the SDK's default chains (on Lambda: the function's role and
//! `AWS_REGION`).

use std::path::PathBuf;
use std::sync::Arc;

use aws_lambda_events::event::sqs::SqsEvent;
use hort_core::pipeline::SplitCache;
use hort_core::stage::Stage;
use lambda_runtime::{Diagnostic, LambdaEvent, service_fn};
use serde_json::Value;

use super::AwsSettings;
use super::api_backend::{AwsBackend, DeploymentLimits};
use super::sfn::Executions;
use super::sqs::JobQueue;
use super::starter::start_batch;
use crate::handlers::{Function, FunctionEnv, HandlerError, Invoked, Tmp, dispatch};
use crate::{S3Config, S3Store};

/// The bucket the functions serve.
pub const BUCKET_VAR: &str = "HORT_BUCKET";
/// The split cache's budget in MiB.
pub const SPLIT_CACHE_VAR: &str = "HORT_SPLIT_CACHE_MB";
/// The state machine the Starter starts.
pub const STATE_MACHINE_VAR: &str = "HORT_STATE_MACHINE_ARN";
/// An S3-compatible endpoint instead of AWS S3.
pub const S3_ENDPOINT_VAR: &str = "HORT_S3_ENDPOINT";
/// An endpoint for the Step Functions API instead of AWS.
pub const AWS_ENDPOINT_VAR: &str = "HORT_AWS_ENDPOINT";
/// The intake queue's URL (the api function).
pub const QUEUE_URL_VAR: &str = "HORT_QUEUE_URL";
/// The Map concurrency written into job requests (the api function; default 0, no limit).
pub const MAX_CONCURRENCY_VAR: &str = "HORT_MAX_CONCURRENCY";
/// The Worker's memory in MB: the most a job may plan its tasks for (the api function, default
/// 2048; the Plan function, unchecked when unset).
pub const WORKER_MEMORY_VAR: &str = "HORT_WORKER_MEMORY_MB";
/// The size of the function's `/tmp` in MB (the template sets it with its `EphemeralStorage`).
pub const TMP_VAR: &str = "HORT_TMP_MB";
/// Lambda's variable holding the function's memory in MiB.
pub const MEMORY_VAR: &str = "AWS_LAMBDA_FUNCTION_MEMORY_SIZE";
/// The split cache budget without [`SPLIT_CACHE_VAR`], before the half-memory cap.
pub const DEFAULT_SPLIT_CACHE_MB: u64 = 1024;

/// The settings of a Plan or Worker function.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FunctionSettings {
    /// The bucket served.
    pub bucket: String,
    /// The split cache's budget in bytes (0 for the Plan function, which reads no split).
    pub split_cache_bytes: u64,
    /// An S3-compatible endpoint instead of AWS S3.
    pub s3_endpoint: Option<String>,
    /// The Worker function's memory, MB, the most a job's tasks may be planned for: for the
    /// Plan function its [`WORKER_MEMORY_VAR`] (set by the template), for the Worker its own
    /// [`MEMORY_VAR`] (set by Lambda); `None` when unset.
    pub worker_memory_mb: Option<u32>,
    /// The size of `/tmp` in bytes ([`TMP_VAR`]); `None` when unset (not checked).
    pub tmp_bytes: Option<u64>,
}

impl FunctionSettings {
    /// The settings of `function` from the variables `var` returns (the process environment in
    /// [`FunctionSettings::from_env`]); the error names the variable.
    pub fn from_vars(
        function: Function,
        var: impl Fn(&str) -> Option<String>,
    ) -> Result<Self, String> {
        let bucket = required(&var, BUCKET_VAR)?;
        let split_cache_bytes = match function {
            Function::Plan => 0,
            Function::Worker => {
                let memory_cap = match var(MEMORY_VAR) {
                    Some(mb) => parse_mb(MEMORY_VAR, &mb)? / 2,
                    None => u64::MAX,
                };
                let mb = match var(SPLIT_CACHE_VAR) {
                    Some(mb) => parse_mb(SPLIT_CACHE_VAR, &mb)?,
                    None => DEFAULT_SPLIT_CACHE_MB.min(memory_cap),
                };
                mb << 20
            }
        };
        // The Plan function is told the Worker's memory; the Worker knows its own.
        let memory_var = match function {
            Function::Plan => WORKER_MEMORY_VAR,
            Function::Worker => MEMORY_VAR,
        };
        let worker_memory_mb = var(memory_var)
            .map(|mb| {
                u32::try_from(parse_mb(memory_var, &mb)?)
                    .map_err(|_| format!("{memory_var}={mb:?} is not a memory size in MB"))
            })
            .transpose()?;
        Ok(FunctionSettings {
            bucket,
            split_cache_bytes,
            s3_endpoint: var(S3_ENDPOINT_VAR).filter(|v| !v.is_empty()),
            worker_memory_mb,
            tmp_bytes: var(TMP_VAR)
                .map(|mb| parse_mb(TMP_VAR, &mb).map(|mb| mb << 20))
                .transpose()?,
        })
    }

    /// [`FunctionSettings::from_vars`] over the process environment.
    pub fn from_env(function: Function) -> Result<Self, String> {
        Self::from_vars(function, |name| std::env::var(name).ok())
    }

    /// The S3 configuration: AWS S3 with the default chains, or the endpoint path-style.
    pub fn s3_config(&self) -> S3Config {
        let mut config = S3Config::aws(self.bucket.clone(), None);
        if let Some(endpoint) = &self.s3_endpoint {
            config.endpoint = Some(endpoint.clone());
            config.force_path_style = true;
        }
        config
    }
}

fn required(var: &impl Fn(&str) -> Option<String>, name: &str) -> Result<String, String> {
    var(name)
        .filter(|v| !v.is_empty())
        .ok_or_else(|| format!("the environment variable {name} is not set"))
}

fn parse_mb(name: &str, value: &str) -> Result<u64, String> {
    value
        .trim()
        .parse::<u64>()
        .ok()
        .filter(|mb| *mb <= 1 << 20)
        .ok_or_else(|| format!("{name}={value:?} is not a size in MiB (0 to 1048576)"))
}

/// The settings of the api function.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ApiSettings {
    /// The bucket served.
    pub bucket: String,
    /// The intake queue.
    pub queue_url: String,
    /// The job state machine.
    pub state_machine_arn: String,
    /// What jobs run with.
    pub limits: DeploymentLimits,
    /// An S3-compatible endpoint instead of AWS S3.
    pub s3_endpoint: Option<String>,
    /// An endpoint for SQS and Step Functions instead of AWS.
    pub aws_endpoint: Option<String>,
}

impl ApiSettings {
    /// The settings from the variables `var` returns; the error names the variable.
    pub fn from_vars(var: impl Fn(&str) -> Option<String>) -> Result<Self, String> {
        let number = |name: &str, default: u32| match var(name).filter(|v| !v.is_empty()) {
            None => Ok(default),
            Some(v) => v
                .trim()
                .parse::<u32>()
                .map_err(|_| format!("{name}={v:?} is not a whole number")),
        };
        Ok(ApiSettings {
            bucket: required(&var, BUCKET_VAR)?,
            queue_url: required(&var, QUEUE_URL_VAR)?,
            state_machine_arn: required(&var, STATE_MACHINE_VAR)?,
            limits: DeploymentLimits {
                max_concurrency: number(MAX_CONCURRENCY_VAR, 0)?,
                worker_memory_mb: number(WORKER_MEMORY_VAR, 2048)?,
            },
            s3_endpoint: var(S3_ENDPOINT_VAR).filter(|v| !v.is_empty()),
            aws_endpoint: var(AWS_ENDPOINT_VAR).filter(|v| !v.is_empty()),
        })
    }

    /// [`ApiSettings::from_vars`] over the process environment.
    pub fn from_env() -> Result<Self, String> {
        Self::from_vars(|name| std::env::var(name).ok())
    }

    /// The backend: the S3 store, the queue and the executions, built once on the current
    /// (multi-threaded) runtime.
    pub async fn backend(&self) -> Result<AwsBackend, String> {
        let mut s3 = S3Config::aws(self.bucket.clone(), None);
        if let Some(endpoint) = &self.s3_endpoint {
            s3.endpoint = Some(endpoint.clone());
            s3.force_path_style = true;
        }
        let store = S3Store::connect(&s3).await.map_err(|e| e.to_string())?;
        let settings = AwsSettings {
            endpoint: self.aws_endpoint.clone(),
            ..AwsSettings::aws()
        };
        let config = settings.sdk_config().await;
        let label = AwsSettings::label(&config);
        Ok(AwsBackend::new(
            store,
            JobQueue::new(aws_sdk_sqs::Client::new(&config), &self.queue_url, &label),
            Executions::new(
                aws_sdk_sfn::Client::new(&config),
                &self.state_machine_arn,
                &label,
            ),
            tokio::runtime::Handle::current(),
            self.limits,
        ))
    }
}

/// The Lambda error of a handler failure: error type `Hort.Retryable` or `Hort.BadInput`
/// (what the state machine's `Retry` and `Catch` match), message the cause.
pub fn diagnostic(e: &HandlerError) -> Diagnostic {
    Diagnostic {
        error_type: e.error_type.as_str().to_owned(),
        error_message: e.cause.clone(),
    }
}

/// What a warm container keeps between invocations.
struct Container {
    function: Function,
    store: S3Store,
    bucket: String,
    work_dir: PathBuf,
    tmp_bytes: Option<u64>,
    split_cache: SplitCache,
    worker_memory_mb: Option<u32>,
}

/// The tokio runtime of an entry point (multi-threaded: the S3 store blocks handler threads
/// while runtime workers drive the sockets).
fn runtime() -> Result<tokio::runtime::Runtime, lambda_runtime::Error> {
    Ok(tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?)
}

/// The whole life of a Plan or Worker container: read the settings, build the S3 client and
/// the split cache once, then serve invocations until Lambda ends the process. Each event goes
/// to [`dispatch`] on a blocking thread.
pub fn run_handler_function(function: Function) -> Result<(), lambda_runtime::Error> {
    let name = function_name(function);
    let settings = FunctionSettings::from_env(function).map_err(|e| format!("{name}: {e}"))?;
    runtime()?.block_on(async move {
        let store = S3Store::connect(&settings.s3_config())
            .await
            .map_err(|e| format!("{name}: {e}"))?;
        let container = Arc::new(Container {
            function,
            store,
            bucket: settings.bucket,
            work_dir: std::env::temp_dir(),
            tmp_bytes: settings.tmp_bytes,
            split_cache: SplitCache::new(settings.split_cache_bytes),
            worker_memory_mb: settings.worker_memory_mb,
        });
        lambda_runtime::run(service_fn(move |event: LambdaEvent<Value>| {
            invoke(Arc::clone(&container), event.payload)
        }))
        .await
    })
}

async fn invoke(container: Arc<Container>, event: Value) -> Result<Value, Diagnostic> {
    let name = function_name(container.function);
    let joined = tokio::task::spawn_blocking(move || {
        let env = FunctionEnv {
            store: &container.store,
            bucket: &container.bucket,
            tmp: Tmp {
                dir: &container.work_dir,
                limit_bytes: container.tmp_bytes,
            },
            split_cache: &container.split_cache,
            worker_memory_mb: container.worker_memory_mb,
        };
        // One invocation at a time per container: the process's high-water mark during this
        // one is the task's memory (with what the container keeps: its split cache, clients).
        hort_task_memory::reset_process_peak();
        let result = dispatch(container.function, event, &env);
        (result, hort_task_memory::process_peak_bytes())
    })
    .await;
    match joined {
        Ok((Ok(mut invoked), peak)) => {
            // Measured only where the binary installs `hort_task_memory::TaskAlloc` (the Worker).
            if let Some(peak) = peak {
                invoked.set_peak_memory(peak);
            }
            let Invoked { output, task } = invoked;
            match task {
                // The Plan function's `TaskDone` (stage `plan`) carries only its time breakdown.
                Some(done) if done.stage != Stage::Plan => println!(
                    "{name}: {} task {} done: {}",
                    done.stage,
                    done.task.0,
                    serde_json::to_string(&done.metrics).unwrap_or_default()
                ),
                _ => println!("{name}: done: {output}"),
            }
            Ok(output)
        }
        Ok((Err(e), _)) => {
            eprintln!("{name}: {e}");
            Err(diagnostic(&e))
        }
        Err(join) => {
            // A panic is a bug, but the state machine retries crashed functions
            // (`Lambda.Unknown`) and the emulator reports a panic that way: retryable here too.
            let e = HandlerError::retryable(format!("the {name} handler panicked: {join}"));
            eprintln!("{name}: {e}");
            Err(diagnostic(&e))
        }
    }
}

fn function_name(function: Function) -> &'static str {
    match function {
        Function::Plan => "plan",
        Function::Worker => "worker",
    }
}

/// The whole life of a Starter container: the Step Functions client built once, then each SQS
/// batch handed to [`start_batch`].
pub fn run_starter() -> Result<(), lambda_runtime::Error> {
    let var = |name: &str| std::env::var(name).ok();
    let bucket = required(&var, BUCKET_VAR).map_err(|e| format!("starter: {e}"))?;
    let machine = required(&var, STATE_MACHINE_VAR).map_err(|e| format!("starter: {e}"))?;
    let settings = AwsSettings {
        endpoint: var(AWS_ENDPOINT_VAR).filter(|v| !v.is_empty()),
        ..AwsSettings::aws()
    };
    runtime()?.block_on(async move {
        let config = settings.sdk_config().await;
        let executions = Arc::new(Executions::new(
            aws_sdk_sfn::Client::new(&config),
            machine,
            AwsSettings::label(&config),
        ));
        let bucket = Arc::new(bucket);
        lambda_runtime::run(service_fn(move |event: LambdaEvent<SqsEvent>| {
            let (executions, bucket) = (Arc::clone(&executions), Arc::clone(&bucket));
            async move { Ok::<_, Diagnostic>(start_batch(&executions, &bucket, &event.payload).await) }
        }))
        .await
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn vars(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let map: HashMap<String, String> = pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        move |name| map.get(name).cloned()
    }

    #[test]
    fn settings_come_from_the_environment() {
        let worker =
            |pairs: &[(&str, &str)]| FunctionSettings::from_vars(Function::Worker, vars(pairs));
        let e = worker(&[]).unwrap_err();
        assert_eq!(e, "the environment variable HORT_BUCKET is not set");
        let s = worker(&[("HORT_BUCKET", "b")]).unwrap();
        assert_eq!(s.split_cache_bytes, 1024 << 20);
        assert_eq!(s.s3_endpoint, None);
        assert_eq!(s.s3_config().endpoint, None);
        assert_eq!(s.worker_memory_mb, None);
        let s = worker(&[("HORT_BUCKET", "b"), (MEMORY_VAR, "1024")]).unwrap();
        assert_eq!(s.split_cache_bytes, 512 << 20, "half the memory");
        assert_eq!(
            s.worker_memory_mb,
            Some(1024),
            "the Worker's own memory, from Lambda"
        );
        let s = worker(&[
            ("HORT_BUCKET", "b"),
            (MEMORY_VAR, "1024"),
            (SPLIT_CACHE_VAR, "700"),
        ])
        .unwrap();
        assert_eq!(s.split_cache_bytes, 700 << 20, "an explicit budget wins");
        let e = worker(&[("HORT_BUCKET", "b"), (SPLIT_CACHE_VAR, "lots")]).unwrap_err();
        assert!(e.contains("HORT_SPLIT_CACHE_MB=\"lots\""), "{e}");
        let plan = FunctionSettings::from_vars(
            Function::Plan,
            vars(&[
                ("HORT_BUCKET", "b"),
                (S3_ENDPOINT_VAR, "http://127.0.0.1:9"),
            ]),
        )
        .unwrap();
        assert_eq!(plan.split_cache_bytes, 0);
        let config = plan.s3_config();
        assert_eq!(config.endpoint.as_deref(), Some("http://127.0.0.1:9"));
        assert!(config.force_path_style);
    }

    #[test]
    fn api_settings_come_from_the_environment() {
        let e = ApiSettings::from_vars(vars(&[("HORT_BUCKET", "b")])).unwrap_err();
        assert_eq!(e, "the environment variable HORT_QUEUE_URL is not set");
        let all = [
            ("HORT_BUCKET", "b"),
            ("HORT_QUEUE_URL", "https://sqs/q"),
            (
                "HORT_STATE_MACHINE_ARN",
                "arn:aws:states:r:1:stateMachine:m",
            ),
        ];
        let s = ApiSettings::from_vars(vars(&all)).unwrap();
        assert_eq!(
            s.limits,
            DeploymentLimits {
                max_concurrency: 0,
                worker_memory_mb: 2048
            }
        );
        let mut more = all.to_vec();
        more.push((MAX_CONCURRENCY_VAR, "100"));
        more.push((WORKER_MEMORY_VAR, "lots"));
        let e = ApiSettings::from_vars(vars(&more)).unwrap_err();
        assert!(e.contains("HORT_WORKER_MEMORY_MB=\"lots\""), "{e}");
    }

    #[test]
    fn handler_errors_become_typed_lambda_errors() {
        let d = diagnostic(&HandlerError::bad_input(
            "job request jobs/j/manifest.json does not exist",
        ));
        assert_eq!(d.error_type, "Hort.BadInput");
        assert_eq!(
            d.error_message,
            "job request jobs/j/manifest.json does not exist"
        );
        let d = diagnostic(&HandlerError::retryable("get: unreachable"));
        assert_eq!(d.error_type, "Hort.Retryable");
        // What the Runtime API receives.
        assert_eq!(
            serde_json::to_value(&d).unwrap(),
            serde_json::json!({"errorType": "Hort.Retryable", "errorMessage": "get: unreachable"})
        );
    }
}
