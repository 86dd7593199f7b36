//! Wavefront OBJ meshes through `tobj`: polygons triangulated (fan), one index per vertex
//! (a position used with two different `vn` becomes two vertices), every `o`/`g` group merged
//! into one mesh. `vn` normals are used when every vertex has one; `.mtl` files are not read
//! (materials come from the scene file). Axes are taken as they are in the file.

use crate::mesh::{finish_mesh, RawMesh};
use crate::{LoadedMeshes, SceneError};
use glam::{DMat4, Vec3};
use std::io::BufReader;
use std::path::Path;

/// Reads an OBJ file, transforms it by `to_world` and cleans it (see [`crate::load_mesh`]).
///
/// The result has one mesh (material index 0) and no materials.
///
/// # Errors
/// [`SceneError::Io`] if the file cannot be read, [`SceneError::Mesh`] if it does not parse,
/// has an out-of-range index or a non-finite position, or has no non-degenerate triangle.
pub fn load_obj(path: &Path, to_world: &DMat4) -> Result<LoadedMeshes, SceneError> {
    let file = std::fs::File::open(path).map_err(|e| SceneError::io(path, e))?;
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    };
    let (models, _materials) = tobj::load_obj_buf(&mut BufReader::new(file), &options, |_| {
        Ok(Default::default())
    })
    .map_err(|e| SceneError::mesh(path, format!("not a readable OBJ file: {e}")))?;

    let mut raw = RawMesh {
        name: file_name(path),
        ..RawMesh::default()
    };
    let mut normals = Vec::new();
    let mut all_have_normals = true;
    let mut texcoords = Vec::new();
    let mut all_have_texcoords = true;
    for model in &models {
        let m = &model.mesh;
        let base = raw.positions.len();
        if m.positions.len() % 3 != 0 || m.indices.len() % 3 != 0 {
            return Err(SceneError::mesh(
                path,
                format!(
                    "group `{}`: position or index count not a multiple of 3",
                    model.name
                ),
            ));
        }
        let count = m.positions.len() / 3;
        raw.positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|c| Vec3::new(c[0], c[1], c[2])),
        );
        if m.texcoords.len() / 2 == count && !m.texcoords.is_empty() {
            // OBJ's `vt` has v up from the image's bottom; glTF's (and ours) v down from its
            // top row.
            texcoords.extend(m.texcoords.chunks_exact(2).map(|c| [c[0], 1.0 - c[1]]));
        } else {
            all_have_texcoords = false;
        }
        if m.normals.len() == m.positions.len() {
            normals.extend(
                m.normals
                    .chunks_exact(3)
                    .map(|c| Vec3::new(c[0], c[1], c[2])),
            );
        } else {
            all_have_normals = false;
        }
        let too_many = u32::try_from(base + count).is_err();
        if too_many {
            return Err(SceneError::mesh(path, "more than 2^32 vertices"));
        }
        raw.indices.extend(m.indices.chunks_exact(3).map(|c| {
            // Indices past `count` stay past it after the shift, so finish_mesh reports them.
            [c[0], c[1], c[2]].map(|i| i.saturating_add(base as u32))
        }));
    }
    if raw.indices.is_empty() {
        return Err(SceneError::mesh(path, "the OBJ file has no faces"));
    }
    if all_have_normals {
        raw.normals = Some(normals);
    }
    if all_have_texcoords {
        raw.texcoords = vec![texcoords];
    }
    let (mesh, repairs) = finish_mesh(path, raw, to_world, 0)?;
    Ok(LoadedMeshes {
        meshes: vec![mesh],
        materials: Vec::new(),
        material_indices: Vec::new(),
        warnings: repairs.warnings(path),
        ..LoadedMeshes::default()
    })
}

/// The file name for messages and mesh names.
pub(crate) fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}
