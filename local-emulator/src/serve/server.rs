//! The HTTP side of `hort serve`: hyper 1 over HTTP/1.1 (on 127.0.0.1 unless told otherwise),
//! each request answered by
//! the router of `hort_functions::api` on a thread of its own (the router blocks on storage and
//! scene parsing). Bodies are checked before they are read: the head first
//! ([`api::check_head`]: route, method, content type, a declared length over the limit), then
//! the body is read up to [`api::MAX_BODY_BYTES`] and no further.

use std::convert::Infallible;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Instant;

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

/// Serves `backend` on `addr` until `stop` fires. `ready` gets the bound address (the port may
/// be 0: a free one).
pub fn serve(
    backend: Arc<dyn RenderBackend>,
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
                            respond(Arc::clone(&backend), request, started)
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
                        Ok(_) => rx.await.unwrap_or_else(|_| {
                            ApiError::internal("the request's thread ended without an answer")
                                .into_response()
                        }),
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
