//! Scratch folders for tests: each a fresh folder under the system's temporary folder, removed
//! with everything in it when the guard is dropped (a failed test's folder too).

use std::ops::Deref;
use std::path::Path;

/// A scratch folder, usable as a [`Path`]; removed on drop.
pub(crate) struct Scratch(tempfile::TempDir);

impl Scratch {
    /// A fresh folder whose name starts with `prefix`.
    pub(crate) fn new(prefix: &str) -> Scratch {
        Scratch(
            tempfile::Builder::new()
                .prefix(prefix)
                .tempdir()
                .expect("a scratch folder"),
        )
    }
}

impl Deref for Scratch {
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
