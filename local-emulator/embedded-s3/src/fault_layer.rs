//! The HTTP layer that carries out [`crate::StorageFaults`]: a hyper service around the S3
//! service, a body that stops early, and a socket that can be reset.
//!
//! Error answers (503 `SlowDown`, 500 `InternalError`) are sent instead of carrying the request
//! out. Latency delays the request. Reset and truncation carry the request out (a PUT is
//! stored, a DELETE done), then damage the answer: the client cannot tell whether the request
//! took effect, as with a real network failure.

use std::io;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::task::{Context, Poll};
use std::time::Duration;

use bytes::Bytes;
use http_body::{Frame, SizeHint};
use hyper::body::Incoming;
use s3s::service::S3Service;
use s3s::{Body, HttpError};
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpStream;
use tokio::time::Sleep;

use crate::faults::{Decision, FaultKind, Injector, object_key};

/// How long a damaged body waits after its first half, so that half reaches the client before
/// the connection ends.
const FLUSH_PAUSE: Duration = Duration::from_millis(5);

/// Set when a connection must end with a TCP reset instead of an orderly close.
#[derive(Debug, Default)]
pub(crate) struct ResetFlag(AtomicBool);

impl ResetFlag {
    fn raise(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    fn is_raised(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// A TCP stream that, once its [`ResetFlag`] is raised, fails every read and write and is
/// closed with a reset (`SO_LINGER` 0) when dropped.
pub(crate) struct ResettableStream {
    stream: TcpStream,
    reset: Arc<ResetFlag>,
}

impl ResettableStream {
    pub(crate) fn new(stream: TcpStream, reset: Arc<ResetFlag>) -> Self {
        ResettableStream { stream, reset }
    }

    fn failed(&self) -> Option<io::Error> {
        self.reset
            .is_raised()
            .then(|| io::Error::new(io::ErrorKind::ConnectionReset, "injected connection reset"))
    }
}

impl Drop for ResettableStream {
    fn drop(&mut self) {
        if self.reset.is_raised() {
            // Closing with SO_LINGER 0 sends RST; if it cannot be set, the close is orderly.
            let _ = self.stream.set_zero_linger();
        }
    }
}

impl AsyncRead for ResettableStream {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        if let Some(e) = self.failed() {
            return Poll::Ready(Err(e));
        }
        Pin::new(&mut self.stream).poll_read(cx, buf)
    }
}

impl AsyncWrite for ResettableStream {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        if let Some(e) = self.failed() {
            return Poll::Ready(Err(e));
        }
        Pin::new(&mut self.stream).poll_write(cx, buf)
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        if let Some(e) = self.failed() {
            return Poll::Ready(Err(e));
        }
        Pin::new(&mut self.stream).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        if let Some(e) = self.failed() {
            return Poll::Ready(Err(e));
        }
        Pin::new(&mut self.stream).poll_shutdown(cx)
    }
}

/// The S3 service of one connection, with faults drawn by `injector` (none without one).
#[derive(Clone)]
pub(crate) struct FaultyService {
    pub(crate) inner: S3Service,
    pub(crate) injector: Option<Arc<Injector>>,
    pub(crate) reset: Arc<ResetFlag>,
}

impl hyper::service::Service<http::Request<Incoming>> for FaultyService {
    type Response = http::Response<Body>;
    type Error = HttpError;
    type Future = Pin<Box<dyn Future<Output = Result<Self::Response, Self::Error>> + Send>>;

    fn call(&self, req: http::Request<Incoming>) -> Self::Future {
        let this = self.clone();
        Box::pin(async move { this.handle(req.map(Body::from)).await })
    }
}

impl FaultyService {
    async fn handle(&self, req: http::Request<Body>) -> Result<http::Response<Body>, HttpError> {
        let Some(injector) = &self.injector else {
            return self.inner.call(req).await;
        };
        let path = req.uri().path().to_owned();
        let path_and_query = req
            .uri()
            .path_and_query()
            .map_or_else(|| path.clone(), |p| p.as_str().to_owned());
        let key = object_key(&path);
        let is_head = req.method() == http::Method::HEAD;
        let Some(decision) =
            injector.decide(req.method().as_str(), &path_and_query, key.as_deref())
        else {
            return self.inner.call(req).await;
        };
        match decision.kind {
            FaultKind::SlowDown => {
                injector.count(decision);
                Ok(error_answer(
                    503,
                    "SlowDown",
                    "Please reduce your request rate.",
                    &path,
                ))
            }
            FaultKind::InternalError => {
                injector.count(decision);
                Ok(error_answer(
                    500,
                    "InternalError",
                    "We encountered an internal error. Please try again.",
                    &path,
                ))
            }
            FaultKind::Latency => {
                injector.count(decision);
                tokio::time::sleep(injector.faults.latency_duration).await;
                self.inner.call(req).await
            }
            FaultKind::Reset | FaultKind::Truncate => {
                let answer = self.inner.call(req).await?;
                self.damage(injector, answer, decision, is_head).await
            }
        }
    }

    /// `answer` cut after half its body, then reset or closed as `decision` says.
    async fn damage(
        &self,
        injector: &Injector,
        answer: http::Response<Body>,
        decision: Decision,
        is_head: bool,
    ) -> Result<http::Response<Body>, HttpError> {
        let (parts, mut body) = answer.into_parts();
        let bytes = body
            .store_all_limited(usize::MAX)
            .await
            .map_err(HttpError::new)?;
        if is_head || bytes.is_empty() {
            if decision.kind == FaultKind::Truncate {
                // Nothing to cut: the answer goes out whole, and no fault is counted.
                return Ok(http::Response::from_parts(parts, Body::from(bytes)));
            }
            injector.count(decision);
            self.reset.raise();
            return Err(HttpError::new(Box::new(io::Error::new(
                io::ErrorKind::ConnectionReset,
                "injected connection reset before the answer",
            ))));
        }
        injector.count(decision);
        let body = PartialBody {
            declared: bytes.len() as u64,
            first: Some(bytes.slice(..bytes.len() / 2)),
            pause: None,
            reset: (decision.kind == FaultKind::Reset).then(|| Arc::clone(&self.reset)),
        };
        Ok(http::Response::from_parts(parts, Body::http_body(body)))
    }
}

/// An S3 error answer: the status, `Content-Type: application/xml` and the error document AWS
/// S3 sends.
fn error_answer(status: u16, code: &str, message: &str, resource: &str) -> http::Response<Body> {
    let xml = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Error><Code>{code}</Code><Message>{message}\
         </Message><Resource>{resource}</Resource><RequestId>injected-fault</RequestId></Error>"
    );
    let mut answer = http::Response::new(Body::from(xml));
    *answer.status_mut() = http::StatusCode::from_u16(status).unwrap_or_default();
    answer.headers_mut().insert(
        http::header::CONTENT_TYPE,
        http::HeaderValue::from_static("application/xml"),
    );
    answer
}

/// A body that announces `declared` bytes, sends `first` (fewer), pauses so it is flushed, then
/// ends the connection: with a reset if `reset` is given, else with an error that makes hyper
/// close it (the announced length was not met).
struct PartialBody {
    declared: u64,
    first: Option<Bytes>,
    pause: Option<Pin<Box<Sleep>>>,
    reset: Option<Arc<ResetFlag>>,
}

impl http_body::Body for PartialBody {
    type Data = Bytes;
    type Error = io::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, io::Error>>> {
        if let Some(first) = self.first.take() {
            self.pause = Some(Box::pin(tokio::time::sleep(FLUSH_PAUSE)));
            return Poll::Ready(Some(Ok(Frame::data(first))));
        }
        if let Some(pause) = self.pause.as_mut() {
            std::task::ready!(pause.as_mut().poll(cx));
        }
        let what = match &self.reset {
            Some(flag) => {
                flag.raise();
                "injected connection reset in the middle of the body"
            }
            None => "injected truncation: the body ends before its Content-Length",
        };
        Poll::Ready(Some(Err(io::Error::new(
            io::ErrorKind::ConnectionReset,
            what,
        ))))
    }

    fn size_hint(&self) -> SizeHint {
        SizeHint::with_exact(self.declared)
    }
}

#[cfg(test)]
mod tests {
    use crate::{EmbeddedS3, FaultCounts, FaultKind, PersistentFault, StorageFaults};
    use std::io::{Read, Write};
    use std::time::Instant;

    /// A server over a fresh folder with `faults`; the folder is removed by the caller.
    fn server(name: &str, faults: StorageFaults) -> (EmbeddedS3, std::path::PathBuf) {
        let dir =
            std::env::temp_dir().join(format!("embedded-s3-faults-{name}-{}", std::process::id()));
        let server = EmbeddedS3::start_with_faults(&dir, "ak", "sk", faults).unwrap();
        server.ensure_bucket("bkt").unwrap();
        (server, dir)
    }

    /// What came back for one raw unsigned `GET /bkt/{key}`: the bytes up to the end of the
    /// stream, and the error that ended it, if any.
    fn raw_get(server: &EmbeddedS3, key: &str) -> (Vec<u8>, Option<std::io::ErrorKind>) {
        let addr = server.endpoint().trim_start_matches("http://").to_owned();
        let mut socket = std::net::TcpStream::connect(addr).unwrap();
        socket
            .set_read_timeout(Some(std::time::Duration::from_secs(10)))
            .unwrap();
        write!(
            socket,
            "GET /bkt/{key} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n"
        )
        .unwrap();
        let mut got = Vec::new();
        let mut buf = [0u8; 4096];
        loop {
            match socket.read(&mut buf) {
                Ok(0) => return (got, None),
                Ok(n) => got.extend_from_slice(&buf[..n]),
                Err(e) => return (got, Some(e.kind())),
            }
        }
    }

    /// (status, announced Content-Length, body bytes received).
    fn parse(answer: &[u8]) -> (u16, Option<usize>, Vec<u8>) {
        let text = String::from_utf8_lossy(answer);
        let (head, _) = text.split_once("\r\n\r\n").expect("a complete head");
        let body = answer[head.len() + 4..].to_vec();
        let status = head[9..12].parse().unwrap();
        let length = head
            .lines()
            .find_map(|l| {
                l.to_ascii_lowercase()
                    .strip_prefix("content-length: ")
                    .map(str::to_owned)
            })
            .map(|v| v.trim().parse().unwrap());
        (status, length, body)
    }

    fn only(kind: FaultKind) -> StorageFaults {
        let mut faults = StorageFaults::default();
        match kind {
            FaultKind::SlowDown => faults.slow_down = 1.0,
            FaultKind::InternalError => faults.internal_error = 1.0,
            FaultKind::Latency => faults.latency = 1.0,
            FaultKind::Reset => faults.reset = 1.0,
            FaultKind::Truncate => faults.truncate = 1.0,
        }
        faults
    }

    #[test]
    fn error_answers_are_s3_error_documents() {
        for (kind, status, code) in [
            (FaultKind::SlowDown, 503, "SlowDown"),
            (FaultKind::InternalError, 500, "InternalError"),
        ] {
            let (server, dir) = server(kind.name(), only(kind));
            let (answer, error) = raw_get(&server, "some/key");
            assert_eq!(error, None, "{kind}");
            let (got, length, body) = parse(&answer);
            assert_eq!(got, status, "{kind}");
            assert_eq!(length, Some(body.len()), "{kind}: whole body");
            let body = String::from_utf8(body).unwrap();
            assert!(body.contains(&format!("<Code>{code}</Code>")), "{body}");
            assert!(
                body.contains("<Resource>/bkt/some/key</Resource>"),
                "{body}"
            );
            assert_eq!(server.fault_counts().of(kind), 1);
            assert_eq!(server.fault_counts().total(), 1);
            drop(server);
            let _ = std::fs::remove_dir_all(dir);
        }
    }

    #[test]
    fn truncation_announces_the_length_and_sends_half() {
        let (server, dir) = server("truncate", only(FaultKind::Truncate));
        // The unsigned request is refused with an error document: a body to cut.
        let (answer, error) = raw_get(&server, "k");
        let (status, length, body) = parse(&answer);
        assert_eq!(status, 403);
        let length = length.expect("Content-Length");
        assert!(length > 100, "{length}");
        assert_eq!(
            body.len(),
            length / 2,
            "half of {length} bytes, then the end"
        );
        assert_eq!(error, None, "an orderly close, not a reset");
        assert_eq!(
            server.fault_counts(),
            FaultCounts {
                truncate: 1,
                ..FaultCounts::default()
            }
        );
        drop(server);
        let _ = std::fs::remove_dir_all(dir);
    }

    #[test]
    fn a_reset_cuts_the_body_with_a_tcp_reset() {
        let (server, dir) = server("reset", only(FaultKind::Reset));
        let (answer, error) = raw_get(&server, "k");
        assert_eq!(error, Some(std::io::ErrorKind::ConnectionReset));
        let (status, length, body) = parse(&answer);
        assert_eq!(status, 403);
        assert!(body.len() < length.expect("Content-Length"));
        assert_eq!(server.fault_counts().reset, 1);
        drop(server);
        let _ = std::fs::remove_dir_all(dir);
    }

    #[test]
    fn latency_delays_the_whole_answer() {
        let faults = StorageFaults {
            latency_duration: std::time::Duration::from_millis(300),
            ..only(FaultKind::Latency)
        };
        let (server, dir) = server("latency", faults);
        let started = Instant::now();
        let (answer, error) = raw_get(&server, "k");
        assert!(started.elapsed().as_millis() >= 300);
        assert_eq!(error, None);
        let (status, length, body) = parse(&answer);
        assert_eq!((status, length), (403, Some(body.len())));
        assert_eq!(server.fault_counts().latency, 1);
        drop(server);
        let _ = std::fs::remove_dir_all(dir);
    }

    #[test]
    fn the_persistent_fault_spares_other_keys() {
        let faults = StorageFaults {
            persistent: Some(PersistentFault {
                key_prefix: "jobs/x/".into(),
                kind: FaultKind::InternalError,
            }),
            ..StorageFaults::default()
        };
        let (server, dir) = server("persistent", faults);
        for _ in 0..3 {
            assert_eq!(parse(&raw_get(&server, "jobs/x/a").0).0, 500);
        }
        assert_eq!(parse(&raw_get(&server, "jobs/y/a").0).0, 403);
        assert_eq!(
            server.fault_counts(),
            FaultCounts {
                persistent: 3,
                ..FaultCounts::default()
            }
        );
        drop(server);
        let _ = std::fs::remove_dir_all(dir);
    }

    #[test]
    fn invalid_faults_are_refused() {
        let dir = std::env::temp_dir().join(format!("embedded-s3-bad-{}", std::process::id()));
        let faults = StorageFaults {
            reset: 2.0,
            ..StorageFaults::default()
        };
        let err = EmbeddedS3::start_with_faults(&dir, "ak", "sk", faults).unwrap_err();
        assert_eq!(
            err.to_string(),
            "embedded S3 server: invalid faults: reset: the rate 2 is not between 0 and 1"
        );
    }
}
