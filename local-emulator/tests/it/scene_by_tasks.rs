//! `hort render --scene-range-bytes`: a scene split by tasks (Plan's scan, Partition, Cut,
//! Build, PlanFromParts) renders the monolithic image's bytes, fused and staged, under injected
//! faults, and its report has a row for each of those steps, as `hort plan` counts them.

use crate::common;

use common::{hort, scene, scratch, stderr};

fn render(dir: &std::path::Path, name: &str, extra: &[&str]) -> (Vec<u8>, serde_json::Value) {
    let scene = scene("bunny/bunny.json");
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
        "2",
        "--out",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = hort(&args);
    assert!(o.status.success(), "{name}: {}", stderr(&o));
    let report = serde_json::from_slice(&std::fs::read(report).unwrap()).unwrap();
    (std::fs::read(out).unwrap(), report)
}

fn rows(report: &serde_json::Value) -> Vec<(String, u64)> {
    report["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            let name = s["name"].as_str().unwrap().to_owned();
            (name, s["tasks"].as_u64().unwrap())
        })
        .collect()
}

#[test]
fn scenes_split_by_tasks_render_the_monolithic_image() {
    let dir = scratch("scene-by-tasks");
    let scene_path = scene("bunny/bunny.json");
    let (mono, _) = render(&dir, "mono", &["--monolithic", "--threads", "2"]);
    // bunny.obj (110,537 bytes) in 6 ranges of 20,000 bytes, ground.obj in 1.
    let ranges = ["--scene-range-bytes", "20000"];
    let staged = [&ranges[..], &["--splits", "3", "--spans", "4"]].concat();
    let (image, report) = render(&dir, "staged", &staged);
    assert_eq!(image, mono, "staged");
    let stages = rows(&report);
    let names: Vec<&str> = stages.iter().map(|s| s.0.as_str()).collect();
    assert_eq!(
        names,
        [
            "plan",
            "partition",
            "cut",
            "build",
            "plan-from-parts",
            "cast-map",
            "cast-reduce",
            "expand",
            "trace-map",
            "trace-reduce",
            "combine"
        ]
    );
    assert_eq!(stages[1].1, 7, "one partition task per range");
    assert_eq!(stages[3].1, 3, "one build task per split");
    // `hort plan` counts the same steps and tasks from its own scan, but for the CastMap pairs:
    // before the partition it knows no split's bounds, so it leaves none out.
    let mut plan_args = vec!["plan", scene_path.to_str().unwrap()];
    plan_args.extend_from_slice(&["--width", "64", "--height", "48", "--spp", "2", "--json"]);
    plan_args.extend_from_slice(&staged);
    let o = hort(&plan_args);
    assert!(o.status.success(), "{}", stderr(&o));
    let planned: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let planned = rows(&planned);
    for (row, (name, tasks)) in planned.iter().enumerate() {
        assert_eq!(name, &stages[row].0);
        if name == "cast-map" {
            assert!(*tasks >= stages[row].1 && *tasks == 3 * 4, "{tasks}");
        } else {
            assert_eq!(*tasks, stages[row].1, "{name}");
        }
    }
    assert_eq!(planned.len(), stages.len());
    let fused = [&ranges[..], &["--splits", "1", "--spans", "3"]].concat();
    let (image, report) = render(&dir, "fused", &fused);
    assert_eq!(image, mono, "fused");
    assert_eq!(rows(&report)[5].0, "render");
    let faulty = [&staged[..], &["--fail-rate", "0.2", "--seed", "7"]].concat();
    let (image, _) = render(&dir, "faults", &faulty);
    assert_eq!(image, mono, "staged, 20% of attempts failing");
}

/// The client does not load a scene it splits by tasks: a bad one is refused by the Plan
/// function's scan, with the whole-scene loader's message (file and line).
#[test]
fn a_bad_scene_split_by_tasks_fails_in_the_plan_naming_file_and_line() {
    let dir = scratch("scene-by-tasks-bad");
    let obj = dir.join("bad.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 7\n").unwrap();
    let whole = hort(&["render", obj.to_str().unwrap(), "--monolithic"]);
    let expected = stderr(&whole);
    let detail = expected
        .strip_prefix("error: ")
        .and_then(|e| e.split_once("bad.obj:5: "))
        .map(|(_, detail)| detail.trim_end().to_owned())
        .unwrap_or_else(|| panic!("a whole-scene error naming bad.obj:5: {expected}"));
    let o = hort(&[
        "render",
        obj.to_str().unwrap(),
        "--scene-range-bytes",
        "16",
        "--width",
        "8",
        "--height",
        "8",
    ]);
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    let last = err.lines().last().unwrap_or_default();
    assert!(
        last.starts_with("error: job ") && last.contains(" failed in plan: Hort.BadInput: "),
        "{err}"
    );
    let named = format!(" failed in plan: Hort.BadInput: Plan failed: bad.obj:5: {detail}");
    assert!(last.ends_with(&named), "{err}");

    // Its warnings reach the user too, naming the file as the user named it.
    let obj = dir.join("warn.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl nothing\nf 1 2 3\n").unwrap();
    let o = hort(&[
        "render",
        obj.to_str().unwrap(),
        "--scene-range-bytes",
        "16",
        "--width",
        "8",
        "--height",
        "8",
        "--out",
        dir.join("warn.png").to_str().unwrap(),
    ]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let warning = "warning: warn.obj:4: material \"nothing\" is not defined by any mtllib; using \
                   grey 0.7";
    assert!(err.lines().any(|l| l == warning), "{err}");
}
