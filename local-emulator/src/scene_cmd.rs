//! `hort scene generate`: a deterministic synthetic OBJ plus a manifest whose camera the scene
//! fills (the bare OBJ's default framing shows it small: it is wide and flat).

use crate::cli::GenerateArgs;
use crate::outputs::{write_atomically, write_atomically_with};
use anyhow::{Context, Result, bail};
use hort_core::scene::{load_scene, scene_bounds};
use std::path::Path;

pub fn generate(args: GenerateArgs) -> Result<()> {
    let is_obj = args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    if !is_obj {
        bail!(
            "--out {}: must end in .obj (a manifest is written beside it with .json)",
            args.out.display()
        );
    }
    let manifest = args.out.with_extension("json");
    hort_core::generate::check_triangle_count(args.triangles).map_err(anyhow::Error::msg)?;
    if !args.force {
        for path in [&args.out, &manifest] {
            if path.exists() {
                bail!(
                    "{} exists; pass --force to overwrite it (scene generate writes {} and {})",
                    path.display(),
                    args.out.display(),
                    manifest.display()
                );
            }
        }
    }
    let summary = write_generated(args.triangles, args.seed, &args.out)?;
    eprintln!(
        "wrote {} triangles, {} vertices -> {} (and {} with a camera the scene fills)",
        summary.triangles,
        summary.vertices,
        args.out.display(),
        args.out.with_extension("json").display()
    );
    Ok(())
}

/// Writes the OBJ at `out` and its manifest beside it (`out` with extension `.json`), each
/// atomically (a temporary file renamed into place), replacing existing files.
pub fn write_generated(
    triangles: u64,
    seed: u64,
    out: &Path,
) -> Result<hort_core::generate::GenerateSummary> {
    hort_core::generate::check_triangle_count(triangles).map_err(anyhow::Error::msg)?;
    let summary = write_atomically_with(out, |mut w| {
        hort_core::generate::generate_scene(triangles, seed, &mut w)
    })?;
    write_manifest(out)?;
    Ok(summary)
}

/// A manifest looking down at the scene from the front, so the ground fills the frame.
fn write_manifest(obj: &Path) -> Result<()> {
    let scene = load_scene(obj)?;
    // The loaded mesh is relative to the scene's origin; the manifest is in the file's frame.
    let (lo, hi) = scene_bounds(&scene.mesh, obj)?;
    let (lo, hi) = (lo + scene.origin, hi + scene.origin);
    let c = (lo + hi) * 0.5;
    let x = hi.x - lo.x;
    let eye = [c.x, lo.y + 0.33 * x, hi.z + 0.28 * x];
    let look_at = [c.x, lo.y + 0.03 * x, c.z + 0.02 * x];
    let name = obj
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let manifest = serde_json::json!({
        "meshes": [name],
        "camera": {"eye": eye, "look_at": look_at, "up": [0.0, 1.0, 0.0], "vfov": 45.0},
    });
    let path = obj.with_extension("json");
    let text = serde_json::to_string_pretty(&manifest).context("manifest")?;
    write_atomically(&path, (text + "\n").as_bytes())
}
