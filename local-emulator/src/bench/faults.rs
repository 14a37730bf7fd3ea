//! `hort bench faults`: what injected faults cost, and a campaign proving they change nothing.
//! For each seed the same job runs fault-free, then once per fault mix; the table gives each
//! faulted time over the fault-free time of the same seed, the attempts and rerun rounds it
//! took, and whether the image and hit buffer are identical. A faulted job that fails or
//! differs is a row saying so, and the command then fails after printing the whole table.
//!
//! Mixes (`--mixes`): `a` 20% failed attempts + 20% duplicated deliveries + 10% stragglers
//! (target: at most 2x); `b` one of the function slots dies halfway through the fault-free run's
//! time (target: at most +60%, the paper's Hadoop figure); `fail` 20% failures alone; `dup` 20%
//! duplicates alone; `slow` 10% stragglers alone; `heavy` 40% + 30% + 20%.

use super::scenes::generated;
use super::table::{Table, f3};
use anyhow::{Result, bail};
use asl_interpreter::{Event, Observer};
use hort::emulator::{EmulatorConfig, EmulatorRun, FaultSettings, run_job};
use hort_core::pipeline::{PlanRequest, SplitMode, StoredOutputs};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
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
    /// Fault seeds: a list of numbers and ranges, such as `1,2,3` or `1-20`.
    #[arg(long, value_delimiter = ',', value_parser = parse_seed_range, default_value = "1-3")]
    pub seeds: Vec<(u64, u64)>,
    /// Fault mixes, each run per seed: a, b, fail, dup, slow, heavy (see the module docs).
    #[arg(long, value_delimiter = ',', default_value = "a,b")]
    pub mixes: Vec<Mix>,
    /// Append the table to this CSV file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write the table as Markdown to this file.
    #[arg(long)]
    pub markdown: Option<PathBuf>,
    /// Where generated scenes are cached.
    #[arg(long, default_value = "target/bench-scenes")]
    pub scene_dir: PathBuf,
}

/// A named fault mix.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mix {
    /// 20% failed attempts + 20% duplicated deliveries + 10% stragglers.
    A,
    /// One of the slots dies halfway through the fault-free run's time.
    B,
    /// 20% failed attempts.
    Fail,
    /// 20% duplicated deliveries.
    Dup,
    /// 10% stragglers.
    Slow,
    /// 40% failed attempts + 30% duplicated deliveries + 20% stragglers.
    Heavy,
}

impl Mix {
    fn label(self) -> &'static str {
        match self {
            Mix::A => "(a) 20% fail + 20% dup + 10% slow",
            Mix::B => "(b) 1 slot dies halfway",
            Mix::Fail => "20% fail",
            Mix::Dup => "20% dup",
            Mix::Slow => "10% slow",
            Mix::Heavy => "40% fail + 30% dup + 20% slow",
        }
    }

    /// The faults of this mix for `seed`, given the fault-free run's time.
    fn faults(self, seed: u64, clean_seconds: f64) -> FaultSettings {
        let rates = |fail_rate, duplicate_rate, slow_rate| FaultSettings {
            fail_rate,
            duplicate_rate,
            slow_rate,
            seed,
            kill_slot_after: None,
        };
        match self {
            Mix::A => rates(0.2, 0.2, 0.1),
            Mix::B => FaultSettings {
                seed,
                kill_slot_after: Some(clean_seconds / 2.0),
                ..FaultSettings::default()
            },
            Mix::Fail => rates(0.2, 0.0, 0.0),
            Mix::Dup => rates(0.0, 0.2, 0.0),
            Mix::Slow => rates(0.0, 0.0, 0.1),
            Mix::Heavy => rates(0.4, 0.3, 0.2),
        }
    }
}

/// `7` or `1-20` (inclusive).
fn parse_seed_range(text: &str) -> Result<(u64, u64), String> {
    let number = |s: &str| {
        s.trim()
            .parse::<u64>()
            .map_err(|_| format!("{s:?} is not a seed (a whole number)"))
    };
    match text.split_once('-') {
        None => number(text).map(|n| (n, n)),
        Some((a, b)) => {
            let (a, b) = (number(a)?, number(b)?);
            if a > b {
                return Err(format!("the seed range {text:?} is empty"));
            }
            Ok((a, b))
        }
    }
}

fn config(slots: usize, faults: FaultSettings) -> EmulatorConfig {
    EmulatorConfig {
        faults,
        ..EmulatorConfig::embedded(slots)
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

/// One job's run: what it produced (or why it failed), its seconds and its rerun rounds.
fn timed(
    args: &FaultsBenchArgs,
    path: &Path,
    faults: FaultSettings,
) -> (Result<EmulatorRun>, f64, u64) {
    let request = PlanRequest {
        width: args.width,
        height: args.height,
        spp: args.spp,
        splits: Some(args.splits),
        spans: Some(args.spans),
        mode: SplitMode::Spatial,
        execution: None,
        memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
        adaptive: None,
        outputs: StoredOutputs::ALL,
        frame: Default::default(),
    };
    let reruns = Reruns::default();
    let t = Instant::now();
    let run = run_job(&config(args.slots, faults), path, request, &reruns);
    (run, t.elapsed().as_secs_f64(), reruns.0.into_inner())
}

/// Total attempts over all stages.
fn attempts(run: &EmulatorRun) -> u64 {
    run.stages.iter().map(|s| s.attempts).sum()
}

pub fn run_faults_bench(args: &FaultsBenchArgs) -> Result<()> {
    let path = generated(&args.scene_dir, args.triangles, 1)?;
    let seeds: Vec<u64> = args.seeds.iter().flat_map(|&(a, b)| a..=b).collect();
    let mut table = Table::new(
        &format!(
            "faults: {} triangles, {}x{} spp {}, k={} s={}, {} slots, {} seeds (ratio = faulted / \
             fault-free time of the same seed; targets: (a) <= 2x, (b) <= 1.6x)",
            args.triangles,
            args.width,
            args.height,
            args.spp,
            args.splits,
            args.spans,
            args.slots,
            seeds.len()
        ),
        &[
            "seed",
            "faults",
            "fault-free s",
            "faulted s",
            "ratio",
            "attempts (fault-free)",
            "attempts",
            "failed attempts",
            "reruns",
            "identical",
        ],
    );
    let mut ratios: Vec<Vec<f64>> = vec![Vec::new(); args.mixes.len()];
    let mut bad = Vec::new();
    for &seed in &seeds {
        let (clean, clean_seconds, _) = timed(args, &path, FaultSettings::default());
        let clean = clean?;
        for (i, &mix) in args.mixes.iter().enumerate() {
            let (run, seconds, reruns) = timed(args, &path, mix.faults(seed, clean_seconds));
            let ratio = seconds / clean_seconds;
            let mut row = vec![
                seed.to_string(),
                mix.label().into(),
                f3(clean_seconds),
                f3(seconds),
                f3(ratio),
                attempts(&clean).to_string(),
            ];
            match run {
                Ok(run) => {
                    ratios[i].push(ratio);
                    let identical = run.image == clean.image && run.hits == clean.hits;
                    if !identical {
                        bad.push(format!("seed {seed}, {}: the image differs", mix.label()));
                    }
                    row.extend([
                        attempts(&run).to_string(),
                        run.failed_attempts().to_string(),
                        reruns.to_string(),
                        if identical { "yes" } else { "NO" }.into(),
                    ]);
                }
                Err(e) => {
                    bad.push(format!(
                        "seed {seed}, {}: the job failed: {e:#}",
                        mix.label()
                    ));
                    row.extend(["-".into(), "-".into(), reruns.to_string(), "FAILED".into()]);
                }
            }
            table.push(row);
        }
    }
    for (i, mix) in args.mixes.iter().enumerate() {
        let n = ratios[i].len().max(1) as f64;
        let mean = ratios[i].iter().sum::<f64>() / n;
        let worst = ratios[i].iter().copied().fold(0.0, f64::max);
        let mut row = vec!["all".into(), format!("{} mean", mix.label())];
        row.extend(["-".into(), "-".into()]);
        row.push(format!("{} (worst {})", f3(mean), f3(worst)));
        row.extend(["-".into(), "-".into(), "-".into(), "-".into(), "-".into()]);
        table.push(row);
    }
    table.print();
    if let Some(csv) = &args.csv {
        table.append_csv(csv)?;
    }
    if let Some(md) = &args.markdown {
        std::fs::write(md, table.markdown())
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", md.display()))?;
    }
    if !bad.is_empty() {
        bail!(
            "{} of {} faulted jobs failed or differ: {}",
            bad.len(),
            seeds.len() * args.mixes.len(),
            bad.join("; ")
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_are_numbers_or_inclusive_ranges() {
        assert_eq!(parse_seed_range("7"), Ok((7, 7)));
        assert_eq!(parse_seed_range("1-20"), Ok((1, 20)));
        assert_eq!(
            parse_seed_range("5-2"),
            Err("the seed range \"5-2\" is empty".into())
        );
        assert_eq!(
            parse_seed_range("x"),
            Err("\"x\" is not a seed (a whole number)".into())
        );
    }
}
