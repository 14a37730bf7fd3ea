//! `hort render`: load, render, write the image, hit buffer and report.

use crate::cli::RenderArgs;
use anyhow::{Context, Result, bail};
use hort_core::hits::encode_hits;
use hort_core::image::write_image;
use hort_core::render::{RenderSettings, build_scene_bvh, render};
use hort_core::report::{RayReport, Report, Seconds};
use hort_core::scene::{DEFAULT_HEIGHT, DEFAULT_WIDTH, load_scene};
use std::path::{Path, PathBuf};
use std::time::Instant;

pub fn run(args: RenderArgs) -> Result<()> {
    if !args.monolithic {
        bail!(
            "the distributed pipeline is not available in this build yet: add --monolithic to render in one process"
        );
    }
    let started = Instant::now();
    let scene = load_scene(&args.scene)?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let load_seconds = started.elapsed().as_secs_f64();
    let settings = RenderSettings {
        width: args.width.or(scene.image.width).unwrap_or(DEFAULT_WIDTH),
        height: args.height.or(scene.image.height).unwrap_or(DEFAULT_HEIGHT),
        spp: args.spp.or(scene.image.spp).unwrap_or(1),
        threads: args.threads.unwrap_or(0),
    };
    if args.threads == Some(0) {
        bail!("--threads must be at least 1");
    }
    hort_core::scene::check_image_size(settings.width, settings.height, settings.spp)?;
    let build_start = Instant::now();
    let bvh = build_scene_bvh(&scene.mesh);
    let build_seconds = build_start.elapsed().as_secs_f64();
    let output = render(&scene, &bvh, settings)?;

    let out = args.out.clone().unwrap_or_else(|| default_out(&args.scene));
    write_image(&out, &output.image)?;
    if let Some(path) = &args.hits {
        write_file(path, &encode_hits(&output.hits))?;
    }
    let threads = if settings.threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        settings.threads
    };
    let report = Report {
        mode: "monolithic".into(),
        scene: args.scene.display().to_string(),
        width: settings.width,
        height: settings.height,
        spp: settings.spp,
        triangles: scene.mesh.triangle_count() as u64,
        threads,
        rays: RayReport {
            primary: output.rays.primary,
            shadow: output.rays.shadow,
        },
        seconds: Seconds {
            total: started.elapsed().as_secs_f64(),
            render: output.render_seconds,
            load: load_seconds,
            build: build_seconds,
        },
        stages: Vec::new(),
        replication: None,
        cost_usd: None,
    };
    if let Some(path) = &args.report {
        write_file(path, report.to_json().as_bytes())?;
    }
    let mrays =
        (report.rays.primary + report.rays.shadow) as f64 / output.render_seconds.max(1e-9) / 1e6;
    eprintln!(
        "rendered {}x{} at {} spp, {} triangles: {:.3} s render ({:.2} Mrays/s on {} threads), {:.3} s total -> {}",
        settings.width,
        settings.height,
        settings.spp,
        report.triangles,
        output.render_seconds,
        mrays,
        threads,
        report.seconds.total,
        out.display()
    );
    Ok(())
}

fn default_out(scene: &Path) -> PathBuf {
    let stem = scene
        .file_stem()
        .map_or("render".into(), |s| s.to_string_lossy().into_owned());
    PathBuf::from(format!("{stem}.png"))
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    std::fs::write(path, bytes).with_context(|| format!("cannot write {}", path.display()))
}
