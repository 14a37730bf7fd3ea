//! Submitting and resuming jobs over an in-memory store: what the client stores, and when a
//! resume is refused.

use super::upload::{Submitted, binary_scene, scene_files, submit_job, submit_or_resume};
use hort_core::ids::JobId;
use hort_core::pipeline::{PlanRequest, SplitMode, StoredOutputs};
use hort_core::scene::{Scene, decode_scene, load_scene};
use hort_core::store::{BlobStore, MemoryStore};
use hort_functions::handlers::{JobRequest, SceneFormat};
use std::path::{Path, PathBuf};

/// A fresh copy of the bundled Cornell room in a folder of its own (removed when the first
/// value drops); returns the folder and its main file.
fn cornell_copy() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let from = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell");
    for file in ["cornell.json", "cornell.obj", "cornell.mtl"] {
        std::fs::copy(from.join(file), dir.path().join(file)).unwrap();
    }
    let main = dir.path().join("cornell.json");
    (dir, main)
}

fn request(format: SceneFormat) -> JobRequest {
    JobRequest {
        scene: "cornell.json".into(),
        render: PlanRequest {
            width: 16,
            height: 12,
            spp: 1,
            splits: None,
            spans: None,
            mode: SplitMode::Spatial,
            execution: None,
            memory_mb: hort_core::pipeline::DEFAULT_MEMORY_MB,
            adaptive: None,
            outputs: StoredOutputs::ALL,
            frame: Default::default(),
        },
        max_concurrency: 2,
        task_timeout_seconds: None,
        scene_format: format,
        scene_range_bytes: None,
        scene_key: None,
        budget: None,
    }
}

fn job() -> JobId {
    JobId::new("j").unwrap()
}

fn load(main: &Path) -> Scene {
    load_scene(main).unwrap()
}

#[test]
fn a_binary_job_stores_only_the_parsed_scene_whatever_folder_it_came_from() {
    let ((_a_dir, a), (_b_dir, b)) = (cornell_copy(), cornell_copy());
    let (sa, sb) = (load(&a), load(&b));
    assert_ne!(sa.source, sb.source);
    let store = MemoryStore::new();
    submit_job(&store, &job(), &a, &sa, &request(SceneFormat::Binary)).unwrap();
    assert_eq!(
        store.list("jobs/j/").unwrap(),
        ["jobs/j/manifest.json", "jobs/j/scene/scene.bin"]
    );
    let stored = store.get("jobs/j/scene/scene.bin").unwrap();
    assert_eq!(stored, binary_scene(&sb, "cornell.json"));
    let decoded = decode_scene("scene.bin", &stored).unwrap();
    assert_eq!(decoded.source, PathBuf::from("cornell.json"));
    assert!(decoded.warnings.is_empty());
    assert_eq!(decoded.mesh.triangles, sa.mesh.triangles);
    // The same scene from another folder resumes the job.
    assert_eq!(
        submit_or_resume(
            &store,
            &job(),
            &b,
            Some(&sb),
            &request(SceneFormat::Binary),
            true,
            ""
        )
        .unwrap(),
        Submitted::Resumed
    );
    // A resumed job whose scene.bin was deleted gets it back.
    store.delete("jobs/j/scene/scene.bin").unwrap();
    submit_or_resume(
        &store,
        &job(),
        &b,
        Some(&sb),
        &request(SceneFormat::Binary),
        true,
        "",
    )
    .unwrap();
    assert_eq!(store.get("jobs/j/scene/scene.bin").unwrap(), stored);
}

#[test]
fn a_changed_scene_does_not_resume_and_a_files_job_resumes_with_its_files() {
    let (_dir, main) = cornell_copy();
    let store = MemoryStore::new();
    submit_job(
        &store,
        &job(),
        &main,
        &load(&main),
        &request(SceneFormat::Binary),
    )
    .unwrap();
    let mtl = main.with_file_name("cornell.mtl");
    let text = std::fs::read_to_string(&mtl).unwrap();
    std::fs::write(&mtl, text.replacen("Kd ", "Kd 0.5 0.5 0.5\n#", 1)).unwrap();
    let changed = load(&main);
    let e = submit_or_resume(
        &store,
        &job(),
        &main,
        Some(&changed),
        &request(SceneFormat::Binary),
        true,
        "",
    )
    .unwrap_err()
    .to_string();
    assert_eq!(
        e,
        format!(
            "cannot resume job \"j\": {} changed since the job started; run `hort jobs clean \
             --job j` to delete it, or choose another --job id",
            main.display()
        )
    );

    // A job started with the files (an older client) is resumed with the files.
    let (_dir, main) = cornell_copy();
    let store = MemoryStore::new();
    let scene = load(&main);
    submit_job(&store, &job(), &main, &scene, &request(SceneFormat::Files)).unwrap();
    let keys = [
        "jobs/j/manifest.json",
        "jobs/j/scene/cornell.json",
        "jobs/j/scene/cornell.mtl",
        "jobs/j/scene/cornell.obj",
    ];
    assert_eq!(store.list("jobs/j/").unwrap(), keys);
    let resumed = submit_or_resume(
        &store,
        &job(),
        &main,
        Some(&scene),
        &request(SceneFormat::Binary),
        true,
        "",
    );
    assert_eq!(resumed.unwrap(), Submitted::Resumed);
    assert_eq!(store.list("jobs/j/").unwrap(), keys);
}

#[test]
fn scene_files_are_the_obj_and_the_libraries_its_mtllib_lines_name() {
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path();
    for lib in ["a.mtl", "b.mtl", "c.mtl", "d.mtl", "e.mtl"] {
        std::fs::write(dir.join(lib), "newmtl m\nKd 1 1 1\n").unwrap();
    }
    // Indented and tab-separated `mtllib` lines count, with every library they name; a word
    // that only starts with "mtllib", a comment, and a library that is not there do not; a
    // line of invalid UTF-8 is skipped, not an error. A library is listed once.
    let mut obj = b"v 0 0 0\n \tmtllib a.mtl\tb.mtl\nmtllibx c.mtl\n# mtllib d.mtl\n\
        \xff\xfe mtllib\nmtllib missing.mtl\n"
        .to_vec();
    // The file is read a megabyte at a time: one `mtllib` line straddles the first boundary,
    // a line of three megabytes follows, and the last line has no newline.
    while obj.len() < (1 << 20) - 4 {
        obj.extend_from_slice(b"v 0 0 0\n");
    }
    obj.truncate((1 << 20) - 4);
    obj.extend_from_slice(b"\nmtllib e.mtl\r\nf 1 1 1\n# ");
    obj.extend(std::iter::repeat_n(b'x', 3 << 20));
    obj.extend_from_slice(b" mtllib d.mtl\nmtllib c.mtl");
    std::fs::write(dir.join("m.obj"), obj).unwrap();
    let files = scene_files(&dir.join("m.obj")).unwrap();
    assert_eq!(
        files,
        ["m.obj", "a.mtl", "b.mtl", "e.mtl", "c.mtl"].map(PathBuf::from),
        "{files:?}"
    );
}

/// A scene's files include the diffuse textures its libraries name (each once, beside the
/// library that names it); nothing else of the folder.
#[test]
fn scene_files_include_the_diffuse_textures_of_the_libraries() {
    let globe = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/globe/globe.json");
    assert_eq!(
        scene_files(&globe).unwrap(),
        [
            "globe.json",
            "globe.obj",
            "globe.mtl",
            "globe.png",
            "tiles.png"
        ]
        .map(PathBuf::from)
    );
}

/// A library or texture named by an absolute path leaves the scene's folder wherever the file
/// naming it lies: refused, naming it.
#[test]
fn an_absolute_library_is_outside_the_scene_folder() {
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path();
    std::fs::create_dir_all(dir.join("m")).unwrap();
    std::fs::write(dir.join("s.json"), r#"{"meshes": ["m/a.obj"]}"#).unwrap();
    std::fs::write(dir.join("m/a.obj"), "mtllib /etc/hort-none.mtl\nv 0 0 0\n").unwrap();
    let main = dir.join("s.json");
    let e = scene_files(&main).unwrap_err().to_string();
    assert_eq!(
        e,
        format!(
            "{}: the scene file /etc/hort-none.mtl is outside the scene's folder; the emulator \
             uploads the folder's files only",
            main.display()
        )
    );
}
