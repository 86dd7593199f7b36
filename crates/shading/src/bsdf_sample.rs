//! The result of sampling a BSDF: shared by the lobes that draw directions and by
//! [`crate::sample`], which chooses among them.

use glam::Vec3;

/// A direction drawn by [`crate::sample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Sampled incident direction (world, unit, away from the surface).
    pub wi: Vec3,
    /// `f · |cos θ_i| / pdf`, RGB (for a delta lobe: reflectance / selection probability).
    pub weight: Vec3,
    /// Solid-angle pdf of `wi`; for delta lobes the discrete selection probability.
    pub pdf: f32,
    /// True when `wi` came from a delta lobe (mirror): no other strategy can generate it.
    pub is_delta: bool,
}
