//! `hort bench plan`: `hort plan --target emulator` against the emulator runs it predicts. For
//! every scene, image size, slot count and injected S3 latency it projects the job, then runs
//! `hort render SCENE --workers W` (this same binary, in a child process, the latency injected
//! through `HORT_S3_FAULTS`) and prints predicted seconds, measured seconds (the report's total
//! less the scene's load, which `hort plan` does not predict) and their ratio; with `--stages`,
//! the same for every stage (the rows the model's rates are fitted from). With `--repeats N`
//! every case runs N times, round robin, and the medians are printed.

use super::table::{Table, f3};
use crate::plan_cmd::{
    ArchArg, Calibration, PlanArgs, PlanOutput, TargetArg, calibrate, plan_with,
};
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
    /// Image sizes, WIDTHxHEIGHT, comma-separated (default: the scene's, else 960x540).
    #[arg(long, value_delimiter = ',', value_parser = parse_size)]
    pub sizes: Vec<(u32, u32)>,
    /// Also print each stage's predicted and measured seconds.
    #[arg(long)]
    pub stages: bool,
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
    /// Runs of each case, round robin (every case once per pass); the median job time and
    /// the median of each stage are reported (one run of an emulator job moves by up to 30%).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=99))]
    pub repeats: u32,
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
            "size",
            "triangles",
            "workers",
            "latency ms",
            "predicted",
            "measured",
            "measured/predicted",
        ],
    );
    let mut stage_table = Table::new(
        "each stage of the runs above: predicted and measured seconds",
        &[
            "scene",
            "size",
            "workers",
            "latency ms",
            "stage",
            "tasks",
            "predicted",
            "measured",
            "measured/predicted",
        ],
    );
    let sizes: Vec<(Option<u32>, Option<u32>)> = if args.sizes.is_empty() {
        vec![(None, None)]
    } else {
        args.sizes
            .iter()
            .map(|&(w, h)| (Some(w), Some(h)))
            .collect()
    };
    // One calibration for every prediction of the table.
    let calibration = calibrate()?;
    println!(
        "calibration: speed {:.2} (BVH {:.2} ms, render {:.2} ms)",
        calibration.speed, calibration.build_ms, calibration.trace_ms
    );
    let mut cases = Vec::new();
    for scene in &scenes {
        for &size in &sizes {
            for &latency in &args.latency_ms {
                for &workers in &args.workers {
                    let case = Case {
                        scene: scene.clone(),
                        size,
                        workers,
                        latency,
                    };
                    let planned = plan_case(&case, args, &dir, calibration)?;
                    cases.push((case, planned));
                }
            }
        }
    }
    // Round robin: each pass runs every case once, so a slow spell of the machine falls on
    // one run of many cases rather than on every run of a few.
    let mut runs: Vec<Vec<Measured>> = cases.iter().map(|_| Vec::new()).collect();
    for _ in 0..args.repeats {
        for ((case, _), runs) in cases.iter().zip(&mut runs) {
            runs.push(measure(&exe, &dir, case, args)?);
        }
    }
    let (mut within, mut worst) = (0, 1.0_f64);
    for ((case, planned), runs) in cases.iter().zip(&runs) {
        let run = Measured::median(runs);
        let (predicted, measured) = (planned.chosen.seconds, run.seconds);
        let ratio = measured / predicted;
        within += usize::from((ratio - 1.0).abs() <= 0.2);
        if (ratio - 1.0).abs() > (worst - 1.0).abs() {
            worst = ratio;
        }
        let (scene, workers) = (case.scene.display().to_string(), case.workers.to_string());
        let latency = format!("{}", case.latency);
        let size = format!("{}x{}", planned.width, planned.height);
        for stage in &planned.chosen.stages {
            let measured = run.stage_seconds(&stage.name);
            stage_table.push(vec![
                scene.clone(),
                size.clone(),
                workers.clone(),
                latency.clone(),
                stage.name.clone(),
                stage.tasks.to_string(),
                f3(stage.seconds),
                f3(measured),
                format!("{:.2}", measured / stage.seconds),
            ]);
        }
        table.push(vec![
            scene,
            size,
            planned.triangles.to_string(),
            workers,
            latency,
            f3(predicted),
            f3(measured),
            format!("{ratio:.2}"),
        ]);
    }
    let _ = std::fs::remove_dir_all(&dir);
    table.print();
    if args.stages {
        stage_table.print();
    }
    println!(
        "within 20%: {within} of {}; furthest from 1: {worst:.2}",
        cases.len()
    );
    if let Some(csv) = &args.csv {
        table.append_csv(csv)?;
    }
    Ok(())
}

/// One row of the table: a scene at an image size, run on `workers` slots with `latency` ms
/// injected per S3 request.
struct Case {
    scene: PathBuf,
    /// Width and height (`None`: the scene's).
    size: (Option<u32>, Option<u32>),
    workers: u32,
    latency: f64,
}

/// `hort plan --target emulator --json` of `case`, with the outputs `measure` stores (the PNG
/// only).
fn plan_case(
    case: &Case,
    args: &PlanBenchArgs,
    dir: &std::path::Path,
    calibration: Calibration,
) -> Result<PlanOutput> {
    let (width, height) = case.size;
    plan_with(
        &PlanArgs {
            scene: case.scene.clone(),
            more_scenes: Vec::new(),
            chart: None,
            functions: Some(case.workers),
            arch: ArchArg::Arm64,
            target: TargetArg::Emulator,
            json: true,
            fail_rate: 0.0,
            s3_latency_ms: case.latency,
            plan: PlanFlags {
                width,
                height,
                spp: args.spp,
                splits: args.splits,
                spans: None,
                split_mode: SplitMode::Spatial,
                mode: args.mode,
                memory_mb: 2048,
                scene_range_bytes: args.scene_range_bytes,
            },
            outputs: OutputFlags {
                out: Some(dir.join("image.png")),
                hits: None,
            },
            animation: Default::default(),
        },
        calibration,
    )
}

/// `--sizes`' `WIDTHxHEIGHT`.
fn parse_size(text: &str) -> Result<(u32, u32), String> {
    let max = hort_core::scene::MAX_IMAGE_SIDE;
    let side = |s: &str| s.parse::<u32>().ok().filter(|v| (1..=max).contains(v));
    text.split_once('x')
        .and_then(|(w, h)| Some((side(w)?, side(h)?)))
        .ok_or_else(|| format!("{text:?} is not WIDTHxHEIGHT with sides 1 to {max}"))
}

/// What one measured run took.
struct Measured {
    /// The report's total less the scene's load.
    seconds: f64,
    /// The report's stages: name and seconds (a stage run more than once counts each time).
    stages: Vec<(String, f64)>,
}

impl Measured {
    /// The median of `runs` (at least one): of the job's seconds and of each stage's.
    fn median(runs: &[Measured]) -> Measured {
        let seconds = median(runs.iter().map(|r| r.seconds).collect());
        let mut names: Vec<&String> = Vec::new();
        for (name, _) in &runs[0].stages {
            if !names.contains(&name) {
                names.push(name);
            }
        }
        let stages = names
            .into_iter()
            .map(|name| {
                let each = runs.iter().map(|r| r.stage_seconds(name)).collect();
                (name.clone(), median(each))
            })
            .collect();
        Measured { seconds, stages }
    }

    fn stage_seconds(&self, name: &str) -> f64 {
        self.stages
            .iter()
            .filter(|(n, _)| n == name)
            .map(|(_, s)| s)
            .sum()
    }
}

/// The median of `values` (at least one; the mean of the middle two for an even count).
fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    (values[(n - 1) / 2] + values[n / 2]) / 2.0
}

/// One emulator run: its report's total less the scene's load, and its stages.
fn measure(
    exe: &std::path::Path,
    dir: &std::path::Path,
    case: &Case,
    args: &PlanBenchArgs,
) -> Result<Measured> {
    let (scene, (width, height)) = (&case.scene, case.size);
    let (workers, latency_ms) = (case.workers, case.latency);
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
        ("--width", width),
        ("--height", height),
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
    let stages = json["stages"]
        .as_array()
        .map(|stages| {
            stages
                .iter()
                .map(|s| {
                    let name = s["name"].as_str().unwrap_or_default().to_owned();
                    (name, s["seconds"].as_f64().unwrap_or(0.0))
                })
                .collect()
        })
        .unwrap_or_default();
    Ok(Measured {
        seconds: seconds("total") - seconds("load"),
        stages,
    })
}
