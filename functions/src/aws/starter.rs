//! The Starter function's logic: each SQS message of a batch is one job
//! ([`ExecutionInput`] as JSON) and becomes the execution named by its job id. The answer lists
//! the messages that failed (`ReportBatchItemFailures`), so SQS deletes the others and makes only
//! the failed ones visible again; after the queue's `maxReceiveCount` receives a message moves to
//! the dead-letter queue.
//!
//! A message whose execution exists already is handled (SQS delivers at least once). A message
//! that is not a job for this deployment's bucket is reported failed too, so that it ends in
//! the dead-letter queue where it can be seen, rather than being dropped.

use aws_lambda_events::event::sqs::{SqsBatchResponse, SqsEvent, SqsMessage};

use super::sfn::{ExecutionInput, Executions};

/// Starts the execution of every job message of `event`; `bucket` is the deployment's bucket.
/// Logs one line per message (standard output for started jobs, standard error for failures).
pub async fn start_batch(
    executions: &Executions,
    bucket: &str,
    event: &SqsEvent,
) -> SqsBatchResponse {
    let mut response = SqsBatchResponse::default();
    for record in &event.records {
        // Without an id the failure cannot be named: an empty identifier makes Lambda retry the
        // whole batch, which is the safe reading.
        let id = record.message_id.clone().unwrap_or_default();
        match start_one(executions, bucket, record).await {
            Ok(line) => println!("starter: message {id}: {line}"),
            Err(cause) => {
                eprintln!("starter: message {id} failed: {cause}");
                response.add_failure(id);
            }
        }
    }
    response
}

/// Starts the job of one message; the log line on success, the cause on failure.
async fn start_one(
    executions: &Executions,
    bucket: &str,
    record: &SqsMessage,
) -> Result<String, String> {
    let body = record.body.as_deref().unwrap_or("");
    let input: ExecutionInput = serde_json::from_str(body)
        .map_err(|e| format!("not a job message ({e}): {}", excerpt(body)))?;
    if input.bucket != bucket {
        return Err(format!(
            "job {} names bucket {:?}, this deployment serves {bucket:?}",
            input.job, input.bucket
        ));
    }
    let started = executions.start(&input).await.map_err(|e| e.to_string())?;
    Ok(if started.already_started {
        format!(
            "job {} already has execution {}",
            input.job, started.execution_arn
        )
    } else {
        format!("job {} started as {}", input.job, started.execution_arn)
    })
}

/// The first 200 characters of `body`, for log lines.
fn excerpt(body: &str) -> String {
    let mut text: String = body.chars().take(200).collect();
    if text.len() < body.len() {
        text.push_str("...");
    }
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}
