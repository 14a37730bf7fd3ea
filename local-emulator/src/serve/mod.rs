//! `hort serve`: the HTTP API of `hort_functions::api` and its dashboard (`GET /`) on
//! 127.0.0.1 (another address only with `--bind`), its jobs run by the local
//! emulator ([`backend::EmulatorBackend`]) on background threads, its objects and job records
//! in an embedded S3 server over `--data-dir`, so a restarted server answers for finished jobs.

mod backend;
mod execution;
mod server;

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use anyhow::{Result, bail};
use clap::Args;
use hort_core::plural::count;
use hort_core::worker_pool::available_cores;
use tokio::sync::oneshot;

pub use backend::EmulatorBackend;
pub use execution::recorded_state;

/// The flags of `hort serve`.
#[derive(Args)]
pub struct ServeArgs {
    /// Port (0: any free port; the address is printed at start).
    #[arg(long, default_value_t = 8080)]
    pub port: u16,
    /// Address to listen on. The API has no authentication: anything but a loopback address
    /// lets every machine that reaches it run jobs and read their images.
    #[arg(long, default_value = "127.0.0.1")]
    pub bind: std::net::IpAddr,
    /// Most jobs queued or running at once; a submission past it is refused with 429.
    #[arg(long, default_value_t = 4, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=1024))]
    pub max_jobs: usize,
    /// Keep the jobs' objects and records in DIR (`DIR/hort/...`), so a restarted server
    /// answers for them (default: a temporary folder, removed when the server stops).
    #[arg(long)]
    pub data_dir: Option<PathBuf>,
    /// Function slots of each job: its tasks running at once (default: all cores).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=4096))]
    pub workers: Option<usize>,
}

/// Runs the server until Ctrl-C or SIGTERM; then running jobs stop (they end FAILED,
/// interrupted, their objects kept) and the server exits.
pub fn run(args: ServeArgs) -> Result<()> {
    let workers = args.workers.unwrap_or_else(available_cores);
    let (data_dir, temporary) = match &args.data_dir {
        Some(dir) => {
            if dir.exists() && !dir.is_dir() {
                bail!("--data-dir {}: is not a folder", dir.display());
            }
            (dir.clone(), false)
        }
        None => (
            std::env::temp_dir().join(format!("hort-serve-{}", std::process::id())),
            true,
        ),
    };
    std::fs::create_dir_all(&data_dir)
        .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", data_dir.display()))?;
    let addr = std::net::SocketAddr::new(args.bind, args.port);
    let result = serve_over(&data_dir, workers, args.max_jobs, addr, temporary);
    if temporary {
        let _ = std::fs::remove_dir_all(&data_dir);
    }
    result
}

fn serve_over(
    data_dir: &std::path::Path,
    workers: usize,
    max_jobs: usize,
    addr: std::net::SocketAddr,
    temporary: bool,
) -> Result<()> {
    let backend = Arc::new(EmulatorBackend::open(data_dir, workers, max_jobs)?);
    let (stop_tx, stop_rx) = oneshot::channel();
    let stop_tx = Mutex::new(Some(stop_tx));
    let _ = crate::stop_signals::on_stop_signals(move |signal| {
        match stop_tx.lock().unwrap_or_else(|e| e.into_inner()).take() {
            Some(tx) => {
                eprintln!("hort serve: stopping; {}", signal.quit_at_once());
                let _ = tx.send(());
            }
            None => hort::emulator::exit_now(signal.exit_code()),
        }
    });
    let jobs = backend.job_count();
    let kept = if temporary {
        " (temporary: removed when the server stops; --data-dir keeps jobs across restarts)"
    } else {
        ""
    };
    let deployed = hort::deployment::Deployment::bundled().api;
    let api = server::ApiFunction {
        timeout: std::time::Duration::from_secs(u64::from(deployed.timeout_seconds)),
        reserved_concurrency: deployed.reserved_concurrency.map(|n| n as usize),
    };
    server::serve(
        backend.clone(),
        api,
        addr,
        |addr| {
            let reach = if addr.ip().is_loopback() {
                "loopback only: other machines cannot connect; --bind ADDRESS to change".to_owned()
            } else {
                format!(
                    "bound to {}: every machine that reaches it can submit and read jobs, with \
                     no authentication",
                    addr.ip()
                )
            };
            eprintln!(
                "hort serve: listening on http://{addr} ({reach}; dashboard at http://{addr}/; \
                 {} per job, at most {} at once, data in {}{kept}, {} known)",
                count(workers as u64, "function slot"),
                count(max_jobs as u64, "job"),
                data_dir.display(),
                count(jobs as u64, "job"),
            );
        },
        stop_rx,
    )?;
    backend.stop();
    Ok(())
}
