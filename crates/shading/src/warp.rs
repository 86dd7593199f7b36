//! Warps from the unit square to directions, each as a `sample_*` / `*_pdf` / `invert_*` trio.
//!
//! The cosine-weighted hemisphere uses Malley's method with the polar disc map
//! (`r = √u₀`, `φ = 2πu₁`), whose inverse is exact and cheap.

use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, TAU};

/// Cosine-weighted direction on the `+z` hemisphere (Malley's method, polar disc map).
#[must_use]
pub fn sample_cosine_hemisphere(u: [f32; 2]) -> Vec3 {
    let r = u[0].sqrt();
    let (s, c) = (TAU * u[1]).sin_cos();
    let z = (1.0 - u[0]).max(0.0).sqrt();
    Vec3::new(r * c, r * s, z)
}

/// Solid-angle pdf of [`sample_cosine_hemisphere`]: `max(cos θ, 0)/π`.
#[must_use]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Inverse of [`sample_cosine_hemisphere`]: the `u` that maps to `v` (unit, `v.z ≥ 0`).
#[must_use]
pub fn invert_cosine_hemisphere(v: Vec3) -> [f32; 2] {
    let u0 = (v.x * v.x + v.y * v.y).min(1.0);
    [u0, wrap_angle(v.y.atan2(v.x))]
}

/// Uniform direction on the unit sphere (`z = 1 − 2u₀`, `φ = 2πu₁`).
#[must_use]
pub fn sample_uniform_sphere(u: [f32; 2]) -> Vec3 {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = (TAU * u[1]).sin_cos();
    Vec3::new(r * c, r * s, z)
}

/// Solid-angle pdf of [`sample_uniform_sphere`]: `1/(4π)`.
#[must_use]
pub fn uniform_sphere_pdf() -> f32 {
    0.25 * FRAC_1_PI
}

/// Inverse of [`sample_uniform_sphere`].
#[must_use]
pub fn invert_uniform_sphere(v: Vec3) -> [f32; 2] {
    [
        ((1.0 - v.z) * 0.5).clamp(0.0, 1.0),
        wrap_angle(v.y.atan2(v.x)),
    ]
}

/// Uniform direction on the `+z` hemisphere (`z = u₀`, `φ = 2πu₁`).
#[must_use]
pub fn sample_uniform_hemisphere(u: [f32; 2]) -> Vec3 {
    let z = u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = (TAU * u[1]).sin_cos();
    Vec3::new(r * c, r * s, z)
}

/// Solid-angle pdf of [`sample_uniform_hemisphere`]: `1/(2π)`.
#[must_use]
pub fn uniform_hemisphere_pdf() -> f32 {
    0.5 * FRAC_1_PI
}

/// Inverse of [`sample_uniform_hemisphere`].
#[must_use]
pub fn invert_uniform_hemisphere(v: Vec3) -> [f32; 2] {
    [v.z.clamp(0.0, 1.0), wrap_angle(v.y.atan2(v.x))]
}

/// `atan2` result in `(−π, π]` to `[0, 1)`.
fn wrap_angle(phi: f32) -> f32 {
    let mut u = phi / TAU;
    if u < 0.0 {
        u += 1.0;
    }
    if u >= 1.0 {
        u = 0.0;
    }
    u
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn round_trip(sample: fn([f32; 2]) -> Vec3, invert: fn(Vec3) -> [f32; 2]) {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        for _ in 0..100_000 {
            let u = [rng.random::<f32>(), rng.random::<f32>()];
            let v = sample(u);
            assert!((v.length() - 1.0).abs() < 1e-5);
            let w = invert(v);
            // Compare directions rather than u (φ wraps at u₁ = 0 ≡ 1).
            assert!((sample(w) - v).length() < 2e-3, "{u:?} -> {v} -> {w:?}");
        }
    }

    #[test]
    fn warps_invert() {
        round_trip(sample_cosine_hemisphere, invert_cosine_hemisphere);
        round_trip(sample_uniform_sphere, invert_uniform_sphere);
        round_trip(sample_uniform_hemisphere, invert_uniform_hemisphere);
        // Away from the pole, u itself is recovered.
        let u = [0.3, 0.7];
        let w = invert_cosine_hemisphere(sample_cosine_hemisphere(u));
        assert!((w[0] - u[0]).abs() < 1e-5 && (w[1] - u[1]).abs() < 1e-5);
    }
}
