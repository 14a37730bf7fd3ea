//! The binary scene's last section (version 2): texture coordinates and diffuse textures.
//!
//! In order: `texcoords` (u64 count, 2 f32 each); `triangle_texcoords` (u64 count, 0 or the
//! triangle count, 3 u32 each, [`NO_TEXCOORD`] for an untextured triangle); each material's
//! texture (u8 0 or 1, then a u32 index into the textures if 1); `textures` (u32 count, each a
//! name string, width and height u32, then 3 bytes per texel).

use super::{Reader, check_indices, put_str, put_u32, put_u64, triples};
use crate::scene::mesh::{Mesh, NO_TEXCOORD};
use crate::texture::{MAX_TEXTURE_SIDE, Texture};
use std::sync::Arc;

/// Appends the section for `mesh`.
pub(super) fn put_textures(out: &mut Vec<u8>, mesh: &Mesh) {
    put_u64(out, mesh.texcoords.len() as u64);
    for uv in &mesh.texcoords {
        uv.iter()
            .for_each(|c| out.extend_from_slice(&c.to_le_bytes()));
    }
    put_u64(out, mesh.triangle_texcoords.len() as u64);
    for t in &mesh.triangle_texcoords {
        t.iter().for_each(|&i| put_u32(out, i));
    }
    for m in &mesh.materials {
        match m.texture {
            None => out.push(0),
            Some(t) => {
                out.push(1);
                put_u32(out, t);
            }
        }
    }
    put_u32(out, mesh.textures.len() as u32);
    for t in &mesh.textures {
        put_str(out, &t.name);
        put_u32(out, t.width);
        put_u32(out, t.height);
        out.extend_from_slice(&t.texels);
    }
}

/// Reads the section into `mesh` (whose other arrays are read and checked), checking every
/// index, count and size.
pub(super) fn read_textures(r: &mut Reader<'_>, mesh: &mut Mesh) -> Result<(), String> {
    let n = r.count64("texcoords count", 8)?;
    let at = r.at;
    mesh.texcoords = r
        .take(n * 8, "texcoords")?
        .chunks_exact(8)
        .map(|c| {
            [
                f32::from_le_bytes([c[0], c[1], c[2], c[3]]),
                f32::from_le_bytes([c[4], c[5], c[6], c[7]]),
            ]
        })
        .collect();
    if let Some(i) = mesh
        .texcoords
        .iter()
        .position(|uv| !uv.iter().all(|c| c.is_finite()))
    {
        return Err(format!(
            "byte {}: texcoords[{i}] is {:?}, not finite",
            at + 8 * i,
            mesh.texcoords[i]
        ));
    }
    let count_at = r.at;
    let rows = r.count64("triangle_texcoords count", 12)?;
    let triangles = mesh.triangles.len() as u64;
    if rows != 0 && rows != triangles {
        return Err(format!(
            "byte {count_at}: triangle_texcoords count is {rows}, expected 0 or the triangle \
             count {triangles}"
        ));
    }
    let rows_at = r.at;
    mesh.triangle_texcoords = triples(r.take(rows * 12, "triangle_texcoords")?);
    check_indices(
        &mesh.triangle_texcoords,
        mesh.texcoords.len(),
        rows_at,
        "triangle_texcoords",
        "texcoords",
        Some(NO_TEXCOORD),
    )?;
    let mut material_textures = Vec::with_capacity(mesh.materials.len());
    for i in 0..mesh.materials.len() {
        let at = r.at;
        material_textures.push((at, r.option_u32(&format!("materials[{i}].texture"))?));
    }
    let texture_count = r.count32("textures", 12)?;
    for i in 0..texture_count {
        let name = r.string(&format!("textures[{i}].name"))?;
        let size_at = r.at;
        let width = r.u32(&format!("textures[{i}].width"))?;
        let height = r.u32(&format!("textures[{i}].height"))?;
        let sides = 1..=MAX_TEXTURE_SIDE;
        if !sides.contains(&width) || !sides.contains(&height) {
            return Err(format!(
                "byte {size_at}: textures[{i}] is {width}x{height} texels, expected 1 to \
                 {MAX_TEXTURE_SIDE} each way"
            ));
        }
        let texels = r
            .take(
                3 * u64::from(width) * u64::from(height),
                &format!("textures[{i}].texels"),
            )?
            .to_vec();
        mesh.textures
            .push(Arc::new(Texture::new(name, width, height, texels)));
    }
    for (material, (at, texture)) in mesh.materials.iter_mut().zip(material_textures) {
        if let Some(t) = texture.filter(|&t| t as usize >= texture_count) {
            return Err(format!(
                "byte {at}: {:?}'s texture is {t}, but there are {texture_count} textures",
                material.name
            ));
        }
        material.texture = texture;
    }
    let untextured = mesh
        .triangle_texcoords
        .iter()
        .enumerate()
        .position(|(i, t)| {
            t[0] != NO_TEXCOORD
                && mesh.materials[mesh.triangle_materials[i] as usize]
                    .texture
                    .is_none()
        });
    if let Some(i) = untextured {
        return Err(format!(
            "byte {}: triangle_texcoords[{i}] gives texture coordinates to a triangle whose \
             material has no texture",
            rows_at + 12 * i
        ));
    }
    Ok(())
}
