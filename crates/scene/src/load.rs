//! Loading a mesh file of any supported kind, chosen by its extension.

use crate::gltf_io::load_gltf;
use crate::obj::load_obj;
use crate::SceneError;
use glam::DMat4;
use std::path::Path;

/// Reads a mesh file by extension (`.obj`, `.gltf`, `.glb`, case-insensitive) and transforms
/// it to world space with `to_world` (see the module docs of this crate for the clean-up).
///
/// # Errors
/// [`SceneError::Format`] for an unknown extension; the errors of
/// [`crate::load_obj`] and [`crate::load_gltf`].
pub fn load_mesh(path: &Path, to_world: &DMat4) -> Result<crate::LoadedMeshes, SceneError> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "obj" => load_obj(path, to_world),
        "gltf" | "glb" => load_gltf(path, to_world),
        _ => Err(SceneError::format(
            path,
            format!("unknown mesh extension `{ext}`: expected .obj, .gltf or .glb"),
        )),
    }
}
