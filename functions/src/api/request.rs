//! The body of `POST /renders`, decoded strictly: unknown fields are refused, and every error
//! names the JSON path of the field at fault (`scene.files.x.obj`, `width`).

use std::collections::BTreeMap;

use hort_core::pipeline::{ExecutionMode, SplitMode, StoredOutputs};
use serde::Deserialize;

use super::error::ApiError;

/// What a client asks to render. All but `scene` are optional, as for `hort render`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderRequest {
    /// The scene: inline files, or the key of its main file in the bucket.
    pub scene: SceneSpec,
    /// Image width in pixels, 1 to 65536 (default: the manifest's, else 960).
    #[serde(default)]
    pub width: Option<u32>,
    /// Image height in pixels, 1 to 65536 (default: the manifest's, else 540).
    #[serde(default)]
    pub height: Option<u32>,
    /// Samples per pixel, 1 to 65536 (default: the manifest's, else 1).
    #[serde(default)]
    pub spp: Option<u32>,
    /// Scene splits k (default: automatic).
    #[serde(default)]
    pub splits: Option<u32>,
    /// Pixel spans s (default: automatic).
    #[serde(default)]
    pub spans: Option<u32>,
    /// `spatial` (default) or `naive`.
    #[serde(default)]
    pub split_mode: Option<SplitMode>,
    /// `fused` or `staged`, forced (default: the plan chooses from the scene and `memory_mb`).
    #[serde(default)]
    pub mode: Option<ExecutionMode>,
    /// Memory of one function, MB, 128 to 10240 (default 2048): no task may need more.
    #[serde(default)]
    pub memory_mb: Option<u32>,
    /// A hard budget: the request is refused (422) when the predicted cost is higher.
    #[serde(default)]
    pub max_cost_usd: Option<f64>,
    /// Which large outputs the job stores beside its PNG, `{"linear": bool, "hits": bool}`
    /// (default: both). A job without its linear image serves no `pfm` or `exr` (404).
    #[serde(default)]
    pub outputs: Option<StoredOutputs>,
    /// Frames of the scene's animation, or of the `orbit` turntable, one job renders: frames
    /// 0 to `frames` - 1 (default: a still image).
    #[serde(default)]
    pub frames: Option<u32>,
    /// Render frame `frame` (of the `frames`) alone.
    #[serde(default)]
    pub frame: Option<u32>,
    /// A turntable: the eye turns this many degrees about the vertical axis through the
    /// framed target over the `frames` (which it needs).
    #[serde(default)]
    pub orbit: Option<f64>,
    /// Camera keyframes, as a manifest's `animation` (world coordinates): they replace the
    /// scene's own. For a scene given inline.
    #[serde(default)]
    pub animation: Option<hort_core::scene::ManifestAnimation>,
}

/// Where the scene comes from: `{"main", "files"}` inline, or `{"key"}` in the bucket.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneSpec {
    /// The main file (an OBJ, or a `.json` manifest), one of `files`.
    #[serde(default)]
    pub main: Option<String>,
    /// File name (relative to the scene's folder) to its text.
    #[serde(default)]
    pub files: Option<BTreeMap<String, String>>,
    /// The key of the main file in the bucket; the files it names are read beside it.
    #[serde(default)]
    pub key: Option<String>,
}

/// Deepest nesting of JSON arrays and objects a request body may have (a valid request needs
/// 3: the body, `scene`, `scene.files`).
pub const MAX_JSON_DEPTH: usize = 8;

/// Decodes a request body: not JSON, or nested deeper than [`MAX_JSON_DEPTH`], is
/// `invalid_json`; a field of the wrong type, unknown or missing is `invalid_request` naming
/// its JSON path.
pub fn parse_render_request(body: &[u8]) -> Result<RenderRequest, ApiError> {
    if body.iter().all(u8::is_ascii_whitespace) {
        return Err(ApiError::invalid_json(
            "the request body is empty: send a JSON object with at least \"scene\"",
        ));
    }
    if let Some(at) = too_deep(body, MAX_JSON_DEPTH) {
        return Err(ApiError::invalid_json(format!(
            "the request body nests arrays or objects more than {MAX_JSON_DEPTH} levels deep \
             (at byte {at}); a render request needs 3"
        )));
    }
    let de = &mut serde_json::Deserializer::from_slice(body);
    let request: RenderRequest = serde_path_to_error::deserialize(&mut *de).map_err(|e| {
        let path = e.path().to_string();
        let inner = e.into_inner();
        if !inner.is_data() {
            return ApiError::invalid_json(format!("the request body is not valid JSON: {inner}"));
        }
        field_error(&path, &without_position(&inner))
    })?;
    de.end()
        .map_err(|e| ApiError::invalid_json(format!("the request body is not valid JSON: {e}")))?;
    Ok(request)
}

/// The offset of the first `[` or `{` (outside strings) that opens level `limit + 1`, if any.
/// Brackets inside strings, escaped quotes included, do not count; malformed JSON is left to
/// the parser.
fn too_deep(body: &[u8], limit: usize) -> Option<usize> {
    let (mut depth, mut in_string, mut escaped) = (0usize, false, false);
    for (i, &b) in body.iter().enumerate() {
        if in_string {
            match b {
                _ if escaped => escaped = false,
                b'\\' => escaped = true,
                b'"' => in_string = false,
                _ => {}
            }
            continue;
        }
        match b {
            b'"' => in_string = true,
            b'[' | b'{' => {
                depth += 1;
                if depth > limit {
                    return Some(i);
                }
            }
            b']' | b'}' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    None
}

/// A serde data error's message without serde_json's ` at line L column C` suffix (the JSON
/// path says where).
fn without_position(e: &serde_json::Error) -> String {
    let text = e.to_string();
    let suffix = format!(" at line {} column {}", e.line(), e.column());
    match text.strip_suffix(&suffix) {
        Some(t) => t.to_owned(),
        None => text,
    }
}

/// The error of a bad field at `path` (serde_path_to_error's form: `.` for the root,
/// `scene.files`). Unknown and missing fields are named by serde's message, so their own name
/// is appended to the path of the object holding them.
fn field_error(path: &str, message: &str) -> ApiError {
    let parent = if path == "." || path == "?" { "" } else { path };
    let named = ["unknown field `", "missing field `"]
        .iter()
        .find_map(|start| message.strip_prefix(start))
        .and_then(|rest| rest.split_once('`'))
        .map(|(name, _)| name);
    let field = match named {
        // serde_path_to_error already ends the path with the unknown key in some versions.
        Some(name) if parent == name || parent.ends_with(&format!(".{name}")) => parent.to_owned(),
        Some(name) if parent.is_empty() => name.to_owned(),
        Some(name) => format!("{parent}.{name}"),
        None if parent.is_empty() => "(root)".to_owned(),
        None => parent.to_owned(),
    };
    ApiError::invalid_field(field.clone(), format!("{field}: {message}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(body: &str) -> ApiError {
        parse_render_request(body.as_bytes()).unwrap_err()
    }

    #[test]
    fn errors_name_the_json_path() {
        let e = err(r#"{"scene": {"key": "a.obj"}, "width": "wide"}"#);
        assert_eq!(e.code, "invalid_request");
        assert_eq!(e.field.as_deref(), Some("width"));
        assert_eq!(
            e.message,
            "width: invalid type: string \"wide\", expected u32"
        );
        let e = err(r#"{"scene": {"key": "a.obj", "colour": 1}}"#);
        assert_eq!(e.field.as_deref(), Some("scene.colour"));
        assert_eq!(
            e.message,
            "scene.colour: unknown field `colour`, expected one of `main`, `files`, `key`"
        );
        let e = err(r#"{"width": 3}"#);
        assert_eq!(e.field.as_deref(), Some("scene"));
        assert_eq!(e.message, "scene: missing field `scene`");
        let e = err(r#"{"scene": {"main": "a.obj", "files": {"a.obj": 7}}}"#);
        assert_eq!(e.field.as_deref(), Some("scene.files.a.obj"));
        let e = err(r#"{"scene": {"key": "a"}, "split_mode": "clever"}"#);
        assert_eq!(
            e.message,
            "split_mode: unknown variant `clever`, expected `naive` or `spatial`"
        );
        let e = err(r#"{"scene": {"key": "a"}, "spp": -1}"#);
        assert_eq!(e.message, "spp: invalid value: integer `-1`, expected u32");
    }

    #[test]
    fn nesting_is_bounded_before_parsing() {
        let deep = format!("{}{}", "[".repeat(9), "]".repeat(9));
        let e = err(&deep);
        assert_eq!(e.code, "invalid_json");
        assert_eq!(
            e.message,
            "the request body nests arrays or objects more than 8 levels deep (at byte 8); a \
             render request needs 3"
        );
        // A million brackets are refused at the ninth, without recursing.
        let e = err(&"{\"a\":".repeat(1_000_000));
        assert_eq!(e.code, "invalid_json");
        assert!(e.message.contains("(at byte 40)"), "{}", e.message);
        // Brackets and escaped quotes inside strings are text.
        let text = format!(
            r#"{{"scene": {{"main": "a.obj", "files": {{"a.obj": "\"{}"}}}}}}"#,
            "[{".repeat(50)
        );
        assert!(parse_render_request(text.as_bytes()).is_ok());
        // Eight levels are allowed (and then refused for their content, not their depth).
        let e = err(&format!(
            r#"{{"scene": {}1{}}}"#,
            "[".repeat(7),
            "]".repeat(7)
        ));
        assert_eq!(e.code, "invalid_request");
    }

    #[test]
    fn malformed_json_is_invalid_json() {
        let e = err(r#"{"scene": "#);
        assert_eq!(e.code, "invalid_json");
        assert_eq!(
            e.message,
            "the request body is not valid JSON: EOF while parsing a value at line 1 column 10"
        );
        assert_eq!(err("  ").code, "invalid_json");
        assert_eq!(err(r#"{"scene": {"key": "a"}} x"#).code, "invalid_json");
        let ok = parse_render_request(br#"{"scene": {"key": "a"}, "width": null}"#).unwrap();
        assert_eq!(ok.width, None);
    }

    /// A JSON key holding a control character (`"\r"` escaped in the body) is echoed escaped,
    /// so the message stays one line.
    #[test]
    fn control_characters_in_keys_stay_escaped() {
        let e = err(r#"{"scene": {"key": "a"}, "x\ry": 1}"#);
        assert_eq!(e.field.as_deref(), Some("x\\ry"));
        assert!(
            e.message.starts_with("x\\ry: unknown field `x\\ry`"),
            "{}",
            e.message
        );
        let e = err(r#"{"scene": {"main": "a", "files": {"a\nb": 7}}}"#);
        assert_eq!(e.field.as_deref(), Some("scene.files.a\\nb"));
    }
}
