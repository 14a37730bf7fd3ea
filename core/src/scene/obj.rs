//! A streaming Wavefront OBJ reader that keeps file order and names the line of every error.
//!
//! Why not `tobj` for the geometry: its errors carry no line numbers and it groups faces into
//! models; we need `path:line` messages and exact file order. Material libraries (`mtllib`) are
//! read with `tobj::load_mtl`.
//!
//! Accepted: `v x y z [w]`, `vn`, `vt`, `f` with `v`, `v/vt`, `v//vn`, `v/vt/vn` corners and
//! negative (relative) indices, `o`, `g`, `s`, `usemtl`, `mtllib`, comments, and the free-form
//! curve statements (ignored). Any other statement, or binary data, is "not an OBJ file".

use super::mesh::{Material, Mesh, NO_NORMAL};
use crate::error::SceneError;
use glam::Vec3;
use std::collections::HashMap;
use std::io::BufRead;
use std::path::{Path, PathBuf};

/// Grey of faces without a material (and of `usemtl` names no library defines).
pub const DEFAULT_KD: [f32; 3] = [0.7, 0.7, 0.7];

/// Statements that are valid OBJ but carry nothing a triangle renderer uses.
const IGNORED: &[&str] = &[
    "vp",
    "l",
    "p",
    "cstype",
    "deg",
    "bmat",
    "step",
    "curv",
    "curv2",
    "surf",
    "parm",
    "trim",
    "hole",
    "scrv",
    "sp",
    "end",
    "con",
    "mg",
    "bevel",
    "c_interp",
    "d_interp",
    "lod",
    "usemap",
    "maplib",
    "shadow_obj",
    "trace_obj",
    "ctech",
    "stech",
];

/// Reads an OBJ file (and the MTL libraries it names, relative to its folder).
pub fn load_obj(path: &Path, warnings: &mut Vec<String>) -> Result<Mesh, SceneError> {
    let file = std::fs::File::open(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let reader = std::io::BufReader::with_capacity(1 << 20, file);
    let mesh = parse_obj(reader, path, warnings)?;
    if mesh.triangles.is_empty() {
        return Err(SceneError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(mesh)
}

/// Parses OBJ text from `reader`; `path` names the file in errors and locates `mtllib` files.
/// An empty result is not an error here (the caller decides).
pub fn parse_obj(
    mut reader: impl BufRead,
    path: &Path,
    warnings: &mut Vec<String>,
) -> Result<Mesh, SceneError> {
    let mut parser = ObjParser::new(path);
    let mut buf = Vec::with_capacity(256);
    loop {
        buf.clear();
        let n = reader
            .read_until(b'\n', &mut buf)
            .map_err(|source| SceneError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        if n == 0 {
            break;
        }
        parser.line += 1;
        let text = std::str::from_utf8(&buf).map_err(|_| parser.not_obj("binary data"))?;
        parser.statement(text)?;
    }
    warnings.append(&mut parser.warnings);
    Ok(parser.mesh)
}

struct ObjParser<'a> {
    path: &'a Path,
    line: u64,
    mesh: Mesh,
    texcoords: usize,
    current_material: u32,
    /// Materials known from `mtllib` files, by name, as (kd, index in mesh.materials if used).
    library: HashMap<String, ([f32; 3], Option<u32>)>,
    warnings: Vec<String>,
    corners: Vec<(u32, u32)>,
}

impl<'a> ObjParser<'a> {
    fn new(path: &'a Path) -> Self {
        let mut mesh = Mesh::default();
        mesh.materials.push(Material {
            name: "default".into(),
            kd: DEFAULT_KD,
        });
        ObjParser {
            path,
            line: 0,
            mesh,
            texcoords: 0,
            current_material: 0,
            library: HashMap::new(),
            warnings: Vec::new(),
            corners: Vec::new(),
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

    fn statement(&mut self, text: &str) -> Result<(), SceneError> {
        let text = text.split('#').next().unwrap_or("");
        let mut words = text.split_ascii_whitespace();
        let Some(keyword) = words.next() else {
            return Ok(());
        };
        match keyword {
            "v" => {
                let p = self.vector(&mut words, "vertex")?;
                self.mesh.positions.push(p);
            }
            "vn" => {
                let n = self.vector(&mut words, "normal")?;
                self.mesh.normals.push(n);
            }
            "vt" => self.texcoords += 1,
            "f" | "fo" => self.face(words)?,
            "usemtl" => self.use_material(words.next().unwrap_or("")),
            "mtllib" => {
                for file in words {
                    self.load_library(file)?;
                }
            }
            "o" | "g" | "s" => {}
            k if IGNORED.contains(&k) => {}
            k => {
                let shown: String = k.chars().take(24).collect();
                return Err(self.not_obj(&format!("unknown statement \"{shown}\"")));
            }
        }
        Ok(())
    }

    fn vector<'w>(
        &self,
        words: &mut impl Iterator<Item = &'w str>,
        what: &'static str,
    ) -> Result<Vec3, SceneError> {
        let mut xyz = [0.0f32; 3];
        for (axis, slot) in xyz.iter_mut().enumerate() {
            let word = words
                .next()
                .ok_or_else(|| self.syntax(format!("{what} needs 3 coordinates, found {axis}")))?;
            let value: f32 = word.parse().map_err(|_| {
                self.syntax(format!("{what} coordinate \"{word}\" is not a number"))
            })?;
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
        Ok(Vec3::from(xyz))
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
        for i in 1..corners.len() - 1 {
            let (a, b, c) = (corners[0], corners[i], corners[i + 1]);
            self.mesh.triangles.push([a.0, b.0, c.0]);
            let normals = if a.1 == NO_NORMAL || b.1 == NO_NORMAL || c.1 == NO_NORMAL {
                [NO_NORMAL; 3]
            } else {
                [a.1, b.1, c.1]
            };
            self.mesh.triangle_normals.push(normals);
            self.mesh.triangle_materials.push(self.current_material);
        }
        self.corners = corners;
        Ok(())
    }

    /// Resolves one `v[/vt][/vn]` corner to (position index, normal index or NO_NORMAL).
    fn corner(&self, word: &str) -> Result<(u32, u32), SceneError> {
        let mut parts = word.split('/');
        let v = parts.next().unwrap_or("");
        let vt = parts.next().unwrap_or("");
        let vn = parts.next().unwrap_or("");
        let position = self.index(v, self.mesh.positions.len(), "vertex")?;
        if !vt.is_empty() {
            self.index(vt, self.texcoords, "texture coordinate")?;
        }
        let normal = if vn.is_empty() {
            NO_NORMAL
        } else {
            self.index(vn, self.mesh.normals.len(), "normal")?
        };
        Ok((position, normal))
    }

    fn index(&self, word: &str, count: usize, what: &'static str) -> Result<u32, SceneError> {
        let raw: i64 = word
            .parse()
            .map_err(|_| self.syntax(format!("face {what} index \"{word}\" is not an integer")))?;
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

    fn use_material(&mut self, name: &str) {
        match self.library.get_mut(name) {
            Some((kd, slot)) => {
                let index = *slot.get_or_insert_with(|| {
                    self.mesh.materials.push(Material {
                        name: name.to_string(),
                        kd: *kd,
                    });
                    (self.mesh.materials.len() - 1) as u32
                });
                self.current_material = index;
            }
            None => {
                self.warnings.push(format!(
                    "{}:{}: material \"{name}\" is not defined by any mtllib; using grey {}",
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
        let (materials, _) = tobj::load_mtl(&mtl_path).map_err(|e| SceneError::Mtl {
            path: mtl_path.clone(),
            detail: e.to_string(),
        })?;
        for m in materials {
            let kd = m.diffuse.unwrap_or(DEFAULT_KD);
            if kd.iter().any(|c| !c.is_finite()) {
                return Err(SceneError::Mtl {
                    path: mtl_path,
                    detail: format!("material \"{}\" has a non-finite Kd", m.name),
                });
            }
            self.library.entry(m.name).or_insert((kd, None));
        }
        Ok(())
    }
}
