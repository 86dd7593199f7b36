//! Error metrics of a test image against a reference (CONVENTIONS "Colour and images").

use crate::error::{CompareError, Result};
use crate::mask::Mask;
use prt_image::{ldr_value, Image};

/// Options of [`compare_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompareOptions {
    /// Exposure of the 8-bit PNG view used by `psnr_ldr`, in stops (EV): linear values are
    /// multiplied by `2^exposure_ev` before the clamp and the sRGB curve. Default 0.
    pub exposure_ev: f64,
}

impl CompareOptions {
    /// The defaults of CONVENTIONS: exposure 0 EV.
    #[must_use]
    pub const fn conventions() -> Self {
        Self { exposure_ev: 0.0 }
    }

    /// Fails unless the exposure is finite.
    pub fn validate(&self) -> Result<()> {
        if !self.exposure_ev.is_finite() {
            return Err(CompareError::InvalidOption(format!(
                "exposure must be a finite number of stops, got {}",
                self.exposure_ev
            )));
        }
        Ok(())
    }
}

impl Default for CompareOptions {
    fn default() -> Self {
        Self::conventions()
    }
}

/// Errors over one set of pixels (all of them, or those of a mask). All sums run over the
/// three channels of every pixel in the set: `N = 3 × pixels` values.
///
/// Non-finite values have a meaning and are written as JSON `null`:
/// - `psnr_ldr`, `psnr_hdr` are `+∞` when the images are identical on the set (`rmse == 0`,
///   resp. equal 8-bit views);
/// - `psnr_hdr` is NaN (undefined) when the reference's peak is ≤ 0 and the images differ;
/// - `rel_l2` is `+∞` when the reference is 0 everywhere on the set and the images differ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorStats {
    /// Number of pixels in the set.
    pub pixels: usize,
    /// `10 log10(255² / MSE₈)`, MSE₈ over the 8-bit sRGB views (values 0…255), in dB.
    pub psnr_ldr: f64,
    /// `10 log10(peak² / MSE)` on linear values, `peak` = [`Self::hdr_peak`], in dB.
    pub psnr_hdr: f64,
    /// `sqrt(Σ(a−b)² / N)`, linear.
    pub rmse: f64,
    /// `sqrt(Σ(a−b)² / Σb²)`, b = reference.
    pub rel_l2: f64,
    /// `Σ|a−b| / N`, linear.
    pub mae: f64,
    /// `max |a−b|` over all values, linear.
    pub max_abs: f64,
    /// MSE of the 8-bit views, in 8-bit units squared.
    pub mse_ldr: f64,
    /// The peak of `psnr_hdr`: the largest reference value (any channel) in the set.
    pub hdr_peak: f64,
}

/// The result of [`compare`]: errors over the whole image and, with a mask, over the mask.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Metrics {
    /// Image width in pixels.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
    /// Exposure of the LDR view, EV.
    pub exposure_ev: f64,
    /// Errors over every pixel.
    pub whole: ErrorStats,
    /// Errors over the mask's pixels, when a mask was given.
    pub masked: Option<ErrorStats>,
}

/// Sums of one pixel set, accumulated in f64.
#[derive(Debug, Clone, Copy)]
struct Accum {
    pixels: usize,
    sum_sq: f64,
    sum_abs: f64,
    max_abs: f64,
    sum_ref_sq: f64,
    ref_max: f64,
    sum_sq_ldr: f64,
}

impl Accum {
    fn new() -> Self {
        Self {
            pixels: 0,
            sum_sq: 0.0,
            sum_abs: 0.0,
            max_abs: 0.0,
            sum_ref_sq: 0.0,
            ref_max: f64::NEG_INFINITY,
            sum_sq_ldr: 0.0,
        }
    }

    fn add(&mut self, a: [f32; 3], b: [f32; 3], exposure_ev: f64) {
        self.pixels += 1;
        for c in 0..3 {
            let (x, r) = (f64::from(a[c]), f64::from(b[c]));
            let d = x - r;
            self.sum_sq += d * d;
            self.sum_abs += d.abs();
            self.max_abs = self.max_abs.max(d.abs());
            self.sum_ref_sq += r * r;
            self.ref_max = self.ref_max.max(r);
            let dl =
                f64::from(ldr_value(a[c], exposure_ev)) - f64::from(ldr_value(b[c], exposure_ev));
            self.sum_sq_ldr += dl * dl;
        }
    }

    fn finish(&self) -> ErrorStats {
        let n = 3.0 * self.pixels as f64;
        let mse = self.sum_sq / n;
        let mse_ldr = self.sum_sq_ldr / n;
        ErrorStats {
            pixels: self.pixels,
            psnr_ldr: psnr(255.0, mse_ldr),
            psnr_hdr: psnr(self.ref_max, mse),
            rmse: mse.sqrt(),
            rel_l2: if self.sum_sq == 0.0 {
                0.0
            } else {
                (self.sum_sq / self.sum_ref_sq).sqrt()
            },
            mae: self.sum_abs / n,
            max_abs: self.max_abs,
            mse_ldr,
            hdr_peak: self.ref_max,
        }
    }
}

/// `10 log10(peak² / mse)`: `+∞` when `mse == 0`, NaN when `peak ≤ 0` and `mse > 0`.
#[must_use]
pub fn psnr(peak: f64, mse: f64) -> f64 {
    if mse == 0.0 {
        f64::INFINITY
    } else if peak <= 0.0 {
        f64::NAN
    } else {
        10.0 * (peak * peak / mse).log10()
    }
}

/// Compares a test image `a` with a `reference` at the default exposure (0 EV).
///
/// See [`compare_with`].
pub fn compare(a: &Image, reference: &Image, mask: Option<&Mask>) -> Result<Metrics> {
    compare_with(a, reference, mask, &CompareOptions::default())
}

/// Compares a test image `a` with a `reference`: [`ErrorStats`] over all pixels and, with a
/// mask, over the mask's pixels only.
///
/// Fails when the images (or the mask) differ in size, when an image is empty or has a
/// NaN or infinite value (the message names the pixel), or when an option is invalid.
pub fn compare_with(
    a: &Image,
    reference: &Image,
    mask: Option<&Mask>,
    options: &CompareOptions,
) -> Result<Metrics> {
    options.validate()?;
    check_pair(a, "test image", reference, "reference", mask)?;
    let mut whole = Accum::new();
    let mut masked = Accum::new();
    for (i, (&pa, &pb)) in a.pixels.iter().zip(&reference.pixels).enumerate() {
        whole.add(pa, pb, options.exposure_ev);
        if mask.is_some_and(|m| m.contains_index(i)) {
            masked.add(pa, pb, options.exposure_ev);
        }
    }
    Ok(Metrics {
        width: reference.width,
        height: reference.height,
        exposure_ev: options.exposure_ev,
        whole: whole.finish(),
        masked: mask.map(|_| masked.finish()),
    })
}

/// Validates two images and an optional mask for a pixel-by-pixel comparison.
pub(crate) fn check_pair(
    a: &Image,
    a_name: &str,
    b: &Image,
    b_name: &str,
    mask: Option<&Mask>,
) -> Result<()> {
    a.validate(a_name)?;
    b.validate(b_name)?;
    if (a.width, a.height) != (b.width, b.height) {
        return Err(CompareError::SizeMismatch {
            first: a_name.into(),
            first_width: a.width,
            first_height: a.height,
            second: b_name.into(),
            second_width: b.width,
            second_height: b.height,
        });
    }
    if let Some(m) = mask {
        m.check_size(b_name, b.width, b.height)?;
    }
    Ok(())
}
