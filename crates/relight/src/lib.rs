//! Relighting of precomputed radiance transfer (PRT) under a distant environment given by SH
//! coefficients: full order and locally adaptive, diffuse and glossy specular (Phong, and any
//! isotropic lobe given as a per-view-elevation sum of zonal lobes, [`FittedLobe`]), on plain
//! in-memory arrays laid out as a bake stores them.
//!
//! # What is implemented, and after whom
//! - **Diffuse PRT** (Sloan, Kautz & Snyder 2002, "Precomputed radiance transfer for real-time
//!   rendering in dynamic, low-frequency lighting environments"): outgoing radiance
//!   `albedo/π ⊙ (L_c · T_c)` with the shadowed transfer `T_i = ∫ V(ω) max(0, n·ω) y_i(ω) dω`
//!   (or an interreflected one). The transfer **excludes the receiving point's own albedo/π**,
//!   applied once by [`DiffuseParams`]. With `T` the clamped cosine about `n` this is the
//!   irradiance formula of Ramamoorthi & Hanrahan 2001.
//! - **Specular PRT** (Lee & Kim 2014, "Locally Adaptive Products for Genuine Spherical
//!   Harmonic Lighting", WSCG 2014 / KAIST thesis, eq. 4.3–4.4, after Sloan et al. 2002):
//!   the incident radiance `R = L ⊛ V` is the SH product (triple-product / Gaunt tensor of Ng,
//!   Ramamoorthi & Hanrahan 2004, "Triple product wavelet integrals for all-frequency
//!   relighting") of the lighting and the per-point visibility, convolved with the zonal Phong
//!   lobe and evaluated at the reflection direction `r = 2(n·ω_o)n − ω_o`.
//! - **Glossy lobes without a zonal form** (Blinn–Phong, Ward, Cook–Torrance, the glTF
//!   metallic-roughness BRDF): after Ramamoorthi's reparameterisation of a microfacet lobe
//!   about the reflection direction (thesis, ch. 5), where it is nearly zonal, but with `K`
//!   zonal lobes about axes in the plane of the normal and the view, fitted per view elevation
//!   by least squares above the horizon (`prt_shading::projection::fitted_table`), so that grazing,
//!   horizon-clipped lobes are held too. Shading is the Phong path's `Σ w_i (L ⊛ V)_i` with
//!   `w = Σ_k A^k_l y(a_k)` ([`SpecularLobe::Fitted`]).
//! - **Locally adaptive relighting** (Lee & Kim 2014, chapter 5): bands `0..3` for every
//!   point, then band by band only while the accumulated difference from the base stays above
//!   a threshold (Algorithms 1–3, with the incremental product of Algorithm 3), ROI refinement
//!   by breadth-first search over the mesh ([`Adjacency`], 5.2.1) and boundary smoothing over
//!   two tiers (5.2.2) — [`StopRule::Significance`]. Our addition, the default
//!   ([`StopRule::Convergence`]): a point also stops once its last two levels moved it by less
//!   than the threshold, so points inside the ROI get their own order too, with the threshold
//!   of each later level raised in proportion to that level's price in products
//!   ([`AdaptiveParams::cost_exponent`]); and [`Threshold::Display`] measures every change on the 8-bit view (exposure, clamp, sRGB), as
//!   the thesis' "T = 0.02 on 8-bit normalised values" and `psnr_ldr` do. See
//!   [`Relighter::adaptive`] and the crate README for what each buys on a real bake.
//! - **Clustered PCA** (Sloan, Hall, Hart & Snyder 2003, "Clustered principal components for
//!   precomputed radiance transfer"): a block stored as per-cluster means and bases plus
//!   per-point weights is relit without reconstructing it — [`diffuse_cpca`] relights each
//!   cluster row once per frame, [`specular_cpca`] multiplies each visibility row by the
//!   lighting's product matrix once per frame (`L ⊛ V` is linear in `V`), and a point then
//!   costs `M` (diffuse) or `3(M+1)n²` (glossy) multiply-adds instead of `3n²` or `≈3n⁴`.
//!
//! # The specular approximation, precisely
//! `CONVENTIONS.md`'s Phong term gives the outgoing radiance
//! `L_s(ω_o) = ∫ L(ω) vis(ω) · specular · (e+2)/(2π) max(0, r·ω)^e · max(0, n·ω) dω`.
//! The PRT approximation (Sloan et al. 2002; Lee & Kim eq. 4.4) moves the cosine out of the
//! integral, evaluated at the lobe centre where `n·r = n·ω_o`:
//! `L_s ≈ specular · (e+2)/(e+1) · max(0, n·ω_o) · ∫ L vis · p(r·ω) dω`, with the *normalised*
//! lobe `p(t) = (e+1)/(2π) max(0, t)^e` (unit integral), whose band multipliers `A_l`
//! (`prt_sh::zonal::phong_lobe_bands`) turn the integral into `Σ_lm A_l R_lm y_lm(r)`
//! (Funk–Hecke). So the factor `(e+2)/(e+1) · max(0, n·r)` is the whole difference between the
//! two lobes. It is exact for the integrand with the cosine frozen; against the true integrand
//! it overestimates a uniform environment seen along the normal by exactly `(e+2)/(e+1)`
//! (true 1, approximation `(e+2)/(e+1)`), and errs more at grazing views, where the lobe is
//! clipped by the horizon (measured in `tests/specular.rs` and the README). Points facing away
//! (`n·ω_o ≤ 0`) are 0, as the BRDF is. Bands beyond the order are dropped from `L ⊛ V` and
//! from the lobe.
//!
//! # Layout and determinism
//! The diffuse kernel reads the light interleaved by coefficient (`[L_r, L_g, L_b, 0]`), so a
//! band is one 4-lane multiply–add per coefficient for all three channels. The specular kernel
//! keeps each band's rows of `L̂` by column (rows zero-padded to a multiple of 4 lanes), so a
//! level is two sums of columns scaled by `v_j` and `w_j` and one dot product — no per-row
//! reductions; bands of ≤ 16 lanes do the three colour channels in one sweep, and levels 3 and 4
//! (which every point evaluates) go together through one 16-lane sweep. It runs an AVX2 instance
//! when the CPU has AVX2 (detected at run time; with the prefetch hints, the only `unsafe` of
//! the crate) and a baseline one otherwise; both do the same element-wise multiplies and adds in
//! the same order (no FMA contraction), so they agree bit for bit (tested). Work is parallel
//! over chunks of 256 points with rayon; every point's sums are formed in a fixed order, so
//! results do not depend on the thread count or the CPU, and the adaptive path with threshold
//! 0 equals the full-order path bit for bit (both go through the same band-by-band kernels).
//! The adaptive path reads bands `0..5` from compact copies ([`TransferView::with_low_bands`]),
//! then, for the points of a block that go on, their full rows (hinted into cache a few points
//! ahead: they are scattered, and the stalls cost more than the arithmetic) and their basis
//! values band by band ([`prt_sh::BandCursor`]) only as far as each goes.
//!
//! ```
//! use prt_relight::{DiffuseParams, Lighting, Relighter, TransferView};
//! // Uniform environment of radiance 1 (L_0 = √(4π)); unoccluded transfer of a +Z normal,
//! // T_i = A_l y_i(n): the clamped cosine's band multipliers times the basis at the normal.
//! let order = 3;
//! let mut env = vec![[0.0f64; 3]; order * order];
//! env[0] = [(4.0 * std::f64::consts::PI).sqrt(); 3];
//! let lighting = Lighting::from_rgb_coefficients(&env, None).unwrap();
//! let a = prt_sh::zonal::clamped_cosine_bands(order).unwrap();
//! let y = prt_sh::Basis::new(order).unwrap().eval(glam::DVec3::Z);
//! let transfer: Vec<f32> = (0..order * order)
//!     .map(|i| (a[prt_sh::degree_and_order(i).0] * y[i]) as f32)
//!     .collect();
//! let relighter = Relighter::new(order).unwrap();
//! let frame = relighter.frame_lighting(&lighting, false).unwrap();
//! let view = TransferView::new(order, 1, &transfer).unwrap();
//! let rgb = relighter.diffuse(&view, &frame, &DiffuseParams::from_albedo([0.5; 3])).unwrap();
//! // Irradiance π, radiance albedo/π · π = albedo.
//! assert!((rgb[0][0] - 0.5).abs() < 1e-6);
//! ```

mod adaptive;
mod adjacency;
mod compressed;
mod compressed_specular;
mod error;
mod filter;
mod input;
mod kernel;
mod levels;
mod relighter;
mod roi;

pub use adaptive::{
    AdaptiveFrame, AdaptiveInput, AdaptiveParams, FrameStats, StopRule, TermStats, Threshold,
    MAX_COST_EXPONENT,
};
pub use adjacency::Adjacency;
pub use compressed::{diffuse_cpca, CpcaTransfer};
pub use compressed_specular::specular_cpca;
pub use error::RelightError;
pub use input::{
    low_bands, DiffuseParams, FittedLobe, Lighting, PhongParams, SpecularInput, SpecularLobe,
    Surface, TransferView, Viewer, LOW_ORDER, MAX_FITTED_LOBES,
};
pub use kernel::BASE_ORDER;
pub use relighter::{grid_locate, FrameLighting, Relighter};
