//! The SQS and Step Functions wrappers (`hort_functions::aws`) and the Starter function's batch
//! logic against a real server: moto, started by `tests/s3-servers/with-moto.sh`, which sets
//! `HORT_TEST_AWS_ENDPOINT`:
//!
//!     bash tests/s3-servers/with-moto.sh cargo test -p hort-tests --test it aws_moto:: -- --nocapture
//!
//! The API's deployment backend is driven through the router (`hort_functions::api::handle`).
//! Without that variable the moto tests say they are skipped and pass, unless
//! `HORT_TEST_INTEGRATION` is set (then they fail); `.ci/run` sets it and runs them under
//! `with-moto.sh`. moto keeps real time: visibility timeouts expire, and a message received
//! `maxReceiveCount` times moves to the dead-letter queue on the next receive. moto records
//! Step Functions executions (start, describe, stop) but does not run the state machine.

use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Duration;

use hort_core::ids::JobId;
use hort_core::store::BlobStore;
use hort_functions::S3Credentials;
use hort_functions::aws::aws_lambda_events::event::sqs::{SqsEvent, SqsMessage};
use hort_functions::aws::aws_sdk_sqs::types::QueueAttributeName;
use hort_functions::aws::starter::start_batch;
use hort_functions::aws::{
    AwsErrorKind, AwsSettings, ExecutionInput, ExecutionStatus, Executions, JobQueue,
    ReceivedMessage, aws_sdk_sfn, aws_sdk_sqs,
};

const ROLE_ARN: &str = "arn:aws:iam::123456789012:role/hort-state-machine";

/// The moto server's SDK configuration, or `None` (after saying so) without
/// `HORT_TEST_AWS_ENDPOINT`.
async fn moto() -> Option<(hort_functions::aws::SdkConfig, String)> {
    let endpoint = hort_tests::integration_endpoint(
        "HORT_TEST_AWS_ENDPOINT",
        "see tests/s3-servers/with-moto.sh",
    )?;
    println!("AWS endpoint (SQS, Step Functions): {endpoint}");
    let settings = AwsSettings {
        endpoint: Some(endpoint),
        region: Some("us-east-1".into()),
        credentials: S3Credentials::Static {
            access_key: "testing".into(),
            secret_key: "testing".into(),
        },
    };
    let config = settings.sdk_config().await;
    let label = AwsSettings::label(&config);
    Some((config, label))
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("tokio runtime")
}

/// A name no other test of this run (nor an earlier run on the same server) uses.
fn unique(prefix: &str) -> String {
    static N: AtomicU32 = AtomicU32::new(0);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .subsec_nanos();
    format!(
        "{prefix}-{}-{}-{nanos}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    )
}

fn input(job: &str, bucket: &str) -> ExecutionInput {
    ExecutionInput {
        job: JobId::new(job).unwrap(),
        bucket: bucket.into(),
    }
}

/// Creates queue `name` with `attributes`; returns its wrapper.
async fn queue(
    client: &aws_sdk_sqs::Client,
    label: &str,
    name: &str,
    attributes: &[(QueueAttributeName, String)],
) -> JobQueue {
    let mut create = client.create_queue().queue_name(name);
    for (key, value) in attributes {
        create = create.attributes(key.clone(), value);
    }
    create.send().await.expect("create queue");
    JobQueue::by_name(client.clone(), name, label)
        .await
        .expect("queue URL")
}

/// The state machine of `infra/statemachine.asl.json` with placeholder function ARNs.
async fn state_machine(client: &aws_sdk_sfn::Client, name: &str) -> String {
    let definition = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../infra/statemachine.asl.json"
    ))
    .expect("state machine file")
    .replace(
        "${PlanFunctionArn}",
        "arn:aws:lambda:us-east-1:123456789012:function:hort-plan",
    )
    .replace(
        "${WorkerFunctionArn}",
        "arn:aws:lambda:us-east-1:123456789012:function:hort-worker",
    );
    assert!(!definition.contains("${"), "every placeholder substituted");
    client
        .create_state_machine()
        .name(name)
        .definition(definition)
        .role_arn(ROLE_ARN)
        .send()
        .await
        .expect("create state machine")
        .state_machine_arn
}

/// The SQS records of a Lambda event for `messages`.
fn sqs_event(messages: &[ReceivedMessage]) -> SqsEvent {
    let mut event = SqsEvent::default();
    for m in messages {
        let mut record = SqsMessage::default();
        record.message_id = Some(m.message_id.clone());
        record.receipt_handle = Some(m.receipt_handle.clone());
        record.body = Some(m.body.clone());
        record.event_source = Some("aws:sqs".into());
        event.records.push(record);
    }
    event
}

#[test]
fn a_message_that_keeps_failing_lands_in_the_dead_letter_queue() {
    runtime().block_on(async {
        let Some((config, label)) = moto().await else {
            return;
        };
        let client = aws_sdk_sqs::Client::new(&config);
        let dlq = queue(&client, &label, &unique("hort-dlq"), &[]).await;
        let dlq_arn = client
            .get_queue_attributes()
            .queue_url(dlq.url())
            .attribute_names(QueueAttributeName::QueueArn)
            .send()
            .await
            .expect("DLQ attributes")
            .attributes
            .and_then(|a| a.get(&QueueAttributeName::QueueArn).cloned())
            .expect("DLQ ARN");
        let redrive = format!(r#"{{"deadLetterTargetArn":"{dlq_arn}","maxReceiveCount":"2"}}"#);
        let intake = queue(
            &client,
            &label,
            &unique("hort-intake"),
            &[
                (QueueAttributeName::VisibilityTimeout, "1".into()),
                (QueueAttributeName::RedrivePolicy, redrive),
            ],
        )
        .await;

        let failing = input("job-fails", "b");
        let handled = input("job-ok", "b");
        intake.enqueue(&failing).await.expect("enqueue");
        intake.enqueue(&handled).await.expect("enqueue");
        let first = intake.receive(10, Duration::ZERO).await.expect("receive");
        assert_eq!(first.len(), 2, "{first:?}");
        for m in &first {
            assert_eq!(m.receive_count, 1);
            let body: ExecutionInput = serde_json::from_str(&m.body).expect("a job message");
            if body == handled {
                intake.delete(&m.receipt_handle).await.expect("delete");
            } else {
                assert_eq!(body, failing);
            }
        }
        // Within the visibility timeout nothing is visible: one message is deleted, the other
        // is in flight.
        let hidden = intake.receive(10, Duration::ZERO).await.expect("receive");
        assert_eq!(hidden, []);

        tokio::time::sleep(Duration::from_millis(1500)).await;
        let second = intake.receive(10, Duration::ZERO).await.expect("receive");
        assert_eq!(second.len(), 1, "the undeleted message is back: {second:?}");
        assert_eq!(second[0].receive_count, 2);
        assert_eq!(
            second[0].message_id,
            first
                .iter()
                .find(|m| m.body == second[0].body)
                .unwrap()
                .message_id
        );

        // Received maxReceiveCount (2) times and not deleted: the next receive moves it.
        tokio::time::sleep(Duration::from_millis(1500)).await;
        let third = intake.receive(10, Duration::ZERO).await.expect("receive");
        assert_eq!(third, [], "the message left the intake queue");
        let dead = dlq.receive(10, Duration::ZERO).await.expect("receive DLQ");
        assert_eq!(dead.len(), 1, "{dead:?}");
        let body: ExecutionInput = serde_json::from_str(&dead[0].body).expect("a job message");
        assert_eq!(body, failing);
    });
}

#[test]
fn executions_are_named_by_job_and_start_at_most_once() {
    runtime().block_on(async {
        let Some((config, label)) = moto().await else {
            return;
        };
        let client = aws_sdk_sfn::Client::new(&config);
        let arn = state_machine(&client, &unique("hort-jobs")).await;
        let executions = Executions::new(client.clone(), &arn, &label);
        let job = JobId::new("render-1").unwrap();
        let request = input("render-1", "bucket-a");

        let started = executions.start(&request).await.expect("start");
        assert_eq!(started.execution_arn, executions.execution_arn(&job));
        assert!(!started.already_started);
        // The same start again (a redelivered message): the same execution, no second one.
        let again = executions.start(&request).await.expect("start again");
        assert_eq!(again.execution_arn, started.execution_arn);
        // Another input under the same name: the name is taken, which is success.
        let other = executions
            .start(&input("render-1", "bucket-b"))
            .await
            .expect("start with other input");
        assert!(other.already_started);
        assert_eq!(other.execution_arn, started.execution_arn);
        let listed = client
            .list_executions()
            .state_machine_arn(&arn)
            .send()
            .await
            .expect("list executions")
            .executions;
        assert_eq!(listed.len(), 1, "{listed:?}");

        let running = executions.describe(&job).await.expect("describe");
        assert_eq!(running.status, ExecutionStatus::Running);
        assert!(!running.status.is_final());
        assert_eq!(running.name, "render-1");
        assert_eq!(running.arn, started.execution_arn);
        let seen: ExecutionInput =
            serde_json::from_str(running.input.as_deref().expect("input")).expect("input JSON");
        assert_eq!(seen, request);

        executions
            .stop(&job, "Hort.Cancelled", "stopped by the test")
            .await
            .expect("stop");
        let stopped = executions.describe(&job).await.expect("describe");
        assert_eq!(stopped.status, ExecutionStatus::Aborted);
        assert!(stopped.status.is_final());
        let after = executions.start(&request).await.expect("start after stop");
        assert!(after.already_started, "a finished execution keeps its name");

        let missing = executions
            .describe(&JobId::new("never-started").unwrap())
            .await
            .expect_err("no such execution");
        assert_eq!(missing.kind, AwsErrorKind::NotFound, "{missing}");
        assert!(
            missing.to_string().starts_with(&format!(
                "describe execution \"never-started\": Step Functions at {label}"
            )),
            "{missing}"
        );

        let nowhere = Executions::new(
            client.clone(),
            arn.replace(":stateMachine:hort-jobs", ":stateMachine:no-such-machine"),
            &label,
        );
        let e = nowhere.start(&request).await.expect_err("no such machine");
        assert_eq!(e.kind, AwsErrorKind::NotFound, "{e}");
        assert!(!e.is_retryable());
    });
}

#[test]
fn the_starter_starts_each_job_once_and_reports_only_bad_messages() {
    runtime().block_on(async {
        let Some((config, label)) = moto().await else {
            return;
        };
        let sqs = aws_sdk_sqs::Client::new(&config);
        let sfn = aws_sdk_sfn::Client::new(&config);
        let arn = state_machine(&sfn, &unique("hort-starter")).await;
        let executions = Executions::new(sfn.clone(), &arn, &label);
        let intake = queue(&sqs, &label, &unique("hort-intake"), &[]).await;
        intake
            .enqueue(&input("job-a", "bucket"))
            .await
            .expect("enqueue");
        intake
            .enqueue(&input("job-b", "bucket"))
            .await
            .expect("enqueue");
        for body in ["not json", r#"{"job":"job-c","bucket":"elsewhere"}"#] {
            sqs.send_message()
                .queue_url(intake.url())
                .message_body(body)
                .send()
                .await
                .expect("send");
        }
        let messages = intake.receive(10, Duration::ZERO).await.expect("receive");
        assert_eq!(messages.len(), 4, "{messages:?}");
        let event = sqs_event(&messages);
        let mut bad: Vec<String> = messages
            .iter()
            .filter(|m| !m.body.contains(r#""bucket":"bucket""#))
            .map(|m| m.message_id.clone())
            .collect();
        bad.sort();

        let failed =
            |response: &hort_functions::aws::aws_lambda_events::event::sqs::SqsBatchResponse| {
                let mut ids: Vec<String> = response
                    .batch_item_failures
                    .iter()
                    .map(|f| f.item_identifier.clone())
                    .collect();
                ids.sort();
                ids
            };
        let response = start_batch(&executions, "bucket", &event).await;
        assert_eq!(failed(&response), bad);
        // The Lambda answer is the documented partial batch response.
        let json = serde_json::to_value(&response).expect("response JSON");
        assert_eq!(
            json["batchItemFailures"].as_array().map(Vec::len),
            Some(2),
            "{json}"
        );
        assert!(
            json["batchItemFailures"][0]["itemIdentifier"].is_string(),
            "{json}"
        );

        for job in ["job-a", "job-b"] {
            let execution = executions
                .describe(&JobId::new(job).unwrap())
                .await
                .expect("started");
            assert_eq!(execution.status, ExecutionStatus::Running);
        }
        // SQS delivers at least once: the same batch again starts nothing new and fails only
        // the bad messages.
        let response = start_batch(&executions, "bucket", &event).await;
        assert_eq!(failed(&response), bad);
        let listed = sfn
            .list_executions()
            .state_machine_arn(&arn)
            .send()
            .await
            .expect("list executions")
            .executions;
        assert_eq!(listed.len(), 2, "{listed:?}");
    });
}

#[test]
fn an_unreachable_endpoint_is_retryable_and_named() {
    runtime().block_on(async {
        // Port 1 on the loopback address: nothing listens there, the connection is refused.
        let settings = AwsSettings {
            endpoint: Some("http://127.0.0.1:1".into()),
            region: Some("us-east-1".into()),
            credentials: S3Credentials::Static {
                access_key: "testing".into(),
                secret_key: "testing".into(),
            },
        };
        let config = settings.sdk_config().await;
        let label = AwsSettings::label(&config);
        assert_eq!(label, "http://127.0.0.1:1");
        let queue = JobQueue::new(
            aws_sdk_sqs::Client::new(&config),
            "http://127.0.0.1:1/123456789012/q",
            &label,
        );
        let e = queue
            .enqueue(&input("j", "b"))
            .await
            .expect_err("unreachable");
        assert_eq!(e.kind, AwsErrorKind::Unavailable, "{e}");
        assert!(e.is_retryable());
        assert!(
            e.to_string()
                .starts_with("enqueue job \"j\": SQS at http://127.0.0.1:1 is unreachable"),
            "{e}"
        );
        let executions = Executions::new(
            aws_sdk_sfn::Client::new(&config),
            "arn:aws:states:us-east-1:123456789012:stateMachine:m",
            &label,
        );
        let e = executions
            .start(&input("j", "b"))
            .await
            .expect_err("unreachable");
        assert_eq!(e.kind, AwsErrorKind::Unavailable, "{e}");
    });
}

/// One request through the HTTP API's router over `backend`: (status, JSON body).
fn call(
    backend: &hort_functions::aws::api_backend::AwsBackend,
    method: &str,
    uri: &str,
    body: Option<serde_json::Value>,
    key: Option<&str>,
) -> (u16, serde_json::Value) {
    let mut request = http::Request::builder()
        .method(method)
        .uri(uri)
        .header("host", "api.example");
    if body.is_some() {
        request = request.header("content-type", "application/json");
    }
    if let Some(key) = key {
        request = request.header("idempotency-key", key);
    }
    let bytes = body.map(|b| b.to_string().into_bytes()).unwrap_or_default();
    let response = hort_functions::api::handle(backend, request.body(bytes).unwrap());
    let status = response.status().as_u16();
    let json = serde_json::from_slice(response.body()).unwrap_or(serde_json::Value::Null);
    (status, json)
}

/// The deployed API's backend over moto (a fresh intake queue and state machine, bucket
/// `bucket`), its queue and executions, and a store of the bucket for this (non-runtime) thread:
/// the backend's store blocks on `runtime`.
fn api_backend(
    runtime: &tokio::runtime::Runtime,
    config: &hort_functions::aws::SdkConfig,
    label: &str,
    bucket: &str,
) -> (
    hort_functions::aws::api_backend::AwsBackend,
    JobQueue,
    Executions,
    hort_functions::S3Store,
) {
    let endpoint = std::env::var("HORT_TEST_AWS_ENDPOINT").unwrap();
    let (backend, intake, executions) = runtime.block_on(async {
        let s3 = hort_functions::S3Config::compatible(&endpoint, bucket, "testing", "testing");
        let store = hort_functions::S3Store::connect(&s3)
            .await
            .expect("S3 client");
        let sqs = aws_sdk_sqs::Client::new(config);
        let sfn = aws_sdk_sfn::Client::new(config);
        let intake = queue(&sqs, label, &unique(&format!("{bucket}-intake")), &[]).await;
        let arn = state_machine(&sfn, &unique(&format!("{bucket}-jobs"))).await;
        let executions = Executions::new(sfn, &arn, label);
        let backend = hort_functions::aws::api_backend::AwsBackend::new(
            store,
            intake.clone(),
            executions.clone(),
            tokio::runtime::Handle::current(),
            hort_functions::aws::api_backend::DeploymentLimits {
                max_concurrency: 50,
                worker_memory_mb: 2048,
            },
        );
        (backend, intake, executions)
    });
    let store = hort_functions::S3Store::open(&hort_functions::S3Config::compatible(
        &endpoint, bucket, "testing", "testing",
    ))
    .expect("S3 client");
    store.create_bucket_if_missing().expect("bucket");
    (backend, intake, executions, store)
}

#[test]
fn the_deployment_api_backend_queues_starts_reports_and_cancels_jobs() {
    let runtime = runtime();
    let Some((config, label)) = runtime.block_on(moto()) else {
        return;
    };
    let bucket = unique("hort-api");
    let (backend, intake, executions, store) = api_backend(&runtime, &config, &label, &bucket);
    let triangle = serde_json::json!({
        "scene": {"main": "a.obj", "files": {"a.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"}},
        "width": 32, "height": 24
    });

    let (status, accepted) = call(
        &backend,
        "POST",
        "/renders",
        Some(triangle.clone()),
        Some("k1"),
    );
    assert_eq!(status, 202, "{accepted}");
    let job = accepted["job"].as_str().expect("job id").to_owned();
    let job_id = JobId::new(&job).unwrap();
    let (status, again) = call(
        &backend,
        "POST",
        "/renders",
        Some(triangle.clone()),
        Some("k1"),
    );
    assert!(status < 300, "{status} {again}");
    assert_eq!(
        again["job"], accepted["job"],
        "the idempotency key names the first job"
    );
    let mut other = triangle.clone();
    other["width"] = serde_json::json!(16);
    let (status, reused) = call(&backend, "POST", "/renders", Some(other), Some("k1"));
    assert_eq!(
        (status, &reused["error"]["code"]),
        (422, &serde_json::json!("idempotency_key_reused")),
        "the key with another body: {reused}"
    );
    // The job is stored as the Plan function reads it.
    let manifest: hort_functions::handlers::JobRequest =
        serde_json::from_slice(&store.get(&format!("jobs/{job}/manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest.scene, "a.obj");
    assert_eq!(manifest.max_concurrency, 50);
    assert_eq!((manifest.render.width, manifest.render.height), (32, 24));
    // The scene the API parsed, stored once as scene.bin: the Plan function decodes it and
    // never parses the OBJ again (so the OBJ itself is not stored).
    assert_eq!(
        manifest.scene_format,
        hort_functions::handlers::SceneFormat::Binary
    );
    let key = format!("jobs/{job}/scene/scene.bin");
    let scene = hort_core::scene::decode_scene(&key, &store.get(&key).unwrap()).unwrap();
    assert_eq!(scene.mesh.triangle_count(), 1);
    assert!(store.get(&format!("jobs/{job}/scene/a.obj")).is_err());

    let (status, queued) = call(&backend, "GET", &format!("/renders/{job}"), None, None);
    assert_eq!(
        (status, queued["status"].as_str()),
        (200, Some("QUEUED")),
        "{queued}"
    );
    let (status, _) = call(
        &backend,
        "GET",
        &format!("/renders/{job}/image"),
        None,
        None,
    );
    assert_eq!(status, 404, "no image before the job succeeds");
    let (status, _) = call(&backend, "GET", "/renders/r-nosuchjob", None, None);
    assert_eq!(status, 404);

    // The Starter takes the queued message(s): one execution, named by the job.
    let messages = runtime
        .block_on(intake.receive(10, Duration::ZERO))
        .expect("receive");
    assert!(!messages.is_empty());
    let response = runtime.block_on(start_batch(&executions, &bucket, &sqs_event(&messages)));
    assert!(response.batch_item_failures.is_empty(), "{response:?}");
    let (_, running) = call(&backend, "GET", &format!("/renders/{job}"), None, None);
    assert_eq!(running["status"], "RUNNING", "{running}");

    // Cancelling stops the execution and deletes intermediate objects, keeping the request.
    let block = hort_core::keys::partition_key(
        &job_id,
        hort_core::stage::Stage::CastMap,
        hort_core::ids::TaskId(0),
        hort_core::ids::PartitionId(0),
    );
    store.put(&block, b"block").unwrap();
    // Progress comes from the execution's Map Runs, not from listing the job's objects; moto
    // records executions without running them, so this one is still planning.
    let (_, progress) = call(&backend, "GET", &format!("/renders/{job}"), None, None);
    assert_eq!(progress["tasks_done"], 0, "{progress}");
    assert_eq!(progress["stage"], "plan", "{progress}");
    let (status, cancelled) = call(&backend, "DELETE", &format!("/renders/{job}"), None, None);
    assert_eq!(
        (status, cancelled["status"].as_str()),
        (200, Some("CANCELLED")),
        "{cancelled}"
    );
    assert!(store.get(&block).unwrap_err().is_not_found());
    assert!(store.get(&format!("jobs/{job}/manifest.json")).is_ok());
    let described = runtime.block_on(executions.describe(&job_id)).unwrap();
    assert_eq!(described.status, ExecutionStatus::Aborted);

    // A job cancelled while queued never runs: its message later starts nothing.
    let (_, second) = call(&backend, "POST", "/renders", Some(triangle.clone()), None);
    let second = second["job"].as_str().expect("job id").to_owned();
    assert_ne!(second, job);
    let (_, cancelled) = call(
        &backend,
        "DELETE",
        &format!("/renders/{second}"),
        None,
        None,
    );
    assert_eq!(cancelled["status"], "CANCELLED", "{cancelled}");
    let messages = runtime
        .block_on(intake.receive(10, Duration::ZERO))
        .expect("receive");
    let response = runtime.block_on(start_batch(&executions, &bucket, &sqs_event(&messages)));
    assert!(response.batch_item_failures.is_empty(), "{response:?}");
    let (_, still) = call(&backend, "GET", &format!("/renders/{second}"), None, None);
    assert_eq!(still["status"], "CANCELLED", "{still}");
    let (status, report) = call(
        &backend,
        "GET",
        &format!("/renders/{second}/report"),
        None,
        None,
    );
    assert_eq!(status, 404, "{report}");

    // The first job's objects expire (the bucket's lifecycle rule) while its execution's name
    // stays taken: its key can start nothing new, and says so.
    let record = format!("jobs/{job}/api.json");
    store.delete(&record).unwrap();
    let (status, expired) = call(&backend, "POST", "/renders", Some(triangle), Some("k1"));
    assert_eq!(status, 422, "{expired}");
    assert_eq!(
        expired["error"]["message"],
        format!(
            "Idempotency-Key \"k1\" named job {job}, whose objects have expired (the bucket \
             deletes jobs/ after JobExpirationDays) while Step Functions keeps its execution's \
             name for 90 days: use a new key"
        )
    );
    assert!(store.get(&record).unwrap_err().is_not_found());
}

#[test]
fn the_deployment_api_lists_a_thousand_jobs_within_api_gateways_30_seconds() {
    let runtime = runtime();
    let Some((config, label)) = runtime.block_on(moto()) else {
        return;
    };
    let bucket = unique("hort-list");
    let (backend, _, executions, store) = api_backend(&runtime, &config, &label, &bucket);
    // 1,000 jobs as the API stores them (its record), each with 4 intermediate objects a
    // listing of every key would have to page through, and a folder the API did not make.
    const JOBS: usize = 1000;
    let mut objects = Vec::new();
    for i in 0..JOBS {
        let job = format!("r-{i:04}");
        let record = serde_json::json!({
            "job": job, "scene": "a.obj", "tasks_total": 9, "predicted_cost_usd": 0.001,
            "predicted_seconds": 2.0, "created_unix_us": 1_000_000 + i as u64,
            "idempotency_key": null, "max_cost_usd": null
        });
        objects.push((
            format!("jobs/{job}/api.json"),
            record.to_string().into_bytes(),
        ));
        for block in 0..4 {
            objects.push((format!("jobs/{job}/cast-map/{block}/part-0"), b"b".to_vec()));
        }
    }
    objects.push(("jobs/from-the-cli/manifest.json".into(), b"{}".to_vec()));
    for result in store.put_many(&objects) {
        result.expect("put");
    }
    let running = JobId::new("r-0999").unwrap();
    runtime
        .block_on(executions.start(&input(running.as_str(), &bucket)))
        .expect("start");

    let started = std::time::Instant::now();
    let (status, listed) = call(&backend, "GET", "/renders?limit=1000", None, None);
    let took = started.elapsed();
    println!("GET /renders?limit=1000 over {JOBS} jobs of 5 objects each: {took:?}");
    assert_eq!(status, 200, "{listed}");
    let renders = listed["renders"].as_array().expect("renders");
    assert_eq!(renders.len(), JOBS);
    assert_eq!(renders[0]["job"], "r-0999", "newest first");
    assert_eq!(renders[0]["status"], "RUNNING");
    assert_eq!(renders[0]["stage"], "plan");
    assert_eq!(renders[JOBS - 1]["job"], "r-0000");
    assert!(renders[1..].iter().all(|r| r["status"] == "QUEUED"));
    assert!(
        took < Duration::from_secs(hort_aws_quotas::HTTP_API_INTEGRATION_SECONDS),
        "the list took {took:?}, past API Gateway's integration timeout"
    );
    let (_, one) = call(&backend, "GET", "/renders?limit=1", None, None);
    assert_eq!(one["renders"][0]["job"], "r-0999", "{one}");
}

#[test]
fn a_scene_by_key_is_sized_by_the_api_and_copied_into_its_job_by_the_plan_function() {
    let runtime = runtime();
    let Some((config, label)) = runtime.block_on(moto()) else {
        return;
    };
    let bucket = unique("hort-key");
    let (backend, _intake, _executions, store) = api_backend(&runtime, &config, &label, &bucket);
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/cornell");
    for file in ["cornell.json", "cornell.obj", "cornell.mtl"] {
        let bytes = std::fs::read(format!("{dir}/{file}")).unwrap();
        // A space in the key: CopyObject's source must be URL-encoded.
        store.put(&format!("scenes/my box/{file}"), &bytes).unwrap();
    }
    let body = serde_json::json!({
        "scene": {"key": "scenes/my box/cornell.json"}, "width": 32, "height": 24,
        "max_cost_usd": 1.0
    });
    let (status, accepted) = call(&backend, "POST", "/renders", Some(body), None);
    assert_eq!(status, 202, "{accepted}");
    let job = accepted["job"].as_str().expect("job id").to_owned();
    // Only the request is stored: the scene stays where it is until the Plan function runs.
    let manifest: hort_functions::handlers::JobRequest =
        serde_json::from_slice(&store.get(&format!("jobs/{job}/manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest.scene, "cornell.json");
    assert_eq!(
        manifest.scene_key.as_deref(),
        Some("scenes/my box/cornell.json")
    );
    assert_eq!(
        manifest.scene_format,
        hort_functions::handlers::SceneFormat::Files
    );
    let budget = manifest.budget.expect("the budget to check again");
    assert_eq!(budget.max_cost_usd, 1.0);
    assert_eq!(
        (budget.model.concurrency, budget.model.memory_mb),
        (50, 2048)
    );
    assert!(
        store
            .list(&format!("jobs/{job}/scene/"))
            .unwrap()
            .is_empty()
    );

    // The Plan function copies the files (CopyObject on moto) and plans the job.
    let event = hort_functions::handlers::PlanEvent {
        job: JobId::new(&job).unwrap(),
        bucket: bucket.clone(),
        attempt: 0,
        round: 1,
        step: hort_functions::handlers::PlanStep::Start,
    };
    let tmp = tempfile::tempdir().unwrap();
    hort_functions::handlers::handle_plan(
        &store,
        &bucket,
        &event,
        hort_functions::handlers::Tmp::unlimited(tmp.path()),
    )
    .expect("plan");
    assert_eq!(
        store.list(&format!("jobs/{job}/scene/")).unwrap(),
        ["cornell.json", "cornell.mtl", "cornell.obj"].map(|f| format!("jobs/{job}/scene/{f}"))
    );
    for file in ["cornell.json", "cornell.mtl", "cornell.obj"] {
        assert_eq!(
            store.get(&format!("jobs/{job}/scene/{file}")).unwrap(),
            store.get(&format!("scenes/my box/{file}")).unwrap(),
            "{file}"
        );
    }
    assert!(store.get(&format!("jobs/{job}/plan.json")).is_ok());
}
