//! `hort bench emulator`: the local emulator end to end (embedded S3 server, state machine,
//! function handlers) against the monolithic renderer on the same machine and threads, with
//! the in-process pipeline in between to show where the time goes: in-process minus monolithic
//! is the pipeline's own work (encoding, compression, split loads, extra traversal); emulator
//! minus in-process is storage round trips over S3 and orchestration. First the emulator's
//! fixed cost per stage and per task (`overhead.rs`); last the paper's fault experiment: one
//! of 16 function slots dies mid-run.

use super::BenchCommon;
use super::overhead::overhead_table;
use super::scenes::{bundled, generated};
use super::table::{Table, f3};
use anyhow::Result;
use asl_interpreter::NoObserver;
use hort::emulator::{EmulatorConfig, FaultSettings, run_job};
use hort_core::ids::JobId;
use hort_core::image::encode_png;
use hort_core::pipeline::{
    ExecutionMode, PipelineOptions, PlanRequest, SplitMode, StoredOutputs, run_pipeline,
};
use hort_core::render::{RenderSettings, build_scene_bvh, render};
use hort_core::scene::load_scene;
use hort_core::store::MemoryStore;
use hort_core::worker_pool::available_cores;
use std::time::Instant;

/// Options of `hort bench emulator`.
#[derive(clap::Args, Clone, Debug)]
pub struct EmulatorBenchArgs {
    /// Triangles of the generated scene.
    #[arg(long, default_value_t = 1_000_000)]
    pub triangles: u64,
    /// Image size, threads, CSV output and scene cache.
    #[command(flatten)]
    pub common: BenchCommon,
    /// Skip the 16-slot fault experiment.
    #[arg(long)]
    pub skip_faults: bool,
    /// Measure only the fixed overhead per stage and per task (two tiny jobs on the bundled
    /// Cornell box), not the end-to-end comparison.
    #[arg(long)]
    pub overhead_only: bool,
}

fn emulator_config(workers: usize, faults: FaultSettings) -> EmulatorConfig {
    EmulatorConfig {
        faults,
        ..EmulatorConfig::embedded(workers)
    }
}

pub fn run_emulator_bench(args: &EmulatorBenchArgs) -> Result<()> {
    let overhead = overhead_table(
        &emulator_config(1, FaultSettings::default()),
        &bundled("cornell/cornell.json"),
    )?;
    let print = |t: &Table| -> Result<()> {
        t.print();
        if let Some(csv) = &args.common.csv {
            t.append_csv(csv)?;
        }
        Ok(())
    };
    print(&overhead)?;
    if args.overhead_only {
        return Ok(());
    }
    let threads = args.common.threads.unwrap_or_else(available_cores);
    let path = generated(&args.common.scene_dir, args.triangles, 1)?;
    let scene = load_scene(&path)?;
    let mut table = Table::new(
        &format!(
            "emulator vs monolithic: {} triangles, {}x{}, {threads} threads/slots, every row from parsing the OBJ on (ratio = time / monolithic)",
            scene.mesh.triangle_count(),
            args.common.width,
            args.common.height
        ),
        &[
            "run",
            "seconds",
            "ratio",
            "S3 requests",
            "MB written",
            "B/pixel/stage",
            "cost USD",
            "identical PNG",
        ],
    );
    // Every row starts from the OBJ file, as `hort render` does: the emulator's client parses
    // the scene once (and uploads it binary), so the monolithic and in-process rows parse too.
    // Every row ends with the PNG in memory: the monolithic row encodes it, the jobs store it
    // (and only it, as `hort render x.png` asks) and read it back.
    let start = Instant::now();
    let scene = load_scene(&path)?;
    let bvh = build_scene_bvh(&scene.mesh);
    let settings = RenderSettings {
        width: args.common.width,
        height: args.common.height,
        spp: 1,
        threads,
        frame: Default::default(),
    };
    let mono = render(&scene, &bvh, settings)?;
    let mono_png = encode_png(&mono.image)?;
    let mono_seconds = start.elapsed().as_secs_f64();
    drop(bvh);
    table.push(vec![
        "monolithic".into(),
        f3(mono_seconds),
        "1.000".into(),
        "-".into(),
        "-".into(),
        "-".into(),
        "-".into(),
        "-".into(),
    ]);
    // Fused is what the plan chooses for a scene that fits one function; staged k=1 is the
    // paper's MR1 (the shuffle with one split), staged k=8 its MR2.
    for (name, k, execution) in [
        ("fused k=1 s=16", 1u32, ExecutionMode::Fused),
        ("staged k=1 s=16", 1, ExecutionMode::Staged),
        ("staged k=8 s=16 spatial", 8, ExecutionMode::Staged),
    ] {
        let request = PlanRequest {
            width: args.common.width,
            height: args.common.height,
            spp: 1,
            splits: Some(k),
            spans: Some(16),
            mode: SplitMode::Spatial,
            execution: Some(execution),
            memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
            adaptive: None,
            outputs: StoredOutputs::PNG,
            frame: Default::default(),
        };
        let options = PipelineOptions {
            job: JobId::new("bench")?,
            workers: threads,
            split_cache_bytes: 1 << 30,
        };
        let t = Instant::now();
        let scene = load_scene(&path)?;
        let run = run_pipeline(&MemoryStore::new(), &scene, request, &options)?;
        let in_process = t.elapsed().as_secs_f64();
        table.push(vec![
            format!("in-process {name}"),
            f3(in_process),
            f3(in_process / mono_seconds),
            "-".into(),
            "-".into(),
            "-".into(),
            "-".into(),
            yes(run.png == mono_png),
        ]);
        let t = Instant::now();
        let run = run_job(
            &emulator_config(threads, FaultSettings::default()),
            &path,
            request,
            &NoObserver,
        )?;
        let seconds = t.elapsed().as_secs_f64();
        let requests: u64 = run
            .usage
            .iter()
            .map(|u| u.traffic.gets + u.traffic.puts + u.traffic.lists)
            .sum();
        let written: u64 = run.usage.iter().map(|u| u.traffic.bytes_written).sum();
        table.push(vec![
            format!("emulator {name}"),
            f3(seconds),
            f3(seconds / mono_seconds),
            requests.to_string(),
            format!("{:.1}", written as f64 / 1e6),
            format!("{:.1}", shuffle_bytes_per_pixel_stage(&run)),
            format!("{:.5}", run.cost.total),
            yes(run.png == mono_png),
        ]);
    }
    let mut tables = vec![table];
    if !args.skip_faults {
        tables.push(fault_table(args, &path, &mono_png)?);
    }
    for t in &tables {
        print(t)?;
    }
    Ok(())
}

/// Compressed bytes the task stages between plan and combine wrote, per pixel and per stage
/// (0 for a fused job's single stage beyond its pixel blocks' share).
fn shuffle_bytes_per_pixel_stage(run: &hort::emulator::EmulatorRun) -> f64 {
    let pixels = u64::from(run.plan.width) * u64::from(run.plan.height);
    let middle: Vec<_> = run
        .stages
        .iter()
        .filter(|s| s.name != "plan" && s.name != "combine")
        .collect();
    let bytes: u64 = middle.iter().map(|s| s.bytes_written).sum();
    bytes as f64 / pixels.max(1) as f64 / middle.len().max(1) as f64
}

fn yes(b: bool) -> String {
    if b { "yes" } else { "NO" }.into()
}

/// The paper's experiment: 16 slots, one dies halfway through the fault-free run's time.
fn fault_table(
    args: &EmulatorBenchArgs,
    path: &std::path::Path,
    reference: &[u8],
) -> Result<Table> {
    let job = PlanRequest {
        width: args.common.width,
        height: args.common.height,
        spp: 1,
        splits: Some(8),
        spans: Some(16),
        mode: SplitMode::Spatial,
        execution: None,
        memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
        adaptive: None,
        outputs: StoredOutputs::PNG,
        frame: Default::default(),
    };
    let t = Instant::now();
    let clean = run_job(
        &emulator_config(16, FaultSettings::default()),
        path,
        job,
        &NoObserver,
    )?;
    let clean_seconds = t.elapsed().as_secs_f64();
    let faults = FaultSettings {
        kill_slot_after: Some(clean_seconds / 2.0),
        ..FaultSettings::default()
    };
    let t = Instant::now();
    let killed = run_job(&emulator_config(16, faults), path, job, &NoObserver)?;
    let killed_seconds = t.elapsed().as_secs_f64();
    let mut table = Table::new(
        "one of 16 function slots dies halfway (the paper: +60% on Hadoop)",
        &[
            "run",
            "seconds",
            "extra",
            "failed attempts",
            "identical PNG",
        ],
    );
    table.push(vec![
        "16 slots".into(),
        f3(clean_seconds),
        "-".into(),
        clean.failed_attempts().to_string(),
        yes(clean.png == reference),
    ]);
    table.push(vec![
        "16 slots, one dies".into(),
        f3(killed_seconds),
        format!("{:+.0}%", 100.0 * (killed_seconds / clean_seconds - 1.0)),
        killed.failed_attempts().to_string(),
        yes(killed.png == reference),
    ]);
    Ok(table)
}
