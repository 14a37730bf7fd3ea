//! Frames of a camera path (`--frames`, `--frame`, `--orbit`): frame K is the same image
//! whichever way it is rendered, and malformed frame requests are refused before any work.

use crate::common;

use common::{files_in, hort, scene, scratch, stderr};
use std::path::Path;

/// Renders the teapot at 40x30, 4 spp, with `extra` flags; panics with standard error if the
/// command fails.
fn render(out: &Path, hits: &Path, extra: &[&str]) {
    let teapot = scene("teapot/teapot.json");
    let mut args = vec![
        "render",
        teapot.to_str().unwrap(),
        "--width",
        "40",
        "--height",
        "30",
        "--spp",
        "4",
        "--out",
        out.to_str().unwrap(),
        "--hits",
        hits.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = hort(&args);
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
}

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A 4-frame turntable rendered as one job (in-process, and in the emulator fused and staged
/// over two splits) writes every frame's PFM and hit buffer with the bytes of the monolithic
/// renderer's frames; frame 2 rendered alone (`--frame 2`) in the emulator is frame 2 again;
/// frame 0 is the still image, and the frames differ from one another. The job's report lists
/// the frames and counts the rays of all four.
#[test]
fn a_turntable_frame_is_the_same_image_alone_and_in_a_run_in_every_mode() {
    let dir = scratch("frames-orbit");
    let turn = ["--orbit", "360", "--frames", "4"];
    let frame_files = |prefix: &str| -> Vec<Vec<u8>> {
        (0..4)
            .flat_map(|k| {
                [
                    format!("{prefix}_{k:02}.pfm"),
                    format!("{prefix}_{k:02}.bin"),
                ]
            })
            .map(|name| read(&dir.join(name)))
            .collect()
    };
    let mut all = vec!["--monolithic"];
    all.extend_from_slice(&turn);
    render(&dir.join("mono_##.pfm"), &dir.join("mono_##.bin"), &all);
    let reference = frame_files("mono");
    for (name, mode) in [
        ("inproc", &["--in-process"][..]),
        ("fused", &["--mode", "fused", "--workers", "2"][..]),
        (
            "staged",
            &["--mode", "staged", "--splits", "2", "--workers", "2"][..],
        ),
    ] {
        let report = dir.join(format!("{name}.json"));
        let mut args = vec!["--report", report.to_str().unwrap()];
        args.extend_from_slice(&turn);
        args.extend_from_slice(mode);
        let pattern = |ext: &str| dir.join(format!("{name}_##.{ext}"));
        render(&pattern("pfm"), &pattern("bin"), &args);
        assert!(frame_files(name) == reference, "{name}: the frames differ");
        let report: serde_json::Value = serde_json::from_slice(&read(&report)).unwrap();
        let listed: Vec<u64> = report["frames"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f["frame"].as_u64().unwrap())
            .collect();
        assert_eq!(listed, [0, 1, 2, 3], "{name}");
        assert_eq!(report["rays"]["primary"], 4 * 40 * 30 * 4, "{name}");
    }
    let (out, hit) = (dir.join("alone.pfm"), dir.join("alone.bin"));
    let mut alone = vec!["--frame", "2", "--mode", "staged", "--splits", "2"];
    alone.extend_from_slice(&turn);
    render(&out, &hit, &alone);
    assert!(
        read(&out) == reference[4] && read(&hit) == reference[5],
        "frame 2 alone"
    );
    let (still, still_hits) = (dir.join("still.pfm"), dir.join("still.bin"));
    render(&still, &still_hits, &["--monolithic"]);
    assert!(read(&still) == reference[0], "frame 0 is the still image");
    assert!(read(&still_hits) == reference[1]);
    assert!(reference[2] != reference[4], "frames 1 and 2 differ");
}

/// Each malformed frame request fails before any work with one line naming the flag.
#[test]
fn malformed_frame_requests_are_refused_before_any_work() {
    let dir = scratch("frames-bad");
    let teapot = scene("teapot/teapot.json");
    let out = dir.join("o.png");
    let cases: [(&[&str], &str); 5] = [
        (
            &["--frames", "3"],
            "error: --frames/--frame: the scene has no animation; give --orbit DEGREES, or an \"animation\" in its manifest",
        ),
        (
            &["--frames", "3", "--orbit", "90"],
            &format!(
                "error: --out {}: 3 frames need a `#` run in the file name for the frame number (for example {})",
                out.display(),
                dir.join("o_####.png").display()
            ),
        ),
        (
            &["--frames", "4", "--orbit", "90", "--frame", "4"],
            "error: --frames/--frame: frame 4 is outside the animation's 4 frames (0 to 3)",
        ),
        (
            &["--frames", "5..5", "--orbit", "90"],
            "error: invalid value '5..5' for '--frames <N|A..B>': `5..5` holds no frame",
        ),
        (
            &["--frames", "4", "--orbit", "inf"],
            "error: --orbit inf: the turn must be a finite number of degrees",
        ),
    ];
    for (extra, expected) in cases {
        let mut args = vec![
            "render",
            teapot.to_str().unwrap(),
            "--monolithic",
            "--width",
            "8",
            "--height",
            "6",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = hort(&args);
        assert!(!o.status.success(), "{extra:?} succeeded");
        let text = stderr(&o);
        assert_eq!(
            text.lines().next().unwrap_or(""),
            expected,
            "{extra:?}: {text}"
        );
        assert!(
            files_in(&dir).is_empty(),
            "{extra:?} wrote {:?}",
            files_in(&dir)
        );
    }
}
