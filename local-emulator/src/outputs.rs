//! The files a command writes: every output path is checked before any work starts (format,
//! folder, writability), and every file is written atomically (a temporary file in the same
//! folder, renamed into place), so a failed run leaves no partial output behind.

use anyhow::{Result, anyhow, bail};
use hort_core::image::{Image, ImageError, write_image};
use std::ffi::OsString;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Where a textual result goes: a file, or standard output (`-`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum OutputTarget {
    /// Standard output.
    Stdout,
    /// A file, replaced atomically.
    File(PathBuf),
}

/// Checks that an image can be written at `path` (named by `flag` in errors): a supported
/// extension, an existing folder, a name that is not a folder, and a folder this process can
/// write to. Nothing is left behind.
pub fn check_image_path(flag: &str, path: &Path) -> Result<()> {
    check_file_path(flag, path)?;
    // Encode a 1x1 image through the same writer into the same folder: this checks the format
    // exactly as the real write will, and the folder's permissions.
    let probe = sibling(path, "probe");
    let result = write_image(&probe, &Image::new(1, 1));
    let _ = std::fs::remove_file(&probe);
    match result {
        Ok(()) => Ok(()),
        Err(ImageError::UnsupportedExtension { ext, .. }) => Err(anyhow!(
            "{flag} {}: {}",
            path.display(),
            ImageError::UnsupportedExtension {
                ext,
                path: path.to_path_buf()
            }
        )),
        Err(ImageError::Io { source, .. }) => Err(anyhow!(
            "{flag} {}: cannot write in {}: {}",
            path.display(),
            folder_of(path).display(),
            plain_io(&source)
        )),
        Err(e) => Err(anyhow!("{flag} {}: {e}", path.display())),
    }
}

/// Checks that a file can be written at `path` (or `-`, standard output, when `allow_stdout`).
pub fn check_output_path(flag: &str, path: &Path, allow_stdout: bool) -> Result<OutputTarget> {
    if path == Path::new("-") {
        if allow_stdout {
            return Ok(OutputTarget::Stdout);
        }
        bail!("{flag} -: this output cannot go to standard output; give a file name");
    }
    check_file_path(flag, path)?;
    let probe = sibling(path, "probe");
    let created = std::fs::File::create(&probe);
    let _ = std::fs::remove_file(&probe);
    created.map_err(|e| {
        anyhow!(
            "{flag} {}: cannot write in {}: {}",
            path.display(),
            folder_of(path).display(),
            plain_io(&e)
        )
    })?;
    Ok(OutputTarget::File(path.to_path_buf()))
}

/// Writes `bytes` to `target`: a file atomically, or standard output.
pub fn write_output(target: &OutputTarget, bytes: &[u8]) -> Result<()> {
    match target {
        OutputTarget::Stdout => {
            let mut out = std::io::stdout().lock();
            out.write_all(bytes)
                .and_then(|()| out.flush())
                .map_err(|e| anyhow!("cannot write to standard output: {}", plain_io(&e)))
        }
        OutputTarget::File(path) => write_atomically(path, bytes),
    }
}

/// Writes `bytes` to a temporary file beside `path`, then renames it over `path`; on failure
/// the temporary file is removed and `path` is untouched.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomically_with(path, |w| w.write_all(bytes))
}

/// Streams what `write` produces to a temporary file beside `path`, then renames it over
/// `path`; on failure the temporary file is removed and `path` is untouched.
pub fn write_atomically_with<T>(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<T>,
) -> Result<T> {
    let tmp = sibling(path, "tmp");
    let result = std::fs::File::create(&tmp).and_then(|file| {
        let mut writer = std::io::BufWriter::new(file);
        let value = write(&mut writer)?;
        writer.flush()?;
        std::fs::rename(&tmp, path)?;
        Ok(value)
    });
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        anyhow!("cannot write {}: {}", path.display(), plain_io(&e))
    })
}

/// Refuses two outputs at the same path (the second would overwrite the first).
pub fn check_distinct(outputs: &[(&str, &Path)]) -> Result<()> {
    for (i, (flag_a, a)) in outputs.iter().enumerate() {
        for (flag_b, b) in &outputs[i + 1..] {
            if a == b && *a != Path::new("-") {
                bail!(
                    "{flag_a} and {flag_b} name the same file {}; give each its own",
                    a.display()
                );
            }
        }
    }
    Ok(())
}

/// Checks the parts every output path shares: a file name, an existing folder, not a folder.
fn check_file_path(flag: &str, path: &Path) -> Result<()> {
    if path.as_os_str().is_empty() {
        bail!("{flag}: the path is empty");
    }
    if path.is_dir() || path.as_os_str().to_string_lossy().ends_with('/') {
        bail!(
            "{flag} {}: is a folder; give a file name inside it",
            path.display()
        );
    }
    let folder = folder_of(path);
    if !folder.is_dir() {
        bail!(
            "{flag} {}: the folder {} does not exist",
            path.display(),
            folder.display()
        );
    }
    Ok(())
}

/// The folder `path` is in (`.` for a bare file name).
fn folder_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A hidden file beside `path`, unique to this process, with exactly `path`'s extension (so an
/// image probe goes through the same encoder): `.hort-{what}-{pid}-{name}`.
fn sibling(path: &Path, what: &str) -> PathBuf {
    let name = path.file_name().map(OsString::from).unwrap_or_default();
    let mut hidden = OsString::from(format!(".hort-{what}-{}-", std::process::id()));
    hidden.push(&name);
    folder_of(path).join(hidden)
}

/// An I/O error's message without the `(os error N)` suffix the standard library adds.
pub fn plain_io(e: &std::io::Error) -> String {
    let text = e.to_string();
    match text.find(" (os error ") {
        Some(at) => text[..at].to_owned(),
        None => text,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_paths_are_refused_before_work_with_the_flag_named() {
        let dir = std::env::temp_dir().join(format!("hort-outputs-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let jpg = dir.join("render.jpgx");
        let e = check_image_path("--out", &jpg).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!(
                "--out {}: unsupported image extension \"jpgx\" for {}",
                jpg.display(),
                jpg.display()
            )),
            "{e}"
        );
        let e = check_image_path("--out", &dir).unwrap_err().to_string();
        assert_eq!(
            e,
            format!(
                "--out {}: is a folder; give a file name inside it",
                dir.display()
            )
        );
        let missing = dir.join("nope/x.png");
        let e = check_output_path("--hits", &missing, false)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            format!(
                "--hits {}: the folder {} does not exist",
                missing.display(),
                dir.join("nope").display()
            )
        );
        assert_eq!(
            check_output_path("--report", Path::new("-"), true).unwrap(),
            OutputTarget::Stdout
        );
        let ok = dir.join("ok.png");
        check_image_path("--out", &ok).unwrap();
        assert!(!ok.exists(), "a check writes nothing");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "no probe left");
        write_atomically(&dir.join("r.json"), b"{}").unwrap();
        assert_eq!(std::fs::read(dir.join("r.json")).unwrap(), b"{}");
        assert_eq!(
            std::fs::read_dir(&dir).unwrap().count(),
            1,
            "no temporary left"
        );
        let e = check_distinct(&[("--out", &ok), ("--hits", &ok)])
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            format!(
                "--out and --hits name the same file {}; give each its own",
                ok.display()
            )
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
