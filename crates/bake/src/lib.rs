//! Monte Carlo precomputed radiance transfer (Sloan, Kautz & Snyder, "Precomputed Radiance
//! Transfer for Real-Time Rendering in Dynamic, Low-Frequency Lighting Environments",
//! SIGGRAPH 2002), baked with the same ray tracer as the reference images.
//!
//! For every vertex of every object (or, in pixel mode, the primary hit of every pixel of the
//! scene camera; in texel mode, the surface point of every texel of each object's lightmap,
//! `prt_scene::lightmap`) the baker estimates, to an order chosen per object:
//! - **shadowed diffuse transfer** `T_i = ∫ V(ω) max(0, n·ω) y_i(ω) dω` with cosine-distributed
//!   rays from the R2 low-discrepancy sequence, Cranley–Patterson shifted per point;
//! - **visibility** `V_i = ∫ V(ω) y_i(ω) dω` for materials with a glossy lobe (relit as
//!   `(L ⊛ V)` convolved with the lobe, Lee & Kim 2014 eq. 4.3);
//! - **interreflected diffuse transfer** with `B` bounces: each bounce gathers the previous
//!   bounce's transfer at the hit points, interpolated by barycentrics, times the hit
//!   surface's albedo/π (see [`transfer`]);
//! - optionally the analytic **unshadowed** transfer (the clamped cosine rotated to `n`);
//! - the environment's exact SH projection and the BRDF projections of the materials used
//!   (`prt_shading::projection`: zonal clamped-cosine and Phong lobes; per-view-elevation tables for
//!   Blinn–Phong, Ward and Cook–Torrance, after Kautz, Sloan & Snyder 2002).
//!
//! A bake with bounces can run as sharded passes across machines ([`passes`]: each ray traced
//! once, the merged result byte-identical to one unsharded bake), and a finished bake can be
//! compressed by clustered PCA ([`compress`]: Sloan, Hall, Hart & Snyder, "Clustered Principal
//! Components for Precomputed Radiance Transfer", SIGGRAPH 2003).
//!
//! Conventions: the diffuse transfer **excludes the receiving point's own albedo/π**; the
//! outgoing diffuse radiance is `(albedo/π) Σ_i L_i T_i`. Every random number comes from a
//! stream keyed by (seed, purpose, object, point), so bakes are bit-identical for any thread
//! count and for sharded-then-merged bakes. Only what the scene needs is baked, and every
//! such decision is written to the bake's metadata ([`plan`]).

mod assembly;
pub mod compress;
mod driver;
mod error;
mod material;
pub mod passes;
mod per_pixel;
mod per_texel;
mod per_vertex;
pub mod plan;
mod probe;
mod relit;
mod report;
mod rows;
mod settings;
mod setup;
pub mod shard_plan;
pub mod subdivide;
pub mod transfer;

pub use driver::{bake, bake_pass};
pub use error::BakeError;
pub use material::material_binding;
pub use passes::PassInput;
pub use relit::relit_diffuse;
pub use report::{BakeOutput, BakeReport, ObjectReport};
pub use settings::{BakeSettings, PointKind, DEFAULT_PIXEL_SAMPLES, MAX_PIXEL_SAMPLES};
pub use setup::memory_estimate;
