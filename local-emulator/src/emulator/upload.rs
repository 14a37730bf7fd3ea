//! Submitting a job: the scene files and the job request go to storage, as a client of the
//! cloud deployment would upload them before starting an execution.

use anyhow::{Context, Result, bail};
use hort_core::ids::JobId;
use hort_core::keys::{manifest_key, scene_prefix};
use hort_core::scene::parse_manifest;
use hort_core::store::{BlobStore, PutOutcome};
use hort_functions::handlers::JobRequest;
use std::path::{Component, Path, PathBuf};

/// The scene's files relative to the main file's folder: the main file, the OBJ files a
/// manifest names, and the material libraries the OBJ files name.
pub fn scene_files(main: &Path) -> Result<Vec<PathBuf>> {
    let base = main.parent().unwrap_or(Path::new("."));
    let name = PathBuf::from(main.file_name().context("the scene path names no file")?);
    let mut files = vec![name.clone()];
    let is_json = main
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let objs: Vec<PathBuf> = if is_json {
        let text = std::fs::read_to_string(main)
            .with_context(|| format!("cannot read {}", main.display()))?;
        parse_manifest(&text, main)?
            .meshes
            .into_iter()
            .map(PathBuf::from)
            .collect()
    } else {
        vec![name]
    };
    for obj in objs {
        if !files.contains(&obj) {
            files.push(obj.clone());
        }
        let text = std::fs::read(base.join(&obj))
            .with_context(|| format!("cannot read {}", base.join(&obj).display()))?;
        let obj_dir = obj.parent().map(Path::to_path_buf).unwrap_or_default();
        for line in text.split(|&b| b == b'\n') {
            let line = String::from_utf8_lossy(line);
            let mut words = line.split_ascii_whitespace();
            if words.next() == Some("mtllib") {
                for lib in words {
                    let rel = obj_dir.join(lib);
                    if base.join(&rel).is_file() && !files.contains(&rel) {
                        files.push(rel);
                    }
                }
            }
        }
    }
    for f in &files {
        if !f.components().all(|c| matches!(c, Component::Normal(_))) {
            bail!(
                "{}: the scene file {} is outside the scene's folder; the emulator uploads the folder's files only",
                main.display(),
                f.display()
            );
        }
    }
    Ok(files)
}

/// Uploads the scene and creates the job request (once: a second submission of the same job
/// id is an error, as the request is the job's identity).
pub fn submit_job(
    store: &dyn BlobStore,
    job: &JobId,
    main: &Path,
    request: &JobRequest,
) -> Result<()> {
    let base = main.parent().unwrap_or(Path::new("."));
    let prefix = scene_prefix(job);
    for rel in scene_files(main)? {
        let bytes = std::fs::read(base.join(&rel))
            .with_context(|| format!("cannot read {}", base.join(&rel).display()))?;
        let key = format!("{prefix}{}", rel.to_string_lossy().replace('\\', "/"));
        store.put(&key, &bytes)?;
    }
    let json = serde_json::to_vec_pretty(request).context("job request")?;
    match store.put_if_absent(&manifest_key(job), &json)? {
        PutOutcome::Created => Ok(()),
        PutOutcome::AlreadyExists => bail!(
            "job \"{job}\" already exists in this bucket: choose another --job id or another --data-dir"
        ),
    }
}
