//! The command-line contract (docs/ARCHITECTURE.md, "Command line"): names and meanings scripts
//! rely on.

use clap::{Args, Parser, Subcommand};
use hort_core::pipeline::SplitMode;
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "hort",
    version,
    about = "HORT-serverless: distributed ray tracing with MapReduce"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
    /// Render an OBJ file or a JSON scene manifest.
    Render(Box<RenderArgs>),
    /// Scene tools.
    Scene {
        #[command(subcommand)]
        command: SceneCommand,
    },
    /// Benchmarks: tables of ratios against a baseline measured in the same run.
    Bench {
        #[command(subcommand)]
        command: BenchCommand,
    },
}

#[derive(Subcommand)]
pub enum BenchCommand {
    /// The in-process pipeline against the monolithic renderer: time, skipped pairs, memory.
    Pipeline(crate::bench::PipelineBenchArgs),
    /// The local emulator end to end against the monolithic renderer, and a dying slot.
    Emulator(crate::bench::EmulatorBenchArgs),
    /// Single-thread BVH kernel against native Embree on identical rays: Mrays/s, build, load.
    Kernel(crate::bench::KernelBenchArgs),
}

#[derive(Subcommand)]
pub enum SceneCommand {
    /// Write a deterministic synthetic scene (ground plus scattered objects) as OBJ.
    Generate(GenerateArgs),
}

#[derive(Args)]
pub struct RenderArgs {
    /// The scene: an OBJ file, or a JSON manifest (.json) naming OBJ files.
    pub scene: PathBuf,
    /// Image width in pixels (default: manifest, else 960).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels (default: manifest, else 540).
    #[arg(long)]
    pub height: Option<u32>,
    /// Samples per pixel (default: manifest, else 1).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Render in one process with one BVH over the whole scene.
    #[arg(long)]
    pub monolithic: bool,
    /// Worker threads of a monolithic render (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Scene splits k (default: about one per 250k triangles).
    #[arg(long)]
    pub splits: Option<u32>,
    /// Pixel spans s, one reduce task each; HORT's d = s x k map inputs (default: about one per
    /// 64k samples, at most 100).
    #[arg(long)]
    pub spans: Option<u32>,
    /// How the scene is cut: spatial clusters (default) or the paper's naive index ranges.
    #[arg(long, default_value = "spatial")]
    pub split_mode: SplitMode,
    /// Function slots: tasks run concurrently (default: all cores).
    #[arg(long)]
    pub workers: Option<usize>,
    /// Run the stages with the in-process driver over memory instead of the emulator (no S3,
    /// no state machine): the fastest way to check a scene through the pipeline.
    #[arg(long, conflicts_with_all = ["s3_endpoint", "data_dir"])]
    pub in_process: bool,
    /// Use this S3-compatible endpoint (MinIO, Garage, Ceph RGW, moto, AWS) instead of the
    /// embedded server; credentials from --access-key/--secret-key or the AWS environment.
    #[arg(long, requires = "bucket")]
    pub s3_endpoint: Option<String>,
    /// Bucket at --s3-endpoint.
    #[arg(long, requires = "s3_endpoint")]
    pub bucket: Option<String>,
    /// Access key for --s3-endpoint (else AWS_ACCESS_KEY_ID and the default chain).
    #[arg(long, requires = "secret_key", env = "HORT_S3_ACCESS_KEY")]
    pub access_key: Option<String>,
    /// Secret key for --s3-endpoint.
    #[arg(
        long,
        requires = "access_key",
        env = "HORT_S3_SECRET_KEY",
        hide_env_values = true
    )]
    pub secret_key: Option<String>,
    /// Keep the embedded server's objects in DIR (default: a temporary folder, removed after).
    #[arg(long)]
    pub data_dir: Option<PathBuf>,
    /// Job id (default: a fresh one); objects go under jobs/ID/.
    #[arg(long)]
    pub job: Option<String>,
    /// Probability that an attempt fails (before running, or after writing part of its outputs).
    #[arg(long, default_value_t = 0.0)]
    pub fail_rate: f64,
    /// Probability that an attempt is delivered twice and runs concurrently.
    #[arg(long, default_value_t = 0.0)]
    pub duplicate_rate: f64,
    /// Probability that an attempt straggles past its timeout (retried on States.Timeout).
    #[arg(long, default_value_t = 0.0)]
    pub slow_rate: f64,
    /// This many seconds into the run, one function slot dies with its attempt (the paper's
    /// fault experiment): the attempt times out and is retried, the slot never comes back.
    #[arg(long)]
    pub kill_slot_after: Option<f64>,
    /// Seed of fault injection and retry jitter.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Per-task timeout in seconds (default: derived from each task's work, 10 to 90 s).
    #[arg(long)]
    pub task_timeout: Option<u32>,
    /// Multiplies every wait and timeout of the state machine (1 = real time).
    #[arg(long, default_value_t = 1.0, hide = true)]
    pub time_scale: f64,
    /// Lambda memory (MB) the cost estimate assumes.
    #[arg(long, default_value_t = 2048)]
    pub memory_mb: u32,
    /// Output image: .png (8-bit sRGB), .pfm or .exr (linear). Default: SCENE's name with .png.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write the hit buffer: per pixel a little-endian {u32 triangle, f32 t}.
    #[arg(long)]
    pub hits: Option<PathBuf>,
    /// Write the JSON report.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

#[derive(Args)]
pub struct GenerateArgs {
    /// Exact number of triangles (10k to 2M are the benchmark sizes).
    #[arg(long)]
    pub triangles: u64,
    /// Seed: the same triangles and seed give the same bytes on every machine.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output OBJ path.
    #[arg(long)]
    pub out: PathBuf,
}
