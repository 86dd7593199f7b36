//! Beckmann microfacet lobes: isotropic Ward (1992) and Cook–Torrance (1982).
//!
//! Both are sampled the same way: the half vector is drawn from the Beckmann distribution
//! weighted by `cos θ_h` (Walter, Marschner, Li and Torrance 2007, "Microfacet models for
//! refraction through rough surfaces", eqs. 28–29): `tan² θ_h = −α² ln(1 − u₀)`,
//! `φ_h = 2π u₁`, pdf `p(h) = D(h) cos θ_h = exp(−tan²θ_h/α²) / (π α² cos³θ_h)`, then
//! reflected: `p(ω_i) = p(h) / (4 |ω_o·h|)`. For Ward the roughness `α` of its Gaussian-like
//! lobe `exp(−tan²θ_h/α²)` plays the role of the Beckmann `m`; this is the sampler Walter
//! (2005, "Notes on the Ward BRDF") derived for the same lobe.

use crate::fresnel::fresnel_dielectric;
use crate::phong::reflect;
use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, TAU};

/// `tan² θ` of a local direction with `z > 0`.
fn tan2(h: Vec3) -> f32 {
    (h.x * h.x + h.y * h.y) / (h.z * h.z)
}

/// Beckmann normal distribution `D(h) = exp(−tan²θ_h/α²) / (π α² cos⁴θ_h)` (0 below the horizon).
#[must_use]
pub fn beckmann_d(h: Vec3, alpha: f32) -> f32 {
    if h.z <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let c2 = h.z * h.z;
    (-tan2(h) / a2).exp() * FRAC_1_PI / (a2 * c2 * c2)
}

/// Draws a local half vector with pdf `D(h) cos θ_h` (Walter et al. 2007).
#[must_use]
pub fn sample_beckmann_half_vector(alpha: f32, u: [f32; 2]) -> Vec3 {
    let t2 = -alpha * alpha * (-u[0]).ln_1p();
    let cos_t = 1.0 / (1.0 + t2).sqrt();
    let sin_t = (t2 / (1.0 + t2)).sqrt();
    let (s, c) = (TAU * u[1]).sin_cos();
    Vec3::new(sin_t * c, sin_t * s, cos_t)
}

/// Solid-angle pdf of the reflected direction when `h` comes from
/// [`sample_beckmann_half_vector`].
fn reflected_pdf(wo: Vec3, wi: Vec3, alpha: f32) -> f32 {
    let h = (wo + wi).normalize_or_zero();
    let oh = wo.dot(h);
    if wi.z <= 0.0 || h.z <= 0.0 || oh <= 0.0 {
        return 0.0;
    }
    beckmann_d(h, alpha) * h.z / (4.0 * oh)
}

fn sample_reflected(wo: Vec3, alpha: f32, u: [f32; 2]) -> Option<Vec3> {
    let h = sample_beckmann_half_vector(alpha, u);
    if wo.dot(h) <= 0.0 || !h.is_finite() {
        return None;
    }
    let wi = reflect(wo, h);
    (wi.z > 0.0).then_some(wi)
}

/// Isotropic Ward specular lobe `exp(−tan²θ_h/α²) / (4π α² sqrt(cos θ_i cos θ_o))`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct WardLobe {
    pub(crate) alpha: f32,
}

impl WardLobe {
    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        let h = (wo + wi).normalize_or_zero();
        if h.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        (-tan2(h) / a2).exp() * 0.25 * FRAC_1_PI / (a2 * (wi.z * wo.z).sqrt())
    }

    pub(crate) fn sample(&self, wo: Vec3, u: [f32; 2]) -> Option<Vec3> {
        sample_reflected(wo, self.alpha, u)
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        reflected_pdf(wo, wi, self.alpha)
    }
}

/// Cook–Torrance specular lobe `F(ω_i·h) D(h) G / (4 cos θ_i cos θ_o)` with Beckmann `D`,
/// the V-groove `G` and exact dielectric Fresnel `F`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CookTorranceLobe {
    pub(crate) m: f32,
    pub(crate) ior: f32,
}

impl CookTorranceLobe {
    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        let h = (wo + wi).normalize_or_zero();
        let oh = wo.dot(h);
        if h.z <= 0.0 || oh <= 0.0 {
            return 0.0;
        }
        let g = (2.0 * h.z * wo.z / oh).min(2.0 * h.z * wi.z / oh).min(1.0);
        let f = fresnel_dielectric(wi.dot(h), self.ior);
        f * beckmann_d(h, self.m) * g / (4.0 * wi.z * wo.z)
    }

    pub(crate) fn sample(&self, wo: Vec3, u: [f32; 2]) -> Option<Vec3> {
        sample_reflected(wo, self.m, u)
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        reflected_pdf(wo, wi, self.m)
    }

    /// Fresnel reflectance at `ω_o`, a cheap estimate of the lobe's albedo for lobe selection.
    pub(crate) fn albedo_hint(&self, wo: Vec3) -> f32 {
        fresnel_dielectric(wo.z, self.ior)
    }
}
