//! `hort render`: load, render (monolithic or through the pipeline), write the image, hit
//! buffer and report.

use crate::cli::RenderArgs;
use crate::frame_flags::check_one_job;
use crate::frame_paths::{check_frame_pattern, frame_path};
use crate::outputs::{
    OutputTarget, check_distinct, check_image_path, check_output_path, write_output,
};
use crate::plan_flags::{ImageSize, is_png};
use anyhow::{Context, Result, anyhow, bail};
use hort::deployment::Deployment;
use hort::emulator::{
    EmulatorConfig, EmulatorRun, FaultSettings, JobOptions, LambdaTarget, StorageTarget,
    run_job_loaded, splits_by_tasks,
};
use hort::progress::{ProgressMode, ProgressObserver, print_breakdown, print_summary};
use hort_core::adaptive::{AdaptiveCounts, AdaptiveSettings, render_adaptive};
use hort_core::bvh::BuildPreset;
use hort_core::bvh::Bvh;
use hort_core::cost::Arch;
use hort_core::hits::{Hit, encode_hits};
use hort_core::ids::JobId;
use hort_core::image::{Image, encode_gif, write_image as encode_and_write};
use hort_core::pipeline::FrameSelection;
use hort_core::pipeline::{
    ExecutionMode, JobOutputs, PipelineOptions, PlanRequest, resolve_counts_with, run_pipeline,
};
use hort_core::plural::count;
use hort_core::render::{RenderSettings, build_scene_bvh_with, render};
use hort_core::report::{
    AdaptiveReport, FrameReport, Outputs, Preparation, RayReport, Report, Seconds, StageReport,
};
use hort_core::scene::{Scene, check_image_size, load_scene_with, scene_image_settings};
use hort_core::stage::Stage;
use hort_core::store::MemoryStore;
use hort_core::unoccludable::unoccludable_lights;
use hort_core::worker_pool::available_cores;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// What either renderer hands back for writing.
struct Rendered {
    /// The linear image: always from a monolithic render, from a job only when `--out` is not a
    /// PNG (the request's `outputs.linear`).
    image: Option<Image>,
    /// The PNG the Combine task stored (pipeline runs): `encode_png` of `image`, byte for byte.
    png: Option<Vec<u8>>,
    /// The hit buffer: always from a monolithic render, from a job only with `--hits`.
    hits: Option<Vec<Hit>>,
    /// A job of several frames: each frame's outputs (the fields above are the first frame's).
    frames: Vec<(u32, JobOutputs)>,
    /// A run of several frames: each frame's figures where the run measures them (the image
    /// file is filled in when written).
    frame_reports: Vec<FrameReport>,
    /// A run of several frames: the one-time part.
    preparation: Option<Preparation>,
    rays: RayReport,
    build_seconds: f64,
    render_seconds: f64,
    threads: usize,
    stages: Vec<StageReport>,
    replication: Option<f64>,
    cost_usd: Option<f64>,
    retried_attempts: u64,
    recomputed_blocks: u64,
    /// Splits and spans of the plan (pipeline modes).
    plan: Option<(u32, u32)>,
    /// The plan's mode and why it was chosen (pipeline modes).
    execution: Option<(ExecutionMode, String)>,
    /// How the BVH (monolithic) or the split objects (pipeline modes) were built.
    bvh_build: Option<BuildPreset>,
    /// Tasks at once (pipeline modes).
    workers: Option<usize>,
    /// The job id (pipeline modes).
    job: Option<String>,
    /// The adaptive sampler's settings and counts, when it ran.
    adaptive: Option<AdaptiveReport>,
    /// The lights whose shadow rays the render skipped (no surface can occlude them): the
    /// plan's list in pipeline modes.
    unoccludable_lights: Vec<u32>,
    /// The scene's lights and triangles (the plan's, in pipeline modes).
    lights: usize,
    triangles: u64,
}

/// True if `out` names a PNG (the one output a job always stores).
/// What to add to the error of `--adaptive MAX_SPP` over a first pass of `spp` samples too
/// small for an error estimate (the default `--spp 1`): the `--spp` that makes it run.
fn first_pass_hint(spp: u32, max_spp: u32) -> String {
    if spp >= 2 || max_spp <= 2 {
        return String::new();
    }
    let suggested = (max_spp - 1).min(4);
    format!(
        "; add --spp {suggested} (--adaptive {max_spp} --spp {suggested}: {suggested} samples in every pixel, then {max_spp} where needed)"
    )
}

/// The default of `--adaptive-threshold`.
const DEFAULT_ADAPTIVE_THRESHOLD: f64 = 0.002;

pub fn run(args: RenderArgs) -> Result<()> {
    let started = Instant::now();
    // Every output is checked before any work, so a bad path never costs a render.
    let targets = check_outputs(&args)?;
    let scene = load_unless_split_by_tasks(&args)?;
    let load_seconds = started.elapsed().as_secs_f64();
    let image = match &scene {
        Some(scene) => scene.image,
        None => scene_image_settings(&args.scene)?,
    };
    let size = args.plan.image_size(&image)?;
    let frames = args.animation.plan(scene.as_ref())?;
    check_frame_outputs(&targets, &frames)?;
    if !args.monolithic {
        check_one_job(&frames, size.width, size.height)?;
    }
    if let Some(scene) = &scene {
        check_cameras(scene, &args.scene, size, &frames)?;
    }
    let adaptive = adaptive_settings(&args, size)?;
    if adaptive.is_some() && !args.monolithic && frames.count() > 1 {
        bail!(
            "--adaptive renders one frame per job: give --frame K, or --monolithic for the {} \
             frames",
            frames.count()
        );
    }
    let request = args.plan.request(
        size,
        adaptive,
        // A job stores the large outputs only when this command writes them.
        args.outputs.stored(),
    );
    // One job renders every frame: the scene is uploaded, planned and split once.
    let job_request = PlanRequest {
        frame: frames.job_choice(),
        ..request
    };
    if let Some(scene) = scene.as_ref().filter(|_| !args.monolithic) {
        // Refuse impossible partitionings here, with the scene at hand, before any upload.
        let triangles = scene.mesh.triangle_count() as u64;
        let (shape, s) = resolve_counts_with(&job_request, triangles, &scene.mesh.textures)?;
        warn_if_oversplit(triangles, shape.splits, s);
    }
    let (rendered, images) = match &scene {
        Some(scene) if args.monolithic => {
            render_monolithic_frames(scene, request, &frames, (args.threads, started), adaptive)?
        }
        _ => {
            let request = job_request;
            let rendered = match &scene {
                Some(scene) if args.in_process => render_pipeline(scene, request, &args)?,
                _ => render_emulated(scene.as_ref(), &args, request)?,
            };
            let images = frame_images_of(&rendered, frames.frames.start);
            (rendered, images)
        }
    };
    let mut written = write_frames(&images, &targets)?;
    add_frame_figures(&mut written, &rendered.frame_reports);
    let preparation = rendered.preparation.clone().map(|p| Preparation {
        // The monolithic preparation is the BVH build after the load.
        seconds: p.seconds + if args.monolithic { load_seconds } else { 0.0 },
        ..p
    });
    let render_seconds = rendered.render_seconds;
    let mut report = run_report(&args, &targets.out, size, rendered, started, load_seconds);
    if frames.count() > 1 {
        report.frames = written;
        report.preparation = preparation;
    }
    for skip in &report.skips {
        eprintln!("skipped: {skip}");
    }
    if let Some(target) = &targets.report {
        write_output(target, (report.to_json() + "\n").as_bytes())?;
    }
    print_run_summary(&report, render_seconds, &targets.out)
}

/// Refuses, before any upload or render, a frame whose camera cannot be built: the scene's
/// fault, named by its path.
fn check_cameras(
    scene: &Scene,
    path: &Path,
    size: ImageSize,
    frames: &FrameSelection,
) -> Result<()> {
    for k in frames.frames.clone() {
        let settings = RenderSettings {
            width: size.width,
            height: size.height,
            spp: size.spp,
            threads: 1,
            frame: frames.choice(k),
        };
        settings
            .camera(scene)
            .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    }
    Ok(())
}

/// Gives each written frame the figures its render reported (the written image path kept).
fn add_frame_figures(written: &mut [FrameReport], figures: &[FrameReport]) {
    for frame in written {
        if let Some(found) = figures.iter().find(|f| f.frame == frame.frame) {
            *frame = FrameReport {
                image: std::mem::take(&mut frame.image),
                ..found.clone()
            };
        }
    }
}

/// What one frame of a run hands over for writing.
struct FrameImages {
    frame: u32,
    /// The linear image (monolithic renders; jobs that store it).
    image: Option<Image>,
    /// The PNG a job stored.
    png: Option<Vec<u8>>,
    /// The hit buffer (monolithic renders; jobs that store it).
    hits: Option<Vec<Hit>>,
}

/// The frames of a job's run, numbered from `first` (a job of one frame: its outputs).
fn frame_images_of(rendered: &Rendered, first: u32) -> Vec<FrameImages> {
    if rendered.frames.is_empty() {
        return vec![FrameImages {
            frame: first,
            image: rendered.image.clone(),
            png: rendered.png.clone(),
            hits: rendered.hits.clone(),
        }];
    }
    rendered
        .frames
        .iter()
        .map(|(frame, outputs)| FrameImages {
            frame: *frame,
            image: outputs.image.clone(),
            png: Some(outputs.png.clone()),
            hits: outputs.hits.clone(),
        })
        .collect()
}

/// Writes each frame's image and hit buffer to its files (an animated GIF `--out` gathers the
/// frames into one file, written after the last), and says which file holds which frame.
fn write_frames(images: &[FrameImages], targets: &OutputTargets) -> Result<Vec<FrameReport>> {
    let mut written = Vec::new();
    let mut gif_frames = Vec::new();
    for frame in images {
        let targets = targets.of_frame(frame.frame);
        if is_gif(&targets.out) {
            let image = frame.image.clone();
            gif_frames.push(image.ok_or_else(|| anyhow!("the job stored no linear image"))?);
        } else {
            write_image(frame, &targets.out)?;
        }
        write_hits(frame, &targets)?;
        written.push(FrameReport {
            frame: frame.frame,
            image: targets.out.display().to_string(),
            ready_seconds: None,
            rays: None,
            seconds: None,
            cost_usd: None,
        });
    }
    if !gif_frames.is_empty() {
        let gif = encode_gif(&gif_frames, GIF_FRAME_MS)?;
        write_output(&OutputTarget::File(targets.out.clone()), &gif)?;
    }
    Ok(written)
}

/// How long an animated GIF (`--out x.gif`) shows each frame: 25 frames a second.
const GIF_FRAME_MS: u32 = 40;

/// Whether `out` names an animated GIF preview.
fn is_gif(out: &Path) -> bool {
    out.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gif"))
}

/// With several frames, each frame's image and hit buffer need their own files: `--out`
/// (unless an animated GIF) and `--hits` must name them with a `#` run. The report is one, for
/// the whole run.
fn check_frame_outputs(targets: &OutputTargets, frames: &FrameSelection) -> Result<()> {
    let n = frames.count();
    if !is_gif(&targets.out) {
        check_frame_pattern("--out", &targets.out, n)?;
    }
    if let Some(OutputTarget::File(path)) = &targets.hits {
        check_frame_pattern("--hits", path, n)?;
    }
    Ok(())
}

/// The monolithic renders of `request`'s image of each of `frames`, over one BVH of `scene`:
/// the run's totals (rays and render seconds summed, the BVH built once) and each frame.
fn render_monolithic_frames(
    scene: &Scene,
    request: PlanRequest,
    frames: &FrameSelection,
    (threads, started): (Option<usize>, Instant),
    adaptive: Option<AdaptiveSettings>,
) -> Result<(Rendered, Vec<FrameImages>)> {
    let threads = threads.unwrap_or_else(available_cores);
    let build_start = Instant::now();
    // Few samples per triangle (large meshes at low sample counts) get the fast build.
    let samples = request.samples().saturating_mul(frames.frames.len() as u64);
    let preset = BuildPreset::for_samples(samples, scene.mesh.triangle_count() as u64);
    let bvh = build_scene_bvh_with(&scene.mesh, threads, preset);
    let build_seconds = build_start.elapsed().as_secs_f64();
    let mut total: Option<Rendered> = None;
    let mut images = Vec::new();
    let mut ready = Vec::new();
    for frame in frames.frames.clone() {
        let request = PlanRequest {
            frame: frames.choice(frame),
            ..request
        };
        let mut rendered =
            render_monolithic(scene, (&bvh, build_seconds), request, threads, adaptive)?;
        images.push(FrameImages {
            frame,
            image: rendered.image.take(),
            png: None,
            hits: rendered.hits.take(),
        });
        ready.push(FrameReport {
            frame,
            image: String::new(),
            ready_seconds: Some(started.elapsed().as_secs_f64()),
            rays: Some(rendered.rays),
            seconds: Some(rendered.render_seconds),
            cost_usd: None,
        });
        total = Some(match total {
            None => rendered,
            Some(mut sum) => {
                sum.rays.primary += rendered.rays.primary;
                sum.rays.shadow += rendered.rays.shadow;
                sum.render_seconds += rendered.render_seconds;
                sum
            }
        });
    }
    let mut total = total.ok_or_else(|| anyhow!("no frame to render"))?;
    total.bvh_build = Some(preset);
    if frames.count() > 1 {
        total.frame_reports = ready;
        total.preparation = Some(Preparation {
            seconds: build_seconds,
            cost_usd: None,
        });
    }
    Ok((total, images))
}

/// Where `hort render` writes: the image (`--out`, by default the scene's name as a PNG), the
/// hit buffer and the report (when asked for).
struct OutputTargets {
    out: PathBuf,
    hits: Option<OutputTarget>,
    report: Option<OutputTarget>,
}

impl OutputTargets {
    /// Frame `frame`'s files: each path's `#` run replaced by the frame number.
    fn of_frame(&self, frame: u32) -> OutputTargets {
        let file = |t: &OutputTarget| match t {
            OutputTarget::File(path) => OutputTarget::File(frame_path(path, frame)),
            OutputTarget::Stdout => OutputTarget::Stdout,
        };
        OutputTargets {
            out: frame_path(&self.out, frame),
            hits: self.hits.as_ref().map(file),
            report: self.report.as_ref().map(file),
        }
    }
}

/// The outputs of `args`, each path checked (writable, of a known kind) and all distinct.
fn check_outputs(args: &RenderArgs) -> Result<OutputTargets> {
    let out = args
        .outputs
        .out
        .clone()
        .unwrap_or_else(|| default_out(&args.scene));
    if is_gif(&out) {
        check_output_path("--out", &out, false)?;
    } else {
        check_image_path("--out", &out)?;
    }
    let hits = match &args.outputs.hits {
        Some(path) => Some(check_output_path("--hits", path, false)?),
        None => None,
    };
    let report = match &args.report {
        Some(path) => Some(check_output_path("--report", path, true)?),
        None => None,
    };
    let mut paths = vec![("--out", out.as_path())];
    paths.extend(args.outputs.hits.as_deref().map(|p| ("--hits", p)));
    paths.extend(args.report.as_deref().map(|p| ("--report", p)));
    check_distinct(&paths)?;
    Ok(OutputTargets { out, hits, report })
}

/// The scene of `args`, loaded with its warnings printed; `None` for a scene the emulator
/// splits by tasks, which goes up as its files: this process does not load it (it may not fit
/// here either); the Plan function checks it.
fn load_unless_split_by_tasks(args: &RenderArgs) -> Result<Option<Scene>> {
    let by_tasks = !args.monolithic
        && !args.in_process
        && splits_by_tasks(
            &args.scene,
            args.plan.memory_mb,
            args.plan.scene_range_bytes,
        );
    let scene = if by_tasks {
        None
    } else {
        Some(load_scene_with(&args.scene, args.missing_textures.into())?)
    };
    for w in scene.iter().flat_map(|s| &s.warnings) {
        eprintln!("warning: {w}");
    }
    Ok(scene)
}

/// The adaptive sampler's settings of `--adaptive` over the first pass of `size.spp` samples,
/// checked (with a hint when the first pass is too small for an error estimate) and within the
/// image size limits; `None` without `--adaptive`.
fn adaptive_settings(args: &RenderArgs, size: ImageSize) -> Result<Option<AdaptiveSettings>> {
    let ImageSize { width, height, spp } = size;
    let Some(max_spp) = args.adaptive else {
        return Ok(None);
    };
    let settings = AdaptiveSettings {
        base_spp: spp,
        max_spp,
        threshold: args
            .adaptive_threshold
            .unwrap_or(DEFAULT_ADAPTIVE_THRESHOLD),
    };
    settings.check().map_err(|e| {
        anyhow!(
            "--spp, --adaptive and --adaptive-threshold: {e}{}",
            first_pass_hint(spp, max_spp)
        )
    })?;
    check_image_size(width, height, max_spp).context("--adaptive")?;
    Ok(Some(settings))
}

/// Writes a frame's image to `out` (the PNG the job stored as it is, when `out` is a PNG); an
/// error if the run has no image to write.
fn write_image(rendered: &FrameImages, out: &Path) -> Result<()> {
    match (rendered.png.as_deref(), &rendered.image) {
        // The job stored this very encoding of the image: no need to encode it again.
        (Some(png), _) if is_png(out) => write_output(&OutputTarget::File(out.to_path_buf()), png),
        (_, Some(image)) => Ok(encode_and_write(out, image)?),
        (_, None) => bail!("the job stored no linear image to write {}", out.display()),
    }
}

/// Writes the hit buffer to `--hits` if asked for; an error if the run has no hits to write.
fn write_hits(rendered: &FrameImages, targets: &OutputTargets) -> Result<()> {
    if let Some(target) = &targets.hits {
        let hits = rendered
            .hits
            .as_deref()
            .ok_or_else(|| anyhow!("the job stored no hit buffer to write --hits"))?;
        write_output(target, &encode_hits(hits))?;
    }
    Ok(())
}

/// The report of the run: what `args` asked for, what `rendered` did and its times (the total
/// up to now, from `started`).
fn run_report(
    args: &RenderArgs,
    out: &Path,
    size: ImageSize,
    rendered: Rendered,
    started: Instant,
    load_seconds: f64,
) -> Report {
    let ImageSize { width, height, spp } = size;
    let outputs = Outputs {
        image: Some(out.display().to_string()),
        hits: args.outputs.hits.as_ref().map(|p| p.display().to_string()),
        report: args.report.as_ref().map(|p| p.display().to_string()),
    };
    let skipped = skips(
        rendered.lights,
        rendered.execution.as_ref().map(|(mode, _)| *mode),
        &rendered.unoccludable_lights,
        rendered.adaptive.as_ref(),
    );
    Report {
        mode: if args.monolithic {
            "monolithic"
        } else if args.in_process {
            "pipeline"
        } else {
            "emulator"
        }
        .into(),
        scene: args.scene.display().to_string(),
        width,
        height,
        spp,
        triangles: rendered.triangles,
        threads: rendered.threads,
        rays: rendered.rays,
        seconds: Seconds {
            total: started.elapsed().as_secs_f64(),
            render: rendered.render_seconds,
            load: load_seconds,
            build: rendered.build_seconds,
        },
        stages: rendered.stages,
        replication: rendered.replication,
        cost_usd: rendered.cost_usd,
        retried_attempts: rendered.retried_attempts,
        recomputed_blocks: rendered.recomputed_blocks,
        splits: rendered.plan.map(|(k, _)| k),
        spans: rendered.plan.map(|(_, s)| s),
        execution: rendered.execution.as_ref().map(|(m, _)| m.to_string()),
        execution_reason: rendered.execution.map(|(_, why)| why),
        bvh_build: rendered.bvh_build,
        workers: rendered.workers,
        job: rendered.job,
        outputs,
        skips: skipped,
        adaptive: rendered.adaptive,
        frames: Vec::new(),
        preparation: None,
    }
}

/// The adaptive part of a pipeline run's report: the request's settings and the Render
/// tasks' summed counts.
fn adaptive_report(request: PlanRequest, counts: AdaptiveCounts) -> Option<AdaptiveReport> {
    request.adaptive.map(|settings| AdaptiveReport {
        settings,
        counts: Some(counts),
    })
}

/// The work the run skipped because it cannot change the image, one sentence each, for a
/// scene of `lights` lights. `mode` is the pipeline's execution mode (`None` for a monolithic
/// render), `unoccludable` the lights whose shadow rays it skipped.
fn skips(
    lights: usize,
    mode: Option<ExecutionMode>,
    unoccludable: &[u32],
    adaptive: Option<&AdaptiveReport>,
) -> Vec<String> {
    let mut out = Vec::new();
    let staged = mode == Some(ExecutionMode::Staged);
    if lights == 0 {
        out.push(if staged {
            "the scene has no lights: no shadow rays traced, no expand or trace-map stages"
                .to_owned()
        } else {
            "the scene has no lights: no shadow rays traced".to_owned()
        });
    } else {
        for light in unoccludable {
            out.push(format!(
                "no surface can occlude light {light}: its shadow rays are not traced"
            ));
        }
        if staged && unoccludable.len() == lights {
            out.push("no light can be occluded: no expand or trace-map stages".to_owned());
        }
    }
    if let Some(counts) = adaptive.and_then(|a| a.counts)
        && counts.background_pixels > 0
    {
        out.push(format!(
            "{} pixels saw only background in the first pass: no extra samples",
            counts.background_pixels
        ));
    }
    out
}

/// Splits far smaller than useful multiply tasks and overhead for nothing: say so.
fn warn_if_oversplit(triangles: u64, k: u32, s: u32) {
    const USEFUL_TRIANGLES_PER_SPLIT: u64 = 1000;
    if k > 1 && triangles / u64::from(k) < USEFUL_TRIANGLES_PER_SPLIT {
        eprintln!(
            "warning: --splits {k} leaves about {} triangles per split; the job will run up to \
             {} map tasks, each paying a function call and storage round trips for little ray \
             work (splits pay off from about {USEFUL_TRIANGLES_PER_SPLIT} triangles each)",
            triangles.div_ceil(u64::from(k)),
            2 * u64::from(k) * u64::from(s)
        );
    }
}

/// The summary every render mode prints to standard error: the stage table (pipeline modes),
/// then one line of size, mode, time, ray throughput and output path.
fn print_run_summary(report: &Report, render_seconds: f64, out: &Path) -> Result<()> {
    if !report.stages.is_empty() {
        let mut table = Vec::new();
        print_summary(&report.stages, &mut table).context("summary")?;
        print_breakdown(&report.stages, &mut table).context("summary")?;
        eprint!("{}", String::from_utf8_lossy(&table));
    }
    let (width, height, spp) = (report.width, report.height, report.spp);
    let mrays = (report.rays.primary + report.rays.shadow) as f64 / render_seconds.max(1e-9) / 1e6;
    let threads = match report.threads {
        1 => "1 thread".to_owned(),
        n => format!("{n} threads"),
    };
    let spp = match &report.adaptive {
        Some(a) => {
            let pixels = u64::from(width) * u64::from(height);
            let mean = a.counts.map_or(0.0, |c| c.samples as f64 / pixels as f64);
            format!("{spp}..{} (adaptive, mean {mean:.2})", a.settings.max_spp)
        }
        None => spp.to_string(),
    };
    eprintln!(
        "rendered {width}x{height} at {spp} spp ({}), {} triangles: {:.3} s render ({mrays:.2} Mrays/s on {threads}), {:.3} s total -> {}",
        report.mode,
        report.triangles,
        render_seconds,
        report.seconds.total,
        out.display()
    );
    Ok(())
}

/// The monolithic render of `request`'s frame of `scene` on `threads` threads with its BVH
/// (built in `build_seconds`).
fn render_monolithic(
    scene: &Scene,
    (bvh, build_seconds): (&Bvh, f64),
    request: PlanRequest,
    threads: usize,
    adaptive: Option<AdaptiveSettings>,
) -> Result<Rendered> {
    let settings = RenderSettings {
        width: request.width,
        height: request.height,
        spp: request.spp,
        threads,
        frame: request.frame,
    };
    let (output, adaptive) = match adaptive {
        Some(a) => {
            let (output, counts) = render_adaptive(scene, bvh, settings, a)?;
            let report = AdaptiveReport {
                settings: a,
                counts: Some(counts),
            };
            (output, Some(report))
        }
        None => (render(scene, bvh, settings)?, None),
    };
    Ok(Rendered {
        image: Some(output.image),
        png: None,
        hits: Some(output.hits),
        frames: Vec::new(),
        frame_reports: Vec::new(),
        preparation: None,
        rays: RayReport {
            primary: output.rays.primary,
            shadow: output.rays.shadow,
        },
        build_seconds,
        render_seconds: output.render_seconds,
        threads,
        stages: Vec::new(),
        replication: None,
        cost_usd: None,
        retried_attempts: 0,
        recomputed_blocks: 0,
        plan: None,
        bvh_build: None,
        execution: None,
        workers: None,
        job: None,
        adaptive,
        unoccludable_lights: unoccludable_lights(&scene.mesh, &scene.lights)
            .into_iter()
            .enumerate()
            .filter(|(_, free)| *free)
            .map(|(light, _)| light as u32)
            .collect(),
        lights: scene.lights.len(),
        triangles: scene.mesh.triangle_count() as u64,
    })
}

fn render_pipeline(scene: &Scene, request: PlanRequest, args: &RenderArgs) -> Result<Rendered> {
    let workers = args.workers.unwrap_or_else(available_cores);
    let options = PipelineOptions {
        job: JobId::new("local").context("job id")?,
        workers,
        split_cache_bytes: 1 << 30,
    };
    let store = MemoryStore::new();
    let run = run_pipeline(&store, scene, request, &options)?;
    let counts = run
        .metrics
        .iter()
        .fold(AdaptiveCounts::default(), |mut sum, m| {
            sum += m.adaptive;
            sum
        });
    let adaptive = adaptive_report(request, counts);
    Ok(Rendered {
        image: run.image,
        png: Some(run.png),
        hits: run.hits,
        frames: run.frames,
        frame_reports: Vec::new(),
        preparation: None,
        rays: RayReport {
            primary: run.primary_rays,
            shadow: run.shadow_rays,
        },
        build_seconds: run.stages.first().map_or(0.0, |s| s.seconds),
        render_seconds: run.render_seconds,
        threads: workers,
        stages: run.stages,
        replication: Some(run.replication),
        cost_usd: None,
        retried_attempts: 0,
        recomputed_blocks: run.metrics.iter().map(|m| m.recomputed).sum(),
        plan: Some((run.plan.k(), run.plan.spans.len() as u32)),
        execution: Some((run.plan.mode, run.plan.mode_reason.clone())),
        bvh_build: Some(run.plan.bvh_build),
        workers: Some(workers),
        job: Some(options.job.to_string()),
        adaptive,
        unoccludable_lights: run.plan.unoccludable_lights.clone(),
        lights: run.plan.lights.len(),
        triangles: run.plan.triangles,
    })
}

fn render_emulated(
    scene: Option<&Scene>,
    args: &RenderArgs,
    request: PlanRequest,
) -> Result<Rendered> {
    let workers = args.workers.unwrap_or_else(available_cores);
    check_fault_flags(args)?;
    let storage = args.storage.target();
    let cancel = stop_on_signals();
    let config = emulator_config(args, storage, workers, cancel);
    let progress = ProgressObserver::new(ProgressMode::detect());
    let options = JobOptions {
        keep_intermediates: args.keep_intermediates,
        resume: args.resume,
        scene_range_bytes: args.plan.scene_range_bytes,
    };
    // The scene loaded above goes up parsed: no function parses it again (a scene split by
    // tasks, not loaded, goes up as its files).
    let run = run_job_loaded(&config, options, &args.scene, scene, request, &progress)?;
    print_job_notes(&run, workers);
    Ok(emulated_rendered(run, request, workers))
}

/// Refuses fault rates that are not probabilities and a time scale that is not a positive
/// number.
fn check_fault_flags(args: &RenderArgs) -> Result<()> {
    for (name, p) in [
        ("--fail-rate", args.fail_rate),
        ("--duplicate-rate", args.duplicate_rate),
        ("--slow-rate", args.slow_rate),
    ] {
        if !(0.0..=1.0).contains(&p) {
            bail!("{name} {p} is not a probability between 0 and 1");
        }
    }
    if !(args.time_scale > 0.0 && args.time_scale.is_finite()) {
        bail!("--time-scale must be a positive number");
    }
    Ok(())
}

/// The cancel flag of the run, set by the first stop signal (no new tasks start); a second
/// signal quits at once. A failure to watch the signals leaves the default behaviour.
fn stop_on_signals() -> Arc<AtomicBool> {
    let cancel = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&cancel);
    let _ = crate::stop_signals::on_stop_signals(move |signal| {
        if flag.swap(true, Ordering::Relaxed) {
            // Destructors do not run: remove the temporary folders first.
            hort::emulator::exit_now(signal.exit_code());
        }
        eprintln!("\nstopping: no new tasks start; {}", signal.quit_at_once());
    });
    cancel
}

/// How the emulator runs the job of `args` on `storage` with `workers` function slots: the
/// faults and time scale asked for, 1 GiB of split cache, arm64 functions of `--memory-mb`
/// (or the Lambda functions named), the bundled deployment's limits.
fn emulator_config(
    args: &RenderArgs,
    storage: StorageTarget,
    workers: usize,
    cancel: Arc<AtomicBool>,
) -> EmulatorConfig {
    EmulatorConfig {
        storage,
        job: args.job.clone(),
        workers,
        faults: FaultSettings {
            fail_rate: args.fail_rate,
            duplicate_rate: args.duplicate_rate,
            slow_rate: args.slow_rate,
            seed: args.seed,
            kill_slot_after: args.kill_slot_after,
        },
        time_scale: args.time_scale,
        task_timeout_seconds: args.task_timeout,
        split_cache_bytes: 1 << 30,
        memory_mb: args.plan.memory_mb,
        arch: Arch::Arm64,
        cancel,
        lambda: args.lambda_endpoint.as_ref().map(|endpoint| LambdaTarget {
            endpoint: Some(endpoint.clone()),
            plan: args.plan_function.clone(),
            worker: args.worker_function.clone(),
        }),
        functions: Deployment::bundled().function_limits(),
    }
}

/// Prints what the emulator's run of a job on `workers` slots met, to standard error: the
/// scan's warnings, the faults injected, the blocks recomputed, the job's line with its
/// measured cost, and its objects.
fn print_job_notes(run: &EmulatorRun, workers: usize) {
    for w in &run.scan_warnings {
        eprintln!("warning: {w}");
    }
    let retries = run.failed_attempts();
    if let Some(f) = &run.faults {
        eprintln!(
            "faults injected: {} failed before running, {} failed after writing, {} duplicated, {} straggled; {retries} attempts retried",
            f.failed_before.load(Ordering::Relaxed),
            f.failed_after_writing.load(Ordering::Relaxed),
            f.duplicated.load(Ordering::Relaxed),
            f.slowed.load(Ordering::Relaxed),
        );
        if f.slots_killed.load(Ordering::Relaxed) > 0 {
            eprintln!(
                "one function slot died with its attempt; the rest ran on {} slots",
                workers - 1
            );
        }
    }
    if run.recomputed() > 0 {
        eprintln!(
            "{} recomputed from lineage",
            count(run.recomputed(), "lost or corrupt block")
        );
    }
    eprintln!(
        "job {} on {} ({}: {}; {}, {}); measured AWS cost ${:.6} (AWS prices for this run's \
         task times on this machine and its requests; `hort plan` predicts a cost from its model \
         instead, so the two differ)",
        run.job,
        run.endpoint,
        run.plan.mode,
        run.plan.mode_reason,
        count(u64::from(run.plan.k()), "split"),
        count(run.plan.spans.len() as u64, "span"),
        run.cost.total
    );
    crate::jobs_cmd::print_job_objects(run);
}

/// What the emulator's `run` of `request` on `workers` slots hands back for writing: its
/// outputs, rays (the adaptive sampler's samples, or every pixel's `spp`), the task stages'
/// seconds (the plan's left out) and the plan's shape.
fn emulated_rendered(run: EmulatorRun, request: PlanRequest, workers: usize) -> Rendered {
    let retries = run.failed_attempts();
    let split_read = run.ledger.total().split_bytes_read;
    let recomputed = run.recomputed();
    let render_seconds = run
        .stages
        .iter()
        .filter(|s| s.name != "plan")
        .map(|s| s.seconds)
        .sum();
    let counts = run.ledger.total().adaptive;
    let adaptive = adaptive_report(request, counts);
    let frames = run.plan.frame_numbers().len() as u64;
    let (frame_reports, preparation) = emulated_frames(&run, request);
    Rendered {
        image: run.image,
        png: Some(run.png),
        hits: run.hits,
        frame_reports,
        preparation,
        frames: run.frames,
        rays: RayReport {
            primary: adaptive
                .as_ref()
                .map_or(request.samples() * frames, |_| counts.samples),
            shadow: run.ledger.total().shadow_rays,
        },
        build_seconds: run.stages.first().map_or(0.0, |s| s.seconds),
        render_seconds,
        threads: workers,
        replication: Some(split_read as f64 / run.plan.scene_bytes().max(1) as f64),
        retried_attempts: retries,
        recomputed_blocks: recomputed,
        plan: Some((run.plan.k(), run.plan.spans.len() as u32)),
        execution: Some((run.plan.mode, run.plan.mode_reason.clone())),
        bvh_build: Some(run.plan.bvh_build),
        workers: Some(workers),
        job: Some(run.job.to_string()),
        unoccludable_lights: run.plan.unoccludable_lights.clone(),
        lights: run.plan.lights.len(),
        triangles: run.plan.triangles,
        stages: run.stages,
        cost_usd: Some(run.cost.total),
        adaptive,
    }
}

/// A job of several frames' figures per frame (rays, its tasks' seconds, its share of the
/// cost by function time, when it was ready) and its plan step's; none for one frame.
fn emulated_frames(
    run: &EmulatorRun,
    request: PlanRequest,
) -> (Vec<FrameReport>, Option<Preparation>) {
    if run.frame_figures.is_empty() {
        return (Vec::new(), None);
    }
    let total_seconds = run.ledger.total().task_us as f64 / 1e6;
    let share = |seconds: f64| run.cost.total * seconds / total_seconds.max(1e-9);
    let primary = request.samples();
    let frames = run
        .frame_figures
        .iter()
        .map(|f| FrameReport {
            frame: f.frame,
            image: String::new(),
            ready_seconds: Some(f.ready_seconds),
            rays: Some(RayReport {
                primary,
                shadow: f.shadow_rays,
            }),
            seconds: Some(f.task_seconds),
            cost_usd: Some(share(f.task_seconds)),
        })
        .collect();
    let plan_seconds = run.ledger.stage(Stage::Plan).task_us as f64 / 1e6;
    let preparation = Preparation {
        seconds: run.stages.first().map_or(plan_seconds, |s| s.seconds),
        cost_usd: Some(share(plan_seconds)),
    };
    (frames, Some(preparation))
}

fn default_out(scene: &Path) -> PathBuf {
    let stem = scene
        .file_stem()
        .map_or("render".into(), |s| s.to_string_lossy().into_owned());
    PathBuf::from(format!("{stem}.png"))
}
