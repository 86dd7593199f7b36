//! Light at a surface and where light comes from: the BRDFs of `CONVENTIONS.md` with
//! importance sampling, sampling of distant environment maps, and a chi-square harness that
//! tests any direction sampler against its pdf.
//! [`projection`] projects BRDFs into SH for bakes and relighting: zonal lobes, the
//! per-view-elevation tables of Kautz, Sloan & Snyder 2002, and the fitted zonal lobes the
//! relighter shades glossy materials with.
//!
//! # Materials
//! [`eval`], [`pdf`] and [`sample`] implement the formulas of `CONVENTIONS.md` ("Materials
//! (BRDFs)") exactly, every glossy one with the diffuse term `albedo/π`:
//!
//! | material | specular lobe | model | sampling |
//! |---|---|---|---|
//! | `Lambert` | — | `albedo/π` | cosine hemisphere (Malley) |
//! | `Phong` | `(e+2)/(2π) max(0, r·ω_i)^e` | Phong 1975, normalised as in Lafortune & Willems 1994 | `cos^e` about `r` |
//! | `BlinnPhong` | `(e+8)/(8π) (n·h)^e` | Blinn 1977 | `cos^(e+1) θ_h`, reflected |
//! | `Ward` | `exp(−tan²θ_h/α²) / (4πα² √(cos θ_i cos θ_o))` | Ward 1992 (isotropic) | Beckmann `D cos θ_h` |
//! | `CookTorrance` | `F D G / (4 cos θ_i cos θ_o)`, Beckmann `D`, V-groove `G` | Cook & Torrance 1982 | Beckmann `D cos θ_h` (Walter et al. 2007) |
//! | `Pbr` | glTF 2.0 metallic-roughness: GGX `D`, height-correlated Smith `V`, Schlick `F`, `(1 − F)` diffuse | glTF 2.0 spec, Appendix B | GGX visible normals (Heitz 2018) |
//! | `Mirror` | delta lobe of reflectance `specular` | — | discrete choice |
//!
//! Glossy materials choose a lobe with a probability from the lobes' luminance (see
//! [`bsdf`](crate::specular_selection_probability) for the rule) and return the mixture pdf.
//! [`sample_lobe`] instead draws from each lobe on its own, for estimators that take one
//! sample per lobe ("lobe splitting", weighted by [`split_pdf`], the sum of the lobes'
//! densities: Veach & Guibas 1995's balance heuristic).
//!
//! ## Where CONVENTIONS.md differs from the lecture notes
//! The lecture notes (Lensch, "BRDFs & Texturing") present the *unnormalised* Phong lobe
//! `k_s (R·V)^{k_e}` (called "not energy conserving/reciprocal" there) and Blinn–Phong
//! `k_s (H·N)^{k_e}`; Cook–Torrance as `F D G / (π (N·V)(N·I))` with the Beckmann
//! distribution written `D = exp(−tan²α/m²) / (4 m² cos⁴α)` and an approximate Fresnel term.
//! CONVENTIONS.md uses instead the energy-normalised, reciprocal Phong `(e+2)/(2π)`
//! (directional albedo exactly 1 at normal incidence for a white lobe), the usual `(e+8)/(8π)`
//! Blinn–Phong factor, and the modern microfacet normalisation: `D = exp(−tan²θ_h/m²) /
//! (π m² cos⁴θ_h)`, normalised so that `∫ D cos θ_h dω_h = 1`, the denominator
//! `4 cos θ_i cos θ_o` (Walter et al. 2007) and the exact unpolarised dielectric Fresnel
//! reflectance. The V-groove `G` keeps the lecture's form with `ω_o·h` in both denominators,
//! and Ward's lobe is the lecture's formula. Those are the formulas
//! implemented here; the tests check the normalisations against closed forms.
//!
//! # Environment maps
//! [`EnvSampler`] draws directions with probability proportional to luminance × solid angle
//! of each texel and returns exactly the pdf of the piecewise-constant map (see its docs), or,
//! for estimators that combine it with BRDF sampling by MIS, with the MIS-compensated
//! densities of Karlík et al. 2019 ([`EnvSampling`]: one table, or one per shading normal).
//!
//! # Testing samplers
//! [`chi2`] is a Pearson chi-square test of a sampler against its pdf over bins of the sphere,
//! with expected counts from adaptive quadrature of the pdf and a Šidák-corrected significance.

mod bsdf;
mod bsdf_sample;
pub mod chi2;
pub mod distribution;
mod envmap;
mod frame;
mod fresnel;
mod lambert;
mod microfacet;
mod mirror;
mod normal_tables;
mod pbr;
mod phong;
pub mod projection;
mod split;
mod warp;

pub use bsdf::{
    chooses_lobe, eval, eval_and_pdf, has_delta, is_pure_delta, pdf, sample,
    specular_selection_probability,
};
pub use bsdf_sample::BsdfSample;
pub use distribution::{Distribution1D, Distribution2D};
pub use envmap::{EnvSample, EnvSampler, EnvSampling};
pub use frame::Frame;
pub use fresnel::{fresnel_amplitudes, fresnel_dielectric};
pub use microfacet::{beckmann_d, sample_beckmann_half_vector};
pub use pbr::{ggx_d, ggx_g1, pbr_terms, sample_ggx_visible_normal, MIN_ALPHA};
pub use split::{eval_and_split_pdf, sample_lobe, split_pdf, splits, SplitLobe, SPLIT_LOBES};
pub use warp::{
    cosine_hemisphere_pdf, invert_cosine_hemisphere, invert_uniform_hemisphere,
    invert_uniform_sphere, sample_cosine_hemisphere, sample_uniform_hemisphere,
    sample_uniform_sphere, uniform_hemisphere_pdf, uniform_sphere_pdf,
};

use glam::Vec3;

/// Relative luminance of linear Rec.709 RGB: `0.2126 R + 0.7152 G + 0.0722 B`.
#[must_use]
pub fn luminance(rgb: Vec3) -> f32 {
    0.2126 * rgb.x + 0.7152 * rgb.y + 0.0722 * rgb.z
}
