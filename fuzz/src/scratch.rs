//! A scratch folder per thread for targets whose code under test reads files.

use std::cell::OnceCell;
use std::path::{Path, PathBuf};

thread_local! {
    static DIR: OnceCell<tempfile::TempDir> = const { OnceCell::new() };
}

/// This thread's scratch folder (created on first use, under the system temp folder as
/// `hort-fuzz-XXXXXX`; unique per thread, so parallel tests and fuzzer instances never share
/// one), removed with its files when the thread ends.
pub fn dir() -> PathBuf {
    DIR.with(|d| {
        d.get_or_init(|| {
            tempfile::Builder::new()
                .prefix("hort-fuzz-")
                .tempdir()
                .expect("cannot create the scratch folder")
        })
        .path()
        .to_path_buf()
    })
}

/// Writes `bytes` to `name` in the scratch folder and returns its path.
pub fn write(name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir().join(name);
    std::fs::write(&path, bytes).expect("cannot write a scratch file");
    path
}

/// `data` cut at the first `marker`: (before, after); after is empty without a marker.
pub fn cut<'a>(data: &'a [u8], marker: &[u8]) -> (&'a [u8], &'a [u8]) {
    match data.windows(marker.len()).position(|w| w == marker) {
        Some(i) => (&data[..i], &data[i + marker.len()..]),
        None => (data, &[]),
    }
}

/// Whether `name` stays inside the scratch folder (relative, no `..`, no root).
pub fn is_plain(name: &str) -> bool {
    let path = Path::new(name);
    path.components()
        .all(|c| matches!(c, std::path::Component::Normal(_)))
}

#[cfg(test)]
mod tests {
    /// A thread's scratch folder, and what was written in it, is gone once the thread ended.
    #[test]
    fn a_threads_folder_is_gone_when_the_thread_ends() {
        let dir = std::thread::spawn(|| {
            let file = super::write("f", b"x");
            assert!(file.exists());
            super::dir()
        })
        .join()
        .unwrap();
        assert!(!dir.exists(), "{} is left", dir.display());
    }
}
