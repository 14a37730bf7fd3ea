//! The `hort` command as users and scripts call it: files it writes and errors it prints.

use crate::common;

use common::{hort, scene, scratch};
use hort_core::hits::decode_hits;
use hort_core::image::decode_pfm;
use std::path::Path;

fn render(scene_file: &Path, dir: &Path, extra: &[&str]) -> (Vec<u8>, Vec<u8>, serde_json::Value) {
    let (out, hits, report) = (dir.join("o.pfm"), dir.join("h.bin"), dir.join("r.json"));
    let mut args = vec![
        "render",
        scene_file.to_str().unwrap(),
        "--monolithic",
        "--width",
        "64",
        "--height",
        "48",
        "--out",
        out.to_str().unwrap(),
        "--hits",
        hits.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = hort(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(report).unwrap()).unwrap();
    (
        std::fs::read(out).unwrap(),
        std::fs::read(hits).unwrap(),
        report,
    )
}

#[test]
fn monolithic_render_writes_contract_files() {
    let dir = scratch("contract");
    let (pfm, hits, report) = render(&scene("bunny/bunny.json"), &dir, &["--spp", "2"]);
    let image = decode_pfm(&pfm).unwrap();
    assert_eq!((image.width, image.height), (64, 48));
    let hits = decode_hits(&hits, 64, 48).unwrap();
    let triangles = report["triangles"].as_u64().unwrap();
    assert_eq!(triangles, 3676);
    let hit_count = hits.iter().filter(|h| !h.is_miss()).count() as u64;
    assert!(
        hit_count > 500,
        "the bunny on its ground fills part of the frame"
    );
    assert!(
        hits.iter()
            .all(|h| h.is_miss() || (u64::from(h.triangle) < triangles && h.t > 0.0))
    );
    assert!(
        hits.iter()
            .filter(|h| h.is_miss())
            .all(|h| h.t == f32::INFINITY)
    );
    assert_eq!(report["width"], 64);
    assert_eq!(report["height"], 48);
    assert_eq!(report["rays"]["primary"], 64 * 48 * 2);
    // 6,144 samples over 3,676 triangles: below 4 a triangle, so the fast build.
    assert_eq!(report["bvh_build"], "fast");
    // One shadow ray per hit sample and light (one light): at least the sample-0 hits.
    assert!(report["rays"]["shadow"].as_u64().unwrap() >= hit_count);
    assert!(
        report["seconds"]["render"].as_f64().unwrap()
            <= report["seconds"]["total"].as_f64().unwrap()
    );
    assert_eq!(report["stages"], serde_json::json!([]));
    assert!(report["replication"].is_null() && report["cost_usd"].is_null());
}

#[test]
fn thread_count_does_not_change_a_byte() {
    let dir1 = scratch("threads1");
    let dir3 = scratch("threads3");
    let a = render(
        &scene("cornell/cornell.json"),
        &dir1,
        &["--threads", "1", "--spp", "3"],
    );
    let b = render(
        &scene("cornell/cornell.json"),
        &dir3,
        &["--threads", "3", "--spp", "3"],
    );
    assert_eq!(a.0, b.0, "image");
    assert_eq!(a.1, b.1, "hit buffer");
}

#[test]
fn png_output_has_the_png_signature() {
    let dir = scratch("png");
    let out = dir.join("img.png");
    let o = hort(&[
        "render",
        scene("teapot/teapot.json").to_str().unwrap(),
        "--monolithic",
        "--width",
        "32",
        "--height",
        "24",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    let bytes = std::fs::read(out).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
}

#[test]
fn bad_input_prints_one_error_line_and_fails() {
    let dir = scratch("bad");
    let bad = dir.join("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").unwrap();
    let o = hort(&["render", bad.to_str().unwrap(), "--monolithic"]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8(o.stderr).unwrap();
    assert_eq!(
        err,
        format!(
            "error: {}:4: face refers to vertex 9, but only 3 vertices are defined so far\n",
            bad.display()
        )
    );
    let o = hort(&[
        "render",
        scene("bunny/bunny.obj").to_str().unwrap(),
        "--monolithic",
        "--width",
        "70000",
    ]);
    // Ranges of single flags are checked by the command line parser (exit status 2).
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8(o.stderr).unwrap().starts_with(
        "error: invalid value '70000' for '--width <WIDTH>': 70000 is not in 1..=65536\n"
    ));
    let o = hort(&[
        "render",
        scene("bunny/bunny.obj").to_str().unwrap(),
        "--monolithic",
        "--out",
        dir.join("x.bmp").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8(o.stderr).unwrap();
    let bmp = dir.join("x.bmp");
    assert!(
        err.starts_with(&format!(
            "error: --out {}: unsupported image extension \"bmp\" for {}",
            bmp.display(),
            bmp.display()
        )),
        "{err}"
    );
}

#[test]
fn scene_generate_is_deterministic_and_exact() {
    let dir = scratch("generate");
    let (a, b) = (dir.join("a.obj"), dir.join("b.obj"));
    for p in [&a, &b] {
        let o = hort(&[
            "scene",
            "generate",
            "--triangles",
            "10000",
            "--seed",
            "5",
            "--out",
            p.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let text = std::fs::read(&a).unwrap();
    assert_eq!(text, std::fs::read(&b).unwrap());
    let faces = text
        .split(|&c| c == b'\n')
        .filter(|l| l.starts_with(b"f "))
        .count();
    assert_eq!(faces, 10_000);
    let o = hort(&[
        "scene",
        "generate",
        "--triangles",
        "0",
        "--out",
        dir.join("z.obj").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
}

#[test]
fn pipeline_render_equals_monolithic_byte_for_byte() {
    let mono_dir = scratch("pipe-mono");
    let mono = render(&scene("teapot/teapot.json"), &mono_dir, &[]);
    // --splits 1 runs fused, K > 1 staged, unless --mode forces the other.
    for (k, s, mode, workers, forced, execution) in [
        ("1", "16", "spatial", "2", None, "fused"),
        ("1", "4", "spatial", "1", Some("staged"), "staged"),
        ("5", "3", "naive", "1", None, "staged"),
        ("3", "5", "spatial", "2", Some("fused"), "fused"),
        ("7", "13", "spatial", "3", None, "staged"),
    ] {
        let dir = scratch(&format!("pipe-{k}-{s}-{mode}-{execution}"));
        let (out, hits, report) = (dir.join("o.pfm"), dir.join("h.bin"), dir.join("r.json"));
        let forced: Vec<&str> = forced.map_or(vec![], |m| vec!["--mode", m]);
        let o = hort(
            &[
                "render",
                scene("teapot/teapot.json").to_str().unwrap(),
                "--width",
                "64",
                "--height",
                "48",
                "--in-process",
                "--splits",
                k,
                "--spans",
                s,
                "--split-mode",
                mode,
                "--workers",
                workers,
                "--out",
                out.to_str().unwrap(),
                "--hits",
                hits.to_str().unwrap(),
                "--report",
                report.to_str().unwrap(),
            ]
            .iter()
            .chain(&forced)
            .copied()
            .collect::<Vec<_>>(),
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(
            std::fs::read(&out).unwrap(),
            mono.0,
            "image, k={k} s={s} {mode} {execution}"
        );
        assert_eq!(
            std::fs::read(&hits).unwrap(),
            mono.1,
            "hits, k={k} s={s} {mode}"
        );
        let r: serde_json::Value = serde_json::from_slice(&std::fs::read(report).unwrap()).unwrap();
        assert_eq!(r["mode"], "pipeline");
        assert_eq!(r["execution"], execution);
        assert_eq!(r["splits"].as_u64().unwrap(), k.parse::<u64>().unwrap());
        let names: Vec<&str> = r["stages"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s["name"].as_str().unwrap())
            .collect();
        let (expected, per_span): (&[&str], usize) = if execution == "fused" {
            (&["plan", "render", "combine"], 1)
        } else {
            (
                &[
                    "plan",
                    "cast-map",
                    "cast-reduce",
                    "expand",
                    "trace-map",
                    "trace-reduce",
                    "combine",
                ],
                2,
            )
        };
        assert_eq!(names, expected);
        assert_eq!(
            r["stages"][per_span]["tasks"].as_u64().unwrap(),
            s.parse::<u64>().unwrap()
        );
        // In process the workers take the split objects the plan step built (their caches
        // hold them all), so no task reads a split from storage.
        assert_eq!(r["replication"].as_f64().unwrap(), 0.0);
        assert_eq!(r["rays"], mono.2["rays"]);
    }
    let o = hort(&[
        "render",
        scene("teapot/teapot.json").to_str().unwrap(),
        "--splits",
        "5000",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        String::from_utf8(o.stderr).unwrap(),
        "error: --splits 5000 is out of range: the scene has 994 triangles, so use 1 to 994\n"
    );
}

#[test]
fn emulator_render_equals_monolithic_and_reports_cost() {
    let mono_dir = scratch("emu-mono");
    let mono = render(&scene("cornell/cornell.json"), &mono_dir, &[]);
    let dir = scratch("emu");
    let (out, hits, report) = (dir.join("o.pfm"), dir.join("h.bin"), dir.join("r.json"));
    let data = dir.join("data");
    let o = hort(&[
        "render",
        scene("cornell/cornell.json").to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "48",
        "--splits",
        "3",
        "--spans",
        "4",
        "--workers",
        "3",
        "--data-dir",
        data.to_str().unwrap(),
        "--job",
        "cli-test",
        "--out",
        out.to_str().unwrap(),
        "--hits",
        hits.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert_eq!(std::fs::read(&out).unwrap(), mono.0);
    assert_eq!(std::fs::read(&hits).unwrap(), mono.1);
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(report).unwrap()).unwrap();
    assert_eq!(r["mode"], "emulator");
    assert!(r["cost_usd"].as_f64().unwrap() > 0.0);
    assert_eq!(r["retried_attempts"], 0);
    assert_eq!(r["recomputed_blocks"], 0);
    assert_eq!(r["stages"][0]["name"], "plan");
    assert!(
        stderr.contains("stage") && stderr.contains("compression"),
        "summary table: {stderr}"
    );
    // The cost is the report's, measured from this run, and says so (`hort plan`'s is predicted).
    let job_line = stderr
        .lines()
        .find(|l| l.starts_with("job cli-test on "))
        .expect("the job line");
    assert!(
        job_line.ends_with(&format!(
            "; 3 splits, 4 spans); measured AWS cost ${:.6} (AWS prices for this run's task \
             times on this machine and its requests; `hort plan` predicts a cost from its model \
             instead, so the two differ)",
            r["cost_usd"].as_f64().unwrap()
        )),
        "{job_line}"
    );
    // A PNG is written as the job's Combine task stored it (emulator and in-process runs):
    // the bytes a monolithic render encodes.
    let cornell = scene("cornell/cornell.json");
    let png = |name: &str, mode: &[&str]| {
        let path = dir.join(name);
        let mut args = vec![
            "render",
            cornell.to_str().unwrap(),
            "--width",
            "64",
            "--height",
            "48",
            "--out",
            path.to_str().unwrap(),
        ];
        args.extend_from_slice(mode);
        let o = hort(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(path).unwrap()
    };
    let monolithic = png("monolithic.png", &["--monolithic"]);
    assert_eq!(png("emulator.png", &["--splits", "1"]), monolithic);
    assert_eq!(png("in-process.png", &["--in-process"]), monolithic);
    // --data-dir keeps the objects for inspection, and a job id is used once.
    assert!(std::fs::read_dir(&data).unwrap().count() > 0);
    let again = hort(&[
        "render",
        scene("cornell/cornell.json").to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "48",
        "--data-dir",
        data.to_str().unwrap(),
        "--job",
        "cli-test",
        "--out",
        dir.join("x.png").to_str().unwrap(),
    ]);
    assert_eq!(again.status.code(), Some(1));
    assert_eq!(
        String::from_utf8(again.stderr).unwrap(),
        format!(
            "error: job \"cli-test\" already exists in this bucket and finished (its outputs are \
             under jobs/cli-test/out/): run `hort jobs clean --job cli-test --data-dir {}` to \
             delete it, or choose another --job id\n",
            data.display()
        )
    );
}

#[test]
fn storage_problems_are_one_clear_line() {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    drop(listener);
    let dir = scratch("s3-errors");
    let server = embedded_s3::EmbeddedS3::start(&dir, "right-key", "right-secret").unwrap();
    server.ensure_bucket("real").unwrap();
    let endpoint = server.endpoint();
    let dead = format!("http://127.0.0.1:{port}");
    let cases = [
        (
            dead.as_str(),
            "real",
            "right-key",
            "right-secret",
            format!(
                "error: storage unavailable (retryable): check bucket: S3 endpoint {dead} is unreachable (connection refused)\n"
            ),
        ),
        (
            endpoint.as_str(),
            "nope",
            "right-key",
            "right-secret",
            format!(
                "error: bucket \"nope\" does not exist at {endpoint}: create it first, for example \
                 with `aws s3 mb s3://nope --endpoint-url {endpoint}` (hort does not create buckets)\n"
            ),
        ),
        (
            endpoint.as_str(),
            "real",
            "wrong-key",
            "right-secret",
            format!(
                "error: storage access denied: check bucket: S3 rejected the credentials (InvalidAccessKeyId) for bucket \"real\" at {endpoint}\n"
            ),
        ),
    ];
    for (url, bucket, key, secret, expected) in cases {
        let o = hort(&[
            "render",
            scene("bunny/bunny.json").to_str().unwrap(),
            "--width",
            "16",
            "--height",
            "12",
            "--s3-endpoint",
            url,
            "--bucket",
            bucket,
            "--access-key",
            key,
            "--secret-key",
            secret,
            "--out",
            dir.join("x.png").to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1));
        assert_eq!(String::from_utf8(o.stderr).unwrap(), expected);
    }
}

#[test]
fn injected_failures_are_counted_in_the_report_and_change_nothing() {
    let mono = render(&scene("cornell/cornell.json"), &scratch("faults-mono"), &[]);
    let dir = scratch("faults");
    let (out, report) = (dir.join("o.pfm"), dir.join("r.json"));
    let o = hort(&[
        "render",
        scene("cornell/cornell.json").to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "48",
        "--splits",
        "2",
        "--spans",
        "5",
        "--workers",
        "3",
        "--fail-rate",
        "0.3",
        "--duplicate-rate",
        "0.2",
        "--seed",
        "4",
        "--time-scale",
        "0.02",
        "--task-timeout",
        "50",
        "--out",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert_eq!(std::fs::read(&out).unwrap(), mono.0);
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(report).unwrap()).unwrap();
    let retried = r["retried_attempts"].as_u64().unwrap();
    assert!(retried > 0, "{stderr}");
    let attempts: u64 = r["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["attempts"].as_u64().unwrap())
        .sum();
    let tasks: u64 = r["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["tasks"].as_u64().unwrap())
        .sum();
    assert_eq!(attempts, tasks + retried);
    assert!(stderr.contains("faults injected:"), "{stderr}");
}

#[test]
fn storage_faults_from_the_environment_change_no_byte() {
    let mono = render(
        &scene("cornell/cornell.json"),
        &scratch("s3-faults-mono"),
        &[],
    );
    let dir = scratch("s3-faults");
    let (out, hits) = (dir.join("o.pfm"), dir.join("h.bin"));
    let cornell = scene("cornell/cornell.json");
    let args = [
        "render",
        cornell.to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "48",
        "--splits",
        "2",
        "--spans",
        "3",
        // Real time: the storage client's own retry backoff (about a second) is not scaled,
        // so a scaled-down task timeout would expire during it.
        "--out",
        out.to_str().unwrap(),
        "--hits",
        hits.to_str().unwrap(),
    ];
    let spec = "seed=3,slow-down=0.04,internal-error=0.04,latency=0.04,latency-ms=10,reset=0.04,\
                truncate=0.04";
    let o = std::process::Command::new(common::HORT)
        .args(args)
        .env("HORT_S3_FAULTS", spec)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert_eq!(std::fs::read(&out).unwrap(), mono.0);
    assert_eq!(std::fs::read(&hits).unwrap(), mono.1);
    let line = stderr
        .lines()
        .find_map(|l| l.strip_prefix("hort: HORT_S3_FAULTS: the embedded S3 server injected "))
        .unwrap_or_else(|| panic!("no fault counts in {stderr}"));
    eprintln!("hort render under HORT_S3_FAULTS: {line}");
    // "N slow-down, N internal-error, N latency, N reset, N truncate, 0 persistent"
    let counts: Vec<u64> = line
        .split(", ")
        .map(|part| part.split(' ').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(counts.len(), 6, "{line}");
    assert!(counts[..5].iter().sum::<u64>() > 0, "{line}");
    assert_eq!(counts[5], 0, "{line}");

    let bad = std::process::Command::new(common::HORT)
        .args(args)
        .env("HORT_S3_FAULTS", "reset=2")
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    // (After the warning about tiny splits that these flags earn.)
    let errors: Vec<&str> = std::str::from_utf8(&bad.stderr)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with("warning: "))
        .collect();
    assert_eq!(
        errors,
        ["error: HORT_S3_FAULTS=\"reset=2\": reset: the rate 2 is not between 0 and 1"]
    );
}
