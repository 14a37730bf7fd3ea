//! `hort`: render scenes on this machine, monolithically or through the HORT pipeline, and make
//! synthetic scenes. See `hort --help`.
#![forbid(unsafe_code)]

mod cli;
mod render_cmd;
mod scene_cmd;

use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = cli::Cli::parse();
    let result = match cli.command {
        cli::Command::Render(args) => render_cmd::run(args),
        cli::Command::Scene {
            command: cli::SceneCommand::Generate(args),
        } => scene_cmd::generate(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
