//! The `hort` command and a job's objects: temporary folders never outlive a run (signals
//! included, stale ones of killed runs are removed), intermediates are deleted after success,
//! `hort jobs list|clean`, resuming a stopped job, and the storage messages that say what to
//! do (missing credentials, missing bucket, existing job).

use crate::common;

use common::scratch;
use embedded_s3::EmbeddedS3;
use hort_core::store::BlobStore;
use hort_functions::{S3Config, S3Store};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

const HORT: &str = env!("CARGO_BIN_EXE_hort");
const KEY: &str = "jobs-key";
const SECRET: &str = "jobs-secret";

fn scene(rel: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenes")
        .join(rel)
        .to_string_lossy()
        .into_owned()
}

/// `hort` with `args`, its temporary folders in `tmp`.
fn hort_in(tmp: &Path, args: &[&str]) -> Output {
    Command::new(HORT)
        .args(args)
        .env("TMPDIR", tmp)
        .output()
        .expect("hort runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The entries of `dir` named `hort-s3-{pid}-*`.
fn temp_folders_of(dir: &Path, pid: u32) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(&format!("hort-s3-{pid}-")))
        .collect()
}

/// An embedded S3 server with bucket `bucket`, used as an external endpoint.
struct Bucket {
    server: EmbeddedS3,
    bucket: &'static str,
}

impl Bucket {
    fn start(dir: &Path, bucket: &'static str) -> Bucket {
        let server = EmbeddedS3::start(dir, KEY, SECRET).unwrap();
        server.ensure_bucket(bucket).unwrap();
        Bucket { server, bucket }
    }

    /// The storage flags of `hort` for this bucket.
    fn flags(&self) -> Vec<String> {
        [
            "--s3-endpoint",
            &self.server.endpoint(),
            "--bucket",
            self.bucket,
            "--access-key",
            KEY,
            "--secret-key",
            SECRET,
        ]
        .map(str::to_owned)
        .to_vec()
    }

    fn store(&self) -> S3Store {
        S3Store::open(&S3Config::compatible(
            self.server.endpoint(),
            self.bucket,
            KEY,
            SECRET,
        ))
        .unwrap()
    }

    /// Keys under `prefix`, relative to it.
    fn keys(&self, prefix: &str) -> Vec<String> {
        self.store()
            .list(prefix)
            .unwrap()
            .into_iter()
            .map(|k| k[prefix.len()..].to_owned())
            .collect()
    }
}

/// `hort render SCENE` at 32x24 (2 splits, 3 spans) against `bucket` with `extra` flags.
/// The count of the `resumed job {job}: N finished tasks skipped` line of a resumed run.
fn skipped_tasks(err: &str, job: &str) -> u64 {
    err.lines()
        .find_map(|l| l.strip_prefix(&format!("resumed job {job}: ")))
        .and_then(|l| {
            l.strip_suffix(" finished tasks skipped")
                .or_else(|| l.strip_suffix(" finished task skipped"))
        })
        .expect("a resume line")
        .parse()
        .unwrap()
}

fn render_to(tmp: &Path, bucket: &Bucket, scene_rel: &str, extra: &[&str]) -> Output {
    let scene_file = scene(scene_rel);
    let mut args: Vec<String> = [
        "render",
        &scene_file,
        "--width",
        "32",
        "--height",
        "24",
        "--splits",
        "2",
        "--spans",
        "3",
        "--workers",
        "2",
    ]
    .map(str::to_owned)
    .to_vec();
    args.extend(bucket.flags());
    args.extend(extra.iter().map(|s| (*s).to_owned()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    hort_in(tmp, &args)
}

/// Starts a render that cannot end before the signal on any machine (every task attempt
/// straggles, sleeping past its 300 s timeout before it renders), sends `signal` once its
/// stderr shows the render stage started, and checks that it stopped through the cancel path
/// without leaving its temporary folder or an output file.
#[cfg(target_os = "linux")]
fn interrupted_render_leaves_nothing(signal: &str) {
    let dir = scratch(&format!("signal-{signal}"));
    let tmp = dir.join("tmp");
    std::fs::create_dir_all(&tmp).unwrap();
    let out = dir.join("out.png");
    let mut child = Command::new(HORT)
        .args([
            "render",
            &scene("cornell/cornell.json"),
            "--width",
            "32",
            "--height",
            "24",
            "--workers",
            "2",
            "--slow-rate",
            "1",
            "--task-timeout",
            "300",
            "--out",
            out.to_str().unwrap(),
        ])
        .env("TMPDIR", &tmp)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let pid = child.id();
    let (lines, seen) = mpsc::channel();
    let reader = BufReader::new(child.stderr.take().unwrap());
    let log = std::thread::spawn(move || {
        let mut all = String::new();
        for line in reader.lines().map_while(Result::ok) {
            let _ = lines.send(line.clone());
            all += &line;
            all.push('\n');
        }
        all
    });
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        let line = seen
            .recv_timeout(deadline.saturating_duration_since(Instant::now()))
            .expect("the render shows progress");
        // The first task stage (this job runs fused: render) has begun.
        if line.contains("render: started") {
            break;
        }
    }
    assert!(
        !temp_folders_of(&tmp, pid).is_empty(),
        "the run has its temporary folder while it runs"
    );
    let sent = Command::new("kill")
        .args([&format!("-{signal}"), &pid.to_string()])
        .status()
        .unwrap();
    assert!(sent.success());
    let deadline = Instant::now() + Duration::from_secs(120);
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        assert!(
            Instant::now() < deadline,
            "hort did not stop after {signal}"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    let log = log.join().unwrap();
    assert!(!status.success(), "{log}");
    assert!(
        log.contains("error: cancelled"),
        "stopped through the cancel path: {log}"
    );
    let again = match signal {
        "INT" => "press Ctrl-C again to quit at once",
        "TERM" => "send SIGTERM again or press Ctrl-C to quit at once",
        other => panic!("no message known for SIG{other}"),
    };
    assert!(
        log.lines()
            .any(|line| line == format!("stopping: no new tasks start; {again}")),
        "the stop message names what to send again: {log}"
    );
    assert_eq!(temp_folders_of(&tmp, pid), Vec::<String>::new(), "{log}");
    assert!(!out.exists(), "no output after {signal}");
    let left: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(left, ["tmp"], "no partial output after {signal}");
}

#[cfg(target_os = "linux")]
#[test]
fn sigint_removes_the_temporary_folder() {
    interrupted_render_leaves_nothing("INT");
}

#[cfg(target_os = "linux")]
#[test]
fn sigterm_removes_the_temporary_folder() {
    interrupted_render_leaves_nothing("TERM");
}

#[test]
fn stale_temporary_folders_of_dead_processes_are_removed() {
    let dir = scratch("stale");
    let tmp = dir.join("tmp");
    std::fs::create_dir_all(&tmp).unwrap();
    // A process that has ended: its pid is free (and not reused this soon).
    let mut gone = Command::new("true").spawn().unwrap();
    let dead = gone.id();
    gone.wait().unwrap();
    let stale = tmp.join(format!("hort-s3-{dead}-0"));
    std::fs::create_dir_all(stale.join("data/hort/jobs/x")).unwrap();
    std::fs::write(stale.join("data/hort/jobs/x/manifest.json~obj"), b"{}").unwrap();
    // A live process (this test) and a name that is not a temporary folder are left alone.
    let live = tmp.join(format!("hort-s3-{}-7", std::process::id()));
    let other = tmp.join("hort-s3-notes");
    std::fs::create_dir_all(&live).unwrap();
    std::fs::create_dir_all(&other).unwrap();

    let o = hort_in(
        &tmp,
        &[
            "render",
            &scene("cornell/cornell.json"),
            "--width",
            "16",
            "--height",
            "12",
            "--out",
            dir.join("o.png").to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stale.exists(), "the dead process's folder is removed");
    assert!(live.exists() && other.exists());
    let mut left: Vec<String> = std::fs::read_dir(&tmp)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    let mut expected = [
        "hort-s3-notes".to_owned(),
        format!("hort-s3-{}-7", std::process::id()),
    ];
    left.sort();
    expected.sort();
    assert_eq!(left, expected, "the run left nothing of its own");
}

#[test]
fn a_successful_job_keeps_only_its_request_plan_and_outputs() {
    let dir = scratch("keep");
    let bucket = Bucket::start(&dir.join("s3"), "jobs");
    let out = dir.join("o.pfm");
    let o = render_to(
        &dir,
        &bucket,
        "bunny/bunny.json",
        &[
            "--job",
            "j1",
            "--out",
            out.to_str().unwrap(),
            "--hits",
            dir.join("o.hits").to_str().unwrap(),
        ],
    );
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert_eq!(
        bucket.keys("jobs/j1/"),
        [
            "manifest.json",
            "out/hits.bin",
            "out/image.pfm",
            "out/image.png",
            "plan.json"
        ]
    );
    assert!(
        err.contains("intermediate objects (")
            && err.contains(
                "bytes) of job j1; kept jobs/j1/manifest.json, plan.json and out/ \
                 (--keep-intermediates keeps everything)\n"
            ),
        "{err}"
    );

    // --keep-intermediates keeps everything: the scene, splits, items and partitions.
    let o = render_to(
        &dir,
        &bucket,
        "bunny/bunny.json",
        &[
            "--job",
            "j2",
            "--keep-intermediates",
            "--out",
            out.to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let kept = bucket.keys("jobs/j2/");
    for prefix in [
        "scene/",
        "splits/",
        "items/",
        "cast-map/",
        "expand/",
        "trace-map/",
    ] {
        assert!(
            kept.iter().any(|k| k.starts_with(prefix)),
            "{prefix} {kept:?}"
        );
    }

    // `hort jobs list`: both jobs, finished, with their object counts and bytes.
    let s3 = bucket.store();
    let bytes = |job: &str| -> u64 {
        s3.list_sizes(&format!("jobs/{job}/"))
            .unwrap()
            .iter()
            .map(|o| o.bytes)
            .sum()
    };
    let flags = bucket.flags();
    let mut args = vec!["jobs", "list"];
    args.extend(flags.iter().map(String::as_str));
    let o = hort_in(&dir, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        String::from_utf8(o.stdout).unwrap(),
        format!(
            "job  status       objects         bytes\n\
             j1   finished           5  {:>12}\n\
             j2   finished    {:>8}  {:>12}\n",
            bytes("j1"),
            kept.len(),
            bytes("j2")
        )
    );

    // `hort jobs clean --job j1` deletes that job only and says so.
    let j1_bytes = bytes("j1");
    let mut args = vec!["jobs", "clean", "--job", "j1"];
    args.extend(flags.iter().map(String::as_str));
    let o = hort_in(&dir, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        stderr(&o),
        format!("deleted job j1: 5 objects, {j1_bytes} bytes\n")
    );
    assert_eq!(bucket.keys("jobs/j1/"), Vec::<String>::new());
    assert_eq!(bucket.keys("jobs/j2/").len(), kept.len());

    // `--all` deletes the rest; a second listing is empty.
    let mut args = vec!["jobs", "clean", "--all"];
    args.extend(flags.iter().map(String::as_str));
    let o = hort_in(&dir, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).starts_with("deleted job j2: "), "{}", stderr(&o));
    assert_eq!(bucket.keys("jobs/"), Vec::<String>::new());
    let mut args = vec!["jobs", "list"];
    args.extend(flags.iter().map(String::as_str));
    let o = hort_in(&dir, &args);
    assert!(o.status.success());
    assert_eq!(o.stdout, b"");
    assert_eq!(
        stderr(&o),
        format!(
            "no jobs in bucket \"jobs\" at {}\n",
            bucket.server.endpoint()
        )
    );
}

#[test]
fn a_stopped_job_is_refused_without_resume_and_finished_with_it() {
    let dir = scratch("resume");
    let bucket = Bucket::start(&dir.join("s3"), "jobs");
    let endpoint = bucket.server.endpoint();
    let (first, second) = (dir.join("first.pfm"), dir.join("second.pfm"));
    let o = render_to(
        &dir,
        &bucket,
        "bunny/bunny.json",
        &[
            "--job",
            "r1",
            "--keep-intermediates",
            "--out",
            first.to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));

    // A finished job is not resumed.
    let o = render_to(
        &dir,
        &bucket,
        "bunny/bunny.json",
        &["--job", "r1", "--out", second.to_str().unwrap()],
    );
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o),
        format!(
            "error: job \"r1\" already exists in this bucket and finished (its outputs are under \
             jobs/r1/out/): run `hort jobs clean --job r1 --s3-endpoint {endpoint} --bucket jobs` \
             to delete it, or choose another --job id\n"
        )
    );

    // Make it a stopped job: no outputs, no trace-reduce, one cast-map task lost.
    let store = bucket.store();
    for key in store.list("jobs/r1/").unwrap() {
        if key.contains("/out/") || key.contains("/trace-reduce/") {
            store.delete(&key).unwrap();
        }
    }
    let cast = store.list("jobs/r1/cast-map/").unwrap();
    store.delete(&cast[0]).unwrap();

    let o = render_to(
        &dir,
        &bucket,
        "bunny/bunny.json",
        &["--job", "r1", "--out", second.to_str().unwrap()],
    );
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o),
        format!(
            "error: job \"r1\" already exists in this bucket and did not finish: add --resume to \
             continue it, run `hort jobs clean --job r1 --s3-endpoint {endpoint} --bucket jobs` \
             to delete it, or choose another --job id\n"
        )
    );

    // Other settings cannot resume it.
    let o = render_to(
        &dir,
        &bucket,
        "bunny/bunny.json",
        &["--job", "r1", "--resume", "--spp", "2"],
    );
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o),
        format!(
            "error: cannot resume job \"r1\": it was started with other settings (scene \
             bunny.json, 32x24 at 1 spp, splits 2, spans 3, split mode spatial); resume it with \
             those, or run `hort jobs clean --job r1 --s3-endpoint {endpoint} --bucket jobs` to \
             delete it\n"
        )
    );
    // Nor can a resume that asks for an output the job does not store.
    let hits = dir.join("r1.hits");
    let o = render_to(
        &dir,
        &bucket,
        "bunny/bunny.json",
        &[
            "--job",
            "r1",
            "--resume",
            "--out",
            second.to_str().unwrap(),
            "--hits",
            hits.to_str().unwrap(),
        ],
    );
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o),
        format!(
            "error: cannot resume job \"r1\": it was started without storing its hit buffer \
             (--hits); resume it without asking for that, or run `hort jobs clean --job r1 \
             --s3-endpoint {endpoint} --bucket jobs` to delete it\n"
        )
    );
    assert!(!second.exists() && !hits.exists());

    // --resume finishes it, skipping the tasks whose outputs are there, with the same image.
    let o = render_to(
        &dir,
        &bucket,
        "bunny/bunny.json",
        &["--job", "r1", "--resume", "--out", second.to_str().unwrap()],
    );
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let skipped = skipped_tasks(&err, "r1");
    // cast-map (all but one), cast-reduce (3), expand (3) and trace-map (6) were done.
    assert!(skipped >= 12, "{err}");
    assert_eq!(
        std::fs::read(&second).unwrap(),
        std::fs::read(&first).unwrap()
    );
    // A `.pfm` without `--hits`: the job stores no hit buffer.
    assert_eq!(
        bucket.keys("jobs/r1/"),
        [
            "manifest.json",
            "out/image.pfm",
            "out/image.png",
            "plan.json"
        ]
    );

    // Nothing to resume under an unknown id.
    let o = render_to(
        &dir,
        &bucket,
        "bunny/bunny.json",
        &["--job", "r9", "--resume"],
    );
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o),
        "error: job \"r9\" does not exist in this bucket: there is nothing to resume\n"
    );
}

#[test]
fn missing_bucket_says_it_does_not_exist_and_how_to_create_it() {
    let dir = scratch("no-bucket");
    let bucket = Bucket::start(&dir.join("s3"), "real");
    let endpoint = bucket.server.endpoint();
    let o = hort_in(
        &dir,
        &[
            "render",
            &scene("bunny/bunny.json"),
            "--s3-endpoint",
            &endpoint,
            "--bucket",
            "nope",
            "--access-key",
            KEY,
            "--secret-key",
            SECRET,
        ],
    );
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o),
        format!(
            "error: bucket \"nope\" does not exist at {endpoint}: create it first, for example \
             with `aws s3 mb s3://nope --endpoint-url {endpoint}` (hort does not create buckets)\n"
        )
    );
}

/// `hort` with no AWS credentials anywhere: an empty environment, an empty home (no profile),
/// the EC2 metadata service off; `env` adds variables.
fn hort_without_credentials(dir: &Path, args: &[&str], env: &[(&str, &str)]) -> Output {
    let home = dir.join("home");
    std::fs::create_dir_all(&home).unwrap();
    Command::new(HORT)
        .args(args)
        .env_clear()
        .env("HOME", &home)
        .env("TMPDIR", dir)
        .env("AWS_EC2_METADATA_DISABLED", "true")
        .envs(env.iter().copied())
        .output()
        .expect("hort runs")
}

#[test]
fn missing_credentials_say_how_to_give_them() {
    let dir = scratch("no-credentials");
    let bucket = Bucket::start(&dir.join("s3"), "real");
    let endpoint = bucket.server.endpoint();
    let scene_file = scene("bunny/bunny.json");
    let o = hort_without_credentials(
        &dir,
        &[
            "render",
            &scene_file,
            "--s3-endpoint",
            &endpoint,
            "--bucket",
            "real",
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o),
        format!(
            "error: no AWS credentials found for bucket \"real\" at {endpoint}: pass \
             --access-key/--secret-key or set AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY (or \
             configure an AWS profile)\n"
        )
    );

    // --bucket alone is AWS S3, in the region of --region, else AWS_REGION, else us-east-1
    // (the credentials are looked for before any request, so nothing goes out).
    for (extra, env, region) in [
        (&[][..], &[][..], "us-east-1"),
        (&["--region", "eu-west-3"][..], &[][..], "eu-west-3"),
        (&[][..], &[("AWS_REGION", "ap-south-1")][..], "ap-south-1"),
    ] {
        let mut args = vec!["render", &scene_file, "--bucket", "some-bucket"];
        args.extend_from_slice(extra);
        let o = hort_without_credentials(&dir, &args, env);
        assert_eq!(o.status.code(), Some(1));
        assert_eq!(
            stderr(&o),
            format!(
                "error: no AWS credentials found for bucket \"some-bucket\" at AWS S3 ({region}): \
                 pass --access-key/--secret-key or set AWS_ACCESS_KEY_ID and \
                 AWS_SECRET_ACCESS_KEY (or configure an AWS profile)\n"
            )
        );
    }
}

#[test]
fn jobs_commands_need_a_place_and_a_choice() {
    let dir = scratch("jobs-args");
    let o = hort_in(&dir, &["jobs", "list"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = hort_in(&dir, &["jobs", "clean", "--bucket", "b"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));

    // A --data-dir of `hort render` works too.
    let data = dir.join("data");
    let o = hort_in(
        &dir,
        &[
            "render",
            &scene("cornell/cornell.json"),
            "--width",
            "16",
            "--height",
            "12",
            "--data-dir",
            data.to_str().unwrap(),
            "--job",
            "d1",
            "--out",
            dir.join("o.png").to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = hort_in(
        &dir,
        &["jobs", "list", "--data-dir", data.to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let listed = String::from_utf8(o.stdout).unwrap();
    // A PNG alone: the request, the plan and the PNG.
    assert!(listed.contains("\nd1   finished           3  "), "{listed}");
    let o = hort_in(
        &dir,
        &[
            "jobs",
            "clean",
            "--job",
            "d1",
            "--data-dir",
            data.to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).starts_with("deleted job d1: 3 objects, "));
    let o = hort_in(
        &dir,
        &["jobs", "list", "--data-dir", data.to_str().unwrap()],
    );
    assert_eq!(
        stderr(&o),
        format!("no jobs in --data-dir {}\n", data.display())
    );
}

/// A staged adaptive job stopped in its second round resumes with the same image: the
/// round-1 tasks (and round 2's finished ones, under their own task ids) are skipped.
#[test]
fn a_staged_adaptive_job_resumes_in_its_second_round() {
    let dir = scratch("resume-adaptive");
    let bucket = Bucket::start(&dir.join("s3"), "jobs");
    let (first, second) = (dir.join("first.pfm"), dir.join("second.pfm"));
    let adaptive = [
        "--spp",
        "4",
        "--adaptive",
        "16",
        "--adaptive-threshold",
        "0.01",
    ];
    let run = |extra: &[&str]| {
        let mut args = adaptive.to_vec();
        args.extend_from_slice(&["--job", "a1"]);
        args.extend_from_slice(extra);
        render_to(&dir, &bucket, "teapot/teapot.json", &args)
    };
    let o = run(&["--keep-intermediates", "--out", first.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Stop it in round 2: no outputs, no round-2 trace-reduce blocks (task ids from 3 on, the
    // round-1 count), and one round-2 cast-map block lost.
    let store = bucket.store();
    let round_two_reduce: Vec<String> = store
        .list("jobs/a1/trace-reduce/")
        .unwrap()
        .into_iter()
        .filter(|k| !k.contains("/00000/") && !k.contains("/00001/") && !k.contains("/00002/"))
        .collect();
    assert!(!round_two_reduce.is_empty(), "a second round ran");
    for key in store
        .list("jobs/a1/out/")
        .unwrap()
        .iter()
        .chain(&round_two_reduce)
    {
        store.delete(key).unwrap();
    }
    let casts = store.list("jobs/a1/cast-map/").unwrap();
    store.delete(casts.last().unwrap()).unwrap();
    let o = run(&["--resume", "--out", second.to_str().unwrap()]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let skipped = skipped_tasks(&err, "a1");
    // Round 1 alone: cast-reduce, expand and trace-reduce (3 each) and trace-map (6).
    assert!(skipped >= 15, "{err}");
    assert_eq!(
        std::fs::read(&second).unwrap(),
        std::fs::read(&first).unwrap()
    );
}

/// A job whose scene is split by tasks resumes too: finished partition and build tasks (their
/// index or split summary stored) are skipped, a lost split is built again.
#[test]
fn a_job_split_by_tasks_resumes_skipping_finished_partition_and_build_tasks() {
    let dir = scratch("resume-parts");
    let bucket = Bucket::start(&dir.join("s3"), "jobs");
    let (first, second) = (dir.join("first.pfm"), dir.join("second.pfm"));
    let run = |extra: &[&str]| {
        let mut args = vec!["--scene-range-bytes", "20000", "--job", "p1"];
        args.extend_from_slice(extra);
        render_to(&dir, &bucket, "bunny/bunny.json", &args)
    };
    let o = run(&["--keep-intermediates", "--out", first.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Stop it: no outputs, no cast-map blocks, split 1 and its summary lost.
    let store = bucket.store();
    for key in store.list("jobs/p1/").unwrap() {
        let lost = key.contains("/out/")
            || key.contains("/cast-map/")
            || key == "jobs/p1/splits/00001.bin"
            || key == "jobs/p1/parts/split-00001.json";
        if lost {
            store.delete(&key).unwrap();
        }
    }
    let o = run(&[
        "--resume",
        "--keep-intermediates",
        "--out",
        second.to_str().unwrap(),
    ]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let skipped = skipped_tasks(&err, "p1");
    // 7 partition tasks and build 0 (split 1 is built again), then cast-reduce (3), expand
    // (3), trace-map (6) and trace-reduce (3), whose outputs are there.
    assert_eq!(skipped, 7 + 1 + 15, "{err}");
    assert!(store.get("jobs/p1/parts/split-00001.json").is_ok());
    assert_eq!(
        std::fs::read(&second).unwrap(),
        std::fs::read(&first).unwrap()
    );
}
