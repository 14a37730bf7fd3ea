//! `hort bench ...`: benchmarks that print tables with ratios against a baseline measured in the
//! same run, and append the rows to a CSV file.

mod breakdown;
mod emulator;
mod faults;
mod kernel;
#[cfg(feature = "obvhs-bench")]
mod obvhs_kernel;
mod overhead;
mod pipeline;
mod plan;
mod samples;
mod scenes;
mod table;
mod timing;
mod whole_render;

pub use emulator::{EmulatorBenchArgs, run_emulator_bench};
pub use faults::{FaultsBenchArgs, run_faults_bench};
pub use kernel::{KernelBenchArgs, run_kernel_bench};
pub use pipeline::{PipelineBenchArgs, run_pipeline_bench};
pub use plan::{PlanBenchArgs, run_plan_bench};
pub use samples::{SamplesBenchArgs, run_samples_bench};

/// Process-wide allocation meter (the binary's global allocator), for per-task memory peaks.
pub trait MemoryMeter {
    /// Bytes allocated now.
    fn current(&self) -> usize;
    /// Highest allocation since the last reset.
    fn peak(&self) -> usize;
    /// Starts a new high-water mark from the current allocation.
    fn reset_peak(&self);
}

/// Options the pipeline and emulator benchmarks share.
#[derive(clap::Args, Clone, Debug)]
pub struct BenchCommon {
    /// Image width.
    #[arg(long, default_value_t = 1920)]
    pub width: u32,
    /// Image height.
    #[arg(long, default_value_t = 1080)]
    pub height: u32,
    /// Threads of the monolithic render, and workers (function slots) of the pipeline
    /// (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Append every table to this CSV file.
    #[arg(long)]
    pub csv: Option<std::path::PathBuf>,
    /// Where generated scenes are cached.
    #[arg(long, default_value = "target/bench-scenes")]
    pub scene_dir: std::path::PathBuf,
}
