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

/// A 4-frame turntable rendered as one job (in-process, and in the emulator fused, staged over
/// two splits, and staged under injected failures and duplicate deliveries) writes every frame's PFM and hit buffer with the bytes of the monolithic
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
        (
            "faults",
            &[
                "--mode",
                "staged",
                "--splits",
                "2",
                "--fail-rate",
                "0.2",
                "--duplicate-rate",
                "0.2",
                "--seed",
                "7",
            ][..],
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
        // The emulator times each frame: ready when the task that finished it assembled it.
        if name != "inproc" {
            let total = report["seconds"]["total"].as_f64().unwrap();
            let (mut shadow, mut cost) = (0, 0.0);
            for frame in report["frames"].as_array().unwrap() {
                let ready = frame["ready_seconds"].as_f64().expect("a ready time");
                assert!(ready > 0.0 && ready <= total, "{name}: {frame}");
                assert_eq!(frame["rays"]["primary"], 40 * 30 * 4, "{name}: {frame}");
                assert!(frame["seconds"].as_f64().unwrap() > 0.0, "{name}: {frame}");
                shadow += frame["rays"]["shadow"].as_u64().unwrap();
                cost += frame["cost_usd"].as_f64().unwrap();
            }
            // The frames' shadow rays are the run's; their costs and the preparation's are
            // shares of the run's cost.
            assert_eq!(shadow, report["rays"]["shadow"].as_u64().unwrap(), "{name}");
            let preparation = &report["preparation"];
            cost += preparation["cost_usd"].as_f64().unwrap();
            let run_cost = report["cost_usd"].as_f64().unwrap();
            assert!(
                cost > 0.0 && cost <= run_cost * (1.0 + 1e-9),
                "{name}: {cost} of {run_cost}"
            );
            assert!(preparation["seconds"].as_f64().unwrap() > 0.0, "{name}");
        }
        if name == "faults" {
            let retried = report["retried_attempts"].as_u64().unwrap();
            assert!(retried > 0, "no fault was injected");
        }
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

/// `POST /renders` with `orbit` and `frames` renders the turntable in one job (its status lists
/// the frames, all done): each frame's
/// PNG (`GET /renders/{id}/frames/{k}/image`) is `hort render --frame k` of the same turntable,
/// byte for byte; a frame the job did not render is 404, and frames of a scene without an
/// animation are refused naming the field.
#[test]
fn the_api_renders_a_turntable_in_one_job_and_serves_each_frame() {
    use common::server::{Serve, cornell};
    use serde_json::json;
    let dir = scratch("frames-api");
    let server = Serve::start(&dir.join("data"));
    let body = json!({"scene": cornell(), "width": 32, "height": 24, "spp": 2,
                      "orbit": 90, "frames": 3});
    let accepted = server.post("/renders", &body, &[]);
    assert_eq!(accepted.status, 202, "{}", accepted.text());
    let job = accepted.json()["job"].as_str().unwrap().to_owned();
    let status = server.wait_done(&job, std::time::Duration::from_secs(120));
    assert_eq!(status["status"], "SUCCEEDED", "{status}");
    assert_eq!(status["frames"], json!([0, 1, 2]), "{status}");
    assert_eq!(status["frames_done"], 3, "{status}");
    let cornell_json = scene("cornell/cornell.json");
    for k in 0..3u32 {
        let reply = server.get(&format!("/renders/{job}/frames/{k}/image"));
        assert_eq!(reply.status, 200, "frame {k}: {}", reply.text());
        let out = dir.join(format!("cli_{k}.png"));
        let args = [
            "render",
            cornell_json.to_str().unwrap(),
            "--monolithic",
            "--width",
            "32",
            "--height",
            "24",
            "--spp",
            "2",
            "--orbit",
            "90",
            "--frames",
            "3",
            "--frame",
            &k.to_string(),
            "--out",
            out.to_str().unwrap(),
        ];
        let o = hort(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(
            reply.body == read(&out),
            "frame {k} differs from hort render --frame {k}"
        );
    }
    let missing = server.get(&format!("/renders/{job}/frames/3/image"));
    assert_eq!(missing.status, 404);
    assert_eq!(
        missing.json()["error"]["message"],
        format!("render {job} has no frame 3")
    );
    let still = json!({"scene": cornell(), "width": 32, "height": 24, "frames": 3});
    let refused = server.post("/renders", &still, &[]);
    assert_eq!(refused.status, 400, "{}", refused.text());
    assert_eq!(
        refused.json()["error"],
        json!({"code": "invalid_request", "field": "frames",
               "message": "frames: the scene has no animation; give orbit, or an \"animation\" in its manifest"})
    );
}

/// A manifest's camera keyframes: a run of frames 0 to 5 in one emulator job (staged over two
/// splits, the scene uploaded parsed, keyframes and all) writes the monolithic renderer's
/// frames byte for byte, and frame 3 alone in a fused job is frame 3 again; a keyframe whose
/// eye is its target is refused naming the keyframe.
#[test]
fn a_keyframed_camera_path_renders_the_same_frames_in_every_mode() {
    let dir = scratch("frames-keys");
    for file in ["teapot.obj", "ground.obj", "ground.mtl"] {
        std::fs::copy(scene(&format!("teapot/{file}")), dir.join(file)).unwrap();
    }
    let manifest = |third_eye: &str| {
        format!(
            r#"{{"meshes": ["ground.obj", "teapot.obj"],
               "camera": {{"eye": [8, 18, 45], "look_at": [3, -2, 0]}},
               "animation": {{"frames": 6, "keyframes": [
                 {{"frame": 0, "eye": [8, 18, 45], "look_at": [3, -2, 0]}},
                 {{"frame": 2, "eye": [30, 12, 30], "look_at": [3, 0, 0], "vfov": 40}},
                 {{"frame": 5, "eye": {third_eye}, "look_at": [0, 2, 0]}}]}}}}"#
        )
    };
    let path = dir.join("keys.json");
    std::fs::write(&path, manifest("[-20, 25, 35]")).unwrap();
    let run = |name: &str, extra: &[&str]| {
        let mut args = vec![
            "render",
            path.to_str().unwrap(),
            "--width",
            "40",
            "--height",
            "30",
            "--spp",
            "2",
        ];
        let (out, hits) = (
            dir.join(format!("{name}_#.pfm")),
            dir.join(format!("{name}_#.bin")),
        );
        let (out, hits) = (
            out.to_str().unwrap().to_owned(),
            hits.to_str().unwrap().to_owned(),
        );
        args.extend(["--out", &out, "--hits", &hits]);
        args.extend_from_slice(extra);
        let o = hort(&args);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
    };
    run("mono", &["--monolithic", "--frames", "6"]);
    run(
        "staged",
        &["--frames", "0..6", "--mode", "staged", "--splits", "2"],
    );
    run("alone", &["--frame", "3", "--mode", "fused"]);
    for k in 0..6 {
        for ext in ["pfm", "bin"] {
            let reference = read(&dir.join(format!("mono_{k}.{ext}")));
            assert!(
                read(&dir.join(format!("staged_{k}.{ext}"))) == reference,
                "frame {k} {ext}"
            );
        }
    }
    assert!(read(&dir.join("alone_3.pfm")) == read(&dir.join("mono_3.pfm")));
    assert!(read(&dir.join("mono_1.pfm")) != read(&dir.join("mono_2.pfm")));
    std::fs::write(&path, manifest("[0, 2, 0]")).unwrap();
    let o = hort(&[
        "render",
        path.to_str().unwrap(),
        "--monolithic",
        "--frames",
        "6",
    ]);
    assert!(!o.status.success());
    assert_eq!(
        stderr(&o),
        format!(
            "error: {}: manifest field `animation.keyframes[2]`: eye and look_at are the same \
             point\n",
            path.display()
        )
    );
}

/// `POST /renders` with an inline `animation` (world coordinates, as a manifest's) renders the
/// frames of the same scene with that animation in its manifest, byte for byte; a malformed
/// keyframe is refused naming its field, and an animation with an orbit is refused.
#[test]
fn the_api_takes_camera_keyframes_in_the_request() {
    use common::server::{Serve, cornell};
    use serde_json::json;
    let dir = scratch("frames-api-keys");
    let animation = json!({"frames": 3, "keyframes": [
        {"frame": 0, "eye": [2.78, 2.744, -6.0], "look_at": [2.78, 2.4, 5.592]},
        {"frame": 2, "eye": [4.5, 3.5, -5.0], "look_at": [2.78, 2.4, 5.592], "vfov": 40}]});
    for file in ["cornell.obj", "cornell.mtl"] {
        std::fs::copy(scene(&format!("cornell/{file}")), dir.join(file)).unwrap();
    }
    let mut manifest: serde_json::Value =
        serde_json::from_slice(&read(&scene("cornell/cornell.json"))).unwrap();
    manifest["animation"] = animation.clone();
    let manifest_path = dir.join("animated.json");
    std::fs::write(&manifest_path, manifest.to_string()).unwrap();
    let server = Serve::start(&dir.join("data"));
    let body = json!({"scene": cornell(), "width": 24, "height": 16, "frames": 3,
                      "animation": animation});
    let accepted = server.post("/renders", &body, &[]);
    assert_eq!(accepted.status, 202, "{}", accepted.text());
    let job = accepted.json()["job"].as_str().unwrap().to_owned();
    let status = server.wait_done(&job, std::time::Duration::from_secs(120));
    assert_eq!(status["status"], "SUCCEEDED", "{status}");
    let out = dir.join("cli_#.png");
    let o = hort(&[
        "render",
        manifest_path.to_str().unwrap(),
        "--monolithic",
        "--width",
        "24",
        "--height",
        "16",
        "--frames",
        "3",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    for k in 0..3 {
        let reply = server.get(&format!("/renders/{job}/frames/{k}/image"));
        assert_eq!(reply.status, 200, "frame {k}");
        assert!(
            reply.body == read(&dir.join(format!("cli_{k}.png"))),
            "frame {k}"
        );
    }
    let mut bad = body.clone();
    bad["animation"]["keyframes"][1]["eye"] = json!([2.78, 2.4, 5.592]);
    let refused = server.post("/renders", &bad, &[]);
    assert_eq!(refused.status, 400, "{}", refused.text());
    assert_eq!(
        refused.json()["error"],
        json!({"code": "invalid_request", "field": "animation.keyframes[1]",
               "message": "animation.keyframes[1]: eye and look_at are the same point"})
    );
    let mut both = body;
    both["orbit"] = json!(90);
    let refused = server.post("/renders", &both, &[]);
    assert_eq!(refused.status, 400, "{}", refused.text());
    assert_eq!(
        refused.json()["error"]["message"],
        "animation: give one camera path, an orbit or keyframes"
    );
}
