//! What the CLI test files share: the built `hort` binary, bundled scenes, scratch folders.
#![allow(dead_code)] // each test file uses a different part

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

/// An empty folder of this test process, named after the test.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("hort-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs `hort` with `args` and waits for it.
pub fn hort(args: &[&str]) -> Output {
    Command::new(HORT).args(args).output().expect("hort runs")
}

/// Standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The files in `dir`, sorted.
pub mod server;

pub fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}
