//! Replays every kept corpus input (`corpus/<target>/`) and every input of a past finding
//! (`regressions/<target>/`, kept when a corpus is minimized anew) through its target on the
//! stable toolchain: the CI smoke pass of the fuzzers. A target that panics on an input fails
//! the test naming the file.

use std::path::{Path, PathBuf};

/// The files of `folder/target/` in name order; none if the folder does not exist.
fn files_in(folder: &str, target: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(folder)
        .join(target);
    if !dir.exists() {
        return Vec::new();
    }
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
        .map(|entry| entry.expect("a folder entry").path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    files
}

fn replay(target: &str) {
    let run = hort_fuzz::TARGETS
        .iter()
        .find(|(name, _)| *name == target)
        .map(|(_, run)| *run)
        .expect("a known target");
    let corpus = files_in("corpus", target);
    assert!(
        corpus.len() >= 5,
        "corpus/{target} holds {} inputs, expected a kept corpus",
        corpus.len()
    );
    for file in corpus.into_iter().chain(files_in("regressions", target)) {
        let data = std::fs::read(&file).expect("a readable corpus file");
        if std::panic::catch_unwind(|| run(&data)).is_err() {
            panic!("target {target} panicked on {}", file.display());
        }
    }
}

#[test]
fn obj_corpus() {
    replay("obj");
}

#[test]
fn manifest_corpus() {
    replay("manifest");
}

#[test]
fn split_object_corpus() {
    replay("split_object");
}

#[test]
fn shuffle_block_corpus() {
    replay("shuffle_block");
}

#[test]
fn asl_corpus() {
    replay("asl");
}

#[cfg(feature = "http")]
#[test]
fn http_corpus() {
    replay("http");
}
