//! How a scene mesh binds to a bake file (SPEC §3.9.2, §3.10): the geometry hash a bake
//! stores for it and the `MESH` section it writes. The baker writes both; relighting and
//! export check a scene against a bake with the same functions, so the two cannot drift.

use crate::Camera;
use crate::Mesh;
use glam::Vec3;
use prt_bakefile::{CameraInfo, MeshGeometry};

/// The geometry hash the bake file stores (FNV-1a of positions and indices, [`prt_bakefile::geometry_hash`]).
#[must_use]
pub fn geometry_hash(positions: &[Vec3], indices: &[[u32; 3]]) -> u64 {
    let p: Vec<[f32; 3]> = positions.iter().map(|v| v.to_array()).collect();
    prt_bakefile::geometry_hash(&p, indices)
}

/// The mesh section of a bake (SPEC §3.10): the world-space positions and triangles the
/// geometry hash covers, and the unit normals the bake used at the vertices (the loader's
/// normal, renormalised; +Y where it is degenerate, as the baker's vertex points do).
#[must_use]
pub fn mesh_geometry(mesh: &Mesh) -> MeshGeometry {
    MeshGeometry {
        positions: mesh.positions.iter().map(|p| p.to_array()).collect(),
        normals: mesh
            .normals
            .iter()
            .map(|n| n.normalize_or(Vec3::Y).to_array())
            .collect(),
        triangles: mesh.indices.clone(),
    }
}

/// The camera of a per-pixel bake (SPEC §3.9), as the renderer uses it.
#[must_use]
pub fn camera_info(c: &Camera) -> CameraInfo {
    CameraInfo {
        model: CameraInfo::PINHOLE.into(),
        eye: c.eye.to_array(),
        target: c.target.to_array(),
        up: c.up.to_array(),
        fov_y_degrees: c.fov_y_deg,
        width: c.width,
        height: c.height,
    }
}
