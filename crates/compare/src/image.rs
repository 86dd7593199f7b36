//! The in-memory image, the sRGB curves and the PNG view of CONVENTIONS "Colour and images".

use crate::error::{CompareError, Result};

/// A linear RGB image (Rec.709 primaries), row-major, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width × height` linear RGB pixels, row after row from the top.
    pub pixels: Vec<[f32; 3]>,
}

impl Image {
    /// An image from its pixels; fails when `pixels.len() != width × height`.
    pub fn new(width: usize, height: usize, pixels: Vec<[f32; 3]>) -> Result<Self> {
        if width.checked_mul(height) != Some(pixels.len()) {
            return Err(CompareError::PixelCount {
                what: "image".into(),
                len: pixels.len(),
                width,
                height,
            });
        }
        Ok(Self {
            width,
            height,
            pixels,
        })
    }

    /// An image whose pixel `(x, y)` is `f(x, y)`.
    #[must_use]
    pub fn from_fn(
        width: usize,
        height: usize,
        mut f: impl FnMut(usize, usize) -> [f32; 3],
    ) -> Self {
        let mut pixels = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                pixels.push(f(x, y));
            }
        }
        Self {
            width,
            height,
            pixels,
        }
    }

    /// The pixel at column `x`, row `y`, or `None` outside the image.
    #[must_use]
    pub fn pixel(&self, x: usize, y: usize) -> Option<[f32; 3]> {
        if x < self.width && y < self.height {
            self.pixels.get(y * self.width + x).copied()
        } else {
            None
        }
    }

    /// Checks the pixel count and that every value is finite; `what` names the image in errors.
    pub fn validate(&self, what: &str) -> Result<()> {
        if self.width.checked_mul(self.height) != Some(self.pixels.len()) {
            return Err(CompareError::PixelCount {
                what: what.into(),
                len: self.pixels.len(),
                width: self.width,
                height: self.height,
            });
        }
        if self.pixels.is_empty() {
            return Err(CompareError::EmptyImage { what: what.into() });
        }
        for (i, p) in self.pixels.iter().enumerate() {
            for (c, &v) in p.iter().enumerate() {
                if !v.is_finite() {
                    return Err(CompareError::NonFinite {
                        what: what.into(),
                        x: i % self.width,
                        y: i / self.width,
                        channel: ['R', 'G', 'B'][c],
                        value: v,
                    });
                }
            }
        }
        Ok(())
    }
}

/// The sRGB electro-optical transfer function (IEC 61966-2-1): encoded value in [0, 1] → linear.
///
/// `v ≤ 0.04045 → v / 12.92`, otherwise `((v + 0.055) / 1.055)^2.4`.
#[must_use]
pub fn srgb_eotf(encoded: f64) -> f64 {
    if encoded <= 0.04045 {
        encoded / 12.92
    } else {
        ((encoded + 0.055) / 1.055).powf(2.4)
    }
}

/// The sRGB opto-electronic transfer function (the inverse of [`srgb_eotf`]): linear in [0, 1] →
/// encoded.
///
/// `x ≤ 0.0031308 → 12.92 x`, otherwise `1.055 x^(1/2.4) − 0.055`.
#[must_use]
pub fn srgb_oetf(linear: f64) -> f64 {
    if linear <= 0.0031308 {
        12.92 * linear
    } else {
        1.055 * linear.powf(1.0 / 2.4) - 0.055
    }
}

/// One linear value in the 8-bit PNG view of CONVENTIONS "Colour and images": scale by
/// `2^exposure_ev`, clamp to [0, 1], apply the sRGB curve, round to the nearest of 0…255
/// (halves away from zero). Computed in f64.
#[must_use]
pub fn ldr_value(linear: f32, exposure_ev: f64) -> u8 {
    let scaled = f64::from(linear) * exposure_ev.exp2();
    let clamped = if scaled.is_nan() {
        0.0
    } else {
        scaled.clamp(0.0, 1.0)
    };
    // In [0, 255] after the clamp, so the cast cannot truncate.
    (srgb_oetf(clamped) * 255.0).round() as u8
}

/// The 8-bit sRGB PNG view of an image: [`ldr_value`] of every channel, row-major RGB bytes.
#[must_use]
pub fn ldr_view(image: &Image, exposure_ev: f64) -> Vec<[u8; 3]> {
    image
        .pixels
        .iter()
        .map(|p| p.map(|v| ldr_value(v, exposure_ev)))
        .collect()
}
