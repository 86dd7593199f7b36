//! Shared helpers of the integration tests.
#![allow(dead_code)]

use glam::Vec3;
use prt_scene::Material;
use prt_shading::chi2::integrate;

/// Family-wise significance of every chi-square suite in this crate.
pub const ALPHA: f64 = 0.01;

/// `(sin θ, 0, cos θ)`.
pub fn dir_at(theta_deg: f32) -> Vec3 {
    let t = theta_deg.to_radians();
    Vec3::new(t.sin(), 0.0, t.cos())
}

/// `[v, v, v]`.
pub fn grey(v: f32) -> [f32; 3] {
    [v, v, v]
}

/// Phong material with grey albedo and specular.
pub fn phong(albedo: f32, specular: f32, e: f32) -> Material {
    Material::Phong {
        albedo: grey(albedo),
        specular: grey(specular),
        exponent: e,
    }
}
/// Blinn–Phong material with grey albedo and specular.
pub fn blinn(albedo: f32, specular: f32, e: f32) -> Material {
    Material::BlinnPhong {
        albedo: grey(albedo),
        specular: grey(specular),
        exponent: e,
    }
}
/// Ward material with grey albedo and specular.
pub fn ward(albedo: f32, specular: f32, a: f32) -> Material {
    Material::Ward {
        albedo: grey(albedo),
        specular: grey(specular),
        roughness: a,
    }
}
/// Cook–Torrance material (ior 1.5) with grey albedo and specular.
pub fn cook(albedo: f32, specular: f32, m: f32) -> Material {
    Material::CookTorrance {
        albedo: grey(albedo),
        specular: grey(specular),
        roughness: m,
        ior: 1.5,
    }
}

/// glTF metallic-roughness material with grey base colour, no textures.
pub fn pbr(base: f32, metallic: f32, roughness: f32) -> Material {
    Material::Pbr {
        base_color: grey(base),
        metallic,
        roughness,
        base_color_texture: None,
        metallic_roughness_texture: None,
    }
}

/// `∫_{H²} g(ω) dω` about +Z by nested adaptive Simpson in `(cos θ, φ)`.
pub fn hemisphere_integral(g: impl Fn(Vec3) -> f64, tol: f64) -> f64 {
    integrate(
        |z| {
            let s = (1.0 - z * z).max(0.0).sqrt();
            integrate(
                |p| {
                    g(Vec3::new(
                        (s * p.cos()) as f32,
                        (s * p.sin()) as f32,
                        z as f32,
                    ))
                },
                0.0,
                std::f64::consts::TAU,
                tol,
            )
        },
        0.0,
        1.0,
        tol,
    )
}

/// Directional albedo `∫ f(ω_i, ω_o) cos θ_i dω_i` (n = +Z) by quadrature, green channel.
pub fn albedo_quadrature(mat: &Material, wo: Vec3) -> f64 {
    hemisphere_integral(
        |wi| f64::from(prt_shading::eval(mat, Vec3::Z, wo, wi).y) * f64::from(wi.z),
        1e-7,
    )
}
