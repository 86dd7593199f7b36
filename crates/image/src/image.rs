//! The in-memory image: linear RGB, row-major, row 0 at the top.

use crate::error::{ImageError, Result};

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
    ///
    /// # Errors
    /// [`ImageError::PixelCount`].
    pub fn new(width: usize, height: usize, pixels: Vec<[f32; 3]>) -> Result<Self> {
        if width.checked_mul(height) != Some(pixels.len()) {
            return Err(ImageError::PixelCount {
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
    ///
    /// # Errors
    /// [`ImageError::PixelCount`], [`ImageError::EmptyImage`] or [`ImageError::NonFinite`].
    pub fn validate(&self, what: &str) -> Result<()> {
        if self.width.checked_mul(self.height) != Some(self.pixels.len()) {
            return Err(ImageError::PixelCount {
                what: what.into(),
                len: self.pixels.len(),
                width: self.width,
                height: self.height,
            });
        }
        if self.pixels.is_empty() {
            return Err(ImageError::EmptyImage { what: what.into() });
        }
        for (i, p) in self.pixels.iter().enumerate() {
            for (c, &v) in p.iter().enumerate() {
                if !v.is_finite() {
                    return Err(ImageError::NonFinite {
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
