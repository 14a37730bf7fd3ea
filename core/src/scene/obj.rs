//! A streaming Wavefront OBJ reader that keeps file order and names the line of every error.
//!
//! Why not `tobj` for the geometry: its errors carry no line numbers and it groups faces into
//! models; we need `path:line` messages and exact file order. Material libraries (`mtllib`) are
//! read with `tobj::load_mtl` (and checked for unrendered features by `mtl.rs`).
//!
//! Accepted: `v x y z [w]`, `vn`, `vt`, `f` with `v`, `v/vt`, `v//vn`, `v/vt/vn` corners and
//! negative (relative) indices, `o`, `g`, `s`, `mg`, `usemtl`, `mtllib` and comments (which may
//! hold any bytes but NUL). Skipped with one warning per kind and file (naming the first line):
//! valid OBJ statements a triangle renderer cannot show (points, lines, free-form geometry,
//! texture maps, display attributes), unknown statements whose keyword looks like a word (a
//! letter, then letters, digits, `_`, `-` or `.`; e.g. the `vw` skin-weight extension), faces
//! naming normals or texture coordinates in a file that defines none (geometric normals are used).
//! "Not an OBJ file": "binary data" for a NUL byte, control bytes or invalid UTF-8 in a keyword
//! or invalid UTF-8 in a statement we read; "unknown statement" for a keyword that is not a word
//! (`<html>`, `{`, `0.5`, `été`).

use super::mesh::{Material, Mesh, NO_NORMAL, NO_TEXCOORD};
use super::mtl::{diffuse_map_lines, first_bad_number, map_file, mtl_warnings, with_full_colours};
use super::world::WorldMesh;
use crate::error::SceneError;
use glam::DVec3;
use std::collections::{HashMap, HashSet};
use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::sync::Arc;

mod stream;
pub use stream::{ObjRange, ObjScan, RangeFaces, parse_obj_range, scan_obj};

/// Grey of faces without a material (and of `usemtl` names no library defines).
pub const DEFAULT_KD: [f32; 3] = [0.7, 0.7, 0.7];

/// Valid OBJ statements that carry nothing a triangle renderer shows, by the kind of thing they
/// describe; each kind is reported once per file.
const UNRENDERED: &[(&str, Unrendered)] = &[
    ("p", Unrendered::PointsAndLines),
    ("l", Unrendered::PointsAndLines),
    ("vp", Unrendered::FreeForm),
    ("cstype", Unrendered::FreeForm),
    ("deg", Unrendered::FreeForm),
    ("bmat", Unrendered::FreeForm),
    ("step", Unrendered::FreeForm),
    ("curv", Unrendered::FreeForm),
    ("curv2", Unrendered::FreeForm),
    ("surf", Unrendered::FreeForm),
    ("parm", Unrendered::FreeForm),
    ("trim", Unrendered::FreeForm),
    ("hole", Unrendered::FreeForm),
    ("scrv", Unrendered::FreeForm),
    ("sp", Unrendered::FreeForm),
    ("end", Unrendered::FreeForm),
    ("con", Unrendered::FreeForm),
    ("ctech", Unrendered::FreeForm),
    ("stech", Unrendered::FreeForm),
    ("usemap", Unrendered::TextureMaps),
    ("maplib", Unrendered::TextureMaps),
    ("lod", Unrendered::Attributes),
    ("bevel", Unrendered::Attributes),
    ("c_interp", Unrendered::Attributes),
    ("d_interp", Unrendered::Attributes),
    ("shadow_obj", Unrendered::Attributes),
    ("trace_obj", Unrendered::Attributes),
];

/// Kinds of valid but unrendered OBJ statements.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Unrendered {
    PointsAndLines,
    FreeForm,
    TextureMaps,
    Attributes,
}

impl Unrendered {
    /// What is not rendered, and what happens instead.
    fn explain(self, keyword: &str) -> String {
        match self {
            Unrendered::PointsAndLines => format!(
                "point and line elements are not rendered; \"{keyword}\" and other point and \
                 line statements are skipped (only faces are rendered)"
            ),
            Unrendered::FreeForm => format!(
                "free-form curves and surfaces are not rendered; \"{keyword}\" and the other \
                 free-form statements are skipped (only polygon faces are rendered)"
            ),
            Unrendered::TextureMaps => format!(
                "texture maps are not rendered; \"{keyword}\" statements are skipped (surfaces \
                 show their material's Kd colour)"
            ),
            Unrendered::Attributes => format!(
                "display and render attributes are not supported; \"{keyword}\" and similar \
                 statements are skipped"
            ),
        }
    }
}

/// Unknown keywords reported one by one; more are counted in one last warning.
const MAX_UNKNOWN_WARNINGS: usize = 8;

/// What a loader does when a material's diffuse texture (`map_Kd`) cannot be used.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TextureFallback {
    /// The scene is refused, naming the texture file and the material (the default).
    #[default]
    Error,
    /// A warning names the texture and what is wrong, and the surface shows its flat Kd.
    Flat,
}

/// Reads an OBJ file (and the MTL libraries it names, relative to its folder), positions in
/// double precision.
pub(super) fn load_obj(
    path: &Path,
    warnings: &mut Vec<String>,
    fallback: TextureFallback,
) -> Result<WorldMesh, SceneError> {
    let file = std::fs::File::open(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let reader = std::io::BufReader::with_capacity(1 << 20, file);
    let mesh = parse_obj_world(reader, path, warnings, fallback)?;
    if mesh.mesh.triangles.is_empty() {
        return Err(SceneError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(mesh)
}

/// Parses OBJ text from `reader`; `path` names the file in errors and locates `mtllib` files.
/// An empty result is not an error here (the caller decides). Positions are the file's
/// coordinates rounded to f32, in the file's own frame (no re-centring: [`crate::scene::load_scene`]
/// is what keeps far-away scenes precise).
pub fn parse_obj(
    reader: impl BufRead,
    path: &Path,
    warnings: &mut Vec<String>,
) -> Result<Mesh, SceneError> {
    let world = parse_obj_world(reader, path, warnings, TextureFallback::Error)?;
    world.into_local(DVec3::ZERO, path)
}

/// [`parse_obj`] with the positions in double precision, as written in the file.
pub(super) fn parse_obj_world(
    mut reader: impl BufRead,
    path: &Path,
    warnings: &mut Vec<String>,
    fallback: TextureFallback,
) -> Result<WorldMesh, SceneError> {
    let mut parser = ObjParser::new(path);
    parser.keep_texcoords = true;
    parser.texture_fallback = fallback;
    let mut buf = Vec::with_capacity(256);
    while read_line(&mut reader, &mut buf, path)? > 0 {
        parser.next_line(&buf)?;
    }
    parser.finish();
    warnings.append(&mut parser.warnings);
    Ok(WorldMesh {
        mesh: parser.mesh,
        positions: parser.positions,
    })
}

/// Reads the next line of `reader` (its `\n` included) into `buf`, replacing what it held;
/// returns its length, 0 at the end. `path` names the file in errors.
fn read_line(
    reader: &mut impl BufRead,
    buf: &mut Vec<u8>,
    path: &Path,
) -> Result<usize, SceneError> {
    buf.clear();
    reader
        .read_until(b'\n', buf)
        .map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })
}

/// Whether an unknown keyword looks like a word of some OBJ extension (so it is skipped with a
/// warning) rather than a sign that the file is something else.
fn is_word(keyword: &str) -> bool {
    let mut chars = keyword.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic())
        && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'))
}

/// The first 24 characters of a keyword, for messages.
fn shown(keyword: &str) -> String {
    keyword.chars().take(24).collect()
}

struct ObjParser<'a> {
    path: &'a Path,
    line: u64,
    /// Everything but the positions, which are in `positions` until the scene is localised.
    mesh: Mesh,
    /// Vertex positions as written, in double precision.
    positions: Vec<DVec3>,
    /// Texture coordinates defined so far (including those before a range).
    texcoords: usize,
    /// Whether texture coordinates are kept in `mesh.texcoords` and faces get their indices:
    /// only when a whole file is read (a file read in ranges with textures is refused).
    keep_texcoords: bool,
    texture_fallback: TextureFallback,
    current_material: u32,
    /// Materials known from `mtllib` files, by name, as (the material, index in mesh.materials
    /// if used).
    library: HashMap<String, (Material, Option<u32>)>,
    warnings: Vec<String>,
    corners: Vec<Corner>,
    /// Material libraries already read by this file (each is checked and reported once).
    libraries: HashSet<PathBuf>,
    /// Kinds of unrendered statements already reported.
    unrendered: HashSet<Unrendered>,
    /// Unknown keywords already seen, and the first unknown keyword not reported one by one
    /// (keyword, line) with the count of such keywords.
    unknown: HashSet<String>,
    unknown_unreported: Option<(String, u64, usize)>,
    /// The first face that named a normal while none was defined: (line, index as written).
    /// A warning if the file never defines one, else the error it always was.
    normal_without_vn: Option<(u64, i64)>,
    /// The same for texture coordinates.
    texcoord_without_vt: Option<(u64, i64)>,
    /// Positions and normals defined before the first one in `positions` and `mesh.normals`
    /// (a file read in ranges: see `stream.rs`). 0 for a whole file.
    position_base: usize,
    normal_base: usize,
    /// Reading one range of a file alone: the material each `usemtl` selects, in order, as the
    /// scan of the whole file found (`mtllib` is then skipped: the scan read the libraries).
    material_script: Option<std::collections::VecDeque<u32>>,
    /// Scanning: the material each `usemtl` selected, in order (see `stream.rs`).
    usemtl_log: Vec<u32>,
}

impl<'a> ObjParser<'a> {
    fn new(path: &'a Path) -> Self {
        let mut mesh = Mesh::default();
        mesh.materials.push(Material::plain("default", DEFAULT_KD));
        ObjParser {
            path,
            line: 0,
            mesh,
            positions: Vec::new(),
            texcoords: 0,
            keep_texcoords: false,
            texture_fallback: TextureFallback::Error,
            current_material: 0,
            library: HashMap::new(),
            warnings: Vec::new(),
            corners: Vec::new(),
            libraries: HashSet::new(),
            unrendered: HashSet::new(),
            unknown: HashSet::new(),
            unknown_unreported: None,
            normal_without_vn: None,
            texcoord_without_vt: None,
            position_base: 0,
            normal_base: 0,
            material_script: None,
            usemtl_log: Vec::new(),
        }
    }

    /// Positions defined so far (including those before a range).
    fn position_count(&self) -> usize {
        self.position_base + self.positions.len()
    }

    /// Normals defined so far (including those before a range).
    fn normal_count(&self) -> usize {
        self.normal_base + self.mesh.normals.len()
    }

    /// Counts and reads the next line (a UTF-8 byte-order mark is dropped from line 1).
    fn next_line(&mut self, line: &[u8]) -> Result<(), SceneError> {
        self.line += 1;
        let line = match line.strip_prefix(b"\xEF\xBB\xBF") {
            Some(rest) if self.line == 1 => rest,
            _ => line,
        };
        self.statement(line)
    }

    /// `file:line` of the current line, for warnings.
    fn here(&self) -> String {
        format!("{}:{}", self.path.display(), self.line)
    }

    /// The error a face referring to an undefined normal or texture coordinate always got.
    fn undefined_index(&self, line: u64, what: &'static str, index: i64) -> SceneError {
        SceneError::IndexOutOfRange {
            path: self.path.to_path_buf(),
            line,
            what,
            index,
            count: 0,
        }
    }

    /// End of file: report what was skipped as a whole. Texture coordinates no textured
    /// triangle uses are dropped (the binary scene does not carry them).
    fn finish(&mut self) {
        if self.mesh.triangle_texcoords.is_empty() {
            self.mesh.texcoords = Vec::new();
        }
        let path = self.path.display();
        if let Some((line, _)) = self.normal_without_vn {
            self.warnings.push(format!(
                "{path}:{line}: faces name vertex normals, but the file defines none (no \"vn\" \
                 statements); those faces use their geometric normal (flat shading)"
            ));
        }
        if let Some((line, _)) = self.texcoord_without_vt {
            self.warnings.push(format!(
                "{path}:{line}: faces name texture coordinates, but the file defines none (no \
                 \"vt\" statements); they are ignored (their materials show no texture)"
            ));
        }
        if let Some((keyword, line, more)) = self.unknown_unreported.take() {
            self.warnings.push(format!(
                "{path}: {more} more unknown statement keywords skipped (the first, \"{keyword}\", \
                 at line {line}); is this really an OBJ file?"
            ));
        }
    }

    /// Notes an unknown keyword (known not to be a sign of another format): one warning per
    /// keyword, up to [`MAX_UNKNOWN_WARNINGS`] keywords, then a count.
    fn unknown_statement(&mut self, keyword: &str) {
        if self.unknown.contains(keyword) {
            return;
        }
        self.unknown.insert(keyword.to_string());
        let keyword = shown(keyword);
        if self.unknown.len() <= MAX_UNKNOWN_WARNINGS {
            self.warnings.push(format!(
                "{}: unknown statement \"{keyword}\" skipped",
                self.here()
            ));
        } else {
            let line = self.line;
            self.unknown_unreported.get_or_insert((keyword, line, 0)).2 += 1;
        }
    }

    fn not_obj(&self, detail: &str) -> SceneError {
        SceneError::NotObj {
            path: self.path.to_path_buf(),
            line: self.line,
            detail: detail.to_string(),
        }
    }

    fn syntax(&self, detail: String) -> SceneError {
        SceneError::Syntax {
            path: self.path.to_path_buf(),
            line: self.line,
            detail,
        }
    }

    /// One line, comment included.
    fn statement(&mut self, line: &[u8]) -> Result<(), SceneError> {
        if line.contains(&0) {
            return Err(self.not_obj("binary data"));
        }
        let code = line.split(|&b| b == b'#').next().unwrap_or_default();
        let start = code
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .unwrap_or(code.len());
        let code = &code[start..];
        let end = code
            .iter()
            .position(|b| b.is_ascii_whitespace())
            .unwrap_or(code.len());
        let (keyword, rest) = code.split_at(end);
        if keyword.is_empty() {
            return Ok(());
        }
        // Control bytes or invalid UTF-8 in the keyword: not text.
        if keyword.iter().any(u8::is_ascii_control) {
            return Err(self.not_obj("binary data"));
        }
        let keyword = std::str::from_utf8(keyword).map_err(|_| self.not_obj("binary data"))?;
        let text = |p: &Self| std::str::from_utf8(rest).map_err(|_| p.not_obj("binary data"));
        match keyword {
            "v" => {
                let p = self.vector(&mut text(self)?.split_ascii_whitespace(), "vertex")?;
                self.positions.push(p);
            }
            "vn" => {
                if let Some((line, index)) = self.normal_without_vn {
                    return Err(self.undefined_index(line, "normal", index));
                }
                let n = self.vector(&mut text(self)?.split_ascii_whitespace(), "normal")?;
                self.mesh.normals.push(n.as_vec3());
            }
            "vt" => {
                if let Some((line, index)) = self.texcoord_without_vt {
                    return Err(self.undefined_index(line, "texture coordinate", index));
                }
                let uv = self.texcoord(&mut text(self)?.split_ascii_whitespace())?;
                if self.keep_texcoords {
                    self.mesh.texcoords.push(uv);
                }
                self.texcoords += 1;
            }
            "f" | "fo" => self.face(text(self)?.split_ascii_whitespace())?,
            "usemtl" => {
                let name = text(self)?.split_ascii_whitespace().next().unwrap_or("");
                self.use_material(name)?;
            }
            "mtllib" if self.material_script.is_some() => {}
            "mtllib" => {
                for file in text(self)?.split_ascii_whitespace() {
                    self.load_library(file)?;
                }
            }
            "o" | "g" | "s" | "mg" => {}
            k => {
                if let Some(&(_, kind)) = UNRENDERED.iter().find(|(name, _)| *name == k) {
                    if self.unrendered.insert(kind) {
                        let message = format!("{}: {}", self.here(), kind.explain(k));
                        self.warnings.push(message);
                    }
                } else if is_word(k) {
                    self.unknown_statement(k);
                } else {
                    let shown = shown(k);
                    return Err(self.not_obj(&format!("unknown statement \"{shown}\"")));
                }
            }
        }
        Ok(())
    }

    fn vector<'w>(
        &self,
        words: &mut impl Iterator<Item = &'w str>,
        what: &'static str,
    ) -> Result<DVec3, SceneError> {
        let mut xyz = [0.0f64; 3];
        for (axis, slot) in xyz.iter_mut().enumerate() {
            let word = words
                .next()
                .ok_or_else(|| self.syntax(format!("{what} needs 3 coordinates, found {axis}")))?;
            // Read in double precision (the scene is re-centred before rounding to f32), but
            // refused, as always, where f32 cannot hold the coordinate.
            let value: f64 = word.parse().map_err(|_| {
                self.syntax(format!("{what} coordinate \"{word}\" is not a number"))
            })?;
            if !(value as f32).is_finite() {
                return Err(SceneError::NonFinite {
                    path: self.path.to_path_buf(),
                    line: self.line,
                    what,
                    text: word.to_string(),
                });
            }
            *slot = value;
        }
        Ok(DVec3::from(xyz))
    }

    /// `u [v [w]]` of a `vt` statement (v defaults to 0; w is not used), finite in f32.
    fn texcoord<'w>(
        &self,
        words: &mut impl Iterator<Item = &'w str>,
    ) -> Result<[f32; 2], SceneError> {
        let what = "texture coordinate";
        let mut uv = [0.0f32; 2];
        for (axis, slot) in uv.iter_mut().enumerate() {
            let Some(word) = words.next() else {
                if axis == 0 {
                    return Err(self.syntax(format!("{what} needs 1 to 3 values, found 0")));
                }
                break;
            };
            let value: f32 = word
                .parse()
                .map_err(|_| self.syntax(format!("{what} value \"{word}\" is not a number")))?;
            if !value.is_finite() {
                return Err(SceneError::NonFinite {
                    path: self.path.to_path_buf(),
                    line: self.line,
                    what,
                    text: word.to_string(),
                });
            }
            *slot = value;
        }
        Ok(uv)
    }

    fn face<'w>(&mut self, words: impl Iterator<Item = &'w str>) -> Result<(), SceneError> {
        let mut corners = std::mem::take(&mut self.corners);
        corners.clear();
        for word in words {
            corners.push(self.corner(word)?);
        }
        if corners.len() < 3 {
            return Err(self.syntax(format!(
                "face needs at least 3 corners, found {}",
                corners.len()
            )));
        }
        let textured = self.keep_texcoords
            && self.mesh.materials[self.current_material as usize]
                .texture
                .is_some()
            && corners.iter().all(|c| c.texcoord != NO_TEXCOORD);
        if textured && self.mesh.triangle_texcoords.is_empty() {
            let n = self.mesh.triangles.len();
            self.mesh.triangle_texcoords.resize(n, [NO_TEXCOORD; 3]);
        }
        for i in 1..corners.len() - 1 {
            let (a, b, c) = (corners[0], corners[i], corners[i + 1]);
            self.mesh
                .triangles
                .push([a.position, b.position, c.position]);
            let normals = if a.normal == NO_NORMAL || b.normal == NO_NORMAL || c.normal == NO_NORMAL
            {
                [NO_NORMAL; 3]
            } else {
                [a.normal, b.normal, c.normal]
            };
            self.mesh.triangle_normals.push(normals);
            self.mesh.triangle_materials.push(self.current_material);
            if textured {
                let uv = [a.texcoord, b.texcoord, c.texcoord];
                self.mesh.triangle_texcoords.push(uv);
            } else if !self.mesh.triangle_texcoords.is_empty() {
                self.mesh.triangle_texcoords.push([NO_TEXCOORD; 3]);
            }
        }
        self.corners = corners;
        Ok(())
    }

    /// Resolves one `v[/vt][/vn]` corner. A normal or texture coordinate named while the file
    /// has defined none is noted (see `normal_without_vn`) and left out.
    fn corner(&mut self, word: &str) -> Result<Corner, SceneError> {
        let mut parts = word.split('/');
        let v = parts.next().unwrap_or("");
        let vt = parts.next().unwrap_or("");
        let vn = parts.next().unwrap_or("");
        let position = self.index(v, self.position_count(), "vertex")?;
        let mut texcoord = NO_TEXCOORD;
        if !vt.is_empty() {
            if self.texcoords == 0 {
                let raw = self.raw_index(vt, "texture coordinate")?;
                if raw == 0 {
                    return Err(self.undefined_index(self.line, "texture coordinate", raw));
                }
                self.texcoord_without_vt.get_or_insert((self.line, raw));
            } else {
                texcoord = self.index(vt, self.texcoords, "texture coordinate")?;
            }
        }
        let normal = if vn.is_empty() {
            NO_NORMAL
        } else if self.normal_count() == 0 {
            let raw = self.raw_index(vn, "normal")?;
            if raw == 0 {
                return Err(self.undefined_index(self.line, "normal", raw));
            }
            self.normal_without_vn.get_or_insert((self.line, raw));
            NO_NORMAL
        } else {
            self.index(vn, self.normal_count(), "normal")?
        };
        Ok(Corner {
            position,
            texcoord,
            normal,
        })
    }

    fn raw_index(&self, word: &str, what: &'static str) -> Result<i64, SceneError> {
        word.parse()
            .map_err(|_| self.syntax(format!("face {what} index \"{word}\" is not an integer")))
    }

    fn index(&self, word: &str, count: usize, what: &'static str) -> Result<u32, SceneError> {
        let raw = self.raw_index(word, what)?;
        let resolved = if raw > 0 { raw - 1 } else { count as i64 + raw };
        if raw == 0 || resolved < 0 || resolved >= count as i64 || resolved >= i64::from(NO_NORMAL)
        {
            return Err(SceneError::IndexOutOfRange {
                path: self.path.to_path_buf(),
                line: self.line,
                what,
                index: raw,
                count,
            });
        }
        Ok(resolved as u32)
    }

    fn use_material(&mut self, name: &str) -> Result<(), SceneError> {
        if self.material_script.is_some() {
            let next = self.material_script.as_mut().and_then(|s| s.pop_front());
            self.current_material = next.ok_or_else(|| {
                self.syntax("more usemtl statements than the scan of the file found".into())
            })?;
            return Ok(());
        }
        self.select_material(name);
        self.usemtl_log.push(self.current_material);
        Ok(())
    }

    fn select_material(&mut self, name: &str) {
        match self.library.get_mut(name) {
            Some((material, slot)) => {
                let index = *slot.get_or_insert_with(|| {
                    self.mesh.materials.push(material.clone());
                    (self.mesh.materials.len() - 1) as u32
                });
                self.current_material = index;
            }
            None => {
                self.warnings.push(format!(
                    "{}:{}: material {name:?} is not defined by any mtllib; using grey {}",
                    self.path.display(),
                    self.line,
                    DEFAULT_KD[0]
                ));
                self.current_material = 0;
            }
        }
    }

    fn load_library(&mut self, file: &str) -> Result<(), SceneError> {
        let mtl_path: PathBuf = self.path.parent().unwrap_or(Path::new(".")).join(file);
        if !mtl_path.is_file() {
            self.warnings.push(format!(
                "{}:{}: material library {} not found; its materials render grey",
                self.path.display(),
                self.line,
                mtl_path.display()
            ));
            return Ok(());
        }
        let mtl_error = |detail: String| SceneError::Mtl {
            path: mtl_path.clone(),
            detail,
        };
        let bytes = std::fs::read(&mtl_path).map_err(|source| SceneError::Io {
            path: mtl_path.clone(),
            source,
        })?;
        let text = std::str::from_utf8(&bytes).map_err(|e| {
            mtl_error(format!(
                "not UTF-8 text (invalid UTF-8 at byte offset {})",
                e.valid_up_to()
            ))
        })?;
        let full = with_full_colours(text).map_err(|(line, statement)| {
            mtl_error(format!(
                "line {line}: {statement:?} needs 3 values (r g b) or 1 (grey)"
            ))
        })?;
        let (materials, _) = tobj::load_mtl_buf(&mut full.as_bytes()).map_err(|e| {
            // tobj says only what failed; find the line for the message.
            let detail = match first_bad_number(text) {
                Some((line, statement)) => {
                    format!("line {line}: {statement:?} is not a valid statement ({e})")
                }
                None => e.to_string(),
            };
            SceneError::Mtl {
                path: mtl_path.clone(),
                detail,
            }
        })?;
        if self.libraries.insert(mtl_path.clone()) {
            self.warnings.extend(mtl_warnings(&mtl_path, text));
        }
        let map_lines = diffuse_map_lines(text);
        for m in materials {
            let kd = m.diffuse.unwrap_or(DEFAULT_KD);
            if kd.iter().any(|c| !c.is_finite()) {
                return Err(SceneError::Mtl {
                    path: mtl_path,
                    detail: format!("material {:?} has a non-finite Kd", m.name),
                });
            }
            if self.library.contains_key(&m.name) {
                continue;
            }
            let texture = match m.diffuse_texture.as_deref() {
                Some(map) => {
                    let line = map_lines.get(&m.name).copied().unwrap_or(0);
                    if !self.keep_texcoords {
                        return Err(SceneError::Texture {
                            path: mtl_path.parent().unwrap_or(Path::new(".")).join(map),
                            material: format!(
                                "{}:{line} material {:?}",
                                mtl_path.display(),
                                m.name
                            ),
                            detail: "diffuse textures are rendered only in scenes loaded whole, \
                                     and this one is read in ranges (it is too large for one \
                                     function's memory): raise --memory-mb, or remove the map_Kd"
                                .into(),
                        });
                    }
                    self.diffuse_map(&mtl_path, line, &m.name, map)?
                }
                None => None,
            };
            let material = Material {
                name: m.name.clone(),
                kd,
                texture,
            };
            self.library.insert(m.name, (material, None));
        }
        Ok(())
    }

    /// Loads the diffuse map `map` (the `map_Kd` statement's file, after any options) of
    /// material `material`, named at `library:line`, relative to the library's folder; its index
    /// in the mesh's textures. A texture that cannot be used is an error naming the file and the
    /// material, or with [`TextureFallback::Flat`] a warning, and `None`.
    fn diffuse_map(
        &mut self,
        library: &Path,
        line: usize,
        material: &str,
        map: &str,
    ) -> Result<Option<u32>, SceneError> {
        let file = map_file(map);
        let path = library.parent().unwrap_or(Path::new(".")).join(file);
        let name = Path::new(file)
            .file_name()
            .map_or_else(|| file.to_string(), |n| n.to_string_lossy().into_owned());
        match crate::texture::decode_texture_file(&path, &name) {
            Ok(texture) => Ok(Some(self.mesh.texture_id(Arc::new(texture)))),
            Err(detail) => {
                let error = SceneError::Texture {
                    path,
                    material: format!("{}:{line} material {material:?}", library.display()),
                    detail,
                };
                match self.texture_fallback {
                    TextureFallback::Error => Err(error),
                    TextureFallback::Flat => {
                        self.warnings.push(format!(
                            "{error}; the surface shows its flat Kd colour instead \
                             (--missing-textures flat)"
                        ));
                        Ok(None)
                    }
                }
            }
        }
    }
}

/// One face corner: its position index, and its texture coordinate and normal indices or
/// [`NO_TEXCOORD`] / [`NO_NORMAL`].
#[derive(Clone, Copy, Debug)]
struct Corner {
    position: u32,
    texcoord: u32,
    normal: u32,
}
