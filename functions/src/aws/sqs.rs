//! [`JobQueue`]: the job intake queue. A message is one [`ExecutionInput`] as JSON
//! (`{"job": ..., "bucket": ...}`); the Starter function turns it into an execution.

use std::time::Duration;

use aws_sdk_sqs::Client;
use aws_sdk_sqs::types::MessageSystemAttributeName;

use super::error::{AwsError, AwsErrorKind, classify};
use super::sfn::ExecutionInput;

const SERVICE: &str = "SQS";

/// One SQS queue of job messages.
#[derive(Debug, Clone)]
pub struct JobQueue {
    client: Client,
    queue_url: String,
    endpoint: String,
}

/// A message as [`JobQueue::receive`] returns it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReceivedMessage {
    /// The message id (the `itemIdentifier` of a partial batch failure).
    pub message_id: String,
    /// What [`JobQueue::delete`] needs.
    pub receipt_handle: String,
    /// The body as sent.
    pub body: String,
    /// How many times the message has been received, this time included.
    pub receive_count: u32,
}

impl JobQueue {
    /// The queue at `queue_url`, through `client`; `endpoint` names the server in messages
    /// ([`super::AwsSettings::label`]).
    pub fn new(client: Client, queue_url: impl Into<String>, endpoint: impl Into<String>) -> Self {
        JobQueue {
            client,
            queue_url: queue_url.into(),
            endpoint: endpoint.into(),
        }
    }

    /// The queue named `name` (GetQueueUrl).
    pub async fn by_name(
        client: Client,
        name: &str,
        endpoint: impl Into<String>,
    ) -> Result<Self, AwsError> {
        let endpoint = endpoint.into();
        let out = client
            .get_queue_url()
            .queue_name(name)
            .send()
            .await
            .map_err(|e| classify(e, &format!("find queue {name:?}"), SERVICE, &endpoint))?;
        let url = out.queue_url.ok_or_else(|| AwsError {
            kind: AwsErrorKind::Other,
            what: format!("find queue {name:?}: {SERVICE} at {endpoint} answered without a URL"),
        })?;
        Ok(Self::new(client, url, endpoint))
    }

    /// The queue's URL.
    pub fn url(&self) -> &str {
        &self.queue_url
    }

    /// The SDK client, for what this wrapper does not cover.
    pub fn client(&self) -> &Client {
        &self.client
    }

    /// Sends the job message `input`; returns the message id.
    pub async fn enqueue(&self, input: &ExecutionInput) -> Result<String, AwsError> {
        let op = format!("enqueue job {:?}", input.job.as_str());
        let body = serde_json::to_string(input).map_err(|e| AwsError {
            kind: AwsErrorKind::Invalid,
            what: format!("{op}: cannot encode the message: {e}"),
        })?;
        let out = self
            .client
            .send_message()
            .queue_url(&self.queue_url)
            .message_body(body)
            .send()
            .await
            .map_err(|e| classify(e, &op, SERVICE, &self.endpoint))?;
        Ok(out.message_id.unwrap_or_default())
    }

    /// Receives up to `max` messages (1 to 10), waiting up to `wait` (at most 20 s) for the
    /// first. Each stays invisible for the queue's visibility timeout unless deleted.
    pub async fn receive(
        &self,
        max: i32,
        wait: Duration,
    ) -> Result<Vec<ReceivedMessage>, AwsError> {
        let out = self
            .client
            .receive_message()
            .queue_url(&self.queue_url)
            .max_number_of_messages(max.clamp(1, 10))
            .wait_time_seconds(wait.as_secs().min(20) as i32)
            .message_system_attribute_names(MessageSystemAttributeName::ApproximateReceiveCount)
            .send()
            .await
            .map_err(|e| classify(e, "receive messages", SERVICE, &self.endpoint))?;
        Ok(out
            .messages
            .unwrap_or_default()
            .into_iter()
            .map(|m| {
                let receive_count = m
                    .attributes
                    .as_ref()
                    .and_then(|a| a.get(&MessageSystemAttributeName::ApproximateReceiveCount))
                    .and_then(|n| n.parse().ok())
                    .unwrap_or(0);
                ReceivedMessage {
                    message_id: m.message_id.unwrap_or_default(),
                    receipt_handle: m.receipt_handle.unwrap_or_default(),
                    body: m.body.unwrap_or_default(),
                    receive_count,
                }
            })
            .collect())
    }

    /// Deletes a received message (it was handled).
    pub async fn delete(&self, receipt_handle: &str) -> Result<(), AwsError> {
        self.client
            .delete_message()
            .queue_url(&self.queue_url)
            .receipt_handle(receipt_handle)
            .send()
            .await
            .map_err(|e| classify(e, "delete message", SERVICE, &self.endpoint))?;
        Ok(())
    }
}
