//! `hort plan`: the JSON contract and its consistency, the figures that follow from the cost
//! constants, the model's monotonic behaviour, the errors for bad flags, and that the plan is
//! the one `hort render` runs.

use crate::common;

use common::{hort, scene, stderr};
use hort_core::cost::{
    LAMBDA_USD_PER_MILLION_REQUESTS, S3_USD_PER_1000_GET_LIKE, S3_USD_PER_1000_PUT_LIKE,
};
use serde_json::Value;

/// `hort plan` with `args` and `--json`, parsed; fails the test on an error.
fn plan_json(args: &[&str]) -> Value {
    let mut all = vec!["plan"];
    all.extend_from_slice(args);
    all.push("--json");
    let o = hort(&all);
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_slice(&o.stdout).expect("one JSON object")
}

/// The Cornell box at 64x48, 2 spp, with the flags given.
fn cornell(extra: &[&str]) -> Value {
    cornell_at("64", "48", extra)
}

/// The Cornell box at `width` x `height`, 2 spp, with the flags given.
fn cornell_at(width: &str, height: &str, extra: &[&str]) -> Value {
    let path = scene("cornell/cornell.json");
    let mut args = vec![
        path.to_str().unwrap(),
        "--width",
        width,
        "--height",
        height,
        "--spp",
        "2",
    ];
    args.extend_from_slice(extra);
    plan_json(&args)
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

fn u(v: &Value) -> u64 {
    v.as_u64().unwrap_or_else(|| panic!("not an integer: {v}"))
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 + 1e-9 * b.abs()
}

#[test]
fn json_has_the_contract_fields_and_they_agree() {
    let o = cornell(&["--splits", "2", "--spans", "3"]);
    assert_eq!(o["mode"], "staged");
    assert_eq!(u(&o["splits"]), 2);
    assert_eq!(u(&o["spans"]), 3);
    let stages = o["stages"].as_array().unwrap();
    let names: Vec<&str> = stages.iter().map(|s| s["name"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        [
            "plan",
            "cast-map",
            "cast-reduce",
            "expand",
            "trace-map",
            "trace-reduce",
            "combine"
        ]
    );
    // Tasks per stage as the plan has them: one plan and one combine, s per reduce stage,
    // s x k trace-map pairs, at most s x k cast-map pairs.
    let tasks = |name: &str| u(&stages.iter().find(|s| s["name"] == name).unwrap()["tasks"]);
    assert_eq!(tasks("plan"), 1);
    assert_eq!(tasks("combine"), 1);
    for name in ["cast-reduce", "expand", "trace-reduce"] {
        assert_eq!(tasks(name), 3, "{name}");
    }
    assert_eq!(tasks("trace-map"), 6);
    assert!((1..=6).contains(&tasks("cast-map")));
    let sum: u64 = stages.iter().map(|s| u(&s["tasks"])).sum();
    assert_eq!(u(&o["tasks"]), sum);
    // The Combine stage of `hort render`'s default output stores the PNG only: 4 bytes per pixel
    // before compression.
    let combine = stages.iter().find(|s| s["name"] == "combine").unwrap();
    assert_eq!(u(&combine["bytes"]), 64 * 48 * 4);
    let sweep: Vec<u64> = o["projection"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| u(&p["functions"]))
        .collect();
    assert_eq!(sweep, [10, 100, 1000, 10000]);
    for p in o["projection"].as_array().unwrap() {
        assert!(f(&p["seconds"]) > 0.0 && f(&p["dollars"]) > 0.0, "{p}");
        // Every projection runs the same stages with the same tasks.
        let t: Vec<u64> = p["stages"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| u(&s["tasks"]))
            .collect();
        let want: Vec<u64> = stages.iter().map(|s| u(&s["tasks"])).collect();
        assert_eq!(t, want);
    }
    // No --functions: the chosen count is the best of the sweep, and its projection is there.
    assert_eq!(o["functions_is_best"], true);
    let chosen = u(&o["functions"]);
    assert!(sweep.contains(&chosen));
}

#[test]
fn dollars_follow_from_the_cost_constants() {
    for fail_rate in ["0", "0.5"] {
        let o = cornell(&[
            "--splits",
            "2",
            "--spans",
            "3",
            "--functions",
            "4",
            "--fail-rate",
            fail_rate,
        ]);
        let p = &o["chosen"];
        assert_eq!(u(&p["functions"]), 4);
        let cost = &p["cost"];
        let lines = [
            "lambda_compute",
            "lambda_requests",
            "s3_requests",
            "s3_storage",
        ];
        let sum: f64 = lines.iter().map(|l| f(&cost[l])).sum::<f64>() + f(&cost["step_functions"]);
        assert!(close(f(&cost["total"]), sum), "{cost}");
        assert!(close(f(&p["dollars"]), f(&cost["total"])));
        // One invocation per attempt: 1 / (1 - P) attempts per worker and plan task.
        let attempts = 1.0 / (1.0 - fail_rate.parse::<f64>().unwrap());
        let tasks = u(&o["tasks"]) as f64;
        assert!(
            close(
                f(&cost["lambda_requests"]),
                tasks * attempts * LAMBDA_USD_PER_MILLION_REQUESTS / 1e6
            ),
            "{cost}"
        );
        let requests = u(&p["s3_gets"]) as f64 * S3_USD_PER_1000_GET_LIKE / 1000.0
            + u(&p["s3_puts"]) as f64 * S3_USD_PER_1000_PUT_LIKE / 1000.0;
        assert!(close(f(&cost["s3_requests"]), requests), "{cost}");
    }
}

#[test]
fn retries_multiply_the_billed_work() {
    let args = ["--splits", "2", "--spans", "3", "--functions", "4"];
    let clean = cornell(&args);
    let mut failing = args.to_vec();
    failing.extend_from_slice(&["--fail-rate", "0.5"]);
    let failing = cornell(&failing);
    let fs = |o: &Value| f(&o["chosen"]["function_seconds"]);
    assert!(close(fs(&failing), 2.0 * fs(&clean)));
    assert!(f(&failing["chosen"]["seconds"]) > f(&clean["chosen"]["seconds"]));
}

#[test]
fn more_functions_never_take_longer_below_the_scaling_ramp() {
    // 100 spans x 4 splits: 400 trace-map tasks, below the 1,000 environments Lambda starts
    // at once, so the sweep's seconds can only fall or stay.
    let o = cornell_at("512", "512", &["--splits", "4", "--spans", "100"]);
    let seconds: Vec<f64> = o["projection"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| f(&p["seconds"]))
        .collect();
    for pair in seconds.windows(2) {
        assert!(pair[1] <= pair[0], "{seconds:?}");
    }
    assert!(
        seconds[1] < seconds[0],
        "100 functions beat 10: {seconds:?}"
    );
    // Beyond the widest stage nothing changes.
    assert_eq!(seconds[2], seconds[3]);
}

#[test]
fn memory_below_one_vcpu_stretches_compute_and_above_gains_nothing() {
    let task = |memory: &str| {
        let o = cornell(&["--mode", "fused", "--spans", "2", "--memory-mb", memory]);
        let stages = o["stages"].as_array().unwrap().clone();
        let render = stages.iter().find(|s| s["name"] == "render").unwrap();
        f(&render["task_seconds"])
    };
    let (half, full, double) = (task("885"), task("1769"), task("3538"));
    assert!(half > full, "{half} {full}");
    assert_eq!(full, double);
}

#[test]
fn over_a_thousand_functions_at_once_need_a_quota_raise() {
    let o = cornell_at(
        "256",
        "256",
        &["--splits", "4", "--spans", "500", "--functions", "2000"],
    );
    let notes: Vec<&str> = o["chosen"]["notes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    assert!(
        notes.contains(
            &"2000 functions at once exceed the default Lambda concurrency of 1000 per Region: \
              ask for a quota raise"
        ),
        "{notes:?}"
    );
}

#[test]
fn text_output_states_the_plan() {
    let path = scene("cornell/cornell.json");
    let o = hort(&[
        "plan",
        path.to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "48",
        "--spp",
        "2",
        "--splits",
        "2",
        "--spans",
        "3",
        "--functions",
        "10",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    let json = cornell(&["--splits", "2", "--spans", "3"]);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines[0],
        format!(
            "plan: {}, 64x48, 2 spp, {} triangles, 1 light",
            path.display(),
            json["triangles"]
        )
    );
    assert_eq!(
        lines[2],
        format!("splits: 2 (spatial), spans: 3, tasks: {}", json["tasks"])
    );
    assert!(
        lines[4].starts_with("target: AWS Lambda arm64 2048 MB"),
        "{text}"
    );
    assert!(text.contains("\nstages at 10 functions:\n"), "{text}");
    // The cost is a prediction, and says so (`hort render`'s is measured).
    let total = lines.iter().position(|l| l.starts_with("total: ")).unwrap();
    assert_eq!(
        lines[total + 1],
        "cost: predicted from the model above, not measured (`hort render` prices a run's task \
         times on this machine and its requests, so the two differ)"
    );
}

#[test]
fn bad_flags_get_one_line_naming_them() {
    let first_line = |args: &[&str]| {
        let o = hort(args);
        assert!(!o.status.success());
        stderr(&o).lines().next().unwrap_or("").to_owned()
    };
    let cornell = scene("cornell/cornell.json");
    let c = cornell.to_str().unwrap();
    assert_eq!(
        first_line(&["plan", c, "--functions", "0"]),
        "error: invalid value '0' for '--functions <FUNCTIONS>': 0 is not in 1..=10000"
    );
    assert_eq!(
        first_line(&["plan", c, "--arch", "sparc"]),
        "error: invalid value 'sparc' for '--arch <ARCH>'"
    );
    assert_eq!(
        first_line(&["plan", "no-such-scene.obj"]),
        "error: cannot read no-such-scene.obj: No such file or directory"
    );
    assert_eq!(
        first_line(&["plan", c, "--fail-rate", "1"]),
        "error: --fail-rate 1 is not a probability from 0 to below 1"
    );
    assert_eq!(
        first_line(&["plan", c, "--s3-latency-ms", "20"]),
        "error: --s3-latency-ms applies to --target emulator only (AWS is projected at S3's \
         own first-byte latency)"
    );
}

#[test]
fn the_plan_is_the_one_render_runs() {
    for (rel, extra) in [
        (
            "cornell/cornell.json",
            &["--splits", "2", "--spans", "3"][..],
        ),
        ("bunny/bunny.json", &[][..]),
        ("teapot/teapot.json", &["--memory-mb", "128"][..]),
    ] {
        let path = scene(rel);
        let p = path.to_str().unwrap();
        let mut args = vec![p, "--width", "48", "--height", "32"];
        args.extend_from_slice(extra);
        let planned = plan_json(&args);
        let dir = common::scratch(&format!("plan-{}", rel.replace('/', "-")));
        let out = dir.join("o.png");
        let mut render = vec!["render"];
        render.extend_from_slice(&args);
        render.extend_from_slice(&["--in-process", "--out", out.to_str().unwrap()]);
        render.extend_from_slice(&["--report", "-"]);
        let o = hort(&render);
        assert!(o.status.success(), "{}", stderr(&o));
        let report: Value = serde_json::from_slice(&o.stdout).expect("the report");
        assert_eq!(planned["mode"], report["execution"], "{rel}");
        assert_eq!(planned["mode_reason"], report["execution_reason"], "{rel}");
        assert_eq!(planned["splits"], report["splits"], "{rel}");
        assert_eq!(planned["spans"], report["spans"], "{rel}");
        // The split objects' build preset: fast below 4 camera samples per triangle (bunny's
        // 3,676 and the teapot's 994 triangles at 48x32), quality above (Cornell's 36).
        let fast = 48 * 32 < 4 * u(&report["triangles"]);
        assert_eq!(
            report["bvh_build"],
            if fast { "fast" } else { "quality" },
            "{rel}"
        );
        let tasks = |stages: &Value| -> Vec<(String, u64)> {
            stages
                .as_array()
                .unwrap()
                .iter()
                .map(|s| (s["name"].as_str().unwrap().to_owned(), u(&s["tasks"])))
                .collect()
        };
        assert_eq!(tasks(&planned["stages"]), tasks(&report["stages"]), "{rel}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// `--chart` plans every scene given (each printed as without it) and draws their projected
/// time and dollars against the function count into one PNG; several scenes need it.
#[test]
fn a_chart_draws_every_scene_and_several_scenes_need_it() {
    let dir = common::scratch("plan-chart");
    let (cornell, teapot) = (scene("cornell/cornell.json"), scene("teapot/teapot.json"));
    let (cornell, teapot) = (cornell.to_str().unwrap(), teapot.to_str().unwrap());
    let png = dir.join("projection.png");
    let size = ["--width", "64", "--height", "48"];
    let mut args = vec!["plan", cornell, teapot, "--chart", png.to_str().unwrap()];
    args.extend_from_slice(&size);
    let o = hort(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(out.matches("\nsweep:\n").count(), 2, "{out}");
    assert!(out.contains(&format!("plan: {cornell}, 64x48")), "{out}");
    assert!(out.contains(&format!("plan: {teapot}, 64x48")), "{out}");
    assert_eq!(stderr(&o), format!("wrote {}\n", png.display()));
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    // IHDR: two 620 x 460 panels.
    assert_eq!(&bytes[16..24], &[0, 0, 4, 216, 0, 0, 1, 204]);
    let mut args = vec!["plan", cornell, teapot];
    args.extend_from_slice(&size);
    let o = hort(&args);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o),
        "error: several scenes are planned together only for a chart: add --chart FILE.png\n"
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn the_output_flags_decide_what_the_planned_job_stores() {
    let combine_bytes = |extra: &[&str]| {
        let o = cornell(extra);
        let stages = o["stages"].as_array().unwrap();
        u(&stages.iter().find(|s| s["name"] == "combine").unwrap()["bytes"])
    };
    // As `hort render` stores them: the PNG (4 bytes a pixel before compression), the linear
    // image unless --out is a PNG (12), the hit buffer with --hits (8). Nothing is written.
    let dir = tempfile::tempdir().unwrap();
    let at = |name: &str| dir.path().join(name).display().to_string();
    let pixels = 64 * 48;
    assert_eq!(combine_bytes(&[]), pixels * 4);
    assert_eq!(combine_bytes(&["--out", &at("x.png")]), pixels * 4);
    assert_eq!(combine_bytes(&["--out", &at("x.pfm")]), pixels * 16);
    assert_eq!(combine_bytes(&["--hits", &at("h.bin")]), pixels * 12);
    assert_eq!(
        combine_bytes(&["--out", &at("x.exr"), "--hits", &at("h.bin")]),
        pixels * 24
    );
    // The folder exists, so nothing kept `hort plan` from writing there.
    let written: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(written.is_empty(), "hort plan wrote {written:?}");
}
