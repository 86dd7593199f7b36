//! `albedo/π` plus a perfect mirror of reflectance `specular` (a delta lobe).
//!
//! Sampling makes a discrete choice: the mirror direction with probability
//! `P = lum(specular) / (lum(specular) + lum(albedo))`, else a cosine-weighted diffuse
//! direction. The mirror sample has weight `specular / P`, `pdf = P` (a probability, not a
//! density) and `is_delta = true`. `eval` and `pdf` describe only the diffuse part, whose
//! density is `(1 − P) cos θ/π`.

use crate::bsdf_sample::BsdfSample;
use crate::{lambert, luminance, phong::reflect_z};
use glam::Vec3;

/// Probability of choosing the delta lobe.
#[must_use]
pub(crate) fn delta_probability(albedo: Vec3, specular: Vec3) -> f32 {
    let s = luminance(specular).max(0.0);
    let d = luminance(albedo).max(0.0);
    if s <= 0.0 {
        0.0
    } else {
        s / (s + d)
    }
}

/// Local-frame sample (`wo.z > 0`).
pub(crate) fn sample(albedo: Vec3, specular: Vec3, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
    let p = delta_probability(albedo, specular);
    if u[0] < p {
        return Some(BsdfSample {
            wi: reflect_z(wo),
            weight: specular / p,
            pdf: p,
            is_delta: true,
        });
    }
    let wi = lambert::sample([u[1], u[2]]);
    if wi.z <= 0.0 {
        return None;
    }
    let pdf = (1.0 - p) * lambert::pdf(wi);
    Some(BsdfSample {
        wi,
        weight: albedo / (1.0 - p),
        pdf,
        is_delta: false,
    })
}

/// Diffuse-part pdf of [`sample`] (local frame).
pub(crate) fn pdf(albedo: Vec3, specular: Vec3, wi: Vec3) -> f32 {
    (1.0 - delta_probability(albedo, specular)) * lambert::pdf(wi)
}
