//! `hort bench plan`: `hort plan --target emulator` against the emulator runs it predicts. For
//! every scene, slot count and injected S3 latency it projects the job, then runs
//! `hort render SCENE --workers W` (this same binary, in a child process, the latency injected
//! through `HORT_S3_FAULTS`) and prints predicted seconds, measured seconds (the report's total
//! less the scene's load, which `hort plan` does not predict) and their ratio.

use super::table::{Table, f3};
use crate::plan_cmd::{ArchArg, PlanArgs, TargetArg, calibrate, plan_with};
use crate::plan_flags::{OutputFlags, PlanFlags};
use anyhow::{Context, Result, bail};
use hort::emulator::S3_FAULTS_VAR;
use hort_core::pipeline::{ExecutionMode, SplitMode};
use std::path::PathBuf;
use std::process::Command;

/// Options of `hort bench plan`.
#[derive(clap::Args, Clone, Debug)]
pub struct PlanBenchArgs {
    /// Scenes to run (default: the bundled teapot and bunny).
    pub scenes: Vec<PathBuf>,
    /// Function slots, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,2,4,8")]
    pub workers: Vec<u32>,
    /// Injected S3 latencies, ms, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0,20")]
    pub latency_ms: Vec<f64>,
    /// Image width (default: the scene's, else 960).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height (default: the scene's, else 540).
    #[arg(long)]
    pub height: Option<u32>,
    /// Samples per pixel (default: the scene's, else 1).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Force fused or staged execution (default: the plan chooses).
    #[arg(long)]
    pub mode: Option<ExecutionMode>,
    /// Scene splits k (default: the plan chooses).
    #[arg(long)]
    pub splits: Option<u32>,
    /// Split the scenes by tasks in ranges of this many bytes (as `hort render
    /// --scene-range-bytes`).
    #[arg(long, value_name = "BYTES")]
    pub scene_range_bytes: Option<u64>,
    /// Append the table to this CSV file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
}

/// Runs `hort bench plan`.
pub fn run_plan_bench(args: &PlanBenchArgs) -> Result<()> {
    let scenes = if args.scenes.is_empty() {
        vec![
            PathBuf::from("scenes/teapot/teapot.json"),
            PathBuf::from("scenes/bunny/bunny.json"),
        ]
    } else {
        args.scenes.clone()
    };
    let exe = std::env::current_exe().context("this program's path")?;
    let dir = std::env::temp_dir().join(format!("hort-bench-plan-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| dir.display().to_string())?;
    let mut table = Table::new(
        "hort plan --target emulator against hort render --workers W (seconds)",
        &[
            "scene",
            "triangles",
            "workers",
            "latency ms",
            "predicted",
            "measured",
            "measured/predicted",
        ],
    );
    // One calibration for every prediction of the table.
    let calibration = calibrate()?;
    println!(
        "calibration: speed {:.2} (BVH {:.2} ms, render {:.2} ms)",
        calibration.speed, calibration.build_ms, calibration.trace_ms
    );
    let mut worst: f64 = 1.0;
    for scene in &scenes {
        for &latency in &args.latency_ms {
            for &workers in &args.workers {
                let planned = plan_with(
                    &PlanArgs {
                        scene: scene.clone(),
                        more_scenes: Vec::new(),
                        chart: None,
                        functions: Some(workers),
                        arch: ArchArg::Arm64,
                        target: TargetArg::Emulator,
                        json: true,
                        fail_rate: 0.0,
                        s3_latency_ms: latency,
                        plan: PlanFlags {
                            width: args.width,
                            height: args.height,
                            spp: args.spp,
                            splits: args.splits,
                            spans: None,
                            split_mode: SplitMode::Spatial,
                            mode: args.mode,
                            memory_mb: 2048,
                            scene_range_bytes: args.scene_range_bytes,
                        },
                        // What `measure` writes: the PNG only.
                        outputs: OutputFlags {
                            out: Some(dir.join("image.png")),
                            hits: None,
                        },
                    },
                    calibration,
                )?;
                let measured = measure(&exe, &dir, scene, workers, latency, args)?;
                let predicted = planned.chosen.seconds;
                let ratio = measured / predicted;
                worst = if (ratio - 1.0).abs() > (worst - 1.0).abs() {
                    ratio
                } else {
                    worst
                };
                table.push(vec![
                    scene.display().to_string(),
                    planned.triangles.to_string(),
                    workers.to_string(),
                    format!("{latency}"),
                    f3(predicted),
                    f3(measured),
                    format!("{ratio:.2}"),
                ]);
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    table.print();
    println!("furthest from 1: {worst:.2}");
    if let Some(csv) = &args.csv {
        table.append_csv(csv)?;
    }
    Ok(())
}

/// Seconds of one emulator run: its report's total less the scene's load.
fn measure(
    exe: &std::path::Path,
    dir: &std::path::Path,
    scene: &std::path::Path,
    workers: u32,
    latency_ms: f64,
    args: &PlanBenchArgs,
) -> Result<f64> {
    let report = dir.join("report.json");
    let mut cmd = Command::new(exe);
    cmd.arg("render")
        .arg(scene)
        .arg("--workers")
        .arg(workers.to_string())
        .arg("--out")
        .arg(dir.join("image.png"))
        .arg("--report")
        .arg(&report);
    for (flag, value) in [
        ("--width", args.width),
        ("--height", args.height),
        ("--spp", args.spp),
    ] {
        if let Some(v) = value {
            cmd.arg(flag).arg(v.to_string());
        }
    }
    if let Some(mode) = args.mode {
        cmd.arg("--mode").arg(mode.to_string());
    }
    if let Some(k) = args.splits {
        cmd.arg("--splits").arg(k.to_string());
    }
    if let Some(bytes) = args.scene_range_bytes {
        cmd.arg("--scene-range-bytes").arg(bytes.to_string());
    }
    if latency_ms > 0.0 {
        cmd.env(
            S3_FAULTS_VAR,
            format!("seed=1,latency=1,latency-ms={latency_ms}"),
        );
    } else {
        cmd.env_remove(S3_FAULTS_VAR);
    }
    let out = cmd.output().context("running hort render")?;
    if !out.status.success() {
        bail!(
            "hort render {} --workers {workers}: {}",
            scene.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    let text = std::fs::read_to_string(&report).context("the render's report")?;
    let json: serde_json::Value = serde_json::from_str(&text).context("the render's report")?;
    let seconds = |field: &str| json["seconds"][field].as_f64().unwrap_or(0.0);
    Ok(seconds("total") - seconds("load"))
}
