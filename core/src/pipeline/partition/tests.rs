use super::*;
use crate::bvh::BuildPreset;
use crate::ids::{JobId, SplitId};
use crate::keys::{parts_table_key, scene_prefix, split_key};
use crate::pipeline::{
    ExecutionMode, JobPlan, PlanRequest, SplitMode, StoredOutputs, plan_into_store, read_outputs,
    run_task,
};
use crate::scene::load_scene;
use crate::store::{BlobStore, MemoryStore};
use std::path::{Path, PathBuf};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)
}

fn request(splits: u32, execution: Option<ExecutionMode>) -> PlanRequest {
    PlanRequest {
        width: 40,
        height: 30,
        spp: 2,
        splits: Some(splits),
        spans: Some(3),
        mode: SplitMode::Spatial,
        execution,
        memory_mb: crate::pipeline::DEFAULT_MEMORY_MB,
        adaptive: None,
        outputs: StoredOutputs::ALL,
        frame: Default::default(),
    }
}

/// Stores the scene's files under the job's scene prefix, as a client does.
fn upload(store: &dyn BlobStore, job: &JobId, main: &Path) {
    let dir = main.parent().unwrap();
    for file in std::fs::read_dir(dir).unwrap() {
        let path = file.unwrap().path();
        if path.is_file() {
            let name = path.file_name().unwrap().to_string_lossy();
            let key = format!("{}{name}", scene_prefix(job));
            store.put(&key, &std::fs::read(&path).unwrap()).unwrap();
        }
    }
}

/// The five steps of a scene split by tasks, with ranges of `range_bytes`.
fn plan_by_parts(
    store: &dyn BlobStore,
    job: &JobId,
    main: &Path,
    range_bytes: u64,
    request: &PlanRequest,
) -> JobPlan {
    upload(store, job, main);
    let table = scan_scene(store, job, main.parent().unwrap(), main, range_bytes).unwrap();
    for range in 0..table.ranges.len() as u32 {
        partition_range(store, job, range).unwrap();
    }
    let (cut, _) = cut_scene(store, job, request).unwrap();
    for split in 0..cut.splits.len() as u32 {
        build_split_from_parts(store, job, split).unwrap();
    }
    plan_from_parts(store, job, main, request).unwrap().plan
}

fn run_all(store: &dyn BlobStore, job: &JobId, plan: &JobPlan) -> crate::pipeline::JobOutputs {
    for &stage in plan.task_stages() {
        for task in 0..plan.task_count(stage) as u32 {
            run_task(store, job, plan, stage, task).unwrap();
        }
    }
    read_outputs(store, job, plan).unwrap()
}

/// A fresh scratch folder for one test, `hort-parts-{name}-XXXXXX`, removed when dropped.
fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("hort-parts-{name}-"))
        .tempdir()
        .unwrap()
}

fn bits(image: &crate::image::Image) -> Vec<u32> {
    image
        .pixels
        .iter()
        .flat_map(|p| p.map(f32::to_bits))
        .collect()
}

/// A scene whose faces name vertices ranges back (absolute and negative indices), normals,
/// quads, materials switched mid-file from two libraries, and a byte-order mark.
fn tricky_scene(dir: &Path) -> PathBuf {
    std::fs::write(
        dir.join("a.mtl"),
        "newmtl red\nKd 0.8 0.1 0.1\nnewmtl blue\nKd 0.1 0.2 0.9\n",
    )
    .unwrap();
    let mut obj = String::from("\u{feff}# tricky\nmtllib a.mtl\n");
    for i in 0..40 {
        let (x, z) = (f64::from(i % 8) * 1.5, f64::from(i / 8) * 1.5);
        obj += &format!(
            "v {x} 0 {z}\nv {} 0 {z}\nv {x} 1.25 {}\nv {} 1 {}\n",
            x + 1.0,
            z + 0.5,
            x + 1.0,
            z + 0.25
        );
        obj += &format!("vn 0 1 0\nvn 0.{i} 1 0\n");
    }
    obj += "usemtl red\n";
    for i in 0..40u32 {
        let b = 4 * i + 1;
        if i % 3 == 0 {
            obj += &format!(
                "f {b}//{} {}//{} {}//{} {}//{}\n",
                2 * i + 1,
                b + 1,
                2 * i + 2,
                b + 3,
                2 * i + 1,
                b + 2,
                2 * i + 2
            );
        } else {
            obj += &format!("f {} {} {}\n", b, b + 1, b + 2);
        }
        if i == 17 {
            obj += "usemtl blue\nusemtl nothing\n";
        }
        if i == 25 {
            obj += "usemtl blue\n";
        }
    }
    obj += "v 4 3 4\nv 5 3 4\nv 4 3 5\nf -3 -2 -1\nf 1 -1 2\n";
    let path = dir.join("tricky.obj");
    std::fs::write(&path, obj).unwrap();
    path
}

#[test]
fn one_split_built_by_tasks_is_byte_for_byte_the_in_memory_split() {
    let tmp = scratch("one-split");
    let dir = tmp.path();
    let tricky = tricky_scene(dir);
    // One line per range, and a few ranges, for the small scene; larger ranges for the rest.
    let cases = [
        (tricky, vec![1, 200, 1 << 30]),
        (repo("scenes/bunny/bunny.json"), vec![100_000, 1 << 30]),
        (repo("scenes/cornell/cornell.json"), vec![300, 1 << 30]),
    ];
    for (main, sizes) in cases {
        for range_bytes in sizes {
            let whole = MemoryStore::new();
            let parts = MemoryStore::new();
            let job = JobId::new("j").unwrap();
            let scene = load_scene(&main).unwrap();
            let req = request(1, Some(ExecutionMode::Fused));
            let expected = plan_into_store(&whole, &job, &scene, &req).unwrap().plan;
            let mut plan = plan_by_parts(&parts, &job, &main, range_bytes, &req);
            let key = split_key(&job, SplitId(0));
            let what = format!("{} in ranges of {range_bytes} bytes", main.display());
            // The plan also records the scan's shape, for the prediction models: the files'
            // bytes, in ranges of at most range_bytes (a line longer than a range is its own).
            let shape = plan.scene_parts.take().expect("a plan made from parts");
            let files: u64 = crate::scene::scene_mesh_files(&main)
                .unwrap()
                .iter()
                .map(|f| std::fs::metadata(f).unwrap().len())
                .sum();
            assert_eq!(shape.scene_bytes, files, "{what}");
            let table: PartsTable = read_json(&parts, &parts_table_key(&job)).unwrap();
            assert_eq!(shape.ranges as usize, table.ranges.len(), "{what}");
            assert!(
                whole.get(&key).unwrap() == parts.get(&key).unwrap(),
                "{what}"
            );
            assert_eq!(
                serde_json::to_value(&plan).unwrap(),
                serde_json::to_value(&expected).unwrap(),
                "{what}"
            );
        }
    }
}

#[test]
fn staged_jobs_split_by_tasks_render_the_monolithic_image() {
    let tmp = scratch("staged");
    let dir = tmp.path();
    let tricky = tricky_scene(dir);
    for (main, k) in [
        (tricky, 3),
        (repo("scenes/bunny/bunny.json"), 4),
        (repo("scenes/teapot/teapot.json"), 2),
    ] {
        let whole = MemoryStore::new();
        let parts = MemoryStore::new();
        let job = JobId::new("j").unwrap();
        let scene = load_scene(&main).unwrap();
        let req = request(k, Some(ExecutionMode::Staged));
        let expected_plan = plan_into_store(&whole, &job, &scene, &req).unwrap().plan;
        let expected = run_all(&whole, &job, &expected_plan);
        let plan = plan_by_parts(&parts, &job, &main, 2048, &req);
        assert_eq!(plan.splits.len(), k as usize);
        let sizes: Vec<u64> = plan.splits.iter().map(|s| s.triangles).collect();
        let n = scene.mesh.triangle_count() as u64;
        assert_eq!(sizes.iter().sum::<u64>(), n);
        assert!(
            sizes
                .iter()
                .all(|&s| s == n / u64::from(k) || s == n / u64::from(k) + 1),
            "{sizes:?}"
        );
        let got = run_all(&parts, &job, &plan);
        assert_eq!(
            bits(got.image.as_ref().expect("the linear image")),
            bits(expected.image.as_ref().expect("the linear image")),
            "{}",
            main.display()
        );
        assert_eq!(got.hits, expected.hits, "{}", main.display());
    }
}

#[test]
fn a_bad_scene_is_refused_by_the_scan_with_the_whole_load_error() {
    let tmp = scratch("bad");
    let dir = tmp.path();
    let main = dir.join("bad.obj");
    std::fs::write(&main, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 7\n").unwrap();
    let whole = load_scene(&main).unwrap_err().to_string();
    let store = MemoryStore::new();
    let job = JobId::new("j").unwrap();
    let scan = scan_scene(&store, &job, dir, &main, 8)
        .unwrap_err()
        .to_string();
    assert_eq!(scan, whole);
    assert!(scan.contains("bad.obj:5"), "{scan}");
}

#[test]
fn cuts_take_equal_runs_of_bucket_then_id_order() {
    let index = |buckets: Vec<(u32, u64)>| PartIndex {
        records: buckets.iter().map(|b| b.1).sum(),
        buckets,
        frames: vec![0, 1],
        used: Some(([0.0; 3], [2.0, 4.0, 6.0])),
    };
    let store = MemoryStore::new();
    let job = JobId::new("j").unwrap();
    // Order: bucket 1 (range 0: 3, range 1: 2), bucket 2 (range 1: 1), bucket 5 (range 0: 4).
    let indexes = [index(vec![(1, 3), (5, 4)]), index(vec![(1, 2), (2, 1)])];
    let cut = cut_splits(&store, &job, &indexes, 3, BuildPreset::Quality).unwrap();
    let run = |range, start, end| RecordRun { range, start, end };
    assert_eq!(cut.origin, [1.0, 2.0, 3.0]);
    assert_eq!(
        cut.splits,
        vec![vec![run(0, 0, 3)], vec![run(1, 0, 3)], vec![run(0, 3, 7)],]
    );
    assert_eq!(
        cut_splits(&store, &job, &indexes, 11, BuildPreset::Quality)
            .unwrap_err()
            .to_string(),
        "cannot cut 10 triangles into 11 splits"
    );
}

#[test]
fn a_build_task_recomputes_lost_or_damaged_partitions_from_their_lineage() {
    let tmp = scratch("lineage");
    let dir = tmp.path();
    let main = tricky_scene(dir);
    let req = request(2, Some(ExecutionMode::Staged));
    let job = JobId::new("j").unwrap();
    let clean = MemoryStore::new();
    plan_by_parts(&clean, &job, &main, 200, &req);
    let damaged = MemoryStore::new();
    upload(&damaged, &job, &main);
    let table = scan_scene(&damaged, &job, dir, &main, 200).unwrap();
    assert!(table.ranges.len() > 3, "{} ranges", table.ranges.len());
    for range in 0..table.ranges.len() as u32 {
        partition_range(&damaged, &job, range).unwrap();
    }
    cut_scene(&damaged, &job, &req).unwrap();
    use crate::keys::{parts_index_key, parts_records_key};
    let with_faces: Vec<u32> = (0..table.ranges.len() as u32)
        .filter(|&r| table.ranges[r as usize].obj.triangle_count > 0)
        .collect();
    assert!(with_faces.len() >= 3, "{with_faces:?}");
    damaged
        .delete(&parts_records_key(&job, with_faces[0]))
        .unwrap();
    let mut bytes = damaged
        .get(&parts_records_key(&job, with_faces[1]))
        .unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 0x55;
    damaged
        .put(&parts_records_key(&job, with_faces[1]), &bytes)
        .unwrap();
    damaged
        .delete(&parts_index_key(&job, with_faces[2]))
        .unwrap();
    for split in 0..2 {
        build_split_from_parts(&damaged, &job, split).unwrap();
        let key = split_key(&job, SplitId(split));
        assert!(
            damaged.get(&key).unwrap() == clean.get(&key).unwrap(),
            "split {split}"
        );
    }
}
