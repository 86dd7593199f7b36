//! Wavelets for all-frequency relighting from reflectance functions.
//!
//! The wavelet foundation of Masselus, Peers, Dutré and Willems, *Smooth Reconstruction and
//! Compact Representation of Reflectance Functions for Image-based Relighting*, Eurographics
//! Symposium on Rendering 2004 (text: `shared/papers/masselus-2004-reflectance-functions-
//! relighting.txt`): functions on a lat-long grid are transformed with the Haar, LeGall 5/3 or
//! CDF 9/7 wavelet, "repeating the signal on vertical boundaries … \[and\] mirror\[ing\] the
//! wavelets on horizontal boundaries" (§4), compressed by keeping their largest coefficients
//! (§5.2), and coarse samplings are refined by wavelet interpolation (§4).
//!
//! - [`forward_1d`] / [`inverse_1d`]: multi-level 1D transforms, layout `[a_L | d_L | … | d_1]`.
//! - [`Transform2d`]: multi-level 2D transforms of row-major `[y][x]` grids, exactly
//!   `pywt.wavedec2`'s decomposition, in the Mallat layout (drawn in [`Transform2d`]; bands
//!   [`BandKind`]); per-axis [`Boundary`] rules, [`Boundaries::LAT_LONG`] = periodic in
//!   azimuth (x), whole-sample symmetric at the poles (y).
//! - Non-linear approximation: [`Transform2d::rank`] ranks coefficients by their L2 cost
//!   `c_i² ‖Φ_i‖²` ([`Transform2d::basis_norms_squared`]); [`RankedCoefficients::keep`] keeps
//!   `K`, [`RankedCoefficients::count_for_error`] the fewest meeting a relative error estimated
//!   in the primal/dual bases as the paper does ([`Transform2d::primal_coefficients`]) and
//!   [`RankedCoefficients::count_for_exact_error`] the fewest meeting it exactly (the estimate
//!   fails at small errors for the biorthogonal wavelets: see [`RankedCoefficients`]);
//!   [`Transform2d::reconstruct_sparse`] inverts a sparse `(index, value)` list.
//! - [`interpolate`]: wavelet interpolation of a coarse grid to a finer one.
//! - [`relative_l2_error`] (optionally weighted by [`texel_solid_angles`]) and
//!   [`sobolev_h1_relative_error`].
//!
//! **Normalisation and boundaries.** Coefficients equal PyWavelets' (`haar`, `bior2.2`,
//! `bior4.4`) in its `periodization` mode, which [`Boundary::Periodic`] is; PyWavelets has no
//! critically sampled symmetric mode, so [`Boundary::Symmetric`] is the JPEG2000 one (its
//! coefficients equal a slice of PyWavelets' non-critically-sampled `reflect` mode).
//! `tools/wavelet_oracle.py` produces the reference data the tests compare against; the filter
//! taps are the exact ones rounded to f64 (PyWavelets' `bior4.4` taps carry only 12 digits,
//! see [`Wavelet`]). All arithmetic is f64.
//!
//! ```
//! use prt_wavelet::{relative_l2_error, Transform2d, Wavelet};
//!
//! // A smooth function on a 64×16 lat-long grid, rows = polar angle, columns = azimuth.
//! let (w, h) = (64, 16);
//! let f: Vec<f64> = (0..w * h)
//!     .map(|i| {
//!         let (x, y) = ((i % w) as f64, (i / w) as f64);
//!         let (phi, theta) = (2.0 * std::f64::consts::PI * (x + 0.5) / w as f64,
//!                             std::f64::consts::PI * (y + 0.5) / h as f64);
//!         1.0 + theta.sin() * phi.cos()
//!     })
//!     .collect();
//! let t = Transform2d::lat_long(Wavelet::Cdf97, w, h, None).unwrap(); // 4 levels
//! let c = t.forward(&f).unwrap();
//! let back = t.inverse(&c).unwrap();
//! assert!(relative_l2_error(&f, &back, w, h, None).unwrap() < 1e-14);
//!
//! // Keep the 32 most important of the 1024 coefficients (`--coefficients 32`)…
//! let ranked = t.rank(&f).unwrap();
//! let approx = t.reconstruct_sparse(&ranked.keep(32)).unwrap();
//! let error = relative_l2_error(&f, &approx, w, h, None).unwrap();
//! assert!(error < 0.05, "{error}");
//! assert!((error - ranked.relative_error(32)).abs() < 1e-12);
//! // …or the fewest that meet a 1 % relative L2 error.
//! let count = ranked.count_for_exact_error(0.01).unwrap();
//! let approx = t.reconstruct_sparse(&ranked.keep(count)).unwrap();
//! assert!(relative_l2_error(&f, &approx, w, h, None).unwrap() <= 0.01);
//! assert!(count < 1024);
//! ```

mod approx;
mod dwt1d;
mod dwt2d;
mod error;
mod interpolate;
mod metrics;
mod norms;
mod wavelet;

pub use crate::approx::RankedCoefficients;
pub use crate::dwt1d::{forward_1d, inverse_1d, max_levels_1d};
pub use crate::dwt2d::{Band, BandKind, Transform2d};
pub use crate::error::{Result, WaveletError};
pub use crate::interpolate::interpolate;
pub use crate::metrics::{
    relative_l2_error, sobolev_h1_norm2, sobolev_h1_relative_error, texel_solid_angles,
};
pub use crate::wavelet::{Boundaries, Boundary, Filter, Wavelet};
