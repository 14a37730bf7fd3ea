//! `hort bench faults`: what injected faults cost. For each seed, the same job runs fault-free
//! and then (a) with 20% failed attempts, 20% duplicated deliveries and 10% stragglers, and (b)
//! with one of the function slots dying halfway through the fault-free run's time; the table
//! gives each faulted time over the fault-free time of the same seed, and whether the image is
//! identical. Targets: at most 2x for (a), at most +60% for (b) (the paper's Hadoop figure).

use super::scenes::generated;
use super::table::{Table, f3};
use anyhow::Result;
use asl_interpreter::{Event, Observer};
use hort::emulator::{EmulatorConfig, EmulatorRun, FaultSettings, StorageTarget, run_job};
use hort_core::cost::Arch;
use hort_core::pipeline::{PlanRequest, SplitMode};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

/// Options of `hort bench faults`.
#[derive(clap::Args, Clone, Debug)]
pub struct FaultsBenchArgs {
    /// Triangles of the generated scene.
    #[arg(long, default_value_t = 200_000)]
    pub triangles: u64,
    /// Image width.
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    /// Image height.
    #[arg(long, default_value_t = 360)]
    pub height: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 2)]
    pub spp: u32,
    /// Scene splits.
    #[arg(long, default_value_t = 4)]
    pub splits: u32,
    /// Pixel spans.
    #[arg(long, default_value_t = 32)]
    pub spans: u32,
    /// Function slots (the paper's experiment has 16).
    #[arg(long, default_value_t = 16)]
    pub slots: usize,
    /// Fault seeds, one fault-free and two faulted runs each.
    #[arg(long, value_delimiter = ',', default_value = "1,2,3")]
    pub seeds: Vec<u64>,
    /// Append the table to this CSV file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Where generated scenes are cached.
    #[arg(long, default_value = "target/bench-scenes")]
    pub scene_dir: PathBuf,
}

fn config(slots: usize, faults: FaultSettings) -> EmulatorConfig {
    EmulatorConfig {
        storage: StorageTarget::Embedded { data_dir: None },
        job: None,
        workers: slots,
        faults,
        time_scale: 1.0,
        task_timeout_seconds: None,
        split_cache_bytes: 1 << 30,
        memory_mb: 2048,
        arch: Arch::Arm64,
        cancel: Arc::new(AtomicBool::new(false)),
        lambda: None,
    }
}

/// Counts the Map Runs of the rerun loops (`{Map}Rerun`).
#[derive(Default)]
struct Reruns(AtomicU64);

impl Observer for Reruns {
    fn event(&self, event: &Event) {
        if let Event::MapStarted { state, .. } = event
            && state.ends_with("Rerun")
        {
            self.0.fetch_add(1, Ordering::Relaxed);
        }
    }
}

fn timed(
    args: &FaultsBenchArgs,
    path: &Path,
    faults: FaultSettings,
) -> Result<(EmulatorRun, f64, u64)> {
    let request = PlanRequest {
        width: args.width,
        height: args.height,
        spp: args.spp,
        splits: Some(args.splits),
        spans: Some(args.spans),
        mode: SplitMode::Spatial,
    };
    let reruns = Reruns::default();
    let t = Instant::now();
    let run = run_job(&config(args.slots, faults), path, request, &reruns)?;
    Ok((run, t.elapsed().as_secs_f64(), reruns.0.into_inner()))
}

pub fn run_faults_bench(args: &FaultsBenchArgs) -> Result<()> {
    let path = generated(&args.scene_dir, args.triangles, 1)?;
    let mut table = Table::new(
        &format!(
            "faults: {} triangles, {}x{} spp {}, k={} s={}, {} slots (ratio = faulted / fault-free \
             time of the same seed; targets: (a) <= 2x, (b) <= 1.6x)",
            args.triangles, args.width, args.height, args.spp, args.splits, args.spans, args.slots
        ),
        &[
            "seed",
            "faults",
            "fault-free s",
            "its failed attempts",
            "faulted s",
            "ratio",
            "failed attempts",
            "reruns",
            "identical",
        ],
    );
    let mut ratios: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for &seed in &args.seeds {
        let (clean, clean_seconds, _) = timed(args, &path, FaultSettings::default())?;
        let scenarios = [
            (
                "(a) 20% fail + 20% dup + 10% slow",
                FaultSettings {
                    fail_rate: 0.2,
                    duplicate_rate: 0.2,
                    slow_rate: 0.1,
                    seed,
                    kill_slot_after: None,
                },
            ),
            (
                "(b) 1 slot dies halfway",
                FaultSettings {
                    seed,
                    kill_slot_after: Some(clean_seconds / 2.0),
                    ..FaultSettings::default()
                },
            ),
        ];
        for (i, (name, faults)) in scenarios.into_iter().enumerate() {
            let (run, seconds, reruns) = timed(args, &path, faults)?;
            let ratio = seconds / clean_seconds;
            if std::env::var_os("HORT_BENCH_STAGES").is_some() {
                for (c, f) in clean.stages.iter().zip(&run.stages) {
                    eprintln!(
                        "{name} {}: {:.2}s -> {:.2}s, attempts {} -> {}",
                        c.name, c.seconds, f.seconds, c.attempts, f.attempts
                    );
                }
            }
            ratios[i].push(ratio);
            table.push(vec![
                seed.to_string(),
                name.into(),
                f3(clean_seconds),
                clean.failed_attempts().to_string(),
                f3(seconds),
                f3(ratio),
                run.failed_attempts().to_string(),
                reruns.to_string(),
                if run.image.pixels == clean.image.pixels && run.hits == clean.hits {
                    "yes"
                } else {
                    "NO"
                }
                .into(),
            ]);
        }
    }
    for (i, name) in ["(a) mean", "(b) mean"].into_iter().enumerate() {
        let n = ratios[i].len().max(1) as f64;
        let mean = ratios[i].iter().sum::<f64>() / n;
        let worst = ratios[i].iter().copied().fold(0.0, f64::max);
        table.push(vec![
            "all".into(),
            name.into(),
            "-".into(),
            "-".into(),
            "-".into(),
            format!("{} (worst {})", f3(mean), f3(worst)),
            "-".into(),
            "-".into(),
            "-".into(),
        ]);
    }
    table.print();
    if let Some(csv) = &args.csv {
        table.append_csv(csv)?;
    }
    Ok(())
}
