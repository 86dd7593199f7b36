//! Reflectance fields (Masselus, Peers, Dutré & Willems, "Smooth Reconstruction and Compact
//! Representation of Reflectance Functions for Image-based Relighting", EGSR 2004): all-frequency
//! relighting of a fixed view from each pixel's sampled response to distant lights.
//!
//! - [`sample`]: `prt reflectance` — per camera pixel, the response to a distant light from each
//!   direction of a `W × H` lat-long grid (a virtual light stage, with bounces), into a bake
//!   file's `RFLD` section.
//! - [`reconstruct`]: the paper's scattered-data reconstructions as precomputed linear maps
//!   (inverse-distance weighting, biquadric and SH least squares, multilevel B-splines of Lee,
//!   Wolberg & Shin 1997).
//! - [`relight`]: each pixel's function reconstructed on a fine grid (zero-order hold,
//!   bilinear, LeGall 5/3 and CDF 9/7 wavelet interpolation, or the maps of [`reconstruct`]),
//!   integrated against the environment; non-linear wavelet approximation (Haar, 5/3, 9/7;
//!   `prt-wavelet`) relit as sparse dot products; the flicker of a turning map.

mod error;
pub mod reconstruct;
pub mod relight;
pub mod sample;

pub use error::FieldError;
use relight::Reconstruction;

/// Every reconstruction, in the order reports and tables list them.
pub const RECONSTRUCTIONS: [Reconstruction; 8] = [
    Reconstruction::Nearest,
    Reconstruction::Linear,
    Reconstruction::LeGall53,
    Reconstruction::Cdf97,
    Reconstruction::Idw,
    Reconstruction::Biquadric,
    Reconstruction::Sh25,
    Reconstruction::BSpline,
];
