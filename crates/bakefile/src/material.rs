//! Per-object material binding (format 1.2, SPEC.md §3.9.1): what the transfer of an object
//! is to be shaded with, so that the bake file alone finishes the shading.

use serde::{Deserialize, Serialize};

use crate::error::BakeFileError;

/// An RGB triple, linear Rec.709.
pub type Rgb = [f32; 3];

/// The material an object was baked for: `objects[].material` in the metadata.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MaterialBinding {
    /// The scene's material name: also the `material` of its `BRDF`/`GLSY` records.
    pub name: String,
    /// The BRDF model and its parameters (`"model"` and `"parameters"` in the JSON).
    #[serde(flatten)]
    pub model: MaterialModel,
    /// What makes the material vary over the surface (the factors then multiply it), in this
    /// order: empty for a uniform material.
    pub varies: Vec<Variation>,
    /// The glTF asset that defined the material, `None` for one of the scene file's.
    pub source: Option<MaterialSource>,
}

/// A BRDF model with its parameters (CONVENTIONS.md's formulas; SPEC.md §3.9.1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", content = "parameters", rename_all = "kebab-case")]
pub enum MaterialModel {
    /// `albedo/π`.
    Lambert(LambertParams),
    /// `albedo/π + specular (e+2)/(2π) max(0, r·ω_i)^e`.
    Phong(LobeParams),
    /// `albedo/π + specular (e+8)/(8π) max(0, n·h)^e`.
    BlinnPhong(LobeParams),
    /// Isotropic Ward.
    Ward(RoughParams),
    /// Beckmann, V-groove masking, dielectric Fresnel.
    CookTorrance(CookTorranceParams),
    /// The glTF 2.0 metallic-roughness material (its factors).
    Pbr(PbrParams),
    /// `albedo/π` plus a perfect mirror of reflectance `specular`.
    Mirror(MirrorParams),
}

/// Parameters of `lambert`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LambertParams {
    /// Diffuse reflectance.
    pub albedo: Rgb,
}

/// Parameters of `phong` and `blinn-phong`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LobeParams {
    /// Diffuse reflectance.
    pub albedo: Rgb,
    /// Specular reflectance.
    pub specular: Rgb,
    /// Exponent `e ≥ 0`.
    pub exponent: f32,
}

/// Parameters of `ward`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RoughParams {
    /// Diffuse reflectance.
    pub albedo: Rgb,
    /// Specular reflectance.
    pub specular: Rgb,
    /// Roughness `α > 0`.
    pub roughness: f32,
}

/// Parameters of `cook-torrance`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CookTorranceParams {
    /// Diffuse reflectance.
    pub albedo: Rgb,
    /// Specular reflectance.
    pub specular: Rgb,
    /// Beckmann roughness `m > 0`.
    pub roughness: f32,
    /// Index of refraction.
    pub ior: f32,
}

/// Parameters of `pbr`: the glTF factors.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PbrParams {
    /// `baseColorFactor` (RGB).
    pub base_color: Rgb,
    /// `metallicFactor`.
    pub metallic: f32,
    /// `roughnessFactor`.
    pub roughness: f32,
}

/// Parameters of `mirror`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MirrorParams {
    /// Diffuse reflectance.
    pub albedo: Rgb,
    /// Mirror reflectance.
    pub specular: Rgb,
}

/// An input that makes a material vary over the surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Variation {
    /// A `baseColorTexture`.
    BaseColorTexture,
    /// A `metallicRoughnessTexture`.
    MetallicRoughnessTexture,
    /// Vertex colours (`COLOR_0`).
    VertexColors,
}

/// The glTF asset a material came from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSource {
    /// The asset's path as the scene file names it.
    pub asset: String,
    /// Index of the material in the asset's `materials`.
    pub material: u32,
}

impl MaterialModel {
    /// The JSON name of the model (`"lambert"`, `"phong"`, ...).
    #[must_use]
    pub const fn name(&self) -> &'static str {
        match self {
            MaterialModel::Lambert(_) => "lambert",
            MaterialModel::Phong(_) => "phong",
            MaterialModel::BlinnPhong(_) => "blinn-phong",
            MaterialModel::Ward(_) => "ward",
            MaterialModel::CookTorrance(_) => "cook-torrance",
            MaterialModel::Pbr(_) => "pbr",
            MaterialModel::Mirror(_) => "mirror",
        }
    }

    /// Every parameter, for the finiteness check.
    fn numbers(&self) -> Vec<f32> {
        match *self {
            MaterialModel::Lambert(p) => p.albedo.to_vec(),
            MaterialModel::Phong(p) | MaterialModel::BlinnPhong(p) => {
                [&p.albedo[..], &p.specular, &[p.exponent]].concat()
            }
            MaterialModel::Ward(p) => [&p.albedo[..], &p.specular, &[p.roughness]].concat(),
            MaterialModel::CookTorrance(p) => {
                [&p.albedo[..], &p.specular, &[p.roughness, p.ior]].concat()
            }
            MaterialModel::Pbr(p) => [&p.base_color[..], &[p.metallic, p.roughness]].concat(),
            MaterialModel::Mirror(p) => [&p.albedo[..], &p.specular].concat(),
        }
    }
}

impl MaterialBinding {
    /// The rules of SPEC.md §3.9.1 that the JSON types do not already enforce: a non-empty
    /// name, finite parameters, distinct `varies` entries in their order, a non-empty asset.
    ///
    /// # Errors
    /// [`BakeFileError::Metadata`] naming the object and the rule.
    pub fn check(&self, object: &str) -> Result<(), BakeFileError> {
        let bad = |m: String| {
            Err(BakeFileError::Metadata(format!(
                "objects[{object:?}].material: {m}"
            )))
        };
        if self.name.is_empty() {
            return bad("the name is empty".into());
        }
        if self.model.numbers().iter().any(|x| !x.is_finite()) {
            return bad(format!("a {} parameter is not finite", self.model.name()));
        }
        if !self.varies.windows(2).all(|w| w[0] < w[1]) {
            return bad(format!(
                "`varies` must list distinct entries in the order of SPEC §3.9.1, not {:?}",
                self.varies
            ));
        }
        if self.source.as_ref().is_some_and(|s| s.asset.is_empty()) {
            return bad("source.asset is empty".into());
        }
        Ok(())
    }
}

/// One line for `prt inspect`: `material "gold": pbr {…}, varies with …, from asset.gltf #0`.
#[must_use]
pub fn material_line(m: &MaterialBinding) -> String {
    // `{"model":…,"parameters":{…}}` with each f32 in its shortest form: keep the object.
    let json = serde_json::to_string(&m.model).unwrap_or_default();
    let params = json
        .find("\"parameters\":")
        .map_or("", |i| &json[i + 13..json.len() - 1]);
    let mut line = format!("material {:?}: {} {params}", m.name, m.model.name());
    if !m.varies.is_empty() {
        let v: Vec<String> = m
            .varies
            .iter()
            .map(|v| {
                serde_json::to_value(v).map_or_else(
                    |_| String::new(),
                    |s| s.as_str().unwrap_or_default().to_owned(),
                )
            })
            .collect();
        line += &format!(", varies with {}", v.join(", "));
    }
    if let Some(s) = &m.source {
        line += &format!(", from {} material {}", s.asset, s.material);
    }
    line
}
