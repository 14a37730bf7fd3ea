//! The split object: one scene split as one stored blob, loadable without building anything.
//!
//! It is a shuffle block of kind `SplitObject` (zstd, checksums; see [`crate::shuffle`]) whose
//! raw bytes are the BVH's traversal form (its boxes left out), then the ids and the shading, in
//! these sections (version [`SPLIT_FORMAT_VERSION`]; little-endian, floats as IEEE bits):
//!
//! | section | bytes | values |
//! |---|---|---|
//! | header | 60 | u32: format version, split id, triangle count n, 4-wide node count w, triangle pack count p, distinct vertex count v, triangles with normals c, distinct kd count k, textured triangles x; f32: root box lo.xyz, hi.xyz |
//! | nodes | 32 w | the 4-wide nodes' structure, root first ([`NODE_BYTES`]: 4 child words, 4 pack counts); their boxes are derived from the triangles on loading, as the builder derives them |
//! | pack lanes | p | u8: triangles in each `Triangle4` pack (1 to 4), in pack order |
//! | vertices | 12 v | planes of 3 f32 (x, y, z) per distinct corner position, in order of first use |
//! | corners | 12 n | planes of 3 u32 per triangle: the indices of its corners' vertices, BVH leaf order |
//! | ids | 4 n | planes of u32: global triangle id (scene order), leaf order |
//! | kd values | 12 k | 3 f32 per distinct kd, in order of first use |
//! | kd indices | 4 n | planes of u32: index of each triangle's kd value, leaf order |
//! | shading flags | n | u8: bit 0 set if the triangle has vertex normals, bit 1 if it is textured; no other bit |
//! | normals | 36 c | 9 f32 per triangle with normals (corner 0 xyz, 1, 2), leaf order |
//! | textures | 28 x | per textured triangle, leaf order: u32 texture (an index into the plan's textures), 6 f32 texture coordinates (corner 0 uv, 1, 2) |
//!
//! A section of "planes" holds its words in groups of 12,288 ([`PLANE_GROUP`]; the last group
//! shorter), each group as its words' byte 0s, then their byte 1s, 2s and 3s (as the shuffle
//! columns' byte planes). "Distinct" compares bit patterns, so every value (signed zeros, NaN
//! payloads) round-trips exactly; "in order of first use" means each index is at most the
//! number of values used before it, and every value is used.
//!
//! Why this layout (measured, docs/ARCHITECTURE.md section 8): loading is one pass over the
//! raw bytes as zstd produces them, 256 KiB at a time into one reused buffer that stays in the
//! cache, each section converted straight into its final array (the nodes' structure word for
//! word, the packs filled triangle by triangle, gathering each corner from the vertices, which
//! are numbered in order of first use and so read almost in order, the shading kept as it is
//! stored, a kd table with one index per triangle and the flagged triangles' normals, in a
//! [`ShadingTable`]) and checked as it passes, then one pass over the nodes setting their
//! boxes from the packs' boxes (each taken as its pack is filled); nothing is collapsed or
//! searched, and no buffer holds the raw bytes whole. The final arrays are asked to be backed
//! by huge pages (`hort_huge_pages`), so filling them costs a page fault per 2 MiB, not per
//! 4 KiB. The node boxes are not stored (version 5) because they are derived exactly, in less
//! time than zstd took to undo them: they were three quarters of the node bytes, 15 of the 47 raw MB and about half the stored bytes of a
//! million-triangle split, mostly incompressible float bits. Planes come in groups so that a
//! group (48 KiB) is unshuffled as it arrives. The corners refer to distinct vertices rather
//! than being written out: written out they compress about as small (zstd finds the repeated
//! vertices itself) but are twice the raw bytes, made of short matches that took zstd several
//! times as long to undo as the vertices and indices. Byte planes make the vertices, indices
//! and ids a quarter to a half smaller stored and faster to decompress (high bytes repeat).
//! kd values repeat per material, so kd indices are a small table's; normals and texture
//! coordinates are stored written out, as few scenes have them. The textures themselves are
//! objects of their own (one per distinct texture per job, [`crate::texture`]), attached to a
//! decoded split by the task that loads it ([`SplitObject::textures`]).
//!
//! Decoding checks everything it relies on: the version (objects of other versions name their
//! version and are refused; a task rebuilds such an object from the scene as it does a
//! damaged one), the header's counts against each other and the exact raw length, the BVH as
//! [`Bvh::from_parts`] does (children in depth-first order after their parent, depth, leaves
//! inside the packs and covering them, pack sizes), vertex and kd indices numbering their
//! tables in order of first use, shading flags of bits 0 and 1 only with as many of each set
//! as declared; and, as
//! `decode_block` does, every raw byte against the block's raw CRC and length before it
//! returns anything (a damaged block gives the block's error, whatever its bytes say). It
//! does not check that table values are distinct (a duplicate only costs bytes; re-encoding
//! merges it), so `encode_split` of a decoded object gives back the bytes it came from
//! whenever they were written by `encode_split`, and otherwise bytes that decode to an equal
//! object.

use crate::bvh::{Aabb, Bvh, NODE_BYTES};
use crate::shuffle::{RecordKind, encode_block};
use crate::texture::Texture;
use std::collections::BTreeMap;
use std::sync::Arc;

mod decode;
mod distinct;
mod shading;
pub use decode::decode_split;
use distinct::Distinct;
pub use shading::{ShadingTable, TriangleShading};

/// Version of the layout above; bump on any change.
pub const SPLIT_FORMAT_VERSION: u32 = 6;

/// Bytes of the header section: 9 u32 and 6 f32.
const HEADER_BYTES: usize = 60;

/// A decoded split: its BVH (triangles in leaf order) and the shading data in the same order.
#[derive(Clone, Debug, PartialEq)]
pub struct SplitObject {
    /// The split's id, `0..k`.
    pub split: u32,
    /// BVH over the split's triangles, carrying their scene-wide ids.
    pub bvh: Bvh,
    /// `shading.get(i)` belongs to the BVH's i-th triangle in leaf order.
    pub shading: ShadingTable,
    /// The textures the triangles use, by index: not part of the stored bytes (textures are
    /// objects of their own), attached by whoever loads the split ([`SplitObject::attach`]).
    pub textures: BTreeMap<u32, Arc<Texture>>,
}

impl SplitObject {
    /// Bytes the decoded object holds in memory, its attached textures included.
    pub fn memory_bytes(&self) -> u64 {
        self.bvh.memory_bytes()
            + self.shading.memory_bytes()
            + self
                .textures
                .values()
                .map(|t| t.memory_bytes())
                .sum::<u64>()
    }

    /// Attaches the textures the triangles use, taking texture `i` from `texture(i)`; the
    /// first error `texture` gives is returned.
    pub fn attach<E>(
        &mut self,
        mut texture: impl FnMut(u32) -> Result<Arc<Texture>, E>,
    ) -> Result<(), E> {
        for id in self.shading.texture_ids() {
            if let std::collections::btree_map::Entry::Vacant(slot) = self.textures.entry(id) {
                slot.insert(texture(id)?);
            }
        }
        Ok(())
    }

    /// The attached texture of index `texture` (an index into the plan's textures).
    ///
    /// # Panics
    /// If the texture was not attached (a loader's bug: every path that loads a split
    /// attaches its textures before rendering).
    #[inline]
    pub fn attached_texture(&self, texture: u32) -> &Texture {
        self.textures.get(&texture).unwrap_or_else(|| {
            panic!(
                "split {}: texture {texture} is used but was not attached",
                self.split
            )
        })
    }
}

/// The header's counts: triangles, 4-wide nodes, packs, distinct vertices, triangles with
/// normals, distinct kd, textured triangles.
#[derive(Clone, Copy)]
struct Counts {
    n: u32,
    w: u32,
    p: u32,
    v: u32,
    c: u32,
    k: u32,
    x: u32,
}

/// Bytes of one textured triangle's entry: the texture index and 6 f32.
const TEXTURED_BYTES: u64 = 28;

impl Counts {
    /// The sections' lengths in bytes after the header, in order.
    fn section_lengths(self) -> [u64; 10] {
        let Counts {
            n,
            w,
            p,
            v,
            c,
            k,
            x,
        } = self;
        let [n, w, p, v, c, k, x] = [n, w, p, v, c, k, x].map(u64::from);
        [
            w * NODE_BYTES as u64,
            p,
            12 * v,
            12 * n,
            4 * n,
            12 * k,
            4 * n,
            n,
            36 * c,
            TEXTURED_BYTES * x,
        ]
    }
}

/// Words per group of a planes section: a multiple of 3, so that a group holds whole vertices
/// and whole triangles' corners, and small enough (48 KiB) to be unshuffled from the cache.
const PLANE_GROUP: usize = 3 * 4096;

/// Appends `words` as byte planes, [`PLANE_GROUP`] words at a time: each group's byte 0s, then
/// its byte 1s, 2s and 3s.
fn put_planes(out: &mut Vec<u8>, words: &[u32]) {
    out.reserve(4 * words.len());
    for group in words.chunks(PLANE_GROUP) {
        for plane in 0..4 {
            out.extend(group.iter().map(|w| w.to_le_bytes()[plane]));
        }
    }
}

/// Encodes a split object as a compressed block (deterministic: the same object gives the same
/// bytes). `object.shading` holds one entry per triangle.
pub fn encode_split(object: &SplitObject) -> Vec<u8> {
    let bvh = &object.bvh;
    let n = bvh.triangle_count();
    let mut vertices = Distinct::with_capacity(3 * n);
    for t in bvh.leaf_triangles() {
        for corner in t {
            vertices.push(corner.to_array());
        }
    }
    let mut kd = Distinct::with_capacity(n);
    for s in object.shading.iter() {
        kd.push(s.kd);
    }
    let counts = Counts {
        n: n as u32,
        w: bvh.wide_node_count() as u32,
        p: bvh.pack_count() as u32,
        v: vertices.values.len() as u32,
        c: object
            .shading
            .iter()
            .filter(|s| s.normals.is_some())
            .count() as u32,
        k: kd.values.len() as u32,
        x: object
            .shading
            .iter()
            .filter(|s| s.texture.is_some())
            .count() as u32,
    };
    let total: u64 = counts.section_lengths().iter().sum();
    let mut raw = Vec::with_capacity(HEADER_BYTES + total as usize);
    let Counts {
        n,
        w,
        p,
        v,
        c,
        k,
        x,
    } = counts;
    for word in [SPLIT_FORMAT_VERSION, object.split, n, w, p, v, c, k, x] {
        raw.extend_from_slice(&word.to_le_bytes());
    }
    let Aabb { lo, hi } = bvh.bounds();
    for x in lo.to_array().into_iter().chain(hi.to_array()) {
        raw.extend_from_slice(&x.to_le_bytes());
    }
    bvh.put_nodes(&mut raw);
    bvh.put_lanes(&mut raw);
    let vertex_bits: Vec<u32> = vertices
        .values
        .iter()
        .flatten()
        .map(|x| x.to_bits())
        .collect();
    put_planes(&mut raw, &vertex_bits);
    put_planes(&mut raw, &vertices.uses);
    put_planes(&mut raw, bvh.ids());
    for x in kd.values.iter().flatten() {
        raw.extend_from_slice(&x.to_le_bytes());
    }
    put_planes(&mut raw, &kd.uses);
    raw.extend(
        object
            .shading
            .iter()
            .map(|s| u8::from(s.normals.is_some()) | u8::from(s.texture.is_some()) << 1),
    );
    for normals in object.shading.iter().filter_map(|s| s.normals) {
        for x in normals.iter().flat_map(|v| v.to_array()) {
            raw.extend_from_slice(&x.to_le_bytes());
        }
    }
    for t in object.shading.iter().filter_map(|s| s.texture) {
        raw.extend_from_slice(&t.texture.to_le_bytes());
        for x in t.uv.iter().flatten() {
            raw.extend_from_slice(&x.to_le_bytes());
        }
    }
    encode_block(RecordKind::SplitObject, u64::from(n), &raw)
}

#[cfg(test)]
mod tests;
