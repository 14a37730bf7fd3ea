//! What the CLI test files share: the built `hort` binary, bundled scenes, scratch folders.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `hort` binary cargo built for these tests.
pub const HORT: &str = env!("CARGO_BIN_EXE_hort");

/// A bundled scene, e.g. `scene("bunny/bunny.json")`.
pub fn scene(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenes")
        .join(rel)
}

/// An empty folder under the system temporary folder, named after the test, removed with
/// everything in it when dropped (a failed test leaves nothing behind either). Used as a `Path`.
pub struct Scratch(tempfile::TempDir);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        self.0.path()
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        self.0.path()
    }
}

/// A fresh [`Scratch`] folder, `hort-cli-{name}-XXXXXX`.
pub fn scratch(name: &str) -> Scratch {
    let dir = tempfile::Builder::new()
        .prefix(&format!("hort-cli-{name}-"))
        .tempdir()
        .unwrap_or_else(|e| panic!("cannot create a scratch folder for {name}: {e}"));
    Scratch(dir)
}

/// Runs `hort` with `args` and waits for it.
pub fn hort(args: &[&str]) -> Output {
    Command::new(HORT).args(args).output().expect("hort runs")
}

/// Standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

pub mod server;

/// The files in `dir`, sorted.
pub fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}
