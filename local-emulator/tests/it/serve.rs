//! `hort serve` over loopback, as a client sees it (the harness: `common/server.rs`).

use crate::common;

use common::server::{Reply, Serve, call, cornell, scenes};
use common::{HORT, hort, scratch, stderr};
use hort_functions::api::usd;
use serde_json::{Value, json};
use std::io::Write;
use std::net::TcpStream;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

/// The bundled Cornell box rendered with `--monolithic` into `dir/file` (its extension chooses
/// the format), with `args`: the file's bytes.
fn monolithic(dir: &Path, file: &str, args: &[&str]) -> Vec<u8> {
    let out = dir.join(file);
    let scene = scenes().join("cornell/cornell.json");
    let o = Command::new(HORT)
        .args(["render", scene.to_str().unwrap(), "--monolithic", "--out"])
        .arg(&out)
        .args(args)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::read(out).unwrap()
}

/// Files under `dir`, relative, sorted.
/// What a cancelled job keeps (the embedded S3 server's files): the request, the scene and
/// the API's records, as a deployment's cancel keeps them.
const KEPT_ON_CANCEL: [&str; 4] = [
    "api.json~obj",
    "execution.json~obj",
    "manifest.json~obj",
    "scene/scene.bin~obj",
];

fn files_under(dir: &Path) -> Vec<String> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<String>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for e in entries.flatten() {
            let path = e.path();
            if path.is_dir() {
                walk(root, &path, out);
            } else {
                out.push(path.strip_prefix(root).unwrap().display().to_string());
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out);
    out.sort();
    out
}

#[test]
fn a_render_equals_the_monolithic_one_and_outlives_the_server() {
    let dir = scratch("render");
    let data = dir.join("data");
    let server = Serve::start(&data);
    let body = json!({
        "scene": cornell(), "width": 64, "height": 48, "spp": 2, "splits": 2, "spans": 3
    });

    let dry = server.post("/renders?dry_run=true", &body, &[]);
    assert_eq!(dry.status, 200, "{}", String::from_utf8_lossy(&dry.body));
    let dry = dry.json();
    assert_eq!(
        (dry["splits"].as_u64(), dry["spans"].as_u64()),
        (Some(2), Some(3))
    );
    assert!(
        !data.join("hort/jobs").exists() && !data.join("hort/api").exists(),
        "a dry run stores nothing"
    );

    let t0 = Instant::now();
    let key = [("Idempotency-Key", "cornell-64x48")];
    let first = server.post("/renders", &body, &key);
    assert_eq!(
        first.status,
        202,
        "{}",
        String::from_utf8_lossy(&first.body)
    );
    let first = first.json();
    let job = first["job"].as_str().unwrap().to_owned();
    assert_eq!(first["status_url"], format!("/renders/{job}"));
    assert_eq!(first["replayed"], false);
    let again = server.post("/renders", &body, &key);
    assert_eq!(again.status, 202);
    assert_eq!(
        again.json()["job"],
        job.as_str(),
        "the same key names the same job"
    );
    assert_eq!(again.json()["replayed"], true);
    // The same key with another body is no retry: 422 naming the key and the job, nothing
    // started (IETF Idempotency-Key draft).
    let mut other = body.clone();
    other["width"] = json!(32);
    let reused = server.post("/renders", &other, &key);
    assert_eq!(
        (reused.status, reused.json()),
        (
            422,
            serde_json::json!({"error": {"code": "idempotency_key_reused",
            "field": "headers.Idempotency-Key",
            "message": format!("Idempotency-Key \"cornell-64x48\" was used for job {job} with \
                another request body: a key names one request; send the same body to see that \
                job, or use a new key for a new request")}})
        )
    );

    let status = server.wait_done(&job, Duration::from_secs(120));
    let seconds = t0.elapsed().as_secs_f64();
    assert_eq!(status["status"], "SUCCEEDED", "{status}");
    eprintln!(
        "time to SUCCEEDED: {seconds:.2} s (server's elapsed_seconds {:.2} s, predicted {:.2} s); \
         cost ${:.6} (predicted ${:.6})",
        status["elapsed_seconds"].as_f64().unwrap(),
        dry["predicted_seconds"].as_f64().unwrap(),
        status["cost_usd"].as_f64().unwrap(),
        dry["predicted_cost_usd"].as_f64().unwrap(),
    );
    assert_eq!(status["stage"], "combine");
    assert_eq!(status["tasks_done"], status["tasks_total"]);
    assert_eq!(status["tasks_total"], dry["tasks_total"]);
    assert_eq!(status["retried_attempts"], 0);
    assert!(status["cost_usd"].as_f64().unwrap() > 0.0);
    assert_eq!(status["image_url"], format!("/renders/{job}/image"));
    // The API's records, at the deployment's keys: one per job.
    let stored = files_under(&data.join("hort/jobs"));
    let records: Vec<&String> = stored
        .iter()
        .filter(|f| f.ends_with("/api.json~obj"))
        .collect();
    assert_eq!(
        records,
        [&format!("{job}/api.json~obj")],
        "two posts with one key made one job: {stored:?}"
    );
    assert!(
        job.starts_with("key-"),
        "an idempotency key names its job: {job}"
    );

    let pfm = server.get(&format!("/renders/{job}/image?format=pfm"));
    assert_eq!(pfm.status, 200);
    assert_eq!(
        pfm.header("content-type"),
        Some("image/x-portable-floatmap")
    );
    let reference = monolithic(
        &dir,
        "monolithic.pfm",
        &["--width", "64", "--height", "48", "--spp", "2"],
    );
    assert!(
        pfm.body == reference,
        "the served image equals the monolithic render"
    );
    let png = server.get(&format!("/renders/{job}/image"));
    assert_eq!(png.header("content-type"), Some("image/png"));
    assert!(png.body.starts_with(b"\x89PNG\r\n\x1a\n"));
    let exr = server.get(&format!("/renders/{job}/image?format=exr"));
    assert!(
        exr.body.starts_with(&[0x76, 0x2f, 0x31, 0x01]),
        "OpenEXR magic"
    );

    let report = server.get(&format!("/renders/{job}/report"));
    assert_eq!(report.status, 200);
    let r = report.json();
    assert_eq!(r["mode"], "emulator");
    assert_eq!(r["job"], job.as_str());
    assert_eq!(r["scene"], "cornell.json");
    assert_eq!(
        (r["splits"].as_u64(), r["spans"].as_u64()),
        (Some(2), Some(3))
    );
    assert_eq!(r["rays"]["primary"], 64 * 48 * 2);
    assert_eq!(r["cost_usd"], status["cost_usd"]);
    let tasks = |stages: &Value, key: &str| -> Vec<u64> {
        let list = stages.as_array().unwrap();
        list.iter().map(|s| s[key].as_u64().unwrap()).collect()
    };
    assert_eq!(
        tasks(&r["stages"], "tasks"),
        tasks(&dry["stages"], "tasks"),
        "the dry run's plan is the plan that ran"
    );

    // A crash, then a new server over the same data folder answers for the finished job.
    server.kill_hard();
    let server = Serve::start(&data);
    let after = server.get(&format!("/renders/{job}"));
    assert_eq!(after.status, 200);
    let after = after.json();
    for field in [
        "status",
        "tasks_done",
        "tasks_total",
        "cost_usd",
        "elapsed_seconds",
        "image_url",
    ] {
        assert_eq!(after[field], status[field], "{field} after a restart");
    }
    assert!(server.get(&format!("/renders/{job}/image?format=pfm")).body == reference);
    assert_eq!(
        server.get(&format!("/renders/{job}/report")).body,
        report.body
    );
    let replay = server.post("/renders", &body, &key).json();
    assert_eq!(
        (replay["job"].as_str(), replay["replayed"].as_bool()),
        (Some(job.as_str()), Some(true)),
        "idempotency keys outlive the server too"
    );
    drop(server);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// One bad request: what it is, its answer, and the status, code, message and field wanted.
type Case<'a> = (&'a str, Reply, u16, &'a str, String, Option<&'a str>);

#[test]
fn a_render_asking_for_the_png_alone_stores_and_serves_only_it() {
    let dir = scratch("png-only");
    let data = dir.join("data");
    let server = Serve::start(&data);
    let body = json!({
        "scene": cornell(), "width": 32, "height": 24, "splits": 2, "spans": 2,
        "outputs": {"linear": false, "hits": false}
    });
    let posted = server.post("/renders", &body, &[]);
    assert_eq!(
        posted.status,
        202,
        "{}",
        String::from_utf8_lossy(&posted.body)
    );
    let job = posted.json()["job"].as_str().unwrap().to_owned();
    let status = server.wait_done(&job, Duration::from_secs(120));
    assert_eq!(status["status"], "SUCCEEDED", "{status}");
    // The status says what the job stored, and the dashboard links only that.
    assert_eq!(status["outputs"], json!({"linear": false, "hits": false}));
    let page = server.get("/").text();
    assert!(
        page.contains(&format!("<a href=\"renders/{job}/report\">report</a>")),
        "{page}"
    );
    assert!(
        !page.contains("format=pfm") && !page.contains("format=exr"),
        "{page}"
    );

    // The PNG is the monolithic render's, byte for byte; nothing else is stored under out/.
    let png = server.get(&format!("/renders/{job}/image"));
    assert_eq!(png.status, 200);
    let mono = monolithic(&dir, "monolithic.png", &["--width", "32", "--height", "24"]);
    assert!(png.body == mono, "the monolithic PNG");
    let stored = files_under(&data.join(format!("hort/jobs/{job}/out")));
    assert_eq!(stored, ["image.png~obj"], "{stored:?}");
    for format in ["pfm", "exr"] {
        let image = server.get(&format!("/renders/{job}/image?format={format}"));
        assert_eq!(image.status, 404, "{format}");
        assert_eq!(
            image.json()["error"]["message"],
            format!(
                "render {job} stored no linear image (its request's outputs.linear was false): \
                 only format=png is served"
            ),
            "{format}"
        );
    }
}

#[test]
fn bad_requests_get_their_status_and_exact_message() {
    let dir = scratch("errors");
    let data = dir.join("data");
    // A scene in the bucket, as the embedded server stores objects: key + "~obj".
    let in_bucket = data.join("hort/scenes/box");
    std::fs::create_dir_all(&in_bucket).unwrap();
    for name in ["cornell.json", "cornell.obj", "cornell.mtl"] {
        std::fs::copy(
            scenes().join("cornell").join(name),
            in_bucket.join(format!("{name}~obj")),
        )
        .unwrap();
    }
    let server = Serve::start(&data);
    let json_type = [("Content-Type", "application/json")];
    let mut bad_obj = cornell();
    bad_obj["files"]["cornell.obj"] = json!("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");

    let dry = server
        .post(
            "/renders?dry_run=true",
            &json!({"scene": cornell(), "width": 64, "height": 48}),
            &[],
        )
        .json();
    let over = format!(
        "the predicted cost {} is over the budget max_cost_usd = $0.000100 ({} tasks, about \
         {:.1} s); raise the budget or render fewer pixels or samples",
        usd(dry["predicted_cost_usd"].as_f64().unwrap()),
        dry["tasks_total"],
        dry["predicted_seconds"].as_f64().unwrap()
    );
    let cases: Vec<Case> =
        vec![
        (
            "malformed JSON",
            server.call("POST", "/renders", &json_type, br#"{"scene": "#),
            400,
            "invalid_json",
            "the request body is not valid JSON: EOF while parsing a value at line 1 column 10"
                .into(),
            None,
        ),
        (
            "unknown field",
            server.post("/renders", &json!({"scene": cornell(), "colour": "red"}), &[]),
            400,
            "invalid_request",
            "colour: unknown field `colour`, expected one of `scene`, `width`, `height`, `spp`, \
             `splits`, `spans`, `split_mode`, `mode`, `memory_mb`, `max_cost_usd`, `outputs`, `frames`, `frame`, `orbit`, `animation`"
                .into(),
            Some("colour"),
        ),
        (
            "unknown output",
            server.post(
                "/renders",
                &json!({"scene": cornell(), "outputs": {"linear": true, "hit": true}}),
                &[],
            ),
            400,
            "invalid_request",
            "outputs.hit: unknown field `hit`, expected `linear` or `hits`".into(),
            Some("outputs.hit"),
        ),
        (
            "unknown nested field",
            server.post("/renders", &json!({"scene": {"key": "a.json", "url": "x"}}), &[]),
            400,
            "invalid_request",
            "scene.url: unknown field `url`, expected one of `main`, `files`, `key`".into(),
            Some("scene.url"),
        ),
        (
            "wrong type",
            server.post("/renders", &json!({"scene": cornell(), "width": "wide"}), &[]),
            400,
            "invalid_request",
            "width: invalid type: string \"wide\", expected u32".into(),
            Some("width"),
        ),
        (
            "missing scene",
            server.post("/renders", &json!({"width": 64}), &[]),
            400,
            "invalid_request",
            "scene: missing field `scene`".into(),
            Some("scene"),
        ),
        (
            "bad scene file and line",
            server.post("/renders", &json!({"scene": bad_obj}), &[]),
            400,
            "invalid_scene",
            "cornell.obj:4: face refers to vertex 9, but only 3 vertices are defined so far".into(),
            Some("scene"),
        ),
        (
            "missing key",
            server.post("/renders", &json!({"scene": {"key": "scenes/none.json"}}), &[]),
            400,
            "invalid_request",
            "scene.key: there is no object scenes/none.json in the bucket".into(),
            Some("scene.key"),
        ),
        (
            "unknown job",
            server.get("/renders/r-0-0"),
            404,
            "not_found",
            "no render \"r-0-0\"".into(),
            None,
        ),
        (
            "no image of an unknown job",
            server.get("/renders/r-0-0/image?format=pfm"),
            404,
            "not_found",
            "no render \"r-0-0\"".into(),
            None,
        ),
        (
            "unknown route",
            server.get("/jobs"),
            404,
            "not_found",
            "no route GET /jobs: the API has /renders, /renders/{id}, /renders/{id}/image, \
             /renders/{id}/frames/{k}/image and /renders/{id}/report, and the dashboard at /"
                .into(),
            None,
        ),
        (
            "wrong method",
            server.call("PUT", "/renders/r-0-0", &[], b""),
            405,
            "method_not_allowed",
            "PUT is not allowed on /renders/r-0-0; allowed: GET, DELETE".into(),
            None,
        ),
        (
            // Only the head is sent: the answer comes without the body being read.
            "body over the limit",
            server.call(
                "POST",
                "/renders",
                &[("Content-Type", "application/json"), ("Content-Length", "7340033")],
                b"",
            ),
            413,
            "payload_too_large",
            "the request body is 7340033 bytes, over the limit of 6291456 bytes; give a large \
             scene by key ({\"scene\": {\"key\": \"...\"}}) instead of inline files"
                .into(),
            None,
        ),
        (
            "not JSON",
            server.call("POST", "/renders", &[("Content-Type", "text/plain")], b"{}"),
            415,
            "unsupported_media_type",
            "the request body must be JSON (Content-Type: application/json), not text/plain".into(),
            None,
        ),
        (
            "over budget",
            server.post(
                "/renders",
                &json!({"scene": cornell(), "width": 64, "height": 48, "max_cost_usd": 0.0001}),
                &[],
            ),
            422,
            "over_budget",
            over,
            Some("max_cost_usd"),
        ),
    ];
    for (what, reply, status, code, message, field) in cases {
        assert_eq!(
            reply.status,
            status,
            "{what}: {}",
            String::from_utf8_lossy(&reply.body)
        );
        assert_eq!(
            reply.header("content-type"),
            Some("application/json"),
            "{what}"
        );
        let (got_code, got_message, got_field) = reply.error();
        assert_eq!(got_code, code, "{what}");
        assert_eq!(got_message, message, "{what}");
        assert_eq!(got_field.as_deref(), field, "{what}");
        if status == 405 {
            assert_eq!(reply.header("allow"), Some("GET, DELETE"));
        }
    }
    assert!(
        !data.join("hort/jobs").exists(),
        "no bad request started a job"
    );

    // A scene given by key is sized beside its main file, not loaded: the dry run's plan is an
    // estimate (a small mesh is read whole, so its triangles are counted exactly).
    let by_key_body =
        json!({"scene": {"key": "scenes/box/cornell.json"}, "width": 64, "height": 48});
    let by_key = server.post("/renders?dry_run=true", &by_key_body, &[]);
    assert_eq!(
        by_key.status,
        200,
        "{}",
        String::from_utf8_lossy(&by_key.body)
    );
    let by_key = by_key.json();
    assert_eq!(by_key["scene"], "scenes/box/cornell.json");
    assert_eq!(by_key["scene_estimate"]["triangles"], dry["triangles"]);
    assert!(
        by_key["tasks_total"].as_u64() >= dry["tasks_total"].as_u64(),
        "an estimate leaves no task out: {} < {}",
        by_key["tasks_total"],
        dry["tasks_total"]
    );
    // The Plan function copies it into the job: the monolithic render's bytes.
    let accepted = server.post("/renders", &by_key_body, &[]);
    assert_eq!(accepted.status, 202);
    let job = accepted.json()["job"].as_str().unwrap().to_owned();
    let status = server.wait_done(&job, Duration::from_secs(120));
    assert_eq!(status["status"], "SUCCEEDED", "{status}");
    let pfm = server.get(&format!("/renders/{job}/image?format=pfm"));
    let reference = monolithic(&dir, "by-key.pfm", &["--width", "64", "--height", "48"]);
    assert!(pfm.body == reference, "a scene by key renders as uploaded");
    // A fault in a mesh the API did not parse fails the job at Plan, naming the file by key.
    std::fs::write(
        in_bucket.join("cornell.obj~obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
    )
    .unwrap();
    let accepted = server.post("/renders", &by_key_body, &[]);
    assert_eq!(accepted.status, 202);
    let job = accepted.json()["job"].as_str().unwrap().to_owned();
    let status = server.wait_done(&job, Duration::from_secs(120));
    assert_eq!(status["status"], "FAILED", "{status}");
    let error = status["error"].as_str().unwrap();
    assert!(
        error.ends_with(
            "plan: Hort.BadInput: Plan failed: scenes/box/cornell.obj:4: face refers to vertex 9, \
             but only 3 vertices are defined so far"
        ),
        "{error}"
    );
    drop(server);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn delete_cancels_a_running_job_and_removes_its_intermediates() {
    let dir = scratch("cancel");
    let data = dir.join("data");
    let server = Serve::start(&data);
    // About 17 million camera samples in 100 spans: minutes of work on two slots.
    let body = json!({"scene": cornell(), "width": 1024, "height": 1024, "spp": 16});
    let accepted = server.post("/renders", &body, &[]);
    assert_eq!(
        accepted.status,
        202,
        "{}",
        String::from_utf8_lossy(&accepted.body)
    );
    let job = accepted.json()["job"].as_str().unwrap().to_owned();
    let t0 = Instant::now();
    loop {
        let s = server.get(&format!("/renders/{job}")).json();
        assert_eq!(s["error"], Value::Null, "{s}");
        if s["status"] == "RUNNING" && s["tasks_done"].as_u64().unwrap() >= 3 {
            // The scene fits one function: the job runs fused, plan then render.
            assert_eq!(s["stage"], "render", "{s}");
            break;
        }
        assert!(t0.elapsed() < Duration::from_secs(120), "{s}");
        std::thread::sleep(Duration::from_millis(50));
    }
    let job_dir = data.join(format!("hort/jobs/{job}"));
    assert!(
        files_under(&job_dir)
            .iter()
            .any(|f| f.starts_with("splits/")),
        "the job has intermediates to delete: {:?}",
        files_under(&job_dir)
    );
    let t1 = Instant::now();
    let deleted = server.call("DELETE", &format!("/renders/{job}"), &[], b"");
    assert_eq!(
        deleted.status,
        200,
        "{}",
        String::from_utf8_lossy(&deleted.body)
    );
    let deleted = deleted.json();
    eprintln!("DELETE answered in {:.2} s", t1.elapsed().as_secs_f64());
    assert_eq!(deleted["status"], "CANCELLED", "{deleted}");
    assert!(deleted["tasks_done"].as_u64() < deleted["tasks_total"].as_u64());
    assert_eq!(files_under(&job_dir), KEPT_ON_CANCEL);
    let status = server.get(&format!("/renders/{job}")).json();
    assert_eq!(status["status"], "CANCELLED");
    let image = server.get(&format!("/renders/{job}/image"));
    assert_eq!(image.status, 404);
    assert_eq!(
        image.error().1,
        format!("render {job} has no image: the job is CANCELLED")
    );
    // Cancelling again changes nothing.
    let again = server
        .call("DELETE", &format!("/renders/{job}"), &[], b"")
        .json();
    assert_eq!(again["status"], "CANCELLED");

    // A client that leaves before the answer does not stop its job.
    let small = json!({"scene": cornell(), "width": 32, "height": 32});
    let mut stream = TcpStream::connect(("127.0.0.1", server.port)).unwrap();
    let text = small.to_string();
    write!(
        stream,
        "POST /renders HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nIdempotency-Key: \
         gone\r\nContent-Length: {}\r\n\r\n{text}",
        text.len()
    )
    .unwrap();
    drop(stream);
    // Handled once the listing holds it beside the cancelled job (polled, at most 60 s).
    let t0 = Instant::now();
    while server.get("/renders").json()["renders"]
        .as_array()
        .unwrap()
        .len()
        < 2
    {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "the dropped client's POST never made a job"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let replay = server
        .post("/renders", &small, &[("Idempotency-Key", "gone")])
        .json();
    assert_eq!(replay["replayed"], true, "{replay}");
    let finished = replay["job"].as_str().unwrap();
    let done = server.wait_done(finished, Duration::from_secs(120));
    assert_eq!(done["status"], "SUCCEEDED", "{done}");
    drop(server);
    // Over the server's whole life after the cancel (another job ran meanwhile), nothing of the
    // cancelled job's was written.
    assert_eq!(
        files_under(&job_dir),
        KEPT_ON_CANCEL,
        "nothing of the job's is written after the cancel"
    );
    // `hort jobs list` over the server's folder: the cancelled job says so (the four objects it
    // keeps), the other finished.
    let listed = hort(&["jobs", "list", "--data-dir", data.to_str().unwrap()]);
    assert!(listed.status.success(), "{}", stderr(&listed));
    let listed = String::from_utf8(listed.stdout).unwrap();
    let row = |id: &str| -> Vec<String> {
        listed
            .lines()
            .find(|line| line.starts_with(id))
            .unwrap_or_else(|| panic!("no row of {id}: {listed}"))
            .split_whitespace()
            .map(str::to_owned)
            .collect()
    };
    let kept_bytes: u64 = files_under(&job_dir)
        .iter()
        .map(|f| std::fs::metadata(job_dir.join(f)).unwrap().len())
        .sum();
    assert_eq!(
        row(&job),
        [
            job.clone(),
            "cancelled".into(),
            "4".into(),
            kept_bytes.to_string()
        ],
        "{listed}"
    );
    assert_eq!(row(finished)[1], "finished", "{listed}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_full_server_answers_429_binds_loopback_and_keeps_its_keys_private() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scratch("full");
    let server = Serve::start_with(&dir.join("data"), &["--max-jobs", "1"]);
    let log = server.log.lock().unwrap().clone();
    assert!(
        log.contains(&format!(
            "listening on http://127.0.0.1:{} (loopback only: other machines cannot connect; \
             --bind ADDRESS to change; dashboard at http://127.0.0.1:{}/;",
            server.port, server.port
        )),
        "{log}"
    );
    // The embedded S3 server's key pair: random, in the data folder, owner-only.
    let key_file = dir.join("data/.hort-s3-key");
    let mode = std::fs::metadata(&key_file).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600);
    let keys = std::fs::read_to_string(&key_file).unwrap();
    assert!(!keys.contains("hort-local-secret"), "{keys}");
    assert_eq!(keys.split_whitespace().nth(1).unwrap().len(), 64);

    let long = json!({"scene": cornell(), "width": 320, "height": 240, "spp": 16});
    let first = server.post("/renders", &long, &[]);
    assert_eq!(first.status, 202, "{}", first.text());
    let job = first.json()["job"].as_str().unwrap().to_owned();
    let second = server.post("/renders", &long, &[]);
    assert_eq!(second.status, 429, "{}", second.text());
    assert_eq!(
        second.error(),
        (
            "too_many_jobs".to_owned(),
            "1 jobs are queued or running, the most this server runs at once (hort serve \
             --max-jobs 1); submit again once one has ended"
                .to_owned(),
            None
        )
    );
    // The listing and the dashboard name the one job.
    let listing = server.get("/renders").json();
    assert_eq!(listing["renders"].as_array().unwrap().len(), 1);
    assert_eq!(listing["renders"][0]["job"], job.as_str());
    assert_eq!(listing["renders"][0]["scene"], "cornell.json");
    let page = server.get("/");
    assert_eq!(page.status, 200);
    assert_eq!(
        page.header("content-type"),
        Some("text/html; charset=utf-8")
    );
    assert!(page.text().contains(&format!("<tr data-job=\"{job}\"")));
    let cancelled = server
        .call("DELETE", &format!("/renders/{job}"), &[], b"")
        .json();
    assert_eq!(cancelled["status"], "CANCELLED");
    // Once it ended, a job is taken again.
    let third = server.post(
        "/renders",
        &json!({"scene": cornell(), "width": 8, "height": 8}),
        &[],
    );
    assert_eq!(third.status, 202, "{}", third.text());
    // The server's own listing is newest first, and `limit` keeps the newest.
    let third = third.json()["job"].as_str().unwrap().to_owned();
    let jobs = |path: &str| -> Vec<String> {
        server.get(path).json()["renders"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["job"].as_str().unwrap().to_owned())
            .collect()
    };
    assert_eq!(jobs("/renders"), [third.clone(), job]);
    assert_eq!(jobs("/renders?limit=1"), [third]);
}

#[test]
fn a_chunked_body_over_the_limit_is_read_no_further_than_the_limit() {
    let dir = scratch("chunked");
    let server = Serve::start(&dir.join("data"));
    // 7 chunks of 1 MiB, no length declared: the server stops at 6 MiB and answers 413.
    let mut body = Vec::new();
    for _ in 0..7 {
        body.extend_from_slice(format!("{:x}\r\n", 1 << 20).as_bytes());
        body.extend(std::iter::repeat_n(b' ', 1 << 20));
        body.extend_from_slice(b"\r\n");
    }
    body.extend_from_slice(b"0\r\n\r\n");
    let reply = server.call(
        "POST",
        "/renders",
        &[
            ("Content-Type", "application/json"),
            ("Transfer-Encoding", "chunked"),
        ],
        &body,
    );
    assert_eq!(reply.status, 413);
    assert_eq!(
        reply.error().1,
        "the request body is over the limit of 6291456 bytes; give a large scene by key \
         ({\"scene\": {\"key\": \"...\"}}) instead of inline files"
    );
}

/// An image too large for a Lambda response (the 1080p PFM: 24.9 MB, 33 MB as base64) is
/// answered with a 307 to a presigned GET of the stored object, which the embedded S3 server
/// serves byte for byte as the monolithic render wrote it; no answer of the API has a body over
/// 4.5 MiB (whose base64 is Lambda's 6 MB).
#[test]
fn a_large_image_is_redirected_to_a_presigned_get_within_the_lambda_quota() {
    let dir = scratch("presigned");
    let server = Serve::start(&dir.join("data"));
    let body = json!({"scene": cornell(), "width": 1920, "height": 1080});
    let accepted = server.post("/renders", &body, &[]);
    assert_eq!(accepted.status, 202, "{}", accepted.text());
    let job = accepted.json()["job"].as_str().unwrap().to_owned();
    let status = server.wait_done(&job, Duration::from_secs(300));
    assert_eq!(status["status"], "SUCCEEDED", "{status}");
    let quota = 4_718_592; // 4.5 MiB: 6 MiB once base64-encoded
    let pfm = server.get(&format!("/renders/{job}/image?format=pfm"));
    assert_eq!(pfm.status, 307, "{}", pfm.text());
    assert!(pfm.body.len() < quota);
    let location = pfm.header("Location").expect("a Location").to_owned();
    let answer = pfm.json();
    assert_eq!(answer["image_url"], location.as_str());
    assert_eq!(
        answer["bytes"],
        1920 * 1080 * 12 + "PF\n1920 1080\n-1.0\n".len()
    );
    let rest = location
        .strip_prefix("http://127.0.0.1:")
        .expect("the embedded S3 server's address");
    let (port, path) = rest.split_at(rest.find('/').unwrap());
    assert!(path.contains("X-Amz-Signature="), "{location}");
    let fetched = call(port.parse().unwrap(), "GET", path, &[], b"");
    assert_eq!(fetched.status, 200, "{}", fetched.text());
    let reference = monolithic(&dir, "ref.pfm", &["--width", "1920", "--height", "1080"]);
    assert!(
        fetched.body == reference,
        "the presigned GET serves the monolithic render's PFM"
    );
    // A tampered signature is refused by the server, not served.
    let at = path.find("X-Amz-Signature=").unwrap() + "X-Amz-Signature=".len();
    let flipped = if &path[at..=at] == "0" { "1" } else { "0" };
    let forged = format!("{}{flipped}{}", &path[..at], &path[at + 1..]);
    assert_eq!(
        call(port.parse().unwrap(), "GET", &forged, &[], b"").status,
        403
    );
    // The PNG fits a Lambda response and is answered inline.
    let png = server.get(&format!("/renders/{job}/image"));
    assert_eq!(
        (png.status, png.header("Content-Type")),
        (200, Some("image/png"))
    );
    assert!(png.body.len() < quota);
    for format in ["exr", "png"] {
        let reply = server.get(&format!("/renders/{job}/image?format={format}"));
        assert!(
            matches!(reply.status, 200 | 307),
            "{format}: {}",
            reply.status
        );
        assert!(
            reply.body.len() < quota,
            "{format}: {} bytes",
            reply.body.len()
        );
    }
    drop(server);
    std::fs::remove_dir_all(&dir).unwrap();
}
