//! Where the emulator keeps objects: an S3 server embedded in the process (default) or any S3
//! bucket (an S3-compatible endpoint or AWS S3 itself), always reached through the real S3
//! protocol with `S3Store`.
//!
//! Every run also gets a temporary folder, `{temp}/hort-s3-{pid}-{n}/` (`{temp}`: `$TMPDIR` when
//! set, else `/dev/shm` where it is a writable directory, else the system's temporary folder;
//! see [`temp_roots`]): the embedded server's
//! objects when no data folder is given (`data/`) and the Plan function's scratch copy of the
//! scene (`work/`). It is removed when the [`Storage`] is dropped, again by
//! [`remove_temp_folders`] (which the command calls just before it exits, however it exits,
//! since tasks a cancelled run abandoned may still write), and, if the process was killed
//! outright (SIGKILL), by the next [`Storage::open`] once the owning process is gone.

use anyhow::{Result, anyhow, bail};
use embedded_s3::{EmbeddedS3, StorageFaults};
use hort_core::store::{BlobStore, CountingStore};
use hort_functions::s3_store::BucketProblem;
use hort_functions::{S3Config, S3Credentials, S3Store};
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// The file in a data folder holding its embedded server's key pair (`ACCESS SECRET`), owner
/// read and write only.
pub const EMBEDDED_KEY_FILE: &str = ".hort-s3-key";
/// Bucket used with the embedded server.
pub const EMBEDDED_BUCKET: &str = "hort";
/// The environment variable holding storage faults for the embedded server (a specification
/// `embedded_s3::StorageFaults` parses, such as `seed=1,slow-down=0.05,reset=0.05`): a testing
/// aid, not a command-line flag.
pub const S3_FAULTS_VAR: &str = "HORT_S3_FAULTS";
/// Name prefix of the per-run temporary folders, followed by `{pid}-{n}`.
const TEMP_PREFIX: &str = "hort-s3-";
/// The file inside a temporary folder that its process keeps locked while it lives.
const OWNER_LOCK: &str = "owner.lock";

/// Which S3 service to use.
#[derive(Clone, Debug)]
pub enum StorageTarget {
    /// Start an S3 server in this process over `data_dir` (a temporary folder when `None`).
    Embedded {
        /// Where objects are kept after the run; a temporary folder, removed at exit, if `None`.
        data_dir: Option<PathBuf>,
    },
    /// An S3-compatible endpoint (MinIO, Garage, Ceph RGW, moto) with path-style requests and
    /// region `us-east-1`: [`S3Config::compatible`] with these credentials.
    External {
        /// The endpoint URL, e.g. `http://127.0.0.1:9000`.
        endpoint: String,
        /// The bucket holding the jobs; it must exist.
        bucket: String,
        /// How requests are signed.
        credentials: S3Credentials,
    },
    /// Any bucket as a full configuration: AWS S3 itself (`endpoint: None`) or an
    /// S3-compatible endpoint with a chosen region. The bucket must exist.
    Bucket(S3Config),
}

impl StorageTarget {
    /// True if the objects outlive the process (a bucket, or an embedded data folder).
    pub fn is_persistent(&self) -> bool {
        !matches!(self, StorageTarget::Embedded { data_dir: None })
    }

    /// The `hort` storage flags naming this target, each preceded by a space, for commands
    /// suggested in messages (credentials left out); empty for a temporary embedded server.
    pub fn flags(&self) -> String {
        match self {
            StorageTarget::Embedded { data_dir: None } => String::new(),
            StorageTarget::Embedded {
                data_dir: Some(dir),
            } => format!(" --data-dir {}", dir.display()),
            StorageTarget::External {
                endpoint, bucket, ..
            } => format!(" --s3-endpoint {endpoint} --bucket {bucket}"),
            StorageTarget::Bucket(config) => {
                let mut flags = match &config.endpoint {
                    Some(endpoint) => format!(" --s3-endpoint {endpoint}"),
                    None => String::new(),
                };
                flags += &format!(" --bucket {}", config.bucket);
                if let Some(region) = &config.region {
                    flags += &format!(" --region {region}");
                }
                flags
            }
        }
    }
}

/// An opened bucket: the store every function and the orchestrator use, with request counts.
pub struct Storage {
    /// The bucket's objects over the S3 protocol, with request counts.
    pub store: Arc<CountingStore<S3Store>>,
    /// The bucket's name.
    pub bucket: String,
    /// The S3 endpoint URL the store talks to (`AWS S3 (REGION)` for AWS itself).
    pub endpoint: String,
    /// How the store's client reaches the bucket: other runs can open the same bucket with
    /// `StorageTarget::Bucket(config)` while this storage (and its embedded server) lives.
    pub config: S3Config,
    /// Keeps the embedded server alive; dropped before the temporary folder.
    server: Option<EmbeddedS3>,
    /// Whether the embedded server injects faults ([`S3_FAULTS_VAR`]).
    injecting: bool,
    temp: TempFolder,
}

impl Drop for Storage {
    /// Reports the storage faults injected, if any were asked for.
    fn drop(&mut self) {
        if let Some(server) = self.server.as_ref().filter(|_| self.injecting) {
            eprintln!(
                "hort: {S3_FAULTS_VAR}: the embedded S3 server injected {}",
                server.fault_counts()
            );
        }
    }
}

/// The storage faults of [`S3_FAULTS_VAR`], if it is set and not empty.
fn faults_from_env() -> Result<Option<StorageFaults>> {
    match std::env::var(S3_FAULTS_VAR) {
        Ok(spec) if !spec.trim().is_empty() => spec
            .parse()
            .map(Some)
            .map_err(|e| anyhow!("{S3_FAULTS_VAR}={spec:?}: {e}")),
        _ => Ok(None),
    }
}

impl Storage {
    /// Starts or connects to the target and checks the bucket and the credentials, with
    /// one-line errors that say what to do. First removes the temporary folders of runs whose
    /// process is gone.
    pub fn open(target: &StorageTarget) -> Result<Storage> {
        Self::open_scaled(target, 1.0)
    }

    /// [`Storage::open`], with the S3 client's backoff between attempts of a request scaled by
    /// `time_scale` (the orchestrator's), for the embedded server and `External` endpoints;
    /// a `Bucket` configuration is used as given. With [`S3_FAULTS_VAR`] set, the embedded
    /// server injects those faults (and reports their counts on standard error when the
    /// storage is dropped); with another target it is an error.
    pub fn open_scaled(target: &StorageTarget, time_scale: f64) -> Result<Storage> {
        remove_stale_temp_folders();
        let faults = faults_from_env()?;
        if faults.is_some() && !matches!(target, StorageTarget::Embedded { .. }) {
            bail!(
                "{S3_FAULTS_VAR} injects faults into the embedded S3 server only: unset it to                  use another S3 endpoint"
            );
        }
        let scaled = |mut config: S3Config| {
            config.initial_backoff = config.initial_backoff.mul_f64(time_scale.clamp(1e-3, 1e3));
            config
        };
        let temp = TempFolder::create()?;
        match target {
            StorageTarget::Embedded { data_dir } => {
                let dir = data_dir.clone().unwrap_or_else(|| temp.path().join("data"));
                std::fs::create_dir_all(&dir)
                    .map_err(|e| anyhow!("cannot create data folder {}: {e}", dir.display()))?;
                let (access, secret) = match data_dir {
                    Some(dir) => data_dir_keys(dir)?,
                    None => random_keys()?,
                };
                let injecting = faults.is_some();
                let server = match faults {
                    Some(faults) => EmbeddedS3::start_with_faults(&dir, &access, &secret, faults),
                    None => EmbeddedS3::start(&dir, &access, &secret),
                }
                .map_err(|e| anyhow!("cannot start the embedded S3 server: {e}"))?;
                server
                    .ensure_bucket(EMBEDDED_BUCKET)
                    .map_err(|e| anyhow!("cannot create the embedded bucket: {e}"))?;
                let config = scaled(S3Config::compatible(
                    server.endpoint(),
                    EMBEDDED_BUCKET,
                    &access,
                    &secret,
                ));
                let store = S3Store::open(&config)?;
                store.check_bucket()?;
                Ok(Storage {
                    endpoint: server.endpoint(),
                    store: Arc::new(CountingStore::new(store)),
                    bucket: EMBEDDED_BUCKET.into(),
                    config,
                    server: Some(server),
                    injecting,
                    temp,
                })
            }
            StorageTarget::External {
                endpoint,
                bucket,
                credentials,
            } => {
                let mut config = S3Config::compatible(endpoint.clone(), bucket.clone(), "", "");
                config.credentials = credentials.clone();
                open_bucket(&scaled(config), temp)
            }
            StorageTarget::Bucket(config) => open_bucket(config, temp),
        }
    }

    /// The store as the trait object handlers take.
    pub fn blob_store(&self) -> Arc<dyn BlobStore> {
        self.store.clone()
    }

    /// The S3 store itself (listing with sizes, parallel deletes), without request counts.
    pub fn s3(&self) -> &S3Store {
        self.store.inner()
    }

    /// A scratch folder of this run (the Plan function's `/tmp`), removed with the storage.
    pub fn work_dir(&self) -> PathBuf {
        self.temp.path().join("work")
    }
}

/// A fresh key pair for an embedded server: `hort-` and 16 random bytes in hex as the access
/// key, 32 random bytes in hex as the secret (from the kernel's random source), so no other
/// local process can sign requests to it.
fn random_keys() -> Result<(String, String)> {
    let mut bytes = [0u8; 48];
    std::io::Read::read_exact(
        &mut File::open("/dev/urandom")
            .map_err(|e| anyhow!("cannot open /dev/urandom for the S3 server's keys: {e}"))?,
        &mut bytes,
    )
    .map_err(|e| anyhow!("cannot read /dev/urandom for the S3 server's keys: {e}"))?;
    let hex = |b: &[u8]| b.iter().map(|x| format!("{x:02x}")).collect::<String>();
    Ok((format!("hort-{}", hex(&bytes[..16])), hex(&bytes[16..])))
}

/// The key pair of a data folder: read from `{dir}/.hort-s3-key`, or made by [`random_keys`]
/// and written there first, created with mode 0600 (owner read and write only). A key file
/// that others may read or write, or that is malformed, is an error naming it.
fn data_dir_keys(dir: &Path) -> Result<(String, String)> {
    use std::io::Write;
    use std::os::unix::fs::{OpenOptionsExt, PermissionsExt};
    let path = dir.join(EMBEDDED_KEY_FILE);
    match std::fs::read_to_string(&path) {
        Ok(text) => {
            let mode = std::fs::metadata(&path)
                .map_err(|e| anyhow!("{}: {e}", path.display()))?
                .permissions()
                .mode();
            if mode & 0o077 != 0 {
                bail!(
                    "{}: others may read or change this key file (mode {:o}); run `chmod 600 {}`",
                    path.display(),
                    mode & 0o777,
                    path.display()
                );
            }
            match text.split_whitespace().collect::<Vec<_>>()[..] {
                [access, secret] if !access.is_empty() && secret.len() >= 32 => {
                    Ok((access.to_owned(), secret.to_owned()))
                }
                _ => bail!(
                    "{}: not a key file (expected `ACCESS SECRET` on one line, the secret at \
                     least 32 characters); delete it and a new key pair is made",
                    path.display()
                ),
            }
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let (access, secret) = random_keys()?;
            let file = std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .mode(0o600)
                .open(&path);
            let mut file = match file {
                Ok(file) => file,
                // Another run over the same folder made it first: use its pair.
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    std::thread::sleep(std::time::Duration::from_millis(50));
                    return data_dir_keys(dir);
                }
                Err(e) => bail!("cannot create {}: {e}", path.display()),
            };
            file.write_all(format!("{access} {secret}\n").as_bytes())
                .map_err(|e| anyhow!("cannot write {}: {e}", path.display()))?;
            Ok((access, secret))
        }
        Err(e) => bail!("cannot read {}: {e}", path.display()),
    }
}

/// Opens a bucket that must exist, explaining missing credentials and a missing bucket.
fn open_bucket(config: &S3Config, temp: TempFolder) -> Result<Storage> {
    let store = S3Store::open(config)?;
    let (bucket, endpoint) = (store.bucket().to_owned(), store.endpoint().to_owned());
    match store.probe_bucket() {
        Ok(()) => {}
        Err(BucketProblem::NoCredentials { detail }) => {
            let detail = detail.map(|d| format!(" ({d})")).unwrap_or_default();
            bail!(
                "no AWS credentials found for bucket {bucket:?} at {endpoint}{detail}: pass \
                 --access-key/--secret-key or set AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY \
                 (or configure an AWS profile)"
            );
        }
        Err(BucketProblem::Missing) => {
            let how = match &config.endpoint {
                Some(_) => format!("--endpoint-url {endpoint}"),
                None => format!("--region {}", store.region().unwrap_or("us-east-1")),
            };
            bail!(
                "bucket {bucket:?} does not exist at {endpoint}: create it first, for example \
                 with `aws s3 mb s3://{bucket} {how}` (hort does not create buckets)"
            );
        }
        Err(BucketProblem::Store(e)) => return Err(e.into()),
    }
    Ok(Storage {
        store: Arc::new(CountingStore::new(store)),
        bucket,
        endpoint,
        config: config.clone(),
        server: None,
        injecting: false,
        temp,
    })
}

/// Every temporary folder this process made (removed ones included: a request still in flight
/// when a run was dropped may recreate part of one).
static TEMP_FOLDERS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Removes every temporary folder of this process that exists now (objects of temporary
/// embedded servers, scratch copies), in use or not. Call it last, just before the process
/// exits: on exit paths that skip destructors, and after a run that was cancelled, whose
/// abandoned tasks may still write.
pub fn remove_temp_folders() {
    let made = TEMP_FOLDERS
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .clone();
    for dir in made.iter().filter(|d| d.exists()) {
        remove_folder(dir);
    }
}

/// Removes this process's temporary folders, then exits with `code` at once (for a second
/// Ctrl-C, when destructors would not run).
pub fn exit_now(code: i32) -> ! {
    remove_temp_folders();
    std::process::exit(code)
}

/// Removes `dir`, trying again a few times in case a request in flight recreated part of it.
fn remove_folder(dir: &Path) {
    for _ in 0..3 {
        if std::fs::remove_dir_all(dir).is_ok() || !dir.exists() {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// Where temporary folders go, in order of preference: `$TMPDIR` when it is set (the user's
/// choice), else `/dev/shm` (memory: the embedded server writes and renames a file or two for
/// every request, and on a disk file system that metadata work was a sixth of a near-empty
/// task's time, measured with `hort bench emulator`), then the system's temporary folder.
fn temp_roots() -> Vec<PathBuf> {
    let mut roots = Vec::new();
    if std::env::var_os("TMPDIR").is_none_or(|v| v.is_empty()) {
        let shm = Path::new("/dev/shm");
        if shm.is_dir() {
            roots.push(shm.to_path_buf());
        }
    }
    roots.push(std::env::temp_dir());
    roots
}

/// One run's temporary folder `{temp}/hort-s3-{pid}-{n}`, locked while it lives, removed on
/// drop.
struct TempFolder {
    path: PathBuf,
    /// Holds the lock on `owner.lock` (released when the process ends, however it ends).
    _lock: File,
}

impl TempFolder {
    fn create() -> Result<TempFolder> {
        // Unique per run: several runs may share a process (benches, tests).
        static RUN: AtomicU64 = AtomicU64::new(0);
        let name = format!(
            "{TEMP_PREFIX}{}-{}",
            std::process::id(),
            RUN.fetch_add(1, Ordering::Relaxed)
        );
        // The first root that takes the folder; the last one's error otherwise.
        let mut made = Err(anyhow!("no temporary folder to create {name} in"));
        for root in temp_roots() {
            let path = root.join(&name);
            made = std::fs::create_dir_all(&path)
                .map(|()| path.clone())
                .map_err(|e| anyhow!("cannot create temporary folder {}: {e}", path.display()));
            if made.is_ok() {
                break;
            }
        }
        let path = made?;
        TEMP_FOLDERS
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(path.clone());
        let folder = |e: std::io::Error| {
            anyhow!(
                "cannot lock temporary folder {}: {e}",
                path.join(OWNER_LOCK).display()
            )
        };
        let lock = File::create(path.join(OWNER_LOCK)).map_err(folder)?;
        lock.try_lock().map_err(|e| folder(e.into()))?;
        Ok(TempFolder { path, _lock: lock })
    }

    fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for TempFolder {
    fn drop(&mut self) {
        remove_folder(&self.path);
    }
}

/// The process id in a temporary folder's name `hort-s3-{pid}-{n}`, if it is one.
fn temp_folder_pid(name: &str) -> Option<u32> {
    let (pid, run) = name.strip_prefix(TEMP_PREFIX)?.split_once('-')?;
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    (digits(pid) && digits(run)).then(|| pid.parse().ok())?
}

/// True unless the process that made `dir` is known to be gone: on Linux, `/proc/{pid}` does
/// not exist; elsewhere, nobody holds the lock on its `owner.lock`.
fn owner_alive(dir: &Path, pid: u32) -> bool {
    if cfg!(target_os = "linux") {
        return Path::new("/proc").join(pid.to_string()).exists();
    }
    match File::open(dir.join(OWNER_LOCK)) {
        Ok(file) => !matches!(file.try_lock(), Ok(())),
        // Created but not yet locked, or not ours after all: leave it.
        Err(_) => true,
    }
}

/// Removes the temporary folders of other processes that are gone (killed before they could
/// clean up). Errors are ignored: this is housekeeping.
pub fn remove_stale_temp_folders() {
    let me = std::process::id();
    let entries = temp_roots()
        .into_iter()
        .filter_map(|root| std::fs::read_dir(root).ok())
        .flatten();
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(temp_folder_pid) else {
            continue;
        };
        let dir = entry.path();
        if pid != me && dir.is_dir() && !owner_alive(&dir, pid) {
            remove_folder(&dir);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temp_folder_names_give_their_pid() {
        assert_eq!(temp_folder_pid("hort-s3-123-0"), Some(123));
        assert_eq!(temp_folder_pid("hort-s3-77-12"), Some(77));
        for other in [
            "hort-s3-",
            "hort-s3-12",
            "hort-s3-12-",
            "hort-s3-a-1",
            "hort-s3-1-2-3",
            "hort-plan-1-2",
            "hort-s3--1",
        ] {
            assert_eq!(temp_folder_pid(other), None, "{other}");
        }
    }

    #[test]
    fn keys_are_random_and_a_data_folder_keeps_its_pair_private() {
        use std::os::unix::fs::PermissionsExt;
        let (a1, s1) = random_keys().unwrap();
        let (a2, s2) = random_keys().unwrap();
        assert_ne!((&a1, &s1), (&a2, &s2));
        assert_eq!((a1.len(), s1.len()), (37, 64));
        let dir = std::env::temp_dir().join(format!("hort-keys-test-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let first = data_dir_keys(&dir).unwrap();
        let path = dir.join(EMBEDDED_KEY_FILE);
        let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        assert_eq!(data_dir_keys(&dir).unwrap(), first);
        assert_ne!(first.1, "hort-local-secret");
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
        let e = data_dir_keys(&dir).unwrap_err().to_string();
        assert_eq!(
            e,
            format!(
                "{}: others may read or change this key file (mode 644); run `chmod 600 {}`",
                path.display(),
                path.display()
            )
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn flags_name_the_target() {
        let mut config = S3Config::aws("b", Some("eu-west-1".into()));
        assert_eq!(
            StorageTarget::Bucket(config.clone()).flags(),
            " --bucket b --region eu-west-1"
        );
        config.endpoint = Some("http://h:9".into());
        config.region = None;
        assert_eq!(
            StorageTarget::Bucket(config).flags(),
            " --s3-endpoint http://h:9 --bucket b"
        );
        assert_eq!(StorageTarget::Embedded { data_dir: None }.flags(), "");
        assert!(!StorageTarget::Embedded { data_dir: None }.is_persistent());
    }
}
