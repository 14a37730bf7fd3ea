//! Many clients at once against `hort serve` on loopback: every submission ends as exactly one
//! job (none lost, none duplicated, whatever 429s and repeated keys happen on the way), every
//! job renders the same bytes, and the server's memory stays bounded. The latency of
//! `POST /renders` is printed (a measurement, not an assertion).

use crate::common;

use common::scratch;
use common::server::{Serve, cornell};
use serde_json::json;
use std::collections::{BTreeMap, BTreeSet};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Clients posting at once.
const CLIENTS: usize = 16;
/// Distinct jobs (idempotency keys); each key is posted by two different clients.
const KEYS: usize = 48;
/// Tries of one post at most (100 ms apart) before the test fails: a refusal that never ends.
const MAX_ATTEMPTS: u32 = 1200;
/// The server's peak resident memory may not exceed this.
const MEMORY_BOUND_KIB: u64 = 1 << 20;

/// Peak resident memory of a process, KiB (`VmHWM` of `/proc/PID/status`).
fn peak_rss_kib(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap_or_else(|| panic!("no VmHWM in /proc/{pid}/status"))
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

#[test]
fn concurrent_submissions_become_exactly_one_job_each() {
    let dir = scratch("serve-load");
    let server = Arc::new(Serve::start_with(&dir, &["--max-jobs", "8"]));
    let body = json!({
        "scene": cornell(), "width": 32, "height": 24, "spp": 1, "splits": 2, "spans": 2,
    });

    // Client c posts keys c, c + CLIENTS, ... and then the next client's keys again, so every
    // key is sent twice, by two clients, at about the same time. A 429 (the server runs as
    // many jobs as it takes) and API Gateway's 500 (more requests at once than the API
    // function's reserved concurrency: Lambda throttled it, so it never ran) are retried with
    // the same key after a short pause, as a client following the message would, a bounded
    // number of times.
    let answers: Arc<Mutex<Vec<(usize, String, f64)>>> = Arc::default();
    let refused = Arc::new(Mutex::new(0u32));
    let clients: Vec<_> = (0..CLIENTS)
        .map(|c| {
            let (server, body, answers, refused) = (
                Arc::clone(&server),
                body.clone(),
                Arc::clone(&answers),
                Arc::clone(&refused),
            );
            std::thread::spawn(move || {
                let own = (c..KEYS).step_by(CLIENTS);
                let neighbour = ((c + 1) % CLIENTS..KEYS).step_by(CLIENTS);
                for key in own.chain(neighbour) {
                    let header = format!("load-{key}");
                    for attempt in 0.. {
                        assert!(
                            attempt < MAX_ATTEMPTS,
                            "key {key}: refused {MAX_ATTEMPTS} times"
                        );
                        let t0 = Instant::now();
                        let reply = server.post("/renders", &body, &[("Idempotency-Key", &header)]);
                        let ms = t0.elapsed().as_secs_f64() * 1e3;
                        let throttled = reply.status == 500
                            && reply.body
                                == hort_aws_quotas::API_GATEWAY_INTERNAL_ERROR_BODY.as_bytes();
                        if reply.status == 429 || throttled {
                            *refused.lock().unwrap() += 1;
                            std::thread::sleep(Duration::from_millis(100));
                            continue;
                        }
                        assert_eq!(
                            reply.status,
                            202,
                            "key {key}: {}",
                            String::from_utf8_lossy(&reply.body)
                        );
                        let job = reply.json()["job"].as_str().unwrap().to_owned();
                        answers.lock().unwrap().push((key, job, ms));
                        break;
                    }
                }
            })
        })
        .collect();
    for client in clients {
        client.join().unwrap();
    }

    let answers = answers.lock().unwrap().clone();
    assert_eq!(answers.len(), 2 * KEYS, "every post got an answer");
    let mut jobs_of_key: BTreeMap<usize, BTreeSet<String>> = BTreeMap::new();
    for (key, job, _) in &answers {
        jobs_of_key.entry(*key).or_default().insert(job.clone());
    }
    for (key, jobs) in &jobs_of_key {
        assert_eq!(jobs.len(), 1, "key {key} named several jobs: {jobs:?}");
    }
    let jobs: BTreeSet<String> = jobs_of_key.values().flatten().cloned().collect();
    assert_eq!(jobs.len(), KEYS, "one job per key, none shared");

    // The server lists exactly these jobs, and every one renders the same bytes.
    let listed = server.get("/renders?limit=1000").json();
    let listed: BTreeSet<String> = listed["renders"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["job"].as_str().unwrap().to_owned())
        .collect();
    assert_eq!(listed, jobs, "the listing holds exactly the submitted jobs");
    let mut images = BTreeSet::new();
    for job in &jobs {
        let done = server.wait_done(job, Duration::from_secs(300));
        assert_eq!(done["status"], "SUCCEEDED", "{done}");
        let image = server.get(&format!("/renders/{job}/image?format=pfm"));
        assert_eq!(image.status, 200);
        images.insert(image.body);
    }
    assert_eq!(images.len(), 1, "every job rendered the same bytes");

    let peak = peak_rss_kib(server.child.id());
    let mut latencies: Vec<f64> = answers.iter().map(|(_, _, ms)| *ms).collect();
    latencies.sort_by(f64::total_cmp);
    eprintln!(
        "{} posts from {CLIENTS} clients ({} answered 429 or were throttled and were sent again): POST /renders \
         latency p50 {:.1} ms, p99 {:.1} ms, max {:.1} ms; server peak memory {} MiB",
        answers.len(),
        refused.lock().unwrap(),
        percentile(&latencies, 0.5),
        percentile(&latencies, 0.99),
        latencies[latencies.len() - 1],
        peak / 1024
    );
    assert!(
        peak < MEMORY_BOUND_KIB,
        "server peak memory {peak} KiB is over {MEMORY_BOUND_KIB} KiB"
    );
    drop(server);
    std::fs::remove_dir_all(&dir).unwrap();
}
