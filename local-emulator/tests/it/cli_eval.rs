//! `hort eval` end to end on a tiny Cornell box (16x12) against a Mitsuba reference fixture
//! (`tests/fixtures/eval`, written by `eval/mitsuba_refs.py` at 16x12, 2 x 528 spp): the CSV's
//! columns and rows, the error falling with spp, the chart, and bad inputs.

use crate::common;

use common::{files_in, hort, scene, scratch, stderr};
use std::path::{Path, PathBuf};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/eval")
}

fn eval(out: &Path, refs: &Path, width: &str, extra: &[&str]) -> std::process::Output {
    let cornell = scene("cornell/cornell.json");
    let mut args = vec![
        "eval",
        cornell.to_str().unwrap(),
        "--references",
        refs.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--width",
        width,
        "--height",
        "12",
    ];
    args.extend_from_slice(extra);
    hort(&args)
}

#[test]
fn writes_the_csv_and_both_charts() {
    let out = scratch("eval-ok");
    let o = eval(
        &out,
        &fixtures(),
        "16",
        &[
            "--spp",
            "1,4,64",
            "--adaptive-spp",
            "16,64",
            "--runs",
            "1",
            "--distributed",
            "k2:2:3",
            "--distributed-spp",
            "4",
            "--distributed-adaptive-spp",
            "16",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(out.join("eval.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        "chart,scene,method,spp,seconds,rmse,relmse,psnr,pareto"
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let keys: Vec<(&str, &str, &str, &str)> =
        rows.iter().map(|r| (r[0], r[1], r[2], r[3])).collect();
    assert_eq!(
        keys,
        [
            ("single-core", "cornell", "ours", "1"),
            ("single-core", "cornell", "ours", "4"),
            ("single-core", "cornell", "ours", "64"),
            ("single-core", "cornell", "ours adaptive", "16"),
            ("single-core", "cornell", "ours adaptive", "64"),
            ("single-core", "cornell", "mitsuba independent", "1"),
            ("single-core", "cornell", "mitsuba independent", "4"),
            ("single-core", "cornell", "mitsuba multijitter", "1"),
            ("single-core", "cornell", "mitsuba multijitter", "4"),
            ("distributed", "cornell", "k2", "4"),
            ("distributed", "cornell", "k2 adaptive", "16"),
        ]
    );
    let psnr = |i: usize| rows[i][7].parse::<f64>().unwrap();
    // Mitsuba's rows are copied from the fixture's CSV as they are.
    assert_eq!(
        rows[8][4..8],
        ["0.002396", "3.273762e-2", "8.788367e-3", "29.6991"]
    );
    // Ours converges to Mitsuba's reference: the error falls with spp, and at 64 spp PSNR is
    // above 40 dB (the same scene contract: one of the 192 pixels off by 0.25 in one channel
    // would already cost that much).
    assert!(psnr(0) < psnr(1) && psnr(1) < psnr(2), "{csv}");
    assert!(psnr(2) > 40.0, "{csv}");
    // The distributed pipeline renders the same image as the monolithic renderer.
    assert_eq!(rows[9][5..8], rows[1][5..8], "{csv}");
    // So does its adaptive run (staged, two rounds) as the monolithic adaptive sampler.
    assert_eq!(rows[10][5..8], rows[3][5..8], "{csv}");
    // The most accurate single-core point is on the front; every row says 0 or 1.
    assert_eq!(rows[2][8], "1", "{csv}");
    assert!(rows.iter().all(|r| r[8] == "0" || r[8] == "1"));
    for chart in ["eval.png", "eval-distributed.png"] {
        let png = std::fs::read(out.join(chart)).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{chart}");
        // IHDR: one 560 x 460 panel per scene.
        assert_eq!(&png[16..24], &[0, 0, 2, 48, 0, 0, 1, 204], "{chart}");
    }
    let err = stderr(&o);
    assert!(
        err.contains("cornell: ours at 64 spp: PSNR "),
        "the summary names our top setting: {err}"
    );
}

#[test]
fn a_missing_reference_and_a_wrong_size_are_refused_by_name() {
    let out = scratch("eval-bad");
    let empty = scratch("eval-bad-refs");
    std::fs::copy(fixtures().join("mitsuba.csv"), empty.join("mitsuba.csv")).unwrap();
    let o = eval(&out, &empty, "16", &["--spp", "1", "--skip-distributed"]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o).lines().last().unwrap(),
        format!(
            "error: reading the reference {}: No such file or directory",
            empty.join("cornell.pfm").display()
        )
    );
    let o = eval(
        &out,
        &fixtures(),
        "8",
        &["--spp", "1", "--skip-distributed"],
    );
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o).lines().last().unwrap(),
        format!(
            "error: {}: the reference is 16x12 but the sweep renders 8x12 (--width, --height)",
            fixtures().join("cornell.pfm").display()
        )
    );
    let o = eval(&out, &out, "16", &["--spp", "1"]);
    assert_eq!(
        stderr(&o).lines().last().unwrap(),
        format!(
            "error: reading {}: No such file or directory",
            out.join("mitsuba.csv").display()
        )
    );
    assert!(!out.join("eval.csv").exists());
}

/// Without `--out`, `hort eval` writes to `out/eval/` of the current folder, never over the
/// committed `docs/eval/`.
#[test]
fn the_default_output_folder_is_out_eval() {
    let cwd = scratch("eval-default-out");
    let cornell = scene("cornell/cornell.json");
    let o = std::process::Command::new(common::HORT)
        .current_dir(&cwd)
        .args(["eval", cornell.to_str().unwrap(), "--references"])
        .arg(fixtures())
        .args([
            "--width", "16", "--height", "12", "--spp", "1", "--runs", "1",
        ])
        .arg("--skip-distributed")
        .output()
        .expect("hort runs");
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(files_in(&cwd), ["out"]);
    assert_eq!(files_in(&cwd.join("out")), ["eval"]);
    assert_eq!(files_in(&cwd.join("out/eval")), ["eval.csv", "eval.png"]);
    std::fs::remove_dir_all(&cwd).unwrap();
}
