//! An S3 server inside the process: objects live as files under a data directory and are served
//! over the real S3 HTTP protocol (SigV4-signed, path-style) on `127.0.0.1` at a random port, so
//! the emulator exercises exactly the code path that talks to AWS S3.
//!
//! Built from `s3s` (protocol, SigV4 verification) and `s3s-fs` (storage), wrapped by
//! [`object_files`] so that object keys behave as S3 keys rather than file paths (`a` and `a/b`
//! can both exist) and conditional puts are atomic.
//!
//! The server runs on a tokio runtime of its own (two worker threads named `hort-embedded-s3`),
//! so callers need no runtime. Dropping [`EmbeddedS3`] stops accepting, lets open requests
//! finish (up to 5 s) and joins the runtime; drop it outside async tasks (a plain thread or
//! `main`), as for any tokio runtime. Objects stay on disk after the server stops.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod fault_layer;
mod faults;
mod object_files;

pub use faults::{FaultCounts, FaultKind, PersistentFault, StorageFaults};

use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use hyper_util::rt::{TokioExecutor, TokioIo};
use hyper_util::server::conn::auto::Builder as ConnBuilder;
use hyper_util::server::graceful::GracefulShutdown;
use s3s::auth::{S3Auth, SecretKey};
use s3s::service::S3ServiceBuilder;
use s3s::{S3Result, s3_error};
use tokio::net::TcpListener;
use tokio::runtime::Runtime;
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

use self::fault_layer::{FaultyService, ResetFlag, ResettableStream};
use self::faults::Injector;
use self::object_files::ObjectFiles;

/// How long dropping the server waits for requests in flight before cutting them off.
const GRACEFUL_SHUTDOWN: Duration = Duration::from_secs(5);

/// Why the embedded S3 server could not start or create a bucket. Each message is one line that
/// names what was attempted.
#[derive(Debug, thiserror::Error)]
pub enum EmbeddedS3Error {
    /// A filesystem or socket operation failed.
    #[error("embedded S3 server: cannot {what}: {cause}")]
    Io {
        /// What was attempted, naming the path or address.
        what: String,
        /// The operating system's reason.
        cause: io::Error,
    },
    /// The name breaks the S3 bucket naming rules.
    #[error(
        "embedded S3 server: {name:?} is not a valid bucket name (3-63 characters: lowercase \
         letters, digits, '-' and '.')"
    )]
    InvalidBucketName {
        /// The rejected name.
        name: String,
    },
    /// The fault specification is out of range.
    #[error("embedded S3 server: invalid faults: {reason}")]
    InvalidFaults {
        /// What is wrong, naming the field.
        reason: String,
    },
}

/// A running S3 server on `127.0.0.1` storing objects under one data directory.
///
/// Guarantees: [`EmbeddedS3::endpoint`] answers S3 requests signed (SigV4) with the access key
/// and secret given to [`EmbeddedS3::start`]; requests signed with other keys are refused with
/// `InvalidAccessKeyId` or `SignatureDoesNotMatch`, as AWS does. Clients must use path-style
/// addressing (`http://127.0.0.1:PORT/bucket/key`). Buckets are subdirectories of the data
/// directory; a bucket exists once [`EmbeddedS3::ensure_bucket`] or a `CreateBucket` made it.
pub struct EmbeddedS3 {
    endpoint: String,
    data_dir: PathBuf,
    shutdown: Option<oneshot::Sender<()>>,
    server: Option<JoinHandle<()>>,
    runtime: Option<Runtime>,
    /// The fault injector, when started with faults.
    injector: Option<Arc<Injector>>,
}

impl EmbeddedS3 {
    /// Creates `data_dir` if needed and starts serving it on a free port of `127.0.0.1`.
    ///
    /// Returns once the socket is bound, so [`EmbeddedS3::endpoint`] accepts connections
    /// immediately. Existing buckets and objects under `data_dir` are served as they are.
    pub fn start(
        data_dir: &Path,
        access_key: &str,
        secret_key: &str,
    ) -> Result<Self, EmbeddedS3Error> {
        Self::start_inner(data_dir, access_key, secret_key, None)
    }

    /// [`EmbeddedS3::start`], injecting `faults` into the HTTP exchanges (see
    /// [`StorageFaults`]): error answers, delays, reset connections and cut bodies, drawn per
    /// request from the seed. Objects are stored exactly as without faults; only the answers
    /// are damaged. Fails with [`EmbeddedS3Error::InvalidFaults`] if the rates are out of range.
    pub fn start_with_faults(
        data_dir: &Path,
        access_key: &str,
        secret_key: &str,
        faults: StorageFaults,
    ) -> Result<Self, EmbeddedS3Error> {
        faults
            .validate()
            .map_err(|reason| EmbeddedS3Error::InvalidFaults { reason })?;
        Self::start_inner(
            data_dir,
            access_key,
            secret_key,
            Some(Arc::new(Injector::new(faults))),
        )
    }

    fn start_inner(
        data_dir: &Path,
        access_key: &str,
        secret_key: &str,
        injector: Option<Arc<Injector>>,
    ) -> Result<Self, EmbeddedS3Error> {
        std::fs::create_dir_all(data_dir).map_err(|cause| EmbeddedS3Error::Io {
            what: format!("create data directory {}", data_dir.display()),
            cause,
        })?;
        let data_dir = data_dir
            .canonicalize()
            .map_err(|cause| EmbeddedS3Error::Io {
                what: format!("resolve data directory {}", data_dir.display()),
                cause,
            })?;
        let files = s3s_fs::FileSystem::new(&data_dir).map_err(|e| EmbeddedS3Error::Io {
            what: format!("open data directory {}", data_dir.display()),
            cause: io::Error::other(describe_fs_error(e)),
        })?;
        let mut builder = S3ServiceBuilder::new(ObjectFiles::new(files, data_dir.clone()));
        builder.set_auth(SingleKeyAuth {
            access_key: access_key.to_owned(),
            secret_key: SecretKey::from(secret_key),
        });
        let service = builder.build();

        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("hort-embedded-s3")
            .enable_all()
            .build()
            .map_err(|cause| EmbeddedS3Error::Io {
                what: "start its tokio runtime".to_owned(),
                cause,
            })?;
        let listener = runtime
            .block_on(TcpListener::bind(("127.0.0.1", 0)))
            .map_err(|cause| EmbeddedS3Error::Io {
                what: "bind 127.0.0.1:0".to_owned(),
                cause,
            })?;
        let addr = listener.local_addr().map_err(|cause| EmbeddedS3Error::Io {
            what: "read the bound address".to_owned(),
            cause,
        })?;
        let (shutdown, stop) = oneshot::channel();
        let server = runtime.spawn(serve(listener, service, injector.clone(), stop));
        Ok(Self {
            endpoint: format!("http://{addr}"),
            data_dir,
            shutdown: Some(shutdown),
            server: Some(server),
            runtime: Some(runtime),
            injector,
        })
    }

    /// The faults injected so far (all zero for a server started without faults).
    pub fn fault_counts(&self) -> FaultCounts {
        self.injector
            .as_ref()
            .map(|i| i.counts())
            .unwrap_or_default()
    }

    /// The URL to give an S3 client: `http://127.0.0.1:PORT`, no trailing slash.
    pub fn endpoint(&self) -> String {
        self.endpoint.clone()
    }

    /// The data directory, absolute and canonical; bucket `b` is its subdirectory `b`.
    pub fn data_dir(&self) -> &Path {
        &self.data_dir
    }

    /// Creates bucket `name` unless it exists; existing objects are kept. Rejects names that
    /// break the S3 bucket naming rules.
    pub fn ensure_bucket(&self, name: &str) -> Result<(), EmbeddedS3Error> {
        if !s3s::path::check_bucket_name(name) {
            return Err(EmbeddedS3Error::InvalidBucketName {
                name: name.to_owned(),
            });
        }
        let dir = self.data_dir.join(name);
        std::fs::create_dir_all(&dir).map_err(|cause| EmbeddedS3Error::Io {
            what: format!("create bucket directory {}", dir.display()),
            cause,
        })
    }
}

impl std::fmt::Debug for EmbeddedS3 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EmbeddedS3")
            .field("endpoint", &self.endpoint)
            .field("data_dir", &self.data_dir)
            .finish_non_exhaustive()
    }
}

impl Drop for EmbeddedS3 {
    fn drop(&mut self) {
        if let Some(shutdown) = self.shutdown.take() {
            // The server task may already be gone; then there is nothing to stop.
            let _ = shutdown.send(());
        }
        let Some(runtime) = self.runtime.take() else {
            return;
        };
        if tokio::runtime::Handle::try_current().is_ok() {
            // Blocking inside a runtime would panic: stop without waiting.
            runtime.shutdown_background();
            return;
        }
        if let Some(server) = self.server.take() {
            // The serve loop never panics; a join error can only be a cancellation.
            let _ = runtime.block_on(server);
        }
        runtime.shutdown_timeout(Duration::from_secs(1));
    }
}

/// Accepts connections until `stop` fires, then waits up to [`GRACEFUL_SHUTDOWN`] for open
/// connections to finish their current request.
async fn serve(
    listener: TcpListener,
    service: s3s::service::S3Service,
    injector: Option<Arc<Injector>>,
    mut stop: oneshot::Receiver<()>,
) {
    let http = ConnBuilder::new(TokioExecutor::new());
    let graceful = GracefulShutdown::new();
    loop {
        tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((socket, _peer)) => {
                    // Small request/response pairs stall ~40 ms under Nagle + delayed ACK.
                    let _ = socket.set_nodelay(true);
                    let reset = Arc::new(ResetFlag::default());
                    let service = FaultyService {
                        inner: service.clone(),
                        injector: injector.clone(),
                        reset: Arc::clone(&reset),
                    };
                    let socket = ResettableStream::new(socket, reset);
                    let conn = http.serve_connection(TokioIo::new(socket), service);
                    let conn = graceful.watch(conn.into_owned());
                    // A connection error means the client went away; nothing to report.
                    tokio::spawn(async move {
                        let _ = conn.await;
                    });
                }
                // Out of file descriptors or a connection reset before accept: back off, go on.
                Err(_) => tokio::time::sleep(Duration::from_millis(10)).await,
            },
            _ = &mut stop => break,
        }
    }
    drop(listener);
    let _ = tokio::time::timeout(GRACEFUL_SHUTDOWN, graceful.shutdown()).await;
}

/// The reason inside an `s3s_fs::Error` (which has no `Display` of its own).
fn describe_fs_error(e: s3s_fs::Error) -> String {
    let e = s3s::S3Error::from(e);
    e.source()
        .map_or_else(|| format!("{:?}", e.code()), ToString::to_string)
}

/// One access key pair, refusing unknown keys with `InvalidAccessKeyId` as AWS S3 does
/// (`s3s::auth::SimpleAuth` answers `NotSignedUp`, which no AWS client expects).
struct SingleKeyAuth {
    access_key: String,
    secret_key: SecretKey,
}

#[async_trait::async_trait]
impl S3Auth for SingleKeyAuth {
    async fn get_secret_key(&self, access_key: &str) -> S3Result<SecretKey> {
        if access_key == self.access_key {
            Ok(self.secret_key.clone())
        } else {
            Err(s3_error!(
                InvalidAccessKeyId,
                "The AWS Access Key Id you provided does not exist in our records."
            ))
        }
    }
}
