//! Output paths of a run of several frames: in `shots/turn_####.png` the last run of `#` in the
//! file name stands for the frame number, zero-padded to the run's length (longer numbers keep
//! all their digits).

use anyhow::{Result, bail};
use std::path::{Path, PathBuf};

/// Whether `path`'s file name holds a run of `#`.
pub fn has_frame_pattern(path: &Path) -> bool {
    path.file_name()
        .is_some_and(|name| name.to_string_lossy().contains('#'))
}

/// `pattern` with the last run of `#` in its file name replaced by `frame`, zero-padded to the
/// run's length; `pattern` itself when its name has no `#`.
pub fn frame_path(pattern: &Path, frame: u32) -> PathBuf {
    let Some(name) = pattern
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
    else {
        return pattern.to_path_buf();
    };
    let Some(end) = name.rfind('#').map(|i| i + 1) else {
        return pattern.to_path_buf();
    };
    let start = name[..end].trim_end_matches('#').len();
    let width = end - start;
    let named = format!("{}{frame:0width$}{}", &name[..start], &name[end..]);
    pattern.with_file_name(named)
}

/// Checks that a run of `frames` frames can give each frame its own file under `flag`'s
/// `path`: with more than one frame, its file name must hold a `#` run.
pub fn check_frame_pattern(flag: &str, path: &Path, frames: u32) -> Result<()> {
    if frames > 1 && !has_frame_pattern(path) {
        bail!(
            "{flag} {}: {frames} frames need a `#` run in the file name for the frame number \
             (for example {})",
            path.display(),
            example(path).display()
        );
    }
    Ok(())
}

/// `path` with `_####` before its extension: the suggestion of [`check_frame_pattern`].
fn example(path: &Path) -> PathBuf {
    let stem = path
        .file_stem()
        .map_or("frame".into(), |s| s.to_string_lossy().into_owned());
    let named = match path.extension() {
        Some(ext) => format!("{stem}_####.{}", ext.to_string_lossy()),
        None => format!("{stem}_####"),
    };
    path.with_file_name(named)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_last_hash_run_of_the_name_is_the_zero_padded_frame() {
        let p = |s: &str, k| frame_path(Path::new(s), k).display().to_string();
        assert_eq!(p("shots/turn_####.png", 7), "shots/turn_0007.png");
        assert_eq!(p("shots/turn_##.png", 123), "shots/turn_123.png");
        assert_eq!(p("a#b_###.pfm", 5), "a#b_005.pfm");
        assert_eq!(p("#.png", 0), "0.png");
        assert_eq!(p("sh#ts/still.png", 3), "sh#ts/still.png");
        assert!(has_frame_pattern(Path::new("x/f_#.exr")));
        assert!(!has_frame_pattern(Path::new("x#/f.exr")));
    }

    #[test]
    fn several_frames_need_a_pattern_and_the_error_suggests_one() {
        check_frame_pattern("--out", Path::new("still.png"), 1).unwrap();
        check_frame_pattern("--out", Path::new("f_#.png"), 9).unwrap();
        let e = check_frame_pattern("--out", Path::new("shots/turn.png"), 8).unwrap_err();
        assert_eq!(
            e.to_string(),
            "--out shots/turn.png: 8 frames need a `#` run in the file name for the frame number \
             (for example shots/turn_####.png)"
        );
    }
}
