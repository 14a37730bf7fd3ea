//! `hort`: render scenes on this machine, monolithically or through the HORT pipeline, and make
//! synthetic scenes. See `hort --help`.
#![forbid(unsafe_code)]

mod bench;
mod cli;
mod eval;
mod jobs_cmd;
mod outputs;
mod render_cmd;
mod scene_cmd;
mod serve;

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
        cli::Command::Jobs { command } => jobs_cmd::run(command),
        cli::Command::Eval(args) => eval::run(&args),
        cli::Command::Serve(args) => serve::run(args),
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
            command: cli::BenchCommand::Faults(args),
        } => bench::run_faults_bench(&args),
        cli::Command::Bench {
            command: cli::BenchCommand::Kernel(args),
        } => bench::run_kernel_bench(&args),
        cli::Command::Bench {
            command: cli::BenchCommand::Samples(args),
        } => bench::run_samples_bench(&args),
    };
    // Last: tasks a cancelled run abandoned may have written into its temporary folder.
    hort::emulator::remove_temp_folders();
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_chain(&e));
            std::process::ExitCode::FAILURE
        }
    }
}

/// The error and its causes joined by `: `, leaving out a cause whose text the message before
/// it already contains (errors that print their source would otherwise say it twice), and the
/// `(os error N)` suffixes of I/O errors.
fn error_chain(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let part = cause.to_string();
        let part = match part.find(" (os error ") {
            Some(at) if part.ends_with(')') => part[..at].to_owned(),
            _ => part,
        };
        if !text.contains(&part) {
            if !text.is_empty() {
                text.push_str(": ");
            }
            text.push_str(&part);
        }
    }
    text
}
