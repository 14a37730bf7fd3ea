//! What a new user runs into first: outputs checked before any work and never left half
//! written, flags that do not apply refused, values checked where they are given, messages that
//! say what to do, and a report that says how the render ran.

use crate::common;

use common::{files_in, hort, scene, scratch, stderr};

/// A small render's arguments with `extra` appended.
fn small(scene_rel: &str, extra: &[&str]) -> Vec<String> {
    let mut args: Vec<String> = ["render", scene(scene_rel).to_str().unwrap()]
        .iter()
        .map(|s| s.to_string())
        .collect();
    args.extend(["--width", "32", "--height", "24"].map(String::from));
    args.extend(extra.iter().map(|s| s.to_string()));
    args
}

fn run(args: &[String]) -> std::process::Output {
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    hort(&refs)
}

#[test]
fn bad_output_paths_are_refused_before_any_work_and_leave_nothing() {
    let dir = scratch("first-use-outputs");
    let p = |name: &str| dir.join(name).to_str().unwrap().to_owned();
    let cases: Vec<(Vec<String>, String)> = vec![
        (
            vec!["--out".into(), p("render.jpgx")],
            format!(
                "error: --out {}: unsupported image extension \"jpgx\" for {}",
                p("render.jpgx"),
                p("render.jpgx")
            ),
        ),
        (
            vec!["--out".into(), p("render")],
            format!(
                "error: --out {}: unsupported image extension \"\" for {}",
                p("render"),
                p("render")
            ),
        ),
        (
            vec!["--out".into(), dir.to_str().unwrap().into()],
            format!(
                "error: --out {}: is a folder; give a file name inside it",
                dir.display()
            ),
        ),
        (
            vec!["--out".into(), p("missing/x.png")],
            format!(
                "error: --out {}: the folder {} does not exist",
                p("missing/x.png"),
                p("missing")
            ),
        ),
        (
            vec![
                "--out".into(),
                p("ok.png"),
                "--hits".into(),
                p("missing/h.bin"),
            ],
            format!(
                "error: --hits {}: the folder {} does not exist",
                p("missing/h.bin"),
                p("missing")
            ),
        ),
        (
            vec!["--out".into(), p("ok.png"), "--report".into(), p("ok.png")],
            format!(
                "error: --out and --report name the same file {}; give each its own",
                p("ok.png")
            ),
        ),
    ];
    for (extra, expected) in cases {
        for mode in [&["--monolithic"][..], &["--in-process"][..], &[][..]] {
            let mut args = small("bunny/bunny.obj", mode);
            args.extend(extra.iter().cloned());
            let o = run(&args);
            let err = stderr(&o);
            assert!(!o.status.success(), "{args:?}");
            assert!(err.starts_with(&expected), "{args:?}\n{err}");
            assert!(
                !err.contains("rendered") && !err.contains("plan: started"),
                "no work before the check: {err}"
            );
            assert!(files_in(&dir).is_empty(), "{args:?}: {:?}", files_in(&dir));
        }
    }
}

#[test]
fn outputs_are_written_whole_and_report_dash_is_standard_output() {
    let dir = scratch("first-use-stdout");
    let out = dir.join("b.png");
    let hits = dir.join("h.bin");
    let o = run(&small(
        "bunny/bunny.obj",
        &[
            "--in-process",
            "--splits",
            "2",
            "--spans",
            "3",
            "--workers",
            "2",
            "--out",
            out.to_str().unwrap(),
            "--hits",
            hits.to_str().unwrap(),
            "--report",
            "-",
        ],
    ));
    assert!(o.status.success(), "{}", stderr(&o));
    // Standard output holds the report and nothing else; progress and summary go to stderr.
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON on stdout");
    assert_eq!(report["mode"], "pipeline");
    assert_eq!(report["splits"], 2);
    assert_eq!(report["spans"], 3);
    assert_eq!(report["workers"], 2);
    assert_eq!(report["job"], "local");
    assert_eq!(report["outputs"]["image"], out.to_str().unwrap());
    assert_eq!(report["outputs"]["hits"], hits.to_str().unwrap());
    assert_eq!(report["outputs"]["report"], "-");
    assert!(stderr(&o).contains("rendered 32x24"), "{}", stderr(&o));
    assert_eq!(
        files_in(&dir),
        ["b.png", "h.bin"],
        "no temporary files left"
    );
    assert_eq!(std::fs::read(&hits).unwrap().len(), 32 * 24 * 8);
    assert!(!std::path::Path::new("-").exists());
}

#[test]
fn flags_of_another_mode_are_refused_naming_both() {
    let cases: [(&[&str], &str); 11] = [
        (
            &["--threads", "2"],
            "error: the following required arguments were not provided:\n  --monolithic",
        ),
        (
            &["--monolithic", "--workers", "2"],
            "error: the argument '--monolithic' cannot be used with '--workers <WORKERS>'",
        ),
        (
            &["--monolithic", "--splits", "2"],
            "error: the argument '--monolithic' cannot be used with '--splits <SPLITS>'",
        ),
        (
            &["--monolithic", "--fail-rate", "0.1"],
            "error: the argument '--monolithic' cannot be used with '--fail-rate <FAIL_RATE>'",
        ),
        (
            &["--monolithic", "--data-dir", "/tmp/x"],
            "error: the argument '--monolithic' cannot be used with '--data-dir <DATA_DIR>'",
        ),
        (
            &["--monolithic", "--in-process"],
            "error: the argument '--monolithic' cannot be used with '--in-process'",
        ),
        (
            &["--in-process", "--job", "j1"],
            "error: the argument '--in-process' cannot be used with '--job <JOB>'",
        ),
        (
            &[
                "--s3-endpoint",
                "http://127.0.0.1:1",
                "--bucket",
                "b",
                "--data-dir",
                "/tmp/x",
            ],
            "error: the argument '--s3-endpoint <S3_ENDPOINT>' cannot be used with '--data-dir <DATA_DIR>'",
        ),
        (
            &["--monolithic", "--lambda-endpoint", "http://127.0.0.1:1"],
            "error: the argument '--monolithic' cannot be used with '--lambda-endpoint <LAMBDA_ENDPOINT>'",
        ),
        (
            // The functions must reach the run's bucket: the embedded server's is not theirs.
            &["--lambda-endpoint", "http://127.0.0.1:1"],
            "error: the following required arguments were not provided:\n  --bucket <BUCKET>",
        ),
        (
            &[
                "--lambda-endpoint",
                "http://127.0.0.1:1",
                "--bucket",
                "b",
                "--fail-rate",
                "0.1",
            ],
            "error: the argument '--lambda-endpoint <LAMBDA_ENDPOINT>' cannot be used with '--fail-rate <FAIL_RATE>'",
        ),
    ];
    for (flags, expected) in cases {
        let o = run(&small("bunny/bunny.obj", flags));
        assert_eq!(o.status.code(), Some(2), "{flags:?}");
        assert!(
            stderr(&o).starts_with(expected),
            "{flags:?}\n{}",
            stderr(&o)
        );
    }
}

#[test]
fn values_are_checked_where_they_are_given() {
    let cases: [(&[&str], &str); 6] = [
        (
            &["--spp", "-1"],
            "error: invalid value '-1' for '--spp <SPP>': -1 is not in 1..=65536",
        ),
        (
            &["--width", "0"],
            "error: invalid value '0' for '--width <WIDTH>': 0 is not in 1..=65536",
        ),
        (
            &["--task-timeout", "0"],
            "error: invalid value '0' for '--task-timeout <TASK_TIMEOUT>': 0 is not in 1..=300",
        ),
        (
            &["--memory-mb", "0"],
            "error: invalid value '0' for '--memory-mb <MEMORY_MB>': 0 is not in 128..=10240",
        ),
        (
            &["--memory-mb", "100000"],
            "error: invalid value '100000' for '--memory-mb <MEMORY_MB>': 100000 is not in 128..=10240",
        ),
        (
            &["--monolithic", "--threads", "0"],
            "error: invalid value '0' for '--threads <THREADS>': 0 is not in 1..=4096",
        ),
    ];
    let bunny = scene("bunny/bunny.obj");
    for (flags, expected) in cases {
        let o = hort(&[&["render", bunny.to_str().unwrap()][..], flags].concat());
        assert_eq!(o.status.code(), Some(2), "{flags:?}");
        assert!(
            stderr(&o).starts_with(expected),
            "{flags:?}\n{}",
            stderr(&o)
        );
    }
}

#[test]
fn a_bad_camera_names_the_file_before_any_upload() {
    let dir = scratch("first-use-camera");
    let manifest = dir.join("cam.json");
    let obj = scene("bunny/bunny.obj");
    std::fs::write(
        &manifest,
        format!(
            r#"{{"meshes": [{:?}], "camera": {{"eye": [0, 1, 0], "look_at": [0, 1, 0]}}}}"#,
            obj.to_str().unwrap()
        ),
    )
    .unwrap();
    let out = dir.join("o.png");
    for mode in [&["--monolithic"][..], &[][..]] {
        let mut args = vec![
            "render".to_owned(),
            manifest.to_str().unwrap().to_owned(),
            "--out".into(),
            out.to_str().unwrap().into(),
        ];
        args.extend(mode.iter().map(|s| s.to_string()));
        let o = run(&args);
        assert!(!o.status.success());
        let err = stderr(&o);
        assert!(
            err.starts_with(&format!("error: {}: ", manifest.display())),
            "{err}"
        );
        assert!(err.contains("eye and look_at are the same point"), "{err}");
        assert!(!err.contains("plan: started"), "{err}");
    }
}

#[test]
fn splits_far_below_useful_are_warned_about() {
    // An unreachable endpoint ends the run right after planning: the warning is what counts.
    let dir = scratch("first-use-splits");
    let out = dir.join("o.png");
    let o = run(&small(
        "bunny/bunny.obj",
        &[
            "--splits",
            "2000",
            "--spans",
            "1",
            "--s3-endpoint",
            "http://127.0.0.1:1",
            "--bucket",
            "b",
            "--access-key",
            "k",
            "--secret-key",
            "s",
            "--out",
            out.to_str().unwrap(),
        ],
    ));
    assert!(!o.status.success());
    assert!(
        stderr(&o).starts_with(
            "warning: --splits 2000 leaves about 2 triangles per split; the job will run up to \
             4000 map tasks, each paying a function call and storage round trips for little ray \
             work (splits pay off from about 1000 triangles each)\n"
        ),
        "{}",
        stderr(&o)
    );
    let o = run(&small(
        "bunny/bunny.obj",
        &[
            "--splits",
            "3",
            "--s3-endpoint",
            "http://127.0.0.1:1",
            "--bucket",
            "b",
            "--access-key",
            "k",
            "--secret-key",
            "s",
            "--out",
            out.to_str().unwrap(),
        ],
    ));
    assert!(!stderr(&o).contains("warning: --splits"), "{}", stderr(&o));
}

#[test]
fn messages_say_things_once_and_in_good_english() {
    let missing = scene("nope/missing.obj");
    let o = hort(&["render", missing.to_str().unwrap(), "--monolithic"]);
    assert_eq!(
        stderr(&o),
        format!(
            "error: cannot read {}: No such file or directory\n",
            missing.display()
        )
    );
    let dir = scratch("first-use-messages");
    let out = dir.join("o.pfm");
    let o = run(&small(
        "bunny/bunny.obj",
        &[
            "--monolithic",
            "--threads",
            "1",
            "--out",
            out.to_str().unwrap(),
        ],
    ));
    assert!(stderr(&o).contains(" on 1 thread)"), "{}", stderr(&o));
}

#[test]
fn scene_generate_never_destroys_files() {
    let dir = scratch("first-use-generate");
    let victim = dir.join("victim.json");
    std::fs::write(&victim, "{\"meshes\": []}").unwrap();
    let o = hort(&[
        "scene",
        "generate",
        "--triangles",
        "1000",
        "--out",
        victim.to_str().unwrap(),
    ]);
    assert_eq!(
        stderr(&o),
        format!(
            "error: --out {}: must end in .obj (a manifest is written beside it with .json)\n",
            victim.display()
        )
    );
    assert_eq!(std::fs::read(&victim).unwrap(), b"{\"meshes\": []}");

    let keep = dir.join("keep.obj");
    let keep_json = dir.join("keep.json");
    std::fs::write(&keep_json, "mine").unwrap();
    let args = [
        "scene",
        "generate",
        "--triangles",
        "1000",
        "--out",
        keep.to_str().unwrap(),
    ];
    let o = hort(&args);
    assert_eq!(
        stderr(&o),
        format!(
            "error: {} exists; pass --force to overwrite it (scene generate writes {} and {})\n",
            keep_json.display(),
            keep.display(),
            keep_json.display()
        )
    );
    assert_eq!(std::fs::read(&keep_json).unwrap(), b"mine");
    assert!(!keep.exists());
    let o = hort(&[&args[..], &["--force"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        std::fs::read_to_string(&keep_json)
            .unwrap()
            .contains("keep.obj")
    );
    assert_eq!(files_in(&dir), ["keep.json", "keep.obj", "victim.json"]);
}

/// `--help` of every command with the S3 key flags names their variables but never shows the
/// values set in the environment.
#[test]
fn help_never_shows_the_s3_keys_from_the_environment() {
    for command in [&["render"][..], &["jobs", "list"], &["jobs", "clean"]] {
        let o = std::process::Command::new(common::HORT)
            .args(command)
            .arg("--help")
            .env("HORT_S3_ACCESS_KEY", "access-from-env")
            .env("HORT_S3_SECRET_KEY", "secret-from-env")
            .output()
            .expect("hort runs");
        assert!(o.status.success(), "{command:?}: {o:?}");
        let help = String::from_utf8(o.stdout).unwrap();
        for variable in ["HORT_S3_ACCESS_KEY", "HORT_S3_SECRET_KEY"] {
            assert!(
                help.contains(&format!("[env: {variable}]")),
                "{command:?}: {help}"
            );
            assert!(
                !help.contains(&format!("{variable}=")),
                "{command:?}: {help}"
            );
        }
        assert!(
            !help.contains("access-from-env") && !help.contains("secret-from-env"),
            "{command:?}: {help}"
        );
    }
}

/// The tests' scratch folders remove themselves, with what is in them, when dropped.
#[test]
fn scratch_folders_are_gone_after_drop() {
    let dir = scratch("drop-check");
    let path = dir.to_path_buf();
    assert!(path.starts_with(std::env::temp_dir()), "{}", path.display());
    std::fs::create_dir_all(path.join("a/b")).unwrap();
    std::fs::write(path.join("a/b/file"), b"x").unwrap();
    assert_eq!(files_in(&dir), ["a"]);
    drop(dir);
    assert!(!path.exists(), "{} is left", path.display());
}
