//! `hort eval`: speed against accuracy. Sweeps samples per pixel on scenes, times our
//! monolithic renderer on one thread (best of `--runs`), measures RMSE, relative MSE and PSNR
//! against a reference, adds Mitsuba's timed sweep from the references folder (written by
//! `eval/mitsuba_refs.py`), marks the Pareto front per scene, and writes `eval.csv` and
//! `eval.png`; then the same for the distributed renderer through the emulator
//! (`eval-distributed.png`), one series per `--distributed` entry.

pub(crate) mod chart;
mod csv_rows;
mod floor_csv;
mod metrics;
pub(crate) mod mitsuba_csv;
mod output;
mod pareto;
mod sweep;

use anyhow::{Context, Result, bail};
use metrics::Errors;
use std::path::PathBuf;

/// Options of `hort eval`.
#[derive(clap::Args, Clone, Debug)]
pub struct EvalArgs {
    /// Scene manifests or OBJ files; the reference of scene `S.json` is `REFERENCES/S.pfm`.
    #[arg(required = true)]
    pub scenes: Vec<PathBuf>,
    /// The folder with one `{scene}.pfm` per scene and `mitsuba.csv` (eval/references).
    #[arg(long)]
    pub references: PathBuf,
    /// Output folder for `eval.csv`, `eval.png` and `eval-distributed.png` (default out/eval,
    /// beside the committed results; `--out docs/eval` replaces those).
    #[arg(long, default_value = "out/eval")]
    pub out: PathBuf,
    /// Image size; must be the references' size.
    #[arg(long, default_value_t = 320, value_parser = clap::value_parser!(u32).range(1..=i64::from(hort_core::scene::MAX_IMAGE_SIDE)))]
    pub width: u32,
    /// Image size; must be the references' size.
    #[arg(long, default_value_t = 180, value_parser = clap::value_parser!(u32).range(1..=i64::from(hort_core::scene::MAX_IMAGE_SIDE)))]
    pub height: u32,
    /// Samples per pixel of the single-core sweep, comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "1,2,3,4,6,8,12,16,24,32,48,64,96,128,192,256"
    )]
    pub spp: Vec<u32>,
    /// Max samples per pixel of the adaptive series, comma-separated (5 to 65536); each
    /// point's first pass takes max / 16 samples (at least 4) in every pixel.
    #[arg(long, value_delimiter = ',', default_value = "16,64,256,1024")]
    pub adaptive_spp: Vec<u32>,
    /// The adaptive series' threshold on a pixel's standard error after the first pass.
    #[arg(long, default_value_t = 0.002)]
    pub adaptive_threshold: f64,
    /// Timed runs per setting; the best counts. The runs are taken in passes over every
    /// setting of a scene, so a slow minute costs each setting at most one of them.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub runs: u32,
    /// Distributed series `NAME:SPLITS:SPANS` through the emulator (repeatable; one split runs
    /// fused, more run staged); none given means `fused:1:16` and `staged:4:16`.
    #[arg(long = "distributed", value_parser = parse_series)]
    pub distributed: Vec<Series>,
    /// Samples per pixel of the distributed sweep, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,4,16,64")]
    pub distributed_spp: Vec<u32>,
    /// Max samples per pixel of each distributed series' adaptive runs (series `NAME
    /// adaptive`), comma-separated, as `--adaptive-spp`.
    #[arg(long, value_delimiter = ',', default_value = "16,64,256")]
    pub distributed_adaptive_spp: Vec<u32>,
    /// No adaptive runs in the distributed sweep.
    #[arg(long)]
    pub skip_distributed_adaptive: bool,
    /// Function slots of the emulator (default: all cores).
    #[arg(long)]
    pub workers: Option<usize>,
    /// Skip the distributed sweep and its chart.
    #[arg(long)]
    pub skip_distributed: bool,
}

/// One distributed series: a name and the pipeline's split and span counts.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// The series name in the CSV and the chart legend.
    pub name: String,
    /// Scene splits k.
    pub splits: u32,
    /// Pixel spans s.
    pub spans: u32,
}

/// Parses `NAME:SPLITS:SPANS`.
fn parse_series(s: &str) -> Result<Series, String> {
    let parts: Vec<&str> = s.split(':').collect();
    let [name, splits, spans] = parts[..] else {
        return Err(format!("`{s}`: expected NAME:SPLITS:SPANS"));
    };
    let count = |v: &str, what: &str| {
        v.parse::<u32>()
            .ok()
            .filter(|&n| n > 0)
            .ok_or_else(|| format!("`{s}`: {what} `{v}` is not a positive integer"))
    };
    if name.is_empty() {
        return Err(format!("`{s}`: the name is empty"));
    }
    Ok(Series {
        name: name.to_owned(),
        splits: count(splits, "SPLITS")?,
        spans: count(spans, "SPANS")?,
    })
}

/// One measured setting: a method on a scene at a sample count.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    /// The scene's file stem.
    pub scene: String,
    /// `ours`, `mitsuba independent`, `mitsuba multijitter`, or a distributed series name.
    pub method: String,
    /// Samples per pixel actually taken.
    pub spp: u32,
    /// Render seconds (one thread; wall time of the whole job for distributed series).
    pub seconds: f64,
    /// Error against the reference.
    pub errors: Errors,
}

/// Runs `hort eval`.
pub fn run(args: &EvalArgs) -> Result<()> {
    for (what, list) in [
        ("--spp", &args.spp),
        ("--distributed-spp", &args.distributed_spp),
    ] {
        let max = hort_core::scene::MAX_SPP;
        if let Some(bad) = list.iter().find(|&&s| s == 0 || s > max) {
            bail!("{what}: {bad} is not in 1..={max}");
        }
    }
    let levels = |maxes: &[u32]| -> Vec<(u32, u32)> {
        maxes.iter().map(|&max| ((max / 16).max(4), max)).collect()
    };
    let adaptive_levels = levels(&args.adaptive_spp);
    let distributed_levels = if args.skip_distributed_adaptive {
        Vec::new()
    } else {
        levels(&args.distributed_adaptive_spp)
    };
    let checks = [
        ("--adaptive-spp", &adaptive_levels),
        ("--distributed-adaptive-spp", &distributed_levels),
    ];
    for (flag, list) in checks {
        for &(base_spp, max_spp) in list {
            let settings = hort_core::adaptive::AdaptiveSettings {
                base_spp,
                max_spp,
                threshold: args.adaptive_threshold,
            };
            settings
                .check()
                .with_context(|| format!("{flag} {max_spp}, --adaptive-threshold"))?;
        }
    }
    let series = if args.distributed.is_empty() {
        vec![
            parse_series("fused:1:16").map_err(anyhow::Error::msg)?,
            parse_series("staged:4:16").map_err(anyhow::Error::msg)?,
        ]
    } else {
        args.distributed.clone()
    };
    let csv_path = args.references.join("mitsuba.csv");
    let csv_text = std::fs::read_to_string(&csv_path)
        .with_context(|| format!("reading {}", csv_path.display()))?;
    let mitsuba = mitsuba_csv::parse(&csv_path.display().to_string(), &csv_text)
        .map_err(anyhow::Error::msg)?;
    // The references' own error, when the folder has it.
    let floor_path = args.references.join("floor.csv");
    let floors = match std::fs::read_to_string(&floor_path) {
        Ok(text) => floor_csv::parse(&floor_path.display().to_string(), &text)
            .map_err(anyhow::Error::msg)?,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
        Err(e) => return Err(e).with_context(|| format!("reading {}", floor_path.display())),
    };
    let workers = args
        .workers
        .unwrap_or_else(hort_core::worker_pool::available_cores);
    let mut single = Vec::new();
    let mut distributed = Vec::new();
    let mut names = Vec::new();
    for path in &args.scenes {
        let scene = sweep::SceneUnderTest::load(path, &args.references, args.width, args.height)?;
        names.push(scene.name.clone());
        single.extend(sweep::monolithic(&scene, &args.spp, args.runs)?);
        single.extend(sweep::adaptive(
            &scene,
            &adaptive_levels,
            args.adaptive_threshold,
            args.runs,
        )?);
        let theirs: Vec<Point> = mitsuba
            .iter()
            .filter(|p| p.scene == scene.name)
            .cloned()
            .collect();
        if theirs.is_empty() {
            bail!("{}: no rows for scene {}", csv_path.display(), scene.name);
        }
        single.extend(theirs);
        if !args.skip_distributed {
            distributed.extend(sweep::distributed(
                &scene,
                &series,
                &args.distributed_spp,
                &distributed_levels,
                args.adaptive_threshold,
                args.workers
                    .unwrap_or_else(hort_core::worker_pool::available_cores),
            )?);
        }
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let distributed_x = format!("job seconds (emulator, {workers} function slots)");
    let charts = [
        (
            "single-core",
            &single,
            "eval.png",
            chart::ChartText {
                title: "1 thread, time vs error",
                x_desc: "render seconds, 1 thread",
                floors: &floors,
            },
        ),
        (
            "distributed",
            &distributed,
            "eval-distributed.png",
            chart::ChartText {
                title: "emulator, time vs error",
                x_desc: &distributed_x,
                floors: &floors,
            },
        ),
    ];
    let mut rows = Vec::new();
    for (chart_name, points, file, text) in &charts {
        if points.is_empty() {
            continue;
        }
        let front = output::fronts(points);
        let methods = output::methods(points);
        let png = chart::draw(text, &names, &methods, points, &front)?;
        output::write_atomic(&args.out.join(file), &png)?;
        rows.extend(points.iter().zip(&front).map(|(p, &f)| (*chart_name, p, f)));
    }
    output::write_atomic(&args.out.join("eval.csv"), output::csv(&rows).as_bytes())?;
    eprint!("{}", output::summary(&single, &names));
    eprintln!(
        "wrote {}",
        ["eval.csv", "eval.png", "eval-distributed.png"]
            .iter()
            .take(if distributed.is_empty() { 2 } else { 3 })
            .map(|f| args.out.join(f).display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn series_parse_and_refuse() {
        assert_eq!(
            parse_series("fused:4:16").unwrap(),
            Series {
                name: "fused".into(),
                splits: 4,
                spans: 16
            }
        );
        assert_eq!(
            parse_series("a:4").unwrap_err(),
            "`a:4`: expected NAME:SPLITS:SPANS"
        );
        assert_eq!(
            parse_series("a:0:16").unwrap_err(),
            "`a:0:16`: SPLITS `0` is not a positive integer"
        );
        assert_eq!(
            parse_series(":1:16").unwrap_err(),
            "`:1:16`: the name is empty"
        );
    }
}
