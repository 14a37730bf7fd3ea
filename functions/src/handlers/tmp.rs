//! A function's `/tmp`: the folder it may write to, and how much it holds. Lambda gives each
//! function 512 MB unless the template raises its ephemeral storage (up to 10,240 MB); a write
//! past it fails with "No space left on device". The handlers that copy scene files there (the
//! Plan function, and a Worker rebuilding a lost split from the scene) check the copy against the
//! size first and refuse, naming both numbers, instead of failing the same way on every retry.

use std::path::Path;

use super::HandlerError;

/// Where a function may write scratch files, and how many bytes fit.
#[derive(Clone, Copy, Debug)]
pub struct Tmp<'a> {
    /// The folder (the function's `/tmp`, or a folder standing in for it).
    pub dir: &'a Path,
    /// Its size; `None`: not checked.
    pub limit_bytes: Option<u64>,
}

impl<'a> Tmp<'a> {
    /// `dir`, its size not checked.
    pub fn unlimited(dir: &'a Path) -> Self {
        Tmp {
            dir,
            limit_bytes: None,
        }
    }

    /// Refuses to write `more` bytes of `what` after `written` bytes of the same copy when they
    /// would not fit.
    pub(super) fn check(&self, written: u64, more: u64, what: &str) -> Result<(), HandlerError> {
        match self.limit_bytes {
            Some(limit) if written.saturating_add(more) > limit => {
                Err(HandlerError::bad_input(format!(
                    "{what} does not fit this function's /tmp of {}: the copy would reach {} \
                     bytes; raise the function's EphemeralStorage (infra/template.yaml; Lambda \
                     allows up to 10240 MB)",
                    size(limit),
                    written.saturating_add(more)
                )))
            }
            _ => Ok(()),
        }
    }
}

/// `bytes` in MB when whole (as the template gives sizes), else in bytes.
fn size(bytes: u64) -> String {
    if bytes.is_multiple_of(1 << 20) {
        format!("{} MB", bytes >> 20)
    } else {
        format!("{bytes} bytes")
    }
}
