//! `hort jobs list|clean`: the jobs in a bucket (or an embedded data folder) and deleting their
//! objects; and the storage target every emulator command builds from its storage flags.

use anyhow::{Result, bail};
use clap::{Args, Subcommand};
use hort::emulator::{EmulatorRun, Storage, StorageTarget, delete_job, list_jobs};
use hort_core::ids::JobId;
use hort_core::plural::count;
use hort_functions::api::JobState;
use hort_functions::{S3Config, S3Credentials};
use std::path::{Path, PathBuf};

#[derive(Subcommand)]
pub enum JobsCommand {
    /// List the jobs: id, status (finished, cancelled or unfinished), objects and bytes, on
    /// standard output.
    List(ListArgs),
    /// Delete every object of one job (--job ID) or of all jobs (--all).
    Clean(CleanArgs),
}

/// The storage flags of every emulator command that reaches a bucket (`hort render`, `hort jobs`):
/// a bucket (--bucket, with --s3-endpoint for a compatible server), or the embedded server over
/// a data folder (--data-dir).
#[derive(Args, Clone, Debug, Default)]
pub struct StorageArgs {
    /// Use this S3-compatible endpoint (MinIO, Garage, Ceph RGW, moto) instead of the embedded
    /// server; credentials from --access-key/--secret-key or the AWS environment.
    #[arg(long, requires = "bucket")]
    pub s3_endpoint: Option<String>,
    /// Bucket at --s3-endpoint, or without it a bucket of AWS S3 itself; it must exist.
    #[arg(long)]
    pub bucket: Option<String>,
    /// Signing region of --bucket (default: AWS_REGION or the AWS profile's, else us-east-1).
    #[arg(long, requires = "bucket")]
    pub region: Option<String>,
    /// Access key for --s3-endpoint (else AWS_ACCESS_KEY_ID and the default chain).
    // `--help` names the variable, never its value (as for the secret key).
    #[arg(
        long,
        requires = "secret_key",
        env = "HORT_S3_ACCESS_KEY",
        hide_env_values = true
    )]
    pub access_key: Option<String>,
    /// Secret key for --s3-endpoint.
    #[arg(
        long,
        requires = "access_key",
        env = "HORT_S3_SECRET_KEY",
        hide_env_values = true
    )]
    pub secret_key: Option<String>,
    /// The embedded server's objects in DIR (`hort render`: default a temporary folder,
    /// removed after).
    #[arg(long, conflicts_with_all = ["s3_endpoint", "bucket"])]
    pub data_dir: Option<PathBuf>,
}

/// Where the jobs to list are: one of --bucket and --data-dir is required.
#[derive(Args)]
#[command(group(clap::ArgGroup::new("where").required(true).args(["bucket", "data_dir"])))]
pub struct ListArgs {
    #[command(flatten)]
    pub storage: StorageArgs,
}

#[derive(Args)]
#[command(group(clap::ArgGroup::new("where").required(true).args(["bucket", "data_dir"])))]
#[command(group(clap::ArgGroup::new("which").required(true).args(["job", "all"])))]
pub struct CleanArgs {
    #[command(flatten)]
    pub storage: StorageArgs,
    /// The job whose objects to delete.
    #[arg(long)]
    pub job: Option<String>,
    /// Delete the objects of every job.
    #[arg(long)]
    pub all: bool,
}

/// The storage target of the storage flags shared by `hort render` and `hort jobs`: a bucket
/// (at `endpoint`, else on AWS S3), else the embedded server over `data_dir` (a temporary
/// folder when `None`). Credentials are the key pair when both are given, else the AWS default
/// chain; the region is `region`, else the chain's, else us-east-1.
fn storage_target(
    endpoint: Option<&str>,
    bucket: Option<&str>,
    region: Option<&str>,
    keys: (Option<&str>, Option<&str>),
    data_dir: Option<&Path>,
) -> StorageTarget {
    let Some(bucket) = bucket else {
        return StorageTarget::Embedded {
            data_dir: data_dir.map(Path::to_path_buf),
        };
    };
    let mut config = match endpoint {
        Some(endpoint) => {
            let mut config = S3Config::compatible(endpoint, bucket, "", "");
            config.region = None;
            config
        }
        None => S3Config::aws(bucket, None),
    };
    config.region = region.map(str::to_owned);
    config.credentials = match keys {
        (Some(access_key), Some(secret_key)) => S3Credentials::Static {
            access_key: access_key.to_owned(),
            secret_key: secret_key.to_owned(),
        },
        _ => S3Credentials::DefaultChain,
    };
    StorageTarget::Bucket(config)
}

impl StorageArgs {
    /// Where the jobs are, in messages.
    fn place(&self, storage: &Storage) -> String {
        match &self.data_dir {
            Some(dir) => format!("--data-dir {}", dir.display()),
            None => format!("bucket {:?} at {}", storage.bucket, storage.endpoint),
        }
    }

    /// The storage target of an existing bucket or data folder (`hort jobs`).
    fn existing_target(&self) -> Result<StorageTarget> {
        if let Some(dir) = &self.data_dir
            && !dir.is_dir()
        {
            bail!("--data-dir {}: no such folder", dir.display());
        }
        Ok(self.target())
    }

    /// The storage target of these flags (see [`storage_target`]).
    pub fn target(&self) -> StorageTarget {
        storage_target(
            self.s3_endpoint.as_deref(),
            self.bucket.as_deref(),
            self.region.as_deref(),
            (self.access_key.as_deref(), self.secret_key.as_deref()),
            self.data_dir.as_deref(),
        )
    }
}

pub fn run(command: JobsCommand) -> Result<()> {
    match command {
        JobsCommand::List(args) => list(&args.storage),
        JobsCommand::Clean(args) => clean(&args),
    }
}

fn list(args: &StorageArgs) -> Result<()> {
    let storage = Storage::open(&args.existing_target()?)?;
    let jobs = list_jobs(storage.s3())?;
    if jobs.is_empty() {
        eprintln!("no jobs in {}", args.place(&storage));
        return Ok(());
    }
    let width = jobs.iter().map(|j| j.job.len()).max().unwrap_or(0).max(3);
    println!(
        "{:<width$}  {:<10}  {:>8}  {:>12}",
        "job", "status", "objects", "bytes"
    );
    for job in &jobs {
        let status = if job.finished {
            "finished"
        } else if served_and_cancelled(storage.s3(), &job.job)? {
            // Cancelled through `hort serve`'s API: its intermediates are gone, it cannot resume.
            "cancelled"
        } else {
            "unfinished"
        };
        println!(
            "{:<width$}  {status:<10}  {:>8}  {:>12}",
            job.job, job.objects, job.bytes
        );
    }
    Ok(())
}

fn clean(args: &CleanArgs) -> Result<()> {
    let storage = Storage::open(&args.storage.existing_target()?)?;
    let jobs: Vec<String> = match &args.job {
        Some(job) => vec![JobId::new(job.clone())?.as_str().to_owned()],
        None => list_jobs(storage.s3())?
            .into_iter()
            .map(|j| j.job)
            .collect(),
    };
    let mut any = false;
    for job in jobs {
        let deleted = delete_job(storage.s3(), &job)?;
        if deleted.objects > 0 {
            any = true;
            eprintln!(
                "deleted job {job}: {}, {}",
                count(deleted.objects, "object"),
                count(deleted.bytes, "byte")
            );
        } else if args.job.is_some() {
            eprintln!(
                "job {job} has no objects in {}: nothing to delete",
                args.storage.place(&storage)
            );
        }
    }
    if !any && args.all {
        eprintln!(
            "no jobs in {}: nothing to delete",
            args.storage.place(&storage)
        );
    }
    Ok(())
}

/// What `hort render` says about a job's objects after it succeeded: tasks skipped on resume,
/// intermediates deleted (or why not).
pub fn print_job_objects(run: &EmulatorRun) {
    let job = &run.job;
    if run.skipped_tasks > 0 {
        eprintln!(
            "resumed job {job}: {} skipped",
            count(run.skipped_tasks, "finished task")
        );
    }
    match &run.deleted_intermediates {
        Some(Ok(deleted)) => eprintln!(
            "deleted {} ({}) of job {job}; kept jobs/{job}/manifest.json, plan.json and out/ \
             (--keep-intermediates keeps everything)",
            count(deleted.objects, "intermediate object"),
            count(deleted.bytes, "byte")
        ),
        Some(Err(e)) => eprintln!(
            "warning: the intermediate objects of job {job} were not deleted: {e}; `hort jobs \
             clean --job {job}` deletes the whole job"
        ),
        None => {}
    }
}

/// Whether `hort serve` ran job `job` (a job folder's name) and it was cancelled.
fn served_and_cancelled(store: &dyn hort_core::store::BlobStore, job: &str) -> Result<bool> {
    let Ok(id) = hort_core::ids::JobId::new(job) else {
        return Ok(false);
    };
    Ok(crate::serve::recorded_state(store, &id)? == Some(JobState::Cancelled))
}
