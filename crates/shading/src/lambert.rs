//! The diffuse lobe `albedo/π`, shared by every material, sampled by the cosine warp.

use crate::warp::{cosine_hemisphere_pdf, sample_cosine_hemisphere};
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

/// `albedo/π` (local frame; both directions above the surface is the caller's business).
#[must_use]
pub(crate) fn eval(albedo: Vec3) -> Vec3 {
    albedo * FRAC_1_PI
}

/// Cosine-weighted local direction.
#[must_use]
pub(crate) fn sample(u: [f32; 2]) -> Vec3 {
    sample_cosine_hemisphere(u)
}

/// Solid-angle pdf of [`sample`] for a local direction.
#[must_use]
pub(crate) fn pdf(wi: Vec3) -> f32 {
    cosine_hemisphere_pdf(wi.z)
}
