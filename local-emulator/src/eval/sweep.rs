//! The measurements of `hort eval`: our monolithic renderer on one thread, and distributed
//! series through the local emulator, each image compared with the scene's reference.

use super::metrics::errors;
use super::{Point, Series};
use anyhow::{Context, Result, anyhow, bail};
use asl_interpreter::NoObserver;
use hort::emulator::{EmulatorConfig, run_job};
use hort_core::adaptive::{AdaptiveSettings, render_adaptive};
use hort_core::bvh::Bvh;
use hort_core::image::{Image, decode_pfm};
use hort_core::pipeline::{PlanRequest, SplitMode, StoredOutputs};
use hort_core::render::{RenderSettings, build_scene_bvh, render};
use hort_core::scene::{Scene, load_scene};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A loaded scene, its BVH and its reference image.
pub struct SceneUnderTest {
    /// The scene file's stem (`bunny` for `bunny.json`).
    pub name: String,
    /// The scene file.
    pub path: PathBuf,
    scene: Scene,
    bvh: Bvh,
    reference: Image,
    width: u32,
    height: u32,
}

impl SceneUnderTest {
    /// Loads `path` and `{references}/{stem}.pfm`, which must be `width x height`.
    pub fn load(path: &Path, references: &Path, width: u32, height: u32) -> Result<Self> {
        let name = path
            .file_stem()
            .with_context(|| format!("{}: the scene path names no file", path.display()))?
            .to_string_lossy()
            .into_owned();
        let scene = load_scene(path).with_context(|| format!("loading {}", path.display()))?;
        let reference_path = references.join(format!("{name}.pfm"));
        let bytes = std::fs::read(&reference_path)
            .with_context(|| format!("reading the reference {}", reference_path.display()))?;
        let reference =
            decode_pfm(&bytes).map_err(|e| anyhow!("{}: {e}", reference_path.display()))?;
        if (reference.width, reference.height) != (width, height) {
            bail!(
                "{}: the reference is {}x{} but the sweep renders {width}x{height} (--width, --height)",
                reference_path.display(),
                reference.width,
                reference.height
            );
        }
        let bvh = build_scene_bvh(&scene.mesh);
        Ok(SceneUnderTest {
            name,
            path: path.to_owned(),
            scene,
            bvh,
            reference,
            width,
            height,
        })
    }

    fn point(&self, method: &str, spp: u32, seconds: f64, image: &Image) -> Result<Point> {
        Ok(Point {
            scene: self.name.clone(),
            method: method.to_owned(),
            spp,
            seconds,
            errors: errors(image, &self.reference)
                .map_err(|e| anyhow!("{}: {e}", self.path.display()))?,
        })
    }
}

/// Best of `runs` timings of each of `settings`, taken in `runs` passes over all of them (one
/// run of each setting a pass), so that a slow minute of a shared machine costs each setting
/// at most one of its runs rather than all of them. `run` renders one setting and returns its
/// time in seconds and what it produced (the same every run: rendering is deterministic);
/// returns each setting's best time and last product, in order.
fn best_of_passes<S, T>(
    settings: &[S],
    runs: u32,
    mut run: impl FnMut(&S) -> Result<(f64, T)>,
) -> Result<Vec<(f64, T)>> {
    let mut best: Vec<Option<(f64, T)>> = settings.iter().map(|_| None).collect();
    for _ in 0..runs.max(1) {
        for (setting, best) in settings.iter().zip(best.iter_mut()) {
            let (seconds, product) = run(setting)?;
            let fastest = best.as_ref().map_or(seconds, |(b, _)| b.min(seconds));
            *best = Some((fastest, product));
        }
    }
    Ok(best
        .into_iter()
        .map(|b| b.expect("at least one pass"))
        .collect())
}

/// Our monolithic renderer on one thread at each of `spp`: the best render time of `runs`
/// (rendering only, the BVH is built once; runs taken in passes over every count,
/// [`best_of_passes`]), and the error of the image (the same bytes every run: rendering is
/// deterministic).
pub fn monolithic(scene: &SceneUnderTest, spp: &[u32], runs: u32) -> Result<Vec<Point>> {
    let timed = best_of_passes(spp, runs, |&n| {
        let settings = RenderSettings {
            width: scene.width,
            height: scene.height,
            spp: n,
            threads: 1,
            frame: Default::default(),
        };
        let out = render(&scene.scene, &scene.bvh, settings)?;
        Ok((out.render_seconds, out.image))
    })?;
    let mut points = Vec::new();
    for (&n, (best, image)) in spp.iter().zip(timed) {
        let point = scene.point("ours", n, best, &image)?;
        eprintln!(
            "{} ours {n} spp: {best:.4} s, PSNR {:.2} dB",
            scene.name, point.errors.psnr
        );
        points.push(point);
    }
    Ok(points)
}

/// The adaptive sampler on one thread at each `(base, max)` sample count pair with `threshold`:
/// the best render time of `runs` and the image's error, as [`monolithic`]. The point's `spp`
/// is the max; the mean samples per pixel taken is printed.
pub fn adaptive(
    scene: &SceneUnderTest,
    levels: &[(u32, u32)],
    threshold: f64,
    runs: u32,
) -> Result<Vec<Point>> {
    let timed = best_of_passes(levels, runs, |&(base_spp, max_spp)| {
        let settings = RenderSettings {
            width: scene.width,
            height: scene.height,
            spp: base_spp,
            threads: 1,
            frame: Default::default(),
        };
        let adaptive = AdaptiveSettings {
            base_spp,
            max_spp,
            threshold,
        };
        let (out, counts) = render_adaptive(&scene.scene, &scene.bvh, settings, adaptive)?;
        Ok((out.render_seconds, (out.image, counts)))
    })?;
    let mut points = Vec::new();
    for (&(base_spp, max_spp), (best, (image, counts))) in levels.iter().zip(timed) {
        let point = scene.point(ADAPTIVE_METHOD, max_spp, best, &image)?;
        let pixels = u64::from(scene.width) * u64::from(scene.height);
        eprintln!(
            "{} {ADAPTIVE_METHOD} {base_spp}..{max_spp} spp (mean {:.1}, {} of {pixels} pixels refined): {best:.4} s, PSNR {:.2} dB",
            scene.name,
            counts.samples as f64 / pixels as f64,
            counts.refined_pixels,
            point.errors.psnr
        );
        points.push(point);
    }
    Ok(points)
}

/// The method name of the adaptive series in `eval.csv` and the charts.
pub const ADAPTIVE_METHOD: &str = "ours adaptive";

/// Each distributed series at each of `spp` through the emulator (embedded S3 server, state
/// machine, function handlers) with `workers` slots: wall time of the whole job, one run.
/// Each series of `series` through the emulator at every uniform spp of `spp`, then with the
/// adaptive sampler at every (base, max) level of `adaptive` (series `{name} adaptive`, its
/// `spp` the max), `threshold` on the standard error.
pub fn distributed(
    scene: &SceneUnderTest,
    series: &[Series],
    spp: &[u32],
    adaptive: &[(u32, u32)],
    threshold: f64,
    workers: usize,
) -> Result<Vec<Point>> {
    let config = EmulatorConfig::embedded(workers);
    let mut points = Vec::new();
    for s in series {
        let uniform = spp.iter().map(|&n| (s.name.clone(), n, n, None));
        let refined = adaptive.iter().map(|&(base_spp, max_spp)| {
            let settings = AdaptiveSettings {
                base_spp,
                max_spp,
                threshold,
            };
            (
                format!("{} adaptive", s.name),
                base_spp,
                max_spp,
                Some(settings),
            )
        });
        for (name, base, max, settings) in uniform.chain(refined) {
            let request = PlanRequest {
                width: scene.width,
                height: scene.height,
                spp: base,
                splits: Some(s.splits),
                spans: Some(s.spans),
                mode: SplitMode::Spatial,
                execution: None,
                memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
                adaptive: settings,
                outputs: StoredOutputs::ALL,
                frame: Default::default(),
            };
            let start = Instant::now();
            let run = run_job(&config, &scene.path, request, &NoObserver)
                .with_context(|| format!("{} {name} at {max} spp", scene.name))?;
            let seconds = start.elapsed().as_secs_f64();
            let image = run
                .image
                .as_ref()
                .context("the job stored no linear image")?;
            let point = scene.point(&name, max, seconds, image)?;
            eprintln!(
                "{} {name} {max} spp: {seconds:.3} s, PSNR {:.2} dB",
                scene.name, point.errors.psnr
            );
            points.push(point);
        }
    }
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs go pass by pass over every setting, and each setting keeps its fastest time and
    /// its last product.
    #[test]
    fn best_of_passes_takes_one_run_of_each_setting_a_pass() {
        let mut calls = Vec::new();
        let times = [[3.0, 1.0, 2.0], [5.0, 6.0, 4.0]];
        let mut pass = [0usize; 2];
        let out = best_of_passes(&[0usize, 1], 3, |&s| {
            calls.push(s);
            let t = times[s][pass[s]];
            pass[s] += 1;
            Ok((t, (s, pass[s])))
        })
        .unwrap();
        assert_eq!(calls, [0, 1, 0, 1, 0, 1]);
        assert_eq!(out, [(1.0, (0, 3)), (4.0, (1, 3))]);
        let failed = best_of_passes(&[0], 2, |_| -> Result<(f64, ())> { bail!("no scene") });
        assert_eq!(failed.unwrap_err().to_string(), "no scene");
    }
}
