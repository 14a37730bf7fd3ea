//! `hort`: render scenes on this machine, monolithically or through the HORT pipeline, and make
//! synthetic scenes. See `hort --help`.
#![forbid(unsafe_code)]

mod bench;
mod cli;
#[cfg(test)]
mod cli_reference;
mod eval;
mod frame_flags;
mod frame_paths;
mod jobs_cmd;
mod outputs;
mod plan_cmd;
mod plan_flags;
mod render_cmd;
mod scene_cmd;
mod serve;
mod stop_signals;

use clap::Parser;
use hort_task_memory::{TaskAlloc, process_live_bytes, process_peak_bytes, reset_process_peak};

/// Counts allocations: each in-process function invocation measures its memory high-water mark
/// (and is held to the function's budget), and `hort bench` reports per-task memory.
#[global_allocator]
static ALLOCATOR: TaskAlloc = TaskAlloc;

struct AllocationMeter;

impl bench::MemoryMeter for AllocationMeter {
    fn current(&self) -> usize {
        process_live_bytes().map_or(0, |b| usize::try_from(b).unwrap_or(usize::MAX))
    }
    fn peak(&self) -> usize {
        process_peak_bytes().map_or(0, |b| usize::try_from(b).unwrap_or(usize::MAX))
    }
    fn reset_peak(&self) {
        reset_process_peak();
    }
}

fn main() -> std::process::ExitCode {
    let cli = cli::Cli::parse();
    let result = match cli.command {
        cli::Command::Render(args) => render_cmd::run(*args),
        cli::Command::Plan(args) => plan_cmd::run(&args),
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
        cli::Command::Bench {
            command: cli::BenchCommand::Plan(args),
        } => bench::run_plan_bench(&args),
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
