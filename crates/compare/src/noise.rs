//! Monte Carlo noise of a path-traced reference.
//!
//! A path-traced reference `B` is the truth `T` plus zero-mean noise. Any error measured
//! against `B` contains that noise, so it is reported beside every error: a PSNR above the
//! noise's "ceiling" cannot be measured with this reference.
//!
//! # From two independent renders (`noise_from_pair`)
//! Let `A = T + e_A` and `B = T + e_B` be two renders of the same scene with the same sample
//! count and independent seeds, so that per value `e_A`, `e_B` are independent, zero-mean,
//! with the same variance `σ_i²`. Then `E[(A_i − B_i)²] = E[e_A²] + E[e_B²] − 2E[e_A]E[e_B] =
//! 2σ_i²`. Hence the expected MSE of **one** render against the truth,
//! `(1/N) Σ σ_i²`, is estimated without bias by `‖A − B‖² / (2N)`: that is
//! [`NoiseEstimate::rmse`] (its square root). The mean `(A + B)/2` has half that variance:
//! [`NoiseEstimate::rmse_of_mean`] `= rmse / √2`.
//!
//! For a test image `X` whose own error is independent of `e_B`,
//! `E[MSE(X, B)] = MSE(X, T) + (1/N) Σ σ_i²`, so `sqrt(max(0, rmse² − noise_rmse²))`
//! ([`noise_corrected_rmse`]) estimates the RMSE against the truth, and
//! `psnr_hdr_ceiling = 10 log10(peak² / noise_rmse²)` is the PSNR of a perfect `X` against
//! `B`.
//!
//! The LDR ceiling of the pair method is computed the same way on the 8-bit views
//! (`Σ(ldr(A) − ldr(B))² / (2N)`); because the view clamps and rounds it is an approximation
//! (it includes the rounding noise of the views).
//!
//! # From a variance image (`noise_from_variance`)
//! A tracer can write, per pixel and channel, the variance of its mean estimate
//! (`s²/n`, the sample variance over the pixel's `n` samples). Then `rmse = sqrt(mean(var))`.
//! The LDR ceiling uses the first-order (delta-method) propagation through the view:
//! `σ₈ ≈ 255 · 2^EV · f'(2^EV · b) · σ` with `f` the sRGB curve and `f' = 0` where the view
//! clamps; it ignores the rounding to 8 bits.

use crate::error::{CompareError, Result};
use crate::mask::Mask;
use crate::metrics::{check_pair, psnr, CompareOptions};
use prt_image::{ldr_value, Image};

/// How the noise was estimated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseMethod {
    /// From two independent renders ([`noise_from_pair`]).
    Pair,
    /// From a per-pixel variance-of-the-mean image ([`noise_from_variance`]).
    Variance,
}

impl NoiseMethod {
    /// `"pair"` or `"variance"`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            NoiseMethod::Pair => "pair",
            NoiseMethod::Variance => "variance",
        }
    }
}

/// The noise of a reference over one set of pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseEstimate {
    /// Number of pixels in the set.
    pub pixels: usize,
    /// Estimated RMSE of the reference (one render) against the truth, linear.
    pub rmse: f64,
    /// Estimated RMSE of the mean of the two renders against the truth (pair method only).
    pub rmse_of_mean: Option<f64>,
    /// `10 log10(peak² / rmse²)` with the reference's peak: the largest `psnr_hdr` measurable.
    pub psnr_hdr_ceiling: f64,
    /// `10 log10(255² / MSE₈)` of the noise on the 8-bit view (approximate, see module docs).
    pub psnr_ldr_ceiling: f64,
}

/// Noise estimates over the whole image and, with a mask, over the mask.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseReport {
    /// How it was estimated.
    pub method: NoiseMethod,
    /// Over every pixel.
    pub whole: NoiseEstimate,
    /// Over the mask, when one was given.
    pub masked: Option<NoiseEstimate>,
}

/// `sqrt(max(0, rmse² − noise_rmse²))`: the RMSE of a test image against the truth,
/// estimated from its RMSE against a noisy reference (see the module docs).
#[must_use]
pub fn noise_corrected_rmse(rmse: f64, noise_rmse: f64) -> f64 {
    (rmse * rmse - noise_rmse * noise_rmse).max(0.0).sqrt()
}

#[derive(Clone, Copy)]
struct Sums {
    pixels: usize,
    sum_sq: f64,
    sum_sq_ldr: f64,
    peak: f64,
}

impl Sums {
    fn new() -> Self {
        Self {
            pixels: 0,
            sum_sq: 0.0,
            sum_sq_ldr: 0.0,
            peak: f64::NEG_INFINITY,
        }
    }
}

/// Estimates the noise of the reference `reference` from a second render `second` of the
/// same scene with the same sample count and an independent seed (see the module docs).
///
/// `reference`'s maximum is the PSNR peak. Fails on size mismatch or non-finite values.
pub fn noise_from_pair(
    reference: &Image,
    second: &Image,
    mask: Option<&Mask>,
    options: &CompareOptions,
) -> Result<NoiseReport> {
    options.validate()?;
    check_pair(second, "second render", reference, "reference", mask)?;
    let mut sums = [Sums::new(); 2];
    for (i, (&a, &b)) in second.pixels.iter().zip(&reference.pixels).enumerate() {
        let inside = mask.is_some_and(|m| m.contains_index(i));
        for s in sums.iter_mut().take(if inside { 2 } else { 1 }) {
            s.pixels += 1;
            for c in 0..3 {
                let d = f64::from(a[c]) - f64::from(b[c]);
                s.sum_sq += d * d;
                let dl = f64::from(ldr_value(a[c], options.exposure_ev))
                    - f64::from(ldr_value(b[c], options.exposure_ev));
                s.sum_sq_ldr += dl * dl;
                s.peak = s.peak.max(f64::from(b[c]));
            }
        }
    }
    let finish = |s: &Sums| {
        let n = 3.0 * s.pixels as f64;
        let mse = s.sum_sq / (2.0 * n);
        NoiseEstimate {
            pixels: s.pixels,
            rmse: mse.sqrt(),
            rmse_of_mean: Some((mse / 2.0).sqrt()),
            psnr_hdr_ceiling: psnr(s.peak, mse),
            psnr_ldr_ceiling: psnr(255.0, s.sum_sq_ldr / (2.0 * n)),
        }
    };
    Ok(NoiseReport {
        method: NoiseMethod::Pair,
        whole: finish(&sums[0]),
        masked: mask.map(|_| finish(&sums[1])),
    })
}

/// Derivative of the 8-bit view `255 · oetf(clamp(2^ev x))` with respect to `x` (0 where
/// the view clamps).
fn ldr_slope(x: f64, exposure_ev: f64) -> f64 {
    let k = exposure_ev.exp2();
    let s = k * x;
    if !(0.0..1.0).contains(&s) {
        0.0
    } else if s <= 0.0031308 {
        255.0 * k * 12.92
    } else {
        255.0 * k * 1.055 / 2.4 * s.powf(1.0 / 2.4 - 1.0)
    }
}

/// Estimates the noise of `reference` from `variance`, an image of per-pixel, per-channel
/// variances of the mean estimate (the tracer's variance AOV); see the module docs.
///
/// Fails on size mismatch, non-finite or negative variances.
pub fn noise_from_variance(
    variance: &Image,
    reference: &Image,
    mask: Option<&Mask>,
    options: &CompareOptions,
) -> Result<NoiseReport> {
    options.validate()?;
    check_pair(variance, "variance image", reference, "reference", mask)?;
    let mut sums = [Sums::new(); 2];
    for (i, (&v, &b)) in variance.pixels.iter().zip(&reference.pixels).enumerate() {
        if let Some(c) = v.iter().position(|&x| x < 0.0) {
            return Err(CompareError::InvalidOption(format!(
                "variance image: pixel (x = {}, y = {}) channel {} is negative ({}); a variance is ≥ 0",
                i % variance.width,
                i / variance.width,
                ['R', 'G', 'B'][c],
                v[c]
            )));
        }
        let inside = mask.is_some_and(|m| m.contains_index(i));
        for s in sums.iter_mut().take(if inside { 2 } else { 1 }) {
            s.pixels += 1;
            for c in 0..3 {
                let var = f64::from(v[c]);
                let r = f64::from(b[c]);
                s.sum_sq += var;
                let slope = ldr_slope(r, options.exposure_ev);
                s.sum_sq_ldr += slope * slope * var;
                s.peak = s.peak.max(r);
            }
        }
    }
    let finish = |s: &Sums| {
        let n = 3.0 * s.pixels as f64;
        let mse = s.sum_sq / n;
        NoiseEstimate {
            pixels: s.pixels,
            rmse: mse.sqrt(),
            rmse_of_mean: None,
            psnr_hdr_ceiling: psnr(s.peak, mse),
            psnr_ldr_ceiling: psnr(255.0, s.sum_sq_ldr / n),
        }
    };
    Ok(NoiseReport {
        method: NoiseMethod::Variance,
        whole: finish(&sums[0]),
        masked: mask.map(|_| finish(&sums[1])),
    })
}
