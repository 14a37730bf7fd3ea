//! The HTTP target: one request through the API router, over a backend that accepts every job
//! and knows one scene object.

use hort_functions::api::fake::Fake;
use hort_functions::api::{check_head, handle};
use http::{Method, Request, StatusCode};

use crate::assert_one_line;

/// The object a request may name by key (`{"scene": {"key": "scenes/tri.obj"}}`).
const SCENE_KEY: &str = "scenes/tri.obj";
const SCENE_OBJ: &[u8] = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

/// HTTP target: the input is a request as text, `METHOD URI\n`, then `Name: value` header lines
/// up to an empty line, then the body (bytes). Requests `http` cannot represent are skipped.
/// The answer must be a documented status; an error answer is the JSON error object with a
/// one-line message.
pub fn http(data: &[u8]) {
    let Some(request) = parse(data) else {
        return;
    };
    let head = check_head(request.method(), request.uri(), request.headers());
    if let Err(e) = &head {
        assert_one_line("HTTP head", &e.to_string());
    }
    // Accepts every job; knows one scene object.
    let backend = Fake {
        objects: [(SCENE_KEY.to_owned(), SCENE_OBJ.to_vec())].into(),
        ..Fake::default()
    };
    let response = handle(&backend, request);
    let status = response.status();
    let documented = [
        StatusCode::OK,
        StatusCode::ACCEPTED,
        StatusCode::BAD_REQUEST,
        StatusCode::NOT_FOUND,
        StatusCode::METHOD_NOT_ALLOWED,
        StatusCode::PAYLOAD_TOO_LARGE,
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
        StatusCode::UNPROCESSABLE_ENTITY,
    ];
    assert!(
        documented.contains(&status),
        "HTTP: undocumented status {status}"
    );
    if status.is_client_error() {
        let body: serde_json::Value =
            serde_json::from_slice(response.body()).expect("an error body is JSON");
        let message = body["error"]["message"]
            .as_str()
            .expect("an error body has error.message");
        assert_one_line("HTTP", message);
        assert!(body["error"]["code"].is_string(), "HTTP: no error.code");
    }
}

/// The request an input stands for.
fn parse(data: &[u8]) -> Option<Request<Vec<u8>>> {
    let (head, body) = crate::scratch::cut(data, b"\n\n");
    let head = std::str::from_utf8(head).ok()?;
    let mut lines = head.split('\n');
    let (method, uri) = lines.next()?.split_once(' ')?;
    let mut builder = Request::builder()
        .method(Method::from_bytes(method.as_bytes()).ok()?)
        .uri(uri);
    for line in lines {
        let (name, value) = line.split_once(':')?;
        builder = builder.header(name.trim(), value.trim());
    }
    builder.body(body.to_vec()).ok()
}
