//! The HTTP side of `hort serve`: hyper 1 over HTTP/1.1 (on 127.0.0.1 unless told otherwise),
//! each request answered by
//! the router of `hort_functions::api` on a thread of its own (the router blocks on storage and
//! scene parsing). Bodies are checked before they are read: the head first
//! ([`api::check_head`]: route, method, content type, a declared length over the limit), then
//! the body is read up to [`api::MAX_BODY_BYTES`] and no further.
//!
//! A request is answered within the API function's timeout (the deployment's, 29 s), as API
//! Gateway answers it: past it, Lambda stops the function and the client gets API Gateway's
//! `500 {"message":"Internal Server Error"}` (the emulator cannot stop the request's thread; its
//! answer is dropped).

use std::convert::Infallible;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use bytes::Bytes;
use hort_functions::api::{self, ApiError, RenderBackend};
use http_body_util::{BodyExt, Full, Limited};
use hyper::body::Incoming;
use hyper::server::conn::http1;
use hyper::service::service_fn;
use hyper::{Request, Response};
use hyper_util::rt::TokioIo;
use tokio::net::TcpListener;
use tokio::sync::oneshot;

/// Serves `backend` on `addr` until `stop` fires, each request answered within `timeout` (the
/// API function's). `ready` gets the bound address (the port may be 0: a free one).
pub fn serve(
    backend: Arc<dyn RenderBackend>,
    timeout: Duration,
    addr: SocketAddr,
    ready: impl FnOnce(SocketAddr),
    stop: oneshot::Receiver<()>,
) -> Result<()> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("hort-serve-http")
        .enable_all()
        .build()
        .context("cannot start the HTTP server's runtime")?;
    runtime.block_on(async move {
        let listener = TcpListener::bind(addr)
            .await
            .with_context(|| format!("cannot listen on {addr}"))?;
        ready(listener.local_addr()?);
        let started = Instant::now();
        let mut stop = stop;
        loop {
            tokio::select! {
                accepted = listener.accept() => {
                    let Ok((stream, _peer)) = accepted else { continue };
                    let backend = Arc::clone(&backend);
                    tokio::spawn(async move {
                        let service = service_fn(move |request| {
                            respond(Arc::clone(&backend), request, started, timeout)
                        });
                        // A client that goes away ends its connection, nothing else: jobs run
                        // on their own threads.
                        // A request read in full is answered (and acted on) even if the
                        // client closed its side meanwhile.
                        let _ = http1::Builder::new()
                            .half_close(true)
                            .serve_connection(TokioIo::new(stream), service)
                            .await;
                    });
                }
                _ = &mut stop => break,
            }
        }
        Ok(())
    })
}

type Answer = Response<Full<Bytes>>;

async fn respond(
    backend: Arc<dyn RenderBackend>,
    request: Request<Incoming>,
    started: Instant,
    timeout: Duration,
) -> Result<Answer, Infallible> {
    let t0 = Instant::now();
    let (parts, body) = request.into_parts();
    let line = format!("{} {}", parts.method, parts.uri);
    let response =
        match api::check_head(&parts.method, &parts.uri, &parts.headers) {
            Err(e) => e.into_response(),
            Ok(()) => match Limited::new(body, api::MAX_BODY_BYTES).collect().await {
                Err(e) if e.is::<http_body_util::LengthLimitError>() => {
                    api::too_large_streamed().into_response()
                }
                Err(e) => ApiError::invalid_json(format!("cannot read the request body: {e}"))
                    .into_response(),
                Ok(collected) => {
                    let request = Request::from_parts(parts, collected.to_bytes());
                    let (tx, rx) = oneshot::channel();
                    let spawned = std::thread::Builder::new()
                        .name("hort-serve-request".into())
                        .spawn(move || {
                            let _ = tx.send(api::handle(backend.as_ref(), request));
                        });
                    match spawned {
                        Ok(_) => match tokio::time::timeout(timeout, rx).await {
                            Ok(answer) => answer.unwrap_or_else(|_| {
                                ApiError::internal("the request's thread ended without an answer")
                                    .into_response()
                            }),
                            Err(_) => function_timed_out(timeout),
                        },
                        Err(e) => ApiError::internal(format!("cannot start a thread: {e}"))
                            .into_response(),
                    }
                }
            },
        };
    eprintln!(
        "[{:8.2}s] {line} -> {} ({:.0} ms)",
        started.elapsed().as_secs_f64(),
        response.status().as_u16(),
        t0.elapsed().as_secs_f64() * 1e3
    );
    Ok(response.map(|body| Full::new(Bytes::from(body))))
}

/// API Gateway's answer when the API function ran past its timeout (Lambda stopped it).
fn function_timed_out(timeout: Duration) -> Response<Vec<u8>> {
    eprintln!(
        "the API function ran past its timeout of {} s: Lambda stops it, API Gateway answers 500",
        timeout.as_secs_f64()
    );
    Response::builder()
        .status(500)
        .header("content-type", "application/json")
        .body(
            hort_aws_quotas::API_GATEWAY_INTERNAL_ERROR_BODY
                .as_bytes()
                .to_vec(),
        )
        .expect("a valid response")
}

#[cfg(test)]
mod tests {
    use super::*;
    use hort_functions::api::{
        ImageAnswer, ImageFormat, JobSpec, JobStatus, PredictionModel, Submission,
    };
    use std::io::{Read, Write};

    /// Lists slowly (past the timeout); knows no job, at once.
    struct Slow;

    impl RenderBackend for Slow {
        fn read_object(&self, _: &str) -> Result<Option<Vec<u8>>, ApiError> {
            Ok(None)
        }
        fn prediction_model(&self) -> PredictionModel {
            PredictionModel::reference(1)
        }
        fn submit(&self, _: JobSpec) -> Result<Submission, ApiError> {
            Err(ApiError::internal("not here"))
        }
        fn status(&self, job: &str) -> Result<JobStatus, ApiError> {
            Err(ApiError::not_found(format!("no render {job:?}")))
        }
        fn list(&self, _: usize) -> Result<Vec<JobStatus>, ApiError> {
            std::thread::sleep(Duration::from_secs(2));
            Ok(Vec::new())
        }
        fn image(&self, job: &str, _: ImageFormat) -> Result<ImageAnswer, ApiError> {
            self.status(job).map(|_| unreachable!())
        }
        fn report(&self, job: &str) -> Result<Vec<u8>, ApiError> {
            self.status(job).map(|_| unreachable!())
        }
        fn cancel(&self, job: &str) -> Result<JobStatus, ApiError> {
            self.status(job)
        }
    }

    fn get(addr: SocketAddr, path: &str) -> String {
        let mut stream = std::net::TcpStream::connect(addr).unwrap();
        write!(
            stream,
            "GET {path} HTTP/1.1\r\nhost: {addr}\r\nconnection: close\r\n\r\n"
        )
        .unwrap();
        let mut answer = String::new();
        stream.read_to_string(&mut answer).unwrap();
        answer
    }

    #[test]
    fn a_request_past_the_api_functions_timeout_gets_api_gateways_500() {
        let (addr_tx, addr_rx) = std::sync::mpsc::channel();
        let (stop_tx, stop_rx) = oneshot::channel();
        let server = std::thread::spawn(move || {
            serve(
                Arc::new(Slow),
                Duration::from_millis(300),
                "127.0.0.1:0".parse().unwrap(),
                |addr| addr_tx.send(addr).unwrap(),
                stop_rx,
            )
        });
        let addr = addr_rx.recv().unwrap();
        let slow = get(addr, "/renders");
        assert!(slow.starts_with("HTTP/1.1 500 "), "{slow}");
        assert!(
            slow.ends_with("\r\n\r\n{\"message\":\"Internal Server Error\"}"),
            "{slow}"
        );
        let quick = get(addr, "/renders/r-1");
        assert!(quick.starts_with("HTTP/1.1 404 "), "{quick}");
        stop_tx.send(()).unwrap();
        server.join().unwrap().unwrap();
    }
}
