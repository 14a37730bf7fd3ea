//! `hort render --adaptive`: the same bytes monolithic, in process and through the emulator
//! (fused), the settings and decisions in the report, each skip reported, and one-line errors.

mod common;

use common::{hort, scene, scratch, stderr};

fn render(dir: &std::path::Path, name: &str, extra: &[&str]) -> (Vec<u8>, serde_json::Value) {
    let scene = scene("teapot/teapot.json");
    let (out, report) = (
        dir.join(format!("{name}.pfm")),
        dir.join(format!("{name}.json")),
    );
    let mut args = vec![
        "render",
        scene.to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "48",
        "--spp",
        "4",
        "--adaptive",
        "16",
        "--adaptive-threshold",
        "0.01",
        "--out",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = hort(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let background = "skipped: 945 pixels saw only background in the first pass: no extra samples";
    assert!(stderr(&o).contains(background), "{name}: {}", stderr(&o));
    let report = serde_json::from_slice(&std::fs::read(report).unwrap()).unwrap();
    (std::fs::read(out).unwrap(), report)
}

#[test]
fn adaptive_renders_agree_across_modes_and_report_their_decisions() {
    let dir = scratch("adaptive-modes");
    let (mono, mono_report) = render(&dir, "mono", &["--monolithic", "--threads", "2"]);
    let (inproc, inproc_report) = render(
        &dir,
        "inproc",
        &["--in-process", "--splits", "1", "--spans", "3"],
    );
    let (emu, emu_report) = render(&dir, "emu", &["--splits", "1", "--spans", "5"]);
    assert_eq!(inproc, mono, "in process");
    assert_eq!(emu, mono, "emulator");
    let adaptive = &mono_report["adaptive"];
    assert_eq!(
        adaptive["settings"],
        serde_json::json!({"base_spp": 4, "max_spp": 16, "threshold": 0.01})
    );
    let counts = &adaptive["counts"];
    let pixels = 64 * 48;
    let (refined, background, converged) = (
        counts["refined_pixels"].as_u64().unwrap(),
        counts["background_pixels"].as_u64().unwrap(),
        counts["converged_pixels"].as_u64().unwrap(),
    );
    assert_eq!(refined + background + converged, pixels);
    assert!(refined > 0 && converged > 0, "{counts}");
    assert_eq!(background, 945);
    assert_eq!(
        counts["samples"],
        serde_json::json!(pixels * 4 + refined * 12)
    );
    assert_eq!(mono_report["rays"]["primary"], counts["samples"]);
    assert_eq!(mono_report["spp"], 4);
    for (what, report) in [("in process", &inproc_report), ("emulator", &emu_report)] {
        assert_eq!(&report["adaptive"], adaptive, "{what}");
        assert_eq!(report["rays"], mono_report["rays"], "{what}");
        assert_eq!(report["skips"], mono_report["skips"], "{what}");
    }
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn a_scene_without_lights_reports_the_skipped_shadow_rays() {
    let dir = scratch("adaptive-dark");
    std::fs::write(
        dir.join("tri.obj"),
        "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("dark.json"),
        r#"{"meshes": ["tri.obj"], "lights": [], "ambient": 0.5,
            "camera": {"eye": [0, 0, 3], "look_at": [0, 0, 0]}}"#,
    )
    .unwrap();
    let report = dir.join("r.json");
    let o = hort(&[
        "render",
        dir.join("dark.json").to_str().unwrap(),
        "--monolithic",
        "--width",
        "16",
        "--height",
        "12",
        "--out",
        dir.join("o.png").to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("skipped: the scene has no lights: no shadow rays traced\n"),
        "{}",
        stderr(&o)
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(report).unwrap()).unwrap();
    assert_eq!(
        report["skips"],
        serde_json::json!(["the scene has no lights: no shadow rays traced"])
    );
    assert_eq!(report["rays"]["shadow"], 0);
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn bad_adaptive_settings_and_staged_jobs_get_one_error_line() {
    let teapot = scene("teapot/teapot.json");
    let teapot = teapot.to_str().unwrap();
    let size = ["--width", "64", "--height", "48"];
    for (extra, message) in [
        (
            &["--monolithic", "--spp", "5", "--adaptive", "16"][..],
            "error: --spp, --adaptive and --adaptive-threshold: adaptive base spp = 5 is out of \
             range: must be a power of 4 from 4 to 16384 (4, 16, 64, 256, ...)\n",
        ),
        (
            &["--monolithic", "--spp", "4", "--adaptive", "32"][..],
            "error: --spp, --adaptive and --adaptive-threshold: adaptive max spp = 32 is out of \
             range: must be a power of 4 above the base spp 4 and at most 65536\n",
        ),
        (
            &[
                "--monolithic",
                "--spp",
                "4",
                "--adaptive",
                "16",
                "--adaptive-threshold",
                "-1",
            ][..],
            "error: --spp, --adaptive and --adaptive-threshold: adaptive threshold = -1 is out \
             of range: must be a finite number above 0\n",
        ),
        (
            &[
                "--in-process",
                "--spp",
                "4",
                "--adaptive",
                "16",
                "--splits",
                "2",
            ][..],
            "error: --adaptive runs in fused mode only, and this job would run staged \
             (--splits 2: HORT's staged shuffle over 2 splits); use --splits 1 or --mode fused\n",
        ),
    ] {
        let mut args = vec!["render", teapot];
        args.extend_from_slice(&size);
        args.extend_from_slice(extra);
        let o = hort(&args);
        assert_eq!(o.status.code(), Some(1), "{extra:?}");
        assert_eq!(stderr(&o), message, "{extra:?}");
    }
}
