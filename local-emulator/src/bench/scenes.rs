//! Benchmark scenes: the bundled ones and generated ones cached under `target/bench-scenes`.

use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// The folder the workspace's bundled scenes are in.
pub fn bundled(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenes")
        .join(rel)
}

/// A generated scene of `triangles` triangles (its manifest, with the camera the generator
/// writes), made once and cached in `dir`.
pub fn generated(dir: &Path, triangles: u64, seed: u64) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let obj = dir.join(format!("generated-{triangles}-{seed}.obj"));
    let manifest = obj.with_extension("json");
    if !manifest.is_file() {
        eprintln!(
            "generating a {triangles}-triangle scene -> {}",
            obj.display()
        );
        crate::scene_cmd::write_generated(triangles, seed, &obj)?;
    }
    Ok(manifest)
}
