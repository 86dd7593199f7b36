//! The TOML scene file (schema in the crate docs). Parsing is two steps: serde reads the file
//! into plain structs (unknown keys and wrong types are errors that point at the line), then
//! every value is checked and errors name the scene file and the key.

use crate::load::load_mesh;
use crate::mesh::object_transform;
use crate::{
    load_environment, Camera, LoadedScene, Mapping, Material, RenderSettings, Rgb, Scene,
    SceneError,
};
use glam::DVec3;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileScene {
    camera: FileCamera,
    environment: FileEnvironment,
    #[serde(default)]
    materials: BTreeMap<String, FileMaterial>,
    #[serde(default)]
    objects: Vec<FileObject>,
    #[serde(default)]
    render: FileRender,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileCamera {
    eye: [f64; 3],
    target: [f64; 3],
    up: Option<[f64; 3]>,
    fov_y: f64,
    resolution: [u32; 2],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileEnvironment {
    file: PathBuf,
    #[serde(default)]
    mapping: FileMapping,
    #[serde(default)]
    rotation_y: f64,
    scale: Option<f64>,
}

#[derive(Deserialize, Default, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum FileMapping {
    #[default]
    Latlong,
    Angular,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileMaterial {
    #[serde(rename = "type")]
    kind: String,
    albedo: Option<[f64; 3]>,
    specular: Option<[f64; 3]>,
    exponent: Option<f64>,
    roughness: Option<f64>,
    ior: Option<f64>,
    base_color: Option<[f64; 3]>,
    metallic: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileObject {
    mesh: PathBuf,
    material: Option<String>,
    translate: Option<[f64; 3]>,
    rotate: Option<[f64; 3]>,
    scale: Option<toml::Value>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct FileRender {
    spp: Option<u32>,
    bounces: Option<i32>,
    seed: Option<u64>,
    normal_maps: Option<bool>,
    emission: Option<bool>,
}

/// Which parameters each material type needs (`true`) or ignores (`false`), in the order
/// albedo, specular, exponent, roughness, ior, base_color, metallic. `ior` is optional
/// (default 1.5).
const MATERIAL_TYPES: [(&str, [bool; 7]); 7] = [
    ("lambert", [true, false, false, false, false, false, false]),
    ("phong", [true, true, true, false, false, false, false]),
    (
        "blinn_phong",
        [true, true, true, false, false, false, false],
    ),
    ("ward", [true, true, false, true, false, false, false]),
    (
        "cook_torrance",
        [true, true, false, true, true, false, false],
    ),
    ("mirror", [true, true, false, false, false, false, false]),
    ("pbr", [false, false, false, true, false, true, true]),
];

/// Reads a TOML scene file, every mesh and the environment map it names, and checks them.
///
/// Relative paths in the file are relative to the file's folder. Materials are stored in
/// the order of their names (sorted), followed by the materials of glTF objects without a
/// `material` key (named `"<file>#<material>"`).
///
/// # Errors
/// [`SceneError::Io`] when the scene file cannot be read; [`SceneError::Format`] when it is not
/// valid TOML or has unknown keys or wrong types; [`SceneError::Invalid`] naming the key of a
/// bad value or missing file; [`SceneError::Referenced`] wrapping the error of a mesh or map
/// that fails to load.
pub fn load_scene(path: &Path) -> Result<LoadedScene, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|e| SceneError::io(path, e))?;
    parse_scene_str(&text, path)
}

/// [`load_scene`] on scene-file text already in memory (used by the `scene_parser` fuzz
/// target). `path` is not read: it names the scene in messages, and its folder is where
/// relative mesh and map paths are resolved (those files are read as usual).
///
/// # Errors
/// As [`load_scene`], except [`SceneError::Io`] for the scene file itself.
pub fn parse_scene_str(text: &str, path: &Path) -> Result<LoadedScene, SceneError> {
    let file: FileScene = toml::from_str(text)
        .map_err(|e| SceneError::format(path, format!("invalid scene file: {e}")))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let invalid = |key: &str, msg: String| SceneError::invalid(path, key, msg);
    let mut warnings = Vec::new();

    let c = &file.camera;
    let camera = Camera {
        eye: DVec3::from_array(c.eye),
        target: DVec3::from_array(c.target),
        up: c.up.map_or(DVec3::Y, DVec3::from_array),
        fov_y_deg: c.fov_y,
        width: c.resolution[0],
        height: c.resolution[1],
    };
    camera
        .check()
        .map_err(|(key, m)| invalid(&format!("camera.{key}"), m))?;

    let e = &file.environment;
    let env_path = existing_file(path, dir, &e.file, "environment.file")?;
    if !e.rotation_y.is_finite() {
        return Err(invalid(
            "environment.rotation_y",
            format!("{} is not finite", e.rotation_y),
        ));
    }
    let scale = e.scale.unwrap_or(1.0);
    if !(scale.is_finite() && scale >= 0.0 && scale <= f64::from(f32::MAX)) {
        return Err(invalid(
            "environment.scale",
            format!("{scale} must be finite and ≥ 0"),
        ));
    }
    let mapping = match e.mapping {
        FileMapping::Latlong => Mapping::LatLong,
        FileMapping::Angular => Mapping::Angular,
    };
    let (environment, env_warnings) =
        load_environment(&env_path, mapping, e.rotation_y, scale as f32).map_err(|err| {
            SceneError::Referenced {
                path: path.into(),
                key: "environment.file".into(),
                source: Box::new(err),
            }
        })?;
    warnings.extend(env_warnings);

    let mut scene = Scene::new(camera, environment);
    for (name, m) in &file.materials {
        let material = build_material(path, name, m, &mut warnings).map_err(|(k, msg)| {
            invalid(
                &format!("materials.{name}{}{k}", if k.is_empty() { "" } else { "." }),
                msg,
            )
        })?;
        scene.add_material(name, material);
    }

    let r = &file.render;
    scene.render = RenderSettings {
        spp: r.spp.unwrap_or(RenderSettings::default().spp),
        bounces: r.bounces.unwrap_or(RenderSettings::default().bounces),
        seed: r.seed.unwrap_or(RenderSettings::default().seed),
    };
    if scene.render.spp == 0 {
        return Err(invalid("render.spp", "must be ≥ 1".into()));
    }
    if scene.render.bounces < -1 {
        return Err(invalid(
            "render.bounces",
            format!("{} < -1 (-1 means unlimited)", scene.render.bounces),
        ));
    }

    if file.objects.is_empty() {
        warnings.push(format!("{}: the scene has no [[objects]]", path.display()));
    }
    for (i, o) in file.objects.iter().enumerate() {
        let key = |k: &str| format!("objects[{i}].{k}");
        let mesh_path = existing_file(path, dir, &o.mesh, &key("mesh"))?;
        let translate =
            finite3(o.translate.unwrap_or([0.0; 3])).map_err(|m| invalid(&key("translate"), m))?;
        let rotate =
            finite3(o.rotate.unwrap_or([0.0; 3])).map_err(|m| invalid(&key("rotate"), m))?;
        let scale = parse_scale(o.scale.as_ref()).map_err(|m| invalid(&key("scale"), m))?;
        let material = match &o.material {
            Some(name) => Some(
                scene
                    .material_names
                    .iter()
                    .position(|n| n == name)
                    .ok_or_else(|| {
                        invalid(
                            &key("material"),
                            format!(
                                "material `{name}` is not defined (defined: {})",
                                file.materials
                                    .keys()
                                    .cloned()
                                    .collect::<Vec<_>>()
                                    .join(", ")
                            ),
                        )
                    })?,
            ),
            None => None,
        };
        let to_world = object_transform(translate, rotate, scale);
        let mut loaded =
            load_mesh(&mesh_path, &to_world).map_err(|err| SceneError::Referenced {
                path: path.into(),
                key: key("mesh"),
                source: Box::new(err),
            })?;
        warnings.append(&mut loaded.warnings);
        if material.is_none() && loaded.materials.is_empty() {
            return Err(invalid(
                &key("material"),
                format!("required: `{}` defines no materials", o.mesh.display()),
            ));
        }
        // Map the file's own materials to scene indices, reusing identical ones.
        let file_to_scene = if material.is_none() {
            adopt_materials(&mut scene, &mut loaded, &o.mesh.display().to_string())
        } else {
            Vec::new()
        };
        let mut tangents = loaded.tangents;
        tangents.resize(loaded.meshes.len(), Vec::new());
        for (mesh, t) in loaded.meshes.into_iter().zip(tangents) {
            let index = material.unwrap_or_else(|| file_to_scene[mesh.material]);
            let o = scene.add_mesh(mesh, index);
            // Tangents only serve the file's own material's normal map.
            if material.is_none() && !t.is_empty() {
                scene.set_tangents(o, t);
            }
        }
    }
    switch_off_inputs(&mut scene, &file.render, path, &mut warnings);
    scene
        .validate()
        .map_err(|e| SceneError::format(path, format!("the loaded scene is invalid: {e}")))?;
    Ok(LoadedScene { scene, warnings })
}

/// `[render] normal_maps = false` / `emission = false`: the glTF materials' normal maps or
/// emission are dropped (e.g. to compare against a render with them), said in a warning.
fn switch_off_inputs(scene: &mut Scene, r: &FileRender, path: &Path, warnings: &mut Vec<String>) {
    for (off, what) in [
        (r.normal_maps == Some(false), "normal maps"),
        (r.emission == Some(false), "emission"),
    ] {
        if !off {
            continue;
        }
        for s in &mut scene.surface_inputs {
            if what == "emission" {
                s.emissive = [0.0; 3];
                s.emissive_texture = None;
            } else {
                s.normal_map = None;
            }
        }
        warnings.push(format!(
            "{}: [render] switches the glTF materials' {what} off",
            path.display()
        ));
    }
}

/// Adds a mesh file's own materials (and the textures they read, and their surface inputs)
/// to the scene, reusing an identical material already there, and returns the scene index
/// of each; `asset` is the file as the scene names it (the materials' source).
fn adopt_materials(scene: &mut Scene, loaded: &mut crate::LoadedMeshes, asset: &str) -> Vec<usize> {
    let mut file_to_scene = Vec::with_capacity(loaded.materials.len());
    // The file's textures join the scene's (an identical one, e.g. from a second
    // instance of the file, is shared); its materials' references move with them.
    let texture_to_scene: Vec<usize> = std::mem::take(&mut loaded.textures)
        .into_iter()
        .map(|t| {
            let same = |s: &crate::Texture| {
                s.name == t.name
                    && (s.width, s.height, s.wrap) == (t.width, t.height, t.wrap)
                    && s.texels == t.texels
            };
            scene.textures.iter().position(same).unwrap_or_else(|| {
                scene.textures.push(t);
                scene.textures.len() - 1
            })
        })
        .collect();
    let indices = std::mem::take(&mut loaded.material_indices);
    let mut inputs = std::mem::take(&mut loaded.surface_inputs);
    inputs.resize(loaded.materials.len(), crate::SurfaceInputs::default());
    for (k, ((name, mut m), mut input)) in std::mem::take(&mut loaded.materials)
        .into_iter()
        .zip(inputs)
        .enumerate()
    {
        let mut refs = vec![
            input.normal_map.as_mut().map(|n| &mut n.texture),
            input.emissive_texture.as_mut(),
        ];
        if let crate::AlphaMode::Mask { texture, .. } = &mut input.alpha {
            refs.push(texture.as_mut());
        }
        for t in refs.into_iter().flatten() {
            t.index = texture_to_scene[t.index];
        }
        if let Material::Pbr {
            base_color_texture,
            metallic_roughness_texture,
            ..
        } = &mut m
        {
            for t in [base_color_texture, metallic_roughness_texture]
                .into_iter()
                .flatten()
            {
                t.index = texture_to_scene[t.index];
            }
        }
        let found = (0..scene.materials.len()).position(|i| {
            scene.material_names[i] == name
                && scene.materials[i] == m
                && scene.surface_inputs(i) == input
        });
        file_to_scene.push(found.unwrap_or_else(|| {
            let index = scene.add_material(&name, m);
            scene.set_surface_inputs(index, input);
            scene.material_sources[index] =
                indices
                    .get(k)
                    .copied()
                    .flatten()
                    .map(|material| crate::MaterialSource {
                        asset: asset.to_owned(),
                        material,
                    });
            index
        }));
    }
    file_to_scene
}

/// Resolves `rel` against the scene folder and checks that it is a file.
fn existing_file(scene: &Path, dir: &Path, rel: &Path, key: &str) -> Result<PathBuf, SceneError> {
    let full = dir.join(rel);
    if full.is_file() {
        Ok(full)
    } else {
        let what = if full.exists() {
            "is not a file"
        } else {
            "does not exist"
        };
        Err(SceneError::invalid(
            scene,
            key,
            format!("`{}` {what} (looked at {})", rel.display(), full.display()),
        ))
    }
}

fn finite3(v: [f64; 3]) -> Result<DVec3, String> {
    let d = DVec3::from_array(v);
    if d.is_finite() {
        Ok(d)
    } else {
        Err(format!("{v:?} is not finite"))
    }
}

/// `scale = s` or `scale = [sx, sy, sz]`, every factor finite and non-zero.
fn parse_scale(v: Option<&toml::Value>) -> Result<DVec3, String> {
    let number = |x: &toml::Value| match x {
        toml::Value::Float(f) => Some(*f),
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    };
    let s = match v {
        None => DVec3::ONE,
        Some(toml::Value::Array(a)) if a.len() == 3 => {
            let c: Vec<f64> = a.iter().filter_map(number).collect();
            if c.len() != 3 {
                return Err("must be a number or an array of 3 numbers".into());
            }
            DVec3::new(c[0], c[1], c[2])
        }
        Some(x) => DVec3::splat(number(x).ok_or("must be a number or an array of 3 numbers")?),
    };
    if !s.is_finite() || s.x == 0.0 || s.y == 0.0 || s.z == 0.0 {
        return Err(format!("{s} must be finite and non-zero on every axis"));
    }
    Ok(s)
}

/// Builds a material from its table; errors are `(key within the table, message)`.
fn build_material(
    path: &Path,
    name: &str,
    m: &FileMaterial,
    warnings: &mut Vec<String>,
) -> Result<Material, (&'static str, String)> {
    let Some((_, needs)) = MATERIAL_TYPES.iter().find(|(t, _)| *t == m.kind) else {
        let known: Vec<&str> = MATERIAL_TYPES.iter().map(|(t, _)| *t).collect();
        return Err((
            "type",
            format!("unknown type `{}` (known: {})", m.kind, known.join(", ")),
        ));
    };
    let keys = [
        "albedo",
        "specular",
        "exponent",
        "roughness",
        "ior",
        "base_color",
        "metallic",
    ];
    let present = [
        m.albedo.is_some(),
        m.specular.is_some(),
        m.exponent.is_some(),
        m.roughness.is_some(),
        m.ior.is_some(),
        m.base_color.is_some(),
        m.metallic.is_some(),
    ];
    for k in 0..keys.len() {
        if present[k] && !needs[k] {
            warnings.push(format!(
                "{}: materials.{name}.{}: ignored by type {}",
                path.display(),
                keys[k],
                m.kind
            ));
        }
        // ior (k = 4) is optional.
        if !present[k] && needs[k] && k != 4 {
            return Err((keys[k], format!("required by type {}", m.kind)));
        }
    }
    let rgb = |v: Option<[f64; 3]>| -> Rgb { v.unwrap_or([0.0; 3]).map(|x| x as f32) };
    let (albedo, specular) = (rgb(m.albedo), rgb(m.specular));
    let exponent = m.exponent.unwrap_or(0.0) as f32;
    let roughness = m.roughness.unwrap_or(0.0) as f32;
    let ior = m.ior.unwrap_or(1.5) as f32;
    let material = match m.kind.as_str() {
        "lambert" => Material::Lambert { albedo },
        "phong" => Material::Phong {
            albedo,
            specular,
            exponent,
        },
        "blinn_phong" => Material::BlinnPhong {
            albedo,
            specular,
            exponent,
        },
        "ward" => Material::Ward {
            albedo,
            specular,
            roughness,
        },
        "cook_torrance" => Material::CookTorrance {
            albedo,
            specular,
            roughness,
            ior,
        },
        "pbr" => Material::Pbr {
            base_color: rgb(m.base_color),
            metallic: m.metallic.unwrap_or(0.0) as f32,
            roughness,
            base_color_texture: None,
            metallic_roughness_texture: None,
        },
        _ => Material::Mirror { albedo, specular },
    };
    material.check()?;
    if (0..3).any(|k| albedo[k] + specular[k] > 1.0) {
        warnings.push(format!(
            "{}: materials.{name}: albedo + specular exceeds 1 in some channel: the material \
             can reflect more light than it receives",
            path.display()
        ));
    }
    Ok(material)
}
