//! The `prt` pipeline end to end, on top of the stage crates: relighting a scene from its bake
//! into an image comparable with the path tracer's ([`relit`], [`imaging`]), and the
//! speed-against-error report that answers "how much accuracy does the faster method give away,
//! and how much time does it save?" ([`report`]), with its error budget ([`budget`]: each
//! approximation's cost measured by a controlled experiment), adaptive relighting to a PSNR
//! target ([`target`]) and the per-object choice of what a scene needs ([`recommend`], behind
//! `prt bake --target-psnr`), and its page: an interactive, self-contained HDR viewer with
//! charts ([`viewer`]).
//!
//! The relighting follows Sloan, Kautz & Snyder 2002 (diffuse PRT) and Lee & Kim 2014 (specular
//! PRT through SH products and locally adaptive SH), as implemented by `prt-relight`, and, for
//! Blinn–Phong, Ward and Cook–Torrance, Kautz, Sloan & Snyder 2002 (per-view-elevation BRDF
//! projections, [`glossy`]); image
//! formation interpolates per-vertex radiance over the triangles hit by the scene camera's rays
//! (Gouraud), which is the approximation per-pixel bakes avoid, or reads per-texel bakes
//! bilinearly at each hit's lightmap UV.
//!
//! Beyond SH, [`reflectance`] relights sampled reflectance fields (Masselus, Peers, Dutré &
//! Willems, EGSR 2004): reconstruction of each pixel's sampled function on a fine lat-long grid
//! (zero-order hold, bilinear, LeGall 5/3 and CDF 9/7 wavelet interpolation) and non-linear
//! wavelet approximation (Haar, 5/3, 9/7; `prt-wavelet`) relit as sparse dot products.

pub mod budget;
mod error;
pub mod plots;
pub mod recommend;
pub mod reflectance;
pub mod report;
pub mod rf_reconstruct;
pub mod rf_section;
pub mod viewer;

pub use error::ReportError;
pub use report::{run_report, ObjectRays, ReferenceInfo, ReportData, ReportSettings};
