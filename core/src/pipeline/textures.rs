//! A job's textures: stored once each by the plan step under their content key, listed in the
//! plan (a split refers to them by their index there, the scene's texture index), read by the
//! tasks that shade (Render, CastMap) through the warm container's cache, and counted in every
//! task's memory.

use super::PipelineError;
use super::mode::RUNTIME_BYTES;
use crate::ids::JobId;
use crate::keys::texture_key;
use crate::texture::{Texture, decode_texture, encode_texture};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// A texture as the plan lists it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PlannedTexture {
    /// The content key ([`Texture::content_key`]): the object is `jobs/{job}/textures/{key}.tex`.
    pub key: String,
    /// The file it came from, as the material library names it.
    pub name: String,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
}

impl PlannedTexture {
    /// The plan's entry for `texture`.
    pub fn of(texture: &Texture) -> PlannedTexture {
        PlannedTexture {
            key: texture.content_key(),
            name: texture.name.clone(),
            width: texture.width,
            height: texture.height,
        }
    }
}

/// The objects the plan step stores for `textures`, listed in the plan as `planned` (same
/// order): (key, bytes), one per texture (the mesh holds each content once). The keys are the
/// plan's, so no texture is hashed again.
pub fn texture_objects(
    job: &JobId,
    textures: &[Arc<Texture>],
    planned: &[PlannedTexture],
) -> Vec<(String, Vec<u8>)> {
    textures
        .iter()
        .zip(planned)
        .map(|(t, p)| (texture_key(job, &p.key), encode_texture(t)))
        .collect()
}

/// Reads and checks texture `id` of `plan`'s list from its object `bytes` (read from `key`):
/// its content must be what the plan lists.
pub fn decode_planned_texture(
    key: &str,
    bytes: &[u8],
    planned: &PlannedTexture,
) -> Result<Texture, PipelineError> {
    let texture = decode_texture(key, bytes).map_err(PipelineError::Corrupt)?;
    if texture.content_key() != planned.key {
        return Err(PipelineError::Corrupt(format!(
            "texture object {key}: its texels do not match its content key (the object is \
             damaged or was replaced)"
        )));
    }
    Ok(texture)
}

/// Refuses textures that leave a task no room within `memory_mb`: every task that shades holds
/// all of them, beside the runtime. The error names the largest texture and its size. Returns
/// the bytes they hold.
pub fn check_texture_memory(
    textures: &[Arc<Texture>],
    memory_mb: u32,
) -> Result<u64, PipelineError> {
    let bytes: u64 = textures.iter().map(|t| t.memory_bytes()).sum();
    let budget = u64::from(memory_mb) << 20;
    if RUNTIME_BYTES.saturating_add(bytes) <= budget {
        return Ok(bytes);
    }
    let largest = textures
        .iter()
        .max_by_key(|t| t.memory_bytes())
        .expect("textures over budget are not none");
    let mb = |b: u64| b.div_ceil(1 << 20);
    let all = if textures.len() == 1 {
        String::new()
    } else {
        format!(
            " (the scene's {} textures hold {} MB)",
            textures.len(),
            mb(bytes)
        )
    };
    Err(PipelineError::BadInput(format!(
        "texture {} ({}x{} texels, {} MB decoded) does not fit --memory-mb {memory_mb} beside \
         the {} MB every task needs{all}: raise --memory-mb or use a smaller texture",
        largest.name,
        largest.width,
        largest.height,
        mb(largest.memory_bytes()),
        mb(RUNTIME_BYTES)
    )))
}
