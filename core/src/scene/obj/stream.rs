//! An OBJ file read in byte ranges, so that no one reader holds the whole file's geometry.
//!
//! [`scan_obj`] reads the file once, front to back, exactly as [`super::parse_obj_world`] does
//! (the same errors and warnings, with the same `path:line`), but keeps only one range's
//! vertices at a time: every `range_bytes` bytes (at the next line start) it closes a range,
//! hands its vertex positions and normals to the caller, and forgets them and its faces. What
//! each range's lines need from the lines before it (line number, vertex, normal and texture
//! coordinate counts, the current material, and the material each of its `usemtl` statements
//! selects) is recorded in its [`ObjRange`].
//!
//! [`parse_obj_range`] then reads one range alone, from its bytes and its [`ObjRange`]: its faces
//! come out with the indices, normal indices and materials the whole-file parse gives them
//! (vertex and normal indices count from the start of the file, so a face may name a vertex of
//! an earlier range; the caller looks those up in what the scan handed out).

use super::{ObjParser, SceneError, read_line};
use crate::scene::mesh::Material;
use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One byte range of an OBJ file (whole lines) and what its lines need from the lines before.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObjRange {
    /// Byte offset of the range's first line in the file.
    pub start: u64,
    /// Byte offset just past the range's last line (the next range's `start`).
    pub end: u64,
    /// Lines before the range.
    pub line: u64,
    /// Vertex positions defined before the range.
    pub vertices: u64,
    /// Vertex normals defined before the range.
    pub normals: u64,
    /// Texture coordinates defined before the range.
    pub texcoords: u64,
    /// The material current at the range's start (an index into the file's materials).
    pub material: u32,
    /// The material each `usemtl` statement of the range selects, in order.
    pub usemtl: Vec<u32>,
    /// Vertex positions the range defines.
    pub vertex_count: u64,
    /// Vertex normals the range defines.
    pub normal_count: u64,
    /// Triangles the range's faces make.
    pub triangle_count: u64,
}

/// What [`scan_obj`] learnt of a whole file.
#[derive(Clone, Debug)]
pub struct ObjScan {
    /// The ranges, in file order; together they cover the file.
    pub ranges: Vec<ObjRange>,
    /// The file's materials (index 0 the default grey), as the whole-file parse numbers them.
    pub materials: Vec<Material>,
    /// The bounding box of every vertex position as written (used or not), `None` without any.
    pub vertex_bounds: Option<(DVec3, DVec3)>,
    /// Triangles in the file.
    pub triangles: u64,
}

/// Reads the OBJ file `path` front to back in ranges of about `range_bytes` bytes (at least
/// one line each), checking it exactly as a whole-file load does (a file without triangles is
/// [`SceneError::Empty`]). `on_range` gets each range as it closes, with the vertex positions
/// (as written, double precision) and normals it defines; they are dropped afterwards.
pub fn scan_obj<E: From<SceneError>>(
    path: &Path,
    range_bytes: u64,
    warnings: &mut Vec<String>,
    mut on_range: impl FnMut(&ObjRange, &[DVec3], &[Vec3]) -> Result<(), E>,
) -> Result<ObjScan, E> {
    let file = std::fs::File::open(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut reader = std::io::BufReader::with_capacity(1 << 20, file);
    let mut parser = ObjParser::new(path);
    let mut scan = ObjScan {
        ranges: Vec::new(),
        materials: Vec::new(),
        vertex_bounds: None,
        triangles: 0,
    };
    let mut range = open_range(&parser, 0);
    let mut offset = 0u64;
    let mut buf = Vec::with_capacity(256);
    loop {
        let n = read_line(&mut reader, &mut buf, path)?;
        if n == 0 {
            break;
        }
        if offset - range.start >= range_bytes.max(1) {
            close_range(&mut parser, &mut scan, range, offset, &mut on_range)?;
            range = open_range(&parser, offset);
        }
        parser.next_line(&buf)?;
        offset += n as u64;
    }
    close_range(&mut parser, &mut scan, range, offset, &mut on_range)?;
    parser.finish();
    warnings.append(&mut parser.warnings);
    if scan.triangles == 0 {
        return Err(SceneError::Empty {
            path: path.to_path_buf(),
        }
        .into());
    }
    scan.materials = parser.mesh.materials;
    Ok(scan)
}

/// A range starting at byte `start`, where `parser` stands.
fn open_range(parser: &ObjParser, start: u64) -> ObjRange {
    ObjRange {
        start,
        end: start,
        line: parser.line,
        vertices: parser.position_count() as u64,
        normals: parser.normal_count() as u64,
        texcoords: parser.texcoords as u64,
        material: parser.current_material,
        usemtl: Vec::new(),
        vertex_count: 0,
        normal_count: 0,
        triangle_count: 0,
    }
}

/// Ends `range` at byte `end`: hands it out with its vertices, then forgets them and its faces.
fn close_range<E>(
    parser: &mut ObjParser,
    scan: &mut ObjScan,
    mut range: ObjRange,
    end: u64,
    on_range: &mut impl FnMut(&ObjRange, &[DVec3], &[Vec3]) -> Result<(), E>,
) -> Result<(), E> {
    range.end = end;
    range.usemtl = std::mem::take(&mut parser.usemtl_log);
    range.vertex_count = parser.positions.len() as u64;
    range.normal_count = parser.mesh.normals.len() as u64;
    range.triangle_count = parser.mesh.triangles.len() as u64;
    for &p in &parser.positions {
        let (lo, hi) = scan.vertex_bounds.get_or_insert((p, p));
        *lo = lo.min(p);
        *hi = hi.max(p);
    }
    on_range(&range, &parser.positions, &parser.mesh.normals)?;
    parser.position_base += parser.positions.len();
    parser.normal_base += parser.mesh.normals.len();
    parser.positions.clear();
    parser.mesh.normals.clear();
    parser.mesh.triangles.clear();
    parser.mesh.triangle_normals.clear();
    parser.mesh.triangle_materials.clear();
    scan.triangles += range.triangle_count;
    scan.ranges.push(range);
    Ok(())
}

/// The faces of one range, as the whole-file parse gives them.
#[derive(Clone, Debug, Default)]
pub struct RangeFaces {
    /// Vertex positions the range defines (as written); the first has index `range.vertices`.
    pub positions: Vec<DVec3>,
    /// Normals the range defines; the first has index `range.normals`.
    pub normals: Vec<Vec3>,
    /// Each triangle's corners: vertex indices from the start of the file.
    pub triangles: Vec<[u32; 3]>,
    /// Each triangle's corner normals (indices from the start of the file), or `NO_NORMAL`.
    pub triangle_normals: Vec<[u32; 3]>,
    /// Each triangle's material (an index into the file's materials).
    pub triangle_materials: Vec<u32>,
}

/// Reads the range `range` of the OBJ file `path` from its bytes alone (the scan checked the
/// file, so an error here means the bytes are not those the scan read; it names the line).
pub fn parse_obj_range(
    bytes: &[u8],
    path: &Path,
    range: &ObjRange,
) -> Result<RangeFaces, SceneError> {
    let mut parser = ObjParser::new(path);
    parser.line = range.line;
    parser.position_base = range.vertices as usize;
    parser.normal_base = range.normals as usize;
    parser.texcoords = range.texcoords as usize;
    parser.current_material = range.material;
    parser.material_script = Some(range.usemtl.iter().copied().collect());
    for line in bytes.split_inclusive(|&b| b == b'\n') {
        parser.next_line(line)?;
    }
    let found = (
        parser.positions.len() as u64,
        parser.mesh.normals.len() as u64,
        parser.mesh.triangles.len() as u64,
    );
    let expected = (range.vertex_count, range.normal_count, range.triangle_count);
    if found != expected
        || parser
            .material_script
            .as_ref()
            .is_some_and(|s| !s.is_empty())
    {
        return Err(parser.syntax(format!(
            "bytes {}..{} hold {found:?} vertices, normals and triangles, but the scan of the \
             file found {expected:?}: the file changed between the scan and this read",
            range.start, range.end
        )));
    }
    let mesh = parser.mesh;
    Ok(RangeFaces {
        positions: parser.positions,
        normals: mesh.normals,
        triangles: mesh.triangles,
        triangle_normals: mesh.triangle_normals,
        triangle_materials: mesh.triangle_materials,
    })
}
