//! Errors of scene input and rendering. Every message names the file and, where the parser knows
//! it, the line (`path:line: what`), or the JSON path of a bad manifest field.

use std::path::PathBuf;

/// Why a scene could not be loaded or rendered. `Display` is one line meant for a user.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read at all.
    #[error("cannot read {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file is not an OBJ (binary data, or a statement OBJ does not have).
    #[error("{path}:{line}: not an OBJ file: {detail}")]
    NotObj {
        path: PathBuf,
        line: u64,
        detail: String,
    },
    /// A statement of a known kind could not be parsed (bad number, too few values).
    #[error("{path}:{line}: {detail}")]
    Syntax {
        path: PathBuf,
        line: u64,
        detail: String,
    },
    /// A face refers to a vertex or normal that does not exist.
    #[error(
        "{path}:{line}: face refers to {what} {index}, but only {count} {what}s are defined so far"
    )]
    IndexOutOfRange {
        path: PathBuf,
        line: u64,
        what: &'static str,
        index: i64,
        count: usize,
    },
    /// A vertex or normal has a NaN or infinite coordinate.
    #[error("{path}:{line}: {what} has a non-finite coordinate ({text})")]
    NonFinite {
        path: PathBuf,
        line: u64,
        what: &'static str,
        text: String,
    },
    /// The scene has no triangles at all.
    #[error("{path}: the scene contains no triangles")]
    Empty { path: PathBuf },
    /// Every triangle is degenerate, so the scene has no extent to frame or light.
    #[error("{path}: the scene has no extent (all vertices coincide), so it cannot be framed")]
    NoExtent { path: PathBuf },
    /// A material library could not be read or parsed.
    #[error("{path}: material library: {detail}")]
    Mtl { path: PathBuf, detail: String },
    /// A JSON scene manifest is malformed; `field` is the JSON path of the bad field.
    #[error("{path}: manifest field `{field}`: {detail}")]
    Manifest {
        path: PathBuf,
        field: String,
        detail: String,
    },
    /// A size is outside the documented limits.
    #[error("{what} = {value} is out of range: {limit}")]
    OutOfRange {
        what: &'static str,
        value: String,
        limit: String,
    },
    /// The camera cannot form a view (eye at the target, up parallel to the view direction).
    #[error("invalid camera: {detail}")]
    Camera { detail: String },
}
