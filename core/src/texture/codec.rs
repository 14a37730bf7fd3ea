//! A texture as a stored object: a compressed block of kind
//! [`RecordKind::Texture`](crate::shuffle::RecordKind::Texture) whose raw bytes are the width
//! and height (u32 little-endian), the name (u32 byte length, UTF-8), then the texels.
//! Decoding checks every length, so a damaged or foreign object is an error naming its key.

use super::Texture;
use crate::shuffle::{RecordKind, decode_block, encode_block};

/// Encodes `texture` as a compressed block (deterministic).
pub fn encode_texture(texture: &Texture) -> Vec<u8> {
    let name = texture.name.as_bytes();
    let mut raw = Vec::with_capacity(12 + name.len() + texture.texels.len());
    raw.extend_from_slice(&texture.width.to_le_bytes());
    raw.extend_from_slice(&texture.height.to_le_bytes());
    raw.extend_from_slice(&(name.len() as u32).to_le_bytes());
    raw.extend_from_slice(name);
    raw.extend_from_slice(&texture.texels);
    encode_block(
        RecordKind::Texture,
        u64::from(texture.width) * u64::from(texture.height),
        &raw,
    )
}

/// Decodes a texture object stored at `key`; the error names the key and what is wrong.
pub fn decode_texture(key: &str, bytes: &[u8]) -> Result<Texture, String> {
    let block = decode_block(key, bytes, RecordKind::Texture).map_err(|e| e.to_string())?;
    let raw = block.raw;
    let bad = |what: &str| format!("texture object {key}: {what}");
    let word = |at: usize| -> Result<u32, String> {
        raw.get(at..at + 4)
            .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
            .ok_or_else(|| bad("shorter than its header"))
    };
    let (width, height, name_len) = (word(0)?, word(4)?, word(8)? as usize);
    let name_end = 12usize
        .checked_add(name_len)
        .filter(|&end| end <= raw.len())
        .ok_or_else(|| bad("its name runs past the end"))?;
    let name = std::str::from_utf8(&raw[12..name_end])
        .map_err(|_| bad("its name is not UTF-8"))?
        .to_string();
    let texels = raw[name_end..].to_vec();
    // u128: three times two u32 sides can exceed u64 (a hostile header).
    let expected = 3 * u128::from(width) * u128::from(height);
    if width == 0 || height == 0 || texels.len() as u128 != expected {
        return Err(bad(&format!(
            "{width}x{height} texels need {expected} bytes, it holds {}",
            texels.len()
        )));
    }
    Ok(Texture::new(name, width, height, texels))
}
