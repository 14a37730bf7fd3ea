//! A scratch folder per thread for targets whose code under test reads files.

use std::cell::OnceCell;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

static NEXT: AtomicU64 = AtomicU64::new(0);

thread_local! {
    static DIR: OnceCell<PathBuf> = const { OnceCell::new() };
}

/// This thread's scratch folder (created on first use, under the system temp folder; unique per
/// process and thread, so parallel tests and fuzzer instances never share one).
pub fn dir() -> PathBuf {
    DIR.with(|d| {
        d.get_or_init(|| {
            let n = NEXT.fetch_add(1, Ordering::Relaxed);
            let dir = std::env::temp_dir().join(format!("hort-fuzz-{}-{n}", std::process::id()));
            std::fs::create_dir_all(&dir).expect("cannot create the scratch folder");
            dir
        })
        .clone()
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
