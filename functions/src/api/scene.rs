//! The scene of a request: its files gathered (inline, or read from the bucket), checked for
//! safety (every name a plain relative path inside the scene's folder), and loaded by the same
//! loader `hort render` uses, so a bad scene is refused before any job exists, naming the file
//! and line.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use hort_core::scene::files::{SceneFileKind, SceneFileSource, walk_scene_files};
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

/// Reads one file of a scene by its name: `None` if there is no such file.
pub type Fetch<'a> = dyn FnMut(&str) -> Result<Option<Vec<u8>>, ApiError> + 'a;

/// Gathers the files of the scene whose main file is `main`: `fetch(name)` gives a file's
/// bytes (`None`: no such file); `shown(name)` is how messages name a file. Meshes must exist;
/// material libraries and textures are optional (the loader warns of a missing library and
/// names a missing texture). Every name a file gives must pass [`check_relative`].
pub fn gather(
    main: &str,
    shown: &dyn Fn(&str) -> String,
    fetch: &mut Fetch<'_>,
) -> Result<BTreeMap<String, Vec<u8>>, ApiError> {
    let mut gathering = Gathering {
        main,
        shown,
        fetch,
        files: BTreeMap::new(),
    };
    walk_scene_files(main, &mut gathering)?;
    Ok(gathering.files)
}

/// [`gather`]'s side of the scene walk: the fetched files, by name.
struct Gathering<'a, 'f> {
    main: &'a str,
    shown: &'a dyn Fn(&str) -> String,
    fetch: &'a mut Fetch<'f>,
    files: BTreeMap<String, Vec<u8>>,
}

impl Gathering<'_, '_> {
    /// Keeps `bytes` as the file `name`, refusing a scene of more than [`MAX_SCENE_FILES`].
    fn keep(&mut self, name: &str, bytes: Vec<u8>) -> Result<(), ApiError> {
        self.files.insert(name.to_owned(), bytes);
        if self.files.len() > MAX_SCENE_FILES {
            return Err(ApiError::invalid_scene(format!(
                "{}: the scene has more than {MAX_SCENE_FILES} files",
                (self.shown)(self.main)
            )));
        }
        Ok(())
    }
}

impl SceneFileSource for Gathering<'_, '_> {
    type Error = ApiError;

    fn take_main(&mut self, main: &str) -> Result<(), ApiError> {
        let Some(bytes) = (self.fetch)(main)? else {
            return Err(ApiError::invalid_scene(format!(
                "{}: no such file",
                (self.shown)(main)
            )));
        };
        self.keep(main, bytes)
    }

    fn manifest_meshes(&mut self, main: &str) -> Result<Vec<String>, ApiError> {
        let text = String::from_utf8_lossy(&self.files[main]);
        let manifest = parse_manifest(&text, Path::new(&(self.shown)(main)))
            .map_err(|e| ApiError::invalid_scene(e.to_string()))?;
        Ok(manifest.meshes)
    }

    fn check_name(
        &mut self,
        name: &str,
        kind: SceneFileKind,
        named_by: &str,
    ) -> Result<(), ApiError> {
        check_relative(name, kind.noun())
            .map_err(|m| ApiError::invalid_scene(format!("{}: {m}", (self.shown)(named_by))))
    }

    fn take_mesh(&mut self, mesh: &str) -> Result<(), ApiError> {
        let Some(bytes) = (self.fetch)(mesh)? else {
            return Err(ApiError::invalid_scene(format!(
                "{}: the mesh {} does not exist",
                (self.shown)(self.main),
                (self.shown)(mesh)
            )));
        };
        self.keep(mesh, bytes)
    }

    fn mesh_libraries(&mut self, mesh: &str) -> Result<Vec<String>, ApiError> {
        Ok(material_libraries(&self.files[mesh]))
    }

    fn take_library(&mut self, library: &str) -> Result<Option<Vec<String>>, ApiError> {
        let Some(bytes) = (self.fetch)(library)? else {
            return Ok(None);
        };
        let textures = diffuse_map_files(&String::from_utf8_lossy(&bytes));
        self.keep(library, bytes)?;
        Ok(Some(textures))
    }

    fn take_texture(&mut self, texture: &str) -> Result<(), ApiError> {
        match (self.fetch)(texture)? {
            Some(bytes) => self.keep(texture, bytes),
            None => Ok(()),
        }
    }
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
