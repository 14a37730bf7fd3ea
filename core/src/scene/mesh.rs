//! The triangle mesh every stage works on: flat arrays in scene order.

use glam::Vec3;

/// Marks a triangle corner without a vertex normal.
pub const NO_NORMAL: u32 = u32::MAX;

/// A Lambertian material.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// The MTL material name (or `default`).
    pub name: String,
    /// Diffuse reflectance per RGB channel, in [0, 1] for physical materials.
    pub kd: [f32; 3],
}

/// Triangles in scene order with positions, optional vertex normals and a material each.
/// Guarantees (checked by the loaders): every index is in range, every coordinate is finite,
/// and the three per-triangle arrays have the same length.
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
        self.positions.extend(other.positions);
        self.normals.extend(other.normals);
        self.materials.extend(other.materials);
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
}
