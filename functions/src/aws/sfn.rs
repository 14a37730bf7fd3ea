//! [`Executions`]: executions of the HORT state machine (`infra/statemachine.asl.json`), each
//! named by its job id, so that a job has at most one execution and its ARN follows from the
//! job id.

use std::collections::BTreeMap;

use aws_sdk_sfn::Client;
use aws_sdk_sfn::types::ExecutionStatus as SdkStatus;
use hort_core::ids::JobId;
use serde::{Deserialize, Serialize};

use super::error::{AwsError, AwsErrorKind, classify};

const SERVICE: &str = "Step Functions";

/// The state machine's execution input, and the body of a job message on the intake queue.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExecutionInput {
    /// The job; its scene and `manifest.json` are stored under `jobs/{job}/` before the start.
    pub job: JobId,
    /// The bucket holding the job.
    pub bucket: String,
}

/// Where an execution is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ExecutionStatus {
    /// Still running.
    Running,
    /// Finished; the image is stored.
    Succeeded,
    /// Failed; [`Execution::error`] and [`Execution::cause`] say why.
    Failed,
    /// Ran past the state machine's time limit.
    TimedOut,
    /// Stopped ([`Executions::stop`]).
    Aborted,
    /// Failed and waiting for a redrive.
    PendingRedrive,
    /// A status this code does not know, as the service spelled it.
    Unknown(String),
}

impl ExecutionStatus {
    /// True once the execution can no longer change (all but running and pending redrive).
    pub fn is_final(&self) -> bool {
        !matches!(
            self,
            ExecutionStatus::Running | ExecutionStatus::PendingRedrive
        )
    }

    fn from_sdk(status: &SdkStatus) -> Self {
        match status {
            SdkStatus::Running => ExecutionStatus::Running,
            SdkStatus::Succeeded => ExecutionStatus::Succeeded,
            SdkStatus::Failed => ExecutionStatus::Failed,
            SdkStatus::TimedOut => ExecutionStatus::TimedOut,
            SdkStatus::Aborted => ExecutionStatus::Aborted,
            SdkStatus::PendingRedrive => ExecutionStatus::PendingRedrive,
            other => ExecutionStatus::Unknown(other.as_str().to_owned()),
        }
    }
}

/// One execution as DescribeExecution tells it.
#[derive(Debug, Clone, PartialEq)]
pub struct Execution {
    /// The execution's ARN.
    pub arn: String,
    /// Its name (the job id, for executions [`Executions::start`] made).
    pub name: String,
    /// Where it is.
    pub status: ExecutionStatus,
    /// Its input JSON, if the service returned it.
    pub input: Option<String>,
    /// Its output JSON, once it succeeded.
    pub output: Option<String>,
    /// The error name of a failed execution (for example `States.ExceedToleratedFailureThreshold`).
    pub error: Option<String>,
    /// The cause of a failed execution (`"<Stage> failed: ..."`).
    pub cause: Option<String>,
    /// When it ended, in microseconds since the Unix epoch, once it did.
    pub stopped_unix_us: Option<u64>,
}

/// One execution as ListExecutions tells it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Listed {
    /// Where it is.
    pub status: ExecutionStatus,
    /// When it ended, in microseconds since the Unix epoch, once it did.
    pub stopped_unix_us: Option<u64>,
}

/// One Map Run of an execution, as DescribeMapRun tells it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MapRun {
    /// Its ARN.
    pub arn: String,
    /// The Map state's label (its name, for HORT's Maps): `CastMap`, `CastMapRerun`, ...
    pub label: String,
    /// Items that succeeded so far.
    pub succeeded: u64,
    /// Items in the run.
    pub total: u64,
    /// When it started, milliseconds since the Unix epoch.
    pub started_unix_ms: i64,
}

/// `date` in microseconds since the Unix epoch (at millisecond precision, as the service gives
/// it); `None` before the epoch or out of range.
fn unix_micros(date: &aws_sdk_sfn::primitives::DateTime) -> Option<u64> {
    let micros = date.to_millis().ok()?.checked_mul(1000)?;
    u64::try_from(micros).ok()
}

/// The label of a Map Run ARN, `arn:…:mapRun:{state machine}/{label}:{id}`.
fn map_run_label(arn: &str) -> &str {
    let tail = arn.rsplit_once(":mapRun:").map_or(arn, |(_, t)| t);
    let after_machine = tail.split_once('/').map_or(tail, |(_, t)| t);
    after_machine
        .rsplit_once(':')
        .map_or(after_machine, |(label, _)| label)
}

/// A successful [`Executions::start`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Started {
    /// The execution's ARN.
    pub execution_arn: String,
    /// True if the service said an execution of that name existed already. (AWS answers a
    /// repeated start of a running execution with the same input with plain success, so a
    /// repeat may also come back `false`.)
    pub already_started: bool,
}

/// The executions of one state machine.
#[derive(Debug, Clone)]
pub struct Executions {
    client: Client,
    state_machine_arn: String,
    endpoint: String,
}

impl Executions {
    /// The executions of the state machine `state_machine_arn`, through `client`; `endpoint`
    /// names the server in messages ([`super::AwsSettings::label`]).
    pub fn new(
        client: Client,
        state_machine_arn: impl Into<String>,
        endpoint: impl Into<String>,
    ) -> Self {
        Executions {
            client,
            state_machine_arn: state_machine_arn.into(),
            endpoint: endpoint.into(),
        }
    }

    /// The state machine's ARN.
    pub fn state_machine_arn(&self) -> &str {
        &self.state_machine_arn
    }

    /// The SDK client, for what this wrapper does not cover.
    pub fn client(&self) -> &Client {
        &self.client
    }

    /// The ARN of the execution named `job`: `arn:PARTITION:states:REGION:ACCOUNT:execution:
    /// MACHINE:JOB`, from the state machine's `...:stateMachine:MACHINE`.
    pub fn execution_arn(&self, job: &JobId) -> String {
        let base = self
            .state_machine_arn
            .replacen(":stateMachine:", ":execution:", 1);
        format!("{base}:{job}")
    }

    /// Starts the execution of `input.job`, named by the job id. An execution of that name that
    /// exists already (running or finished) is success with [`Started::already_started`]: job
    /// messages are delivered at least once.
    pub async fn start(&self, input: &ExecutionInput) -> Result<Started, AwsError> {
        let op = format!("start execution {:?}", input.job.as_str());
        let json = serde_json::to_string(input).map_err(|e| AwsError {
            kind: AwsErrorKind::Invalid,
            what: format!("{op}: cannot encode the input: {e}"),
        })?;
        let sent = self
            .client
            .start_execution()
            .state_machine_arn(&self.state_machine_arn)
            .name(input.job.as_str())
            .input(json)
            .send()
            .await;
        match sent {
            Ok(out) => Ok(Started {
                execution_arn: out.execution_arn,
                already_started: false,
            }),
            Err(e) => {
                let e = classify(e, &op, SERVICE, &self.endpoint);
                if e.kind == AwsErrorKind::AlreadyExists {
                    Ok(Started {
                        execution_arn: self.execution_arn(&input.job),
                        already_started: true,
                    })
                } else {
                    Err(e)
                }
            }
        }
    }

    /// The execution of `job`; [`AwsErrorKind::NotFound`] if there is none.
    pub async fn describe(&self, job: &JobId) -> Result<Execution, AwsError> {
        let arn = self.execution_arn(job);
        let out = self
            .client
            .describe_execution()
            .execution_arn(&arn)
            .send()
            .await
            .map_err(|e| {
                classify(
                    e,
                    &format!("describe execution {:?}", job.as_str()),
                    SERVICE,
                    &self.endpoint,
                )
            })?;
        Ok(Execution {
            arn: out.execution_arn,
            name: out.name.unwrap_or_default(),
            status: ExecutionStatus::from_sdk(&out.status),
            input: out.input,
            output: out.output,
            error: out.error,
            cause: out.cause,
            stopped_unix_us: out.stop_date.as_ref().and_then(unix_micros),
        })
    }

    /// The Map Runs the execution of `job` has started, with their items' counts (ListMapRuns,
    /// then DescribeMapRun of each): a job's progress without listing its objects.
    pub async fn map_runs(&self, job: &JobId) -> Result<Vec<MapRun>, AwsError> {
        let what = |op: &str| format!("{op} of execution {:?}", job.as_str());
        let mut arns = Vec::new();
        let mut token: Option<String> = None;
        loop {
            let page = self
                .client
                .list_map_runs()
                .execution_arn(self.execution_arn(job))
                .set_next_token(token.clone())
                .send()
                .await
                .map_err(|e| classify(e, &what("list map runs"), SERVICE, &self.endpoint))?;
            arns.extend(page.map_runs().iter().map(|r| r.map_run_arn().to_owned()));
            match page.next_token() {
                Some(next) if token.as_deref() != Some(next) => token = Some(next.to_owned()),
                _ => break,
            }
        }
        let mut runs = Vec::with_capacity(arns.len());
        for arn in arns {
            let out = self
                .client
                .describe_map_run()
                .map_run_arn(&arn)
                .send()
                .await
                .map_err(|e| classify(e, &what("describe map run"), SERVICE, &self.endpoint))?;
            let counts = out.item_counts();
            runs.push(MapRun {
                label: map_run_label(&arn).to_owned(),
                succeeded: counts.map_or(0, |c| u64::try_from(c.succeeded()).unwrap_or(0)),
                total: counts.map_or(0, |c| u64::try_from(c.total()).unwrap_or(0)),
                started_unix_ms: out.start_date().to_millis().unwrap_or(0),
                arn,
            });
        }
        runs.sort_by_key(|r| r.started_unix_ms);
        Ok(runs)
    }

    /// Every execution of the state machine by name, with its status and end (ListExecutions,
    /// 1,000 a page): the state of many jobs in a few requests.
    pub async fn list(&self) -> Result<BTreeMap<String, Listed>, AwsError> {
        let mut out = BTreeMap::new();
        let mut token: Option<String> = None;
        loop {
            let page = self
                .client
                .list_executions()
                .state_machine_arn(&self.state_machine_arn)
                .max_results(1000)
                .set_next_token(token.clone())
                .send()
                .await
                .map_err(|e| classify(e, "list executions", SERVICE, &self.endpoint))?;
            for e in page.executions() {
                out.insert(
                    e.name().to_owned(),
                    Listed {
                        status: ExecutionStatus::from_sdk(e.status()),
                        stopped_unix_us: e.stop_date().and_then(unix_micros),
                    },
                );
            }
            match page.next_token() {
                Some(next) if token.as_deref() != Some(next) => token = Some(next.to_owned()),
                _ => break,
            }
        }
        Ok(out)
    }

    /// Stops the execution of `job` with `error` and `cause` (at most 256 and 32768 characters);
    /// it ends `Aborted`. Stopping a finished execution is not an error on AWS.
    pub async fn stop(&self, job: &JobId, error: &str, cause: &str) -> Result<(), AwsError> {
        self.client
            .stop_execution()
            .execution_arn(self.execution_arn(job))
            .error(error)
            .cause(cause)
            .send()
            .await
            .map_err(|e| {
                classify(
                    e,
                    &format!("stop execution {:?}", job.as_str()),
                    SERVICE,
                    &self.endpoint,
                )
            })?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn execution_arns_follow_from_the_state_machine_and_the_job() {
        let config = aws_sdk_sfn::Config::builder()
            .behavior_version(aws_sdk_sfn::config::BehaviorVersion::latest())
            .build();
        let executions = Executions::new(
            Client::from_conf(config),
            "arn:aws:states:eu-west-1:123456789012:stateMachine:hort-jobs",
            "AWS (eu-west-1)",
        );
        assert_eq!(
            executions.execution_arn(&JobId::new("job-7").unwrap()),
            "arn:aws:states:eu-west-1:123456789012:execution:hort-jobs:job-7"
        );
    }

    #[test]
    fn a_map_runs_label_is_its_map_states_name() {
        assert_eq!(
            map_run_label(
                "arn:aws:states:eu-west-1:123456789012:mapRun:hort-jobs/CastMapRerun:7f0c-1"
            ),
            "CastMapRerun"
        );
    }

    #[test]
    fn input_is_the_documented_json() {
        let input = ExecutionInput {
            job: JobId::new("j1").unwrap(),
            bucket: "b".into(),
        };
        assert_eq!(
            serde_json::to_string(&input).unwrap(),
            r#"{"job":"j1","bucket":"b"}"#
        );
        let bad = serde_json::from_str::<ExecutionInput>(r#"{"job":"J!","bucket":"b"}"#);
        assert!(bad.is_err());
    }
}
