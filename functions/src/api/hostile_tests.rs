//! Hostile inputs, one test each, with the exact answer each gets (the table of
//! docs/HTTP-HARDENING.md).

use http::{Method, Request, StatusCode};
use serde_json::{Value, json};

use super::tests::{Fake, call, cornell, error, post};
use super::*;

const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

/// Posts a scene whose only file is named `name` (a triangle), and returns the error.
fn named(name: &str) -> (StatusCode, (String, String, Option<String>)) {
    let body = json!({"scene": {"main": name, "files": {name: TRIANGLE}}});
    let (status, value) = post(&Fake::default(), "/renders", &body);
    (status, error(&value))
}

fn refused_name(name: &str, shown: &str) {
    let (status, (code, message, field)) = named(name);
    assert_eq!(
        (status, code.as_str()),
        (StatusCode::BAD_REQUEST, "invalid_request")
    );
    assert_eq!(field.as_deref(), Some("scene.main"));
    assert_eq!(
        message,
        format!(
            "scene.main: scene.main {shown} is not a relative path inside the scene's folder (1 \
             to 1024 bytes, parts of at most 255 bytes separated by /, no empty, . or .. parts, \
             no \\ or control characters)"
        )
    );
}

#[test]
fn a_name_climbing_out_of_the_folder_is_refused() {
    refused_name("../secret.obj", "\"../secret.obj\"");
    refused_name("a/../../b.obj", "\"a/../../b.obj\"");
}

#[test]
fn an_absolute_name_is_refused() {
    refused_name("/etc/passwd", "\"/etc/passwd\"");
}

#[test]
fn a_name_with_nul_or_a_newline_is_refused() {
    refused_name("a\0.obj", "\"a\\0.obj\"");
    refused_name("a\n.obj", "\"a\\n.obj\"");
}

#[test]
fn a_name_with_a_backslash_is_refused() {
    refused_name("..\\a.obj", "\"..\\\\a.obj\"");
}

#[test]
fn a_name_over_1024_bytes_or_a_part_over_255_is_refused() {
    let a = "a".repeat(200);
    let long = format!("{}/{}.obj", [a.as_str(); 5].join("/"), "b".repeat(16));
    assert_eq!(long.len(), 1024 + 1);
    refused_name(&long, &format!("{long:?}"));
    let part = format!("{}.obj", "a".repeat(252));
    refused_name(&part, &format!("{part:?}"));
    // 1024 bytes in parts of at most 255 are fine (and then the scene loads).
    let ok = format!("{}/{}.obj", [a.as_str(); 4].join("/"), "d".repeat(216));
    assert_eq!(ok.len(), 1024);
    let body = json!({"scene": {"main": ok, "files": {&ok: TRIANGLE}}, "width": 4, "height": 4});
    let (status, value) = post(&Fake::default(), "/renders?dry_run=true", &body);
    assert_eq!(status, StatusCode::OK, "{value}");
}

#[test]
fn a_bad_name_among_the_files_is_named_by_its_path() {
    let body = json!({"scene": {"main": "a.obj", "files": {"a.obj": TRIANGLE, "../b.mtl": ""}}});
    let (status, value) = post(&Fake::default(), "/renders", &body);
    assert_eq!(status, StatusCode::BAD_REQUEST);
    let (_, message, field) = error(&value);
    assert_eq!(field.as_deref(), Some("scene.files.../b.mtl"));
    assert!(
        message.starts_with("scene.files.../b.mtl: file \"../b.mtl\" is not a relative path"),
        "{message}"
    );
}

#[test]
fn a_mesh_path_climbing_out_of_the_folder_is_refused() {
    let manifest = r#"{"meshes": ["../../etc/passwd"]}"#;
    let body = json!({"scene": {"main": "a.json", "files": {"a.json": manifest}}});
    let (status, value) = post(&Fake::default(), "/renders", &body);
    let (code, message, _) = error(&value);
    assert_eq!(
        (status, code.as_str()),
        (StatusCode::BAD_REQUEST, "invalid_scene")
    );
    assert!(message.contains("\"../../etc/passwd\""), "{message}");
}

#[test]
fn more_than_256_files_are_refused() {
    let files: serde_json::Map<String, Value> = (0..=MAX_SCENE_FILES)
        .map(|i| (format!("f{i}.obj"), Value::from(TRIANGLE)))
        .collect();
    let body = json!({"scene": {"main": "f0.obj", "files": files}});
    let (status, value) = post(&Fake::default(), "/renders", &body);
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(
        error(&value),
        (
            "invalid_request".to_owned(),
            "scene.files: 257 files, at most 256".to_owned(),
            Some("scene.files".to_owned())
        )
    );
}

#[test]
fn a_declared_length_over_the_limit_is_refused_before_the_body() {
    let mut headers = http::HeaderMap::new();
    headers.insert("content-type", "application/json".parse().unwrap());
    headers.insert("content-length", "6291457".parse().unwrap());
    let e = check_head(&Method::POST, &"/renders".parse().unwrap(), &headers).unwrap_err();
    assert_eq!(e.status, StatusCode::PAYLOAD_TOO_LARGE);
    assert_eq!(
        e.message,
        "the request body is 6291457 bytes, over the limit of 6291456 bytes; give a large scene \
         by key ({\"scene\": {\"key\": \"...\"}}) instead of inline files"
    );
    // A body over the limit handed to the router is refused too.
    let (status, _) = call(
        &Fake::default(),
        Method::POST,
        "/renders",
        &vec![b' '; MAX_BODY_BYTES + 1],
    );
    assert_eq!(status, StatusCode::PAYLOAD_TOO_LARGE);
}

#[test]
fn deep_json_is_refused_before_it_is_parsed() {
    let body = format!(
        "{{\"scene\": {}{}}}",
        "[".repeat(100_000),
        "]".repeat(100_000)
    );
    let (status, value) = call(&Fake::default(), Method::POST, "/renders", body.as_bytes());
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(
        error(&value),
        (
            "invalid_json".to_owned(),
            "the request body nests arrays or objects more than 8 levels deep (at byte 17); a \
             render request needs 3"
                .to_owned(),
            None
        )
    );
}

#[test]
fn unknown_fields_are_refused_at_every_level() {
    let fake = Fake::default();
    for (body, field) in [
        (json!({"scene": cornell(), "admin": true}), "admin"),
        (
            json!({"scene": {"key": "a.json", "bucket": "other"}}),
            "scene.bucket",
        ),
    ] {
        let (status, value) = post(&fake, "/renders", &body);
        assert_eq!(status, StatusCode::BAD_REQUEST);
        let (code, message, got) = error(&value);
        assert_eq!(code, "invalid_request");
        assert_eq!(got.as_deref(), Some(field));
        assert!(
            message.starts_with(&format!("{field}: unknown field")),
            "{message}"
        );
    }
    let (status, value) = call(&fake, Method::GET, "/?debug=1", b"");
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(
        error(&value).1,
        "query.debug: unknown query parameter; this route takes view"
    );
}

#[test]
fn a_full_backend_answers_429_and_starts_nothing() {
    let fake = Fake {
        capacity: Some(1),
        ..Fake::default()
    };
    let body = json!({"scene": cornell(), "width": 8, "height": 8});
    assert_eq!(post(&fake, "/renders", &body).0, StatusCode::ACCEPTED);
    let (status, value) = post(&fake, "/renders", &body);
    assert_eq!(status, StatusCode::TOO_MANY_REQUESTS);
    assert_eq!(
        error(&value),
        (
            "too_many_jobs".to_owned(),
            "1 jobs are running, the most this server runs at once".to_owned(),
            None
        )
    );
    assert_eq!(fake.jobs.lock().unwrap().len(), 1);
}

fn get_text(fake: &Fake, uri: &str) -> (StatusCode, String, String) {
    let request = Request::builder().uri(uri).body(Vec::new()).unwrap();
    let response = handle(fake, request);
    let kind = response.headers()["content-type"]
        .to_str()
        .unwrap()
        .to_owned();
    (
        response.status(),
        kind,
        String::from_utf8(response.body().clone()).unwrap(),
    )
}

#[test]
fn a_job_named_script_renders_as_text() {
    let fake = Fake::default();
    let name = "<script>alert(1)</script>.obj";
    let body = json!({"scene": {"main": name, "files": {name: TRIANGLE}}, "width": 4, "height": 4});
    let (status, value) = post(&fake, "/renders", &body);
    assert_eq!(status, StatusCode::ACCEPTED, "{value}");
    let (status, kind, html) = get_text(&fake, "/");
    assert_eq!(status, StatusCode::OK);
    assert_eq!(kind, "text/html; charset=utf-8");
    assert!(html.contains("<td class=\"scene\">&lt;script&gt;alert(1)&lt;/script&gt;.obj</td>"));
    assert!(
        !html.contains("<script>alert"),
        "the name entered the page as HTML"
    );
    // The page's only scripts are its own two.
    assert_eq!(html.matches("<script").count(), 2);
    let (_, _, table) = get_text(&fake, "/?view=jobs");
    assert!(table.starts_with("<tr data-job=\"job-0\" data-status=\"SUCCEEDED\">"));
    assert!(table.contains("&lt;script&gt;alert(1)&lt;/script&gt;.obj"));
}

#[test]
fn escape_html_escapes_the_five_characters() {
    assert_eq!(
        escape_html("<a href=\"x\" title='y'>&amp;</a>"),
        "&lt;a href=&quot;x&quot; title=&#39;y&#39;&gt;&amp;amp;&lt;/a&gt;"
    );
}

/// The router passes `limit` on and adds each job's image URL; the order is the backend's (the
/// real backends' newest-first listings are tested in `local-emulator/tests/it/serve.rs`,
/// `a_full_server_...`, and `tests/tests/it/aws_moto.rs`, `the_deployment_api_lists_...`).
#[test]
fn the_listing_passes_the_limit_and_adds_image_urls() {
    let fake = Fake::default();
    let body = json!({"scene": cornell(), "width": 8, "height": 8});
    for _ in 0..3 {
        assert_eq!(post(&fake, "/renders", &body).0, StatusCode::ACCEPTED);
    }
    let (status, value) = call(&fake, Method::GET, "/renders?limit=2", b"");
    assert_eq!(status, StatusCode::OK);
    let jobs: Vec<&str> = value["renders"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| j["job"].as_str().unwrap())
        .collect();
    assert_eq!(jobs, ["job-2", "job-1"]);
    assert_eq!(value["renders"][0]["image_url"], "/renders/job-2/image");
    assert_eq!(value["renders"][0]["scene"], "cornell.json");
    let (status, value) = call(&fake, Method::GET, "/renders?limit=0", b"");
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(
        error(&value).1,
        "query.limit: \"0\" is not a number from 1 to 1000"
    );
}
