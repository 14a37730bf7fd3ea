//! `hort bench ...`: benchmarks that print tables with ratios against a baseline measured in the
//! same run, and append the rows to a CSV file.

mod emulator;
mod kernel;
#[cfg(feature = "obvhs-bench")]
mod obvhs_kernel;
mod pipeline;
mod scenes;
mod table;

pub use emulator::{EmulatorBenchArgs, run_emulator_bench};
pub use kernel::{KernelBenchArgs, run_kernel_bench};
pub use pipeline::{PipelineBenchArgs, run_pipeline_bench};

/// Process-wide allocation meter (the binary's global allocator), for per-task memory peaks.
pub trait MemoryMeter {
    /// Bytes allocated now.
    fn current(&self) -> usize;
    /// Highest allocation since the last reset.
    fn peak(&self) -> usize;
    /// Starts a new high-water mark from the current allocation.
    fn reset_peak(&self);
}
