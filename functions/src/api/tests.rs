//! The router over a fake backend: routes, methods, content types, limits, request and scene
//! validation, dry runs and budgets.

use http::{Method, Request, StatusCode};
use serde_json::{Value, json};

use super::*;
pub(super) use crate::api::fake::Fake;

pub(super) fn scene_file(rel: &str) -> String {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/");
    std::fs::read_to_string(format!("{path}{rel}")).unwrap()
}

pub(super) fn cornell() -> Value {
    json!({
        "main": "cornell.json",
        "files": {
            "cornell.json": scene_file("cornell/cornell.json"),
            "cornell.obj": scene_file("cornell/cornell.obj"),
            "cornell.mtl": scene_file("cornell/cornell.mtl"),
        }
    })
}

pub(super) fn call(backend: &Fake, method: Method, uri: &str, body: &[u8]) -> (StatusCode, Value) {
    let request = Request::builder()
        .method(method)
        .uri(uri)
        .header("content-type", "application/json")
        .body(body.to_vec())
        .unwrap();
    let response = handle(backend, request);
    let status = response.status();
    let value = serde_json::from_slice(response.body()).unwrap_or(Value::Null);
    (status, value)
}

pub(super) fn post(backend: &Fake, uri: &str, body: &Value) -> (StatusCode, Value) {
    call(backend, Method::POST, uri, body.to_string().as_bytes())
}

/// The error of a response: (code, message, field).
pub(super) fn error(value: &Value) -> (String, String, Option<String>) {
    let e = &value["error"];
    (
        e["code"].as_str().unwrap().to_owned(),
        e["message"].as_str().unwrap().to_owned(),
        e["field"].as_str().map(str::to_owned),
    )
}

#[test]
fn a_valid_request_is_accepted_and_its_plan_is_exact() {
    let fake = Fake::default();
    let body =
        json!({"scene": cornell(), "width": 64, "height": 48, "spp": 2, "splits": 3, "spans": 4});
    let (status, value) = post(&fake, "/renders", &body);
    assert_eq!(status, StatusCode::ACCEPTED, "{value}");
    assert_eq!(value["job"], "job-0");
    assert_eq!(value["status_url"], "/renders/job-0");
    let jobs = fake.jobs.lock().unwrap();
    let job = &jobs[0];
    let JobScene::Uploaded { main, files, .. } = &job.scene else {
        panic!("inline files are uploaded, got {:?}", job.scene);
    };
    assert_eq!(main, "cornell.json");
    assert_eq!(
        files.keys().collect::<Vec<_>>(),
        ["cornell.json", "cornell.mtl", "cornell.obj"]
    );
    assert_eq!(
        (job.request.width, job.request.height, job.request.spp),
        (64, 48, 2)
    );
    let p = &job.prediction;
    assert_eq!((p.splits, p.spans), (3, 4));
    let tasks: Vec<u64> = p.stages.iter().map(|s| s.tasks).collect();
    assert_eq!(tasks[0], 1);
    assert!(tasks[1] >= 1 && tasks[1] <= 12, "cast-map pairs: {tasks:?}");
    assert_eq!(&tasks[2..], [4, 4, 12, 4, 1]);
    assert_eq!(p.tasks_total, tasks.iter().sum::<u64>());
    assert!(p.predicted_cost_usd > 0.0 && p.predicted_seconds > 0.0);
}

#[test]
fn a_dry_run_answers_the_plan_and_starts_nothing() {
    let fake = Fake::default();
    let body = json!({"scene": cornell(), "width": 64, "height": 48, "splits": 2});
    let (status, value) = post(&fake, "/renders?dry_run=true", &body);
    assert_eq!(status, StatusCode::OK, "{value}");
    assert_eq!(value["dry_run"], true);
    assert_eq!(value["splits"], 2);
    assert_eq!(value["spans"], 1);
    assert_eq!(value["stages"][4]["stage"], "trace-map");
    assert_eq!(value["stages"][4]["tasks"], 2);
    assert!(value["predicted_cost_usd"].as_f64().unwrap() > 0.0);
    assert!(fake.jobs.lock().unwrap().is_empty());
}

#[test]
fn over_budget_is_422_naming_prediction_and_budget() {
    let fake = Fake::default();
    let body = json!({"scene": cornell(), "width": 64, "height": 48, "max_cost_usd": 1e-9});
    let (status, value) = post(&fake, "/renders", &body);
    assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY);
    let (code, message, field) = error(&value);
    assert_eq!(code, "over_budget");
    assert_eq!(field.as_deref(), Some("max_cost_usd"));
    assert!(
        message.starts_with("the predicted cost $0.0")
            && message.contains("over the budget max_cost_usd = $0.00000000100"),
        "{message}"
    );
    assert!(fake.jobs.lock().unwrap().is_empty());
}

#[test]
fn bad_scenes_name_file_and_line() {
    let fake = Fake::default();
    let mut scene = cornell();
    scene["files"]["cornell.obj"] = json!("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    let (status, value) = post(&fake, "/renders", &json!({"scene": scene}));
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(
        error(&value),
        (
            "invalid_scene".into(),
            "cornell.obj:4: face refers to vertex 9, but only 3 vertices are defined so far".into(),
            Some("scene".into())
        )
    );
    let mut scene = cornell();
    scene["files"]
        .as_object_mut()
        .unwrap()
        .remove("cornell.obj");
    let (_, value) = post(&fake, "/renders", &json!({"scene": scene}));
    assert_eq!(
        error(&value).1,
        "cornell.json: the mesh cornell.obj does not exist"
    );
    let scene = json!({"main": "a.json", "files": {"a.json": "{\"meshes\": [\"../etc/x.obj\"]}"}});
    let (_, value) = post(&fake, "/renders", &json!({"scene": scene}));
    assert!(
        error(&value)
            .1
            .starts_with("a.json: mesh \"../etc/x.obj\" is not a relative path"),
        "{value}"
    );
    let scene =
        json!({"main": "a.json", "files": {"a.json": "{\"meshes\": [\"a.obj\"], \"fov\": 3}"}});
    let (_, value) = post(&fake, "/renders", &json!({"scene": scene}));
    assert!(
        error(&value).1.starts_with("a.json: manifest field `fov`"),
        "{value}"
    );
}

#[test]
fn scenes_by_key_are_sized_beside_their_main_file_and_never_loaded() {
    let mut fake = Fake::default();
    for (name, rel) in [
        ("scenes/c/cornell.json", "cornell/cornell.json"),
        ("scenes/c/cornell.obj", "cornell/cornell.obj"),
        ("scenes/c/cornell.mtl", "cornell/cornell.mtl"),
    ] {
        fake.objects
            .insert(name.into(), scene_file(rel).into_bytes());
    }
    let obj_len = fake.objects["scenes/c/cornell.obj"].len();
    let body = json!({"scene": {"key": "scenes/c/cornell.json"}, "width": 32, "height": 32});
    let (status, value) = post(&fake, "/renders?dry_run=true", &body);
    assert_eq!(status, StatusCode::OK, "{value}");
    // A small mesh is read whole (one range): its faces are counted, not estimated.
    let estimate = &value["scene_estimate"];
    assert_eq!(estimate["obj_bytes"], obj_len as u64, "{value}");
    assert_eq!(estimate["triangles"], 36, "{value}");
    assert_eq!(value["triangles"], 36, "{value}");
    assert_eq!(
        *fake.reads.lock().unwrap(),
        [
            "scenes/c/cornell.json".to_owned(),
            format!("scenes/c/cornell.obj 0..{obj_len}")
        ],
        "the manifest read whole, the mesh sampled, the material library not at all"
    );
    let (status, value) = post(&fake, "/renders", &body);
    assert_eq!(status, StatusCode::ACCEPTED, "{value}");
    let jobs = fake.jobs.lock().unwrap();
    assert_eq!(jobs[0].scene_name, "scenes/c/cornell.json");
    assert!(
        matches!(&jobs[0].scene, JobScene::Key(key) if key == "scenes/c/cornell.json"),
        "{:?}",
        jobs[0].scene
    );
    drop(jobs);

    let body = json!({"scene": {"key": "scenes/c/none.json"}});
    let (status, value) = post(&fake, "/renders", &body);
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(
        error(&value).1,
        "scene.key: there is no object scenes/c/none.json in the bucket"
    );
    fake.objects.remove("scenes/c/cornell.obj");
    let body = json!({"scene": {"key": "scenes/c/cornell.json"}});
    let (_, value) = post(&fake, "/renders", &body);
    assert_eq!(
        error(&value).1,
        "scenes/c/cornell.json: the mesh scenes/c/cornell.obj does not exist"
    );
    // A mesh over S3's 5 GiB single-copy limit cannot be copied into a job: refused at once.
    let huge = hort_aws_quotas::S3_COPY_OBJECT_MAX_BYTES + 1;
    fake.sizes.insert("scenes/c/cornell.obj".into(), huge);
    let (status, value) = post(&fake, "/renders", &body);
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(
        error(&value).1,
        format!(
            "scenes/c/cornell.obj: {huge} bytes, over the 5368709120 bytes S3 copies in one \
             request; split the mesh into files of at most 5 GiB and list them in a manifest"
        )
    );
    // A mesh the API does not parse: the Plan function finds its fault (handlers' tests).
    fake.objects.insert(
        "scenes/c/cornell.obj".into(),
        b"v 0 0 0\nf 1 2 3\n".to_vec(),
    );
    let (status, value) = post(&fake, "/renders", &body);
    assert_eq!(status, StatusCode::ACCEPTED, "{value}");
}

#[test]
fn request_fields_are_checked() {
    let fake = Fake::default();
    let cases = [
        (
            json!({"scene": cornell(), "width": 0}),
            "width",
            "width: 0 is out of range: must be 1 to 65536",
        ),
        (
            json!({"scene": cornell(), "splits": 99}),
            "splits",
            "splits: 99 is out of range: the scene has 36 triangles, so use 1 to 36",
        ),
        (
            json!({"scene": cornell(), "max_cost_usd": -1}),
            "max_cost_usd",
            "max_cost_usd: -1 is not a positive number of dollars",
        ),
        (
            json!({"scene": {"key": "a.json", "main": "a.json"}}),
            "scene",
            "scene: give either {\"main\", \"files\"} (the files inline) or {\"key\"} (the main file's key in the bucket)",
        ),
        (
            json!({"scene": {"main": "b.json", "files": {"a.json": ""}}}),
            "scene.main",
            "scene.main: \"b.json\" is not one of scene.files",
        ),
        (
            json!({"scene": {"key": "/etc/passwd"}}),
            "scene.key",
            "scene.key: scene.key \"/etc/passwd\" is not a relative path inside the scene's folder (1 to 1024 bytes, parts of at most 255 bytes separated by /, no empty, . or .. parts, no \\ or control characters)",
        ),
    ];
    for (body, field, message) in cases {
        let (status, value) = post(&fake, "/renders", &body);
        assert_eq!(status, StatusCode::BAD_REQUEST, "{body}");
        let (code, got, got_field) = error(&value);
        assert_eq!(code, "invalid_request");
        assert_eq!(got, message);
        assert_eq!(got_field.as_deref(), Some(field));
    }
}

#[test]
fn routes_methods_types_and_limits() {
    let fake = Fake::default();
    let (status, value) = call(&fake, Method::GET, "/nope", b"");
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert_eq!(error(&value).0, "not_found");
    let (status, value) = call(&fake, Method::GET, "/renders/job-7", b"");
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert_eq!(error(&value).1, "no render \"job-7\"");
    let (status, value) = call(&fake, Method::GET, "/renders/Bad_Id", b"");
    assert_eq!(
        (status, error(&value).1),
        (StatusCode::NOT_FOUND, "no render \"Bad_Id\"".to_owned())
    );

    let request = Request::builder()
        .method(Method::PUT)
        .uri("/renders/x")
        .body(Vec::new())
        .unwrap();
    let response = handle(&fake, request);
    assert_eq!(response.status(), StatusCode::METHOD_NOT_ALLOWED);
    assert_eq!(response.headers()["allow"], "GET, DELETE");

    let request = Request::builder()
        .method(Method::POST)
        .uri("/renders")
        .header("content-type", "text/plain")
        .body(b"{}".to_vec())
        .unwrap();
    let response = handle(&fake, request);
    assert_eq!(response.status(), StatusCode::UNSUPPORTED_MEDIA_TYPE);

    let big = vec![b' '; MAX_BODY_BYTES + 1];
    let (status, value) = call(&fake, Method::POST, "/renders", &big);
    assert_eq!(status, StatusCode::PAYLOAD_TOO_LARGE);
    assert_eq!(error(&value).0, "payload_too_large");

    let (status, value) = post(&fake, "/renders?dry_run=maybe", &json!({}));
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(error(&value).2.as_deref(), Some("query.dry_run"));

    let (_, value) = post(
        &fake,
        "/renders",
        &json!({"scene": cornell(), "width": 8, "height": 8}),
    );
    let job = value["job"].as_str().unwrap();
    let (status, value) = call(&fake, Method::GET, &format!("/renders/{job}"), b"");
    assert_eq!(status, StatusCode::OK);
    assert_eq!(value["status"], "SUCCEEDED");
    assert_eq!(value["image_url"], format!("/renders/{job}/image"));
    let request = Request::builder()
        .uri(format!("/renders/{job}/image?format=exr"))
        .body(Vec::new())
        .unwrap();
    let response = handle(&fake, request);
    assert_eq!(response.headers()["content-type"], "image/x-exr");
    assert_eq!(response.body(), b"exr");
    let (status, value) = call(
        &fake,
        Method::GET,
        &format!("/renders/{job}/image?format=tga"),
        b"",
    );
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(
        error(&value).1,
        "query.format: \"tga\" is not one of png, pfm, exr"
    );
}
