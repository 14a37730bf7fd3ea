//! The HTTP API of HORT-serverless as a plain function: an [`http::Request`] in, an
//! [`http::Response`] out, over a [`RenderBackend`] that runs the jobs. The same router serves
//! `hort serve` (hyper, on 127.0.0.1) and API Gateway through `lambda_http` (`src/bin/api.rs`);
//! it needs no async runtime and no AWS crate, and builds without feature `aws`.
//!
//! | route | answer |
//! |---|---|
//! | `GET /` | 200 the job dashboard, one self-contained HTML page (`?view=jobs`: its job table alone) |
//! | `GET /renders[?limit=N]` | 200 `{"renders": [...]}`: the newest jobs' statuses, newest first (default 50) |
//! | `POST /renders` | 202 `{"job", "status_url", ...}` once the request and the scene are valid; `?dry_run=true`: 200 with the plan and the prediction, nothing started |
//! | `GET /renders/{id}` | 200 the job's status ([`JobStatus`]) |
//! | `GET /renders/{id}/image[?format=png\|pfm\|exr]` | 200 the image (a job of several frames: its first frame's); 404 until the job succeeded |
//! | `GET /renders/{id}/frames/{k}/image[?format=...]` | 200 frame k's image, as above; 404 for a frame the job did not render |
//! | `GET /renders/{id}/report` | 200 the report JSON of `hort render --report`; 404 until the job succeeded |
//! | `DELETE /renders/{id}` | 200 the status after cancelling (a finished job is left as it is) |
//!
//! Errors are `{"error": {"code", "message", "field"?}}` ([`ApiError`]): 400 for a body that is
//! not JSON, a bad field (named by its JSON path; unknown fields are refused) or a bad scene
//! (named by file and line), 404 for an unknown job or route, 405 for a method the route does
//! not take, 413 for a body over [`MAX_BODY_BYTES`], 415 for a body that is not
//! `application/json`, 422 for a predicted cost over `max_cost_usd`, 429 when the backend runs
//! as many jobs as it takes.
//!
//! A server that streams bodies calls [`check_head`] before reading the body, so a request
//! whose `Content-Length` is over the limit is refused without reading it, and stops reading at
//! the limit otherwise; [`handle`] checks both again.

mod backend;
mod dashboard;
mod error;
#[cfg(any(test, feature = "test-support"))]
pub mod fake;
mod frames;
#[cfg(test)]
mod hostile_tests;
mod image;
mod job_record;
mod request;
mod scene;
mod scene_by_key;
#[cfg(test)]
mod tests;

pub use backend::{
    JobScene, JobSpec, JobState, JobStatus, RenderBackend, StageProgress, Submission, frames_of,
    idempotency_key_expired, idempotency_key_reused, object_in, object_range_in, object_size_in,
    request_fingerprint, with_frames_done,
};
pub use dashboard::{DASHBOARD_JOBS, escape_html, jobs_table, page};
pub use error::ApiError;
pub use hort_core::predict::{
    CLIENT_PUTS, JobStep, Prediction, PredictionModel, RATES, Rates, SPLIT_BYTES_PER_TRIANGLE,
    SPLIT_NORMAL_BYTES_PER_TRIANGLE, StagePrediction, predict, preview_plan, usd,
};
pub use image::{
    ImageAnswer, ImageBucket, ImageFormat, MAX_INLINE_BODY_BYTES, PRESIGNED_URL_SECONDS,
    check_response_size, stored_image,
};
pub use job_record::{JobRecord, fresh_id, job_for, keyed_id, now_unix_us};
pub use request::{MAX_JSON_DEPTH, RenderRequest, SceneSpec, parse_render_request};
pub use scene::{LoadedScene, MAX_SCENE_FILES, SceneFiles, check_relative, material_libraries};
pub use scene_by_key::{ESTIMATE_BOUNDS, SceneEstimate, SizedScene, size_scene};

use std::collections::BTreeMap;

use hort_core::camera::Camera;
use hort_core::error::SceneError;
use hort_core::ids::JobId;
use hort_core::pipeline::estimate::estimated_plan;
use hort_core::pipeline::{MAX_SPANS, MAX_SPLITS, PlanRequest, SplitMode, StoredOutputs};
use hort_core::plural::count;
use hort_core::scene::{
    DEFAULT_HEIGHT, DEFAULT_WIDTH, MAX_IMAGE_SIDE, MAX_SPP, Scene, check_image_size,
};
use http::{HeaderMap, Method, Request, Response, StatusCode, header};
use serde::Serialize;

/// Largest request body, bytes: 6 MiB, the payload limit of a synchronous Lambda invocation,
/// so the local server and a deployment refuse the same requests. Larger scenes go by key.
pub const MAX_BODY_BYTES: usize = 6 * 1024 * 1024;

/// Longest `Idempotency-Key`, bytes.
pub const MAX_IDEMPOTENCY_KEY_BYTES: usize = 255;

/// The routes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Route<'a> {
    Dashboard,
    Renders,
    Render(&'a str),
    /// A render's image, or one frame's (`/renders/{id}/frames/{k}/image`).
    Image(&'a str, Option<&'a str>),
    Report(&'a str),
}

impl Route<'_> {
    fn parse(path: &str) -> Option<Route<'_>> {
        if path == "/" {
            return Some(Route::Dashboard);
        }
        let rest = path.strip_prefix("/renders")?;
        if rest.is_empty() {
            return Some(Route::Renders);
        }
        let rest = rest.strip_prefix('/')?;
        let (id, tail) = match rest.split_once('/') {
            Some((id, tail)) => (id, Some(tail)),
            None => (rest, None),
        };
        if id.is_empty() {
            return None;
        }
        match tail {
            None => Some(Route::Render(id)),
            Some("image") => Some(Route::Image(id, None)),
            Some("report") => Some(Route::Report(id)),
            Some(tail) => {
                let frame = tail.strip_prefix("frames/")?.strip_suffix("/image")?;
                (!frame.is_empty() && !frame.contains('/')).then_some(Route::Image(id, Some(frame)))
            }
        }
    }

    /// The methods the route takes, as the `Allow` header lists them.
    fn allow(self) -> &'static str {
        match self {
            Route::Dashboard => "GET",
            Route::Renders => "GET, POST",
            Route::Render(_) => "GET, DELETE",
            Route::Image(..) | Route::Report(_) => "GET",
        }
    }

    fn takes(self, method: &Method) -> bool {
        match self {
            Route::Dashboard => method == Method::GET,
            Route::Renders => method == Method::GET || method == Method::POST,
            Route::Render(_) => method == Method::GET || method == Method::DELETE,
            Route::Image(..) | Route::Report(_) => method == Method::GET,
        }
    }
}

/// Checks what can be checked before the body is read: the route (404), the method (405), and
/// for `POST /renders` the content type (415) and a declared length over [`MAX_BODY_BYTES`]
/// (413). A server calls this first, and answers with the error without reading the body.
pub fn check_head(method: &Method, uri: &http::Uri, headers: &HeaderMap) -> Result<(), ApiError> {
    let path = uri.path();
    let Some(route) = Route::parse(path) else {
        return Err(ApiError::not_found(format!(
            "no route {method} {path}: the API has /renders, /renders/{{id}}, \
             /renders/{{id}}/image, /renders/{{id}}/frames/{{k}}/image and \
             /renders/{{id}}/report, and the dashboard at /"
        )));
    };
    if !route.takes(method) {
        return Err(ApiError::method_not_allowed(
            format!(
                "{method} is not allowed on {path}; allowed: {}",
                route.allow()
            ),
            route.allow(),
        ));
    }
    if route == Route::Renders && method == Method::POST {
        check_content_type(headers)?;
        if let Some(length) = headers
            .get(header::CONTENT_LENGTH)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.trim().parse::<u64>().ok())
            && length > MAX_BODY_BYTES as u64
        {
            return Err(too_large(length));
        }
    }
    Ok(())
}

/// The 413 error for a body of `length` bytes (or more).
pub fn too_large(length: u64) -> ApiError {
    ApiError::too_large(format!(
        "the request body is {length} bytes, over the limit of {MAX_BODY_BYTES} bytes; give \
         a large scene by key ({{\"scene\": {{\"key\": \"...\"}}}}) instead of inline files"
    ))
}

/// 413 for a body that went over [`MAX_BODY_BYTES`] while it was read (no length declared).
pub fn too_large_streamed() -> ApiError {
    ApiError::too_large(format!(
        "the request body is over the limit of {MAX_BODY_BYTES} bytes; give a large scene by \
         key ({{\"scene\": {{\"key\": \"...\"}}}}) instead of inline files"
    ))
}

fn check_content_type(headers: &HeaderMap) -> Result<(), ApiError> {
    let given = headers
        .get(header::CONTENT_TYPE)
        .map(|v| String::from_utf8_lossy(v.as_bytes()).into_owned());
    let is_json = given.as_deref().is_some_and(|v| {
        v.split(';')
            .next()
            .is_some_and(|t| t.trim().eq_ignore_ascii_case("application/json"))
    });
    if is_json {
        return Ok(());
    }
    Err(ApiError::unsupported_media_type(match given {
        Some(t) => {
            format!("the request body must be JSON (Content-Type: application/json), not {t}")
        }
        None => "the request body must be JSON: send Content-Type: application/json".to_owned(),
    }))
}

/// Answers one request. Never panics on any input; every failure is a JSON error response.
pub fn handle<B: AsRef<[u8]>>(
    backend: &dyn RenderBackend,
    request: Request<B>,
) -> Response<Vec<u8>> {
    let response = match route(backend, request) {
        Ok(response) => response,
        Err(e) => return e.into_response(),
    };
    let text = response
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|t| t.starts_with("text/") || t.starts_with("application/json"));
    match check_response_size(response.body().len(), text) {
        Ok(()) => response,
        Err(e) => e.into_response(),
    }
}

fn route<B: AsRef<[u8]>>(
    backend: &dyn RenderBackend,
    request: Request<B>,
) -> Result<Response<Vec<u8>>, ApiError> {
    let (parts, body) = request.into_parts();
    check_head(&parts.method, &parts.uri, &parts.headers)?;
    let query = parse_query(parts.uri.query().unwrap_or(""))?;
    let route = Route::parse(parts.uri.path()).ok_or_else(|| ApiError::internal("no route"))?;
    match route {
        Route::Dashboard => {
            only_params(&query, &["view"])?;
            let jobs = backend.list(DASHBOARD_JOBS)?;
            let html = match query.get("view").map(String::as_str) {
                None => page(&jobs),
                Some("jobs") => jobs_table(&jobs),
                Some(other) => {
                    return Err(ApiError::invalid_field(
                        "query.view",
                        format!("query.view: \"{other}\" is not jobs"),
                    ));
                }
            };
            let mut response = bytes_response("text/html; charset=utf-8", html.into_bytes())?;
            // The page runs only its own inline script and loads nothing from elsewhere but
            // images: one over a Lambda response's size comes by redirect from the bucket (a
            // presigned S3 URL: https on AWS, the embedded server on loopback under `hort
            // serve`), and a CSP checks the redirect's target too.
            response.headers_mut().insert(
                header::CONTENT_SECURITY_POLICY,
                http::HeaderValue::from_static(
                    "default-src 'self'; script-src 'unsafe-inline'; style-src \
                     'unsafe-inline'; img-src 'self' https: http://127.0.0.1:* \
                     http://localhost:*; frame-ancestors 'none'",
                ),
            );
            Ok(response)
        }
        Route::Renders if parts.method == Method::GET => {
            only_params(&query, &["limit"])?;
            let limit = match query.get("limit") {
                None => DASHBOARD_JOBS,
                Some(text) => text
                    .parse::<usize>()
                    .ok()
                    .filter(|n| (1..=1000).contains(n))
                    .ok_or_else(|| {
                        ApiError::invalid_field(
                            "query.limit",
                            format!("query.limit: \"{text}\" is not a number from 1 to 1000"),
                        )
                    })?,
            };
            let renders: Vec<JobStatus> = backend
                .list(limit)?
                .into_iter()
                .map(with_image_url)
                .collect();
            json(StatusCode::OK, &serde_json::json!({ "renders": renders }))
        }
        Route::Renders => {
            let body = body.as_ref();
            if body.len() > MAX_BODY_BYTES {
                return Err(too_large(body.len() as u64));
            }
            only_params(&query, &["dry_run"])?;
            let dry_run = match query.get("dry_run").map(String::as_str) {
                None | Some("false") => false,
                Some("true") => true,
                Some(other) => {
                    return Err(ApiError::invalid_field(
                        "query.dry_run",
                        format!("query.dry_run: \"{other}\" is not true or false"),
                    ));
                }
            };
            let key = idempotency_key(&parts.headers)?;
            post_renders(backend, body, dry_run, key)
        }
        Route::Render(id) => {
            only_params(&query, &[])?;
            let id = job_id(id)?;
            let status = if parts.method == Method::DELETE {
                backend.cancel(&id)?
            } else {
                backend.status(&id)?
            };
            json(StatusCode::OK, &with_image_url(status))
        }
        Route::Image(id, frame) => {
            only_params(&query, &["format"])?;
            let id = job_id(id)?;
            let frame = frame
                .map(|k| {
                    k.parse::<u32>().map_err(|_| {
                        ApiError::not_found(format!("render {id} has no frame \"{k}\""))
                    })
                })
                .transpose()?;
            let format = match query.get("format") {
                None => ImageFormat::Png,
                Some(name) => ImageFormat::parse(name).ok_or_else(|| {
                    ApiError::invalid_field(
                        "query.format",
                        format!("query.format: \"{name}\" is not one of png, pfm, exr"),
                    )
                })?,
            };
            match backend.image(&id, format, frame)? {
                ImageAnswer::Bytes(bytes) => bytes_response(format.content_type(), bytes),
                ImageAnswer::Redirect { url, bytes } => {
                    let body = serde_json::json!({"image_url": url, "bytes": bytes});
                    let mut response = json(StatusCode::TEMPORARY_REDIRECT, &body)?;
                    let location = http::HeaderValue::from_str(&url).map_err(|e| {
                        ApiError::internal(format!("the presigned URL is no header value: {e}"))
                    })?;
                    response.headers_mut().insert(header::LOCATION, location);
                    Ok(response)
                }
            }
        }
        Route::Report(id) => {
            only_params(&query, &[])?;
            let id = job_id(id)?;
            let bytes = backend.report(&id)?;
            bytes_response("application/json", bytes)
        }
    }
}

/// A job id from a path: anything that is not a valid id names no job.
fn job_id(id: &str) -> Result<String, ApiError> {
    JobId::new(id)
        .map(|id| id.as_str().to_owned())
        .map_err(|_| ApiError::not_found(format!("no render {id:?}")))
}

fn with_image_url(mut status: JobStatus) -> JobStatus {
    if status.status == JobState::Succeeded {
        status.image_url = Some(format!("/renders/{}/image", status.job));
    }
    status
}

/// The query parameters (`a=b&c=d`; `+` and `%XX` decoded); a repeated one is an error.
fn parse_query(query: &str) -> Result<BTreeMap<String, String>, ApiError> {
    let mut params = BTreeMap::new();
    for pair in query.split('&').filter(|p| !p.is_empty()) {
        let (name, value) = pair.split_once('=').unwrap_or((pair, ""));
        let (name, value) = (decode(name), decode(value));
        if params.insert(name.clone(), value).is_some() {
            return Err(ApiError::invalid_field(
                format!("query.{name}"),
                format!("query.{name}: given more than once"),
            ));
        }
    }
    Ok(params)
}

fn decode(text: &str) -> String {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        match bytes[i] {
            b'+' => out.push(b' '),
            b'%' if bytes.len() >= i + 3
                && hex(bytes[i + 1]).is_some()
                && hex(bytes[i + 2]).is_some() =>
            {
                let value = hex(bytes[i + 1]).unwrap_or(0) * 16 + hex(bytes[i + 2]).unwrap_or(0);
                out.push(value as u8);
                i += 2;
            }
            b => out.push(b),
        }
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

fn only_params(query: &BTreeMap<String, String>, known: &[&str]) -> Result<(), ApiError> {
    match query.keys().find(|k| !known.contains(&k.as_str())) {
        None => Ok(()),
        Some(name) => Err(ApiError::invalid_field(
            format!("query.{name}"),
            match known {
                [] => format!("query.{name}: unknown query parameter; this route takes none"),
                _ => format!(
                    "query.{name}: unknown query parameter; this route takes {}",
                    known.join(", ")
                ),
            },
        )),
    }
}

fn idempotency_key(headers: &HeaderMap) -> Result<Option<String>, ApiError> {
    let Some(value) = headers.get("idempotency-key") else {
        return Ok(None);
    };
    let bad = || {
        ApiError::invalid_field(
            "headers.Idempotency-Key",
            format!(
                "headers.Idempotency-Key: must be 1 to {MAX_IDEMPOTENCY_KEY_BYTES} visible ASCII \
                 characters"
            ),
        )
    };
    let text = value.to_str().map_err(|_| bad())?;
    if text.is_empty()
        || text.len() > MAX_IDEMPOTENCY_KEY_BYTES
        || !text.bytes().all(|b| b.is_ascii_graphic())
    {
        return Err(bad());
    }
    Ok(Some(text.to_owned()))
}

fn json<T: Serialize>(status: StatusCode, value: &T) -> Result<Response<Vec<u8>>, ApiError> {
    let mut bytes = serde_json::to_vec_pretty(value)
        .map_err(|e| ApiError::internal(format!("cannot encode the answer: {e}")))?;
    bytes.push(b'\n');
    Response::builder()
        .status(status)
        .header(header::CONTENT_TYPE, "application/json")
        .body(bytes)
        .map_err(|e| ApiError::internal(format!("cannot build the answer: {e}")))
}

fn bytes_response(content_type: &str, bytes: Vec<u8>) -> Result<Response<Vec<u8>>, ApiError> {
    Response::builder()
        .status(StatusCode::OK)
        .header(header::CONTENT_TYPE, content_type)
        .body(bytes)
        .map_err(|e| ApiError::internal(format!("cannot build the answer: {e}")))
}

/// The 202 answer of `POST /renders`.
#[derive(Serialize)]
struct Accepted<'a> {
    job: &'a str,
    status_url: String,
    /// True when the `Idempotency-Key` named an existing job.
    replayed: bool,
    predicted_seconds: f64,
    predicted_cost_usd: f64,
    warnings: &'a [String],
}

/// The 200 answer of a dry run.
#[derive(Serialize)]
struct DryRun<'a> {
    dry_run: bool,
    scene: &'a str,
    #[serde(flatten)]
    prediction: &'a Prediction,
    /// How a scene given by key was sized (its plan is an estimate); absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    scene_estimate: Option<&'a SceneEstimate>,
    max_cost_usd: Option<f64>,
    warnings: &'a [String],
}

fn post_renders(
    backend: &dyn RenderBackend,
    body: &[u8],
    dry_run: bool,
    idempotency_key: Option<String>,
) -> Result<Response<Vec<u8>>, ApiError> {
    let request = parse_render_request(body)?;
    if let Some(budget) = request.max_cost_usd
        && !(budget.is_finite() && budget > 0.0)
    {
        return Err(ApiError::invalid_field(
            "max_cost_usd",
            format!("max_cost_usd: {budget} is not a positive number of dollars"),
        ));
    }
    for (field, value) in [("width", request.width), ("height", request.height)] {
        check_range(field, value, 1, MAX_IMAGE_SIDE)?;
    }
    check_range("spp", request.spp, 1, MAX_SPP)?;
    check_range("splits", request.splits, 1, MAX_SPLITS)?;
    check_range("spans", request.spans, 1, MAX_SPANS)?;
    let mut loaded = load_request_scene(backend, &request.scene)?;
    frames::take_request_animation(&request, &mut loaded)?;
    let scene = loaded.scene();
    let image = scene.image;
    let width = request.width.or(image.width).unwrap_or(DEFAULT_WIDTH);
    let height = request.height.or(image.height).unwrap_or(DEFAULT_HEIGHT);
    let spp = request.spp.or(image.spp).unwrap_or(1);
    check_size(width, height, spp, &request)?;
    Camera::new(&scene.camera_for(width, height), width, height)
        .map_err(|e| ApiError::invalid_scene(format!("{}: {e}", loaded.name())))?;
    let triangles = loaded.triangles();
    let pixels = u64::from(width) * u64::from(height);
    // Tasks run on the deployed Worker: plan for its memory, never for more.
    let worker_memory_mb = backend.prediction_model().memory_mb;
    let plan_request = PlanRequest {
        width,
        height,
        spp,
        splits: request.splits,
        spans: request.spans,
        mode: request.split_mode.unwrap_or(SplitMode::Spatial),
        execution: request.mode,
        memory_mb: request.memory_mb.unwrap_or(worker_memory_mb),
        adaptive: None,
        outputs: request.outputs.unwrap_or(StoredOutputs::ALL),
        frame: frames::frame_choice(&request, scene, width, height)?,
    };
    if let Some(mb) = request.memory_mb {
        let lambda = hort_aws_quotas::LAMBDA_MEMORY_MB;
        if !lambda.contains(&u64::from(mb)) {
            return Err(ApiError::invalid_field(
                "memory_mb",
                format!(
                    "memory_mb: {mb} is out of range: use {} to {}, as Lambda does",
                    lambda.start(),
                    lambda.end()
                ),
            ));
        }
        if mb > worker_memory_mb {
            return Err(ApiError::over_deployment(
                "memory_mb",
                format!(
                    "memory_mb: {mb} MB is more than the deployed Worker function has \
                     ({worker_memory_mb} MB): tasks planned for it would run out of memory; \
                     ask for {worker_memory_mb} MB or less (the default), or redeploy with a \
                     larger WorkerMemoryMB"
                ),
            ));
        }
    }
    let max_k = triangles.min(u64::from(MAX_SPLITS)) as u32;
    let max_s = pixels.min(u64::from(MAX_SPANS)) as u32;
    // A scene by key has an estimated count only: the Plan function checks its splits.
    if let Some(k) = request.splits
        && k > max_k
        && matches!(loaded, RequestScene::Loaded(_))
    {
        return Err(ApiError::invalid_field(
            "splits",
            format!(
                "splits: {k} is out of range: the scene has {}, so use 1 to {max_k}",
                count(triangles, "triangle")
            ),
        ));
    }
    if let Some(s) = request.spans
        && s > max_s
    {
        return Err(ApiError::invalid_field(
            "spans",
            format!(
                "spans: {s} is out of range: the image has {}, so use 1 to {max_s}",
                count(pixels, "pixel")
            ),
        ));
    }
    let (shape, s) = hort_core::pipeline::resolve_counts(&plan_request, triangles)
        .map_err(|e| ApiError::invalid_field("splits", e.to_string()))?;
    let plan = match &loaded {
        RequestScene::Loaded(loaded) => preview_plan(&loaded.scene, &plan_request, &shape, s)
            .map_err(|e| ApiError::invalid_scene(e.to_string()))?,
        RequestScene::ByKey(sized) => estimated_plan(
            &sized.scene,
            sized.estimate.triangles,
            sized.estimate.obj_bytes,
            &plan_request,
            ESTIMATE_BOUNDS,
            SPLIT_BYTES_PER_TRIANGLE + SPLIT_NORMAL_BYTES_PER_TRIANGLE,
        )
        .map_err(|e| ApiError::invalid_scene(format!("{}: {e}", sized.key)))?,
    };
    let prediction = backend.predict(&plan);
    if let Some(budget) = request.max_cost_usd
        && prediction.predicted_cost_usd > budget
    {
        return Err(ApiError::over_budget(format!(
            "the predicted cost {} is over the budget max_cost_usd = {} ({}, about {:.1} s); \
             raise the budget or render fewer pixels or samples",
            usd(prediction.predicted_cost_usd),
            usd(budget),
            count(prediction.tasks_total, "task"),
            prediction.predicted_seconds,
        )));
    }
    if dry_run {
        return json(
            StatusCode::OK,
            &DryRun {
                dry_run: true,
                scene: loaded.name(),
                prediction: &prediction,
                scene_estimate: match &loaded {
                    RequestScene::ByKey(sized) => Some(&sized.estimate),
                    RequestScene::Loaded(_) => None,
                },
                max_cost_usd: request.max_cost_usd,
                warnings: loaded.warnings(),
            },
        );
    }
    let (scene_name, scene, warnings) = match loaded {
        RequestScene::Loaded(loaded) => {
            let scene_bin = hort_core::scene::encode_scene_named(&loaded.scene, &loaded.files.main);
            let LoadedScene {
                files, warnings, ..
            } = loaded;
            let scene = JobScene::Uploaded {
                main: files.main,
                files: files.files,
                scene_bin,
            };
            (files.name, scene, warnings)
        }
        RequestScene::ByKey(sized) => (sized.key.clone(), JobScene::Key(sized.key), Vec::new()),
    };
    let spec = JobSpec {
        scene_name,
        scene,
        request: plan_request,
        prediction: prediction.clone(),
        max_cost_usd: request.max_cost_usd,
        idempotency_key,
        request_fingerprint: backend::request_fingerprint(body),
    };
    let submission = backend.submit(spec)?;
    let status_url = format!("/renders/{}", submission.job);
    let mut response = json(
        StatusCode::ACCEPTED,
        &Accepted {
            job: &submission.job,
            status_url: status_url.clone(),
            replayed: submission.replayed,
            predicted_seconds: prediction.predicted_seconds,
            predicted_cost_usd: prediction.predicted_cost_usd,
            warnings: &warnings,
        },
    )?;
    if let Ok(location) = http::HeaderValue::from_str(&status_url) {
        response.headers_mut().insert(header::LOCATION, location);
    }
    Ok(response)
}

fn check_range(field: &str, value: Option<u32>, lo: u32, hi: u32) -> Result<(), ApiError> {
    match value {
        Some(v) if v < lo || v > hi => Err(ApiError::invalid_field(
            field,
            format!("{field}: {v} is out of range: must be {lo} to {hi}"),
        )),
        _ => Ok(()),
    }
}

/// The image limits of `hort render` (`hort_core::scene::check_image_size`, the one check) on
/// the resolved size, naming the request's field the value came from, or `scene` when the
/// manifest gave it.
fn check_size(width: u32, height: u32, spp: u32, request: &RenderRequest) -> Result<(), ApiError> {
    let named = |given: Option<u32>, field: &'static str| {
        if given.is_some() { field } else { "scene" }
    };
    check_image_size(width, height, spp).map_err(|e| {
        let field = match &e {
            SceneError::OutOfRange { what, .. } if what.contains("spp") => {
                named(request.spp, "spp")
            }
            SceneError::OutOfRange { what, .. } if *what == "height" => {
                named(request.height, "height")
            }
            _ => named(request.width.or(request.height), "width"),
        };
        ApiError::invalid_field(field, e.to_string())
    })
}

/// The request's scene, as far as the API reads it.
enum RequestScene {
    /// Inline files, gathered and loaded.
    Loaded(LoadedScene),
    /// A scene given by key, sized and never loaded.
    ByKey(SizedScene),
}

impl RequestScene {
    /// The scene: whole, or without geometry (by key).
    fn scene(&self) -> &Scene {
        match self {
            RequestScene::Loaded(loaded) => &loaded.scene,
            RequestScene::ByKey(sized) => &sized.scene,
        }
    }

    /// How messages and reports name it: the main file, or the key.
    fn name(&self) -> &str {
        match self {
            RequestScene::Loaded(loaded) => &loaded.files.name,
            RequestScene::ByKey(sized) => &sized.key,
        }
    }

    /// Its triangles: counted, or estimated (by key).
    fn triangles(&self) -> u64 {
        match self {
            RequestScene::Loaded(loaded) => loaded.scene.mesh.triangle_count() as u64,
            RequestScene::ByKey(sized) => sized.estimate.triangles,
        }
    }

    /// The loader's warnings (none for a scene not loaded).
    fn warnings(&self) -> &[String] {
        match self {
            RequestScene::Loaded(loaded) => &loaded.warnings,
            RequestScene::ByKey(_) => &[],
        }
    }
}

/// Gathers and loads the request's inline scene, or sizes the scene given by key (see
/// [`scene_by_key`]).
fn load_request_scene(
    backend: &dyn RenderBackend,
    spec: &SceneSpec,
) -> Result<RequestScene, ApiError> {
    match (&spec.main, &spec.files, &spec.key) {
        (Some(main), Some(files), None) => {
            check_relative(main, "scene.main")
                .map_err(|m| ApiError::invalid_field("scene.main", format!("scene.main: {m}")))?;
            if files.len() > MAX_SCENE_FILES {
                return Err(ApiError::invalid_field(
                    "scene.files",
                    format!(
                        "scene.files: {} files, at most {MAX_SCENE_FILES}",
                        files.len()
                    ),
                ));
            }
            for name in files.keys() {
                check_relative(name, "file").map_err(|m| {
                    ApiError::invalid_field(
                        format!("scene.files.{name}"),
                        format!("scene.files.{name}: {m}"),
                    )
                })?;
            }
            if !files.contains_key(main) {
                return Err(ApiError::invalid_field(
                    "scene.main",
                    format!("scene.main: \"{main}\" is not one of scene.files"),
                ));
            }
            let gathered = scene::gather(main, &|name| name.to_owned(), &mut |name| {
                Ok(files.get(name).map(|text| text.as_bytes().to_vec()))
            })?;
            scene::load(
                SceneFiles {
                    main: main.clone(),
                    name: main.clone(),
                    files: gathered,
                },
                "",
            )
            .map(RequestScene::Loaded)
        }
        (None, None, Some(key)) => {
            check_relative(key, "scene.key")
                .map_err(|m| ApiError::invalid_field("scene.key", format!("scene.key: {m}")))?;
            scene_by_key::size_scene(backend, key).map(RequestScene::ByKey)
        }
        _ => Err(ApiError::invalid_field(
            "scene",
            "scene: give either {\"main\", \"files\"} (the files inline) or {\"key\"} (the main \
             file's key in the bucket)",
        )),
    }
}
