//! A job's objects from the client's side: submitting a job (the scene and the job request go
//! to storage, as a client of the cloud deployment would upload them before starting an
//! execution), resuming a stopped one, listing the jobs of a bucket, and deleting a job's
//! objects or only its intermediates.
//!
//! The scene goes up parsed: the client has loaded it already (to check it, frame it and size
//! the job), so it stores the binary scene `jobs/{job}/scene/scene.bin` ([`binary_scene`]) and
//! a job request with `scene_format` `binary`, and no function parses the files again (the Plan
//! function decodes it; so does a Worker rebuilding a lost split or plan). The original files
//! are not uploaded: nothing reads them, and the binary scene is what lineage rebuilds from.
//! A stopped job started with the files (`scene_format` `files`) is resumed with the files.
//!
//! What stays after a successful job (unless `--keep-intermediates`): `manifest.json` (the job
//! request: the job's identity, so the id stays taken and `hort jobs list` shows the job),
//! `plan.json` (small; needed to read the outputs back) and everything under `out/`. Deleted:
//! `scene/` (the client's copy of the scene), `splits/`, `items/` and every stage's shuffle
//! partitions.
//!
//! Resuming (`--resume`) reruns the state machine over the objects a stopped run left: the plan
//! step runs again (deterministic: it rewrites the same bytes), and every later task whose
//! output partitions all exist is skipped, since a task's outputs are a pure function of the
//! plan and its inputs and a PUT is all or nothing. Tasks with some or none of their outputs
//! run again and rewrite the same bytes. Combine always runs.

use anyhow::{Context, Result, bail};
use asl_interpreter::{TaskFailure, TaskInvoker};
use hort_core::ids::{JobId, PartitionId, TaskId};
use hort_core::keys::{
    FrameKeys, image_key, kept_after_success, manifest_key, partition_key, parts_index_key,
    parts_split_info_key, plan_key, scene_binary_key, scene_prefix,
};
use hort_core::pipeline::{JobPlan, PlanRequest, StoredOutputs, TaskMetrics};
use hort_core::scene::files::{SceneFileKind, SceneFileSource, walk_scene_files};
use hort_core::scene::{Scene, diffuse_map_files, encode_scene_named, parse_manifest};
use hort_core::stage::Stage;
use hort_core::store::{BlobStore, PutOutcome, StoreError};
use hort_functions::S3Store;
use hort_functions::handlers::{JobRequest, SceneFormat, WorkerEvent};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};
use std::sync::Arc;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// The scene's files relative to the main file's folder: the main file, the OBJ files a
/// manifest names, the material libraries the OBJ files name and the diffuse textures the
/// libraries name.
pub fn scene_files(main: &Path) -> Result<Vec<PathBuf>> {
    let base = main.parent().unwrap_or(Path::new("."));
    let name = main
        .file_name()
        .context("the scene path names no file")?
        .to_string_lossy()
        .into_owned();
    let mut local = LocalScene {
        main,
        base,
        files: Vec::new(),
    };
    walk_scene_files(&name, &mut local)?;
    for f in &local.files {
        if !f.components().all(|c| matches!(c, Component::Normal(_))) {
            bail!(
                "{}: the scene file {} is outside the scene's folder; the emulator uploads the folder's files only",
                main.display(),
                f.display()
            );
        }
    }
    Ok(local.files)
}

/// [`scene_files`]' side of the scene walk: the files found in the main file's folder `base`.
struct LocalScene<'a> {
    /// The main file, as given (messages name it so).
    main: &'a Path,
    base: &'a Path,
    /// The files, relative to `base`, in the walk's order.
    files: Vec<PathBuf>,
}

impl SceneFileSource for LocalScene<'_> {
    type Error = anyhow::Error;

    fn take_main(&mut self, main: &str) -> Result<()> {
        self.files.push(PathBuf::from(main));
        Ok(())
    }

    fn manifest_meshes(&mut self, _main: &str) -> Result<Vec<String>> {
        let text = std::fs::read_to_string(self.main)
            .with_context(|| format!("cannot read {}", self.main.display()))?;
        Ok(parse_manifest(&text, self.main)?.meshes)
    }

    /// An absolute name leaves the folder wherever it is written; the other names are checked
    /// once the walk is done (every file inside the folder).
    fn check_name(&mut self, name: &str, _kind: SceneFileKind, _named_by: &str) -> Result<()> {
        if Path::new(name).is_absolute() {
            bail!(
                "{}: the scene file {name} is outside the scene's folder; the emulator uploads the folder's files only",
                self.main.display()
            );
        }
        Ok(())
    }

    fn take_mesh(&mut self, mesh: &str) -> Result<()> {
        self.files.push(PathBuf::from(mesh));
        Ok(())
    }

    fn mesh_libraries(&mut self, mesh: &str) -> Result<Vec<String>> {
        let path = self.base.join(mesh);
        material_libraries(&path).with_context(|| format!("cannot read {}", path.display()))
    }

    fn take_library(&mut self, library: &str) -> Result<Option<Vec<String>>> {
        let path = self.base.join(library);
        if !path.is_file() {
            return Ok(None);
        }
        let text =
            std::fs::read(&path).with_context(|| format!("cannot read {}", path.display()))?;
        self.files.push(PathBuf::from(library));
        Ok(Some(diffuse_map_files(&String::from_utf8_lossy(&text))))
    }

    fn take_texture(&mut self, texture: &str) -> Result<()> {
        if self.base.join(texture).is_file() {
            self.files.push(PathBuf::from(texture));
        }
        Ok(())
    }
}

/// The names on the `mtllib` lines of the OBJ file at `path`, in order. The file is read in
/// chunks and searched for the word (an OBJ can be gigabytes, and its size is what this is
/// asked for): only lines whose first word is `mtllib` are decoded, as UTF-8 with invalid
/// bytes replaced, and split on ASCII whitespace as the OBJ parser splits them.
fn material_libraries(path: &Path) -> std::io::Result<Vec<String>> {
    const CHUNK: usize = 1 << 20;
    let mut file = std::fs::File::open(path)?;
    let finder = memchr::memmem::Finder::new(b"mtllib");
    let mut names = Vec::new();
    let mut take_line = |line: &[u8]| {
        let line = String::from_utf8_lossy(line);
        let mut words = line.split_ascii_whitespace();
        if words.next() == Some("mtllib") {
            names.extend(words.map(str::to_owned));
        }
    };
    // `buf[..held]` starts at a line's start; lines are searched once they end (or at EOF).
    let mut buf = vec![0u8; CHUNK];
    let mut held = 0;
    loop {
        if held == buf.len() {
            buf.resize(2 * buf.len(), 0); // one line longer than the buffer
        }
        let read = std::io::Read::read(&mut file, &mut buf[held..])?;
        let end = held + read;
        let whole = if read == 0 {
            end
        } else {
            match memchr::memrchr(b'\n', &buf[held..end]) {
                Some(last) => held + last + 1,
                None => {
                    held = end;
                    continue;
                }
            }
        };
        let lines = &buf[..whole];
        let mut searched = 0;
        while let Some(at) = finder.find(&lines[searched..]).map(|i| searched + i) {
            let start = memchr::memrchr(b'\n', &lines[..at]).map_or(0, |i| i + 1);
            let stop = memchr::memchr(b'\n', &lines[at..]).map_or(lines.len(), |i| at + i);
            if lines[start..at].iter().all(u8::is_ascii_whitespace) {
                take_line(&lines[start..stop]);
            }
            searched = stop;
        }
        if read == 0 {
            return Ok(names);
        }
        buf.copy_within(whole..end, 0);
        held = end - whole;
    }
}

/// The binary scene the client stores for `scene`, loaded from a main file named `main_name`:
/// [`encode_scene_named`] of the scene with `source` set to `main_name` (the name the job request
/// gives it) and without its warnings (the client showed them). So its bytes depend on the
/// scene files' contents and the main file's name only, not on the folder the client ran in,
/// and a resumed job can compare them.
pub fn binary_scene(scene: &Scene, main_name: &str) -> Vec<u8> {
    encode_scene_named(scene, main_name)
}

/// Uploads the scene (`scene`, loaded from `main`, in `request.scene_format`) and creates the
/// job request (once: a second submission of the same job id is an error, as the request is
/// the job's identity).
pub fn submit_job(
    store: &dyn BlobStore,
    job: &JobId,
    main: &Path,
    scene: &Scene,
    request: &JobRequest,
) -> Result<()> {
    submit_or_resume(store, job, main, Some(scene), request, false, "").map(drop)
}

/// How [`submit_or_resume`] went.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Submitted {
    /// A new job: the scene and the job request were stored.
    New,
    /// A stopped job of the same request and scene, to be continued.
    Resumed,
}

/// One object of a job's scene: its key, its bytes, and the file it stands for (in messages).
struct SceneObject {
    key: String,
    bytes: Vec<u8>,
    file: PathBuf,
}

/// The objects that store `scene` (loaded from `main`) in `format`: the binary scene, or the
/// scene's files ([`scene_files`]) under `jobs/{job}/scene/`.
fn scene_objects(
    job: &JobId,
    main: &Path,
    scene: Option<&Scene>,
    request: &JobRequest,
    format: SceneFormat,
) -> Result<Vec<SceneObject>> {
    if format == SceneFormat::Binary {
        let scene = scene.context("a job of the binary scene format needs the loaded scene")?;
        return Ok(vec![SceneObject {
            key: scene_binary_key(job),
            bytes: binary_scene(scene, &request.scene),
            file: main.to_path_buf(),
        }]);
    }
    let base = main.parent().unwrap_or(Path::new("."));
    let prefix = scene_prefix(job);
    scene_files(main)?
        .into_iter()
        .map(|rel| {
            let file = base.join(&rel);
            let bytes =
                std::fs::read(&file).with_context(|| format!("cannot read {}", file.display()))?;
            Ok(SceneObject {
                key: scene_key(&prefix, &rel),
                bytes,
                file,
            })
        })
        .collect()
}

/// Submits a new job (storing `scene`, loaded from `main`, as `request.scene_format` says; the
/// `files` format needs no loaded scene), or
/// with `resume` checks that the stopped job `job` has the same request and scene (stored in
/// the format it was started with) and continues it. A job id that exists is an error without
/// `resume` (the message suggests `--resume`, `hort jobs clean` with `flags`, the storage flags
/// as [`super::StorageTarget::flags`] gives them, or another id); so is resuming a job that
/// does not exist, that finished, or whose request or scene differ.
pub fn submit_or_resume(
    store: &dyn BlobStore,
    job: &JobId,
    main: &Path,
    scene: Option<&Scene>,
    request: &JobRequest,
    resume: bool,
    flags: &str,
) -> Result<Submitted> {
    let stored = match store.get(&manifest_key(job)) {
        Ok(bytes) => Some(bytes),
        Err(StoreError::NotFound { .. }) => None,
        Err(e) => return Err(e.into()),
    };
    let clean = format!("`hort jobs clean --job {job}{flags}`");
    let Some(stored) = stored else {
        if resume {
            bail!("job \"{job}\" does not exist in this bucket: there is nothing to resume");
        }
        // A scene by key is copied into the job by the Plan function.
        if request.scene_key.is_none() {
            for object in scene_objects(job, main, scene, request, request.scene_format)? {
                store.put(&object.key, &object.bytes)?;
            }
        }
        let json = serde_json::to_vec_pretty(request).context("job request")?;
        return match store.put_if_absent(&manifest_key(job), &json)? {
            PutOutcome::Created => Ok(Submitted::New),
            // Our own write whose answer was lost (a reset connection): the client's retry
            // found it. Same bytes mean same job request, so the job is ours to run.
            PutOutcome::AlreadyExists if store.get(&manifest_key(job))? == json => {
                Ok(Submitted::New)
            }
            PutOutcome::AlreadyExists => bail!(
                "job \"{job}\" already exists in this bucket: add --resume to continue it, run \
                 {clean} to delete it, or choose another --job id"
            ),
        };
    };
    if is_finished(&store.list(&format!("jobs/{job}/out/"))?, job) {
        bail!(
            "job \"{job}\" already exists in this bucket and finished (its outputs are under \
             jobs/{job}/out/): run {clean} to delete it, or choose another --job id"
        );
    }
    if !resume {
        bail!(
            "job \"{job}\" already exists in this bucket and did not finish: add --resume to \
             continue it, run {clean} to delete it, or choose another --job id"
        );
    }
    let stored: JobRequest = serde_json::from_slice(&stored)
        .with_context(|| format!("cannot resume job \"{job}\": its job request"))?;
    // Which outputs are stored is not a setting of the tasks before Combine: a resume may ask
    // for fewer (the stored request still governs), not for more.
    let settings = |r: &JobRequest| PlanRequest {
        outputs: StoredOutputs::ALL,
        ..r.render
    };
    if stored.scene != request.scene || settings(&stored) != settings(request) {
        bail!(
            "cannot resume job \"{job}\": it was started with other settings (scene {}, {}x{} \
             at {} spp, splits {}, spans {}, split mode {}); resume it with those, or run {clean} \
             to delete it",
            stored.scene,
            stored.render.width,
            stored.render.height,
            stored.render.spp,
            count(stored.render.splits),
            count(stored.render.spans),
            serde_json::to_value(stored.render.mode)
                .ok()
                .and_then(|v| v.as_str().map(str::to_owned))
                .unwrap_or_default(),
        );
    }
    let (had, asked) = (stored.render.outputs, request.render.outputs);
    let missing: Vec<&str> = [
        (asked.linear && !had.linear).then_some("its linear image (an --out other than .png)"),
        (asked.hits && !had.hits).then_some("its hit buffer (--hits)"),
    ]
    .into_iter()
    .flatten()
    .collect();
    if !missing.is_empty() {
        bail!(
            "cannot resume job \"{job}\": it was started without storing {}; resume it without \
             asking for that, or run {clean} to delete it",
            missing.join(" or ")
        );
    }
    // The scene as the job stored it: the functions read it in the stored request's format.
    for object in scene_objects(job, main, scene, &stored, stored.scene_format)? {
        match store.get(&object.key) {
            Ok(old) if old == object.bytes => {}
            Ok(_) => bail!(
                "cannot resume job \"{job}\": {} changed since the job started; run {clean} to \
                 delete it, or choose another --job id",
                object.file.display()
            ),
            // Deleted meanwhile: the plan step needs it again.
            Err(StoreError::NotFound { .. }) => store.put(&object.key, &object.bytes)?,
            Err(e) => return Err(e.into()),
        }
    }
    Ok(Submitted::Resumed)
}

fn scene_key(prefix: &str, rel: &Path) -> String {
    format!("{prefix}{}", rel.to_string_lossy().replace('\\', "/"))
}

fn count(n: Option<u32>) -> String {
    n.map_or_else(|| "automatic".to_owned(), |n| n.to_string())
}

/// True if `keys` hold what Combine stores last for `job`, its PNG: then every output the job
/// asked for is there.
fn is_finished(keys: &[String], job: &JobId) -> bool {
    keys.contains(&image_key(job, "png"))
}

/// Objects deleted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Deleted {
    /// How many.
    pub objects: u64,
    /// Their bytes.
    pub bytes: u64,
}

/// Deletes the intermediate objects of `job` (everything but what [`kept_after_success`]
/// keeps).
pub fn delete_intermediates(store: &S3Store, job: &JobId) -> Result<Deleted> {
    let objects = store.list_sizes(&format!("jobs/{job}/"))?;
    let doomed: Vec<_> = objects
        .into_iter()
        .filter(|o| !kept_after_success(job, &o.key))
        .collect();
    delete_objects(store, doomed)
}

/// Deletes every object of `job`.
pub fn delete_job(store: &S3Store, job: &str) -> Result<Deleted> {
    delete_objects(store, store.list_sizes(&format!("jobs/{job}/"))?)
}

fn delete_objects(
    store: &S3Store,
    objects: Vec<hort_functions::s3_store::ListedObject>,
) -> Result<Deleted> {
    let deleted = Deleted {
        objects: objects.len() as u64,
        bytes: objects.iter().map(|o| o.bytes).sum(),
    };
    let keys: Vec<String> = objects.into_iter().map(|o| o.key).collect();
    store.delete_all(&keys)?;
    Ok(deleted)
}

/// One job of a bucket, as `hort jobs list` shows it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JobSummary {
    /// The job id (the folder name under `jobs/`).
    pub job: String,
    /// True if Combine finished (its PNG, stored last, is there).
    pub finished: bool,
    /// Objects under `jobs/{job}/`.
    pub objects: u64,
    /// Their bytes.
    pub bytes: u64,
}

/// Every job with objects under `jobs/`, by id.
pub fn list_jobs(store: &S3Store) -> Result<Vec<JobSummary>> {
    let mut jobs: BTreeMap<String, (Vec<String>, u64)> = BTreeMap::new();
    for object in store.list_sizes("jobs/")? {
        let Some(job) = object
            .key
            .strip_prefix("jobs/")
            .and_then(|rest| rest.split_once('/'))
            .map(|(job, _)| job.to_owned())
        else {
            continue;
        };
        let entry = jobs.entry(job).or_default();
        entry.0.push(object.key);
        entry.1 += object.bytes;
    }
    Ok(jobs
        .into_iter()
        .map(|(job, (keys, bytes))| JobSummary {
            finished: JobId::new(job.clone()).is_ok_and(|id| is_finished(&keys, &id)),
            objects: keys.len() as u64,
            bytes,
            job,
        })
        .collect())
}

/// Wraps the functions of a resumed job: a Worker task whose output partitions all exist is
/// not run again (its answer is empty metrics); every other invocation goes to `inner`.
pub struct SkipFinishedTasks {
    inner: Arc<dyn TaskInvoker>,
    store: Arc<dyn BlobStore>,
    job: JobId,
    plan: Mutex<Option<Arc<JobPlan>>>,
    /// Tasks skipped so far.
    pub skipped: AtomicU64,
}

impl SkipFinishedTasks {
    /// Skips the finished tasks of `job` in `store`, running the rest with `inner`.
    pub fn new(inner: Arc<dyn TaskInvoker>, store: Arc<dyn BlobStore>, job: JobId) -> Self {
        SkipFinishedTasks {
            inner,
            store,
            job,
            plan: Mutex::new(None),
            skipped: AtomicU64::new(0),
        }
    }

    /// The stored plan, read once (the plan step has run again by the time a Worker runs).
    fn plan(&self) -> Option<Arc<JobPlan>> {
        let mut cached = self.plan.lock().unwrap_or_else(|e| e.into_inner());
        if cached.is_none() {
            let key = plan_key(&self.job);
            let bytes = self.store.get(&key).ok()?;
            *cached = Some(Arc::new(JobPlan::from_json(&key, &bytes).ok()?));
        }
        cached.clone()
    }

    /// The partitions task `task` of `stage` writes; `None` for Plan and Combine (never
    /// skipped) and for tasks the plan does not have.
    fn outputs(&self, stage: Stage, frame: Option<u32>, task: u32) -> Option<Vec<String>> {
        let job_plan = self.plan()?;
        let plan = job_plan.frame_view(frame).ok()?;
        // Round 2 of a staged adaptive job has its own task ids (`JobPlan::round_of`).
        let (round, index) = plan.round_of(stage, task)?;
        let parts: Vec<u32> = match stage {
            Stage::CastMap => {
                let span = plan.cast_tasks.get(index as usize)?.span;
                vec![plan.round_task(Stage::CastReduce, span, round)]
            }
            Stage::TraceMap => {
                let span = plan.trace_tasks.get(index as usize)?.span;
                vec![plan.round_task(Stage::TraceReduce, span, round)]
            }
            // Round 1 of an adaptive job also writes the span's refine list.
            Stage::TraceReduce if round == 1 && plan.has_second_round() => vec![0, 1],
            Stage::CastReduce | Stage::TraceReduce | Stage::Render => vec![0],
            Stage::Expand => (0..plan.k()).collect(),
            _ => return None,
        };
        let scope = FrameKeys {
            job: &self.job,
            frame,
        };
        Some(
            parts
                .into_iter()
                .map(|p| partition_key(&scope, stage, TaskId(task), PartitionId(p)))
                .collect(),
        )
    }

    /// True if every output partition of the task exists; for the partition and build tasks of
    /// a scene split by tasks, if the object each writes last exists (its index, its split's
    /// summary).
    fn finished(&self, stage: Stage, frame: Option<u32>, task: u32) -> bool {
        let last = match stage {
            Stage::Partition => Some(parts_index_key(&self.job, task)),
            Stage::Build => Some(parts_split_info_key(&self.job, task)),
            _ => None,
        };
        if let Some(key) = last {
            return self.store.get_range(&key, 0..1).is_ok();
        }
        let Some(outputs) = self.outputs(stage, frame, task) else {
            return false;
        };
        let scope = FrameKeys {
            job: &self.job,
            frame,
        };
        let prefix = format!("jobs/{scope}/{stage}/{task:05}/");
        match self.store.list(&prefix) {
            Ok(keys) => outputs.iter().all(|k| keys.binary_search(k).is_ok()),
            Err(_) => false,
        }
    }
}

impl TaskInvoker for SkipFinishedTasks {
    fn invoke(&self, resource: &str, input: Value) -> Result<Value, TaskFailure> {
        if let Ok(event) = serde_json::from_value::<WorkerEvent>(input.clone())
            && event.job == self.job
            && self.finished(event.stage, event.item.frame, event.item.task.0)
        {
            self.skipped.fetch_add(1, Ordering::Relaxed);
            return Ok(serde_json::to_value(TaskMetrics::default()).unwrap_or_default());
        }
        self.inner.invoke(resource, input)
    }
}
