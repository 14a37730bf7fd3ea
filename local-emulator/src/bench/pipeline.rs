//! `hort bench pipeline`: the in-process HORT pipeline against the monolithic renderer on the
//! same machine and threads (time ratios, extra traversal, shuffle bytes per pixel), the pairs
//! spatial splits let stages skip, and per-task memory peaks against the monolithic render's.

use super::scenes::{bundled, generated};
use super::table::{Table, f3};
use super::{BenchCommon, MemoryMeter};
use anyhow::{Result, ensure};
use hort_core::ids::{JobId, SplitId};
use hort_core::keys::split_key;
use hort_core::pipeline::{
    ExecutionMode, PipelineOptions, PipelineRun, PlanRequest, SplitMode, StoredOutputs, plan_job,
    resolve_counts, run_pipeline, run_task, split_build_preset, split_scene,
};
use hort_core::render::{RenderSettings, build_scene_bvh, render};
use hort_core::scene::{Scene, load_scene};
use hort_core::stage::Stage;
use hort_core::store::{BlobStore, MemoryStore};
use hort_core::worker_pool::available_cores;
use std::time::Instant;

/// Options of `hort bench pipeline`.
#[derive(clap::Args, Clone, Debug)]
pub struct PipelineBenchArgs {
    /// Triangles of the generated scene for the time and skip tables.
    #[arg(long, default_value_t = 1_000_000)]
    pub triangles: u64,
    /// Triangles of the generated scene for the memory table.
    #[arg(long, default_value_t = 2_000_000)]
    pub memory_triangles: u64,
    /// Image size, threads, CSV output and scene cache.
    #[command(flatten)]
    pub common: BenchCommon,
    /// Skip the memory table (it renders the large scene twice more).
    #[arg(long)]
    pub skip_memory: bool,
}

pub fn run_pipeline_bench(args: &PipelineBenchArgs, meter: &dyn MemoryMeter) -> Result<()> {
    let threads = args.common.threads.unwrap_or_else(available_cores);
    let scene_path = generated(&args.common.scene_dir, args.triangles, 1)?;
    let scene = load_scene(&scene_path)?;
    let mut tables = vec![time_table(&scene, args, threads)?];
    let bunny = load_scene(&bundled("bunny/bunny.json"))?;
    tables.push(skip_table(
        &[("bunny", &bunny), ("generated", &scene)],
        args,
        threads,
    )?);
    drop(scene);
    if !args.skip_memory {
        let path = generated(&args.common.scene_dir, args.memory_triangles, 1)?;
        tables.push(memory_table(&path, args, threads, meter)?);
    }
    for t in &tables {
        t.print();
        if let Some(csv) = &args.common.csv {
            t.append_csv(csv)?;
        }
    }
    Ok(())
}

/// The bench's job: `k` splits and `s` spans, fused with one split and staged with more unless
/// `execution` forces a mode.
fn request(
    args: &PipelineBenchArgs,
    k: u32,
    s: u32,
    mode: SplitMode,
    execution: Option<ExecutionMode>,
) -> PlanRequest {
    PlanRequest {
        width: args.common.width,
        height: args.common.height,
        spp: 1,
        splits: Some(k),
        spans: Some(s),
        mode,
        execution,
        memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
        adaptive: None,
        outputs: StoredOutputs::ALL,
        frame: Default::default(),
    }
}

fn run(scene: &Scene, req: PlanRequest, workers: usize) -> Result<(PipelineRun, f64)> {
    let store = MemoryStore::new();
    let options = PipelineOptions {
        job: JobId::new("bench")?,
        workers,
        split_cache_bytes: 1 << 30,
    };
    let start = Instant::now();
    let run = run_pipeline(&store, scene, req, &options)?;
    Ok((run, start.elapsed().as_secs_f64()))
}

const SHUFFLE_STAGES: [Stage; 5] = Stage::ROUND;

fn time_table(scene: &Scene, args: &PipelineBenchArgs, threads: usize) -> Result<Table> {
    let mut table = Table::new(
        &format!(
            "pipeline vs monolithic: {} triangles, {}x{}, {threads} threads (ratio = time / monolithic time)",
            scene.mesh.triangle_count(),
            args.common.width,
            args.common.height
        ),
        &[
            "run",
            "seconds",
            "ratio",
            "render s",
            "render ratio",
            "cast rays/ray",
            "shadow tests/ray",
            "B/px cast-map",
            "B/px cast-reduce",
            "B/px expand",
            "B/px trace-map",
            "B/px trace-reduce",
            "identical",
        ],
    );
    let start = Instant::now();
    let bvh = build_scene_bvh(&scene.mesh);
    let settings = RenderSettings {
        width: args.common.width,
        height: args.common.height,
        spp: 1,
        threads,
        frame: Default::default(),
    };
    let mono = render(scene, &bvh, settings)?;
    let mono_total = start.elapsed().as_secs_f64();
    drop(bvh);
    table.push(vec![
        "monolithic".into(),
        f3(mono_total),
        "1.000".into(),
        f3(mono.render_seconds),
        "1.000".into(),
        "1.000".into(),
        "1.000".into(),
        "-".into(),
        "-".into(),
        "-".into(),
        "-".into(),
        "-".into(),
        "-".into(),
    ]);
    let pixels = f64::from(args.common.width) * f64::from(args.common.height);
    // Fused is what a scene that fits one function runs; staged k=1 is the paper's MR1, k=8 MR2.
    for (name, k, s, mode, execution) in [
        ("fused k=1 s=16", 1, 16, SplitMode::Spatial, None),
        (
            "MR1 staged k=1 s=16",
            1,
            16,
            SplitMode::Spatial,
            Some(ExecutionMode::Staged),
        ),
        ("MR2 k=8 s=16 spatial", 8, 16, SplitMode::Spatial, None),
        ("MR2 k=8 s=16 naive", 8, 16, SplitMode::Naive, None),
    ] {
        let (run, seconds) = run(scene, request(args, k, s, mode, execution), threads)?;
        let identical =
            run.image.as_ref() == Some(&mono.image) && run.hits.as_ref() == Some(&mono.hits);
        ensure!(
            identical,
            "{name}: the pipeline image differs from the monolithic one"
        );
        // A fused task casts its span against every split.
        let cast_samples: u64 = if run.plan.mode == ExecutionMode::Fused {
            pixels as u64 * u64::from(run.plan.k())
        } else {
            run.plan
                .cast_tasks
                .iter()
                .map(|t| {
                    run.plan.spans[t.span as usize].end - run.plan.spans[t.span as usize].start
                })
                .sum()
        };
        let stage_metrics = |stage: Stage| {
            run.stages
                .iter()
                .zip(&run.metrics)
                .find(|(r, _)| r.name == stage.as_str())
                .map(|(r, m)| (r.clone(), *m))
        };
        let queries = stage_metrics(Stage::Expand).map_or(0, |(_, m)| m.records);
        let mut row = vec![
            name.to_string(),
            f3(seconds),
            f3(seconds / mono_total),
            f3(run.render_seconds),
            f3(run.render_seconds / mono.render_seconds),
            f3(cast_samples as f64 / pixels),
            f3(queries as f64 / run.shadow_rays.max(1) as f64),
        ];
        for stage in SHUFFLE_STAGES {
            let bytes = stage_metrics(stage).map_or(0, |(r, _)| r.bytes_written);
            row.push(format!("{:.2}", bytes as f64 / pixels));
        }
        row.push("yes".into());
        table.push(row);
    }
    Ok(table)
}

fn skip_table(
    scenes: &[(&str, &Scene)],
    args: &PipelineBenchArgs,
    threads: usize,
) -> Result<Table> {
    let mut table = Table::new(
        &format!(
            "(span, split) pairs skipped by spatial splits, k=8 s=16, {}x{}",
            args.common.width, args.common.height
        ),
        &[
            "scene",
            "mode",
            "cast pairs run",
            "cast skipped",
            "trace pairs run",
            "trace skipped",
            "shuffle MB",
            "saved vs naive",
        ],
    );
    for (name, scene) in scenes {
        let k = 8.min(scene.mesh.triangle_count() as u32);
        let mut naive_bytes = 0u64;
        for mode in [SplitMode::Naive, SplitMode::Spatial] {
            let (run, _) = run(scene, request(args, k, 16, mode, None), threads)?;
            let pairs = f64::from(k) * 16.0;
            // Metrics are per stage of the plan's mode, plan first.
            let trace = run.metrics[run
                .plan
                .stages()
                .iter()
                .position(|s| *s == Stage::TraceMap)
                .unwrap_or(0)];
            let trace_run = run.plan.trace_tasks.len() as u64 - trace.skipped_tasks;
            let bytes: u64 = run
                .stages
                .iter()
                .filter(|s| SHUFFLE_STAGES.iter().any(|t| t.as_str() == s.name))
                .map(|s| s.bytes_written)
                .sum();
            if mode == SplitMode::Naive {
                naive_bytes = bytes;
            }
            table.push(vec![
                name.to_string(),
                format!("{mode:?}").to_lowercase(),
                run.plan.cast_tasks.len().to_string(),
                format!(
                    "{:.1}%",
                    100.0 * (1.0 - run.plan.cast_tasks.len() as f64 / pairs)
                ),
                trace_run.to_string(),
                format!("{:.1}%", 100.0 * (1.0 - trace_run as f64 / pairs)),
                format!("{:.2}", bytes as f64 / 1e6),
                format!(
                    "{:.1}%",
                    100.0 * (1.0 - bytes as f64 / naive_bytes.max(1) as f64)
                ),
            ]);
        }
    }
    Ok(table)
}

fn memory_table(
    path: &std::path::Path,
    args: &PipelineBenchArgs,
    threads: usize,
    meter: &dyn MemoryMeter,
) -> Result<Table> {
    let mb = |b: usize| format!("{:.1}", b as f64 / (1 << 20) as f64);
    let base = meter.current();
    meter.reset_peak();
    let scene = load_scene(path)?;
    let scene_mem = meter.current() - base;
    // Monolithic: the parsed scene, its BVH, the render buffers.
    let bvh = build_scene_bvh(&scene.mesh);
    let settings = RenderSettings {
        width: args.common.width,
        height: args.common.height,
        spp: 1,
        threads,
        frame: Default::default(),
    };
    let mono = render(&scene, &bvh, settings)?;
    let mono_peak = meter.peak() - base;
    drop((bvh, mono));
    // Splitter: the parsed scene plus one split's buffers at a time.
    let store = MemoryStore::new();
    let job = JobId::new("memory")?;
    let req = request(args, 16, 16, SplitMode::Spatial, None);
    let (shape, s) = resolve_counts(&req, scene.mesh.triangle_count() as u64)?;
    let k = shape.splits;
    meter.reset_peak();
    let before_split = meter.current();
    let preset = split_build_preset(&req, scene.mesh.triangle_count() as u64);
    let infos = split_scene(&scene.mesh, k as usize, req.mode, preset, |i, bytes| {
        store.put(&split_key(&job, SplitId(i)), &bytes)
    })?;
    let stored: usize = infos.iter().map(|i| i.bytes as usize).sum();
    let splitter_peak = meter.peak() - before_split - stored + scene_mem;
    let plan = plan_job(&scene, &req, infos, &shape, s)?;
    drop(scene);
    // Map tasks, one at a time, each measured from its own start.
    let mut peaks: Vec<(Stage, usize)> = Vec::new();
    for &stage in plan.task_stages() {
        for task in 0..plan.task_count(stage) {
            let before = meter.current();
            meter.reset_peak();
            run_task(&store, &job, &plan, stage, task as u32)?;
            peaks.push((stage, meter.peak() - before));
        }
    }
    let mut table = Table::new(
        &format!(
            "memory: {} triangles, k={k} s={s}, {}x{} (allocation high-water marks; ratio = / monolithic)",
            plan.triangles, args.common.width, args.common.height
        ),
        &["what", "peak MB", "ratio"],
    );
    table.push(vec![
        "monolithic render (scene + BVH + buffers)".into(),
        mb(mono_peak),
        "1.000".into(),
    ]);
    table.push(vec![
        "splitter (scene + one split)".into(),
        mb(splitter_peak),
        f3(splitter_peak as f64 / mono_peak as f64),
    ]);
    for &stage in Stage::TASKS {
        let of_stage: Vec<usize> = peaks
            .iter()
            .filter(|(s, _)| *s == stage)
            .map(|(_, p)| *p)
            .collect();
        let max = of_stage.iter().copied().max().unwrap_or(0);
        table.push(vec![
            format!("{stage} task, max of {}", of_stage.len()),
            mb(max),
            f3(max as f64 / mono_peak as f64),
        ]);
    }
    Ok(table)
}
