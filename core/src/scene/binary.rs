//! The binary scene: a parsed [`Scene`] as one compact, versioned, checksummed object, so that
//! a scene parsed once (by the client) is never parsed again (by the Plan function, or by a
//! Worker rebuilding a lost split).
//!
//! Layout (all integers and floats little-endian, floats as their IEEE bits):
//!
//! | bytes | field |
//! |---|---|
//! | 0..8 | magic `HORTSCN\0` |
//! | 8..10 | format version, u16 = [`SCENE_BINARY_VERSION`] |
//! | 10..12 | reserved, u16 = 0 |
//! | 12..20 | body length in bytes, u64 |
//! | 20..24 | CRC-32 (as the shuffle blocks use) of bytes 0..20 followed by the body |
//! | 24.. | the body |
//!
//! The body, in this order: `origin` (3 f64); `source` (string); the triangle count n (u64),
//! then `triangles` (3n u32), `triangle_normals` (3n u32, [`NO_NORMAL`] for none),
//! `triangle_materials` (n u32); `positions` (u64 count, 3 f32 each); `normals` (u64 count, 3
//! f32 each); `materials` (u32 count, each a name string and 3 f32 kd); the camera (eye,
//! look_at, up: 3 f64 each, then vfov f64); `framed_bounds` (u8 0 or 1, then 6 f64 if 1);
//! `lights` (u32 count, each a u8 kind, 0 point or 1 directional, 3 f64 position or direction,
//! 3 f32 intensity or irradiance); `ambient`, `background` (3 f32 each); width, height, spp
//! (each a u8 0 or 1, then a u32 if 1); `warnings` (u32 count of strings); the texture
//! section (`textures.rs`: texture coordinates, each material's texture, the textures). A
//! string is a u32 byte length and UTF-8 bytes. Nothing follows the last field.
//!
//! A scene with an `animation` (a manifest's camera keyframes, in the local frame) has one more
//! field after the texture section: the animation as a JSON string (serde_json writes and reads
//! every f64 exactly), checked again when read. A scene without one ends with the textures, so
//! its bytes are those of a scene from before animations.
//!
//! Guarantees: [`encode_scene`] is deterministic (the same scene gives the same bytes on every
//! platform), and `decode_scene(encode_scene(s))` equals `s` exactly, floats bit for bit (a `source` path that is not UTF-8 is stored lossily). [`decode_scene`] never panics and
//! accepts only what a loader could have produced: every check of the header, the checksum,
//! each count against the bytes left, every index in range, every float finite and at least
//! one triangle; each failure is one line naming the object, the field and its byte offset.
//! Arrays are read in bulk, so decoding runs at memory speed.

mod textures;

use super::mesh::{Material, Mesh, NO_NORMAL};
use super::{CameraSpec, ImageSettings, Light, Scene};
use crate::animation::Animation;
use glam::{DVec3, Vec3};
use std::path::PathBuf;

/// The first 8 bytes of every binary scene.
pub const SCENE_BINARY_MAGIC: [u8; 8] = *b"HORTSCN\0";
/// The format version this build writes, and the only one it reads.
pub const SCENE_BINARY_VERSION: u16 = 2;
/// Header length in bytes; the body starts here.
pub const SCENE_BINARY_HEADER_LEN: usize = 24;
/// Offset of the CRC in the header; it covers every header byte before it and the body.
const CRC_AT: usize = 20;

/// Why bytes are not a binary scene. `Display` is one line: `{name}: {detail}`, the detail
/// naming the field and its byte offset.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{name}: {detail}")]
pub struct SceneBinaryError {
    /// The object or file the bytes came from.
    pub name: String,
    /// What is wrong, and where.
    pub detail: String,
}

/// Encodes `scene` in the binary scene format (see the module documentation).
pub fn encode_scene(scene: &Scene) -> Vec<u8> {
    encode_as(scene, &scene.source.to_string_lossy(), &scene.warnings)
}

/// [`encode_scene`] of `scene` with `source` and `warnings` in place of its own, written
/// straight into the output after room for the header (no copy of the scene or of the body).
fn encode_as(scene: &Scene, source: &str, warnings: &[String]) -> Vec<u8> {
    let mesh = &scene.mesh;
    let mut out = Vec::with_capacity(
        SCENE_BINARY_HEADER_LEN
            + 256
            + mesh.triangles.len() * 28
            + (mesh.positions.len() + mesh.normals.len()) * 12,
    );
    out.resize(SCENE_BINARY_HEADER_LEN, 0);
    put_dvec3(&mut out, scene.origin);
    put_str(&mut out, source);
    put_u64(&mut out, mesh.triangles.len() as u64);
    for t in mesh.triangles.iter().chain(&mesh.triangle_normals) {
        t.iter().for_each(|&i| put_u32(&mut out, i));
    }
    mesh.triangle_materials
        .iter()
        .for_each(|&m| put_u32(&mut out, m));
    for vectors in [&mesh.positions, &mesh.normals] {
        put_u64(&mut out, vectors.len() as u64);
        for v in vectors.iter() {
            v.to_array().iter().for_each(|&c| put_f32(&mut out, c));
        }
    }
    put_u32(&mut out, mesh.materials.len() as u32);
    for m in &mesh.materials {
        put_str(&mut out, &m.name);
        put_rgb(&mut out, m.kd);
    }
    let camera = &scene.camera;
    [camera.eye, camera.look_at, camera.up]
        .into_iter()
        .for_each(|v| put_dvec3(&mut out, v));
    out.extend_from_slice(&camera.vfov_degrees.to_le_bytes());
    match scene.framed_bounds {
        None => out.push(0),
        Some((lo, hi)) => {
            out.push(1);
            put_dvec3(&mut out, lo);
            put_dvec3(&mut out, hi);
        }
    }
    put_u32(&mut out, scene.lights.len() as u32);
    for light in &scene.lights {
        let (kind, v, rgb) = match *light {
            Light::Point {
                position,
                intensity,
            } => (0, position, intensity),
            Light::Directional {
                direction,
                irradiance,
            } => (1, direction, irradiance),
        };
        out.push(kind);
        put_dvec3(&mut out, v);
        put_rgb(&mut out, rgb);
    }
    put_rgb(&mut out, scene.ambient);
    put_rgb(&mut out, scene.background);
    let image = scene.image;
    for setting in [image.width, image.height, image.spp] {
        match setting {
            None => out.push(0),
            Some(v) => {
                out.push(1);
                put_u32(&mut out, v);
            }
        }
    }
    put_u32(&mut out, warnings.len() as u32);
    warnings.iter().for_each(|w| put_str(&mut out, w));
    textures::put_textures(&mut out, mesh);
    if let Some(animation) = &scene.animation {
        put_str(
            &mut out,
            &serde_json::to_string(animation).expect("an animation encodes"),
        );
    }

    let body_len = (out.len() - SCENE_BINARY_HEADER_LEN) as u64;
    out[..8].copy_from_slice(&SCENE_BINARY_MAGIC);
    out[8..10].copy_from_slice(&SCENE_BINARY_VERSION.to_le_bytes());
    out[10..12].copy_from_slice(&0u16.to_le_bytes());
    out[12..20].copy_from_slice(&body_len.to_le_bytes());
    let (head, body) = out.split_at(SCENE_BINARY_HEADER_LEN);
    let crc = checksum(&head[..CRC_AT], body);
    out[CRC_AT..SCENE_BINARY_HEADER_LEN].copy_from_slice(&crc.to_le_bytes());
    out
}

/// The binary scene a client stores for `scene`, loaded from a main file named `main_name`:
/// [`encode_scene`] of the scene with `source` set to `main_name` (the name the job request
/// gives it) and without its warnings (the client showed them). So its bytes depend on the
/// scene files' contents and the main file's name only, not on the folder it was loaded from.
pub fn encode_scene_named(scene: &Scene, main_name: &str) -> Vec<u8> {
    encode_as(scene, main_name, &[])
}

/// Decodes a binary scene read from `name` (an object key or file path, for messages). See the
/// module documentation for what is checked.
pub fn decode_scene(name: &str, bytes: &[u8]) -> Result<Scene, SceneBinaryError> {
    decode(bytes).map_err(|detail| SceneBinaryError {
        name: name.to_owned(),
        detail,
    })
}

fn decode(bytes: &[u8]) -> Result<Scene, String> {
    let Some((head, body)) = bytes.split_first_chunk::<SCENE_BINARY_HEADER_LEN>() else {
        return Err(format!(
            "{} bytes, shorter than the {SCENE_BINARY_HEADER_LEN}-byte header of a binary scene",
            bytes.len()
        ));
    };
    if head[..8] != SCENE_BINARY_MAGIC {
        return Err(format!(
            "not a binary scene: bytes 0..8 are \"{}\", expected \"{}\"",
            head[..8].escape_ascii(),
            SCENE_BINARY_MAGIC.escape_ascii()
        ));
    }
    let version = u16::from_le_bytes([head[8], head[9]]);
    if version != SCENE_BINARY_VERSION {
        return Err(format!(
            "format version {version} at byte 8 is not supported: this build reads version \
             {SCENE_BINARY_VERSION} only"
        ));
    }
    let reserved = u16::from_le_bytes([head[10], head[11]]);
    if reserved != 0 {
        return Err(format!(
            "reserved field at byte 10 is {reserved}, expected 0"
        ));
    }
    let declared = u64::from_le_bytes(head[12..20].try_into().unwrap_or_default());
    if declared != body.len() as u64 {
        return Err(format!(
            "body length at byte 12 declares {declared} bytes, but {} follow the header",
            body.len()
        ));
    }
    let stored = u32::from_le_bytes(head[CRC_AT..].try_into().unwrap_or_default());
    let computed = checksum(&head[..CRC_AT], body);
    if stored != computed {
        return Err(format!(
            "checksum at byte {CRC_AT} is {stored:#010x}, but the bytes give {computed:#010x}: \
             the object is corrupt"
        ));
    }
    let mut r = Reader {
        bytes,
        at: SCENE_BINARY_HEADER_LEN,
    };
    let origin = r.dvec3("origin")?;
    let source = PathBuf::from(r.string("source")?);
    let count_at = r.at;
    let n = r.count64("triangle count", 28)?;
    if n == 0 {
        return Err(format!(
            "byte {count_at}: triangle count is 0, but a scene has at least one triangle"
        ));
    }
    let triangles_at = r.at;
    let triangles = triples(r.take(n * 12, "triangles")?);
    let normals_at = r.at;
    let triangle_normals = triples(r.take(n * 12, "triangle_normals")?);
    let materials_at = r.at;
    let triangle_materials: Vec<u32> = r
        .take(n * 4, "triangle_materials")?
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let positions = r.vectors("positions")?;
    let normals = r.vectors("normals")?;
    let material_count = r.count32("materials", 16)?;
    let mut materials = Vec::with_capacity(material_count);
    for i in 0..material_count {
        let name = r.string(&format!("materials[{i}].name"))?;
        let kd = r.rgb(&format!("materials[{i}].kd"))?;
        materials.push(Material::plain(name, kd));
    }
    check_indices(
        &triangles,
        positions.len(),
        triangles_at,
        "triangles",
        "positions",
        None,
    )?;
    check_indices(
        &triangle_normals,
        normals.len(),
        normals_at,
        "triangle_normals",
        "normals",
        Some(NO_NORMAL),
    )?;
    if let Some(i) = triangle_materials
        .iter()
        .position(|&m| m as usize >= materials.len())
    {
        return Err(format!(
            "byte {}: triangle_materials[{i}] is {}, but there are {} materials",
            materials_at + 4 * i,
            triangle_materials[i],
            materials.len()
        ));
    }
    let camera = CameraSpec {
        eye: r.dvec3("camera.eye")?,
        look_at: r.dvec3("camera.look_at")?,
        up: r.dvec3("camera.up")?,
        vfov_degrees: r.f64("camera.vfov_degrees")?,
    };
    let framed_bounds = if r.flag("framed_bounds")? {
        Some((r.dvec3("framed_bounds.lo")?, r.dvec3("framed_bounds.hi")?))
    } else {
        None
    };
    let light_count = r.count32("lights", 37)?;
    let mut lights = Vec::with_capacity(light_count);
    for i in 0..light_count {
        let kind_at = r.at;
        let kind = r.take(1, &format!("lights[{i}].kind"))?[0];
        let light = match kind {
            0 => Light::Point {
                position: r.dvec3(&format!("lights[{i}].position"))?,
                intensity: r.rgb(&format!("lights[{i}].intensity"))?,
            },
            1 => Light::Directional {
                direction: r.dvec3(&format!("lights[{i}].direction"))?,
                irradiance: r.rgb(&format!("lights[{i}].irradiance"))?,
            },
            other => {
                return Err(format!(
                    "byte {kind_at}: lights[{i}].kind is {other}, expected 0 (point) or 1 \
                     (directional)"
                ));
            }
        };
        lights.push(light);
    }
    let ambient = r.rgb("ambient")?;
    let background = r.rgb("background")?;
    let image = ImageSettings {
        width: r.option_u32("width")?,
        height: r.option_u32("height")?,
        spp: r.option_u32("spp")?,
    };
    let warning_count = r.count32("warnings", 4)?;
    let warnings = (0..warning_count)
        .map(|i| r.string(&format!("warnings[{i}]")))
        .collect::<Result<Vec<_>, _>>()?;
    let mut mesh = Mesh {
        positions,
        normals,
        triangles,
        triangle_normals,
        triangle_materials,
        materials,
        ..Mesh::default()
    };
    textures::read_textures(&mut r, &mut mesh)?;
    let animation = if r.at == bytes.len() {
        None
    } else {
        let at = r.at;
        let text = r.string("animation")?;
        let animation: Animation = serde_json::from_str(&text)
            .map_err(|e| format!("byte {at}: animation is not an animation: {e}"))?;
        animation
            .validate()
            .map_err(|e| format!("byte {at}: {e}"))?;
        Some(animation)
    };
    if r.at != bytes.len() {
        return Err(format!(
            "byte {}: {} bytes follow the last field (animation)",
            r.at,
            bytes.len() - r.at
        ));
    }
    Ok(Scene {
        source,
        origin,
        mesh,
        camera,
        framed_bounds,
        lights,
        ambient,
        background,
        image,
        warnings,
        animation,
    })
}

/// Every index of `rows` (stored from byte `at`) below `len`, except `none` where allowed.
fn check_indices(
    rows: &[[u32; 3]],
    len: usize,
    at: usize,
    field: &str,
    target: &str,
    none: Option<u32>,
) -> Result<(), String> {
    let bad = rows
        .iter()
        .flatten()
        .position(|&i| i as usize >= len && Some(i) != none);
    match bad {
        None => Ok(()),
        Some(flat) => Err(format!(
            "byte {}: {field}[{}][{}] is {}, but there are {len} {target}",
            at + 4 * flat,
            flat / 3,
            flat % 3,
            rows[flat / 3][flat % 3]
        )),
    }
}

/// Consecutive `[u32; 3]` rows of little-endian bytes (a multiple of 12 long).
fn triples(bytes: &[u8]) -> Vec<[u32; 3]> {
    bytes
        .chunks_exact(12)
        .map(|c| {
            [
                u32::from_le_bytes([c[0], c[1], c[2], c[3]]),
                u32::from_le_bytes([c[4], c[5], c[6], c[7]]),
                u32::from_le_bytes([c[8], c[9], c[10], c[11]]),
            ]
        })
        .collect()
}

/// A cursor over the whole object; offsets in messages are from its first byte.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    /// The next `len` bytes of `field`.
    fn take(&mut self, len: u64, field: &str) -> Result<&'a [u8], String> {
        let left = (self.bytes.len() - self.at) as u64;
        if len > left {
            return Err(format!(
                "byte {}: {field} needs {len} bytes, but only {left} are left",
                self.at
            ));
        }
        let slice = &self.bytes[self.at..self.at + len as usize];
        self.at += len as usize;
        Ok(slice)
    }

    fn u32(&mut self, field: &str) -> Result<u32, String> {
        let b = self.take(4, field)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn u64(&mut self, field: &str) -> Result<u64, String> {
        let b = self.take(8, field)?;
        Ok(u64::from_le_bytes(b.try_into().unwrap_or_default()))
    }

    /// A u64 count of elements of at least `min_size` bytes each, checked against what is left.
    fn count64(&mut self, field: &str, min_size: u64) -> Result<u64, String> {
        let at = self.at;
        let n = self.u64(field)?;
        self.check_count(at, n, field, min_size)?;
        Ok(n)
    }

    /// A u32 count, checked like [`Reader::count64`].
    fn count32(&mut self, field: &str, min_size: u64) -> Result<usize, String> {
        let at = self.at;
        let n = self.u32(&format!("{field} count"))?;
        self.check_count(at, u64::from(n), &format!("{field} count"), min_size)?;
        Ok(n as usize)
    }

    fn check_count(&self, at: usize, n: u64, field: &str, min_size: u64) -> Result<(), String> {
        let left = (self.bytes.len() - self.at) as u64;
        if n.checked_mul(min_size).is_none_or(|need| need > left) {
            return Err(format!(
                "byte {at}: {field} is {n}, but only {left} bytes are left"
            ));
        }
        Ok(())
    }

    fn flag(&mut self, field: &str) -> Result<bool, String> {
        let at = self.at;
        match self.take(1, field)?[0] {
            0 => Ok(false),
            1 => Ok(true),
            other => Err(format!(
                "byte {at}: {field} flag is {other}, expected 0 or 1"
            )),
        }
    }

    fn option_u32(&mut self, field: &str) -> Result<Option<u32>, String> {
        if self.flag(field)? {
            Ok(Some(self.u32(field)?))
        } else {
            Ok(None)
        }
    }

    fn string(&mut self, field: &str) -> Result<String, String> {
        let at = self.at;
        let len = self.u32(&format!("{field} length"))?;
        let bytes = self.take(u64::from(len), field)?;
        String::from_utf8(bytes.to_vec())
            .map_err(|_| format!("byte {at}: {field} is not valid UTF-8"))
    }

    fn f64(&mut self, field: &str) -> Result<f64, String> {
        let at = self.at;
        let v = f64::from_le_bytes(self.take(8, field)?.try_into().unwrap_or_default());
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("byte {at}: {field} is {v}, not finite"))
        }
    }

    fn dvec3(&mut self, field: &str) -> Result<DVec3, String> {
        let at = self.at;
        let b = self.take(24, field)?;
        let c = |i: usize| f64::from_le_bytes(b[i * 8..i * 8 + 8].try_into().unwrap_or_default());
        let v = DVec3::new(c(0), c(1), c(2));
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("byte {at}: {field} is {v}, not finite"))
        }
    }

    fn rgb(&mut self, field: &str) -> Result<[f32; 3], String> {
        let at = self.at;
        let b = self.take(12, field)?;
        let c = |i: usize| f32::from_le_bytes([b[i * 4], b[i * 4 + 1], b[i * 4 + 2], b[i * 4 + 3]]);
        let v = [c(0), c(1), c(2)];
        if v.iter().all(|x| x.is_finite()) {
            Ok(v)
        } else {
            Err(format!("byte {at}: {field} is {v:?}, not finite"))
        }
    }

    /// A u64 count, then that many f32 triples, all finite.
    fn vectors(&mut self, field: &str) -> Result<Vec<Vec3>, String> {
        let n = self.count64(&format!("{field} count"), 12)?;
        let at = self.at;
        let v: Vec<Vec3> = self
            .take(n * 12, field)?
            .chunks_exact(12)
            .map(|c| {
                Vec3::new(
                    f32::from_le_bytes([c[0], c[1], c[2], c[3]]),
                    f32::from_le_bytes([c[4], c[5], c[6], c[7]]),
                    f32::from_le_bytes([c[8], c[9], c[10], c[11]]),
                )
            })
            .collect();
        if let Some(i) = v.iter().position(|p| !p.is_finite()) {
            return Err(format!(
                "byte {}: {field}[{i}] is {}, not finite",
                at + 12 * i,
                v[i]
            ));
        }
        Ok(v)
    }
}

fn checksum(header: &[u8], body: &[u8]) -> u32 {
    let mut hasher = crc32fast::Hasher::new();
    hasher.update(header);
    hasher.update(body);
    hasher.finalize()
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn put_u64(out: &mut Vec<u8>, v: u64) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn put_f32(out: &mut Vec<u8>, v: f32) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn put_rgb(out: &mut Vec<u8>, v: [f32; 3]) {
    v.iter().for_each(|&c| put_f32(out, c));
}

fn put_dvec3(out: &mut Vec<u8>, v: DVec3) {
    v.to_array()
        .iter()
        .for_each(|c| out.extend_from_slice(&c.to_le_bytes()));
}

fn put_str(out: &mut Vec<u8>, s: &str) {
    put_u32(out, s.len() as u32);
    out.extend_from_slice(s.as_bytes());
}
