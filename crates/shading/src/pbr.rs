//! The glTF 2.0 metallic-roughness BRDF (glTF 2.0 specification, Appendix B; CONVENTIONS.md)
//! and its sampler.
//!
//! `f = (1 − m)·[(1 − F_d)·c/π + F_d·D·V] + m·D·V·(c + (1 − c)·s)` with `α = r²`,
//! `s = (1 − |ω_o·h|)⁵`, `F_d = 0.04 + 0.96·s`, the GGX / Trowbridge–Reitz distribution
//! `D = α² / (π ((n·h)²(α² − 1) + 1)²)` and the height-correlated Smith visibility of the
//! specification, `V = 1 / (2 (|n·ω_o| √(α² + (1 − α²)(n·ω_i)²) + |n·ω_i| √(α² + (1 − α²)(n·ω_o)²)))`.
//!
//! CONVENTIONS.md writes `V` in the separable form `1 / ((|n·ω_i| + √…)(|n·ω_o| + √…))`; it also
//! says that where it and Appendix B differ the specification wins, and the specification's
//! `V` is the height-correlated one (glTF 2.0, "Specular BRDF": "the height-correlated form of
//! the Smith joint masking-shadowing function"). The two agree when either direction is the
//! normal and differ by up to 2× when both graze; the independent oracle
//! (`tools/pbr_oracle.py`) carries both, and the tests check this code against the
//! specification's.
//!
//! Sampling is a one-sample mixture of the cosine-weighted diffuse lobe and GGX
//! visible-normal sampling (Heitz 2018, "Sampling the GGX Distribution of Visible Normals",
//! JCGT 7(4)): the half vector has density `D_ωo(h) = G₁(ω_o) max(0, ω_o·h) D(h) / (n·ω_o)`
//! and the reflected direction `p(ω_i) = G₁(ω_o) D(h) / (4 n·ω_o)`, with the Smith
//! `G₁(ω) = 2 n·ω / (n·ω + √(α² + (1 − α²)(n·ω)²))`. Reflected directions below the horizon
//! are rejected, so the specular pdf integrates to `1 −` (their share).
//!
//! A roughness of 0 is a perfect mirror, which no finite density represents: `α` is kept at
//! least [`MIN_ALPHA`] (roughness 0.01), a lobe 1e-4 wide.

use crate::phong::reflect;
use crate::{lambert, luminance};
use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, TAU};

/// Smallest `α = roughness²` evaluated (roughness 0.01).
pub const MIN_ALPHA: f32 = 1e-4;

/// The metallic-roughness BRDF with resolved parameters (textures already applied).
#[derive(Clone, Copy, Debug)]
pub(crate) struct PbrLobe {
    pub(crate) base: Vec3,
    pub(crate) metallic: f32,
    pub(crate) alpha: f32,
}

/// GGX `D(h)` for a local unit half vector, written as `α² / (π (sin²θ_h + α² cos²θ_h)²)` so
/// that it keeps its precision near the peak.
#[must_use]
pub fn ggx_d(h: Vec3, alpha: f32) -> f32 {
    if h.z <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let t = (h.x * h.x + h.y * h.y) + a2 * h.z * h.z;
    a2 * FRAC_1_PI / (t * t)
}

/// `√(α² + (1 − α²) c²)`, the shared term of Smith `G₁` and `V`.
fn lambda_root(c: f32, a2: f32) -> f32 {
    (a2 + (1.0 - a2) * c * c).sqrt()
}

/// Smith `G₁(ω) = 2 cos θ / (cos θ + √(α² + (1 − α²) cos²θ))` of a local direction.
#[must_use]
pub fn ggx_g1(w: Vec3, alpha: f32) -> f32 {
    if w.z <= 0.0 {
        return 0.0;
    }
    2.0 * w.z / (w.z + lambda_root(w.z, alpha * alpha))
}

/// Draws a GGX visible normal for local `wo` (`wo.z > 0`) from two uniform numbers
/// (Heitz 2018, listing 1).
#[must_use]
pub fn sample_ggx_visible_normal(wo: Vec3, alpha: f32, u: [f32; 2]) -> Vec3 {
    // The view in the hemisphere configuration (stretched to α = 1).
    let vh = Vec3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let lensq = vh.x * vh.x + vh.y * vh.y;
    let t1 = if lensq > 0.0 {
        Vec3::new(-vh.y, vh.x, 0.0) / lensq.sqrt()
    } else {
        Vec3::X
    };
    let t2 = vh.cross(t1);
    // A point on the projected disc, warped to the visible half.
    let r = u[0].sqrt();
    let (sin_p, cos_p) = (TAU * u[1]).sin_cos();
    let p1 = r * cos_p;
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * sin_p;
    let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
    // Back to the ellipsoid configuration.
    Vec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(0.0)).normalize()
}

/// The colour-independent terms of the metallic-roughness BRDF at local directions above the
/// surface: `(D·V, s)` with `s = (1 − |ω_o·h|)⁵`. The BRDF is then, per channel,
/// `(1 − m)·0.96·c/π + A·D·V + B·s·D·V − (1 − m)·0.96·c·s/π` with `A = 0.04(1 − m) + m·c`
/// and `B = 0.96(1 − m) + m(1 − c)` — the split the bakes tabulate.
#[must_use]
pub fn pbr_terms(roughness: f32, wo: Vec3, wi: Vec3) -> (f32, f32) {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return (0.0, 0.0);
    }
    PbrLobe::new(Vec3::ONE, 0.0, roughness).dv_and_schlick(wo, wi)
}

impl PbrLobe {
    /// The lobe of resolved parameters; `roughness` is squared and kept `≥` [`MIN_ALPHA`].
    pub(crate) fn new(base: Vec3, metallic: f32, roughness: f32) -> Self {
        Self {
            base,
            metallic,
            alpha: (roughness * roughness).max(MIN_ALPHA),
        }
    }

    /// `(D·V, s)` for local directions above the surface (`D·V` is 0 when `h` is below).
    fn dv_and_schlick(&self, wo: Vec3, wi: Vec3) -> (f32, f32) {
        let h = (wo + wi).normalize_or_zero();
        let s = (1.0 - wo.dot(h).abs()).clamp(0.0, 1.0).powi(5);
        let a2 = self.alpha * self.alpha;
        let v = 0.5 / (wo.z * lambda_root(wi.z, a2) + wi.z * lambda_root(wo.z, a2));
        (ggx_d(h, self.alpha) * v, s)
    }

    /// The full BRDF, RGB (local frame, both directions above the surface).
    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let (dv, s) = self.dv_and_schlick(wo, wi);
        let m = self.metallic;
        let fd = 0.04 + 0.96 * s;
        let dielectric = lambert::eval(self.base) * (1.0 - fd) + Vec3::splat(fd * dv);
        let metal = dv * (self.base + (Vec3::ONE - self.base) * s);
        dielectric * (1.0 - m) + metal * m
    }

    /// Reflectance at normal incidence `F0 = 0.04 (1 − m) + m·c`.
    fn f0(&self) -> Vec3 {
        Vec3::splat(0.04 * (1.0 - self.metallic)) + self.base * self.metallic
    }

    /// Probability of sampling the specular lobe at `wo`: the luminance of the Schlick
    /// reflectance `F0 + (1 − F0)(1 − cos θ_o)⁵` against that of the diffuse reflectance
    /// `(1 − m)·0.96·c`, clamped to `[0.05, 0.95]` (1 when there is no diffuse term).
    pub(crate) fn specular_probability(&self, wo: Vec3) -> f32 {
        let f0 = self.f0();
        let sw = (1.0 - wo.z.clamp(0.0, 1.0)).powi(5);
        let s = luminance(f0 + (Vec3::ONE - f0) * sw).max(0.0);
        let d = luminance(self.base * ((1.0 - self.metallic) * 0.96)).max(0.0);
        if d <= 0.0 {
            1.0
        } else if s <= 0.0 {
            0.0
        } else {
            (s / (s + d)).clamp(0.05, 0.95)
        }
    }

    /// Draws `ω_i` from the visible normals (`None` below the horizon).
    pub(crate) fn sample_specular(&self, wo: Vec3, u: [f32; 2]) -> Option<Vec3> {
        let h = sample_ggx_visible_normal(wo, self.alpha, u);
        if !h.is_finite() || wo.dot(h) <= 0.0 {
            return None;
        }
        let wi = reflect(wo, h);
        (wi.z > 0.0).then_some(wi)
    }

    /// Solid-angle pdf of [`Self::sample_specular`]: `G₁(ω_o) D(h) / (4 n·ω_o)`.
    pub(crate) fn specular_pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let h = (wo + wi).normalize_or_zero();
        if wi.z <= 0.0 || wo.z <= 0.0 || h.z <= 0.0 || wo.dot(h) <= 0.0 {
            return 0.0;
        }
        ggx_g1(wo, self.alpha) * ggx_d(h, self.alpha) / (4.0 * wo.z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `∫ D(h) cos θ_h dω_h = 1` (the normalisation of any microfacet distribution), by
    /// quadrature in `tan θ_h` fine enough to resolve the narrowest lobe.
    #[test]
    fn ggx_is_normalised() {
        for alpha in [0.01f32, 0.1, 0.5, 1.0] {
            // Substitute t = tan θ, dω cos θ = 2π sinθ cosθ dθ = 2π t / (1 + t²)² dt.
            let n = 200_000;
            let t_max = 2000.0 * f64::from(alpha);
            let dt = t_max / n as f64;
            let mut sum = 0.0f64;
            for k in 0..n {
                let t = (k as f64 + 0.5) * dt;
                let c = 1.0 / (1.0 + t * t).sqrt();
                let h = Vec3::new((t * c) as f32, 0.0, c as f32);
                sum += f64::from(ggx_d(h, alpha)) * std::f64::consts::TAU * t
                    / (1.0 + t * t).powi(2)
                    * dt;
            }
            // The tail beyond t_max holds ≈ α²/t_max² = 2.5e-7 of the mass.
            assert!((sum - 1.0).abs() < 2e-4, "α = {alpha}: ∫D cos = {sum}");
        }
    }
}
