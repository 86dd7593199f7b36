//! The binding of a bake to its scene, checked once before relighting: the same meshes (by
//! geometry hash, or the hash of the mesh a subdivided object was refined from), a complete
//! unsharded bake with its environment, and for per-texel bakes the lightmap UVs it was baked
//! with; and what relighting reads of the bake's settings (lightmaps, refined meshes, the
//! environment, the pixel samples of a per-pixel bake).

use crate::error::SceneRelightError;
use glam::Vec3;
use prt_bakefile::{Bake, SampleKind};
use prt_scene::Scene;
use std::path::Path;

/// Checks that `bake` was made for `scene`'s meshes (count, names, geometry hashes).
pub fn check_bake(scene: &Scene, bake: &Bake, path: &Path) -> Result<(), SceneRelightError> {
    let bad = |reason: String| SceneRelightError::BakeMismatch {
        path: path.to_path_buf(),
        reason,
    };
    if bake.objects.len() != scene.meshes.len() {
        return Err(bad(format!(
            "the bake holds {} objects but the scene has {} meshes",
            bake.objects.len(),
            scene.meshes.len()
        )));
    }
    if let Some(p) = &bake.meta.pass {
        return Err(bad(format!(
            "this is the intermediate file of pass {} of a distributed bake (passes 0..={}): run the remaining passes (prt bake --pass {} --previous ...)",
            p.index,
            p.last,
            p.index + 1
        )));
    }
    if bake.meta.shard.count != 1 {
        return Err(bad(format!(
            "this is shard {} of {}: merge the shards with `prt merge` first",
            bake.meta.shard.index, bake.meta.shard.count
        )));
    }
    for (o, (obj, mesh)) in bake.objects.iter().zip(&scene.meshes).enumerate() {
        let h = prt_scene::binding::geometry_hash(&mesh.positions, &mesh.indices);
        // A subdivided object was baked on a refinement of the scene's mesh: its source hash.
        let source = subdivided_from(bake, &obj.name).unwrap_or(obj.geometry_hash);
        if h != source {
            return Err(bad(format!(
                "object {o} ({}) was baked for different geometry (hash {:#018x}, the scene's mesh {:#018x}): re-bake",
                obj.name, obj.geometry_hash, h
            )));
        }
    }
    if bake.environment.is_none() {
        return Err(bad("the bake carries no environment coefficients".into()));
    }
    if let SampleKind::Texel { .. } = bake.meta.sample_kind {
        for (obj, mesh) in bake.objects.iter().zip(&scene.meshes) {
            let Some(entry) = lightmap_entry(bake, &obj.name) else {
                if obj.coverage.is_some() {
                    return Err(bad(format!(
                        "object {}: texels without a settings.lightmaps entry",
                        obj.name
                    )));
                }
                continue;
            };
            // A generated atlas travels in the file (checked against its hash on reading).
            let Some(set) = entry.uv_set else { continue };
            let h = mesh.texcoords.get(set).map(|uv| prt_bakefile::uv_hash(uv));
            if h != Some(entry.uv_hash) {
                return Err(bad(format!(
                    "object {}: its lightmap UVs (set {set}) differ from those it was baked with: re-bake",
                    obj.name
                )));
            }
        }
    }
    Ok(())
}

/// An object's `settings.lightmaps` entry of a per-texel bake: a UV set of the scene's mesh,
/// or a generated atlas's per-corner UVs (SPEC §3.9.3).
struct LightmapEntry {
    uv_set: Option<usize>,
    atlas: Option<Vec<[[f32; 2]; 3]>>,
    uv_hash: u64,
}

fn lightmap_entry(bake: &Bake, name: &str) -> Option<LightmapEntry> {
    let all = bake.meta.settings.get("lightmaps")?.as_array()?;
    let e = all
        .iter()
        .find(|e| e.get("object").and_then(serde_json::Value::as_str) == Some(name))?;
    let atlas = match e.get("atlas") {
        Some(a) => Some(prt_bakefile::atlas_corner_uvs(a, None).ok()?),
        None => None,
    };
    let uv_set = match e.get("uv_set") {
        Some(k) => Some(usize::try_from(k.as_u64()?).ok()?),
        None => None,
    };
    (uv_set.is_some() != atlas.is_some()).then_some(())?;
    Some(LightmapEntry {
        uv_set,
        atlas,
        uv_hash: e.get("uv_hash")?.as_str()?.parse().ok()?,
    })
}

/// The lightmap of every object of a per-texel bake that was baked per texel (`None`
/// otherwise): rasterised again from the scene's UVs (checked against the bake's hash by
/// [`check_bake`]), or from the generated atlas the file carries (SPEC §3.9.3), with the
/// bake's own code, so texel `k` is the bake's point `k`.
///
/// # Errors
/// A lightmap the rasteriser refuses (it accepted it when baking).
pub fn lightmaps(
    scene: &Scene,
    bake: &Bake,
) -> Result<Vec<Option<prt_scene::lightmap::Lightmap>>, SceneRelightError> {
    let SampleKind::Texel { width, height } = bake.meta.sample_kind else {
        return Ok(vec![None; bake.objects.len()]);
    };
    bake.objects
        .iter()
        .zip(&scene.meshes)
        .map(|(obj, mesh)| {
            if obj.coverage.is_none() {
                return Ok(None);
            }
            let atlas = lightmap_entry(bake, &obj.name).and_then(|e| e.atlas);
            match atlas {
                Some(c) => prt_scene::lightmap::lightmap_from_corners(mesh, c, width, height),
                None => prt_scene::lightmap::lightmap(mesh, width, height),
            }
            .map(Some)
            .map_err(|e| SceneRelightError::Invalid(format!("object {}: {e}", obj.name)))
        })
        .collect()
}

/// The hash of the mesh a subdivided object was refined from (`settings.subdivided_from`).
fn subdivided_from(bake: &Bake, name: &str) -> Option<u64> {
    let h = bake
        .meta
        .settings
        .get("subdivided_from")?
        .get(name)?
        .get("geometry_hash")?;
    u64::from_str_radix(h.as_str()?.strip_prefix("0x")?, 16).ok()
}

/// The scene as the bake saw it: every object the bake subdivided gets the bake's refined
/// mesh (its `MESH` section: positions, normals, triangles), so that relighting, image
/// formation and export use the vertices the transfer belongs to. Other objects are
/// unchanged. Call after [`check_bake`].
///
/// # Errors
/// A subdivided object whose mesh is missing from the file.
pub fn baked_scene(scene: &Scene, bake: &Bake) -> Result<Scene, SceneRelightError> {
    let mut out = scene.clone();
    for (obj, mesh) in bake.objects.iter().zip(&mut out.meshes) {
        if subdivided_from(bake, &obj.name).is_none() {
            continue;
        }
        let g = obj.mesh.as_ref().ok_or_else(|| {
            SceneRelightError::Invalid(format!(
                "object {} was subdivided but the bake holds no mesh for it",
                obj.name
            ))
        })?;
        mesh.positions = g.positions.iter().map(|p| Vec3::from_array(*p)).collect();
        mesh.normals = g.normals.iter().map(|n| Vec3::from_array(*n)).collect();
        mesh.indices.clone_from(&g.triangles);
    }
    Ok(out)
}

/// The bake's environment as RGB coefficients `[coeff][channel]`.
pub(crate) fn environment(bake: &Bake) -> (usize, Vec<[f64; 3]>) {
    let env = bake.environment.as_ref().expect("checked");
    let order = env.order as usize;
    let n2 = order * order;
    let c = (0..n2)
        .map(|i| [env.values[i], env.values[n2 + i], env.values[2 * n2 + i]])
        .collect();
    (order, c)
}

/// Sub-pixel samples per pixel of a per-pixel bake: its `pixel_samples` setting; bakes made
/// before that setting existed sampled the pixel centre only (1).
pub(crate) fn baked_pixel_samples(bake: &Bake) -> u32 {
    bake.meta
        .settings
        .get("pixel_samples")
        .and_then(serde_json::Value::as_u64)
        .map_or(1, |k| {
            k.clamp(1, u64::from(prt_tracer::points::MAX_PIXEL_SAMPLES)) as u32
        })
}
