//! Relighting a scene from its bake: per-object full-order or adaptive shading (prt-relight),
//! with the environment rotated about +Y by one SH rotation per frame.

use crate::error::SceneRelightError;
use glam::{DMat3, Vec3};
use prt_bakefile::{Bake, SampleKind, TransferKind};
use prt_relight::{
    AdaptiveInput, AdaptiveParams, Adjacency, DiffuseParams, FrameStats, Lighting, PhongParams,
    Relighter, SpecularInput, Surface, TransferView, Viewer,
};
use prt_scene::{Material, Scene};
use prt_sh::Rotation;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How to relight.
#[derive(Clone, Debug)]
pub struct RelightOptions {
    /// Order to relight at (`None`: each object's baked order); capped at the baked order.
    pub order: Option<usize>,
    /// Adaptive relighting parameters; `None` for full order.
    pub adaptive: Option<AdaptiveParams>,
    /// Environment rotation about +Y, degrees (same sense as the scene's `rotation_y`).
    pub rotate_y_deg: f64,
    /// Frames timed; the median is reported.
    pub timing_frames: usize,
    /// Frames shaded before the timed ones and not timed (lit as frame 0; results dropped),
    /// so that the timings are of the steady state a rotating-environment sequence runs in:
    /// the first frames of a process pay for fresh memory from the system and cold caches
    /// (measured on the 37k-vertex bunny: the median of the first 5 adaptive frames ~15 %
    /// above that of frames 3–17).
    pub warmup_frames: usize,
    /// Rotation about +Y added per timed frame, degrees (0: the same frame again). Frame `k`
    /// is lit by the environment rotated by `rotate_y_deg + k · step`; the radiance returned
    /// is frame 0's.
    pub rotate_y_step_deg: f64,
    /// Shade only these points of each object (full order only; the others come out 0):
    /// what a quality estimate relights at full order. `None`: every point.
    pub points: Option<Vec<Vec<u32>>>,
    /// How glossy lobes without a zonal form (Blinn–Phong, Ward, Cook–Torrance, `pbr`) are
    /// relit.
    pub glossy: GlossyPath,
}

/// The relighting path of glossy lobes without a zonal form.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GlossyPath {
    /// A zonal fit of the lobe per view elevation about its mean direction
    /// (`prt_shading::projection::fitted_table`), shaded by the Phong kernels: full order and adaptive,
    /// at Phong's cost.
    #[default]
    Fitted,
    /// The bake's per-view-elevation BRDF projections, rotated per point and dotted with
    /// `L ⊛ V` (Kautz, Sloan & Snyder 2002): exact up to the order, `O(order⁵)` per point —
    /// the reference the fitted path is measured against.
    Exact,
    /// The fitted path, except at the points whose view elevation (and roughness) puts the
    /// fit's relative L2 error against the lobe at `fit_error` or more
    /// (`prt_shading::projection::FittedTable::error`, interpolated as the lobe rows are): those are
    /// shaded by the exact path. A sharp lobe is far from zonal at grazing views, where the fit
    /// falls behind; the hybrid spends the exact path's cost only there. `fit_error = 0`
    /// shades every point exactly, a value above every error none.
    Hybrid {
        /// The fit error from which a point is shaded exactly.
        fit_error: f32,
    },
}

impl Default for RelightOptions {
    fn default() -> Self {
        Self {
            order: None,
            adaptive: None,
            rotate_y_deg: 0.0,
            timing_frames: 5,
            warmup_frames: 2,
            rotate_y_step_deg: 0.0,
            points: None,
            glossy: GlossyPath::Fitted,
        }
    }
}

/// Radiance of every point of every object, and what it cost.
#[derive(Clone, Debug)]
pub struct Relit {
    /// Per object: radiance per point (diffuse + specular).
    pub radiance: Vec<Vec<[f32; 3]>>,
    /// Per object: whether each point is in the (diffuse or specular) ROI, for adaptive runs.
    pub roi: Vec<Vec<bool>>,
    /// Figures of the run.
    pub stats: RelightStats,
    /// Per-pixel bakes: the sub-pixel samples the bake averaged over (its seed and
    /// `pixel_samples`), which image formation uses for the background share of each pixel.
    /// `None` for per-vertex bakes.
    pub footprints: Option<prt_tracer::points::PixelFootprints>,
    /// Per-texel bakes: per object its lightmap (`None` for objects relit per vertex), which
    /// image formation looks the texels' radiance up in; empty otherwise.
    pub lightmaps: Vec<Option<prt_scene::lightmap::Lightmap>>,
}

/// Figures of one relighting run.
#[derive(Clone, Debug, Default, Serialize)]
pub struct RelightStats {
    /// Order used (the largest over objects).
    pub order: usize,
    /// Whether the adaptive path was used.
    pub adaptive: bool,
    /// Absolute threshold (adaptive only).
    pub threshold: Option<f32>,
    /// Shading time of one frame over all objects, milliseconds: the median of the timed
    /// frames (the upper median for an even count).
    pub shade_ms: f64,
    /// The fastest timed frame, ms.
    pub shade_ms_min: f64,
    /// The slowest timed frame, ms.
    pub shade_ms_max: f64,
    /// Frames per second of the whole per-frame work over the timed frames: environment
    /// rotation, per-frame lighting preparation (light product matrices) and shading.
    pub fps: f64,
    /// Points shaded.
    pub points: usize,
    /// Fraction of points in the diffuse ROI (adaptive), weighted over objects.
    pub roi_fraction_diffuse: Option<f64>,
    /// Fraction of active points in the specular ROI (adaptive), weighted over objects.
    pub roi_fraction_specular: Option<f64>,
    /// Per-level fractions of the diffuse filtering pass (adaptive), weighted over objects.
    pub level_fraction_diffuse: Vec<f64>,
    /// Per-level fractions of the specular filtering pass (adaptive), weighted over objects.
    pub level_fraction_specular: Vec<f64>,
    /// Mean number of bands a diffuse point was shaded with (adaptive), weighted over objects.
    pub mean_order_diffuse: Option<f64>,
    /// Mean number of bands an active specular point was shaded with (adaptive).
    pub mean_order_specular: Option<f64>,
    /// Coefficient products spent (adaptive, both terms, all objects).
    pub products: Option<u64>,
    /// Products the full-order path spends on the same points.
    pub full_order_products: Option<u64>,
    /// Notes (e.g. specular lobes that could not be relit).
    pub notes: Vec<String>,
}

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
            let set = entry.uv_set;
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

/// An object's `settings.lightmaps` entry of a per-texel bake.
struct LightmapEntry {
    uv_set: usize,
    uv_hash: u64,
}

fn lightmap_entry(bake: &Bake, name: &str) -> Option<LightmapEntry> {
    let all = bake.meta.settings.get("lightmaps")?.as_array()?;
    let e = all
        .iter()
        .find(|e| e.get("object").and_then(serde_json::Value::as_str) == Some(name))?;
    Some(LightmapEntry {
        uv_set: usize::try_from(e.get("uv_set")?.as_u64()?).ok()?,
        uv_hash: e.get("uv_hash")?.as_str()?.parse().ok()?,
    })
}

/// The lightmap of every object of a per-texel bake that was baked per texel (`None`
/// otherwise): rasterised again from the scene's UVs (checked against the bake's hash by
/// [`check_bake`]) with the bake's own code, so texel `k` is the bake's point `k`.
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
            prt_scene::lightmap::lightmap(mesh, width, height)
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
fn environment(bake: &Bake) -> (usize, Vec<[f64; 3]>) {
    let env = bake.environment.as_ref().expect("checked");
    let order = env.order as usize;
    let n2 = order * order;
    let c = (0..n2)
        .map(|i| [env.values[i], env.values[n2 + i], env.values[2 * n2 + i]])
        .collect();
    (order, c)
}

/// [`truncate`] of the points listed in `subset` only (in that order), or of all of them
/// without a subset; the listed rows are picked before truncating, so a small subset costs
/// little.
fn select(
    data: &[f32],
    from: usize,
    to: usize,
    channels: usize,
    channels_out: usize,
    subset: Option<&[u32]>,
) -> Vec<f32> {
    match subset {
        None => truncate(data, from, to, channels, channels_out),
        Some(sub) => {
            let stride = channels * from * from;
            let rows: Vec<f32> = sub
                .iter()
                .flat_map(|&i| &data[i as usize * stride..(i as usize + 1) * stride])
                .copied()
                .collect();
            truncate(&rows, from, to, channels, channels_out)
        }
    }
}

/// Repacks `[point][channel][coeff]` data from order `from` to order `to ≤ from`, keeping
/// `channels_out` channels (the first ones).
fn truncate(
    data: &[f32],
    from: usize,
    to: usize,
    channels: usize,
    channels_out: usize,
) -> Vec<f32> {
    if from == to && channels == channels_out {
        return data.to_vec();
    }
    let (f2, t2) = (from * from, to * to);
    let points = data.len() / (channels * f2);
    let mut out = Vec::with_capacity(points * channels_out * t2);
    for p in 0..points {
        for c in 0..channels_out {
            let s = (p * channels + c) * f2;
            out.extend_from_slice(&data[s..s + t2]);
        }
    }
    out
}

/// Relights every object of `scene` from `bake` (already checked with [`check_bake`]).
pub fn relight(
    scene: &Scene,
    accel: &prt_tracer::Accel,
    bake: &Bake,
    opt: &RelightOptions,
) -> Result<Relit, SceneRelightError> {
    let (env_order, env) = environment(bake);
    let rotation = |deg: f64| -> Result<Option<Rotation>, SceneRelightError> {
        Ok(if deg == 0.0 {
            None
        } else {
            Some(Rotation::new(
                env_order,
                DMat3::from_rotation_y(deg.to_radians()),
            )?)
        })
    };
    let rot = rotation(opt.rotate_y_deg)?;
    // The lighting of timed frame `k` (rotated by its own angle), and the time that took.
    let frame_angle = |k: usize| opt.rotate_y_deg + opt.rotate_y_step_deg * k as f64;
    let frame_light = |k: usize| -> Result<(Lighting, f64), SceneRelightError> {
        let start = Instant::now();
        let r = rotation(frame_angle(k))?;
        let l = Lighting::from_rgb_coefficients(&env, r.as_ref())?;
        Ok((l, start.elapsed().as_secs_f64()))
    };
    let env_rotated: Vec<[f64; 3]> = match &rot {
        Some(r) => r.apply_rgb(&env),
        None => env.clone(),
    };
    let eye = scene.camera.eye.as_vec3().to_array();
    let per_pixel = matches!(bake.meta.sample_kind, SampleKind::Pixel { .. });
    let footprints = if per_pixel {
        Some(prt_tracer::points::pixel_footprints(
            scene,
            accel,
            bake.meta.seed,
            pixel_samples(bake),
        )?)
    } else {
        None
    };
    let lightmaps = lightmaps(scene, bake)?;
    let mut stats = RelightStats {
        adaptive: opt.adaptive.is_some(),
        ..RelightStats::default()
    };
    let mut radiance = Vec::new();
    let mut roi = Vec::new();
    let mut times = vec![0.0f64; opt.timing_frames.max(1)];
    // Whole per-frame work (rotation, lighting preparation, shading), for frames per second.
    let mut frame_seconds = 0.0f64;
    let (mut roi_d, mut roi_s, mut n_d, mut n_s) = (0.0, 0.0, 0.0, 0.0);
    for (o, obj) in bake.objects.iter().enumerate() {
        let mesh = &scene.meshes[o];
        let material = &scene.materials[mesh.material];
        let baked = obj.order as usize;
        let order = opt.order.unwrap_or(baked).min(baked).min(env_order);
        stats.order = stats.order.max(order);
        let relighter = Relighter::new(order)?;
        let diffuse_block = obj
            .diffuse_block()
            .ok_or_else(|| SceneRelightError::BakeMismatch {
                path: PathBuf::from("<bake>"),
                reason: format!("object {} has no diffuse transfer", obj.name),
            })?;
        let channels = obj.channels as usize;
        let subset = opt
            .points
            .as_ref()
            .map(|p| p.get(o).map_or(&[][..], Vec::as_slice));
        let lightmap = lightmaps[o].as_ref();
        if subset.is_some() && (opt.adaptive.is_some() || per_pixel || lightmap.is_some()) {
            return Err(SceneRelightError::Invalid(
                "relighting a subset of points is for full-order per-vertex relighting only".into(),
            ));
        }
        let all_points = diffuse_block.data.len() / (channels * baked * baked).max(1);
        if let Some(bad) = subset.and_then(|s| s.iter().find(|&&i| i as usize >= all_points)) {
            return Err(SceneRelightError::Invalid(format!(
                "point {bad} of object {} does not exist ({all_points} points)",
                obj.name
            )));
        }
        let diffuse_data = select(
            &diffuse_block.data,
            baked,
            order,
            channels,
            channels,
            subset,
        );
        // Compact copies of the low bands for the adaptive path's level-by-level reading
        // (made once per run, outside the timed frames).
        let diffuse_low = prt_relight::low_bands(&diffuse_data, order);
        let diffuse_view =
            TransferView::new(order, channels, &diffuse_data)?.with_low_bands(&diffuse_low)?;
        // Surface points: vertices, or pixel hits for per-pixel bakes.
        let (positions, normals): (Vec<[f32; 3]>, Vec<[f32; 3]>) = if let Some(lm) = lightmap {
            // Texels: their surface points; empty texels a placeholder facing away from the
            // camera (their transfer is zero).
            let away = (
                (Vec3::from_array(eye) + Vec3::Y).to_array(),
                Vec3::Y.to_array(),
            );
            lm.texels
                .iter()
                .map(|t| t.map_or(away, |t| (t.position.to_array(), t.normal.to_array())))
                .unzip()
        } else if per_pixel {
            let fp = footprints
                .as_ref()
                .expect("per-pixel bakes have footprints");
            crate::footprint::pixel_surface(scene, fp, o)
                .into_iter()
                .unzip()
        } else {
            (
                mesh.positions.iter().map(|p| p.to_array()).collect(),
                mesh.normals
                    .iter()
                    .map(|n| n.normalize_or(Vec3::Y).to_array())
                    .collect(),
            )
        };
        // Materials that vary over the surface (textures, vertex colours): resolved per point.
        let point_materials: Option<Vec<Material>> = scene.material_varies(o).then(|| {
            let all = match (&footprints, lightmap) {
                (_, Some(lm)) => lm
                    .texels
                    .iter()
                    .map(|t| match t {
                        Some(t) => scene.material_at(
                            o,
                            prt_scene::SurfacePoint::Triangle {
                                tri: t.triangle,
                                u: t.bary[1],
                                v: t.bary[2],
                            },
                        ),
                        None => *material,
                    })
                    .collect(),
                (Some(fp), None) => crate::footprint::pixel_materials(scene, fp, o),
                (None, None) => (0..mesh.positions.len() as u32)
                    .map(|v| scene.material_at(o, prt_scene::SurfacePoint::Vertex(v)))
                    .collect(),
            };
            match subset {
                Some(sub) => sub.iter().map(|&i| all[i as usize]).collect(),
                None => all,
            }
        });
        let (positions, normals) = match subset {
            Some(sub) => (
                sub.iter().map(|&i| positions[i as usize]).collect(),
                sub.iter().map(|&i| normals[i as usize]).collect(),
            ),
            None => (positions, normals),
        };
        let is_pbr = matches!(material, Material::Pbr { .. });
        // The diffuse term is relit with unit albedo and scaled per point afterwards when the
        // albedo varies or (pbr) depends on the view.
        let per_point_diffuse = point_materials.is_some() || is_pbr;
        let albedo = material.albedo();
        let dparams = DiffuseParams::from_albedo(if per_point_diffuse { [1.0; 3] } else { albedo });
        // A compressed diffuse block relights from its clustered-PCA form (full order only).
        let cpca = diffuse_block
            .cpca
            .as_ref()
            .filter(|_| subset.is_none() && opt.adaptive.is_none());
        let cpca_view = cpca.map(|c| prt_relight::CpcaTransfer {
            order: baked,
            channels,
            clusters: c.clusters as usize,
            components: c.components as usize,
            centres: &c.centres,
            cluster_of: &c.cluster_of,
            weights: &c.weights,
        });
        if let Some(c) = cpca {
            stats.notes.push(format!(
                "{}: diffuse relit from clustered PCA ({} clusters, {} components, relative L2 error {:.3} %)",
                obj.name,
                c.clusters,
                c.components,
                100.0 * c.rel_error
            ));
        }
        let phong = match material {
            Material::Phong {
                specular, exponent, ..
            } => Some(PhongParams {
                specular: *specular,
                exponent: *exponent,
            }),
            Material::Lambert { .. }
            | Material::BlinnPhong { .. }
            | Material::Ward { .. }
            | Material::CookTorrance { .. }
            | Material::Pbr { .. } => None,
            other => {
                stats.notes.push(format!(
                    "{}: the specular lobe of a {} material is not relit (diffuse part only)",
                    obj.name,
                    other.type_name()
                ));
                None
            }
        };
        let glossy = GlossyLobe::of(material, point_materials.as_deref(), &mut stats, &obj.name);
        // The fitted lobe's table (built once per object, outside the timed frames).
        let fitted = match (&glossy, opt.glossy) {
            (Some(g), GlossyPath::Fitted | GlossyPath::Hybrid { .. }) => {
                let tables: Vec<_> = g.levels.iter().map(|m| fitted_cached(m, order)).collect();
                Some(FittedF32::stacked(&tables))
            }
            _ => None,
        };
        // The exact path's tables from the bake.
        let material_name = scene
            .material_names
            .get(mesh.material)
            .cloned()
            .unwrap_or_default();
        let exact_tables: Option<Vec<&prt_bakefile::GlossyBrdfTable>> = match (&glossy, opt.glossy)
        {
            (Some(_), GlossyPath::Exact | GlossyPath::Hybrid { .. }) => {
                let names: Vec<String> = if is_pbr {
                    prt_shading::projection::PbrComponent::ALL
                        .iter()
                        .map(|c| format!("{material_name}{}", c.suffix()))
                        .collect()
                } else {
                    vec![material_name.clone()]
                };
                let found: Option<Vec<_>> = names
                    .iter()
                    .map(|n| bake.glossy.iter().find(|t| t.material == *n))
                    .collect();
                if found.is_none() {
                    stats.notes.push(format!(
                        "{}: the bake has no BRDF table for {material_name}; specular not relit",
                        obj.name
                    ));
                }
                found
            }
            _ => None,
        };
        let vis_block = obj
            .blocks
            .iter()
            .find(|b| b.kind == TransferKind::Visibility);
        let wants_visibility = phong.is_some() || fitted.is_some() || exact_tables.is_some();
        let vis_data = match (wants_visibility, vis_block) {
            (true, Some(b)) => Some(select(&b.data, baked, order, channels, 1, subset)),
            (true, None) => {
                stats.notes.push(format!(
                    "{}: no visibility transfer in the bake; specular not relit",
                    obj.name
                ));
                None
            }
            _ => None,
        };
        let vis_low = vis_data.as_ref().map(|v| prt_relight::low_bands(v, order));
        let lobe = match (phong, &fitted, &glossy) {
            (Some(p), _, _) => Some(prt_relight::SpecularLobe::Phong(p)),
            (None, Some(f), Some(g)) => {
                Some(prt_relight::SpecularLobe::Fitted(prt_relight::FittedLobe {
                    elevations: &f.elevations,
                    roughness: &g.level_roughness,
                    point_roughness: &g.point_roughness,
                    lobes: f.lobes,
                    axis: &f.axis,
                    order: f.order,
                    bands: &f.bands,
                    bands_b: &f.bands_b,
                    colour_a: &g.colour_a,
                    colour_b: &g.colour_b,
                }))
            }
            _ => None,
        };
        let specular_input = match (lobe, &vis_data, &vis_low) {
            (Some(lobe), Some(v), Some(low)) => Some(SpecularInput {
                visibility: TransferView::new(order, 1, v)?.with_low_bands(low)?,
                surface: Surface {
                    positions: &positions,
                    normals: &normals,
                },
                viewer: Viewer::Eye(eye),
                lobe,
            }),
            _ => None,
        };
        let points = diffuse_view.point_count();
        stats.points += points;
        // The hybrid path's points shaded exactly: where the fit's error at the point's view
        // elevation and roughness reaches the threshold.
        let exact_points: Option<Vec<bool>> = match (opt.glossy, &fitted, &glossy, &exact_tables) {
            (GlossyPath::Hybrid { fit_error }, Some(f), Some(g), Some(_)) => {
                // Per point: shaded exactly, and facing the viewer (the others have no
                // specular; the share is counted over those that do).
                let (chosen, facing): (Vec<bool>, Vec<bool>) = (0..points)
                    .map(|p| {
                        let n = Vec3::from_array(normals[p]);
                        let wo = (Vec3::from_array(eye) - Vec3::from_array(positions[p]))
                            .normalize_or_zero();
                        let rough = if g.point_roughness.len() == 1 {
                            g.point_roughness[0]
                        } else {
                            g.point_roughness[p]
                        };
                        let cos_o = n.dot(wo);
                        (
                            f.error_at(cos_o, rough, &g.level_roughness) >= fit_error,
                            cos_o > 0.0,
                        )
                    })
                    .unzip();
                let front = facing.iter().filter(|&&f| f).count();
                let k = chosen.iter().zip(&facing).filter(|(&c, &f)| c && f).count();
                stats.notes.push(format!(
                    "{}: hybrid glossy path: {k} of the {front} points facing the viewer ({:.1} %), where the fit's error reaches {fit_error}, shaded exactly",
                    obj.name,
                    100.0 * k as f64 / front.max(1) as f64
                ));
                Some(chosen)
            }
            _ => None,
        };
        // Per-point diffuse albedo (relit with unit albedo above): the resolved material's,
        // and for `pbr` on the fitted path times `1 − s̄_d(θ_o)`, the cosine-weighted mean of
        // the `(1 − F)` factor's Schlick part (the exact path has it as a table).
        let diffuse_scale: Option<Vec<[f32; 3]>> = per_point_diffuse.then(|| {
            (0..points)
                .map(|p| {
                    let a = point_materials.as_ref().map_or(albedo, |m| m[p].albedo());
                    let exact_here = exact_points.as_ref().is_some_and(|e| e[p]);
                    let keep = match (&fitted, is_pbr) {
                        (Some(f), true) if !exact_here => {
                            let n = Vec3::from_array(normals[p]);
                            let wo = (Vec3::from_array(eye) - Vec3::from_array(positions[p]))
                                .normalize_or_zero();
                            1.0 - f.diffuse_fresnel_at(n.dot(wo))
                        }
                        _ => 1.0,
                    };
                    a.map(|x| x * keep)
                })
                .collect()
        });
        let scaled = |d: &[[f32; 3]]| -> Vec<[f32; 3]> {
            match &diffuse_scale {
                None => d.to_vec(),
                Some(k) => d
                    .iter()
                    .zip(k)
                    .map(|(v, k)| std::array::from_fn(|c| v[c] * k[c]))
                    .collect(),
            }
        };
        // The diffuse term (scaled) and the fitted or Phong specular, summed below.
        let (diffuse_part, specular_part): (Vec<[f32; 3]>, Vec<[f32; 3]>);
        let mut in_roi = vec![false; points];
        match (&opt.adaptive, per_pixel) {
            (Some(params), false) => {
                // Texels are neighbours on the lightmap's grid (two triangles per cell).
                let grid;
                let triangles = match lightmap {
                    Some(lm) => {
                        grid = texel_grid(lm.width, lm.height);
                        &grid
                    }
                    None => &mesh.indices,
                };
                let adjacency = Adjacency::from_triangles(points, triangles)?;
                let input = AdaptiveInput {
                    diffuse: Some((diffuse_view, dparams)),
                    specular: specular_input,
                    adjacency: &adjacency,
                };
                let mut first = None;
                for k in 0..opt.warmup_frames + times.len() {
                    // Timed frame `i` after the warm-up (which is lit as frame 0).
                    let timed = k.checked_sub(opt.warmup_frames);
                    let (lighting, rotate) = frame_light(timed.unwrap_or(0))?;
                    let prep = Instant::now();
                    let frame = relighter.frame_lighting(&lighting, specular_input.is_some())?;
                    let start = Instant::now();
                    let f = relighter.adaptive(&input, &frame, params)?;
                    let Some(i) = timed else { continue };
                    times[i] += start.elapsed().as_secs_f64();
                    frame_seconds += rotate + prep.elapsed().as_secs_f64();
                    if i == 0 {
                        first = Some(f);
                    }
                }
                let f = first.expect("at least one frame");
                accumulate_stats(
                    &mut stats, &f.stats, &mut roi_d, &mut roi_s, &mut n_d, &mut n_s,
                );
                for (i, r) in in_roi.iter_mut().enumerate() {
                    *r = f.roi[0].get(i).copied().unwrap_or(false)
                        || f.roi[1].get(i).copied().unwrap_or(false);
                }
                (diffuse_part, specular_part) = (scaled(&f.diffuse), f.specular);
            }
            (Some(_), true) => return Err(SceneRelightError::Invalid(
                "adaptive relighting walks the mesh's vertex adjacency: it needs a per-vertex bake"
                    .into(),
            )),
            (None, _) => {
                let mut first = (Vec::new(), Vec::new());
                for k in 0..opt.warmup_frames + times.len() {
                    let timed = k.checked_sub(opt.warmup_frames);
                    let (lighting, rotate) = frame_light(timed.unwrap_or(0))?;
                    let prep = Instant::now();
                    let frame = relighter.frame_lighting(&lighting, specular_input.is_some())?;
                    let start = Instant::now();
                    let d = match &cpca_view {
                        Some(c) => prt_relight::diffuse_cpca(order, c, &lighting, &dparams)?,
                        None => relighter.diffuse(&diffuse_view, &frame, &dparams)?,
                    };
                    let s = match &specular_input {
                        Some(si) => relighter.specular(si, &frame)?,
                        None => Vec::new(),
                    };
                    let Some(i) = timed else { continue };
                    times[i] += start.elapsed().as_secs_f64();
                    frame_seconds += rotate + prep.elapsed().as_secs_f64();
                    if i == 0 {
                        first = (d, s);
                    }
                }
                (diffuse_part, specular_part) = (scaled(&first.0), first.1);
            }
        }
        let result = match (&exact_tables, &vis_data, &glossy) {
            (Some(tables), Some(v), Some(g)) => {
                if opt.adaptive.is_some() {
                    stats.notes.push(format!(
                        "{}: the exact glossy specular is shaded at full order (the adaptive scheme covers the fitted path)",
                        obj.name
                    ));
                }
                let start = Instant::now();
                // The points shaded exactly: all of them, or the hybrid path's choice.
                let chosen: Vec<usize> = match &exact_points {
                    Some(e) => (0..points).filter(|&p| e[p]).collect(),
                    None => (0..points).collect(),
                };
                let n2 = order * order;
                let gather3 =
                    |a: &[[f32; 3]]| -> Vec<[f32; 3]> { chosen.iter().map(|&p| a[p]).collect() };
                let vis: Vec<f32> = chosen
                    .iter()
                    .flat_map(|&p| v[p * n2..(p + 1) * n2].iter().copied())
                    .collect();
                let parts = crate::glossy::glossy_components(
                    tables,
                    order,
                    &env_rotated,
                    &vis,
                    &gather3(&positions),
                    &gather3(&normals),
                    eye,
                )?;
                let pick = |w: &[[f32; 3]], p: usize| if w.len() == 1 { w[0] } else { w[p] };
                let weights = [&g.colour_a, &g.colour_b, &g.colour_c];
                let mut s = specular_part;
                s.resize(points, [0.0; 3]);
                for (k, &p) in chosen.iter().enumerate() {
                    s[p] = std::array::from_fn(|c| {
                        let sum: f64 = parts
                            .iter()
                            .zip(weights)
                            .map(|(part, w)| f64::from(pick(w, p)[c]) * part[k][c])
                            .sum();
                        sum.max(0.0) as f32
                    });
                }
                let dt = start.elapsed().as_secs_f64();
                times.iter_mut().for_each(|t| *t += dt);
                frame_seconds += dt * times.len() as f64;
                sum_terms(&diffuse_part, &s, points)
            }
            _ => sum_terms(&diffuse_part, &specular_part, points),
        };
        let result = match subset {
            Some(sub) => {
                let mut all = vec![[0.0f32; 3]; all_points];
                for (&i, r) in sub.iter().zip(result) {
                    all[i as usize] = r;
                }
                all
            }
            None => result,
        };
        let in_roi = if subset.is_some() {
            vec![false; all_points]
        } else {
            in_roi
        };
        radiance.push(result);
        roi.push(in_roi);
    }
    stats.fps = times.len() as f64 / frame_seconds.max(1e-12);
    times.sort_by(f64::total_cmp);
    stats.shade_ms = 1e3 * times[times.len() / 2];
    stats.shade_ms_min = 1e3 * times[0];
    stats.shade_ms_max = 1e3 * times[times.len() - 1];
    if stats.adaptive {
        stats.roi_fraction_diffuse = (n_d > 0.0).then(|| roi_d / n_d);
        stats.roi_fraction_specular = (n_s > 0.0).then(|| roi_s / n_s);
        let total_d = n_d.max(1.0);
        let total_s = n_s.max(1.0);
        if let Some(m) = stats.mean_order_diffuse.as_mut() {
            *m /= total_d;
        }
        if let Some(m) = stats.mean_order_specular.as_mut() {
            *m /= total_s;
        }
        stats
            .level_fraction_diffuse
            .iter_mut()
            .for_each(|v| *v /= total_d);
        stats
            .level_fraction_specular
            .iter_mut()
            .for_each(|v| *v /= total_s);
    }
    Ok(Relit {
        radiance,
        roi,
        stats,
        footprints,
        lightmaps,
    })
}

/// Two triangles per cell of a `w × h` texel grid (texel `y·w + x`): the neighbourhood the
/// adaptive path's region-of-interest growth walks for per-texel objects.
fn texel_grid(w: u32, h: u32) -> Vec<[u32; 3]> {
    let mut t = Vec::with_capacity(2 * w as usize * h as usize);
    for y in 0..h.saturating_sub(1) {
        for x in 0..w.saturating_sub(1) {
            let k = y * w + x;
            t.push([k, k + 1, k + w + 1]);
            t.push([k, k + w + 1, k + w]);
        }
    }
    t
}

/// Sub-pixel samples per pixel of a per-pixel bake: its `pixel_samples` setting; bakes made
/// before that setting existed sampled the pixel centre only (1).
fn pixel_samples(bake: &Bake) -> u32 {
    bake.meta
        .settings
        .get("pixel_samples")
        .and_then(serde_json::Value::as_u64)
        .map_or(1, |k| {
            k.clamp(1, u64::from(prt_tracer::points::MAX_PIXEL_SAMPLES)) as u32
        })
}

fn accumulate_stats(
    stats: &mut RelightStats,
    f: &FrameStats,
    roi_d: &mut f64,
    roi_s: &mut f64,
    n_d: &mut f64,
    n_s: &mut f64,
) {
    stats.threshold = Some(f.threshold);
    let mut add_work = |t: &prt_relight::TermStats| {
        *stats.products.get_or_insert(0) += t.products;
        *stats.full_order_products.get_or_insert(0) += t.full_order_products;
    };
    if let Some(d) = &f.diffuse {
        add_work(d);
    }
    if let Some(s) = &f.specular {
        add_work(s);
    }
    if let Some(d) = &f.diffuse {
        let n = d.active_points as f64;
        *roi_d += d.roi_fraction * n;
        *n_d += n;
        *stats.mean_order_diffuse.get_or_insert(0.0) += d.mean_order * n;
        add_levels(&mut stats.level_fraction_diffuse, &d.level_fraction, n);
    }
    if let Some(s) = &f.specular {
        let n = s.active_points as f64;
        *roi_s += s.roi_fraction * n;
        *n_s += n;
        *stats.mean_order_specular.get_or_insert(0.0) += s.mean_order * n;
        add_levels(&mut stats.level_fraction_specular, &s.level_fraction, n);
    }
}

fn add_levels(acc: &mut Vec<f64>, levels: &[f64], weight: f64) {
    if acc.len() < levels.len() {
        acc.resize(levels.len(), 0.0);
    }
    for (a, l) in acc.iter_mut().zip(levels) {
        *a += l * weight;
    }
}

fn sum_terms(d: &[[f32; 3]], s: &[[f32; 3]], n: usize) -> Vec<[f32; 3]> {
    (0..n)
        .map(|i| {
            let a = d.get(i).copied().unwrap_or([0.0; 3]);
            let b = s.get(i).copied().unwrap_or([0.0; 3]);
            [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
        })
        .collect()
}

/// A glossy lobe without a zonal form at one object: the material whose lobe shape is fitted
/// (for a `pbr` material that varies, its mean roughness), and the colour weights of its
/// components per point (one entry when uniform): `a`, `b` and, for the exact path of `pbr`,
/// `c` — the weights of the `D·V`, `s·D·V` and `s/π` tables (see
/// `prt_shading::projection::PbrComponent`); for the other lobes `a` is the specular colour.
struct GlossyLobe {
    /// The lobe shape at each roughness level the fit is made at (one unless a texture varies
    /// a `pbr` roughness).
    levels: Vec<Material>,
    /// Those levels' roughness (0 for the non-`pbr` lobes: one level).
    level_roughness: Vec<f32>,
    /// Each point's roughness (one value when uniform).
    point_roughness: Vec<f32>,
    colour_a: Vec<[f32; 3]>,
    colour_b: Vec<[f32; 3]>,
    colour_c: Vec<[f32; 3]>,
}

impl GlossyLobe {
    fn of(
        material: &Material,
        points: Option<&[Material]>,
        stats: &mut RelightStats,
        object: &str,
    ) -> Option<Self> {
        match *material {
            Material::BlinnPhong { specular, .. }
            | Material::Ward { specular, .. }
            | Material::CookTorrance { specular, .. } => Some(Self {
                levels: vec![*material],
                level_roughness: vec![0.0],
                point_roughness: vec![0.0],
                colour_a: vec![specular],
                colour_b: vec![[0.0; 3]],
                colour_c: vec![[0.0; 3]],
            }),
            Material::Pbr { roughness, .. } => {
                let mats: Vec<Material> = points.map_or_else(|| vec![*material], <[_]>::to_vec);
                let weights = |k: prt_shading::projection::PbrComponent| -> Vec<[f32; 3]> {
                    mats.iter()
                        .map(|m| match *m {
                            Material::Pbr {
                                base_color,
                                metallic,
                                ..
                            } => base_color.map(|c| k.weight(c, metallic)),
                            _ => [0.0; 3],
                        })
                        .collect()
                };
                use prt_shading::projection::PbrComponent as C;
                let rough: Vec<f32> = mats
                    .iter()
                    .map(|m| match *m {
                        Material::Pbr { roughness, .. } => roughness,
                        _ => roughness,
                    })
                    .collect();
                let lo = rough.iter().copied().fold(f32::INFINITY, f32::min);
                let hi = rough.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                // A roughness texture: the lobe fitted at ROUGHNESS_LEVELS levels over the
                // points' range, each point's lobe bilinear in (roughness, θ_o).
                let (level_roughness, point_roughness) = if hi - lo > 0.02 {
                    stats.notes.push(format!(
                        "{object}: roughness varies over the surface ({lo:.2}–{hi:.2}); the specular lobe is fitted at {ROUGHNESS_LEVELS} levels"
                    ));
                    let levels = (0..ROUGHNESS_LEVELS)
                        .map(|i| lo + (hi - lo) * i as f32 / (ROUGHNESS_LEVELS - 1) as f32)
                        .collect();
                    (levels, rough)
                } else {
                    (vec![lo], vec![lo])
                };
                let shape = |r: f32| Material::Pbr {
                    base_color: [1.0; 3],
                    metallic: 1.0,
                    roughness: r,
                    base_color_texture: None,
                    metallic_roughness_texture: None,
                };
                Some(Self {
                    levels: level_roughness.iter().map(|&r| shape(r)).collect(),
                    level_roughness,
                    point_roughness,
                    colour_a: weights(C::Dv),
                    colour_b: weights(C::SchlickDv),
                    colour_c: weights(C::SchlickDiffuse),
                })
            }
            _ => None,
        }
    }
}

/// Roughness levels of the fit when a texture varies a `pbr` roughness.
const ROUGHNESS_LEVELS: usize = 5;

/// The view-dependent terms [`relight`] shades an object with at full order on the fitted
/// glossy path (the default): what `prt export` writes so that an engine relights to the
/// same radiance (SPEC §10.1).
pub struct ViewDependent {
    /// `pbr`: the table `(elevations, s̄_d)` of the diffuse factor `1 − s̄_d(θ_o)`.
    pub diffuse_fresnel: Option<(Vec<f32>, Vec<f32>)>,
    /// The specular lobe, if the material has one [`relight`] shades.
    pub specular: Option<ExportLobe>,
}

/// A specular lobe as [`relight`] shades it (SPEC §10.1).
pub enum ExportLobe {
    /// The `phong` material: its exponent and colour and the lobe's band multipliers.
    Phong {
        /// The Phong exponent.
        exponent: f32,
        /// The specular colour.
        specular: [f32; 3],
        /// The lobe's zonal band multipliers, one per band.
        bands: Vec<f32>,
    },
    /// A fitted lobe: [`prt_relight::FittedLobe`]'s tables (stacked `[level][elevation]`)
    /// and its colours and roughness, one or one per point.
    Fitted {
        /// The order the tables were fitted at.
        table_order: usize,
        /// Zonal lobes per table row.
        lobes: usize,
        /// The tabulated view elevations (radians).
        elevations: Vec<f32>,
        /// The roughness of each fitted level (one level, roughness 0, unless a texture varies a
        /// `pbr` roughness).
        roughness_levels: Vec<f32>,
        /// The fitted lobes' axes, stacked `[level][elevation]` as `prt_relight::FittedLobe`
        /// reads them.
        axis: Vec<f32>,
        /// The fitted lobes' band multipliers, stacked likewise.
        bands: Vec<f32>,
        /// Likewise for the table's second term (`pbr`'s Fresnel split; see `FittedLobe`).
        bands_b: Vec<f32>,
        /// The colour weighting `bands`, one or one per point.
        colour_a: Vec<[f32; 3]>,
        /// The colour weighting `bands_b`, one or one per point.
        colour_b: Vec<[f32; 3]>,
        /// Each point's roughness (one value when uniform).
        point_roughness: Vec<f32>,
    },
}

/// The view-dependent terms of `material` relit at `order` (`points`: the material resolved
/// per point when it varies over the surface), built by the same functions [`relight`] uses.
pub fn view_dependent(
    material: &Material,
    points: Option<&[Material]>,
    order: usize,
) -> Result<ViewDependent, SceneRelightError> {
    let mut notes = RelightStats::default();
    let glossy = GlossyLobe::of(material, points, &mut notes, "");
    let fitted = glossy.as_ref().map(|g| {
        let tables: Vec<_> = g.levels.iter().map(|m| fitted_cached(m, order)).collect();
        FittedF32::stacked(&tables)
    });
    let diffuse_fresnel = match (&fitted, material) {
        (Some(f), Material::Pbr { .. }) => Some((f.elevations.clone(), f.diffuse_fresnel.clone())),
        _ => None,
    };
    let specular = match (material, glossy, fitted) {
        (
            Material::Phong {
                specular, exponent, ..
            },
            _,
            _,
        ) => Some(ExportLobe::Phong {
            exponent: *exponent,
            specular: *specular,
            bands: prt_sh::zonal::phong_lobe_bands(f64::from(*exponent), order)
                .map_err(|e| SceneRelightError::Invalid(e.to_string()))?
                .into_iter()
                .map(|a| a as f32)
                .collect(),
        }),
        (_, Some(g), Some(f)) => Some(ExportLobe::Fitted {
            table_order: f.order,
            lobes: f.lobes,
            elevations: f.elevations,
            roughness_levels: g.level_roughness,
            axis: f.axis,
            bands: f.bands,
            bands_b: f.bands_b,
            colour_a: g.colour_a,
            colour_b: g.colour_b,
            point_roughness: g.point_roughness,
        }),
        _ => None,
    };
    Ok(ViewDependent {
        diffuse_fresnel,
        specular,
    })
}

/// The fitted table of a lobe shape at an order, built once per process (a report relights
/// the same objects at many orders and settings; a table takes ~0.5 s to fit).
fn fitted_cached(shape: &Material, order: usize) -> std::sync::Arc<FittedF32> {
    type Cache = std::sync::Mutex<Vec<(Material, usize, std::sync::Arc<FittedF32>)>>;
    static CACHE: std::sync::OnceLock<Cache> = std::sync::OnceLock::new();
    let cache = CACHE.get_or_init(|| std::sync::Mutex::new(Vec::new()));
    if let Ok(c) = cache.lock() {
        if let Some((_, _, t)) = c.iter().find(|(m, o, _)| m == shape && *o == order) {
            return t.clone();
        }
    }
    let t = std::sync::Arc::new(FittedF32::new(
        &prt_shading::projection::fitted_table(shape, order)
            .expect("glossy materials have a fitted table"),
    ));
    if let Ok(mut c) = cache.lock() {
        c.push((*shape, order, t.clone()));
    }
    t
}

/// A [`prt_shading::projection::FittedTable`] in the f32 arrays prt-relight reads.
struct FittedF32 {
    order: usize,
    lobes: usize,
    elevations: Vec<f32>,
    axis: Vec<f32>,
    bands: Vec<f32>,
    bands_b: Vec<f32>,
    diffuse_fresnel: Vec<f32>,
    /// `[level][elevation]` relative L2 error of the fit against the lobe.
    error: Vec<f32>,
}

impl FittedF32 {
    fn new(t: &prt_shading::projection::FittedTable) -> Self {
        let f = |v: &[f64]| v.iter().map(|x| *x as f32).collect();
        Self {
            order: t.order,
            lobes: t.lobes,
            elevations: f(&t.elevations),
            axis: f(&t.axis),
            bands: f(&t.bands),
            bands_b: f(&t.bands_b),
            diffuse_fresnel: f(&t.diffuse_fresnel),
            error: f(&t.error),
        }
    }

    /// The tables of several roughness levels stacked `[level][elevation]` (their elevations
    /// and diffuse Fresnel factors are the same: neither depends on roughness).
    fn stacked(tables: &[std::sync::Arc<FittedF32>]) -> Self {
        let first = &tables[0];
        let cat =
            |f: fn(&FittedF32) -> &Vec<f32>| tables.iter().flat_map(|t| f(t).clone()).collect();
        Self {
            order: first.order,
            lobes: first.lobes,
            elevations: first.elevations.clone(),
            axis: cat(|t| &t.axis),
            bands: cat(|t| &t.bands),
            bands_b: cat(|t| &t.bands_b),
            diffuse_fresnel: first.diffuse_fresnel.clone(),
            error: cat(|t| &t.error),
        }
    }

    /// The fit's relative L2 error at `cos θ_o` and roughness `rough` (levels
    /// `level_roughness`): bilinear between rows as the lobe rows are, clamped to the grid.
    fn error_at(&self, cos_o: f32, rough: f32, level_roughness: &[f32]) -> f32 {
        let ne = self.elevations.len();
        let (ie, te) = prt_relight::grid_locate(&self.elevations, view_elevation(cos_o));
        let (ir, tr) = prt_relight::grid_locate(level_roughness, rough);
        let next = usize::from(level_roughness.len() > 1);
        let row =
            |r: usize| self.error[r * ne + ie] * (1.0 - te) + self.error[r * ne + ie + 1] * te;
        row(ir) * (1.0 - tr) + row(ir + next) * tr
    }

    /// `s̄_d` at `cos θ_o` (linear between rows, clamped to the ends).
    fn diffuse_fresnel_at(&self, cos_o: f32) -> f32 {
        let (i, t) = prt_relight::grid_locate(&self.elevations, view_elevation(cos_o));
        let v = &self.diffuse_fresnel;
        // The last row itself beyond it (not `a + (b − a)`, which may round off `b`).
        if t == 1.0 {
            v[i + 1]
        } else {
            v[i] + t * (v[i + 1] - v[i])
        }
    }
}

/// The view elevation `θ_o` of `cos θ_o`, capped at the horizon (points facing away read the
/// tables' last row).
fn view_elevation(cos_o: f32) -> f32 {
    cos_o
        .clamp(-1.0, 1.0)
        .acos()
        .min(std::f32::consts::FRAC_PI_2)
}
