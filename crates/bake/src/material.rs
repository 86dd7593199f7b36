//! The material binding a bake records per object (SPEC.md §3.9.1): the scene material's
//! name, model and parameters, what makes it vary, and the glTF asset that defined it.

use prt_bakefile::{
    CookTorranceParams, LambertParams, LobeParams, MaterialBinding, MaterialModel, MaterialSource,
    MirrorParams, PbrParams, RoughParams, Variation,
};
use prt_scene::{Material, Scene};

/// The binding of scene mesh `mesh`'s material.
#[must_use]
pub fn material_binding(scene: &Scene, mesh: usize) -> MaterialBinding {
    let m = &scene.meshes[mesh];
    let material = &scene.materials[m.material];
    let model = match *material {
        Material::Lambert { albedo } => MaterialModel::Lambert(LambertParams { albedo }),
        Material::Phong {
            albedo,
            specular,
            exponent,
        } => MaterialModel::Phong(LobeParams {
            albedo,
            specular,
            exponent,
        }),
        Material::BlinnPhong {
            albedo,
            specular,
            exponent,
        } => MaterialModel::BlinnPhong(LobeParams {
            albedo,
            specular,
            exponent,
        }),
        Material::Ward {
            albedo,
            specular,
            roughness,
        } => MaterialModel::Ward(RoughParams {
            albedo,
            specular,
            roughness,
        }),
        Material::CookTorrance {
            albedo,
            specular,
            roughness,
            ior,
        } => MaterialModel::CookTorrance(CookTorranceParams {
            albedo,
            specular,
            roughness,
            ior,
        }),
        Material::Pbr {
            base_color,
            metallic,
            roughness,
            ..
        } => MaterialModel::Pbr(PbrParams {
            base_color,
            metallic,
            roughness,
        }),
        Material::Mirror { albedo, specular } => {
            MaterialModel::Mirror(MirrorParams { albedo, specular })
        }
    };
    let mut varies = Vec::new();
    if let Material::Pbr {
        base_color_texture,
        metallic_roughness_texture,
        ..
    } = material
    {
        if base_color_texture.is_some() {
            varies.push(Variation::BaseColorTexture);
        }
        if metallic_roughness_texture.is_some() {
            varies.push(Variation::MetallicRoughnessTexture);
        }
        // glTF multiplies COLOR_0 into the base colour; other models do not read it.
        if !m.colors.is_empty() {
            varies.push(Variation::VertexColors);
        }
    }
    MaterialBinding {
        name: scene.material_names[m.material].clone(),
        model,
        varies,
        source: scene.material_sources[m.material]
            .as_ref()
            .map(|s| MaterialSource {
                asset: s.asset.clone(),
                material: u32::try_from(s.material).unwrap_or(u32::MAX),
            }),
    }
}
