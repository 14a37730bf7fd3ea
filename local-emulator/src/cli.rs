//! The command-line contract (docs/ARCHITECTURE.md, "Command line"): names and meanings scripts
//! rely on.

use clap::{Args, Parser, Subcommand};
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
    /// The plan `hort render` would run, and its time, requests and dollars projected on N
    /// functions (AWS Lambda or the local emulator), before paying for anything.
    Plan(Box<crate::plan_cmd::PlanArgs>),
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
    /// The jobs in a bucket or data folder: list them, delete their objects.
    Jobs {
        #[command(subcommand)]
        command: crate::jobs_cmd::JobsCommand,
    },
    /// Speed against accuracy: time and error (RMSE, relative MSE, PSNR) against reference
    /// images, over samples per pixel, ours and Mitsuba's; writes eval.csv and PNG charts.
    Eval(Box<crate::eval::EvalArgs>),
    /// Serve the HTTP API (POST /renders, GET /renders/{id}, ...) on 127.0.0.1, jobs run by
    /// the emulator.
    Serve(crate::serve::ServeArgs),
}

#[derive(Subcommand)]
pub enum BenchCommand {
    /// The in-process pipeline against the monolithic renderer: time, skipped pairs, memory.
    Pipeline(crate::bench::PipelineBenchArgs),
    /// The local emulator end to end against the monolithic renderer, and a dying slot.
    Emulator(crate::bench::EmulatorBenchArgs),
    /// Time under injected faults over fault-free time: failures, duplicates and stragglers,
    /// and a dying function slot, over several seeds.
    Faults(crate::bench::FaultsBenchArgs),
    /// Single-thread BVH kernel against native Embree on identical rays: Mrays/s, build, load.
    Kernel(crate::bench::KernelBenchArgs),
    /// Single-thread samples/s of the monolithic renderer against Mitsuba's multijitter timings
    /// (eval/references), same scenes, size and spp.
    Samples(crate::bench::SamplesBenchArgs),
    /// `hort plan --target emulator` against the emulator runs it predicts: predicted and
    /// measured seconds and their ratio per scene, slot count and injected S3 latency.
    Plan(crate::bench::PlanBenchArgs),
}

#[derive(Subcommand)]
pub enum SceneCommand {
    /// Write a deterministic synthetic scene (ground plus scattered objects) as OBJ.
    Generate(GenerateArgs),
}

/// The flags of `hort render`. One rule for flags that do not apply: a flag that belongs to
/// another mode than the one chosen is refused, and the message names both flags (monolithic:
/// `--threads`; in process: `--workers`, `--splits`, `--spans`, `--split-mode`; the emulator:
/// those and the storage, job and fault flags).
#[derive(Args)]
pub struct RenderArgs {
    /// The scene: an OBJ file, or a JSON manifest (.json) naming OBJ files.
    pub scene: PathBuf,
    /// What a material's diffuse texture (map_Kd) that is missing or unreadable does: `error`
    /// refuses the scene, naming the file and the material; `flat` warns and renders the
    /// material's flat Kd colour.
    #[arg(long, value_enum, default_value_t = MissingTextures::Error)]
    pub missing_textures: MissingTextures,
    /// The image and the plan's shape (the flags of `hort plan` too).
    #[command(flatten)]
    pub plan: crate::plan_flags::PlanFlags,
    /// Which frames of which camera path.
    #[command(flatten)]
    pub animation: crate::frame_flags::FrameFlags,
    /// Adaptive sampling up to MAX_SPP samples per pixel (above --spp): first --spp samples
    /// (at least 2) in every pixel, then MAX_SPP in the pixels whose standard error is above
    /// --adaptive-threshold. Monolithic, fused or staged.
    #[arg(long, value_name = "MAX_SPP", allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=i64::from(hort_core::scene::MAX_SPP)))]
    pub adaptive: Option<u32>,
    /// The adaptive sampler's threshold on a pixel's standard error (linear radiance, the
    /// largest over R, G, B) after the first pass (default 0.002).
    #[arg(long, requires = "adaptive", allow_negative_numbers = true)]
    pub adaptive_threshold: Option<f64>,
    /// Render in one process with one BVH over the whole scene.
    #[arg(long, conflicts_with_all = [
        "in_process", "workers", "splits", "spans", "split_mode", "s3_endpoint", "bucket",
        "region", "access_key", "secret_key", "data_dir", "job", "resume", "keep_intermediates",
        "fail_rate", "duplicate_rate", "slow_rate", "kill_slot_after", "seed", "task_timeout",
        "time_scale", "memory_mb", "lambda_endpoint", "mode", "scene_range_bytes",
    ])]
    pub monolithic: bool,
    /// Worker threads of a monolithic render and its BVH build (default: all cores).
    #[arg(long, requires = "monolithic", allow_negative_numbers = true, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=4096))]
    pub threads: Option<usize>,
    /// Function slots (emulator) or worker threads (--in-process): tasks run concurrently
    /// (default: all cores).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=4096))]
    pub workers: Option<usize>,
    /// Run the stages with the in-process driver over memory instead of the emulator (no S3,
    /// no state machine): the fastest way to check a scene through the pipeline.
    #[arg(long, conflicts_with_all = [
        "s3_endpoint", "bucket", "region", "access_key", "secret_key", "data_dir", "job", "resume",
        "keep_intermediates", "fail_rate", "duplicate_rate", "slow_rate", "kill_slot_after",
        "seed", "task_timeout", "time_scale", "lambda_endpoint", "scene_range_bytes",
    ])]
    pub in_process: bool,
    /// Where the job's objects go (the storage flags of `hort jobs` too).
    #[command(flatten)]
    pub storage: crate::jobs_cmd::StorageArgs,
    /// Job id (default: a fresh one); objects go under jobs/ID/.
    #[arg(long)]
    pub job: Option<String>,
    /// Continue the stopped job --job ID: tasks whose outputs exist are skipped.
    #[arg(long, requires = "job")]
    pub resume: bool,
    /// Keep the job's intermediate objects after success (default: only the job request,
    /// plan.json and out/ stay in a bucket or --data-dir).
    #[arg(long)]
    pub keep_intermediates: bool,
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
    // The help text is `task_timeout_help`: its default range comes from the plan's constants.
    #[arg(long, help = task_timeout_help(), allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=300))]
    pub task_timeout: Option<u32>,
    /// Multiplies every wait and timeout of the state machine (1 = real time).
    #[arg(long, default_value_t = 1.0, hide = true)]
    pub time_scale: f64,
    /// Invoke the Plan and Worker functions through the Lambda Invoke API at URL (for example
    /// `cargo lambda watch` at http://127.0.0.1:9000) instead of in this process. They read and
    /// write the bucket themselves: give --s3-endpoint and --bucket they can reach too.
    #[arg(long, requires = "bucket", conflicts_with_all = [
        "fail_rate", "duplicate_rate", "slow_rate", "kill_slot_after", "data_dir", "resume",
    ])]
    pub lambda_endpoint: Option<String>,
    /// The Plan function's name at --lambda-endpoint.
    #[arg(long, default_value = "plan", requires = "lambda_endpoint")]
    pub plan_function: String,
    /// The Worker function's name at --lambda-endpoint.
    #[arg(long, default_value = "worker", requires = "lambda_endpoint")]
    pub worker_function: String,
    /// The image and hit buffer to write.
    #[command(flatten)]
    pub outputs: crate::plan_flags::OutputFlags,
    /// Write the JSON report to this file, or to standard output with `-`.
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
    /// Output OBJ path (must end in .obj). Also writes a manifest beside it, the same path
    /// with .json, whose camera the scene fills. Neither file is overwritten without --force.
    #[arg(long)]
    pub out: PathBuf,
    /// Overwrite the .obj and .json if they exist.
    #[arg(long)]
    pub force: bool,
}

/// `--task-timeout`'s help, with the bounds the plan clamps its default timeouts to.
fn task_timeout_help() -> String {
    use hort_core::predict::{MAX_TIMEOUT_SECONDS, MIN_TIMEOUT_SECONDS, TIMEOUT_MULTIPLE};
    format!(
        "Per-task timeout in seconds, 1 to 300 (default: {TIMEOUT_MULTIPLE} times each task's \
         predicted time, {MIN_TIMEOUT_SECONDS} to {MAX_TIMEOUT_SECONDS} s; partition and build tasks get \
         longer ones, from their bytes and triangles); a Map item's attempts must fit an \
         EXPRESS child's 5 minutes."
    )
}

/// `--missing-textures`: see [`hort_core::scene::TextureFallback`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum MissingTextures {
    /// Refuse the scene, naming the texture file and the material.
    Error,
    /// Warn, and render the material's flat Kd colour.
    Flat,
}

impl From<MissingTextures> for hort_core::scene::TextureFallback {
    fn from(m: MissingTextures) -> Self {
        match m {
            MissingTextures::Error => hort_core::scene::TextureFallback::Error,
            MissingTextures::Flat => hort_core::scene::TextureFallback::Flat,
        }
    }
}
