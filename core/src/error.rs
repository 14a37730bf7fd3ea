//! Errors of scene input and rendering. Every message names the file and, where the parser knows
//! it, the line (`path:line: what`), or the JSON path of a bad manifest field.

use std::path::PathBuf;

/// `text` with control characters escaped (`\r`, `\n`, `\u{1b}`), so a name, key or JSON
/// field taken from user input keeps a message on one line.
pub fn printable(text: &str) -> String {
    text.chars()
        .map(|c| {
            if c.is_control() {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

/// `path` as a message shows it: its display form, control characters escaped ([`printable`]),
/// so a file name taken from a manifest keeps the message on one line.
fn shown(path: &std::path::Path) -> String {
    printable(&path.display().to_string())
}

/// Why a scene could not be loaded or rendered. `Display` is one line meant for a user.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read at all.
    #[error("cannot read {p}: {source}", p = shown(path))]
    Io {
        /// The file that could not be opened or read.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not an OBJ (binary data, or a statement OBJ does not have).
    #[error("{p}:{line}: not an OBJ file: {detail}", p = shown(path))]
    NotObj {
        /// The OBJ file.
        path: PathBuf,
        /// The 1-based line where it stopped looking like OBJ.
        line: u64,
        /// What was found there.
        detail: String,
    },
    /// A statement of a known kind could not be parsed (bad number, too few values).
    #[error("{p}:{line}: {detail}", p = shown(path))]
    Syntax {
        /// The OBJ file.
        path: PathBuf,
        /// The 1-based line of the statement.
        line: u64,
        /// What is wrong with it.
        detail: String,
    },
    /// A face refers to a vertex or normal that does not exist.
    #[error(
        "{p}:{line}: face refers to {what} {index}, but only {defined} defined so far",
        defined = crate::plural::count_is(*count as u64, what),
        p = shown(path)
    )]
    IndexOutOfRange {
        /// The OBJ file.
        path: PathBuf,
        /// The 1-based line of the face.
        line: u64,
        /// The element referred to: `"vertex"`, `"normal"` or `"texture coordinate"`.
        what: &'static str,
        /// The index as written: 1-based, or negative to count back from the last defined.
        index: i64,
        /// How many elements of that kind were defined before this line.
        count: usize,
    },
    /// A vertex or normal has a NaN or infinite coordinate.
    #[error("{p}:{line}: {what} has a non-finite coordinate ({text})", p = shown(path))]
    NonFinite {
        /// The OBJ file.
        path: PathBuf,
        /// The 1-based line of the statement.
        line: u64,
        /// The element: `"vertex"` or `"normal"`.
        what: &'static str,
        /// The offending coordinate as written.
        text: String,
    },
    /// The scene has no triangles at all.
    #[error("{p}: the scene contains no triangles", p = shown(path))]
    Empty {
        /// The scene file (OBJ or manifest).
        path: PathBuf,
    },
    /// Every triangle is degenerate, so the scene has no extent to frame or light.
    #[error("{p}: the scene has no extent (all vertices coincide), so it cannot be framed", p = shown(path))]
    NoExtent {
        /// The scene file (OBJ or manifest).
        path: PathBuf,
    },
    /// Some vertices lie farther from the scene's centre than f32 can hold.
    #[error(
        "{p}: the scene is too large: vertices lie farther than 3.4e38 from its centre, \
         beyond single precision",
        p = shown(path)
    )]
    TooLarge {
        /// The scene file (OBJ or manifest).
        path: PathBuf,
    },
    /// A material library could not be read or parsed.
    #[error("{p}: material library: {detail}", p = shown(path))]
    Mtl {
        /// The `.mtl` file, resolved against the OBJ file's directory.
        path: PathBuf,
        /// What went wrong reading it.
        detail: String,
    },
    /// A texture map a material names cannot be used: missing, unreadable, not a PNG or JPEG,
    /// or too large. `material` is the library and line that names it.
    #[error("{p}: texture of {material}: {detail}", p = shown(path))]
    Texture {
        /// The image file, resolved against the material library's directory.
        path: PathBuf,
        /// `library.mtl:line material "name"`.
        material: String,
        /// What is wrong with it.
        detail: String,
    },
    /// A JSON scene manifest is malformed; `field` is the JSON path of the bad field.
    #[error("{p}: manifest field `{field}`: {detail}", p = shown(path))]
    Manifest {
        /// The manifest file.
        path: PathBuf,
        /// The JSON path of the bad field (`materials.steel.kd`), or `(root)`.
        field: String,
        /// What is wrong with it.
        detail: String,
    },
    /// A size is outside the documented limits.
    #[error("{what} = {value} is out of range: {limit}")]
    OutOfRange {
        /// The quantity checked (`"width"`, `"spp"`, `"width x height"`, ...).
        what: &'static str,
        /// Its value, in decimal.
        value: String,
        /// The limit it breaks, as a phrase (`must be 1 to 65536`).
        limit: String,
    },
    /// The camera cannot form a view (eye at the target, up parallel to the view direction).
    #[error("invalid camera: {detail}")]
    Camera {
        /// Which of the two it is.
        detail: String,
    },
    /// A camera animation is invalid, or a frame is outside it or its camera cannot form a
    /// view ([`crate::animation::Animation`]). The detail is the whole message, naming the
    /// keyframe (`animation keyframe 2 (frame 24): ...`) or the frame.
    #[error("{detail}")]
    Animation {
        /// What is wrong, and where.
        detail: String,
    },
}
