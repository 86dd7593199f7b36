//! The normalised ("modified") Phong lobe and the Blinn–Phong lobe, with their samplers.
//!
//! * Phong: `specular · (e+2)/(2π) · max(0, r·ω_i)^e`, `r` the mirror direction of `ω_o`.
//!   The factor `(e+2)/(2π)` makes the lobe's directional albedo exactly 1 at normal incidence
//!   (Lafortune and Willems 1994, "Using the modified Phong reflectance model for physically
//!   based rendering"). Sampled with pdf `(e+1)/(2π) cos^e α` about `r` (α the angle to `r`),
//!   which integrates to 1 over the sphere; samples below the horizon are rejected.
//! * Blinn–Phong: `specular · (e+8)/(8π) · max(0, n·h)^e` (Blinn 1977; the `(e+8)/(8π)` factor is
//!   the usual approximate normalisation). The half vector is sampled with pdf
//!   `(e+2)/(2π) cos^(e+1) θ_h` — the normalised `D(h) cos θ_h` of the NDF `(e+2)/(2π) cos^e θ_h` —
//!   and reflected, so `p(ω_i) = p(h) / (4 |ω_o·h|)`.

use crate::Frame;
use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, TAU};

/// Direction at angle `acos(cos_a)` from the local `+z`, azimuth `2π u`.
fn cone_direction(cos_a: f32, u: f32) -> Vec3 {
    let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
    let (s, c) = (TAU * u).sin_cos();
    Vec3::new(sin_a * c, sin_a * s, cos_a)
}

/// Mirror direction of local `wo` about the local normal `+z`.
#[must_use]
pub(crate) fn reflect_z(wo: Vec3) -> Vec3 {
    Vec3::new(-wo.x, -wo.y, wo.z)
}

/// Mirror direction of `wo` about `h`: `2(wo·h)h − wo`.
#[must_use]
pub(crate) fn reflect(wo: Vec3, h: Vec3) -> Vec3 {
    2.0 * wo.dot(h) * h - wo
}

/// The specular lobe of normalised Phong with exponent `e`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PhongLobe {
    pub(crate) e: f32,
}

impl PhongLobe {
    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        let c = reflect_z(wo).dot(wi);
        if c <= 0.0 {
            return 0.0;
        }
        (self.e + 2.0) * 0.5 * FRAC_1_PI * c.powf(self.e)
    }

    pub(crate) fn sample(&self, wo: Vec3, u: [f32; 2]) -> Option<Vec3> {
        // 1 − u₀ ∈ (0, 1] keeps the cone strictly inside the hemisphere about r.
        let cos_a = (1.0 - u[0]).powf(1.0 / (self.e + 1.0));
        let wi = Frame::from_normal(reflect_z(wo)).to_world(cone_direction(cos_a, u[1]));
        (wi.z > 0.0).then_some(wi)
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let c = reflect_z(wo).dot(wi);
        if wi.z <= 0.0 || c <= 0.0 {
            return 0.0;
        }
        (self.e + 1.0) * 0.5 * FRAC_1_PI * c.powf(self.e)
    }
}

/// The specular lobe of Blinn–Phong with exponent `e`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BlinnPhongLobe {
    pub(crate) e: f32,
}

impl BlinnPhongLobe {
    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        let h = (wo + wi).normalize_or_zero();
        if h.z <= 0.0 {
            return 0.0;
        }
        (self.e + 8.0) * 0.125 * FRAC_1_PI * h.z.powf(self.e)
    }

    pub(crate) fn sample(&self, wo: Vec3, u: [f32; 2]) -> Option<Vec3> {
        let h = cone_direction((1.0 - u[0]).powf(1.0 / (self.e + 2.0)), u[1]);
        if wo.dot(h) <= 0.0 {
            return None;
        }
        let wi = reflect(wo, h);
        (wi.z > 0.0).then_some(wi)
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let h = (wo + wi).normalize_or_zero();
        let oh = wo.dot(h);
        if wi.z <= 0.0 || h.z <= 0.0 || oh <= 0.0 {
            return 0.0;
        }
        (self.e + 2.0) * 0.5 * FRAC_1_PI * h.z.powf(self.e + 1.0) / (4.0 * oh)
    }
}
