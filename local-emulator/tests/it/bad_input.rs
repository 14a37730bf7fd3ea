//! `docs/bad-input.md` as a test: every row's input is given to the code that reads it, and what
//! the user sees must be the row's message, exactly.
//!
//! Rows by kind (the input cell's escapes: `\n` newline, `\r` carriage return, `\t` tab, `\\` backslash, `\|` a pipe,
//! `\xNN` a byte):
//!
//! | kind | input | what is compared |
//! |---|---|---|
//! | `obj` | `scene.obj` (the text after a `#MTL` line is `m.mtl`) | a line of `hort render scene.obj --monolithic` standard error, run in the scene's folder |
//! | `manifest` | `scene.json`, beside `a.obj` (one triangle, material `red` from `m.mtl`) | the same for `hort render scene.json` |
//! | `flags` | arguments of `hort`, split at spaces, run beside a valid `scene.obj` | a line of standard error |
//! | `http` | a request: `METHOD URI`, header lines, an empty line, the body | `STATUS body` of the API router's answer |
//! | `split` | an edit of the plan's split object of a one-triangle scene | the decoder's error |
//! | `block` | an edit of a valid `Hit` shuffle block | the decoder's error |
//! | `job` | an edit of a planned one-triangle job's object, then `run STAGE TASK` | the task's error |
//! | `scene-bin` | an edit of the binary scene a client stored for a one-triangle job | the Plan function's error |
//! | `asl` | a state machine definition | the loader's error |
//!
//! Edits: `delete`, `truncate N` (keep N bytes), `flip N` (invert byte N), `append N` (N zero
//! bytes), `as KIND` (read as another record kind).

use crate::common;

use std::path::Path;
use std::process::Command;

use hort::emulator::binary_scene;
use hort_core::ids::{JobId, SplitId};
use hort_core::keys::{manifest_key, scene_binary_key, split_key};
use hort_core::pipeline::{
    PlanRequest, SplitMode, StoredOutputs, SurfaceHit, decode_split, decode_surface_hits,
    encode_surface_hits, plan_into_store, run_task,
};
use hort_core::scene::load_scene;
use hort_core::shading::SurfacePoint;
use hort_core::shuffle::RecordKind;
use hort_core::stage::Stage;
use hort_core::store::{BlobStore, MemoryStore};
use hort_functions::handlers::{JobRequest, PlanEvent, PlanStep, SceneFormat, Tmp, handle_plan};

const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
/// The triangle and a second one behind it, so that the default light can be occluded and a
/// staged job has trace-map tasks.
const TWO_TRIANGLES: &str =
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 -1\nv 1 0 -1\nv 0 1 -1\nf 1 2 3\nf 4 5 6\n";
const MANIFEST_OBJ: &str = "mtllib m.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
const MANIFEST_MTL: &str = "newmtl red\nKd 0.8 0.1 0.1\n";

/// One row of the table.
struct Row {
    line: usize,
    kind: String,
    input: Vec<u8>,
    message: String,
}

/// The rows of `docs/bad-input.md`: every table row whose first cell is a number.
fn rows() -> Vec<Row> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/bad-input.md");
    let text = std::fs::read_to_string(&path).expect("docs/bad-input.md");
    let mut rows = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let cells = split_cells(line);
        if cells.len() != 4 || cells[0].parse::<u32>().is_err() {
            continue;
        }
        rows.push(Row {
            line: i + 1,
            kind: code(&cells[1]),
            input: unescape(&code(&cells[2])),
            message: code(&cells[3]),
        });
    }
    rows
}

/// The cells of a table line (`| a | b |`), with `\|` kept inside a cell.
fn split_cells(line: &str) -> Vec<String> {
    let Some(inner) = line
        .trim()
        .strip_prefix('|')
        .and_then(|l| l.strip_suffix('|'))
    else {
        return Vec::new();
    };
    let mut cells = vec![String::new()];
    let mut chars = inner.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' if chars.peek() == Some(&'|') => {
                chars.next();
                cells.last_mut().unwrap().push('|');
            }
            '|' => cells.push(String::new()),
            _ => cells.last_mut().unwrap().push(c),
        }
    }
    cells.iter().map(|c| c.trim().to_owned()).collect()
}

/// The text of a code span (`` `x` `` or ``` `` x `` ```).
fn code(cell: &str) -> String {
    if let Some(inner) = cell.strip_prefix("`` ").and_then(|c| c.strip_suffix(" ``")) {
        return inner.to_owned();
    }
    cell.strip_prefix('`')
        .and_then(|c| c.strip_suffix('`'))
        .unwrap_or(cell)
        .to_owned()
}

/// The bytes an input cell stands for.
fn unescape(text: &str) -> Vec<u8> {
    let mut out = Vec::new();
    let mut rest = text.as_bytes();
    while let Some((&b, tail)) = rest.split_first() {
        rest = tail;
        if b != b'\\' {
            out.push(b);
            continue;
        }
        let (byte, used) = match rest {
            [b'n', ..] => (b'\n', 1),
            [b't', ..] => (b'\t', 1),
            [b'r', ..] => (b'\r', 1),
            [b'\\', ..] => (b'\\', 1),
            [b'x', a, b, ..] => {
                let hex = std::str::from_utf8(&[*a, *b]).unwrap().to_owned();
                (u8::from_str_radix(&hex, 16).expect("\\xNN"), 3)
            }
            _ => (b'\\', 0),
        };
        out.push(byte);
        rest = &rest[used..];
    }
    out
}

/// A fresh folder for one row, removed when dropped.
fn folder(row: &Row) -> common::Scratch {
    common::scratch(&format!("bad-input-{}", row.line))
}

/// Runs `hort` in `dir`; returns standard error.
fn hort(dir: &Path, args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_hort"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("hort runs");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Renders `scene` (a file in `dir`) tiny and in process.
fn render(dir: &Path, scene: &str) -> String {
    hort(
        dir,
        &[
            "render",
            scene,
            "--monolithic",
            "--width",
            "8",
            "--height",
            "6",
            "--out",
            "o.png",
        ],
    )
}

/// Applies an edit (`delete`, `truncate N`, `flip N`, `append N`) to `bytes`; `None` deletes.
fn edit(bytes: Vec<u8>, op: &str) -> Option<Vec<u8>> {
    let mut bytes = bytes;
    let (verb, arg) = op.split_once(' ').unwrap_or((op, ""));
    let n = || arg.parse::<usize>().expect("an edit's number");
    match verb {
        "delete" => return None,
        "truncate" => bytes.truncate(n()),
        "flip" => bytes[n()] ^= 0xff,
        "append" => bytes.extend(std::iter::repeat_n(0, n())),
        _ => panic!("unknown edit {op:?}"),
    }
    Some(bytes)
}

/// A one-triangle scene planned into a fresh store (1 split, 1 span, 8x6, 1 spp).
/// A staged job of one split and one span over the scene `obj`, planned into a fresh store.
fn planned_job(dir: &Path, obj: &str) -> (MemoryStore, JobId, hort_core::pipeline::JobPlan) {
    std::fs::write(dir.join("scene.obj"), obj).unwrap();
    let scene = load_scene(&dir.join("scene.obj")).unwrap();
    let store = MemoryStore::new();
    let job = JobId::new("bad-input").unwrap();
    let request = PlanRequest {
        width: 8,
        height: 6,
        spp: 1,
        splits: Some(1),
        spans: Some(1),
        mode: SplitMode::Spatial,
        execution: Some(hort_core::pipeline::ExecutionMode::Staged),
        memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
        adaptive: None,
        outputs: StoredOutputs::ALL,
        frame: Default::default(),
    };
    let planned = plan_into_store(&store, &job, &scene, &request).unwrap();
    (store, job, planned.plan)
}

fn stage(name: &str) -> Stage {
    match name {
        "cast-map" => Stage::CastMap,
        "cast-reduce" => Stage::CastReduce,
        "expand" => Stage::Expand,
        "trace-map" => Stage::TraceMap,
        "trace-reduce" => Stage::TraceReduce,
        "combine" => Stage::Combine,
        _ => panic!("unknown stage {name:?}"),
    }
}

/// What the user sees for `row`, in the form the table gives it.
fn actual(row: &Row) -> Vec<String> {
    let dir = folder(row);
    let text = String::from_utf8_lossy(&row.input).into_owned();
    let lines = |s: String| s.lines().map(str::to_owned).collect();
    match row.kind.as_str() {
        "obj" => {
            let marker = b"\n#MTL\n";
            let at = row.input.windows(marker.len()).position(|w| w == marker);
            let obj = &row.input[..at.unwrap_or(row.input.len())];
            std::fs::write(dir.join("scene.obj"), obj).unwrap();
            if let Some(at) = at {
                std::fs::write(dir.join("m.mtl"), &row.input[at + marker.len()..]).unwrap();
            }
            lines(render(&dir, "scene.obj"))
        }
        "manifest" => {
            std::fs::write(dir.join("a.obj"), MANIFEST_OBJ).unwrap();
            std::fs::write(dir.join("m.mtl"), MANIFEST_MTL).unwrap();
            std::fs::write(dir.join("scene.json"), &row.input).unwrap();
            lines(render(&dir, "scene.json"))
        }
        "flags" => {
            std::fs::write(dir.join("scene.obj"), TRIANGLE).unwrap();
            let args: Vec<&str> = text.split(' ').collect();
            lines(hort(&dir, &args))
        }
        "http" => vec![http(&row.input)],
        "split" => {
            let (store, job, _) = planned_job(&dir, TRIANGLE);
            let key = split_key(&job, SplitId(0));
            let bytes = edit(store.get(&key).unwrap(), &text).expect("an edit that keeps bytes");
            vec![decode_split(&key, &bytes).unwrap_err().to_string()]
        }
        "block" => {
            let key = "jobs/bad-input/cast-reduce/00000/part-00000";
            let bytes = encode_surface_hits(RecordKind::Hit, &[hit()]);
            let (bytes, kind) = match text.strip_prefix("as ") {
                Some("ShadowQuery") => (bytes, RecordKind::ShadowQuery),
                Some(other) => panic!("unknown kind {other}"),
                None => (edit(bytes, &text).unwrap(), RecordKind::Hit),
            };
            let result = match kind {
                RecordKind::Hit => decode_surface_hits(key, &bytes, kind).map(|_| ()),
                _ => hort_core::pipeline::decode_queries(key, &bytes).map(|_| ()),
            };
            vec![result.unwrap_err().to_string()]
        }
        "job" => {
            let (object, run) = text
                .split_once("; run ")
                .expect("EDIT OBJECT; run STAGE TASK");
            // A lone triangle cannot shadow itself, so its job has no trace-map tasks: those
            // rows plan the triangle with a second one behind it.
            let obj = if run.starts_with("trace-map") {
                TWO_TRIANGLES
            } else {
                TRIANGLE
            };
            let (store, job, plan) = planned_job(&dir, obj);
            let (op, object) = object.rsplit_once(' ').expect("EDIT OBJECT");
            let key = match object {
                "split" => split_key(&job, SplitId(0)),
                _ => panic!("unknown object {object:?}"),
            };
            match edit(store.get(&key).unwrap(), op) {
                None => store.delete(&key).unwrap(),
                Some(bytes) => store.put(&key, &bytes).unwrap(),
            }
            let (stage_name, task) = run.split_once(' ').unwrap();
            let err = run_task(
                &store,
                &job,
                &plan,
                stage(stage_name),
                task.parse().unwrap(),
            )
            .unwrap_err();
            vec![format!("{}: {err}", err.error_type())]
        }
        "scene-bin" => vec![binary_scene_error(&dir, &text)],
        "asl" => {
            let options = asl_interpreter::OrchestratorOptions::default();
            match asl_interpreter::Orchestrator::new(&text, options) {
                Ok(_) => vec!["(the definition loaded)".to_owned()],
                Err(e) => vec![e.to_string()],
            }
        }
        other => panic!("line {}: unknown kind {other:?}", row.line),
    }
}

/// The Plan function's error for a one-triangle job stored as the emulator stores it (the
/// binary scene, `scene_format` `binary`), after `op` edited its `scene.bin`.
fn binary_scene_error(dir: &Path, op: &str) -> String {
    std::fs::write(dir.join("scene.obj"), TRIANGLE).unwrap();
    let scene = load_scene(&dir.join("scene.obj")).unwrap();
    let store = MemoryStore::new();
    let job = JobId::new("bad-input").unwrap();
    let request = JobRequest {
        scene: "scene.obj".into(),
        render: PlanRequest {
            width: 8,
            height: 6,
            spp: 1,
            splits: Some(1),
            spans: Some(1),
            mode: SplitMode::Spatial,
            execution: None,
            memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
            adaptive: None,
            outputs: StoredOutputs::ALL,
            frame: Default::default(),
        },
        max_concurrency: 1,
        task_timeout_seconds: None,
        scene_format: SceneFormat::Binary,
        scene_range_bytes: None,
        scene_key: None,
        budget: None,
    };
    let json = serde_json::to_vec(&request).unwrap();
    store.put(&manifest_key(&job), &json).unwrap();
    if let Some(bytes) = edit(binary_scene(&scene, "scene.obj"), op) {
        store.put(&scene_binary_key(&job), &bytes).unwrap();
    }
    let event = PlanEvent {
        job,
        bucket: "b".into(),
        attempt: 0,
        round: 1,
        step: PlanStep::Start,
    };
    handle_plan(&store, "b", &event, Tmp::unlimited(dir))
        .expect_err("an edit that breaks the scene")
        .to_string()
}

fn hit() -> SurfaceHit {
    let v = glam::Vec3::new(0.25, 0.25, 0.0);
    SurfaceHit {
        pixel: 3,
        sample: 0,
        t: 2.0,
        triangle: 0,
        surface: SurfacePoint {
            p: v,
            p_error: glam::Vec3::splat(1e-6),
            n_geo: glam::Vec3::Z,
            n_shade: glam::Vec3::Z,
            p_shadow: v,
            p_shadow_error: glam::Vec3::splat(1e-6),
            kd: [0.5; 3],
        },
    }
}

/// The API router's answer to a request, as `STATUS body`, over a fresh fake backend (no job,
/// no object).
fn http(input: &[u8]) -> String {
    use hort_functions::api::{fake::Fake, handle};
    let split = input.windows(2).position(|w| w == b"\n\n");
    let (head, body) = match split {
        Some(i) => (&input[..i], input[i + 2..].to_vec()),
        None => (input, Vec::new()),
    };
    let head = std::str::from_utf8(head).unwrap();
    let mut lines = head.split('\n');
    let (method, uri) = lines.next().unwrap().split_once(' ').unwrap();
    let mut builder = hyper::Request::builder().method(method).uri(uri);
    for line in lines {
        let (name, value) = line.split_once(':').unwrap();
        builder = builder.header(name.trim(), value.trim());
    }
    let response = handle(&Fake::default(), builder.body(body).unwrap());
    let body = String::from_utf8_lossy(response.body());
    format!("{} {}", response.status().as_u16(), body.trim_end())
}

#[test]
fn every_row_of_the_bad_input_table_is_what_the_user_sees() {
    let rows = rows();
    assert!(
        rows.len() >= 40,
        "docs/bad-input.md has {} rows",
        rows.len()
    );
    let mut wrong = Vec::new();
    for row in &rows {
        let seen = actual(row);
        if !seen.contains(&row.message) {
            wrong.push(format!(
                "docs/bad-input.md:{} ({}): the table says\n  {}\nbut the user sees\n  {}",
                row.line,
                row.kind,
                row.message,
                seen.join("\n  ")
            ));
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}
