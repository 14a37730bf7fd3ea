//! `hort plan`: the plan `hort render` would run for a scene, and a projection of its time,
//! requests and dollars on N functions (AWS Lambda, or the local emulator on this machine),
//! without building a BVH or paying for anything.

mod calibrate;
mod chart;
mod text;

pub use calibrate::{Calibration, calibrate};

use crate::frame_flags::check_one_job;
use anyhow::{Result, anyhow, bail};
use clap::{Args, ValueEnum};
use hort::emulator::scene_range_for;
use hort_core::camera::Camera;
use hort_core::cost::Arch;
use hort_core::pipeline::partition::{preview_plan_from_table, scan_table};
use hort_core::pipeline::{ExecutionMode, JobPlan, PlanRequest, SplitMode, resolve_counts_with};
use hort_core::predict::{
    Projection, ProjectionSettings, RATES, SPLIT_BYTES_PER_TRIANGLE,
    SPLIT_NORMAL_BYTES_PER_TRIANGLE, SWEEP, Target, best_of, preview_plan, project,
};
use hort_core::scene::{ImageSettings, load_scene, scene_image_settings};
use hort_core::worker_pool::available_cores;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The function slot counts an emulator projection sweeps (a machine has few cores).
pub const EMULATOR_SWEEP: [u32; 5] = [1, 2, 4, 8, 16];

/// The flags of `hort plan`: the render flags that shape a plan (same names and defaults as
/// `hort render`), and where and on how many functions to project it.
#[derive(Args, Clone)]
pub struct PlanArgs {
    /// The scene: an OBJ file, or a JSON manifest (.json) naming OBJ files.
    pub scene: PathBuf,
    /// More scenes, charted beside the first (with --chart only; each is also planned and
    /// printed).
    pub more_scenes: Vec<PathBuf>,
    /// Also draw each scene's projected wall time and dollars against the function count (1 to
    /// 10,000 on AWS; the emulator's slot counts with --target emulator) into this PNG.
    #[arg(long)]
    pub chart: Option<PathBuf>,
    /// Functions to project (default: the best of the sweep), 1 to 10000.
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub functions: Option<u32>,
    /// Lambda architecture: its price per GB-second and its cold start.
    #[arg(long, value_enum, default_value = "arm64")]
    pub arch: ArchArg,
    /// Project AWS Lambda and Step Functions, or the local emulator on this machine with N
    /// function slots (`hort render --workers N`).
    #[arg(long, value_enum, default_value = "aws")]
    pub target: TargetArg,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Probability that an attempt fails and is retried, 0 to below 1.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub fail_rate: f64,
    /// With --target emulator: the delay the embedded S3 server adds to every request, ms (as
    /// HORT_S3_FAULTS=latency=1,latency-ms=N does).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub s3_latency_ms: f64,
    /// The image and the plan's shape: `hort render`'s flags, with its names and defaults.
    #[command(flatten)]
    pub plan: crate::plan_flags::PlanFlags,
    /// The outputs `hort render` would write, which decide what the job stores.
    #[command(flatten)]
    pub outputs: crate::plan_flags::OutputFlags,
    /// The frames `hort render` would render in one job (`--frames`, `--frame`, `--orbit`).
    #[command(flatten)]
    pub animation: crate::frame_flags::FrameFlags,
}

/// `--arch`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ArchArg {
    /// Graviton.
    Arm64,
    /// Intel/AMD.
    #[value(name = "x86_64")]
    X86_64,
}

/// `--target`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum TargetArg {
    /// AWS Lambda and Step Functions.
    Aws,
    /// The local emulator on this machine.
    Emulator,
}

/// Everything `hort plan` prints, text or JSON.
#[derive(Serialize)]
pub struct PlanOutput {
    /// The scene path as given.
    pub scene: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Triangles.
    pub triangles: u64,
    /// Lights.
    pub lights: u64,
    /// `fused` or `staged`.
    pub mode: ExecutionMode,
    /// Why the plan chose it.
    pub mode_reason: String,
    /// `spatial` or `naive`.
    pub split_mode: SplitMode,
    /// Scene splits k.
    pub splits: u32,
    /// Pixel spans s.
    pub spans: u32,
    /// Tasks over all stages.
    pub tasks: u64,
    /// Frames the job renders (1 for a still image); the projection covers them all.
    pub frames: u32,
    /// The stages at the chosen function count.
    pub stages: Vec<hort_core::predict::StageProjection>,
    /// Where the projection runs.
    pub target: Target,
    /// This machine against the reference.
    pub calibration: Calibration,
    /// The speed the projection assumes for one function's core (the calibration's for the
    /// emulator; 1, the reference machine, for Lambda).
    pub speed: f64,
    /// Failure rate assumed.
    pub fail_rate: f64,
    /// The function count projected in detail: --functions, else the best of the sweep.
    pub functions: u32,
    /// Whether `functions` is the sweep's best (no --functions given).
    pub functions_is_best: bool,
    /// The projection at `functions`.
    pub chosen: Projection,
    /// The sweep, fewest functions first.
    pub projection: Vec<Projection>,
}

/// Runs `hort plan`.
pub fn run(args: &PlanArgs) -> Result<()> {
    if !args.more_scenes.is_empty() && args.chart.is_none() {
        bail!("several scenes are planned together only for a chart: add --chart FILE.png");
    }
    let Some(chart_path) = &args.chart else {
        return print_plan(&plan(args)?, args.json);
    };
    check_flags(args)?;
    let calibration = calibrate()?;
    let mut series = Vec::new();
    let mut subtitle = None;
    for scene in std::iter::once(&args.scene).chain(&args.more_scenes) {
        let prepared = prepare(args, scene, &calibration)?;
        // Titled after the first scene's image settings.
        subtitle.get_or_insert_with(|| {
            format!(
                "{}x{}, {} spp, {}",
                prepared.width,
                prepared.height,
                prepared.spp,
                target_name(&prepared.settings.target)
            )
        });
        print_plan(
            &plan_prepared(args, scene, &prepared, calibration)?,
            args.json,
        )?;
        let sweep: &[u32] = match args.target {
            TargetArg::Aws => &chart::CHART_SWEEP,
            TargetArg::Emulator => &EMULATOR_SWEEP,
        };
        let name = scene.file_stem().map_or_else(
            || scene.display().to_string(),
            |n| n.to_string_lossy().into(),
        );
        series.push(chart::SceneSeries {
            label: format!("{name} ({} triangles)", prepared.triangles),
            points: sweep
                .iter()
                .map(|&n| project(&prepared.job, n, &prepared.settings))
                .collect(),
        });
    }
    let png = chart::draw(&subtitle.unwrap_or_default(), &series)?;
    std::fs::write(chart_path, png)
        .map_err(|e| anyhow!("cannot write --chart {}: {e}", chart_path.display()))?;
    eprintln!("wrote {}", chart_path.display());
    Ok(())
}

fn print_plan(output: &PlanOutput, json: bool) -> Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(output)?);
    } else {
        print!("{}", text::render(output));
    }
    Ok(())
}

/// A short name of where a projection runs, for chart titles.
fn target_name(target: &Target) -> String {
    match target {
        Target::Aws { memory_mb, arch } => {
            format!(
                "Lambda {} {memory_mb} MB",
                format!("{arch:?}").to_lowercase()
            )
        }
        Target::Emulator { .. } => "the emulator on this machine".to_owned(),
    }
}

/// The plan and its projections for `args` (what `hort plan` prints), calibrating first.
pub fn plan(args: &PlanArgs) -> Result<PlanOutput> {
    check_flags(args)?;
    plan_with(args, calibrate()?)
}

/// Refuses flag values `hort plan` cannot use, naming the flag.
fn check_flags(args: &PlanArgs) -> Result<()> {
    if !(0.0..1.0).contains(&args.fail_rate) {
        bail!(
            "--fail-rate {} is not a probability from 0 to below 1",
            args.fail_rate
        );
    }
    if !(args.s3_latency_ms >= 0.0 && args.s3_latency_ms.is_finite()) {
        bail!(
            "--s3-latency-ms {} is not a number of milliseconds, 0 or more",
            args.s3_latency_ms
        );
    }
    if args.target == TargetArg::Aws && args.s3_latency_ms > 0.0 {
        bail!(
            "--s3-latency-ms applies to --target emulator only (AWS is projected at S3's own \
             first-byte latency)"
        );
    }
    Ok(())
}

/// [`plan`] with a calibration already made.
pub fn plan_with(args: &PlanArgs, calibration: Calibration) -> Result<PlanOutput> {
    check_flags(args)?;
    let prepared = prepare(args, &args.scene, &calibration)?;
    plan_prepared(args, &args.scene, &prepared, calibration)
}

/// The request `hort render` would send for `scene` (`None`: not loaded here) whose manifest
/// fixes `image`: its frames one job's.
fn plan_request(
    args: &PlanArgs,
    scene: Option<&hort_core::scene::Scene>,
    image: &ImageSettings,
) -> Result<PlanRequest> {
    let size = args.plan.image_size(image)?;
    let frames = args.animation.plan(scene)?;
    check_one_job(&frames, size.width, size.height)?;
    Ok(PlanRequest {
        frame: frames.job_choice(),
        ..args.plan.request(size, None, args.outputs.stored())
    })
}

/// The plan of a scene loaded whole, with its camera samples' hit fraction estimated.
fn preview_loaded(args: &PlanArgs, scene_path: &Path) -> Result<JobPlan> {
    let scene = load_scene(scene_path)?;
    let request = plan_request(args, Some(&scene), &scene.image)?;
    let (width, height) = (request.width, request.height);
    Camera::new(&scene.camera_for(width, height), width, height)
        .map_err(|e| anyhow!("{}: {e}", scene_path.display()))?;
    let (shape, s) = resolve_counts_with(
        &request,
        scene.mesh.triangle_count() as u64,
        &scene.mesh.textures,
    )?;
    preview_plan(&scene, &request, &shape, s)
        .map_err(|e| anyhow!("{}: {}", scene_path.display(), e))
}

/// The plan of a scene split by tasks in ranges of `range` bytes, from its scan (the vertex
/// pages dropped as each range closes): the Partition and Build tasks counted, every sample
/// assumed to hit (no mesh is held to estimate it).
fn preview_scanned(args: &PlanArgs, scene_path: &Path, range: u64) -> Result<JobPlan> {
    let request = plan_request(args, None, &scene_image_settings(scene_path)?)?;
    let dir = scene_path.parent().unwrap_or(Path::new(""));
    // A scene split by tasks is large: say what the wait is for.
    eprintln!(
        "scanning {} in ranges of {} bytes, as the Plan function will (it is split by tasks)",
        scene_path.display(),
        range
    );
    let table = scan_table(dir, scene_path, range, |_, _, _| Ok(()))?;
    // Every triangle may have normals when the files define some (the scan does not say which).
    let normal_bytes = if table.shape().normals > 0 {
        SPLIT_NORMAL_BYTES_PER_TRIANGLE
    } else {
        0
    };
    let plan = preview_plan_from_table(
        scene_path,
        &table,
        &request,
        SPLIT_BYTES_PER_TRIANGLE + normal_bytes,
    )?;
    let (width, height) = (plan.width, plan.height);
    Camera::new(&plan.camera, width, height)
        .map_err(|e| anyhow!("{}: {e}", scene_path.display()))?;
    Ok(plan)
}

/// A scene's plan and what projecting it needs.
struct Prepared {
    job: JobPlan,
    settings: ProjectionSettings,
    sweep: &'static [u32],
    width: u32,
    height: u32,
    spp: u32,
    triangles: u64,
}

/// Plans `scene` under `args` without building anything: loaded whole, or, for a scene the
/// Plan function would split by tasks, scanned range by range as it would scan it (so that no
/// more than a range's vertices are held).
fn prepare(args: &PlanArgs, scene_path: &Path, calibration: &Calibration) -> Result<Prepared> {
    let job = match scene_range_for(scene_path, args.plan.memory_mb, args.plan.scene_range_bytes) {
        Some(range) => preview_scanned(args, scene_path, range)?,
        None => preview_loaded(args, scene_path)?,
    };
    let (width, height, spp, triangles) = (job.width, job.height, job.spp, job.triangles);
    let arch = match args.arch {
        ArchArg::Arm64 => Arch::Arm64,
        ArchArg::X86_64 => Arch::X86_64,
    };
    let (target, speed, sweep): (Target, f64, &'static [u32]) = match args.target {
        TargetArg::Aws => (
            Target::Aws {
                memory_mb: args.plan.memory_mb,
                arch,
            },
            1.0,
            &SWEEP,
        ),
        TargetArg::Emulator => (
            Target::Emulator {
                cores: available_cores() as u32,
                s3_latency_ms: args.s3_latency_ms,
                memory_mb: args.plan.memory_mb,
                arch,
            },
            calibration.speed,
            &EMULATOR_SWEEP,
        ),
    };
    let settings = ProjectionSettings {
        target,
        speed,
        rates: RATES,
        fail_rate: args.fail_rate,
    };
    Ok(Prepared {
        job,
        settings,
        sweep,
        width,
        height,
        spp,
        triangles,
    })
}

/// What `hort plan` prints for a prepared scene.
fn plan_prepared(
    args: &PlanArgs,
    scene: &Path,
    prepared: &Prepared,
    calibration: Calibration,
) -> Result<PlanOutput> {
    let Prepared {
        job,
        settings,
        sweep,
        width,
        height,
        spp,
        triangles,
    } = prepared;
    let projection: Vec<Projection> = sweep.iter().map(|&n| project(job, n, settings)).collect();
    let (functions, functions_is_best) = match args.functions {
        Some(n) => (n, false),
        None => (sweep[best_of(&projection).unwrap_or(0)], true),
    };
    let chosen = project(job, functions, settings);
    Ok(PlanOutput {
        scene: scene.display().to_string(),
        width: *width,
        height: *height,
        spp: *spp,
        triangles: *triangles,
        lights: job.lights.len() as u64,
        mode: job.mode,
        mode_reason: job.mode_reason.clone(),
        split_mode: job.split_mode,
        splits: job.k(),
        spans: job.spans.len() as u32,
        tasks: chosen.stages.iter().map(|s| s.tasks).sum(),
        frames: job.frame_numbers().len() as u32,
        stages: chosen.stages.clone(),
        target: settings.target,
        calibration,
        speed: settings.speed,
        fail_rate: args.fail_rate,
        functions,
        functions_is_best,
        chosen,
        projection,
    })
}
