//! Lobe splitting: one sample from *each* lobe of a two-lobe material instead of one sample
//! from a lobe chosen at random.
//!
//! [`sample`](crate::sample) estimates `∫ f cos θ_i L dω_i` with one direction from the
//! mixture `c_d p_d + c_s p_s`: it first chooses the diffuse or the specular lobe. Where the
//! two lobes see very different light (a chrome teapot: its mirror direction sees the sky,
//! its diffuse part the floor), that choice is most of the noise. Splitting draws one
//! direction from each lobe's own density and weights each by the *sum* of the densities,
//!
//! ```text
//!   Σ_i f(ω_i) cos θ_i L(ω_i) / (p_d(ω_i) + p_s(ω_i)),   ω_d ~ p_d, ω_s ~ p_s,
//! ```
//!
//! which is Veach's multi-sample estimator with one sample per technique and the balance
//! heuristic (Veach & Guibas 1995, "Optimally combining sampling techniques for Monte Carlo
//! rendering"; Veach's thesis 1997, §9.2.2): its expectation is `Σ_i ∫ p_i f cos L / Σ_j p_j
//! = ∫ f cos L` wherever `p_d + p_s > 0`, and the diffuse lobe covers the whole hemisphere.
//! The two samples together are one BRDF technique of density `p_d + p_s`, which is what a
//! caller combines with light sampling ([`split_pdf`]). A delta lobe (the mirror of
//! `Material::Mirror`) is its own technique: its one direction has weight `specular`, and
//! nothing else generates it. Cycles' former "branched path tracing" sampled every closure
//! of the first hit the same way.
//!
//! The price is a second ray and the path behind it, so renderers split only at the first
//! vertices of a path (the tracer's `RenderSettings::split_lobes`).

use crate::bsdf::{
    eval_local, finish_sample, local_pair, parts, specular_selection_probability, Parts,
};
use crate::bsdf_sample::BsdfSample;
use crate::phong::reflect_z;
use crate::{lambert, Frame};
use glam::Vec3;
use prt_scene::Material;

/// One lobe of a two-lobe material, for [`sample_lobe`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplitLobe {
    /// The diffuse lobe `albedo/π` (the `(1 − F)` diffuse term of the glTF material),
    /// sampled by the cosine warp.
    Diffuse,
    /// The specular lobe (Phong, Blinn–Phong, Ward, Cook–Torrance, GGX) with its own sampler,
    /// or the mirror direction of `Material::Mirror` (a delta lobe).
    Specular,
}

/// Both lobes, in the order a splitting renderer follows them.
pub const SPLIT_LOBES: [SplitLobe; 2] = [SplitLobe::Diffuse, SplitLobe::Specular];

/// Whether splitting pays at `wo`: the material has two lobes that [`crate::sample`] would
/// choose between (its specular selection probability is strictly between 0 and 1). Lambert,
/// pure mirrors, pure specular lobes and metals are one lobe and are never split.
#[must_use]
pub fn splits(mat: &Material, n: Vec3, wo: Vec3) -> bool {
    let p = specular_selection_probability(mat, n, wo);
    p > 0.0 && p < 1.0
}

/// Density of the split samples' non-delta directions, `p_d + p_s` (local frame, both
/// directions above the surface).
fn split_pdf_local(p: &Parts, wo: Vec3, wi: Vec3) -> f32 {
    match p {
        Parts::Diffuse(_) | Parts::Mirror { .. } => lambert::pdf(wi),
        Parts::Glossy { lobe, .. } => lambert::pdf(wi) + lobe.pdf(wo, wi),
        Parts::Pbr(l) => lambert::pdf(wi) + l.specular_pdf(wo, wi),
    }
}

/// The density that one sample of each lobe ([`sample_lobe`] over [`SPLIT_LOBES`]) gives
/// `wi` as a BRDF technique: the sum of the non-delta lobes' own densities (the delta lobe of
/// a mirror excluded, as in [`crate::pdf`]). The weight light sampling gets against them.
/// Zero when either direction is below the surface.
#[must_use]
pub fn split_pdf(mat: &Material, n: Vec3, wo: Vec3, wi: Vec3) -> f32 {
    local_pair(n, wo, wi).map_or(0.0, |(wo, wi)| split_pdf_local(&parts(mat), wo, wi))
}

/// [`crate::eval`] and [`split_pdf`] of one pair of directions with one frame (next-event
/// estimation at a vertex that splits). `(0, 0)` when either direction is below the surface.
#[must_use]
pub fn eval_and_split_pdf(mat: &Material, n: Vec3, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
    local_pair(n, wo, wi).map_or((Vec3::ZERO, 0.0), |(wo, wi)| {
        let p = parts(mat);
        (eval_local(&p, wo, wi), split_pdf_local(&p, wo, wi))
    })
}

/// Draws `wi` from lobe `lobe` alone with two uniform numbers. The weight is
/// `f(wi, wo) cos θ_i / split_pdf` with the full BRDF and `pdf` is [`split_pdf`], so the sum of
/// the weights of one sample per lobe estimates the whole material; the mirror lobe gives the
/// mirror direction with weight `specular`, `pdf` 1 and `is_delta`. `None` when `wo` is below
/// the surface, the lobe has no sample there (a Lambert material's specular lobe, a direction
/// below the horizon) or the density is zero.
#[must_use]
pub fn sample_lobe(
    mat: &Material,
    n: Vec3,
    wo: Vec3,
    lobe: SplitLobe,
    u: [f32; 2],
) -> Option<BsdfSample> {
    let frame = Frame::from_normal(n);
    let wo_l = frame.to_local(wo);
    if wo_l.z <= 0.0 {
        return None;
    }
    let p = parts(mat);
    let wi = match (&p, lobe) {
        (_, SplitLobe::Diffuse) => lambert::sample(u),
        (Parts::Mirror { specular, .. }, SplitLobe::Specular) => {
            return Some(BsdfSample {
                wi: frame.to_world(reflect_z(wo_l)),
                weight: *specular,
                pdf: 1.0,
                is_delta: true,
            });
        }
        (Parts::Glossy { lobe, .. }, SplitLobe::Specular) => lobe.sample(wo_l, u)?,
        (Parts::Pbr(l), SplitLobe::Specular) => l.sample_specular(wo_l, u)?,
        (Parts::Diffuse(_), SplitLobe::Specular) => return None,
    };
    finish_sample(&p, &frame, wo_l, wi, split_pdf_local)
}
