//! Pixel masks: which pixels belong to the object whose error is measured.

use crate::error::{CompareError, Result};
use std::path::Path;

/// A set of pixels of a `width × height` image; never empty.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Mask {
    width: usize,
    height: usize,
    inside: Vec<bool>,
    count: usize,
}

impl Mask {
    /// A mask from one boolean per pixel (row-major, row 0 at the top; `true` = inside).
    ///
    /// Fails when the vector does not have `width × height` entries or when no entry is `true`.
    pub fn from_bools(width: usize, height: usize, inside: Vec<bool>) -> Result<Self> {
        Self::build("mask", width, height, inside)
    }

    /// Reads a mask from a PNG (or OpenEXR) file: a pixel is inside when any of its colour
    /// (or gray) channels is nonzero; alpha is ignored.
    ///
    /// Fails when the file is missing or not an image, or when every pixel is zero.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let (width, height, inside) = prt_image::read::nonzero_mask(path)?;
        Self::build(&path.display().to_string(), width, height, inside)
    }

    fn build(what: &str, width: usize, height: usize, inside: Vec<bool>) -> Result<Self> {
        if width.checked_mul(height) != Some(inside.len()) {
            return Err(CompareError::PixelCount {
                what: what.into(),
                len: inside.len(),
                width,
                height,
            });
        }
        let count = inside.iter().filter(|&&b| b).count();
        if count == 0 {
            return Err(CompareError::EmptyMask { what: what.into() });
        }
        Ok(Self {
            width,
            height,
            inside,
            count,
        })
    }

    /// Width in pixels.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Number of pixels inside (at least 1).
    #[must_use]
    pub fn count(&self) -> usize {
        self.count
    }

    /// Whether the pixel with row-major index `index` is inside (`false` past the end).
    #[must_use]
    pub fn contains_index(&self, index: usize) -> bool {
        self.inside.get(index).copied().unwrap_or(false)
    }

    /// One boolean per pixel, row-major.
    #[must_use]
    pub fn as_slice(&self) -> &[bool] {
        &self.inside
    }

    /// Fails unless the mask is `width × height`; `image` names the image in the message.
    pub fn check_size(&self, image: &str, width: usize, height: usize) -> Result<()> {
        if (self.width, self.height) != (width, height) {
            return Err(CompareError::SizeMismatch {
                first: "the mask".into(),
                first_width: self.width,
                first_height: self.height,
                second: image.into(),
                second_width: width,
                second_height: height,
            });
        }
        Ok(())
    }
}
