//! Image comparison for path-traced references and their PRT/SH approximations.
//!
//! The metrics follow CONVENTIONS "Colour and images":
//! - `psnr_ldr`: both images go through the 8-bit PNG view (exposure, default 0 EV; clamp to
//!   [0, 1]; sRGB curve; rounding to 8 bits), then `10 log10(255² / MSE)` over every channel
//!   of every (masked) pixel;
//! - `psnr_hdr`: linear RGB, peak = the reference's largest (masked) channel value;
//! - `rmse`, `rel_l2 = sqrt(Σ(a−b)² / Σb²)` (b the reference, the relative error of Masselus
//!   et al. 2004), `mae`, `max_abs` on linear values.
//!
//! Identical images have an infinite PSNR; JSON has no infinity, so the report writes
//! `null` (with `rmse` = 0 telling why).
//!
//! Beside every error the Monte Carlo noise of the reference can be reported
//! ([`noise_from_pair`], [`noise_from_variance`]; derivation in [`noise`]), and a
//! false-colour error image with a scale bar can be written ([`write_error_png`]).
//!
//! ```
//! use prt_compare::{compare, Image};
//! let reference = Image::new(2, 1, vec![[1.0, 1.0, 1.0], [0.5, 0.5, 0.5]]).unwrap();
//! let test = Image::new(2, 1, vec![[1.0, 1.0, 1.0], [0.25, 0.25, 0.25]]).unwrap();
//! let m = compare(&test, &reference, None).unwrap();
//! // MSE = (3 · 0.25²) / 6 = 1/32; peak 1: PSNR = 10 log10(32).
//! assert!((m.whole.psnr_hdr - 10.0 * 32f64.log10()).abs() < 1e-12);
//! ```

mod colormap;
mod error;
mod error_image;
mod font;
mod io;
mod mask;
mod metrics;
pub mod noise;
mod report;

pub use crate::colormap::{viridis, viridis_rgb8, VIRIDIS_STOPS};
pub use crate::error::{CompareError, Result};
pub use crate::error_image::{
    error_values, render_error_picture, write_error_png, write_png_atomic, ErrorChannel,
    ErrorImageOptions, ErrorMeasure, ErrorPicture,
};
pub use crate::font::format_number;
pub use crate::io::{check_same_kind, read_pair};
pub use crate::mask::Mask;
pub use crate::metrics::{compare, compare_with, psnr, CompareOptions, ErrorStats, Metrics};
pub use crate::noise::{
    noise_corrected_rmse, noise_from_pair, noise_from_variance, NoiseEstimate, NoiseMethod,
    NoiseReport,
};
pub use crate::report::{json_number, report_json, report_table};
pub use prt_image::{
    ldr_value, ldr_view, read_image, srgb_eotf, srgb_oetf, ColorChannels, Image, ImageError,
    ImageFormat, LoadedImage,
};
