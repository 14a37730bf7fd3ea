//! Double-precision positions and the scene's local frame.
//!
//! OBJ coordinates are read as f64. When a whole scene is loaded, its local origin is the centre
//! of the bounding box of the vertices used by triangles, computed in f64; every position is
//! stored as its f32 offset from that origin, and the camera and lights are moved into the same
//! frame in f64 ([`super::Scene::origin`]). So the stored geometry depends on the scene's shape
//! and size, not on where it sits: a scene translated far from the world origin keeps every
//! detail, and an f32 coordinate errs by at most half an ulp of half the scene's extent (about
//! 3e-8 of its size), wherever it is.

use super::mesh::Mesh;
use crate::error::SceneError;
use glam::DVec3;
use std::path::Path;

/// A mesh whose positions are still in double precision, in the file's frame. `mesh.positions`
/// is empty; `positions` holds them.
#[derive(Debug, Default)]
pub(super) struct WorldMesh {
    /// Triangles, normals and materials; indices refer to `positions`.
    pub(super) mesh: Mesh,
    /// Vertex positions as written, finite.
    pub(super) positions: Vec<DVec3>,
}

impl WorldMesh {
    /// Appends `other`, renumbering its indices; triangle order is `self` then `other`.
    pub(super) fn append(&mut self, other: WorldMesh) {
        let base = self.positions.len() as u32;
        self.positions.extend(other.positions);
        self.mesh.append_with_position_base(other.mesh, base);
    }

    /// The centre of the bounding box of the vertices used by triangles, or `None` when there
    /// are no triangles.
    pub(super) fn centre(&self) -> Option<DVec3> {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for &i in self.mesh.triangles.iter().flatten() {
            let p = self.positions[i as usize];
            lo = lo.min(p);
            hi = hi.max(p);
        }
        (!self.mesh.triangles.is_empty()).then(|| (lo + hi) * 0.5)
    }

    /// The mesh with every position stored as its f32 offset from `origin` (computed in f64,
    /// rounded once). Errors, naming `path`, when an offset does not fit in f32 (vertices
    /// farther apart than the f32 range).
    pub(super) fn into_local(self, origin: DVec3, path: &Path) -> Result<Mesh, SceneError> {
        let WorldMesh {
            mut mesh,
            positions,
        } = self;
        mesh.positions = Vec::with_capacity(positions.len());
        for p in positions {
            let local = (p - origin).as_vec3();
            if !local.is_finite() {
                return Err(SceneError::TooLarge {
                    path: path.to_path_buf(),
                });
            }
            mesh.positions.push(local);
        }
        Ok(mesh)
    }

    /// Moves the mesh into its local frame: the origin is [`WorldMesh::centre`] (the world
    /// origin for a mesh without triangles), returned with the localised mesh.
    pub(super) fn localise(self, path: &Path) -> Result<(Mesh, DVec3), SceneError> {
        let origin = self.centre().unwrap_or(DVec3::ZERO);
        Ok((self.into_local(origin, path)?, origin))
    }
}
