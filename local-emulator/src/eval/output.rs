//! What `hort eval` writes: Pareto fronts per scene, the CSV, and the summary on standard error.

use super::Point;
use super::pareto::pareto_front;
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::Path;

/// The CSV header of `eval.csv`.
pub const HEADER: &str = "chart,scene,method,spp,seconds,rmse,relmse,psnr,pareto";

/// For each point, whether it is on its scene's Pareto front of (seconds, RMSE).
pub fn fronts(points: &[Point]) -> Vec<bool> {
    let mut front = vec![false; points.len()];
    let mut scenes: Vec<&str> = points.iter().map(|p| p.scene.as_str()).collect();
    scenes.dedup();
    for scene in scenes {
        let idx: Vec<usize> = (0..points.len())
            .filter(|&i| points[i].scene == scene)
            .collect();
        let coords: Vec<(f64, f64)> = idx
            .iter()
            .map(|&i| (points[i].seconds, points[i].errors.rmse))
            .collect();
        for (&i, on) in idx.iter().zip(pareto_front(&coords)) {
            front[i] = on;
        }
    }
    front
}

/// The methods in order of first appearance.
pub fn methods(points: &[Point]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for p in points {
        if !out.contains(&p.method) {
            out.push(p.method.clone());
        }
    }
    out
}

/// `eval.csv`: [`HEADER`], then one line per (chart, point, on the front).
pub fn csv(rows: &[(&str, &Point, bool)]) -> String {
    let mut s = format!("{HEADER}\n");
    for (chart, p, front) in rows {
        let _ = writeln!(
            s,
            "{chart},{},{},{},{:.6},{:.6e},{:.6e},{:.4},{}",
            p.scene,
            p.method,
            p.spp,
            p.seconds,
            p.errors.rmse,
            p.errors.relmse,
            p.errors.psnr,
            u8::from(*front)
        );
    }
    s
}

/// Per scene: each method's PSNR at its highest sample count, and our per-sample throughput
/// over Mitsuba multijitter's at 64 spp when both were measured there.
pub fn summary(points: &[Point], scenes: &[String]) -> String {
    let mut s = String::new();
    for scene in scenes {
        let mine: Vec<&Point> = points.iter().filter(|p| &p.scene == scene).collect();
        for method in methods(points) {
            if let Some(top) = mine
                .iter()
                .filter(|p| p.method == method)
                .max_by_key(|p| p.spp)
            {
                let _ = writeln!(
                    s,
                    "{scene}: {method} at {} spp: PSNR {:.2} dB in {:.4} s",
                    top.spp, top.errors.psnr, top.seconds
                );
            }
        }
        let at = |m: &str| mine.iter().find(|p| p.method == m && p.spp == 64);
        if let (Some(ours), Some(theirs)) = (at("ours"), at("mitsuba multijitter")) {
            let _ = writeln!(
                s,
                "{scene}: per-sample throughput at 64 spp, ours / mitsuba multijitter: {:.3}x",
                theirs.seconds / ours.seconds
            );
        }
    }
    s
}

/// Writes `bytes` to a hidden temporary file beside `path`, then renames it into place.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let name = path
        .file_name()
        .with_context(|| format!("{}: names no file", path.display()))?;
    let tmp = path.with_file_name(format!(".{}.tmp", name.to_string_lossy()));
    std::fs::write(&tmp, bytes).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::metrics::Errors;

    fn p(scene: &str, method: &str, spp: u32, seconds: f64, rmse: f64) -> Point {
        Point {
            scene: scene.into(),
            method: method.into(),
            spp,
            seconds,
            errors: Errors {
                rmse,
                relmse: rmse * 2.0,
                psnr: 20.0,
            },
        }
    }

    #[test]
    fn fronts_are_per_scene() {
        // In scene b, (2, 0.5) is dominated; in scene a it would not matter that b's points
        // are faster and more accurate.
        let points = [
            p("a", "ours", 1, 10.0, 1.0),
            p("b", "ours", 1, 1.0, 0.1),
            p("b", "m", 1, 2.0, 0.5),
        ];
        assert_eq!(fronts(&points), vec![true, true, false]);
    }

    #[test]
    fn csv_lines_and_summary() {
        let a = p("a", "ours", 64, 2.0, 0.25);
        let b = p("a", "mitsuba multijitter", 64, 0.5, 0.5);
        assert_eq!(
            csv(&[("single-core", &a, true), ("single-core", &b, false)]),
            format!(
                "{HEADER}\nsingle-core,a,ours,64,2.000000,2.500000e-1,5.000000e-1,20.0000,1\n\
                 single-core,a,mitsuba multijitter,64,0.500000,5.000000e-1,1.000000e0,20.0000,0\n"
            )
        );
        assert_eq!(
            summary(&[a, b], &["a".into()]),
            "a: ours at 64 spp: PSNR 20.00 dB in 2.0000 s\n\
             a: mitsuba multijitter at 64 spp: PSNR 20.00 dB in 0.5000 s\n\
             a: per-sample throughput at 64 spp, ours / mitsuba multijitter: 0.250x\n"
        );
    }
}
