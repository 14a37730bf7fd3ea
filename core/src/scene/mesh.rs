//! The triangle mesh every stage works on: flat arrays in scene order.

use crate::texture::{Texture, TexturedCorners};
use glam::Vec3;
use std::sync::Arc;

/// Marks a triangle corner without a vertex normal.
pub const NO_NORMAL: u32 = u32::MAX;
/// Marks a triangle without texture coordinates.
pub const NO_TEXCOORD: u32 = u32::MAX;

/// A Lambertian material.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// The MTL material name (or `default`).
    pub name: String,
    /// Diffuse reflectance per RGB channel, in [0, 1] for physical materials.
    pub kd: [f32; 3],
    /// Index into the mesh's `textures` of the diffuse map (`map_Kd`) that multiplies `kd`.
    pub texture: Option<u32>,
}

impl Material {
    /// An untextured material.
    pub fn plain(name: impl Into<String>, kd: [f32; 3]) -> Material {
        Material {
            name: name.into(),
            kd,
            texture: None,
        }
    }
}

/// One triangle's shading data, as a split object carries it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleShading {
    /// The corners' vertex normals, in corner order; `None` shades with the geometric normal.
    pub normals: Option<[Vec3; 3]>,
    /// Diffuse reflectance per RGB channel, from the triangle's material.
    pub kd: [f32; 3],
    /// The material's diffuse texture and the corners' texture coordinates, if textured.
    pub texture: Option<TexturedCorners>,
}

impl TriangleShading {
    /// Black, flat and untextured: what a table gives for a triangle it cannot find (never,
    /// for a table its own constructors made).
    pub const NONE: TriangleShading = TriangleShading {
        normals: None,
        kd: [0.0; 3],
        texture: None,
    };
}

/// Triangles in scene order with positions, optional vertex normals and a material each.
/// Guarantees (checked by the loaders): every index is in range, every coordinate is finite,
/// the per-triangle arrays have the same length (`triangle_texcoords` is either empty, when no
/// triangle is textured, or as long as the others), and a triangle has texture coordinates
/// only if its material has a texture.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Vertex positions, world units, all finite.
    pub positions: Vec<Vec3>,
    /// Vertex normals (`vn`), as given (not necessarily unit length).
    pub normals: Vec<Vec3>,
    /// Position indices of each triangle's corners.
    pub triangles: Vec<[u32; 3]>,
    /// Normal indices of each triangle's corners; all [`NO_NORMAL`] for flat shading.
    pub triangle_normals: Vec<[u32; 3]>,
    /// Index into `materials` of each triangle.
    pub triangle_materials: Vec<u32>,
    /// The materials the triangles name.
    pub materials: Vec<Material>,
    /// Texture coordinates (`vt`): u, v.
    pub texcoords: Vec<[f32; 2]>,
    /// Texture coordinate indices of each textured triangle's corners, [`NO_TEXCOORD`] for the
    /// others; empty when no triangle is textured.
    pub triangle_texcoords: Vec<[u32; 3]>,
    /// The distinct diffuse textures the materials name.
    pub textures: Vec<Arc<Texture>>,
}

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The corner positions of triangle `i`.
    pub fn corners(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[i];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// The texture and the corners' texture coordinates of triangle `i`, if it is textured.
    #[inline]
    pub fn texture_of(&self, i: usize) -> Option<(u32, [[f32; 2]; 3])> {
        let ids = *self.triangle_texcoords.get(i)?;
        if ids[0] == NO_TEXCOORD {
            return None;
        }
        let texture = self.materials[self.triangle_materials[i] as usize].texture?;
        // Spelled out: `array::map` is not always inlined.
        let uv = |k: usize| self.texcoords[ids[k] as usize];
        Some((texture, [uv(0), uv(1), uv(2)]))
    }

    /// Bytes the textures hold decoded.
    pub fn texture_bytes(&self) -> u64 {
        self.textures.iter().map(|t| t.memory_bytes()).sum()
    }

    /// Appends `other`, renumbering its indices; triangle order is `self` then `other`.
    pub fn append(&mut self, other: Mesh) {
        let pos_base = self.positions.len() as u32;
        self.append_with_position_base(other, pos_base);
    }

    /// [`Mesh::append`] with `other`'s position indices shifted by `pos_base` (for meshes whose
    /// positions are kept elsewhere while loading).
    pub(super) fn append_with_position_base(&mut self, other: Mesh, pos_base: u32) {
        let nrm_base = self.normals.len() as u32;
        let mat_base = self.materials.len() as u32;
        let tc_base = self.texcoords.len() as u32;
        let textured = !self.triangle_texcoords.is_empty() || !other.triangle_texcoords.is_empty();
        if textured {
            self.triangle_texcoords
                .resize(self.triangles.len(), [NO_TEXCOORD; 3]);
            let mut theirs = other.triangle_texcoords;
            theirs.resize(other.triangles.len(), [NO_TEXCOORD; 3]);
            self.triangle_texcoords.extend(
                theirs
                    .iter()
                    .map(|t| t.map(|i| if i == NO_TEXCOORD { i } else { i + tc_base })),
            );
        }
        self.texcoords.extend(other.texcoords);
        // Textures are shared by content: one the mesh already holds is not held twice.
        let texture_ids: Vec<u32> = other
            .textures
            .into_iter()
            .map(|t| self.texture_id(t))
            .collect();
        self.positions.extend(other.positions);
        self.normals.extend(other.normals);
        self.materials
            .extend(other.materials.into_iter().map(|mut m| {
                m.texture = m.texture.map(|t| texture_ids[t as usize]);
                m
            }));
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|i| i + pos_base)));
        self.triangle_normals.extend(
            other
                .triangle_normals
                .iter()
                .map(|t| t.map(|i| if i == NO_NORMAL { i } else { i + nrm_base })),
        );
        self.triangle_materials
            .extend(other.triangle_materials.iter().map(|m| m + mat_base));
    }

    /// The index of `texture` in `textures`, adding it unless one with the same content is
    /// there.
    pub fn texture_id(&mut self, texture: Arc<Texture>) -> u32 {
        if let Some(i) = self.textures.iter().position(|t| {
            t.width == texture.width && t.height == texture.height && t.texels == texture.texels
        }) {
            return i as u32;
        }
        self.textures.push(texture);
        (self.textures.len() - 1) as u32
    }
}
