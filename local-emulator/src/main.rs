//! `hort`: render scenes on this machine, monolithically or through the HORT pipeline, and make
//! synthetic scenes. See `hort --help`.
#![forbid(unsafe_code)]

mod bench;
mod cli;
mod render_cmd;
mod scene_cmd;

use clap::Parser;
use peak_alloc::PeakAlloc;

/// Counts allocations so `hort bench` can report per-task memory high-water marks.
#[global_allocator]
static ALLOCATOR: PeakAlloc = PeakAlloc;

struct AllocationMeter;

impl bench::MemoryMeter for AllocationMeter {
    fn current(&self) -> usize {
        ALLOCATOR.current_usage()
    }
    fn peak(&self) -> usize {
        ALLOCATOR.peak_usage()
    }
    fn reset_peak(&self) {
        ALLOCATOR.reset_peak_usage();
    }
}

fn main() -> std::process::ExitCode {
    let cli = cli::Cli::parse();
    let result = match cli.command {
        cli::Command::Render(args) => render_cmd::run(*args),
        cli::Command::Scene {
            command: cli::SceneCommand::Generate(args),
        } => scene_cmd::generate(args),
        cli::Command::Bench {
            command: cli::BenchCommand::Pipeline(args),
        } => bench::run_pipeline_bench(&args, &AllocationMeter),
        cli::Command::Bench {
            command: cli::BenchCommand::Emulator(args),
        } => bench::run_emulator_bench(&args),
        cli::Command::Bench {
            command: cli::BenchCommand::Kernel(args),
        } => bench::run_kernel_bench(&args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
