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
//! answer is dropped). At most the API function's reserved concurrency (the deployment's, 10) of
//! requests run at once: one more is throttled by Lambda, which API Gateway also answers with
//! that 500, at once. A request holds its seat until it is answered or its timeout stops it.

use std::convert::Infallible;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
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

/// The API function's settings, as the deployment sets them.
#[derive(Debug, Clone, Copy)]
pub struct ApiFunction {
    /// Its timeout: a request not answered by then gets API Gateway's 500.
    pub timeout: Duration,
    /// Its reserved concurrency: requests at once past it get API Gateway's 500 at once;
    /// `None`: unreserved.
    pub reserved_concurrency: Option<usize>,
}

/// Requests running in the API function, against its reserved concurrency.
struct Seats {
    reserved: Option<usize>,
    taken: AtomicUsize,
}

/// One request's seat, freed when dropped.
struct Seat<'a>(&'a AtomicUsize);

impl Seats {
    /// A seat, or `None` when all `reserved` are taken (Lambda throttles the invocation).
    fn take(&self) -> Option<Seat<'_>> {
        let reserved = self.reserved.unwrap_or(usize::MAX);
        self.taken
            .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| {
                (n < reserved).then_some(n + 1)
            })
            .ok()
            .map(|_| Seat(&self.taken))
    }
}

impl Drop for Seat<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Serves `backend` on `addr` until `stop` fires, as the API function `api` would answer
/// behind API Gateway. `ready` gets the bound address (the port may be 0: a free one).
pub fn serve(
    backend: Arc<dyn RenderBackend>,
    api: ApiFunction,
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
        let seats = Arc::new(Seats {
            reserved: api.reserved_concurrency,
            taken: AtomicUsize::new(0),
        });
        let mut stop = stop;
        loop {
            tokio::select! {
                accepted = listener.accept() => {
                    let Ok((stream, _peer)) = accepted else { continue };
                    let backend = Arc::clone(&backend);
                    let seats = Arc::clone(&seats);
                    tokio::spawn(async move {
                        let service = service_fn(move |request| {
                            respond(
                                Arc::clone(&backend),
                                request,
                                started,
                                api.timeout,
                                Arc::clone(&seats),
                            )
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
    seats: Arc<Seats>,
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
                Ok(collected) => 'invoked: {
                    let Some(_seat) = seats.take() else {
                        break 'invoked api_gateway_500(&format!(
                            "the API function is running {} requests, its reserved \
                             concurrency: Lambda throttles this one (TooManyRequestsException), \
                             API Gateway answers 500",
                            seats.reserved.unwrap_or_default()
                        ));
                    };
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
    api_gateway_500(&format!(
        "the API function ran past its timeout of {} s: Lambda stops it, API Gateway answers 500",
        timeout.as_secs_f64()
    ))
}

/// API Gateway's `500 {"message":"Internal Server Error"}` when the Lambda integration fails
/// (`why` goes to the log, as it would to CloudWatch: the client sees nothing of it).
fn api_gateway_500(why: &str) -> Response<Vec<u8>> {
    eprintln!("{why}");
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
    use hort_functions::api::fake::Fake;
    use std::io::{Read, Write};

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

    /// [`serve`] of a backend that lists slowly (2 s, past the timeout) and knows no job, as
    /// the API function `api`, on a free port of 127.0.0.1: its address, and a closure that
    /// stops it and waits for it.
    fn start(api: ApiFunction) -> (SocketAddr, impl FnOnce()) {
        let (addr_tx, addr_rx) = std::sync::mpsc::channel();
        let (stop_tx, stop_rx) = oneshot::channel();
        let server = std::thread::spawn(move || {
            serve(
                Arc::new(Fake {
                    list_delay: Duration::from_secs(2),
                    ..Fake::default()
                }),
                api,
                "127.0.0.1:0".parse().unwrap(),
                |addr| addr_tx.send(addr).unwrap(),
                stop_rx,
            )
        });
        let stop = move || {
            stop_tx.send(()).unwrap();
            server.join().unwrap().unwrap();
        };
        (addr_rx.recv().unwrap(), stop)
    }

    #[test]
    fn a_request_past_the_api_functions_timeout_gets_api_gateways_500() {
        let (addr, stop) = start(ApiFunction {
            timeout: Duration::from_millis(300),
            reserved_concurrency: None,
        });
        let slow = get(addr, "/renders");
        assert!(slow.starts_with("HTTP/1.1 500 "), "{slow}");
        assert!(
            slow.ends_with("\r\n\r\n{\"message\":\"Internal Server Error\"}"),
            "{slow}"
        );
        let quick = get(addr, "/renders/r-1");
        assert!(quick.starts_with("HTTP/1.1 404 "), "{quick}");
        stop();
    }

    #[test]
    fn a_request_past_the_api_functions_reserved_concurrency_gets_api_gateways_500_at_once() {
        let (addr, stop) = start(ApiFunction {
            timeout: Duration::from_secs(10),
            reserved_concurrency: Some(1),
        });
        // The list takes 2 s: it holds the one seat meanwhile.
        let slow = std::thread::spawn(move || get(addr, "/renders"));
        std::thread::sleep(Duration::from_millis(500));
        let t0 = Instant::now();
        let throttled = get(addr, "/renders/r-1");
        assert!(throttled.starts_with("HTTP/1.1 500 "), "{throttled}");
        assert!(
            throttled.ends_with("\r\n\r\n{\"message\":\"Internal Server Error\"}"),
            "{throttled}"
        );
        assert!(t0.elapsed() < Duration::from_secs(1), "throttled at once");
        let slow = slow.join().unwrap();
        assert!(slow.starts_with("HTTP/1.1 200 "), "{slow}");
        // The seat is free again.
        let quick = get(addr, "/renders/r-1");
        assert!(quick.starts_with("HTTP/1.1 404 "), "{quick}");
        stop();
    }
}
