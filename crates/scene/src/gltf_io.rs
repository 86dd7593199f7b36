//! glTF 2.0 (`.gltf` with external or embedded buffers, and binary `.glb`) through the `gltf`
//! crate, with the metallic-roughness materials of the file: factors, `baseColorTexture` and
//! `metallicRoughnessTexture` (PNG or JPEG, decoded by the `image` crate through `gltf`;
//! base colour from sRGB), their UV sets (`TEXCOORD_n`, float or normalised integers) and
//! `COLOR_0`.
//!
//! - Every node reachable from the default scene (the first scene when none is marked default)
//!   is visited with its world transform (parent × node, `matrix` or TRS); each of its mesh's
//!   primitives becomes one [`Mesh`]. A mesh used by several nodes is instanced as several.
//! - `TRIANGLES`, `TRIANGLE_STRIP` and `TRIANGLE_FAN` are read (strips and fans triangulated
//!   with the winding rule of the glTF specification, §3.7.2.1); `POINTS` and `LINE*` primitives
//!   are skipped with a warning.
//! - `POSITION` must be float VEC3; `NORMAL` (float VEC3) is used when present; every
//!   `TEXCOORD_n` a material reads and `COLOR_0` (float or normalised unsigned bytes/shorts,
//!   VEC3 or VEC4) are read.
//! - `KHR_texture_transform` on a texture reference is honoured (offset, rotation, scale and
//!   its `texCoord` override; [`crate::UvTransform`]).
//! - Errors: a required extension other than `KHR_texture_transform` and
//!   `KHR_materials_emissive_strength` (both honoured), sparse accessors, accessors that run
//!   past their buffer, out-of-range indices and non-finite positions.
//! - Materials: see [`map_material`] and the material inputs of [`crate::SurfaceInputs`]:
//!   `normalTexture` (with its `scale`, UV set and `KHR_texture_transform`) and the tangents
//!   it needs (`TANGENT`, transformed to world space, or MikkTSpace tangents generated on the
//!   world-space mesh when the primitive has none), `emissiveFactor`, `emissiveTexture`
//!   (sRGB) and `KHR_materials_emissive_strength`, `alphaMode MASK` with `alphaCutoff`
//!   (alpha = `baseColorFactor` A × `baseColorTexture` A; `COLOR_0`'s alpha is not read).
//!   What a material has that nothing here models — the occlusion map (the path tracer and
//!   the bakes compute occlusion), `alphaMode BLEND` (treated as opaque) — and any extension
//!   the file uses that is not one of the two above, is a warning naming the file, the
//!   material (or the extension) and the feature.

use crate::mesh::{finish_mesh, RawMesh, Repairs};
use crate::obj::file_name;
use crate::surface::mikktspace_tangents;
use crate::{
    AlphaMode, LoadedMeshes, Material, Mesh, NormalMap, SceneError, SurfaceInputs, Texture,
    TextureRef, UvTransform, Wrap,
};
use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::mesh::{Mode, Semantic};
use glam::{DMat3, DMat4, Mat4, Vec3};
use std::path::Path;

/// What of a glTF material nothing here models, each as a sentence for a warning: the
/// occlusion map and `alphaMode BLEND`.
fn unmodelled_features(m: &::gltf::Material) -> Vec<String> {
    let mut out = Vec::new();
    if m.occlusion_texture().is_some() {
        out.push(
            "occlusionTexture is ignored: the path tracer and the bakes compute occlusion themselves"
                .to_owned(),
        );
    }
    if m.alpha_mode() == ::gltf::material::AlphaMode::Blend {
        out.push(
            "alphaMode BLEND is treated as OPAQUE: the surface is opaque everywhere (alpha ignored)"
                .to_owned(),
        );
    }
    out
}

/// Extensions the loader reads (a required one outside this list is an error; a used one, a
/// warning): the texture transform and the emissive strength are honoured.
const SUPPORTED_EXTENSIONS: [&str; 2] =
    ["KHR_texture_transform", "KHR_materials_emissive_strength"];

/// A `KHR_texture_transform` given as JSON (the `gltf` crate does not parse it on a
/// `normalTexture`): `(transform, texCoord override)`.
fn parse_texture_transform(v: &::gltf::json::Value) -> (UvTransform, Option<u32>) {
    let pair = |key: &str, default: [f32; 2]| -> [f32; 2] {
        v.get(key)
            .and_then(|a| a.as_array())
            .filter(|a| a.len() == 2)
            .and_then(|a| Some([a[0].as_f64()? as f32, a[1].as_f64()? as f32]))
            .unwrap_or(default)
    };
    let t = UvTransform {
        offset: pair("offset", [0.0; 2]),
        rotation: v.get("rotation").and_then(|r| r.as_f64()).unwrap_or(0.0) as f32,
        scale: pair("scale", [1.0; 2]),
    };
    let set = v
        .get("texCoord")
        .and_then(|t| t.as_u64())
        .and_then(|t| u32::try_from(t).ok());
    (t, set)
}

/// Maps a glTF metallic-roughness material's factors to our older BRDFs (before `pbr`
/// existed; kept for scenes that want a Cook–Torrance stand-in). With `c` = baseColorFactor
/// (RGB; alpha and textures ignored), `m` = metallicFactor and `r` = roughnessFactor (each
/// clamped to `[0, 1]`), the rule is:
/// - `m < 0.5` and `r ≥ 0.8` (a rough dielectric, whose specular lobe is weak and wide):
///   `lambert { albedo = c }`;
/// - otherwise `cook_torrance { albedo = (1 − m)·c, specular = m·c + (1 − m)·(1, 1, 1),
///   roughness = max(r², 0.01), ior = 1.5 + 18.5·m }`: `r²` is the usual GGX α that Beckmann's
///   `m` approximates, and the index rises from 1.5 (normal-incidence reflectance 0.04) for a
///   dielectric to 20 (0.82) for a metal, since our Fresnel term is a dielectric's.
#[must_use]
pub fn map_material(base_color: [f32; 3], metallic: f32, roughness: f32) -> Material {
    let c = base_color.map(|v| {
        if v.is_finite() {
            v.clamp(0.0, 1.0)
        } else {
            0.0
        }
    });
    let m = if metallic.is_finite() {
        metallic.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let r = if roughness.is_finite() {
        roughness.clamp(0.0, 1.0)
    } else {
        1.0
    };
    if m < 0.5 && r >= 0.8 {
        return Material::Lambert { albedo: c };
    }
    Material::CookTorrance {
        albedo: c.map(|v| (1.0 - m) * v),
        specular: c.map(|v| (m * v + (1.0 - m)).clamp(0.0, 1.0)),
        roughness: (r * r).max(0.01),
        ior: 1.5 + 18.5 * m,
    }
}

/// Reads a `.gltf` or `.glb` file, transforms it by `to_world` (applied after the node
/// transforms) and cleans every primitive (see [`crate::load_mesh`]).
///
/// Material indices of the meshes refer to the returned `materials` list, named
/// `"<file>#<material name or index>"`; primitives without a material get glTF's default
/// material (white, metallic 1, roughness 1).
///
/// # Errors
/// [`SceneError::Io`] if a file cannot be read, [`SceneError::Mesh`] for everything listed in
/// the module docs and when no triangle is found.
pub fn load_gltf(path: &Path, to_world: &DMat4) -> Result<LoadedMeshes, SceneError> {
    let bytes = std::fs::read(path).map_err(|e| SceneError::io(path, e))?;
    if bytes.is_empty() {
        return Err(SceneError::mesh(path, "the file is empty (0 bytes)"));
    }
    let unchecked = ::gltf::Gltf::from_slice_without_validation(&bytes)
        .map_err(|e| SceneError::mesh(path, format!("not a readable glTF 2.0 file: {e}")))?;
    let unsupported: Vec<&str> = unchecked
        .extensions_required()
        .filter(|e| !SUPPORTED_EXTENSIONS.contains(e))
        .collect();
    if !unsupported.is_empty() {
        return Err(SceneError::mesh(
            path,
            format!(
                "requires unsupported extension(s) {}; decode or convert the file first \
                 (e.g. remove Draco/meshopt compression)",
                unsupported.join(", ")
            ),
        ));
    }
    drop(unchecked);
    let gltf = ::gltf::Gltf::from_slice(&bytes)
        .map_err(|e| SceneError::mesh(path, format!("invalid glTF 2.0 file: {e}")))?;
    let buffers = ::gltf::import_buffers(&gltf.document, path.parent(), gltf.blob.clone())
        .map_err(|e| {
            // The gltf crate's I/O errors do not say which file: name the external ones.
            let external: Vec<String> = gltf
                .buffers()
                .filter_map(|b| match b.source() {
                    ::gltf::buffer::Source::Uri(u) if !u.starts_with("data:") => {
                        Some(format!("`{u}`"))
                    }
                    _ => None,
                })
                .collect();
            let files = if external.is_empty() {
                String::new()
            } else {
                format!(
                    " (buffer files {} in {})",
                    external.join(", "),
                    path.parent().unwrap_or(Path::new(".")).display()
                )
            };
            SceneError::mesh(path, format!("cannot load buffers: {e}{files}"))
        })?;
    let scene = gltf
        .default_scene()
        .or_else(|| gltf.scenes().next())
        .ok_or_else(|| SceneError::mesh(path, "the file has no scene"))?;

    let mut out = Loader {
        path,
        file: file_name(path),
        buffers: &buffers,
        meshes: Vec::new(),
        materials: Vec::new(),
        inputs: Vec::new(),
        repairs: Repairs::default(),
        warnings: gltf
            .extensions_used()
            .filter(|e| !SUPPORTED_EXTENSIONS.contains(e))
            .map(|e| {
                format!(
                    "{}: extension {e} is used by the file but not modelled (ignored)",
                    path.display()
                )
            })
            .collect(),
        textures: Vec::new(),
        texture_keys: Vec::new(),
    };
    let mut stack: Vec<(::gltf::Node, DMat4, usize)> =
        scene.nodes().map(|n| (n, *to_world, 0)).collect();
    let node_count = gltf.nodes().len();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > node_count {
            return Err(SceneError::mesh(path, "the node hierarchy has a cycle"));
        }
        let local = Mat4::from_cols_array_2d(&node.transform().matrix()).as_dmat4();
        let world = parent * local;
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                out.primitive(&node, &mesh, &prim, &world)?;
            }
        }
        stack.extend(node.children().map(|c| (c, world, depth + 1)));
    }
    if out.meshes.is_empty() {
        return Err(SceneError::mesh(
            path,
            "the default scene has no triangle primitive",
        ));
    }
    let mut warnings = out.warnings;
    warnings.extend(out.repairs.warnings(path));
    let mut order: Vec<(usize, Mesh, Vec<[f32; 4]>)> = out.meshes;
    order.sort_by_key(|(k, _, _)| *k);
    let (meshes, tangents) = order.into_iter().map(|(_, m, t)| (m, t)).unzip();
    Ok(LoadedMeshes {
        meshes,
        tangents,
        surface_inputs: out.inputs,
        material_indices: out.materials.iter().map(|(i, _, _)| *i).collect(),
        materials: out.materials.into_iter().map(|(_, n, m)| (n, m)).collect(),
        textures: out.textures,
        warnings,
    })
}

/// State while walking the node tree.
struct Loader<'a> {
    path: &'a Path,
    file: String,
    buffers: &'a [::gltf::buffer::Data],
    /// (node index × 65536 + primitive, mesh, its tangents or nothing): sorted at the end so
    /// the order is the file's.
    meshes: Vec<(usize, Mesh, Vec<[f32; 4]>)>,
    /// (glTF material index or None, name, material).
    materials: Vec<(Option<usize>, String, Material)>,
    /// Parallel to `materials`: normal map, emission, alpha mode.
    inputs: Vec<SurfaceInputs>,
    repairs: Repairs,
    warnings: Vec<String>,
    /// Decoded textures, and for each its (glTF texture index, decoded from sRGB).
    textures: Vec<Texture>,
    texture_keys: Vec<(usize, bool)>,
}

impl Loader<'_> {
    fn primitive(
        &mut self,
        node: &::gltf::Node,
        mesh: &::gltf::Mesh,
        prim: &::gltf::Primitive,
        world: &DMat4,
    ) -> Result<(), SceneError> {
        let name = format!(
            "{}#node{}{}/mesh{}/prim{}",
            self.file,
            node.index(),
            node.name().map(|n| format!("({n})")).unwrap_or_default(),
            mesh.index(),
            prim.index()
        );
        let mode = prim.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            self.warnings.push(format!(
                "{}: skipped {name}: mode {mode:?} is not triangles",
                self.path.display()
            ));
            return Ok(());
        }
        let positions_acc = prim
            .get(&Semantic::Positions)
            .ok_or_else(|| SceneError::mesh(self.path, format!("{name}: no POSITION attribute")))?;
        let positions = self.read_vec3(&positions_acc, &name, "POSITION")?;
        let mut normals = None;
        if let Some(acc) = prim.get(&Semantic::Normals) {
            match self.read_vec3(&acc, &name, "NORMAL") {
                Ok(n) if n.len() == positions.len() => normals = Some(n),
                Ok(_) => self.warnings.push(format!(
                    "{}: {name}: NORMAL count differs from POSITION count; normals computed",
                    self.path.display()
                )),
                Err(e) => self.warnings.push(format!("{e}; normals computed")),
            }
        }
        let vertex_order: Vec<u32> = match prim.indices() {
            Some(acc) => self.read_indices(&acc, &name)?,
            None => (0..positions.len() as u32).collect(),
        };
        let v = &vertex_order;
        let indices: Vec<[u32; 3]> = match mode {
            Mode::Triangles => v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            Mode::TriangleStrip => (0..v.len().saturating_sub(2))
                .map(|i| {
                    if i % 2 == 0 {
                        [v[i], v[i + 1], v[i + 2]]
                    } else {
                        [v[i + 1], v[i], v[i + 2]]
                    }
                })
                .collect(),
            _ => (1..v.len().saturating_sub(1))
                .map(|i| [v[i], v[i + 1], v[0]])
                .collect(),
        };
        let material = self.material(prim.material())?;
        // The UV sets the material reads, and the vertex colours.
        let mut sets = 0;
        let inputs = self.inputs[material];
        let mut used = vec![
            inputs.normal_map.map(|n| n.texture),
            inputs.emissive_texture,
        ];
        if let Material::Pbr {
            base_color_texture,
            metallic_roughness_texture,
            ..
        } = self.materials[material].2
        {
            used.extend([base_color_texture, metallic_roughness_texture]);
        }
        for t in used.into_iter().flatten() {
            sets = sets.max(t.texcoord + 1);
        }
        let mut texcoords = Vec::with_capacity(sets);
        for set in 0..sets {
            let what = format!("TEXCOORD_{set}");
            let acc = prim
                .get(&Semantic::TexCoords(set as u32))
                .ok_or_else(|| {
                    SceneError::mesh(
                        self.path,
                        format!(
                            "{name}: material `{}` has a texture on {what}, but the primitive has no {what}",
                            self.materials[material].1
                        ),
                    )
                })?;
            let uv = self.read_floats::<2>(&acc, &name, &what)?;
            if uv.len() != positions.len() {
                return Err(SceneError::mesh(
                    self.path,
                    format!(
                        "{name}: {what} has {} values for {} positions",
                        uv.len(),
                        positions.len()
                    ),
                ));
            }
            texcoords.push(uv);
        }
        let colors = match prim.get(&Semantic::Colors(0)) {
            None => Vec::new(),
            Some(acc) => {
                let c: Vec<[f32; 3]> = match acc.dimensions() {
                    Dimensions::Vec4 => self
                        .read_floats::<4>(&acc, &name, "COLOR_0")?
                        .into_iter()
                        .map(|c| [c[0], c[1], c[2]])
                        .collect(),
                    _ => self.read_floats::<3>(&acc, &name, "COLOR_0")?,
                };
                if c.len() != positions.len() {
                    return Err(SceneError::mesh(
                        self.path,
                        format!(
                            "{name}: COLOR_0 has {} values for {} positions",
                            c.len(),
                            positions.len()
                        ),
                    ));
                }
                c
            }
        };
        let raw = RawMesh {
            name,
            positions,
            normals,
            indices,
            texcoords,
            colors,
        };
        let (mesh, repairs) = finish_mesh(self.path, raw, world, material)?;
        self.repairs.add(repairs);
        let tangents = match inputs.normal_map {
            Some(map) => self.tangents(prim, &mesh, map, world, &mesh.name)?,
            None => Vec::new(),
        };
        self.meshes
            .push((node.index() * 65536 + prim.index(), mesh, tangents));
        Ok(())
    }

    /// World-space tangents of a normal-mapped primitive: its `TANGENT` (xyz by the linear
    /// part of `world`, renormalised; `w` negated by a mirroring transform, which keeps the
    /// bitangent `w · n × t` the image of the file's) when it has a usable one, else
    /// MikkTSpace's on the world-space mesh with the normal texture's UVs (exact for the
    /// rotations and uniform scales of ordinary node transforms; a non-uniform scale changes
    /// the Gram–Schmidt step slightly, as it would for any tool that generates after the
    /// transform). A `TANGENT` that cannot be used is a warning, and tangents are generated.
    fn tangents(
        &mut self,
        prim: &::gltf::Primitive,
        mesh: &Mesh,
        map: NormalMap,
        world: &DMat4,
        name: &str,
    ) -> Result<Vec<[f32; 4]>, SceneError> {
        if let Some(acc) = prim.get(&Semantic::Tangents) {
            let problem = match self.read_floats::<4>(&acc, name, "TANGENT") {
                Ok(t) if t.len() != mesh.positions.len() => format!(
                    "TANGENT has {} values for {} positions",
                    t.len(),
                    mesh.positions.len()
                ),
                Ok(t) if t.iter().flatten().any(|x| !x.is_finite()) => {
                    "TANGENT has non-finite values".to_owned()
                }
                Ok(t) => {
                    let linear = DMat3::from_mat4(*world);
                    let flip = if linear.determinant() < 0.0 {
                        -1.0
                    } else {
                        1.0
                    };
                    return Ok(t
                        .into_iter()
                        .map(|[x, y, z, w]| {
                            let v = (linear * glam::DVec3::new(x.into(), y.into(), z.into()))
                                .normalize_or_zero()
                                .as_vec3();
                            let w = if w < 0.0 { -flip } else { flip };
                            [v.x, v.y, v.z, w as f32]
                        })
                        .collect());
                }
                Err(e) => e.to_string(),
            };
            self.warnings.push(format!(
                "{}: {name}: {problem}; MikkTSpace tangents generated instead",
                self.path.display()
            ));
        }
        let t = map.texture;
        let uv: Vec<[f32; 2]> = mesh
            .texcoords
            .get(t.texcoord)
            .map(|set| {
                set.iter()
                    .map(|&uv| t.transform.map_or(uv, |tr| tr.apply(uv)))
                    .collect()
            })
            .unwrap_or_default();
        mikktspace_tangents(mesh, &uv).ok_or_else(|| {
            SceneError::mesh(
                self.path,
                format!("{name}: MikkTSpace could not generate tangents for the normal map"),
            )
        })
    }

    /// Index of `m` in `self.materials`, adding it (and decoding its textures) on first use.
    /// The material is the file's own metallic-roughness material: `pbr` with the factors
    /// (clamped to `[0, 1]`, non-finite ones replaced by glTF's defaults, with a warning) and
    /// the textures.
    fn material(&mut self, m: ::gltf::Material) -> Result<usize, SceneError> {
        if let Some(k) = self.materials.iter().position(|(i, _, _)| *i == m.index()) {
            return Ok(k);
        }
        let label = match (m.index(), m.name()) {
            (_, Some(n)) => n.to_owned(),
            (Some(i), None) => format!("material{i}"),
            (None, None) => "default".to_owned(),
        };
        let name = format!("{}#{label}", self.file);
        let pbr = m.pbr_metallic_roughness();
        let mut fixed = Vec::new();
        let mut unit = |v: f32, default: f32, what: &str| {
            if v.is_finite() && (0.0..=1.0).contains(&v) {
                v
            } else {
                fixed.push(format!("{what} {v}"));
                if v.is_finite() {
                    v.clamp(0.0, 1.0)
                } else {
                    default
                }
            }
        };
        let [r, g, b, _] = pbr.base_color_factor();
        let base_color = [
            unit(r, 1.0, "baseColorFactor"),
            unit(g, 1.0, "baseColorFactor"),
            unit(b, 1.0, "baseColorFactor"),
        ];
        let metallic = unit(pbr.metallic_factor(), 1.0, "metallicFactor");
        let roughness = unit(pbr.roughness_factor(), 1.0, "roughnessFactor");
        if !fixed.is_empty() {
            self.warnings.push(format!(
                "{}: material `{label}`: {} outside [0, 1] (clamped)",
                self.path.display(),
                fixed.join(", ")
            ));
        }
        let base_color_texture = match pbr.base_color_texture() {
            Some(info) => Some(self.texture_of(&info, true, &label)?),
            None => None,
        };
        let metallic_roughness_texture = match pbr.metallic_roughness_texture() {
            Some(info) => Some(self.texture_of(&info, false, &label)?),
            None => None,
        };
        let mat = Material::Pbr {
            base_color,
            metallic,
            roughness,
            base_color_texture,
            metallic_roughness_texture,
        };
        let inputs = self.surface_inputs(&m, base_color_texture, &label)?;
        for feature in unmodelled_features(&m) {
            self.warnings.push(format!(
                "{}: material `{label}`: {feature}",
                self.path.display()
            ));
        }
        self.materials.push((m.index(), name, mat));
        self.inputs.push(inputs);
        Ok(self.materials.len() - 1)
    }

    /// A material's normal map, emission and alpha mode (see [`SurfaceInputs`]); factors
    /// that are not finite or negative are warned about and replaced (glTF's defaults).
    fn surface_inputs(
        &mut self,
        m: &::gltf::Material,
        base_color_texture: Option<TextureRef>,
        label: &str,
    ) -> Result<SurfaceInputs, SceneError> {
        let mut fixed = Vec::new();
        let normal_map = match m.normal_texture() {
            None => None,
            Some(n) => {
                let (transform, set) = n
                    .extension_value("KHR_texture_transform")
                    .map(parse_texture_transform)
                    .map_or((None, None), |(t, s)| (Some(t), s));
                let mut texture =
                    self.texture(&n.texture(), set.unwrap_or(n.tex_coord()), false, label)?;
                texture.transform = transform;
                let mut scale = n.scale();
                if !scale.is_finite() {
                    fixed.push(format!("normalTexture.scale {scale} (1 used)"));
                    scale = 1.0;
                }
                Some(NormalMap { texture, scale })
            }
        };
        let mut strength = m.emissive_strength().unwrap_or(1.0);
        if !(strength.is_finite() && strength >= 0.0) {
            fixed.push(format!("emissiveStrength {strength} (1 used)"));
            strength = 1.0;
        }
        let emissive = m.emissive_factor().map(|e| {
            if (0.0..=1.0).contains(&e) {
                e * strength
            } else {
                fixed.push(format!("emissiveFactor {e} outside [0, 1] (clamped)"));
                if e.is_finite() {
                    e.clamp(0.0, 1.0) * strength
                } else {
                    0.0
                }
            }
        });
        let emissive_texture = match m.emissive_texture() {
            Some(info) if emissive.iter().any(|&e| e > 0.0) => {
                Some(self.texture_of(&info, true, label)?)
            }
            _ => None,
        };
        let alpha = match m.alpha_mode() {
            ::gltf::material::AlphaMode::Mask => {
                let mut cutoff = m.alpha_cutoff().unwrap_or(0.5);
                if !(cutoff.is_finite() && cutoff >= 0.0) {
                    fixed.push(format!("alphaCutoff {cutoff} (0.5 used)"));
                    cutoff = 0.5;
                }
                let factor = m.pbr_metallic_roughness().base_color_factor()[3];
                AlphaMode::Mask {
                    cutoff,
                    factor: if factor.is_finite() {
                        factor.clamp(0.0, 1.0)
                    } else {
                        1.0
                    },
                    texture: base_color_texture,
                }
            }
            _ => AlphaMode::Opaque,
        };
        if !fixed.is_empty() {
            self.warnings.push(format!(
                "{}: material `{label}`: {}",
                self.path.display(),
                fixed.join(", ")
            ));
        }
        Ok(SurfaceInputs {
            normal_map,
            emissive,
            emissive_texture,
            alpha,
            occlusion_map: m.occlusion_texture().is_some(),
            blend: m.alpha_mode() == ::gltf::material::AlphaMode::Blend,
        })
    }

    /// The texture a `textureInfo` refers to, with its `KHR_texture_transform` (whose
    /// `texCoord`, when given, overrides the info's).
    fn texture_of(
        &mut self,
        info: &::gltf::texture::Info,
        srgb: bool,
        material: &str,
    ) -> Result<TextureRef, SceneError> {
        let transform = info.texture_transform();
        let set = transform
            .as_ref()
            .and_then(|t| t.tex_coord())
            .unwrap_or(info.tex_coord());
        let mut t = self.texture(&info.texture(), set, srgb, material)?;
        t.transform = transform.map(|t| UvTransform {
            offset: t.offset(),
            rotation: t.rotation(),
            scale: t.scale(),
        });
        Ok(t)
    }

    /// The decoded texture `t` (sRGB-decoded when `srgb`), decoding it on first use.
    fn texture(
        &mut self,
        t: &::gltf::Texture,
        texcoord: u32,
        srgb: bool,
        material: &str,
    ) -> Result<TextureRef, SceneError> {
        let key = (t.index(), srgb);
        let texcoord = texcoord as usize;
        if let Some(index) = self.texture_keys.iter().position(|k| *k == key) {
            return Ok(TextureRef {
                index,
                texcoord,
                transform: None,
            });
        }
        let image = t.source();
        let image_name = match (image.name(), image.source()) {
            (_, ::gltf::image::Source::Uri { uri, .. }) if !uri.starts_with("data:") => {
                format!("`{uri}`")
            }
            (Some(n), _) => format!("image `{n}` ({})", image.index()),
            (None, _) => format!("image {}", image.index()),
        };
        let err = |msg: String| {
            SceneError::mesh(
                self.path,
                format!(
                    "material `{material}`: texture {} ({image_name}): {msg}",
                    t.index()
                ),
            )
        };
        if let ::gltf::image::Source::View { view, .. } = image.source() {
            let data = self.buffers.get(view.buffer().index());
            let end = view.offset().checked_add(view.length());
            if data.zip(end).is_none_or(|(d, e)| e > d.len()) {
                return Err(err("its buffer view runs past the end of its buffer".into()));
            }
        }
        let data =
            ::gltf::image::Data::from_source(image.source(), self.path.parent(), self.buffers)
                .map_err(|e| err(format!("cannot read or decode the image: {e}")))?;
        let (width, height) = (data.width as usize, data.height as usize);
        let texels = decode_texels(&data, srgb).ok_or_else(|| {
            err(format!(
                "{width}×{height} image with an unexpected pixel layout"
            ))
        })?;
        if width == 0 || height == 0 || texels.len() != width * height {
            return Err(err(format!("{width}×{height} image has no texels")));
        }
        let sampler = t.sampler();
        let wrap = |w: ::gltf::texture::WrappingMode| match w {
            ::gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
            ::gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
            ::gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
        };
        self.textures.push(Texture {
            name: format!("{}#{image_name}", self.file),
            width,
            height,
            texels,
            wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
        });
        self.texture_keys.push(key);
        Ok(TextureRef {
            index: self.textures.len() - 1,
            texcoord,
            transform: None,
        })
    }

    /// Reads a float VECn accessor, or a normalised unsigned byte/short one (values / 255 or
    /// / 65535, as glTF defines them).
    fn read_floats<const N: usize>(
        &self,
        acc: &::gltf::Accessor,
        name: &str,
        what: &str,
    ) -> Result<Vec<[f32; N]>, SceneError> {
        let label = format!("{name} {what}");
        let dims = match acc.dimensions() {
            Dimensions::Vec2 => 2,
            Dimensions::Vec3 => 3,
            Dimensions::Vec4 => 4,
            _ => 0,
        };
        let size = match acc.data_type() {
            DataType::F32 => 4,
            DataType::U16 if acc.normalized() => 2,
            DataType::U8 if acc.normalized() => 1,
            _ => 0,
        };
        if dims != N || size == 0 {
            return Err(SceneError::mesh(
                self.path,
                format!(
                    "{label}: must be VEC{N} of float or normalised unsigned byte/short, found {:?} {:?}{}",
                    acc.data_type(),
                    acc.dimensions(),
                    if acc.normalized() { " normalised" } else { "" }
                ),
            ));
        }
        let (bytes, stride, _, count) = self.accessor_bytes(acc, &label)?;
        let value = |e: &[u8], k: usize| -> f32 {
            match size {
                4 => f32::from_le_bytes([e[4 * k], e[4 * k + 1], e[4 * k + 2], e[4 * k + 3]]),
                2 => f32::from(u16::from_le_bytes([e[2 * k], e[2 * k + 1]])) / 65535.0,
                _ => f32::from(e[k]) / 255.0,
            }
        };
        Ok((0..count)
            .map(|i| {
                let e = &bytes[i * stride..i * stride + N * size];
                std::array::from_fn(|k| value(e, k))
            })
            .collect())
    }

    /// The bytes of accessor `acc`: (data from its first element, stride, element size, count).
    fn accessor_bytes(
        &self,
        acc: &::gltf::Accessor,
        what: &str,
    ) -> Result<(&[u8], usize, usize, usize), SceneError> {
        let err = |msg: String| {
            SceneError::mesh(
                self.path,
                format!("{what} (accessor {}): {msg}", acc.index()),
            )
        };
        if acc.sparse().is_some() {
            return Err(err("sparse accessors are not supported".into()));
        }
        let view = acc
            .view()
            .ok_or_else(|| err("accessor has no buffer view".into()))?;
        let data = self
            .buffers
            .get(view.buffer().index())
            .ok_or_else(|| err("buffer not loaded".into()))?;
        let elem = acc.size();
        let stride = view.stride().unwrap_or(elem);
        if stride < elem {
            return Err(err(format!(
                "byte stride {stride} is smaller than the element ({elem} bytes)"
            )));
        }
        let view_end = view.offset().checked_add(view.length());
        let view_bytes = view_end
            .and_then(|end| data.get(view.offset()..end))
            .ok_or_else(|| err("buffer view runs past the end of its buffer".into()))?;
        let count = acc.count();
        if count == 0 {
            return Ok((&[], stride, elem, 0));
        }
        let needed = (count - 1)
            .checked_mul(stride)
            .and_then(|x| x.checked_add(elem));
        let bytes = needed
            .and_then(|n| acc.offset().checked_add(n))
            .and_then(|end| view_bytes.get(acc.offset()..end))
            .ok_or_else(|| {
                err(format!(
                    "{count} elements run past the end of the buffer view"
                ))
            })?;
        Ok((bytes, stride, elem, count))
    }

    fn read_vec3(
        &self,
        acc: &::gltf::Accessor,
        name: &str,
        what: &str,
    ) -> Result<Vec<Vec3>, SceneError> {
        let label = format!("{name} {what}");
        if acc.data_type() != DataType::F32 || acc.dimensions() != Dimensions::Vec3 {
            return Err(SceneError::mesh(
                self.path,
                format!(
                    "{label}: must be float VEC3, found {:?} {:?} (quantized meshes are not supported)",
                    acc.data_type(),
                    acc.dimensions()
                ),
            ));
        }
        let (bytes, stride, _, count) = self.accessor_bytes(acc, &label)?;
        let f = |b: &[u8], k: usize| {
            f32::from_le_bytes([b[4 * k], b[4 * k + 1], b[4 * k + 2], b[4 * k + 3]])
        };
        Ok((0..count)
            .map(|i| {
                let e = &bytes[i * stride..i * stride + 12];
                Vec3::new(f(e, 0), f(e, 1), f(e, 2))
            })
            .collect())
    }

    fn read_indices(&self, acc: &::gltf::Accessor, name: &str) -> Result<Vec<u32>, SceneError> {
        let label = format!("{name} indices");
        if acc.dimensions() != Dimensions::Scalar
            || !matches!(
                acc.data_type(),
                DataType::U8 | DataType::U16 | DataType::U32
            )
        {
            return Err(SceneError::mesh(
                self.path,
                format!(
                    "{label}: must be unsigned SCALAR, found {:?} {:?}",
                    acc.data_type(),
                    acc.dimensions()
                ),
            ));
        }
        let (bytes, stride, elem, count) = self.accessor_bytes(acc, &label)?;
        Ok((0..count)
            .map(|i| {
                let e = &bytes[i * stride..i * stride + elem];
                match elem {
                    1 => u32::from(e[0]),
                    2 => u32::from(u16::from_le_bytes([e[0], e[1]])),
                    _ => u32::from_le_bytes([e[0], e[1], e[2], e[3]]),
                }
            })
            .collect())
    }
}

/// The sRGB transfer function's inverse (IEC 61966-2-1).
fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// RGBA texels of a decoded image, in `[0, 1]` (sRGB-decoded RGB when `srgb`); grey images
/// fill R, G and B. `None` if the byte count does not match the format.
fn decode_texels(data: &::gltf::image::Data, srgb: bool) -> Option<Vec<[f32; 4]>> {
    use ::gltf::image::Format;
    let (channels, bytes) = match data.format {
        Format::R8 => (1, 1),
        Format::R8G8 => (2, 1),
        Format::R8G8B8 => (3, 1),
        Format::R8G8B8A8 => (4, 1),
        Format::R16 => (1, 2),
        Format::R16G16 => (2, 2),
        Format::R16G16B16 => (3, 2),
        Format::R16G16B16A16 => (4, 2),
        Format::R32G32B32FLOAT => (3, 4),
        Format::R32G32B32A32FLOAT => (4, 4),
    };
    let texel = channels * bytes;
    let n = data.width as usize * data.height as usize;
    if data.pixels.len() != n.checked_mul(texel)? {
        return None;
    }
    // `gltf` stores 16-bit and float pixels in native byte order.
    let value = |b: &[u8]| -> f32 {
        match bytes {
            1 => f32::from(b[0]) / 255.0,
            2 => f32::from(u16::from_ne_bytes([b[0], b[1]])) / 65535.0,
            _ => f32::from_ne_bytes([b[0], b[1], b[2], b[3]]),
        }
    };
    let colour = |v: f32| if srgb { srgb_to_linear(v) } else { v };
    Some(
        data.pixels
            .chunks_exact(texel)
            .map(|p| {
                let c: Vec<f32> = p.chunks_exact(bytes).map(value).collect();
                match channels {
                    1 => [colour(c[0]), colour(c[0]), colour(c[0]), 1.0],
                    2 => [colour(c[0]), colour(c[0]), colour(c[0]), c[1]],
                    3 => [colour(c[0]), colour(c[1]), colour(c[2]), 1.0],
                    _ => [colour(c[0]), colour(c[1]), colour(c[2]), c[3]],
                }
            })
            .collect(),
    )
}
