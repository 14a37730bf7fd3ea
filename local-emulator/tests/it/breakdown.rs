//! The time breakdown of `hort render --report` (docs/ARCHITECTURE.md, section 14): each
//! stage's `breakdown` is there, its parts are consistent with each other and with the stage's
//! time, and storage latency injected into the embedded S3 server shows up as storage time.

use crate::common;

use common::{HORT, scene, scratch};
use serde_json::Value;
use std::process::Command;

/// Milliseconds the embedded server delays every request in the latency run.
const LATENCY_MS: u64 = 30;

/// Renders the Cornell box (16x12, 2 splits, 2 spans, 2 workers) with `extra` flags and the
/// environment `env`, and returns the report.
fn report(name: &str, extra: &[&str], env: &[(&str, &str)]) -> Value {
    let dir = scratch(name);
    let (out, report) = (dir.join("o.png"), dir.join("r.json"));
    let cornell = scene("cornell/cornell.json");
    let mut args = vec![
        "render",
        cornell.to_str().unwrap(),
        "--width",
        "16",
        "--height",
        "12",
        "--splits",
        "2",
        "--spans",
        "2",
        "--workers",
        "2",
        "--out",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = Command::new(HORT)
        .args(&args)
        .envs(env.iter().copied())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    // The terminal summary has the breakdown table, one row per stage and a total.
    let table: Vec<&str> = stderr
        .lines()
        .skip_while(|l| !(l.starts_with("stage ") && l.ends_with("  orchestration")))
        .take_while(|l| !l.starts_with("rendered "))
        .collect();
    assert_eq!(table.len(), 1 + 7 + 2, "{stderr}");
    assert!(table[9].starts_with("total "), "{stderr}");
    let report = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    report
}

/// The parts of a stage, by name.
fn part(stage: &Value, name: &str) -> f64 {
    stage["breakdown"][name]
        .as_f64()
        .unwrap_or_else(|| panic!("{} has no breakdown.{name}: {stage}", stage["name"]))
}

/// What holds in every mode: parts non-negative, task parts within the task time, task time
/// within the slots' share of the stage's wall time, orchestration within the wall time.
fn check_consistent(report: &Value) -> Vec<Value> {
    let stages = report["stages"].as_array().unwrap().clone();
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
    let slots = report["workers"].as_f64().unwrap();
    for s in &stages {
        let [
            task,
            compute,
            encode,
            decode,
            storage,
            invocation,
            orchestration,
        ] = [
            "task",
            "compute",
            "encode",
            "decode",
            "storage",
            "invocation",
            "orchestration",
        ]
        .map(|n| part(s, n));
        for v in [
            task,
            compute,
            encode,
            decode,
            storage,
            invocation,
            orchestration,
        ] {
            assert!(v >= 0.0 && v.is_finite(), "{s}");
        }
        // Microsecond sums: the parts never overlap within a task.
        assert!(compute + encode + decode + storage <= task + 1e-9, "{s}");
        let wall = s["seconds"].as_f64().unwrap();
        assert!(orchestration <= wall + 1e-6, "{s}");
        assert!(task + invocation <= slots * wall + 1e-3, "{s}");
        // Every stage encodes something (the plan step: its split objects).
        assert!(task > 0.0, "{s}");
        assert!(encode > 0.0, "{s}");
        if s["name"] != "plan" {
            // Cast-map reads only its split, which in process comes from the plan step's
            // objects in the workers' caches, not from storage: nothing to decode.
            let in_process = report["mode"] == "pipeline";
            if !(in_process && s["name"] == "cast-map") {
                assert!(decode > 0.0, "{s}");
            } else {
                assert_eq!(decode, 0.0, "{s}");
            }
        }
    }
    stages
}

#[test]
fn injected_storage_latency_shows_as_storage_time() {
    let spec = format!("seed=1,latency=1,latency-ms={LATENCY_MS}");
    let report = report("latency", &[], &[("HORT_S3_FAULTS", &spec)]);
    assert_eq!(report["mode"], "emulator");
    let stages = check_consistent(&report);
    for s in &stages[1..] {
        // Every worker task writes at least its output, delayed by the latency (a warm worker
        // has the plan and its splits already).
        let tasks = s["tasks"].as_f64().unwrap();
        let floor = tasks * LATENCY_MS as f64 / 1e3;
        assert!(part(s, "storage") >= floor, "storage below {floor}: {s}");
        assert!(part(s, "storage") <= part(s, "task"), "{s}");
    }
    // The Plan function reads the request and the scene, and writes a split object and the
    // plan at least: four delayed requests, and loading the scene is its decode part.
    let plan = &stages[0];
    let floor = 4.0 * LATENCY_MS as f64 / 1e3;
    assert!(
        part(plan, "storage") >= floor,
        "storage below {floor}: {plan}"
    );
    assert!(part(plan, "decode") > 0.0, "{plan}");
}

#[test]
fn in_process_runs_have_no_invocation_overhead() {
    let report = report("in-process", &["--in-process"], &[]);
    assert_eq!(report["mode"], "pipeline");
    for s in &check_consistent(&report) {
        assert_eq!(part(s, "invocation"), 0.0, "{s}");
    }
}
