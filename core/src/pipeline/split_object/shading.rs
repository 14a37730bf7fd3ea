//! A split's shading data in the form it is stored in: a table of distinct reflectances with
//! one index per triangle, and vertex normals only for the triangles that have them.
//!
//! Written out per triangle (an optional 36-byte normal triple and a 12-byte reflectance, 52
//! bytes with padding) the shading was 40% of a decoded split object's memory: 52 MB of a
//! million-triangle split whose triangles share a handful of materials and carry no normals.
//! Held as the split object stores it, it takes 4 bytes a triangle, plus 4 more and the
//! normals when some triangle has them, so loading a split writes and faults in that much
//! less memory, and a task holds more triangles within its budget.

use glam::Vec3;

use super::distinct::Distinct;
use crate::texture::TexturedCorners;

pub use crate::scene::TriangleShading;

/// No entry for this triangle, in [`ShadingTable::normal_slots`] and `texture_slots`.
const NO_SLOT: u32 = u32::MAX;

/// The shading of a split's triangles, in leaf order: `get(i)` belongs to the BVH's i-th
/// triangle. Equality compares what `get` gives for every triangle, whatever the tables'
/// layout (a decoded table may hold a reflectance twice where a built one holds it once).
#[derive(Clone, Debug, Default)]
pub struct ShadingTable {
    /// Distinct reflectances (built tables: in order of first use).
    kd_values: Vec<[f32; 3]>,
    /// Each triangle's index into `kd_values`.
    kd_index: Vec<u32>,
    /// Each triangle's index into `normals`, or [`NO_SLOT`]; empty when no triangle has
    /// normals.
    normal_slots: Vec<u32>,
    /// The normals of the triangles that have them, in triangle order.
    normals: Vec<[Vec3; 3]>,
    /// Each triangle's index into `textured`, or [`NO_SLOT`]; empty when no triangle is
    /// textured.
    texture_slots: Vec<u32>,
    /// The texture data of the textured triangles, in triangle order.
    textured: Vec<TexturedCorners>,
}

impl ShadingTable {
    /// A table from its parts, as the split object decoder reads them: `kd_index` numbers
    /// `kd_values`, and `normal_slots` (empty, or one per triangle) numbers `normals` or holds
    /// `u32::MAX` for a triangle without normals. The decoder has checked every index.
    pub(super) fn from_parts(
        kd_values: Vec<[f32; 3]>,
        kd_index: Vec<u32>,
        normal_slots: Vec<u32>,
        normals: Vec<[Vec3; 3]>,
        texture_slots: Vec<u32>,
        textured: Vec<TexturedCorners>,
    ) -> Self {
        debug_assert!(kd_index.iter().all(|&i| (i as usize) < kd_values.len()));
        debug_assert!(normal_slots.is_empty() || normal_slots.len() == kd_index.len());
        debug_assert!(texture_slots.is_empty() || texture_slots.len() == kd_index.len());
        ShadingTable {
            kd_values,
            kd_index,
            normal_slots,
            normals,
            texture_slots,
            textured,
        }
    }

    /// The marker [`ShadingTable::from_parts`] takes for a triangle without normals (or
    /// without a texture).
    pub(super) const NO_SLOT: u32 = NO_SLOT;

    /// Triangles in the table.
    pub fn len(&self) -> usize {
        self.kd_index.len()
    }

    /// Whether the table holds no triangle.
    pub fn is_empty(&self) -> bool {
        self.kd_index.is_empty()
    }

    /// The shading of leaf-order triangle `i`, or `None` past the end.
    #[inline]
    pub fn get(&self, i: usize) -> Option<TriangleShading> {
        let kd = *self.kd_values.get(*self.kd_index.get(i)? as usize)?;
        let normals = match self.normal_slots.get(i) {
            Some(&slot) if slot != NO_SLOT => self.normals.get(slot as usize).copied(),
            _ => None,
        };
        let texture = match self.texture_slots.get(i) {
            Some(&slot) if slot != NO_SLOT => self.textured.get(slot as usize).copied(),
            _ => None,
        };
        Some(TriangleShading {
            normals,
            kd,
            texture,
        })
    }

    /// The reflectance of leaf-order triangle `i` when it has no vertex normals and no
    /// texture (what [`ShadingTable::get`] gives as its `kd` then); else, or past the end,
    /// `None`.
    #[inline]
    pub fn flat_kd(&self, i: usize) -> Option<[f32; 3]> {
        let has = |slots: &[u32]| slots.get(i).is_some_and(|&slot| slot != NO_SLOT);
        if has(&self.normal_slots) || has(&self.texture_slots) {
            return None;
        }
        self.kd_values.get(*self.kd_index.get(i)? as usize).copied()
    }

    /// The distinct textures the triangles use, ascending.
    pub fn texture_ids(&self) -> Vec<u32> {
        let mut ids: Vec<u32> = self.textured.iter().map(|t| t.texture).collect();
        ids.sort_unstable();
        ids.dedup();
        ids
    }

    /// Every triangle's shading, in leaf order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = TriangleShading> + '_ {
        (0..self.len()).map(|i| self.get(i).unwrap_or(TriangleShading::NONE))
    }

    /// Bytes the table holds in memory.
    pub fn memory_bytes(&self) -> u64 {
        (self.kd_values.len() * 12
            + (self.kd_index.len() + self.normal_slots.len() + self.texture_slots.len()) * 4
            + self.normals.len() * std::mem::size_of::<[Vec3; 3]>()
            + self.textured.len() * std::mem::size_of::<TexturedCorners>()) as u64
    }
}

impl FromIterator<TriangleShading> for ShadingTable {
    /// A table of these triangles' shading, in order: reflectances merged by bit pattern and
    /// numbered in order of first use.
    fn from_iter<I: IntoIterator<Item = TriangleShading>>(shading: I) -> Self {
        let shading = shading.into_iter();
        let mut kd = Distinct::with_capacity(shading.size_hint().0);
        let mut normal_slots = Vec::new();
        let mut normals = Vec::new();
        let mut texture_slots = Vec::new();
        let mut textured = Vec::new();
        for (i, s) in shading.enumerate() {
            kd.push(s.kd);
            push_sparse(&mut normal_slots, &mut normals, i, s.normals);
            push_sparse(&mut texture_slots, &mut textured, i, s.texture);
        }
        ShadingTable {
            kd_values: kd.values,
            kd_index: kd.uses,
            normal_slots,
            normals,
            texture_slots,
            textured,
        }
    }
}

/// Records triangle `i`'s optional `value`: its slot in `values`, or [`NO_SLOT`]; `slots` stays
/// empty until some triangle has a value (then it is filled for the triangles before).
fn push_sparse<T>(slots: &mut Vec<u32>, values: &mut Vec<T>, i: usize, value: Option<T>) {
    match value {
        Some(v) => {
            if slots.is_empty() {
                slots.resize(i, NO_SLOT);
            }
            slots.push(values.len() as u32);
            values.push(v);
        }
        None if !slots.is_empty() => slots.push(NO_SLOT),
        None => {}
    }
}

impl PartialEq for ShadingTable {
    fn eq(&self, other: &Self) -> bool {
        self.len() == other.len() && self.iter().eq(other.iter())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shading(kd: f32, normals: bool) -> TriangleShading {
        TriangleShading {
            normals: normals.then(|| [Vec3::X * kd, Vec3::Y, Vec3::Z]),
            kd: [kd, 0.5, -0.0],
            texture: None,
        }
    }

    #[test]
    fn a_table_gives_back_what_it_was_built_from_and_stores_each_reflectance_once() {
        let input: Vec<_> = [(0.25, false), (0.5, true), (0.25, false), (0.5, false)]
            .into_iter()
            .map(|(kd, n)| shading(kd, n))
            .collect();
        let table: ShadingTable = input.iter().copied().collect();
        assert_eq!(table.len(), 4);
        assert_eq!(table.iter().collect::<Vec<_>>(), input);
        assert_eq!(table.get(4), None);
        assert_eq!(table.kd_values.len(), 2);
        assert_eq!(table.normals.len(), 1);
        assert_eq!(table.memory_bytes(), 2 * 12 + 8 * 4 + 36);
    }

    /// `flat_kd` gives the reflectance exactly for the triangles without normals and
    /// texture, and nothing past the end.
    #[test]
    fn flat_kd_is_the_reflectance_of_flat_untextured_triangles_only() {
        let textured = TriangleShading {
            texture: Some(TexturedCorners {
                texture: 0,
                uv: [[0.0; 2]; 3],
            }),
            ..shading(0.75, false)
        };
        let input = [shading(0.25, false), shading(0.5, true), textured];
        let table: ShadingTable = input.iter().copied().collect();
        assert_eq!(table.flat_kd(0), Some([0.25, 0.5, -0.0]));
        assert_eq!(table.flat_kd(1), None);
        assert_eq!(table.flat_kd(2), None);
        assert_eq!(table.flat_kd(3), None);
        let plain: ShadingTable = [shading(0.25, false)].into_iter().collect();
        assert_eq!(plain.flat_kd(0), Some([0.25, 0.5, -0.0]));
        assert_eq!(plain.flat_kd(1), None);
    }

    #[test]
    fn a_table_without_normals_holds_four_bytes_a_triangle() {
        let table: ShadingTable = (0..1000).map(|_| shading(0.25, false)).collect();
        assert_eq!(table.memory_bytes(), 12 + 1000 * 4);
        assert!(table.iter().all(|s| s.normals.is_none()));
    }

    #[test]
    fn equality_looks_through_a_repeated_reflectance() {
        let built: ShadingTable = [shading(0.25, false), shading(0.25, false)]
            .into_iter()
            .collect();
        let repeated = ShadingTable::from_parts(
            vec![[0.25, 0.5, -0.0]; 2],
            vec![0, 1],
            vec![],
            vec![],
            vec![],
            vec![],
        );
        assert_eq!(built, repeated);
        let other = ShadingTable::from_parts(
            vec![[0.75, 0.5, -0.0]],
            vec![0, 0],
            vec![],
            vec![],
            vec![],
            vec![],
        );
        assert_ne!(built, other);
    }
}
