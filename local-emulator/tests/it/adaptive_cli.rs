//! `hort render --adaptive`: the same bytes monolithic, in process and through the emulator
//! (fused), the settings and decisions in the report, each skip reported (no lights, lights no
//! surface can occlude, background pixels; staged jobs without shadow rays run no expand or
//! trace-map stage), and one-line errors.

use crate::common;

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
    let staged_flags = ["--mode", "staged", "--splits", "2", "--spans", "3"];
    let (staged, staged_report) = render(&dir, "staged", &staged_flags);
    let mut inproc_staged_flags = vec!["--in-process"];
    inproc_staged_flags.extend_from_slice(&staged_flags);
    let (inproc_staged, inproc_staged_report) = render(&dir, "inproc-staged", &inproc_staged_flags);
    assert_eq!(inproc, mono, "in process");
    assert_eq!(emu, mono, "emulator");
    assert_eq!(staged, mono, "emulator, staged");
    assert_eq!(inproc_staged, mono, "in process, staged");
    // Staged: a second round ran (the refine row), its tasks counted in the stages' rows.
    for report in [&staged_report, &inproc_staged_report] {
        let stages: Vec<(&str, u64)> = report["stages"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| (s["name"].as_str().unwrap(), s["tasks"].as_u64().unwrap()))
            .collect();
        let names: Vec<&str> = stages.iter().map(|s| s.0).collect();
        assert_eq!(
            names,
            [
                "plan",
                "cast-map",
                "cast-reduce",
                "expand",
                "trace-map",
                "trace-reduce",
                "refine",
                "combine"
            ]
        );
        // 3 spans in round 1, and a second round for the spans with refined pixels.
        assert!(stages[2].1 > 3 && stages[2].1 <= 6, "{stages:?}");
    }
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
    for (what, report) in [
        ("in process", &inproc_report),
        ("emulator", &emu_report),
        ("emulator, staged", &staged_report),
        ("in process, staged", &inproc_staged_report),
    ] {
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
fn bad_adaptive_settings_get_one_error_line() {
    let teapot = scene("teapot/teapot.json");
    let teapot = teapot.to_str().unwrap();
    let size = ["--width", "64", "--height", "48"];
    for (extra, message) in [
        (
            &["--monolithic", "--spp", "1", "--adaptive", "16"][..],
            "error: --spp, --adaptive and --adaptive-threshold: adaptive base spp = 1 is out of \
             range: must be from 2 (a pixel's error estimate needs two samples) to 65535; add \
             --spp 4 (--adaptive 16 --spp 4: 4 samples in every pixel, then 16 where needed)\n",
        ),
        (
            // The default --spp 1 (no --spp given), and a MAX_SPP that leaves room for only 2.
            &["--monolithic", "--adaptive", "3"][..],
            "error: --spp, --adaptive and --adaptive-threshold: adaptive base spp = 1 is out of \
             range: must be from 2 (a pixel's error estimate needs two samples) to 65535; add \
             --spp 2 (--adaptive 3 --spp 2: 2 samples in every pixel, then 3 where needed)\n",
        ),
        (
            &["--monolithic", "--spp", "4", "--adaptive", "4"][..],
            "error: --spp, --adaptive and --adaptive-threshold: adaptive max spp = 4 is out of \
             range: must be above the base spp 4 and at most 65536\n",
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
    ] {
        let mut args = vec!["render", teapot];
        args.extend_from_slice(&size);
        args.extend_from_slice(extra);
        let o = hort(&args);
        assert_eq!(o.status.code(), Some(1), "{extra:?}");
        assert_eq!(stderr(&o), message, "{extra:?}");
    }
}

/// Renders `dir/{scene}` at 32x24, 4 spp, with `extra` flags; returns the PFM bytes, the report
/// and standard error.
fn render_small(
    dir: &std::path::Path,
    scene: &str,
    name: &str,
    extra: &[&str],
) -> (Vec<u8>, serde_json::Value, String) {
    let (out, report) = (
        dir.join(format!("{name}.pfm")),
        dir.join(format!("{name}.json")),
    );
    let scene = dir.join(scene);
    let mut args = vec![
        "render",
        scene.to_str().unwrap(),
        "--width",
        "32",
        "--height",
        "24",
        "--spp",
        "4",
        "--out",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = hort(&args);
    assert!(o.status.success(), "{name}: {}", stderr(&o));
    let report = serde_json::from_slice(&std::fs::read(report).unwrap()).unwrap();
    (std::fs::read(out).unwrap(), report, stderr(&o))
}

fn stage_names(report: &serde_json::Value) -> Vec<&str> {
    report["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect()
}

#[test]
fn a_staged_job_without_lights_skips_expand_and_trace_map_and_keeps_the_image() {
    let dir = scratch("staged-dark");
    std::fs::write(
        dir.join("quads.obj"),
        "v -1 -1 0\nv 0 -1 0\nv 0 1 0\nv -1 1 0\nv 0 -1 -0.5\nv 1 -1 -0.5\nv 1 1 -0.5\n\
         v 0 1 -0.5\nf 1 2 3\nf 1 3 4\nf 5 6 7\nf 5 7 8\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("dark.json"),
        r#"{"meshes": ["quads.obj"], "lights": [], "ambient": 0.5,
            "camera": {"eye": [0, 0, 3], "look_at": [0, 0, 0]}}"#,
    )
    .unwrap();
    let (mono, _, _) = render_small(&dir, "dark.json", "mono", &["--monolithic"]);
    let (staged, report, err) = render_small(
        &dir,
        "dark.json",
        "staged",
        &["--mode", "staged", "--splits", "2"],
    );
    assert_eq!(staged, mono);
    let skip = "the scene has no lights: no shadow rays traced, no expand or trace-map stages";
    assert!(err.contains(&format!("skipped: {skip}\n")), "{err}");
    assert_eq!(report["skips"], serde_json::json!([skip]));
    assert_eq!(
        stage_names(&report),
        ["plan", "cast-map", "cast-reduce", "trace-reduce", "combine"]
    );
    assert_eq!(report["rays"]["shadow"], 0);
    std::fs::remove_dir_all(dir).unwrap();
}

/// Inside a closed box with the light inside, no surface can occlude the light: its shadow
/// rays are skipped everywhere (a staged job runs no expand or trace-map stage), and every
/// mode still gives the monolithic bytes.
#[test]
fn a_light_no_surface_can_occlude_traces_no_shadow_rays_in_any_mode() {
    let dir = scratch("unoccludable");
    std::fs::write(
        dir.join("room.obj"),
        "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\n\
         v -1 1 1\nf 1 2 3\nf 1 3 4\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 3 7\n\
         f 4 7 8\nf 1 4 8\nf 1 8 5\nf 2 3 7\nf 2 7 6\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("room.json"),
        r#"{"meshes": ["room.obj"],
            "camera": {"eye": [0.2, -0.3, 0.9], "look_at": [-0.4, 0.1, -1]},
            "lights": [{"kind": "point", "position": [0.3, 0.6, 0.2], "intensity": 2.0}]}"#,
    )
    .unwrap();
    let skip = "no surface can occlude light 0: its shadow rays are not traced";
    let (mono, mono_report, err) = render_small(&dir, "room.json", "mono", &["--monolithic"]);
    assert!(err.contains(&format!("skipped: {skip}\n")), "{err}");
    assert_eq!(mono_report["skips"], serde_json::json!([skip]));
    let (fused, fused_report, _) = render_small(&dir, "room.json", "fused", &["--mode", "fused"]);
    assert_eq!(fused, mono, "fused");
    assert_eq!(fused_report["skips"], serde_json::json!([skip]));
    let (staged, report, _) = render_small(
        &dir,
        "room.json",
        "staged",
        &["--mode", "staged", "--splits", "2"],
    );
    assert_eq!(staged, mono, "staged");
    assert_eq!(
        report["skips"],
        serde_json::json!([
            skip,
            "no light can be occluded: no expand or trace-map stages"
        ])
    );
    assert_eq!(
        stage_names(&report),
        ["plan", "cast-map", "cast-reduce", "trace-reduce", "combine"]
    );
    std::fs::remove_dir_all(dir).unwrap();
}
