//! The scene of a request: its files gathered (inline, or read from the bucket), checked for
//! safety (every name a plain relative path inside the scene's folder), and loaded by the same
//! loader `hort render` uses, so a bad scene is refused before any job exists, naming the file
//! and line.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use hort_core::scene::{Scene, diffuse_map_files, load_scene, parse_manifest};

use super::error::ApiError;

/// Most files a scene may have.
pub const MAX_SCENE_FILES: usize = 256;
/// Longest file name or key, bytes.
pub const MAX_NAME_BYTES: usize = 1024;
/// Longest part of a name between slashes, bytes (a file name on Linux file systems).
pub const MAX_PART_BYTES: usize = 255;

/// A scene's files, gathered and loaded.
#[derive(Clone, Debug)]
pub struct SceneFiles {
    /// The main file, relative to the scene's folder (`bunny.json`).
    pub main: String,
    /// How messages and reports name the scene: the main file, or the key it was read from.
    pub name: String,
    /// Every file the scene uses (the main file, the meshes a manifest names, the material
    /// libraries the meshes name), relative to the scene's folder.
    pub files: BTreeMap<String, Vec<u8>>,
}

/// A scene that loaded.
pub struct LoadedScene {
    /// Its files.
    pub files: SceneFiles,
    /// The scene as `hort render` would render it.
    pub scene: Scene,
    /// The loader's warnings, naming files as the request does.
    pub warnings: Vec<String>,
}

/// Checks that `name` is a plain relative path (`a.obj`, `sub/a.obj`): no empty, `.` or `..`
/// parts, no leading `/`, no backslash, no control character (NUL, newline, ...), at most
/// [`MAX_NAME_BYTES`] bytes, each part at most [`MAX_PART_BYTES`]. `what` names it in the message.
pub fn check_relative(name: &str, what: &str) -> Result<(), String> {
    let ok = !name.is_empty()
        && name.len() <= MAX_NAME_BYTES
        && !name.contains('\\')
        && !name.chars().any(char::is_control)
        && name.split('/').all(|part| {
            !part.is_empty() && part.len() <= MAX_PART_BYTES && part != "." && part != ".."
        });
    if ok {
        Ok(())
    } else {
        Err(format!(
            "{what} {name:?} is not a relative path inside the scene's folder (1 to \
             {MAX_NAME_BYTES} bytes, parts of at most {MAX_PART_BYTES} bytes separated by /, no empty, . or .. parts, no \\ or \
             control characters)"
        ))
    }
}

/// `rel` relative to the folder of `file` (both relative to the scene's folder).
fn beside(file: &str, rel: &str) -> String {
    match file.rsplit_once('/') {
        Some((dir, _)) => format!("{dir}/{rel}"),
        None => rel.to_owned(),
    }
}

/// Reads one file of a scene by its name: `None` if there is no such file.
pub type Fetch<'a> = dyn FnMut(&str) -> Result<Option<Vec<u8>>, ApiError> + 'a;

/// Gathers the files of the scene whose main file is `main`: `fetch(name)` gives a file's
/// bytes (`None`: no such file); `shown(name)` is how messages name a file. Meshes must exist;
/// material libraries are optional (the loader warns about missing ones).
pub fn gather(
    main: &str,
    shown: &dyn Fn(&str) -> String,
    fetch: &mut Fetch<'_>,
) -> Result<BTreeMap<String, Vec<u8>>, ApiError> {
    let mut files = BTreeMap::new();
    let Some(main_bytes) = fetch(main)? else {
        return Err(ApiError::invalid_scene(format!(
            "{}: no such file",
            shown(main)
        )));
    };
    let is_json = Path::new(main)
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let meshes: Vec<String> = if is_json {
        let text = String::from_utf8_lossy(&main_bytes);
        let manifest = parse_manifest(&text, Path::new(&shown(main)))
            .map_err(|e| ApiError::invalid_scene(e.to_string()))?;
        let mut meshes = Vec::new();
        for mesh in manifest.meshes {
            check_relative(&mesh, "mesh")
                .map_err(|m| ApiError::invalid_scene(format!("{}: {m}", shown(main))))?;
            meshes.push(beside(main, &mesh));
        }
        meshes
    } else {
        vec![main.to_owned()]
    };
    files.insert(main.to_owned(), main_bytes);
    for mesh in meshes {
        if !files.contains_key(&mesh) {
            let Some(bytes) = fetch(&mesh)? else {
                return Err(ApiError::invalid_scene(format!(
                    "{}: the mesh {} does not exist",
                    shown(main),
                    shown(&mesh)
                )));
            };
            files.insert(mesh.clone(), bytes);
        }
        let libraries = material_libraries(&files[&mesh]);
        for lib in libraries {
            check_relative(&lib, "material library")
                .map_err(|m| ApiError::invalid_scene(format!("{}: {m}", shown(&mesh))))?;
            let lib = beside(&mesh, &lib);
            if !files.contains_key(&lib)
                && let Some(bytes) = fetch(&lib)?
            {
                // Diffuse textures: a missing one is the loader's error, naming it.
                for map in diffuse_map_files(&String::from_utf8_lossy(&bytes)) {
                    check_relative(&map, "texture")
                        .map_err(|m| ApiError::invalid_scene(format!("{}: {m}", shown(&lib))))?;
                    let map = beside(&lib, &map);
                    if !files.contains_key(&map)
                        && let Some(texture) = fetch(&map)?
                    {
                        files.insert(map, texture);
                    }
                }
                files.insert(lib, bytes);
            }
        }
        if files.len() > MAX_SCENE_FILES {
            return Err(ApiError::invalid_scene(format!(
                "{}: the scene has more than {MAX_SCENE_FILES} files",
                shown(main)
            )));
        }
    }
    Ok(files)
}

/// The names after `mtllib` in OBJ text.
pub fn material_libraries(obj: &[u8]) -> Vec<String> {
    let mut libs = Vec::new();
    for line in obj.split(|&b| b == b'\n') {
        let line = String::from_utf8_lossy(line);
        let mut words = line.split_ascii_whitespace();
        if words.next() == Some("mtllib") {
            libs.extend(words.map(str::to_owned));
        }
    }
    libs
}

/// Loads `files` with the loader of `hort render`: they are written to a fresh scratch folder
/// (removed again), loaded from there, and every path in an error or warning is shown relative
/// to the scene's folder, behind `prefix` (`""` for inline files, the key's folder with `/` for
/// a scene in the bucket).
pub fn load(files: SceneFiles, prefix: &str) -> Result<LoadedScene, ApiError> {
    let dir = Scratch::create().map_err(|e| {
        ApiError::internal(format!("cannot create a scratch folder for the scene: {e}"))
    })?;
    for (name, bytes) in &files.files {
        let path = dir.path.join(name);
        let written = path
            .parent()
            .map_or(Ok(()), std::fs::create_dir_all)
            .and_then(|()| std::fs::write(&path, bytes));
        written.map_err(|e| {
            ApiError::internal(format!("cannot write the scene's file {name}: {e}"))
        })?;
    }
    let root = format!("{}/", dir.path.display());
    let shown = |text: String| plain_io(&text.replace(&root, prefix));
    let scene = load_scene(&dir.path.join(&files.main))
        .map_err(|e| ApiError::invalid_scene(shown(e.to_string())))?;
    let warnings = scene.warnings.iter().map(|w| shown(w.clone())).collect();
    Ok(LoadedScene {
        files,
        scene,
        warnings,
    })
}

/// `text` without the ` (os error N)` suffixes of I/O errors.
fn plain_io(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(at) = rest.find(" (os error ") {
        out.push_str(&rest[..at]);
        rest = &rest[at..];
        match rest.find(')') {
            Some(end) => rest = &rest[end + 1..],
            None => break,
        }
    }
    out.push_str(rest);
    out
}

/// A folder of its own under the system's temporary folder, removed on drop.
struct Scratch {
    path: PathBuf,
}

impl Scratch {
    fn create() -> std::io::Result<Scratch> {
        static NEXT: AtomicU64 = AtomicU64::new(0);
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let path = std::env::temp_dir().join(format!(
            "hort-api-scene-{}-{}-{nanos:x}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&path)?;
        Ok(Scratch { path })
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_must_stay_inside_the_scene_folder() {
        for ok in ["a.obj", "sub/a.obj", "a b.obj"] {
            assert!(check_relative(ok, "file").is_ok(), "{ok}");
        }
        for bad in [
            "", "/a.obj", "../a.obj", "a/../b", "./a", "a//b", "a\\b", "a/",
        ] {
            assert!(check_relative(bad, "file").is_err(), "{bad:?}");
        }
    }

    #[test]
    fn os_error_suffixes_go() {
        assert_eq!(
            plain_io("cannot read a.obj: No such file or directory (os error 2)"),
            "cannot read a.obj: No such file or directory"
        );
    }
}
