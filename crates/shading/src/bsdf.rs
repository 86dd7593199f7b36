//! Dispatch over [`Material`]: `eval`, `pdf`, `sample` and `has_delta`.
//!
//! Every function works in the local frame of the shading normal ([`Frame::from_normal`]).
//! Glossy materials are a one-sample mixture of the diffuse lobe (cosine sampling) and their
//! specular lobe; the specular lobe is chosen with probability
//! `clamp(s / (s + d), 0.05, 0.95)` where `d = lum(albedo)` and `s = lum(specular)` (times the
//! Fresnel reflectance at `ω_o` for Cook–Torrance, whose lobe is scaled by `F`); it is 0 when
//! `s = 0` and 1 when `d = 0`. The returned pdf is the mixture pdf and the weight is
//! `f(ω_i, ω_o) cos θ_i / pdf` with the full BRDF, so one sample estimates the whole material.

use crate::bsdf_sample::BsdfSample;
use crate::microfacet::{CookTorranceLobe, WardLobe};
use crate::pbr::PbrLobe;
use crate::phong::{BlinnPhongLobe, PhongLobe};
use crate::{lambert, luminance, mirror, Frame};
use glam::Vec3;
use prt_scene::Material;

/// A specular lobe of a glossy material (local frame).
#[derive(Clone, Copy, Debug)]
pub(crate) enum Lobe {
    Phong(PhongLobe),
    Blinn(BlinnPhongLobe),
    Ward(WardLobe),
    CookTorrance(CookTorranceLobe),
}

impl Lobe {
    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        match self {
            Lobe::Phong(l) => l.eval(wo, wi),
            Lobe::Blinn(l) => l.eval(wo, wi),
            Lobe::Ward(l) => l.eval(wo, wi),
            Lobe::CookTorrance(l) => l.eval(wo, wi),
        }
    }
    pub(crate) fn sample(&self, wo: Vec3, u: [f32; 2]) -> Option<Vec3> {
        match self {
            Lobe::Phong(l) => l.sample(wo, u),
            Lobe::Blinn(l) => l.sample(wo, u),
            Lobe::Ward(l) => l.sample(wo, u),
            Lobe::CookTorrance(l) => l.sample(wo, u),
        }
    }
    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match self {
            Lobe::Phong(l) => l.pdf(wo, wi),
            Lobe::Blinn(l) => l.pdf(wo, wi),
            Lobe::Ward(l) => l.pdf(wo, wi),
            Lobe::CookTorrance(l) => l.pdf(wo, wi),
        }
    }
    fn albedo_hint(&self, wo: Vec3) -> f32 {
        match self {
            Lobe::CookTorrance(l) => l.albedo_hint(wo),
            _ => 1.0,
        }
    }
}

/// A material split into what the sampler needs.
pub(crate) enum Parts {
    Diffuse(Vec3),
    Glossy {
        albedo: Vec3,
        specular: Vec3,
        lobe: Lobe,
    },
    Mirror {
        albedo: Vec3,
        specular: Vec3,
    },
    /// The glTF metallic-roughness BRDF (its own mixture rule, see [`PbrLobe`]).
    Pbr(PbrLobe),
}

pub(crate) fn parts(mat: &Material) -> Parts {
    let v = |c: &[f32; 3]| Vec3::from_array(*c);
    match mat {
        Material::Lambert { albedo } => Parts::Diffuse(v(albedo)),
        Material::Phong {
            albedo,
            specular,
            exponent,
        } => Parts::Glossy {
            albedo: v(albedo),
            specular: v(specular),
            lobe: Lobe::Phong(PhongLobe {
                e: exponent.max(0.0),
            }),
        },
        Material::BlinnPhong {
            albedo,
            specular,
            exponent,
        } => Parts::Glossy {
            albedo: v(albedo),
            specular: v(specular),
            lobe: Lobe::Blinn(BlinnPhongLobe {
                e: exponent.max(0.0),
            }),
        },
        Material::Ward {
            albedo,
            specular,
            roughness,
        } => Parts::Glossy {
            albedo: v(albedo),
            specular: v(specular),
            lobe: Lobe::Ward(WardLobe { alpha: *roughness }),
        },
        Material::CookTorrance {
            albedo,
            specular,
            roughness,
            ior,
        } => Parts::Glossy {
            albedo: v(albedo),
            specular: v(specular),
            lobe: Lobe::CookTorrance(CookTorranceLobe {
                m: *roughness,
                ior: *ior,
            }),
        },
        Material::Mirror { albedo, specular } => Parts::Mirror {
            albedo: v(albedo),
            specular: v(specular),
        },
        // Texture references are resolved by the caller (`Scene::material_at`); the factors
        // are the material here.
        Material::Pbr {
            base_color,
            metallic,
            roughness,
            ..
        } => Parts::Pbr(PbrLobe::new(v(base_color), *metallic, *roughness)),
    }
}

/// Probability of sampling the specular lobe of a glossy material (rule in the module docs).
fn specular_probability(albedo: Vec3, specular: Vec3, lobe: &Lobe, wo: Vec3) -> f32 {
    let s = luminance(specular).max(0.0) * lobe.albedo_hint(wo);
    let d = luminance(albedo).max(0.0);
    if s <= 0.0 {
        0.0
    } else if d <= 0.0 {
        1.0
    } else {
        (s / (s + d)).clamp(0.05, 0.95)
    }
}

/// Probability that [`sample`] chooses the specular (or, for mirrors, the delta) lobe at `wo`.
/// 0 for Lambert and when `wo` is below the surface.
#[must_use]
pub fn specular_selection_probability(mat: &Material, n: Vec3, wo: Vec3) -> f32 {
    let wo = Frame::from_normal(n).to_local(wo);
    if wo.z <= 0.0 {
        return 0.0;
    }
    match parts(mat) {
        Parts::Diffuse(_) => 0.0,
        Parts::Glossy {
            albedo,
            specular,
            lobe,
        } => specular_probability(albedo, specular, &lobe, wo),
        Parts::Mirror { albedo, specular } => mirror::delta_probability(albedo, specular),
        Parts::Pbr(l) => l.specular_probability(wo),
    }
}

/// BRDF value in the local frame (`wo.z > 0`, `wi.z > 0` checked by callers).
pub(crate) fn eval_local(p: &Parts, wo: Vec3, wi: Vec3) -> Vec3 {
    match p {
        Parts::Diffuse(albedo) | Parts::Mirror { albedo, .. } => lambert::eval(*albedo),
        Parts::Glossy {
            albedo,
            specular,
            lobe,
        } => lambert::eval(*albedo) + *specular * lobe.eval(wo, wi),
        Parts::Pbr(l) => l.eval(wo, wi),
    }
}

fn pdf_local(p: &Parts, wo: Vec3, wi: Vec3) -> f32 {
    match p {
        Parts::Diffuse(_) => lambert::pdf(wi),
        Parts::Glossy {
            albedo,
            specular,
            lobe,
        } => {
            let ps = specular_probability(*albedo, *specular, lobe, wo);
            let spec = if ps > 0.0 { ps * lobe.pdf(wo, wi) } else { 0.0 };
            (1.0 - ps) * lambert::pdf(wi) + spec
        }
        Parts::Mirror { albedo, specular } => mirror::pdf(*albedo, *specular, wi),
        Parts::Pbr(l) => {
            let ps = l.specular_probability(wo);
            (1.0 - ps) * lambert::pdf(wi) + ps * l.specular_pdf(wo, wi)
        }
    }
}

/// BRDF value f(wi, wo) (no cosine), RGB, per CONVENTIONS.md; delta lobes excluded (0).
/// `n` is the unit shading normal; `wi`/`wo` unit, pointing away from the surface.
/// Zero when either direction is not strictly above the surface.
#[must_use]
pub fn eval(mat: &Material, n: Vec3, wo: Vec3, wi: Vec3) -> Vec3 {
    local_pair(n, wo, wi).map_or(Vec3::ZERO, |(wo, wi)| eval_local(&parts(mat), wo, wi))
}

/// `wo` and `wi` in the local frame of the unit normal `n`, if both are strictly above the
/// surface (what `eval` and the pdfs require).
pub(crate) fn local_pair(n: Vec3, wo: Vec3, wi: Vec3) -> Option<(Vec3, Vec3)> {
    let f = Frame::from_normal(n);
    let (wo, wi) = (f.to_local(wo), f.to_local(wi));
    (wo.z > 0.0 && wi.z > 0.0).then_some((wo, wi))
}

/// [`eval`] and [`pdf`] of one pair of directions, with one frame and one look at the
/// material: what next-event estimation asks of a light sample's direction (the BRDF value,
/// and the density BRDF sampling gives it for the MIS weight). `(0, 0)` when either
/// direction is not strictly above the surface.
#[must_use]
pub fn eval_and_pdf(mat: &Material, n: Vec3, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
    local_pair(n, wo, wi).map_or((Vec3::ZERO, 0.0), |(wo, wi)| {
        let p = parts(mat);
        (eval_local(&p, wo, wi), pdf_local(&p, wo, wi))
    })
}

/// Solid-angle pdf with which [`sample`] generates `wi` (non-delta part, including
/// lobe-selection probabilities). Zero when either direction is below the surface.
#[must_use]
pub fn pdf(mat: &Material, n: Vec3, wo: Vec3, wi: Vec3) -> f32 {
    local_pair(n, wo, wi).map_or(0.0, |(wo, wi)| pdf_local(&parts(mat), wo, wi))
}

/// Importance-samples `wi` given `wo` with three uniform numbers (`u[0]` chooses the lobe,
/// `u[1..3]` the direction). `None` if `wo` is below the surface or the sample is invalid
/// (below the horizon, zero pdf).
#[must_use]
pub fn sample(mat: &Material, n: Vec3, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
    let frame = Frame::from_normal(n);
    let wo_l = frame.to_local(wo);
    if wo_l.z <= 0.0 {
        return None;
    }
    let p = parts(mat);
    let wi = match &p {
        Parts::Diffuse(_) => lambert::sample([u[1], u[2]]),
        Parts::Mirror { albedo, specular } => {
            let mut s = mirror::sample(*albedo, *specular, wo_l, u)?;
            s.wi = frame.to_world(s.wi);
            return Some(s);
        }
        Parts::Glossy {
            albedo,
            specular,
            lobe,
        } => {
            let ps = specular_probability(*albedo, *specular, lobe, wo_l);
            if u[0] < ps {
                lobe.sample(wo_l, [u[1], u[2]])?
            } else {
                lambert::sample([u[1], u[2]])
            }
        }
        Parts::Pbr(l) => {
            if u[0] < l.specular_probability(wo_l) {
                l.sample_specular(wo_l, [u[1], u[2]])?
            } else {
                lambert::sample([u[1], u[2]])
            }
        }
    };
    finish_sample(&p, &frame, wo_l, wi, pdf_local)
}

/// The sample of local direction `wi` drawn at local `wo_l` with density `pdf_of`: weight
/// and pdf from the world direction taken back to the local frame, i.e. exactly the numbers
/// `eval` and `pdf_of` give for the returned `wi`, so MIS sees a consistent pdf. `None` below
/// the horizon or at a zero density.
pub(crate) fn finish_sample(
    p: &Parts,
    frame: &Frame,
    wo_l: Vec3,
    wi: Vec3,
    pdf_of: impl Fn(&Parts, Vec3, Vec3) -> f32,
) -> Option<BsdfSample> {
    let wi_world = frame.to_world(wi);
    let wi = frame.to_local(wi_world);
    if wi.z <= 0.0 {
        return None;
    }
    let pdf = pdf_of(p, wo_l, wi);
    if !(pdf.is_finite() && pdf > 0.0) {
        return None;
    }
    Some(BsdfSample {
        wi: wi_world,
        weight: eval_local(p, wo_l, wi) * (wi.z / pdf),
        pdf,
        is_delta: false,
    })
}

/// Whether [`sample`] reads its first number `u[0]` (the lobe choice): every material but
/// Lambert, whose one lobe needs no choice. A caller may skip drawing it otherwise.
#[must_use]
pub fn chooses_lobe(mat: &Material) -> bool {
    !matches!(mat, Material::Lambert { .. })
}

/// True when the material is nothing but a delta lobe (a mirror with zero albedo): [`eval`]
/// is then zero for every pair of directions, so light sampling at such a vertex can never
/// contribute and only the sampled mirror direction carries light.
#[must_use]
pub fn is_pure_delta(mat: &Material) -> bool {
    matches!(mat, Material::Mirror { albedo, .. } if albedo.iter().all(|&a| a == 0.0))
}

/// True when the material has a delta lobe that [`eval`] and [`pdf`] cannot see
/// (a mirror with non-zero specular reflectance).
#[must_use]
pub fn has_delta(mat: &Material) -> bool {
    matches!(mat, Material::Mirror { specular, .. } if luminance(Vec3::from_array(*specular)) > 0.0)
}
